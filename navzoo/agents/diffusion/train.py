"""Train the trajectory diffusion model: ``navzoo train diffusion`` / ``python -m navzoo.agents.diffusion.train``.

Data: the ETH/UCY prediction windows of :mod:`navzoo.forecast.data` (8 observed + 12 future steps,
16 neighbours within 10 m, agent-centric frames, each window with its scene's time step), from one
side of a split: ``--split val`` trains on the files' ``train`` part of all five scenes and validates
on their ``val`` part; ``--split loo --test-scene S`` trains on the other four scenes' whole
recordings. Training resumes from ``<out>/checkpoint`` when the same command runs again; ``--export
DIR`` writes the EMA weights as a shippable model (``model.pt`` + ``config.json``).
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np

from navzoo.agents.diffusion.model import DiffusionConfig
from navzoo.agents.diffusion.trainer import TrainConfig, export, train

__all__ = ["add_arguments", "load_data", "main", "run_cli"]


def load_data(split: str = "val", test_scene: str | None = None, data_dir: str | None = None,
              k_neighbors: int = 16) -> tuple[dict[str, np.ndarray], dict[str, np.ndarray], dict[str, Any]]:
    """(train windows, validation windows, description) of a split, agent-centric."""
    from navzoo.forecast import data as fdata

    kw = {"k_neighbors": k_neighbors}
    tr = fdata.load_split(data_dir, split, "train", test_scene, **kw)
    te = fdata.load_split(data_dir, split, "test", test_scene, **kw)
    train_w, val_w = fdata.concat(tr.values()), fdata.concat(te.values())
    desc = {"split": split, "test_scene": test_scene, "train_windows": {k: fdata.batch_size(v) for k, v in tr.items()},
            "val_windows": {k: fdata.batch_size(v) for k, v in te.items()}}
    return train_w, val_w, desc


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--out", default="runs/diffusion", help="run directory (resumed if it exists)")
    parser.add_argument("--split", default="val", choices=["val", "loo"])
    parser.add_argument("--test-scene", default=None, help="held-out scene of --split loo")
    parser.add_argument("--data", default=None, help="ETH/UCY folder (default ../shared/data/trajectories/eth_ucy)")
    parser.add_argument("--steps", type=int, default=TrainConfig.steps)
    parser.add_argument("--batch-size", type=int, default=TrainConfig.batch_size)
    parser.add_argument("--lr", type=float, default=TrainConfig.lr)
    parser.add_argument("--device", default="cpu")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--time-limit-s", type=float, default=None, help="stop (with a checkpoint) after this long")
    parser.add_argument("--ckpt-every", type=int, default=TrainConfig.ckpt_every)
    parser.add_argument("--eval-every", type=int, default=TrainConfig.eval_every)
    parser.add_argument("--base", type=int, default=16, help="U-Net width of the first level")
    parser.add_argument("--dropout", type=float, default=0.1)
    parser.add_argument("--cond-drop", type=float, default=0.2, help="probability of dropping neighbours (and map)")
    parser.add_argument("--goal", action="store_true",
                        help="condition on the end point of the horizon (the crowd's waypoint in the loop)")
    parser.add_argument("--goal-drop", type=float, default=0.5, help="probability of withholding the goal in training")
    parser.add_argument("--weight-decay", type=float, default=1e-4)
    parser.add_argument("--no-augment", action="store_true", help="train on the windows as they are")
    parser.add_argument("--export", default=None, metavar="DIR", help="write the trained model here at the end")
    parser.add_argument("--json", action="store_true", help="print the final summary as JSON")


def run_cli(args: argparse.Namespace) -> int:
    import torch

    torch.set_num_threads(max(1, torch.get_num_threads()))
    t0 = time.time()
    train_w, val_w, desc = load_data(args.split, args.test_scene, args.data)
    def log(message: str) -> None:
        print(message, file=sys.stderr, flush=True)

    log(f"{sum(desc['train_windows'].values())} training windows {desc['train_windows']}, "
        f"{sum(desc['val_windows'].values())} validation windows, loaded in {time.time() - t0:.1f} s")
    # ETH/UCY windows carry no map (docs/crowd.md); 16k windows call for a small, regularised model.
    model_cfg = DiffusionConfig(base=args.base, map_cells=0, dropout=args.dropout, cond_drop=args.cond_drop,
                                goal=args.goal, goal_drop=args.goal_drop)
    cfg = TrainConfig(steps=args.steps, batch_size=args.batch_size, lr=args.lr, device=args.device, seed=args.seed,
                      time_limit_s=args.time_limit_s, ckpt_every=args.ckpt_every, eval_every=args.eval_every,
                      weight_decay=args.weight_decay, augment=not args.no_augment)
    command = "navzoo train diffusion " + " ".join(sys.argv[3:] if sys.argv[1:3] == ["train", "diffusion"] else sys.argv[1:])
    summary = train(model_cfg, cfg, train_w, args.out, val_w, log=log, extra_meta={"data": desc})
    if args.export:
        export(Path(args.out) / "checkpoint", args.export, card={"data": desc, "command": command})
        summary["export"] = args.export
    if args.json:
        print(json.dumps(summary))
    else:
        log(f"done: step {summary['step']}, loss {summary.get('loss', float('nan')):.4f}, {summary['wall_s']:.0f} s")
    return 0


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    add_arguments(parser)
    return run_cli(parser.parse_args(argv))


if __name__ == "__main__":
    raise SystemExit(main())
