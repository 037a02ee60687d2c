"""Evaluate the closed-loop crowds: ``navzoo eval crowd [--quick] [--json]``.

Three measurements of the trajectory generators of kinematic and physics pedestrians
(``crowd_model`` in ``diffusion``, ``sfm``, ``orca``, ``orca_rvo2``):

**Realism** against real pedestrian tracks (ETH/UCY). Every crowd drives kinematic pedestrians
(``human_model="kinematic"``, no robots, ``dt`` = 0.1 s) in the scenes of
:data:`navzoo.benchmark.pedestrians.SCENES` (3-15 people, :func:`~navzoo.benchmark.pedestrians.people_per_scene`)
for ``seconds`` each. Positions are recorded at every env step; each person's track is resampled by
linear interpolation to :data:`STEP` = 0.4 s (the data's step) and cut into *continuous pieces*:
a step longer than ``max_jump`` (2 m in 0.4 s, i.e. 5 m/s: a teleport or goal reset, not walking)
splits the track and no difference is taken across it. Samples before a simulated person first
moves (speed below ``min_start_speed`` = 0.1 m/s, a spawn artifact) are dropped; real tracks are
kept whole (people standing in the data are real behaviour). Within a piece, by finite differences
at 0.4 s:

* speed ``|x[k+1] - x[k]| / dt`` (m/s),
* acceleration ``|x[k+1] - 2 x[k] + x[k-1]| / dt^2`` (m/s^2),
* jerk ``|x[k+2] - 3 x[k+1] + 3 x[k] - x[k-1]| / dt^3`` (m/s^3).

The real rows are all files of the ``all_data`` part of :func:`navzoo.forecast.data.discover` in the
default data folder (the ``train``/``val`` files are a split of the same recordings and are not
counted twice), each with its own time step (:func:`navzoo.forecast.data.read_tracks`: 0.4 s, biwi_eth
0.667 s, resampled to 0.4 s here), a track cut where a pedestrian misses annotated frames.

For every crowd and quantity the report gives the mean, the 1-Wasserstein distance to the real
values (:func:`scipy.stats.wasserstein_distance` on the raw samples, in the quantity's unit) and the
Jensen-Shannon divergence (base 2, in [0, 1]; the square of scipy's ``jensenshannon`` distance) of
the histograms on the fixed bins :data:`BINS` (values beyond the last edge go into the last bin).

*Collision rate*: the share of person-steps (at the sim's ``dt``; for the real data, at the file's
annotated frames) in which the person's centre is closer than a threshold to another person's centre.
``collision_rate`` uses :data:`OVERLAP_M` = 0.4 m for every crowd and the real data (two real bodies,
~0.2 m torso half-width each, overlapping); ``collision_rate_env_radius`` uses 2 x the env's body
radius (``NavConfig.human_radius``, 0.3 m: 0.6 m, the discs of the simulation touching), given for
the real data too for reference.

**Reliability** (the paper's pedestrian navigation reliability table), by
:func:`navzoo.benchmark.pedestrians.following`: rows SFM+AMP, Diffusion+AMP, SFM+kinematic,
Diffusion+kinematic; success, fall, map collision, agent collision rates of trips and path error, in
the 8 scenes with 3-15 people for ``seconds`` each, at 30 Hz. For kinematic bodies falls are 0 by
construction, contacts are geometric (centre within the body radius of a wall; centres closer than
two radii), the path error of the diffusion crowd is measured to the current point of the person's
diffusion plan and is not applicable (None) to the social-force crowd, whose success then equals its
goal rate. The paper's figures are added as reference rows (:data:`PAPER_RELIABILITY`). Each row also
says how its people walked (``walked``): their centres at every step of the same runs (a fallen body's track
ends at its fall) go through the realism part's kinematics and distances, so that physics bodies and
kinematic ones can be compared with the real tracks alike; collisions there count standing people only.

**Cost**: milliseconds per diffusion replan (:meth:`DiffusionCrowd.plan_now`, all pedestrians of a
world in one batch) for 1, 16 and 64 pedestrians on the CPU (and CUDA when available; median of
``repeats`` replans after one warm-up), and the env step time (mean over a few hundred steps of the
ms per ``env.step`` through the crowd policy, replans amortised; the median step is given too) with
the diffusion crowd next to the social-force crowd in the same scene with the same people. Timings
are wall-clock on a machine that may be shared: other load (and torch's intra-op threads competing
with it) inflates them.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import sys
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from navzoo.benchmark import pedestrians

__all__ = [
    "BINS", "CROWDS", "OVERLAP_M", "PAPER_RELIABILITY", "RELIABILITY_ROWS", "STEP",
    "resample", "continuous_pieces", "trim_still_start", "kinematics", "track_kinematics",
    "collision_share", "walked_kinematics", "walked_collisions", "distribution_distance", "real_data", "crowd_scene",
    "realism", "reliability",
    "replan_cost", "step_cost", "cost", "evaluate", "markdown", "main", "add_arguments", "run_cli", "row_resume_file",
]

#: Crowd models this evaluation can run (``NavConfig.crowd_model``).
CROWDS = ("diffusion", "sfm", "orca", "orca_rvo2")
#: Crowds of the realism part by default.
DEFAULT_CROWDS = ("diffusion", "sfm", "orca")
#: Seconds per sample of the kinematics (the ETH/UCY annotation step).
STEP = 0.4
#: A step longer than this (m in one :data:`STEP`) is a teleport: no difference is taken across it.
MAX_JUMP_M = 2.0
#: Simulated samples before a person first moves faster than this (m/s) are dropped.
MIN_START_SPEED = 0.1
#: Centre distance (m) below which two people count as colliding (bodies overlapping), for all rows.
OVERLAP_M = 0.4
#: Histogram bin edges of the Jensen-Shannon divergence (speed m/s, acceleration m/s^2, jerk m/s^3).
BINS: dict[str, np.ndarray] = {
    "speed": np.linspace(0.0, 3.0, 31),  # 0.1 m/s bins
    "accel": np.linspace(0.0, 4.0, 41),  # 0.1 m/s^2 bins (real: 99 % below 1.3)
    "jerk": np.linspace(0.0, 10.0, 41),  # 0.25 m/s^3 bins (real: 99 % below 3.7)
}
QUANTITIES = tuple(BINS)
#: Rows of the reliability table: (crowd_model, human_model).
RELIABILITY_ROWS: dict[str, tuple[str, str]] = {
    "sfm+amp": ("sfm", "amp"),
    "diffusion+amp": ("diffusion", "amp"),
    "sfm+kinematic": ("sfm", "kinematic"),
    "diffusion+kinematic": ("diffusion", "kinematic"),
}
#: The paper's pedestrian navigation reliability table (Isaac Lab): rates as shares, path error in m.
PAPER_RELIABILITY: dict[str, dict[str, float]] = {
    "sfm+amp": {"success_rate": 0.7424, "fall_rate": 0.0499, "map_collision_rate": 0.0374,
                "agent_collision_rate": 0.1717, "path_error_m": 0.189},
    "diffusion+amp": {"success_rate": 0.8867, "fall_rate": 0.0112, "map_collision_rate": 0.0240,
                      "agent_collision_rate": 0.0781, "path_error_m": 0.153},
}
REALISM_DT = 0.1  # s, the kinematic crowds' control period in the realism runs (NavConfig's default)
QUICK_SCENES = ("lobby", "corridor")
QUICK_SECONDS = 20.0


# ---------------------------------------------------------------------------------------- metrics
def resample(t: np.ndarray, xy: np.ndarray, step: float = STEP) -> np.ndarray:
    """Positions (K, 2) at ``t[0], t[0] + step, ...`` up to ``t[-1]``, linear between the given samples.

    Args:
        t: (T,) increasing sample times (s).
        xy: (T, 2) positions.
        step: the new sample spacing (s).
    """
    t = np.asarray(t, dtype=np.float64)
    xy = np.asarray(xy, dtype=np.float64).reshape(-1, 2)
    if t.shape != (len(xy),):
        raise ValueError(f"resample needs one time per position, got {t.shape} times for {len(xy)} positions")
    if not step > 0:
        raise ValueError(f"step must be > 0, got {step!r}")
    if len(t) == 0:
        return np.zeros((0, 2))
    if np.any(np.diff(t) <= 0):
        raise ValueError("resample needs strictly increasing times")
    grid = t[0] + step * np.arange(int(np.floor((t[-1] - t[0]) / step + 1e-9)) + 1)
    return np.stack([np.interp(grid, t, xy[:, 0]), np.interp(grid, t, xy[:, 1])], axis=1)


def continuous_pieces(xy: np.ndarray, max_jump: float = MAX_JUMP_M) -> list[np.ndarray]:
    """Split a track (K, 2) wherever one step is longer than ``max_jump`` metres (a teleport/reset)."""
    xy = np.asarray(xy, dtype=np.float64).reshape(-1, 2)
    if len(xy) == 0:
        return []
    cuts = np.flatnonzero(np.linalg.norm(np.diff(xy, axis=0), axis=1) > max_jump) + 1
    return [piece for piece in np.split(xy, cuts) if len(piece)]


def trim_still_start(xy: np.ndarray, step: float = STEP, min_speed: float = MIN_START_SPEED) -> np.ndarray:
    """Drop the samples before the first step faster than ``min_speed`` (a person waiting at its spawn
    point); an empty array if the person never moves."""
    xy = np.asarray(xy, dtype=np.float64).reshape(-1, 2)
    moving = np.flatnonzero(np.linalg.norm(np.diff(xy, axis=0), axis=1) / step >= min_speed)
    return xy[moving[0]:] if moving.size else xy[:0]


def kinematics(xy: np.ndarray, step: float = STEP) -> dict[str, np.ndarray]:
    """Speed (K-1,), acceleration magnitude (K-2,) and jerk magnitude (K-3,) of one continuous piece
    (K, 2) sampled every ``step`` seconds, by forward finite differences (see the module doc)."""
    xy = np.asarray(xy, dtype=np.float64).reshape(-1, 2)
    out = {}
    d = xy
    for order, name in enumerate(QUANTITIES, start=1):
        d = np.diff(d, axis=0)
        out[name] = np.linalg.norm(d, axis=1) / step ** order
    return out


#: m/s: below this speed over a ``STEP``-long interval a person stands (:func:`standing`).
STAND_SPEED = 0.1


def standing(pos: np.ndarray, dt: float, step: float = STEP, speed: float = STAND_SPEED) -> tuple[int, int]:
    """Person-steps standing in ``pos`` ((T, n, 2) positions every ``dt`` s, whole tracks, no start trimmed): the
    number of ``step``-long intervals (positions subsampled every ``step`` s) covered at under ``speed``, and the
    number of intervals. Standing people (waiting, queueing, jammed) add near-zero accelerations."""
    k = max(1, int(round(step / dt)))
    sp = np.linalg.norm(np.diff(np.asarray(pos)[::k], axis=0), axis=-1) / (k * dt)
    return int((sp < speed).sum()), int(sp.size)


def walking_accel(t: np.ndarray, xy: np.ndarray, step: float = STEP, speed: float = STAND_SPEED,
                  trim: bool = True, max_jump: float = MAX_JUMP_M) -> np.ndarray:
    """A track's accelerations while walking: resampled to ``step``, its still start trimmed (``trim``, as for
    simulated people), cut at jumps, and only the samples whose two speeds are both at least ``speed`` (an
    acceleration between a standing and a moving step is a start or a stop, not walking)."""
    res = resample(np.asarray(t, dtype=float), np.asarray(xy, dtype=float), step)
    if trim:
        res = trim_still_start(res, step, MIN_START_SPEED)
    out = []
    for piece in continuous_pieces(res, max_jump):
        kin = kinematics(piece, step)
        v, a = kin["speed"], kin["accel"]
        out.append(a[(v[:-1] >= speed) & (v[1:] >= speed)])
    return np.concatenate(out) if out else np.zeros(0)


def track_kinematics(tracks: Sequence[tuple[np.ndarray, np.ndarray]], step: float = STEP,
                     max_jump: float = MAX_JUMP_M, min_start_speed: float | None = MIN_START_SPEED
                     ) -> dict[str, np.ndarray]:
    """Pooled speed / acceleration / jerk samples of tracks given as ``(t (T,), xy (T, 2))``: each is
    resampled to ``step``, its still start trimmed (unless ``min_start_speed`` is None), cut at jumps
    longer than ``max_jump`` and differenced piece by piece."""
    parts: dict[str, list[np.ndarray]] = {q: [] for q in QUANTITIES}
    for t, xy in tracks:
        res = resample(t, xy, step)
        if min_start_speed is not None:
            res = trim_still_start(res, step, min_start_speed)
        for piece in continuous_pieces(res, max_jump):
            for q, v in kinematics(piece, step).items():
                parts[q].append(v)
    return {q: np.concatenate(v) if v else np.zeros(0) for q, v in parts.items()}


def walked_kinematics(pos: np.ndarray, dt: float, step: float = STEP, max_jump: float = MAX_JUMP_M,
                      min_start_speed: float | None = MIN_START_SPEED) -> dict[str, np.ndarray]:
    """Pooled speed / acceleration / jerk samples of people's centres recorded every ``dt`` seconds.

    Args:
        pos: (T, N, 2) centres, NaN where a person is not walking (a fallen body): each person's track is
            split at its NaN gaps, and no difference is taken across one.
        dt: seconds between the recorded rows.

    The pieces then go through :func:`track_kinematics` (resampled to ``step``, still start trimmed, cut at
    jumps)."""
    pos = np.asarray(pos, dtype=np.float64)
    if pos.ndim != 3 or pos.shape[-1] != 2:
        raise ValueError(f"pos must be (T, N, 2), got {pos.shape}")
    if not dt > 0:
        raise ValueError(f"dt must be > 0, got {dt!r}")
    t = np.arange(len(pos)) * float(dt)
    tracks = []
    for j in range(pos.shape[1]):
        ok = ~np.isnan(pos[:, j]).any(axis=1)
        edges = np.flatnonzero(np.diff(np.r_[0, ok.astype(np.int8), 0]))
        tracks += [(t[a:b], pos[a:b, j]) for a, b in zip(edges[::2], edges[1::2], strict=True) if b - a >= 2]
    return track_kinematics(tracks, step, max_jump, min_start_speed)


def walked_collisions(pos: np.ndarray, threshold: float = OVERLAP_M, chunk: int = 1000) -> tuple[int, int]:
    """:func:`collision_share` of centres (T, N, 2) with NaN rows for people not walking (not counted, and
    not counted against), in chunks of ``chunk`` steps (the pairwise distances of a long run at once are big)."""
    pos = np.asarray(pos, dtype=np.float64)
    present = ~np.isnan(pos).any(axis=-1)
    hit = total = 0
    for a in range(0, len(pos), chunk):
        h, n = collision_share(np.nan_to_num(pos[a:a + chunk]), threshold, present[a:a + chunk])
        hit, total = hit + h, total + n
    return hit, total


def collision_share(pos: np.ndarray, threshold: float, present: np.ndarray | None = None) -> tuple[int, int]:
    """Person-steps with another person's centre closer than ``threshold`` metres.

    Args:
        pos: (T, N, 2) centres at every step.
        threshold: centre distance (m).
        present: (T, N) bool, who is there at each step (default: everyone).

    Returns:
        (colliding person-steps, person-steps): the share is their ratio.
    """
    pos = np.asarray(pos, dtype=np.float64)
    if pos.ndim != 3 or pos.shape[-1] != 2:
        raise ValueError(f"pos must be (T, N, 2), got {pos.shape}")
    present = np.ones(pos.shape[:2], dtype=bool) if present is None else np.asarray(present, dtype=bool)
    d = np.linalg.norm(pos[:, :, None, :] - pos[:, None, :, :], axis=-1)
    n = pos.shape[1]
    d[:, np.arange(n), np.arange(n)] = np.inf
    d = np.where(present[:, :, None] & present[:, None, :], d, np.inf)
    hit = (d < threshold).any(axis=2) & present
    return int(hit.sum()), int(present.sum())


def distribution_distance(sim: np.ndarray, real: np.ndarray, bins: np.ndarray) -> dict[str, float]:
    """1-Wasserstein distance of the samples and Jensen-Shannon divergence (base 2) of their histograms
    on ``bins`` (values clipped into the first/last bin); NaN when either side has no sample."""
    from scipy.spatial.distance import jensenshannon
    from scipy.stats import wasserstein_distance

    sim = np.asarray(sim, dtype=np.float64).ravel()
    real = np.asarray(real, dtype=np.float64).ravel()
    if sim.size == 0 or real.size == 0:
        return {"w1": float("nan"), "js": float("nan")}
    lo, hi = float(bins[0]), float(bins[-1])
    eps = 1e-9 * (hi - lo)
    h_sim = np.histogram(np.clip(sim, lo, hi - eps), bins)[0].astype(np.float64)
    h_real = np.histogram(np.clip(real, lo, hi - eps), bins)[0].astype(np.float64)
    js = float(jensenshannon(h_sim / h_sim.sum(), h_real / h_real.sum(), base=2) ** 2)
    return {"w1": float(wasserstein_distance(sim, real)), "js": max(js, 0.0)}


def _summary(kin: dict[str, np.ndarray], real: dict[str, np.ndarray] | None) -> dict[str, Any]:
    out: dict[str, Any] = {}
    for q in QUANTITIES:
        v = kin[q]
        out[f"{q}_mean"] = float(v.mean()) if v.size else float("nan")
        out[f"{q}_median"] = float(np.median(v)) if v.size else float("nan")
        if real is not None:
            dist = distribution_distance(v, real[q], BINS[q])
            out[f"{q}_w1"], out[f"{q}_js"] = dist["w1"], dist["js"]
    out["samples"] = {q: int(kin[q].size) for q in QUANTITIES}
    return out


# ---------------------------------------------------------------------------------------- real data
def file_tracks(tr: Any) -> list[tuple[np.ndarray, np.ndarray]]:
    """The tracks of one recording (:func:`navzoo.forecast.data.read_tracks`) as ``(t (T,), xy (T, 2))`` pieces:
    one per person and run of consecutive annotated frames, times from 0 at the piece's first frame."""
    order = np.lexsort((tr.frame, tr.ped))
    ped, frame, xy = tr.ped[order], tr.frame[order], tr.xy[order]
    cuts = np.flatnonzero((np.diff(ped) != 0) | (np.diff(frame) != tr.frame_step)) + 1
    return [((f_piece - f_piece[0]) / tr.frame_step * tr.dt, xy_piece)
            for f_piece, xy_piece in zip(np.split(frame, cuts), np.split(xy, cuts), strict=True)]


