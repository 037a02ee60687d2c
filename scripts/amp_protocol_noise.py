"""How far the following protocol's success moves between policies that should be equal: a reference policy and
untrained copies of it (``scripts/amp_perturb_policy.py``), each run on the same seeds.

    python scripts/amp_protocol_noise.py --files 'docs/results/amp_noise/*.jsonl' --reference vcdef \\
        --controls pert1,pert2,pert3,pert4 [--seeds 0,1,2,3] [--scenes protocol] [--metric M] [--json]

Reads result files of ``scripts/amp_target_ablation.py`` (globs; a run found in several files is counted once if its
counts agree, and refused if they differ: :func:`amp_target_ablation.read_rows`). For every configuration and seed
whose rows cover all the chosen scenes, the scene runs are pooled (trips counted together) into a success rate per
time limit, as ``amp_target_ablation.py --summary`` pools a seed (``--metric``: another rate, or one counted one trip
per goal, :data:`METRICS`). Only seeds on which the reference and every
control ran are used. Prints one line per seed and then, in points (0-100):

- the reference's mean over the seeds and the controls' mean, and the paired difference reference - mean of the
  controls, seed by seed, with its mean and standard error;
- the spread of one (policy, seed) draw once each seed's mean is taken out (``residual_sd``: the two-way
  decomposition policy + seed + residual over all the policies given), and the spread of the seeds' means
  (``seed_sd``);
- ``seeds_needed``: for a difference of 2, 3, 5 and 8 points (``--differences``), how many seeds per arm a paired
  comparison of two policies needs to find it (two-sided 5 %, power 80 %: n = (1.96 + 0.84)^2 x 2 residual_sd^2 / d^2,
  at least 2).
"""

from __future__ import annotations

import argparse
import glob
import importlib.util
import json
import math
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from navzoo.benchmark.pedestrians import goal_trip_rates, scene_names

_SPEC = importlib.util.spec_from_file_location("amp_target_ablation",
                                               Path(__file__).resolve().parent / "amp_target_ablation.py")
_ablation = importlib.util.module_from_spec(_SPEC)
_SPEC.loader.exec_module(_ablation)

_Z = 1.96 + 0.8416  # two-sided 5 %, power 80 %


#: ``--metric`` choices: a rate of :func:`goal_trip_rates`, of the trips per time limit (the protocol's headline) or,
#: with the ``per_goal_`` prefix, of the same runs counted one trip per goal (the rows' ``by_goal`` counts).
METRICS = tuple(f"{prefix}{key}" for prefix in ("", "per_goal_")
                for key in ("success_rate", "goal_rate", "fall_rate", "map_collision_rate", "agent_collision_rate",
                            "timeout_rate"))


def seed_rates(rows: Sequence[dict], configs: Sequence[str], scenes: Sequence[str],
               seeds: Sequence[int] | None = None, metric: str = "success_rate") -> dict[str, dict[int, float]]:
    """One rate (``metric``, :data:`METRICS`; default success per limit) of each configuration and seed, its scene
    runs pooled, on the seeds where every configuration ran every scene. A ValueError names an unknown metric, a
    configuration with no rows, or says that no seed is complete."""
    if metric not in METRICS:
        raise ValueError(f"unknown metric {metric!r}; choose from {', '.join(METRICS)}")
    per_goal = metric.startswith("per_goal_")
    key = metric.removeprefix("per_goal_")
    have: dict[tuple[str, int], dict[str, dict]] = {}
    for r in rows:
        if r["config"] in configs and r["scene"] in scenes and (seeds is None or r["seed"] in seeds):
            have.setdefault((r["config"], r["seed"]), {})[r["scene"]] = r
    for c in configs:
        if not any(k[0] == c for k in have):
            raise ValueError(f"no rows of configuration {c!r} in the result files"
                             + ("" if seeds is None else f" on seeds {list(seeds)}"))
    all_seeds = sorted({k[1] for k in have})
    complete = [s for s in all_seeds if all(len(have.get((c, s), {})) == len(scenes) for c in configs)]
    if not complete:
        raise ValueError(f"no seed on which {', '.join(configs)} all ran the {len(scenes)} scenes "
                         f"(seeds with rows: {all_seeds})")
    out: dict[str, dict[int, float]] = {c: {} for c in configs}
    for c in configs:
        for s in complete:
            runs = list(have[(c, s)].values())
            if per_goal and any(not r.get("by_goal") for r in runs):
                raise ValueError(f"rows of {c!r} on seed {s} have no per-goal counts (by_goal)")
            out[c][s] = goal_trip_rates([r["by_goal"] if per_goal else r for r in runs])[key]
    return out


