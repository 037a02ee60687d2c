"""Plot the feet's split during scene training runs (``env/stance_split_m`` of metrics.jsonl.gz) next to the
clips' level and the stance term's free band:

    python scripts/plot_amp_stance.py --run "run 33 (w 2, lr 1e-4)=docs/results/amp_run33_34_stance/run33_metrics.jsonl.gz" \\
        --run "run 34 (w 0.5, lr 5e-5)=docs/results/amp_run33_34_stance/run34_metrics.jsonl.gz" \\
        --run "amp_bc run 20 (w 0, cloned lineage)=docs/results/amp_bc_run20_scenes_device/metrics.jsonl.gz" \\
        --clips docs/results/amp_stance_split_vm.json --out docs/img/amp_stance_training.png
"""

from __future__ import annotations

import argparse
import gzip
import json
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from navzoo.agents.amp.features import STANCE_FREE_M  # noqa: E402


def load(path: str) -> dict[str, np.ndarray]:
    with gzip.open(path, "rt") as f:
        rows = [json.loads(line) for line in f if line.strip()]
    rows = [r for r in rows if r.get("env/stance_split_m") is not None]
    if not rows:
        raise SystemExit(f"{path}: no env/stance_split_m rows (a run before the stance log)")
    step = np.array([r["global_step"] for r in rows], float)
    return {"samples_m": (step - step[0]) / 1e6, "split": np.array([r["env/stance_split_m"] for r in rows]),
            "task": np.array([r["rewards/task"] for r in rows])}


def smooth(y: np.ndarray, k: int = 9) -> np.ndarray:
    return np.convolve(y, np.ones(k) / k, mode="valid") if len(y) > k else y


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--run", action="append", required=True, metavar="LABEL=METRICS")
    ap.add_argument("--clips", default=None, help="amp_stance_split.py output: draw the clips' level")
    ap.add_argument("--out", default="docs/img/amp_stance_training.png")
    args = ap.parse_args(argv)
    fig, axes = plt.subplots(1, 2, figsize=(11, 4))
    for item in args.run:
        label, sep, path = item.partition("=")
        if not sep:
            ap.error(f"--run takes LABEL=METRICS, got {item!r}")
        d = load(path)
        k = 9
        x = d["samples_m"][k - 1:] if len(d["split"]) > k else d["samples_m"]
        axes[0].plot(x, smooth(d["split"], k), label=label)
        axes[1].plot(x, smooth(d["task"], k), label=label)
    axes[0].axhline(STANCE_FREE_M, color="grey", ls="--", lw=1, label="free band of the stance term")
    if args.clips:
        clips = json.loads(Path(args.clips).read_text())["clips"]["mean_abs_running_mean_m"]
        axes[0].axhline(clips, color="k", ls=":", lw=1, label="reference clips")
    axes[0].set(xlabel="pedestrian steps since the run's start (M)", ylabel="|running mean of the feet's split| (m)",
                title="stance in training (rollout mean, 9-iteration mean)", ylim=(0, None))
    axes[1].set(xlabel="pedestrian steps since the run's start (M)", ylabel="task reward per step",
                title="task reward (stance term included)")
    axes[0].legend(fontsize=8)
    axes[1].legend(fontsize=8)
    fig.tight_layout()
    Path(args.out).parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(args.out, dpi=110)
    print(f"wrote {args.out}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
