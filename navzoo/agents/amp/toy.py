"""Physics-free :class:`~navzoo.agents.amp.learner.AmpVecEnv`\\ s for tests and benchmarks.

``CirclingPointMass`` — a toy where the motion prior matters
============================================================

Description:
    E independent 2-D point masses chase a slowly wandering target. The *task* alone is best solved
    by sitting on the target; the *style* (reference motion) is walking along circles of radius
    1-2.5 m at 1 m/s. An AMP policy that does both orbits the target at walking speed.

Action space: ``Box(-1, 1, (2,))`` — acceleration ``max_accel * a`` (m/s²) per axis.

Observation space: ``(6,)`` — target position relative to the mass (m), mass velocity (m/s),
    target velocity (m/s); world frame.

Discriminator input (``amp_obs``): a window of ``num_frames`` frames ending at the state just
    reached; per frame ``(p_i - p_last, v_i)`` (m, m/s), i.e. ``4 * num_frames`` numbers. Velocities
    are chord velocities ``(p_i - p_{i-1}) / dt``, as the simulation integrates them (semi-implicit
    Euler), so reference windows are exactly reachable.

Rewards: task ``exp(-(d / task_scale)^2)`` with ``d`` the distance to the target.

Starting state: mass 0.5-3 m from the target, random heading, speed 0-0.3 m/s (nearly standing); the frame history
    is extrapolated backwards at constant velocity.

Episode end: terminated when ``d > fail_distance``; truncated after ``episode_steps`` steps
    (``info["final_obs"]`` then carries the last observation). Auto-reset.

``RandomAmpVecEnv`` — random numbers with the dimensions of the humanoid (obs 125, act 28, amp 210),
for measuring the learner's update cost.

Run ``python -m navzoo.agents.amp.toy --help`` for the toy training and the benchmark.
"""

from __future__ import annotations

import argparse
import json
import time
from dataclasses import dataclass
from typing import Any

import numpy as np


@dataclass(frozen=True)
class ToyConfig:
    """Parameters of :class:`CirclingPointMass` (units: m, s)."""

    num_envs: int = 64
    dt: float = 0.1
    max_accel: float = 2.0
    max_speed: float = 2.0
    ref_speed: float = 1.0
    ref_radius: tuple[float, float] = (1.0, 2.5)
    num_frames: int = 3
    target_speed: float = 0.3
    target_turn_std: float = 0.1
    episode_steps: int = 200
    fail_distance: float = 6.0
    task_scale: float = 2.0

    def __post_init__(self) -> None:
        if self.num_envs <= 0 or self.num_frames < 2 or self.episode_steps <= 0:
            raise ValueError(
                f"num_envs and episode_steps must be positive and num_frames >= 2, got {self.num_envs}, "
                f"{self.episode_steps}, {self.num_frames}"
            )
        if not 0 < self.ref_radius[0] <= self.ref_radius[1]:
            raise ValueError(f"ref_radius must be 0 < lo <= hi, got {self.ref_radius}")
        for name in ("dt", "max_accel", "max_speed", "ref_speed", "fail_distance", "task_scale"):
            if not getattr(self, name) > 0:
                raise ValueError(f"ToyConfig.{name} must be positive, got {getattr(self, name)!r}")


