"""Adversarial Motion Priors (Peng et al. 2021) on PPO: a generic learner for any :class:`AmpVecEnv`.

The loop reads top to bottom (CleanRL style)::

    learner = AmpLearner(env, AmpConfig(), device="cpu")
    learner.train(total_steps=20_000_000, log_dir="runs/amp", ckpt_dir="runs/amp/ckpt")

    # or by hand:
    while ...:
        learner.collect(config.rollout_steps)   # E envs x T steps with the current policy
        stats = learner.update()                # rewards, GAE, PPO epochs, discriminator steps

One iteration (``docs/amp_learner.md`` has the equations and the sources of every default):

1. ``collect``: act with ``a = mu(s) + sigma * eps`` (actions clipped to [-1, 1] for the env), store
   raw observations, actions, task rewards, termination/truncation flags, the discriminator input of
   every transition and the final observation of truncated episodes.
2. ``update``: fold the rollout (and a fresh batch of reference windows) into the running
   normalisers; style reward ``r_S = -log(max(1 - sigmoid(D(x)), 1e-4))`` from the discriminator
   *before* it trains on this batch; ``r = scale * (w_S r_S + w_T r_T)``; values, GAE with
   bootstrapping from ``V(final_obs)`` on truncation; then ``epochs`` passes over shuffled
   minibatches, each one a PPO actor step (clipped surrogate + bounds loss), a critic step (MSE on
   normalised returns) and a discriminator step (BCE reference-vs-policy with policy samples half
   fresh, half from the replay buffer, gradient penalty on reference samples, logit regularisation,
   weight decay). Finally the rollout's discriminator inputs enter the replay buffer.

Randomness: one ``numpy`` generator (minibatch order, replay and reference sampling) and one CPU
``torch`` generator (action noise), both seeded from ``config.seed`` and saved in checkpoints, so
that a resumed run continues bit-identically on CPU when the env can save its state too (optional
``env.state_dict()`` / ``env.load_state_dict()``; without them the env is reset on resume).
"""

from __future__ import annotations

import copy
import dataclasses
import json
import math
import signal
import threading
import time
import warnings
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Protocol, runtime_checkable

import numpy as np
import torch
from torch import nn
from torch.nn import functional as F

from navzoo.agents.amp import checkpoint as ckpt
from navzoo.agents.amp.checkpoint import CheckpointError, load_policy  # noqa: F401  (re-exported)
from navzoo.agents.amp.networks import (
    Actor,
    Critic,
    Discriminator,
    bounds_loss,
    gradient_penalty,
    style_reward,
)
from navzoo.agents.amp.normalizer import RunningMeanStd
from navzoo.agents.amp.replay import ReplayBuffer

__all__ = [
    "AmpConfig",
    "AmpLearner",
    "AmpVecEnv",
    "CheckpointError",
    "compute_gae",
    "load_policy",
]


@runtime_checkable
class AmpVecEnv(Protocol):
    """A batched, auto-resetting environment: all the learner needs from the physics.

    Attributes:
        num_envs: E, number of parallel environments.
        obs_dim: policy observation size.
        act_dim: action size; actions are normalised to [-1, 1] (the learner clips them).
        amp_obs_dim: size of one discriminator input: the features of a window of frames, already
            stacked, describing the transition just taken.

    ``step`` returns ``(obs, task_reward, terminated, truncated, info)`` with shapes (E, obs_dim),
    (E,), (E,) bool, (E,) bool. Finished envs are reset inside ``step``: their ``obs`` row is the
    first observation of the new episode. ``info["amp_obs"]`` (E, amp_obs_dim) describes the
    transition just taken (for a finished env: the one *into* its final state, before the reset);
    ``info["final_obs"]`` (E, obs_dim) holds, in the rows of envs that finished this step, their last
    observation (used to bootstrap truncated episodes; other rows are ignored and it may be absent
    when no env was truncated).

    Optional, for bit-identical resume: ``state_dict() -> dict`` of numpy arrays and JSON values,
    and ``load_state_dict(state)``.
    """

    num_envs: int
    obs_dim: int
    act_dim: int
    amp_obs_dim: int

    def reset(self, seed: int | None = None) -> np.ndarray: ...

    def step(
        self, actions: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, dict[str, Any]]: ...

    def sample_reference_amp_obs(self, n: int, rng: np.random.Generator) -> np.ndarray: ...


# Discriminator inputs of checkpoints saved before ``amp_obs_version`` was recorded (up to 3315).
_LEGACY_AMP_OBS_VERSION = "velocity=physics;ground=None"

# Fields that fix tensor shapes: a checkpoint can only be loaded into a learner that agrees on them.
_ARCH_FIELDS = ("actor_hidden", "critic_hidden", "disc_hidden", "activation", "learn_std")


