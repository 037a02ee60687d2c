"""Short-horizon 2D target trajectories for physics pedestrians, rolled out with the social force model.

An articulated pedestrian cannot follow a crowd model's velocity command directly: its controller is
trained to follow a *trajectory* (the next few seconds of target points). :func:`sfm_rollout` produces
that trajectory by integrating the social force model forward from the body's actual position and
velocity for a few seconds, with the other agents extrapolated at constant velocity and walls as
repulsive segments. Re-running it every couple of seconds ("replanning") keeps the target attached to
the body while it reacts to the crowd. Used by curriculum stage 3 of the AMP training task
(:mod:`navzoo.agents.amp.path_env`) and by ``human_model="amp"`` in :class:`navzoo.envs.nav_env.NavEnv`.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from navzoo.agents.sfm import SocialForceParams, social_force_velocities

PrefVelocity = Callable[[np.ndarray, int], np.ndarray]


def goal_pref_velocity(goals: np.ndarray, speed: np.ndarray, slow_radius: float = 1.0) -> PrefVelocity:
    """Preferred velocity towards fixed ``goals`` (N, 2) at ``speed`` (N,), slowing to rest inside
    ``slow_radius`` of the goal (so a rollout that reaches its goal stands there)."""
    goals = np.asarray(goals, dtype=float)
    return waypoints_pref_velocity(goals[:, None], np.ones(len(goals), dtype=int), speed, slow_radius=slow_radius)


def waypoints_pref_velocity(waypoints: np.ndarray, counts: np.ndarray, speed: np.ndarray, reach: float = 0.5,
                            slow_radius: float = 1.0) -> PrefVelocity:
    """Preferred velocity along a short list of waypoints per person at ``speed`` (N,).

    ``waypoints`` (N, W, 2) holds each person's waypoints in order, of which the first ``counts`` (N,)
    are used (at least 1; the last one used is the goal). A person heads for its current waypoint and
    moves on to the next once within ``reach`` of it; only the goal slows the person down (to rest
    inside ``slow_radius``). The returned function keeps each person's progress between calls, so use a
    fresh one for every rollout.
    """
    wps = np.asarray(waypoints, dtype=float)
    counts = np.asarray(counts, dtype=int)
    speed = np.asarray(speed, dtype=float)
    if wps.ndim != 3 or wps.shape[2] != 2 or counts.shape != (wps.shape[0],) or speed.shape != counts.shape:
        raise ValueError(f"waypoints must be (N, W, 2) with counts and speed (N,), got {wps.shape}, "
                         f"{counts.shape} and {speed.shape}")
    if (counts < 1).any() or (counts > wps.shape[1]).any():
        raise ValueError(f"counts must lie in 1..{wps.shape[1]}, got {counts.tolist()}")
    cursor = np.zeros(len(counts), dtype=int)
    rows = np.arange(len(counts))
    last = counts - 1

    def pref(pos: np.ndarray, _k: int) -> np.ndarray:
        while True:
            d = wps[rows, cursor] - pos
            dist = np.linalg.norm(d, axis=1)
            move = (cursor < last) & (dist < reach)
            if not move.any():
                break
            cursor[move] += 1
        unit = d / np.maximum(dist, 1e-9)[:, None]
        v = np.where(cursor == last, speed * np.minimum(1.0, dist / slow_radius), speed)
        return unit * v[:, None]

    return pref


def sfm_rollout(
    pos: np.ndarray,
    vel: np.ndarray,
    pref_velocity: PrefVelocity,
    steps: int,
    dt: float,
    *,
    max_speed: np.ndarray | float = 2.0,
    radius: np.ndarray | float = 0.3,
    params: SocialForceParams | None = None,
    others_pos: np.ndarray | None = None,
    others_vel: np.ndarray | None = None,
    others_radius: float = 0.3,
    segments: np.ndarray | None = None,
    segment_groups: np.ndarray | None = None,
    wall_radius: np.ndarray | float | None = None,
) -> np.ndarray:
    """Positions (N, steps + 1, 2) of N people integrated with the social force model for ``steps``
    steps of ``dt`` from ``pos``/``vel`` (row 0 is ``pos``). People interact with each other, with
    ``others`` (e.g. robots, or people not being planned) moving at constant velocity, and with wall
    ``segments``. ``pref_velocity(pos, k)`` gives each person's preferred velocity at step k;
    ``wall_radius`` is the radius the walls see (default: ``radius``)."""
    params = params or SocialForceParams()
    p = np.asarray(pos, dtype=float).copy()
    v = np.asarray(vel, dtype=float).copy()
    if p.ndim != 2 or p.shape[1] != 2 or v.shape != p.shape:
        raise ValueError(f"pos and vel must both be (N, 2), got {p.shape} and {v.shape}")
    out = np.empty((p.shape[0], steps + 1, 2))
    out[:, 0] = p
    op = None if others_pos is None or len(others_pos) == 0 else np.asarray(others_pos, dtype=float)
    ov = None if op is None else (np.zeros_like(op) if others_vel is None else np.asarray(others_vel, dtype=float))
    for k in range(steps):
        o = None if op is None else op + (k * dt) * ov
        v = social_force_velocities(p, v, pref_velocity(p, k), radius, max_speed, dt, params, segments,
                                    o, ov, others_radius, segment_groups, wall_radius)
        p = p + dt * v
        out[:, k + 1] = p
    return out


def resample(path: np.ndarray, src_dt: float, dst_dt: float, n: int) -> np.ndarray:
    """Linear resampling of trajectories (N, T, 2) sampled every ``src_dt`` to ``n`` points every
    ``dst_dt`` (points past the end repeat the last one)."""
    t_src = np.arange(path.shape[1]) * src_dt
    t_dst = np.minimum(np.arange(n) * dst_dt, t_src[-1])
    i = np.clip(np.searchsorted(t_src, t_dst, side="right") - 1, 0, path.shape[1] - 2) if path.shape[1] > 1 else None
    if i is None:
        return np.repeat(path[:, :1], n, axis=1)
    w = ((t_dst - t_src[i]) / src_dt)[None, :, None]
    return path[:, i] * (1.0 - w) + path[:, i + 1] * w
