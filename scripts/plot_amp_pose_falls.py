"""Pose error against falls over whole clips, one point per tracked policy: the trade-off of the cloning term.

Reads the JSON lines of ``scripts/amp_checkpoint_tracking.py``; a policy needs a ``tracking_full`` row (whole
clips, no stop at failure: falls, pose error) and gets its paper's-protocol clip share from its ``tracking`` row
when there is one. Prints one JSON line per policy and, with ``--out``, draws the points::

    python scripts/plot_amp_pose_falls.py docs/results/amp_tracking_root_offsets.jsonl \\
        --label policies/amp_pedestrian=shipped --label git:0ccd479:training/amp=lineage \\
        --label training/amp_scratch=scratch --out /tmp/pose_vs_falls.png

``--only S`` (repeatable) keeps the sources that contain S; ``--label SOURCE=NAME`` names a point (otherwise
:func:`short_name`). The plot in docs/ has its own command under it (docs/pedestrians_log.md, "The cloning weight sets
pose against falls"), with the ``--only`` selection it shows.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path


def pose_and_falls(rows: list[dict], only: list[str] | None = None) -> list[dict]:
    """One dict per source with a whole-clip row (the last such row of a source and checkpoint counts):
    ``{"source", "samples_m", "pose_rad", "rot_rad", "falls", "clips_tracked"}``, in the rows' order."""
    full: dict[tuple, dict] = {}
    paper: dict[tuple, dict] = {}
    for row in rows:
        if only and not any(s in row["source"] for s in only):
            continue
        key = (row["source"], row.get("trained_iterations"))
        protocol = row.get("protocol", "tracking")
        if protocol == "tracking_full":
            full[key] = row
        elif protocol == "tracking":
            paper[key] = row
    out = []
    for key, row in full.items():
        missing = [k for k in ("mean_pose_rot_error_rad", "fall_rate", "mean_rot_error_rad") if k not in row]
        if missing:
            raise ValueError(f"whole-clip row of {key[0]!r} lacks {missing}")
        steps = row.get("trained_steps")
        out.append({"source": key[0], "samples_m": round(steps / 1e6, 2) if steps else None,
                    "pose_rad": row["mean_pose_rot_error_rad"], "rot_rad": row["mean_rot_error_rad"],
                    "falls": row["fall_rate"],
                    "clips_tracked": paper[key]["clip_success_rate"] if key in paper else None})
    return out


def short_name(source: str) -> str:
    """``training/amp_bc/policies/policy_00005617`` -> ``5617``; other sources: the last part of the path."""
    last = source.rstrip("/").split("/")[-1]
    stem, _, digits = last.rpartition("_")
    return str(int(digits)) if stem == "policy" and digits.isdigit() else last


def draw(points: list[dict], labels: dict[str, str], out: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(10, 5))
    fig.subplots_adjust(left=0.08, right=0.665, bottom=0.11, top=0.92)
    listing = []
    for i, p in enumerate(points, start=1):
        name = labels.get(p["source"], short_name(p["source"]))
        named = p["source"] in labels
        x, y = p["pose_rad"], 100 * p["falls"]
        ax.scatter(x, y, s=40 if named else 25, color="tab:red" if named else "tab:blue", zorder=3)
        ax.annotate(str(i), (x, y), textcoords="offset points", xytext=(3, 3), fontsize=7)
        samples = f", {p['samples_m']:g} M" if p["samples_m"] else ""
        listing.append(f"{i:>2}  {name}{samples}: {x:.3f}, {y:.0f} %")
    fig.text(0.685, 0.92, "policy, samples: pose (rad), falls\n\n" + "\n".join(listing), va="top", ha="left", fontsize=7, family="monospace")
    ax.set_xlabel("pose error over whole clips (rad; links relative to their root)")
    ax.set_ylabel("clips in which the body falls (%)")
    ax.set_title("Clip tracking over whole clips: pose against falls")
    ax.grid(alpha=0.3)
    out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out, dpi=120)
    plt.close(fig)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("rows", help="JSON lines written by scripts/amp_checkpoint_tracking.py")
    ap.add_argument("--only", action="append", default=[], help="keep sources containing this (repeatable)")
    ap.add_argument("--label", action="append", default=[], help="SOURCE=NAME for a point (repeatable)")
    ap.add_argument("--out", help="PNG to draw")
    a = ap.parse_args(argv)
    labels = {}
    for item in a.label:
        source, sep, name = item.rpartition("=")
        if not sep or not source:
            ap.error(f"--label takes SOURCE=NAME, got {item!r}")
        labels[source] = name
    rows = [json.loads(line) for line in Path(a.rows).read_text().splitlines() if line.strip()]
    points = pose_and_falls(rows, a.only or None)
    if not points:
        ap.error(f"no whole-clip (tracking_full) rows in {a.rows}" + (f" for {a.only}" if a.only else ""))
    for p in points:
        print(json.dumps(p))
    if a.out:
        draw(points, labels, Path(a.out))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
