"""navzoo as an RLlib MultiAgentEnv: spaces, agents that leave early, ``__all__``, frozen sides."""

from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip("ray.rllib")

from navzoo.rl.config import JointConfig  # noqa: E402
from navzoo.rl.rllib_env import ENV_NAME, NavzooMultiAgentEnv, env_creator, register  # noqa: E402

# Corridor: robot_0 is 2 m from its goal and drives to it; robot_1 stands still far from its goal.
CORRIDOR = {
    "robot_starts": [[8.0, 1.7], [4.0, 0.8]], "robot_goals": [[10.0, 1.7], [14.0, 0.8]], "robot_yaws": [0.0, 0.0],
    "human_starts": [[3.0, 2.6]], "human_goals": [[3.0, 2.6]],
}


def _drive(env, obs, go=("robot_0",)):
    # Actions for the agents that got an observation; one that just finished is ignored by the adapter.
    return {a: np.array([1.0, 0.0], np.float32) if a in go else np.zeros(2, np.float32) for a in obs}


def test_reset_and_step_follow_the_multi_agent_api():
    from ray.rllib.utils.pre_checks.env import check_multiagent_environments

    env = NavzooMultiAgentEnv({"n_humans": 2})
    check_multiagent_environments(env)
    assert env.possible_agents == ["robot_0", "human_0", "human_1"]
    obs, infos = env.reset(seed=0)
    assert set(obs) == set(infos) == set(env.possible_agents) == set(env.agents)
    for a, o in obs.items():
        space = env.observation_spaces[a]
        assert o.shape == space.shape and o.dtype == np.float32 and len(space.shape) == 1  # flat
        assert env.action_spaces[a].shape == (2,)
        assert env.get_observation_space(a) == space
    obs, rew, term, trunc, infos = env.step({a: env.action_spaces[a].sample() for a in obs})
    assert set(obs) == set(rew) == set(infos) == set(env.possible_agents)
    assert set(term) == set(trunc) == set(env.possible_agents) | {"__all__"}
    assert term["__all__"] is False and trunc["__all__"] is False
    assert all(isinstance(r, float) for r in rew.values())
    env.close()


def test_agent_that_finishes_leaves_and_the_episode_ends_with_all_flags():
    env = NavzooMultiAgentEnv({"env_id": "navzoo/Corridor-v0", "n_robots": 2, "n_humans": 1, "env": {"time_limit": 6.0}})
    obs, _ = env.reset(seed=0, options=CORRIDOR)
    left_at = None
    steps = 0
    while True:
        obs, rew, term, trunc, infos = env.step(_drive(env, obs))
        steps += 1
        if left_at is None and term.get("robot_0"):
            left_at = steps
            assert infos["robot_0"]["event"] == "goal" and rew["robot_0"] >= 20
            assert term["__all__"] is False and trunc["__all__"] is False  # the others go on
        elif left_at is not None:
            assert "robot_0" not in obs and "robot_0" not in rew and "robot_0" not in term
        if term["__all__"] or trunc["__all__"]:
            break
    assert left_at is not None and left_at < steps == 60
    # The time limit cut off robot_1 and the pedestrian: a truncation of the whole episode.
    assert trunc == {"robot_1": True, "human_0": True, "__all__": True}
    assert term == {"robot_1": False, "human_0": False, "__all__": False}
    assert env.agents == []
    assert env.episode_summary["robot_success"] == 0.5 and env.episode_summary["robot_timeout"] == 0.5


def test_last_robot_at_goal_ends_the_episode_for_the_pedestrians_too():
    # RLlib's ParallelPettingZooEnv misses this ending (terminated robot + truncated pedestrians).
    env = NavzooMultiAgentEnv({"env_id": "navzoo/Corridor-v0", "n_robots": 1, "n_humans": 1})
    opts = {k: v[:1] for k, v in CORRIDOR.items()}
    obs, _ = env.reset(seed=0, options=opts)
    while True:
        obs, rew, term, trunc, infos = env.step(_drive(env, obs))
        if term["__all__"] or trunc["__all__"]:
            break
    assert term == {"robot_0": True, "human_0": False, "__all__": False}
    assert trunc == {"robot_0": False, "human_0": True, "__all__": True}


def test_everyone_terminated_is_a_termination():
    # Pedestrians on the crowd model (inside the env): the robot is the only agent.
    env = NavzooMultiAgentEnv({"env_id": "navzoo/Corridor-v0", "n_robots": 1, "n_humans": 1, "humans": "crowd"})
    assert env.possible_agents == ["robot_0"]
    obs, _ = env.reset(seed=0, options={k: v[:1] for k, v in CORRIDOR.items()})
    while True:
        obs, rew, term, trunc, infos = env.step(_drive(env, obs))
        if term["__all__"] or trunc["__all__"]:
            break
    assert term == {"robot_0": True, "__all__": True} and trunc == {"robot_0": False, "__all__": False}
    # The pedestrian, hidden from RLlib, started on its goal: counted all the same.
    assert env.episode_summary["human_goals_per_human"] >= 1 and env.episode_summary["robot_success"] == 1.0


def test_frozen_robots_leave_only_pedestrians_as_agents():
    env = NavzooMultiAgentEnv(JointConfig(n_humans=3, robots="frozen", robot_policy="orca"))
    assert env.possible_agents == ["human_0", "human_1", "human_2"]
    obs, _ = env.reset(seed=3)
    n = 0
    while True:
        obs, rew, term, trunc, _ = env.step({a: np.zeros(2, np.float32) for a in obs})
        n += 1
        if term["__all__"] or trunc["__all__"]:
            break
    # The episode still ends when the (frozen) robot is done.
    assert n <= 100 and env.episode_summary["episode_steps"] == n


def test_registered_with_tune():
    from ray.tune.registry import ENV_CREATOR, _global_registry

    assert register() == ENV_NAME == "navzoo"
    assert _global_registry.contains(ENV_CREATOR, "navzoo")
    env = env_creator({"n_humans": 1})
    assert isinstance(env, NavzooMultiAgentEnv) and env.possible_agents == ["robot_0", "human_0"]


def test_frozen_amp_pedestrians_around_a_learning_robot():
    # Physics pedestrians on the shipped AMP controller, inside the env; RLlib sees the robot only.
    env = NavzooMultiAgentEnv({"env_id": "navzoo/Lobby-v0", "n_humans": 2, "humans": "frozen",
                               "env": {"human_model": "amp"}})
    assert env.possible_agents == ["robot_0"]
    obs, _ = env.reset(seed=0)
    nav = env.unwrapped_nav
    start = nav.pos[1:].copy()
    for _ in range(15):
        obs, *_ = env.step({"robot_0": np.zeros(2, np.float32)})
    assert np.linalg.norm(nav.pos[1:] - start, axis=1).min() > 0.1  # they walk