class CirclingPointMass:
    """Batched point masses whose reference style is circling at walking speed (see module doc)."""

    obs_dim = 6
    act_dim = 2

    def __init__(self, config: ToyConfig | None = None) -> None:
        self.cfg = config or ToyConfig()
        self.num_envs = self.cfg.num_envs
        self.amp_obs_dim = 4 * self.cfg.num_frames
        self._rng = np.random.default_rng(0)
        E, W = self.num_envs, self.cfg.num_frames
        self.pos = np.zeros((E, 2))
        self.vel = np.zeros((E, 2))
        self.target = np.zeros((E, 2))
        self.target_vel = np.zeros((E, 2))
        self.t = np.zeros(E, dtype=np.int64)
        self.hist_p = np.zeros((E, W, 2))
        self.hist_v = np.zeros((E, W, 2))
        self._started = False

    # -- state

    def _reset_envs(self, idx: np.ndarray) -> None:
        n, rng, c = len(idx), self._rng, self.cfg
        if n == 0:
            return
        self.target[idx] = rng.uniform(-3.0, 3.0, (n, 2))
        a = rng.uniform(0, 2 * np.pi, n)
        self.target_vel[idx] = c.target_speed * np.stack([np.cos(a), np.sin(a)], 1)
        r, b = rng.uniform(0.5, 3.0, n), rng.uniform(0, 2 * np.pi, n)
        self.pos[idx] = self.target[idx] + r[:, None] * np.stack([np.cos(b), np.sin(b)], 1)
        h, s = rng.uniform(0, 2 * np.pi, n), rng.uniform(0.0, 0.3, n)
        self.vel[idx] = s[:, None] * np.stack([np.cos(h), np.sin(h)], 1)
        back = np.arange(c.num_frames - 1, -1, -1) * c.dt  # (W,) time before now of each frame
        self.hist_p[idx] = self.pos[idx, None, :] - back[None, :, None] * self.vel[idx, None, :]
        self.hist_v[idx] = self.vel[idx, None, :]
        self.t[idx] = 0

    def _obs(self) -> np.ndarray:
        return np.concatenate([self.target - self.pos, self.vel, self.target_vel], 1).astype(np.float32)

    def _amp_obs(self) -> np.ndarray:
        rel = self.hist_p - self.hist_p[:, -1:, :]
        return np.concatenate([rel, self.hist_v], 2).reshape(self.num_envs, -1).astype(np.float32)

    # -- AmpVecEnv

    def reset(self, seed: int | None = None) -> np.ndarray:
        if seed is not None:
            self._rng = np.random.default_rng(seed)
        self._reset_envs(np.arange(self.num_envs))
        self._started = True
        return self._obs()

    def step(
        self, actions: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, dict[str, Any]]:
        if not self._started:
            raise RuntimeError("CirclingPointMass.step before reset")
        a = np.asarray(actions, dtype=np.float64)
        if a.shape != (self.num_envs, 2):
            raise ValueError(f"actions must have shape ({self.num_envs}, 2), got {a.shape}")
        if not np.isfinite(a).all():
            raise ValueError(f"non-finite actions for envs {np.flatnonzero(~np.isfinite(a).all(1)).tolist()}")
        c = self.cfg
        vel = self.vel + c.dt * c.max_accel * np.clip(a, -1.0, 1.0)
        speed = np.linalg.norm(vel, axis=1, keepdims=True)
        self.vel = vel * np.minimum(1.0, c.max_speed / np.maximum(speed, 1e-12))
        self.pos = self.pos + c.dt * self.vel
        self.hist_p = np.concatenate([self.hist_p[:, 1:], self.pos[:, None]], 1)
        self.hist_v = np.concatenate([self.hist_v[:, 1:], self.vel[:, None]], 1)
        turn = self._rng.normal(0.0, c.target_turn_std, self.num_envs)
        cs, sn = np.cos(turn), np.sin(turn)
        tv = self.target_vel
        self.target_vel = np.stack([cs * tv[:, 0] - sn * tv[:, 1], sn * tv[:, 0] + cs * tv[:, 1]], 1)
        self.target = self.target + c.dt * self.target_vel
        self.t += 1

        dist = np.linalg.norm(self.target - self.pos, axis=1)
        reward = np.exp(-((dist / c.task_scale) ** 2))
        terminated = dist > c.fail_distance
        truncated = (self.t >= c.episode_steps) & ~terminated
        info: dict[str, Any] = {"amp_obs": self._amp_obs(), "reward/task": reward.copy()}
        done = terminated | truncated
        if done.any():
            info["final_obs"] = self._obs()
            self._reset_envs(np.flatnonzero(done))
        return self._obs(), reward, terminated, truncated, info

    def sample_reference_amp_obs(self, n: int, rng: np.random.Generator) -> np.ndarray:
        """Windows of circular motion: radius U(ref_radius), speed ``ref_speed``, either direction."""
        c, W = self.cfg, self.cfg.num_frames
        radius = rng.uniform(*c.ref_radius, n)
        direction = rng.choice([-1.0, 1.0], n)
        theta0 = rng.uniform(0, 2 * np.pi, n)
        # Choose the angular rate so that the *chord* speed equals ref_speed (the sim's velocity).
        omega = 2 * np.arcsin(np.clip(c.ref_speed * c.dt / (2 * radius), 0, 1)) / c.dt
        k = np.arange(W + 1)
        theta = theta0[:, None] + direction[:, None] * omega[:, None] * c.dt * k[None, :]
        p = radius[:, None, None] * np.stack([np.cos(theta), np.sin(theta)], 2)  # (n, W+1, 2)
        v = (p[:, 1:] - p[:, :-1]) / c.dt
        rel = p[:, 1:] - p[:, -1:]
        return np.concatenate([rel, v], 2).reshape(n, -1).astype(np.float32)

    def style_error(self, amp_obs: np.ndarray) -> np.ndarray:
        """Ground-truth style error of windows: mean |speed - ref_speed| over the window's frames (m/s)."""
        v = np.asarray(amp_obs).reshape(len(amp_obs), self.cfg.num_frames, 4)[:, :, 2:]
        return np.abs(np.linalg.norm(v, axis=2) - self.cfg.ref_speed).mean(1)

    # -- optional state for bit-identical resume

    def state_dict(self) -> dict[str, Any]:
        return {
            "pos": self.pos.copy(),
            "vel": self.vel.copy(),
            "target": self.target.copy(),
            "target_vel": self.target_vel.copy(),
            "t": self.t.copy(),
            "hist_p": self.hist_p.copy(),
            "hist_v": self.hist_v.copy(),
            "rng": self._rng.bit_generator.state,
            "started": self._started,
        }

    def load_state_dict(self, state: dict[str, Any]) -> None:
        for k in ("pos", "vel", "target", "target_vel", "t", "hist_p", "hist_v"):
            v = np.asarray(state[k])
            if v.shape != getattr(self, k).shape:
                raise ValueError(f"state '{k}' has shape {v.shape}, expected {getattr(self, k).shape}")
            setattr(self, k, v.copy())
        self._rng = np.random.default_rng()
        self._rng.bit_generator.state = state["rng"]
        self._started = bool(state["started"])