def real_data(data_dir: str | Path | None = None, step: float = STEP, max_jump: float = MAX_JUMP_M,
              thresholds: dict[str, float] | None = None) -> tuple[dict[str, np.ndarray], dict[str, Any]]:
    """Kinematics and collision counts of the real ETH/UCY tracks (see the module doc).

    Returns:
        (pooled samples {speed, accel, jerk}, summary: files, per-threshold collision counts, rates).
    """
    from navzoo.forecast import data as fdata

    thresholds = thresholds or _thresholds(2 * _default_radius())
    folder = Path(data_dir) if data_dir is not None else fdata.default_data_dir()
    found = fdata.discover(folder)
    files = found["all"] or {**found["train"], **found["val"]}
    if not files:
        raise FileNotFoundError(f"no ETH/UCY files in {folder}")
    tracks: list[tuple[np.ndarray, np.ndarray]] = []
    counts = {k: [0, 0] for k in thresholds}
    per_file = []
    for scene, path in sorted(files.items()):
        tr = fdata.read_tracks(path)
        n_before = len(tracks)
        tracks.extend(file_tracks(tr))
        # Collisions frame by frame (rows are sorted by (frame, ped)).
        starts = np.flatnonzero(np.r_[True, np.diff(tr.frame) != 0])
        file_counts = {}
        for name, thr in thresholds.items():
            hit = total = 0
            for rows in np.split(np.arange(len(tr.frame)), starts[1:]):
                h, n = collision_share(tr.xy[rows][None], thr)
                hit, total = hit + h, total + n
            counts[name][0] += hit
            counts[name][1] += total
            file_counts[name] = hit / max(total, 1)
        per_file.append({"scene": scene, "dt": tr.dt, "tracks": len(tracks) - n_before, "rows": len(tr.frame),
                         **{f"collision_rate{_suffix(k)}": v for k, v in file_counts.items()}})
    kin = track_kinematics(tracks, step, max_jump, min_start_speed=None)
    summary = _summary(kin, None)
    walking = np.concatenate([walking_accel(t, xy, step, trim=False, max_jump=max_jump) for t, xy in tracks])
    summary["accel_walking_mean"] = float(walking.mean()) if walking.size else float("nan")
    # the speeds are those of every step-long interval of the whole tracks (no start trimmed), as standing() counts
    summary["standing_share"] = float(np.mean(kin["speed"] < STAND_SPEED)) if kin["speed"].size else float("nan")
    for name, (hit, total) in counts.items():
        summary[f"collision_rate{_suffix(name)}"] = hit / max(total, 1)
    summary["person_steps"] = counts[next(iter(counts))][1]
    summary["thresholds_m"] = dict(thresholds)
    summary["files"] = per_file
    return kin, summary


