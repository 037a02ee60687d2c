"""How fast do physics pedestrians who hold a door go near it, and where do they stand? One run, traced.

    python scripts/door_holders.py --scene doorway --people 13 --seed 5 [--seconds 200] [--crowd diffusion]
        [--centre 8.0,4.0] [--const NAME=VALUE ...] --out F.json
    python scripts/door_holders.py --summary F.json [F2.json.gz ...]

Runs one scene of the following protocol as ``scripts/amp_stand_trace.py`` does (``navzoo.benchmark.pedestrians._make``:
the shipped AMP policy, today's target settings, door turns on) and, every ``--every`` s, records each upright person
who **holds** its next door (door turns' grant) and is within ``--reach`` m of the door at ``--centre`` (the doorway's
1.0 m door by default), outside its throat (more than ``THROAT_M`` from the door's wall line along the crossing):

- ``speed``: the body's speed over the sample interval; ``target_speed``: that of its target point
  (``env.amp.target_now()``, held at most ``LAG_LIMIT_S`` ahead of the body);
- ``rollout_pace``: the pace of the person's target path over its next second (``env.amp.waypoints()``, points 0.5 s
  apart): what the target rollout plans, before the body holds it back;
- ``plan_pace``: with diffusion targets, how far the person's diffusion plan moves in the next second;
- ``along`` / ``right``: the person's position in the door's frame: along its crossing (negative before the
  centre) and to the right of the crossing direction (m);
- ``near_1_2``: how many other upright people are within 1.2 m.

The same is recorded for people without a door turn more than 3 m from the door (``zone`` "open") as a reference.
``--summary`` prints the medians of both zones and the most visited 0.5 m cells of the door's frame with their
medians: a holder that stands pressed against the wall beside the opening shows as a busy cell at ``along`` -0.5
and ``right`` +0.5 to +1.0 with a slow body. ``--const NAME=VALUE`` sets an upper-case constant of
``navzoo.envs.amp_humans`` for the run (e.g. ``--const DOOR_LINE_UP=0.35``). A diagnostic of one seed.
"""

from __future__ import annotations

import argparse
import collections
import json
import sys
import time
from pathlib import Path

import numpy as np

THROAT_M = 0.3
OPEN_M = 3.0


def trace(scene: str, people: int, crowd: str, seconds: float, seed: int, centre: np.ndarray, reach: float,
          every: float) -> dict:
    sys.path.insert(0, str(Path(__file__).resolve().parent))
    from amp_stand_trace import door_state, sample_interval, sampled_run

    from navzoo.benchmark import pedestrians as P
    from navzoo.torch_threads import one_torch_thread

    rows: list[dict] = []
    t0 = time.time()
    with one_torch_thread():
        wrapped, env = P._make(scene, people, "amp", seconds, seed, None, crowd, None)
        if env.door_turns is None:
            raise SystemExit("door turns are off in this run: nobody holds a door")
        h = np.arange(env.n_robots, env.n_total)
        dt_s = sample_interval(env, every)
        for pos, _, speed, tgt_speed in sampled_run(wrapped, env, h, dt_s):
            wps = env.amp.waypoints()
            pace = np.linalg.norm(wps[:, 2] - wps[:, 0], axis=1)  # two 0.5 s steps: metres in one second
            plan = None
            if env.diffusion is not None:
                now = env.diffusion._plans_at(env.sim_time)[:, 0]
                plan = np.linalg.norm(env.diffusion._plans_at(env.sim_time + 1.0)[:, 0] - now, axis=1)
            upright = ~env.human_fallen
            d_all = np.linalg.norm(pos[:, None] - pos[None], axis=2)
            np.fill_diagonal(d_all, np.inf)
            d_all[:, ~upright] = np.inf
            turns = env.door_turns
            for j in np.flatnonzero(upright):
                state = door_state(turns, j, pos[j])
                dist = float(np.linalg.norm(pos[j] - centre))
                zone = None
                cur = int(turns._cur[j])
                if state.get("door_state") == "held" and dist <= reach and abs(state["door_m"] - dist) < 0.15:
                    ax = turns.axes[cur] * turns._sign[j]
                    along = float((pos[j] - centre) @ ax)
                    right = float((pos[j] - centre) @ np.array([ax[1], -ax[0]]))
                    if abs(along) >= THROAT_M:
                        zone = "door"
                elif dist > OPEN_M and state.get("door_state") in ("none", "free"):
                    zone, along, right = "open", None, None
                if zone is None:
                    continue
                rows.append({"t": round(float(env.sim_time), 2), "id": int(j), "zone": zone,
                             "speed": float(speed[j]), "target_speed": float(tgt_speed[j]),
                             "rollout_pace": float(pace[j]), "plan_pace": None if plan is None else float(plan[j]),
                             "along": along, "right": right, "near_1_2": int((d_all[j] < 1.2).sum())})
        goals = int(env.goals_reached[h].sum())
        wrapped.close()
    return {"scene": scene, "people": people, "crowd": crowd, "seed": seed, "seconds": seconds,
            "centre": [float(v) for v in centre], "reach": reach, "every_s": dt_s, "goals": goals,
            "wall_s": round(time.time() - t0, 1), "rows": rows}


