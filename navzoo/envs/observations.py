"""Observation terms: pure, vectorised functions of the world's state arrays.

All features are expressed in the observing agent's frame at the current step (x forward, y left),
as in the paper: goal (x_g, y_g, d_g, sin theta_g, cos theta_g), own velocity, and the K nearest
other agents over the last T steps as (x, y, u, v, cos theta, sin theta, radius) with a validity mask.
"""

from __future__ import annotations

import numpy as np

NEIGHBOR_FEATURES = 7
POS_BOUND = 50.0  # m: relative positions are clipped to +-POS_BOUND so they always lie in the space
VEL_BOUND = 10.0  # m/s (and rad/s)
GOAL_BOUND = 200.0  # m


def to_frame(vec: np.ndarray, yaw: np.ndarray) -> np.ndarray:
    """Rotate world-frame vectors ``vec`` (A, ..., 2) into frames with headings ``yaw`` (A,)."""
    c, s = np.cos(yaw), np.sin(yaw)
    shape = (-1,) + (1,) * (vec.ndim - 2)
    c, s = c.reshape(shape), s.reshape(shape)
    x, y = vec[..., 0], vec[..., 1]
    return np.stack([c * x + s * y, -s * x + c * y], axis=-1)


def goal_features(pos: np.ndarray, yaw: np.ndarray, goal: np.ndarray) -> np.ndarray:
    """(A, 5) goal features [x_g, y_g, d_g, sin theta_g, cos theta_g] in each agent's frame."""
    rel = to_frame(goal - pos, yaw)
    d = np.linalg.norm(rel, axis=1)
    theta = np.arctan2(rel[:, 1], rel[:, 0])
    out = np.stack([rel[:, 0], rel[:, 1], d, np.sin(theta), np.cos(theta)], axis=1)
    out[:, :2] = np.clip(out[:, :2], -GOAL_BOUND, GOAL_BOUND)
    out[:, 2] = np.clip(out[:, 2], 0.0, GOAL_BOUND * 1.5)
    return out


def velocity_features(vel: np.ndarray, yaw: np.ndarray, omega: np.ndarray) -> np.ndarray:
    """(A, 3) own velocity in the agent's frame (forward, left) and yaw rate."""
    v = to_frame(vel, yaw)
    return np.clip(np.concatenate([v, omega[:, None]], axis=1), -VEL_BOUND, VEL_BOUND)


def neighbor_features(
    hist_pos: np.ndarray,
    hist_vel: np.ndarray,
    hist_yaw: np.ndarray,
    hist_valid: np.ndarray,
    radius: np.ndarray,
    visible: np.ndarray,
    observers: np.ndarray,
    k: int,
    sensor_range: float,
    hist_present: np.ndarray | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """The K nearest other agents over the last T steps, in each observer's current frame.

    Args:
        hist_pos: (T, N, 2) world positions, index T-1 = now.
        hist_vel: (T, N, 2) world velocities.
        hist_yaw: (T, N) headings.
        hist_valid: (T,) whether that history step exists (False before the episode started).
        radius: (N,) agent radii.
        visible: (N,) which agents can be observed (alive, in the world).
        observers: (A,) indices of the observing agents.
        k: number of neighbour slots.
        sensor_range: agents farther than this (centre to centre, now) are not observed.
        hist_present: optional (T, N) bool: whether each agent was in the world at each history step
            (replayed people appear and leave mid-episode); entries where it was not are masked.

    Returns:
        ``(features (A, K, T, 7), mask (A, K, T))``: neighbours sorted nearest first; empty slots
        and masked entries are zero.
    """
    t_len, n, _ = hist_pos.shape
    a = observers.shape[0]
    feats = np.zeros((a, k, t_len, NEIGHBOR_FEATURES), dtype=np.float32)
    mask = np.zeros((a, k, t_len), dtype=np.float32)
    if a == 0 or n <= 1:
        return feats, mask
    now = hist_pos[-1]
    d = np.linalg.norm(now[observers][:, None, :] - now[None, :, :], axis=2)  # (A, N)
    d[np.arange(a), observers] = np.inf
    d[:, ~visible] = np.inf
    d[d > sensor_range] = np.inf
    kk = min(k, n - 1)
    idx = np.argsort(d, axis=1, kind="stable")[:, :kk]  # (A, kk)
    ok = np.isfinite(np.take_along_axis(d, idx, axis=1))  # (A, kk)
    yaw_o = hist_yaw[-1, observers]  # (A,)
    pos_o = now[observers]  # (A, 2)
    # Gather (A, kk, T, .) histories of the chosen neighbours.
    p_n = np.transpose(hist_pos[:, idx], (1, 2, 0, 3))
    v_n = np.transpose(hist_vel[:, idx], (1, 2, 0, 3))
    y_n = np.transpose(hist_yaw[:, idx], (1, 2, 0))
    rel_p = to_frame(p_n - pos_o[:, None, None, :], yaw_o)
    rel_v = to_frame(v_n, yaw_o)
    rel_yaw = y_n - yaw_o[:, None, None]
    f = np.concatenate(
        [
            np.clip(rel_p, -POS_BOUND, POS_BOUND),
            np.clip(rel_v, -VEL_BOUND, VEL_BOUND),
            np.cos(rel_yaw)[..., None],
            np.sin(rel_yaw)[..., None],
            np.broadcast_to(radius[idx][:, :, None, None], rel_yaw.shape + (1,)),
        ],
        axis=-1,
    )
    m = ok[:, :, None] & hist_valid[None, None, :]
    if hist_present is not None:
        m = m & np.transpose(hist_present[:, idx], (1, 2, 0))
    m = m.astype(np.float32)
    feats[:, :kk] = f * m[..., None]
    mask[:, :kk] = m
    return feats, mask
