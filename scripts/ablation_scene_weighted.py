"""Compare two settings of the following protocol scene by scene, on the seeds both ran, and pool them with fixed
scene weights.

    python scripts/ablation_scene_weighted.py --a 'docs/results/diffusion_sight/floor2_s*' ... \\
        --b 'docs/results/diffusion_sight/fis_s*' ... [--weight-seeds 0,1,2,3,4,5] [--scenes protocol|heldout|S,S] [--json]

``--a`` and ``--b`` take result files of ``scripts/amp_target_ablation.py`` (globs; one row per scene run). Scenes can
have run on different numbers of seeds; each scene is compared on the seeds that both settings ran. The pooled rates
weight each scene by its share of A's trips (per limit) or goal trips (per goal) on ``--weight-seeds``, the seeds that
every scene ran, so that a scene run on more seeds does not weigh more. Paired: the mean difference B - A in
successes per scene run, its standard error, and the seeds where B or A is ahead (docs/crowd_log.md, "Sixteen seeds").
With ``--by-seed``, each seed's scene runs are pooled instead and the settings compared seed by seed. ``--json`` also
gives each scene's successes seed by seed.

A pair is a fair one only when both runs walked on the same kind of CPU: on another kind the same seed walks other
trips (docs/pedestrians.md, "Reproducing these figures"). Pairs whose rows record different CPUs are named on
stderr; ``--same-cpu`` leaves them out (rows that record no CPU are kept).
"""

from __future__ import annotations

import argparse
import glob
import json
import sys
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from navzoo.benchmark.pedestrians import goal_trip_rates


def load(patterns: Sequence[str], scenes: Sequence[str] | None = None) -> dict[tuple[str, int], dict]:
    """Rows of the files matching ``patterns``, keyed by (scene, seed); a run found twice is an error. With
    ``scenes``, only those scenes' rows."""
    rows: dict[tuple[str, int], dict] = {}
    files = sorted({f for pat in patterns for f in glob.glob(pat)})
    if not files:
        raise SystemExit(f"no result files match {list(patterns)}")
    for f in files:
        for line in Path(f).read_text().splitlines():
            if line.strip():
                r = json.loads(line)
                key = (r["scene"], int(r["seed"]))
                if key in rows:
                    raise SystemExit(f"{f}: scene {key[0]} seed {key[1]} is in more than one file")
                rows[key] = r
    if scenes is not None:
        rows = {k: r for k, r in rows.items() if k[0] in scenes}
        if not rows:
            raise SystemExit(f"no rows of scenes {list(scenes)} in {files}")
    return rows


def cpu_mismatches(a: dict, b: dict) -> list[tuple[str, int, str, str]]:
    """The runs both settings ran whose rows record different CPUs: (scene, seed, A's CPU, B's CPU)."""
    return [(s, k, a[(s, k)]["cpu"], b[(s, k)]["cpu"]) for s, k in sorted(set(a) & set(b))
            if a[(s, k)].get("cpu") and b[(s, k)].get("cpu") and a[(s, k)]["cpu"] != b[(s, k)]["cpu"]]


def same_cpu(a: dict, b: dict) -> tuple[dict, dict]:
    """``a`` and ``b`` without the runs of :func:`cpu_mismatches` (in both, so they leave the pairs and the pools)."""
    drop = {(s, k) for s, k, _, _ in cpu_mismatches(a, b)}
    return ({key: r for key, r in a.items() if key not in drop}, {key: r for key, r in b.items() if key not in drop})


def _warn_cpus(a: dict, b: dict, dropped: bool) -> None:
    bad = cpu_mismatches(a, b)
    if not bad:
        return
    kinds = sorted({f"A on {ca}, B on {cb}" for _, _, ca, cb in bad})
    seeds = sorted({k for _, k, _, _ in bad})
    what = "left out (--same-cpu)" if dropped else "compared anyway; --same-cpu leaves them out"
    print(f"warning: {len(bad)} of {len(set(a) & set(b))} paired runs ran on different CPUs ({'; '.join(kinds)}; "
          f"seeds {','.join(map(str, seeds))}): their trips differ by CPU as well as by setting; {what}",
          file=sys.stderr)


def _pooled(rows: Sequence[dict], by_goal: bool) -> dict:
    """Success rate and trips of scene runs pooled (trips counted together), per limit or one trip per goal."""
    return goal_trip_rates([r["by_goal"] if by_goal else r for r in rows])


