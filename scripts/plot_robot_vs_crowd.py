"""Tables and a plot of the robot side of the behaviour-change study (docs/scaling.md).

Reads the benchmark runs of ``training/robot_vs_crowd/run_benchmark.sh`` (one folder per robot policy: shipped,
vs_learned_seed<k>, vs_orca_seed<k>), pools training seeds per condition and prints a Markdown table of success,
collision, smallest distance and navigation time per robot and crowd, with 95 % normal intervals; writes the
per-episode records (gzipped) and a summary JSON to docs/results/robot_vs_crowd/ and the plot to
docs/img/robot_vs_crowd.png.

    python scripts/plot_robot_vs_crowd.py runs/rvc_bench runs/r2bench   # round 1 and round 2 benchmark folders
"""

from __future__ import annotations

import gzip
import json
import math
import sys
from collections import defaultdict
from pathlib import Path

CROWDS = [  # (benchmark crowd name, label)
    ("orca_rvo2", "ORCA (RVO2)"),
    ("sfm", "social force"),
    ("rllib:runs/joint_study/joint_study/with_robots_seed0", "learned with robots, seed 0 (fine-tuned against)"),
    ("rllib:runs/joint_study/joint_study/with_robots_seed1", "learned with robots, seed 1 (unseen)"),
    ("rllib:runs/joint_study/joint_study/no_robots_seed0", "learned without robots, seed 0 (unseen)"),
    ("rllib:runs/round2/vs_finetuned_robot_seed0", "learned among the robot fine-tuned vs learned seed 0 (round 2)"),
]
ROBOTS = [("shipped", "shipped CrowdNav policy"), ("vs_orca", "fine-tuned vs ORCA crowd"),
          ("vs_learned", "fine-tuned vs learned crowd")]


def load(roots: list[Path]) -> dict[str, list[dict]]:
    """Episode records by robot condition (training seeds pooled)."""
    out: dict[str, list[dict]] = defaultdict(list)
    runs = [p for root in roots for p in sorted(root.iterdir()) if (p / "episodes.jsonl").is_file()]
    for run in runs:
        cond = run.name.split("_seed")[0]
        for line in (run / "episodes.jsonl").read_text().splitlines():
            rec = json.loads(line)
            rec["policy_run"] = run.name
            out[cond].append(rec)
    return out


def rate(xs: list[float]) -> tuple[float, float]:
    n = len(xs)
    p = sum(xs) / n
    return p, 1.96 * math.sqrt(max(p * (1 - p), 1e-12) / n)


def main(argv: list[str]) -> int:
    data = load([Path(a) for a in (argv or ["runs/rvc_bench"])])
    summary: dict[str, dict] = {}
    print("| robot | runs | crowd | episodes | success | collision | smallest distance (m) | navigation time (s) |")
    print("|---|---|---|---|---|---|---|---|")
    for cond, label in ROBOTS:
        recs = data.get(cond, [])
        runs = sorted({r["policy_run"] for r in recs})
        for crowd, clabel in CROWDS:
            rs = [r for r in recs if r["crowd"] == crowd]
            if not rs:
                continue
            s, sci = rate([float(r["success"]) for r in rs])
            c, cci = rate([float(r["collision"]) for r in rs])
            md = sum(r["min_distance_m"] for r in rs) / len(rs)
            ok = [r["nav_time_s"] for r in rs if r["success"]]
            nt = sum(ok) / len(ok) if ok else float("nan")
            per_run = {run: sum(r["success"] for r in rs if r["policy_run"] == run) / max(1, sum(
                r["policy_run"] == run for r in rs)) for run in runs}
            summary.setdefault(cond, {})[crowd] = {"episodes": len(rs), "success": s, "success_ci95": sci,
                                                   "collision": c, "collision_ci95": cci, "min_distance_m": md,
                                                   "nav_time_s": nt, "success_per_run": per_run}
            seeds = " / ".join(f"{v:.2f}" for v in per_run.values())
            print(f"| {label} | {len(runs)} | {clabel} | {len(rs)} | {s:.2f} ± {sci:.2f} ({seeds}) | {c:.2f} ± {cci:.2f} "
                  f"| {md:.2f} | {nt:.1f} |")
    dst = Path("docs/results/robot_vs_crowd")
    dst.mkdir(parents=True, exist_ok=True)
    (dst / "summary.json").write_text(json.dumps(summary, indent=1) + "\n")
    with gzip.open(dst / "episodes.jsonl.gz", "wt") as f:
        for cond in data:
            for r in data[cond]:
                f.write(json.dumps(r) + "\n")

    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import numpy as np

    fig, ax = plt.subplots(figsize=(12, 4.8))
    width = 0.8 / len(ROBOTS)
    x = np.arange(len(CROWDS))
    for i, (cond, label) in enumerate(ROBOTS):
        vals = [summary.get(cond, {}).get(c, {}).get("success", np.nan) for c, _ in CROWDS]
        errs = [summary.get(cond, {}).get(c, {}).get("success_ci95", 0.0) for c, _ in CROWDS]
        ax.bar(x + (i - 1) * width, vals, width, yerr=errs, capsize=3, label=label)
    ax.set_xticks(x, [lbl.replace(" (", "\n(").replace(", seed", "\nseed").replace(" fine-tuned", "\nfine-tuned")
                      for _, lbl in CROWDS], fontsize=8)
    ax.set_ylabel("robot success rate")
    ax.set_ylim(0, 1.05)
    ax.set_title("CrowdNav transformer policy fine-tuned against a learned vs a rule-based crowd (circle crossing, 4 people)")
    ax.title.set_fontsize(9)
    ax.legend(fontsize=8, loc="upper center", bbox_to_anchor=(0.5, -0.2), ncol=3)
    fig.tight_layout()
    fig.savefig("docs/img/robot_vs_crowd.png", dpi=120)
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
