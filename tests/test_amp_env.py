"""human_model="amp": physics pedestrians in NavEnv, frozen on the shipped policy, and their evaluation."""

from __future__ import annotations

import json
import subprocess
import sys

import numpy as np
import pytest
from pettingzoo.test import parallel_api_test

from navzoo.benchmark import pedestrians
from navzoo.envs.amp_humans import ACT_DIM, OBS_DIM
from navzoo.envs.config import NavConfig
from navzoo.envs.nav_env import NavEnv
from navzoo.envs.registry import make

DT = 1.0 / 30.0


def _raw(**kw):
    cfg = dict(scene="lobby", n_robots=1, n_humans=2, human_model="amp", dt=DT, max_episode_steps_override=30)
    cfg.update(kw)
    return NavEnv(**cfg)


def test_amp_config_needs_the_controller_rate():
    with pytest.raises(ValueError, match="multiple of 1/30"):
        NavConfig(human_model="amp", dt=0.1 + 1e-3)
    NavConfig(human_model="amp", dt=0.1)  # 3 control steps per env step: allowed
    with pytest.raises(ValueError, match="human_model"):
        NavConfig(human_model="ragdoll")
    with pytest.raises(ValueError, match="at least one agent"):
        NavConfig(n_robots=0, n_humans=0)


def test_amp_spaces_and_action_validation():
    env = _raw()
    obs, _ = env.reset(seed=0)
    assert env.action_space("human_0").shape == (ACT_DIM,)
    assert env.observation_space("human_0").shape == (OBS_DIM,)
    assert obs["human_0"].shape == (OBS_DIM,) and np.isfinite(obs["human_0"]).all()
    assert env.action_space("robot_0").shape == (2,)
    good = {"robot_0": np.zeros(2), "human_0": np.zeros(ACT_DIM), "human_1": np.zeros(ACT_DIM)}
    with pytest.raises(ValueError, match=r"human_0.*shape \(28,\)"):
        env.step({**good, "human_0": np.zeros(2)})
    bad = np.zeros(ACT_DIM)
    bad[3] = np.nan
    with pytest.raises(ValueError, match="NaN"):
        env.step({**good, "human_1": bad})
    env.step(good)  # nothing was lost by the rejected calls
    env.close()


def test_amp_parallel_api():
    env = _raw(max_episode_steps_override=12)
    parallel_api_test(env, num_cycles=12)
    env.close()


def test_frozen_amp_pedestrians_walk_their_paths():
    env = make("navzoo/Lobby-v0", human_model="amp", n_humans=3, max_episode_steps_override=120)
    raw = env.unwrapped
    assert raw.config.dt == pytest.approx(DT)
    env.reset(seed=3)
    start = raw.pos[raw.n_robots:].copy()
    errs = []
    for _ in range(90):  # 3 s
        env.step({"robot_0": np.zeros(2, np.float32)})
        errs.append(np.linalg.norm(raw.pos[raw.n_robots:] - raw.amp.target_now(), axis=1))
    moved = np.linalg.norm(raw.pos[raw.n_robots:] - start, axis=1)
    assert (moved > 1.5).all(), moved  # walking (about 1.2 m/s), not standing or drifting
    assert not raw.human_fallen.any()
    assert float(np.mean(errs)) < 0.4
    # The bodies stand upright (root near its standing height).
    z = raw.amp.state()["root_pos"][:, 2]
    assert (z > 0.7 * raw.amp.bodies.standing_height).all()
    env.close()


def test_pushed_pedestrian_falls_and_is_done():
    env = _raw(n_humans=2, max_episode_steps_override=200)
    env.reset(seed=1)
    env.amp.bodies.push([0], np.array([[0.0, 1500.0, 0.0]]), 0.3)
    zero = {"robot_0": np.zeros(2), "human_0": np.zeros(ACT_DIM), "human_1": np.zeros(ACT_DIM)}
    fell_at = None
    for k in range(60):
        _, _, term, _, info = env.step({a: zero[a] for a in env.agents})
        if "human_0" in term and term["human_0"]:
            assert info["human_0"]["fallen"]
            fell_at = k
            break
    assert fell_at is not None, "a 1500 N push for 0.3 s must knock the body over"
    assert "human_0" not in env.agents and "human_1" in env.agents
    env.close()