def _default_radius() -> float:
    from navzoo.envs.config import NavConfig

    return float(NavConfig.human_radius)


def _thresholds(env_threshold: float, overlap_m: float = OVERLAP_M) -> dict[str, float]:
    return {"overlap": float(overlap_m), "env_radius": float(env_threshold)}


def _suffix(name: str) -> str:
    return "" if name == "overlap" else f"_{name}"


# ---------------------------------------------------------------------------------------- realism
def _check_crowds(crowds: Sequence[str]) -> tuple[str, ...]:
    crowds = tuple(crowds)
    bad = [c for c in crowds if c not in CROWDS]
    if bad or not crowds:
        raise ValueError(f"unknown crowd model(s) {bad or crowds!r}; choose from {', '.join(CROWDS)}")
    return crowds


def _check_scenes(scenes: Sequence[str]) -> tuple[str, ...]:
    """Library scene names; ``heldout`` stands for the scenes of :data:`navzoo.benchmark.pedestrians.HELDOUT_SCENES`
    (:func:`navzoo.benchmark.pedestrians.expand_scenes`)."""
    return pedestrians.expand_scenes(scenes)


def crowd_scene(crowd: str, scene: str, n: int, seconds: float, seed: int = 0, dt: float = REALISM_DT,
                step: float = STEP, max_jump: float = MAX_JUMP_M, min_start_speed: float = MIN_START_SPEED,
                overlap_m: float = OVERLAP_M, env_overrides: dict[str, Any] | None = None) -> dict[str, Any]:
    """One scene of :func:`realism`: ``n`` kinematic pedestrians of ``crowd`` for ``seconds``; returns
    the pooled kinematics samples and collision counts (at the sim's dt). ``env_overrides``: further NavConfig
    fields (e.g. ``{"crowd_wall_strength": 0.3}``).

    The run uses one torch thread, however it is called (:func:`navzoo.torch_threads.one_torch_thread`), so the
    diffusion crowd walks the same in ``--workers 1`` (the calling process) as in a pool of single-threaded
    workers; until 2026-12-03 the calling process used all its threads, and the two could differ."""
    from navzoo.torch_threads import one_torch_thread

    with one_torch_thread():
        return _crowd_scene(crowd, scene, n, seconds, seed, dt, step, max_jump, min_start_speed, overlap_m,
                            env_overrides)


