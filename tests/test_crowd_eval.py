"""`navzoo eval crowd`: the realism metrics on hand-made tracks, the real-data loader, a tiny CLI run."""

from __future__ import annotations

import json

import numpy as np
import pytest

from navzoo.benchmark import crowd_eval as ce
from navzoo.forecast import data as fdata

DT = 0.4


def test_constant_speed_line_has_known_speed_and_no_accel_or_jerk():
    t = np.arange(50) * 0.1  # sim steps of 0.1 s, resampled to 0.4 s
    xy = np.stack([1.3 * t, 0.5 + 0.0 * t], axis=1)
    kin = ce.track_kinematics([(t, xy)])
    assert kin["speed"].size == 12  # 4.9 s -> floor(4.9 / 0.4) + 1 = 13 samples at 0.4 s
    np.testing.assert_allclose(kin["speed"], 1.3, atol=1e-9)
    np.testing.assert_allclose(kin["accel"], 0.0, atol=1e-9)
    np.testing.assert_allclose(kin["jerk"], 0.0, atol=1e-9)


def test_kinematics_of_uniform_acceleration_and_circle():
    k = np.arange(20) * DT
    xy = np.stack([0.5 * 0.8 * k ** 2, np.zeros_like(k)], axis=1)  # a = 0.8 m/s^2 along x
    kin = ce.kinematics(xy)
    np.testing.assert_allclose(kin["accel"], 0.8, atol=1e-9)
    np.testing.assert_allclose(kin["jerk"], 0.0, atol=1e-9)
    assert kin["speed"].shape == (19,) and kin["accel"].shape == (18,) and kin["jerk"].shape == (17,)


def test_resample_uses_the_given_time_base():
    t = np.arange(10) * 0.667  # biwi_eth's step
    xy = np.stack([1.5 * t, 0.0 * t], axis=1)
    res = ce.resample(t, xy)
    assert len(res) == int(np.floor(9 * 0.667 / 0.4)) + 1
    np.testing.assert_allclose(np.diff(res[:, 0]) / DT, 1.5, atol=1e-9)
    with pytest.raises(ValueError, match="increasing"):
        ce.resample(np.array([0.0, 0.0]), np.zeros((2, 2)))


def test_teleport_jumps_are_dropped():
    k = np.arange(10) * DT
    a = np.stack([k, np.zeros_like(k)], axis=1)  # 1 m/s
    b = a + np.array([20.0, 5.0])  # a goal reset far away, then walking on at 1 m/s
    xy = np.concatenate([a, b])
    assert [len(p) for p in ce.continuous_pieces(xy)] == [10, 10]
    kin = ce.track_kinematics([(np.arange(20) * DT, xy)])
    np.testing.assert_allclose(kin["speed"], 1.0, atol=1e-9)
    assert kin["speed"].size == 18 and kin["accel"].size == 16 and kin["jerk"].size == 14
    np.testing.assert_allclose(kin["accel"], 0.0, atol=1e-9)


def test_still_start_is_trimmed_but_a_stop_later_is_kept():
    still = np.zeros((5, 2))
    walk = np.stack([np.arange(1, 11) * 0.4, np.zeros(10)], axis=1)  # 1 m/s after 5 still samples
    stop = np.repeat(walk[-1:], 3, axis=0)
    xy = np.concatenate([still, walk, stop])
    trimmed = ce.trim_still_start(xy)
    assert len(trimmed) == len(xy) - 4  # the last still sample is where the walk starts
    kin = ce.track_kinematics([(np.arange(len(xy)) * DT, xy)])
    assert (kin["speed"] == 0).sum() == 3  # the stop at the end stays
    assert ce.trim_still_start(np.zeros((6, 2))).shape == (0, 2)