@dataclass(frozen=True)
class AmpConfig:
    """Hyper-parameters of AMP + PPO. Sources of the defaults are in ``docs/amp_learner.md``.

    Attributes:
        seed: seeds network initialisation, the learner's generators and the first env reset.
        rollout_steps: T, steps per env per iteration (IsaacGymEnvs ``horizon_length`` 16).
        actor_hidden, critic_hidden, disc_hidden: MLP widths ([512, 256] CPU default; public GPU
            runs use [1024, 512]).
        activation: hidden activation (``relu`` as IsaacGymEnvs).
        gamma, gae_lambda: discount and GAE lambda.
        clip_coef: PPO ratio clip.
        epochs: passes over the rollout per iteration.
        minibatch_size: PPO minibatch (the rollout is split into ``round(T*E / minibatch_size)``
            near-equal parts, at least one).
        actor_lr, critic_lr, disc_lr: Adam learning rates.
        adam_eps: Adam epsilon.
        max_grad_norm: gradient-norm clip, per network.
        normalize_advantages: standardise advantages over the rollout.
        normalize_value: the critic predicts returns standardised by a running mean/std.
        init_log_std: log of the action noise std in the [-1, 1] action box (-2.9 -> sigma 0.055). With a
            fixed std (``learn_std`` False) it is a hyper-parameter like the learning rates: a resumed
            checkpoint takes this value (``navzoo train amp --init-log-std``).
        learn_std: learn the log-std (default: fixed, as public AMP).
        bounds_loss_coef, bounds_soft: penalty ``coef * sum(relu(|mu| - soft)^2)`` on the mean action.
        entropy_coef: entropy bonus (0: with a fixed std it would be constant anyway).
        mirror_coef: weight of the mirror-symmetry loss on the mean action,
            ``|mu(o) - M_a mu(M_o o)|^2`` summed over action columns (Yu, Turk and Liu 2018; maps in
            :mod:`navzoo.agents.amp.symmetry`); 0 = off. Needs the controller's observation layout
            (self-observation, 10 target points, optionally the 16 rays) and its 28 actions.
        disc_minibatch_size: policy samples per discriminator step (taken from the PPO minibatch);
            as many replay samples and reference samples join them.
        disc_grad_penalty: weight of the gradient penalty on reference samples.
        disc_logit_reg: weight of the squared logit-layer weights.
        disc_weight_decay: weight of the squared weights of all discriminator layers.
        replay_size: capacity of the replay buffer of policy discriminator inputs.
        replay_keep_prob: once the buffer has seen ``replay_size`` rows, keep a new row with this
            probability (IsaacGymEnvs: 0.01 with a 10^6 buffer; 1.0 = plain FIFO).
        style_weight, task_weight: ``r = reward_scale * (style_weight r_S + task_weight r_T)``.
        reward_scale: overall reward multiplier.
        reward_clip: clip of the combined per-step reward to ``[-clip, clip]``; ``None`` = off.
        obs_clip: clip of normalised observations and discriminator inputs.
        norm_eps: added to variances before normalising.
        ckpt_replay_rows: replay rows saved in a checkpoint (all of them when the buffer holds fewer:
            then a resume is exact; otherwise a uniform sample).
        keep_checkpoints: how many checkpoints ``train`` keeps.
        bc_coef: weight of a behaviour-cloning term on the actor, the mean over a minibatch of cloning pairs
            (:meth:`AmpLearner.set_bc_data`) of the squared distance between the mean action and the pair's action,
            summed over action dimensions; it keeps an actor cloned from the clips near their gait while PPO
            teaches it balance (:mod:`navzoo.agents.amp.bc`). 0 = off; > 0 needs the pairs.
        anchor_coef: weight of a trust-region term that holds the actor near a frozen copy of itself (its anchor,
            :meth:`AmpLearner.set_anchor`, e.g. the policy a fine-tune starts from): the mean over the minibatch's own
            states of KL(anchor(.|s) || actor(.|s)), summed over action dimensions; each policy reads the state
            through its own observation normaliser, so the anchor keeps meaning what it meant when it was set.
            With the fixed exploration std (0.055) a mean shift of 0.055 in one action dimension costs 0.5.
            0 = off (the KL is still logged as ``anchor/kl`` when an anchor is set); > 0 needs an anchor.
        actor_warmup_iters: the actor is not updated before this iteration (critic and discriminator are), e.g.
            to fit a fresh critic to an actor that starts from behaviour cloning (:mod:`navzoo.agents.amp.bc`);
            0 = off. The iteration counts from the start of the run, so a resumed run past it is unaffected.
    """

    seed: int = 0
    rollout_steps: int = 16
    actor_hidden: tuple[int, ...] = (512, 256)
    critic_hidden: tuple[int, ...] = (512, 256)
    disc_hidden: tuple[int, ...] = (512, 256)
    activation: str = "relu"
    gamma: float = 0.99
    gae_lambda: float = 0.95
    clip_coef: float = 0.2
    epochs: int = 5
    minibatch_size: int = 2048
    actor_lr: float = 5e-5
    critic_lr: float = 1e-4
    disc_lr: float = 1e-4
    adam_eps: float = 1e-5
    max_grad_norm: float = 1.0
    normalize_advantages: bool = True
    normalize_value: bool = True
    init_log_std: float = -2.9
    learn_std: bool = False
    bounds_loss_coef: float = 10.0
    bounds_soft: float = 1.1
    entropy_coef: float = 0.0
    mirror_coef: float = 0.0
    disc_minibatch_size: int = 512
    disc_grad_penalty: float = 5.0
    disc_logit_reg: float = 0.05
    disc_weight_decay: float = 1e-4
    replay_size: int = 100_000
    replay_keep_prob: float = 1.0
    style_weight: float = 1.0
    task_weight: float = 0.5
    reward_scale: float = 1.0
    reward_clip: float | None = 100.0
    obs_clip: float = 5.0
    norm_eps: float = 1e-5
    ckpt_replay_rows: int = 100_000
    keep_checkpoints: int = 3
    actor_warmup_iters: int = 0
    bc_coef: float = 0.0
    anchor_coef: float = 0.0

    def __post_init__(self) -> None:
        for name in ("actor_hidden", "critic_hidden", "disc_hidden"):
            value = tuple(int(h) for h in getattr(self, name))
            if not value or any(h <= 0 for h in value):
                raise ValueError(f"AmpConfig.{name} must be non-empty positive widths, got {value}")
            object.__setattr__(self, name, value)
        positive_ints = (
            "rollout_steps",
            "epochs",
            "minibatch_size",
            "disc_minibatch_size",
            "replay_size",
            "ckpt_replay_rows",
            "keep_checkpoints",
        )
        for name in positive_ints:
            if int(getattr(self, name)) <= 0:
                raise ValueError(f"AmpConfig.{name} must be a positive integer, got {getattr(self, name)!r}")
        positive = (
            "actor_lr",
            "critic_lr",
            "disc_lr",
            "adam_eps",
            "max_grad_norm",
            "clip_coef",
            "obs_clip",
            "norm_eps",
            "bounds_soft",
            "reward_scale",
        )
        for name in positive:
            v = getattr(self, name)
            if not (isinstance(v, int | float) and math.isfinite(v) and v > 0):
                raise ValueError(f"AmpConfig.{name} must be a finite positive number, got {v!r}")
        non_negative = (
            "bounds_loss_coef",
            "entropy_coef",
            "mirror_coef",
            "disc_grad_penalty",
            "disc_logit_reg",
            "disc_weight_decay",
            "style_weight",
            "task_weight",
            "bc_coef",
            "anchor_coef",
        )
        if not (isinstance(self.actor_warmup_iters, int) and self.actor_warmup_iters >= 0):
            raise ValueError(f"AmpConfig.actor_warmup_iters must be an integer >= 0, got {self.actor_warmup_iters!r}")
        for name in non_negative:
            v = getattr(self, name)
            if not (isinstance(v, int | float) and math.isfinite(v) and v >= 0):
                raise ValueError(f"AmpConfig.{name} must be a finite number >= 0, got {v!r}")
        for name in ("gamma", "gae_lambda"):
            v = getattr(self, name)
            if not 0.0 <= v <= 1.0:
                raise ValueError(f"AmpConfig.{name} must be in [0, 1], got {v!r}")
        if not 0.0 < self.replay_keep_prob <= 1.0:
            raise ValueError(f"AmpConfig.replay_keep_prob must be in (0, 1], got {self.replay_keep_prob!r}")
        if self.reward_clip is not None and not self.reward_clip > 0:
            raise ValueError(f"AmpConfig.reward_clip must be positive or None, got {self.reward_clip!r}")
        if self.activation not in ("relu", "elu", "tanh"):
            raise ValueError(f"AmpConfig.activation must be relu, elu or tanh, got {self.activation!r}")
        if not math.isfinite(self.init_log_std):
            raise ValueError(f"AmpConfig.init_log_std must be finite, got {self.init_log_std!r}")

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> AmpConfig:
        """Build from a dict (e.g. JSON); unknown keys raise ``ValueError`` listing the valid ones."""
        valid = {f.name for f in dataclasses.fields(cls)}
        unknown = sorted(set(data) - valid)
        if unknown:
            raise ValueError(f"unknown AmpConfig keys {unknown}; valid keys: {sorted(valid)}")
        return cls(**data)

    def to_dict(self) -> dict[str, Any]:
        d = dataclasses.asdict(self)
        return {k: list(v) if isinstance(v, tuple) else v for k, v in d.items()}