def test_fallen_body_is_stamped_where_it_comes_to_rest():
    from navzoo.envs.fallen import FALLEN_RESTAMP_M

    env = _raw(n_robots=0, n_humans=2, max_episode_steps_override=200, human_fallen_obstacles=True)
    env.reset(seed=1, options={"human_starts": [[6.0, 5.0], [3.0, 5.0]], "human_goals": [[6.0, 5.0], [10.0, 5.0]]})
    env.amp.bodies.push([0], np.array([[800.0, 0.0, 0.0]]), 0.3)
    zero = np.zeros(ACT_DIM)
    for _ in range(60):
        env.step({a: zero for a in env.agents})
        if env.human_fallen[0]:
            break
    first = env._fallen_stamped[0].copy()
    for _ in range(60):  # 2 s: the body slides on and comes to rest
        env.step({a: zero for a in env.agents})
    now = env._fallen_lying()[0]
    assert np.linalg.norm(now[0] - first[0]) > 2 * FALLEN_RESTAMP_M  # it moved on after it was found fallen...
    assert np.max(np.linalg.norm(now - env._fallen_stamped[0], axis=1)) <= FALLEN_RESTAMP_M  # ...and was stamped again
    assert not env._fallen_grid.is_free(now[:1])[0]
    assert env._fallen_grid.is_free(first[:1])[0] or np.linalg.norm(now - first[0], axis=1).min() < 0.3
    env.close()


def test_fall_log_tells_a_fallen_body_from_a_standing_person():
    import pybullet as p

    env = _raw(n_robots=0, n_humans=2, max_episode_steps_override=200)
    env.reset(seed=1, options={"human_starts": [[6.0, 5.0], [3.0, 5.0]], "human_goals": [[6.0, 5.0], [10.0, 5.0]]})
    log = pedestrians.FallLog(env)
    env.amp.bodies.push([0], np.array([[800.0, 0.0, 0.0]]), 0.3)
    zero = np.zeros(ACT_DIM)

    def step():
        env.step({a: zero for a in env.agents})
        log.update(env.human_map_contact, env.human_fallen)

    for _ in range(60):
        step()
        if env.human_fallen[0]:
            break
    assert env.human_fallen[0] and not env.human_fallen[1]
    (first,) = log.events
    # pushed over in the open, 3 m from the other person: nothing touched it
    assert first["id"] == 0 and first["fallen_m"] is None and first["person_m"] > 2.0
    assert pedestrians.fall_cause(first) == "none"
    assert first["speed_mps"] > 0.3 and first["target_speed_mps"] is None  # it was shoved before it fell; no targets given
    # the other person is put down on the fallen body: it touches a body that fell, not a standing person
    root = env.amp.state()["root_pos"][0]
    body = env.amp.ids[1]
    pos, orn = p.getBasePositionAndOrientation(body, physicsClientId=env.client)
    p.resetBasePositionAndOrientation(body, [root[0], root[1], pos[2]], orn, physicsClientId=env.client)
    for _ in range(60):
        step()
        if env.human_fallen[1]:
            break
    assert env.human_fallen[1]
    second = log.events[1]
    assert second["id"] == 1 and second["since_agent_s"] is None and second["fallen_m"] < 0.3
    assert pedestrians.fall_cause(second) == "fallen body"
    log.finish()
    assert first["slid_m"] > 0.4  # pushed hard: found fallen while it still slid on
    env.close()


def test_fall_log_keeps_the_motion_before_a_fall():
    from types import SimpleNamespace

    dt = 0.1
    env = SimpleNamespace(n_humans=2, n_robots=1, n_total=3, config=SimpleNamespace(dt=dt), sim_time=0.0,
                          amp=SimpleNamespace(ids=[5, 6], touched=[set(), set()]),
                          pos=np.zeros((3, 2)), vel=np.zeros((3, 2)), omega=np.zeros(3))
    log = pedestrians.FallLog(env)
    none = {"speed_mps": None, "turn_rad_s": None, "target_speed_mps": None, "lag_m": None}
    for k in range(40):
        env.sim_time = k * dt
        env.pos[1] = [1.0 * k * dt, 0.0]  # person 0 walks at 1 m/s ...
        env.vel[1] = [1.0, 0.0] if k < 30 else [0.0, 0.0]  # ... and stops for its last second
        env.pos[2] = [5.0, 5.0]  # person 1 turns on the spot
        env.vel[2] = [0.0, 0.2]
        env.omega[2] = -0.5
        target = np.array([[env.pos[1, 0] + 0.5, 0.0], [5.0, 6.0]])  # 0.5 m ahead of person 0; person 1's stays
        log.update(np.zeros(2, dtype=bool), np.zeros(2, dtype=bool), target)
        if k == 5:  # within 0.5 s of the start there is no window before
            assert log._motion_before(0) == none
    # the window is 2.0 to 0.5 s before now (steps 19-34): 11 steps at 1 m/s, 5 standing
    m0 = log._motion_before(0)
    assert m0["speed_mps"] == pytest.approx(11 / 16, abs=1e-3) and m0["turn_rad_s"] == 0.0
    assert m0["target_speed_mps"] == pytest.approx(1.0) and m0["lag_m"] == pytest.approx(0.5)
    m1 = log._motion_before(1)
    assert m1 == {"speed_mps": pytest.approx(0.2), "turn_rad_s": pytest.approx(0.5), "target_speed_mps": 0.0,
                  "lag_m": pytest.approx(1.0)}
    bare = pedestrians.FallLog(env)  # a run without target points
    for _ in range(20):
        bare.update(np.zeros(2, dtype=bool), np.zeros(2, dtype=bool))
    assert bare._motion_before(0)["target_speed_mps"] is None and bare._motion_before(0)["lag_m"] is None
    assert bare._motion_before(1)["speed_mps"] == pytest.approx(0.2)


