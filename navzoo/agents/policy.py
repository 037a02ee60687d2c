"""The policy interface shared by rule-based controllers, frozen crowds and learned models."""

from __future__ import annotations

from typing import TYPE_CHECKING, Any, Protocol, runtime_checkable

import numpy as np

if TYPE_CHECKING:
    from navzoo.envs.nav_env import NavEnv


@runtime_checkable
class Policy(Protocol):
    """Anything that acts for a set of agents.

    ``act`` receives the observations of the agents it controls (a dict keyed by agent) and the
    unwrapped env, which privileged controllers (social force, ORCA, DWA) read state arrays from;
    learned policies use only the observations. It returns one action per controlled live agent.
    """

    def reset(self, env: NavEnv) -> None: ...

    def act(self, observations: dict[str, Any], env: NavEnv) -> dict[str, np.ndarray]: ...


def velocity_to_diff_drive(
    desired: np.ndarray, yaw: np.ndarray, max_speed: float, max_turn_rate: float, turn_gain: float = 2.5
) -> np.ndarray:
    """Normalised (v, omega) actions that track world-frame desired velocities (vectorised).

    The base turns toward the desired direction and drives forward with the desired speed scaled
    by cos(heading error), never backwards (it turns in place when the target is behind it).
    """
    speed = np.linalg.norm(desired, axis=1)
    err = np.where(speed > 1e-6, np.arctan2(desired[:, 1], desired[:, 0]) - yaw, 0.0)
    err = (err + np.pi) % (2 * np.pi) - np.pi
    v = speed * np.clip(np.cos(err), 0.0, 1.0)
    w = np.clip(turn_gain * err, -max_turn_rate, max_turn_rate)
    return np.stack([np.clip(v / max_speed, -1, 1), np.clip(w / max_turn_rate, -1, 1)], axis=1).astype(np.float32)


def preferred_velocity(pos: np.ndarray, waypoint: np.ndarray, goal: np.ndarray, v_pref: np.ndarray,
                       slow_radius: float = 0.5) -> np.ndarray:
    """Velocity toward the next waypoint at the preferred speed, slowing down near the final goal."""
    d = waypoint - pos
    dist = np.linalg.norm(d, axis=1)
    dist_goal = np.linalg.norm(goal - pos, axis=1)
    speed = v_pref * np.clip(dist_goal / slow_radius, 0.0, 1.0)
    return np.where(dist[:, None] > 1e-6, d / np.maximum(dist, 1e-6)[:, None] * speed[:, None], 0.0)