def test_collision_share_of_two_people_passing():
    # Two people on parallel lines 0.5 m apart: never closer than 0.5 m; with x offset they meet once.
    T = 41
    x = np.linspace(-4.0, 4.0, T)
    pos = np.stack([np.stack([x, np.zeros(T)], 1), np.stack([-x, np.full(T, 0.5)], 1)], axis=1)  # (T, 2, 2)
    assert ce.collision_share(pos, 0.4) == (0, 2 * T)
    # Closer than 0.6 m while |2 x| < sqrt(0.6^2 - 0.5^2) = 0.3317: |x| < 0.166 -> x in {-0.0, 0.0} (step 0.2)
    dx = np.hypot(2 * x, 0.5)
    expected = int((dx < 0.6).sum())
    assert expected == 1
    assert ce.collision_share(pos, 0.6) == (2 * expected, 2 * T)
    # Someone absent does not collide, nor count.
    present = np.ones((T, 2), dtype=bool)
    present[:, 1] = False
    assert ce.collision_share(pos, 0.6, present) == (0, T)


def test_walked_tracks_split_at_their_gaps_and_end_at_a_fall():
    """Centres at 30 Hz with NaN while a body is down: no difference is taken across a gap, even a short one
    (here 1.5 m, under the teleport cut), and a fallen body's track simply ends."""
    dt = 1.0 / 30.0
    T = 240  # 8 s
    t = np.arange(T) * dt
    walker = np.stack([1.2 * t, np.zeros(T)], axis=1)  # 1.2 m/s throughout
    gap = np.stack([1.0 * t, np.full(T, 3.0)], axis=1)
    gap[100:130] = np.nan  # down for 1 s ...
    gap[130:] += np.array([1.5, 0.0])  # ... and back 1.5 m further on (a respawn, not a step)
    faller = np.stack([0.8 * t, np.full(T, 6.0)], axis=1)
    faller[150:] = np.nan  # fell after 5 s and stays down
    pos = np.stack([walker, gap, faller], axis=1)
    kin = ce.walked_kinematics(pos, dt)
    speeds = np.sort(np.unique(np.round(kin["speed"], 6)))
    np.testing.assert_allclose(speeds, [0.8, 1.0, 1.2], atol=1e-6)  # no spike across the gap
    np.testing.assert_allclose(kin["accel"], 0.0, atol=1e-9)
    # points at 0.4 s: 7.97 s -> 20, 3.30 s + 3.63 s -> 9 + 10, 4.97 s -> 13; one speed fewer per piece
    assert kin["speed"].size == 19 + 8 + 9 + 12
    hits, total = ce.walked_collisions(pos)
    assert hits == 0 and total == 3 * T - 30 - (T - 150)  # the fallen and the absent are not counted
    close = np.stack([walker, walker + np.array([0.3, 0.0])], axis=1)
    close[:50, 1] = np.nan
    assert ce.walked_collisions(close, chunk=7) == (2 * (T - 50), 2 * T - 50)
    with pytest.raises(ValueError, match=r"pos must be \(T, N, 2\)"):
        ce.walked_kinematics(np.zeros((5, 2)), dt)
    with pytest.raises(ValueError, match="dt must be > 0"):
        ce.walked_kinematics(pos, 0.0)


def test_distances_of_identical_and_shifted_distributions():
    rng = np.random.default_rng(0)
    a = rng.normal(1.2, 0.2, 5000).clip(0)
    same = ce.distribution_distance(a, a.copy(), ce.BINS["speed"])
    assert same["w1"] == pytest.approx(0.0, abs=1e-12) and same["js"] == pytest.approx(0.0, abs=1e-12)
    shifted = ce.distribution_distance(a + 0.5, a, ce.BINS["speed"])
    assert shifted["w1"] == pytest.approx(0.5, abs=0.02)
    assert 0.1 < shifted["js"] <= 1.0
    assert np.isnan(ce.distribution_distance(np.zeros(0), a, ce.BINS["speed"])["w1"])


