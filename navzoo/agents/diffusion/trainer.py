"""Resumable training of :class:`TrajectoryDiffusion` on prediction windows.

Windows are a dict of numpy arrays in the agent frame (``hist (N, 8, 2)``, ``fut (N, 12, 2)``,
``dt (N,)``, optionally ``neigh (N, K, 8, 2)``, ``neigh_mask (N, K, 8)``, ``map (N, C, C)``,
``has_map (N,)``). :func:`train` draws minibatches, steps Adam, keeps an exponential moving average
(EMA) of the weights, logs to TensorBoard and ``metrics.jsonl`` and writes a checkpoint every
``ckpt_every`` steps and on Ctrl-C, time limit or the end:

``<out>/checkpoint/state.pt`` (tensors only: model, EMA, optimiser, torch/numpy RNG states; loaded
with ``weights_only=True``) and ``meta.json`` (config, step, sha256 of ``state.pt``), written to a
temporary name and renamed into place so a crash never leaves a half-written checkpoint. Running
the same command again resumes from it. :func:`export` writes the EMA weights as a shippable model
(``model.pt`` + ``config.json``), :func:`load_model` reads one back.
"""

from __future__ import annotations

import json
import os
import signal
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import torch

from navzoo.agents.amp.checkpoint import sha256_file
from navzoo.agents.diffusion.model import DiffusionConfig, TrajectoryDiffusion

__all__ = ["TrainConfig", "augment", "export", "load_model", "train", "warp_maps", "windows_to_batch"]

FORMAT = "navzoo-trajectory-diffusion"
VERSION = 1
_KEYS = ("hist", "fut", "dt", "neigh", "neigh_mask", "map", "has_map")


@dataclass(frozen=True)
class TrainConfig:
    """Optimisation settings.

    Attributes:
        steps: total optimiser steps.
        batch_size: windows per step.
        lr: Adam learning rate (TRACE: 2e-4).
        ema: EMA decay of the exported weights (TRACE: 0.995).
        ckpt_every: steps between checkpoints.
        eval_every: steps between validation losses.
        seed: seed of the minibatch sampler, the diffusion noise and the weights.
        device: torch device.
        time_limit_s: stop (after a checkpoint) after this many seconds; None = no limit.
        weight_decay: AdamW weight decay.
        augment: agent-frame augmentation of every minibatch (:func:`augment`).
    """

    steps: int = 40_000
    batch_size: int = 256
    lr: float = 2e-4
    ema: float = 0.995
    ckpt_every: int = 1000
    eval_every: int = 500
    seed: int = 0
    device: str = "cpu"
    time_limit_s: float | None = None
    weight_decay: float = 1e-4
    augment: bool = True


def augment(windows: dict[str, np.ndarray], rng: np.random.Generator, mirror: float = 0.5, max_turn_deg: float = 15.0,
            scale: tuple[float, float] = (0.85, 1.15), drop_neighbor: float = 0.2, hist_noise: float = 0.02) -> dict[str, np.ndarray]:
    """Random agent-frame augmentation of a minibatch (16k real windows are few for a diffusion model).

    Per window: a mirror image across the heading axis (left/right) with probability ``mirror``, a turn
    about the current position by up to ``max_turn_deg`` (the heading estimate of the last step is
    noisy), a common speed factor from ``scale`` (all positions scaled), each neighbour dropped with
    probability ``drop_neighbor`` and Gaussian noise of ``hist_noise`` m on the observed points (the
    current position stays the origin). Futures get the same linear map, never noise. An occupancy
    crop ``map`` (agent frame, see :func:`warp_maps`) gets the same map too, so walls stay where they
    were relative to the path (exact for the mirror image, nearest-cell resampling for turn and scale).
    """
    n = len(windows["hist"])
    ang = np.radians(rng.uniform(-max_turn_deg, max_turn_deg, n))
    c, s = np.cos(ang), np.sin(ang)
    flip = np.where(rng.random(n) < mirror, -1.0, 1.0)
    k = rng.uniform(*scale, n)
    # p' = k R(ang) diag(1, flip) p
    A = np.stack([np.stack([c, -s * flip], -1), np.stack([s, c * flip], -1)], -2) * k[:, None, None]  # (n, 2, 2)

    def apply(p: np.ndarray) -> np.ndarray:
        return np.einsum("nij,n...j->n...i", A, p)

    out = dict(windows)
    hist = apply(np.asarray(windows["hist"], dtype=np.float64))
    noise = rng.normal(0.0, hist_noise, hist.shape)
    noise[:, -1] = 0.0
    out["hist"] = hist + noise
    out["fut"] = apply(np.asarray(windows["fut"], dtype=np.float64))
    if windows.get("neigh") is not None and np.asarray(windows["neigh"]).shape[1] > 0:
        mask = np.asarray(windows["neigh_mask"]).copy()
        keep = rng.random(mask.shape[:2]) >= drop_neighbor
        mask &= keep[..., None]
        out["neigh"] = np.where(mask[..., None], apply(np.asarray(windows["neigh"], dtype=np.float64)), 0.0)
        out["neigh_mask"] = mask
    if windows.get("map") is not None:
        out["map"] = warp_maps(np.asarray(windows["map"]), A)
    return out


