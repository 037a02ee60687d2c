"""Trace the trips that time out or end in a fall in one scene of the following protocol: where, how fast,
next to what.

    python scripts/amp_timeout_trace.py [--scene lobby] [--people 15] [--seconds 200] [--seed 0] \
        [--crowd sfm] [--bodies amp] [--set human_replan_blocked=amp ...]

Runs the pedestrian-following setup of ``navzoo eval pedestrians`` (the trip bookkeeping of
:func:`navzoo.benchmark.pedestrians.follow_scene`: a trip ends at its goal, in a fall or when it takes
longer than 2 x its path / preferred speed + 10 s) and prints one JSON line per ended trip. A timed-out
trip also gets: the person's position, goal and path still ahead (m); its mean speed over the trip and
that of its target point (AMP bodies; the target jumps back to the body at each 2 s replan, which adds
about lag / 2 s to its speed); the shares of the trip's steps spent under 0.25 m/s; the mean distance
between body and target; the nearest other person and the number within 1 m at the end; the shares of
steps with a wall or a person touching the body (AMP bodies); and the distance from the nearest obstacle.
A trip that ends in a fall gets the same, over the last ``--fall-window`` seconds before the fall (2 s; keys
``window_*``), and besides: how many other people were within 1 m over that window at most, whether the wall or
person contact came first in the window (``first_contact``: ``wall``, ``person``, ``both`` or ``none``, and
``first_contact_s`` before the fall).
"""

from __future__ import annotations

import argparse
import json

import numpy as np

from navzoo.benchmark import pedestrians as P


def _value(text: str):
    name, _, value = text.partition("=")
    if not name or not value:
        raise argparse.ArgumentTypeError(f"--set takes NAME=VALUE, got {text!r}")
    for cast in (int, float):
        try:
            return name, cast(value)
        except ValueError:
            pass
    return name, {"true": True, "false": False}.get(value.lower(), value)


def span_stats(pos: np.ndarray, tgt: np.ndarray, wall: np.ndarray, person: np.ndarray, j: int, hz: float) -> dict:
    """Person ``j`` over a span of steps (arrays (steps, people, ...)): its mean speed, the share of steps under
    0.25 m/s, its mean distance to its target, and the shares of steps with a wall or a person touching it."""
    p_, q_ = pos[:, j], tgt[:, j]
    vp = np.linalg.norm(np.diff(p_, axis=0), axis=1) * hz if len(p_) > 1 else np.zeros(1)
    return {"body_speed": round(float(vp.mean()), 2), "body_slow": round(float((vp < 0.25).mean()), 2),
            "lag_m": round(float(np.linalg.norm(p_ - q_, axis=1).mean()), 2),
            "wall_contact": round(float(wall[:, j].mean()), 2), "person_contact": round(float(person[:, j].mean()), 2)}


