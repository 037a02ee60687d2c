"""How a one-person door's time is spent, from traces of ``scripts/amp_stand_trace.py`` (door turns on).

    python scripts/amp_stand_trace.py --scene doorway --people 13 --crowd diffusion --seed 0 --out T.json
    python scripts/door_flow.py T.json [T2.json ...] [--centre 8.0,4.0] [--normal 1,0] [--json]

The door is given by its centre and the normal of its wall (the direction people cross it in; the defaults are the
``doorway`` scene's 1.0 m door). From the trace's samples (every upright person every ``every_s`` seconds) it
counts, per trace and pooled:

- ``crossings``: a person goes from one side of the door to the other through it (a side is more than ``--side`` m
  from the centre along the normal), and ``per_min`` of them;
- ``busy``: the share of sample times with someone in the door (within ``--depth`` m of the centre along the normal
  and ``--half-width`` m across it);
- ``held``: the share with the door granted to someone (``door_state`` "held" for this door), ``held_empty`` the
  share of those times with nobody in the door (the holder is on its way, or stands elsewhere), ``waits`` the share
  with someone waiting for this door, ``waits_empty`` those with nobody in the door;
- ``dwell_s``: the median time from entering the door to reaching the other side, per crossing;
- ``holder_standing``: the share of the holders' time that they stand (slower than the trace's ``still_mps``);
- ``unturned``: of the samples within ``--reach`` m of the door whose goal lies on the other side of the door's
  line, the share with no door turn at all (``door_state`` "none": the door turns found no door on the person's
  path, so it neither asks for the door nor waits for it). Meant for a door in a wall across the whole scene (the
  doorway), where every such person must cross this door; traces without ``goal`` fields give None.

A person's samples belong to this door when its next door's distance (``door_m``) is its distance to ``--centre``
(within ``SAME_DOOR_M``: door turns place a door's centre on the people's paths, a few centimetres off the scene's).
A diagnostic of where a door's throughput goes; it does not say why the bodies act so.
"""

from __future__ import annotations

import argparse
import collections
import json
import sys

import numpy as np

SAME_DOOR_M = 0.15

def _pair(text: str, name: str) -> np.ndarray:
    try:
        v = np.array([float(x) for x in text.split(",")], dtype=float)
    except ValueError:
        raise SystemExit(f"{name} {text!r}: expected two comma-separated numbers") from None
    if v.shape != (2,) or not np.isfinite(v).all():
        raise SystemExit(f"{name} {text!r}: expected two comma-separated finite numbers")
    return v


def flow(trace: dict, centre: np.ndarray, normal: np.ndarray, depth: float = 0.75, half_width: float = 0.7,
         side: float = 0.5, reach: float = 2.5) -> dict:
    """The door figures of one trace (see the module's docstring); ``counts`` holds the sums for pooling."""
    samples, dt, still = trace["samples"], float(trace["every_s"]), float(trace["still_mps"])
    n = normal / np.linalg.norm(normal)
    lateral = np.array([-n[1], n[0]])
    by_t: dict[float, list[dict]] = collections.defaultdict(list)
    by_id: dict[int, list[dict]] = collections.defaultdict(list)
    for s in samples:
        by_t[s["t"]].append(s)
        by_id[s["id"]].append(s)

    def along(s) -> float:
        return float((np.array([s["x"], s["y"]]) - centre) @ n)

    def inside(s) -> bool:
        d = np.array([s["x"], s["y"]]) - centre
        return abs(float(d @ n)) < depth and abs(float(d @ lateral)) < half_width

    def this_door(s) -> bool:
        m = s.get("door_m")
        return m is not None and abs(m - float(np.linalg.norm(np.array([s["x"], s["y"]]) - centre))) < SAME_DOOR_M

    c = collections.Counter()
    for t in sorted(by_t):
        here = by_t[t]
        busy = any(inside(s) for s in here)
        held = any(s.get("door_state") == "held" and this_door(s) for s in here)
        waits = any(s.get("door_state") == "waits" and this_door(s) for s in here)
        c["times"] += 1
        c["busy"] += busy
        c["held"] += held
        c["held_empty"] += held and not busy
        c["waits"] += waits
        c["waits_empty"] += waits and not busy
    dwell = []
    for ss in by_id.values():
        ss.sort(key=lambda s: s["t"])
        last_side, entered = 0, None
        for s in ss:
            if inside(s) and entered is None:
                entered = s["t"]
            a = along(s)
            now = -1 if a < -side else 1 if a > side else 0
            if now:
                if last_side and now != last_side and entered is not None:  # from one side to the other through it
                    c["crossings"] += 1
                    dwell.append(s["t"] - entered)
                last_side, entered = now, None
    for s in samples:
        if s.get("door_state") == "held" and this_door(s):
            c["holder"] += 1
            c["holder_standing"] += s["speed"] < still
        if "goal" in s and np.hypot(s["x"] - centre[0], s["y"] - centre[1]) < reach:
            g = float((np.asarray(s["goal"], dtype=float) - centre) @ n)
            if g * along(s) < 0:  # its goal is across the door's line
                c["across"] += 1
                c["unturned"] += s.get("door_state") == "none"
    seconds = c["times"] * dt
    return {"goals": trace.get("goals"), "seed": trace.get("seed"), "crowd": trace.get("crowd"),
            **_rates(c, seconds), "dwell_s": float(np.median(dwell)) if dwell else None,
            "counts": dict(c), "dwell": dwell, "seconds": seconds}