def test_fall_cause_takes_the_last_touch_within_its_window():
    e = {"since_agent_s": 0.4, "since_map_s": 0.1, "since_fallen_s": None}
    assert pedestrians.fall_cause(e) == "wall"
    assert pedestrians.fall_cause({**e, "since_map_s": 3.0}) == "person"
    assert pedestrians.fall_cause({**e, "since_map_s": 3.0}, within=0.3) == "none"
    assert pedestrians.fall_cause({"since_agent_s": None, "since_map_s": None, "since_fallen_s": None}) == "none"


@pytest.mark.parametrize("obstacles", [True, False])
def test_others_plan_around_a_fallen_body_when_asked(obstacles):
    from navzoo.envs.fallen import path_passes

    env = _raw(n_robots=0, n_humans=2, max_episode_steps_override=200, human_fallen_obstacles=obstacles)
    # person 1 walks from x = 3 to x = 10 along y = 5, through where person 0 is pushed over
    env.reset(seed=1, options={"human_starts": [[6.0, 5.0], [3.0, 5.0]], "human_goals": [[6.0, 5.0], [10.0, 5.0]]})
    env.amp.bodies.push([0], np.array([[800.0, 0.0, 0.0]]), 0.3)
    before = env.paths[1].copy()
    zero = np.zeros(ACT_DIM)
    for _ in range(60):
        env.step({a: zero for a in env.agents})
        if env.human_fallen[0]:
            break
    assert env.human_fallen[0] and not env.human_fallen[1]
    if not obstacles:
        np.testing.assert_array_equal(env.paths[1], before)
        assert env._fallen_grid is None and env.pedestrian_grid is env.grid
    else:
        body = env._fallen_points
        assert len(body) and path_passes(before, env.pos[1], body, 0.55)  # the old path ran through it
        assert not path_passes(env.paths[1][env.wp_index[1]:], env.pos[1], body, 0.55)
        assert np.allclose(env.paths[1][-1], [10.0, 5.0])
        assert not env._fallen_grid.is_free(body[:1])[0] and env.grid.is_free(body[:1])[0]
        assert env.pedestrian_grid is env._fallen_grid
        # its target trajectory was rolled out again along the new path
        assert env.amp.plan_t.max() == env.amp.t
    env.close()


def test_pedestrian_contact_flags_are_reported_and_consistent():
    """Each pedestrian's info says whether it touched the map, any agent, and a robot; a robot contact is
    also an agent contact."""
    env = _raw(n_humans=2, max_episode_steps_override=200)
    env.reset(seed=1)
    zero = {"robot_0": np.zeros(2), "human_0": np.zeros(ACT_DIM), "human_1": np.zeros(ACT_DIM)}
    for _ in range(20):
        _, _, _, _, info = env.step({a: zero[a] for a in env.agents})
        for h in ("human_0", "human_1"):
            if h in info:
                i = info[h]
                assert {"map_contact", "agent_contact", "robot_contact"} <= set(i)
                assert not i["robot_contact"] or i["agent_contact"]
        if not env.agents:
            break
    env.close()


def test_amp_world_is_deterministic():
    def run():
        env = make("navzoo/Lobby-v0", human_model="amp", n_humans=2, max_episode_steps_override=40)
        env.reset(seed=7)
        for _ in range(20):
            env.step({"robot_0": np.array([0.5, 0.1], np.float32)})
        out = env.unwrapped.pos.copy()
        env.close()
        return out

    np.testing.assert_array_equal(run(), run())


def test_an_episode_depends_on_its_seed_alone_not_on_the_episodes_before_it():
    """reset rebuilds a stepped physics world (PyBullet's broadphase keeps its pair order over restoreState), so an
    episode run after another equals the same episode in a fresh env; the bodies keep their ids."""
    def episode(env, seed, steps=45):
        env.reset(seed=seed)
        for _ in range(steps):
            env.step({a: np.zeros(env.action_space(a).shape, np.float32) for a in env.agents})
        return env.unwrapped.pos.copy()

    kw = dict(scene="station", n_robots=1, n_humans=6, human_model="amp", max_episode_steps_override=60)
    fresh = episode(make(None, **kw), 2)
    reused = make(None, **kw)
    ids = (list(reused.unwrapped.amp.ids), list(reused.unwrapped.robots.ids), list(reused.unwrapped.bodies.body_ids))
    episode(reused, 1)
    np.testing.assert_array_equal(episode(reused, 2), fresh)
    assert ids == (list(reused.unwrapped.amp.ids), list(reused.unwrapped.robots.ids),
                   list(reused.unwrapped.bodies.body_ids))


