"""Compare two benchmark runs of the same methods on exactly the same episodes (before / after a change).

    python benchmarks/compare_before_after.py AFTER/episodes.jsonl BEFORE/episodes.jsonl[.gz] [--by-scene]

Episodes are matched on (scene, method, crowd, level, episode); their seeds must agree. Only episodes
finished in both runs count. Prints, per method and crowd level (and scene with ``--by-scene``), the
success / collision (walls, people) / timeout rates of both runs side by side.
"""

from __future__ import annotations

import collections
import gzip
import json
import sys
from pathlib import Path


def _read(path: str) -> list[dict]:
    opener = gzip.open if path.endswith(".gz") else open
    with opener(Path(path), "rt") as f:
        return [json.loads(line) for line in f if line.strip()]


def _key(d: dict) -> tuple:
    return d["scene"], d["method"], d["crowd"], d["level"], d["episode"]


def main(after: str, before: str, by_scene: bool = False) -> int:
    new = {_key(d): d for d in _read(after)}
    old = {_key(d): d for d in _read(before) if _key(d) in new}
    bad = [k for k, d in old.items() if d["seed"] != new[k]["seed"]]
    if bad:
        raise SystemExit(f"seeds differ for {len(bad)} episodes, e.g. {bad[0]}: not the same episodes")
    groups: dict[tuple, list[tuple[dict, dict]]] = collections.defaultdict(list)
    for k, d in old.items():
        g = (d["method"], d["level"]) if not by_scene else (d["method"], d["scene"], d["level"])
        groups[g].append((d, new[k]))
    cols = "| method |" + (" scene |" if by_scene else "") + " level | n |"
    print(cols + " success before → after | collision (walls / people) before → after | timeout before → after |")
    print("|---" * (cols.count("|") - 1 + 3) + "|")
    for g, pairs in sorted(groups.items()):
        n = len(pairs)

        def rate(k: str, side: int, pairs: list = pairs, n: int = n) -> float:
            return sum(bool(p[side][k]) for p in pairs) / n

        def coll(side: int) -> str:
            return f"{rate('collision', side):.2f} ({rate('obstacle_collision', side):.2f} / {rate('human_collision', side):.2f})"

        print(f"| {' | '.join(str(x) for x in g[:-1])} | {g[-1]} | {n} | {rate('success', 0):.2f} → {rate('success', 1):.2f} "
              f"| {coll(0)} → {coll(1)} | {rate('timeout', 0):.2f} → {rate('timeout', 1):.2f} |")
    return 0


if __name__ == "__main__":
    args = [a for a in sys.argv[1:] if a != "--by-scene"]
    if len(args) != 2:
        raise SystemExit(__doc__)
    raise SystemExit(main(args[0], args[1], "--by-scene" in sys.argv))
