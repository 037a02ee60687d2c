"""Do the physics pedestrians' social-force target rollouts stall at the home's 0.9 m doors?

    python scripts/amp_door_stall.py scan [--radii 0.33,0.35,...,0.4]
    python scripts/amp_door_stall.py lone [--scene home] [--seeds 0,1] [--graded 1|0] [--seconds 200]
    python scripts/amp_door_stall.py cost [--toggle GRADED_WALL_MARGIN|PASS_MARGIN] [--scenes home:5,doorway:13]

``scan`` rolls one social-force disc (0.4 m towards people, as the rollouts of ``navzoo.envs.amp_humans``:
1.3 m/s, 2 rad/s turn limit, 0.1 s steps) through the home's middle door (x = 8 m, 0.9 m wide) from 14 starts,
7 on each side at different offsets from the door's axis, for every wall radius given, and prints how many
starts did not get through in 7 s. ``lone`` runs the following protocol's scene with one person
(:func:`navzoo.benchmark.pedestrians.follow_scene`) and prints its trips per outcome, one JSON line per seed,
with the graded wall margin on (1) or off (0). ``cost`` times one replan of all target rollouts
(``AmpHumans.plan_all``) in the home (5 people) and the doorway (13), with the graded margin (or, with
``--toggle PASS_MARGIN``, the pass margin) off and on, twice each (median of 7 replans).
"""

from __future__ import annotations

import argparse
import json

import numpy as np

WEST = ((7.3, ((8.0, 2.95), (9.0, 2.95), (11.0, 2.5))), (11.0, 2.5))
EAST = ((8.7, ((8.0, 2.95), (7.0, 2.9), (3.0, 2.7))), (3.0, 2.7))
OFFSETS = (2.55, 2.7, 2.85, 2.95, 3.05, 3.2, 3.35)


def roll(env, start, waypoints, goal, wall_radius: float, seconds: float = 7.0) -> np.ndarray:
    """End position of one rollout disc heading through ``waypoints`` to ``goal`` in ``env``'s scene."""
    from navzoo.agents.policy import preferred_velocity
    from navzoo.agents.sfm import SocialForceParams, social_force_velocities
    from navzoo.envs.amp_humans import TARGET_TURN_RATE, limit_turn

    params = SocialForceParams()
    pos, vel = np.array([start], dtype=float), np.zeros((1, 2))
    wps, k = [np.asarray(w, dtype=float) for w in waypoints], 0
    for _ in range(int(seconds / 0.1)):
        while k < len(wps) - 1 and np.linalg.norm(wps[k] - pos[0]) < 0.3:
            k += 1
        pref = preferred_velocity(pos, wps[k][None], np.array([goal], dtype=float), np.array([1.3]))
        new = social_force_velocities(pos, vel, pref, np.array([0.4]), np.array([1.8]), 0.1, params, env.segments,
                                      segment_groups=env.segment_groups, wall_radius=np.array([wall_radius]))
        vel = limit_turn(vel, new, TARGET_TURN_RATE * 0.1)
        pos = pos + 0.1 * vel
    return pos[0]


def scan(radii: list[float]) -> None:
    from navzoo.envs.nav_env import NavEnv

    env = NavEnv(scene="home", n_robots=0, n_humans=1)
    env.reset(seed=0)
    for r in radii:
        stalled = 0
        for y0 in OFFSETS:
            for (x0, wps), goal in (WEST, EAST):
                stalled += abs(roll(env, (x0, y0), wps, goal, r)[0] - goal[0]) > 0.5
        print(json.dumps({"wall_radius": r, "stalled": int(stalled), "starts": 2 * len(OFFSETS)}), flush=True)
    env.close()


def lone(scene: str, seeds: list[int], graded: bool, seconds: float) -> None:
    import navzoo.envs.amp_humans as ah
    from navzoo.benchmark.pedestrians import follow_scene

    ah.GRADED_WALL_MARGIN = graded
    for seed in seeds:
        row = follow_scene(scene, 1, seconds, seed, pose_every=0)
        print(json.dumps({"scene": scene, "seed": seed, "graded": graded,
                          **{k: row[k] for k in ("success", "off_path", "fall", "timeout", "map_trips")}}), flush=True)


def cost(toggle: str = "GRADED_WALL_MARGIN", scenes: str = "home:5,doorway:13") -> None:
    import time

    import navzoo.envs.amp_humans as ah
    from navzoo.envs.nav_env import NavEnv

    default = getattr(ah, toggle)
    for item in scenes.split(","):
        scene, people = item.split(":")
        n = int(people)
        env = NavEnv(scene=scene, n_robots=0, n_humans=n, human_model="amp", dt=1.0 / 30.0)
        env.reset(seed=0)
        ms: dict[str, list[float]] = {"off": [], "on": []}
        for on in (False, True, False, True):
            setattr(ah, toggle, on)
            env.amp.plan_all()  # the first replan also finds the paths' narrow points
            times = []
            for _ in range(7):
                t0 = time.perf_counter()
                env.amp.plan_all()
                times.append(time.perf_counter() - t0)
            ms["on" if on else "off"].append(round(1e3 * float(np.median(times)), 1))
        setattr(ah, toggle, default)
        print(json.dumps({"scene": scene, "people": n, "toggle": toggle, "replan_ms": ms}), flush=True)
        env.close()


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    sub = ap.add_subparsers(dest="cmd", required=True)
    s = sub.add_parser("scan")
    s.add_argument("--radii", default="0.33,0.35,0.36,0.37,0.38,0.39,0.4")
    lo = sub.add_parser("lone")
    lo.add_argument("--scene", default="home")
    lo.add_argument("--seeds", default="0,1")
    lo.add_argument("--graded", type=int, choices=(0, 1), default=1)
    lo.add_argument("--seconds", type=float, default=200.0)
    c = sub.add_parser("cost")
    c.add_argument("--toggle", choices=("GRADED_WALL_MARGIN", "PASS_MARGIN"), default="GRADED_WALL_MARGIN",
                   help="the amp_humans switch timed off and on (default: the graded wall margin)")
    c.add_argument("--scenes", default="home:5,doorway:13", help="SCENE:PEOPLE,... (default home:5,doorway:13)")
    args = ap.parse_args(argv)
    if args.cmd == "scan":
        scan([float(r) for r in args.radii.split(",")])
    elif args.cmd == "cost":
        cost(args.toggle, args.scenes)
    else:
        lone(args.scene, [int(s) for s in args.seeds.split(",")], bool(args.graded), args.seconds)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