def test_pedestrian_only_world_runs_to_the_time_limit():
    env = make(None, scene="lobby", n_robots=0, n_humans=2, human_model="amp", max_episode_steps_override=15)
    env.reset(seed=0)
    steps = 0
    while not env.unwrapped._needs_reset:
        env.step({})
        steps += 1
    assert steps == 15
    env.close()


def test_follow_scene_counts_trips_and_poses():
    row = pedestrians.follow_scene("lobby", 3, seconds=3.0, seed=0)
    assert row["err_n"] > 0 and 0.0 <= row["err_sum"] / row["err_n"] < 1.0
    assert row["poses"].shape[1] == 45 and len(row["poses"]) > 100
    assert row["fall"] + row["success"] + row["off_path"] + row["timeout"] + row["running"] >= 3
    assert pedestrians.people_per_scene(8) == [3, 5, 6, 8, 10, 12, 13, 15]


@pytest.mark.slow
def test_eval_pedestrians_cli_quick(tmp_path):
    out = tmp_path / "ped.json"
    r = subprocess.run([sys.executable, "-m", "navzoo.cli", "eval", "pedestrians", "--quick", "--json",
                        "--no-throughput", "--out", str(out)], capture_output=True, text=True, timeout=600)
    assert r.returncode == 0, r.stderr[-2000:]
    res = json.loads(out.read_text())
    assert set(res["tracking"]) >= {"mean_pos_error_m", "max_pos_error_m", "mean_rot_error_rad", "clip_success_rate"}
    assert set(res["following"]) >= {"success_rate", "fall_rate", "map_collision_rate", "agent_collision_rate",
                                     "path_error_m"}
    for model in ("amp", "kinematic"):
        assert set(res["realism"][model]) >= {"coverage_k50", "entropy_k50", "coverage_k100", "entropy_k100", "mmd"}
        assert 0.0 < res["realism"][model]["coverage_k50"] <= 1.0
    assert 0.0 <= res["following"]["success_rate"] <= 1.0
    assert not (tmp_path / "ped.json.following.jsonl").exists()  # the resume file goes once the result is written


def test_the_optional_progress_reward_pays_for_walking_toward_the_path_and_changes_nothing_else():
    from navzoo.agents.amp.checkpoint import load_policy
    from navzoo.agents.amp.pedestrian_policy import default_policy_dir

    act = load_policy(default_policy_dir())
    envs = [_raw(n_robots=0, n_humans=3, max_episode_steps_override=90),
            _raw(n_robots=0, n_humans=3, max_episode_steps_override=90, amp_progress_reward=0.5)]
    obs = [e.reset(seed=4)[0] for e in envs]
    progress = []
    for _ in range(60):
        acts = {h: np.clip(act(obs[0][h][None])[0], -1, 1) for h in obs[0]}
        (o0, r0, *_, i0), (o1, r1, *_, i1) = (e.step(acts) for e in envs)
        obs = [o0, o1]
        for h in r0:
            assert "reward/path_progress" not in i0[h]
            np.testing.assert_array_equal(o0[h], o1[h])  # the same world: only the reward differs
            assert r1[h] == pytest.approx(r0[h] + 0.5 * i1[h]["reward/path_progress"], abs=1e-6)
            assert -1.0 <= i1[h]["reward/path_progress"] <= 1.0
            progress.append(i1[h]["reward/path_progress"])
    assert np.mean(progress[-60:]) > 0.5  # walking along their paths near their preferred speed
    for e in envs:
        e.close()
    for bad in (-0.1, float("nan"), True):
        with pytest.raises(ValueError, match="amp_progress_reward"):
            NavConfig(human_model="amp", dt=DT, amp_progress_reward=bad)


def test_foot_split_is_the_right_foots_lead_along_the_heading():
    from navzoo.envs.amp_humans import foot_split

    key = np.zeros((2, 5, 3))
    key[:, 2, :2] = [0.3, 0.1]   # right foot
    key[:, 3, :2] = [-0.2, -0.1]  # left foot
    yaw = np.array([0.0, np.pi / 2])
    quat = np.stack([np.zeros(2), np.zeros(2), np.sin(yaw / 2), np.cos(yaw / 2)], axis=1)  # x, y, z, w
    split = foot_split({"root_quat": quat, "key_pos": key})
    np.testing.assert_allclose(split, [0.5, 0.2], atol=1e-9)  # facing +x: 0.5 ahead; facing +y: 0.2 ahead


