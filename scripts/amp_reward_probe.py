"""Does the controller's task reward pay for reaching goals? Run AMP policies deterministically in navzoo scenes
(``navzoo.rl.amp_joint.NavAmpVecEnv``: social-force targets replanned from the body every 2 s, no steering trim,
i.e. what scene training sees) and print, per policy, the mean per-step pedestrian reward (track + energy +
direction, the paper's task terms), the goals reached per pedestrian-minute, falls, contact shares and the path
error. ``--set amp_progress_reward=W`` adds the optional progress term to the reward, ``--set
amp_wall_contact_reward=W`` the optional wall-contact term.

    python scripts/amp_reward_probe.py --scenes apartment,cafe,campus_plaza,hospital_corridor,shopping_mall,two_doors \\
        --policies s5174=policies/amp_pedestrian,n5325=DIR --steps 1800 --out FILE.json
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import numpy as np


def probe(policy_dir: str, scenes: list[str], steps: int, people: int = 6, seed: int = 100,
          overrides: dict | None = None) -> dict:
    from navzoo.agents.amp.checkpoint import load_policy
    from navzoo.rl.amp_joint import NavAmpVecEnv, stats_from_counters

    act = load_policy(policy_dir)
    from navzoo.envs.config import AMP_CONTROL_HZ

    dt = 1.0 / AMP_CONTROL_HZ
    reward_sum, reward_n, goals, counters = 0.0, 0, 0, []
    for k, scene in enumerate(scenes):
        env = NavAmpVecEnv("navzoo/Lobby-v0", 1, people, 0, seed=seed + k, env_overrides={**(overrides or {}), "scene": scene})
        try:
            obs = env.reset(seed=seed + k)
            before = env.envs[0].goals_reached.copy()
            for _ in range(steps):
                obs, rew, term, trunc, _ = env.step(np.clip(act(obs), -1.0, 1.0))
                reward_sum += float(rew.sum())
                reward_n += rew.size
                now = env.envs[0].goals_reached
                if not (term.any() or trunc.any()):  # a restarted copy has new counters: skip that step
                    goals += int(np.clip(now - before, 0, None).sum())
                before = now.copy()
            counters.append(env.counters())
        finally:
            env.close()
    stats = stats_from_counters(counters, dt)
    minutes = stats["pedestrian_steps"] * dt / 60.0
    return {"policy": policy_dir, "mean_reward_per_step": reward_sum / reward_n, "goals": goals,
            "goals_per_pedestrian_minute": goals / minutes, "pedestrian_minutes": minutes,
            **{k: stats[k] for k in ("falls", "agent_contact_share", "map_contact_share", "path_error_m")}}


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scenes", required=True, help="comma-separated library scenes")
    ap.add_argument("--policies", required=True, help="NAME=DIR,... exported AMP policies")
    ap.add_argument("--steps", type=int, default=1800, help="30 Hz steps per scene")
    ap.add_argument("--people", type=int, default=6)
    ap.add_argument("--set", action="append", default=[], metavar="KEY=VALUE",
                    help="NavConfig override, e.g. amp_progress_reward=0.5")
    ap.add_argument("--out", default=None, help="JSON file for the results")
    a = ap.parse_args()
    from navzoo.envs.config import parse_overrides

    scenes = a.scenes.split(",")
    overrides = parse_overrides(a.set)
    out = {"scenes": scenes, "steps": a.steps, "people": a.people, "overrides": overrides, "results": {}}
    for item in a.policies.split(","):
        name, _, pdir = item.partition("=")
        if not (Path(pdir) / "config.json").is_file():
            ap.error(f"{item!r}: no exported AMP policy (config.json) in {pdir!r}")
        t0 = time.time()
        out["results"][name] = {**probe(pdir, scenes, a.steps, a.people, overrides=overrides), "wall_s": round(time.time() - t0, 1)}
        print(name, json.dumps(out["results"][name]), flush=True)
    if a.out:
        Path(a.out).write_text(json.dumps(out, indent=2) + "\n")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
