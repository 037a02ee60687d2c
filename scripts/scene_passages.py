"""How narrow the passages are that a scene's pedestrians must pass, for the following protocol's trips.

For a start and a goal, the *widest route's gap* is the largest free width along which the two are connected: twice
the largest r such that start and goal lie in one connected region of the cells at least r from every obstacle
(the max-min clearance route; walls and furniture from the scene's occupancy grid, centre-to-centre distances, so up
to one grid cell too wide). A trip whose widest route's gap is 0.7 m must squeeze a 0.6 m wide body through a 0.7 m
gap somewhere, whichever way it goes.

    python scripts/scene_passages.py --scenes heldout --seeds 0,1,2,3 [--json]
    python scripts/scene_passages.py                     # the following protocol's 8 scenes and their people

The trips are the people's first start and goal after ``reset(seed)``, sampled as the following protocol samples
them (``navzoo.benchmark.pedestrians``, kinematic bodies, social force; the sampler does not depend on the crowd
model). Prints, per scene, the median widest-route gap and the share of trips whose widest route is narrower than
0.8 m and than 1.0 m.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np
from scipy import ndimage

sys.path.insert(0, str(Path(__file__).resolve().parent))

from amp_target_ablation import parse_scenes  # noqa: E402

from navzoo.world.occupancy import OccupancyGrid  # noqa: E402

#: clearance radii tried, m (a gap is twice the radius)
RADII = np.round(np.arange(0.05, 2.0 + 1e-9, 0.025), 3)


def widest_route_gap(grid: OccupancyGrid, starts: np.ndarray, goals: np.ndarray) -> np.ndarray:
    """Twice the max-min clearance (m) of a route from each start to its goal; 0 where none exists.

    ``starts`` and ``goals`` are (N, 2) world points. A point whose own clearance is below a radius is not in that
    radius's free region, so the gap never exceeds twice the clearance at either end.
    """
    starts = np.asarray(starts, dtype=np.float64).reshape(-1, 2)
    goals = np.asarray(goals, dtype=np.float64).reshape(-1, 2)
    if starts.shape != goals.shape:
        raise ValueError(f"starts {starts.shape} and goals {goals.shape} must have the same shape")
    dist = grid.distance_field()
    rc_s, rc_g = grid.world_to_cell(starts), grid.world_to_cell(goals)
    h, w = dist.shape
    for name, rc in (("start", rc_s), ("goal", rc_g)):
        bad = (rc[:, 0] < 0) | (rc[:, 0] >= h) | (rc[:, 1] < 0) | (rc[:, 1] >= w)
        if bad.any():
            raise ValueError(f"{name} point {np.flatnonzero(bad)[0]} lies outside the grid")
    best = np.zeros(len(starts))
    for r in RADII:
        labels, _ = ndimage.label(dist >= r)
        ls = labels[rc_s[:, 0], rc_s[:, 1]]
        lg = labels[rc_g[:, 0], rc_g[:, 1]]
        ok = (ls > 0) & (ls == lg)
        if not ok.any():
            break
        best[ok] = 2.0 * r
    return best


def scene_trips(scene: str, n: int, seeds: list[int]) -> tuple[OccupancyGrid, np.ndarray, np.ndarray]:
    """The scene's occupancy grid and the first start and goal of each of ``n`` people on each seed."""
    from navzoo.envs.nav_env import NavEnv

    env = NavEnv(scene=scene, n_robots=0, n_humans=n, human_model="kinematic", crowd_model="sfm")
    starts, goals = [], []
    for seed in seeds:
        env.reset(seed=seed)
        starts.append(env.pos[env.n_robots:].copy())
        goals.append(env.goal[env.n_robots:].copy())
    grid = env.grid
    env.close()
    return grid, np.concatenate(starts), np.concatenate(goals)


def summarize(gaps: np.ndarray) -> dict[str, float]:
    return {"trips": int(len(gaps)), "median_gap_m": float(np.median(gaps)),
            "share_below_0.8m": float(np.mean(gaps < 0.8)), "share_below_1.0m": float(np.mean(gaps < 1.0))}


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--scenes", default=None, help="as scripts/amp_target_ablation.py --scenes (default: the 8)")
    ap.add_argument("--seeds", default="0,1,2,3")
    ap.add_argument("--json", action="store_true")
    args = ap.parse_args(argv)
    seeds = [int(s) for s in args.seeds.split(",") if s.strip()]
    if not seeds:
        ap.error("--seeds needs at least one seed")
    rows = {}
    for scene, n in parse_scenes(args.scenes).items():
        grid, starts, goals = scene_trips(scene, n, seeds)
        rows[scene] = {"people": n, **summarize(widest_route_gap(grid, starts, goals))}
    if args.json:
        print(json.dumps({"seeds": seeds, "scenes": rows}, indent=1))
        return 0
    print("| scene | people | trips | widest route's gap, median (m) | share < 0.8 m | share < 1.0 m |")
    print("|---|---|---|---|---|---|")
    for scene, r in rows.items():
        print(f"| {scene} | {r['people']} | {r['trips']} | {r['median_gap_m']:.2f} | {r['share_below_0.8m']:.2f} | "
              f"{r['share_below_1.0m']:.2f} |")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