def test_the_optional_stance_reward_charges_the_running_mean_of_the_feet_split_past_its_free_band_only():
    from navzoo.agents.amp.checkpoint import load_policy
    from navzoo.agents.amp.pedestrian_policy import default_policy_dir
    from navzoo.envs.amp_humans import STANCE_FREE_M, STANCE_TAU_S, foot_split

    act = load_policy(default_policy_dir())
    envs = [_raw(n_robots=0, n_humans=3, max_episode_steps_override=120),
            _raw(n_robots=0, n_humans=3, max_episode_steps_override=120, amp_stance_reward=0.7)]
    obs = [e.reset(seed=4)[0] for e in envs]
    np.testing.assert_array_equal(envs[1].amp.stance, 0.0)
    mean = np.zeros(3)
    for _ in range(90):
        acts = {h: np.clip(act(obs[0][h][None])[0], -1, 1) for h in obs[0]}
        (o0, r0, *_, i0), (o1, r1, *_, i1) = (e.step(acts) for e in envs)
        obs = [o0, o1]
        mean += (1.0 / (30 * STANCE_TAU_S)) * (foot_split(envs[1].amp.state()) - mean)
        for h in r0:
            np.testing.assert_array_equal(o0[h], o1[h])  # the same world: only the reward differs
            assert i0[h]["reward/stance"] == i1[h]["reward/stance"] <= 0.0  # logged whatever the weight
            assert r1[h] == pytest.approx(r0[h] + 0.7 * i1[h]["reward/stance"], abs=1e-6)
    np.testing.assert_allclose(envs[1].amp.stance, mean, atol=1e-9)
    last = [i1[h]["reward/stance"] for h in sorted(r1)]
    np.testing.assert_allclose(last, -np.maximum(0.0, np.abs(mean) - STANCE_FREE_M), atol=1e-9)
    # the shipped policy keeps its right foot ahead (docs/pedestrians_log.md, "Where the realism gap lies")
    assert envs[1].amp.stance.mean() > 0.15
    for e in envs:
        e.close()
    for bad in (-0.1, float("nan"), True, "1"):
        with pytest.raises(ValueError, match="amp_stance_reward"):
            NavConfig(human_model="amp", dt=DT, amp_stance_reward=bad)


def test_the_optional_wall_contact_reward_charges_each_step_a_body_touches_a_scene_obstacle():
    import pybullet as p

    envs = [_raw(n_robots=0, n_humans=1, max_episode_steps_override=60),
            _raw(n_robots=0, n_humans=1, max_episode_steps_override=60, amp_wall_contact_reward=2.0)]
    obs = [e.reset(seed=1)[0] for e in envs]
    (agent,) = obs[0]
    act = {agent: np.zeros(ACT_DIM, dtype=np.float32)}
    # a step in the open: no contact, nothing charged, and the term is logged whatever the weight
    (_, r0, *_, i0), (_, r1, *_, i1) = (e.step(act) for e in envs)
    assert i0[agent]["map_contact"] is i1[agent]["map_contact"] is False
    assert i0[agent]["reward/wall_contact"] == i1[agent]["reward/wall_contact"] == 0.0
    assert r1[agent] == pytest.approx(r0[agent], abs=1e-9)
    # the body put with its pelvis 5 cm inside the edge of a scene obstacle: touching it, charged 2 per step
    for e in envs:
        wall = next(b for b, kind in e._body_kind.items() if kind == "obstacle")
        lo, hi = p.getAABB(wall, physicsClientId=e.client)
        body = e.amp.ids[0]
        pos, orn = p.getBasePositionAndOrientation(body, physicsClientId=e.client)
        p.resetBasePositionAndOrientation(body, [lo[0] + 0.05, (lo[1] + hi[1]) / 2, pos[2]], orn,
                                          physicsClientId=e.client)
    (_, r0, *_, i0), (_, r1, *_, i1) = (e.step(act) for e in envs)
    assert i0[agent]["map_contact"] is i1[agent]["map_contact"] is True
    assert i0[agent]["reward/wall_contact"] == i1[agent]["reward/wall_contact"] == -1.0
    assert r1[agent] == pytest.approx(r0[agent] - 2.0, abs=1e-6)
    for e in envs:
        e.close()
    for bad in (-1.0, float("inf"), False, None):
        with pytest.raises(ValueError, match="amp_wall_contact_reward"):
            NavConfig(human_model="amp", dt=DT, amp_wall_contact_reward=bad)


def test_follow_scene_runs_on_one_torch_thread_and_gives_the_callers_back(monkeypatch):
    """One torch thread whoever calls it, so ``--workers 1`` and pool workers sum floats alike (a two-thread
    inline run walked other trips than the pool's single-thread runs of the same seed)."""
    from tests.amp_helpers import threads_seen

    seen, after = threads_seen(monkeypatch, pedestrians, "_make",
                               lambda: pedestrians.follow_scene("lobby", 2, seconds=0.5, seed=0, pose_every=0))
    assert seen == [1] and after == 2


