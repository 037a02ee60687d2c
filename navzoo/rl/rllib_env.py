"""navzoo as an RLlib multi-agent env (new API stack).

:func:`navzoo.rl.joint.make_parallel_env` builds the PettingZoo env of a
:class:`~navzoo.rl.config.JointConfig`: the bare :class:`~navzoo.envs.nav_env.NavEnv` (robots and
pedestrians are agents, flat observations) with each frozen side wrapped in
:class:`~navzoo.envs.wrappers.FrozenAgents`, so only the learning sides remain agents.

:class:`NavzooMultiAgentEnv` adapts it to RLlib's ``MultiAgentEnv``. RLlib's own
``ParallelPettingZooEnv`` is not used: it sets ``terminateds["__all__"]`` only when *every* agent of
the last step terminated and ``truncateds["__all__"]`` only when every one was truncated, so the
usual navzoo ending (the last robot reaches its goal, terminated, on the step where the pedestrians
are cut off, truncated) is never seen as the end of the episode; it also calls ``render`` with an
argument PettingZoo no longer takes. Here the episode is over exactly when the PettingZoo env has no
live agent left, and ``__all__`` says whether everyone terminated (else it is a truncation, and RLlib
bootstraps the value of the agents that were cut off). Agents that finish early (a robot at its goal
or after a collision) report their last step and then no longer appear, as RLlib expects.

:func:`register` registers the env with Tune's registry as ``"navzoo"``; importing this module needs
Ray (``pip install navzoo[ray]``).
"""

from __future__ import annotations

import time
from typing import Any

import gymnasium as gym
import numpy as np
from ray.rllib.callbacks.callbacks import RLlibCallback
from ray.rllib.env.multi_agent_env import MultiAgentEnv

from navzoo.rl.config import JointConfig
from navzoo.rl.joint import RLModulePolicy, _is_robot, make_parallel_env

__all__ = ["ENV_NAME", "NavzooMetrics", "NavzooMultiAgentEnv", "RLModulePolicy", "env_creator", "make_parallel_env",
           "register"]

ENV_NAME = "navzoo"


class NavzooMultiAgentEnv(MultiAgentEnv):
    """RLlib ``MultiAgentEnv`` of a navzoo joint config (see the module docstring).

    Args:
        config: a :class:`JointConfig`, its dict, or RLlib's ``EnvContext`` holding that dict
            (``config.environment("navzoo", env_config=joint.to_dict())``).
    """

    def __init__(self, config: JointConfig | dict[str, Any] | None = None) -> None:
        super().__init__()
        cfg = config if isinstance(config, JointConfig) else JointConfig.from_dict(dict(config or {}))
        self.joint = cfg
        self.par_env = make_parallel_env(cfg)
        self.possible_agents = list(self.par_env.possible_agents)
        self.agents = []
        self.observation_spaces = {a: self.par_env.observation_space(a) for a in self.possible_agents}
        self.action_spaces = {a: self.par_env.action_space(a) for a in self.possible_agents}
        self.observation_space = gym.spaces.Dict(self.observation_spaces)
        self.action_space = gym.spaces.Dict(self.action_spaces)
        self.episode_summary: dict[str, Any] = {}
        self._events: dict[str, str] = {}
        self._step_s = 0.0

    @property
    def unwrapped_nav(self):
        return self.par_env.unwrapped

    def reset(self, *, seed: int | None = None, options: dict | None = None):
        obs, infos = self.par_env.reset(seed=seed, options=options)
        self.agents = list(self.par_env.agents)
        self._events, self._step_s = {}, 0.0
        return obs, {a: infos.get(a, {}) for a in obs}

    def step(self, action_dict: dict[str, Any]):
        # An agent that finished in the last step got its final observation; an action for it is ignored.
        done = set(self.possible_agents) - set(self.par_env.agents)
        t0 = time.perf_counter()
        obs, rew, term, trunc, infos = self.par_env.step({a: v for a, v in action_dict.items() if a not in done})
        self._step_s += time.perf_counter() - t0
        self.agents = list(self.par_env.agents)
        for a, info in infos.items():
            if _is_robot(a) and (term.get(a) or trunc.get(a)):
                self._events[a] = info.get("event", "timeout" if trunc.get(a) else "done")
        over = not self.agents
        all_term = over and all(term.values())
        term = dict(term)
        trunc = dict(trunc)
        term["__all__"] = all_term
        trunc["__all__"] = over and not all_term
        if over:
            self.episode_summary = self._summary()
        return obs, rew, term, trunc, infos

    def _summary(self) -> dict[str, Any]:
        nav = self.par_env.unwrapped
        robots = [a for a in nav.possible_agents if _is_robot(a)]
        events = [self._events.get(a, nav.events.get(a, "timeout")) for a in robots]
        n = max(len(robots), 1)
        return {
            "robot_success": sum(e == "goal" for e in events) / n if robots else float("nan"),
            "robot_collision": sum(e.startswith("collision") for e in events) / n if robots else float("nan"),
            "robot_timeout": sum(e == "timeout" for e in events) / n if robots else float("nan"),
            # Every pedestrian counts, learning or frozen (the env's own counter).
            "human_goals_per_human": float(nav.goals_reached[nav.n_robots:].mean()) if nav.n_humans else float("nan"),
            "episode_steps": int(nav.steps),
            # Wall time of one env step (simulation and frozen policies) in this env runner.
            "env_step_ms": 1000.0 * self._step_s / max(int(nav.steps), 1),
        }

    def render(self):
        return self.par_env.render()

    def close(self) -> None:
        self.par_env.close()


class NavzooMetrics(RLlibCallback):
    """Logs navzoo's episode outcomes (robot success/collision/timeout rate, pedestrian goals) per episode."""

    def on_episode_end(self, *, episode=None, env=None, env_index: int = 0, metrics_logger=None, **kwargs) -> None:
        if metrics_logger is None or env is None:
            return
        inner = None
        try:
            inner = env.envs[env_index].unwrapped
        except (AttributeError, IndexError, TypeError):
            inner = getattr(env, "unwrapped", None)
        summary = getattr(inner, "episode_summary", None)
        if not summary:
            return
        for key, value in summary.items():
            if isinstance(value, float) and np.isnan(value):
                continue
            metrics_logger.log_value(f"navzoo/{key}", float(value), reduce="mean", window=100)


def env_creator(env_config: dict[str, Any]) -> NavzooMultiAgentEnv:
    """Tune registry entry point: ``env_config`` is a JointConfig dict (RLlib passes an EnvContext)."""
    return NavzooMultiAgentEnv(dict(env_config))


def register(name: str = ENV_NAME) -> str:
    """Register the navzoo env with Tune's registry (``config.environment(name, env_config=...)``)."""
    from ray.tune.registry import register_env

    register_env(name, env_creator)
    return name