def noise(rates: dict[str, dict[int, float]], reference: str, controls: Sequence[str],
          differences: Sequence[float] = (2, 3, 5, 8)) -> dict:
    """Statistics of :func:`seed_rates`' output, in points; see the module docstring. ``seeds_needed`` is given for
    each of ``differences`` (points), and is at least 2 (a paired comparison needs two seeds to see its spread)."""
    seeds = sorted(rates[reference])
    m = 100 * np.array([[rates[c][s] for s in seeds] for c in (reference, *controls)])  # policies x seeds
    ctrl = m[1:].mean(axis=0)
    diff = m[0] - ctrl
    n_p, n_s = m.shape
    resid = m - m.mean(axis=1, keepdims=True) - m.mean(axis=0, keepdims=True) + m.mean()
    dof = (n_p - 1) * (n_s - 1)
    resid_sd = float(math.sqrt((resid ** 2).sum() / dof)) if dof > 0 else float("nan")
    out = {"seeds": seeds, "reference": reference, "controls": list(controls),
           "by_seed": {int(s): {c: round(float(rates[c][s]), 4) for c in (reference, *controls)} for s in seeds},
           "reference_mean": float(m[0].mean()), "controls_mean": float(ctrl.mean()),
           "diff_by_seed": [round(float(d), 2) for d in diff], "diff_mean": float(diff.mean()),
           "diff_se": float(diff.std(ddof=1) / math.sqrt(n_s)) if n_s > 1 else float("nan"),
           "residual_sd": resid_sd,
           "seed_sd": float(m.mean(axis=0).std(ddof=1)) if n_s > 1 else float("nan")}
    out["seeds_needed"] = ({f"{d:g}": max(2, math.ceil(_Z ** 2 * 2 * resid_sd ** 2 / d ** 2)) for d in differences}
                           if math.isfinite(resid_sd) else {})
    return out


def main(argv: Sequence[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--files", nargs="+", required=True, help="result files (globs) of amp_target_ablation.py")
    ap.add_argument("--reference", required=True, help="configuration name of the reference policy")
    ap.add_argument("--controls", required=True, help="configuration names of the controls, joined by commas")
    ap.add_argument("--seeds", default=None, metavar="S,S", help="only these seeds (default: all complete ones)")
    ap.add_argument("--scenes", default="protocol", help="'protocol' (the 8), 'heldout' or scene names")
    ap.add_argument("--metric", default="success_rate", choices=METRICS,
                    help="the rate compared (default: success per time limit; per_goal_*: one trip per goal)")
    ap.add_argument("--differences", default="2,3,5,8", metavar="D,D",
                    help="differences (points) for the seeds needed per arm (default 2,3,5,8; e.g. 0.5,1,2 for falls)")
    ap.add_argument("--json", action="store_true")
    args = ap.parse_args(argv)
    files = sorted({f for pat in args.files for f in glob.glob(pat)})
    if not files:
        ap.error(f"no result files match {args.files}")
    controls = [c for c in args.controls.split(",") if c]
    if not controls or args.reference in controls:
        ap.error("--controls: give at least one configuration other than the reference")
    try:
        scenes = scene_names(args.scenes)
        seeds = None if args.seeds is None else [int(s) for s in args.seeds.split(",")]
        differences = [float(d) for d in args.differences.split(",") if d]
        if not differences or not all(d > 0 for d in differences):
            raise ValueError(f"--differences must be positive numbers, got {args.differences!r}")
        res = noise(seed_rates(_ablation.read_rows(files), [args.reference, *controls], scenes, seeds, args.metric),
                    args.reference, controls, differences)
        res["metric"] = args.metric
    except ValueError as exc:
        ap.error(str(exc))
    if args.json:
        print(json.dumps(res, indent=1))
        return 0
    print(f"{args.metric}:")
    print(f"| seed | {args.reference} | " + " | ".join(controls) + " | controls' mean | difference (points) |")
    print("|---" * (len(controls) + 4) + "|")
    for s, d in zip(res["seeds"], res["diff_by_seed"], strict=True):
        row = res["by_seed"][s]
        vals = [row[c] for c in controls]
        print(f"| {s} | {row[args.reference]:.3f} | " + " | ".join(f"{v:.3f}" for v in vals)
              + f" | {np.mean(vals):.3f} | {d:+.1f} |")
    print(f"{args.reference} - controls: {res['diff_mean']:+.2f} ± {res['diff_se']:.2f} points (mean ± s.e. over "
          f"{len(res['seeds'])} seeds); {args.reference} {res['reference_mean']:.1f}, controls {res['controls_mean']:.1f}")
    print(f"one draw's spread once the seed is taken out: {res['residual_sd']:.2f} points (s.d.); the seeds' means: "
          f"{res['seed_sd']:.2f} points (s.d.)")
    print("seeds per arm for a paired comparison to find a difference (5 %, power 80 %): "
          + ", ".join(f"{d} points: {n}" for d, n in res["seeds_needed"].items()))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
