"""The policy interface shared by rule-based controllers, frozen crowds and learned models."""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
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


def perceived_others(env: NavEnv, idx: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray] | None:
    """What robot ``idx[0]`` perceives of the others, when a perception wrapper is active.

    :class:`navzoo.perception.PerceptionWrapper` publishes each robot's tracked people as
    ``env.perceived_people[i] = (positions, velocities, radii)``. Privileged baselines call this and, when
    it is not None, avoid those instead of the true people; the other robots stay ground truth (robots
    share their state). Returns None when no perception is active.

    Returns:
        ``(positions (M, 2), velocities (M, 2), radii (M,))`` of the other live robots and the perceived
        people, or None.

    Raises:
        ValueError: When perception is active and ``idx`` holds more than one robot (each robot perceives
            differently; act for one robot at a time, see :func:`act_per_robot`).
    """
    perceived = getattr(env, "perceived_people", None)
    if not perceived:
        return None
    if len(idx) != 1:
        raise ValueError("with perceived observations, act for one robot at a time (act_per_robot)")
    i = int(idx[0])
    robots = np.flatnonzero(env.alive & env.is_robot)
    robots = robots[robots != i]
    pp, pv, pr = perceived.get(i, (np.zeros((0, 2)), np.zeros((0, 2)), np.zeros(0)))
    return (np.concatenate([env.pos[robots], pp]), np.concatenate([env.vel[robots], pv]),
            np.concatenate([env.radius[robots], pr]))


def act_per_robot(policy: Any, observations: Mapping[str, Any], env: NavEnv) -> dict[str, np.ndarray] | None:
    """With perception active and several robots, ``policy.act`` for each robot alone (merged), else None."""
    if not getattr(env, "perceived_people", None):
        return None
    robots = [a for a in observations if a.startswith("robot_")]
    if len(robots) <= 1:
        return None
    out: dict[str, np.ndarray] = {}
    for a in robots:
        out.update(policy.act({a: observations[a]}, env))
    return out


# ---------------------------------------------------------------------------------------------
# Observation-only policies (learned models) behind the same interface.


AgentSelector = str | Callable[[str], bool] | None


def _selector(agents: AgentSelector) -> Callable[[str], bool]:
    if agents is None:
        return lambda a: True
    if isinstance(agents, str):
        prefix = agents
        return lambda a: a.startswith(prefix)
    if callable(agents):
        return agents
    raise TypeError(f"agents must be an agent-name prefix, a predicate or None, got {type(agents).__name__}")


def stack_observations(obs: Sequence[Any]) -> Any:
    """Stack per-agent observations into one batch: arrays along a new axis 0, dicts key by key."""
    if not obs:
        raise ValueError("stack_observations needs at least one observation")
    first = obs[0]
    if isinstance(first, Mapping):
        return {k: stack_observations([o[k] for o in obs]) for k in first}
    return np.stack([np.asarray(o) for o in obs])


class ObservationPolicy:
    """Adapter: a function of observations alone, acting through the :class:`Policy` interface.

    Wraps ``fn(observation) -> action`` (``batched=False``, called once per agent) or
    ``fn(batch) -> actions`` (``batched=True``: the controlled agents' observations stacked along a
    new first axis, key by key for Dict observations, and one call per step; ``fn`` returns an
    ``(n_agents, action_dim)`` array). Observations are passed as the env gives them (flat Box or
    Dict), so a model trained on ``navzoo.make(...)`` or ``sb3_vec_env`` plugs in unchanged.

    Args:
        fn: the model's act function (or any callable with the signature above).
        batched: whether ``fn`` takes a batch (see above).
        agents: which agents of ``observations`` it acts for: an agent-name prefix (default
            ``"robot_"``), a predicate on names, or None for all of them. Agents that are not live
            in ``env`` (when ``env`` is given) are skipped.
        name: a label for reports.
    """

    def __init__(self, fn: Callable[[Any], Any], batched: bool = True, agents: AgentSelector = "robot_",
                 name: str = "observation_policy") -> None:
        if not callable(fn):
            raise TypeError(f"fn must be callable, got {type(fn).__name__}")
        self.fn = fn
        self.batched = bool(batched)
        self._select = _selector(agents)
        self.name = name

    def reset(self, env: NavEnv | None = None) -> None:
        return None

    def controlled(self, observations: Mapping[str, Any], env: NavEnv | None = None) -> list[str]:
        """Names of the agents this policy acts for, in ``observations`` order."""
        live = set(env.agents) if env is not None else None
        return [a for a in observations if self._select(a) and (live is None or a in live)]

    def act(self, observations: Mapping[str, Any], env: NavEnv | None = None) -> dict[str, np.ndarray]:
        names = self.controlled(observations, env)
        if not names:
            return {}
        if self.batched:
            actions = np.asarray(self.fn(stack_observations([observations[a] for a in names])))
            if actions.ndim == 0 or actions.shape[0] != len(names):
                raise ValueError(f"batched fn must return one action per agent (first axis {len(names)}), "
                                 f"got shape {actions.shape}")
        else:
            actions = [np.asarray(self.fn(observations[a])) for a in names]
        return {a: np.asarray(actions[k], dtype=np.float32) for k, a in enumerate(names)}


class SB3Policy(ObservationPolicy):
    """A Stable-Baselines3 model (``model.predict(obs, deterministic=...)``) as a :class:`Policy`.

    All controlled robots are predicted in one batched ``predict`` call. ``obs_transform`` is applied
    to the stacked batch first (e.g. ``vec_normalize.normalize_obs`` for a model trained under
    ``VecNormalize``). ``kinematics`` (``"diff_drive"`` / ``"holonomic"``), when given, is the robot the
    model was trained for: acting in an env with the other robot raises ``ValueError`` instead of
    driving it with actions of the wrong meaning.
    """

    def __init__(self, model: Any, deterministic: bool = True, agents: AgentSelector = "robot_",
                 obs_transform: Callable[[Any], Any] | None = None, name: str = "sb3",
                 kinematics: str | None = None) -> None:
        if not hasattr(model, "predict"):
            raise TypeError(f"model must have a predict(obs, deterministic=...) method, got {type(model).__name__}")
        if kinematics not in (None, "diff_drive", "holonomic"):
            raise ValueError(f"kinematics must be None, 'diff_drive' or 'holonomic', got {kinematics!r}")
        self.model = model
        self.deterministic = deterministic
        self.obs_transform = obs_transform
        self.kinematics = kinematics
        super().__init__(self._predict, batched=True, agents=agents, name=name)

    def _check_env(self, env: Any) -> None:
        if self.kinematics is None or env is None:
            return
        actual = getattr(getattr(getattr(env, "unwrapped", env), "config", None), "robot", None)
        actual = getattr(actual, "kinematics", None)
        if actual is not None and actual != self.kinematics:
            raise ValueError(f"policy {self.name!r} was trained for {self.kinematics!r} robots but this env's robot "
                             f"is {actual!r}; make the env with robot={{'kinematics': {self.kinematics!r}}}")

    def reset(self, env: NavEnv | None = None) -> None:
        self._check_env(env)

    def act(self, observations: Mapping[str, Any], env: NavEnv | None = None) -> dict[str, np.ndarray]:
        self._check_env(env)
        return super().act(observations, env)

    def _predict(self, batch: Any) -> np.ndarray:
        if self.obs_transform is not None:
            batch = self.obs_transform(batch)
        actions, _ = self.model.predict(batch, deterministic=self.deterministic)
        return np.asarray(actions)
