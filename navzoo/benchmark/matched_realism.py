"""Crowds against real people from the same start: ``navzoo eval crowd-matched [--quick] [--json]``.

The realism part of ``navzoo eval crowd`` runs each crowd model in the library scenes (rooms, doors,
crossings) and compares its kinematics with *all* ETH/UCY tracks (open plazas and streets). Geometry,
density and goals differ there, so part of any difference is the setting, not the model. This
evaluation removes that: every crowd model walks **the same people from the same positions to the
same places** as the recording, in the recording's open scene (:func:`navzoo.agents.replay.replay_scene`).

*Scenarios.* For each recording (the packaged ``eth``, ``univ``, ``zara1``, ``zara3``,
``uni_examples``) a scenario starts at recording time ``T`` every ``every`` seconds. Its people are
everyone present at ``T`` whose track goes on for at least ``min_remaining`` s (4.8 s, one forecast
horizon). Each person's *real segment* is their track from ``T`` for at most ``horizon`` s (12 s),
sampled every :data:`~navzoo.benchmark.crowd_eval.STEP` (0.4 s, linear between annotated frames).
Its first point is the person's start and its last point their goal. A person who walks at least
``min_walk`` m (2 m) is a *walker*; the others are in the scene, with their goal at their start, but
are not measured.

*Simulation.* ``NavEnv(scene="replay_<recording>", crowd_model=crowd, human_at_goal="stop",
dt=0.1)``, kinematic bodies, no robots, reset with these starts and goals. Each walker's preferred
speed is their real segment's mean speed (path length / duration, clipped to 0.3-2.0 m/s), so every
model is told the same pace. The scenario runs until every walker has arrived or for
``1.5 x horizon + 4`` s. Everyone starts from rest, so the first ``skip`` seconds (2 s) are left out
of the kinematics, of the real segments too.

*Measures*, per crowd model, pooled over all walkers of all scenarios:

* ``speed``, ``accel`` and ``jerk``: means, and 1-Wasserstein distance (``*_w1``) and Jensen-Shannon
  divergence (``*_js``) to the same walkers' real segments (the finite differences, bins and
  definitions of :mod:`navzoo.benchmark.crowd_eval`); the sim track ends where the walker arrives;
* ``ade_m``: mean distance between the simulated and the real position at the same time, over the
  real segment (a walker who arrived stays at the goal); ``fde_m``: at the segment's end;
* ``arrival_rate``: walkers within 0.5 m of their goal by ``1.5 x`` their real duration + 2 s;
  ``time_ratio``: median of sim time / real time over the walkers who arrived; ``never_arrived``: walkers
  never within 0.5 m of their goal, with the medians of their closest approach
  (``never_arrived_closest_m``) and of their distance at the end (``never_arrived_final_m``);
* ``collision_rate``: share of person-steps (every 0.1 s, everyone in the scene) with another centre
  closer than :data:`~navzoo.benchmark.crowd_eval.OVERLAP_M` (0.4 m); the real row gives the same
  people over the same windows.

The real row holds the means of the real segments. Scenarios are deterministic for a given seed.
"""

from __future__ import annotations

import argparse
import json
import multiprocessing as mp
import sys
import time
from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from typing import Any

import numpy as np

from navzoo.benchmark.crowd_eval import (
    BINS,
    OVERLAP_M,
    QUANTITIES,
    STEP,
    collision_share,
    distribution_distance,
    kinematics,
    resample,
)

__all__ = ["DIFFUSION_SETTINGS", "RECORDINGS", "Scenario", "apply_diffusion_settings", "check_diffusion_settings",
           "scenarios", "run_scenario",
           "evaluate", "markdown", "add_arguments", "run_cli"]

#: The recordings of the shared data set (``navzoo/assets/tracks``).
RECORDINGS = ("eth", "univ", "zara1", "zara3", "uni_examples")
CROWDS = ("diffusion", "sfm", "orca", "orca_rvo2")
SIM_DT = 0.1
ARRIVE_M = 0.5


