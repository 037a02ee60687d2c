"""How far exported AMP policies act from a reference policy on the states the reference policy walks into.

Usage::

    .venv/bin/python scripts/amp_policy_drift.py --policies training/amp_scenes/policy_5295,... \\
        [--reference policies/amp_pedestrian] [--scenes station:6,corridor:6,lobby:6] [--steps 300] [--json]

The reference policy drives the pedestrians of each scene (``NavAmpVecEnv``: physics pedestrians on
social-force targets, no robots, the observations scene training sees) for ``--steps`` control steps
(30 Hz); every pedestrian's observation of every step is kept. On those states each policy's mean action
(clipped to [-1, 1], as the pedestrians use it) is compared with the reference's:

- ``kl``: the mean KL(reference || policy) of the training's Gaussian policies, whose exploration std is
  fixed at exp(-2.9) = 0.055 in every action dimension: sum over dimensions of (mu_ref - mu)^2 / (2 std^2).
  It is the quantity ``AmpConfig.anchor_coef`` weighs and ``anchor/kl`` logs during training;
- ``rms_action``: the root mean square of the action difference over all dimensions (action units).

It measures how far a fine-tune moved, in the currency of the anchor term, so a weight can be chosen.
"""

from __future__ import annotations

import argparse
import json
import math

import numpy as np

from navzoo.agents.amp.checkpoint import load_policy
from navzoo.agents.amp.learner import AmpConfig
from navzoo.agents.amp.pedestrian_policy import default_policy_dir
from navzoo.benchmark.pedestrians import parse_scene_counts
from navzoo.rl.amp_joint import NavAmpVecEnv

TRAIN_STD = math.exp(AmpConfig().init_log_std)  # the training's fixed exploration std


def collect_states(reference, scenes: list[tuple[str, int]], steps: int, seed: int) -> np.ndarray:
    states = []
    for k, (scene, n) in enumerate(scenes):
        env = NavAmpVecEnv("navzoo/Lobby-v0", 1, n, 0, seed=seed + 101 * k, env_overrides={"scene": scene})
        try:
            obs = env.reset(seed=seed + 101 * k)
            for _ in range(steps):
                states.append(obs.copy())
                obs = env.step(np.clip(reference(obs), -1.0, 1.0))[0]
        finally:
            env.close()
    return np.concatenate(states)


def drift(reference, policy, states: np.ndarray, std: float = TRAIN_STD) -> dict[str, float]:
    diff = np.clip(policy(states), -1.0, 1.0) - np.clip(reference(states), -1.0, 1.0)
    return {"kl": float((diff**2).sum(-1).mean() / (2 * std**2)), "rms_action": float(np.sqrt((diff**2).mean()))}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--policies", required=True, help="comma-separated exported policy folders")
    ap.add_argument("--reference", default=None, help="the policy that walks (default: the shipped one)")
    ap.add_argument("--scenes", default="station:6,corridor:6,lobby:6", help="SCENE:N,... (N pedestrians)")
    ap.add_argument("--steps", type=int, default=300, help="control steps per scene (30 Hz)")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--json", action="store_true")
    args = ap.parse_args()
    try:
        scenes = parse_scene_counts(args.scenes)
    except ValueError as e:
        ap.error(str(e))
    if args.steps < 1:
        ap.error(f"--steps must be >= 1, got {args.steps}")
    ref_path = args.reference or str(default_policy_dir())
    reference = load_policy(ref_path)
    policies = {p: load_policy(p) for p in args.policies.split(",") if p}
    states = collect_states(reference, scenes, args.steps, args.seed)
    rows = {name: drift(reference, pol, states) for name, pol in policies.items()}
    out = {"reference": ref_path, "scenes": args.scenes, "steps": args.steps, "seed": args.seed,
           "states": len(states), "rows": rows}
    if args.json:
        print(json.dumps(out, indent=2))
        return
    print(f"# {len(states)} states walked by {ref_path} in {args.scenes}")
    for name, row in rows.items():
        print(f"{name}: KL {row['kl']:.3f}, rms action difference {row['rms_action']:.4f}")


if __name__ == "__main__":
    main()
