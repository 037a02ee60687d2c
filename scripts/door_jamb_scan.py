"""Which doors do the door turns miss on paths that enter them slantwise? Sampled A* paths, per scene.

    python scripts/door_jamb_scan.py [--scenes protocol|heldout|all|S1,S2] [--paths 60] [--search 0.3] [--run-scan]
        [--json F]

For each scene, draws ``--paths`` start/goal pairs from the scene's pedestrian goal sampler (seeded), plans each
with a physics pedestrian's A* planner (``NavEnv._plan``: the AMP plan margin and door entries) and finds the path's
doors as the door turns do (``navzoo.envs.doors.path_doors``, two-sided, 0.7 m end margin), once as by default and
once with ``jamb_search=--search`` (``amp_humans.DOOR_JAMB_SEARCH``; with ``--run-scan`` also ``run_scan``,
``amp_humans.DIFFUSION_DOOR_RUN_SCAN`` / ``DOOR_RUN_SCAN``: the narrow stretch's other points tried when its narrowest
has no door). Prints, per scene, how many paths have a door without and with the search, how many get a different
list of doors, and the doors found only with the search (centre rounded to 0.1 m: number of paths; ``new_widths``:
their free width across the door there, m). A static check of the door detection; what it does to the crowds is
measured by the following protocol.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np


def scan(scene: str, paths: int, search: float, seed: int = 0, run_scan: bool = False) -> dict:
    from navzoo.envs.doors import DOOR_HALF_WIDTH, _passage_width, path_doors
    from navzoo.envs.nav_env import NavEnv

    env = NavEnv(scene=scene, n_robots=0, n_humans=1, human_model="amp")
    env.reset(seed=seed)
    rng = np.random.default_rng(seed)
    sampler = env._samplers["human"]
    changed, found, new, widths = 0, [0, 0], {}, {}
    for _ in range(paths):
        s = sampler.sample_goal(rng, np.zeros(2), "human", min_goal_dist=0.0)
        g = sampler.sample_goal(rng, s, "human", min_goal_dist=env.config.min_goal_distance)
        path = env._plan(0, s, g)
        a = [c for c, _, _ in path_doors(path, s, env.grid, two_sided=True, end_margin=0.7)]
        bd = path_doors(path, s, env.grid, two_sided=True, end_margin=0.7, jamb_search=search, run_scan=run_scan)
        b = [c for c, _, _ in bd]
        found[0] += bool(a)
        found[1] += bool(b)
        if len(a) != len(b) or any(np.linalg.norm(x - y) > 0.25 for x, y in zip(a, b, strict=True)):
            changed += 1
            for c, axis, _ in bd:
                if not any(np.linalg.norm(c - x) < 0.6 for x in a):
                    key = f"{c[0]:.1f},{c[1]:.1f}"
                    new[key] = new.get(key, 0) + 1
                    widths[key] = round(_passage_width(env.grid, c, axis, 2.0 * DOOR_HALF_WIDTH), 2)
    env.close()
    return {"scene": scene, "paths": paths, "with_doors": found[0], "with_doors_search": found[1], "changed": changed,
            "new_doors": new, "new_widths": widths, "search": search, "run_scan": run_scan}


def scenes_for(arg: str) -> list[str]:
    """``protocol``, ``heldout``, ``all`` or comma-separated library scene names (ValueError for unknown ones)."""
    from navzoo.benchmark.pedestrians import HELDOUT_SCENES, SCENES
    from navzoo.world.library import get_scene

    held = [s for s, _ in HELDOUT_SCENES]
    named = {"protocol": list(SCENES), "heldout": held, "all": list(SCENES) + held}
    if arg in named:
        return named[arg]
    out = [s.strip() for s in arg.split(",") if s.strip()]
    for s in out:
        try:
            get_scene(s)
        except Exception as e:
            raise ValueError(f"--scenes: unknown scene {s!r}") from e
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--scenes", default="all", help="protocol, heldout, all or comma-separated scene names")
    ap.add_argument("--paths", type=int, default=60, help="sampled paths per scene")
    ap.add_argument("--search", type=float, default=0.3, help="jamb_search (m) to compare with the default")
    ap.add_argument("--run-scan", action="store_true", help="also try a narrow stretch's other points (run_scan)")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--json", default=None, help="write the rows to this file too")
    args = ap.parse_args()
    if args.paths < 1 or not (args.search > 0 or (args.search == 0 and args.run_scan)):
        ap.error("--paths must be >= 1 and --search > 0 (or 0 with --run-scan)")
    try:
        scenes = scenes_for(args.scenes)
    except ValueError as e:
        ap.error(str(e))
    rows = []
    for s in scenes:
        r = scan(s, args.paths, args.search, args.seed, args.run_scan)
        rows.append(r)
        print(f"{s}: {r['changed']} of {r['paths']} paths get other doors (paths with a door: {r['with_doors']}, "
              f"with the search {r['with_doors_search']}); found only with the search: "
              f"{r['new_doors'] or 'none'} (widths {r['new_widths'] or '-'})", flush=True)
    if args.json:
        Path(args.json).write_text(json.dumps(rows, indent=1) + "\n")


if __name__ == "__main__":
    main()
