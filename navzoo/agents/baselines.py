"""Baseline robot controllers (privileged: they read the world state from the env).

All implement :class:`navzoo.agents.policy.Policy` (``reset(env)``, ``act(observations, env)``) and
act for the live robots among the keys of ``observations`` (the values are not read, so
``{a: None for a in env.agents}`` works too):

- :class:`OrcaRobotPolicy`: ORCA toward the next A* waypoint, taking full responsibility for
  avoiding people (people are passive obstacles to it), used directly for a holonomic base or
  mapped to (v, omega) for a differential-drive one.
- :class:`SocialForceRobotPolicy`: the robot follows its A* waypoints driven by the social force
  model of :mod:`navzoo.agents.sfm`, with people (and other robots) as the others.
- :class:`navzoo.agents.dwa.DWAPolicy`: the dynamic window approach.
- :class:`PurePursuitPolicy`: follows its A* path and ignores people (the lower bound).
- :class:`StopPolicy` and :class:`RandomPolicy`: sanity checks.

:func:`make_policy` builds any of them by name (``"orca-holonomic"``, ``"orca-diffdrive"``, ``"sfm"``,
``"dwa"``, ``"pure-pursuit"``, ``"stop"``, ``"random"``, ...); see ``docs/baselines.md``.
"""

from __future__ import annotations

import os
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from navzoo.agents.dwa import DWAParams, DWAPolicy, _check_kinematics, _robot_indices, obstacle_speed_filter
from navzoo.agents.orca import OrcaParams, orca_velocities
from navzoo.agents.policy import (
    Policy,
    act_per_robot,
    perceived_others,
    preferred_velocity,
    velocity_to_diff_drive,
)
from navzoo.agents.sfm import SocialForceParams, social_force_velocities

if TYPE_CHECKING:
    from navzoo.envs.nav_env import NavEnv

__all__ = [
    "DWAParams",
    "DWAPolicy",
    "OrcaRobotPolicy",
    "PurePursuitPolicy",
    "RandomPolicy",
    "SocialForceRobotPolicy",
    "StopPolicy",
    "make_policy",
    "policy_names",
    "register_policy",
]


def _to_actions(env: NavEnv, idx: np.ndarray, desired: np.ndarray, wall_filter: bool = False) -> dict[str, np.ndarray]:
    """World-frame desired velocities as actions: directly (holonomic) or tracked (differential drive,
    optionally with the wall speed filter :func:`navzoo.agents.dwa.obstacle_speed_filter`)."""
    spec = env.config.robot
    if spec.kinematics == "holonomic":
        acts = np.clip(desired / spec.max_speed, -1, 1).astype(np.float32)
    else:
        acts = velocity_to_diff_drive(desired, env.yaw[idx], spec.max_speed, spec.max_turn_rate)
        if wall_filter:
            acts = obstacle_speed_filter(env, idx, acts)
    return {env.possible_agents[i]: acts[k] for k, i in enumerate(idx)}


def _others(env: NavEnv, idx: np.ndarray) -> np.ndarray:
    """Live agents (people and robots) other than the controlled robots ``idx``."""
    mask = env.alive & env.present  # absent (replay: parked) people are not there
    mask[idx] = False
    return np.flatnonzero(mask)


class PurePursuitPolicy:
    """Drive along the A* path at full speed, ignoring people."""

    name = "pure_pursuit"

    def reset(self, env: NavEnv) -> None:
        return None

    def act(self, observations: dict[str, Any], env: NavEnv) -> dict[str, np.ndarray]:
        idx = _robot_indices(observations, env)
        if idx.size == 0:
            return {}
        wp = env.next_waypoints()[idx]
        desired = preferred_velocity(env.pos[idx], wp, env.goal[idx], env.v_pref[idx])
        return _to_actions(env, idx, desired)


