"""PettingZoo / Gymnasium / SB3 conformance, parametrised over every registered id."""

from __future__ import annotations

import gymnasium
import numpy as np
import pettingzoo
import pytest
from pettingzoo.test import api_test, parallel_api_test, seed_test
from pettingzoo.utils.conversions import parallel_to_aec

import navzoo
from navzoo.envs.registry import SCENARIOS
from navzoo.envs.wrappers import SingleRobotEnv

ENV_IDS = sorted(SCENARIOS)
# Small crowds keep the conformance suite fast; the crowd size does not change the API.
SMALL = dict(n_humans=3, max_episode_steps_override=60)


@pytest.mark.parametrize("env_id", ENV_IDS)
def test_registered_with_pettingzoo(env_id):
    env = pettingzoo.make("parallel", env_id, n_humans=2)
    try:
        assert env.possible_agents == ["robot_0"]
        assert env.unwrapped.possible_agents == ["robot_0", "human_0", "human_1"]
    finally:
        env.close()


@pytest.mark.parametrize("env_id", ENV_IDS)
def test_parallel_api(env_id):
    env = navzoo.make(env_id, **SMALL)
    parallel_api_test(env, num_cycles=80)
    env.close()


@pytest.mark.parametrize("env_id", ENV_IDS)
def test_parallel_api_raw_all_agents(env_id):
    env = navzoo.make(env_id, raw=True, n_robots=2, **SMALL)
    parallel_api_test(env, num_cycles=80)
    env.close()


@pytest.mark.parametrize("env_id", ENV_IDS)
def test_aec_api(env_id):
    env = parallel_to_aec(navzoo.make(env_id, raw=True, **SMALL))
    api_test(env, num_cycles=40)
    env.close()


@pytest.mark.parametrize("env_id", ENV_IDS)
def test_seed(env_id):
    seed_test(lambda: parallel_to_aec(navzoo.make(env_id, raw=True, **SMALL)), num_cycles=40)


@pytest.mark.parametrize("env_id", ["navzoo/CircleCrossing-v0", "navzoo/Lobby-v0"])
def test_single_robot_gymnasium_and_sb3_check_env(env_id):
    from gymnasium.utils.env_checker import check_env as gym_check
    from stable_baselines3.common.env_checker import check_env as sb3_check

    env = SingleRobotEnv(navzoo.make(env_id, **SMALL))
    gym_check(env, skip_render_check=True)
    sb3_check(env, warn=True)
    env.close()
    flat = SingleRobotEnv(navzoo.make(env_id, flat_obs=True, **SMALL))
    assert isinstance(flat.observation_space, gymnasium.spaces.Box)
    gym_check(flat, skip_render_check=True)
    sb3_check(flat, warn=True)
    flat.close()


def test_spaces_are_cached_objects():
    env = navzoo.make("navzoo/Corridor-v0", raw=True, **SMALL)
    for a in env.possible_agents:
        assert env.observation_space(a) is env.observation_space(a)
        assert env.action_space(a) is env.action_space(a)
    env.close()


@pytest.mark.parametrize("env_id", ["navzoo/Station-v0", "navzoo/Home-v0", "navzoo/SquareCrossing-v0"])
def test_observations_inside_spaces_and_finite(env_id):
    env = navzoo.make(env_id, raw=True, n_robots=2, n_humans=6, max_episode_steps_override=150)
    obs, _ = env.reset(seed=3)
    rng = np.random.default_rng(0)
    steps = 0
    while env.agents:
        for a, o in obs.items():
            space = env.observation_space(a)
            assert space.contains(o), f"{a} observation outside its space at step {steps}"
            for v in o.values():
                assert np.isfinite(v).all()
        # Deliberately out-of-range actions: they must be clipped, never break the spaces.
        obs, rew, term, trunc, info = env.step({a: rng.uniform(-1.5, 1.5, 2) for a in env.agents})
        assert all(np.isfinite(r) for r in rew.values())
        steps += 1
    assert steps > 0
    env.close()


def test_pad_finished_agents_passes_parallel_api():
    from navzoo.envs.wrappers import PadFinishedAgents

    env = PadFinishedAgents(navzoo.make("navzoo/Lobby-v0", n_robots=3, flat_obs=True, **SMALL))
    for _ in range(5):  # unseeded resets: robots end at different steps in most episodes
        parallel_api_test(env, num_cycles=80)
    # A robot that ends early stays until the end, then reports its real termination.
    obs, _ = env.reset(seed=0, options={
        "robot_starts": [[10.0, 2.0], [4.0, 8.0], [16.0, 8.0]], "robot_goals": [[10.0, 2.2], [4.0, 12.0], [16.0, 4.0]]})
    assert env.agents == ["robot_0", "robot_1", "robot_2"]
    obs, rew, term, trunc, info = env.step({a: np.zeros(2, np.float32) for a in env.agents})
    assert info["robot_0"]["event"] == "goal" and rew["robot_0"] >= 20 and not term["robot_0"]
    assert env.agents == ["robot_0", "robot_1", "robot_2"]
    while env.agents:
        obs, rew, term, trunc, info = env.step({a: np.zeros(2, np.float32) for a in env.agents})
        assert rew["robot_0"] == 0.0 and not obs["robot_0"].any()
    assert term["robot_0"] and trunc["robot_1"] and trunc["robot_2"]
    env.close()
