"""Does a forecaster keep its futures off obstacles? Forecasts on map-aware windows of simulated crowds.

Of the ETH/UCY recordings only ``biwi_eth`` has an obstacle map in its frame (:mod:`navzoo.forecast.scene_maps`,
``navzoo eval forecast --maps opentraj``), so the map input of the trajectory diffusion model is judged on
the simulated-crowd windows of :mod:`navzoo.forecast.sim_data`. This module records fresh crowds (social
force and ORCA, a seed not used for training) in scenes the model did not train on, and scores each
forecaster on the same windows:

* ``min_ade_m`` / ``min_fde_m``: best of ``samples`` futures, averaged over windows (m);
* ``obstacle_rate``: the share of all predicted future points (every sample, every step) that fall on
  an occupied cell of the window's occupancy crop (points beyond the crop are not counted);
* ``windows_in_obstacle``: the share of windows with at least one sample touching an occupied cell.

The ground truth's own ``obstacle_rate`` is the floor: the crop has 0.25 m cells, so a person walking
close to a wall can sit in a cell that the wall touches.

Rows: each diffusion model directory given, with its map (``<name>``) and, for a map-aware model,
with the map withheld (``<name>, map withheld``: ``has_map`` False, the model's "no map" embedding),
plus constant velocity. Command::

    python -m navzoo.forecast.map_eval --models map=runs/diffusion_map/export,shipped \\
        --scenes convenience_store,museum_hall,studio_flat,station,home,grocery --seconds 60 --json
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from navzoo.forecast import data as fdata
from navzoo.forecast import metrics as fm
from navzoo.forecast import sim_data as sd

__all__ = ["obstacle_hits", "score_on_map", "evaluate_map_use", "main", "DEFAULT_SCENES"]

#: Scenes the shipped map-aware model did not train on: its held-out sim scenes and the walled
#: evaluation scenes of the pedestrian evaluation.
DEFAULT_SCENES = ("convenience_store", "museum_hall", "studio_flat", "station", "home", "grocery", "corridor",
                  "doorway", "lobby")


def obstacle_hits(points: np.ndarray, occ: np.ndarray, extent: float = sd.MAP_EXTENT) -> tuple[np.ndarray, np.ndarray]:
    """Which agent-frame points lie on occupied cells of their window's crop.

    Args:
        points: ``(N, ..., 2)`` positions in each window's agent frame (m).
        occ: ``(N, C, C)`` crops; cell ``[r, c]`` covers ``x = (c + 0.5 - C/2) * extent / C``,
            ``y = (r + 0.5 - C/2) * extent / C`` (:mod:`navzoo.forecast.sim_data`); > 0.5 is occupied.
        extent: Side of the crop (m).

    Returns:
        ``(hit, inside)``: bool arrays of ``points.shape[:-1]``; ``inside`` marks points within the crop.
    """
    pts = np.asarray(points, dtype=np.float64)
    occ = np.asarray(occ)
    n, c = occ.shape[0], occ.shape[-1]
    if pts.shape[0] != n or pts.shape[-1] != 2:
        raise ValueError(f"points of shape {pts.shape} do not match {n} crops")
    col = np.floor(pts[..., 0] * c / extent + c / 2).astype(np.int64)
    row = np.floor(pts[..., 1] * c / extent + c / 2).astype(np.int64)
    inside = (col >= 0) & (col < c) & (row >= 0) & (row < c)
    idx = np.broadcast_to(np.arange(n).reshape((n,) + (1,) * (pts.ndim - 2)), inside.shape)
    hit = np.zeros(inside.shape, dtype=bool)
    hit[inside] = occ[idx[inside], row[inside], col[inside]] > 0.5
    return hit, inside


def score_on_map(pred: np.ndarray, batch: Mapping[str, Any]) -> dict[str, float]:
    """minADE / minFDE and obstacle shares of ``pred (N, S, H, 2)`` (agent frame) on a map-aware batch."""
    fut = np.asarray(batch["fut"], dtype=np.float64)
    hit, inside = obstacle_hits(pred, batch["map"])
    return {
        "min_ade_m": float(np.mean(fm.min_ade(pred, fut))),
        "min_fde_m": float(np.mean(fm.min_fde(pred, fut))),
        "obstacle_rate": float(hit.sum() / max(int(inside.sum()), 1)),
        "windows_in_obstacle": float(np.mean(hit.reshape(hit.shape[0], -1).any(axis=1))),
    }


def _windows(scenes: Sequence[str], crowds: Sequence[str], seconds: float, seed: int, map_cells: int,
             stride: int, log) -> dict[str, Any]:
    parts = []
    for crowd in crowds:
        w = sd.simulate_windows(list(scenes), crowd, seconds=seconds, seed=seed, map_cells=map_cells,
                                stride=stride, log=log)
        if fdata.batch_size(w):
            parts.append(w)
    if not parts:
        raise ValueError(f"no windows from scenes {list(scenes)} in {seconds} s")
    return fdata.concat(parts)


def evaluate_map_use(
    models: Mapping[str, str | None],
    scenes: Sequence[str] = DEFAULT_SCENES,
    crowds: Sequence[str] = ("sfm", "orca"),
    seconds: float = 60.0,
    seed: int = 1,
    samples: int = 20,
    stride: int = 2,
    log=None,
) -> dict[str, Any]:
    """Score constant velocity and each diffusion model (name -> exported directory, None = shipped).

    Returns ``{"windows", "scenes", "crowds", "seconds", "seed", "samples", "ground_truth": {...},
    "results": {row: {...}}, "wall_s", "machine"}``.
    """
    from navzoo.agents.diffusion.forecaster import DiffusionForecaster
    from navzoo.benchmark.crowd_eval import _machine as crowd_machine
    from navzoo.forecast.baselines import ConstantVelocity

    t0 = time.time()
    batch = _windows(scenes, crowds, seconds, seed, 32, stride, log)
    n = fdata.batch_size(batch)
    truth = score_on_map(np.asarray(batch["fut"])[:, None], batch)
    results: dict[str, dict[str, float]] = {}
    cv = ConstantVelocity().predict(batch, 1)
    results["constant velocity"] = score_on_map(cv, batch)
    for name, folder in models.items():
        fc = DiffusionForecaster(folder, seed=seed)
        rows = [(name, batch)]
        if fc.model.cfg.map_cells:
            if fc.model.cfg.map_cells != 32:
                raise ValueError(f"model {name!r} takes {fc.model.cfg.map_cells}-cell maps; the windows have 32")
            rows.append((f"{name}, map withheld", {**batch, "has_map": np.zeros(n, dtype=bool)}))
        for row, b in rows:
            t = time.time()
            results[row] = score_on_map(fc.predict(b, samples), batch)
            results[row]["map_input"] = bool(fc.model.cfg.map_cells and np.any(b["has_map"]))
            if log is not None:
                log(f"{row}: {results[row]} ({time.time() - t:.1f} s)")
    return {
        "windows": n, "scenes": list(scenes), "crowds": list(crowds), "seconds": float(seconds), "seed": int(seed),
        "samples": int(samples), "stride": int(stride),
        "ground_truth": {k: truth[k] for k in ("obstacle_rate", "windows_in_obstacle")},
        "results": results, "wall_s": round(time.time() - t0, 1),
        "machine": crowd_machine(),
    }


def format_table(result: Mapping[str, Any]) -> str:
    lines = ["| forecaster | minADE (m) | minFDE (m) | points on obstacles | windows touching obstacles |",
             "|---|---|---|---|---|"]
    for row, r in result["results"].items():
        lines.append(f"| {row} | {r['min_ade_m']:.3f} | {r['min_fde_m']:.3f} | {100 * r['obstacle_rate']:.2f} % "
                     f"| {100 * r['windows_in_obstacle']:.1f} % |")
    gt = result["ground_truth"]
    lines.append(f"| *ground truth* | | | *{100 * gt['obstacle_rate']:.2f} %* | *{100 * gt['windows_in_obstacle']:.1f} %* |")
    return "\n".join(lines)


def _parse_models(text: str) -> dict[str, str | None]:
    out: dict[str, str | None] = {}
    for item in [t for t in text.split(",") if t]:
        name, _, folder = item.partition("=")
        if not name:
            raise ValueError(f"bad --models item {item!r}: expected NAME=DIR or 'shipped'")
        if not folder and name != "shipped":
            raise ValueError(f"bad --models item {item!r}: expected NAME=DIR or 'shipped'")
        out[name] = folder or None
    return out


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--models", default="shipped",
                        help="comma-separated NAME=DIR of exported diffusion models; 'shipped' = policies/trajectory_diffusion")
    parser.add_argument("--scenes", default=",".join(DEFAULT_SCENES))
    parser.add_argument("--crowds", default="sfm,orca")
    parser.add_argument("--seconds", type=float, default=60.0)
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument("--samples", type=int, default=20)
    parser.add_argument("--stride", type=int, default=2, help="window start every STRIDE steps of 0.4 s")
    parser.add_argument("--out", default=None, help="also write the JSON result here")
    parser.add_argument("--json", action="store_true")
    args = parser.parse_args(argv)
    try:
        models = _parse_models(args.models)
    except ValueError as e:
        parser.error(str(e))
    result = evaluate_map_use(models, [s for s in args.scenes.split(",") if s], [c for c in args.crowds.split(",") if c],
                              args.seconds, args.seed, args.samples, args.stride,
                              log=lambda s: print(s, file=sys.stderr, flush=True))
    if args.out:
        with open(args.out, "w") as f:
            json.dump(result, f, indent=1)
    print(json.dumps(result, indent=1) if args.json else format_table(result))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
