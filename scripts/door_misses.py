"""Which paths do the door turns give no door for, though the path crosses one? One run of the following protocol.

    python scripts/door_misses.py --scene doorway --people 13 --crowd diffusion --seed 0 --seconds 100 \
        [--const NAME=VALUE ...] [--json F]

Runs one scene as ``navzoo eval pedestrians`` does (``navzoo.benchmark.pedestrians._make``: the shipped AMP policy,
today's target settings, no robot) and records every path a physics pedestrian is given (at the start and at each
new goal or replan) with the doors the door turns found on it (``navzoo.envs.doors.path_doors`` with the run's
settings, ``NavEnv._update_door_turns``). At the end, a path *crosses* a door when the polyline from the person to
the path's end passes within ``CROSS_M`` of the centre of a door the door turns registered during the run (from
anyone's path), not within ``END_M`` of either end of the path (the door turns leave those out on purpose). A
crossing is *missed* when the path's own door list has no door within ``MERGE_M`` of that centre. For each missed
crossing it also says whether the jamb search (``jamb_search=0.3``) or the run scan (``run_scan=True``) would have
found it on that path. Prints the counts and the missed paths (time, person, start); ``--json`` writes them too.

A static check of the door detection on the paths a crowd really walks (``scripts/door_jamb_scan.py`` samples start
and goal pairs instead); what the misses cost is measured by the following protocol.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

CROSS_M = 0.35
END_M = 0.7
MERGE_M = 0.6


def _seg_dist(line: np.ndarray, p: np.ndarray) -> float:
    """Distance (m) from point ``p`` to the polyline ``line`` (K, 2)."""
    if len(line) == 1:
        return float(np.linalg.norm(line[0] - p))
    a, b = line[:-1], line[1:]
    ab = b - a
    t = np.clip(np.einsum("ij,ij->i", p - a, ab) / np.maximum(np.einsum("ij,ij->i", ab, ab), 1e-12), 0.0, 1.0)
    return float(np.min(np.linalg.norm(a + t[:, None] * ab - p, axis=1)))


def crossings(line: np.ndarray, centres: np.ndarray) -> list[int]:
    """Indices of the door ``centres`` (D, 2) that the polyline ``line`` (K, 2) passes within ``CROSS_M`` of, away from
    its two ends (``END_M``)."""
    out = []
    for i, c in enumerate(centres):
        if min(np.linalg.norm(c - line[0]), np.linalg.norm(c - line[-1])) < END_M:
            continue
        if _seg_dist(line, c) < CROSS_M:
            out.append(i)
    return out


def _has(doors: list, centre: np.ndarray) -> bool:
    """Whether one of ``doors`` (centres) is within ``MERGE_M`` of ``centre``."""
    return any(np.linalg.norm(np.asarray(x) - centre) < MERGE_M for x in doors)


def misses(records: list[dict], centres: np.ndarray) -> dict:
    """Counts of ``records`` (each: ``line`` (K, 2), ``found`` list of door centres, ``jamb`` / ``scan`` the same with
    the jamb search / the run scan, ``t``, ``person``) against the registered door ``centres``."""
    n_cross = n_miss = by_jamb = by_scan = 0
    missed = []
    for r in records:
        for i in crossings(np.asarray(r["line"]), centres):
            n_cross += 1
            c = centres[i]
            if _has(r["found"], c):
                continue
            n_miss += 1
            j, s = _has(r["jamb"], c), _has(r["scan"], c)
            by_jamb += j
            by_scan += s
            missed.append({"t": r["t"], "person": r["person"], "start": [round(float(v), 2) for v in r["line"][0]],
                           "door": [round(float(v), 2) for v in c], "jamb_search_finds": bool(j), "run_scan_finds": bool(s)})
    return {"paths": len(records), "crossings": n_cross, "missed": n_miss, "jamb_search_finds": by_jamb,
            "run_scan_finds": by_scan, "missed_paths": missed}


def run(scene: str, people: int, crowd: str, seconds: float, seed: int) -> dict:
    from navzoo.benchmark import pedestrians as P
    from navzoo.envs import nav_env
    from navzoo.envs.doors import path_doors
    from navzoo.torch_threads import one_torch_thread

    records: list[dict] = []
    original = nav_env.NavEnv._update_door_turns
    real_path_doors = nav_env.path_doors

    def spy(self, t: float = 0.0):
        R = self.n_robots
        changed = [j for j in range(self.n_humans) if self._door_paths[j] is not self.paths[R + j]]
        seen: list[tuple] = []

        def recording(path, start, grid, **kw):
            doors = real_path_doors(path, start, grid, **kw)
            seen.append((path, start, kw, doors))
            return doors

        nav_env.path_doors = recording
        try:
            out = original(self, t)
        finally:
            nav_env.path_doors = real_path_doors
        for j, (path, start, kw, doors) in zip(changed, seen, strict=True):
            base = {k: v for k, v in kw.items() if k not in ("jamb_search", "run_scan")}
            records.append({
                "t": round(float(self.sim_time), 2), "person": j,
                "line": np.concatenate([np.asarray(start, dtype=float).reshape(1, 2), np.asarray(path).reshape(-1, 2)]),
                "found": [c for c, _, _ in doors],
                "jamb": [c for c, _, _ in path_doors(path, start, grid=self.grid, jamb_search=0.3, **base)],
                "scan": [c for c, _, _ in path_doors(path, start, grid=self.grid, run_scan=True, **base)],
            })
        return out

    nav_env.NavEnv._update_door_turns = spy
    try:
        with one_torch_thread():
            wrapped, env = P._make(scene, people, "amp", seconds, seed, None, crowd, None)
            if env.door_turns is None:
                wrapped.close()
                raise SystemExit(f"{scene}: door turns are off in this run (NavConfig.human_door_turns)")
            while not env._needs_reset:
                wrapped.step({})
            centres = env.door_turns.centres.copy()
            wrapped.close()
    finally:
        nav_env.NavEnv._update_door_turns = original
    return {"scene": scene, "people": people, "crowd": crowd, "seconds": seconds, "seed": seed,
            "doors": [[round(float(v), 2) for v in c] for c in centres], **misses(records, centres)}


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--scene", default="doorway")
    ap.add_argument("--people", type=int, default=13)
    ap.add_argument("--crowd", default="diffusion", choices=("sfm", "orca", "diffusion"))
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--seconds", type=float, default=100.0)
    ap.add_argument("--const", action="append", default=[], metavar="NAME=VALUE",
                    help="upper-case numeric or boolean constant of navzoo.envs.amp_humans, repeatable")
    ap.add_argument("--json", default=None, help="write the result here too")
    args = ap.parse_args(argv)
    if args.people < 1 or not args.seconds > 0:
        ap.error("--people must be >= 1 and --seconds > 0")
    sys.path.insert(0, str(Path(__file__).resolve().parent))
    from amp_stand_trace import apply_const

    try:
        consts = apply_const(args.const)
    except ValueError as e:
        ap.error(str(e))
    r = {**run(args.scene, args.people, args.crowd, args.seconds, args.seed), "const": consts}
    print(f"{r['scene']} ({r['people']} people, {r['crowd']}, seed {r['seed']}, {r['seconds']:g} s): {r['paths']} paths, "
          f"{r['crossings']} door crossings, {r['missed']} without their door (the jamb search finds "
          f"{r['jamb_search_finds']}, the run scan {r['run_scan_finds']})")
    for m in r["missed_paths"]:
        print(f"  t {m['t']} s, person {m['person']} from {m['start']}: door {m['door']} "
              f"(jamb search {'finds' if m['jamb_search_finds'] else 'misses'}, "
              f"run scan {'finds' if m['run_scan_finds'] else 'misses'})")
    if args.json:
        Path(args.json).write_text(json.dumps(r, indent=1) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
