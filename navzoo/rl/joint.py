"""The PettingZoo env of a joint config, and trained RLlib modules as navzoo policies (no Ray needed
unless an ``rllib:PATH`` policy is loaded).

:func:`make_parallel_env` builds the bare :class:`~navzoo.envs.nav_env.NavEnv` (robots and pedestrians
are agents, flat observations) and wraps each frozen side in
:class:`~navzoo.envs.wrappers.FrozenAgents`, so that only the learning sides remain agents.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from pettingzoo import ParallelEnv

from navzoo.rl.config import (
    AMP_PREFIX,
    CROWD,
    FROZEN,
    HUMAN_POLICY_ID,
    RLLIB_PREFIX,
    ROBOT_POLICY_ID,
    JointConfig,
)

__all__ = ["FlatObsPolicy", "RLModulePolicy", "frozen_human_policy", "frozen_robot_policy", "make_parallel_env"]


def _is_robot(agent: str) -> bool:
    return agent.startswith("robot_")


def _is_human(agent: str) -> bool:
    return agent.startswith("human_")


def make_parallel_env(cfg: JointConfig | dict[str, Any], render_mode: str | None = None,
                      training: bool = True) -> ParallelEnv:
    """The PettingZoo env of a joint config: learning sides are agents, frozen sides run inside.

    Args:
        cfg: a :class:`JointConfig` or its dict.
        render_mode: passed to the env.
        training: see :meth:`JointConfig.validate` (``False``: every side frozen, no agent left).
    """
    import navzoo
    from navzoo.envs.wrappers import FrozenAgents

    if not isinstance(cfg, JointConfig):
        cfg = JointConfig.from_dict(dict(cfg))
    cfg.validate(check_paths=False, training=training)
    env: ParallelEnv = navzoo.make(cfg.env_id, render_mode=render_mode, raw=True, **cfg.nav_overrides())
    nav = env.unwrapped
    if nav.n_humans and cfg.humans == CROWD:
        from navzoo.agents.crowd import CrowdPolicy

        env = FrozenAgents(env, _is_human, CrowdPolicy(nav.config.crowd_model, see_robots=nav.config.humans_see_robots))
    elif nav.n_humans and cfg.humans == FROZEN:
        env = FrozenAgents(env, _is_human, frozen_human_policy(cfg))
    if nav.n_robots and cfg.robots == FROZEN:
        env = FrozenAgents(env, _is_robot, frozen_robot_policy(cfg))
    return env


def frozen_robot_policy(cfg: JointConfig):
    """The navzoo Policy of frozen robots: a baseline by name or a trained RLlib module."""
    if cfg.robot_policy.startswith(RLLIB_PREFIX):
        return RLModulePolicy(cfg.robot_policy[len(RLLIB_PREFIX):], ROBOT_POLICY_ID)
    from navzoo.agents.baselines import make_policy

    return make_policy(cfg.robot_policy)


def frozen_human_policy(cfg: JointConfig):
    """The navzoo Policy of frozen pedestrians: the AMP controller or a trained RLlib module."""
    spec = cfg.human_policy
    if spec is None or spec == AMP_PREFIX or spec.startswith(AMP_PREFIX + ":"):
        from navzoo.agents.amp.pedestrian_policy import AmpPedestrianPolicy

        return AmpPedestrianPolicy(spec[len(AMP_PREFIX) + 1:] if spec and ":" in spec else None)
    return RLModulePolicy(spec[len(RLLIB_PREFIX):], HUMAN_POLICY_ID)


class FlatObsPolicy:
    """A policy trained on flat observations (``flat_obs=True``), run in an env with Dict observations.

    Flattens each agent's Dict observation with the env's own space (``gymnasium.spaces.flatten``, the
    layout ``flat_obs=True`` gives) before handing it to ``policy``; flat ones pass through. Lets
    pedestrians trained with RLlib walk in the benchmark, whose robots observe Dicts.
    """

    def __init__(self, policy) -> None:
        self.policy = policy

    def reset(self, env) -> None:
        return self.policy.reset(env)

    def act(self, observations: dict[str, Any], env) -> dict[str, np.ndarray]:
        from gymnasium import spaces

        space = env.unwrapped._dict_space
        flat = {a: spaces.flatten(space, o).astype(np.float32) if isinstance(o, dict) else o
                for a, o in observations.items()}
        return self.policy.act(flat, env)


class RLModulePolicy:
    """A trained RLlib module as a navzoo :class:`~navzoo.agents.policy.Policy` (deterministic actions).

    Lets a side trained by :mod:`navzoo.rl.train` be frozen in a later run (``rllib:PATH``) or driven
    by any navzoo tool that takes a policy. One batched forward pass per step, on the CPU.

    Args:
        path: a training ``--out`` folder, a checkpoint, or the module folder.
        module_id: ``"robot"`` or ``"human"``.
    """

    def __init__(self, path: str, module_id: str) -> None:
        import torch
        from ray.rllib.core.rl_module.rl_module import RLModule

        from navzoo.rl.config import resolve_module_dir

        self.path = str(resolve_module_dir(path, module_id))
        self.module_id = module_id
        self.module = RLModule.from_checkpoint(self.path)
        self.module.eval()
        self._dist_cls = self.module.get_inference_action_dist_cls()
        self._torch = torch

    def __getstate__(self) -> dict[str, Any]:  # rebuilt from its folder in another process
        return {"path": self.path, "module_id": self.module_id}

    def __setstate__(self, state: dict[str, Any]) -> None:
        self.__init__(state["path"], state["module_id"])

    def reset(self, env) -> None:
        return None

    def act(self, observations: dict[str, Any], env) -> dict[str, np.ndarray]:
        names = list(observations)
        if not names:
            return {}
        torch = self._torch
        obs = torch.as_tensor(np.stack([np.asarray(observations[a], dtype=np.float32) for a in names]))
        with torch.no_grad():
            out = self.module.forward_inference({"obs": obs})
            dist = self._dist_cls.from_logits(out["action_dist_inputs"]).to_deterministic()
            actions = dist.sample().cpu().numpy()
        actions = np.clip(actions, -1.0, 1.0).astype(np.float32)
        return {a: actions[k] for k, a in enumerate(names)}