def warp_maps(maps: np.ndarray, A: np.ndarray) -> np.ndarray:
    """Occupancy crops ``(N, C, C)`` of the frame in which positions are ``p``, seen in the frame in
    which positions are ``A @ p`` (``A (N, 2, 2)``, invertible, e.g. a turn, mirror and scale).

    Crop convention (``OccupancyGrid.crop_many``, used by the diffusion crowd): cell ``[r, c]`` covers
    the agent-frame point ``((c + 0.5 - C/2) s, (r + 0.5 - C/2) s)`` (rows along +y, columns along +x,
    cell size ``s``). Each new cell takes the value of the old cell holding the point ``A^-1 q``
    (nearest cell; points beyond the crop take the nearest border cell). A mirror across the x axis
    is exactly a flip of the rows; the identity gives the maps back unchanged.
    """
    maps = np.asarray(maps)
    n, C = maps.shape[0], maps.shape[-1]
    if n == 0:
        return maps.copy()
    u = np.arange(C) + 0.5 - 0.5 * C  # cell centres in cell units (the cell size cancels: A is linear)
    qx, qy = np.meshgrid(u, u)  # qx varies along columns, qy along rows
    q = np.stack([qx.ravel(), qy.ravel()], axis=0)  # (2, C*C)
    src = np.einsum("nij,jm->nim", np.linalg.inv(np.asarray(A, dtype=np.float64)), q)  # (n, 2, C*C)
    col = np.clip(np.floor(src[:, 0] + 0.5 * C + 1e-9), 0, C - 1).astype(np.int64)
    row = np.clip(np.floor(src[:, 1] + 0.5 * C + 1e-9), 0, C - 1).astype(np.int64)
    return maps[np.arange(n)[:, None], row, col].reshape(maps.shape)


def windows_to_batch(windows: dict[str, np.ndarray], idx: np.ndarray | slice, device: str | torch.device = "cpu") -> dict[str, torch.Tensor]:
    """Tensors of the rows ``idx`` of ``windows`` (only the keys the model reads)."""
    out = {}
    for k in _KEYS:
        if k in windows and windows[k] is not None:
            a = np.asarray(windows[k])[idx]
            dtype = torch.bool if a.dtype == bool else torch.float32
            out[k] = torch.as_tensor(a, dtype=dtype, device=device)
    return out


def _check_windows(windows: dict[str, np.ndarray], name: str) -> int:
    for k in ("hist", "fut", "dt"):
        if k not in windows:
            raise ValueError(f"{name} windows lack {k!r} (have {sorted(windows)})")
    n = len(windows["hist"])
    if n == 0:
        raise ValueError(f"{name} windows are empty")
    for k in _KEYS:
        if k in windows and windows[k] is not None and len(windows[k]) != n:
            raise ValueError(f"{name} windows: {k!r} has {len(windows[k])} rows, 'hist' has {n}")
    for k in ("hist", "fut", "dt"):
        if not np.isfinite(np.asarray(windows[k], dtype=float)).all():
            raise ValueError(f"{name} windows: {k!r} contains NaN or inf")
    return n


def _atomic_save(obj: dict[str, Any], meta: dict[str, Any], folder: Path, weights_name: str, meta_name: str) -> None:
    folder.mkdir(parents=True, exist_ok=True)
    tmp = folder / f".{weights_name}.tmp"
    torch.save(obj, tmp)
    with open(tmp, "rb") as f:
        os.fsync(f.fileno())
    meta = dict(meta, sha256=sha256_file(tmp))
    tmp_meta = folder / f".{meta_name}.tmp"
    tmp_meta.write_text(json.dumps(meta, indent=1))
    os.replace(tmp, folder / weights_name)
    os.replace(tmp_meta, folder / meta_name)


