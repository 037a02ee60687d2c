"""Why do physics pedestrians time out? Trace who is stuck, next to whom, and who yields.

    python scripts/amp_jam_trace.py [--scene home] [--people 5] [--seconds 60] [--every 5] [--seed 0]

Runs the pedestrian-following setup of ``navzoo eval pedestrians`` (AMP bodies, social-force target
trajectories, no robot) for one scene and prints one JSON line every ``--every`` seconds: per person
its position, whether it has fallen, how long it has made no progress toward its next waypoint
(``TurnTaking.stuck_time``), how often it has yielded, and its nearest other person and the distance
to them. A person stuck alone (nobody within ``YieldParams.reach``) is held by the scene or by a
fallen body, not by a jam that turn-taking could resolve.
"""

from __future__ import annotations

import argparse
import json

import numpy as np

from navzoo.benchmark import pedestrians as P


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--scene", default="home")
    ap.add_argument("--people", type=int, default=5)
    ap.add_argument("--seconds", type=float, default=60.0)
    ap.add_argument("--every", type=float, default=5.0)
    ap.add_argument("--seed", type=int, default=0)
    args = ap.parse_args()
    wrapped, env = P._make(args.scene, args.people, "amp", args.seconds, args.seed, None, "sfm")
    h = np.arange(env.n_robots, env.n_total)
    every = max(int(round(args.every / env.config.dt)), 1)
    reach = env.turn_taking.params.reach if env.turn_taking is not None else None
    k = 0
    while not env._needs_reset:
        wrapped.step({})
        k += 1
        if k % every:
            continue
        pos = env.pos[h]
        d = np.linalg.norm(pos[:, None] - pos[None], axis=2)
        np.fill_diagonal(d, np.inf)
        people = []
        for j in range(len(h)):
            near = int(np.argmin(d[j])) if len(h) > 1 else -1
            people.append({
                "id": j, "pos": pos[j].round(2).tolist(), "fallen": bool(env.human_fallen[j]),
                "stuck_s": round(float(env.turn_taking.stuck_time[j]), 1) if env.turn_taking is not None else None,
                "yields": int(env.turn_taking.yields[j]) if env.turn_taking is not None else None,
                "nearest": near, "nearest_m": round(float(d[j, near]), 2) if near >= 0 else None,
            })
        print(json.dumps({"t": round(float(env.sim_time), 1), "reach_m": reach, "people": people}), flush=True)
    wrapped.close()


if __name__ == "__main__":
    main()