def _crowd_scene(crowd: str, scene: str, n: int, seconds: float, seed: int, dt: float, step: float,
                 max_jump: float, min_start_speed: float, overlap_m: float = OVERLAP_M,
                 env_overrides: dict[str, Any] | None = None) -> dict[str, Any]:
    from navzoo.agents.crowd import CrowdPolicy
    from navzoo.envs.nav_env import NavEnv
    from navzoo.envs.wrappers import FrozenAgents

    t0 = time.time()
    env = NavEnv(scene=scene, n_robots=0, n_humans=n, crowd_model=crowd, dt=dt, time_limit=seconds,
                 **(env_overrides or {}))
    wrapped = FrozenAgents(env, lambda a: a.startswith("human_"), CrowdPolicy(crowd))
    wrapped.reset(seed=seed)
    radius = env.radius[env.n_robots:]
    positions = [env.pos[env.n_robots:].copy()]
    while not env._needs_reset:
        wrapped.step({})
        positions.append(env.pos[env.n_robots:].copy())
    goals = int(env.goals_reached.sum())
    wrapped.close()
    pos = np.asarray(positions)  # (T + 1, n, 2)
    t = np.arange(len(pos)) * dt
    kin = track_kinematics([(t, pos[:, j]) for j in range(n)], step, max_jump, min_start_speed)
    counts = {name: collision_share(pos, thr) for name, thr in _thresholds(2 * float(radius.max()), overlap_m).items()}
    walking = np.concatenate([walking_accel(t, pos[:, j], step, max_jump=max_jump) for j in range(n)] or [np.zeros(0)])
    wall = time.time() - t0
    line = (f"crowd realism {crowd} {scene} ({n} people, {seconds:.0f} s): mean speed "
            f"{kin['speed'].mean() if kin['speed'].size else float('nan'):.2f} m/s, collision share "
            f"{counts['overlap'][0] / max(counts['overlap'][1], 1):.4f}, goals {goals}, {wall:.0f} s")
    print(line, file=sys.stderr, flush=True)
    return {"crowd": crowd, "scene": scene, "pedestrians": n, "kin": kin, "counts": counts, "goals": goals,
            "standing": standing(pos, dt, step), "accel_walking": walking,
            "env_radius_threshold_m": 2 * float(radius.max()), "wall_s": round(wall, 1)}