def compute_gae(
    rewards: torch.Tensor,
    values: torch.Tensor,
    next_values: torch.Tensor,
    terminated: torch.Tensor,
    dones: torch.Tensor,
    gamma: float,
    lam: float,
) -> tuple[torch.Tensor, torch.Tensor]:
    """Generalised advantage estimation over a (T, E) rollout.

    ``next_values[t]`` is ``V`` of the state reached by step ``t``: the next row's state, or, for a
    truncated episode, its final observation (for a terminated one it is ignored). ``dones`` =
    terminated or truncated cuts the recursion between episodes::

        delta_t = r_t + gamma * (1 - terminated_t) * next_values_t - values_t
        A_t     = delta_t + gamma * lam * (1 - done_t) * A_{t+1}

    Returns ``(advantages, returns = advantages + values)``.
    """
    rewards, values, next_values = (
        torch.as_tensor(x, dtype=torch.float32) for x in (rewards, values, next_values)
    )
    not_term = 1.0 - torch.as_tensor(terminated, dtype=torch.float32, device=rewards.device)
    not_done = 1.0 - torch.as_tensor(dones, dtype=torch.float32, device=rewards.device)
    adv = torch.zeros_like(rewards)
    last = torch.zeros_like(rewards[0])
    for t in reversed(range(rewards.shape[0])):
        delta = rewards[t] + gamma * not_term[t] * next_values[t] - values[t]
        last = delta + gamma * lam * not_done[t] * last
        adv[t] = last
    return adv, adv + values


@dataclass
class _Rollout:
    obs: torch.Tensor  # (T, E, obs_dim) raw
    actions: torch.Tensor  # (T, E, act_dim) unclipped samples
    task_rewards: torch.Tensor  # (T, E)
    terminated: torch.Tensor  # (T, E) float
    dones: torch.Tensor  # (T, E) float
    amp_obs: torch.Tensor  # (T, E, amp_obs_dim) raw
    finals: list[tuple[int, torch.Tensor, torch.Tensor]]  # (t, env indices, final obs rows) of truncations
    last_obs: torch.Tensor  # (E, obs_dim)


def _as_array(name: str, x: Any, shape: tuple[int, ...], dtype: Any = np.float32) -> np.ndarray:
    arr = np.asarray(x)
    if arr.shape != shape:
        raise ValueError(f"env returned {name} of shape {arr.shape}, expected {shape}")
    arr = arr.astype(dtype, copy=False)
    if arr.dtype.kind == "f" and not np.isfinite(arr).all():
        bad = np.unique(np.nonzero(~np.isfinite(arr.reshape(shape[0], -1)))[0])[:10].tolist()
        raise ValueError(f"env returned non-finite {name} for env indices {bad}")
    return arr


def _mean(xs: list[torch.Tensor]) -> float:
    return float(torch.stack(xs).float().mean()) if xs else float("nan")


