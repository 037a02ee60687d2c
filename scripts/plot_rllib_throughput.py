"""Plot RLlib env steps/s against env runners from docs/results/rllib_device/summary.json.

    python scripts/plot_rllib_throughput.py [SUMMARY] [OUT_PNG]
"""
from __future__ import annotations

import json
import sys
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402


def main() -> None:
    src = Path(sys.argv[1] if len(sys.argv) > 1 else "docs/results/rllib_device/summary.json")
    out = Path(sys.argv[2] if len(sys.argv) > 2 else "docs/img/rllib_throughput.png")
    rows = json.loads(src.read_text())["runners"]
    n = sorted(int(k) for k in rows)
    sps = [rows[str(k)]["env_steps_per_s_overall"] for k in n]
    fig, ax = plt.subplots(figsize=(5.5, 3.8))
    ax.plot(n, sps, "o-", label="measured (sampling + learning)")
    ax.plot(n, [sps[0] * k for k in n], "--", color="grey", label="linear in runners")
    for k, v in zip(n, sps, strict=True):
        ax.annotate(f"{v:.0f}", (k, v), textcoords="offset points", xytext=(4, -12), fontsize=8)
    ax.set_xscale("log", base=2)
    ax.set_yscale("log")
    ax.set_xticks(n, [str(k) for k in n])
    ax.set_xlabel("env runner processes")
    ax.set_ylabel("env steps / s")
    ax.set_title("RLlib PPO, CircleCrossing 1 robot + 5 pedestrians\n16-core device machine, CPU learner", fontsize=9)
    ax.legend(fontsize=8)
    ax.grid(alpha=0.3, which="both")
    fig.tight_layout()
    out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out, dpi=110)
    print(out)


if __name__ == "__main__":
    main()
