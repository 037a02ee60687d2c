"""Which part of a physics pedestrian touches the walls, and where: one scene of the following protocol, traced.

    python scripts/amp_wall_contact_links.py --scene doorway --people 13 [--crowd sfm|diffusion] [--seed 0] \
        [--seconds 200] [--set NAME=VALUE ...] [--out F.json]
    python scripts/amp_wall_contact_links.py --summary A.json B.json ...

Runs one scene as ``navzoo eval pedestrians`` does (``navzoo.benchmark.pedestrians._make``: the shipped AMP
policy, today's target settings, no robot) and, at every env step, asks PyBullet which links of each standing
body touch a scene obstacle (wall or furniture). A *contact event* is a run of steps in which one person
touches an obstacle, with gaps shorter than ``GAP_S`` (0.5 s) bridged (contacts flicker from step to step). Each event records, at its first step:

- ``first_links`` / ``links``: the body parts touching at the first step / at any step of the event (``pelvis``,
  ``chest``, ``head``, ``upper_arm``, ``forearm``, ``hand``, ``thigh``, ``shin``, ``foot``);
- ``width_m``: the free width across the person's direction of motion, measured from the pelvis (rays of at most
  ``MAX_SIDE_M`` each side against the scene's obstacles), and ``passage``: ``door`` below ``DOOR_M``, ``passage``
  below ``PASSAGE_M``, else ``open``;
- ``pelvis_wall_m`` / ``target_wall_m``: the distance of the pelvis / of the person's target point from the
  nearest obstacle edge (``Scene.clearance``): what the body keeps from walls against what its target keeps;
- ``corner_m``: the distance of the first contact point from the nearest exposed corner of an obstacle (a door
  jamb's end, a shelf's corner: ``Scene.exposed_corners``), and ``where``:
  ``corner`` within ``CORNER_M`` of one, else ``wall`` (along a flat side);
- ``body_off_m``: how far the pelvis is from the middle of that width; ``target_off_m``: the same for the person's
  target point (``env.amp.target_now()``), measured across the same direction;
- ``side_m`` / ``ahead_m``: where the first contact point lies from the pelvis, across and along the direction
  of motion;
- ``people_1m``: other people within 1 m; ``speed``: the body's speed over the last 0.2 s; ``target_speed``: the
  pace its target asks for over the next 0.5 s (target point to the first observed point); ``target_m``: pelvis to
  target point; ``goal_m``: pelvis to the person's current goal; ``fall``: the person fell during the event or
  within 2 s after it.

The summary (printed, and under ``summary`` of ``--out``) counts events per passage class and per place (corner
or flat side), the share of events
whose first contact includes each body part, the medians of the offsets, and the body's speed at the first step
(quartiles, and the share below ``SLOW``; of those slow events, the share whose target stands too, the share near
the goal, their median distance to the target and the share with someone within 1 m). It says where bodies touch, not
why a policy acts; the counts depend on the seed.
"""

from __future__ import annotations

import argparse
import json
import time
from collections import Counter
from pathlib import Path

import numpy as np

from navzoo.envs.config import parse_overrides

LINK_PART = {"base": "pelvis", "root": "pelvis", "chest": "chest", "neck": "head",
             "right_shoulder": "upper_arm", "left_shoulder": "upper_arm", "right_elbow": "forearm",
             "left_elbow": "forearm", "right_wrist": "hand", "left_wrist": "hand", "right_hip": "thigh",
             "left_hip": "thigh", "right_knee": "shin", "left_knee": "shin", "right_ankle": "foot",
             "left_ankle": "foot"}
PARTS = ("pelvis", "chest", "head", "upper_arm", "forearm", "hand", "thigh", "shin", "foot")
DOOR_M = 1.2
PASSAGE_M = 2.0
MAX_SIDE_M = 3.0
GAP_S = 0.5
RAY_STEP_M = 0.02
FALL_AFTER_S = 2.0
CORNER_M = 0.25
SLOW = 0.3  # m/s: a body below this speed at an event's first step counts as slow (``share_slow``)
NEAR_GOAL_M = 1.0  # m: a slow event this close to the person's goal counts as near it


def side_distances(clearance, point: np.ndarray, direction: np.ndarray) -> tuple[float, float]:
    """Free distance from ``point`` to the left and to the right of the unit ``direction`` (2,), each capped at
    ``MAX_SIDE_M``: the first ray sample whose ``clearance`` (a function of (N, 2) points, as
    ``Scene.clearance``) is at most half a ray step."""
    left = np.array([-direction[1], direction[0]])
    t = np.arange(RAY_STEP_M, MAX_SIDE_M + 1e-9, RAY_STEP_M)
    out = []
    for sign in (1.0, -1.0):
        c = clearance(point[None] + sign * t[:, None] * left[None])
        hit = np.flatnonzero(c <= RAY_STEP_M / 2)
        out.append(float(t[hit[0]]) if hit.size else MAX_SIDE_M)
    return out[0], out[1]


def passage_class(width: float) -> str:
    return "door" if width < DOOR_M else "passage" if width < PASSAGE_M else "open"