class Scenario(dict):
    """One start time of one recording: ``recording``, ``t`` (s), ``starts`` (n, 2), ``goals`` (n, 2),
    ``walker`` (n,) bool, ``v_pref`` (n,), ``real`` (list of (K_i, 2) segments at :data:`STEP`) and
    ``real_present`` / ``real_pos`` (T, n, ...) at :data:`SIM_DT` for the real collision rate."""


def _interp(times: np.ndarray, xy: np.ndarray, t: np.ndarray) -> np.ndarray:
    return np.stack([np.interp(t, times, xy[:, 0]), np.interp(t, times, xy[:, 1])], axis=-1)


def scenarios(recording: str, every: float = 20.0, horizon: float = 12.0, min_remaining: float = 4.8,
              min_walk: float = 2.0, max_scenarios: int | None = None) -> list[Scenario]:
    """The scenarios of one recording (see the module doc), evenly thinned to ``max_scenarios``."""
    from navzoo.agents.replay import load_recording

    if not (every > 0 and horizon >= min_remaining > 0):
        raise ValueError(f"need every > 0 and horizon >= min_remaining > 0, got {every}, {horizon}, {min_remaining}")
    rec = load_recording(recording)
    t1 = rec.t1()
    out: list[Scenario] = []
    for T in np.arange(0.0, rec.duration - min_remaining + 1e-9, every):
        here = np.flatnonzero((rec.t0 <= T + 1e-9) & (t1 >= T + min_remaining - 1e-9))
        if here.size == 0:
            continue
        segs, present = [], []
        end = T + horizon
        fine = T + SIM_DT * np.arange(int(round(horizon / SIM_DT)) + 1)
        for i in here:
            times = rec.t0[i] + np.arange(len(rec.xy[i])) * rec.dt
            stop = min(end, times[-1])
            grid = T + STEP * np.arange(int(np.floor((stop - T) / STEP + 1e-9)) + 1)
            segs.append(_interp(times, rec.xy[i], grid))
            inside = fine <= times[-1] + 1e-9
            present.append((inside, _interp(times, rec.xy[i], fine)))
        starts = np.array([s[0] for s in segs])
        goals = np.array([s[-1] for s in segs])
        walk = np.array([np.linalg.norm(np.diff(s, axis=0), axis=1).sum() for s in segs])
        dur = np.array([(len(s) - 1) * STEP for s in segs])
        walker = np.linalg.norm(goals - starts, axis=1) >= min_walk
        if not walker.any():
            continue
        goals[~walker] = starts[~walker]
        v_pref = np.where(walker, np.clip(walk / np.maximum(dur, 1e-9), 0.3, 2.0), 0.5)
        out.append(Scenario(recording=rec.name, t=float(T), starts=starts, goals=goals, walker=walker, v_pref=v_pref,
                            real=segs, real_present=np.stack([p[0] for p in present], axis=1),
                            real_pos=np.stack([p[1] for p in present], axis=1)))
    if max_scenarios is not None and len(out) > max_scenarios:
        keep = np.unique(np.linspace(0, len(out) - 1, max_scenarios).round().astype(int))
        out = [out[k] for k in keep]
    return out


DIFFUSION_SETTINGS = ("n_samples", "replan_s", "guidance_scale", "path_weight", "blend_s", "smooth_weight",
                      "agent_buffer", "target_weight", "agent_weight", "map_weight",
                      "past_goal_turn_deg", "path_in_sight", "hold_in_sight",
                      "hold_floor_s", "floor_in_sight", "floor_ray", "fallen_in_map")


def check_diffusion_settings(settings: dict[str, float] | None) -> dict[str, float]:
    """A copy of ``settings`` after checking names (:data:`DIFFUSION_SETTINGS`) and values (finite;
    ``n_samples`` >= 1, ``replan_s`` > 0, the rest >= 0); a ValueError names the first bad one."""
    settings = dict(settings or {})
    unknown = sorted(set(settings) - set(DIFFUSION_SETTINGS))
    if unknown:
        raise ValueError(f"unknown diffusion crowd setting(s) {unknown}; choose from {list(DIFFUSION_SETTINGS)}")
    for key, value in settings.items():
        low, strict = (1.0, False) if key == "n_samples" else (0.0, key == "replan_s")
        if not (np.isfinite(value) and (value > low if strict else value >= low)):
            raise ValueError(f"diffusion crowd setting {key}={value!r} must be {'>' if strict else '>='} {low:g}")
    return settings


