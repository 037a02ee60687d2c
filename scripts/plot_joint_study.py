"""Plot the pedestrians-with/without-robots study (docs/scaling.md) from docs/results/joint_study/.

    python scripts/plot_joint_study.py [RESULTS_DIR] [OUT_PNG]
"""
from __future__ import annotations

import gzip
import json
import sys
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

METRICS = (("robot_success", "DWA robot success"), ("ped_robot_contacts", "pedestrian-robot contacts / episode"),
           ("min_robot_human_gap_m", "smallest robot-pedestrian gap (m)"),
           ("personal_space_share", "robot-steps with a pedestrian < 0.5 m"))
ROWS = (("crowd_orca", "ORCA crowd"), ("crowd_sfm", "SFM crowd"), ("no_robots", "learned without robots"),
        ("with_robots", "learned with robots"))


def main() -> None:
    src = Path(sys.argv[1] if len(sys.argv) > 1 else "docs/results/joint_study")
    out = Path(sys.argv[2] if len(sys.argv) > 2 else "docs/img/joint_study.png")
    data: dict[str, list[dict]] = {}
    for f in sorted(src.glob("*.json.gz")):
        name = f.name[: -len(".json.gz")]
        key = name.rsplit("_seed", 1)[0]
        data.setdefault(key, []).append(json.loads(gzip.open(f).read())["mean"])
    fig, axes = plt.subplots(1, len(METRICS), figsize=(13, 3.4))
    for ax, (metric, title) in zip(axes, METRICS, strict=True):
        for x, (key, label) in enumerate(ROWS):
            vals = [d[metric] for d in data.get(key, [])]
            ax.bar(x, sum(vals) / len(vals), color=f"C{x}", alpha=0.6, label=label)
            ax.scatter([x] * len(vals), vals, color="k", s=12, zorder=3)
        ax.set_xticks(range(len(ROWS)), [label.replace(" ", "\n", 1) for _, label in ROWS], fontsize=7)
        ax.set_title(title, fontsize=9)
        ax.grid(axis="y", alpha=0.3)
    fig.suptitle("CircleCrossing, 1 DWA robot + 4 pedestrians, 200 seeded episodes per point "
                 "(dots: training seeds of the learned pedestrians)", fontsize=9)
    fig.tight_layout()
    out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out, dpi=100)
    print(out)


if __name__ == "__main__":
    main()