def realism(crowds: Sequence[str] = DEFAULT_CROWDS, scenes: Sequence[str] = pedestrians.SCENES,
            seconds: float = 200.0, seed: int = 0, workers: int = 1, people: Sequence[int] | None = None,
            data_dir: str | Path | None = None, dt: float = REALISM_DT,
            real: tuple[dict[str, np.ndarray], dict[str, Any]] | None = None,
            env_overrides: dict[str, Any] | None = None) -> dict[str, Any]:
    """Realism of each crowd against the real tracks (see the module doc): ``{crowd: {...}, "real": {...}}``.
    ``real``: :func:`real_data`'s result, if already loaded (else it is loaded from ``data_dir``).
    ``env_overrides``: further NavConfig fields of every scene run (checked as
    :func:`navzoo.benchmark.pedestrians.check_env_overrides` checks them)."""
    overrides = pedestrians.check_env_overrides(env_overrides) or None
    crowds = _check_crowds(crowds)
    scenes = _check_scenes(scenes)
    people = list(people) if people is not None else pedestrians.people_per_scene(len(scenes))
    if len(people) != len(scenes):
        raise ValueError(f"need one people count per scene, got {len(people)} for {len(scenes)} scenes")
    real_kin, real_summary = real if real is not None else real_data(data_dir)
    jobs = [(c, sc, n, seconds, seed, dt, STEP, MAX_JUMP_M, MIN_START_SPEED, OVERLAP_M, overrides)
            for c in crowds for sc, n in zip(scenes, people, strict=True)]
    rows = pedestrians._pool_map(crowd_scene, jobs, workers)
    out: dict[str, Any] = {}
    for c in crowds:
        mine = [r for r in rows if r["crowd"] == c]
        kin = {q: np.concatenate([r["kin"][q] for r in mine]) for q in QUANTITIES}
        summary = _summary(kin, real_kin)
        for name in ("overlap", "env_radius"):
            hit = sum(r["counts"][name][0] for r in mine)
            total = sum(r["counts"][name][1] for r in mine)
            summary[f"collision_rate{_suffix(name)}"] = hit / max(total, 1)
        summary["person_steps"] = sum(r["counts"]["overlap"][1] for r in mine)
        summary["env_radius_threshold_m"] = mine[0]["env_radius_threshold_m"]
        summary["goals_reached"] = sum(r["goals"] for r in mine)
        walking = np.concatenate([r["accel_walking"] for r in mine])
        summary["accel_walking_mean"] = float(walking.mean()) if walking.size else float("nan")
        summary["standing_share"] = sum(r["standing"][0] for r in mine) / max(sum(r["standing"][1] for r in mine), 1)
        summary["scenes"] = [{"scene": r["scene"], "pedestrians": r["pedestrians"], "goals": r["goals"],
                              "speed_mean": float(r["kin"]["speed"].mean()) if r["kin"]["speed"].size else None,
                              "collision_rate": r["counts"]["overlap"][0] / max(r["counts"]["overlap"][1], 1),
                              "standing_share": r["standing"][0] / max(r["standing"][1], 1),
                              "wall_s": r["wall_s"]} for r in mine]
        out[c] = summary
    out["real"] = real_summary
    out["settings"] = {"scenes": list(scenes), "people": people, "seconds_per_scene": seconds, "sim_dt": dt,
                       "step_s": STEP, "max_jump_m": MAX_JUMP_M, "min_start_speed": MIN_START_SPEED,
                       "overlap_m": OVERLAP_M, "bins": {q: [float(BINS[q][0]), float(BINS[q][-1]), len(BINS[q]) - 1]
                                                        for q in QUANTITIES}}
    if overrides:
        out["settings"]["env_overrides"] = overrides
    return out


# ---------------------------------------------------------------------------------------- reliability
def reliability(rows: Sequence[str] = tuple(RELIABILITY_ROWS), scenes: Sequence[str] = pedestrians.SCENES,
                seconds: float = 200.0, seed: int = 0, workers: int = 1, policy_dir: str | None = None,
                people: Sequence[int] | None = None, on_row=None, seeds: Sequence[int] | None = None,
                resume_prefix: str | Path | None = None,
                real_kin: dict[str, np.ndarray] | None = None,
                env_overrides: dict[str, Any] | None = None) -> dict[str, Any]:
    """The reliability table: :func:`navzoo.benchmark.pedestrians.following` for each row of
    :data:`RELIABILITY_ROWS` named in ``rows`` (``people`` per scene, default 3-15 spread over
    ``scenes``; ``seconds`` each). ``on_row(rows_so_far)`` is called after each row (to save them).
    ``seeds`` (instead of ``seed``): every row over several seeds (rates pooled, ``by_seed`` per seed).
    ``resume_prefix``: each row keeps its finished scene runs in ``<prefix>.<row>.following.jsonl``,
    so that an interrupted table rerun with the same settings resumes there (the caller removes them).
    Every row also has ``walked``: how its people walked (physics bodies or kinematic ones), in the terms of the
    realism part (:func:`navzoo.benchmark.pedestrians.following` with ``walked=True``), with the distances to
    ``real_kin`` (:func:`real_data`'s samples) when given. ``env_overrides``: further NavConfig fields of every run."""
    scenes = _check_scenes(scenes)
    bad = [r for r in rows if r not in RELIABILITY_ROWS]
    if bad:
        raise ValueError(f"unknown reliability row(s) {bad}; choose from {', '.join(RELIABILITY_ROWS)}")
    out: dict[str, Any] = {}
    for name in rows:
        crowd, body = RELIABILITY_ROWS[name]
        t0 = time.time()
        metrics, _ = pedestrians.following(scenes, seconds, seed, policy_dir, workers=workers, crowd_model=crowd,
                                           human_model=body, pose_every=0,
                                           people=None if people is None else list(people),
                                           seeds=None if seeds is None else list(seeds),
                                           resume=None if resume_prefix is None else row_resume_file(resume_prefix, name),
                                           walked=True, real_kin=real_kin, env_overrides=env_overrides)
        metrics.update({"crowd_model": crowd, "human_model": body, "wall_s": round(time.time() - t0, 1)})
        if body == "kinematic":
            metrics["notes"] = ("kinematic bodies: no falls; contacts geometric (centre within the body radius "
                                "of a wall, centres closer than two radii)" +
                                ("; path error to the current diffusion plan point" if crowd == "diffusion"
                                 else "; no target trajectory: path error n/a, success = goal reached"))
        print(f"reliability {name}: success {metrics['success_rate']:.3f}, fall {metrics['fall_rate']:.3f}, "
              f"trips {metrics['trips']}, {metrics['wall_s']:.0f} s", file=sys.stderr, flush=True)
        out[name] = metrics
        if on_row is not None:
            on_row(out)
    return out


def row_resume_file(prefix: str | Path, row: str) -> Path:
    """Where :func:`reliability` keeps the finished scene runs of ``row`` while it runs."""
    return Path(f"{prefix}.{row.replace('+', '_')}.following.jsonl")


