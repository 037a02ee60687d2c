"""How often the diffusion crowd's old end-target clip pulled targets off the path, scene by scene.

    python scripts/diffusion_end_target_probe.py --scenes home:5,doorway:13,lobby:15 --seconds 40 [--bodies amp]

Until 2026-12-02 every plan's end target (the point of the A* path ``v_pref x 4.8 s`` ahead) was clipped from
the goal toward the target, to the last point with the body's clearance. That is meant for a target carried past
the goal. A target still on the path has walls between it and the goal wherever the path bends around them. The
clip then pulled it across them, toward the goal (docs/crowd_log.md, "End targets left on the path").

The script runs the following protocol's setup (``navzoo.benchmark.pedestrians``, diffusion crowd, seed 0) and
watches every plan. For each person planned, it notes whether the end target is still on the path or carried past
the goal. It also notes how far the old clip would have moved it (``_clip_to_free`` from the goal, as before).
It prints, per scene, the targets planned, how many were on the path, how many of those the old clip moved by more
than 0.1 m, and the median of those moves (m).

It also counts the plans whose person is nearer to a point of its path behind a wall than to any point it sees
(``nearest_hidden``: the nearest path point, searched as ``_ahead_from_nearest`` does, is out of sight by
``_in_sight``). Without ``path_in_sight`` those plans are measured from that hidden point, and their path guidance
pulls into the wall (docs/crowd_log.md, "Path points in sight"). ``--path-in-sight 0`` runs the crowd as before that
setting (``DiffusionCrowd(path_in_sight=False)``).
"""

from __future__ import annotations

import argparse
import json

import numpy as np

import navzoo.agents.diffusion.crowd as dc
from navzoo.benchmark import pedestrians as P
from navzoo.benchmark.matched_realism import diffusion_settings_for_new_crowds


def _nearest_hidden(env, i: int) -> bool:
    """Whether agent ``i``'s nearest path point (from the segment before its current waypoint on) is out of sight."""
    path, start, pos = env.paths[i], int(env.wp_index[i]), env.pos[i]
    pts = np.vstack([pos[None], path]) if len(path) == 1 else path
    first = max(0, start - 1) if len(path) > 1 else 0
    if len(pts) - first < 2:
        return False
    _, _, proj = dc._nearest_on_polyline(pts[first:], pos)
    return not bool(dc._in_sight(env)(pos, proj[None])[0])


def probe(scene: str, n: int, seconds: float, bodies: str = "kinematic", seed: int = 0,
          path_in_sight: bool = True) -> dict:
    """Counts of one scene (see the module doc)."""
    counts = {"targets": 0, "on_path": 0, "moved": 0, "moves_m": [], "nearest_hidden": 0}
    original = dc._end_targets

    def spy(env, people, horizon_s, extend, *args, **kwargs):
        out = original(env, people, horizon_s, extend, *args, **kwargs)
        ends = np.array([env.paths[i][-1] for i in people]).reshape(-1, 2)
        held = original(env, people, horizon_s, False)
        on_path = np.linalg.norm(held - ends, axis=1) >= 1e-9
        old = dc._clip_to_free(env, ends, held, float(env.config.human_radius) + 0.1)
        move = np.linalg.norm(old - held, axis=1)
        counts["targets"] += len(people)
        counts["on_path"] += int(on_path.sum())
        counts["moved"] += int((on_path & (move > 0.1)).sum())
        counts["moves_m"] += move[on_path & (move > 0.1)].tolist()
        counts["nearest_hidden"] += sum(_nearest_hidden(env, i) for i in people)
        return out

    dc._end_targets = spy
    try:
        with diffusion_settings_for_new_crowds({"path_in_sight": float(path_in_sight)}):
            P.follow_scene(scene, n, seconds, seed, crowd_model="diffusion", human_model=bodies)
    finally:
        dc._end_targets = original
    moves = counts.pop("moves_m")
    return {"scene": scene, "pedestrians": n, "seconds": seconds, "bodies": bodies, "path_in_sight": path_in_sight,
            **counts,
            "median_move_m": float(np.median(moves)) if moves else None}


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--scenes", default="home:5,doorway:13,lobby:15", help="scene:pedestrians,...")
    ap.add_argument("--seconds", type=float, default=40.0)
    ap.add_argument("--bodies", default="kinematic", choices=("kinematic", "amp"))
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--path-in-sight", type=int, choices=(0, 1), default=1,
                    help="the diffusion crowd's path_in_sight setting (default 1, on)")
    args = ap.parse_args(argv)
    try:
        scenes = P.parse_scene_counts(args.scenes)
    except ValueError as e:
        ap.error(str(e))
    for name, k in scenes:
        print(json.dumps(probe(name, k, args.seconds, args.bodies, args.seed, bool(args.path_in_sight))), flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