@pytest.mark.skipif(not fdata.default_data_dir().is_dir(), reason="ETH/UCY data not available")
def test_real_tracks_have_plausible_walking_speeds():
    kin, summary = ce.real_data()
    assert {f["scene"] for f in summary["files"]} >= {"biwi_eth", "crowds_zara01", "students001"}
    biwi = next(f for f in summary["files"] if f["scene"] == "biwi_eth")
    assert biwi["dt"] == pytest.approx(0.667)
    # All samples (standing people included) ~0.9 m/s; moving people 1.0-1.1 m/s.
    assert 0.7 < summary["speed_mean"] < 1.2
    moving = kin["speed"][kin["speed"] > 0.2]
    assert 0.9 < moving.mean() < 1.4
    assert 0.0 < summary["collision_rate"] < summary["collision_rate_env_radius"] < 1.0
    assert summary["samples"]["jerk"] > 10_000


def test_bad_arguments_are_clear(monkeypatch):
    with pytest.raises(ValueError, match="unknown crowd model.*choose from"):
        ce.realism(crowds=["social_force"], scenes=["lobby"], seconds=1.0)
    with pytest.raises(ValueError, match="unknown scene"):
        ce.evaluate(scenes=["atlantis"], seconds=1.0)
    with pytest.raises(ValueError, match="unknown reliability row"):
        ce.reliability(rows=["orca+amp"], scenes=["lobby"], seconds=1.0)
    monkeypatch.setattr(ce, "realism", lambda *a, **k: pytest.fail("the realism part ran before the rows were checked"))
    with pytest.raises(ValueError, match="unknown reliability row"):
        ce.evaluate(rows=["orca+amp"], scenes=["lobby"], seconds=1.0)


def test_heldout_scenes_run_with_their_own_people_counts(monkeypatch):
    """``--scenes heldout`` runs the ten held-out scenes with the people of HELDOUT_SCENES, in both parts."""
    seen = {}

    def fake_realism(crowds, scenes, seconds, seed, workers, counts, *a, **k):
        seen["realism"] = (tuple(scenes), counts)
        return {}

    def fake_following(scenes, seconds, seed, policy_dir, **kw):
        seen["following"] = (tuple(scenes), kw["people"])
        return {"success_rate": 0.5, "fall_rate": 0.0, "trips": 2}, None

    monkeypatch.setattr(ce, "realism", fake_realism)
    monkeypatch.setattr(ce, "real_data", lambda *a, **k: ({}, {}))
    monkeypatch.setattr(ce.pedestrians, "following", fake_following)
    args = ce.argparse.ArgumentParser()
    ce.add_arguments(args)
    parsed = args.parse_args(["--scenes", "heldout"])
    ce.evaluate(scenes=parsed.scenes, seconds=1.0, rows=["sfm+kinematic"], with_cost=False)
    names = tuple(name for name, _ in ce.pedestrians.HELDOUT_SCENES)
    counts = [n for _, n in ce.pedestrians.HELDOUT_SCENES]
    assert seen["realism"] == (names, counts)
    assert seen["following"] == (names, counts)
    assert counts != [3] * len(counts) and len(names) == 10
    # mixed with other names it expands in place; the people are then spread over all of them
    assert ce._check_scenes(["lobby", "heldout"]) == ("lobby", *names)
    with pytest.raises(ValueError, match="unknown scene"):
        ce._check_scenes(["held_out"])


def test_each_reliability_row_is_saved_as_it_finishes(tmp_path, monkeypatch):
    """A long run stopped after some rows keeps them in --out (only the chosen rows run)."""
    calls = []

    def fake_following(scenes, seconds, seed, policy_dir, **kw):
        calls.append(kw["crowd_model"])
        if len(calls) == 2:
            raise KeyboardInterrupt  # stopped during the second row
        return {"success_rate": 0.5, "fall_rate": 0.0, "trips": 2}, None

    monkeypatch.setattr(ce, "realism", lambda *a, **k: {})
    monkeypatch.setattr(ce, "real_data", lambda *a, **k: ({}, {}))  # no ETH/UCY data needed without the realism part
    monkeypatch.setattr(ce.pedestrians, "following", fake_following)
    out = tmp_path / "crowd.json"
    with pytest.raises(KeyboardInterrupt):
        ce.evaluate(scenes=["lobby"], seconds=1.0, rows=["sfm+kinematic", "diffusion+kinematic"], with_cost=False,
                    out=out)
    saved = json.loads(out.read_text())
    assert saved["partial"] is True and list(saved["reliability"]) == ["sfm+kinematic"]
    assert calls == ["sfm", "diffusion"]


