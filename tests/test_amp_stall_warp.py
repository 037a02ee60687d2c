"""Stalled physics pedestrians walk their diffusion plans faster (amp_humans.STALL_WARP_S), and the slow-target probe
behind docs/pedestrians_log.md "Slow targets"."""

from __future__ import annotations

import json

import numpy as np
import pytest

from navzoo.envs import amp_humans
from navzoo.envs.amp_humans import blocked_ahead, near_narrow, stall_warp
from tests.fixed_plans import straight_plans
from tests.script_modules import load_script


def test_stall_warp_brings_a_slow_plan_up_to_the_pace_floor():
    v_pref = np.array([1.2, 1.2, 1.2, 1.2, 1.0])
    plan = np.array([0.24, 0.03, 1.0, 0.09, 0.0])
    w = stall_warp(plan, v_pref, pace=0.6, min_speed=0.05, max_warp=4.0)
    assert w[0] == pytest.approx(3.0)  # 0.24 m/s x 3 = 0.72 = 0.6 x 1.2
    assert w[1] == 1.0 and w[4] == 1.0  # a plan that stands is a wait: it stays one
    assert w[2] == 1.0  # already faster than the floor: unchanged, never slowed
    assert w[3] == pytest.approx(4.0)  # at most max_warp
    assert (stall_warp(plan, v_pref) == w).all()  # the module's defaults are these


def test_near_narrow_finds_people_beside_a_narrow_stretch_of_their_path():
    door = np.array([[0.0, 0.0], [1.0, 0.0]])
    pos = np.array([[0.5, 1.2], [0.5, 2.0], [3.0, 0.0]])
    near = near_narrow([door, door, np.zeros((0, 2))], pos, 1.5)
    assert near.tolist() == [True, False, False]  # 1.2 m from the door; 2 m away; no narrow points at all


def test_blocked_ahead_counts_people_in_front_toward_the_plan_only():
    pos = np.array([[0.0, 0.0], [5.0, 0.0], [10.0, 0.0], [20.0, 0.0]])
    to_plan = np.array([[1.0, 0.0], [1.0, 0.0], [0.0, 2.0], [0.0, 0.0]])
    others = np.vstack([pos, [[0.8, 0.3], [4.2, 0.0], [10.9, 0.0], [20.5, 0.0]]])
    b = blocked_ahead(pos, to_plan, others, reach=1.0, half_angle_deg=60.0)
    # 0.85 m ahead, 21 degrees off; behind the second person; beside the third (90 degrees off its +y plan);
    # the fourth has no plan direction (a wait): nobody counts as ahead
    assert b.tolist() == [True, False, False, False]
    assert not blocked_ahead(pos[:1], to_plan[:1], others, reach=0.8, half_angle_deg=60.0)[0]  # farther than reach
    assert not blocked_ahead(pos[:1], to_plan[:1], pos[:1], reach=1.0, half_angle_deg=60.0)[0]  # itself: skipped
    assert blocked_ahead(pos, to_plan, np.zeros((0, 2)), 1.0, 60.0).tolist() == [False] * 4


def _diffusion_env():
    from navzoo.envs.nav_env import NavEnv

    env = NavEnv(scene="circle_crossing", n_robots=0, n_humans=2, human_model="amp", crowd_model="diffusion",
                 dt=1 / 30, time_limit=10.0)
    env.reset(seed=0)
    return env


def test_stall_warp_is_off_by_default_and_counts_standing_time(monkeypatch):
    assert amp_humans.STALL_WARP_S == 0.0
    env = _diffusion_env()
    amp = env.amp
    zero = {a: np.zeros(env.action_space(a).shape, dtype=np.float32) for a in env.agents}
    env.step(zero)
    assert (amp.still_s == 0).all()  # not counted while the option is off
    monkeypatch.setattr(amp_humans, "STALL_WARP_S", 1.0)
    real = amp.planar
    speeds = iter([0.0] * 12 + [0.5] + [0.0] * 3)  # the second body stands still, then walks, then stands again

    def planar():
        p, h, v, w = real()
        v[:] = 0.0
        v[1, 0] = next(speeds)
        return p, h, v, w

    monkeypatch.setattr(amp, "planar", planar)
    for _ in range(16):
        amp.control_step(lambda: None)
    assert amp.still_s[0] == pytest.approx(16 / 30) and amp.still_s[1] == pytest.approx(3 / 30)
    monkeypatch.setattr(amp, "planar", real)
    env.reset(seed=0)
    assert (env.amp.still_s == 0).all()
    env.close()


