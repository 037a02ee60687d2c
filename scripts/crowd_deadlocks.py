"""Trips of the kinematic crowd with and without turn-taking (NavConfig.human_yielding).

    python scripts/crowd_deadlocks.py [--seconds 200] [--crowd sfm|orca|diffusion] [--scenes station,home,...]

Runs the pedestrian-following scenes of ``navzoo eval pedestrians`` (3-15 pedestrians, no robot)
with kinematic pedestrians, once with turn-taking off and once on, and prints a Markdown table of
goals reached, trips that timed out (longer than 2 x shortest path / preferred speed + 10 s, the
same rule as the AMP following evaluation) and people frozen for more than 10 s at the end.
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from navzoo.agents.crowd import CrowdPolicy
from navzoo.benchmark.pedestrians import SCENES, people_per_scene, remaining_path_length
from navzoo.envs.nav_env import NavEnv
from navzoo.envs.wrappers import FrozenAgents


def trips(scene: str, n: int, seconds: float, crowd: str, yielding: bool, seed: int = 0) -> dict[str, int]:
    env = NavEnv(scene=scene, n_robots=0, n_humans=n, crowd_model=crowd, time_limit=seconds, human_yielding=yielding)
    w = FrozenAgents(env, lambda a: a.startswith("human_"), CrowdPolicy(crowd))
    w.reset(seed=seed)
    start = np.zeros(n)
    limit = 2.0 * env.shortest_path_length / env.v_pref + 10.0
    goals = env.goals_reached.copy()
    still = np.zeros(n)
    out = {"goals": 0, "timeouts": 0}
    while not env._needs_reset:
        w.step({})
        t = env.sim_time
        at = env.goals_reached > goals
        late = ~at & (t - start > limit)
        for j in np.flatnonzero(at | late):
            out["goals" if at[j] else "timeouts"] += 1
            start[j] = t
            limit[j] = 2.0 * remaining_path_length(env, j) / env.v_pref[j] + 10.0
        goals = env.goals_reached.copy()
        still = np.where(np.linalg.norm(env.vel, axis=1) < 0.05, still + env.config.dt, 0.0)
    w.close()
    out["frozen_at_end"] = int((still > 10.0).sum())
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seconds", type=float, default=200.0)
    ap.add_argument("--crowd", default="sfm", choices=["sfm", "orca", "diffusion"])
    ap.add_argument("--scenes", default=",".join(SCENES))
    args = ap.parse_args()
    scenes = args.scenes.split(",")
    counts = dict(zip(SCENES, people_per_scene(len(SCENES)), strict=True))
    t0 = time.time()
    print("| scene | people | goals off | timeouts off | frozen off | goals on | timeouts on | frozen on |")
    print("|---|---|---|---|---|---|---|---|")
    tot = np.zeros(6, dtype=int)
    for s in scenes:
        n = counts.get(s, 5)
        off = trips(s, n, args.seconds, args.crowd, False)
        on = trips(s, n, args.seconds, args.crowd, True)
        row = [off["goals"], off["timeouts"], off["frozen_at_end"], on["goals"], on["timeouts"], on["frozen_at_end"]]
        tot += row
        print(f"| {s} | {n} | " + " | ".join(str(v) for v in row) + " |", flush=True)
    print("| all | | " + " | ".join(str(v) for v in tot) + " |")
    print(f"\n{args.crowd} crowd, {args.seconds:.0f} s per scene, seed 0; {time.time() - t0:.0f} s wall")


if __name__ == "__main__":
    main()
