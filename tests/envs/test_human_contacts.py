"""Kinematic pedestrians pay for contacts (NavConfig.human_contact_penalty): -20 when one begins."""

from __future__ import annotations

import numpy as np
import pytest

from navzoo.envs.nav_env import NavEnv


def _env(**kw) -> NavEnv:
    env = NavEnv(scene="circle_crossing", n_robots=1, n_humans=2, crowd_model="sfm", time_limit=20.0, **kw)
    env.reset(seed=0)
    return env


def _place(env: NavEnv, robot, h0, h1) -> None:
    """Put the robot and both pedestrians at fixed places, standing still."""
    for i, xy in enumerate((robot, h0, h1)):
        env.pos[i] = xy
        env.vel[i] = 0.0
    env.robots.straighten(0, env.pos[0], float(env.yaw[0]))


def _still(env: NavEnv) -> dict:
    return {a: np.zeros(2, dtype=np.float32) for a in env.agents}


def test_contact_between_pedestrians_costs_once_and_is_named():
    env = _env()
    _place(env, (-4.0, -4.0), (0.0, 0.0), (0.5, 0.0))  # discs of 0.3 m, 0.5 m apart: overlapping
    _, rew, term, trunc, info = env.step(_still(env))
    assert info["human_0"]["contact"] == "human" and info["human_1"]["contact"] == "human"
    assert info["human_0"]["reward/collision"] == pytest.approx(-20.0)
    assert rew["human_0"] <= -20.0 + 1e-6
    assert not term["human_0"] and not trunc["human_0"], "a pedestrian is not taken out by a contact"
    # Still overlapping on the next step: the contact did not begin there, no second penalty.
    env.pos[1], env.pos[2] = (0.0, 0.0), (0.5, 0.0)
    _, rew, _, _, info = env.step(_still(env))
    assert info["human_0"]["contact"] == "human"
    assert info["human_0"]["reward/collision"] == 0.0
    # Apart: no contact; together again: a new contact, a new penalty.
    env.pos[1], env.pos[2] = (0.0, 0.0), (3.0, 0.0)
    _, _, _, _, info = env.step(_still(env))
    assert info["human_0"]["contact"] == ""
    env.pos[1], env.pos[2] = (0.0, 0.0), (0.5, 0.0)
    _, _, _, _, info = env.step(_still(env))
    assert info["human_1"]["reward/collision"] == pytest.approx(-20.0)
    env.close()


def test_robot_that_runs_into_a_pedestrian_costs_the_pedestrian_too():
    env = _env()
    _place(env, (0.0, 0.0), (0.55, 0.0), (4.0, 4.0))
    robot_yaw = env.yaw[0]
    toward = np.array([np.cos(robot_yaw), np.sin(robot_yaw)])
    gap = env.radius[0] + env.radius[1] - 0.05
    env.pos[1] = env.pos[0] + gap * toward  # 5 cm inside the robot's disc, ahead of it
    act = _still(env)
    act["robot_0"] = np.array([1.0, 0.0], dtype=np.float32)
    _, _, term, _, info = env.step(act)
    assert term["robot_0"] and info["robot_0"]["collision"] == "human"
    assert info["human_0"]["contact"] == "robot"
    assert info["human_0"]["reward/collision"] == pytest.approx(-20.0)
    assert info["human_1"]["contact"] == "" and info["human_1"]["reward/collision"] == 0.0
    env.close()


def test_penalty_off_keeps_the_proximity_term_only():
    env = _env(human_contact_penalty=False)
    _place(env, (-4.0, -4.0), (0.0, 0.0), (0.5, 0.0))
    _, _, _, _, info = env.step(_still(env))
    assert info["human_0"]["contact"] == "human", "contacts are still reported"
    assert info["human_0"]["reward/collision"] == 0.0
    assert info["human_0"]["reward/proximity"] < 0.0
    env.close()


def test_bad_flag_is_refused():
    with pytest.raises(ValueError, match="human_contact_penalty"):
        NavEnv(scene="open_square", n_robots=1, n_humans=1, human_contact_penalty="yes")