def test_a_stalled_body_gets_a_target_that_walks_its_slow_plan_faster(monkeypatch):
    env = _diffusion_env()
    amp, crowd = env.amp, env.diffusion
    crowd.plan_now(env)
    pos = amp.planar()[0]
    goal_dir = env.goal[env.n_robots:] - pos
    goal_dir /= np.linalg.norm(goal_dir, axis=1, keepdims=True)
    # slow plans: 0.2 m/s from each body toward its goal, for every later replan of this test too
    straight_plans(monkeypatch, crowd, pos, 0.2 * goal_dir)
    reach = {}
    for on in (False, True):
        monkeypatch.setattr(amp_humans, "STALL_WARP_S", 1.0 if on else 0.0)
        amp.still_s[:] = 2.0  # both bodies have stood for 2 s (counted only while the option is on)
        amp.plan_all()
        reach[on] = np.linalg.norm(amp.paths[:, 60] - pos, axis=1)  # where the target is 2 s into the plan
    assert (reach[False] < 0.55).all()  # about the plan's 0.4 m
    assert (reach[True] > 1.5 * reach[False]).all()  # at no less than 0.6 x the preferred speed
    assert (reach[True] <= env.v_pref[env.n_robots:] * 2.0 + 0.05).all()
    # with STALL_CLEAR_M, a body whose plan leads into someone standing just ahead keeps the plan's own pace
    monkeypatch.setattr(amp_humans, "STALL_CLEAR_M", 1.0)
    real = amp.planar

    def planar_one_ahead():
        p, h, v, w = real()
        p = p.copy()
        p[1] = pos[0] + 0.7 * goal_dir[0]  # the second body stands 0.7 m ahead of the first, on its plan
        return p, h, v, w

    monkeypatch.setattr(amp, "planar", planar_one_ahead)
    amp.still_s[:] = 2.0
    amp.plan_all()
    reach_clear = np.linalg.norm(amp.paths[0, 60] - pos[0])
    assert reach_clear < 0.55  # no warp: the plan's own 0.4 m
    monkeypatch.setattr(amp, "planar", real)
    env.close()


def test_slow_target_probe_writes_its_rows(tmp_path):
    probe = load_script("amp_slow_target_probe")
    out = tmp_path / "slow.json"
    assert probe.main(["--speeds", "1.0", "--bearings", "0", "--seconds", "3", "--json", str(out)]) == 0
    data = json.loads(out.read_text())
    (row,) = data["rows"]
    assert row["speed"] == 1.0 and row["target_m"] == 3.0 and not row["fell"]
    assert 1.0 < row["along_m"] < 4.0 and row["time_to_1m_s"] is not None  # it walks off with a 1 m/s target
    with pytest.raises(SystemExit, match="positive"):
        probe.main(["--speeds", "0", "--bearings", "0"])


def test_slow_target_probe_takes_the_replans_the_env_asks_for():
    # 12 m straight on at 1 m/s: the body passes its scene goal and the env asks for an event replan of that
    # person (plan_all(who)), which the probe's own plan_all once refused (TypeError)
    probe = load_script("amp_slow_target_probe")
    row = probe.probe(1.0, 0.0, seconds=12.0, seed=0)
    assert row["along_m"] > 8.0 and not row["fell"]


def test_stop_turn_go_probe_counts_from_the_set_off(tmp_path):
    probe = load_script("amp_slow_target_probe")
    out = tmp_path / "stg.json"
    assert probe.main(["--speeds", "1.0", "--bearings", "90", "--seconds", "3", "--lead-in", "1.5", "--pause", "1",
                       "--json", str(out)]) == 0
    (row,) = json.loads(out.read_text())["rows"]
    assert row["lead_in_s"] == 1.5 and row["pause_s"] == 1.0 and row["lead_speed"] == 1.0
    assert not row["fell"] and row["fell_at_s"] is None
    # 3 s after turning 90 degrees off the lead-in: it went some way sideways, no more than the target did
    assert 0.5 < row["along_m"] < 3.5 and row["heading_error_deg"] < 60
    with pytest.raises(SystemExit, match="lead-in"):
        probe.main(["--speeds", "1.0", "--bearings", "0", "--pause", "-1"])
    with pytest.raises(ValueError, match="lead"):
        probe.probe(1.0, 0.0, seconds=1.0, lead_in=1.0, lead_speed=0.0)