# ---------------------------------------------------------------------------------------- cost
def _on_device(crowd: Any, device: str) -> None:
    """Run the crowd's model on ``device``: inputs moved there, samples and guidance costs on the CPU.

    :meth:`DiffusionCrowd.plan_now` builds its conditioning and guidance tensors on the CPU; this wraps
    the model's sampler so that the network runs on ``device`` (transfers included in the timing).
    """
    import torch

    model = crowd.model.to(device)
    sample = model.sample

    def sample_on(batch, n_samples=1, generator=None, guidance=None, guidance_scale=1.0, sample_steps=None):
        moved = {k: v.to(device) if isinstance(v, torch.Tensor) else v for k, v in batch.items()}
        guide = None if guidance is None else (lambda pos, index: guidance(pos.cpu(), index.cpu()).to(pos.device))
        return sample(moved, n_samples, generator=generator, guidance=guide, guidance_scale=guidance_scale,
                      sample_steps=sample_steps).cpu()

    model.sample = sample_on


def replan_cost(counts: Sequence[int] = (1, 16, 64), repeats: int = 5, scene: str = "station",
                device: str = "cpu", seed: int = 0) -> list[dict[str, Any]]:
    """Milliseconds per :meth:`DiffusionCrowd.plan_now` (every pedestrian of the world in one batch),
    median of ``repeats`` replans after one warm-up, for each pedestrian count."""
    from navzoo.envs.nav_env import NavEnv

    if repeats < 1:
        raise ValueError(f"repeats must be >= 1, got {repeats!r}")
    rows = []
    for n in counts:
        env = NavEnv(scene=scene, n_robots=0, n_humans=int(n), crowd_model="diffusion", time_limit=1e6)
        env.reset(seed=seed)
        if device != "cpu":
            _on_device(env.diffusion, device)
        env.diffusion.plan_now(env)  # warm-up
        times = []
        for _ in range(repeats):
            if device.startswith("cuda"):
                import torch

                torch.cuda.synchronize()
            t0 = time.perf_counter()
            env.diffusion.plan_now(env)
            times.append(time.perf_counter() - t0)
        env.close()
        rows.append({"pedestrians": int(n), "device": device, "replan_ms": 1e3 * float(np.median(times)),
                     "min_ms": 1e3 * float(np.min(times)), "repeats": repeats})
        print(f"cost replan {device} {n} pedestrians: {rows[-1]['replan_ms']:.1f} ms", file=sys.stderr, flush=True)
    return rows


def step_cost(crowds: Sequence[str] = ("diffusion", "sfm"), scene: str = "station", n: int = 16,
              steps: int = 300, warmup: int = 20, dt: float = REALISM_DT, seed: int = 0) -> dict[str, Any]:
    """Env step time through the crowd policy, per crowd, over ``steps`` timed steps after ``warmup``:
    ``{crowd}_step_ms`` the mean (replans amortised: with ``dt`` = 0.1 s, 300 steps hold 15 diffusion
    replans), ``{crowd}_median_step_ms`` the median (a typical step without a replan) and
    ``{crowd}_p95_step_ms``; ``diffusion_over_sfm`` the ratio of the means."""
    from navzoo.agents.crowd import CrowdPolicy
    from navzoo.envs.nav_env import NavEnv
    from navzoo.envs.wrappers import FrozenAgents

    if steps < 1:
        raise ValueError(f"steps must be >= 1, got {steps!r}")
    out: dict[str, Any] = {"scene": scene, "pedestrians": n, "dt": dt, "steps": steps}
    for crowd in _check_crowds(crowds):
        env = NavEnv(scene=scene, n_robots=0, n_humans=n, crowd_model=crowd, dt=dt, time_limit=1e6)
        wrapped = FrozenAgents(env, lambda a: a.startswith("human_"), CrowdPolicy(crowd))
        wrapped.reset(seed=seed)
        for _ in range(warmup):
            wrapped.step({})
        plans0 = env.diffusion.plans_made if env.diffusion is not None else 0
        times = np.empty(steps)
        for k in range(steps):
            t0 = time.perf_counter()
            wrapped.step({})
            times[k] = time.perf_counter() - t0
        if env.diffusion is not None:
            out[f"{crowd}_replans"] = env.diffusion.plans_made - plans0
        wrapped.close()
        out[f"{crowd}_step_ms"] = 1e3 * float(times.mean())
        out[f"{crowd}_median_step_ms"] = 1e3 * float(np.median(times))
        out[f"{crowd}_p95_step_ms"] = 1e3 * float(np.percentile(times, 95))
        print(f"cost step {crowd} {scene} {n} people: mean {out[f'{crowd}_step_ms']:.2f} ms, median "
              f"{out[f'{crowd}_median_step_ms']:.2f} ms", file=sys.stderr, flush=True)
    if "diffusion_step_ms" in out and "sfm_step_ms" in out:
        out["diffusion_over_sfm"] = out["diffusion_step_ms"] / out["sfm_step_ms"]
    return out


def cost(quick: bool = False, counts: Sequence[int] = (1, 16, 64)) -> dict[str, Any]:
    """Replan times on the CPU (and CUDA if available) and env step times, diffusion vs social force."""
    import torch

    repeats = 3 if quick else 7
    out: dict[str, Any] = {"torch_threads": torch.get_num_threads(),
                           "replan_cpu": replan_cost(counts, repeats, device="cpu")}
    if torch.cuda.is_available():
        try:
            out["replan_cuda"] = replan_cost(counts, repeats, device="cuda")
            out["cuda_device"] = torch.cuda.get_device_name(0)
        except Exception as exc:  # a broken driver must not lose the rest of the evaluation
            out["replan_cuda"] = {"error": f"{type(exc).__name__}: {exc}"}
    out["step"] = step_cost(steps=100 if quick else 300)
    return out


# ---------------------------------------------------------------------------------------- all of it
def _machine() -> str:
    from navzoo.benchmark.speed import _machine as machine

    try:
        return machine()
    except Exception:  # noqa: BLE001 - only a label
        return f"{platform.machine()}, {os.cpu_count()} logical CPUs"


