"""Falls per pedestrian-minute on recorded and on generated targets in a patch-env run with recorded crowd targets.

    python scripts/amp_recorded_falls.py training/amp_stance_recorded/metrics.jsonl.gz [--every 40] [--from IT]

Reads a training run's metrics (``navzoo train amp`` with ``--recorded-targets``; the env logs ``env/recorded``,
``env/fall_recorded`` and ``env/fall_generated``, rollout means of per-step flags) and prints, per block of
``--every`` iterations and over all: the share of recorded episodes' steps, the falls per pedestrian-minute of each
kind (falls per step of that kind x 30 Hz x 60 s; a fall ends its episode, so each counts once) and the mean
stance split. Under exploration noise, so higher than the deterministic policy's falls.
"""

from __future__ import annotations

import argparse
import gzip
import json
import sys

import numpy as np

KEYS = ("env/recorded", "env/fall_recorded", "env/fall_generated")


def blocks(rows: list[dict], every: int, control_hz: int = 30) -> list[dict]:
    """One summary per ``every`` iterations (the last block takes the rest of the run, if under ``every``) and one
    of all rows."""
    if not rows:
        return []
    its = np.array([r["iteration"] for r in rows])
    starts = list(range(int(its.min()), int(its.max()) + 1, every))
    if len(starts) > 1 and int(its.max()) - starts[-1] + 1 < every:
        starts.pop()
    edges = starts[1:] + [int(its.max()) + 1]
    out = []
    for lo, hi in [*zip(starts, edges, strict=True), (int(its.min()), int(its.max()) + 1)]:
        part = [r for r in rows if lo <= r["iteration"] < hi]
        share = float(np.mean([r["env/recorded"] for r in part]))
        per_min = 60.0 * control_hz
        rec = float(np.mean([r["env/fall_recorded"] for r in part]))
        gen = float(np.mean([r["env/fall_generated"] for r in part]))
        out.append({"from": lo, "to": hi - 1, "iterations": len(part), "recorded_share": round(share, 3),
                    "falls_per_min_recorded": round(rec / share * per_min, 3) if share > 0 else None,
                    "falls_per_min_generated": round(gen / (1 - share) * per_min, 3) if share < 1 else None,
                    "stance_split_m": round(float(np.mean([r.get("env/stance_split_m", np.nan) for r in part])), 3)})
    return out


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("metrics", help="a run's metrics.jsonl or metrics.jsonl.gz")
    ap.add_argument("--every", type=int, default=40, help="iterations per block")
    ap.add_argument("--from", dest="start", type=int, default=0, help="only iterations from this one on")
    a = ap.parse_args(argv)
    if a.every < 1:
        ap.error("--every must be at least 1")
    opener = gzip.open if a.metrics.endswith(".gz") else open
    try:
        with opener(a.metrics, "rt") as f:
            rows = [json.loads(line) for line in f if line.strip()]
    except (OSError, json.JSONDecodeError) as e:
        ap.error(f"{a.metrics}: cannot read it ({e})")
    rows = [r for r in rows if r.get("iteration", -1) >= a.start and all(k in r for k in KEYS)]
    if not rows:
        ap.error(f"{a.metrics}: no iterations with {', '.join(KEYS)} (a run with --recorded-targets logs them)")
    print("| iterations | recorded share | falls per pedestrian-minute, recorded | generated | stance split (m) |")
    print("|---|---|---|---|---|")
    for b in blocks(rows, a.every):
        print(f"| {b['from']}-{b['to']} | {b['recorded_share']:.2f} | {b['falls_per_min_recorded']} | "
              f"{b['falls_per_min_generated']} | {b['stance_split_m']:.3f} |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
