"""Closed-loop crowds without a robot: goals reached, speed and overlaps per crowd model.

    python scripts/crowd_closed_loop.py diffusion,sfm,orca [--path-weight 0,5,10,20]

Kinematic pedestrians in lobby (12), corridor (10) and home (5) for 60 s each, seed 0. Prints per
run: goals reached, share of (step, pair) with centres closer than 0.6 m (bodies overlapping), mean
speed, wall time. ``--path-weight`` sweeps the diffusion crowd's A* path guidance weight
(``DiffusionCrowd.path_weight``; default: the crowd's own default).
"""

import argparse
import time

import numpy as np

from navzoo.agents.crowd import CrowdPolicy
from navzoo.envs.nav_env import NavEnv
from navzoo.envs.wrappers import FrozenAgents

parser = argparse.ArgumentParser()
parser.add_argument("crowds", nargs="?", default="diffusion,sfm,orca")
parser.add_argument("--path-weight", default=None, help="comma-separated weights for the diffusion crowd")
args = parser.parse_args()
runs = []
for crowd in args.crowds.split(","):
    weights = [float(w) for w in args.path_weight.split(",")] if crowd == "diffusion" and args.path_weight else [None]
    runs += [(crowd, w) for w in weights]
for crowd, weight in runs:
    for scene, n in [("lobby", 12), ("corridor", 10), ("home", 5)]:
        env = NavEnv(scene=scene, n_robots=0, n_humans=n, crowd_model=crowd, time_limit=60.0)
        if weight is not None:
            env.diffusion.path_weight = weight
        w = FrozenAgents(env, lambda a: a.startswith("human_"), CrowdPolicy(crowd))
        w.reset(seed=0)
        t0 = time.time()
        P = []
        while not env._needs_reset:
            w.step({})
            P.append(env.pos.copy())
        P = np.array(P)  # (T, N, 2)
        d = np.linalg.norm(P[:, :, None] - P[:, None], axis=-1)
        iu = np.triu_indices(n, 1)
        close = (d[:, iu[0], iu[1]] < 0.6).mean()
        sp = np.linalg.norm(np.diff(P, axis=0), axis=-1) / env.config.dt
        label = crowd if weight is None else f"{crowd}(path_weight={weight:g})"
        print(f"{label:28s} {scene:9s} goals {int(env.goals_reached.sum()):3d}  pair-overlap share {close:.4f}  "
              f"mean speed {sp.mean():.2f}  {time.time() - t0:.0f}s", flush=True)
        w.close()
