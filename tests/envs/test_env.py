"""Behaviour of NavEnv: determinism, validation, collisions, goals, rewards, wrappers, rendering."""

from __future__ import annotations

import hashlib
import multiprocessing as mp
import os

import numpy as np
import pytest

import navzoo
from navzoo.agents.baselines import OrcaRobotPolicy
from navzoo.envs.config import NavConfig
from navzoo.envs.nav_env import NavEnv, _segment_origin_distance
from navzoo.envs.rewards import RewardParams, navigation_reward


def _rollout_digest(env_id: str, seed: int, steps: int, **kw) -> str:
    env = navzoo.make(env_id, raw=True, **kw)
    h = hashlib.sha256()
    obs, _ = env.reset(seed=seed)
    rng = np.random.default_rng(seed)
    for _ in range(steps):
        if not env.agents:
            break
        acts = {a: rng.uniform(-1, 1, 2).astype(np.float32) for a in env.agents}
        obs, rew, term, trunc, info = env.step(acts)
        for a in sorted(obs):
            for k in sorted(obs[a]):
                h.update(np.ascontiguousarray(obs[a][k]).tobytes())
            h.update(np.float64(rew[a]).tobytes())
            h.update(bytes([term[a], trunc[a]]))
        h.update(env.pos.tobytes())
    env.close()
    return h.hexdigest()


def _digest_worker(args):
    return _rollout_digest(*args[:3], **args[3])


def test_multistep_determinism_same_process_and_reset():
    kw = dict(n_robots=2, n_humans=5)
    a = _rollout_digest("navzoo/Lobby-v0", 7, 80, **kw)
    b = _rollout_digest("navzoo/Lobby-v0", 7, 80, **kw)
    c = _rollout_digest("navzoo/Lobby-v0", 8, 80, **kw)
    assert a == b
    assert a != c


def test_reset_same_seed_twice_in_one_env_is_identical():
    env = navzoo.make("navzoo/Home-v0", n_humans=3)
    out = []
    for _ in range(2):
        obs, _ = env.reset(seed=11)
        traj = [obs["robot_0"]["goal"].copy()]
        for _ in range(30):
            if not env.agents:
                break
            obs, *_ = env.step({"robot_0": np.array([0.8, 0.3], np.float32)})
            if "robot_0" in obs:
                traj.append(obs["robot_0"]["agents"].copy())
        out.append(traj)
    assert len(out[0]) == len(out[1])
    for x, y in zip(*out, strict=True):
        np.testing.assert_array_equal(x, y)
    env.close()


def test_determinism_across_processes():
    args = ("navzoo/Corridor-v0", 5, 60, dict(n_humans=6))
    ctx = mp.get_context("spawn")
    with ctx.Pool(1) as pool:
        other = pool.map(_digest_worker, [args])[0]
    assert other == _rollout_digest(*args[:3], **args[3])


def test_step_before_reset_raises():
    env = navzoo.make("navzoo/CircleCrossing-v0")
    with pytest.raises(RuntimeError, match="before reset"):
        env.step({"robot_0": np.zeros(2)})
    env.close()


@pytest.mark.parametrize(
    "action, match",
    [
        ({"robot_0": np.array([np.nan, 0.0])}, "NaN"),
        ({"robot_0": np.array([np.inf, 0.0])}, "NaN or inf"),
        ({"robot_0": np.zeros(3)}, "shape"),
        ({"robot_0": np.zeros(2), "robot_9": np.zeros(2)}, "unknown agent 'robot_9'"),
        ({}, "missing actions"),
        ({"robot_0": "fast"}, "not numeric"),
    ],
)
def test_bad_actions_rejected_with_agent_named(action, match):
    env = navzoo.make("navzoo/CircleCrossing-v0", raw=True, n_humans=0)
    env.reset(seed=0)
    with pytest.raises(ValueError, match=match):
        env.step(action)
    env.close()


def test_out_of_range_actions_clipped_and_counted():
    env = navzoo.make("navzoo/CircleCrossing-v0", raw=True, n_humans=0)
    env.reset(seed=0)
    _, _, _, _, info = env.step({"robot_0": np.array([5.0, 0.0])})
    assert info["robot_0"]["action_clipped"] == 1
    _, _, _, _, info = env.step({"robot_0": np.array([0.5, 0.0])})
    assert info["robot_0"]["action_clipped"] == 1
    env.close()


