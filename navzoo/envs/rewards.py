"""Reward terms of the paper (NavIsaacLab, "Reward"), as pure functions with weights in a config.

r_t = r_nav + r_omega with

    r_nav = 20                       if d_goal < rho                (goal reached)
          = -20                      elif d_obs < 0                 (collision)
          = 0.5 (d_obs - 0.9)        elif 0 <= d_obs < 0.9          (too close to someone/something)
          = 3.2 (d_goal_prev - d_goal) otherwise                    (progress)
    r_omega = -0.1 |omega|           if |omega| > 1 rad/s

d_obs is the smallest edge-to-edge distance to any person, other robot or obstacle. With
``RewardParams.wall_proximity_distance`` set, walls and obstacles get their own proximity distance:
the term is then ``0.5 min(d_agents - 0.9, d_walls - wall_proximity_distance)`` where negative (pass
``d_walls``); with it unset this is exactly the paper's term. Collisions are
detected from the swept motion and PyBullet contacts, not only from end positions, so a collision
counts even when d_obs at the end of the step is positive.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

TERMS = ("goal", "collision", "proximity", "progress", "turn")


@dataclass(frozen=True)
class RewardParams:
    goal_reward: float = 20.0
    collision_reward: float = -20.0
    proximity_distance: float = 0.9
    proximity_scale: float = 0.5
    progress_scale: float = 3.2
    turn_threshold: float = 1.0
    turn_scale: float = 0.1
    wall_proximity_distance: float | None = None  # None: walls as people (proximity_distance)


def navigation_reward(
    d_goal: np.ndarray,
    d_goal_prev: np.ndarray,
    d_obs: np.ndarray,
    reached: np.ndarray,
    collided: np.ndarray,
    omega: np.ndarray,
    params: RewardParams = RewardParams(),
    d_walls: np.ndarray | None = None,
) -> tuple[np.ndarray, dict[str, np.ndarray]]:
    """Vectorised r_nav + r_omega; returns the total (A,) and each term (A,) by name.

    ``d_obs`` is the clearance to everything, or with ``d_walls`` given the clearance to people and
    robots only, ``d_walls`` the clearance to walls and obstacles.
    """
    reached = np.asarray(reached, dtype=bool)
    collided = np.asarray(collided, dtype=bool) & ~reached
    d_obs = np.asarray(d_obs, dtype=np.float64)
    margin = np.maximum(d_obs, 0.0) - params.proximity_distance
    if d_walls is not None:
        wall_dist = params.proximity_distance if params.wall_proximity_distance is None else params.wall_proximity_distance
        margin = np.minimum(margin, np.maximum(np.asarray(d_walls, dtype=np.float64), 0.0) - wall_dist)
    close = ~reached & ~collided & (margin < 0.0)
    progress = ~reached & ~collided & ~close
    terms = {
        "goal": np.where(reached, params.goal_reward, 0.0),
        "collision": np.where(collided, params.collision_reward, 0.0),
        "proximity": np.where(close, params.proximity_scale * margin, 0.0),
        "progress": np.where(progress, params.progress_scale * (d_goal_prev - d_goal), 0.0),
        "turn": np.where(np.abs(omega) > params.turn_threshold, -params.turn_scale * np.abs(omega), 0.0),
    }
    total = sum(terms.values())
    return total, terms