def _rates(c: collections.Counter, seconds: float) -> dict:
    times = max(c["times"], 1)
    return {"crossings": c["crossings"], "per_min": round(c["crossings"] / max(seconds, 1e-9) * 60.0, 2),
            **{k: round(c[k] / times, 3) for k in ("busy", "held", "held_empty", "waits", "waits_empty")},
            "holder_standing": round(c["holder_standing"] / max(c["holder"], 1), 3),
            "unturned": round(c["unturned"] / c["across"], 3) if c["across"] else None}


def pooled(rows: list[dict]) -> dict:
    """The figures of several traces together (sums of their counts; the median dwell over all crossings)."""
    c = collections.Counter()
    for r in rows:
        c.update(r["counts"])
    dwell = [d for r in rows for d in r["dwell"]]
    return {"traces": len(rows), "goals": sum(r["goals"] or 0 for r in rows),
            **_rates(c, sum(r["seconds"] for r in rows)), "dwell_s": float(np.median(dwell)) if dwell else None}


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("traces", nargs="+", help="JSON files of scripts/amp_stand_trace.py")
    ap.add_argument("--centre", default="8.0,4.0", help="the door's centre, x,y (m; default: the doorway's door)")
    ap.add_argument("--normal", default="1,0", help="the direction people cross the door in, x,y")
    ap.add_argument("--depth", type=float, default=0.75, help="m along the normal that count as in the door")
    ap.add_argument("--half-width", type=float, default=0.7, help="m across that count as in the door")
    ap.add_argument("--side", type=float, default=0.5, help="m along the normal beyond which a person is on a side")
    ap.add_argument("--reach", type=float, default=2.5, help="m from the centre within which 'unturned' counts")
    ap.add_argument("--json", action="store_true", help="one JSON line per trace and one for the pool")
    args = ap.parse_args(argv)
    centre, normal = _pair(args.centre, "--centre"), _pair(args.normal, "--normal")
    if np.linalg.norm(normal) == 0:
        raise SystemExit("--normal must not be zero")
    for name in ("depth", "half_width", "side", "reach"):
        if not (np.isfinite(getattr(args, name)) and getattr(args, name) > 0):
            raise SystemExit(f"--{name.replace('_', '-')} must be a finite number > 0")
    rows = []
    for path in args.traces:
        try:
            with open(path) as f:
                trace = json.load(f)
            rows.append(flow(trace, centre, normal, args.depth, args.half_width, args.side, args.reach))
        except (OSError, ValueError, KeyError) as e:
            raise SystemExit(f"{path}: not a trace of scripts/amp_stand_trace.py ({e})") from None
        rows[-1]["file"] = path
    keys = ("crossings", "per_min", "busy", "held", "held_empty", "waits", "waits_empty", "dwell_s", "holder_standing",
            "unturned")
    groups: dict[str, list[dict]] = collections.defaultdict(list)
    for r in rows:
        groups[str(r["crowd"])].append(r)
    if args.json:
        for r in rows:
            print(json.dumps({k: v for k, v in r.items() if k not in ("counts", "dwell")}))
        for crowd, rs in groups.items():
            print(json.dumps({"pooled": crowd, **pooled(rs)}))
        return 0
    print("| trace | goals | " + " | ".join(keys) + " |")
    print("|---|---|" + "---|" * len(keys))
    for r in rows:
        print(f"| {r['file']} | {r['goals']} | " + " | ".join(str(r[k]) for k in keys) + " |")
    for crowd, rs in groups.items():
        p = pooled(rs)
        print(f"| pooled: {crowd}, {p['traces']} traces | {p['goals']} | " + " | ".join(str(p[k]) for k in keys) + " |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