class OrcaRobotPolicy:
    """ORCA robot: avoids people and other robots, taking full responsibility, toward its A* waypoints.

    People (and robots it does not control) are passive agents predicted at their current
    velocity; the robots it controls avoid each other reciprocally. The ORCA velocity is the action
    of a holonomic base; a differential-drive base turns toward it and drives with its speed times
    cos(heading error) (:func:`navzoo.agents.policy.velocity_to_diff_drive`).

    Args:
        params: ORCA parameters (:class:`navzoo.agents.orca.OrcaParams`).
        kinematics: ``None`` (follow the env's robot), ``"holonomic"`` or ``"diff_drive"``; a fixed
            kinematics that does not match the env's robot raises ``ValueError``.
        radius_margin: added to the robot's radius inside ORCA (m). ``None``: 0 for a holonomic
            base, 0.1 m for a differential-drive one, which lags behind the ORCA velocity while it
            turns (the tracking-error margin of NH-ORCA, Alonso-Mora et al. 2010).
        wall_filter: differential drive: scale the forward speed down where driving along the
            current heading (rather than along the ORCA velocity) would hit a wall
            (:func:`navzoo.agents.dwa.obstacle_speed_filter`).
        crowdnav: CrowdNav's ORCA robot exactly (``crowd_sim/envs/policy/orca.py``, registered as
            ``"orca-crowdnav"``): RVO2 semantics (``params`` default without navzoo's right bias and
            one-step safety), every disc, the robot's and the people's, 0.01 m larger inside ORCA,
            people given zero preferred velocity and the robot's maximum speed, slowing down within
            1 m of the goal. Its success and
            collision rates on the ``crowdnav-circle`` protocol are the ones to compare with
            CrowdNav's published ORCA row (docs/benchmarks.md).
    """

    name = "orca"

    def __init__(self, params: OrcaParams | None = None, kinematics: str | None = None,
                 radius_margin: float | None = None, wall_filter: bool = True, crowdnav: bool = False) -> None:
        if kinematics not in (None, "diff_drive", "holonomic"):
            raise ValueError(f"kinematics must be None, 'diff_drive' or 'holonomic', got {kinematics!r}")
        if radius_margin is not None and not (np.isfinite(radius_margin) and radius_margin >= 0):
            raise ValueError(f"radius_margin must be None or a finite number >= 0, got {radius_margin!r}")
        if crowdnav and radius_margin is not None:
            raise ValueError("crowdnav=True fixes the radius margin (0.01 m on every disc); leave radius_margin None")
        self.params = params or (OrcaParams(right_bias=0.0, one_step_safety=False) if crowdnav else OrcaParams())
        self.kinematics = kinematics
        self.radius_margin = radius_margin
        self.wall_filter = wall_filter
        self.crowdnav = bool(crowdnav)

    def reset(self, env: NavEnv) -> None:
        _check_kinematics(self.kinematics, env, "orca")

    def act(self, observations: dict[str, Any], env: NavEnv) -> dict[str, np.ndarray]:
        split = act_per_robot(self, observations, env)
        if split is not None:
            return split
        idx = _robot_indices(observations, env)
        if idx.size == 0:
            return {}
        _check_kinematics(self.kinematics, env, "orca")
        spec = env.config.robot
        margin = self.radius_margin
        if margin is None:
            margin = 0.0 if spec.kinematics == "holonomic" else 0.1
        seen = perceived_others(env, idx)
        if seen is None:
            others = _others(env, idx)
            o_pos, o_vel, o_rad, o_robot = env.pos[others], env.vel[others], env.radius[others], env.is_robot[others]
        else:  # perceived people (and ground-truth robots) from a PerceptionWrapper
            o_pos, o_vel, o_rad = seen
            o_robot = np.zeros(len(o_pos), dtype=bool)
            o_robot[:int(np.sum(env.alive & env.is_robot)) - 1] = True
        n_o = len(o_pos)
        pos = np.concatenate([env.pos[idx], o_pos])
        vel = np.concatenate([env.vel[idx], o_vel])
        wp = env.next_waypoints()[idx]
        pref = preferred_velocity(env.pos[idx], wp, env.goal[idx], env.v_pref[idx],
                                  slow_radius=1.0 if self.crowdnav else 0.5)
        if self.crowdnav:  # CrowdNav: one RVO2 simulator, every agent at radius + 0.01, others' goals unknown
            all_pref = np.concatenate([pref, np.zeros((n_o, 2))])
            vmax = np.full(idx.size + n_o, spec.max_speed)
            radius = np.concatenate([env.radius[idx], o_rad]) + 0.01
        else:
            all_pref = np.concatenate([pref, o_vel])
            vmax = np.concatenate([np.full(idx.size, spec.max_speed),
                                   np.where(o_robot, spec.max_speed, env.config.human_max_speed)])
            radius = np.concatenate([env.radius[idx] + margin, o_rad])
        desired = orca_velocities(pos, vel, all_pref, radius, vmax, env.config.dt,
                                  self.params, env.segments, n_active=idx.size)
        return _to_actions(env, idx, desired, self.wall_filter)


