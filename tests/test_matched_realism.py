"""Matched-start realism (navzoo eval crowd-matched): scenarios from the recordings and their simulation."""

import json

import numpy as np
import pytest

from navzoo.benchmark import matched_realism as mr
from navzoo.benchmark.crowd_eval import STEP


def test_scenarios_start_and_end_where_the_real_people_do():
    from navzoo.agents.replay import load_recording

    rec = load_recording("zara1")
    scs = mr.scenarios("zara1", every=30.0, max_scenarios=3)
    assert 1 <= len(scs) <= 3
    for sc in scs:
        n = len(sc["starts"])
        assert sc["goals"].shape == (n, 2) and sc["walker"].shape == (n,) and sc["walker"].any()
        present = rec.positions_at(sc["t"])
        for j, seg in enumerate(sc["real"]):
            np.testing.assert_allclose(seg[0], sc["starts"][j])
            assert len(seg) - 1 <= round(12.0 / STEP) and (len(seg) - 1) * STEP >= 4.8 - 1e-9
            # every start is a recorded position at the scenario's time
            assert min(np.linalg.norm(p - seg[0]) for p in present.values()) < 1e-9
            if sc["walker"][j]:
                np.testing.assert_allclose(seg[-1], sc["goals"][j])
                assert np.linalg.norm(seg[-1] - seg[0]) >= 2.0
                assert 0.3 <= sc["v_pref"][j] <= 2.0
            else:
                np.testing.assert_allclose(sc["goals"][j], sc["starts"][j])
    # thinning keeps the first and the last start time
    every = mr.scenarios("zara1", every=30.0)
    assert scs[0]["t"] == every[0]["t"] and scs[-1]["t"] == every[-1]["t"]


def test_scenario_arguments_are_checked():
    with pytest.raises(ValueError, match="every"):
        mr.scenarios("zara1", every=0.0)
    with pytest.raises(ValueError, match="unknown crowd"):
        mr.evaluate(crowds=["nope"])
    with pytest.raises(ValueError, match="unknown diffusion crowd setting.*lookahead"):
        mr.evaluate(crowds=["diffusion"], diffusion_settings={"lookahead": 1.0})
    with pytest.raises(ValueError, match="NAME=NUMBER"):
        mr._settings("guidance_scale")


def test_diffusion_settings_reach_the_crowd():
    from types import SimpleNamespace

    crowd = SimpleNamespace(weights=(1.0, 10.0, 10.0), guidance_scale=0.05, n_samples=4)
    mr.apply_diffusion_settings(crowd, {"agent_weight": 3, "guidance_scale": 0.0, "n_samples": 2.0})
    assert crowd.weights == (1.0, 3.0, 10.0) and crowd.guidance_scale == 0.0
    assert crowd.n_samples == 2 and isinstance(crowd.n_samples, int)
    for bad in ({"n_samples": 0.0}, {"replan_s": 0.0}, {"agent_buffer": -0.1}, {"guidance_scale": float("nan")}):
        with pytest.raises(ValueError, match=next(iter(bad))):
            mr.apply_diffusion_settings(crowd, bad)


def _line_scenario(speed: float = 1.0, length: float = 6.0) -> mr.Scenario:
    k = int(round(length / speed / STEP))
    seg = np.stack([np.linspace(-3.0, -3.0 + length, k + 1), np.zeros(k + 1)], axis=1)
    fine = np.arange(int(round(12.0 / mr.SIM_DT)) + 1) * mr.SIM_DT
    real_pos = np.stack([np.interp(fine, STEP * np.arange(k + 1), seg[:, 0]), np.zeros_like(fine)], axis=1)[:, None]
    return mr.Scenario(recording="eth", t=0.0, starts=seg[:1].copy(), goals=seg[-1:].copy(), walker=np.array([True]),
                       v_pref=np.array([speed]), real=[seg], real_present=(fine <= k * STEP + 1e-9)[:, None],
                       real_pos=real_pos)


def test_a_lone_walker_crosses_like_the_straight_real_walk():
    """Social force, alone in the open ETH scene, walks a straight 6 m at the real 1 m/s: it arrives,
    in about the real time (it starts from rest), stays near the real positions, and walks smoothly."""
    row = mr.run_scenario("sfm", _line_scenario(), seed=0)
    assert row["walkers"] == 1 and row["arrived"] == 1 and row["missed"] == []
    assert 0.9 <= row["ratio"][0] <= 1.4
    assert row["ade"][0] < 0.6 and row["fde"][0] < 0.6
    assert row["sim"]["speed"].mean() == pytest.approx(1.0, abs=0.15)
    assert row["sim"]["accel"].mean() < 0.3
    assert row["real"]["accel"].max() < 1e-9  # the real walk is straight at constant speed
    assert row["sim_hits"][0] == 0 and row["real_hits"][0] == 0


def test_cli_quick_prints_every_key(capsys):
    from navzoo.cli import main

    assert main(["eval", "crowd-matched", "--quick", "--crowds", "sfm", "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    for key in ("speed_mean", "speed_w1", "accel_w1", "jerk_w1", "ade_m", "fde_m", "arrival_rate", "time_ratio",
                "collision_rate", "walkers", "never_arrived", "never_arrived_closest_m"):
        assert key in out["sfm"]
    assert out["settings"]["scenarios"] == 2 and out["real"]["samples"]["speed"] > 0


def test_a_walker_who_cannot_make_it_is_counted_with_its_closest_approach():
    """A real walk too fast to copy (12 m in 0.8 s; the sim's pace is capped at 2 m/s and the run at
    1.5 x 0.8 + 4 s): the walker never arrives, and its closest approach is where it stopped."""
    row = mr.run_scenario("sfm", _line_scenario(speed=12.0, length=12.0), seed=0)
    assert row["arrived"] == 0 and row["ratio"] == []
    (closest, final), = row["missed"]
    assert 0.5 < closest < 12.0 and closest == pytest.approx(final, abs=0.05)


def test_fallen_in_map_gives_the_diffusion_crowd_the_grid_with_the_lying_bodies():
    from types import SimpleNamespace

    from navzoo.agents.diffusion.crowd import DiffusionCrowd

    crowd = SimpleNamespace(fallen_in_map=False, weights=(1.0, 10.0, 10.0))
    bare, stamped = object(), object()
    env = SimpleNamespace(grid=bare, pedestrian_grid=bare)  # nobody lies on the floor yet (NavEnv.pedestrian_grid)
    assert DiffusionCrowd._map_grid(crowd, env) is bare
    env.pedestrian_grid = stamped
    assert DiffusionCrowd._map_grid(crowd, env) is bare  # off: the bare scene
    mr.apply_diffusion_settings(crowd, {"fallen_in_map": 1.0})
    assert crowd.fallen_in_map is True
    assert DiffusionCrowd._map_grid(crowd, env) is stamped
    env.pedestrian_grid = bare
    assert DiffusionCrowd._map_grid(crowd, env) is bare