class AmpLearner:
    """AMP + PPO on an :class:`AmpVecEnv`; networks on ``device``, env on CPU.

    Public state: ``actor``, ``critic``, ``disc``, ``obs_norm``, ``amp_norm``, ``value_norm``,
    ``replay``, the three optimisers, ``rng`` (numpy), ``torch_gen`` (CPU), ``iteration``,
    ``global_step`` (env steps collected and trained on).
    """

    def __init__(self, env: AmpVecEnv, config: AmpConfig | None = None, device: str | torch.device = "cpu"):
        self.env = env
        self.cfg = cfg = config if config is not None else AmpConfig()
        self.device = torch.device(device)
        for name in ("num_envs", "obs_dim", "act_dim", "amp_obs_dim"):
            v = getattr(env, name, None)
            if not isinstance(v, int | np.integer) or v <= 0:
                raise ValueError(f"env.{name} must be a positive int, got {v!r}")
        self.num_envs, self.obs_dim = int(env.num_envs), int(env.obs_dim)
        self.act_dim, self.amp_obs_dim = int(env.act_dim), int(env.amp_obs_dim)

        init_gen = torch.Generator().manual_seed(cfg.seed)
        self.actor = Actor(
            self.obs_dim,
            self.act_dim,
            cfg.actor_hidden,
            cfg.activation,
            cfg.init_log_std,
            cfg.learn_std,
            init_gen,
        ).to(self.device)
        self.critic = Critic(self.obs_dim, cfg.critic_hidden, cfg.activation, init_gen).to(self.device)
        self.disc = Discriminator(self.amp_obs_dim, cfg.disc_hidden, cfg.activation, init_gen).to(self.device)
        #: what the env's discriminator inputs mean (``env.amp_obs_version``, None if the env does not say)
        self.amp_obs_version: str | None = getattr(env, "amp_obs_version", None)
        #: iterations at which the discriminator was re-initialised (:meth:`reset_discriminator`)
        self.disc_resets: list[int] = []
        self.obs_norm = RunningMeanStd(self.obs_dim, cfg.norm_eps, cfg.obs_clip).to(self.device)
        self.amp_norm = RunningMeanStd(self.amp_obs_dim, cfg.norm_eps, cfg.obs_clip).to(self.device)
        self.value_norm = RunningMeanStd(1, cfg.norm_eps, clip=None).to(self.device)
        #: behaviour-cloning pairs (observations, actions) for ``cfg.bc_coef`` (:meth:`set_bc_data`)
        self.bc_obs: torch.Tensor | None = None
        self.bc_act: torch.Tensor | None = None
        #: the frozen actor and observation normaliser of ``cfg.anchor_coef`` (:meth:`set_anchor`), None: no anchor
        self.anchor: tuple[Actor, RunningMeanStd] | None = None
        self.actor_params = [p for p in self.actor.parameters() if p.requires_grad]
        self.actor_opt = torch.optim.Adam(self.actor_params, lr=cfg.actor_lr, eps=cfg.adam_eps)
        self.critic_opt = torch.optim.Adam(self.critic.parameters(), lr=cfg.critic_lr, eps=cfg.adam_eps)
        self.disc_opt = torch.optim.Adam(self.disc.parameters(), lr=cfg.disc_lr, eps=cfg.adam_eps)
        self.replay = ReplayBuffer(cfg.replay_size, self.amp_obs_dim, self.device, cfg.replay_keep_prob)
        self._mirror: tuple[Any, Any] | None = None
        if cfg.mirror_coef:
            from navzoo.agents.amp.symmetry import action_mirror, observation_mirror

            if self.act_dim != 28:
                raise ValueError(f"mirror_coef needs the humanoid's 28 actions, this env has {self.act_dim}")
            self._mirror = (observation_mirror(self.obs_dim), action_mirror())  # raises on another layout

        self.rng = np.random.default_rng(cfg.seed)
        self.torch_gen = torch.Generator().manual_seed(cfg.seed + 1)
        self._act_gen = torch.Generator().manual_seed(cfg.seed + 2)
        self.iteration = 0
        self.global_step = 0
        self.nonfinite_skips = 0
        self._obs: np.ndarray | None = None
        self._ep_return = np.zeros(self.num_envs, dtype=np.float64)
        self._ep_len = np.zeros(self.num_envs, dtype=np.int64)
        self._finished: list[tuple[float, int]] = []
        self._rollout: _Rollout | None = None

    def reset_discriminator(self) -> None:
        """Start a fresh discriminator: new weights (seeded by ``config.seed`` and the iteration), optimiser,
        input normaliser and an empty replay buffer. Actor, critic, their optimisers and the observation and
        value normalisers are untouched. For resuming a checkpoint whose discriminator inputs changed
        meaning (``env.amp_obs_version``)."""
        cfg = self.cfg
        gen = torch.Generator().manual_seed(cfg.seed + 7919 * (self.iteration + 1))
        self.disc = Discriminator(self.amp_obs_dim, cfg.disc_hidden, cfg.activation, gen).to(self.device)
        self.disc_opt = torch.optim.Adam(self.disc.parameters(), lr=cfg.disc_lr, eps=cfg.adam_eps)
        self.amp_norm = RunningMeanStd(self.amp_obs_dim, cfg.norm_eps, cfg.obs_clip).to(self.device)
        self.replay = ReplayBuffer(cfg.replay_size, self.amp_obs_dim, self.device, cfg.replay_keep_prob)
        self.disc_resets.append(self.iteration)

    # ------------------------------------------------------------------ acting

    def reset(self, seed: int | None = None) -> None:
        """Reset the env (all episodes restart) and the per-episode statistics."""
        obs = self.env.reset(seed=seed)
        self._obs = _as_array("obs", obs, (self.num_envs, self.obs_dim))
        self._ep_return[:] = 0.0
        self._ep_len[:] = 0

    @torch.no_grad()
    def act(self, obs: np.ndarray, deterministic: bool = True) -> np.ndarray:
        """Actions in [-1, 1] for raw observations (N, obs_dim) with the current policy."""
        o = self.obs_norm.normalize(torch.as_tensor(np.asarray(obs, np.float32), device=self.device))
        mu = self.actor(o)
        if not deterministic:  # its own generator: evaluation never shifts the training streams
            noise = torch.randn(mu.shape, generator=self._act_gen).to(self.device)
            mu = mu + self.actor.log_std.exp() * noise
        return mu.clamp(-1.0, 1.0).cpu().numpy()

    @torch.no_grad()
    def style_rewards(self, amp_obs: np.ndarray) -> np.ndarray:
        """Style reward ``-log(max(1 - sigmoid(D), 1e-4))`` of raw discriminator inputs (N, amp_obs_dim)."""
        x = self.amp_norm.normalize(torch.as_tensor(np.asarray(amp_obs, np.float32), device=self.device))
        return style_reward(self.disc(x)).cpu().numpy()

    @torch.no_grad()
    def collect(self, steps: int) -> dict[str, float]:
        """Roll the current policy out for ``steps`` steps of every env; keeps it for :meth:`update`.

        Returns episode statistics of the episodes that ended during the rollout, and ``env/NAME``: the mean
        over the rollout of every per-row ``info["log/NAME"]`` (E,) the env reports (e.g. the navzoo scene
        env's ``log/stance_split_m``).
        """
        if steps <= 0:
            raise ValueError(f"steps must be positive, got {steps}")
        if self._obs is None:
            # First call, or resumed without an env state: start fresh, seeded by the iteration.
            self.reset(seed=self.cfg.seed + 1_000_003 * self.iteration)
        assert self._obs is not None
        E, T, dev = self.num_envs, steps, self.device
        obs_buf = torch.empty((T, E, self.obs_dim), device=dev)
        act_buf = torch.empty((T, E, self.act_dim), device=dev)
        rew_buf = torch.empty((T, E), device=dev)
        term_buf = torch.empty((T, E), device=dev)
        done_buf = torch.empty((T, E), device=dev)
        amp_buf = torch.empty((T, E, self.amp_obs_dim), device=dev)
        finals: list[tuple[int, torch.Tensor, torch.Tensor]] = []
        self._finished = []
        logged: dict[str, float] = {}
        std = self.actor.log_std.exp()
        for t in range(T):
            obs = torch.as_tensor(self._obs, device=dev)
            obs_buf[t] = obs
            mu = self.actor(self.obs_norm.normalize(obs))
            action = mu + std * torch.randn((E, self.act_dim), generator=self.torch_gen).to(dev)
            act_buf[t] = action
            next_obs, reward, terminated, truncated, info = self.env.step(
                action.clamp(-1.0, 1.0).cpu().numpy()
            )
            next_obs = _as_array("obs", next_obs, (E, self.obs_dim))
            reward = _as_array("task_reward", reward, (E,), np.float64)
            terminated = _as_array("terminated", terminated, (E,), bool)
            truncated = _as_array("truncated", truncated, (E,), bool)
            if "amp_obs" not in info:
                raise ValueError("env.step must return info['amp_obs'] (E, amp_obs_dim)")
            amp = _as_array("info['amp_obs']", info["amp_obs"], (E, self.amp_obs_dim))
            for key in info:
                if key.startswith("log/"):
                    val = _as_array(f"info[{key!r}]", info[key], (E,), np.float64)
                    logged[key] = logged.get(key, 0.0) + float(val.mean()) / T
            trunc_only = truncated & ~terminated
            if trunc_only.any():
                if info.get("final_obs") is None:
                    raise ValueError("env.step truncated episodes but gave no info['final_obs']")
                idx = np.flatnonzero(trunc_only)
                final = _as_array(
                    "info['final_obs'] rows of truncated envs",
                    np.asarray(info["final_obs"])[idx],
                    (len(idx), self.obs_dim),
                )
                finals.append((t, torch.from_numpy(idx).to(dev), torch.as_tensor(final, device=dev)))
            done = terminated | truncated
            rew_buf[t] = torch.as_tensor(reward, dtype=torch.float32, device=dev)
            term_buf[t] = torch.as_tensor(terminated, dtype=torch.float32, device=dev)
            done_buf[t] = torch.as_tensor(done, dtype=torch.float32, device=dev)
            amp_buf[t] = torch.as_tensor(amp, device=dev)

            self._ep_return += reward
            self._ep_len += 1
            for i in np.flatnonzero(done):
                self._finished.append((float(self._ep_return[i]), int(self._ep_len[i])))
            self._ep_return[done] = 0.0
            self._ep_len[done] = 0
            self._obs = next_obs
        self._rollout = _Rollout(
            obs_buf,
            act_buf,
            rew_buf,
            term_buf,
            done_buf,
            amp_buf,
            finals,
            torch.as_tensor(self._obs, device=dev),
        )
        out = {"episode/count": float(len(self._finished))}
        out |= {"env/" + key[4:]: v for key, v in logged.items()}
        if self._finished:
            rets, lens = zip(*self._finished, strict=True)
            out["episode/task_return"] = float(np.mean(rets))
            out["episode/length"] = float(np.mean(lens))
        return out

    # ------------------------------------------------------------------ learning

    def _values(self, obs_n: torch.Tensor) -> torch.Tensor:
        v = self.critic(obs_n)
        if self.cfg.normalize_value:
            v = self.value_norm.denormalize(v.unsqueeze(-1)).squeeze(-1)
        return v

    def _step(self, opt: torch.optim.Optimizer, loss: torch.Tensor, params: Sequence[torch.Tensor]) -> None:
        """One optimiser step, skipped (and counted) when the loss or the gradient is not finite."""
        opt.zero_grad(set_to_none=True)
        if not torch.isfinite(loss):
            self.nonfinite_skips += 1
            return
        loss.backward()
        norm = nn.utils.clip_grad_norm_(params, self.cfg.max_grad_norm)
        if not torch.isfinite(norm):
            opt.zero_grad(set_to_none=True)
            self.nonfinite_skips += 1
            return
        opt.step()

    def set_bc_data(self, obs: np.ndarray, actions: np.ndarray) -> None:
        """Behaviour-cloning pairs for the actor's cloning term (``AmpConfig.bc_coef``): raw observations
        (M, obs_dim), normalised with the learner's observation normaliser at each update, and target actions
        (M, act_dim) in the action box. Not saved in checkpoints: pass them again when resuming."""
        obs = np.asarray(obs, dtype=np.float32)
        actions = np.asarray(actions, dtype=np.float32)
        if obs.ndim != 2 or obs.shape[1] != self.obs_dim or actions.shape != (len(obs), self.act_dim) or len(obs) < 1:
            raise ValueError(f"behaviour-cloning pairs must be (M, {self.obs_dim}) observations and (M, {self.act_dim}) "
                             f"actions, got {obs.shape} and {actions.shape}")
        if not (np.isfinite(obs).all() and np.isfinite(actions).all()):
            raise ValueError("behaviour-cloning pairs contain non-finite values")
        self.bc_obs = torch.as_tensor(obs, device=self.device)
        self.bc_act = torch.as_tensor(actions, device=self.device)

    def set_anchor(self) -> None:
        """Freeze a copy of the current actor and observation normaliser as the anchor of ``cfg.anchor_coef``
        (call it after loading the policy to stay near). Saved in checkpoints, so a resumed run keeps its anchor."""
        actor = copy.deepcopy(self.actor).requires_grad_(False)
        self.anchor = (actor, copy.deepcopy(self.obs_norm).requires_grad_(False))

    def update(self) -> dict[str, float]:
        """Train on the last rollout (see the module docstring); returns scalar statistics."""
        ro = self._rollout
        if ro is None:
            raise RuntimeError("AmpLearner.update() needs a rollout: call collect() first")
        if self.cfg.bc_coef > 0 and self.bc_obs is None:
            raise ValueError(f"AmpConfig.bc_coef is {self.cfg.bc_coef} but no behaviour-cloning pairs were given "
                             f"(AmpLearner.set_bc_data)")
        if self.cfg.anchor_coef > 0 and self.anchor is None:
            raise ValueError(f"AmpConfig.anchor_coef is {self.cfg.anchor_coef} but the learner has no anchor "
                             f"(AmpLearner.set_anchor, or a checkpoint saved with one)")
        cfg, dev = self.cfg, self.device
        T, E = ro.task_rewards.shape
        B = T * E
        obs = ro.obs.reshape(B, self.obs_dim)
        actions = ro.actions.reshape(B, self.act_dim)
        amp = ro.amp_obs.reshape(B, self.amp_obs_dim)
        ref_np = self.env.sample_reference_amp_obs(B, self.rng)
        ref = torch.as_tensor(_as_array("reference amp_obs", ref_np, (B, self.amp_obs_dim)), device=dev)

        # 1. Normalisers see this rollout before anything is computed from it (so the very first
        #    update already works on normalised inputs); they stay frozen for the rest of the update.
        self.obs_norm.update(obs)
        self.amp_norm.update(torch.cat([amp, ref]))

        with torch.no_grad():
            obs_n = self.obs_norm.normalize(obs)
            mirrored_n = self.obs_norm.normalize(self._mirror[0](obs)) if self._mirror else None
            amp_n = self.amp_norm.normalize(amp)
            ref_n = self.amp_norm.normalize(ref)
            # 2. Rewards: style from the discriminator before it sees this batch.
            r_style = style_reward(self.disc(amp_n)).reshape(T, E)
            reward = cfg.reward_scale * (cfg.style_weight * r_style + cfg.task_weight * ro.task_rewards)
            if cfg.reward_clip is not None:
                reward = reward.clamp(-cfg.reward_clip, cfg.reward_clip)
            # 3. Values (with the normalisers just updated), bootstrapping truncations from V(final_obs).
            values = self._values(obs_n).reshape(T, E)
            next_values = torch.empty_like(values)
            next_values[:-1] = values[1:]
            next_values[-1] = self._values(self.obs_norm.normalize(ro.last_obs))
            for t, idx, final in ro.finals:
                next_values[t, idx] = self._values(self.obs_norm.normalize(final))
            old_logp = self.actor.dist(obs_n).log_prob(actions).sum(-1)
            anchor_dist = self.anchor[0].dist(self.anchor[1].normalize(obs)) if self.anchor is not None else None
            adv, returns = compute_gae(
                reward, values, next_values, ro.terminated, ro.dones, cfg.gamma, cfg.gae_lambda
            )
            adv, returns = adv.reshape(B), returns.reshape(B)
            if cfg.normalize_value:
                self.value_norm.update(returns.unsqueeze(-1))
                v_target = self.value_norm.normalize(returns.unsqueeze(-1)).squeeze(-1)
            else:
                v_target = returns
            if cfg.normalize_advantages:
                adv = (adv - adv.mean()) / (adv.std(unbiased=False) + 1e-8)
            ret64 = returns.double()
            explained_var = 1.0 - float((ret64 - values.reshape(B).double()).var() / (ret64.var() + 1e-8))

        # 4. Epochs of minibatch steps: actor, critic, discriminator.
        n_mb = max(1, round(B / cfg.minibatch_size))
        dmb = cfg.disc_minibatch_size
        logs: dict[str, list[torch.Tensor]] = {}

        def log(key: str, value: torch.Tensor) -> None:
            logs.setdefault(key, []).append(value.detach())

        for _ in range(cfg.epochs):
            perm = torch.from_numpy(self.rng.permutation(B)).to(dev)
            ref_perm = torch.from_numpy(self.rng.permutation(B)).to(dev)
            for k, mb in enumerate(torch.tensor_split(perm, n_mb)):
                # PPO actor: clipped surrogate + bounds loss.
                dist = self.actor.dist(obs_n[mb])
                logp = dist.log_prob(actions[mb]).sum(-1)
                log_ratio = logp - old_logp[mb]
                ratio = log_ratio.exp()
                a = adv[mb]
                pg_loss = -torch.min(ratio * a, ratio.clamp(1 - cfg.clip_coef, 1 + cfg.clip_coef) * a).mean()
                b_loss = bounds_loss(dist.mean, cfg.bounds_soft)
                actor_loss = pg_loss + cfg.bounds_loss_coef * b_loss
                if cfg.entropy_coef:
                    actor_loss = actor_loss - cfg.entropy_coef * dist.entropy().sum(-1).mean()
                if mirrored_n is not None:  # the mirrored state's mean action, mirrored back, should agree
                    mirror_loss = (dist.mean - self._mirror[1](self.actor(mirrored_n[mb]))).square().sum(-1).mean()
                    actor_loss = actor_loss + cfg.mirror_coef * mirror_loss
                    log("losses/mirror", mirror_loss)
                if cfg.bc_coef > 0:  # stay near the cloned actions on the cloning pairs' states
                    pick = torch.from_numpy(self.rng.integers(0, len(self.bc_obs), len(mb))).to(dev)
                    with torch.no_grad():
                        bc_in = self.obs_norm.normalize(self.bc_obs[pick]).float()
                    bc_loss = (self.actor(bc_in) - self.bc_act[pick]).square().sum(-1).mean()
                    actor_loss = actor_loss + cfg.bc_coef * bc_loss
                    log("losses/bc", bc_loss)
                if anchor_dist is not None:  # stay near the anchor policy on this rollout's states
                    anchor_mb = torch.distributions.Normal(anchor_dist.mean[mb], anchor_dist.stddev[mb])
                    anchor_kl = torch.distributions.kl_divergence(anchor_mb, dist).sum(-1).mean()
                    if cfg.anchor_coef > 0:
                        actor_loss = actor_loss + cfg.anchor_coef * anchor_kl
                    log("anchor/kl", anchor_kl)
                if self.iteration >= cfg.actor_warmup_iters:
                    self._step(self.actor_opt, actor_loss, self.actor_params)
                # Critic: MSE on (normalised) returns.
                critic_loss = 0.5 * (self.critic(obs_n[mb]) - v_target[mb]).square().mean()
                self._step(self.critic_opt, critic_loss, list(self.critic.parameters()))
                # Discriminator: reference (label 1) vs policy, fresh + replay (label 0).
                pol = amp_n[mb[:dmb]]
                if len(self.replay):
                    pol = torch.cat(
                        [pol, self.amp_norm.normalize(self.replay.sample(pol.shape[0], self.rng))]
                    )
                ref_in = ref_n[ref_perm[(k * dmb + torch.arange(dmb, device=dev)) % B]].requires_grad_(True)
                logit_ref = self.disc(ref_in)
                logit_pol = self.disc(pol)
                bce = 0.5 * (
                    F.binary_cross_entropy_with_logits(logit_pol, torch.zeros_like(logit_pol))
                    + F.binary_cross_entropy_with_logits(logit_ref, torch.ones_like(logit_ref))
                )
                gp = gradient_penalty(logit_ref, ref_in)
                logit_reg = self.disc.logit_weights().square().sum()
                weight_decay = self.disc.all_weights().square().sum()
                disc_loss = (
                    bce
                    + cfg.disc_grad_penalty * gp
                    + cfg.disc_logit_reg * logit_reg
                    + cfg.disc_weight_decay * weight_decay
                )
                self._step(self.disc_opt, disc_loss, list(self.disc.parameters()))

                log("losses/actor", pg_loss)
                log("losses/bounds", b_loss)
                log("losses/critic", critic_loss)
                log("losses/disc", disc_loss)
                log("losses/disc_bce", bce)
                log("losses/disc_grad_penalty", gp)
                log("losses/disc_logit_reg", logit_reg)
                log("losses/disc_weight_decay", weight_decay)
                log("disc/acc_policy", (logit_pol < 0).float().mean())
                log("disc/acc_reference", (logit_ref > 0).float().mean())
                log("disc/logit_policy", logit_pol.mean())
                log("disc/logit_reference", logit_ref.mean())
                with torch.no_grad():
                    log("ppo/approx_kl", ((ratio - 1) - log_ratio).mean())
                    log("ppo/clip_frac", ((ratio - 1).abs() > cfg.clip_coef).float().mean())

        # 5. This rollout's policy samples join the replay buffer; the rollout is consumed.
        self.replay.push(amp, self.rng)
        self._rollout = None
        self.iteration += 1
        self.global_step += B

        stats = {k: _mean(v) for k, v in logs.items()}
        stats |= {
            "rewards/style": float(r_style.mean()),
            "rewards/task": float(ro.task_rewards.mean()),
            "rewards/total": float(reward.mean()),
            "ppo/explained_variance": explained_var,
            "ppo/action_std": float(self.actor.log_std.exp().mean()),
            "ppo/nonfinite_skips": float(self.nonfinite_skips),
            "replay/size": float(len(self.replay)),
        }
        return stats

    # ------------------------------------------------------------------ the loop

    def train(
        self,
        total_steps: int,
        log_dir: str | Path | None = None,
        ckpt_dir: str | Path | None = None,
        ckpt_every: int = 10,
        resume: bool = True,
        verbose: bool = False,
        time_limit_s: float | None = None,
        reset_disc: bool = False,
        snapshot_dir: str | Path | None = None,
        snapshot_every: int = 0,
        any_num_envs: bool = False,
    ) -> dict[str, Any]:
        """Collect and update until ``global_step >= total_steps`` (or ``time_limit_s`` of wall time).

        Resumes from the latest checkpoint in ``ckpt_dir`` (unless ``resume=False``), checkpoints every
        ``ckpt_every`` iterations and at the end, logs to TensorBoard and ``<log_dir>/metrics.jsonl``.
        Ctrl-C (SIGINT, main thread) finishes the current iteration, checkpoints and returns with
        ``interrupted=True``; a second Ctrl-C, or a ``KeyboardInterrupt`` raised inside the loop,
        checkpoints at once (unless this iteration is already saved) and re-raises. ``reset_disc``: the
        resumed checkpoint's discriminator is replaced by a fresh one (see :meth:`load_checkpoint`);
        ``any_num_envs``: the resumed checkpoint may come from another number of envs (its episodes restart).
        ``snapshot_every`` > 0 (with ``snapshot_dir``): also export the deterministic policy
        (:meth:`export_policy`) to ``<snapshot_dir>/policy_<iteration>`` every that many iterations and at
        the start, so that a run's policies can be compared on the following protocol afterwards
        (``scripts/amp_select_snapshots.py``); the checkpoints themselves rotate.
        """
        if ckpt_every <= 0:
            raise ValueError(f"ckpt_every must be positive, got {ckpt_every}")
        if snapshot_every < 0 or (snapshot_every and snapshot_dir is None):
            raise ValueError(f"snapshot_every must be >= 0 and needs a snapshot_dir, got {snapshot_every}, {snapshot_dir}")
        resumed_from = None
        if ckpt_dir is not None and resume:
            latest = ckpt.latest_checkpoint(ckpt_dir)
            if latest is not None:
                self.load_checkpoint(latest, reset_disc=reset_disc, any_num_envs=any_num_envs)
                resumed_from = str(latest)
                if verbose:
                    print(f"resumed from {latest} (iteration {self.iteration}, step {self.global_step})")
        logger = _MetricsLogger(log_dir, self.iteration, self.global_step) if log_dir is not None else None
        saved_at = self.iteration if resumed_from else None
        last_path: Path | None = Path(resumed_from) if resumed_from else None
        stop = threading.Event()
        previous_handler = None
        if threading.current_thread() is threading.main_thread():

            def on_sigint(signum: int, frame: Any) -> None:
                stop.set()
                signal.signal(signal.SIGINT, signal.default_int_handler)  # a second Ctrl-C aborts now
                print("\nInterrupt: finishing this iteration and checkpointing (Ctrl-C again to abort)")

            previous_handler = signal.signal(signal.SIGINT, on_sigint)
        t_start = time.perf_counter()
        start_it = self.iteration

        def snapshot() -> None:
            if snapshot_every and (self.iteration % snapshot_every == 0 or self.iteration == start_it):
                path = Path(snapshot_dir) / f"policy_{self.iteration:08d}"
                if not (path / "config.json").is_file():
                    self.export_policy(path)

        try:
            snapshot()
            while self.global_step < total_steps and not stop.is_set():
                if time_limit_s is not None and time.perf_counter() - t_start >= time_limit_s:
                    break
                t0 = time.perf_counter()
                stats = self.collect(self.cfg.rollout_steps)
                t1 = time.perf_counter()
                stats |= self.update()
                t2 = time.perf_counter()
                samples = self.cfg.rollout_steps * self.num_envs
                stats |= {
                    "perf/fps": samples / (t2 - t0),
                    "perf/collect_s": t1 - t0,
                    "perf/update_s": t2 - t1,
                    "perf/update_ms_per_4096": 1000.0 * (t2 - t1) * 4096 / samples,
                }
                if logger is not None:
                    logger.log(self.iteration, self.global_step, stats)
                if verbose:
                    print(
                        f"it {self.iteration:5d} step {self.global_step:9d} "
                        f"style {stats['rewards/style']:.3f} task {stats['rewards/task']:.3f} "
                        f"disc acc {stats['disc/acc_policy']:.2f}/{stats['disc/acc_reference']:.2f} "
                        f"fps {stats['perf/fps']:.0f}"
                    )
                if ckpt_dir is not None and self.iteration % ckpt_every == 0:
                    last_path = self.save_checkpoint(ckpt_dir)
                    saved_at = self.iteration
                snapshot()
            if ckpt_dir is not None and saved_at != self.iteration:
                last_path = self.save_checkpoint(ckpt_dir)
        except KeyboardInterrupt:
            self._rollout = None  # a partial rollout is dropped; the env state stays consistent with _obs
            if ckpt_dir is not None and saved_at != self.iteration:
                path = self.save_checkpoint(ckpt_dir)
                print(f"\nKeyboardInterrupt: checkpoint saved to {path}")
            raise
        finally:
            if previous_handler is not None:
                signal.signal(signal.SIGINT, previous_handler)
            if logger is not None:
                logger.close()
        return {
            "iteration": self.iteration,
            "global_step": self.global_step,
            "interrupted": stop.is_set(),
            "resumed_from": resumed_from,
            "checkpoint": None if last_path is None else str(last_path),
            "wall_s": time.perf_counter() - t_start,
        }

    # ------------------------------------------------------------------ checkpoints

    def _dims(self) -> dict[str, int]:
        return {
            "num_envs": self.num_envs,
            "obs_dim": self.obs_dim,
            "act_dim": self.act_dim,
            "amp_obs_dim": self.amp_obs_dim,
        }

    def save_checkpoint(self, ckpt_dir: str | Path) -> Path:
        """Write a checkpoint of everything needed to continue (see :mod:`.checkpoint`)."""
        env_arrays: dict[str, torch.Tensor] = {}
        env_json: dict[str, Any] | None = None
        if callable(getattr(self.env, "state_dict", None)):
            env_json = {}
            for k, v in self.env.state_dict().items():
                if isinstance(v, np.ndarray):
                    env_arrays[k] = torch.from_numpy(np.ascontiguousarray(v).copy())
                else:
                    env_json[k] = v
        learner_arrays = {
            "ep_return": torch.from_numpy(self._ep_return.copy()),
            "ep_len": torch.from_numpy(self._ep_len.copy()),
        }
        if self._obs is not None:
            learner_arrays["obs"] = torch.from_numpy(self._obs.copy())
        tensors: dict[str, Any] = {
            "actor": self.actor.state_dict(),
            "critic": self.critic.state_dict(),
            "disc": self.disc.state_dict(),
            "obs_norm": self.obs_norm.state_dict(),
            "amp_norm": self.amp_norm.state_dict(),
            "value_norm": self.value_norm.state_dict(),
            "actor_opt": self.actor_opt.state_dict(),
            "critic_opt": self.critic_opt.state_dict(),
            "disc_opt": self.disc_opt.state_dict(),
            "replay": self.replay.state_dict(self.cfg.ckpt_replay_rows, seed=self.iteration),
            "torch_rng": self.torch_gen.get_state(),
            "learner": learner_arrays,
            "env": env_arrays,
        }
        if self.anchor is not None:
            tensors["anchor"] = {"actor": self.anchor[0].state_dict(), "obs_norm": self.anchor[1].state_dict()}
        companion = getattr(self.env, "companion_state", None)
        if callable(companion):  # e.g. robots learning in the same worlds (navzoo.rl.amp_joint)
            state = companion()
            if state is not None:
                tensors["companion"] = state
        tensors = _to_cpu(tensors)
        meta = {
            "config": self.cfg.to_dict(),
            "dims": self._dims(),
            "counters": {
                "iteration": self.iteration,
                "global_step": self.global_step,
                "nonfinite_skips": self.nonfinite_skips,
            },
            "numpy_rng": self.rng.bit_generator.state,
            "env_state": env_json,
            "amp_obs_version": self.amp_obs_version,
            "disc_resets": list(self.disc_resets),
            "torch_version": torch.__version__,
            "saved_unix": time.time(),
        }
        return ckpt.save_checkpoint(ckpt_dir, self.iteration, tensors, meta, keep=self.cfg.keep_checkpoints)

    def load_checkpoint(self, path: str | Path, reset_disc: bool = False, any_num_envs: bool = False) -> None:
        """Restore a checkpoint written by :meth:`save_checkpoint` (a ``ckpt_*`` directory).

        Raises :class:`CheckpointError` naming the file if it is corrupted, foreign, or made for other
        dimensions or network sizes, or if its discriminator was trained on inputs of another meaning
        (``amp_obs_version``; checkpoints without it were made with ``"velocity=physics;ground=None"``)
        and ``reset_disc`` is false. Other hyper-parameters may differ (a warning lists them): this
        learner's config wins, including the learning rates. ``reset_disc``: load everything but the
        discriminator, its optimiser, input normaliser and replay buffer, and start those fresh
        (:meth:`reset_discriminator`). ``any_num_envs``: accept a checkpoint made with another number of
        envs (a new batch, e.g. to start from a trained controller elsewhere); the env state is not restored.
        """
        tensors, meta = ckpt.load_checkpoint(path)
        meta_path = Path(path) if Path(path).is_dir() else Path(path).parent
        meta_path = meta_path / ckpt.META_FILE
        saved_dims = dict(meta.get("dims") or {})
        mine_dims = self._dims()
        if any_num_envs:
            saved_dims.pop("num_envs", None)
            mine_dims.pop("num_envs")
        if saved_dims != mine_dims:
            raise CheckpointError(
                f"{meta_path}: made for env dims {meta.get('dims')}, this env has {self._dims()}"
                + ("; only the number of envs differs: resume with any_num_envs=True (train: --any-num-envs 1)"
                   if {**saved_dims, "num_envs": 0} == {**mine_dims, "num_envs": 0} else "")
            )
        saved_cfg = meta.get("config") or {}
        mine = self.cfg.to_dict()
        arch = [k for k in _ARCH_FIELDS if saved_cfg.get(k) != mine[k]]
        if arch:
            raise CheckpointError(
                f"{meta_path}: network config differs: "
                + ", ".join(f"{k}={saved_cfg.get(k)!r} (this learner: {mine[k]!r})" for k in arch)
            )
        saved_version = meta.get("amp_obs_version") or _LEGACY_AMP_OBS_VERSION
        if self.amp_obs_version is not None and saved_version != self.amp_obs_version and not reset_disc:
            raise CheckpointError(
                f"{meta_path}: its discriminator was trained on inputs {saved_version!r}, this env gives "
                f"{self.amp_obs_version!r}; resume with reset_disc=True (train: --reset-disc 1)"
            )
        changed = sorted(k for k in mine if k in saved_cfg and saved_cfg[k] != mine[k])
        if changed:
            warnings.warn(
                f"resuming {meta_path.parent.name} with changed hyper-parameters {changed}", stacklevel=2
            )
        try:
            self.actor.load_state_dict(tensors["actor"])
            if not self.cfg.learn_std:  # a fixed exploration std is this learner's hyper-parameter
                with torch.no_grad():
                    self.actor.log_std.fill_(float(self.cfg.init_log_std))
            self.critic.load_state_dict(tensors["critic"])
            self.obs_norm.load_state_dict(tensors["obs_norm"])
            self.value_norm.load_state_dict(tensors["value_norm"])
            self.actor_opt.load_state_dict(tensors["actor_opt"])
            self.critic_opt.load_state_dict(tensors["critic_opt"])
            if not reset_disc:
                self.disc.load_state_dict(tensors["disc"])
                self.amp_norm.load_state_dict(tensors["amp_norm"])
                self.disc_opt.load_state_dict(tensors["disc_opt"])
                self.replay.load_state_dict(tensors["replay"])
            if "anchor" in tensors:
                self.set_anchor()
                self.anchor[0].load_state_dict(tensors["anchor"]["actor"])
                self.anchor[1].load_state_dict(tensors["anchor"]["obs_norm"])
            self.torch_gen.set_state(tensors["torch_rng"])
            self.rng.bit_generator.state = meta["numpy_rng"]
            counters = meta["counters"]
            learner_arrays = tensors["learner"]
            env_arrays = tensors["env"]
        except (KeyError, RuntimeError, ValueError, TypeError) as e:
            raise CheckpointError(
                f"{meta_path.parent / ckpt.STATE_FILE}: incomplete or mismatched state ({e})"
            ) from e
        for opt, lr in (
            (self.actor_opt, self.cfg.actor_lr),
            (self.critic_opt, self.cfg.critic_lr),
            (self.disc_opt, self.cfg.disc_lr),
        ):
            for group in opt.param_groups:
                group["lr"] = lr
        self.iteration = int(counters["iteration"])
        self.global_step = int(counters["global_step"])
        self.nonfinite_skips = int(counters.get("nonfinite_skips", 0))
        self.disc_resets = [int(i) for i in meta.get("disc_resets", [])]
        if reset_disc:
            self.reset_discriminator()
        load_companion = getattr(self.env, "load_companion_state", None)
        if callable(load_companion) and not any_num_envs:
            try:
                load_companion(tensors.get("companion"))
            except ValueError as e:
                raise CheckpointError(f"{meta_path.parent / ckpt.STATE_FILE}: {e}") from e
        self._rollout = None
        env_json = meta.get("env_state")
        if (
            env_json is not None
            and not any_num_envs
            and callable(getattr(self.env, "load_state_dict", None))
            and "obs" in learner_arrays
        ):
            self.env.load_state_dict({**env_json, **{k: v.numpy() for k, v in env_arrays.items()}})
            self._obs = learner_arrays["obs"].numpy().copy()
            self._ep_return = learner_arrays["ep_return"].numpy().copy()
            self._ep_len = learner_arrays["ep_len"].numpy().copy()
        else:
            self._obs = None  # the next collect() resets the env, seeded by the iteration

    # ------------------------------------------------------------------ export

    def export_policy(self, path: str | Path) -> Path:
        """Write the deterministic policy (actor + observation normaliser) to directory ``path``.

        ``policy.pt`` holds tensors only; ``config.json`` the dims, architecture and the sha256 of
        ``policy.pt``. Load it with :func:`load_policy`.
        """
        return ckpt.export_policy_files(
            path,
            self.actor,
            self.obs_norm,
            {
                "obs_dim": self.obs_dim,
                "act_dim": self.act_dim,
                "actor_hidden": list(self.cfg.actor_hidden),
                "activation": self.cfg.activation,
                "action_low": -1.0,
                "action_high": 1.0,
                "trained_iterations": self.iteration,
                "trained_steps": self.global_step,
            },
        )