def test_softer_walls_near_others_of_the_target_rollouts_are_config_fields():
    """``amp_wall_near_range`` / ``_strength`` / ``_ramp`` reach both social-force parameter sets of the target
    rollouts, and change the targets of people who meet in a narrow scene; bad values are refused by name."""
    from navzoo.envs import amp_humans

    kw = {"amp_wall_near_range": 1.5, "amp_wall_near_strength": 0.2, "amp_wall_near_ramp": 1.0}
    paths = {}
    for name, over in (("default", {}), ("near", kw)):
        env = _raw(n_robots=0, n_humans=8, scene="doorway", **over)
        env.reset(seed=1)
        want = (1.5, 0.2, 1.0) if over else (amp_humans.SFM_WALL_NEAR_RANGE, amp_humans.SFM_A_WALL_NEAR,
                                             amp_humans.SFM_WALL_NEAR_RAMP)
        for sfm in (env.amp.sfm, env.amp.sfm_keep):
            assert (sfm.wall_near_range, sfm.A_wall_near, sfm.wall_near_ramp) == want
        for _ in range(30):
            env.step({a: env.action_space(a).sample() * 0 for a in env.agents})
        paths[name] = env.amp.paths.copy()
        env.close()
    assert not np.allclose(paths["default"], paths["near"])
    for field, bad, says in (("amp_wall_near_range", -1.0, ">= 0"), ("amp_wall_near_ramp", float("nan"), ">= 0"),
                             ("amp_wall_near_strength", 0.0, "> 0"), ("amp_wall_near_range", True, ">= 0"),
                             ("amp_wall_near_strength", "0.3", "> 0")):
        with pytest.raises(ValueError, match=f"{field} must be None or a finite number {says}"):
            NavConfig(human_model="amp", dt=DT, **{field: bad})


def test_the_wall_margin_of_the_target_rollouts_is_a_config_field():
    """``amp_wall_margin`` sets the margin that walls see in the social-force target rollouts (None: the module's
    WALL_PLAN_MARGIN): a wider one keeps the targets further from the walls; bad values are refused by name."""
    from navzoo.envs import amp_humans

    clear = {}
    for margin in (None, 0.25):
        env = _raw(n_robots=0, n_humans=6, scene="grocery", amp_wall_margin=margin)
        env.reset(seed=1)
        assert env.amp.wall_margin == (amp_humans.WALL_PLAN_MARGIN if margin is None else 0.25)
        for _ in range(30):
            env.step({a: env.action_space(a).sample() * 0 for a in env.agents})
        clear[margin] = env.scene.clearance(env.amp.paths.reshape(-1, 2))
        env.close()
    assert np.quantile(clear[0.25], 0.02) > np.quantile(clear[None], 0.02)
    for bad in (-0.1, float("nan"), float("inf"), True, "0.2"):
        with pytest.raises(ValueError, match="amp_wall_margin must be None or a finite number >= 0"):
            NavConfig(human_model="amp", dt=DT, amp_wall_margin=bad)


def test_the_wall_strength_of_the_target_rollouts_is_a_config_field():
    """``amp_wall_strength`` sets A_wall of the social-force target rollouts (None: the module's SFM_A_WALL);
    softer walls let the targets pass nearer the walls."""
    from navzoo.envs import amp_humans

    clear = {}
    for wall in (None, 0.3):
        env = _raw(n_robots=0, n_humans=6, scene="doorway", amp_wall_strength=wall)
        env.reset(seed=1)
        assert env.amp.a_wall == (amp_humans.SFM_A_WALL if wall is None else 0.3)
        assert env.amp.sfm.A_wall == env.amp.a_wall
        paths = env.amp.paths.reshape(-1, 2)
        clear[wall] = env.scene.clearance(paths)
        env.close()
    assert not np.array_equal(clear[None], clear[0.3])
    assert np.quantile(clear[0.3], 0.05) < np.quantile(clear[None], 0.05)
    env = _raw(n_robots=0, n_humans=2, scene="doorway")  # the passing-only softness: None takes the module's
    assert (env.amp.sfm.wall_near_range, env.amp.sfm.A_wall_near, env.amp.sfm.wall_near_ramp) == (
        amp_humans.SFM_WALL_NEAR_RANGE, amp_humans.SFM_A_WALL_NEAR, amp_humans.SFM_WALL_NEAR_RAMP)
    env.close()
    for bad in (0, -0.3, float("nan"), float("inf"), True, "0.3"):
        with pytest.raises(ValueError, match="amp_wall_strength"):
            NavConfig(human_model="amp", dt=DT, amp_wall_strength=bad)