def fall_record(env, h: np.ndarray, j: int, pos: np.ndarray, tgt: np.ndarray, wall: np.ndarray, person: np.ndarray,
                window: int, hz: float) -> dict:
    """What happened to person ``j`` over the last ``window`` steps before its fall (arrays are (steps, people))."""
    k0 = max(0, len(pos) - window)
    span = span_stats(pos[k0:], tgt[k0:], wall[k0:], person[k0:], j, hz)
    d = np.linalg.norm(pos[k0:] - pos[k0:, j][:, None], axis=2)
    d[:, j] = np.inf
    w, a = wall[k0:, j], person[k0:, j]
    k_wall = int(np.argmax(w)) if w.any() else len(w)  # first step of each contact in the window (len: none)
    k_person = int(np.argmax(a)) if a.any() else len(a)
    k = min(k_wall, k_person)
    if k == len(w):
        kind = "none"
    else:
        kind = "both" if k_wall == k_person else "wall" if k_wall < k_person else "person"
    return {"pos": env.pos[h][j].round(2).tolist(),
            "obstacle_m": round(float(env.grid.distance_at(env.pos[h][j][None])[0]), 2),
            **{f"window_{k}": v for k, v in span.items() if k != "body_slow"},
            "window_nearest_person_m": round(float(d.min()), 2) if d.shape[1] > 1 else None,
            "window_max_within_1m": int((d < 1.0).sum(axis=1).max()),
            "first_contact": kind, "first_contact_s": None if kind == "none" else round((len(w) - k) / hz, 2)}


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--scene", default="lobby")
    ap.add_argument("--people", type=int, default=15)
    ap.add_argument("--seconds", type=float, default=200.0)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--crowd", default="sfm", choices=("sfm", "orca", "diffusion"))
    ap.add_argument("--bodies", default="amp", choices=("amp", "kinematic"))
    ap.add_argument("--fall-window", type=float, default=2.0, help="seconds before a fall that its record covers")
    ap.add_argument("--set", type=_value, action="append", default=[], metavar="NAME=VALUE",
                    help="a NavConfig field for the run (repeatable)")
    args = ap.parse_args(argv)
    if not args.fall_window > 0:
        ap.error(f"--fall-window must be > 0 s, got {args.fall_window}")
    wrapped, env = P._make(args.scene, args.people, args.bodies, args.seconds, args.seed, None, args.crowd,
                           env_overrides=dict(args.set))
    amp = env.amp is not None
    n, R = args.people, env.n_robots
    h = np.arange(R, env.n_total)
    hz = 1.0 / env.config.dt
    trips = P.Trips(env, n)
    pos_h, tgt_h, map_h, agent_h = [], [], [], []
    while not env._needs_reset:
        wrapped.step({})
        target = env.amp.target_now() if amp else env.pos[h]
        fallen = env.human_fallen if amp else np.zeros(n, dtype=bool)
        pos_h.append(env.pos[h].copy())
        tgt_h.append(np.array(target, dtype=float))
        map_h.append(np.array(env.human_map_contact if amp else np.zeros(n), dtype=bool))
        agent_h.append(np.array(env.human_agent_contact if amp else np.zeros(n), dtype=bool))
        for j, outcome, duration, limit in trips.update(np.linalg.norm(env.pos[h] - target, axis=1), fallen):
            rec = {"t": round(env.sim_time, 1), "person": j, "outcome": outcome, "duration_s": round(duration, 1),
                   "limit_s": round(limit, 1)}
            if outcome == "timeout":
                k0 = max(0, len(pos_h) - int(round(duration * hz)))
                span = span_stats(np.array(pos_h[k0:]), np.array(tgt_h[k0:]), np.array(map_h[k0:]),
                                  np.array(agent_h[k0:]), j, hz)
                vq = np.linalg.norm(np.diff(np.array(tgt_h[k0:])[:, j], axis=0), axis=1) * hz
                d = np.linalg.norm(env.pos[h] - env.pos[h][j], axis=1)
                d[j] = np.inf
                rec.update(
                    pos=env.pos[h][j].round(2).tolist(), goal=env.goal[R + j].round(2).tolist(),
                    path_left_m=round(P.remaining_path_length(env, R + j), 2),
                    body_speed=span["body_speed"], target_speed=round(float(vq.mean()), 2),
                    body_slow=span["body_slow"], target_slow=round(float((vq < 0.25).mean()), 2),
                    lag_m=span["lag_m"],
                    nearest_person_m=round(float(d.min()), 2) if n > 1 else None, within_1m=int((d < 1.0).sum()),
                    wall_contact=span["wall_contact"], person_contact=span["person_contact"],
                    obstacle_m=round(float(env.grid.distance_at(env.pos[h][j][None])[0]), 2))
            if outcome == "fall":  # only the window's steps become arrays, not the whole run's
                w = int(round(args.fall_window * hz))
                rec.update(fall_record(env, h, j, np.array(pos_h[-w:]), np.array(tgt_h[-w:]), np.array(map_h[-w:]),
                                       np.array(agent_h[-w:]), w, hz))
            print(json.dumps(rec), flush=True)
    wrapped.close()
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
