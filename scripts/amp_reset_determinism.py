"""Does an episode of a reused physics world depend on the episodes before it?

    python scripts/amp_reset_determinism.py [--scene station] [--people 10] [--steps 150]

Runs ``--steps`` env steps (zero robot actions, the shipped AMP pedestrians) after ``reset(seed=2)`` in a fresh env,
and again in an env that first ran an episode of seed 1, with and without PyBullet's
``deterministicOverlappingPairs``. Prints the largest distance (m) between the agents' final positions of each pair
of runs (docs/env.md, "Reproducibility").
"""

from __future__ import annotations

import argparse
import json

import numpy as np
import pybullet as p

from navzoo.envs.registry import make
from navzoo.torch_threads import one_torch_thread


def _run(env, seed: int, steps: int) -> np.ndarray:
    env.reset(seed=seed)
    for _ in range(steps):
        env.step({a: np.zeros(env.action_space(a).shape, np.float32) for a in env.agents})
        if not env.agents:
            break
    return env.unwrapped.pos.copy()


def _env(scene: str, people: int, sorted_pairs: bool):
    env = make(None, scene=scene, n_humans=people, human_model="amp")
    if sorted_pairs:
        p.setPhysicsEngineParameter(deterministicOverlappingPairs=1, physicsClientId=env.unwrapped.client)
    return env


def measure(scene: str = "station", people: int = 10, steps: int = 150) -> dict[str, float]:
    """The three distances (m) printed by the command (see the module doc)."""
    out = {}
    with one_torch_thread():
        fresh = {}
        for flag in (False, True):
            fresh[flag] = _run(_env(scene, people, flag), 2, steps)
            reused = _env(scene, people, flag)
            _run(reused, 1, steps)
            out[f"reused_vs_fresh_m{'_sorted_pairs' if flag else ''}"] = float(
                np.abs(_run(reused, 2, steps) - fresh[flag]).max())
        out["fresh_sorted_vs_unsorted_m"] = float(np.abs(fresh[True] - fresh[False]).max())
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--scene", default="station")
    ap.add_argument("--people", type=int, default=10)
    ap.add_argument("--steps", type=int, default=150)
    args = ap.parse_args()
    print(json.dumps(measure(args.scene, args.people, args.steps)))


if __name__ == "__main__":
    main()