def test_softer_walls_for_a_rollout_that_the_walls_hold_still(monkeypatch):
    """SFM_WALL_STALL: in the cluttered room's 0.63 m gap between the pillar and a chair, the walls' push on both sides
    balances the plan's pull and the target rollout of a person alone stands; with softer walls for whom the walls
    hold still it walks on through the gap. A rollout that nothing holds (the home's hall) is the same either way."""
    from navzoo.envs import amp_humans

    def rollout(scene, start, goal, on):
        monkeypatch.setattr(amp_humans, "SFM_WALL_STALL", on)
        env = _raw(scene=scene, n_robots=0, n_humans=1, crowd_model="sfm")
        env.reset(seed=0, options={"human_starts": [start], "human_goals": [goal]})
        path = env.amp.paths[0].copy()
        env.close()
        return path

    held = rollout("cluttered_room", [5.68, 3.88], [3.04, 4.33], False)
    freed = rollout("cluttered_room", [5.68, 3.88], [3.04, 4.33], True)
    assert np.linalg.norm(held[-1] - held[0]) < 0.3
    assert np.linalg.norm(freed[-1] - freed[0]) > 1.5
    np.testing.assert_array_equal(rollout("home", [7.3, 2.6], [11.65, 2.59], False),
                                  rollout("home", [7.3, 2.6], [11.65, 2.59], True))


@pytest.mark.parametrize("wait", [True, False])
def test_a_person_whom_fallen_bodies_cut_off_waits_when_asked(wait):
    """human_fallen_wait: a body across the doorway's only door leaves person 1 no way round; it stands (its target
    trajectory stays where it is) instead of walking on into the body, walks on once the door is free again, and
    a new goal it cannot reach is drawn again. (Without ``human_fallen_redraw``, the default since 2026-12-08, whose
    own test is below: here a person who does not wait walks a straight line at a goal no path reaches.)"""
    env = _raw(scene="doorway", n_robots=0, n_humans=2, max_episode_steps_override=200, human_fallen_wait=wait,
               human_fallen_redraw=False)
    env.reset(seed=1, options={"human_starts": [[2.0, 7.0], [5.0, 4.0]], "human_goals": [[2.0, 7.0], [13.0, 4.0]]})
    before = env.paths[1].copy()
    across = {0: np.array([[8.0, 4.0], [8.0, 3.2], [8.0, 4.8], [8.3, 3.5], [7.7, 4.5], [8.1, 4.0]])}  # root, key bodies
    env._fallen_lying = lambda: across
    env.human_fallen[0] = env.amp.fallen[0] = True
    changed = env._avoid_fallen()
    assert not env._fallen_grid.is_free(np.array([[8.0, 4.0]]))[0]
    np.testing.assert_array_equal(env.paths[1], before)  # no way round: the old path is kept either way
    assert changed[1] == wait and env.human_waiting_fallen[1] == wait and not env.human_waiting_fallen[0]
    env.amp.plan_all()
    reach = np.linalg.norm(env.amp.paths[1] - env.pos[1], axis=1).max()  # how far its target trajectory goes
    assert (reach < 0.3) if wait else (reach > 1.0)
    # the door is free again (the body was pushed on): the waiting person plans round and walks on
    env._fallen_lying = lambda: {0: across[0] + np.array([2.5, 2.5])}
    changed = env._avoid_fallen()
    assert not env.human_waiting_fallen.any()
    assert changed[1] == wait  # the person who walked on kept its path: nothing to change
    # the door is blocked again and person 1 reaches a goal: it gets a new goal it can reach, or (none in
    # FALLEN_GOAL_TRIES draws: the doorway draws goals across the door) it waits
    env._fallen_lying = lambda: across
    env._avoid_fallen()
    assert env.human_waiting_fallen[1] == wait
    env.d_goal[env.n_robots + 1] = 0.0
    env._retarget_humans()
    reachable = env._plan(env.n_robots + 1, env.pos[1], env.goal[1], fallback=False) is not None
    assert env.human_waiting_fallen[1] == (wait and not reachable)
    if not reachable:  # the old behaviour where no path leads to the goal: a straight line to it
        np.testing.assert_array_equal(env.paths[1], env.goal[1][None])
    env.close()


