"""Closed-loop check of a trained AMP policy on the path-following task (training-time metric).

``python -m navzoo.agents.amp.evaluate POLICY_DIR [--envs 16] [--seconds 30] [--stage 1] [--json]``
runs the deterministic policy from standing starts on generated paths and reports how long bodies
stay up and on the path: episodes, mean episode length, falls, losses of the path (> 4 m off),
episodes reaching the 10 s time limit, and the mean path error while walking. The issue's full
evaluation (clip tracking, scene following, realism) builds on this.
"""

from __future__ import annotations

import argparse
import json
from typing import Any

import numpy as np

from navzoo.agents.amp.checkpoint import load_policy
from navzoo.agents.amp.features import FEATURE_DIM, N_RAYS
from navzoo.agents.amp.path_env import AmpPathEnv, PathTaskConfig
from navzoo.agents.amp.train import locomotion_reference
from navzoo.torch_threads import one_torch_thread


def evaluate(policy_dir: str, envs: int = 16, seconds: float = 30.0, stage: int = 1, seed: int = 123,
             pd_mode: str = "motor", steering_trim: float | None = None, symmetric: bool | None = None,
             door_prob: float = 0.0, action_std: float = 0.0) -> dict[str, Any]:
    """``steering_trim`` / ``symmetric`` override the policy's own settings (None keeps them; see
    :meth:`navzoo.agents.amp.checkpoint.AmpPolicy.override`); ``door_prob`` (stage 3, a policy with
    obstacle rays): share of patches split by a wall with a door, as in training. ``action_std`` > 0 adds Gaussian
    noise of that std to every action before it is clipped, as training's exploration does (the policy's
    ``ppo/action_std`` in the training metrics), drawn from ``seed``. Runs on one torch thread
    (:func:`navzoo.torch_threads.one_torch_thread`), so the figures do not depend on the caller's thread count."""
    with one_torch_thread():
        return _evaluate(policy_dir, envs, seconds, stage, seed, pd_mode, steering_trim, symmetric, door_prob,
                         action_std)


def _evaluate(policy_dir: str, envs: int, seconds: float, stage: int, seed: int, pd_mode: str,
              steering_trim: float | None, symmetric: bool | None, door_prob: float,
              action_std: float) -> dict[str, Any]:
    if not (np.isfinite(action_std) and action_std >= 0.0):
        raise ValueError(f"action_std must be a finite number >= 0, got {action_std!r}")
    policy = load_policy(policy_dir)
    if steering_trim is not None or symmetric is not None:
        policy.override(steering_trim, symmetric)
    rays = getattr(policy, "obs_dim", 0) == FEATURE_DIM + 2 * PathTaskConfig().n_waypoints + N_RAYS
    task = PathTaskConfig(stage=stage, rsi_prob=0.0, pd_mode=pd_mode, obstacle_obs=rays,
                          boxes_per_patch=4 if rays and stage == 3 else 0, pair_patches=rays and stage == 3,
                          door_prob=door_prob if rays and stage == 3 else 0.0)
    env = AmpPathEnv(envs, locomotion_reference(), task, seed=seed)
    obs = env.reset(seed=seed)
    steps = np.zeros(envs, dtype=int)
    lengths: list[int] = []
    falls = lost = 0
    errors = []
    parts = ("track", "energy", "direction", "stance")
    reward_sums = dict.fromkeys(parts, 0.0)
    n_steps = int(round(seconds * task.control_hz))
    noise = np.random.default_rng(seed)
    for _ in range(n_steps):
        actions = policy(obs)
        if action_std > 0.0:
            actions = actions + action_std * noise.standard_normal(actions.shape)
        obs, _, term, trunc, info = env.step(actions)
        for part in parts:  # every body's step, the last one of an episode too
            reward_sums[part] += float(np.sum(info[f"reward/{part}"]))
        steps += 1
        done = term | trunc
        running = ~done
        if running.any():
            errors.append(float(info["path_error"][running].mean()))
        falls += int((term & info["fallen"]).sum())
        lost += int((term & ~info["fallen"]).sum())
        lengths += steps[done].tolist()
        steps[done] = 0
    env.close()
    full = [n for n in lengths if n >= env.episode_steps]
    return {
        "episodes_ended": len(lengths),
        "mean_episode_s": float(np.mean(lengths) / task.control_hz) if lengths else float(seconds),
        "falls": falls,
        "lost_path": lost,
        "reached_time_limit": len(full),
        "mean_path_error_m": float(np.mean(errors)) if errors else float("nan"),
        # the paper's task-reward terms per body step (r_tau, r_e, r_d) and the unweighted stance penalty, to see
        # which term a policy's task reward is short in
        "reward_per_step": {part: total / (envs * n_steps) for part, total in reward_sums.items()},
        "envs": envs,
        "seconds": seconds,
        "stage": stage,
        "door_prob": task.door_prob,
        "action_std": action_std,
    }


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("policy_dir")
    parser.add_argument("--envs", type=int, default=16)
    parser.add_argument("--seconds", type=float, default=30.0)
    parser.add_argument("--stage", type=int, default=1)
    parser.add_argument("--seed", type=int, default=123)
    parser.add_argument("--steering-trim", type=float, default=None, help="rad; overrides the policy's trim")
    parser.add_argument("--symmetric", action="store_true", help="make the policy left/right symmetric")
    parser.add_argument("--door-prob", type=float, default=0.0,
                        help="stage 3: share of patches split by a wall with a door")
    parser.add_argument("--action-std", type=float, default=0.0,
                        help="Gaussian noise added to the actions, as in training (0: the policy's mean action)")
    parser.add_argument("--json", action="store_true")
    args = parser.parse_args(argv)
    result = evaluate(args.policy_dir, args.envs, args.seconds, args.stage, args.seed,
                      steering_trim=args.steering_trim, symmetric=True if args.symmetric else None,
                      door_prob=args.door_prob, action_std=args.action_std)
    print(json.dumps(result) if args.json else result)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
