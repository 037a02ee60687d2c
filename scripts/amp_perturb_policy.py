"""Write a copy of an exported AMP policy with small random noise on its actor's weights: a control for how much the
following protocol moves when a policy changes by a given amount in no particular direction.

Usage::

    .venv/bin/python scripts/amp_perturb_policy.py --scale 0.01 --seed 1 --out /tmp/perturbed_s1 \\
        [--policy policies/amp_pedestrian]

Every weight and bias of the actor's layers gets Gaussian noise of ``scale`` times that tensor's own standard
deviation (seeded by ``--seed``); the exploration std and the observation normaliser are kept. The output is an
exported policy (config.json with the sha256 of its weights) that records its source under ``perturbed_from``;
it keeps the source's steering trim. Measure how far it acts from its source with ``scripts/amp_policy_drift.py``.
"""

from __future__ import annotations

import argparse
import math
from pathlib import Path

import torch

from navzoo.agents.amp.checkpoint import export_policy_files, load_policy
from navzoo.agents.amp.pedestrian_policy import default_policy_dir


def perturbed_policy(source: str | Path, out: str | Path, scale: float, seed: int) -> Path:
    if not (math.isfinite(scale) and scale > 0):
        raise ValueError(f"scale must be a finite number > 0, got {scale!r}")
    pol = load_policy(source)
    if not hasattr(pol, "actor"):
        raise ValueError(f"{source}: a blend of policies cannot be perturbed, only one exported policy")
    gen = torch.Generator().manual_seed(int(seed))
    state = pol.actor.state_dict()
    for name, value in state.items():
        if name == "log_std" or value.numel() < 2:
            continue
        noise = torch.randn(value.shape, generator=gen, dtype=torch.float64) * float(value.double().std()) * scale
        state[name] = (value.double() + noise).to(value.dtype)
    pol.actor.load_state_dict(state)
    config = {k: v for k, v in pol.config.items() if k not in ("weights_sha256", "format", "version", "weights_file")}
    config["perturbed_from"] = {"path": str(source), "weights_sha256": pol.config["weights_sha256"],
                                "scale": float(scale), "seed": int(seed)}
    return export_policy_files(out, pol.actor.cpu(), pol.obs_norm.cpu(), config)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--policy", default=None, help="exported policy folder (default: the shipped one)")
    ap.add_argument("--scale", type=float, required=True, help="noise std as a fraction of each tensor's std")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--out", required=True)
    args = ap.parse_args()
    try:
        path = perturbed_policy(args.policy or default_policy_dir(), args.out, args.scale, args.seed)
    except ValueError as e:
        ap.error(str(e))
    print(path)


if __name__ == "__main__":
    main()
