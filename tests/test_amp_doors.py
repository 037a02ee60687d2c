"""Doorways in curriculum stage 3 of the AMP task: a wall with one door splits a patch, crowd paths
to goals behind it pass the door on its axis, and the virtual neighbours stay on their side."""

from __future__ import annotations

import numpy as np
import pytest

from navzoo.agents.amp.path_env import AmpPathEnv, PathTaskConfig
from navzoo.agents.amp.train import TrainArgs, locomotion_reference, run
from navzoo.agents.target_paths import sfm_rollout, waypoints_pref_velocity


def test_waypoints_are_visited_in_order_at_speed_and_the_goal_stops_the_walk():
    wps = np.array([[[2.0, 0.0], [2.0, 2.0], [0.0, 2.0]], [[-3.0, 0.0], [9.0, 9.0], [9.0, 9.0]]])
    roll = sfm_rollout(np.zeros((2, 2)), np.zeros((2, 2)), waypoints_pref_velocity(wps, np.array([3, 1]), np.ones(2)),
                       120, 0.1)
    a = roll[0]
    for w in wps[0, :2]:
        assert np.linalg.norm(a - w, axis=1).min() < 0.5  # passes each waypoint
    assert np.argmin(np.linalg.norm(a - wps[0, 0], axis=1)) < np.argmin(np.linalg.norm(a - wps[0, 1], axis=1))
    assert np.linalg.norm(a[-1] - wps[0, 2]) < 0.2  # and stands at the goal
    speed = np.linalg.norm(np.diff(a, axis=0), axis=1) / 0.1
    k = np.argmin(np.linalg.norm(a - wps[0, 0], axis=1))
    assert speed[k] > 0.7  # no slow-down at an intermediate waypoint
    assert np.linalg.norm(roll[1, -1] - [-3.0, 0.0]) < 0.2  # counts = 1: the first point is the goal


def test_waypoint_arguments_are_checked():
    with pytest.raises(ValueError, match="counts"):
        waypoints_pref_velocity(np.zeros((1, 2, 2)), np.array([3]), np.ones(1))
    with pytest.raises(ValueError, match="waypoints must be"):
        waypoints_pref_velocity(np.zeros((1, 2)), np.array([1]), np.ones(1))


@pytest.fixture(scope="module")
def door_env():
    cfg = PathTaskConfig(stage=3, obstacle_obs=True, boxes_per_patch=4, pair_patches=True, door_prob=1.0,
                         crowd_prob=1.0, door_width=(0.9, 0.9))
    env = AmpPathEnv(4, locomotion_reference(), cfg, seed=3)
    env.reset(seed=3)
    yield env
    env.close()


def test_the_wall_has_one_door_of_the_configured_width(door_env):
    env = door_env
    assert env.doors.shape == (2, 4) and np.isfinite(env.doors).all()
    for i in (0, 2):  # one env of each patch
        c, n = env.doors[env.patch[i], :2], env.doors[env.patch[i], 2:]
        along = np.array([-n[1], n[0]])
        assert env._clearance(i, c[None])[0] == pytest.approx(0.45, abs=1e-6)
        for s in (-1.0, 1.0):  # the wall itself, either side of the door
            assert env._clearance(i, (c + s * 1.0 * along)[None])[0] <= 0.075 + 1e-9  # inside the 0.15 m wall
        # boxes keep clear of the wall line, so the approach to the door is open
        assert env._clearance(i, np.stack([c + 1.2 * n, c - 1.2 * n])).min() > 1.0
        assert env._side(i, np.stack([c + n, c - n])).tolist() == [1.0, -1.0]


def test_a_crowd_path_behind_the_wall_goes_through_the_door(door_env):
    env = door_env
    state = env.bodies.read_state()
    for i in range(env.num_envs):
        c, n = env.doors[env.patch[i], :2], env.doors[env.patch[i], 2:]
        along = np.array([-n[1], n[0]])
        root = state["root_pos"][i, :2]
        side = env._side(i, root[None])[0]
        goal = c - side * 3.0 * n
        route = env._waypoints(i, root, goal)
        np.testing.assert_allclose(route, [c + side * 0.7 * n, c - side * 0.7 * n, goal])
        roll = sfm_rollout(root[None], np.zeros((1, 2)), waypoints_pref_velocity(route[None], np.array([3]),
                                                                                 np.array([1.2])),
                           150, 0.1, params=env._sfm, segments=env._segments,
                           segment_groups=np.arange(len(env._segments)) // 4)[0]
        s = (roll - c) @ n * side
        cross = np.flatnonzero((s[:-1] > 0) & (s[1:] <= 0))
        assert cross.size == 1, f"env {i}: the path crosses the wall line {cross.size} times"
        assert abs((roll[cross[0]] - c) @ along) < 0.2  # inside the 0.9 m door, near its axis
        # the env's replanned target path heads for the door's entry point first
        env._goal[i], env._speed[i], env._wait_until[i] = goal, 1.2, 0
        env._replan(np.array([i]), state)
        ahead = env.paths[i, env.t[i] + 2 * env.cfg.control_hz]
        assert np.linalg.norm(ahead - route[0]) < np.linalg.norm(root - route[0]) - 0.8
    assert env._waypoints(i, root, root + 0.1 * along).shape == (1, 2)  # same side: the goal alone


def test_neighbours_keep_to_their_side(door_env):
    env = door_env
    for i in range(env.num_envs):
        assert (env._side(i, env._nb_pos[i]) == env._side(i, env._nb_goal[i])).all()


def test_no_doors_by_default_and_settings_are_checked():
    env = AmpPathEnv(2, locomotion_reference(), PathTaskConfig(stage=3, boxes_per_patch=2), seed=0)
    assert np.isnan(env.doors).all() and env._segments.shape == (2 * 2 * 4, 2, 2)
    env.close()
    with pytest.raises(ValueError, match="door_prob"):
        PathTaskConfig(door_prob=1.5)
    with pytest.raises(ValueError, match="door_width"):
        PathTaskConfig(door_width=(0.4, 1.0))
    with pytest.raises(ValueError, match="--door-prob"):
        run(TrainArgs(out="/nonexistent/never", stage=2, obstacles=1, door_prob=0.5))
