"""Plot the AMP training curves of training/amp/metrics.jsonl.gz into docs/img/amp_training.png.

    python scripts/plot_amp_training.py [--metrics training/amp/metrics.jsonl.gz] [--out docs/img/amp_training.png]

Two runs against each other, per sample (the second run's curves in orange, its stage lines dotted):

    python scripts/plot_amp_training.py --metrics training/amp_scratch/metrics.jsonl.gz \
        --stages training/amp_scratch/stages.json --compare training/amp/metrics.jsonl.gz \
        --compare-stages training/amp/stages.json --task-per-step --out docs/img/amp_scratch_training.png

Stage boundaries (curriculum changes) are taken from training/amp/stages.json: a list of
{"from_step": N, "label": "..."} entries, drawn as vertical lines.
"""

from __future__ import annotations

import argparse
import gzip
import json
import textwrap
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402


def smooth(y: np.ndarray, k: int = 25) -> np.ndarray:
    ok = np.isfinite(y)
    y = np.where(ok, y, 0.0)
    w = np.convolve(ok.astype(float), np.ones(k), "same")
    return np.convolve(y, np.ones(k), "same") / np.maximum(w, 1)


def read_rows(path: str) -> list[dict]:
    opener = gzip.open if path.endswith(".gz") else open
    with opener(path, "rt") as f:
        return [json.loads(line) for line in f if line.strip()]


def column(rows: list[dict], key: str) -> np.ndarray:
    return np.array([r.get(key) if r.get(key) is not None else np.nan for r in rows], dtype=float)


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--metrics", default="training/amp/metrics.jsonl.gz")
    ap.add_argument("--stages", default="training/amp/stages.json")
    ap.add_argument("--out", default="docs/img/amp_training.png")
    ap.add_argument("--compare", default=None, help="another run's metrics, drawn over the first up to its length")
    ap.add_argument("--compare-stages", default=None, help="the other run's stages.json")
    ap.add_argument("--task-per-step", action="store_true",
                    help="plot the task reward per step instead of the episode task return")
    args = ap.parse_args()
    rows = read_rows(args.metrics)
    step = np.array([r["global_step"] for r in rows]) / 1e6
    first = ("rewards/task", "task reward / step") if args.task_per_step else ("episode/task_return", "episode task return")
    panels = [first, ("episode/length", "episode length (steps, 30 Hz)"),
              ("rewards/style", "style reward / step"), ("disc/acc_policy", "discriminator accuracy on policy")]
    stages = json.loads(Path(args.stages).read_text()) if Path(args.stages).exists() else []
    other = read_rows(args.compare) if args.compare else []
    other = [r for r in other if r["global_step"] <= 1.02 * step[-1] * 1e6]
    other_step = np.array([r["global_step"] for r in other]) / 1e6
    other_stages = json.loads(Path(args.compare_stages).read_text()) if args.compare_stages else []
    other_stages = [s for s in other_stages if s["from_step"] <= step[-1] * 1e6]
    fig, axes = plt.subplots(2, 2, figsize=(11, 6.5), sharex=True)
    for ax, (key, title) in zip(axes.flat, panels, strict=True):
        y = column(rows, key)
        ax.plot(step, y, color="0.8", lw=0.5)
        ax.plot(step, smooth(y), color="C0", lw=1.5, label=Path(args.metrics).parent.name)
        lo, hi = np.nanpercentile(y, [1, 99.5])
        if other:
            yo = column(other, key)
            ax.plot(other_step, smooth(yo), color="C1", lw=1.2, label=Path(args.compare).parent.name)
            lo, hi = min(lo, np.nanpercentile(yo, 1)), max(hi, np.nanpercentile(yo, 99.5))
        ax.set_title(title, fontsize=10)
        ax.set_ylim(lo - 0.05 * (hi - lo), hi + 0.1 * (hi - lo))
        for s in stages:
            ax.axvline(s["from_step"] / 1e6, color="C3", lw=0.8, ls="--")
        for s in other_stages:
            ax.axvline(s["from_step"] / 1e6, color="C1", lw=0.8, ls=":")
        ax.grid(alpha=0.3)
    if other:
        axes[0, 0].legend(fontsize=8, loc="lower right")
    # numbered markers on the lines, the labels spelled out under the figure (they overlap on the axis)
    for k, s in enumerate(stages, 1):
        axes[0, 0].text(s["from_step"] / 1e6, axes[0, 0].get_ylim()[1], f" {k}", color="C3", fontsize=8, va="top")
    for ax in axes[1]:
        ax.set_xlabel("samples (millions)")
    fig.suptitle(f"AMP pedestrian controller: training ({args.metrics})")
    legend = "   ".join(f"{k}: {s['label']}" for k, s in enumerate(stages, 1))
    if other_stages:
        legend += "   |   dotted, " + Path(args.compare).parent.name + ": " + ", ".join(s["label"] for s in other_stages)
    # wrapped by hand, with room kept for every line (matplotlib's wrap=True lets long legends run into the axes)
    lines = textwrap.wrap(legend.strip(" |"), 190)  # empty without stages of either run
    fig.text(0.5, 0.01, "\n".join(lines), ha="center", va="bottom", color="C3", fontsize=8)
    fig.tight_layout(rect=(0, 0.01 + 0.025 * len(lines), 1, 1))
    Path(args.out).parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(args.out, dpi=110)
    print(args.out)


if __name__ == "__main__":
    main()