def test_slow_target_probe_pools_files_per_speed_and_bearing(tmp_path):
    probe = load_script("amp_slow_target_probe")

    def row(speed, bearing, along, t1, fell=False):
        return {"speed": speed, "bearing_deg": bearing, "along_m": along, "time_to_1m_s": t1, "fell": fell}

    a, b = tmp_path / "a.json", tmp_path / "b.json"
    a.write_text(json.dumps({"rows": [row(0.2, 0.0, 1.0, 5.0), row(0.2, 90.0, 0.2, None)]}))
    b.write_text(json.dumps({"rows": [row(0.2, 0.0, 2.0, 4.0), row(0.2, 90.0, 0.4, None, fell=True)]}))
    rows = probe.summary([str(a), str(b)])
    assert rows[0] == {"speed": 0.2, "bearing_deg": 0.0, "runs": 2, "mean_along_m": 1.5, "reached_1m": 2, "fell": 0}
    assert rows[1]["mean_along_m"] == pytest.approx(0.3) and rows[1]["reached_1m"] == 0 and rows[1]["fell"] == 1
    assert rows[2] == {"speed": 0.2, "bearing_deg": None, "runs": 4, "mean_along_m": 0.9, "reached_1m": 2, "fell": 1}
    with pytest.raises(SystemExit, match="--summary"):
        probe.main(["--summary", str(tmp_path / "missing.json")])


def test_diffusion_targets_follow_the_astar_path_near_narrow_doors(monkeypatch):
    """With ``DIFFUSION_DOOR_REACH`` (off by default) a person within that reach of a narrow door of its A* path gets a
    target rollout toward its next A* waypoint at its preferred speed instead of along its diffusion plan; beyond the
    reach, and with the option off, the plan's own pace stays."""
    from navzoo.envs.nav_env import NavEnv

    assert amp_humans.DIFFUSION_DOOR_REACH == 0.0
    env = NavEnv(scene="doorway", n_robots=0, n_humans=4, human_model="amp", crowd_model="diffusion", dt=1 / 30,
                 time_limit=10.0)
    env.reset(seed=0)
    amp, crowd = env.amp, env.diffusion
    h = np.flatnonzero(~env.is_robot)
    pos = amp.planar()[0]
    doors = [pts for pts, _ in amp.narrow_passages([env.paths[i] for i in h], env.radius[h], amp_humans.WALL_PLAN_MARGIN)]
    assert all(len(pts) for pts in doors)  # every path of the doorway passes its 1.0 m door
    door_m = np.array([np.linalg.norm(pts - p, axis=1).min() for pts, p in zip(doors, pos, strict=True)])
    # slow plans: 0.1 m/s straight away from each body's goal, for every replan of this test
    away = pos - env.goal[h]
    away /= np.linalg.norm(away, axis=1, keepdims=True)
    straight_plans(monkeypatch, crowd, pos, 0.1 * away)

    def rollout(reach: float) -> np.ndarray:
        monkeypatch.setattr(amp_humans, "DIFFUSION_DOOR_REACH", reach)
        amp.plan_all()
        return amp.paths.copy()

    off = rollout(0.0)
    everywhere = rollout(100.0)
    # off: every target keeps the plan's pace and direction (0.2 m in 2 s, away from the goal)
    step_off = off[:, 60] - pos
    assert (np.linalg.norm(step_off, axis=1) < 0.35).all() and ((step_off * away).sum(axis=1) > 0.1).all()
    # everywhere: toward the next A* waypoint at about the preferred speed (social force and door turns shape it)
    wp = np.stack([env.paths[i][min(int(env.wp_index[i]), len(env.paths[i]) - 1)] for i in h])
    to_wp = wp - pos
    to_wp /= np.linalg.norm(to_wp, axis=1, keepdims=True)
    first = everywhere[:, 6] - pos  # 0.2 s in
    moving = np.linalg.norm(first, axis=1) > 0.05
    assert moving.any()
    assert ((first[moving] * to_wp[moving]).sum(axis=1) / np.linalg.norm(first[moving], axis=1) > 0.7).all()
    assert np.linalg.norm(everywhere[:, 60] - pos, axis=1).max() > 0.8
    # a reach shorter than any person's distance to its door, along a rollout that creeps 0.5 m: the plans' targets
    assert door_m.min() > 1.0  # seed 0's people start at least a metre from the door
    np.testing.assert_array_equal(rollout(float(door_m.min()) - 0.6), off)
    assert np.abs(rollout(float(door_m.min()) + 0.1) - off).max() > 0.05  # the nearest person is within it
    env.close()