@pytest.mark.skipif(not fdata.default_data_dir().is_dir(), reason="ETH/UCY data not available")
def test_cli_tiny_run_prints_json(capsys, tmp_path):
    from navzoo.cli import main

    out = tmp_path / "crowd.json"
    rc = main(["eval", "crowd", "--scenes", "lobby", "--people", "4", "--seconds", "8", "--crowds", "sfm,diffusion",
               "--no-amp", "--no-cost", "--json", "--out", str(out)])
    assert rc == 0
    res = json.loads(capsys.readouterr().out)
    assert json.loads(out.read_text())["partial"] is False
    assert set(res) >= {"realism", "reliability", "machine"} and "cost" not in res
    assert set(res["realism"]) >= {"sfm", "diffusion", "real"}
    for crowd in ("sfm", "diffusion"):
        row = res["realism"][crowd]
        for q in ("speed", "accel", "jerk"):
            assert {f"{q}_mean", f"{q}_w1", f"{q}_js"} <= set(row)
        assert 0.0 <= row["collision_rate"] <= row["collision_rate_env_radius"] <= 1.0
        assert 0.3 < row["speed_mean"] < 2.0
        assert 0.0 <= row["standing_share"] <= 1.0 and row["accel_walking_mean"] >= 0.0
        assert all(0.0 <= sc["standing_share"] <= 1.0 for sc in row["scenes"])
    assert 0.0 < res["realism"]["real"]["standing_share"] < 1.0 and res["realism"]["real"]["accel_walking_mean"] > 0
    assert set(res["reliability"]) == {"sfm+kinematic", "diffusion+kinematic"}
    for row in res["reliability"].values():
        assert {"success_rate", "fall_rate", "map_collision_rate", "agent_collision_rate", "path_error_m",
                "trips"} <= set(row)
        assert row["fall_rate"] == 0.0
    assert res["reliability"]["sfm+kinematic"]["path_error_m"] is None
    assert res["reliability"]["diffusion+kinematic"]["path_error_m"] >= 0.0
    md = ce.markdown(res)
    assert "paper sfm+amp | 74.24" in md and "real (ETH/UCY)" in md and "| standing share | accel while walking |" in md
    assert main(["eval", "crowd", "--crowds", "nope", "--no-cost"]) == 2


def test_cost_timings_run_small():
    rows = ce.replan_cost((2,), repeats=1, scene="lobby")
    assert rows[0]["pedestrians"] == 2 and rows[0]["replan_ms"] > 0
    step = ce.step_cost(scene="lobby", n=2, steps=25, warmup=2)
    assert step["diffusion_replans"] >= 1  # 2.5 s of sim time: at least one replan in the timed steps
    assert step["diffusion_step_ms"] > 0 and step["sfm_step_ms"] > 0 and step["diffusion_over_sfm"] > 0
    md = ce.markdown({"cost": {"replan_cpu": rows, "step": step}})
    assert "cpu replan (ms)" in md and "Env step (lobby" in md


def test_cost_only_runs_the_timings_alone_and_writes_them(tmp_path, monkeypatch, capsys):
    from navzoo.cli import main

    monkeypatch.setattr(ce, "evaluate", lambda *a, **k: pytest.fail("--cost-only ran the evaluation"))
    monkeypatch.setattr(ce, "cost", lambda quick: {"replan_cpu": [{"pedestrians": 1, "replan_ms": 5.0}], "quick": quick})
    out = tmp_path / "cost.json"
    assert main(["eval", "crowd", "--cost-only", "--quick", "--json", "--out", str(out)]) == 0
    saved = json.loads(out.read_text())
    assert saved["cost"] == {"replan_cpu": [{"pedestrians": 1, "replan_ms": 5.0}], "quick": True} and saved["machine"]
    assert json.loads(capsys.readouterr().out) == saved
    with pytest.raises(SystemExit, match="--cost-only and --no-cost"):
        main(["eval", "crowd", "--cost-only", "--no-cost"])


