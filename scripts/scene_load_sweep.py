"""How one scene's following results change with its number of people: the same protocol, other crowd sizes.

The pedestrian-following protocol (``navzoo eval pedestrians``, :func:`navzoo.benchmark.pedestrians.follow_scene`)
gives each of its 8 scenes a fixed crowd (3-15 people in the scenes' order, so the one-door scene gets 13). This
script runs one scene with several crowd sizes, for any target generator and bodies, and prints per size the trip
rates (per time limit and one trip per goal) and the goals reached per person-minute, so a scene that fails by
congestion can be told from one that fails for every crowd size:

    python scripts/scene_load_sweep.py --scene doorway --people 5,8,13 --crowd diffusion --bodies amp \\
        --seeds 0 --seconds 200 --workers 2 --out docs/results/door_load/doorway_diffusion_amp_vm.jsonl

One JSON line per (people, seed) run is appended to ``--out`` as it ends (a rerun with the same settings skips the
runs already there, so an interrupted sweep resumes); ``--summary FILE`` prints the table of a result file.
"""

from __future__ import annotations

import argparse
import json
import multiprocessing as mp
import sys
from pathlib import Path

from navzoo.benchmark import pedestrians as P


def _counts(text: str) -> list[int]:
    try:
        out = [int(x) for x in text.split(",") if x.strip()]
    except ValueError:
        raise SystemExit(f"--people {text!r}: expected comma-separated crowd sizes, e.g. 5,8,13") from None
    if not out or any(n < 1 for n in out):
        raise SystemExit(f"--people {text!r}: crowd sizes must be positive")
    return out


def _run(job: tuple) -> dict:
    scene, n, seconds, seed, crowd, bodies = job
    row = P.follow_scene(scene, n, seconds, seed, pose_every=0, crowd_model=crowd, human_model=bodies)
    keep = ("success", "off_path", "fall", "timeout", "map_trips", "agent_trips", "running", "by_goal", "err_sum",
            "err_n", "path_error", "wall_s")
    return {"scene": scene, "people": n, "seconds": seconds, "seed": seed, "crowd": crowd, "bodies": bodies,
            **{k: row[k] for k in keep if k in row}}


def summary(rows: list[dict]) -> str:
    lines = ["| scene, crowd, bodies | people | seeds | trips | success per limit | per goal | timeouts per limit "
             "| per goal | falls | goals per person-minute |", "|---|---|---|---|---|---|---|---|---|---|"]
    groups: dict[tuple, list[dict]] = {}
    for r in rows:
        groups.setdefault((r["scene"], r["crowd"], r["bodies"], r["people"]), []).append(r)
    for (scene, crowd, bodies, n), rs in sorted(groups.items()):
        m = P._following_metrics(rs, rs[0]["seconds"])
        g = m["per_goal"] or {}
        goals = sum(r["success"] + r["off_path"] for r in rs)
        per_min = goals / (n * sum(r["seconds"] for r in rs) / 60.0)
        lines.append(f"| {scene}, {crowd}, {bodies} | {n} | {','.join(str(r['seed']) for r in rs)} | {m['trips']} "
                     f"| {m['success_rate']:.3f} | {g.get('success_rate', float('nan')):.3f} "
                     f"| {m['timeout_rate']:.3f} | {g.get('timeout_rate', float('nan')):.3f} | {m['fall_rate']:.3f} "
                     f"| {per_min:.2f} |")
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--scene", default="doorway")
    ap.add_argument("--people", default="5,8,13", help="crowd sizes, comma-separated (default %(default)s)")
    ap.add_argument("--crowd", default="sfm", choices=("sfm", "orca", "diffusion"))
    ap.add_argument("--bodies", default="amp", choices=("amp", "kinematic"))
    ap.add_argument("--seeds", default="0")
    ap.add_argument("--seconds", type=float, default=200.0)
    ap.add_argument("--workers", type=int, default=1)
    ap.add_argument("--out", default=None, help="JSON lines, appended; runs already there are skipped")
    ap.add_argument("--summary", metavar="JSONL", help="print the table of a result file and exit")
    args = ap.parse_args(argv)
    if args.summary:
        print(summary([json.loads(x) for x in Path(args.summary).read_text().splitlines() if x.strip()]))
        return 0
    if args.seconds <= 0:
        raise SystemExit(f"--seconds must be positive, got {args.seconds}")
    try:
        seeds = P.check_seeds([int(s) for s in args.seeds.split(",") if s.strip()])
    except ValueError as e:
        raise SystemExit(f"--seeds {args.seeds!r}: {e}") from None
    jobs = [(args.scene, n, args.seconds, s, args.crowd, args.bodies) for n in _counts(args.people) for s in seeds]
    rows: list[dict] = []
    out = Path(args.out) if args.out else None
    if out and out.exists():
        rows = [json.loads(x) for x in out.read_text().splitlines() if x.strip()]
        done = {(r["scene"], r["people"], r["seconds"], r["seed"], r["crowd"], r["bodies"]) for r in rows}
        jobs = [j for j in jobs if j not in done]
        print(f"{len(jobs)} runs left ({len(done)} in {out})", file=sys.stderr)
    if out:
        out.parent.mkdir(parents=True, exist_ok=True)
    def keep(row: dict) -> None:
        rows.append(row)
        if out:
            with out.open("a") as f:
                f.write(json.dumps(row) + "\n")
        print(f"{row['scene']} {row['people']} people, seed {row['seed']}: {row['success']} success, "
              f"{row['off_path']} off path, {row['fall']} falls, {row['timeout']} timeouts", file=sys.stderr)

    if args.workers <= 1 or len(jobs) <= 1:
        for job in jobs:
            keep(_run(job))
    else:
        with mp.get_context("spawn").Pool(min(args.workers, len(jobs))) as pool:
            for row in pool.imap_unordered(_run, jobs):
                keep(row)
    print(summary(rows))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
