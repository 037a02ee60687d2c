"""Per-run summary of an AMP training history (``training/amp/metrics.jsonl.gz``).

``python scripts/amp_run_summary.py [--metrics training/amp/metrics.jsonl.gz] [--last 6] [--skip 40]``
prints one JSON line per training run (a run starts where ``wall_s`` goes back): its iterations, and
the medians of samples/s, collection and update seconds per iteration and the mean task and style
reward per step over the run's iterations after the first ``--skip`` (right after a resume every
humanoid starts a fresh episode, which is faster to simulate and not representative).
"""

from __future__ import annotations

import argparse
import gzip
import json
import statistics
from pathlib import Path


def split_runs(rows: list[dict]) -> list[list[dict]]:
    runs: list[list[dict]] = []
    last_wall = float("inf")
    for row in rows:
        if not runs or row["wall_s"] < last_wall:
            runs.append([])
        runs[-1].append(row)
        last_wall = row["wall_s"]
    return runs


def summarise(run: list[dict], skip: int) -> dict:
    body = run[skip:] if len(run) > skip else run

    def med(key: str) -> float:
        return round(statistics.median(r[key] for r in body), 3)

    def mean(key: str) -> float:
        return round(statistics.fmean(r[key] for r in body), 4)

    return {"first_iteration": run[0]["iteration"], "last_iteration": run[-1]["iteration"],
            "last_global_step": run[-1]["global_step"], "iterations_summarised": len(body),
            "fps_median": med("perf/fps"), "collect_s_median": med("perf/collect_s"),
            "update_s_median": med("perf/update_s"), "task_reward_mean": mean("rewards/task"),
            "style_reward_mean": mean("rewards/style")}


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--metrics", default="training/amp/metrics.jsonl.gz")
    ap.add_argument("--last", type=int, default=6, help="how many of the latest runs to print (0: all)")
    ap.add_argument("--skip", type=int, default=40, help="iterations left out at the start of each run")
    args = ap.parse_args(argv)
    path = Path(args.metrics)
    if not path.is_file():
        raise SystemExit(f"no metrics file at {path}")
    opener = gzip.open if path.suffix == ".gz" else open
    with opener(path, "rt") as f:
        rows = [json.loads(line) for line in f if line.strip()]
    if not rows:
        raise SystemExit(f"{path} holds no iterations")
    runs = split_runs(rows)
    for run in runs[-args.last:] if args.last > 0 else runs:
        print(json.dumps(summarise(run, max(args.skip, 0))))


if __name__ == "__main__":
    main()