def test_frozen_agents_hide_and_drive_pedestrians():
    env = navzoo.make("navzoo/Corridor-v0", n_humans=4)
    obs, infos = env.reset(seed=1)
    assert list(obs) == ["robot_0"] and env.agents == ["robot_0"]
    nav = env.unwrapped
    start = nav.pos[1:].copy()
    with pytest.raises(ValueError, match="frozen"):
        env.step({"robot_0": np.zeros(2), "human_0": np.zeros(2)})
    for _ in range(20):
        env.step({"robot_0": np.zeros(2, np.float32)})
    moved = np.linalg.norm(nav.pos[1:] - start, axis=1)
    assert (moved > 0.5).all() and moved.mean() > 1.0, moved
    env.close()


@pytest.mark.parametrize("crowd", ["sfm", "orca"])
def test_crowd_makes_progress_to_goals(crowd):
    env = navzoo.make("navzoo/Lobby-v0", n_humans=8, crowd_model=crowd, max_episode_steps_override=400)
    env.reset(seed=2)
    nav = env.unwrapped
    for _ in range(300):
        if not env.agents:
            break
        env.step({"robot_0": np.zeros(2, np.float32)})
    # Pedestrians reach goals and get new ones.
    assert nav.goals_reached[1:].sum() >= 4
    env.close()


def test_robot_collides_with_person_and_obstacle_and_reaches_goal():
    env = NavEnv(NavConfig(scene="corridor", n_humans=1))
    # Person standing still straight ahead.
    obs, _ = env.reset(seed=0, options={
        "robot_starts": [[4.0, 1.7]], "robot_goals": [[12.0, 1.7]], "robot_yaws": [0.0],
        "human_starts": [[6.5, 1.7]], "human_goals": [[6.5, 1.7]],
    })
    ev = None
    for _ in range(60):
        obs, rew, term, trunc, info = env.step({"robot_0": np.array([1.0, 0.0]), "human_0": np.zeros(2)})
        if term.get("robot_0"):
            ev = info["robot_0"]
            break
    assert ev is not None and ev["event"] == "collision_human"
    assert ev["reward/collision"] == -20.0 and rew["robot_0"] <= -20.0
    assert "robot_0" not in env.agents

    # Into the corridor's north wall (its face is at y = 3.2 m).
    env.reset(seed=0, options={
        "robot_starts": [[10.0, 1.7]], "robot_goals": [[16.0, 1.7]], "robot_yaws": [np.pi / 2],
        "human_starts": [[3.0, 1.0]], "human_goals": [[3.0, 1.0]],
    })
    ev = None
    for _ in range(60):
        obs, rew, term, trunc, info = env.step({"robot_0": np.array([1.0, 0.0]), "human_0": np.zeros(2)})
        if term.get("robot_0"):
            ev = info["robot_0"]
            break
    assert ev is not None and ev["event"] == "collision_obstacle"

    # Drive straight to a goal 2 m ahead.
    env.reset(seed=0, options={
        "robot_starts": [[8.0, 1.7]], "robot_goals": [[10.0, 1.7]], "robot_yaws": [0.0],
        "human_starts": [[3.0, 1.0]], "human_goals": [[3.0, 1.0]],
    })
    total = 0.0
    for _ in range(60):
        obs, rew, term, trunc, info = env.step({"robot_0": np.array([1.0, 0.0]), "human_0": np.zeros(2)})
        total += rew["robot_0"]
        if term.get("robot_0"):
            ev = info["robot_0"]
            break
    assert ev["event"] == "goal" and ev["is_success"] and ev["reward/goal"] == 20.0
    assert total > 20.0  # goal bonus plus progress 3.2 per metre
    env.close()


def test_time_limit_truncates_everyone():
    env = navzoo.make("navzoo/CircleCrossing-v0", raw=True, n_humans=2, time_limit=1.0)
    env.reset(seed=0)
    steps = 0
    while env.agents:
        obs, rew, term, trunc, info = env.step({a: np.zeros(2) for a in env.agents})
        steps += 1
    assert steps == 4  # 1 s at dt = 0.25 s
    assert all(trunc.values()) and not any(term.values())
    assert info["robot_0"]["event"] == "timeout"
    env.close()


def test_swept_test_catches_tunnelling():
    # Relative motion passes straight through the origin although both end points are far.
    p0 = np.array([[-2.0, 0.05]])
    p1 = np.array([[2.0, 0.05]])
    assert _segment_origin_distance(p0, p1)[0] == pytest.approx(0.05)
    assert _segment_origin_distance(np.array([[1.0, 1.0]]), np.array([[2.0, 2.0]]))[0] == pytest.approx(np.sqrt(2))