def _load_checked(folder: Path, weights_name: str, meta_name: str) -> tuple[dict[str, Any], dict[str, Any]]:
    meta_path, w_path = folder / meta_name, folder / weights_name
    if not meta_path.is_file() or not w_path.is_file():
        raise FileNotFoundError(f"{folder} has no {weights_name} + {meta_name}")
    try:
        meta = json.loads(meta_path.read_text())
    except json.JSONDecodeError as e:
        raise ValueError(f"{meta_path} is not valid JSON: {e}") from e
    if meta.get("format") != FORMAT:
        raise ValueError(f"{meta_path}: format {meta.get('format')!r} is not {FORMAT!r}")
    if meta.get("version") != VERSION:
        raise ValueError(f"{meta_path}: version {meta.get('version')!r}, this navzoo reads version {VERSION}")
    if meta.get("sha256") != sha256_file(w_path):
        raise ValueError(f"{w_path} does not match the sha256 in {meta_path} (corrupted or replaced)")
    return torch.load(w_path, map_location="cpu", weights_only=True), meta


@torch.no_grad()
def validation_rows(total: int, n: int = 2048) -> np.ndarray:
    """At most ``n`` window indices spread evenly over all ``total`` windows (windows come grouped by
    scene, so the first ``n`` would leave the last scenes out of the validation loss)."""
    if total <= n:
        return np.arange(total)
    return np.unique(np.linspace(0, total - 1, n).round().astype(np.int64))


def _validation_loss(model: TrajectoryDiffusion, windows: dict[str, np.ndarray], device: str, n: int = 2048) -> float:
    model.eval()
    g = torch.Generator(device="cpu").manual_seed(1234)
    rows = validation_rows(len(windows["hist"]), n)
    total, count = 0.0, 0
    for i in range(0, len(rows), 512):
        b = windows_to_batch(windows, rows[i:i + 512], device)
        with torch.no_grad():
            loss, _ = model.loss(b, generator=g if device == "cpu" else None)  # fixed noise where it can be
        total += float(loss) * len(rows[i:i + 512])
        count += len(rows[i:i + 512])
    model.train()
    return total / max(count, 1)