def evaluate(quick: bool = False, seconds: float | None = None, crowds: Sequence[str] = DEFAULT_CROWDS,
             amp: bool = True, with_cost: bool = True, workers: int = 1, seed: int = 0,
             scenes: Sequence[str] | None = None, people: int | None = None, data_dir: str | Path | None = None,
             policy_dir: str | None = None, out: str | Path | None = None,
             rows: Sequence[str] | None = None, seeds: Sequence[int] | None = None,
             env_overrides: dict[str, Any] | None = None) -> dict[str, Any]:
    """Realism, reliability and cost (see the module doc). ``quick``: 2 scenes x 20 s, fewer timing
    repeats. ``people`` fixes the number of pedestrians in every scene (default 3-15 over the scenes).
    ``rows``: the reliability rows to run (default all of :data:`RELIABILITY_ROWS`).
    With ``out`` the result so far is written there after each part and each reliability row
    (``"partial": true`` until done), and the reliability rows resume their finished scene runs when an
    interrupted evaluation is rerun with the same settings (:func:`reliability`). ``seeds``: the
    reliability rows over several seeds (the realism part uses the first). ``env_overrides``: further NavConfig
    fields of every realism and reliability run (``--set``), checked before any run."""
    t0 = time.time()
    env_overrides = pedestrians.check_env_overrides(env_overrides) or None
    crowds = _check_crowds(crowds)
    scenes = _check_scenes(scenes if scenes is not None else (QUICK_SCENES if quick else pedestrians.SCENES))
    seconds = float(seconds if seconds is not None else (QUICK_SECONDS if quick else 200.0))
    if not seconds > 0:
        raise ValueError(f"seconds must be > 0, got {seconds!r}")
    if workers < 1:
        raise ValueError(f"workers must be >= 1, got {workers!r}")
    if people is not None and people < 1:
        raise ValueError(f"people must be >= 1, got {people!r}")
    if seeds is not None:
        seeds = pedestrians.check_seeds(seeds)
        seed = seeds[0]
    rows = list(RELIABILITY_ROWS if rows is None else rows)
    bad = [r for r in rows if r not in RELIABILITY_ROWS]
    if bad:  # checked before the realism part, which runs for minutes
        raise ValueError(f"unknown reliability row(s) {bad}; choose from {', '.join(RELIABILITY_ROWS)}")
    result: dict[str, Any] = {"quick": quick, "machine": _machine()}
    if env_overrides:
        result["env_overrides"] = env_overrides

    def save(partial: bool) -> None:
        result["partial"] = partial
        result["wall_s"] = round(time.time() - t0, 1)
        if out:
            _write_result(out, result)

    if people is not None:
        counts = [people] * len(scenes)
    elif scenes == tuple(name for name, _ in pedestrians.HELDOUT_SCENES):
        counts = [n for _, n in pedestrians.HELDOUT_SCENES]
    else:
        counts = None
    real = real_data(data_dir)
    result["realism"] = realism(crowds, scenes, seconds, seed, workers, counts, data_dir, real=real,
                                env_overrides=env_overrides)
    save(True)
    rows = [r for r in rows if amp or RELIABILITY_ROWS[r][1] != "amp"]

    def row_done(so_far: dict[str, Any]) -> None:  # a long run keeps every finished row
        result["reliability"] = dict(so_far)
        save(True)

    result["reliability"] = reliability(rows, scenes, seconds, seed, workers, policy_dir, counts, row_done, seeds=seeds,
                                        resume_prefix=out, real_kin=real[0], env_overrides=env_overrides)
    result["reliability_paper"] = PAPER_RELIABILITY
    save(True)
    if with_cost:
        result["cost"] = cost(quick)
    save(False)
    if out:
        for name in rows:
            pedestrians.remove_resume_files(row_resume_file(out, name))
    return result


def _write_result(out: str | Path, result: dict[str, Any]) -> None:
    """Write a result (``--out``) as one line of JSON, making its folder."""
    Path(out).parent.mkdir(parents=True, exist_ok=True)
    Path(out).write_text(json.dumps(result, default=_json_default) + "\n")


def _json_default(v: Any) -> Any:
    if isinstance(v, np.ndarray):
        return v.tolist()
    if isinstance(v, np.generic):
        return v.item()
    return str(v)


# ---------------------------------------------------------------------------------------- markdown
def markdown(result: dict[str, Any]) -> str:
    """Markdown tables of an evaluation result (for docs), the paper's reliability rows alongside."""
    def f(v: Any, digits: int = 3) -> str:
        if v is None:
            return "n/a"
        if isinstance(v, float):
            return "nan" if v != v else f"{v:.{digits}f}"
        return str(v)

    lines: list[str] = []
    real = result.get("realism", {})
    if real:
        lines += ["| realism | speed mean (m/s) | W1 | JS | accel mean (m/s²) | W1 | JS | jerk mean (m/s³) | W1 | JS "
                  "| collision rate (<0.4 m) | collision rate (< 2 radii) | standing share | accel while walking |",
                  "|---" * 14 + "|"]
        for name, row in real.items():
            if name in ("settings",):
                continue
            cells = []
            for q in QUANTITIES:
                cells += [f(row.get(f"{q}_mean"), 2), f(row.get(f"{q}_w1")), f(row.get(f"{q}_js"))]
            label = "real (ETH/UCY)" if name == "real" else name
            lines.append(f"| {label} | " + " | ".join(cells) + f" | {f(row.get('collision_rate'), 4)} | "
                         f"{f(row.get('collision_rate_env_radius'), 4)} | {f(row.get('standing_share'))} | "
                         f"{f(row.get('accel_walking_mean'), 2)} |")
        s = real.get("settings", {})
        if s:
            lines.append("")
            lines.append(f"Kinematic pedestrians, {len(s['scenes'])} scenes ({', '.join(s['scenes'])}), "
                         f"{s['people']} people, {s['seconds_per_scene']:.0f} s each at dt {s['sim_dt']} s; "
                         f"kinematics at {s['step_s']} s; W1 against the real samples, JS on "
                         f"{', '.join(f'{q} [{b[0]}, {b[1]}] in {b[2]} bins' for q, b in s['bins'].items())}.")
    rel = result.get("reliability", {})
    if rel:
        keys = ("success_rate", "fall_rate", "map_collision_rate", "agent_collision_rate", "path_error_m")
        lines += ["", "| reliability | success | fall | map collision | agent collision | path error (m) | trips |",
                  "|---|---|---|---|---|---|---|"]
        for name, row in rel.items():
            pct = [f(100 * row[k], 2) if row.get(k) is not None else "n/a" for k in keys[:4]]
            lines.append(f"| {name} | " + " | ".join(pct) + f" | {f(row.get('path_error_m'))} | {row.get('trips')} |")
            if row.get("per_goal"):  # the same runs, one trip per goal (pedestrians.Trips)
                pct = [f(100 * row["per_goal"][k], 2) for k in keys[:4]]
                lines.append(f"| {name}, one trip per goal | " + " | ".join(pct) + f" | | {row['per_goal']['trips']} |")
            for r in row.get("by_seed", []):  # rows over several seeds: each seed under the pooled row
                pct = [f(100 * r[k], 2) if r.get(k) is not None else "n/a" for k in keys[:4]]
                lines.append(f"| {name}, seed {r['seed']} | " + " | ".join(pct) +
                             f" | {f(r.get('path_error_m'))} | {r.get('trips')} |")
        for name, row in result.get("reliability_paper", PAPER_RELIABILITY).items():
            pct = [f(100 * row[k], 2) for k in keys[:4]]
            lines.append(f"| paper {name} | " + " | ".join(pct) + f" | {f(row['path_error_m'])} | |")
        lines.append("")
        lines.append("Rates in % of ended trips. Kinematic rows: no falls by construction, geometric contacts; "
                     "path error n/a for the social-force crowd. \"One trip per goal\": the same runs with a "
                     "person stuck past its time limit counted once, not once per limit.")
        walked = {name: row["walked"] for name, row in rel.items() if row.get("walked")}
        if walked:
            lines += ["", "| walked in the reliability runs | speed mean (m/s) | W1 | JS | accel mean (m/s²) | W1 | JS "
                      "| jerk mean (m/s³) | W1 | JS | collision rate (<0.4 m) |", "|---" * 11 + "|"]
            for name, row in walked.items():
                cells = []
                for q in QUANTITIES:
                    cells += [f(row.get(f"{q}_mean"), 2), f(row.get(f"{q}_w1")), f(row.get(f"{q}_js"))]
                lines.append(f"| {name} | " + " | ".join(cells) + f" | {f(row.get('collision_rate'), 4)} |")
            lines += ["", "The people's centres at every step of the reliability runs (a fallen body's track ends at its "
                      "fall), at 0.4 s as in the realism part; W1 and JS against the same real tracks."]
    c = result.get("cost", {})
    if c:
        lines += ["", "| pedestrians | " + " | ".join(k.split("_", 1)[1] + " replan (ms)" for k in ("replan_cpu", "replan_cuda")
                                                     if isinstance(c.get(k), list)) + " |"]
        devices = [k for k in ("replan_cpu", "replan_cuda") if isinstance(c.get(k), list)]
        lines.append("|---" * (len(devices) + 1) + "|")
        for i, r in enumerate(c["replan_cpu"]):
            lines.append(f"| {r['pedestrians']} | " + " | ".join(f(c[d][i]["replan_ms"], 1) for d in devices) + " |")
        st = c.get("step", {})
        if st:
            lines += ["", f"Env step ({st['scene']}, {st['pedestrians']} people, dt {st['dt']} s, mean with "
                      f"replans amortised / median): diffusion {f(st.get('diffusion_step_ms'), 2)} / "
                      f"{f(st.get('diffusion_median_step_ms'), 2)} ms, social force {f(st.get('sfm_step_ms'), 2)} / "
                      f"{f(st.get('sfm_median_step_ms'), 2)} ms (x{f(st.get('diffusion_over_sfm'), 2)})."]
    if "machine" in result:
        lines += ["", f"Machine: {result['machine']}."]
    return "\n".join(lines)


