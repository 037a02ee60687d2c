"""Curriculum stage 3 of the AMP task: crowd paths replanned from the body's state, and pushes."""

from __future__ import annotations

import numpy as np
import pytest

from navzoo.agents.amp.path_env import AmpPathEnv, PathTaskConfig
from navzoo.agents.amp.sim import ACTION_DIM
from navzoo.agents.amp.train import locomotion_reference
from navzoo.agents.target_paths import goal_pref_velocity, resample, sfm_rollout


def test_sfm_rollout_walks_to_goal_and_resample_is_linear():
    roll = sfm_rollout(np.zeros((1, 2)), np.zeros((1, 2)), goal_pref_velocity(np.array([[4.0, 0.0]]), np.ones(1)),
                       80, 0.1)
    assert roll.shape == (1, 81, 2)
    assert np.linalg.norm(roll[0, -1] - [4.0, 0.0]) < 0.2  # arrives and stops at the goal
    assert roll[0, :, 0].max() < 4.05 and np.abs(roll[0, :, 1]).max() < 1e-9  # straight, overshoot < 5 cm
    path = np.array([[[0.0, 0.0], [1.0, 0.0], [2.0, 2.0]]])
    out = resample(path, 1.0, 0.5, 6)
    np.testing.assert_allclose(out[0], [[0, 0], [0.5, 0], [1, 0], [1.5, 1], [2, 2], [2, 2]])


def test_stage3_replans_from_the_body_and_pushes():
    cfg = PathTaskConfig(stage=3, crowd_prob=1.0, push_interval=(0.2, 0.3), push_force=(400.0, 400.0),
                         replan_seconds=1.0)
    env = AmpPathEnv(2, locomotion_reference(), cfg, seed=0)
    env.reset(seed=0)
    zero = np.zeros((2, ACTION_DIM))
    for _ in range(cfg.control_hz):  # 1 s: a replan is due, and pushes have happened
        env.step(zero)
    state = env.bodies.read_state()
    t = env.t
    # after the replan at t the target point at t is the body's position then; pushes moved the bodies
    assert (env._next_plan > t - 1).all()
    assert (env._next_push > t).all()
    for i in range(2):
        k = int(env._next_plan[i] - round(cfg.replan_seconds * cfg.control_hz))
        if k == t[i]:
            np.testing.assert_allclose(env.paths[i, k], state["root_pos"][i, :2], atol=1e-9)
    env.close()


def test_stage_validation():
    with pytest.raises(ValueError, match="stage"):
        PathTaskConfig(stage=4)


def test_obstacle_rays_measure_walls_and_discs():
    from navzoo.agents.amp.features import N_RAYS, RAY_RANGE, obstacle_observation

    wall = np.array([[[2.0, -5.0], [2.0, 5.0]]])
    discs = np.array([[0.0, 1.5], [0.0, 0.0]])
    f = obstacle_observation(np.zeros((1, 2)), np.zeros(1), wall, discs, 0.5, self_disc=np.array([1]))[0]
    assert f.shape == (N_RAYS,)
    assert f[0] == pytest.approx(1 - 2.0 / RAY_RANGE)  # straight ahead: the wall at 2 m
    assert f[1] == pytest.approx(1 - 2.0 / np.cos(2 * np.pi / N_RAYS) / RAY_RANGE)
    assert f[N_RAYS // 4] == pytest.approx(1 - 1.0 / RAY_RANGE)  # left: the disc's edge at 1 m
    assert f[N_RAYS // 2] == 0.0  # behind: nothing (its own disc is skipped)
    # turning the body turns the rays with it
    g = obstacle_observation(np.zeros((1, 2)), np.array([np.pi / 2]), wall, discs, 0.5, self_disc=np.array([1]))[0]
    assert g[0] == pytest.approx(1 - 1.0 / RAY_RANGE) and g[-N_RAYS // 4] == pytest.approx(1 - 2.0 / RAY_RANGE)
    # inside a disc every ray reads 1; far from everything every ray reads 0
    assert np.all(obstacle_observation(np.array([[0.0, 1.4]]), np.zeros(1), None, discs[:1], 0.5) == 1.0)
    assert np.all(obstacle_observation(np.array([[50.0, 0.0]]), np.zeros(1), wall, discs, 0.5) == 0.0)