def test_reliability_rows_over_several_seeds_resume_their_scene_runs(tmp_path, monkeypatch):
    kw = dict(rows=["sfm+kinematic"], scenes=["station"], seconds=10.0, people=[3])
    whole = ce.reliability(seeds=[0, 1], **kw)["sfm+kinematic"]
    assert whole["seeds"] == [0, 1] and [r["seed"] for r in whole["by_seed"]] == [0, 1]
    assert whole["trips"] == sum(r["trips"] for r in whole["by_seed"])
    prefix = tmp_path / "crowd.json"
    ce.reliability(seeds=[0, 1], resume_prefix=prefix, **kw)
    kept = ce.row_resume_file(prefix, "sfm+kinematic")
    assert len(kept.read_text().splitlines()) == 3  # settings + one line per (scene, seed) run
    real = ce.pedestrians.follow_scene
    monkeypatch.setattr(ce.pedestrians, "follow_scene", lambda *a: pytest.fail(f"ran {a[:4]} again"))
    again = ce.reliability(seeds=[0, 1], resume_prefix=prefix, **kw)["sfm+kinematic"]
    assert again["by_seed"] == whole["by_seed"]
    assert again["walked"] == whole["walked"]  # the walked kinematics come back from the kept runs too
    monkeypatch.setattr(ce.pedestrians, "follow_scene", real)
    text = ce.markdown({"reliability": {"sfm+kinematic": again}})
    assert "| sfm+kinematic, seed 1 |" in text
    assert f"| sfm+kinematic, one trip per goal | {100 * again['per_goal']['success_rate']:.2f} |" in text
    with pytest.raises(SystemExit, match="not both"):
        ce.main(["--seed", "2", "--seeds", "0,1"])


def test_reliability_rows_say_how_their_people_walked():
    """Every row carries its people's walked kinematics, with the distances to the real samples given; the
    Markdown shows them under the reliability table."""
    rng = np.random.default_rng(0)
    real = {"speed": rng.normal(1.0, 0.2, 500).clip(0), "accel": rng.gamma(2.0, 0.1, 500),
            "jerk": rng.gamma(2.0, 0.3, 500)}
    rows = ce.reliability(rows=["sfm+kinematic"], scenes=["station"], seconds=12.0, people=[3], real_kin=real)
    walked = rows["sfm+kinematic"]["walked"]
    for q in ("speed", "accel", "jerk"):
        assert walked["samples"][q] > 0 and walked[f"{q}_w1"] >= 0.0 and 0.0 <= walked[f"{q}_js"] <= 1.0
    assert 0.3 < walked["speed_mean"] < 2.0
    assert 0.0 <= walked["collision_rate"] <= 1.0 and walked["person_steps"] > 0
    no_real = ce.reliability(rows=["sfm+kinematic"], scenes=["station"], seconds=12.0, people=[3])
    assert no_real["sfm+kinematic"]["walked"]["speed_mean"] == walked["speed_mean"]
    assert "speed_w1" not in no_real["sfm+kinematic"]["walked"]
    md = ce.markdown({"reliability": rows})
    assert "| walked in the reliability runs |" in md and "| sfm+kinematic | " in md


def test_a_realism_scene_runs_on_one_torch_thread_and_gives_the_callers_setting_back(monkeypatch):
    torch = pytest.importorskip("torch")
    seen = []
    real_kinematics = ce.track_kinematics

    def spy(*args, **kwargs):
        seen.append(torch.get_num_threads())
        return real_kinematics(*args, **kwargs)

    monkeypatch.setattr(ce, "track_kinematics", spy)
    before = torch.get_num_threads()
    torch.set_num_threads(2)
    try:
        row = ce.crowd_scene("sfm", "corridor", 2, seconds=1.0)
        assert torch.get_num_threads() == 2
    finally:
        torch.set_num_threads(before)
    assert seen == [1] and row["pedestrians"] == 2


