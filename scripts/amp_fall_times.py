"""When bodies fall in clip tracking: per tracked policy, the falls and the median time of a fall after the clip's start.

Reads the JSON lines of ``scripts/amp_checkpoint_tracking.py`` (each row keeps its per-clip results) and prints one
JSON line per row of the chosen protocol::

    python scripts/amp_fall_times.py docs/results/amp_tracking_root_offsets.jsonl --protocol tracking_full
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np


def fall_times(row: dict) -> dict:
    """``{"source", "falls", "clips", "median_fall_s", "quartiles_fall_s"}`` of one tracking row."""
    clips = row.get("per_clip")
    if not clips:
        raise ValueError(f"row of {row.get('source')!r} has no per-clip results")
    t = np.array([c["fall_time_s"] for c in clips if c["fell"] and c["fall_time_s"] is not None], dtype=float)
    return {"source": row.get("source"), "falls": int(len(t)), "clips": len(clips),
            "median_fall_s": float(np.median(t)) if len(t) else None,
            "quartiles_fall_s": np.percentile(t, [25, 75]).round(3).tolist() if len(t) else None}


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("rows", help="JSON lines written by scripts/amp_checkpoint_tracking.py")
    ap.add_argument("--protocol", default="tracking_full", help="only rows of this protocol (default tracking_full)")
    a = ap.parse_args(argv)
    for line in Path(a.rows).read_text().splitlines():
        row = json.loads(line)
        if row.get("protocol", "tracking") == a.protocol and "per_clip" in row:
            print(json.dumps(fall_times(row)))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
