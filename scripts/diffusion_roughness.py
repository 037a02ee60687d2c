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
(its own and its neighbours', the last point kept exact), ``no_map=1`` withholds the occupancy crop, ``no_neigh=1``
withholds the neighbours' histories (the model plans as if alone; the people guidance still acts). Two probes of the
walker, the social force that carries each kinematic body along its plan: ``walker_FIELD=V`` sets a field of its
:class:`~navzoo.agents.sfm.SocialForceParams` (e.g. ``walker_max_accel=1.0``), ``orca_walker=1`` walks the plans
with ORCA instead (``NavConfig.diffusion_walker="orca"``, with :data:`~navzoo.agents.diffusion.crowd.ORCA_WALKER`),
and ``orca_FIELD=V`` sets a field of its :class:`~navzoo.agents.orca.OrcaParams` (also for ``--crowd orca``, from
ORCA's defaults; e.g. ``orca_time_horizon=5``); ``hybrid_walker=1`` walks them with that ORCA and hands the people it
holds still to social force (``NavConfig.diffusion_walker="hybrid"``). ``pace_ramp=A`` (a ``DiffusionCrowd`` setting) spaces the path guidance's points by a pace that
changes from the person's current speed toward its preferred one at A m/s². Prints, per variant, the mean
walked speed, acceleration and jerk, the mean acceleration of the plans themselves (every plan made,
at its 0.4 s points), goals reached, the overlap share (centres closer than 0.4 m), the standing share (0.4 s steps under
:data:`~navzoo.benchmark.crowd_eval.STAND_SPEED`, whole tracks: jams and waits), the mean acceleration while walking (``accel_walking_mean``:
both speeds of the sample at least that speed; ``--real`` measures the real tracks the same way), and the
walked
acceleration split at the goals: within :data:`GOAL_WINDOW_S` of a person's goal arrival (the turn to the next
goal, which the recordings never show) and the rest (``accel_near_goal_mean``, ``accel_between_goals_mean``,
``near_goal_share``).
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import time

import numpy as np
import torch

from navzoo.agents.crowd import CrowdPolicy
from navzoo.agents.diffusion.crowd import ORCA_WALKER
from navzoo.agents.orca import OrcaParams
from navzoo.benchmark.crowd_eval import (
    MIN_START_SPEED,
    STEP,
    collision_share,
    kinematics,
    real_data,
    resample,
    standing,
    track_kinematics,
    trim_still_start,
    walking_accel,
)
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


#: Seconds either side of a goal arrival whose walked accelerations count as "near a goal".
GOAL_WINDOW_S = 2.0


def split_at_goals(t: np.ndarray, xy: np.ndarray, arrivals: np.ndarray, step: float = STEP,
                   window: float = GOAL_WINDOW_S) -> tuple[np.ndarray, np.ndarray]:
    """A track's walked accelerations (resampled to ``step``, still start trimmed, as the realism part) split in two:
    those whose middle sample lies within ``window`` s of one of the ``arrivals`` (times of goal arrivals, s), and the
    rest. Returns ``(near, between)``. The track is taken whole: kinematic walkers never jump."""
    res = resample(np.asarray(t, dtype=float), np.asarray(xy, dtype=float), step)
    kept = trim_still_start(res, step, MIN_START_SPEED)
    first = float(t[0]) + (len(res) - len(kept)) * step  # time of the first kept sample
    acc = kinematics(kept, step)["accel"]
    at = first + step * np.arange(1, 1 + acc.size)  # the accel of samples k-1, k, k+1 belongs to sample k
    arrivals = np.asarray(arrivals, dtype=float)
    if arrivals.size == 0:
        return acc[:0], acc
    near = np.min(np.abs(at[:, None] - arrivals[None, :]), axis=1) <= window
    return acc[near], acc[~near]


def real_line(data_dir: str | None) -> dict:
    """The real ETH/UCY tracks measured as the variants are (:func:`navzoo.benchmark.crowd_eval.real_data`): mean
    acceleration (as the realism part pools it), mean acceleration while walking, and the standing share (0.4 s
    steps under :data:`~navzoo.benchmark.crowd_eval.STAND_SPEED`)."""
    kin, summary = real_data(data_dir)
    return {"variant": "real", "crowd": "real ETH/UCY", "accel_mean": round(summary["accel_mean"], 4),
            "accel_walking_mean": round(summary["accel_walking_mean"], 4),
            "standing_share": round(summary["standing_share"], 4), "tracks": sum(f["tracks"] for f in summary["files"])}


def fit_histories(h: np.ndarray, deg: int) -> np.ndarray:
    """Least-squares polynomial fit of degree ``deg`` over the time axis (-2) of ``(..., T, 2)``
    histories, shifted so that the last point stays where it was."""
    t = np.arange(h.shape[-2], dtype=float)
    vander = np.vander(t, deg + 1)
    fit = np.einsum("ts,...sd->...td", vander @ np.linalg.pinv(vander), h)
    return fit + (h[..., -1:, :] - fit[..., -1:, :])


def _diffusion_probes(crowd, settings: dict[str, float]) -> list[np.ndarray]:
    """Apply a variant's diffusion settings and model probes to the env's ``DiffusionCrowd``; returns the list that
    collects every plan made (filled as the run goes)."""
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
    if settings.pop("no_neigh", 0):
        sample_all = crowd.model.sample

        def sample_alone(batch, *a, **k):
            return sample_all({**batch, "neigh_mask": torch.zeros_like(batch["neigh_mask"])}, *a, **k)

        crowd.model.sample = sample_alone
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
    return plans


def walker_params(base, walker: dict[str, float]):
    """``base`` (a :class:`SocialForceParams` or :class:`OrcaParams`) with the ``walker_FIELD=V`` / ``orca_FIELD=V``
    settings of a variant (names without the prefix), each of the field's type; unknown fields are refused."""
    fields = {f.name for f in dataclasses.fields(type(base)) if f.init}
    unknown = sorted(set(walker) - fields)
    if unknown:
        raise SystemExit(f"{type(base).__name__} has no field(s) {unknown}; choose from {sorted(fields)}")
    return dataclasses.replace(base, **{k: type(getattr(base, k))(v) for k, v in walker.items()})


def run(scene: str, n: int, seconds: float, settings: dict[str, float], seed: int = 0,
        crowd_model: str = "diffusion") -> dict:
    settings = dict(settings)
    hybrid_walker = bool(settings.pop("hybrid_walker", 0))
    orca_walker = bool(settings.pop("orca_walker", 0)) or hybrid_walker
    walker = {k[len("walker_"):]: v for k, v in settings.items() if k.startswith("walker_")}
    orca = {k[len("orca_"):]: v for k, v in settings.items() if k.startswith("orca_")}
    settings = {k: v for k, v in settings.items() if not k.startswith(("walker_", "orca_"))}
    if orca and not orca_walker and crowd_model != "orca":
        raise SystemExit(f"orca_FIELD settings {sorted(orca)} need orca_walker=1 (or --crowd orca)")
    if crowd_model != "diffusion" and (settings or orca_walker or (walker and crowd_model != "sfm")):
        raise SystemExit(f"the {crowd_model} crowd takes no variant settings but walker_FIELD=V (sfm) and "
                         f"orca_FIELD=V (orca), "
                         f"got {sorted(settings) + (['orca_walker'] if orca_walker else []) + sorted(walker)}")
    name = "hybrid" if hybrid_walker else "orca" if orca_walker else "sfm"
    walker_kw = {"diffusion_walker": name} if crowd_model == "diffusion" else {}
    env = NavEnv(scene=scene, n_robots=0, n_humans=n, crowd_model=crowd_model, time_limit=seconds, **walker_kw)
    plans = _diffusion_probes(env.diffusion, settings) if crowd_model == "diffusion" else []
    orca_base = ORCA_WALKER if crowd_model == "diffusion" else OrcaParams()
    policy = CrowdPolicy(crowd_model, orca_params=walker_params(orca_base, orca) if orca else None)
    if walker:
        policy.sfm_params = walker_params(env.crowd_sfm_params, walker)
    wrapped = FrozenAgents(env, lambda a: a.startswith("human_"), policy)
    t0 = time.time()
    wrapped.reset(seed=seed)
    positions = [env.pos.copy()]
    reached = [env.goals_reached.copy()]
    while not env._needs_reset:
        wrapped.step({})
        positions.append(env.pos.copy())
        reached.append(env.goals_reached.copy())
    goals = int(env.goals_reached.sum())
    wrapped.close()
    pos = np.asarray(positions)
    t = np.arange(len(pos)) * env.config.dt
    kin = track_kinematics([(t, pos[:, j]) for j in range(n)], STEP)
    arrived = np.diff(np.asarray(reached), axis=0) > 0  # (T, n): a goal reached in the step that ends at t[k + 1]
    split = [split_at_goals(t, pos[:, j], t[1:][arrived[:, j]]) for j in range(n)]
    plan_acc = np.concatenate([np.linalg.norm(np.diff(p, 2, axis=1), axis=2).ravel() / STEP ** 2 for p in plans]
                              or [np.zeros(0)])
    hit, total = collision_share(pos, 0.4)
    return {"scene": scene, "people": n, "speed": kin["speed"], "accel": kin["accel"], "jerk": kin["jerk"],
            "plan_accel": plan_acc, "accel_near_goal": np.concatenate([a for a, _ in split]),
            "accel_between_goals": np.concatenate([b for _, b in split]), "goals": goals, "overlap": (hit, total),
            "standing": standing(pos, env.config.dt),
            "accel_walking": np.concatenate([walking_accel(t, pos[:, j]) for j in range(n)]),
            "wall_s": time.time() - t0}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--variants", default="default", help="';'-separated variants, each 'default' or NAME=V,...")
    ap.add_argument("--scenes", default="lobby:12,corridor:10,home:5")
    ap.add_argument("--seconds", type=float, default=60.0)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--crowd", default="diffusion", choices=("diffusion", "sfm", "orca"),
                    help="the crowd model (sfm / orca: for comparison; no plans, only walker_ settings for sfm)")
    ap.add_argument("--out", default=None, help="append one JSON line per variant")
    ap.add_argument("--real", action="store_true",
                    help="first measure the real ETH/UCY tracks the same way (one line: accel_mean, accel_walking_mean, "
                         "standing_share); with --variants '' only that")
    ap.add_argument("--data", default=None, help="ETH/UCY folder for --real (default: the shared data folder)")
    args = ap.parse_args()
    if args.real:
        line = real_line(args.data)
        print(json.dumps(line), flush=True)
        if args.out:
            with open(args.out, "a") as f:
                f.write(json.dumps(line) + "\n")
    scenes = [(s.split(":")[0], int(s.split(":")[1])) for s in args.scenes.split(",")]
    for text in filter(None, args.variants.split(";")):
        settings = parse_variant(text)
        rows = [run(sc, n, args.seconds, settings, args.seed, args.crowd) for sc, n in scenes]
        cat = {q: np.concatenate([r[q] for r in rows])
               for q in ("speed", "accel", "jerk", "plan_accel", "accel_near_goal", "accel_between_goals", "accel_walking")}
        hit = sum(r["overlap"][0] for r in rows)
        total = sum(r["overlap"][1] for r in rows)
        line = {"variant": text.strip() or "default", "crowd": args.crowd, "scenes": args.scenes, "seconds": args.seconds,
                "seed": args.seed,
                **{f"{q}_mean": round(float(v.mean()), 4) if v.size else None for q, v in cat.items()},
                "near_goal_share": round(cat["accel_near_goal"].size / max(cat["accel"].size, 1), 4),
                "goals": sum(r["goals"] for r in rows), "overlap_share": round(hit / max(total, 1), 5),
                "standing_share": round(sum(r["standing"][0] for r in rows) / max(sum(r["standing"][1] for r in rows), 1), 4),
                "wall_s": round(sum(r["wall_s"] for r in rows), 1)}
        print(json.dumps(line), flush=True)
        if args.out:
            with open(args.out, "a") as f:
                f.write(json.dumps(line) + "\n")


if __name__ == "__main__":
    main()