def apply_diffusion_settings(crowd: Any, settings: dict[str, float] | None) -> None:
    """Set attributes of a :class:`~navzoo.agents.diffusion.crowd.DiffusionCrowd` (any of
    :data:`DIFFUSION_SETTINGS`; the three guidance weights are kept as one tuple)."""
    settings = check_diffusion_settings(settings)
    names = ("target_weight", "agent_weight", "map_weight")
    crowd.weights = tuple(float(settings.pop(k, w)) for k, w in zip(names, crowd.weights, strict=True))
    for key, value in settings.items():
        setattr(crowd, key, type(getattr(crowd, key))(value))


@contextmanager
def diffusion_settings_for_new_crowds(settings: dict[str, float] | None) -> Iterator[None]:
    """Within the block, every :class:`~navzoo.agents.diffusion.crowd.DiffusionCrowd` built (e.g. by an env)
    gets ``settings`` (:func:`apply_diffusion_settings`); nothing changes when they are empty."""
    if not settings:
        yield
        return
    from navzoo.agents.diffusion.crowd import DiffusionCrowd

    settings = check_diffusion_settings(settings)
    init = DiffusionCrowd.__init__

    def with_settings(self, *args, **kwargs):
        init(self, *args, **kwargs)
        apply_diffusion_settings(self, settings)

    DiffusionCrowd.__init__ = with_settings
    try:
        yield
    finally:
        DiffusionCrowd.__init__ = init