class RandomAmpVecEnv:
    """Random observations, rewards and reference windows with chosen dimensions (for benchmarks).

    Defaults mirror the humanoid: 105-D IsaacGymEnvs-style observation + 10 waypoints x 2 = 125,
    28 actions, a 2-frame discriminator window of 105-D features = 210. Episodes are truncated every
    ``episode_steps`` steps.
    """

    def __init__(
        self,
        num_envs: int = 256,
        obs_dim: int = 125,
        act_dim: int = 28,
        amp_obs_dim: int = 210,
        episode_steps: int = 100,
        seed: int = 0,
    ) -> None:
        self.num_envs, self.obs_dim, self.act_dim, self.amp_obs_dim = num_envs, obs_dim, act_dim, amp_obs_dim
        self.episode_steps = episode_steps
        self._rng = np.random.default_rng(seed)
        self._t = np.zeros(num_envs, dtype=np.int64)

    def reset(self, seed: int | None = None) -> np.ndarray:
        if seed is not None:
            self._rng = np.random.default_rng(seed)
        self._t[:] = 0
        return self._rng.standard_normal((self.num_envs, self.obs_dim), dtype=np.float32)

    def step(
        self, actions: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, dict[str, Any]]:
        E = self.num_envs
        self._t += 1
        truncated = self._t >= self.episode_steps
        self._t[truncated] = 0
        obs = self._rng.standard_normal((E, self.obs_dim), dtype=np.float32)
        info = {
            "amp_obs": self._rng.standard_normal((E, self.amp_obs_dim), dtype=np.float32),
            "final_obs": obs,
        }
        return obs, self._rng.random(E), np.zeros(E, bool), truncated, info

    def sample_reference_amp_obs(self, n: int, rng: np.random.Generator) -> np.ndarray:
        return rng.standard_normal((n, self.amp_obs_dim), dtype=np.float32) * 0.5 + 1.0


def toy_amp_config(**overrides: Any) -> Any:
    """An :class:`AmpConfig` that learns the toy in under a minute on 2 CPU cores."""
    from navzoo.agents.amp.learner import AmpConfig

    base: dict[str, Any] = dict(
        rollout_steps=32,
        actor_hidden=(64, 64),
        critic_hidden=(64, 64),
        disc_hidden=(64, 64),
        epochs=5,
        minibatch_size=512,
        disc_minibatch_size=256,
        actor_lr=3e-4,
        critic_lr=1e-3,
        disc_lr=1e-3,
        disc_grad_penalty=0.5,
        init_log_std=float(np.log(0.3)),
        gamma=0.95,
        replay_size=20_000,
        ckpt_replay_rows=20_000,
    )
    base.update(overrides)
    return AmpConfig(**base)


def evaluate(env: CirclingPointMass, policy: Any, steps: int, seed: int = 123) -> dict[str, Any]:
    """Run ``policy(obs) -> actions`` on ``env`` (reset with ``seed``) for ``steps`` steps.

    Returns the mean task reward per step, the mean ground-truth style error (m/s) and the collected
    discriminator inputs (``amp_obs``, for scoring with a discriminator).
    """
    obs = env.reset(seed=seed)
    rewards, amps = [], []
    for _ in range(steps):
        obs, r, _, _, info = env.step(policy(obs))
        rewards.append(r)
        amps.append(info["amp_obs"])
    amp = np.concatenate(amps)
    return {
        "task_reward": float(np.mean(rewards)),
        "style_error": float(env.style_error(amp).mean()),
        "amp_obs": amp,
    }


