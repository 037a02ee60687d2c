"""Time building the scenes in PyBullet and A* planning: the speed figures of docs/scenes.md.

Usage::

    .venv/bin/python scripts/bench_world.py [--repeats 20] [--json]

Prints the median (and 90th percentile) milliseconds of

- ``build_scene`` for every library scene and for a 100-obstacle scene (60 boxes, 30 circles, 10 L-shaped
  polygons in 20 m x 20 m), each build in a fresh PyBullet DIRECT client (connecting is not timed);
- ``AStarPlanner.plan`` across a 200 x 200 grid (0.1 m cells, 0.2 m inflation): an open grid, and a
  zig-zag maze that makes A* expand almost every cell (its worst case).

These timings used to be bounds in unit tests (scene build < 0.5 s, maze plan < 0.5 s); on a loaded 2-core
machine they failed now and then, so speed is measured here and recorded in docs/, and the tests check
behaviour only.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import time

import numpy as np
import pybullet as p

from navzoo.machine import cpu_model
from navzoo.world.builder import build_scene
from navzoo.world.library import get_scene, list_scenes
from navzoo.world.occupancy import OccupancyGrid
from navzoo.world.planner import AStarPlanner
from navzoo.world.scene import Scene, load_scene


def hundred_obstacle_scene() -> Scene:
    rng = np.random.default_rng(0)
    obstacles = [
        {"type": "box", "center": list(rng.uniform(1, 19, 2)), "size": [0.5, 0.5], "yaw": float(rng.uniform(0, 3))}
        for _ in range(60)
    ]
    obstacles += [{"type": "circle", "center": list(rng.uniform(1, 19, 2)), "radius": 0.3} for _ in range(30)]
    ell = np.array([[0, 0], [1, 0], [1, 0.3], [0.3, 0.3], [0.3, 1], [0, 1]])
    obstacles += [{"type": "polygon", "points": (ell + c).tolist()} for c in rng.uniform(1, 18, (10, 2))]
    return load_scene({"name": "many", "bounds": [0, 0, 20, 20], "obstacles": obstacles}, check_reachability=False)


def zigzag_maze(n: int = 200) -> np.ndarray:
    occ = np.zeros((n, n), dtype=bool)
    for k, x in enumerate(range(20, n, 30)):
        if k % 2 == 0:
            occ[0 : n - 20, x : x + 3] = True
        else:
            occ[20:n, x : x + 3] = True
    return occ


def time_build(scene: Scene, repeats: int) -> list[float]:
    times = []
    for _ in range(repeats):
        cid = p.connect(p.DIRECT)
        try:
            t0 = time.perf_counter()
            build_scene(scene, cid)
            times.append(time.perf_counter() - t0)
        finally:
            p.disconnect(physicsClientId=cid)
    return times


def time_plan(occ: np.ndarray, repeats: int) -> list[float]:
    planner = AStarPlanner(OccupancyGrid(occ, 0.1, (0.0, 0.0)), 0.2)
    goal = ((occ.shape[1] - 0.5) * 0.1, (occ.shape[0] - 0.5) * 0.1)
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        path = planner.plan((0.05, 0.05), goal)
        times.append(time.perf_counter() - t0)
        if path is None:
            raise RuntimeError("the benchmark grid has no path: the maze generator is broken")
    return times


def summary(times: list[float]) -> dict[str, float]:
    ms = np.asarray(times) * 1e3
    return {"median_ms": round(float(np.median(ms)), 2), "p90_ms": round(float(np.percentile(ms, 90)), 2)}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=20, help="timed calls per item (default 20)")
    ap.add_argument("--json", action="store_true", help="print one JSON object instead of a table")
    args = ap.parse_args()
    if args.repeats < 1:
        ap.error(f"--repeats must be >= 1, got {args.repeats}")
    rows: dict[str, dict[str, float]] = {}
    for name in list_scenes():
        scene = get_scene(name)
        rows[f"build {name} ({len(scene.obstacles)} obstacles)"] = summary(time_build(scene, args.repeats))
    rows["build 100 mixed obstacles"] = summary(time_build(hundred_obstacle_scene(), args.repeats))
    rows["A* 200x200 open grid"] = summary(time_plan(np.zeros((200, 200), dtype=bool), args.repeats))
    rows["A* 200x200 zig-zag maze"] = summary(time_plan(zigzag_maze(200), args.repeats))
    machine = f"{cpu_model()}, {os.cpu_count()} cores, Python {platform.python_version()}"
    if args.json:
        print(json.dumps({"machine": machine, "repeats": args.repeats, "rows": rows}, indent=2))
        return
    print(f"# {machine}; median and 90th percentile of {args.repeats} calls")
    width = max(len(k) for k in rows)
    for key, row in rows.items():
        print(f"{key:<{width}}  {row['median_ms']:8.2f} ms  (p90 {row['p90_ms']:.2f})")


if __name__ == "__main__":
    main()
