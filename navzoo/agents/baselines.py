"""Baseline robot controllers (privileged: they read the world state from the env).

- :class:`OrcaRobotPolicy`: ORCA toward the next A* waypoint, taking full responsibility for
  avoiding people (people are passive obstacles to it), then mapped to (v, omega) for a
  differential-drive base or used directly for a holonomic one.
- :class:`PurePursuitPolicy`: follows its A* path and ignores people (the lower bound).
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import numpy as np

from navzoo.agents.orca import OrcaParams, orca_velocities
from navzoo.agents.policy import preferred_velocity, velocity_to_diff_drive

if TYPE_CHECKING:
    from navzoo.envs.nav_env import NavEnv


def _to_actions(env: NavEnv, idx: np.ndarray, desired: np.ndarray) -> dict[str, np.ndarray]:
    spec = env.config.robot
    if spec.kinematics == "holonomic":
        acts = np.clip(desired / spec.max_speed, -1, 1).astype(np.float32)
    else:
        acts = velocity_to_diff_drive(desired, env.yaw[idx], spec.max_speed, spec.max_turn_rate)
    return {env.possible_agents[i]: acts[k] for k, i in enumerate(idx)}


class PurePursuitPolicy:
    """Drive along the A* path at full speed, ignoring people."""

    name = "pure_pursuit"

    def reset(self, env: NavEnv) -> None:
        return None

    def act(self, observations: dict[str, Any], env: NavEnv) -> dict[str, np.ndarray]:
        idx = np.array([env._index[a] for a in observations if a.startswith("robot_") and a in env.agents], dtype=int)
        if idx.size == 0:
            return {}
        wp = env.next_waypoints()[idx]
        desired = preferred_velocity(env.pos[idx], wp, env.goal[idx], env.v_pref[idx])
        return _to_actions(env, idx, desired)


class OrcaRobotPolicy:
    """ORCA robot: avoids people and other robots reciprocally-aware, toward its A* waypoints."""

    name = "orca"

    def __init__(self, params: OrcaParams | None = None) -> None:
        self.params = params or OrcaParams()

    def reset(self, env: NavEnv) -> None:
        return None

    def act(self, observations: dict[str, Any], env: NavEnv) -> dict[str, np.ndarray]:
        idx = np.array([env._index[a] for a in observations if a.startswith("robot_") and a in env.agents], dtype=int)
        if idx.size == 0:
            return {}
        others = np.array([i for i in np.flatnonzero(env.alive) if i not in set(idx.tolist())], dtype=int)
        order = np.concatenate([idx, others])
        wp = env.next_waypoints()[idx]
        pref = preferred_velocity(env.pos[idx], wp, env.goal[idx], env.v_pref[idx])
        all_pref = np.concatenate([pref, env.vel[others]])
        vmax = np.where(env.is_robot[order], env.config.robot.max_speed, env.config.human_max_speed)
        desired = orca_velocities(env.pos[order], env.vel[order], all_pref, env.radius[order], vmax, env.config.dt,
                                  self.params, env.segments, n_active=idx.size)
        return _to_actions(env, idx, desired)