def _cmd_train(args: argparse.Namespace) -> None:
    from navzoo.agents.amp.learner import AmpLearner

    env = CirclingPointMass(ToyConfig(num_envs=args.num_envs))
    learner = AmpLearner(env, toy_amp_config(seed=args.seed), device=args.device)
    eval_env = CirclingPointMass(ToyConfig(num_envs=args.num_envs))
    rng = np.random.default_rng(0)
    before = evaluate(eval_env, lambda o: rng.uniform(-1, 1, (len(o), 2)), 200)
    initial = evaluate(eval_env, lambda o: learner.act(o, deterministic=False), 200)
    t0 = time.perf_counter()
    learner.train(
        args.steps,
        log_dir=args.log_dir,
        ckpt_dir=args.ckpt_dir,
        ckpt_every=args.ckpt_every,
        time_limit_s=args.seconds,
    )
    after = evaluate(eval_env, lambda o: learner.act(o, deterministic=True), 200)
    out = {
        "seconds": round(time.perf_counter() - t0, 1),
        "iterations": learner.iteration,
        "steps": learner.global_step,
    }
    for name, res in (("uniform_random", before), ("initial_policy", initial), ("trained", after)):
        out[name] = {
            "task_reward": round(res["task_reward"], 3),
            "style_error_mps": round(res["style_error"], 3),
            "style_reward_final_disc": round(float(learner.style_rewards(res["amp_obs"]).mean()), 3),
        }
    ref = env.sample_reference_amp_obs(4096, np.random.default_rng(1))
    out["reference_style_reward_final_disc"] = round(float(learner.style_rewards(ref).mean()), 3)
    print(json.dumps(out, indent=1))


def _cmd_bench(args: argparse.Namespace) -> None:
    import torch

    from navzoo.agents.amp.learner import AmpConfig, AmpLearner

    if args.threads:
        torch.set_num_threads(args.threads)
    T = 16
    env = RandomAmpVecEnv(num_envs=args.samples // T)
    hidden = tuple(args.hidden)
    cfg = AmpConfig(
        rollout_steps=T,
        actor_hidden=hidden,
        critic_hidden=hidden,
        disc_hidden=hidden,
        minibatch_size=args.minibatch,
        disc_minibatch_size=args.disc_minibatch,
    )
    learner = AmpLearner(env, cfg, device=args.device)
    times, collect_times = [], []
    for i in range(args.iters + 1):
        t0 = time.perf_counter()
        learner.collect(T)
        t1 = time.perf_counter()
        learner.update()
        if args.device.startswith("cuda"):
            torch.cuda.synchronize()
        t2 = time.perf_counter()
        if i > 0:  # the first iteration warms up allocators
            times.append(t2 - t1)
            collect_times.append(t1 - t0)
    samples = T * env.num_envs
    print(
        json.dumps(
            {
                "hidden": list(hidden),
                "device": args.device,
                "threads": torch.get_num_threads(),
                "samples_per_update": samples,
                "epochs": cfg.epochs,
                "minibatch_size": cfg.minibatch_size,
                "disc_minibatch_size": cfg.disc_minibatch_size,
                "update_ms_per_4096": round(1000 * float(np.median(times)) * 4096 / samples, 1),
                "collect_policy_ms_per_4096_without_env": round(
                    1000 * float(np.median(collect_times)) * 4096 / samples, 1
                ),
            }
        )
    )


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(
        prog="python -m navzoo.agents.amp.toy", description=__doc__.split("\n")[0]
    )
    sub = parser.add_subparsers(dest="cmd", required=True)
    tr = sub.add_parser("train", help="train AMP on the circling point mass and compare with random policies")
    tr.add_argument("--seconds", type=float, default=45.0, help="wall-clock budget of the training")
    tr.add_argument("--steps", type=int, default=10**9, help="env-step budget of the training")
    tr.add_argument("--num-envs", type=int, default=64)
    tr.add_argument("--seed", type=int, default=0)
    tr.add_argument("--device", default="cpu")
    tr.add_argument("--log-dir", default=None)
    tr.add_argument("--ckpt-dir", default=None)
    tr.add_argument("--ckpt-every", type=int, default=10)
    tr.set_defaults(func=_cmd_train)
    be = sub.add_parser("bench", help="time one learner update on random data of humanoid size")
    be.add_argument("--hidden", type=int, nargs="+", default=[512, 256])
    be.add_argument("--samples", type=int, default=4096)
    be.add_argument("--iters", type=int, default=3)
    be.add_argument("--device", default="cpu")
    be.add_argument("--threads", type=int, default=0)
    be.add_argument("--minibatch", type=int, default=2048)
    be.add_argument("--disc-minibatch", type=int, default=512)
    be.set_defaults(func=_cmd_bench)
    args = parser.parse_args(argv)
    args.func(args)


if __name__ == "__main__":
    main()
