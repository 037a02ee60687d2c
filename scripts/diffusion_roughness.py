"""Where the diffusion crowd's accelerations come from: walked and planned roughness per setting.

    python scripts/diffusion_roughness.py --variants "default;guidance_scale=0;lookahead=1.6" \
        [--scenes lobby:12,corridor:10,home:5] [--seconds 60] [--out FILE.jsonl]

Kinematic pedestrians of the diffusion crowd (no robot), seed 0, the realism protocol of
``navzoo eval crowd`` (positions resampled to 0.4 s, still starts trimmed, forward differences). A
variant sets attributes of the env's ``DiffusionCrowd`` (``guidance_scale``, ``replan_s``,
``blend_s``, ``path_weight``, ``smooth_weight``, ``n_samples``, ...), the guidance weights
``target_weight``, ``agent_weight``, ``map_weight``, and ``lookahead``, the seconds ahead on the plan that
the preferred velocity aims at (``preferred_velocities(lookahead=)``). Two probes of the model's inputs:
``history_fit=DEG`` gives the model least-squares polynomial fits of degree DEG to the 8-point histories
(its own and its neighbours', the last point kept exact), ``no_map=1`` withholds the occupancy crop. Prints, per variant, the mean
walked speed, acceleration and jerk, the mean acceleration of the plans themselves (every plan made,
at its 0.4 s points), goals reached and the overlap share (centres closer than 0.4 m).
"""

from __future__ import annotations

import argparse
import json
import time

import numpy as np
import torch

from navzoo.agents.crowd import CrowdPolicy
from navzoo.benchmark.crowd_eval import STEP, collision_share, track_kinematics
from navzoo.envs.nav_env import NavEnv
from navzoo.envs.wrappers import FrozenAgents


def parse_variant(text: str) -> dict[str, float]:
    out: dict[str, float] = {}
    for part in filter(None, (p.strip() for p in text.split(","))):
        if part == "default":
            continue
        key, _, value = part.partition("=")
        if not value:
            raise SystemExit(f"variant part {part!r} is not NAME=VALUE")
        out[key.strip()] = float(value)
    return out


def fit_histories(h: np.ndarray, deg: int) -> np.ndarray:
    """Least-squares polynomial fit of degree ``deg`` over the time axis (-2) of ``(..., T, 2)``
    histories, shifted so that the last point stays where it was."""
    t = np.arange(h.shape[-2], dtype=float)
    vander = np.vander(t, deg + 1)
    fit = np.einsum("ts,...sd->...td", vander @ np.linalg.pinv(vander), h)
    return fit + (h[..., -1:, :] - fit[..., -1:, :])


def run(scene: str, n: int, seconds: float, settings: dict[str, float], seed: int = 0) -> dict:
    env = NavEnv(scene=scene, n_robots=0, n_humans=n, crowd_model="diffusion", time_limit=seconds)
    crowd = env.diffusion
    settings = dict(settings)
    lookahead = settings.pop("lookahead", None)
    history_fit = settings.pop("history_fit", None)
    if history_fit is not None:
        world_batch = crowd._world_batch

        def fitted_batch(e, people, deg=int(history_fit)):
            out = world_batch(e, people)
            out["hist"] = fit_histories(out["hist"], deg)
            out["neigh"] = fit_histories(out["neigh"], deg) * out["neigh_mask"][..., None]
            return out

        crowd._world_batch = fitted_batch
    if settings.pop("no_map", 0):
        sample = crowd.model.sample

        def sample_without_map(batch, *a, **k):
            if "has_map" in batch:
                batch = {**batch, "has_map": torch.zeros_like(batch["has_map"])}
            return sample(batch, *a, **k)

        crowd.model.sample = sample_without_map
    names = ("target_weight", "agent_weight", "map_weight")  # the guidance weights, kept as one tuple
    crowd.weights = tuple(settings.pop(k, w) for k, w in zip(names, crowd.weights, strict=True))
    for key, value in settings.items():
        if not hasattr(crowd, key):
            raise SystemExit(f"DiffusionCrowd has no attribute {key!r}")
        setattr(crowd, key, type(getattr(crowd, key))(value))
    if lookahead is not None:
        original = crowd.preferred_velocities
        crowd.preferred_velocities = lambda e, lookahead=lookahead: original(e, lookahead=lookahead)
    plans: list[np.ndarray] = []
    plan_now = crowd.plan_now

    def recording_plan_now(e, who=None):
        out = plan_now(e, who)
        rows = np.arange(crowd.plan.shape[0]) if who is None else np.asarray(who)
        plans.append(crowd.plan[rows].copy())
        return out

    crowd.plan_now = recording_plan_now
    wrapped = FrozenAgents(env, lambda a: a.startswith("human_"), CrowdPolicy("diffusion"))
    t0 = time.time()
    wrapped.reset(seed=seed)
    positions = [env.pos.copy()]
    while not env._needs_reset:
        wrapped.step({})
        positions.append(env.pos.copy())
    goals = int(env.goals_reached.sum())
    wrapped.close()
    pos = np.asarray(positions)
    t = np.arange(len(pos)) * env.config.dt
    kin = track_kinematics([(t, pos[:, j]) for j in range(n)], STEP)
    plan_acc = np.concatenate([np.linalg.norm(np.diff(p, 2, axis=1), axis=2).ravel() / STEP ** 2 for p in plans])
    hit, total = collision_share(pos, 0.4)
    return {"scene": scene, "people": n, "speed": kin["speed"], "accel": kin["accel"], "jerk": kin["jerk"],
            "plan_accel": plan_acc, "goals": goals, "overlap": (hit, total), "wall_s": time.time() - t0}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--variants", default="default", help="';'-separated variants, each 'default' or NAME=V,...")
    ap.add_argument("--scenes", default="lobby:12,corridor:10,home:5")
    ap.add_argument("--seconds", type=float, default=60.0)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--out", default=None, help="append one JSON line per variant")
    args = ap.parse_args()
    scenes = [(s.split(":")[0], int(s.split(":")[1])) for s in args.scenes.split(",")]
    for text in args.variants.split(";"):
        settings = parse_variant(text)
        rows = [run(sc, n, args.seconds, settings, args.seed) for sc, n in scenes]
        cat = {q: np.concatenate([r[q] for r in rows]) for q in ("speed", "accel", "jerk", "plan_accel")}
        hit = sum(r["overlap"][0] for r in rows)
        total = sum(r["overlap"][1] for r in rows)
        line = {"variant": text.strip() or "default", "scenes": args.scenes, "seconds": args.seconds,
                "seed": args.seed,
                **{f"{q}_mean": round(float(v.mean()), 4) for q, v in cat.items()},
                "goals": sum(r["goals"] for r in rows), "overlap_share": round(hit / max(total, 1), 5),
                "wall_s": round(sum(r["wall_s"] for r in rows), 1)}
        print(json.dumps(line), flush=True)
        if args.out:
            with open(args.out, "a") as f:
                f.write(json.dumps(line) + "\n")


if __name__ == "__main__":
    main()