def _to_cpu(obj: Any) -> Any:
    if isinstance(obj, torch.Tensor):
        return obj.detach().cpu()
    if isinstance(obj, dict):
        return {k: _to_cpu(v) for k, v in obj.items()}
    if isinstance(obj, list | tuple):
        return type(obj)(_to_cpu(v) for v in obj)
    return obj


class _MetricsLogger:
    """TensorBoard scalars + ``metrics.jsonl`` (one JSON object per iteration, non-finite -> null).

    On resume, rows past the resumed iteration (written after the checkpoint by a run that then died)
    are dropped from the jsonl file and TensorBoard events past the resumed step are purged.
    """

    def __init__(self, log_dir: str | Path, resume_iteration: int, resume_step: int) -> None:
        self.dir = Path(log_dir)
        self.dir.mkdir(parents=True, exist_ok=True)
        self.path = self.dir / "metrics.jsonl"
        if self.path.exists():
            kept = []
            for line in self.path.read_text().splitlines():
                try:
                    if json.loads(line).get("iteration", 0) <= resume_iteration:
                        kept.append(line)
                except json.JSONDecodeError:
                    continue  # a line cut by a crash
            ckpt.atomic_write_text(self.path, "".join(f"{line}\n" for line in kept))
        self._file = open(self.path, "a")  # noqa: SIM115  (closed in close())
        self.tb = None
        try:
            from torch.utils.tensorboard import SummaryWriter
        except ImportError:  # tensorboard is optional: the jsonl file is always written
            warnings.warn("tensorboard is not installed: logging to metrics.jsonl only", stacklevel=3)
        else:
            self.tb = SummaryWriter(str(self.dir), purge_step=resume_step if resume_step > 0 else None)
        self._t0 = time.time()

    def log(self, iteration: int, step: int, stats: dict[str, float]) -> None:
        row: dict[str, Any] = {"iteration": iteration, "global_step": step, "wall_s": time.time() - self._t0}
        for k, v in stats.items():
            row[k] = float(v) if math.isfinite(v) else None
            if self.tb is not None and math.isfinite(v):
                self.tb.add_scalar(k, v, step)
        self._file.write(json.dumps(row) + "\n")
        self._file.flush()

    def close(self) -> None:
        self._file.close()
        if self.tb is not None:
            self.tb.close()