class SocialForceRobotPolicy:
    """Social-force robot: follows its A* waypoints under the social force model.

    The robots it controls are the model's "people" (they push each other), the env's people and
    any other robots are its "others" (they push the robot but are not updated), and the scene's
    walls push once per obstacle. The new velocity is the action of a holonomic base, or tracked
    by a differential-drive one (:func:`navzoo.agents.policy.velocity_to_diff_drive`).

    Args:
        params: :class:`navzoo.agents.sfm.SocialForceParams` (default: the pedestrians' parameters).
        kinematics: ``None`` (follow the env's robot), ``"holonomic"`` or ``"diff_drive"``.
        wall_filter: differential drive: the wall speed filter, as :class:`OrcaRobotPolicy`.
    """

    name = "sfm"

    def __init__(self, params: SocialForceParams | None = None, kinematics: str | None = None,
                 wall_filter: bool = True) -> None:
        if kinematics not in (None, "diff_drive", "holonomic"):
            raise ValueError(f"kinematics must be None, 'diff_drive' or 'holonomic', got {kinematics!r}")
        self.params = params or SocialForceParams()
        self.kinematics = kinematics
        self.wall_filter = wall_filter

    def reset(self, env: NavEnv) -> None:
        _check_kinematics(self.kinematics, env, "sfm")

    def act(self, observations: dict[str, Any], env: NavEnv) -> dict[str, np.ndarray]:
        split = act_per_robot(self, observations, env)
        if split is not None:
            return split
        idx = _robot_indices(observations, env)
        if idx.size == 0:
            return {}
        _check_kinematics(self.kinematics, env, "sfm")
        seen = perceived_others(env, idx)
        if seen is None:
            others = _others(env, idx)
            seen = (env.pos[others], env.vel[others], env.radius[others])
        pref = preferred_velocity(env.pos[idx], env.next_waypoints()[idx], env.goal[idx], env.v_pref[idx])
        vel = social_force_velocities(
            env.pos[idx], env.vel[idx], pref, env.radius[idx], env.config.robot.max_speed, env.config.dt,
            self.params, env.segments, others_pos=seen[0], others_vel=seen[1],
            others_radius=seen[2], segment_groups=env.segment_groups,
        )
        return _to_actions(env, idx, vel, self.wall_filter)


class StopPolicy:
    """Always commands zero (the base brakes to a stop under its acceleration limits)."""

    name = "stop"

    def reset(self, env: NavEnv) -> None:
        return None

    def act(self, observations: dict[str, Any], env: NavEnv) -> dict[str, np.ndarray]:
        return {env.possible_agents[i]: np.zeros(2, dtype=np.float32) for i in _robot_indices(observations, env)}


class RandomPolicy:
    """Uniform random actions in [-1, 1]^2 from its own generator (seeded once, at construction)."""

    name = "random"

    def __init__(self, seed: int | None = None) -> None:
        self.rng = np.random.default_rng(seed)

    def reset(self, env: NavEnv) -> None:
        return None

    def act(self, observations: dict[str, Any], env: NavEnv) -> dict[str, np.ndarray]:
        idx = _robot_indices(observations, env)
        acts = self.rng.uniform(-1.0, 1.0, size=(idx.size, 2)).astype(np.float32)
        return {env.possible_agents[i]: acts[k] for k, i in enumerate(idx)}


# ---------------------------------------------------------------------------------------------
# Registry.

_REGISTRY: dict[str, Callable[..., Policy]] = {
    "orca": lambda **kw: OrcaRobotPolicy(**kw),
    "orca-holonomic": lambda **kw: OrcaRobotPolicy(kinematics="holonomic", **kw),
    "orca-diffdrive": lambda **kw: OrcaRobotPolicy(kinematics="diff_drive", **kw),
    "orca-crowdnav": lambda **kw: OrcaRobotPolicy(kinematics="holonomic", crowdnav=True, **kw),
    "sfm": lambda **kw: SocialForceRobotPolicy(**kw),
    "dwa": lambda **kw: DWAPolicy(**kw),
    "dwa-holonomic": lambda **kw: DWAPolicy(kinematics="holonomic", **kw),
    "dwa-diffdrive": lambda **kw: DWAPolicy(kinematics="diff_drive", **kw),
    "pure-pursuit": lambda **kw: PurePursuitPolicy(**kw),
    "stop": lambda **kw: StopPolicy(**kw),
    "random": lambda **kw: RandomPolicy(**kw),
}
_ALIASES = {"orca-diff-drive": "orca-diffdrive", "dwa-diff-drive": "dwa-diffdrive", "social-force": "sfm"}


