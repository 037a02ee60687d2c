"""Episode metrics as pure functions of recorded arrays (definitions in docs/metrics, after METRICS.md).

Arrays follow one layout: ``robot_pos (T+1, 2)`` robot positions at every step including the start,
``human_pos (T+1, H, 2)``, radii in metres, ``dt`` the control period.
"""

from __future__ import annotations

import numpy as np


def path_length(pos: np.ndarray) -> float:
    """Sum of step lengths ||x_{t+1} - x_t|| (m)."""
    pos = np.asarray(pos, dtype=np.float64)
    return float(np.linalg.norm(np.diff(pos, axis=0), axis=1).sum()) if len(pos) > 1 else 0.0


def person_gaps(robot_pos: np.ndarray, human_pos: np.ndarray, robot_radius: float, human_radius: np.ndarray | float) -> np.ndarray:
    """Edge-to-edge robot-person distances (T+1, H) (centre distance minus both radii)."""
    robot_pos = np.asarray(robot_pos, dtype=np.float64)
    human_pos = np.asarray(human_pos, dtype=np.float64)
    if human_pos.ndim != 3 or human_pos.shape[1] == 0:
        return np.full((len(robot_pos), 0), np.inf)
    d = np.linalg.norm(human_pos - robot_pos[:, None, :], axis=2)
    return d - robot_radius - np.asarray(human_radius, dtype=np.float64)


def min_person_distance(robot_pos, human_pos, robot_radius, human_radius) -> float:
    """Minimum edge-to-edge distance to any person over the episode (m); inf without people."""
    g = person_gaps(robot_pos, human_pos, robot_radius, human_radius)
    return float(g.min()) if g.size else float("inf")


def discomfort(robot_pos, human_pos, robot_radius, human_radius, threshold: float = 0.2) -> tuple[int, int]:
    """(steps with a robot-person gap below ``threshold``, all steps) — CrowdNav's discomfort count."""
    g = person_gaps(robot_pos, human_pos, robot_radius, human_radius)[1:]
    if g.size == 0:
        return 0, len(robot_pos) - 1
    return int((g.min(axis=1) < threshold).sum()), int(g.shape[0])


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
) -> dict[str, float | str | bool]:
    """The headline numbers of one robot's episode."""
    success = event == "goal"
    length = path_length(robot_pos)
    steps = len(robot_pos) - 1
    n_disc, n_steps = discomfort(robot_pos, human_pos, robot_radius, human_radius, discomfort_threshold)
    return {
        "event": event,
        "success": success,
        "collision": event.startswith("collision"),
        "human_collision": event == "collision_human",
        "obstacle_collision": event == "collision_obstacle",
        "timeout": event == "timeout",
        "navigation_time_s": steps * dt if success else float(time_limit),
        "path_length_m": length,
        "shortest_path_m": float(shortest_path),
        "path_length_ratio": length / shortest_path if shortest_path > 0 else float("nan"),
        "spl": float(success) * shortest_path / max(length, shortest_path) if shortest_path > 0 else float(success),
        "min_person_distance_m": min_person_distance(robot_pos, human_pos, robot_radius, human_radius),
        "discomfort_steps": n_disc,
        "discomfort_frequency": n_disc / n_steps if n_steps else 0.0,
        "steps": steps,
    }
