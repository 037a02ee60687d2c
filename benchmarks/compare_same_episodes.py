"""Compare a benchmark run with the committed full benchmark on exactly the same episodes.

    python benchmarks/compare_same_episodes.py benchmarks/full_learned_crowdnav/episodes.jsonl.gz \
        benchmarks/full_sfm/episodes.jsonl.gz

Episodes are matched on (scene, crowd, level, episode) and their seeds are checked; the table gives,
per method and crowd level, success, collision (walls / people) and timeout rates with the episode count.
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


def main(run: str, reference: str) -> int:
    def key(d: dict) -> tuple:
        return d["scene"], d["crowd"], d["level"], d["episode"]

    new, ref = _read(run), _read(reference)
    seeds = {key(d): d["seed"] for d in new}
    ref = [d for d in ref if key(d) in seeds]
    bad = [key(d) for d in ref if d["seed"] != seeds[key(d)]]
    if bad:
        raise SystemExit(f"seeds differ for {len(bad)} episodes, e.g. {bad[0]}: not the same episodes")
    groups: dict[tuple, list[dict]] = collections.defaultdict(list)
    for d in new + ref:
        groups[(d["method"], d["level"])].append(d)
    print("| method | level | n | success | collision | walls | people | timeout |")
    print("|---|---|---|---|---|---|---|---|")
    for (method, level), eps in sorted(groups.items()):
        n = len(eps)

        def rate(k: str, eps: list[dict] = eps, n: int = n) -> str:
            return f"{sum(bool(e[k]) for e in eps) / n:.2f}"

        print(f"| {method} | {level} | {n} | {rate('success')} | {rate('collision')} | {rate('obstacle_collision')} "
              f"| {rate('human_collision')} | {rate('timeout')} |")
    return 0


if __name__ == "__main__":
    if len(sys.argv) != 3:
        raise SystemExit(__doc__)
    raise SystemExit(main(sys.argv[1], sys.argv[2]))
