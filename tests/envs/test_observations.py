"""Observation terms on hand-made states with known answers (no PyBullet)."""

from __future__ import annotations

import numpy as np
import pytest

from navzoo.envs.observations import goal_features, neighbor_features, to_frame, velocity_features


def test_goal_features_in_agent_frame():
    # Agent at (1, 1) facing +y; goal at (1, 3) is straight ahead, 2 m.
    g = goal_features(np.array([[1.0, 1.0]]), np.array([np.pi / 2]), np.array([[1.0, 3.0]]))[0]
    np.testing.assert_allclose(g, [2.0, 0.0, 2.0, 0.0, 1.0], atol=1e-12)
    # Goal to the agent's left.
    g = goal_features(np.array([[0.0, 0.0]]), np.array([0.0]), np.array([[0.0, 5.0]]))[0]
    np.testing.assert_allclose(g, [0.0, 5.0, 5.0, 1.0, 0.0], atol=1e-12)


def test_velocity_features_rotate_world_velocity():
    v = velocity_features(np.array([[0.0, 1.0]]), np.array([np.pi / 2]), np.array([0.3]))[0]
    np.testing.assert_allclose(v, [1.0, 0.0, 0.3], atol=1e-12)


def test_to_frame_round_trip_batches():
    rng = np.random.default_rng(0)
    vec = rng.normal(size=(4, 3, 5, 2))
    yaw = rng.uniform(-np.pi, np.pi, 4)
    back = to_frame(to_frame(vec, yaw), -yaw)
    np.testing.assert_allclose(back, vec, atol=1e-12)


def _history(pos_now: np.ndarray, t: int = 3):
    n = pos_now.shape[0]
    hist_pos = np.repeat(pos_now[None], t, axis=0).astype(float)
    hist_vel = np.zeros((t, n, 2))
    hist_yaw = np.zeros((t, n))
    valid = np.ones(t, dtype=bool)
    return hist_pos, hist_vel, hist_yaw, valid


def test_neighbors_sorted_masked_and_in_observer_frame():
    # Observer 0 at the origin facing +y; others at (0, 2) [ahead], (-1, 0) [left], (10, 0) [far].
    pos = np.array([[0.0, 0.0], [0.0, 2.0], [-1.0, 0.0], [10.0, 0.0]])
    hp, hv, hy, valid = _history(pos)
    hy[:, 0] = np.pi / 2
    hy[:, 1] = np.pi  # neighbour 1 faces -x
    hv[:, 1] = [0.0, -1.0]  # walking toward the observer
    valid[0] = False  # the oldest step does not exist yet
    radius = np.array([0.3, 0.25, 0.3, 0.3])
    feats, mask = neighbor_features(hp, hv, hy, valid, radius, np.ones(4, bool), np.array([0]), k=3, sensor_range=6.0)
    assert feats.shape == (1, 3, 3, 7) and mask.shape == (1, 3, 3)
    # Nearest first: the person on the left (1 m), then the one ahead (2 m); the far one is masked.
    np.testing.assert_allclose(feats[0, 0, -1, :2], [0.0, 1.0], atol=1e-12)  # left = +y in the agent frame
    np.testing.assert_allclose(feats[0, 1, -1, :2], [2.0, 0.0], atol=1e-12)  # ahead = +x
    np.testing.assert_allclose(feats[0, 1, -1, 2:4], [-1.0, 0.0], atol=1e-12)  # coming toward us
    # Relative heading pi - pi/2 = pi/2: cos 0, sin 1.
    np.testing.assert_allclose(feats[0, 1, -1, 4:6], [0.0, 1.0], atol=1e-12)
    assert feats[0, 1, -1, 6] == pytest.approx(0.25)
    np.testing.assert_array_equal(mask[0], [[0, 1, 1], [0, 1, 1], [0, 0, 0]])
    assert not feats[0, 2].any() and not feats[0, :, 0].any()


def test_invisible_agents_are_not_observed():
    pos = np.array([[0.0, 0.0], [1.0, 0.0], [2.0, 0.0]])
    hp, hv, hy, valid = _history(pos)
    visible = np.array([True, False, True])
    feats, mask = neighbor_features(hp, hv, hy, valid, np.full(3, 0.3), visible, np.array([0]), k=2, sensor_range=6.0)
    np.testing.assert_allclose(feats[0, 0, -1, :2], [2.0, 0.0])
    assert mask[0, 1].sum() == 0
