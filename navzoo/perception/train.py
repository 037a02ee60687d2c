"""``navzoo train perception``: generate keypoint data in navzoo scenes and train the Monoloco network.

Two resumable stages, both under ``--out``:

1. **data**: one ``data/<scene>.npz`` per training scene (:func:`navzoo.perception.dataset.generate_scene`);
   scenes already there are skipped, so an interrupted run picks up where it stopped;
2. **training**: Adam on the Monoloco loss (Laplace NLL of the relative distance error, L1 on the
   pelvis direction, squared error on the orientation's (sin, cos)), 10 % of the samples held out
   for validation; ``train_state.pt`` (tensors only: weights, optimiser, epoch, RNG) after every epoch,
   ``metrics.jsonl`` one line per epoch; the best model by validation loss is written to
   ``--out/model`` (``model.pt`` + ``config.json``), ready for ``policies/monoloco``.
"""

from __future__ import annotations

import argparse
import json
import math
import signal
import time
from pathlib import Path
from typing import Any

import numpy as np
import torch

from navzoo.perception.dataset import TRAIN_SCENES, generate_scene, load_dataset, save_dataset
from navzoo.perception.monoloco import MonolocoConfig, MonolocoNet, laplace_loss, save_model, wrap_angle

__all__ = ["add_arguments", "build_data", "evaluate_arrays", "main", "run_cli", "train"]


def build_data(out: Path, scenes: tuple[str, ...], steps: int, seed: int, workers: int) -> dict[str, np.ndarray]:
    """Generate (or reuse) the per-scene files and return them concatenated."""
    data_dir = out / "data"
    data_dir.mkdir(parents=True, exist_ok=True)
    todo = [(s, steps, seed + 17 * k) for k, s in enumerate(scenes) if not (data_dir / f"{s}.npz").is_file()]
    if todo:
        from navzoo.benchmark.pedestrians import _pool_map

        t0 = time.perf_counter()
        # One scene per job; each finished scene is saved before the next batch starts.
        for i in range(0, len(todo), max(1, workers)):
            batch = todo[i:i + max(1, workers)]
            parts = _pool_map(generate_scene, batch, workers)
            for (s, *_), part in zip(batch, parts, strict=True):
                save_dataset(part, data_dir / f"{s}.npz")
                print(json.dumps({"scene": s, "samples": int(len(part["distance"])),
                                  "elapsed_s": round(time.perf_counter() - t0, 1)}), flush=True)
    parts = [load_dataset(data_dir / f"{s}.npz") for s in scenes]
    return {k: np.concatenate([p[k] for p in parts]) for k in parts[0]}