def test_reward_terms_match_paper():
    p = RewardParams()
    tot, terms = navigation_reward(
        d_goal=np.array([0.1, 5.0, 5.0, 5.0]), d_goal_prev=np.array([0.3, 5.5, 5.5, 5.5]),
        d_obs=np.array([2.0, -0.1, 0.5, 2.0]), reached=np.array([True, False, False, False]),
        collided=np.array([False, True, False, False]), omega=np.array([0.5, 0.0, 1.5, -2.0]), params=p,
    )
    np.testing.assert_allclose(terms["goal"], [20, 0, 0, 0])
    np.testing.assert_allclose(terms["collision"], [0, -20, 0, 0])
    np.testing.assert_allclose(terms["proximity"], [0, 0, 0.5 * (0.5 - 0.9), 0])
    np.testing.assert_allclose(terms["progress"], [0, 0, 0, 3.2 * 0.5])
    np.testing.assert_allclose(terms["turn"], [0, 0, -0.15, -0.2])
    np.testing.assert_allclose(tot, [20, -20, -0.2 - 0.15, 1.6 - 0.2])


def test_collision_reward_and_proximity_scale_are_configurable():
    env = NavEnv(NavConfig(scene="corridor", n_humans=1, collision_reward=-50.0, proximity_scale=2.0))
    env.reset(seed=0, options={
        "robot_starts": [[4.0, 1.7]], "robot_goals": [[12.0, 1.7]], "robot_yaws": [0.0],
        "human_starts": [[6.5, 1.7]], "human_goals": [[6.5, 1.7]],
    })
    infos = []
    for _ in range(60):
        _, rew, term, _, info = env.step({"robot_0": np.array([1.0, 0.0]), "human_0": np.zeros(2)})
        infos.append(info["robot_0"])
        if term.get("robot_0"):
            break
    assert infos[-1]["event"] == "collision_human" and infos[-1]["reward/collision"] == -50.0
    near = [i["reward/proximity"] for i in infos[:-1] if i["reward/proximity"] < 0]
    assert near and min(near) < -0.5  # within 0.9 m at slope 2 (the paper's 0.5 stays above -0.45)
    env.close()
    for field, value in (("collision_reward", 5.0), ("collision_reward", float("nan")), ("proximity_scale", -1.0),
                         ("proximity_scale", True)):
        with pytest.raises(ValueError, match=f"NavConfig.{field} must be a finite number"):
            NavConfig(**{field: value})


def test_config_validation_messages():
    with pytest.raises(ValueError, match="unknown NavConfig key.*'n_humanz'"):
        NavConfig.from_dict({"n_humanz": 3})
    with pytest.raises(ValueError, match="n_robots must be an integer >= 0"):
        NavConfig(n_robots=-1)
    with pytest.raises(ValueError, match="dt must be a finite number > 0"):
        NavConfig(dt=float("nan"))
    with pytest.raises(ValueError, match="human_speed"):
        NavConfig(human_speed=(1.5, 1.0))
    with pytest.raises(ValueError, match="unknown RobotSpec key"):
        NavConfig.from_dict({"robot": {"radus": 0.2}})
    with pytest.raises(ValueError, match="unknown navzoo env id"):
        navzoo.make("navzoo/Nope-v0")
    with pytest.raises(ValueError, match="scene file"):
        navzoo.make(scene="does/not/exist.yaml")
    with pytest.warns(UserWarning, match="unknown reset option.*robot_start"):
        navzoo.make("navzoo/Doorway-v0", n_humans=1).reset(seed=0, options={"robot_start": [0, 0]})
    with pytest.raises(ValueError, match="robot_starts.*shape"):
        navzoo.make("navzoo/Doorway-v0", n_humans=1).reset(
            seed=0, options={"robot_starts": [0, 0], "robot_goals": [[1, 1]]})


def test_bad_scene_file_rejected(tmp_path):
    from navzoo.world.scene import SceneError

    bad = tmp_path / "bad.yaml"
    bad.write_text("name: bad\nbounds: [0, 0, 5]\n")
    with pytest.raises(SceneError, match="bounds"):
        navzoo.make(scene=str(bad))


def test_multi_robot_episode_with_orca_baseline():
    env = navzoo.make("navzoo/Lobby-v0", n_robots=3, n_humans=5)
    obs, _ = env.reset(seed=4)
    pol = OrcaRobotPolicy()
    events = {}
    while env.agents:
        obs, rew, term, trunc, info = env.step(pol.act(obs, env.unwrapped))
        for a in info:
            if term[a] or trunc[a]:
                events[a] = info[a]["event"]
    assert set(events) == {"robot_0", "robot_1", "robot_2"}
    assert sum(e == "goal" for e in events.values()) >= 1
    env.close()