def run_scenario(crowd: str, sc: Scenario, seed: int = 0, skip: float = 2.0,
                 diffusion_settings: dict[str, float] | None = None) -> dict[str, Any]:
    """Simulate one scenario with ``crowd``; returns the walkers' kinematics samples (sim and real),
    errors, arrivals and collision counts (see the module doc). ``diffusion_settings`` change the
    diffusion crowd's attributes (:func:`apply_diffusion_settings`)."""
    from navzoo.agents.crowd import CrowdPolicy
    from navzoo.envs.nav_env import NavEnv
    from navzoo.envs.wrappers import FrozenAgents

    n = len(sc["starts"])
    dur = np.array([(len(s) - 1) * STEP for s in sc["real"]])
    limit = 1.5 * dur.max() + 4.0
    env = NavEnv(scene=f"replay_{sc['recording']}", n_robots=0, n_humans=n, crowd_model=crowd, dt=SIM_DT,
                 time_limit=limit, human_at_goal="stop")
    wrapped = FrozenAgents(env, lambda a: a.startswith("human_"), CrowdPolicy(crowd))
    wrapped.reset(seed=seed, options={"human_starts": sc["starts"], "human_goals": sc["goals"]})
    env.v_pref[env.n_robots:] = sc["v_pref"]
    if env.diffusion is not None:  # its walking-in histories use the preferred speeds
        apply_diffusion_settings(env.diffusion, diffusion_settings)
        env.diffusion.reset(env)
    h = slice(env.n_robots, env.n_total)
    walker = sc["walker"]
    positions = [env.pos[h].copy()]
    arrive_t = np.full(n, np.nan)
    while not env._needs_reset:
        wrapped.step({})
        positions.append(env.pos[h].copy())
        t = (len(positions) - 1) * SIM_DT
        near = np.linalg.norm(env.pos[h] - sc["goals"], axis=1) < ARRIVE_M
        arrive_t = np.where(np.isnan(arrive_t) & near & walker, t, arrive_t)
        if not np.isnan(arrive_t[walker]).any():
            break
    wrapped.close()
    pos = np.asarray(positions)  # (T, n, 2) every SIM_DT
    times = np.arange(len(pos)) * SIM_DT
    k0 = int(round(skip / STEP))
    sim_kin: dict[str, list[np.ndarray]] = {q: [] for q in QUANTITIES}
    real_kin: dict[str, list[np.ndarray]] = {q: [] for q in QUANTITIES}
    ade, fde, ratio = [], [], []
    missed: list[tuple[float, float]] = []
    arrived = 0
    for j in np.flatnonzero(walker):
        real = sc["real"][j]
        grid = STEP * np.arange(len(real))
        sim_at = _interp(times, pos[:, j], np.minimum(grid, times[-1]))
        err = np.linalg.norm(sim_at - real, axis=1)
        ade.append(float(err.mean()))
        fde.append(float(err[-1]))
        ok = not np.isnan(arrive_t[j]) and arrive_t[j] <= 1.5 * dur[j] + 2.0
        arrived += int(ok)
        if np.isnan(arrive_t[j]):  # never within ARRIVE_M: how close did they come, and where did they end?
            to_goal = np.linalg.norm(pos[:, j] - sc["goals"][j], axis=1)
            missed.append((float(to_goal.min()), float(to_goal[-1])))
        if not np.isnan(arrive_t[j]):
            ratio.append(float(arrive_t[j] / max(dur[j], STEP)))
        last = len(times) if np.isnan(arrive_t[j]) else int(round(arrive_t[j] / SIM_DT)) + 1
        sim_track = resample(times[:last], pos[:last, j], STEP)  # up to the arrival
        for track, into in ((sim_track, sim_kin), (real, real_kin)):
            if len(track) > k0 + 3:
                for q, v in kinematics(track[k0:], STEP).items():
                    into[q].append(v)
    fine = min(len(pos), len(sc["real_pos"]))
    sim_hits = collision_share(pos[:fine], OVERLAP_M)
    real_hits = collision_share(sc["real_pos"][:fine], OVERLAP_M, sc["real_present"][:fine])
    cat = {q: (np.concatenate(v) if v else np.zeros(0)) for q, v in sim_kin.items()}
    cat_real = {q: (np.concatenate(v) if v else np.zeros(0)) for q, v in real_kin.items()}
    return {"crowd": crowd, "recording": sc["recording"], "t": sc["t"], "people": n, "walkers": int(walker.sum()),
            "sim": cat, "real": cat_real, "ade": ade, "fde": fde, "ratio": ratio, "arrived": arrived, "missed": missed,
            "sim_hits": sim_hits, "real_hits": real_hits, "sim_seconds": float(times[-1])}


def _job(job: tuple[str, Scenario, int, dict[str, float] | None]) -> dict[str, Any]:
    import os

    os.environ.setdefault("OMP_NUM_THREADS", "1")
    import torch

    torch.set_num_threads(1)
    crowd, sc, seed, settings = job
    t0 = time.time()
    row = run_scenario(crowd, sc, seed, diffusion_settings=settings)
    print(f"matched {crowd} {sc['recording']} t={sc['t']:.0f} s: {row['walkers']} walkers of {row['people']}, "
          f"ADE {np.mean(row['ade']):.2f} m, arrived {row['arrived']}, {time.time() - t0:.0f} s",
          file=sys.stderr, flush=True)
    return row