def _targets(data: dict[str, np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
    x = data["features"].astype(np.float32)
    y = np.stack([data["distance"], data["xi"], data["eta"], np.sin(data["allocentric"]),
                  np.cos(data["allocentric"])], axis=1).astype(np.float32)
    return x, y


def _loss(out: torch.Tensor, y: torch.Tensor) -> tuple[torch.Tensor, dict[str, float]]:
    d = laplace_loss(out[:, 0], out[:, 1], y[:, 0])
    direction = torch.abs(out[:, 2:4] - y[:, 1:3]).sum(dim=1).mean() * 10.0
    ori = ((out[:, 4:6] - y[:, 3:5]) ** 2).sum(dim=1).mean()
    return d + direction + ori, {"distance": d.item(), "direction": direction.item(), "orientation": ori.item()}


@torch.no_grad()
def evaluate_arrays(net: MonolocoNet, x: np.ndarray, y: np.ndarray) -> dict[str, float]:
    """Errors of ``net`` on features ``x`` and targets ``y`` (columns: d, xi, eta, sin, cos)."""
    net.eval()
    out = net(torch.from_numpy(x)).numpy().astype(np.float64)
    d = y[:, 0].astype(np.float64)
    ray_t = np.stack([y[:, 1], y[:, 2], np.ones(len(y))], axis=1)
    ray_p = np.stack([out[:, 2], out[:, 3], np.ones(len(y))], axis=1)
    p_true = d[:, None] * ray_t / np.linalg.norm(ray_t, axis=1, keepdims=True)
    p_est = out[:, :1] * ray_p / np.linalg.norm(ray_p, axis=1, keepdims=True)
    # Ground-plane error: camera x (right) and z (forward).
    err = np.linalg.norm((p_est - p_true)[:, [0, 2]], axis=1)
    ori = np.abs(wrap_angle(np.arctan2(out[:, 4], out[:, 5]) - np.arctan2(y[:, 3], y[:, 4])))
    b = np.exp(out[:, 1])
    return {"localization_error_m": float(err.mean()), "relative_error": float(np.mean(err / d)),
            "distance_error_m": float(np.abs(out[:, 0] - d).mean()), "orientation_error_rad": float(ori.mean()),
            "laplace_b": float(np.median(b)),
            "within_1std": float(np.mean(np.abs(out[:, 0] - d) <= math.sqrt(2) * b * out[:, 0]))}


def train(out: Path, data: dict[str, np.ndarray], epochs: int, batch_size: int, lr: float, seed: int,
          config: MonolocoConfig, threads: int | None = None) -> dict[str, Any]:
    """Train (resuming ``out/train_state.pt``) and write the best model to ``out/model``."""
    if threads:
        torch.set_num_threads(threads)
    x, y = _targets(data)
    n = len(x)
    if n < 100:
        raise ValueError(f"only {n} samples: generate more data (--steps)")
    split = np.random.default_rng(seed).permutation(n)
    n_val = max(1, n // 10)
    val, tr = split[:n_val], split[n_val:]
    net = MonolocoNet(config)
    opt = torch.optim.Adam(net.parameters(), lr=lr, weight_decay=1e-5)
    sched = torch.optim.lr_scheduler.CosineAnnealingLR(opt, T_max=epochs)
    state_path = out / "train_state.pt"
    start, best = 0, math.inf
    gen = torch.Generator().manual_seed(seed)
    if state_path.is_file():
        st = torch.load(state_path, map_location="cpu", weights_only=True)
        net.load_state_dict(st["net"])
        opt.load_state_dict(st["opt"])
        sched.load_state_dict(st["sched"])
        gen.set_state(st["gen"])
        start, best = int(st["epoch"]), float(st["best"])
        print(json.dumps({"resumed_at_epoch": start}), flush=True)
    xt, yt = torch.from_numpy(x[tr]), torch.from_numpy(y[tr])
    stop = {"flag": False}

    def _sigint(signum, frame):  # finish the epoch, save, then stop
        stop["flag"] = True

    old = signal.signal(signal.SIGINT, _sigint)
    log = open(out / "metrics.jsonl", "a")
    try:
        for epoch in range(start, epochs):
            t0 = time.perf_counter()
            net.train()
            perm = torch.randperm(len(xt), generator=gen)
            total = 0.0
            for i in range(0, len(xt), batch_size):
                b = perm[i:i + batch_size]
                loss, _ = _loss(net(xt[b]), yt[b])
                opt.zero_grad()
                loss.backward()
                torch.nn.utils.clip_grad_norm_(net.parameters(), 5.0)
                opt.step()
                total += loss.item() * len(b)
            sched.step()
            net.eval()
            with torch.no_grad():
                vloss, parts = _loss(net(torch.from_numpy(x[val])), torch.from_numpy(y[val]))
            metrics = evaluate_arrays(net, x[val], y[val])
            row = {"epoch": epoch + 1, "train_loss": total / len(xt), "val_loss": float(vloss), **parts, **metrics,
                   "epoch_s": round(time.perf_counter() - t0, 2)}
            log.write(json.dumps(row) + "\n")
            log.flush()
            print(json.dumps(row), flush=True)
            if float(vloss) < best:
                best = float(vloss)
                save_model(net, out / "model", {"epoch": epoch + 1, "val": metrics, "samples_train": int(len(tr)),
                                                "samples_val": int(n_val)})
            tmp = out / "train_state.pt.tmp"
            torch.save({"net": net.state_dict(), "opt": opt.state_dict(), "sched": sched.state_dict(),
                        "gen": gen.get_state(), "epoch": torch.tensor(epoch + 1), "best": torch.tensor(best)}, tmp)
            tmp.replace(state_path)
            if stop["flag"]:
                print(json.dumps({"interrupted_after_epoch": epoch + 1}), flush=True)
                break
    finally:
        log.close()
        signal.signal(signal.SIGINT, old)
    return json.loads((out / "model" / "config.json").read_text())


def add_arguments(ap: argparse.ArgumentParser) -> argparse.ArgumentParser:
    """The options of ``navzoo train perception``."""
    ap.add_argument("--out", default="runs/perception", help="output folder (data, checkpoints, model)")
    ap.add_argument("--scenes", default=",".join(TRAIN_SCENES), help="comma-separated training scenes")
    ap.add_argument("--steps", type=int, default=1500, help="env steps per scene for the data")
    ap.add_argument("--workers", type=int, default=1, help="data generation processes")
    ap.add_argument("--epochs", type=int, default=40)
    ap.add_argument("--batch-size", type=int, default=512)
    ap.add_argument("--lr", type=float, default=1e-3)
    ap.add_argument("--hidden", type=int, default=256)
    ap.add_argument("--blocks", type=int, default=3)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--threads", type=int, default=1,
                    help="torch threads (default 1: the network is small, more threads only add synchronisation)")
    return ap


def run_cli(args: argparse.Namespace, error=None) -> int:
    """Run ``navzoo train perception`` from parsed options."""
    def fail(msg: str) -> int:
        if error is not None:
            error(msg)
        raise SystemExit(f"navzoo train perception: error: {msg}")

    scenes = tuple(s.strip() for s in args.scenes.split(",") if s.strip())
    from navzoo.world.library import list_scenes

    unknown = [s for s in scenes if s not in list_scenes()]
    if unknown or not scenes:
        return fail(f"unknown scene(s) {unknown}; available: {', '.join(list_scenes())}")
    for name in ("steps", "workers", "epochs", "batch_size", "hidden"):
        if getattr(args, name) < 1:
            return fail(f"--{name.replace('_', '-')} must be >= 1")
    if not (args.lr > 0 and math.isfinite(args.lr)):
        return fail("--lr must be > 0")
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    torch.manual_seed(args.seed)
    data = build_data(out, scenes, args.steps, args.seed, args.workers)
    print(json.dumps({"samples": int(len(data["distance"])), "scenes": list(scenes)}), flush=True)
    cfg = MonolocoConfig(hidden=args.hidden, blocks=args.blocks)
    meta = train(out, data, args.epochs, args.batch_size, args.lr, args.seed, cfg, args.threads)
    print(json.dumps({"model": str(out / "model"), "val": meta.get("val")}), flush=True)
    return 0


def main(argv: list[str] | None = None) -> int:
    ap = add_arguments(argparse.ArgumentParser(prog="navzoo train perception", description=__doc__.split("\n\n")[0]))
    args = ap.parse_args(argv)
    return run_cli(args, ap.error)


if __name__ == "__main__":
    raise SystemExit(main())
