"""Trips of the kinematic crowd with and without turn-taking (NavConfig.human_yielding) or door turns.

    python scripts/crowd_deadlocks.py [--seconds 200] [--crowd sfm|orca|diffusion] [--scenes station,home,...]
        [--toggle human_yielding|human_door_turns] [--seeds 0,1]

Runs the pedestrian-following scenes of ``navzoo eval pedestrians`` (3-15 pedestrians, no robot)
with kinematic pedestrians, once with the toggled NavConfig flag off and once on (default: turn-taking;
``--toggle human_door_turns`` compares the door turns, turn-taking on in both), per seed, and prints a
Markdown table of goals reached, trips that timed out (longer than 2 x shortest path / preferred speed +
10 s, the same rule as the AMP following evaluation) and people frozen for more than 10 s at the end.
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from navzoo.agents.crowd import CrowdPolicy
from navzoo.benchmark.pedestrians import SCENES, people_per_scene, remaining_path_length
from navzoo.envs.nav_env import NavEnv
from navzoo.envs.wrappers import FrozenAgents


def trips(scene: str, n: int, seconds: float, crowd: str, yielding: bool, seed: int = 0,
          toggle: str = "human_yielding") -> dict[str, int]:
    """Goals, timeouts and frozen people of one run, with NavConfig flag ``toggle`` set to ``yielding``."""
    env = NavEnv(scene=scene, n_robots=0, n_humans=n, crowd_model=crowd, time_limit=seconds, **{toggle: yielding})
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
    ap.add_argument("--toggle", default="human_yielding", choices=["human_yielding", "human_door_turns"])
    ap.add_argument("--seeds", default="0")
    args = ap.parse_args()
    seeds = [int(x) for x in args.seeds.split(",")]
    scenes = args.scenes.split(",")
    counts = dict(zip(SCENES, people_per_scene(len(SCENES)), strict=True))
    t0 = time.time()
    print("| scene | people | seed | goals off | timeouts off | frozen off | goals on | timeouts on | frozen on |")
    print("|---|---|---|---|---|---|---|---|---|")
    tot = np.zeros(6, dtype=int)
    for s in scenes:
        n = counts.get(s, 5)
        for seed in seeds:
            off = trips(s, n, args.seconds, args.crowd, False, seed, args.toggle)
            on = trips(s, n, args.seconds, args.crowd, True, seed, args.toggle)
            row = [off["goals"], off["timeouts"], off["frozen_at_end"], on["goals"], on["timeouts"], on["frozen_at_end"]]
            tot += row
            print(f"| {s} | {n} | {seed} | " + " | ".join(str(v) for v in row) + " |", flush=True)
    print("| all | | | " + " | ".join(str(v) for v in tot) + " |")
    print(f"\n{args.crowd} crowd, {args.toggle} off / on, {args.seconds:.0f} s per scene, seeds {args.seeds}; "
          f"{time.time() - t0:.0f} s wall")


if __name__ == "__main__":
    main()
