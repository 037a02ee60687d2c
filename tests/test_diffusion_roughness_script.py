"""scripts/diffusion_roughness.py: the walked accelerations split at goal arrivals, and its walker settings."""


import numpy as np
import pytest

from tests.script_modules import load_script

dr = load_script("diffusion_roughness")


def test_accelerations_near_a_goal_turn_are_split_from_the_straight_walk():
    # 1 m/s along +x for 10 s, a turn back at t = 10 s (the goal), 1 m/s along -x for 10 s; sampled at 0.1 s
    t = np.arange(0, 20.0001, 0.1)
    x = np.where(t <= 10, t, 20 - t)
    xy = np.stack([x, np.zeros_like(x)], axis=1)
    near, between = dr.split_at_goals(t, xy, np.array([10.0]), step=0.4, window=2.0)
    assert near.size + between.size == 49  # 51 samples at 0.4 s: 49 accelerations
    assert np.all(between < 1e-9)  # straight, constant speed
    assert near.max() == pytest.approx(2 * 1.0 / 0.4 ** 2 * 0.4, rel=1e-6)  # the reversal: |dv| = 2 m/s in one step
    assert near.size == 11  # samples within 2 s of t = 10 s, every 0.4 s
    none_near, all_between = dr.split_at_goals(t, xy, np.zeros(0), step=0.4)
    assert none_near.size == 0 and all_between.size == 49


def test_split_drops_the_still_start_and_keeps_its_times():
    # still for 2 s, then 1 m/s; a goal at t = 3 s lies 1 s after the start of walking
    t = np.arange(0, 8.0001, 0.1)
    x = np.maximum(t - 2.0, 0.0)
    xy = np.stack([x, np.zeros_like(x)], axis=1)
    near, between = dr.split_at_goals(t, xy, np.array([3.0]), step=0.4, window=1.0)
    # the kept samples start at 2.0 s; accelerations belong to the samples at 2.4, 2.8, ...; within 1 s of 3.0 s:
    # 2.4, 2.8, 3.2, 3.6, 4.0
    assert near.size == 5
    assert near.size + between.size == 14  # 16 kept samples (2.0 ... 8.0 s)


def test_walker_settings_name_social_force_fields():
    from navzoo.agents.sfm import SocialForceParams

    base = SocialForceParams()
    p = dr.walker_params(base, {"max_accel": 1.0, "tau": 2})
    assert p.max_accel == 1.0 and p.tau == 2.0 and isinstance(p.tau, float)
    with pytest.raises(SystemExit, match="no field"):
        dr.walker_params(base, {"max_acel": 1.0})


def test_rule_based_crowds_refuse_diffusion_settings():
    with pytest.raises(SystemExit, match="takes no variant settings"):
        dr.run("corridor", 1, 1.0, {"guidance_scale": 0.0}, crowd_model="sfm")
    with pytest.raises(SystemExit, match="takes no variant settings"):
        dr.run("corridor", 1, 1.0, {"walker_tau": 1.0}, crowd_model="orca")


@pytest.mark.parametrize("settings, walker", [({}, "sfm"), ({"orca_walker": 1}, "orca"), ({"hybrid_walker": 1}, "hybrid"),
                                              ({"hybrid_walker": 1, "orca_time_horizon": 2.0}, "hybrid")])
def test_walker_variants_choose_the_diffusion_walker(monkeypatch, settings, walker):
    made = []

    class Stop(Exception):
        pass

    def capture(**kwargs):
        made.append(kwargs)
        raise Stop

    monkeypatch.setattr(dr, "NavEnv", capture)
    with pytest.raises(Stop):
        dr.run("doorway", 2, 1.0, settings)
    assert made[0]["diffusion_walker"] == walker


def test_standing_counts_the_slow_steps_of_whole_tracks():
    t = np.arange(0, 4.05, 0.1)
    walker = np.stack([t, 0 * t], -1)  # 1 m/s all along
    stopper = np.stack([np.minimum(t, 2.0), 0 * t], -1)  # walks 2 s, then stands 2 s
    hits, total = dr.standing(np.stack([walker, stopper], 1), 0.1)
    assert total == 2 * 10 and hits == 5  # 0.4 s steps: 10 per person; the stopper stands from 2.0 s to 4.0 s


def test_walking_accelerations_leave_out_stops_and_starts():
    t = np.arange(0, 12.05, 0.1)
    x = np.where(t < 4, t, np.where(t < 8, 4.0, 4.0 + 1.2 * (t - 8)))  # 1 m/s, stands 4 s, 1.2 m/s
    acc = dr.walking_accel(t, np.stack([x, 0 * t], -1))
    assert acc.size > 10 and np.abs(acc).max() < 1e-6  # only the steady walks: the stop and the start are not walking
    everything = dr.kinematics(dr.resample(t, np.stack([x, 0 * t], -1), dr.STEP), dr.STEP)["accel"]
    assert everything.max() > 2.0  # the stop and the start themselves are hard accelerations


def test_the_real_tracks_are_measured_the_same_way(tmp_path):
    folder = tmp_path / "eth_ucy"
    folder.mkdir()
    rows = [f"{10 * k}\t1\t{0.4 * k:.3f}\t0.0" for k in range(20)]  # frame ped x y: one person at 1 m/s
    rows += [f"{10 * k}\t2\t3.0\t{1.0 + (0.4 * k if k < 10 else 4.0):.3f}" for k in range(20)]  # walks, then stands
    (folder / "test_eth.txt").write_text("\n".join(rows) + "\n")
    line = dr.real_line(str(folder))
    assert line["tracks"] == 2 and line["accel_walking_mean"] == pytest.approx(0.0, abs=1e-6)
    assert 0.2 < line["standing_share"] < 0.3  # 9 of the 38 steps of 0.4 s stand