def compare(a: dict, b: dict, weight_seeds: Sequence[int]) -> dict:
    scenes = sorted({s for s, _ in a} & {s for s, _ in b})
    out: dict = {"scenes": {}}
    for by_goal, name in ((False, "per_limit"), (True, "per_goal")):
        w = {s: _pooled([a[(s, k)] for k in weight_seeds if (s, k) in a], by_goal)["trips"] for s in scenes}
        total = sum(w.values())
        if total == 0:
            raise SystemExit(f"A has no trips on --weight-seeds {list(weight_seeds)}")
        pooled = {"a": 0.0, "b": 0.0}
        for s in scenes:
            seeds = sorted(k for (sc, k) in a if sc == s and (s, k) in b)
            rate = {x: _pooled([rows[(s, k)] for k in seeds], by_goal)["success_rate"] for x, rows in (("a", a), ("b", b))}
            for x in rate:
                pooled[x] += w[s] / total * rate[x]
            row = out["scenes"].setdefault(s, {"seeds": seeds, "weight": {}})
            row[name] = rate
            if not by_goal:
                row["success_by_seed"] = {x: {k: rows[(s, k)]["success"] for k in seeds} for x, rows in (("a", a), ("b", b))}
            row["weight"][name] = w[s] / total
            if not by_goal:
                d = np.array([b[(s, k)]["success"] - a[(s, k)]["success"] for k in seeds], dtype=float)
                row["paired_success_diff"] = {
                    "mean": float(d.mean()),
                    "se": float(d.std(ddof=1) / np.sqrt(len(d))) if len(d) > 1 else float("nan"),
                    "b_ahead": int((d > 0).sum()), "a_ahead": int((d < 0).sum())}
        out[name] = pooled
    return out


def by_seed(a: dict, b: dict) -> dict:
    """Per seed, success per limit of all the scene runs of that seed pooled (as ``amp_target_ablation.py
    --summary`` pools a seed), on the seeds where both settings ran the same scenes; the paired differences B - A
    (mean and standard error, in points) and the spread of A's seeds (standard deviation, in points)."""
    seeds = sorted({k for _, k in a} & {k for _, k in b})
    rates: dict[str, list[float]] = {"a": [], "b": []}
    kept = []
    for k in seeds:
        scenes = sorted(s for s, kk in a if kk == k)
        if scenes != sorted(s for s, kk in b if kk == k):
            continue
        kept.append(k)
        for x, rows in (("a", a), ("b", b)):
            rates[x].append(_pooled([rows[(s, k)] for s in scenes], False)["success_rate"])
    if len(kept) < 2:
        raise SystemExit("fewer than two seeds where both settings ran the same scenes")
    d = 100 * (np.array(rates["b"]) - np.array(rates["a"]))
    return {"seeds": kept, "a": rates["a"], "b": rates["b"], "diff_points": d.round(1).tolist(),
            "diff_mean_points": float(d.mean()), "diff_se_points": float(d.std(ddof=1) / np.sqrt(len(d))),
            "a_sd_points": float(100 * np.std(rates["a"], ddof=1))}


def main(argv: Sequence[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--a", nargs="+", required=True, help="result files (globs) of setting A")
    ap.add_argument("--b", nargs="+", required=True, help="result files (globs) of setting B")
    ap.add_argument("--weight-seeds", default="0,1,2,3,4,5", help="seeds whose trips of A weigh the scenes")
    ap.add_argument("--by-seed", action="store_true",
                    help="pool each seed's scene runs instead, and compare the settings seed by seed")
    ap.add_argument("--scenes", default=None, metavar="S,S",
                    help="only these scenes ('protocol' for the 8 of the following protocol, 'heldout' for the 10)")
    ap.add_argument("--same-cpu", action="store_true",
                    help="leave out the runs whose rows in A and B record different CPUs")
    ap.add_argument("--json", action="store_true")
    args = ap.parse_args(argv)
    only = None
    if args.scenes is not None:
        from navzoo.benchmark.pedestrians import scene_names

        try:
            only = scene_names(args.scenes)
        except ValueError as exc:
            ap.error(str(exc))
    a, b = load(args.a, only), load(args.b, only)
    _warn_cpus(a, b, args.same_cpu)
    if args.same_cpu:
        a, b = same_cpu(a, b)
    if args.by_seed:
        res = by_seed(a, b)
        if args.json:
            print(json.dumps(res, indent=1))
            return
        print("| seed | A per limit | B per limit | B - A (points) |")
        print("|---|---|---|---|")
        for k, ra, rb, d in zip(res["seeds"], res["a"], res["b"], res["diff_points"], strict=True):
            print(f"| {k} | {ra:.3f} | {rb:.3f} | {d:+.1f} |")
        print(f"B - A: {res['diff_mean_points']:+.2f} ± {res['diff_se_points']:.2f} points (mean ± s.e. over "
              f"{len(res['seeds'])} seeds); A's seeds spread {res['a_sd_points']:.1f} points (s.d.)")
        return
    res = compare(a, b, [int(s) for s in args.weight_seeds.split(",")])
    if args.json:
        print(json.dumps(res, indent=1))
        return
    print("| scene | seeds | weight per limit | A per limit | B per limit | A per goal | B per goal | "
          "B - A successes per run (± s.e.) | runs B / A ahead |")
    print("|---|---|---|---|---|---|---|---|---|")
    for s, r in res["scenes"].items():
        p = r["paired_success_diff"]
        print(f"| {s} | {len(r['seeds'])} | {r['weight']['per_limit']:.3f} | {r['per_limit']['a']:.3f} | "
              f"{r['per_limit']['b']:.3f} | {r['per_goal']['a']:.3f} | {r['per_goal']['b']:.3f} | "
              f"{p['mean']:+.1f} ± {p['se']:.1f} | {p['b_ahead']} / {p['a_ahead']} |")
    print(f"| weighted pool | | | {res['per_limit']['a']:.3f} | {res['per_limit']['b']:.3f} | "
          f"{res['per_goal']['a']:.3f} | {res['per_goal']['b']:.3f} | | |")


if __name__ == "__main__":
    main()
