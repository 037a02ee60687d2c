"""Where the physics pedestrians' narrow-door rules can act: per scene, how many A* paths pass a narrow door.

    python scripts/narrow_door_paths.py [--scenes protocol|heldout|S1:N,S2:N] [--seeds 12] [--json]

A *narrow point* of a person's A* path is a point with less clearance than the person's radius plus the default
wall margin of the target rollouts (``WALL_PLAN_MARGIN``) plus ``DOOR_SLACK`` (``AmpHumans.narrow_passages``: doors
under about 1.0 m).
The graded wall margin (``GRADED_WALL_MARGIN``) and the keep-right gain near narrow doors
(``NavConfig.amp_side_narrow_reach``) act only near such points, so a scene whose paths have none runs the same,
trip for trip, with or without them. For each scene (with its people count of the following protocol) and each
seed, the env is reset as the protocol does (``human_model="amp"``, no robot) and the paths planned at reset are
checked; paths planned later, after each goal, are not (a scene with none at reset may still have a few).
Prints, per scene, the paths with narrow points, the narrowest clearance met and the share of path points within
1.5 m of a narrow point.
"""

from __future__ import annotations

import argparse
import json

import numpy as np

from navzoo.benchmark.pedestrians import HELDOUT_SCENES, SCENES, parse_scene_counts, people_per_scene
from navzoo.envs.amp_humans import WALL_PLAN_MARGIN
from navzoo.envs.nav_env import NavEnv
from navzoo.world.planner import resample_polyline


def scene_list(text: str) -> list[tuple[str, int]]:
    if text == "protocol":
        return list(zip(SCENES, people_per_scene(len(SCENES)), strict=True))
    if text == "heldout":
        return list(HELDOUT_SCENES)
    try:
        return parse_scene_counts(text)
    except ValueError as e:
        raise SystemExit(str(e)) from None


def count(scene: str, people: int, seeds: int, reach: float = 1.5) -> dict:
    env = NavEnv(scene=scene, n_robots=0, n_humans=people, human_model="amp", dt=1 / 30, time_limit=10.0)
    with_narrow = total = 0
    clearance = np.inf
    share = []
    try:
        for seed in range(seeds):
            env.reset(seed=seed)
            h = np.flatnonzero(~env.is_robot)
            paths = [env.paths[i] for i in h]
            narrow = env.amp.narrow_passages(paths, env.radius[h], WALL_PLAN_MARGIN)  # the keep-right rule's doors
            for path, (pts, c) in zip(paths, narrow, strict=True):
                total += 1
                dense = resample_polyline(np.asarray(path, dtype=float).reshape(-1, 2), 0.05)  # every 5 cm
                if len(pts):
                    with_narrow += 1
                    clearance = min(clearance, float(c.min()))
                    gap = np.linalg.norm(dense[:, None] - pts[None], axis=2).min(axis=1)
                    share.append(float((gap < reach).mean()))
                else:
                    share.append(0.0)
    finally:
        env.close()
    return {"scene": scene, "people": people, "paths": total, "paths_with_narrow_points": with_narrow,
            "min_clearance_m": None if not np.isfinite(clearance) else round(clearance, 3),
            f"share_within_{reach}m": round(float(np.mean(share)), 3)}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--scenes", default="protocol", help="'protocol' (the 8), 'heldout' (the 10) or SCENE:N,...")
    ap.add_argument("--seeds", type=int, default=12, help="resets per scene (seeds 0..N-1)")
    ap.add_argument("--json", action="store_true")
    args = ap.parse_args()
    if args.seeds < 1:
        raise SystemExit("--seeds must be >= 1")
    try:
        rows = [count(s, n, args.seeds) for s, n in scene_list(args.scenes)]
    except ValueError as e:  # an unknown scene or a bad people count, named by the env
        raise SystemExit(f"narrow_door_paths: {e}") from None
    if args.json:
        print(json.dumps(rows, indent=1))
        return
    for r in rows:
        print(f"{r['scene']:18s} {r['people']:3d} people: {r['paths_with_narrow_points']:4d} of {r['paths']:4d} paths "
              f"pass a narrow door; narrowest clearance {r['min_clearance_m']}; path share within 1.5 m "
              f"{r['share_within_1.5m']}")


if __name__ == "__main__":
    main()
