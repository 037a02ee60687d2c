"""Steering trim of an exported AMP pedestrian policy: measure and cancel a constant steering bias.

A trained policy can drift to one side of every target path. Checkpoint 4260 walks about 0.12 rad to
the right of the direction its targets lead (station, 3 people: the target point sits on average
0.18 m to the body's left). In the env the targets are rolled out again from the body every 2 s, so
the policy starts each plan on its path and has slid up to 0.3 m off it by the next one, even in an
empty hall. The *steering trim* turns the target points the policy observes by a fixed angle to the
left about the body (:class:`~navzoo.agents.amp.checkpoint.AmpPolicy`, config entry
``steering_trim``), so that the biased policy lands on the path.

Calibration runs the deployment pipeline itself (``human_model="amp"`` pedestrians on social-force
targets, :func:`navzoo.benchmark.pedestrians.follow_scene`) in a scene that is *not* one of the
evaluation's eight (default ``campus_plaza``, 6 people, 120 s): every trim of a grid runs the same
seeded episode, and the one with the least mean path error is kept, refined by a parabola through it
and its neighbours.

    navzoo train amp-trim [--policy DIR] [--trims 0:0.25:0.025] [--workers N] [--write]

prints the error of every trim and, with ``--write``, records the chosen trim and its calibration in
the policy's ``config.json`` (the weights and their sha256 do not change).
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np

from navzoo.agents.amp.checkpoint import (
    MAX_STEERING_TRIM,
    POLICY_CONFIG,
    TRIM_OFF_KEY,
    atomic_write_text,
    load_policy,
)


def parse_trims(text: str) -> list[float]:
    """``"LO:HI:STEP"`` (inclusive) or ``"A,B,C"`` -> sorted trims (rad), each within ±MAX_STEERING_TRIM."""
    try:
        if ":" in text:
            lo, hi, step = (float(v) for v in text.split(":"))
            if not step > 0 or hi < lo:
                raise ValueError
            trims = [float(v) + 0.0 for v in np.round(np.arange(lo, hi + step / 2, step), 6)]  # no -0.0
        else:
            trims = [float(v) for v in text.split(",") if v.strip()]
    except ValueError:
        raise ValueError(f"trims must be LO:HI:STEP with STEP > 0 and HI >= LO, or a comma-separated list; "
                         f"got {text!r}") from None
    if not trims or not all(np.isfinite(t) and abs(t) <= MAX_STEERING_TRIM for t in trims):
        raise ValueError(f"trims must be finite and within ±{MAX_STEERING_TRIM} rad, got {text!r}")
    return sorted(set(trims))


def refine_minimum(trims: list[float], errors: list[float], span: int = 2) -> float:
    """The trim of least error, refined: the vertex of the least-squares parabola through the grid
    points within ``span`` steps of the minimum (five points: the errors of single episodes are noisy),
    when the parabola opens upwards and its vertex lies among those points; else the grid minimum."""
    i = int(np.argmin(errors))
    lo, hi = max(0, i - span), min(len(trims), i + span + 1)
    if hi - lo >= 3:
        x, y = np.asarray(trims[lo:hi], dtype=float), np.asarray(errors[lo:hi], dtype=float)
        a, b, _ = np.polyfit(x, y, 2)
        if a > 0 and x[0] <= -b / (2 * a) <= x[-1]:
            return float(-b / (2 * a))
    return float(trims[i])


#: The calibration scene: open, with obstacles, and not one of the following evaluation's scenes.
CALIBRATION_SCENE = "campus_plaza"


def _trim_run(policy_dir: str, trim: float, scene: str, people: int, seconds: float, seed: int) -> dict[str, Any]:
    from navzoo.benchmark.pedestrians import follow_scene

    row = follow_scene(scene, people, seconds, seed, policy_dir=policy_dir, pose_every=0, steering_trim=trim)
    return {"trim": trim, "path_error_m": round(row["err_sum"] / max(1, row["err_n"]), 5),
            **{k: row[k] for k in ("success", "off_path", "fall", "timeout")}}


def calibrate(policy_dir: str | Path, trims: list[float], scene: str = CALIBRATION_SCENE, people: int = 6,
              seconds: float = 120.0, seed: int = 0, workers: int = 1, log=print) -> dict[str, Any]:
    """Mean path error of the policy's pedestrians with every trim in the same seeded episode of
    ``scene``; returns the chosen trim (``rad``), the grid (``trims``, ``path_error_m`` and the trip
    outcomes) and the settings."""
    from navzoo.benchmark.pedestrians import SCENES, _pool_map

    if scene in SCENES:
        raise ValueError(f"calibrate in a scene outside the evaluation's {list(SCENES)}, not {scene!r}")
    load_policy(policy_dir)  # check it before starting workers
    t0 = time.time()
    rows = _pool_map(_trim_run, [(str(policy_dir), t, scene, people, seconds, seed) for t in trims], workers)
    for r in rows:
        log(f"trim {r['trim']:+.3f} rad: mean path error {r['path_error_m']:.4f} m; trips: {r['success']} success, "
            f"{r['off_path']} off path, {r['fall']} falls, {r['timeout']} timeouts")
    errors = [r["path_error_m"] for r in rows]
    return {"rad": round(refine_minimum(trims, errors), 3), "scene": scene, "people": people, "seconds": seconds,
            "seed": seed, "trims": trims, "path_error_m": errors,
            "trips": [{k: r[k] for k in ("success", "off_path", "fall", "timeout")} for r in rows],
            "wall_s": round(time.time() - t0, 1)}


def write_trim(policy_dir: str | Path, result: dict[str, Any], command: str) -> Path:
    """Record ``result["rad"]`` and its calibration in ``policy_dir/config.json`` (atomically)."""
    root = Path(policy_dir)
    path = root / POLICY_CONFIG if root.is_dir() else root
    cfg = json.loads(path.read_text())
    policy = load_policy(path.parent)  # checks the policy before anything is written
    start, k = policy.waypoints
    kept = {key: v for key, v in (cfg.get("steering_trim") or {}).items() if key == TRIM_OFF_KEY}
    cfg["steering_trim"] = {
        **kept, "rad": result["rad"], "waypoint_start": start, "n_waypoints": k,
        "calibration": {**{key: result[key] for key in ("scene", "people", "seconds", "seed", "trims",
                                                         "path_error_m", "trips")},
                        "command": command, "date": time.strftime("%Y-%m-%d")},
    }
    atomic_write_text(path, json.dumps(cfg, indent=1, sort_keys=True))
    load_policy(path.parent)  # the written config loads
    return path


def add_arguments(parser: argparse.ArgumentParser) -> argparse.ArgumentParser:
    parser.add_argument("--policy", default=None, help="exported AMP policy directory (default: the shipped one)")
    parser.add_argument("--trims", default="0:0.25:0.025", help="LO:HI:STEP or A,B,C in rad (default %(default)s)")
    parser.add_argument("--scene", default=CALIBRATION_SCENE,
                        help="calibration scene, not one of the evaluation's (default %(default)s)")
    parser.add_argument("--people", type=int, default=6, help="pedestrians in the scene (default %(default)s)")
    parser.add_argument("--seconds", type=float, default=120.0, help="simulated seconds per trim (default %(default)s)")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--workers", type=int, default=1, help="trims run in parallel processes (default %(default)s)")
    parser.add_argument("--write", action="store_true", help="record the chosen trim in the policy's config.json")
    parser.add_argument("--json", action="store_true", help="print the result as JSON")
    return parser


def run(args: argparse.Namespace) -> int:
    from navzoo.agents.amp.pedestrian_policy import default_policy_dir

    try:
        trims = parse_trims(args.trims)
        if args.people < 1 or not args.seconds > 0 or args.workers < 1:
            raise ValueError("--people and --workers must be >= 1 and --seconds > 0")
        from navzoo.benchmark.pedestrians import SCENES

        if args.scene in SCENES:
            raise ValueError(f"--scene must be outside the evaluation's scenes {list(SCENES)}, got {args.scene!r}")
    except ValueError as e:
        print(f"error: {e}", file=sys.stderr)
        return 2
    policy_dir = Path(args.policy) if args.policy else default_policy_dir()
    result = calibrate(policy_dir, trims, args.scene, args.people, args.seconds, args.seed, args.workers,
                       log=lambda m: print(m, file=sys.stderr, flush=True))
    if args.write:
        command = (f"navzoo train amp-trim --policy {args.policy or 'policies/amp_pedestrian'} --trims {args.trims} "
                   f"--scene {args.scene} --people {args.people} --seconds {args.seconds:g} --seed {args.seed} --write")
        result["written_to"] = str(write_trim(policy_dir, result, command))
    print(json.dumps(result) if args.json else f"steering trim {result['rad']:+.4f} rad "
          f"(grid minimum {min(result['path_error_m']):.4f} m)" + (f"; written to {result['written_to']}"
                                                                   if args.write else ""))
    return 0


def main(argv: list[str] | None = None) -> int:
    return run(add_arguments(argparse.ArgumentParser(description=__doc__.splitlines()[0])).parse_args(argv))


if __name__ == "__main__":
    raise SystemExit(main())
