"""navzoo.envs.amp_humans.sight_waypoints and NavConfig.amp_sight_clearance: the controller sees the target
points in sight of the body; those behind a corner are shown continued straight."""

from __future__ import annotations

import numpy as np
import pytest

from navzoo.envs.amp_humans import sight_waypoints

# an obstacle filling x <= 0, y <= 0: its corner at the origin, its faces along -x and -y
CORNER = np.array([[[0.0, 0.0], [0.0, -5.0]], [[-5.0, 0.0], [0.0, 0.0]]])


def _turn(y: float = 0.5) -> np.ndarray:
    """Ten points 0.5 m apart: along +x at height ``y`` past the corner, then down -y beside its face."""
    pts = [[-0.5, y], [0.0, y], [0.5, y]] + [[0.6, y - 0.5 * m] for m in range(1, 8)]
    return np.array([pts], dtype=float)


def test_no_clearance_or_no_walls_changes_nothing():
    pos, wps = np.array([[-1.0, 0.5]]), _turn()
    np.testing.assert_array_equal(sight_waypoints(pos, wps, CORNER, 0.0), wps)
    np.testing.assert_array_equal(sight_waypoints(pos, wps, np.zeros((0, 2, 2)), 0.3), wps)


def test_points_behind_a_corner_are_continued_straight():
    pos, wps = np.array([[-1.0, 0.5]]), _turn()
    out = sight_waypoints(pos, wps, CORNER, 0.3)
    np.testing.assert_array_equal(out[0, :3], wps[0, :3])  # in sight: kept
    # the rest go on along +x, 0.5 m apart, from the last point in sight
    np.testing.assert_allclose(out[0, 3:], np.array([[0.5 + 0.5 * m, 0.5] for m in range(1, 8)]))
    # once the body stands past the corner the points down its face are in sight again
    past = sight_waypoints(np.array([[0.6, 0.3]]), wps[:, 3:], CORNER, 0.3)
    np.testing.assert_array_equal(past, wps[:, 3:])


def test_a_wider_clearance_hides_more_and_a_far_line_hides_nothing():
    pos = np.array([[-1.0, 0.5]])
    wide = _turn(y=0.55)

    def first_changed(clearance: float) -> int:
        return int(np.argmax(np.any(sight_waypoints(pos, wide, CORNER, clearance)[0] != wide[0], axis=1)))

    # the line to the first point round the corner passes 0.23 m from it: hidden with 0.3, in sight with 0.1
    assert first_changed(0.1) > first_changed(0.3) == 3
    far = _turn(y=2.5)
    far[0, 3:, 0] = 2.5  # going down 2.5 m to the right of the corner: every line keeps 0.3 m from it
    np.testing.assert_array_equal(sight_waypoints(np.array([[-1.0, 2.5]]), far, CORNER, 0.3), far)


def test_walking_along_a_wall_closer_than_the_clearance_keeps_the_points():
    wall = np.array([[[-10.0, 0.0], [10.0, 0.0]]])
    pos = np.array([[0.0, 0.25]])  # 0.25 m from the wall, under a 0.3 m clearance
    wps = np.array([[[0.5 * m, 0.25] for m in range(1, 11)]])
    np.testing.assert_array_equal(sight_waypoints(pos, wps, wall, 0.3), wps)


def test_a_first_point_out_of_sight_is_left_alone_and_each_body_is_its_own():
    pos = np.array([[-0.3, 0.1], [-1.0, 0.5]])  # the first body stands at the corner, its first point behind it
    first = np.array([[0.1, -0.3]] + [[0.1, -0.3 - 0.5 * m] for m in range(1, 10)])
    wps = np.stack([first, _turn()[0]])
    out = sight_waypoints(pos, wps, CORNER, 0.3)
    np.testing.assert_array_equal(out[0], wps[0])
    np.testing.assert_array_equal(out[1], sight_waypoints(pos[1:], wps[1:], CORNER, 0.3)[0])
    assert not np.array_equal(out[1], wps[1])


def test_a_line_through_a_door_on_its_axis_is_in_sight():
    jambs = np.array([[[0.0, 0.45], [0.0, 3.0]], [[0.0, -3.0], [0.0, -0.45]]])  # a 0.9 m door in a wall x = 0
    pos = np.array([[-2.0, 0.0]])
    wps = np.array([[[-2.0 + 0.5 * m, 0.0] for m in range(1, 11)]])
    np.testing.assert_array_equal(sight_waypoints(pos, wps, jambs, 0.3), wps)
    aslant = np.array([[[-2.0 + 0.5 * m, 0.0 if m < 4 else 0.3 * (m - 3)] for m in range(1, 11)]])
    assert not np.array_equal(sight_waypoints(pos, aslant, jambs, 0.3), aslant)


def test_the_sight_clearance_is_a_config_field_that_changes_the_observed_points():
    from navzoo.envs import amp_humans
    from navzoo.envs.config import NavConfig
    from tests.test_amp_env import DT, _raw

    changed = 0
    for seed in (1, 2, 3):  # bodies at reset, their targets through the home's doors and round its furniture
        obs = {}
        for clearance in (None, 0.3):
            env = _raw(n_robots=0, n_humans=5, scene="home", amp_sight_clearance=clearance)
            env.reset(seed=seed)
            assert env.amp.sight_clearance == (amp_humans.SIGHT_CLEARANCE if clearance is None else 0.3)
            obs[clearance] = env.amp.observations()
            env.close()
        n_wp = 2 * amp_humans.N_WAYPOINTS
        body = slice(0, obs[None].shape[1] - n_wp - amp_humans.N_RAYS)
        np.testing.assert_array_equal(obs[None][:, body], obs[0.3][:, body])  # only the target points differ
        np.testing.assert_array_equal(obs[None][:, -amp_humans.N_RAYS:], obs[0.3][:, -amp_humans.N_RAYS:])
        changed += int(np.any(obs[None] != obs[0.3], axis=1).sum())
    assert changed >= 1
    for bad in (-0.1, float("nan"), float("inf"), True, "0.3"):
        with pytest.raises(ValueError, match="amp_sight_clearance must be None or a finite number >= 0"):
            NavConfig(human_model="amp", dt=DT, amp_sight_clearance=bad)
