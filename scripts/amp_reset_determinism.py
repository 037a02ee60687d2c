"""Does an episode of a reused physics world depend on the episodes before it?

    python scripts/amp_reset_determinism.py [--scene station] [--people 10] [--steps 150]

Runs ``--steps`` env steps (zero robot actions, the shipped AMP pedestrians) after ``reset(seed=2)`` in a fresh env,
and again in an env that first ran an episode of seed 1. Prints the largest distance (m) between the agents' final
positions of each pair of runs (docs/env.md, "Reproducibility"):

- ``reused_vs_fresh_m``: NavEnv.reset as shipped (a stepped physics world is rebuilt): 0.0 when an episode depends on
  its seed alone;
- ``restored_only_vs_fresh_m``: the reset of before 2026-12-03, ``p.restoreState`` alone (the rebuild skipped);
- ``restored_only_sorted_pairs_vs_fresh_m``: the same with PyBullet's ``deterministicOverlappingPairs=1`` in both
  worlds, which shows the cause: the broadphase's order of overlapping pairs, kept over ``restoreState``;
- ``fresh_sorted_vs_unsorted_m``: what that flag does to a fresh world's trips (why it is not the fix);

and the median seconds of ``reset`` with and without the rebuild (``reset_s``, ``reset_restore_only_s``).

With ``--kinematic``: the same reused-against-fresh distance for kinematic people (restored, never rebuilt) with two
robots driving (``kinematic_<crowd>_reused_vs_fresh_m`` for the social-force and diffusion crowds).
"""

from __future__ import annotations

import argparse
import json
import time

import numpy as np
import pybullet as p

from navzoo.envs.registry import make
from navzoo.torch_threads import one_torch_thread


def _run(env, seed: int, steps: int, restore_only: bool = False) -> np.ndarray:
    if restore_only:  # skip NavEnv.reset's rebuild of a stepped physics world (the reset of before 2026-12-03)
        env.unwrapped._world_stepped = False
    env.reset(seed=seed)
    for _ in range(steps):
        env.step({a: np.zeros(env.action_space(a).shape, np.float32) for a in env.agents})
        if not env.agents:
            break
    return env.unwrapped.pos.copy()


def _env(scene: str, people: int, sorted_pairs: bool = False):
    env = make(None, scene=scene, n_humans=people, human_model="amp")
    if sorted_pairs:
        p.setPhysicsEngineParameter(deterministicOverlappingPairs=1, physicsClientId=env.unwrapped.client)
    return env


def _reset_seconds(env, restore_only: bool, repeats: int = 5) -> float:
    times = []
    for k in range(repeats):
        _run(env, 10 + k, 3)  # a stepped world
        if restore_only:
            env.unwrapped._world_stepped = False
        t0 = time.perf_counter()
        env.reset(seed=10 + k)
        times.append(time.perf_counter() - t0)
    return float(np.median(times))


def measure(scene: str = "station", people: int = 10, steps: int = 150, timing: bool = True) -> dict[str, float]:
    """The distances (m) and reset times (s) printed by the command (see the module doc)."""
    out = {}
    with one_torch_thread():
        fresh = _run(_env(scene, people), 2, steps)
        for name, restore_only in (("reused_vs_fresh_m", False), ("restored_only_vs_fresh_m", True)):
            reused = _env(scene, people)
            _run(reused, 1, steps)
            out[name] = float(np.abs(_run(reused, 2, steps, restore_only) - fresh).max())
        fresh_sorted = _run(_env(scene, people, True), 2, steps)
        reused = _env(scene, people, True)
        _run(reused, 1, steps)
        out["restored_only_sorted_pairs_vs_fresh_m"] = float(
            np.abs(_run(reused, 2, steps, restore_only=True) - fresh_sorted).max())
        out["fresh_sorted_vs_unsorted_m"] = float(np.abs(fresh_sorted - fresh).max())
        if timing:
            env = _env(scene, people)
            out["reset_s"] = _reset_seconds(env, False)
            out["reset_restore_only_s"] = _reset_seconds(env, True)
    return out


def measure_kinematic(scene: str = "station", people: int = 10, steps: int = 150) -> dict[str, float]:
    """Reused against fresh for kinematic people and two robots (forward at 0.8, turning at 0.3), per crowd model."""

    def run(env, seed: int) -> np.ndarray:
        env.reset(seed=seed)
        for _ in range(steps):
            env.step({a: np.array([0.8, 0.3], np.float32) for a in env.agents})
            if not env.agents:
                break
        return env.unwrapped.pos.copy()

    out = {}
    with one_torch_thread():
        for crowd in ("sfm", "diffusion"):
            kw = dict(scene=scene, n_humans=people, n_robots=2, crowd_model=crowd)
            fresh = run(make(None, **kw), 2)
            reused = make(None, **kw)
            run(reused, 1)
            out[f"kinematic_{crowd}_reused_vs_fresh_m"] = float(np.abs(run(reused, 2) - fresh).max())
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--scene", default="station")
    ap.add_argument("--people", type=int, default=10)
    ap.add_argument("--steps", type=int, default=150)
    ap.add_argument("--kinematic", action="store_true", help="kinematic people instead (see the module doc)")
    args = ap.parse_args()
    fn = measure_kinematic if args.kinematic else measure
    print(json.dumps(fn(args.scene, args.people, args.steps)))


if __name__ == "__main__":
    main()
