"""Episode metrics as pure functions of recorded arrays (definitions in docs/metrics.md, after METRICS.md).

Array layout, shared by every function:

* ``robot_pos (T+1, 2)``: the robot's position at every step, the start included (T steps);
* ``robot_yaw (T+1,)``: its yaw (rad), where a metric needs it;
* ``human_pos (T+1, H, 2)``, ``human_vel (T+1, H, 2)``: the people (H may be 0);
* radii in metres (``human_radius`` a scalar or ``(H,)``), ``dt`` the control period (s).

Conventions (docs/metrics.md has the full table):

* A robot-person *gap* is edge-to-edge: centre distance minus both radii.
* Per-step social metrics are evaluated at the samples ``t = 1..T``, the state after each of the T steps
  (the start is not a step), so "share of steps" always divides by T.
* Velocities not given are backward differences ``v_t = (x_t - x_{t-1}) / dt`` (the velocity that brought
  the body to ``x_t``, what a sensor reports at ``t``); ``v_0 = v_1``.
* Undefined values are ``nan`` (e.g. navigation time of a failed episode), "nothing there" is ``inf``
  (minimum distance without people). :func:`mean_ci` skips both.
* Every threshold is a keyword parameter whose default is the METRICS.md value; :class:`Thresholds` groups
  them for :func:`episode_metrics`, which reports the values it used.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import asdict, dataclass, replace
from typing import Any

import numpy as np

__all__ = [
    "Thresholds",
    "accelerations",
    "aggregate_discomfort",
    "aggregate_episodes",
    "classify_trajectory",
    "discomfort",
    "discomfort_stats",
    "episode_metrics",
    "episode_summary",
    "event_from_flags",
    "extra_time_to_goal",
    "heading_change",
    "intrusion_time_ratio",
    "is_stuck",
    "jerks",
    "mean_ci",
    "mean_navigation_time",
    "min_person_distance",
    "motion_headings",
    "motion_stats",
    "multi_robot_summary",
    "navigation_time",
    "outcome_from_event",
    "path_irregularity",
    "path_length",
    "path_length_ratio",
    "path_turning",
    "pedestrian_disturbance_local",
    "pedestrian_disturbance_rerun",
    "person_gaps",
    "personal_space_cost",
    "proxemic_shares",
    "social_work",
    "speeds",
    "spl",
    "swept_obstacle_collisions",
    "swept_person_collisions",
    "swept_person_gaps",
    "time_to_collision",
    "ttc_stats",
    "wrap_angle",
]

_EPS = 1e-12

# Outcome event strings, as NavEnv reports them in info["event"].
GOAL, TIMEOUT = "goal", "timeout"
COLLISION_HUMAN, COLLISION_OBSTACLE, COLLISION_ROBOT = (
    "collision_human",
    "collision_obstacle",
    "collision_robot",
)


# ---------------------------------------------------------------------------------------------------------
# Array helpers
# ---------------------------------------------------------------------------------------------------------


def wrap_angle(a: np.ndarray | float) -> np.ndarray | float:
    """Angle(s) wrapped to [-pi, pi)."""
    return (np.asarray(a, dtype=np.float64) + np.pi) % (2.0 * np.pi) - np.pi


def _pos(robot_pos: np.ndarray) -> np.ndarray:
    p = np.asarray(robot_pos, dtype=np.float64)
    if p.ndim != 2 or p.shape[1] != 2:
        raise ValueError(f"robot_pos must have shape (T+1, 2), got {p.shape}")
    return p


def _humans(human_pos: np.ndarray | None, n: int) -> np.ndarray:
    """``human_pos`` as (n, H, 2); None, an empty array or H = 0 give (n, 0, 2)."""
    if human_pos is None:
        return np.zeros((n, 0, 2))
    h = np.asarray(human_pos, dtype=np.float64)
    if h.size == 0:
        return np.zeros((n, 0, 2))
    if h.ndim != 3 or h.shape[2] != 2 or h.shape[0] != n:
        raise ValueError(f"human_pos must have shape ({n}, H, 2), got {h.shape}")
    return h


def _radii(human_radius: np.ndarray | float, h: int) -> np.ndarray:
    r = np.asarray(human_radius, dtype=np.float64)
    return np.full(h, float(r)) if r.ndim == 0 else r.reshape(h)


def _velocities(pos: np.ndarray, dt: float, given: np.ndarray | None = None) -> np.ndarray:
    """Velocities at every sample, same shape as ``pos``: ``given``, else backward differences (v_0 = v_1)."""
    if given is not None:
        v = np.asarray(given, dtype=np.float64)
        if v.size == 0:
            return np.zeros_like(pos)
        if v.shape != pos.shape:
            raise ValueError(f"velocities must have shape {pos.shape}, got {v.shape}")
        return v
    v = np.zeros_like(pos)
    if len(pos) > 1:
        v[1:] = np.diff(pos, axis=0) / dt
        v[0] = v[1]
    return v


def _mean(x: np.ndarray) -> float:
    return float(np.mean(x)) if np.size(x) else float("nan")


def _max(x: np.ndarray) -> float:
    return float(np.max(x)) if np.size(x) else float("nan")


# ---------------------------------------------------------------------------------------------------------
# Outcome
# ---------------------------------------------------------------------------------------------------------


def outcome_from_event(event: str) -> dict[str, bool]:
    """Outcome flags of an episode from its event string (NavEnv's ``info["event"]``).

    ``"goal"`` is a success; ``"collision_human" | "collision_obstacle" | "collision_robot"`` are collisions
    (each also reported on its own); ``"timeout"`` is the time limit. Anything else (``"nan_state"``,
    ``"running"``) is none of these: a failure that is neither a collision nor a timeout.
    """
    return {
        "success": event == GOAL,
        "collision": event.startswith("collision"),
        "human_collision": event == COLLISION_HUMAN,
        "obstacle_collision": event == COLLISION_OBSTACLE,
        "robot_collision": event == COLLISION_ROBOT,
        "timeout": event == TIMEOUT,
    }


def event_from_flags(
    reached: bool,
    human_collision: bool = False,
    obstacle_collision: bool = False,
    robot_collision: bool = False,
    timed_out: bool = False,
) -> str:
    """The event string from the flags of the step that ended the episode.

    Precedence: a collision beats reaching the goal (METRICS.md: success is "without any collision"), human
    before obstacle before robot when several happen in one step; then goal; then timeout; else ``"running"``.
    """
    if human_collision:
        return COLLISION_HUMAN
    if obstacle_collision:
        return COLLISION_OBSTACLE
    if robot_collision:
        return COLLISION_ROBOT
    if reached:
        return GOAL
    return TIMEOUT if timed_out else "running"


def _segment_origin_distance(p0: np.ndarray, p1: np.ndarray) -> np.ndarray:
    """Distance from the origin to the segments p0 -> p1 (..., 2) -> (...)."""
    d = p1 - p0
    dd = np.einsum("...k,...k->...", d, d)
    s = np.clip(-np.einsum("...k,...k->...", p0, d) / np.maximum(dd, _EPS), 0.0, 1.0)
    return np.linalg.norm(p0 + s[..., None] * d, axis=-1)


def _present_only(gaps: np.ndarray, present: np.ndarray | None) -> np.ndarray:
    """``gaps`` with absent people's entries at inf (``present`` of the same shape, or None: unchanged)."""
    if present is None:
        return gaps
    return np.where(np.asarray(present, dtype=bool).reshape(gaps.shape), gaps, np.inf)


def swept_person_gaps(
    robot_pos: np.ndarray, human_pos: np.ndarray, robot_radius: float, human_radius: np.ndarray | float,
    present: np.ndarray | None = None,
) -> np.ndarray:
    """Smallest edge-to-edge robot-person gap within each step, ``(T, H)`` m (CrowdNav's swept test).

    Robot and person both move linearly during step t (sample t -> t+1), so their relative position moves
    along the segment ``r_t - h_t -> r_{t+1} - h_{t+1}``; the gap is that segment's distance to the origin
    minus both radii. It is <= the gaps at both end samples, so fast bodies cannot pass through each other
    unnoticed.

    ``present`` ``(T+1, H)`` bool (replayed people, who appear and leave): a person absent at the end of a step
    has no gap in it (inf); one who appears during a step is tested where they appear, at the step's end, not
    along the jump from where they were kept while absent.
    """
    rp = _pos(robot_pos)
    hp = _humans(human_pos, len(rp))
    rel = rp[:, None, :] - hp  # (T+1, H, 2)
    start = rel[:-1]
    if present is not None:
        present = np.asarray(present, dtype=bool).reshape(hp.shape[:2])
        appears = ~present[:-1] & present[1:]
        start = np.where(appears[..., None], rp[:-1, None, :] - hp[1:], start)  # the robot moves, the person not
    d = _segment_origin_distance(start, rel[1:])
    gaps = d - robot_radius - _radii(human_radius, hp.shape[1])[None, :]
    return _present_only(gaps, None if present is None else present[1:])


def swept_person_collisions(
    robot_pos: np.ndarray,
    human_pos: np.ndarray,
    robot_radius: float,
    human_radius: np.ndarray | float,
    tolerance: float = 0.0,
    present: np.ndarray | None = None,
) -> np.ndarray:
    """``(T, H)`` bool: robot and person overlap at some time during the step (swept gap < -tolerance);
    ``present`` as :func:`swept_person_gaps`."""
    return swept_person_gaps(robot_pos, human_pos, robot_radius, human_radius, present) < -tolerance


def swept_obstacle_collisions(
    robot_pos: np.ndarray, robot_radius: float, segments: np.ndarray, tolerance: float = 0.0
) -> np.ndarray:
    """``(T,)`` bool: the robot's disc, swept along its motion in the step, touches a wall segment ``(M, 2, 2)``.

    Uses :func:`navzoo.world.geometry.swept_circle_hits_segments` with radius ``robot_radius - tolerance``.
    """
    from navzoo.world.geometry import swept_circle_hits_segments

    rp = _pos(robot_pos)
    if len(rp) < 2:
        return np.zeros(0, dtype=bool)
    return swept_circle_hits_segments(rp[:-1], rp[1:], robot_radius - tolerance, segments)


def classify_trajectory(
    robot_pos: np.ndarray,
    goal: np.ndarray,
    human_pos: np.ndarray | None,
    robot_radius: float,
    human_radius: np.ndarray | float,
    dt: float,
    time_limit: float,
    *,
    segments: np.ndarray | None = None,
    goal_tolerance: float | None = None,
    collision_tolerance: float = 0.0,
) -> dict[str, Any]:
    """Outcome from the arrays alone: the first step with a swept collision or the goal reached ends it.

    The goal is reached at sample t when ``||x_t - goal|| < goal_tolerance`` (default: the robot radius, as
    CrowdNav). In the same step a collision beats the goal (:func:`event_from_flags`). Without either, the
    event is ``"timeout"`` if ``T * dt`` reaches ``time_limit``, else ``"running"``.

    Returns ``{"event": str, "end_step": int}`` (``end_step`` = T when nothing ended the episode).
    """
    rp = _pos(robot_pos)
    n_steps = len(rp) - 1
    tol = robot_radius if goal_tolerance is None else goal_tolerance
    hum = swept_person_collisions(rp, human_pos, robot_radius, human_radius, collision_tolerance).any(axis=1)
    obs = (
        swept_obstacle_collisions(rp, robot_radius, segments, collision_tolerance)
        if segments is not None and np.size(segments)
        else np.zeros(n_steps, dtype=bool)
    )
    reached = np.linalg.norm(rp[1:] - np.asarray(goal, dtype=np.float64), axis=1) < tol
    ended = np.flatnonzero(hum | obs | reached)
    if ended.size:
        k = int(ended[0])
        return {"event": event_from_flags(bool(reached[k]), bool(hum[k]), bool(obs[k])), "end_step": k + 1}
    timed_out = n_steps * dt >= time_limit - 1e-9
    return {"event": TIMEOUT if timed_out else "running", "end_step": n_steps}


def is_stuck(
    robot_pos: np.ndarray,
    dt: float,
    robot_yaw: np.ndarray | None = None,
    *,
    window_s: float = 10.0,
    min_displacement: float = 0.2,
    min_turn_deg: float = 15.0,
) -> bool:
    """The robot moved < ``min_displacement`` m and turned < ``min_turn_deg`` over the last ``window_s``.

    Net change between the sample ``window_s`` before the end and the last sample: displacement
    ``||x_T - x_{T-W}||`` and yaw change ``|wrap(yaw_T - yaw_{T-W})|`` (W = round(window_s / dt)); a robot
    oscillating in place is stuck, one that drove away and back is too (rare; docs/metrics.md). Without
    ``robot_yaw`` only the displacement counts. An episode shorter than the window is never stuck.
    """
    rp = _pos(robot_pos)
    w = int(round(window_s / dt))
    if len(rp) - 1 < w or w <= 0:
        return False
    if np.linalg.norm(rp[-1] - rp[-1 - w]) >= min_displacement:
        return False
    if robot_yaw is not None:
        yaw = np.asarray(robot_yaw, dtype=np.float64)
        if abs(float(wrap_angle(yaw[-1] - yaw[-1 - w]))) >= math.radians(min_turn_deg):
            return False
    return True


# ---------------------------------------------------------------------------------------------------------
# Efficiency
# ---------------------------------------------------------------------------------------------------------


def path_length(pos: np.ndarray) -> float:
    """Sum of step lengths ||x_{t+1} - x_t|| (m)."""
    pos = np.asarray(pos, dtype=np.float64)
    return float(np.linalg.norm(np.diff(pos, axis=0), axis=1).sum()) if len(pos) > 1 else 0.0


def navigation_time(steps: int, dt: float, success: bool) -> float:
    """Time to the goal (s) of one episode: ``steps * dt`` if it succeeded, else nan (not counted)."""
    return steps * dt if success else float("nan")


def mean_navigation_time(times: Iterable[float], successes: Iterable[bool], time_limit: float) -> float:
    """CrowdNav's navigation time: mean over the successful episodes; ``time_limit`` if there is none."""
    ok = [float(t) for t, s in zip(times, successes, strict=True) if s]
    return float(np.mean(ok)) if ok else float(time_limit)


def path_length_ratio(robot_pos: np.ndarray, goal: np.ndarray) -> float:
    """Path length / straight-line distance from the start to ``goal`` (>= 1 for a path that reaches it).

    nan when the goal is at the start.
    """
    rp = _pos(robot_pos)
    straight = float(np.linalg.norm(np.asarray(goal, dtype=np.float64) - rp[0]))
    return path_length(rp) / straight if straight > _EPS else float("nan")


def spl(success: bool, length: float, shortest: float) -> float:
    """Success weighted by path length: ``success * l* / max(l, l*)``; ``l* <= 0`` gives ``success``."""
    if shortest <= 0:
        return float(success)
    return float(success) * shortest / max(length, shortest)


def extra_time_to_goal(time_s: float, shortest_path: float, v_pref: float) -> float:
    """``t - l* / v_pref`` (s): time beyond driving the shortest path at the preferred speed."""
    return float(time_s) - float(shortest_path) / float(v_pref)


# ---------------------------------------------------------------------------------------------------------
# Smoothness
# ---------------------------------------------------------------------------------------------------------


def speeds(pos: np.ndarray, dt: float) -> np.ndarray:
    """``||x_{t+1} - x_t|| / dt``, ``(T,)`` m/s."""
    return np.linalg.norm(np.diff(_pos(pos), axis=0), axis=1) / dt


def accelerations(pos: np.ndarray, dt: float) -> np.ndarray:
    """``||x_{t+2} - 2 x_{t+1} + x_t|| / dt^2``, ``(T-1,)`` m/s^2: the acceleration vector's norm."""
    return np.linalg.norm(np.diff(_pos(pos), n=2, axis=0), axis=1) / dt**2


def jerks(pos: np.ndarray, dt: float) -> np.ndarray:
    """Third differences ``||Δ^3 x|| / dt^3``, ``(T-2,)`` m/s^3."""
    return np.linalg.norm(np.diff(_pos(pos), n=3, axis=0), axis=1) / dt**3


def motion_stats(pos: np.ndarray, dt: float) -> dict[str, float]:
    """Mean and max of :func:`speeds`, :func:`accelerations` and :func:`jerks` (nan where too short)."""
    v, a, j = speeds(pos, dt), accelerations(pos, dt), jerks(pos, dt)
    return {
        "mean_speed": _mean(v),
        "max_speed": _max(v),
        "mean_accel": _mean(a),
        "max_accel": _max(a),
        "mean_jerk": _mean(j),
        "max_jerk": _max(j),
    }


def heading_change(headings: np.ndarray) -> float:
    """Cumulative heading change ``sum |wrap(h_{t+1} - h_t)|`` (rad) of a heading sequence."""
    h = np.asarray(headings, dtype=np.float64)
    return float(np.abs(wrap_angle(np.diff(h))).sum()) if h.size > 1 else 0.0


def _decimate(path: np.ndarray, min_step: float) -> np.ndarray:
    """Keep the points at least ``min_step`` from the previously kept one (the first always kept)."""
    keep = [path[0]]
    for p in path[1:]:
        if np.linalg.norm(p - keep[-1]) >= min_step:
            keep.append(p)
    return np.asarray(keep)


def motion_headings(path: np.ndarray, min_step: float = 1e-3) -> np.ndarray:
    """Directions (rad) of a path's motion, one per step of at least ``min_step`` m.

    Steps are taken between points at least ``min_step`` apart (shorter moves accumulate until they reach
    it), so a robot that stands still or jitters in place adds no spurious heading changes.
    """
    p = np.asarray(path, dtype=np.float64)
    if len(p) < 2:
        return np.zeros(0)
    d = np.diff(_decimate(p, min_step), axis=0)
    return np.arctan2(d[:, 1], d[:, 0])


def path_turning(path: np.ndarray, min_step: float = 1e-3) -> float:
    """Total turning of a path (rad): :func:`heading_change` of its :func:`motion_headings`.

    The geometric total absolute curvature of the polyline: initial and final directions are free, turning
    in place is not included (it is in the yaw's :func:`heading_change`).
    """
    return heading_change(motion_headings(path, min_step))


def path_irregularity(
    robot_pos: np.ndarray,
    reference_path: np.ndarray | None = None,
    goal: np.ndarray | None = None,
    *,
    min_step: float = 1e-3,
) -> float:
    """Turning per metre beyond what the shortest path needs (rad/m).

    ``max(0, turning(robot path) - turning(reference path)) / length(robot path)`` with
    :func:`path_turning`. The reference is the shortest collision-free path from start to goal
    (``reference_path (K, 2)``, e.g. NavEnv's smoothed A* path; the robot's start is prepended when it is not
    its first point); without it, the straight line to ``goal`` (no turning). 0 for a path without length.

    A straight path scores 0; so does a path that turns exactly as much as the shortest path must (around a
    corner); every extra radian of turning costs ``1 / length``. SocNavBench's ``path_irregularity`` is not
    this: it averages over the steps the angle between the position vector ``x_t`` (from the world origin)
    and the vector to the goal, an angle that depends on where the map's origin is, not on the robot's
    turning, and whose docstring's rad/m it never divides by. docs/metrics.md.
    """
    rp = _pos(robot_pos)
    length = path_length(rp)
    if length <= _EPS:
        return 0.0
    ref_turn = 0.0
    if reference_path is not None:
        ref = np.asarray(reference_path, dtype=np.float64).reshape(-1, 2)
        if len(ref) == 0 or np.linalg.norm(ref[0] - rp[0]) > min_step:
            ref = np.vstack([rp[:1], ref])
        ref_turn = path_turning(ref, min_step)
    elif goal is None:
        raise ValueError("path_irregularity needs reference_path or goal")
    return max(0.0, path_turning(rp, min_step) - ref_turn) / length


# ---------------------------------------------------------------------------------------------------------
# Social
# ---------------------------------------------------------------------------------------------------------


def person_gaps(
    robot_pos: np.ndarray, human_pos: np.ndarray, robot_radius: float, human_radius: np.ndarray | float
) -> np.ndarray:
    """Edge-to-edge robot-person distances (T+1, H) (centre distance minus both radii)."""
    robot_pos = np.asarray(robot_pos, dtype=np.float64)
    human_pos = np.asarray(human_pos, dtype=np.float64)
    if human_pos.ndim != 3 or human_pos.shape[1] == 0:
        return np.full((len(robot_pos), 0), np.inf)
    d = np.linalg.norm(human_pos - robot_pos[:, None, :], axis=2)
    return d - robot_radius - np.asarray(human_radius, dtype=np.float64)


def _step_gaps(
    robot_pos: np.ndarray,
    human_pos: np.ndarray | None,
    robot_radius: float,
    human_radius: np.ndarray | float,
    swept: bool,
    present: np.ndarray | None = None,
) -> np.ndarray:
    """(T, H) gap per step: the swept minimum within the step, or the gap at the step's end sample; ``present``
    as :func:`swept_person_gaps` (absent people: inf)."""
    if swept:
        return swept_person_gaps(robot_pos, human_pos, robot_radius, human_radius, present)
    rp = _pos(robot_pos)
    hp = _humans(human_pos, len(rp))
    g = person_gaps(rp, hp, robot_radius, _radii(human_radius, hp.shape[1]))[1:].reshape(len(rp) - 1, hp.shape[1])
    return _present_only(g, None if present is None else np.asarray(present).reshape(len(rp), hp.shape[1])[1:])


def min_person_distance(
    robot_pos: np.ndarray,
    human_pos: np.ndarray | None,
    robot_radius: float,
    human_radius: np.ndarray | float,
    swept: bool = True,
    present: np.ndarray | None = None,
) -> float:
    """Minimum edge-to-edge distance to any person over the episode (m); inf without people.

    ``swept`` (default): the minimum over each step's linear motion (:func:`swept_person_gaps`), which is
    also the minimum over all samples; else over the samples only. ``present`` ``(T+1, H)``: only people
    present count (:func:`swept_person_gaps`).
    """
    rp = _pos(robot_pos)
    if not swept or len(rp) < 2:
        hp = _humans(human_pos, len(rp))
        g = _present_only(person_gaps(rp, hp, robot_radius, _radii(human_radius, hp.shape[1])), present)
    else:
        g = swept_person_gaps(rp, human_pos, robot_radius, human_radius, present)
    return float(g.min()) if g.size else float("inf")


def discomfort_stats(
    robot_pos: np.ndarray,
    human_pos: np.ndarray | None,
    robot_radius: float,
    human_radius: np.ndarray | float,
    threshold: float = 0.2,
    swept: bool = True,
    present: np.ndarray | None = None,
) -> dict[str, float]:
    """CrowdNav's discomfort of one episode (``present``: only people present count, :func:`swept_person_gaps`).

    A step is a discomfort step when its smallest robot-person gap (swept within the step, as CrowdNav's
    ``dmin``, or at its end sample with ``swept=False``) is below ``threshold``. Returns ``steps`` (discomfort
    steps), ``total_steps`` (T), ``gap_sum_m`` (sum of those steps' minimum gaps, for pooling),
    ``frequency`` (steps / T) and ``mean_min_gap_m`` (gap_sum / steps, nan without discomfort steps).
    """
    g = _step_gaps(robot_pos, human_pos, robot_radius, human_radius, swept, present)
    total = g.shape[0]
    if g.shape[1] == 0 or total == 0:
        gmin = np.full(total, np.inf)
    else:
        gmin = g.min(axis=1)
    hit = gmin < threshold
    n = int(hit.sum())
    gap_sum = float(gmin[hit].sum())
    return {
        "steps": n,
        "total_steps": int(total),
        "gap_sum_m": gap_sum,
        "frequency": n / total if total else 0.0,
        "mean_min_gap_m": gap_sum / n if n else float("nan"),
    }


def discomfort(
    robot_pos: np.ndarray,
    human_pos: np.ndarray | None,
    robot_radius: float,
    human_radius: np.ndarray | float,
    threshold: float = 0.2,
    swept: bool = True,
) -> tuple[int, int]:
    """(steps with a robot-person gap below ``threshold``, all steps) — CrowdNav's discomfort count."""
    s = discomfort_stats(robot_pos, human_pos, robot_radius, human_radius, threshold, swept)
    return int(s["steps"]), int(s["total_steps"])


def aggregate_discomfort(episodes: Iterable[Mapping[str, float]]) -> dict[str, float]:
    """Pool :func:`discomfort_stats` of many episodes: discomfort steps / all steps of all episodes, and the
    mean minimum gap over all discomfort steps. Accepts its dicts or :func:`episode_metrics` dicts."""
    n = total = 0
    gap = 0.0
    for e in episodes:
        if "discomfort_steps" in e:  # an episode_metrics dict
            n += int(e["discomfort_steps"])
            total += int(e["total_steps"])
            gap += float(e["discomfort_gap_sum_m"])
        else:  # a discomfort_stats dict
            n += int(e["steps"])
            total += int(e["total_steps"])
            gap += float(e["gap_sum_m"])
    return {
        "discomfort_frequency": n / total if total else 0.0,
        "discomfort_mean_min_gap_m": gap / n if n else float("nan"),
        "discomfort_steps": n,
        "total_steps": total,
    }


def proxemic_shares(
    robot_pos: np.ndarray,
    human_pos: np.ndarray | None,
    robot_radius: float,
    human_radius: np.ndarray | float,
    zones: Sequence[float] = (0.45, 1.2, 3.6),
) -> dict[str, float]:
    """Share of the samples t = 1..T at which the closest person's gap is in each proxemic zone.

    ``zones = (intimate, personal, social)`` upper bounds: intimate ``g < 0.45``, personal ``0.45 <= g < 1.2``,
    social ``1.2 <= g < 3.6``, public ``g >= 3.6`` or nobody (the four shares sum to 1; 0 each for T = 0).
    """
    rp = _pos(robot_pos)
    hp = _humans(human_pos, len(rp))
    t = len(rp) - 1
    if t <= 0:
        return {"intimate": 0.0, "personal": 0.0, "social": 0.0, "public": 0.0}
    g = person_gaps(rp, hp, robot_radius, _radii(human_radius, hp.shape[1]))[1:]
    gmin = g.min(axis=1) if g.shape[1] else np.full(t, np.inf)
    z1, z2, z3 = zones
    return {
        "intimate": float(np.mean(gmin < z1)),
        "personal": float(np.mean((gmin >= z1) & (gmin < z2))),
        "social": float(np.mean((gmin >= z2) & (gmin < z3))),
        "public": float(np.mean(gmin >= z3)),
    }


def intrusion_time_ratio(
    robot_pos: np.ndarray,
    human_pos: np.ndarray | None,
    robot_radius: float,
    human_radius: np.ndarray | float,
    dt: float,
    horizon_s: float = 1.25,
) -> float:
    """CrowdNav++'s intrusion time ratio: share of the samples t = 1..T at which the robot's position is
    within the sum of radii of any person's recorded position at t + k, k = 1..K, K = floor(horizon_s / dt).

    Future samples past the end of the recording are not available (the last K samples look less far ahead).
    """
    rp = _pos(robot_pos)
    hp = _humans(human_pos, len(rp))
    t = len(rp) - 1
    if t <= 0:
        return 0.0
    if hp.shape[1] == 0:
        return 0.0
    k_max = int(math.floor(horizon_s / dt + 1e-9))
    contact = robot_radius + _radii(human_radius, hp.shape[1])
    hit = np.zeros(t + 1, dtype=bool)
    for k in range(1, k_max + 1):
        if k > t:
            break
        d = np.linalg.norm(hp[k:] - rp[: t + 1 - k, None, :], axis=2)  # robot at s, people at s + k
        hit[: t + 1 - k] |= (d < contact).any(axis=1)
    return float(hit[1:].mean())


def time_to_collision(rel_pos: np.ndarray, rel_vel: np.ndarray, radius_sum: np.ndarray | float) -> np.ndarray:
    """Time (s) until two discs touch at constant velocities; 0 if they overlap, inf if they never touch.

    ``rel_pos = x_other - x_self``, ``rel_vel = v_other - v_self`` (..., 2); solves
    ``||rel_pos + rel_vel * tau|| = radius_sum`` for the smallest tau >= 0.
    """
    p = np.asarray(rel_pos, dtype=np.float64)
    v = np.asarray(rel_vel, dtype=np.float64)
    a = np.einsum("...k,...k->...", v, v)
    b = np.einsum("...k,...k->...", p, v)  # half of the linear coefficient
    c = np.einsum("...k,...k->...", p, p) - np.asarray(radius_sum, dtype=np.float64) ** 2
    disc = b * b - a * c
    approaching = (b < 0) & (a > _EPS) & (disc >= 0)
    tau = np.where(approaching, (-b - np.sqrt(np.maximum(disc, 0.0))) / np.maximum(a, _EPS), np.inf)
    return np.where(c <= 0, 0.0, tau)


def ttc_stats(
    robot_pos: np.ndarray,
    human_pos: np.ndarray | None,
    robot_radius: float,
    human_radius: np.ndarray | float,
    dt: float,
    robot_vel: np.ndarray | None = None,
    human_vel: np.ndarray | None = None,
    threshold_s: float = 1.0,
) -> dict[str, Any]:
    """Per-sample TTC (t = 1..T): the smallest :func:`time_to_collision` over people, constant velocities.

    Velocities default to backward differences (module docstring). Returns ``ttc (T,)`` (inf without people
    or when nobody approaches), ``min_ttc_s`` and ``below`` (share of samples with TTC < ``threshold_s``).
    """
    rp = _pos(robot_pos)
    hp = _humans(human_pos, len(rp))
    t = len(rp) - 1
    if t <= 0 or hp.shape[1] == 0:
        ttc = np.full(max(t, 0), np.inf)
    else:
        rv = _velocities(rp, dt, robot_vel)
        hv = _velocities(hp, dt, human_vel)
        contact = robot_radius + _radii(human_radius, hp.shape[1])
        ttc = time_to_collision(hp[1:] - rp[1:, None], hv[1:] - rv[1:, None], contact).min(axis=1)
    return {
        "ttc": ttc,
        "min_ttc_s": float(ttc.min()) if ttc.size else float("inf"),
        "below": float(np.mean(ttc < threshold_s)) if ttc.size else 0.0,
    }


def _forward_fill_headings(vel: np.ndarray, min_speed: float) -> tuple[np.ndarray, np.ndarray]:
    """Heading (n, H) of each person from its velocity, held over samples slower than ``min_speed``;
    second output: whether a heading is known yet."""
    speed = np.linalg.norm(vel, axis=-1)
    moving = speed > min_speed
    ang = np.arctan2(vel[..., 1], vel[..., 0])
    idx = np.where(moving, np.arange(len(vel))[:, None], 0)
    idx = np.maximum.accumulate(idx, axis=0)
    known = np.maximum.accumulate(moving, axis=0)
    return np.take_along_axis(ang, idx, axis=0), known


def personal_space_cost(
    robot_pos: np.ndarray,
    human_pos: np.ndarray | None,
    robot_radius: float,
    human_radius: np.ndarray | float,
    dt: float,
    human_vel: np.ndarray | None = None,
    human_yaw: np.ndarray | None = None,
    *,
    min_sigma: float = 0.5,
    speed_gain: float = 2.0,
    side_ratio: float = 0.25,
    rear_ratio: float = 1.0 / 3.0,
    edge_to_edge: bool = True,
) -> dict[str, Any]:
    """Asymmetric-Gaussian personal-space cost, summed over people and the samples t = 1..T.

    Around person j (speed v, heading theta): ``sigma = max(speed_gain * v, min_sigma)`` in front,
    ``sigma * side_ratio`` to the sides, ``sigma * rear_ratio`` behind (METRICS.md / SocNavBench's
    ``asym_gauss``: front max(2v, 0.5), side sigma/4, rear sigma/3). With the robot's offset from the person
    split into ``f`` along the heading and ``s`` across it, the cost is
    ``exp(-(f^2 / (2 sigma_f^2) + s^2 / (2 sigma_side^2)))`` with ``sigma_f`` the front sigma if f > 0 else
    the rear one, 1 at contact. The offset is edge-to-edge (its length the gap, 0 when overlapping) unless
    ``edge_to_edge=False`` (centre to centre). The heading is ``human_yaw`` if given, else the velocity's
    direction, held while the person stands (< 1 cm/s); a person never seen moving is isotropic (front
    sigma all round).

    Returns ``total`` (the sum), ``per_step`` ``(T,)`` (sum over people) and ``mean`` (total / T).
    """
    rp = _pos(robot_pos)
    hp = _humans(human_pos, len(rp))
    t = len(rp) - 1
    if t <= 0 or hp.shape[1] == 0:
        per = np.zeros(max(t, 0))
        return {"total": 0.0, "per_step": per, "mean": 0.0 if t > 0 else float("nan")}
    hv = _velocities(hp, dt, human_vel)
    if human_yaw is not None:
        theta = np.asarray(human_yaw, dtype=np.float64).reshape(len(rp), hp.shape[1])
        known = np.ones_like(theta, dtype=bool)
    else:
        theta, known = _forward_fill_headings(hv, 0.01)
    speed = np.linalg.norm(hv, axis=-1)
    off = rp[:, None, :] - hp  # person -> robot
    dist = np.linalg.norm(off, axis=-1)
    if edge_to_edge:
        gap = np.maximum(dist - robot_radius - _radii(human_radius, hp.shape[1])[None, :], 0.0)
        off = off * (gap / np.maximum(dist, _EPS))[..., None]
    e = np.stack([np.cos(theta), np.sin(theta)], axis=-1)
    f = np.einsum("thk,thk->th", off, e)
    s = e[..., 0] * off[..., 1] - e[..., 1] * off[..., 0]
    sig = np.maximum(speed_gain * speed, min_sigma)
    sig_f = np.where(f > 0, sig, sig * rear_ratio)
    sig_s = sig * side_ratio
    iso = np.exp(-np.einsum("thk,thk->th", off, off) / (2 * sig**2))
    cost = np.where(known, np.exp(-(f**2 / (2 * sig_f**2) + s**2 / (2 * sig_s**2))), iso)[1:]
    per = cost.sum(axis=1)
    return {"total": float(per.sum()), "per_step": per, "mean": float(per.mean())}


def pedestrian_disturbance_rerun(
    human_pos: np.ndarray, human_pos_rerun: np.ndarray, dt: float, *, min_speed: float = 0.05
) -> dict[str, float]:
    """Disturbance against a rerun without the robot (same seed): how each person's path, speed and heading
    differ, averaged over people and the samples t = 1..L both recordings have.

    ``path_deviation_m``: mean ||p_t - p'_t||; ``max_path_deviation_m``: its max; ``speed_change_mps``: mean
    |speed_t - speed'_t|; ``heading_change_rad``: mean |wrap(theta_t - theta'_t)| over samples where both
    walk faster than ``min_speed`` (velocities: backward differences). Both arrays ``(*, H, 2)``.
    """
    a = np.asarray(human_pos, dtype=np.float64)
    b = np.asarray(human_pos_rerun, dtype=np.float64)
    if a.ndim != 3 or b.ndim != 3 or a.shape[1:] != b.shape[1:]:
        raise ValueError(f"human_pos {a.shape} and human_pos_rerun {b.shape} must both be (T+1, H, 2)")
    n = min(len(a), len(b))
    keys = ("path_deviation_m", "max_path_deviation_m", "speed_change_mps", "heading_change_rad")
    if a.shape[1] == 0:
        return dict.fromkeys(keys, 0.0)
    if n < 2:
        return dict.fromkeys(keys, float("nan"))
    a, b = a[:n], b[:n]
    dev = np.linalg.norm(a - b, axis=-1)[1:]
    va, vb = np.diff(a, axis=0) / dt, np.diff(b, axis=0) / dt
    sa, sb = np.linalg.norm(va, axis=-1), np.linalg.norm(vb, axis=-1)
    both = (sa > min_speed) & (sb > min_speed)
    dh = np.abs(wrap_angle(np.arctan2(va[..., 1], va[..., 0]) - np.arctan2(vb[..., 1], vb[..., 0])))
    return {
        "path_deviation_m": float(dev.mean()),
        "max_path_deviation_m": float(dev.max()),
        "speed_change_mps": float(np.abs(sa - sb).mean()),
        "heading_change_rad": float(dh[both].mean()) if both.any() else 0.0,
    }


def pedestrian_disturbance_local(
    robot_pos: np.ndarray,
    human_pos: np.ndarray | None,
    robot_radius: float,
    human_radius: np.ndarray | float,
    dt: float,
    human_vel: np.ndarray | None = None,
    *,
    radius: float = 3.0,
    min_speed: float = 0.05,
) -> dict[str, float]:
    """Disturbance without a rerun: lateral deviation and velocity loss of people near the robot.

    An *encounter* is a maximal run of samples ``a..b`` in which a person's gap to the robot is below
    ``radius``. Its reference is the sample before it, ``r = a - 1`` (``r = 0`` if it starts at 0): position
    ``p_r``, velocity ``v_r``, direction ``e`` and normal ``n``. During the encounter the person's lateral
    deviation is ``|(p_t - p_r) . n|`` (for a person standing at r, slower than ``min_speed``: ``||p_t - p_r||``)
    and the velocity loss ``max(0, ||v_r|| - v_t . e)`` (0 for a standing person).

    Returns ``lateral_deviation_m`` (mean over encounters of each one's largest lateral deviation),
    ``max_lateral_deviation_m``, ``velocity_loss_mps`` (mean over all encounter samples) and ``encounters``;
    0 without encounters. People also turn on their own (their paths bend): prefer the rerun form.
    """
    rp = _pos(robot_pos)
    hp = _humans(human_pos, len(rp))
    empty = {
        "lateral_deviation_m": 0.0,
        "max_lateral_deviation_m": 0.0,
        "velocity_loss_mps": 0.0,
        "encounters": 0,
    }
    if hp.shape[1] == 0 or len(rp) < 2:
        return empty
    hv = _velocities(hp, dt, human_vel)
    near = person_gaps(rp, hp, robot_radius, _radii(human_radius, hp.shape[1])) < radius
    lateral, losses = [], []
    for j in range(hp.shape[1]):
        t = 0
        while t < len(rp):
            if not near[t, j]:
                t += 1
                continue
            a = t
            while t < len(rp) and near[t, j]:
                t += 1
            r = max(a - 1, 0)
            seg = slice(max(a, 1), t)  # the encounter's samples after the reference
            if seg.start >= seg.stop:
                continue
            vr = hv[r, j]
            sr = float(np.linalg.norm(vr))
            disp = hp[seg, j] - hp[r, j]
            if sr > min_speed:
                e = vr / sr
                lat = np.abs(e[0] * disp[:, 1] - e[1] * disp[:, 0])
                loss = np.maximum(0.0, sr - hv[seg, j] @ e)
            else:
                lat = np.linalg.norm(disp, axis=1)
                loss = np.zeros(len(disp))
            lateral.append(float(lat.max()))
            losses.extend(loss.tolist())
    if not lateral:
        return empty
    return {
        "lateral_deviation_m": float(np.mean(lateral)),
        "max_lateral_deviation_m": float(np.max(lateral)),
        "velocity_loss_mps": float(np.mean(losses)),
        "encounters": len(lateral),
    }


def social_work(
    robot_pos: np.ndarray,
    human_pos: np.ndarray | None,
    robot_radius: float,
    human_radius: np.ndarray | float,
    dt: float,
    robot_vel: np.ndarray | None = None,
    human_vel: np.ndarray | None = None,
    params: Any = None,
) -> dict[str, float]:
    """HuNavSim's social work, integrated over the samples t = 1..T (m/s: force per unit mass times time).

    At each sample: ``||sum_j F_j->robot|| + sum_j ||F_robot->j||``, times ``dt``. Both forces are the
    robot-person term of navzoo's social force model (``navzoo.agents.sfm.social_forces(...).robots``: the
    person-person interaction, elliptical specification II with anisotropy and the keep-right term, cut off
    at ``params.neighbor_dist``), the robot treated as one more person: for the force on the robot, the
    robot is the person and the people are the "others"; for the force on people, the reverse. Each body's
    heading is its velocity direction (no preferred velocities are recorded). Unlike HuNavSim, the wall
    force on the robot is not added (a social, not an obstacle, measure).

    Returns ``social_work`` (sum of both), ``on_robot`` and ``on_people``.
    """
    from navzoo.agents.sfm import SocialForceParams, _headings, _interaction

    rp = _pos(robot_pos)
    hp = _humans(human_pos, len(rp))
    if hp.shape[1] == 0 or len(rp) < 2:
        return {"social_work": 0.0, "on_robot": 0.0, "on_people": 0.0}
    params = params or SocialForceParams()
    t, h = len(rp) - 1, hp.shape[1]
    rv = _velocities(rp, dt, robot_vel)[1:]
    hv = _velocities(hp, dt, human_vel)[1:]
    rel = (rp[1:, None, :] - hp[1:]).reshape(-1, 2)  # robot - person, one row per (sample, person)
    rel_v = (rv[:, None, :] - hv).reshape(-1, 2)
    contact = np.broadcast_to(robot_radius + _radii(human_radius, h), (t, h)).reshape(-1)
    origin, zero_r = np.zeros((1, 2)), np.zeros(1)
    # The term depends on positions and velocities only through their differences, on the radii only
    # through their sum, and on the acting body's own heading: every pair is evaluated at once against a
    # body at rest at the origin (identical to social_forces(...).robots per step; tests/test_metrics.py).
    h_robot = np.repeat(_headings(rv, rv), h, axis=0)
    h_people = _headings(hv.reshape(-1, 2), hv.reshape(-1, 2))
    f_r = _interaction(rel, rel_v, h_robot, contact, origin, origin, zero_r, params, False)  # on the robot
    f_h = _interaction(-rel, -rel_v, h_people, contact, origin, origin, zero_r, params, False)  # on people
    on_robot = float(np.linalg.norm(f_r.reshape(t, h, 2).sum(axis=1), axis=1).sum()) * dt
    on_people = float(np.linalg.norm(f_h, axis=1).sum()) * dt
    return {"social_work": on_robot + on_people, "on_robot": on_robot, "on_people": on_people}


# ---------------------------------------------------------------------------------------------------------
# Multi-robot
# ---------------------------------------------------------------------------------------------------------


def multi_robot_summary(events: Sequence[str], end_steps: Sequence[int], dt: float) -> dict[str, Any]:
    """Outcomes of all robots of one episode.

    ``end_steps[i]``: the step at which robot i was done (goal, collision or the time limit). Returns
    ``per_robot`` (:func:`outcome_from_event` of each), ``success_rate`` / ``collision_rate`` (share of
    robots), ``all_success`` (every robot reached its goal), ``any_collision``, ``aggregated_time_s`` (time
    until all robots are done, whatever their outcome: ``max(end_steps) * dt``) and ``all_success_time_s``
    (the same when all succeeded, else nan).
    """
    if len(events) != len(end_steps):
        raise ValueError(f"{len(events)} events for {len(end_steps)} end steps")
    per = [outcome_from_event(e) for e in events]
    n = len(per)
    agg = max(end_steps) * dt if n else 0.0
    all_success = n > 0 and all(p["success"] for p in per)
    return {
        "per_robot": per,
        "success_rate": sum(p["success"] for p in per) / n if n else float("nan"),
        "collision_rate": sum(p["collision"] for p in per) / n if n else float("nan"),
        "all_success": all_success,
        "any_collision": any(p["collision"] for p in per),
        "aggregated_time_s": float(agg),
        "all_success_time_s": float(agg) if all_success else float("nan"),
    }


# ---------------------------------------------------------------------------------------------------------
# Aggregation
# ---------------------------------------------------------------------------------------------------------


def mean_ci(values: Iterable[float], confidence: float = 0.95, method: str = "t") -> dict[str, float]:
    """Mean and two-sided confidence interval of the finite values (nan and inf are skipped).

    ``method="t"``: Student t with n - 1 degrees of freedom, ``mean +- t * s / sqrt(n)`` (s: sample standard
    deviation); ``"normal"``: the normal quantile instead of t. For 0/1 outcomes (success rate) this is the
    Wald interval. n < 2 gives a nan half-width. Returns ``mean``, ``half_width``, ``low``, ``high``, ``n``.
    """
    x = np.asarray([float(v) for v in values], dtype=np.float64)
    x = x[np.isfinite(x)]
    n = int(x.size)
    if n == 0:
        return {
            "mean": float("nan"),
            "half_width": float("nan"),
            "low": float("nan"),
            "high": float("nan"),
            "n": 0,
        }
    m = float(x.mean())
    if n < 2:
        return {"mean": m, "half_width": float("nan"), "low": float("nan"), "high": float("nan"), "n": n}
    from scipy import stats

    q = (1.0 + confidence) / 2.0
    if method == "t":
        crit = float(stats.t.ppf(q, n - 1))
    elif method == "normal":
        crit = float(stats.norm.ppf(q))
    else:
        raise ValueError(f"method must be 't' or 'normal', got {method!r}")
    h = crit * float(x.std(ddof=1)) / math.sqrt(n)
    return {"mean": m, "half_width": h, "low": m - h, "high": m + h, "n": n}


def aggregate_episodes(
    episodes: Sequence[Mapping[str, Any]], confidence: float = 0.95, method: str = "t"
) -> dict[str, Any]:
    """Aggregate :func:`episode_metrics` dicts: :func:`mean_ci` of every numeric (or bool) metric, plus the
    pooled numbers METRICS.md defines over episodes.

    * ``nav_time_s``: mean over successful episodes (its per-episode value is nan otherwise) and, with no
      success, the time limit (``time_limit_s`` of the episodes) with n = 0;
    * ``discomfort_frequency`` / ``discomfort_mean_min_gap_m``: pooled over all steps of all episodes
      (:func:`aggregate_discomfort`), not a mean of per-episode ratios.

    Returns ``{"n_episodes": N, "metrics": {name: mean_ci dict}}``.
    """
    out: dict[str, Any] = {}
    keys: list[str] = []
    for e in episodes:
        for k, v in e.items():
            if k not in keys and isinstance(v, (bool, int, float, np.floating, np.integer)) and v is not None:
                keys.append(k)
    for k in keys:
        out[k] = mean_ci([float(e[k]) for e in episodes if k in e and e[k] is not None], confidence, method)
    if "nav_time_s" in out and out["nav_time_s"]["n"] == 0:
        limits = [float(e["time_limit_s"]) for e in episodes if np.isfinite(e.get("time_limit_s", np.nan))]
        if limits:
            out["nav_time_s"] = {**out["nav_time_s"], "mean": float(np.mean(limits))}
    if episodes and "discomfort_steps" in episodes[0]:
        pooled = aggregate_discomfort(episodes)
        out["discomfort_frequency"] = {
            **out.get("discomfort_frequency", {}),
            "mean": pooled["discomfort_frequency"],
            "pooled": True,
        }
        out["discomfort_mean_min_gap_m"] = {
            **out.get("discomfort_mean_min_gap_m", {}),
            "mean": pooled["discomfort_mean_min_gap_m"],
            "pooled": True,
        }
    return {"n_episodes": len(episodes), "metrics": out}


# ---------------------------------------------------------------------------------------------------------
# One episode, every metric
# ---------------------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class Thresholds:
    """Every threshold :func:`episode_metrics` uses, with the METRICS.md defaults."""

    goal_tolerance_m: float | None = None  # None: the robot radius (CrowdNav)
    collision_tolerance_m: float = 0.0  # swept tests: overlap deeper than this is a collision
    stuck_window_s: float = 10.0
    stuck_min_displacement_m: float = 0.2
    stuck_min_turn_deg: float = 15.0
    discomfort_m: float = 0.2
    proxemic_zones_m: tuple[float, float, float] = (0.45, 1.2, 3.6)
    intrusion_horizon_s: float = 1.25
    ttc_s: float = 1.0
    ps_min_sigma_m: float = 0.5
    ps_speed_gain_s: float = 2.0
    ps_side_ratio: float = 0.25
    ps_rear_ratio: float = 1.0 / 3.0
    disturbance_radius_m: float = 3.0
    heading_min_step_m: float = 1e-3

    def __post_init__(self) -> None:
        positive = (
            "stuck_window_s",
            "intrusion_horizon_s",
            "ps_min_sigma_m",
            "ps_side_ratio",
            "ps_rear_ratio",
            "disturbance_radius_m",
            "heading_min_step_m",
        )
        for name in positive:
            value = getattr(self, name)
            if not (np.isfinite(value) and value > 0):
                raise ValueError(f"Thresholds.{name} must be finite and > 0, got {value!r}")
        for name in (
            "collision_tolerance_m",
            "stuck_min_displacement_m",
            "stuck_min_turn_deg",
            "discomfort_m",
            "ttc_s",
            "ps_speed_gain_s",
        ):
            value = getattr(self, name)
            if not (np.isfinite(value) and value >= 0):
                raise ValueError(f"Thresholds.{name} must be finite and >= 0, got {value!r}")
        if self.goal_tolerance_m is not None and not self.goal_tolerance_m > 0:
            raise ValueError(
                f"Thresholds.goal_tolerance_m must be > 0 or None, got {self.goal_tolerance_m!r}"
            )
        zones = tuple(self.proxemic_zones_m)
        if len(zones) != 3 or not 0 < zones[0] < zones[1] < zones[2]:
            raise ValueError(
                f"Thresholds.proxemic_zones_m must be 3 increasing positive bounds, got {zones!r}"
            )
        object.__setattr__(self, "proxemic_zones_m", tuple(float(z) for z in zones))

    def as_dict(self) -> dict[str, Any]:
        d = asdict(self)
        d["proxemic_zones_m"] = list(self.proxemic_zones_m)
        return d


def episode_metrics(
    robot_pos: np.ndarray,
    human_pos: np.ndarray | None,
    robot_radius: float,
    human_radius: np.ndarray | float,
    dt: float,
    event: str | None = None,
    *,
    goal: np.ndarray | None = None,
    shortest_path: float | None = None,
    time_limit: float | None = None,
    v_pref: float | None = None,
    robot_yaw: np.ndarray | None = None,
    robot_vel: np.ndarray | None = None,
    human_vel: np.ndarray | None = None,
    human_yaw: np.ndarray | None = None,
    reference_path: np.ndarray | None = None,
    segments: np.ndarray | None = None,
    human_pos_rerun: np.ndarray | None = None,
    end_step: int | None = None,
    sfm_params: Any = None,
    thresholds: Thresholds | None = None,
    human_present: np.ndarray | None = None,
) -> dict[str, Any]:
    """Every per-episode metric of one robot, keyed by its METRICS.md name (docs/metrics.md lists them).

    Args:
        robot_pos, human_pos, robot_radius, human_radius, dt: the recording (module docstring).
        event: NavEnv's event string; None: classified from the arrays (:func:`classify_trajectory`, needs
            ``goal`` and ``time_limit``; obstacle collisions only with ``segments``), and the arrays are cut
            at the step that ended the episode.
        goal: the robot's goal (for the straight-line ratio, the path irregularity reference, classification).
        shortest_path: l*, the shortest collision-free path length (A* on the inflated grid); None: the
            length of ``reference_path``, else nan (SPL, extra time and shortest_path_ratio then nan).
        time_limit: the episode's time limit (s), reported and used by the aggregation.
        v_pref: the robot's preferred speed (extra time to goal; nan without it).
        robot_yaw: ``(T+1,)``; the stuck test's turn and ``heading_change_rad`` (else from the motion).
        robot_vel, human_vel, human_yaw: recorded velocities / person headings (else from positions).
        reference_path: the shortest path's waypoints (path irregularity); else the straight line to goal.
        segments: wall segments ``(M, 2, 2)`` for the swept obstacle test.
        human_pos_rerun: the people in a rerun without the robot (rerun disturbance; nan without it).
        end_step: the step the robot was done at (multi-robot episodes record past it): arrays are cut there.
        sfm_params: ``SocialForceParams`` for social work (default parameters).
        thresholds: :class:`Thresholds` (defaults: METRICS.md); reported under ``"thresholds"``.
        human_present: ``(T+1, H)`` bool, people who are not always there (the replay crowd keeps absent people
            far outside the scene): the swept gaps (minimum distance, discomfort, the swept collision check) skip
            absent people and their jumps in and out; the other social metrics see them where they are kept.
    """
    th = thresholds or Thresholds()
    rp = _pos(robot_pos)
    hp = _humans(human_pos, len(rp))
    hr = _radii(human_radius, hp.shape[1])
    nan = float("nan")
    goal_tol = robot_radius if th.goal_tolerance_m is None else th.goal_tolerance_m
    if end_step is not None:
        rp, hp = rp[: int(end_step) + 1], hp[: int(end_step) + 1]
    if event is None:
        if goal is None or time_limit is None:
            raise ValueError("episode_metrics needs event, or goal and time_limit to classify the arrays")
        c = classify_trajectory(
            rp,
            goal,
            hp,
            robot_radius,
            hr,
            dt,
            time_limit,
            segments=segments,
            goal_tolerance=goal_tol,
            collision_tolerance=th.collision_tolerance_m,
        )
        event, end_step = c["event"], c["end_step"]  # the episode ends at the first ending step
    if end_step is not None:
        n = int(end_step) + 1
        rp, hp = rp[:n], hp[:n]

        def cut(a: np.ndarray | None) -> np.ndarray | None:
            return None if a is None or np.size(a) == 0 else np.asarray(a)[:n]

        robot_yaw, robot_vel, human_vel, human_yaw = map(cut, (robot_yaw, robot_vel, human_vel, human_yaw))
    steps = len(rp) - 1
    out: dict[str, Any] = {"event": event, **outcome_from_event(event)}
    success = out["success"]
    out["stuck"] = bool(
        out["timeout"]
        and is_stuck(
            rp,
            dt,
            robot_yaw,
            window_s=th.stuck_window_s,
            min_displacement=th.stuck_min_displacement_m,
            min_turn_deg=th.stuck_min_turn_deg,
        )
    )
    out["steps"] = steps
    out["time_s"] = steps * dt
    out["time_limit_s"] = float(time_limit) if time_limit is not None else nan

    # Efficiency
    length = path_length(rp)
    if shortest_path is None and reference_path is not None:
        ref = np.asarray(reference_path, dtype=np.float64).reshape(-1, 2)
        shortest_path = path_length(np.vstack([rp[:1], ref])) if len(ref) else 0.0
    l_star = float(shortest_path) if shortest_path is not None and np.isfinite(shortest_path) else nan
    out["nav_time_s"] = navigation_time(steps, dt, success)
    out["path_length_m"] = length
    if goal is not None:
        out["straight_line_m"] = float(np.linalg.norm(np.asarray(goal, dtype=np.float64) - rp[0]))
        out["path_length_ratio"] = path_length_ratio(rp, goal)
    elif success:  # the robot ended within goal tolerance of its goal: the end stands for it
        out["straight_line_m"] = float(np.linalg.norm(rp[-1] - rp[0]))
        out["path_length_ratio"] = path_length_ratio(rp, rp[-1])
    else:
        out["straight_line_m"] = out["path_length_ratio"] = nan
    out["shortest_path_m"] = l_star
    out["shortest_path_ratio"] = length / l_star if l_star > 0 else nan
    out["spl"] = spl(success, length, l_star) if np.isfinite(l_star) else nan
    out["extra_time_s"] = (
        extra_time_to_goal(steps * dt, l_star, v_pref) if success and v_pref and np.isfinite(l_star) else nan
    )

    # Smoothness
    out.update(motion_stats(rp, dt))
    if robot_yaw is not None:
        out["heading_change_rad"] = heading_change(robot_yaw)
    else:
        out["heading_change_rad"] = path_turning(rp, th.heading_min_step_m)
    out["path_turning_rad"] = path_turning(rp, th.heading_min_step_m)
    if reference_path is not None or goal is not None:
        out["path_irregularity"] = path_irregularity(rp, reference_path, goal, min_step=th.heading_min_step_m)
    else:
        out["path_irregularity"] = nan

    # Social
    present = None if human_present is None else np.asarray(human_present, dtype=bool)[: len(rp)]
    out["min_distance_m"] = min_person_distance(rp, hp, robot_radius, hr, present=present)
    disc = discomfort_stats(rp, hp, robot_radius, hr, th.discomfort_m, present=present)
    out["discomfort_steps"] = disc["steps"]
    out["total_steps"] = disc["total_steps"]
    out["discomfort_frequency"] = disc["frequency"]
    out["discomfort_gap_sum_m"] = disc["gap_sum_m"]
    out["discomfort_mean_min_gap_m"] = disc["mean_min_gap_m"]
    for k, v in proxemic_shares(rp, hp, robot_radius, hr, th.proxemic_zones_m).items():
        out[f"proxemic_{k}"] = v
    out["intrusion_time_ratio"] = intrusion_time_ratio(rp, hp, robot_radius, hr, dt, th.intrusion_horizon_s)
    ttc = ttc_stats(rp, hp, robot_radius, hr, dt, robot_vel, human_vel, th.ttc_s)
    out["min_ttc_s"] = ttc["min_ttc_s"]
    out["ttc_below_1s"] = ttc["below"]
    ps = personal_space_cost(
        rp,
        hp,
        robot_radius,
        hr,
        dt,
        human_vel,
        human_yaw,
        min_sigma=th.ps_min_sigma_m,
        speed_gain=th.ps_speed_gain_s,
        side_ratio=th.ps_side_ratio,
        rear_ratio=th.ps_rear_ratio,
    )
    out["personal_space_cost"] = ps["total"]
    out["personal_space_cost_per_step"] = ps["mean"]
    loc = pedestrian_disturbance_local(
        rp, hp, robot_radius, hr, dt, human_vel, radius=th.disturbance_radius_m
    )
    out["disturbance_lateral_m"] = loc["lateral_deviation_m"]
    out["disturbance_max_lateral_m"] = loc["max_lateral_deviation_m"]
    out["disturbance_velocity_loss_mps"] = loc["velocity_loss_mps"]
    out["disturbance_encounters"] = loc["encounters"]
    if human_pos_rerun is not None:
        rer = pedestrian_disturbance_rerun(hp, _humans(human_pos_rerun, len(np.asarray(human_pos_rerun))), dt)
    else:
        rer = dict.fromkeys(
            ("path_deviation_m", "max_path_deviation_m", "speed_change_mps", "heading_change_rad"), nan
        )
    for k, v in rer.items():
        out[f"disturbance_rerun_{k}"] = v
    sw = social_work(rp, hp, robot_radius, hr, dt, robot_vel, human_vel, sfm_params)
    out["social_work"] = sw["social_work"]
    out["social_work_on_robot"] = sw["on_robot"]
    out["social_work_on_people"] = sw["on_people"]

    # Consistency checks from the arrays (the env's own tests decide the event).
    out["swept_human_collision"] = bool(
        swept_person_collisions(rp, hp, robot_radius, hr, th.collision_tolerance_m, present).any()
    )
    out["swept_obstacle_collision"] = (
        bool(swept_obstacle_collisions(rp, robot_radius, segments, th.collision_tolerance_m).any())
        if segments is not None and np.size(segments)
        else None
    )
    out["thresholds"] = {**th.as_dict(), "goal_tolerance_m": goal_tol}
    return out


def episode_summary(
    robot_pos: np.ndarray,
    human_pos: np.ndarray,
    robot_radius: float,
    human_radius: np.ndarray | float,
    dt: float,
    event: str,
    shortest_path: float,
    time_limit: float,
    discomfort_threshold: float = 0.2,
    **kwargs: Any,
) -> dict[str, Any]:
    """The headline numbers of one robot's episode: :func:`episode_metrics` plus the original keys.

    Kept for callers of the first version: ``navigation_time_s`` (time if successful, else the time limit),
    ``min_person_distance_m`` (= ``min_distance_m``). Extra keyword arguments go to :func:`episode_metrics`
    (``goal=``, ``v_pref=``, ``reference_path=``, ``end_step=``, ...); ``discomfort_threshold`` overrides
    ``Thresholds.discomfort_m``.
    """
    th = kwargs.pop("thresholds", None) or Thresholds()
    th = replace(th, discomfort_m=discomfort_threshold)
    m = episode_metrics(
        robot_pos,
        human_pos,
        robot_radius,
        human_radius,
        dt,
        event,
        shortest_path=shortest_path,
        time_limit=time_limit,
        thresholds=th,
        **kwargs,
    )
    m["navigation_time_s"] = m["time_s"] if m["success"] else float(time_limit)
    m["min_person_distance_m"] = m["min_distance_m"]
    return m