def test_render_rgb_array_and_human_without_display(monkeypatch):
    env = navzoo.make("navzoo/Station-v0", render_mode="rgb_array", render_view="both", n_humans=4)
    env.reset(seed=0)
    img = env.render()
    assert img.ndim == 3 and img.shape[2] == 3 and img.dtype == np.uint8
    assert img.std() > 5  # something is drawn
    env.close()
    monkeypatch.delenv("DISPLAY", raising=False)
    with pytest.raises(RuntimeError, match="display"):
        navzoo.make("navzoo/Station-v0", render_mode="human", n_humans=1)


def test_nan_physics_state_ends_episode(monkeypatch):
    env = navzoo.make("navzoo/CircleCrossing-v0", raw=True, n_humans=1)
    env.reset(seed=0)
    real = env.robots.read_state

    def broken():
        pos, yaw, tilt = real()
        pos[0, 0] = np.nan
        return pos, yaw, tilt

    monkeypatch.setattr(env.robots, "read_state", broken)
    obs, rew, term, trunc, info = env.step({a: np.zeros(2) for a in env.agents})
    assert term["robot_0"] and info["robot_0"]["nan_state"]
    assert not env.agents
    assert all(np.isfinite(v).all() for o in obs.values() for v in o.values())
    env.close()


def _ppo_params_after(total_steps: int, **vec_kw):
    import torch
    from stable_baselines3 import PPO
    from stable_baselines3.common.vec_env import VecCheckNan

    from navzoo.envs.vector import sb3_vec_env

    vec = VecCheckNan(sb3_vec_env("navzoo/CircleCrossing-v0", n_humans=3, **vec_kw), raise_exception=True)
    model = PPO("MlpPolicy", vec, n_steps=64, batch_size=64, n_epochs=1, seed=0, device="cpu", verbose=0)
    model.learn(total_timesteps=total_steps)
    assert model.num_timesteps >= total_steps
    vec.close()
    return torch.nn.utils.parameters_to_vector(model.policy.parameters()).detach().clone()


def test_sb3_ppo_smoke_through_supersuit_is_deterministic():
    a = _ppo_params_after(256, n_envs=2, seed=0)
    b = _ppo_params_after(256, n_envs=2, seed=0)
    assert (a == b).all()


def test_sb3_vec_env_with_several_robots_pads_finished_ones():
    from navzoo.envs.vector import sb3_vec_env

    vec = sb3_vec_env("navzoo/Lobby-v0", n_envs=2, seed=3, n_robots=2, n_humans=2, max_episode_steps_override=30)
    assert vec.num_envs == 4
    obs = vec.reset()
    assert obs.shape[0] == 4
    import numpy as np

    for _ in range(40):  # crosses episode ends (robots finishing at different times)
        obs, rew, done, info = vec.step(np.zeros((4, 2), np.float32))
        assert np.isfinite(obs).all() and np.isfinite(rew).all()
    vec.close()


@pytest.mark.skipif(os.environ.get("DISPLAY") is not None, reason="display available")
def test_nothing_printed_by_pybullet_on_make(capfd):
    env = navzoo.make("navzoo/Lobby-v0", n_humans=2)
    env.close()
    out, _ = capfd.readouterr()
    assert "b3Warning" not in out and "urdfdom" not in out


def test_pickled_env_is_an_independent_fresh_copy():
    import pickle

    env = navzoo.make("navzoo/Corridor-v0", n_humans=2)
    env.reset(seed=0)
    copy = pickle.loads(pickle.dumps(env))
    del copy  # closing the copy must not close the original's PyBullet client
    import gc

    gc.collect()
    obs, *_ = env.step({"robot_0": np.zeros(2, np.float32)})
    assert "robot_0" in obs
    copy = pickle.loads(pickle.dumps(env))
    with pytest.raises(RuntimeError, match="before reset"):
        copy.step({"robot_0": np.zeros(2, np.float32)})
    env.close()
    copy.close()


def test_humans_stop_at_goal_when_configured():
    env = navzoo.make("navzoo/CircleCrossing-v0", raw=True, n_humans=1, time_limit=20.0)
    assert env.config.human_at_goal == "stop"
    env.reset(seed=0, options={"robot_starts": [[-6.0, -6.0]], "robot_goals": [[-6.0, 6.0]],
                               "human_starts": [[0.0, 0.0]], "human_goals": [[1.0, 0.0]]})
    goal_rewards = 0
    for _ in range(30):
        if not env.agents:
            break
        obs, rew, term, trunc, info = env.step({"robot_0": np.zeros(2), "human_0": np.array([0.25, 0.0])})
        goal_rewards += info["human_0"]["reward/goal"] > 0
    assert goal_rewards == 1  # reached once, counted once
    np.testing.assert_allclose(env.goal[1], [1.0, 0.0])  # no new goal
    env.close()
