"""Evaluate fixed robots and pedestrians of a joint config (``python -m navzoo.rl.evaluate``).

Every side is frozen (``robots: frozen`` with a baseline or ``rllib:PATH``; ``humans: crowd`` or
``frozen`` with ``rllib:PATH`` / ``amp``); trained RLlib modules act with their mean action in this
process, no Ray instance is started. Episodes are seeded ``seed, seed + 1, ...``, so two
evaluations with the same seed see the same starts and goals.

Per episode and then averaged: robot success / collision / timeout rate, time to goal of the
successful robots, pedestrian goals reached per pedestrian and their mean speed, the smallest
robot-pedestrian gap (edge to edge), the share of robot-steps with a pedestrian closer than 0.5 m
(edge to edge: inside personal space), and the contacts that pedestrians began with a robot and with
another pedestrian per episode (``info["contact"]`` of the env, counted where a contact starts).
"""

from __future__ import annotations

import argparse
import json
import sys
from collections.abc import Callable, Sequence
from typing import Any

import numpy as np

from navzoo.rl.config import JointConfig

__all__ = ["add_arguments", "evaluate", "main", "run_cli"]

PERSONAL_SPACE_M = 0.5


def evaluate(cfg: JointConfig, episodes: int = 20, seed: int = 0) -> dict[str, Any]:
    """Run ``episodes`` seeded episodes of a fully frozen joint config; return means and per-episode rows."""
    from navzoo.rl.joint import make_parallel_env

    cfg.validate(training=False)
    env = make_parallel_env(cfg, training=False)
    nav = env.unwrapped
    R, dt = nav.n_robots, nav.config.dt
    rows = []
    for ep in range(episodes):
        env.reset(seed=seed + ep)
        min_gap, close, robot_steps, speed = np.inf, 0, 0, []
        contacts = {"robot": 0, "human": 0}
        prev_contact = np.zeros(nav.n_humans, dtype=bool)
        finished: dict[int, int] = {}
        while nav.agents:
            env.step({})
            now = nav._human_contact
            for kind in contacts:
                contacts[kind] += int(((now == kind) & ~prev_contact).sum())
            prev_contact = now != ""
            for i in np.flatnonzero(~nav.alive[:R]):
                finished.setdefault(int(i), int(nav.steps))
            alive_r = np.flatnonzero(nav.alive[:R])
            if nav.n_humans:
                h = np.arange(R, nav.n_total)
                speed.append(np.linalg.norm(nav.vel[h], axis=1).mean())
                if len(alive_r):
                    gap = (np.linalg.norm(nav.pos[alive_r, None] - nav.pos[None, h], axis=2)
                           - nav.radius[alive_r, None] - nav.radius[None, h])
                    min_gap = min(min_gap, float(gap.min()))
                    close += int((gap.min(axis=1) < PERSONAL_SPACE_M).sum())
                    robot_steps += len(alive_r)
        events = [nav.events.get(a, "timeout") for a in nav.possible_agents[:R]]
        goal_times = [round(finished[i] * dt, 3) for i, e in enumerate(events) if e == "goal" and i in finished]
        rows.append({
            "seed": seed + ep,
            "steps": int(nav.steps),
            "robot_success": float(np.mean([e == "goal" for e in events])) if R else None,
            "robot_collision": float(np.mean([e.startswith("collision") for e in events])) if R else None,
            "robot_timeout": float(np.mean([e == "timeout" for e in events])) if R else None,
            "robot_events": events,
            "episode_s": round(float(nav.steps * dt), 3),
            "human_goals_per_human": float(nav.goals_reached[R:].mean()) if nav.n_humans else None,
            "human_speed_mps": float(np.mean(speed)) if speed else None,
            "min_robot_human_gap_m": None if not np.isfinite(min_gap) else round(min_gap, 4),
            "personal_space_share": round(close / robot_steps, 4) if robot_steps else None,
            "ped_robot_contacts": contacts["robot"] if nav.n_humans else None,
            "ped_ped_contacts": contacts["human"] if nav.n_humans else None,
            "robot_goal_time_s": round(float(np.mean(goal_times)), 3) if goal_times else None,
        })
    env.close()
    means: dict[str, Any] = {}
    for key in ("robot_success", "robot_collision", "robot_timeout", "robot_goal_time_s", "episode_s", "human_goals_per_human",
                "human_speed_mps", "min_robot_human_gap_m", "personal_space_share", "ped_robot_contacts",
                "ped_ped_contacts"):
        vals = [r[key] for r in rows if r[key] is not None]
        means[key] = round(float(np.mean(vals)), 4) if vals else None
    return {"config": cfg.to_dict(), "episodes": episodes, "seed": seed, "mean": means, "per_episode": rows}


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--config", default=None, metavar="FILE", help="JointConfig YAML/JSON (every side frozen)")
    parser.add_argument("--env", dest="env_id", default=None)
    parser.add_argument("--n-robots", type=int, default=None)
    parser.add_argument("--n-humans", type=int, default=None)
    parser.add_argument("--robot-policy", default=None, help="baseline name or rllib:PATH (default orca)")
    parser.add_argument("--humans", choices=["frozen", "crowd"], default=None, help="default crowd")
    parser.add_argument("--human-policy", default=None, help="rllib:PATH, or amp / amp:DIR")
    parser.add_argument("--set", dest="env_set", action="append", default=[], metavar="KEY=VALUE")
    parser.add_argument("--episodes", type=int, default=20)
    parser.add_argument("--seed", type=int, default=10_000)
    parser.add_argument("--per-episode", action="store_true", help="also print every episode")


def run_cli(args: argparse.Namespace, error: Callable[[str], None] | None = None) -> int:
    from navzoo.rl.train import _key_value

    try:
        cfg = JointConfig.load(args.config) if args.config else JointConfig(robots="frozen", humans="crowd")
        cfg.robots = "frozen"
        for name in ("env_id", "n_robots", "n_humans", "robot_policy", "humans", "human_policy"):
            if getattr(args, name) is not None:
                setattr(cfg, name, getattr(args, name))
        for item in args.env_set:
            key, value = _key_value(item)
            cfg.env[key] = value
        if args.episodes < 1:
            raise ValueError(f"--episodes must be >= 1, got {args.episodes}")
        result = evaluate(cfg, args.episodes, args.seed)
    except (ValueError, TypeError, FileNotFoundError, argparse.ArgumentTypeError) as exc:
        if error is not None:
            error(str(exc))
        print(f"navzoo.rl.evaluate: error: {exc}", file=sys.stderr)
        return 2
    if not args.per_episode:
        result.pop("per_episode")
    print(json.dumps(result))
    return 0


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        prog="python -m navzoo.rl.evaluate",
        description="Evaluate fixed robots and pedestrians of a joint config over seeded episodes (docs/scaling.md).")
    add_arguments(parser)
    return run_cli(parser.parse_args(argv), parser.error)


if __name__ == "__main__":
    sys.exit(main())