def test_a_realism_scenes_overlap_threshold_is_the_one_given():
    """``crowd_scene(overlap_m=...)`` counts pairs closer than that distance (it was accepted and ignored once)."""
    wide = ce.crowd_scene("sfm", "corridor", 2, seconds=1.0, overlap_m=1e3)
    default = ce.crowd_scene("sfm", "corridor", 2, seconds=1.0)
    hits, pairs = wide["counts"]["overlap"]
    assert pairs > 0 and hits == pairs  # every pair is within a kilometre
    assert default["counts"]["overlap"][0] < pairs  # two people starting apart do not all overlap at 0.4 m
    assert default["counts"]["env_radius"] == wide["counts"]["env_radius"]


def test_set_reaches_the_realism_and_reliability_runs_and_is_checked_first(monkeypatch, capsys):
    """``navzoo eval crowd --set KEY=VALUE``: NavConfig fields of every run, refused by name before any run."""
    seen = {}

    def fake_following(scenes, seconds, seed, policy_dir, **kw):
        seen["following"] = kw["env_overrides"]
        return {"success_rate": 0.5, "fall_rate": 0.0, "trips": 2}, None

    monkeypatch.setattr(ce, "real_data", lambda *a, **k: ({q: np.ones(5) for q in ce.QUANTITIES}, {}))
    monkeypatch.setattr(ce.pedestrians, "following", fake_following)
    res = ce.evaluate(scenes=["corridor"], people=2, seconds=2.0, crowds=["sfm"], rows=["sfm+kinematic"],
                      with_cost=False, env_overrides={"crowd_wall_strength": 0.3})
    assert seen["following"] == {"crowd_wall_strength": 0.3} == res["env_overrides"]
    assert res["realism"]["settings"]["env_overrides"] == {"crowd_wall_strength": 0.3}
    # the field reaches the scene runs: the softer walls walk a crowd differently from the default ones
    soft = ce.crowd_scene("sfm", "doorway", 6, seconds=20.0, env_overrides={"crowd_wall_strength": 0.3})
    default = ce.crowd_scene("sfm", "doorway", 6, seconds=20.0)
    assert not np.array_equal(soft["kin"]["speed"], default["kin"]["speed"])
    monkeypatch.setattr(ce, "realism", lambda *a, **k: pytest.fail("ran before --set was checked"))
    for items, msg in ((["crowd_wall_strenght=0.3"], "unknown NavConfig field"),
                       (["crowd_wall_strength=-1"], "crowd_wall_strength must be"),
                       (["dt=0.2"], "set by the following protocol"),
                       (["crowd_wall_strength"], "KEY=VALUE")):
        with pytest.raises(SystemExit, match=msg):
            ce.main(["--scenes", "lobby", "--no-cost", *[x for i in items for x in ("--set", i)]])


def test_standing_and_walking_accelerations_of_hand_made_tracks():
    t = np.arange(0, 12.05, 0.1)
    x = np.where(t < 4, t, np.where(t < 8, 4.0, 4.0 + 1.2 * (t - 8)))  # 1 m/s, stands 4 s, 1.2 m/s
    xy = np.stack([x, 0 * t], -1)
    walking = ce.walking_accel(t, xy)
    assert walking.size > 10 and np.abs(walking).max() < 1e-6  # the stop and the start are not walking
    assert ce.kinematics(ce.resample(t, xy, ce.STEP), ce.STEP)["accel"].max() > 2.0
    hits, total = ce.standing(xy[:, None], 0.1)
    assert total == 30 and hits == 10  # 0.4 s steps: the 4 s stand


@pytest.mark.skipif(not fdata.default_data_dir().is_dir(), reason="ETH/UCY data not available")
def test_real_people_stand_some_of_the_time_and_accelerate_mostly_walking():
    kin, summary = ce.real_data()
    assert 0.02 < summary["standing_share"] < 0.5
    assert 0.5 * summary["accel_mean"] < summary["accel_walking_mean"] < 2.0 * summary["accel_mean"]
