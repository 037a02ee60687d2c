"""Vectorised envs for Stable-Baselines3 through SuperSuit, seeded properly.

SuperSuit's ``concat_vec_envs_v1`` returns a vector env whose ``seed()`` is missing, so
``PPO(..., seed=s)`` fails on it, and copies must be seeded apart. :func:`sb3_vec_env` builds the
usual SuperSuit chain (robots that finish early padded with zero entries, agents as vector entries, copies
concatenated, optionally in worker processes) and wraps it so that ``seed(s)`` makes the next reset
seed copy ``i`` with ``s + i``: two runs with the same seed see the same episodes.
"""

from __future__ import annotations

from typing import Any

import supersuit as ss
from supersuit.vector.sb3_vector_wrapper import SB3VecEnvWrapper

from navzoo.envs.registry import make
from navzoo.envs.wrappers import PadFinishedAgents


class SeededSB3VecEnv(SB3VecEnvWrapper):
    """SuperSuit's SB3 adapter with a working ``seed()``."""

    def __init__(self, venv: Any, seed: int | None = None) -> None:
        super().__init__(venv)
        self._next_seed = seed

    def seed(self, seed: int | None = None) -> list[int | None]:
        self._next_seed = seed
        return [None if seed is None else seed + i for i in range(self.num_envs)]

    def reset(self, seed: int | None = None, options: dict | None = None):
        if seed is not None:
            self._next_seed = seed
        seed, self._next_seed = self._next_seed, None
        observations, self.reset_infos = self.venv.reset(seed=seed, options=options)
        return observations


def sb3_vec_env(
    env_id: str | None = None, n_envs: int = 1, seed: int | None = 0, num_cpus: int = 0, **overrides: Any
) -> SeededSB3VecEnv:
    """A Stable-Baselines3 ``VecEnv`` of ``n_envs`` copies of a navzoo env (robots as entries).

    Each robot of each copy is one entry of the vector (``num_envs = n_envs * n_robots``);
    pedestrians are frozen on their crowd model. Observations are flat (``flat_obs=True``).

    Args:
        env_id: a registered id (or None for the default config).
        n_envs: env copies.
        seed: seed of the first reset (copy i gets ``seed + i``); None = unseeded.
        num_cpus: worker processes for the copies (0 = all in this process).
        **overrides: NavConfig fields.
    """
    if n_envs < 1:
        raise ValueError(f"n_envs must be >= 1, got {n_envs}")
    overrides = {"flat_obs": True, **overrides}
    env = make(env_id, **overrides)
    if len(env.possible_agents) > 1:
        # Robots leave the env when done; SuperSuit's vector needs a fixed set of agents.
        env = PadFinishedAgents(env)
    vec = ss.pettingzoo_env_to_vec_env_v1(env)
    vec = ss.concat_vec_envs_v1(vec, n_envs, num_cpus=num_cpus, base_class="gymnasium")
    return SeededSB3VecEnv(vec, seed)