def off_centre(clearance, point: np.ndarray, direction: np.ndarray) -> float:
    """Distance of ``point`` from the middle of the free width across ``direction`` (m, >= 0)."""
    lft, rgt = side_distances(clearance, point, direction)
    return abs(lft - rgt) / 2.0


def events_from_steps(touching: list[dict[int, frozenset]], gap: int = 0) -> list[tuple[int, int, int]]:
    """``touching[k]`` maps each person touching an obstacle at step ``k`` to its touching parts. Returns the
    contact events as (person, first step, last step), ordered by first step then person; two runs of one
    person separated by at most ``gap`` steps without contact are one event."""
    open_: dict[int, list[int]] = {}  # person -> [first step, last step with contact]
    events = []
    for k, step in enumerate(touching + [{}] * (gap + 1)):
        for j in [j for j, (_, last) in open_.items() if j not in step and k - last > gap]:
            first, last = open_.pop(j)
            events.append((j, first, last))
        for j in step:
            open_.setdefault(j, [k, k])[1] = k
    return sorted(events, key=lambda e: (e[1], e[0]))


def _slow_split(slow: list[dict]) -> dict:
    """Of the slow events: the share whose target stands too (``target_speed`` below ``SLOW``), the share within
    ``NEAR_GOAL_M`` of the goal, the median distance to the target and the share with someone within 1 m (files from
    before these fields: {})."""
    if not slow or "target_speed" not in slow[0]:
        return {}
    return {"slow_share_target_still": round(float(np.mean([e["target_speed"] < SLOW for e in slow])), 3),
            "slow_share_near_goal": round(float(np.mean([e["goal_m"] < NEAR_GOAL_M for e in slow])), 3),
            "slow_median_target_m": round(float(np.median([e["target_m"] for e in slow])), 3),
            "slow_share_people_1m": round(float(np.mean([e["people_1m"] > 0 for e in slow])), 3)}


def summarize(events: list[dict]) -> dict:
    """Counts and medians over contact events (records as in the module docstring)."""
    out: dict = {"events": len(events)}
    for cls, key in (("door", "passage"), ("passage", "passage"), ("open", "passage"), ("corner", "where"),
                     ("wall", "where"), ("all", None)):
        sel = [e for e in events if key is None or e[key] == cls]
        if not sel:
            continue
        first = Counter(part for e in sel for part in e["first_links"])
        out[cls] = {
            "events": len(sel),
            "first_part_share": {part: round(first[part] / len(sel), 3) for part in PARTS if first[part]},
            "median_pelvis_wall_m": round(float(np.median([e["pelvis_wall_m"] for e in sel])), 3),
            "median_target_wall_m": round(float(np.median([e["target_wall_m"] for e in sel])), 3),
            "share_corner": round(float(np.mean([e["where"] == "corner" for e in sel])), 3),
            "median_body_off_m": round(float(np.median([e["body_off_m"] for e in sel])), 3),
            "median_target_off_m": round(float(np.median([e["target_off_m"] for e in sel])), 3),
            "median_side_m": round(float(np.median([abs(e["side_m"]) for e in sel])), 3),
            "share_ahead": round(float(np.mean([e["ahead_m"] > 0.15 for e in sel])), 3),
            "share_people_1m": round(float(np.mean([e["people_1m"] > 0 for e in sel])), 3),
            "median_duration_s": round(float(np.median([e["duration_s"] for e in sel])), 2),
            "speed_quartiles": [round(float(q), 2) for q in np.quantile([e["speed"] for e in sel], [0.25, 0.5, 0.75])],
            "share_slow": round(float(np.mean([e["speed"] < SLOW for e in sel])), 3),
            **_slow_split([e for e in sel if e["speed"] < SLOW]),
            "falls": int(sum(e["fall"] for e in sel)),
        }
    return out