def train(
    model_cfg: DiffusionConfig,
    cfg: TrainConfig,
    train_windows: dict[str, np.ndarray],
    out: str | Path,
    val_windows: dict[str, np.ndarray] | None = None,
    log: Callable[[str], None] = print,
    extra_meta: dict[str, Any] | None = None,
    extra_val: dict[str, dict[str, np.ndarray]] | None = None,
) -> dict[str, Any]:
    """Train (or resume) into ``out``; returns the final summary (step, losses, wall time).

    ``extra_val`` (name -> windows) are validated with ``val_windows`` and logged as
    ``val_loss_<name>``; only ``val_windows`` selects the best weights.
    """
    out = Path(out)
    n = _check_windows(train_windows, "training")
    if val_windows is not None:
        _check_windows(val_windows, "validation")
    for name, w in (extra_val or {}).items():
        _check_windows(w, f"validation {name!r}")
    ckpt = out / "checkpoint"
    torch.manual_seed(cfg.seed)
    model = TrajectoryDiffusion(model_cfg).to(cfg.device)
    ema = TrajectoryDiffusion(model_cfg).to(cfg.device)
    ema.load_state_dict(model.state_dict())
    opt = torch.optim.AdamW(model.parameters(), lr=cfg.lr, weight_decay=cfg.weight_decay)
    rng = np.random.default_rng(cfg.seed)
    step = 0
    if (ckpt / "state.pt").exists():
        state, meta = _load_checked(ckpt, "state.pt", "meta.json")
        saved = DiffusionConfig.from_dict(meta["model_config"])
        if saved != model_cfg:
            raise ValueError(f"{ckpt} was trained with {saved}, not {model_cfg}; use another --out")
        model.load_state_dict(state["model"])
        ema.load_state_dict(state["ema"])
        opt.load_state_dict(state["optim"])
        torch.set_rng_state(state["torch_rng"])
        rng.bit_generator.state = meta["numpy_rng"]
        step = int(meta["step"])
        log(f"resumed from {ckpt} at step {step}")
    tb = None
    try:
        from torch.utils.tensorboard import SummaryWriter

        tb = SummaryWriter(str(out / "tb"))
    except ImportError:  # pragma: no cover - tensorboard is a dependency, but keep training without it
        log("tensorboard not installed: logging to metrics.jsonl only")

    def save() -> None:
        state = {"model": model.state_dict(), "ema": ema.state_dict(), "optim": opt.state_dict(),
                 "torch_rng": torch.get_rng_state()}
        meta = {"format": FORMAT, "version": VERSION, "model_config": model_cfg.to_dict(),
                "train_config": {k: getattr(cfg, k) for k in cfg.__dataclass_fields__}, "step": step,
                "numpy_rng": rng.bit_generator.state, "windows": n, **(extra_meta or {})}
        _atomic_save(state, meta, ckpt, "state.pt", "meta.json")

    stop = {"now": False}

    def on_sigint(signum, frame):  # noqa: ARG001
        stop["now"] = True
        log("interrupted: checkpointing before exit")

    old = signal.signal(signal.SIGINT, on_sigint) if _main_thread() else None
    best = float("inf")
    if (ckpt / "best.json").exists():
        best = float(json.loads((ckpt / "best.json").read_text()).get("val_loss", best))
    t0 = time.time()
    metrics_file = open(out / "metrics.jsonl", "a")  # noqa: SIM115
    info: dict[str, float] = {}
    try:
        model.train()
        while step < cfg.steps and not stop["now"]:
            idx = rng.integers(0, n, cfg.batch_size)
            rows = {k: np.asarray(v)[idx] for k, v in train_windows.items() if k in _KEYS and v is not None}
            if cfg.augment:
                rows = augment(rows, rng)
            batch = windows_to_batch(rows, slice(None), cfg.device)
            loss, info = model.loss(batch)
            opt.zero_grad(set_to_none=True)
            loss.backward()
            torch.nn.utils.clip_grad_norm_(model.parameters(), 1.0)
            opt.step()
            with torch.no_grad():
                for pe, pm in zip(ema.parameters(), model.parameters(), strict=True):
                    pe.lerp_(pm, 1.0 - cfg.ema)
            step += 1
            row: dict[str, Any] = {"step": step, **info, "wall_s": round(time.time() - t0, 2)}
            if val_windows is not None and (step % cfg.eval_every == 0 or step == cfg.steps):
                row["val_loss"] = _validation_loss(ema, val_windows, cfg.device)
                for name, w in (extra_val or {}).items():
                    row[f"val_loss_{name}"] = _validation_loss(ema, w, cfg.device)
            if step % 50 == 0 or "val_loss" in row:
                metrics_file.write(json.dumps(row) + "\n")
                metrics_file.flush()
                if tb is not None:
                    for k, v in row.items():
                        if k != "step":
                            tb.add_scalar(k, v, step)
            if "val_loss" in row and row["val_loss"] < best:
                best = row["val_loss"]
                _atomic_save({k: v.detach().cpu() for k, v in ema.state_dict().items()},
                             {"format": FORMAT, "version": VERSION, "model_config": model_cfg.to_dict(), "step": step,
                              "val_loss": best}, ckpt, "best.pt", "best.json")
            if "val_loss" in row:
                extra = "".join(f", val {name} {row[f'val_loss_{name}']:.4f}" for name in (extra_val or {}))
                log(f"step {step}: loss {info['loss']:.4f}, val {row['val_loss']:.4f}{extra}, {time.time() - t0:.0f} s")
            if step % cfg.ckpt_every == 0:
                save()
            if cfg.time_limit_s is not None and time.time() - t0 > cfg.time_limit_s:
                log(f"time limit {cfg.time_limit_s:.0f} s reached at step {step}")
                break
        save()
    finally:
        metrics_file.close()
        if tb is not None:
            tb.close()
        if old is not None:
            signal.signal(signal.SIGINT, old)
    return {"step": step, **info, "wall_s": time.time() - t0, "checkpoint": str(ckpt)}


def _main_thread() -> bool:
    import threading

    return threading.current_thread() is threading.main_thread()


def export(checkpoint_dir: str | Path, out: str | Path, card: dict[str, Any] | None = None, best: bool = True) -> Path:
    """Write the EMA weights of a training checkpoint as a shippable model directory: those of the
    lowest validation loss so far when ``best`` and the run validated, else the latest."""
    folder = Path(checkpoint_dir)
    if best and (folder / "best.pt").exists():
        weights, meta = _load_checked(folder, "best.pt", "best.json")
        info = {"trained_steps": meta["step"], "val_loss": meta["val_loss"], "selected": "lowest validation loss"}
    else:
        state, meta = _load_checked(folder, "state.pt", "meta.json")
        weights = dict(state["ema"])
        info = {"trained_steps": meta["step"], "selected": "latest"}
    out = Path(out)
    _atomic_save(weights, {"format": FORMAT, "version": VERSION, "model_config": meta["model_config"], **info,
                           **(card or {})}, out, "model.pt", "config.json")
    return out


def load_model(folder: str | Path, device: str = "cpu") -> TrajectoryDiffusion:
    """The model of an exported directory (``model.pt`` + ``config.json``), in eval mode."""
    weights, meta = _load_checked(Path(folder), "model.pt", "config.json")
    model = TrajectoryDiffusion(DiffusionConfig.from_dict(meta["model_config"]))
    missing, unexpected = model.load_state_dict(weights, strict=False)
    if missing or unexpected:
        raise ValueError(f"{folder}/model.pt does not fit its config: missing {missing}, unexpected {unexpected}")
    return model.to(device).eval()