# ---------------------------------------------------------------------------------------- CLI
def _names(text: str) -> list[str]:
    return [v.strip() for v in text.split(",") if v.strip()]


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--quick", action="store_true", help="reduced run (2 scenes x 20 s, fewer timing repeats)")
    parser.add_argument("--json", action="store_true", help="print compact JSON")
    parser.add_argument("--out", default=None, help="also write the JSON result to this file (updated after each part)")
    parser.add_argument("--workers", type=int, default=1, help="processes for the scenes (default 1)")
    parser.add_argument("--seconds", type=float, default=None, help="simulated seconds per scene (default 200, quick 20)")
    parser.add_argument("--crowds", type=_names, default=list(DEFAULT_CROWDS),
                        help=f"crowd models of the realism part, comma-separated, of {', '.join(CROWDS)} "
                        f"(default {','.join(DEFAULT_CROWDS)})")
    parser.add_argument("--scenes", type=_names, default=None,
                        help="scenes, comma-separated (default the 8 of the pedestrian evaluation; quick: lobby,corridor); "
                             "'heldout': the 10 library scenes no setting was chosen on, with their 3-15 people")
    parser.add_argument("--people", type=int, default=None,
                        help="pedestrians in every scene (default 3-15 spread over the scenes)")
    parser.add_argument("--seed", type=int, default=None, help="seed of the scenes (default 0)")
    parser.add_argument("--seeds", default=None, metavar="S1,S2,...",
                        help="the reliability rows over several seeds (rates pooled, each seed's rates and their "
                             "spread); the realism part uses the first")
    parser.add_argument("--no-amp", action="store_true", help="skip the AMP rows of the reliability table")
    parser.add_argument("--rows", type=_names, default=None,
                        help=f"reliability rows to run, comma-separated, of {', '.join(RELIABILITY_ROWS)} (default all)")
    parser.add_argument("--no-cost", action="store_true", help="skip the replan and step timings")
    parser.add_argument("--cost-only", action="store_true",
                        help="only the replan and step timings (seconds, no data needed), then exit")
    parser.add_argument("--data", default=None, help="ETH/UCY folder (default: the shared data folder)")
    parser.add_argument("--policy", default=None, help="exported AMP policy folder (default: the shipped one)")
    parser.add_argument("--set", dest="env_set", action="append", default=[], metavar="KEY=VALUE",
                        help="NavConfig field for every realism and reliability run, repeatable (e.g. --set "
                             "crowd_wall_strength=0.3; values read as JSON, else words); the cost timings keep the "
                             "defaults")
    parser.add_argument("--markdown", default=None, metavar="RESULT_JSON",
                        help="print Markdown tables of an earlier result (--out file) and exit")


def run_cli(args: argparse.Namespace) -> int:
    if args.markdown:
        print(markdown(json.loads(Path(args.markdown).read_text())))
        return 0
    if args.cost_only:
        if args.no_cost:
            raise SystemExit("navzoo eval crowd: --cost-only and --no-cost exclude each other")
        result = {"quick": args.quick, "machine": _machine(), "cost": cost(args.quick)}
        if args.out:
            _write_result(args.out, result)
        print(json.dumps(result, indent=None if args.json else 2, default=_json_default))
        return 0
    seeds = pedestrians.seeds_option("navzoo eval crowd", args.seed, args.seeds)
    try:  # checked before the minutes of the realism part
        overrides = pedestrians.env_set_option("navzoo eval crowd", args.env_set)
    except ValueError as exc:
        raise SystemExit(str(exc)) from None
    result = evaluate(args.quick, args.seconds, args.crowds, amp=not args.no_amp, with_cost=not args.no_cost,
                      workers=args.workers, seed=0 if args.seed is None else args.seed, scenes=args.scenes,
                      people=args.people, data_dir=args.data, policy_dir=args.policy, out=args.out, rows=args.rows,
                      seeds=seeds, env_overrides=overrides)
    print(json.dumps(result, indent=None if args.json else 2, default=_json_default))
    return 0


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="navzoo eval crowd", description=__doc__.splitlines()[0])
    add_arguments(parser)
    return run_cli(parser.parse_args(argv))


if __name__ == "__main__":
    raise SystemExit(main())