def trace(scene: str, people: int, crowd: str, seconds: float, seed: int, env_overrides: dict | None = None) -> dict:
    import pybullet as p

    from navzoo.benchmark import pedestrians as P
    from navzoo.envs.amp_humans import WAYPOINT_DT
    from navzoo.torch_threads import one_torch_thread

    with one_torch_thread():
        wrapped, env = P._make(scene, people, "amp", seconds, seed, None, crowd, env_overrides)
        h = np.arange(env.n_robots, env.n_total)
        ids, client = env.amp.ids, env.amp.client
        names = {-1: "pelvis"} | {i: LINK_PART[p.getJointInfo(ids[0], i, physicsClientId=client)[12].decode()]
                                  for i in range(p.getNumJoints(ids[0], physicsClientId=client))}
        corners = env.scene.exposed_corners()
        hz = 1.0 / env.config.dt
        back = max(int(round(0.2 * hz)), 1)
        touching: list[dict[int, frozenset]] = []
        first: dict[tuple[int, int], dict] = {}
        pos_hist: list[np.ndarray] = []
        fell_at: dict[int, int] = {}
        t0 = time.time()
        while not env._needs_reset:
            wrapped.step({})
            k = len(touching)
            pos = env.pos[h].copy()
            pos_hist.append(pos)
            for j in np.flatnonzero(env.human_fallen):
                fell_at.setdefault(int(j), k)
            step: dict[int, frozenset] = {}
            for j in np.flatnonzero(env.human_map_contact & ~env.human_fallen):
                pts = [c for c in p.getContactPoints(bodyA=ids[j], physicsClientId=client)
                       if env._body_kind.get(c[2]) == "obstacle"]
                if not pts:
                    continue
                step[int(j)] = frozenset(names[c[3]] for c in pts)
                prev = touching[-1] if touching else {}
                if int(j) in prev:
                    continue
                tgt = env.amp.target_now()[j]
                moved = pos[j] - pos_hist[max(0, k - back)][j]
                # a standing body (under 2 cm in 0.2 s) faces the direction to its target instead
                move = moved if np.linalg.norm(moved) >= 0.02 else tgt - pos[j]
                d = move / max(np.linalg.norm(move), 1e-9)
                lft, rgt = side_distances(env.scene.clearance, pos[j], d)
                cp = np.array(pts[0][5][:2])
                c0 = cp - pos[j]
                corner = float(np.linalg.norm(corners - cp, axis=1).min()) if len(corners) else np.inf
                others = np.linalg.norm(pos - pos[j], axis=1)
                others[j] = np.inf
                first[(int(j), k)] = {
                    "t": round(float(env.sim_time), 2), "person": int(j), "first_links": sorted(step[int(j)]),
                    "width_m": round(lft + rgt, 2), "passage": passage_class(lft + rgt),
                    "pelvis_wall_m": round(float(env.scene.clearance(pos[j][None])[0]), 3),
                    "body_off_m": round(abs(lft - rgt) / 2, 3),
                    "target_wall_m": round(float(env.scene.clearance(tgt[None])[0]), 3),
                    "corner_m": round(corner, 3) if np.isfinite(corner) else None,
                    "where": "corner" if corner < CORNER_M else "wall",
                    "target_off_m": round(off_centre(env.scene.clearance, tgt, d), 3),
                    "side_m": round(float(c0 @ np.array([-d[1], d[0]])), 3), "ahead_m": round(float(c0 @ d), 3),
                    "people_1m": int((others < 1.0).sum()),
                    "speed": round(float(np.linalg.norm(moved) * hz / back), 2),
                    "target_speed": round(float(np.linalg.norm(env.amp.waypoints()[j, 0] - tgt) / WAYPOINT_DT), 2),
                    "target_m": round(float(np.linalg.norm(tgt - pos[j])), 3),
                    "goal_m": round(float(np.linalg.norm(env.goal[env.n_robots + j] - pos[j])), 2),
                    "pos": pos[j].round(2).tolist(),
                }
            touching.append(step)
        wrapped.close()
    events = []
    for j, k0, k1 in events_from_steps(touching, gap=int(round(GAP_S * hz))):
        e = dict(first[(j, k0)])
        e["links"] = sorted(set().union(*(touching[k].get(j, frozenset()) for k in range(k0, k1 + 1))))
        e["duration_s"] = round((k1 - k0 + 1) / hz, 2)
        e["fall"] = j in fell_at and k0 <= fell_at[j] <= k1 + 1 + FALL_AFTER_S * hz
        events.append(e)
    return {"scene": scene, "people": people, "crowd": crowd, "seconds": seconds, "seed": seed,
            "env_overrides": env_overrides or {}, "wall_s": round(time.time() - t0, 1), "events": events,
            "summary": summarize(events)}


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--scene", default="doorway")
    ap.add_argument("--people", type=int, default=13)
    ap.add_argument("--crowd", default="sfm", choices=("sfm", "orca", "diffusion"))
    ap.add_argument("--seconds", type=float, default=200.0)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--set", dest="env_set", action="append", default=[], metavar="KEY=VALUE",
                    help="a NavConfig field for the run, repeatable (e.g. --set amp_wall_margin=0.2)")
    ap.add_argument("--out", help="write the events and the summary here (JSON)")
    ap.add_argument("--summary", nargs="+", metavar="JSON", help="summarize earlier --out files together")
    args = ap.parse_args(argv)
    if args.summary:
        events = []
        for f in args.summary:
            try:
                events += json.loads(Path(f).read_text())["events"]
            except (OSError, ValueError, KeyError) as err:
                ap.error(f"{f}: not a result file of this script ({err})")
        print(json.dumps(summarize(events), indent=1))
        return 0
    if args.people < 1 or args.seconds <= 0:
        ap.error(f"--people must be >= 1 and --seconds > 0, got {args.people} and {args.seconds}")
    try:
        overrides = parse_overrides(args.env_set)
    except ValueError as err:
        ap.error(str(err))
    result = trace(args.scene, args.people, args.crowd, args.seconds, args.seed, overrides)
    print(json.dumps(result["summary"], indent=1))
    if args.out:
        Path(args.out).write_text(json.dumps(result) + "\n")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