def _pool(rows: list[dict[str, Any]]) -> dict[str, Any]:
    sim = {q: np.concatenate([r["sim"][q] for r in rows]) for q in QUANTITIES}
    real = {q: np.concatenate([r["real"][q] for r in rows]) for q in QUANTITIES}
    out: dict[str, Any] = {}
    for q in QUANTITIES:
        out[f"{q}_mean"] = float(sim[q].mean()) if sim[q].size else float("nan")
        d = distribution_distance(sim[q], real[q], BINS[q])
        out[f"{q}_w1"], out[f"{q}_js"] = d["w1"], d["js"]
    walkers = sum(r["walkers"] for r in rows)
    ratios = [x for r in rows for x in r["ratio"]]
    missed = [m for r in rows for m in r["missed"]]
    hits = [sum(r["sim_hits"][k] for r in rows) for k in (0, 1)]
    out.update({
        "ade_m": float(np.mean([x for r in rows for x in r["ade"]])),
        "fde_m": float(np.mean([x for r in rows for x in r["fde"]])),
        "arrival_rate": sum(r["arrived"] for r in rows) / max(1, walkers),
        "time_ratio": float(np.median(ratios)) if ratios else float("nan"),
        "never_arrived": len(missed),
        "never_arrived_closest_m": float(np.median([m[0] for r in rows for m in r["missed"]])) if missed else float("nan"),
        "never_arrived_final_m": float(np.median([m[1] for r in rows for m in r["missed"]])) if missed else float("nan"),
        "collision_rate": hits[0] / max(1, hits[1]),
        "walkers": walkers, "scenarios": len(rows),
        "samples": {q: int(sim[q].size) for q in QUANTITIES},
    })
    per: dict[str, Any] = {}
    for name in dict.fromkeys(r["recording"] for r in rows):
        rs = [r for r in rows if r["recording"] == name]
        n = sum(r["walkers"] for r in rs)
        per[name] = {"walkers": n, "ade_m": float(np.mean([x for r in rs for x in r["ade"]])),
                     "arrival_rate": sum(r["arrived"] for r in rs) / max(1, n),
                     "never_arrived": sum(len(r["missed"]) for r in rs),
                     "never_arrived_closest_m": float(np.median([m[0] for r in rs for m in r["missed"]]))
                     if any(r["missed"] for r in rs) else float("nan"),
                     **{f"{q}_mean": float(np.concatenate([r["sim"][q] for r in rs]).mean())
                        if sum(r["sim"][q].size for r in rs) else float("nan") for q in ("speed", "accel")},
                     **{f"real_{q}_mean": float(np.concatenate([r["real"][q] for r in rs]).mean())
                        if sum(r["real"][q].size for r in rs) else float("nan") for q in ("speed", "accel")}}
    out["per_recording"] = per
    return out


def evaluate(crowds: Sequence[str] = ("diffusion", "sfm", "orca"), recordings: Sequence[str] = RECORDINGS,
             every: float = 20.0, max_scenarios: int | None = 8, seed: int = 0, workers: int = 1,
             quick: bool = False, diffusion_settings: dict[str, float] | None = None) -> dict[str, Any]:
    """Run every crowd on the scenarios of every recording; the table's rows (see the module doc)."""
    unknown = sorted(set(crowds) - set(CROWDS))
    if unknown:
        raise ValueError(f"unknown crowd model(s) {unknown}; choose from {list(CROWDS)}")
    diffusion_settings = check_diffusion_settings(diffusion_settings)
    if quick:
        recordings, max_scenarios = tuple(recordings)[:2], 1
    t0 = time.time()
    scs = [sc for name in recordings for sc in scenarios(name, every, max_scenarios=max_scenarios)]
    if not scs:
        raise ValueError(f"no scenario in recordings {list(recordings)} (every {every} s)")
    jobs = [(c, sc, seed, diffusion_settings) for c in crowds for sc in scs]
    jobs.sort(key=lambda j: -len(j[1]["starts"]))  # crowded scenarios first: they take longest
    if workers > 1:
        with mp.get_context("spawn").Pool(workers, maxtasksperchild=4) as pool:
            rows = pool.map(_job, jobs, chunksize=1)
    else:
        rows = [_job(j) for j in jobs]
    result: dict[str, Any] = {}
    for c in crowds:
        result[c] = _pool([r for r in rows if r["crowd"] == c])
    real_rows = [r for r in rows if r["crowd"] == crowds[0]]
    real = {q: np.concatenate([r["real"][q] for r in real_rows]) for q in QUANTITIES}
    hits = [sum(r["real_hits"][k] for r in real_rows) for k in (0, 1)]
    result["real"] = {**{f"{q}_mean": float(real[q].mean()) for q in QUANTITIES},
                      "collision_rate": hits[0] / max(1, hits[1]), "samples": {q: int(real[q].size) for q in QUANTITIES}}
    result["settings"] = {"recordings": list(recordings), "every_s": every, "max_scenarios": max_scenarios,
                          "scenarios": len(scs), "seed": seed, "quick": quick, "skip_s": 2.0, "horizon_s": 12.0,
                          "min_walk_m": 2.0, "sim_dt": SIM_DT, "step_s": STEP,
                          "diffusion_settings": dict(diffusion_settings or {}),
                          "per_recording": {name: sum(sc["recording"] == name for sc in scs) for name in
                                            dict.fromkeys(sc["recording"] for sc in scs)}}
    from navzoo.benchmark.crowd_eval import _machine

    result["machine"] = _machine()
    result["wall_s"] = round(time.time() - t0, 1)
    return result