def summarize(runs: list[dict], cells: int = 10) -> dict:
    """Medians by zone, and the ``cells`` most visited 0.5 m cells of the door's frame (holders)."""
    keys = ("speed", "target_speed", "rollout_pace", "plan_pace")

    def medians(rows):
        out = {"samples": len(rows)}
        for k in keys:
            v = [r[k] for r in rows if r[k] is not None]
            out[k] = round(float(np.median(v)), 3) if v else None
        return out

    rows = [r for run in runs for r in run["rows"]]
    out = {"runs": len(runs), "goals": sum(run["goals"] for run in runs),
           "zones": {z: medians([r for r in rows if r["zone"] == z]) for z in ("door", "open")}}
    grid = collections.defaultdict(list)
    for r in rows:
        if r["zone"] == "door":
            grid[(round(r["along"] * 2) / 2, round(r["right"] * 2) / 2)].append(r)
    top = sorted(grid.items(), key=lambda kv: -len(kv[1]))[:cells]
    out["cells"] = [{"along": k[0], "right": k[1], **medians(v)} for k, v in top]
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--scene", default="doorway")
    ap.add_argument("--people", type=int, default=13)
    ap.add_argument("--crowd", default="diffusion", help="target generator: sfm or diffusion")
    ap.add_argument("--seconds", type=float, default=200.0)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--every", type=float, default=0.5, help="sample interval (s)")
    ap.add_argument("--centre", default="8.0,4.0", help="the door's centre X,Y (m); default: the doorway's door")
    ap.add_argument("--reach", type=float, default=1.6, help="holders within this distance of the centre (m)")
    ap.add_argument("--const", action="append", default=[], metavar="NAME=VALUE",
                    help="an upper-case constant of navzoo.envs.amp_humans for the run")
    ap.add_argument("--out", default=None, help="JSON result (rows and summary)")
    ap.add_argument("--summary", nargs="+", default=None, metavar="F.json", help="print the summary of earlier --out files")
    args = ap.parse_args()
    sys.path.insert(0, str(Path(__file__).resolve().parent))
    if args.summary:
        from amp_stand_trace import load_trace

        print(json.dumps(summarize([load_trace(f) for f in args.summary]), indent=1))
        return
    if not args.out:
        ap.error("--out is required for a run")
    try:
        centre = np.array([float(v) for v in args.centre.split(",")])
        assert centre.shape == (2,) and np.isfinite(centre).all()
    except (ValueError, AssertionError):
        ap.error(f"--centre must be X,Y in metres, got {args.centre!r}")
    from amp_stand_trace import apply_const

    try:
        consts = apply_const(args.const)
    except ValueError as e:
        ap.error(str(e))
    result = trace(args.scene, args.people, args.crowd, args.seconds, args.seed, centre, args.reach, args.every)
    result["const"] = consts
    result["summary"] = summarize([result])
    Path(args.out).write_text(json.dumps(result))
    print(json.dumps(result["summary"], indent=1))


if __name__ == "__main__":
    main()
