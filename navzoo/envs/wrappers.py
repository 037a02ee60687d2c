"""Wrappers: freeze a set of agents under a fixed policy, and a single-robot Gymnasium view."""

from __future__ import annotations

from collections.abc import Callable, Iterable
from typing import Any

import gymnasium
import numpy as np
from pettingzoo import ParallelEnv

from navzoo.agents.policy import Policy
from navzoo.envs.nav_env import NavEnv


class _NavWrapper(ParallelEnv):
    """What every navzoo parallel wrapper forwards unchanged to the env it wraps."""

    def __init__(self, env: ParallelEnv) -> None:
        self.env = env
        self.metadata = env.metadata

    @property
    def unwrapped(self) -> NavEnv:
        return self.env.unwrapped

    @property
    def render_mode(self) -> str | None:
        return self.env.render_mode

    def observation_space(self, agent: str):
        return self.env.observation_space(agent)

    def action_space(self, agent: str):
        return self.env.action_space(agent)

    def render(self):
        return self.env.render()

    def close(self) -> None:
        self.env.close()


class FrozenAgents(_NavWrapper):
    """Owns a fixed policy for some agents, feeds their actions each step and hides them.

    The learner sees only the other agents: ``possible_agents``, ``agents``, spaces, observations,
    rewards and infos exclude the frozen ones. Typical use: pedestrians frozen on social force while
    robots learn (``navzoo.make`` does this), or robots frozen on a trained policy while pedestrians
    learn.

    Args:
        env: the env to wrap (a :class:`NavEnv` or a wrapper of one).
        frozen: names of the frozen agents, or a predicate on agent names.
        policy: acts for the frozen agents (see :class:`navzoo.agents.policy.Policy`).
    """

    def __init__(self, env: ParallelEnv, frozen: Iterable[str] | Callable[[str], bool], policy: Policy) -> None:
        super().__init__(env)
        names = list(env.possible_agents)
        if isinstance(frozen, str):
            raise TypeError(f"frozen must be agent names or a predicate, got the string {frozen!r}; "
                            f"e.g. [{frozen!r}] or lambda a: a.startswith({frozen!r})")
        if callable(frozen):
            self.frozen = frozenset(a for a in names if frozen(a))
        else:
            self.frozen = frozenset(frozen)
            unknown = sorted(self.frozen - set(names))
            if unknown:
                raise ValueError(f"cannot freeze unknown agent(s) {unknown}; possible agents: {names}")
        if not isinstance(policy, Policy):
            raise TypeError(f"policy must implement reset(env) and act(observations, env), got {type(policy).__name__}")
        self.policy = policy
        self.possible_agents = [a for a in names if a not in self.frozen]
        self._frozen_obs: dict[str, Any] = {}

    @property
    def agents(self) -> list[str]:
        return [a for a in self.env.agents if a not in self.frozen]

    def _split(self, d: dict[str, Any]) -> tuple[dict[str, Any], dict[str, Any]]:
        mine = {a: v for a, v in d.items() if a not in self.frozen}
        theirs = {a: v for a, v in d.items() if a in self.frozen}
        return mine, theirs

    def reset(self, seed: int | None = None, options: dict | None = None):
        obs, infos = self.env.reset(seed=seed, options=options)
        self.policy.reset(self.unwrapped)
        obs, self._frozen_obs = self._split(obs)
        return obs, self._split(infos)[0]

    def step(self, actions: dict[str, Any]):
        if not isinstance(actions, dict):
            raise TypeError(f"actions must be a dict {{agent: action}}, got {type(actions).__name__}")
        clash = sorted(set(actions) & self.frozen)
        if clash:
            raise ValueError(f"agent(s) {clash} are frozen (driven by {type(self.policy).__name__}); do not pass their actions")
        live_frozen = {a: o for a, o in self._frozen_obs.items() if a in self.env.agents}
        full = dict(actions)
        full.update(self.policy.act(live_frozen, self.unwrapped) if live_frozen else {})
        obs, rew, term, trunc, infos = self.env.step(full)
        obs, self._frozen_obs = self._split(obs)
        return obs, self._split(rew)[0], self._split(term)[0], self._split(trunc)[0], self._split(infos)[0]


