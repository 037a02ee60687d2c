"""Can a robot that drives straight at its A* subgoal reach the goal without touching a wall?

    python scripts/subgoal_pursuit.py [--scenes Station,Home,Grocery] [--episodes 20] [--lookahead 3.0]
                                      [--paths graded|bare]

The learned paper-scene policy observes a subgoal (``NavConfig.robot_subgoal``): the farthest point of
its A* path within the lookahead that is in sight. This script removes the learning: a proportional
controller turns toward the subgoal and drives forward as it faces it, with no pedestrians, in the
training scenes. Whatever it hits, the subgoal itself led it into.

``--paths bare`` restores the robot guide as it was before 2026-11-22 (tenth session): paths planned
with the bare radius whenever the padded plan failed, and sight lines checked with the bare radius,
so that the subgoal could lie beyond a door corner that the straight line grazes. ``graded`` (the
default) is navzoo's guide now (``AStarPlanner.plan_graded`` and penalty-checked sight lines).
Prints one JSON line per scene: outcomes and the smallest path clearance to the walls.
"""

from __future__ import annotations

import argparse
import json

import numpy as np

import navzoo
from navzoo.envs import subgoal as sg
from navzoo.world.geometry import min_distance_to_segments


def _bare_guide() -> None:
    """The robot guide's planning and sight lines as they were before graded clearance."""

    def _plan(self, i, start, goal):
        r = float(self.radii[i])
        path = self._planner(r + self.clearance).plan(start, goal, spacing=self.spacing) if self.clearance > 0 else None
        if path is None:
            path = self._planner(r).plan(start, goal, spacing=self.spacing)
        if path is None or len(path) == 0:
            return np.asarray(goal, dtype=np.float64).reshape(1, 2)
        path = np.asarray(path, dtype=np.float64)
        if np.linalg.norm(path[-1] - goal) > 1e-9:
            path = np.concatenate([path, np.asarray(goal, dtype=np.float64).reshape(1, 2)])
        return path

    def _subgoal(self, i, p):
        path, k0 = self.paths[i], int(self.index[i])
        d = np.linalg.norm(path[k0:] - p, axis=1)
        near = np.flatnonzero(d <= self.lookahead)
        los = self._planner(float(self.radii[i])).line_of_sight
        for j in near[::-1]:
            if los(p, path[k0 + j]):
                self.index[i] = k0 + int(np.argmin(d[: j + 1]))
                return path[k0 + j].copy()
        return None

    sg.RobotGuide._plan = _plan
    sg.RobotGuide._subgoal = _subgoal


def run(scene: str, episodes: int, lookahead: float) -> dict:
    env = navzoo.make(f"navzoo/{scene}-v0", n_humans=0, robot_subgoal=lookahead)
    nav = env.unwrapped
    outcomes: dict[str, int] = {}
    clearances = []
    for ep in range(episodes):
        obs, _ = env.reset(seed=ep)
        path = nav.robot_guide.paths[0]
        dense = np.concatenate([np.linspace(a, b, 20) for a, b in zip(path[:-1], path[1:], strict=True)]) \
            if len(path) > 1 else path
        clearances.append(float(min_distance_to_segments(dense, nav.segments).min()))
        while True:
            g = obs["robot_0"]["goal"]
            err = float(np.arctan2(g[1], g[0]))
            act = np.array([max(0.0, np.cos(err)) ** 4 * min(1.0, float(g[2])), np.clip(3.0 * err, -1, 1)], np.float32)
            obs, _, term, trunc, info = env.step({"robot_0": act})
            if term.get("robot_0") or trunc.get("robot_0") or "robot_0" not in obs:
                ev = info.get("robot_0", {}).get("event", "timeout")
                outcomes[ev] = outcomes.get(ev, 0) + 1
                break
    env.close()
    return {"scene": scene, "episodes": episodes, "lookahead": lookahead, "outcomes": outcomes,
            "path_clearance_m": {"median": round(float(np.median(clearances)), 3),
                                 "min": round(float(np.min(clearances)), 3)}}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--scenes", default="Station,Home,Grocery")
    ap.add_argument("--episodes", type=int, default=20)
    ap.add_argument("--lookahead", type=float, default=3.0)
    ap.add_argument("--paths", choices=["graded", "bare"], default="graded")
    args = ap.parse_args()
    if args.paths == "bare":
        _bare_guide()
    for scene in args.scenes.split(","):
        print(json.dumps({"paths": args.paths, **run(scene, args.episodes, args.lookahead)}), flush=True)


if __name__ == "__main__":
    main()
