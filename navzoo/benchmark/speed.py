"""Throughput of the env with kinematic crowds, and its overhead over PyBullet's own stepping.

For each crowd size the full pipeline is timed — the crowd policy (SFM or ORCA, all pedestrians in
one vectorised call), action validation, kinematic posing of every humanoid, physics substeps,
collision checks, rewards and observations for every agent — and compared with calling
``stepSimulation`` alone on the very same bodies for the same number of substeps.
"""

from __future__ import annotations

import platform
import time
from typing import Any

import numpy as np
import pybullet as p

from navzoo.agents.baselines import PurePursuitPolicy
from navzoo.agents.crowd import CrowdPolicy
from navzoo.envs.registry import make_raw


def _machine() -> str:
    import os

    from navzoo.benchmark.runner import cpu_model

    return f"{cpu_model()}, {os.cpu_count()} logical CPUs, Python {platform.python_version()}, pybullet {p.getAPIVersion()}"


def measure(n_humans: int, steps: int = 200, repeats: int = 3, scene: str = "station", crowd: str = "sfm",
            seed: int = 0) -> dict[str, Any]:
    """Median env and physics throughput over ``repeats`` runs of ``steps`` steps."""
    env = make_raw(None, scene=scene, n_humans=n_humans, crowd_model=crowd, time_limit=1e6)
    crowd_policy = CrowdPolicy(crowd, see_robots=True)
    robot = PurePursuitPolicy()
    env_times, phys_in_env, bare = [], [], []
    for r in range(repeats):
        obs, _ = env.reset(seed=seed + r)
        env.physics_time = 0.0
        t0 = time.perf_counter()
        n = 0
        while n < steps:
            if not env.agents:
                obs, _ = env.reset(seed=seed + 1000 + n)
            actions = crowd_policy.act(obs, env)
            actions.update(robot.act({a: None for a in env.agents if a.startswith("robot_")}, env))
            obs, *_ = env.step(actions)
            n += 1
        env_times.append((time.perf_counter() - t0) / steps)
        phys_in_env.append(env.physics_time / steps)
        # PyBullet alone: the same bodies, the same substeps per control step.
        t0 = time.perf_counter()
        for _ in range(steps):
            for _ in range(env.config.physics_substeps):
                p.stepSimulation(physicsClientId=env.client)
        bare.append((time.perf_counter() - t0) / steps)
    n_agents = env.n_total
    env_substeps = env.config.physics_substeps
    env.close()
    step_s = float(np.median(env_times))
    bare_s = float(np.median(bare))
    return {
        "humans": n_humans,
        "robots": n_agents - n_humans,
        "env_steps_per_s": 1.0 / step_s,
        "agent_steps_per_s": n_agents / step_s,
        "env_step_ms": 1e3 * step_s,
        "physics_ms_in_env": 1e3 * float(np.median(phys_in_env)),
        "physics_fraction": float(np.median(phys_in_env)) / step_s,
        "bare_physics_ms": 1e3 * bare_s,
        "overhead_ratio": step_s / bare_s,
        "physics_substeps": env_substeps,
        "scene": scene,
        "crowd_model": crowd,
    }


def run(humans: list[int], steps: int = 200, repeats: int = 3, scene: str = "station", crowd: str = "sfm") -> dict[str, Any]:
    return {
        "machine": _machine(),
        "steps": steps,
        "repeats": repeats,
        "results": [measure(n, steps=steps, repeats=repeats, scene=scene, crowd=crowd) for n in humans],
    }