class PadFinishedAgents(_NavWrapper):
    """Keep agents that finished early as zero entries until the episode ends.

    Vector wrappers (SuperSuit's ``pettingzoo_env_to_vec_env_v1``) need a fixed set of agents.
    A robot that reaches its goal or collides gets its last reward on that step (its event is in
    ``info["event"]``), then appears with a zero observation, zero reward and ``False`` flags until
    the episode ends; the last step reports every agent's real outcome (terminated, or truncated
    if it never terminated). SuperSuit's ``black_death_v3`` does the same but only ends the
    episode when an agent is terminated *and* truncated, one step too late for envs whose agents
    end by termination. Observation spaces must be Boxes (``flat_obs=True``).
    """

    def __init__(self, env: ParallelEnv) -> None:
        super().__init__(env)
        self.possible_agents = list(env.possible_agents)
        self.agents: list[str] = []
        for a in self.possible_agents:
            if not isinstance(env.observation_space(a), gymnasium.spaces.Box):
                raise TypeError(f"PadFinishedAgents needs Box observations (flat_obs=True); {a} has {env.observation_space(a)}")

    def reset(self, seed: int | None = None, options: dict | None = None):
        obs, infos = self.env.reset(seed=seed, options=options)
        self.agents = list(self.possible_agents)
        self._terminated: dict[str, bool] = {}
        return obs, {a: infos.get(a, {}) for a in self.agents}

    def step(self, actions: dict[str, Any]):
        live = {a: actions[a] for a in self.env.agents if a in actions}
        obs, rew, term, trunc, infos = self.env.step(live)
        for a, t in term.items():
            self._terminated[a] = self._terminated.get(a, False) or bool(t)
        over = not self.env.agents
        agents = list(self.agents)
        out_obs = {a: obs[a] if a in obs else np.zeros_like(self.observation_space(a).low) for a in agents}
        out_rew = {a: float(rew.get(a, 0.0)) for a in agents}
        out_term = {a: over and self._terminated.get(a, False) for a in agents}
        out_trunc = {a: over and not self._terminated.get(a, False) for a in agents}
        out_info = {a: infos.get(a, {}) for a in agents}
        if over:
            self.agents = []
        return out_obs, out_rew, out_term, out_trunc, out_info


class SingleRobotEnv(gymnasium.Env):
    """A Gymnasium view of one robot in a PettingZoo navzoo env whose other agents are all frozen.

    Args:
        env: a parallel env with exactly one learnable agent (e.g. ``navzoo.make(...)`` with one robot).
    """

    def __init__(self, env: ParallelEnv) -> None:
        if len(env.possible_agents) != 1:
            raise ValueError(
                f"SingleRobotEnv needs exactly one learnable agent, got {env.possible_agents}; "
                "freeze the others with FrozenAgents (navzoo.make does this for pedestrians)"
            )
        self.env = env
        self.agent = env.possible_agents[0]
        self.observation_space = env.observation_space(self.agent)
        self.action_space = env.action_space(self.agent)
        self.metadata = dict(env.metadata)
        self.render_mode = env.render_mode

    def reset(self, *, seed: int | None = None, options: dict | None = None):
        super().reset(seed=seed)
        obs, infos = self.env.reset(seed=seed, options=options)
        return obs[self.agent], infos[self.agent]

    def step(self, action):
        obs, rew, term, trunc, infos = self.env.step({self.agent: action})
        return obs[self.agent], rew[self.agent], term[self.agent], trunc[self.agent], infos[self.agent]

    def render(self):
        return self.env.render()

    def close(self) -> None:
        self.env.close()

    @property
    def unwrapped_nav(self) -> NavEnv:
        return self.env.unwrapped
