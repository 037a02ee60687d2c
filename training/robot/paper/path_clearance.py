"""Share of a robot's A* path within 0.9 m (edge to edge) of a wall, in the paper's three training scenes.

The paper's proximity term replaces the progress term wherever the robot is closer than 0.9 m to
anything, walls included; this measures how much of a shortest route that is (docs/env.md).
usage: python training/robot/paper/path_clearance.py [TASKS]
"""

import sys

import numpy as np

import navzoo

tasks = int(sys.argv[1]) if len(sys.argv) > 1 else 20
for env_id in ("navzoo/Station-v0", "navzoo/Home-v0", "navzoo/Grocery-v0"):
    env = navzoo.make(env_id)
    nav = env.unwrapped
    close, ratio = [], []
    for seed in range(tasks):
        env.reset(seed=seed)
        path = nav.paths[0]
        close.append(np.mean(nav.grid.distance_at(path) - nav.radius[0] < 0.9))
        ratio.append(nav.shortest_path_length[0] / np.linalg.norm(nav.goal[0] - nav.pos[0]))
    print(f"{env_id}: {np.mean(close):.0%} of path points within 0.9 m of a wall; path / straight line "
          f"{np.mean(ratio):.2f} ({tasks} tasks)")
    env.close()
