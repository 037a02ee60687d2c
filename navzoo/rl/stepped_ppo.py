"""SB3 PPO fed one decision at a time by a loop that someone else owns.

Stable-Baselines3 collects its own rollouts (``PPO.learn`` steps a ``VecEnv``). When robots learn inside
another learner's loop -- the AMP pedestrians' learner steps the navzoo worlds
(:mod:`navzoo.rl.amp_joint`) -- the robots' PPO cannot own the env. :class:`SteppedPPO` keeps SB3's
``PPO`` (the transformer actor-critic of :mod:`navzoo.agents.transformer`, its rollout buffer, GAE and
its ``train()``) and replaces only the collection loop, exactly as ``OnPolicyAlgorithm.collect_rollouts``
does it:

* :meth:`SteppedPPO.act` samples actions for every row (one row per robot), remembering observations,
  values and log-probabilities; when the buffer holds ``n_steps`` decisions it first finishes the
  rollout (GAE from the values of these observations) and runs PPO's update.
* :meth:`SteppedPPO.observe` gives the rewards and episode ends of the last decision. A row that was
  *truncated* (its episode was cut, not ended by its own goal or collision) gets ``gamma * V(final
  observation)`` added to its reward, as SB3 does for time limits.

Checkpoints hold tensors only (policy, optimiser, counters: :meth:`state_dict`); the policy is exported
with :func:`navzoo.agents.robot_train.export_policy`, the format of ``policies/transformer_ppo`` that
the benchmark loads.
"""

from __future__ import annotations

import json
import math
import time
from collections import deque
from collections.abc import Mapping
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

import numpy as np
import torch
from gymnasium import spaces
from stable_baselines3.common.vec_env import VecEnv

__all__ = ["RobotLearnConfig", "SteppedPPO"]


@dataclass
class RobotLearnConfig:
    """The learning robots' PPO (defaults: the paper's n_steps 32 and n_epochs 6).

    Attributes:
        n_steps: decisions per row per rollout.
        n_epochs: PPO epochs per rollout.
        batch_size: minibatch (None: ``min(96, n_steps x rows)``).
        lr, gamma, gae_lambda, ent_coef, target_kl, clip_range: PPO's.
        forward_only: speed command in [0, 1] (diff-drive robots that do not reverse).
        init_from: an exported robot policy folder (``policies/transformer_ppo_crowdnav``, a run's
            ``policy/``) whose weights start the robots; None: a fresh network.
        action_repeat: env steps per robot decision (AMP worlds step at 30 Hz; 3 gives the 10 Hz of
            navzoo's default ``dt``). Rewards of the repeated steps are summed.
        features_dim, heads, blocks, net_arch: the transformer's shape (must match ``init_from``).
        device: torch device of the robots' network.
    """

    n_steps: int = 32
    n_epochs: int = 6
    batch_size: int | None = None
    lr: float = 1e-4
    gamma: float = 0.99
    gae_lambda: float = 0.95
    ent_coef: float = 0.0
    target_kl: float | None = None
    clip_range: float = 0.2
    forward_only: bool = False
    init_from: str | None = None
    action_repeat: int = 3
    features_dim: int = 128
    heads: int = 4
    blocks: int = 3
    net_arch: tuple[int, ...] = (128, 128)
    device: str = "cpu"

    def __post_init__(self) -> None:
        for name in ("n_steps", "n_epochs", "action_repeat", "features_dim", "heads", "blocks"):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, int | np.integer) or v < 1:
                raise ValueError(f"robot learner: {name} must be an integer >= 1, got {v!r}")
        if self.n_steps < 2:
            raise ValueError(f"robot learner: n_steps must be >= 2, got {self.n_steps}")
        if self.batch_size is not None and (isinstance(self.batch_size, bool) or int(self.batch_size) < 2):
            raise ValueError(f"robot learner: batch_size must be >= 2, got {self.batch_size!r}")
        for name, lo, hi in (("lr", 0.0, math.inf), ("gamma", 0.0, 1.0), ("gae_lambda", 0.0, 1.0),
                             ("clip_range", 0.0, math.inf)):
            v = getattr(self, name)
            if not (isinstance(v, int | float) and math.isfinite(v) and lo < v <= hi):
                raise ValueError(f"robot learner: {name} must be in ({lo}, {hi}], got {v!r}")
        if not (math.isfinite(self.ent_coef) and self.ent_coef >= 0):
            raise ValueError(f"robot learner: ent_coef must be a finite number >= 0, got {self.ent_coef!r}")
        if self.target_kl is not None and not (math.isfinite(self.target_kl) and self.target_kl > 0):
            raise ValueError(f"robot learner: target_kl must be a number > 0, got {self.target_kl!r}")
        if self.features_dim % self.heads:
            raise ValueError(f"robot learner: features_dim ({self.features_dim}) must be divisible by heads "
                             f"({self.heads})")
        self.net_arch = tuple(int(w) for w in self.net_arch)
        if not self.net_arch or min(self.net_arch) < 1:
            raise ValueError(f"robot learner: net_arch must be positive widths, got {self.net_arch!r}")
        if self.init_from is not None and not (Path(self.init_from) / "config.json").is_file():
            raise FileNotFoundError(f"robot learner: init_from {self.init_from} is not an exported robot policy "
                                    "folder (no config.json)")

    def to_dict(self) -> dict[str, Any]:
        d = asdict(self)
        d["net_arch"] = list(self.net_arch)
        return d