def markdown(result: dict[str, Any]) -> str:
    crowds = [k for k in result if k not in ("real", "settings", "machine", "wall_s")]
    lines = ["| crowd | speed mean (W1) | accel mean (W1) | jerk mean (W1) | ADE / FDE (m) | arrived | time ratio | "
             "collisions |", "|---|---|---|---|---|---|---|---|"]
    for c in crowds:
        r = result[c]
        lines.append(f"| {c} | {r['speed_mean']:.2f} ({r['speed_w1']:.3f}) | {r['accel_mean']:.2f} ({r['accel_w1']:.3f}) | "
                     f"{r['jerk_mean']:.2f} ({r['jerk_w1']:.3f}) | {r['ade_m']:.2f} / {r['fde_m']:.2f} | "
                     f"{r['arrival_rate']:.3f} | {r['time_ratio']:.2f} | {r['collision_rate']:.4f} |")
    r = result["real"]
    lines.append(f"| real (same people) | {r['speed_mean']:.2f} | {r['accel_mean']:.2f} | {r['jerk_mean']:.2f} | | | | "
                 f"{r['collision_rate']:.4f} |")
    s = result["settings"]
    lines.append("")
    lines.append(f"{s['scenarios']} scenarios ({s['per_recording']}), {result[crowds[0]]['walkers']} walkers; "
                 f"{result['machine']}; {result['wall_s']:.0f} s.")
    return "\n".join(lines)


def _default(v: Any) -> Any:
    if isinstance(v, np.generic):
        return v.item()
    raise TypeError(f"not JSON serialisable: {type(v).__name__}")


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--crowds", default="diffusion,sfm,orca", help="comma-separated crowd models")
    parser.add_argument("--recordings", default=",".join(RECORDINGS), help="comma-separated recordings")
    parser.add_argument("--every", type=float, default=20.0, help="seconds between scenario start times")
    parser.add_argument("--max-scenarios", type=int, default=8, help="at most this many per recording (evenly spread)")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--workers", type=int, default=1, help="processes (default 1)")
    parser.add_argument("--quick", action="store_true", help="2 recordings, 1 scenario each")
    parser.add_argument("--diffusion-set", default="", metavar="K=V,...",
                        help=f"diffusion crowd settings, e.g. guidance_scale=0.025 (any of {', '.join(DIFFUSION_SETTINGS)})")
    parser.add_argument("--json", action="store_true", help="print JSON instead of the table")
    parser.add_argument("--out", default=None, help="also write the JSON result here")


def _settings(text: str) -> dict[str, float]:
    out = {}
    for part in filter(None, (p.strip() for p in text.split(","))):
        key, sep, value = part.partition("=")
        try:
            out[key.strip()] = float(value)
        except ValueError:
            sep = ""
        if not sep:
            raise ValueError(f"--diffusion-set takes NAME=NUMBER pairs, got {part!r}")
    return out


def run_cli(args: argparse.Namespace) -> int:
    result = evaluate([c for c in args.crowds.split(",") if c], [r for r in args.recordings.split(",") if r],
                      args.every, args.max_scenarios, args.seed, args.workers, args.quick,
                      _settings(args.diffusion_set))
    text = json.dumps(result, default=_default, indent=1)
    if args.out:
        from pathlib import Path

        Path(args.out).parent.mkdir(parents=True, exist_ok=True)
        Path(args.out).write_text(text + "\n")
    print(text if args.json else markdown(result))
    return 0


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    add_arguments(parser)
    return run_cli(parser.parse_args(argv))


if __name__ == "__main__":
    raise SystemExit(main())