def test_a_person_cut_off_from_every_new_goal_draws_fallen_goal_tries_goals_and_keeps_the_last():
    """human_fallen_wait: with no reachable goal, ``_retarget_humans`` draws FALLEN_GOAL_TRIES goals in all (the
    first one and one after each failed try but the last), and the person waits with the last goal it tried."""
    from navzoo.envs.fallen import FALLEN_GOAL_TRIES

    env = _raw(scene="doorway", n_robots=0, n_humans=2, max_episode_steps_override=200, human_fallen_wait=True)
    env.reset(seed=1, options={"human_starts": [[2.0, 7.0], [5.0, 4.0]], "human_goals": [[2.0, 7.0], [13.0, 4.0]]})
    env._fallen_lying = lambda: {0: np.array([[8.0, 4.0], [8.0, 3.2], [8.0, 4.8], [8.3, 3.5], [7.7, 4.5], [8.1, 4.0]])}
    env.human_fallen[0] = env.amp.fallen[0] = True
    env._avoid_fallen()
    sampler = env._samplers["human"]
    drawn = []

    def beyond_the_door(rng, pos, kind, min_goal_dist=0.0):  # every goal across the blocked door, each a new one
        drawn.append(np.array([13.0, 3.5 + 0.1 * len(drawn)]))
        return drawn[-1]

    sampler.sample_goal = beyond_the_door
    env.d_goal[env.n_robots] = 10.0  # the fallen person 0 (which stands at its goal) is not retargeted here
    env.d_goal[env.n_robots + 1] = 0.0
    env._retarget_humans()
    assert len(drawn) == FALLEN_GOAL_TRIES
    assert env.human_waiting_fallen[1]
    np.testing.assert_array_equal(env.goal[env.n_robots + 1], drawn[-1])
    env.close()


@pytest.mark.parametrize("redraw", [False, True])
def test_a_new_goal_cut_off_by_fallen_bodies_is_drawn_again_or_walked_on_the_scene_path(redraw):
    """human_fallen_redraw: a body across the doorway's only door; person 1 reaches its goal in the left room.
    Every goal across the door: off, it walks a straight line at the goal (into the wall); on, FALLEN_GOAL_TRIES
    goals are drawn and the last is walked on the bare scene's A* path (through the door, on into the body), and
    it does not wait. A goal on its own side among the draws: on, that goal is kept, with a path round the body."""
    from navzoo.envs.fallen import FALLEN_GOAL_TRIES

    env = _raw(scene="doorway", n_robots=0, n_humans=2, max_episode_steps_override=200, human_fallen_redraw=redraw)
    env.reset(seed=1, options={"human_starts": [[2.0, 7.0], [5.0, 4.0]], "human_goals": [[2.0, 7.0], [13.0, 4.0]]})
    body = np.array([[8.0, 4.0], [8.0, 3.2], [8.0, 4.8], [8.3, 3.5], [7.7, 4.5], [8.1, 4.0]])
    env._fallen_lying = lambda: {0: body}
    env.human_fallen[0] = env.amp.fallen[0] = True
    env._avoid_fallen()
    sampler, i = env._samplers["human"], env.n_robots + 1
    drawn = []

    def draw(goals):
        def sample_goal(rng, pos, kind, min_goal_dist=0.0):
            drawn.append(np.array(goals[min(len(drawn), len(goals) - 1)], dtype=float))
            return drawn[-1]
        return sample_goal

    sampler.sample_goal = draw([[13.0, 3.5]])  # across the blocked door, every time
    env.d_goal[env.n_robots] = 10.0
    env.d_goal[i] = 0.0
    env._retarget_humans()
    assert not env.human_waiting_fallen[1]
    np.testing.assert_array_equal(env.goal[i], [13.0, 3.5])
    if not redraw:
        assert len(drawn) == 1
        np.testing.assert_array_equal(env.paths[i], [[13.0, 3.5]])
    else:
        assert len(drawn) == FALLEN_GOAL_TRIES
        path = env.paths[i]
        assert len(path) > 2 and env.grid.is_free(path).all()  # the scene's way, through the door
        assert np.abs(path[:, 0] - 8.0).min() < 0.5 and np.abs(path[:, 1] - 4.0)[np.abs(path[:, 0] - 8.0) < 0.5].max() < 0.6
    # a goal on its own side of the door after one across it
    drawn.clear()
    sampler.sample_goal = draw([[13.0, 3.5], [2.0, 2.0]])
    env.d_goal[i] = 0.0
    env._retarget_humans()
    if redraw:
        assert len(drawn) == 2
        np.testing.assert_array_equal(env.goal[i], [2.0, 2.0])
        assert env._fallen_grid.is_free(env.paths[i]).all()
    else:
        assert len(drawn) == 1
        np.testing.assert_array_equal(env.paths[i], [[13.0, 3.5]])
    env.close()


def test_human_fallen_redraw_must_be_a_bool():
    with pytest.raises(ValueError, match="human_fallen_redraw"):
        NavConfig(human_fallen_redraw="yes")


def test_human_fallen_redraw_is_on_by_default_with_fallen_obstacles():
    """The default since 2026-12-08 (the Intel device's rows, docs/crowd_log.md "Goals cut off by a fallen body")."""
    config = NavConfig()
    assert config.human_fallen_redraw is True and config.human_fallen_obstacles is True
