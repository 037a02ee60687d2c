"""Train the trajectory diffusion model: ``navzoo train diffusion`` / ``python -m navzoo.agents.diffusion.train``.

Data: the ETH/UCY prediction windows of :mod:`navzoo.forecast.data` (8 observed + 12 future steps,
16 neighbours within 10 m, agent-centric frames, each window with its scene's time step), from one
side of a split: ``--split val`` trains on the files' ``train`` part of all five scenes and validates
on their ``val`` part; ``--split loo --test-scene S`` trains on the ``train`` part of the other four
scenes and validates on their ``val`` part, so neither the weights nor their selection see scene S
(the test scene of ``navzoo eval forecast --split loo --loo-models DIR``). ``--resample-dt`` adds the
training files read at another time base (``load_data``). Training resumes from ``<out>/checkpoint``
when the same command runs again; ``--export
DIR`` writes the EMA weights as a shippable model (``model.pt`` + ``config.json``).

Map-aware training: ``--sim-data FILE.npz --map-cells 32`` adds the windows of simulated crowds in
navzoo scenes (:mod:`navzoo.forecast.sim_data`, each with the occupancy crop around the person) to
the ETH/UCY training windows; ETH/UCY windows get an all-zero map with ``has_map=False`` (the model's
"no map" embedding). ``--map-cells`` (default 0: no map input, as before) must equal the file's crop
size. The sim windows of a few whole scenes (``--sim-val-frac`` of the scenes, both crowds) are held
out and validated separately (``val_loss_sim`` in ``metrics.jsonl``); the best weights are still
chosen on the ETH/UCY validation windows. The sim data's description (file, scenes, crowds,
seconds, windows per scene) is recorded in the checkpoint's and the export's ``data.sim_data``.
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

__all__ = ["add_arguments", "load_data", "load_sim_data", "main", "run_cli"]


def load_data(split: str = "val", test_scene: str | None = None, data_dir: str | None = None,
              k_neighbors: int = 16, maps: str = "none", map_cells: int = 0,
              map_dir: str | None = None, resample_dt: tuple[float, ...] = ()
              ) -> tuple[dict[str, np.ndarray], dict[str, np.ndarray], dict[str, Any]]:
    """(train windows, validation windows, description) of a split, agent-centric.

    ``resample_dt`` (time-base augmentation): for each step ``d`` given, every training file whose
    scene has another time step is also read resampled at ``d`` (:func:`navzoo.forecast.data.resample_tracks`),
    and its windows are added under ``"<scene>@<d>s"``. The validation windows are left as recorded.
    A leave-one-scene-out fold for ``biwi_eth`` (0.667 s rows) otherwise never sees its time base.

    With ``maps="opentraj"`` (and ``map_cells``), windows of scenes with an OpenTraj obstacle map
    (:mod:`navzoo.forecast.scene_maps`, ``biwi_eth``) carry its crops (``has_map`` True); the other
    scenes' windows carry an all-zero map with ``has_map`` False.

    Raises:
        ValueError: On an unknown ``maps`` option, or ``"opentraj"`` without ``map_cells``.
    """
    from navzoo.forecast import data as fdata

    if maps not in ("none", "opentraj"):
        raise ValueError(f"unknown maps option {maps!r}; expected 'none' or 'opentraj'")
    if maps == "opentraj" and not map_cells:
        raise ValueError("real-data maps need a model with a map input (--map-cells 32)")
    kw = {"k_neighbors": k_neighbors}
    if split == "loo":
        tr, te, train_files = _loo_train_val(data_dir, test_scene, **kw)
    else:
        tr = fdata.load_split(data_dir, split, "train", test_scene, **kw)
        te = fdata.load_split(data_dir, split, "test", test_scene, **kw)
        train_files = fdata.split_files(data_dir or fdata.default_data_dir(), split, test_scene)[0]
    for d in resample_dt:
        if not (isinstance(d, (int, float)) and np.isfinite(d) and d > 0):
            raise ValueError(f"resample_dt must hold positive time steps (s), got {d!r}")
        for scene, path in train_files.items():
            if abs(fdata.scene_dt(scene) - d) > 1e-6:
                resampled = fdata.resample_tracks(fdata.read_tracks(path), float(d))
                tr[f"{scene}@{float(d):g}s"] = fdata.normalize(fdata.build_windows(resampled, **kw))
    if maps == "opentraj":
        from navzoo.forecast.scene_maps import MAP_EXTENT, attach_maps

        tr = {k: attach_maps(v, k.split("@")[0], map_dir, MAP_EXTENT, map_cells) for k, v in tr.items()}
        te = {k: attach_maps(v, k, map_dir, MAP_EXTENT, map_cells) for k, v in te.items()}
    train_w, val_w = fdata.concat(tr.values()), fdata.concat(te.values())
    desc = {"split": split, "test_scene": test_scene, "train_windows": {k: fdata.batch_size(v) for k, v in tr.items()},
            "val_windows": {k: fdata.batch_size(v) for k, v in te.items()}, "real_maps": maps,
            "real_map_windows": {k: int(np.sum(v["has_map"])) for k, v in tr.items() if "has_map" in v},
            "resample_dt": [float(d) for d in resample_dt]}
    return train_w, val_w, desc


def _loo_train_val(data_dir: str | None, test_scene: str | None, **kw: Any
                   ) -> tuple[dict[str, dict[str, np.ndarray]], dict[str, dict[str, np.ndarray]], dict[str, Path]]:
    """Training and validation windows of a leave-one-scene-out fold: the ``train/`` and ``val/`` files
    of the four other scenes. The held-out scene is used for neither, so the weights chosen by
    validation loss have not seen it (it is the test set of ``navzoo eval forecast --split loo``).
    Returns (training windows, validation windows, training files), each by scene.

    Raises:
        ValueError: On an unknown test scene, or a folder without ``train/`` and ``val/`` files of the
            other scenes.
    """
    from navzoo.forecast import data as fdata

    root = data_dir or fdata.default_data_dir()
    others, _ = fdata.split_files(root, "loo", test_scene)  # validates test_scene
    files = fdata.discover(root)
    missing = sorted(s for s in others if s not in files["train"] or s not in files["val"])
    if missing:
        raise ValueError(f"split 'loo' trains on the train/ files and validates on the val/ files of the other "
                         f"scenes; {missing} lack one of them in {root}")
    tr = {s: fdata.load_windows(files["train"][s], **kw) for s in others}
    va = {s: fdata.load_windows(files["val"][s], **kw) for s in others}
    return tr, va, {s: files["train"][s] for s in others}


# What the trainer reads of a window (the rest is dropped to save memory when sim windows are added).
_MODEL_KEYS = ("hist", "fut", "dt", "neigh", "neigh_mask", "map", "has_map", "scene")


def _sim_scene(label: str) -> str:
    return str(label).rsplit("/", 1)[-1]  # "sim/<crowd>/<scene>" -> "<scene>"


def load_sim_data(path: str, map_cells: int, val_frac: float = 0.1, seed: int = 0
                  ) -> tuple[dict[str, np.ndarray], dict[str, np.ndarray] | None, dict[str, Any]]:
    """(train windows, held-out windows or None, description) of a sim-windows file.

    The held-out part is the windows of ``round(val_frac x scenes)`` whole scenes spread over the
    sorted scene names (none with fewer than two scenes), shuffled with ``seed``. With
    ``map_cells == 0`` the maps are dropped (the model has no map input).

    Raises:
        ValueError: If the file's crop size or extent does not match ``map_cells`` and the crowd's crop.
    """
    from navzoo.agents.diffusion.crowd import MAP_EXTENT
    from navzoo.forecast import data as fdata
    from navzoo.forecast.sim_data import load_sim_dataset

    windows, info = load_sim_dataset(path)
    if map_cells:
        if int(info["map_cells"]) != map_cells:
            raise ValueError(f"{path} has {info['map_cells']}-cell map crops; train with --map-cells {info['map_cells']}")
        if abs(float(info["map_extent"]) - MAP_EXTENT) > 1e-9:
            raise ValueError(f"{path} has {info['map_extent']} m crops, the diffusion crowd uses {MAP_EXTENT} m")
    windows = {k: v for k, v in windows.items() if k in _MODEL_KEYS and (map_cells or k not in ("map", "has_map"))}
    base = np.array([_sim_scene(s) for s in windows["scene"]])
    scenes = sorted(set(base.tolist()))
    m = int(round(val_frac * len(scenes))) if len(scenes) >= 2 else 0
    m = min(m, len(scenes) - 1)
    held = [scenes[int(i)] for i in np.unique(np.round(np.linspace(0, len(scenes) - 1, m + 2)[1:-1]))] if m else []
    is_val = np.isin(base, held)
    train_w = fdata.subset(windows, ~is_val)
    val_w = None
    if is_val.any():
        val_w = fdata.subset(windows, np.random.default_rng(seed).permutation(np.flatnonzero(is_val)))

    def per_scene(w: dict[str, np.ndarray] | None) -> dict[str, int]:
        if w is None:
            return {}
        names, counts = np.unique(w["scene"], return_counts=True)
        return {str(a): int(b) for a, b in zip(names, counts, strict=True)}

    desc = {"path": str(path), "scenes": info["scenes"], "crowds": info["crowds"], "seconds": info["seconds"],
            "people": info["people"], "seed": info["seed"], "map_cells": info["map_cells"],
            "map_extent": info["map_extent"], "windows": info["windows"], "held_out_scenes": held,
            "train_windows": per_scene(train_w), "val_windows": per_scene(val_w)}
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
    parser.add_argument("--map-cells", type=int, default=0,
                        help="occupancy-crop input of the model (cells over 8 m; 0 = no map input)")
    parser.add_argument("--real-maps", default="none", choices=["none", "opentraj"],
                        help="opentraj: ETH/UCY windows of scenes with an OpenTraj obstacle map (biwi_eth) get its "
                             "crops (needs --map-cells); none: every ETH/UCY window has 'no map' (default)")
    parser.add_argument("--resample-dt", default="", metavar="DT[,DT]",
                        help="time-base augmentation: also train on every ETH/UCY training file resampled at these "
                             "steps (s) where its own step differs, e.g. 0.667 (biwi_eth's) for a leave-one-scene-out "
                             "fold of biwi_eth")
    parser.add_argument("--sim-data", default=None, metavar="NPZ",
                        help="add map-aware windows of simulated crowds (python -m navzoo.forecast.sim_data)")
    parser.add_argument("--sim-val-frac", type=float, default=0.1,
                        help="share of the sim scenes held out for a separate validation loss")
    parser.add_argument("--export", default=None, metavar="DIR", help="write the trained model here at the end")
    parser.add_argument("--json", action="store_true", help="print the final summary as JSON")


def run_cli(args: argparse.Namespace) -> int:
    import torch

    torch.set_num_threads(max(1, torch.get_num_threads()))
    t0 = time.time()
    map_cells, sim_data = getattr(args, "map_cells", 0), getattr(args, "sim_data", None)
    try:
        resample = tuple(float(x) for x in str(getattr(args, "resample_dt", "") or "").split(",") if x.strip())
    except ValueError as exc:
        raise ValueError(f"--resample-dt takes comma-separated time steps in seconds, got {args.resample_dt!r}") from exc
    train_w, val_w, desc = load_data(args.split, args.test_scene, args.data, maps=getattr(args, "real_maps", "none"),
                                     map_cells=map_cells, resample_dt=resample)
    def log(message: str) -> None:
        print(message, file=sys.stderr, flush=True)

    log(f"{sum(desc['train_windows'].values())} training windows {desc['train_windows']}, "
        f"{sum(desc['val_windows'].values())} validation windows, loaded in {time.time() - t0:.1f} s")
    extra_val = None
    if sim_data:
        from navzoo.forecast import data as fdata
        from navzoo.forecast.sim_data import with_map

        sim_train, sim_val, sim_desc = load_sim_data(sim_data, map_cells, getattr(args, "sim_val_frac", 0.1), args.seed)
        keep = lambda w: {k: v for k, v in w.items() if k in _MODEL_KEYS}  # noqa: E731
        train_w, val_w = keep(train_w), keep(val_w)
        if map_cells:  # ETH/UCY: zero map, has_map False (unless --real-maps gave a scene its map)
            train_w, val_w = with_map(train_w, map_cells), with_map(val_w, map_cells)
        train_w = fdata.concat([train_w, sim_train])
        if sim_val is not None:
            extra_val = {"sim": sim_val}
        desc["sim_data"] = sim_desc
        log(f"+ {sum(sim_desc['train_windows'].values())} sim training windows from {sim_data}"
            f" ({len(sim_desc['train_windows'])} scene/crowd runs), "
            f"{sum(sim_desc['val_windows'].values())} held out (scenes {sim_desc['held_out_scenes']})")
    elif map_cells and desc["real_maps"] == "none":
        log(f"--map-cells {map_cells} without --sim-data: no window has a map (the model learns only its 'no map' input)")
    # ETH/UCY windows carry no map (docs/crowd.md); 16k windows call for a small, regularised model.
    model_cfg = DiffusionConfig(base=args.base, map_cells=map_cells, dropout=args.dropout,
                                cond_drop=args.cond_drop, goal=args.goal, goal_drop=args.goal_drop)
    cfg = TrainConfig(steps=args.steps, batch_size=args.batch_size, lr=args.lr, device=args.device, seed=args.seed,
                      time_limit_s=args.time_limit_s, ckpt_every=args.ckpt_every, eval_every=args.eval_every,
                      weight_decay=args.weight_decay, augment=not args.no_augment)
    command = "navzoo train diffusion " + " ".join(sys.argv[3:] if sys.argv[1:3] == ["train", "diffusion"] else sys.argv[1:])
    summary = train(model_cfg, cfg, train_w, args.out, val_w, log=log, extra_meta={"data": desc}, extra_val=extra_val)
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