def _key(name: str) -> str:
    key = name.strip().lower().replace("_", "-")
    return _ALIASES.get(key, key)


def policy_names() -> list[str]:
    """The registered policy names (aliases: ``_`` for ``-``, ``orca-diff-drive``, ``social-force``)."""
    return sorted(_REGISTRY)


def make_policy(name: str, **kwargs: Any) -> Policy:
    """A robot policy by name, e.g. ``make_policy("dwa", params=DWAParams(horizon=3.0))``.

    ``"orca"``, ``"dwa"`` and ``"sfm"`` follow the env's robot kinematics; the ``-holonomic`` and
    ``-diffdrive`` variants insist on one. Keyword arguments go to the policy's constructor.
    Learned policies registered with :func:`register_policy` are built the same way.
    """
    if not isinstance(name, str):
        raise TypeError(f"policy name must be a str, got {type(name).__name__}")
    key = _key(name)
    if key not in _REGISTRY:
        raise ValueError(f"unknown robot policy {name!r}; valid names: {policy_names()}")
    return _REGISTRY[key](**kwargs)


def register_policy(name: str, factory: Callable[..., Policy], overwrite: bool = False) -> None:
    """Register ``factory(**kwargs) -> Policy`` under ``name`` (e.g. a loader for a trained model)."""
    key = _key(name)
    if not key:
        raise ValueError("policy name must not be empty")
    if key in _REGISTRY and not overwrite:
        raise ValueError(f"robot policy {key!r} is already registered; pass overwrite=True to replace it")
    if not callable(factory):
        raise TypeError(f"factory must be callable, got {type(factory).__name__}")
    _REGISTRY[key] = factory


# ---------------------------------------------------------------------------------------------
# Learned policies shipped in policies/ (or trained by the user): registered when their weights exist.

_POLICIES_DIR = Path(__file__).resolve().parents[2] / "policies"
LEARNED_POLICIES: dict[str, tuple[str, str]] = {
    # name: (folder under policies/, environment variable that points elsewhere, e.g. at runs/robot/policy)
    "transformer-ppo": ("transformer_ppo", "NAVZOO_TRANSFORMER_PPO_DIR"),
    "transformer-ppo-crowdnav-diffdrive": ("transformer_ppo_crowdnav", "NAVZOO_TRANSFORMER_PPO_CROWDNAV_DIR"),
}


def learned_policy_dir(name: str) -> Path:
    """Where the learned policy ``name`` is loaded from: its environment variable if set, else ``policies/``."""
    folder, var = LEARNED_POLICIES[_key(name)]
    return Path(os.environ[var]) if os.environ.get(var) else _POLICIES_DIR / folder


#: Suffix of a learned policy's name that makes it act with sampled actions instead of the mean action
#: (``transformer-ppo-sampled``); in the benchmark the sampling is seeded per episode.
SAMPLED_SUFFIX = "-sampled"


def register_learned_policy(name: str, model_dir: str | Path | None = None) -> None:
    """Register ``name`` (a key of :data:`LEARNED_POLICIES`) with a factory that loads its exported weights,
    and ``name + "-sampled"``, the same weights acting with actions sampled from the policy's distribution.

    The weights are read when the policy is made (``make_policy(name, deterministic=..., model_dir=...)``)
    from ``model_dir``, else :func:`learned_policy_dir`; so registering never fails, and making it
    without weights raises ``FileNotFoundError`` naming the training command. Registering again
    replaces the earlier registration.
    """
    default_dir = model_dir

    def make_factory(label: str, mean_action: bool) -> Callable[..., Policy]:
        def factory(model_dir: str | Path | None = None, deterministic: bool = mean_action,
                    device: str = "cpu") -> Policy:
            # torch + SB3 only when a learned policy is made
            from navzoo.agents.robot_train import load_policy

            where = model_dir if model_dir is not None else default_dir
            return load_policy(where if where is not None else learned_policy_dir(name),
                               deterministic=deterministic, device=device, name=label)

        return factory

    register_policy(name, make_factory(name, True), overwrite=True)
    register_policy(name + SAMPLED_SUFFIX, make_factory(name + SAMPLED_SUFFIX, False), overwrite=True)


def register_learned_policies() -> list[str]:
    """Register every learned policy whose ``config.json`` exists (done on import); returns their names."""
    found = []
    for name in LEARNED_POLICIES:
        if (learned_policy_dir(name) / "config.json").is_file():
            register_learned_policy(name)
            found.append(name)
    return found


register_learned_policies()