class _SpacesOnly(VecEnv):
    """A VecEnv that carries spaces and nothing else: SB3's PPO needs one to build its policy and
    buffer; the stepping happens in :class:`SteppedPPO`'s caller."""

    def __init__(self, num_envs: int, observation_space: spaces.Space, action_space: spaces.Space) -> None:
        super().__init__(num_envs, observation_space, action_space)

    def _refuse(self, *args: Any, **kwargs: Any) -> Any:
        raise RuntimeError("SteppedPPO's env only carries spaces: step the real env and feed act()/observe()")

    reset = step_async = step_wait = env_method = set_attr = _refuse

    def get_attr(self, attr_name: str, indices: Any = None) -> list[Any]:
        if attr_name == "render_mode":
            return [None] * self.num_envs
        raise AttributeError(attr_name)

    def env_is_wrapped(self, wrapper_class: Any, indices: Any = None) -> list[bool]:
        return [False] * self.num_envs

    def close(self) -> None:
        pass


class SteppedPPO:
    """SB3 PPO (transformer actor-critic) over ``n_rows`` robots stepped by the caller.

    Args:
        observation_space: one robot's flat observation Box (``flat_obs=True``).
        action_space: one robot's action Box.
        n_rows: robots learning in parallel (rows of every decision).
        config: :class:`RobotLearnConfig`.
        seed: SB3's seed (network initialisation and action sampling).
        log_dir: TensorBoard (``tb_robot/``) and ``robot_metrics.jsonl`` (one line per update) go here.
        env_overrides: ``k_neighbors`` / ``history`` / ``scan_rays`` of the env, for the extractor.
    """

    def __init__(self, observation_space: spaces.Space, action_space: spaces.Space, n_rows: int,
                 config: RobotLearnConfig | None = None, seed: int = 0, log_dir: str | Path | None = None,
                 env_overrides: Mapping[str, Any] | None = None) -> None:
        from stable_baselines3 import PPO
        from stable_baselines3.common.logger import configure

        from navzoo.agents.robot_train import FORWARD_ONLY_ACTIONS, init_weights_from
        from navzoo.agents.transformer import transformer_policy_kwargs

        if isinstance(n_rows, bool) or not isinstance(n_rows, int | np.integer) or n_rows < 1:
            raise ValueError(f"n_rows must be an integer >= 1, got {n_rows!r}")
        if not isinstance(observation_space, spaces.Box) or len(observation_space.shape) != 1:
            raise TypeError(f"SteppedPPO needs flat Box observations (flat_obs=True), got {observation_space}")
        self.cfg = config or RobotLearnConfig()
        self.n_rows = int(n_rows)
        ov = dict(env_overrides or {})
        if self.cfg.forward_only:
            action_space = FORWARD_ONLY_ACTIONS
        self.action_space = action_space
        rollout = self.cfg.n_steps * self.n_rows
        batch = min(96, rollout) if self.cfg.batch_size is None else int(self.cfg.batch_size)
        if batch > rollout:
            raise ValueError(f"robot learner: batch_size {batch} exceeds n_steps x rows = {rollout}")
        kwargs = transformer_policy_kwargs(features_dim=self.cfg.features_dim, n_heads=self.cfg.heads,
                                           n_blocks=self.cfg.blocks, net_arch=self.cfg.net_arch,
                                           k_neighbors=ov.get("k_neighbors"), history=ov.get("history"),
                                           scan_rays=ov.get("scan_rays"))
        self.model = PPO("MlpPolicy", _SpacesOnly(self.n_rows, observation_space, action_space),
                         n_steps=self.cfg.n_steps, n_epochs=self.cfg.n_epochs, batch_size=batch,
                         learning_rate=self.cfg.lr, gamma=self.cfg.gamma, gae_lambda=self.cfg.gae_lambda,
                         ent_coef=self.cfg.ent_coef, target_kl=self.cfg.target_kl, clip_range=self.cfg.clip_range,
                         policy_kwargs=kwargs, device=self.cfg.device, seed=int(seed), verbose=0)
        self.log_dir = Path(log_dir) if log_dir is not None else None
        fmt = ["tensorboard"] if self.log_dir is not None else []
        self.model.set_logger(configure(str(self.log_dir / "tb_robot") if self.log_dir else None, fmt))
        self.model._current_progress_remaining = 1.0  # constant learning rate and clip range
        if self.cfg.init_from:
            try:
                init_weights_from(self.model.policy, self.cfg.init_from)
            except ValueError as err:
                raise ValueError(f"robot learner: init_from {self.cfg.init_from}: {err}") from err
        self._pending: tuple[np.ndarray, np.ndarray, torch.Tensor, torch.Tensor] | None = None
        self._episode_starts = np.ones(self.n_rows, dtype=bool)
        self._ep_return = np.zeros(self.n_rows, dtype=np.float64)
        self._episodes: deque[tuple[float, str]] = deque(maxlen=100)
        self.updates = 0
        self.last_update: dict[str, Any] | None = None
        self._t0 = time.perf_counter()
        self._steps0 = 0

    # ------------------------------------------------------------------ counters
    @property
    def num_timesteps(self) -> int:
        """Robot decisions recorded so far (all rows), restored on resume."""
        return int(self.model.num_timesteps)

    # ------------------------------------------------------------------ the loop
    def act(self, obs: np.ndarray) -> np.ndarray:
        """Sample actions ``(n_rows, act_dim)`` (clipped to the action box) for observations ``(n_rows,
        obs_dim)``. Runs PPO's update first when the last rollout is complete."""
        if self._pending is not None:
            raise RuntimeError("SteppedPPO.act: observe() the previous decision's rewards first")
        obs = np.asarray(obs, dtype=np.float32)
        shape = (self.n_rows, *self.model.observation_space.shape)
        if obs.shape != shape or not np.isfinite(obs).all():
            raise ValueError(f"SteppedPPO.act: observations must be finite with shape {shape}, got {obs.shape}")
        if self.model.rollout_buffer.full:
            self._update(obs)
        from stable_baselines3.common.utils import obs_as_tensor

        self.model.policy.set_training_mode(False)
        with torch.no_grad():
            actions, values, log_probs = self.model.policy(obs_as_tensor(obs, self.model.device))
        actions = actions.cpu().numpy()
        self._pending = (obs, actions, values, log_probs)
        return np.clip(actions, self.action_space.low, self.action_space.high)

    def observe(self, rewards: np.ndarray, dones: np.ndarray, final_obs: Mapping[int, np.ndarray] | None = None,
                events: Mapping[int, str] | None = None, padding: np.ndarray | None = None) -> None:
        """Record the outcome of the last :meth:`act`.

        Args:
            rewards: ``(n_rows,)`` rewards since that decision (summed over repeated steps).
            dones: ``(n_rows,)`` whether the row's episode ended.
            final_obs: row -> last observation, for rows whose episode was *truncated*: their reward
                gets ``gamma * V(final observation)`` (rows ended by their own goal or collision get none).
            events: row -> the navzoo event that ended the row's episode (``"goal"``, ``"collision_*"``,
                ...), for the success and collision rates of :meth:`update` lines.
            padding: ``(n_rows,)`` rows that stood in for robots already finished (not counted in
                episode statistics).
        """
        if self._pending is None:
            raise RuntimeError("SteppedPPO.observe: call act() first")
        rewards = np.asarray(rewards, dtype=np.float32).copy()
        dones = np.asarray(dones, dtype=bool)
        if rewards.shape != (self.n_rows,) or dones.shape != (self.n_rows,) or not np.isfinite(rewards).all():
            raise ValueError(f"SteppedPPO.observe: rewards and dones must be finite with shape ({self.n_rows},), "
                             f"got {rewards.shape} and {dones.shape}")
        pad = np.zeros(self.n_rows, bool) if padding is None else np.asarray(padding, dtype=bool)
        self._ep_return += np.where(pad, 0.0, rewards)
        for i in np.flatnonzero(dones & ~pad):
            self._episodes.append((float(self._ep_return[i]), str((events or {}).get(int(i), "truncated"))))
        self._ep_return[dones] = 0.0
        if final_obs:
            rows = sorted(int(i) for i in final_obs)
            x = torch.as_tensor(np.stack([np.asarray(final_obs[i], np.float32) for i in rows]),
                                device=self.model.device)
            with torch.no_grad():
                v = self.model.policy.predict_values(x).squeeze(-1).cpu().numpy()
            rewards[rows] += self.cfg.gamma * v
        obs, actions, values, log_probs = self._pending
        self.model.rollout_buffer.add(obs, actions, rewards, self._episode_starts, values, log_probs)
        self._episode_starts = dones.copy()
        self.model.num_timesteps += self.n_rows
        self._pending = None

    def _update(self, next_obs: np.ndarray) -> dict[str, Any]:
        from stable_baselines3.common.utils import obs_as_tensor

        buf = self.model.rollout_buffer
        with torch.no_grad():
            last_values = self.model.policy.predict_values(obs_as_tensor(next_obs, self.model.device))
        buf.compute_returns_and_advantage(last_values=last_values, dones=self._episode_starts)
        t0 = time.perf_counter()
        with torch.enable_grad():  # the caller's loop may run under no_grad (the AMP learner's collect does)
            self.model.train()
        self.updates += 1
        logged = dict(self.model.logger.name_to_value)
        eps = list(self._episodes)
        n = self.num_timesteps
        row: dict[str, Any] = {
            "robot_timesteps": n, "robot_updates": self.updates,
            "decisions_per_s": round((n - self._steps0) / max(time.perf_counter() - self._t0, 1e-9), 2),
            "update_s": round(time.perf_counter() - t0, 3), "episodes": len(eps),
            "ep_rew_mean": round(float(np.mean([r for r, _ in eps])), 4) if eps else None,
            "success_rate": round(sum(e == "goal" for _, e in eps) / len(eps), 4) if eps else None,
            "collision_rate": round(sum(e.startswith("collision") for _, e in eps) / len(eps), 4) if eps else None,
        }
        for key in ("train/value_loss", "train/policy_gradient_loss", "train/entropy_loss", "train/approx_kl",
                    "train/clip_fraction"):
            if key in logged:
                row[key.split("/")[1]] = round(float(logged[key]), 6)
        for key in ("ep_rew_mean", "success_rate", "collision_rate"):
            if row[key] is not None:
                self.model.logger.record(f"robot/{key}", row[key])
        self.model.logger.dump(n)
        if self.log_dir is not None:
            self.log_dir.mkdir(parents=True, exist_ok=True)
            with open(self.log_dir / "robot_metrics.jsonl", "a") as f:
                f.write(json.dumps(row) + "\n")
        buf.reset()
        self.last_update = row
        return row

    # ------------------------------------------------------------------ checkpoints
    def state_dict(self) -> dict[str, Any]:
        """Tensors and plain numbers only (loadable with ``torch.load(weights_only=True)``): the policy,
        its optimiser, the counters and this learner's config. A partly filled rollout is not kept."""
        return {"policy": self.model.policy.state_dict(), "optimizer": self.model.policy.optimizer.state_dict(),
                "num_timesteps": int(self.model.num_timesteps), "n_updates": int(self.model._n_updates),
                "updates": int(self.updates), "config": json.dumps(self.cfg.to_dict())}

    def load_state_dict(self, state: Mapping[str, Any]) -> None:
        """Restore :meth:`state_dict`; the next :meth:`act` starts a new rollout. Raises ``ValueError``
        naming what does not fit (another network shape, missing entries)."""
        try:
            saved = json.loads(state["config"])
            shape = ("features_dim", "heads", "blocks", "net_arch", "forward_only")
            diff = [k for k in shape if saved.get(k) != self.cfg.to_dict()[k]]
            if diff:
                raise ValueError(f"made with other {diff}: {[saved.get(k) for k in diff]}")
            self.model.policy.load_state_dict(state["policy"])
            self.model.policy.optimizer.load_state_dict(state["optimizer"])
            self.model.num_timesteps = int(state["num_timesteps"])
            self.model._n_updates = int(state["n_updates"])
            self.updates = int(state["updates"])
        except (KeyError, RuntimeError, TypeError, json.JSONDecodeError) as err:
            raise ValueError(f"robot learner state is incomplete or does not fit this network ({err})") from err
        for group in self.model.policy.optimizer.param_groups:  # this run's learning rate wins
            group["lr"] = self.cfg.lr
        self.model.rollout_buffer.reset()
        self._pending = None
        self._episode_starts[:] = True
        self._ep_return[:] = 0.0
        self._steps0 = self.num_timesteps
        self._t0 = time.perf_counter()

    def export(self, out_dir: str | Path, meta: Mapping[str, Any] | None = None) -> Path:
        """Write the policy in the shipped robot-policy format (``policy.pt`` + ``config.json``); returns
        the folder. Load it with ``navzoo.agents.robot_train.load_policy`` or as ``sb3:DIR`` robots."""
        from navzoo.agents.robot_train import export_policy

        return export_policy(self.model, out_dir, {"robot_learner": self.cfg.to_dict(), **dict(meta or {})}).parent
