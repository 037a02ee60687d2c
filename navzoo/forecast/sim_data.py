"""Map-aware prediction windows from simulated crowds in navzoo scenes (training data for the
trajectory diffusion model's occupancy input).

ETH/UCY windows (:mod:`navzoo.forecast.data`) carry no map, so a model trained on them alone cannot
learn to keep off walls. This module runs kinematic rule-based crowds (social force ``"sfm"`` or
navzoo's ORCA ``"orca"``, :class:`navzoo.agents.crowd.CrowdPolicy`) without robots in navzoo library
scenes and cuts their tracks into windows of the ETH/UCY protocol, each with the occupancy crop
around the person that the diffusion crowd feeds the model in the loop.

Simulation (:func:`record_crowd`): ``NavEnv(scene, n_robots=0, n_humans=people, crowd_model=crowd,
dt=0.1)`` wrapped in :class:`navzoo.envs.wrappers.FrozenAgents` with the crowd policy (as
``scripts/crowd_closed_loop.py``), reset with ``seed``, stepped for ``seconds``. Every person's
position is recorded at reset and every 0.4 s (every 4th step), together with its count of goals
reached. A person who reaches its goal gets a new goal where it stands (``human_at_goal="new_goal"``):
positions do not jump, but the walk turns to an unrelated goal. A recorded step longer than 1.5 x
``human_max_speed`` x 0.4 s is taken as a teleport (none happens with the library's scenes and
these crowds; checked anyway).

Windows (:func:`windows_from_recording`), in exactly the format of
:func:`navzoo.forecast.data.build_windows` (see its module doc for the keys) plus two keys:

* one window per person and start frame (``stride``): ``obs_len`` (8) observed + ``pred_len`` (12)
  future positions at 0.4 s (``dt`` = 0.4);
* a window never spans a teleport, nor, with ``cut_at_goal`` (default), a goal reset (a person's
  trip from one goal to the next is one track, like a pedestrian of ETH/UCY);
* neighbours: the ``k_neighbors`` (16) nearest other people within ``radius`` (10 m) at the last
  observed frame, nearest first, with their histories and futures; a neighbour's positions are
  valid in the frames of the window without a teleport between them and the last observed frame
  (its goal resets do not matter: it is just seen walking), so the masks are all True in practice;
* ``ped`` / ``neigh_ped``: person index within its run (-1: empty slot); ``frame``: index of the
  last observed record (0.4 s units from the reset); ``scene``: ``"sim/<crowd>/<scene>"``;
* ``map (N, C, C) float32``: occupancy (1 = obstacle or outside the scene's grid, 0 = free) of the
  ``MAP_EXTENT`` (8 m) square around the person at the last observed step, in the window's agent
  frame, taken with ``env.grid.crop_many(hist_world[:, -1], heading, MAP_EXTENT, C)`` where
  ``heading = arctan2(rot[:, 0, 1], rot[:, 0, 0])`` of :func:`navzoo.forecast.data.normalize`'s
  rotation: exactly how :meth:`navzoo.agents.diffusion.crowd.DiffusionCrowd.plan_now` crops in the
  loop. Cell ``[r, c]`` covers the agent-frame point ``x = (c + 0.5 - C/2) * MAP_EXTENT / C``
  (ahead), ``y = (r + 0.5 - C/2) * MAP_EXTENT / C`` (left): rows run along +y, columns along +x.
  The map is always in the agent frame, also when ``normalized=False`` returns positions in the
  world frame;
* ``has_map (N,) bool``: True.

:func:`with_map` gives map-less windows (ETH/UCY) an all-zero map and ``has_map=False`` so that
they concatenate with these (:func:`navzoo.forecast.data.concat` needs equal keys); the model then
uses its learned "no map" embedding for them.

Default scenes (:func:`default_scenes`): every library scene except the 8 evaluation scenes
:data:`navzoo.benchmark.pedestrians.SCENES`, so crowd evaluations stay on unseen scenes; default
people: the scene's ``default_humans``.

Files (:func:`build_sim_dataset`, :func:`load_sim_dataset`): one ``.npz`` (compressed, arrays only,
loadable with ``allow_pickle=False``) with every batch key (``map`` stored as uint8, x 255) and ``info_json``,
a string array holding the description (scenes, crowds, people, seconds, seed, map cells and extent,
windows per run, build time). Command line::

    python -m navzoo.forecast.sim_data --out runs/sim_windows/sim_windows.npz --crowds sfm,orca --seconds 120

Training on them: ``navzoo train diffusion --sim-data runs/sim_windows/sim_windows.npz --map-cells 32``.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from navzoo.forecast import data as fdata

__all__ = [
    "MAP_EXTENT",
    "MODEL_DT",
    "SIM_DT",
    "Recording",
    "default_scenes",
    "record_crowd",
    "windows_from_recording",
    "map_heading",
    "simulate_windows",
    "with_map",
    "build_sim_dataset",
    "load_sim_dataset",
    "main",
]

#: Seconds per simulation step.
SIM_DT = 0.1
#: Seconds per window step (the ETH/UCY protocol and the diffusion model's step).
MODEL_DT = 0.4
#: Side (m) of the occupancy crop; must equal navzoo.agents.diffusion.crowd.MAP_EXTENT.
MAP_EXTENT = 8.0
# A recorded step longer than this factor x human_max_speed x MODEL_DT is a teleport.
_TELEPORT_FACTOR = 1.5
_CROWDS = ("sfm", "orca")


def default_scenes() -> list[str]:
    """Library scenes without the evaluation scenes of :data:`navzoo.benchmark.pedestrians.SCENES`."""
    from navzoo.benchmark.pedestrians import SCENES
    from navzoo.world.library import list_scenes

    return [s for s in list_scenes() if s not in SCENES]


@dataclass
class Recording:
    """Positions of one simulated crowd every ``MODEL_DT``.

    Attributes:
        scene: Library scene name.
        crowd: Crowd model.
        pos: (F, P, 2) world positions (m), frame 0 = at reset.
        goals: (F, P) goals reached so far by each person.
        teleport: (F, P) bool, True where the step from frame f-1 to f is a jump.
        grid: The scene's occupancy grid (:class:`navzoo.world.occupancy.OccupancyGrid`).
        seed: Reset seed.
        wall_s: Simulation time (s of wall clock).
    """

    scene: str
    crowd: str
    pos: np.ndarray
    goals: np.ndarray
    teleport: np.ndarray
    grid: Any
    seed: int
    wall_s: float


def record_crowd(scene: str, crowd: str = "sfm", people: int | None = None, seconds: float = 120.0,
                 seed: int = 0, dt: float = SIM_DT) -> Recording:
    """Run a kinematic crowd without robots and record it every :data:`MODEL_DT` (see the module doc).

    Raises:
        ValueError: On an unknown crowd, ``seconds`` shorter than one record step, or a ``dt`` that
            does not divide :data:`MODEL_DT`.
    """
    from navzoo.agents.crowd import CrowdPolicy
    from navzoo.envs.nav_env import NavEnv
    from navzoo.envs.wrappers import FrozenAgents

    if crowd not in _CROWDS:
        raise ValueError(f"crowd must be one of {_CROWDS}, got {crowd!r}")
    every = int(round(MODEL_DT / dt))
    if every < 1 or abs(every * dt - MODEL_DT) > 1e-9:
        raise ValueError(f"dt must divide {MODEL_DT} s, got {dt!r}")
    if not seconds >= MODEL_DT:
        raise ValueError(f"seconds must be >= {MODEL_DT}, got {seconds!r}")
    t0 = time.time()
    env = NavEnv(scene=scene, n_robots=0, n_humans=people, crowd_model=crowd, dt=dt, time_limit=float(seconds))
    try:
        w = FrozenAgents(env, lambda a: a.startswith("human_"), CrowdPolicy(crowd))
        w.reset(seed=seed)
        R = env.n_robots
        pos, goals = [env.pos[R:].copy()], [env.goals_reached[R:].copy()]
        steps = 0
        while not env._needs_reset:
            w.step({})
            steps += 1
            if steps % every == 0:
                pos.append(env.pos[R:].copy())
                goals.append(env.goals_reached[R:].copy())
        P = np.asarray(pos, dtype=np.float64)
        jump = np.linalg.norm(np.diff(P, axis=0), axis=2) > _TELEPORT_FACTOR * env.config.human_max_speed * MODEL_DT
        teleport = np.concatenate([np.zeros((1, P.shape[1]), bool), jump], axis=0)
        return Recording(scene=scene, crowd=crowd, pos=P, goals=np.asarray(goals, dtype=np.int64), teleport=teleport,
                         grid=env.grid, seed=int(seed), wall_s=time.time() - t0)
    finally:
        env.close()


def map_heading(batch: Mapping[str, Any]) -> np.ndarray:
    """Heading (rad, world) of each window's agent frame, as crowd.py derives it from ``normalize``'s rotation."""
    rot = np.asarray(batch["rot"], dtype=np.float64)
    return np.arctan2(rot[:, 0, 1], rot[:, 0, 0])


def _empty(obs_len: int, pred_len: int, k: int, map_cells: int) -> dict[str, Any]:
    out = fdata._empty_batch(obs_len, pred_len, k)  # noqa: SLF001 - the exact empty layout of build_windows
    out["map"] = np.zeros((0, map_cells, map_cells), np.float32)
    out["has_map"] = np.zeros(0, bool)
    return out


def windows_from_recording(
    rec: Recording,
    obs_len: int = 8,
    pred_len: int = 12,
    k_neighbors: int = 16,
    radius: float = 10.0,
    stride: int = 1,
    map_cells: int = 32,
    map_extent: float = MAP_EXTENT,
    cut_at_goal: bool = True,
    normalized: bool = True,
) -> dict[str, Any]:
    """Windows of one recording (see the module doc), agent-centric unless ``normalized=False``.

    Raises:
        ValueError: On out-of-range arguments.
    """
    if obs_len < 2 or pred_len < 1 or k_neighbors < 0 or stride < 1 or map_cells < 1:
        raise ValueError(f"need obs_len >= 2, pred_len >= 1, k_neighbors >= 0, stride >= 1, map_cells >= 1; got "
                         f"{obs_len}, {pred_len}, {k_neighbors}, {stride}, {map_cells}")
    if not radius > 0:
        raise ValueError(f"radius must be > 0, got {radius!r}")
    pos = rec.pos
    n_f, n_p = pos.shape[:2]
    L = obs_len + pred_len
    k = k_neighbors
    if n_f < L or n_p == 0:
        return _empty(obs_len, pred_len, k, map_cells)
    seg = np.cumsum(rec.teleport, axis=0)  # (F, P): continuous pieces of each person's track
    trip = seg + (rec.goals if cut_at_goal else 0)  # both counters only grow: equal ends = no change inside
    full = trip[: n_f - L + 1] == trip[L - 1:]
    full[np.arange(full.shape[0]) % stride != 0] = False
    t0, p = np.nonzero(full)
    n = t0.size
    if n == 0:
        return _empty(obs_len, pred_len, k, map_cells)
    core, nearest, ok, t_last = fdata.window_arrays(pos, seg, t0, p, obs_len, pred_len, k, radius)
    batch = {
        **core,
        "neigh_ped": np.where(ok, nearest, -1).astype(np.int64),
        "ped": p.astype(np.int64),
        "frame": t_last.astype(np.int64),
        "dt": np.full(n, MODEL_DT),
        "scene": np.full(n, f"sim/{rec.crowd}/{rec.scene}"),
        "origin": np.zeros((n, 2)),
        "rot": np.broadcast_to(np.eye(2), (n, 2, 2)).copy(),
    }
    local = fdata.normalize(batch)
    # Exactly the loop's crop (crowd.py plan_now): centre = current position, heading from normalize's rotation.
    occ = rec.grid.crop_many(batch["hist"][:, -1], map_heading(local), float(map_extent), int(map_cells))
    out = local if normalized else batch
    out["map"] = np.asarray(occ, dtype=np.float32)
    out["has_map"] = np.ones(n, bool)
    return out


def _people_for(people: int | Mapping[str, int] | None, scene: str) -> int | None:
    if people is None or isinstance(people, int):
        return people
    return people.get(scene)


def simulate_windows(
    scenes: Sequence[str] | str | None = None,
    crowd: str = "sfm",
    people: int | Mapping[str, int] | None = None,
    seconds: float = 120.0,
    seed: int = 0,
    map_cells: int = 32,
    log: Callable[[str], None] | None = None,
    runs: list[dict[str, Any]] | None = None,
    **window_kwargs: Any,
) -> dict[str, Any]:
    """Windows (with ``map`` / ``has_map``) of one crowd model run in each scene, concatenated.

    Args:
        scenes: Library scene names (a comma-separated string works too); default :func:`default_scenes`.
        crowd: ``"sfm"`` or ``"orca"``.
        people: People per scene: None (each scene's ``default_humans``), one number, or a dict
            scene -> number (missing scenes: default).
        seconds: Simulated seconds per scene (one episode, reset with ``seed``).
        seed: Reset seed of every scene's episode.
        map_cells: Side of the occupancy crop (cells over :data:`MAP_EXTENT`).
        log: Called with one line per scene.
        runs: If given, a description of each run (scene, crowd, people, windows, wall time) is appended.
        **window_kwargs: Passed to :func:`windows_from_recording` (obs_len, pred_len, k_neighbors,
            radius, stride, cut_at_goal, normalized, map_extent).
    """
    if scenes is None:
        scenes = default_scenes()
    elif isinstance(scenes, str):
        scenes = [s for s in scenes.split(",") if s]
    k = int(window_kwargs.get("k_neighbors", 16))
    out = []
    for scene in scenes:
        rec = record_crowd(scene, crowd, _people_for(people, scene), seconds, seed)
        w = windows_from_recording(rec, map_cells=map_cells, **window_kwargs)
        n = fdata.batch_size(w)
        possible = rec.pos.shape[1] * max(rec.pos.shape[0] - window_kwargs.get("obs_len", 8)
                                          - window_kwargs.get("pred_len", 12) + 1, 0)
        info = {"scene": scene, "crowd": crowd, "people": int(rec.pos.shape[1]), "seconds": float(seconds),
                "seed": int(seed), "windows": n, "windows_uncut": int(possible),
                "goals_reached": int(rec.goals[-1].sum()), "teleports": int(rec.teleport.sum()),
                "wall_s": round(rec.wall_s, 2)}
        if runs is not None:
            runs.append(info)
        if log is not None:
            log(_run_line(info))
        if n:
            out.append(w)
    if not out:
        return _empty(window_kwargs.get("obs_len", 8), window_kwargs.get("pred_len", 12), k, map_cells)
    return fdata.concat(out)


def _simulate_one(scene: str, crowd: str, people: int | Mapping[str, int] | None, seconds: float, seed: int,
                  map_cells: int, window_kwargs: Mapping[str, Any]) -> tuple[dict[str, Any], dict[str, Any]]:
    """Windows and run description of one crowd in one scene (a worker's job in :func:`build_sim_dataset`)."""
    runs: list[dict[str, Any]] = []
    w = simulate_windows([scene], crowd, people, seconds, seed, map_cells, runs=runs, **window_kwargs)
    return w, runs[0]


def _run_line(info: Mapping[str, Any]) -> str:
    return (f"{info['crowd']:4s} {info['scene']:18s} {info['people']:3d} people: {info['windows']:6d} windows "
            f"({info['goals_reached']} goals reached), {info['wall_s']:.1f} s")


def with_map(batch: Mapping[str, Any], map_cells: int) -> dict[str, Any]:
    """``batch`` with an all-zero ``map (N, C, C)`` and ``has_map=False`` where it has no map (ETH/UCY).

    Raises:
        ValueError: If the batch has a map of another size.
    """
    n = fdata.batch_size(batch)
    out = dict(batch)
    if "map" in batch:
        shape = np.asarray(batch["map"]).shape
        if shape != (n, map_cells, map_cells):
            raise ValueError(f"batch has a map of shape {shape}, expected ({n}, {map_cells}, {map_cells})")
        if "has_map" not in batch:
            out["has_map"] = np.ones(n, bool)
        return out
    out["map"] = np.zeros((n, map_cells, map_cells), np.float32)
    out["has_map"] = np.zeros(n, bool)
    return out


def build_sim_dataset(
    out_path: str | Path,
    scenes: Sequence[str] | str | None = None,
    crowds: Iterable[str] | str = _CROWDS,
    people: int | Mapping[str, int] | None = None,
    seconds: float = 120.0,
    seed: int = 0,
    map_cells: int = 32,
    log: Callable[[str], None] | None = print,
    workers: int = 1,
    **window_kwargs: Any,
) -> dict[str, Any]:
    """Simulate every crowd in every scene (:func:`simulate_windows`) and write one ``.npz``; returns its description.

    ``workers`` > 1 runs the (crowd, scene) recordings in that many processes; the file is the same
    for any number of workers (each run depends only on its scene, crowd, people, seconds and seed).
    """
    if isinstance(crowds, str):
        crowds = [c for c in crowds.split(",") if c]
    crowds = list(crowds)
    if scenes is None:
        scenes = default_scenes()
    elif isinstance(scenes, str):
        scenes = [s for s in scenes.split(",") if s]
    scenes = list(scenes)
    t0 = time.time()
    runs: list[dict[str, Any]] = []
    from navzoo.benchmark.pedestrians import _pool_map

    # crowd-major: the order of the output, whatever the number of workers
    jobs = [(scene, c, people, seconds, seed, map_cells, window_kwargs) for c in crowds for scene in scenes]
    results = _pool_map(_simulate_one, jobs, workers)
    batches = []
    for w, run in results:
        runs.append(run)
        if log is not None:
            log(_run_line(run))
        batches.append(w)
    batch = fdata.concat([b for b in batches if fdata.batch_size(b)] or batches[:1])
    info = {"format": "navzoo-sim-windows", "version": 1, "scenes": scenes, "crowds": crowds,
            "people": people if people is None or isinstance(people, int) else dict(people),
            "seconds": float(seconds), "seed": int(seed), "sim_dt": SIM_DT, "dt": MODEL_DT,
            "map_cells": int(map_cells), "map_extent": float(window_kwargs.get("map_extent", MAP_EXTENT)),
            "window_kwargs": {k: v for k, v in window_kwargs.items() if k != "map_extent"},
            "windows": fdata.batch_size(batch), "runs": runs, "build_s": round(time.time() - t0, 1)}
    out_path = Path(out_path)
    out_path.parent.mkdir(parents=True, exist_ok=True)
    arrays = {k: np.asarray(v) for k, v in batch.items()}
    arrays["map"] = np.rint(np.clip(arrays["map"], 0.0, 1.0) * 255).astype(np.uint8)  # 0/1 stay exact
    arrays["info_json"] = np.array(json.dumps(info))
    tmp = out_path.with_name(out_path.name + ".tmp.npz")
    np.savez_compressed(tmp, **arrays)
    tmp.replace(out_path)
    info["file_bytes"] = out_path.stat().st_size
    if log is not None:
        log(f"wrote {info['windows']} windows to {out_path} ({info['file_bytes'] / 1e6:.1f} MB) in {info['build_s']:.0f} s")
    return info


def load_sim_dataset(path: str | Path) -> tuple[dict[str, Any], dict[str, Any]]:
    """(windows, description) of a file of :func:`build_sim_dataset`; ``map`` back as float32 in [0, 1]."""
    with np.load(Path(path), allow_pickle=False) as z:
        arrays = {k: z[k] for k in z.files}
    info = json.loads(str(arrays.pop("info_json")))
    if info.get("format") != "navzoo-sim-windows":
        raise ValueError(f"{path} is not a navzoo sim-windows file (format {info.get('format')!r})")
    arrays["map"] = arrays["map"].astype(np.float32) / np.float32(255.0)
    arrays["has_map"] = arrays["has_map"].astype(bool)
    return arrays, info


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", default="runs/sim_windows/sim_windows.npz")
    parser.add_argument("--scenes", default=None, help="comma-separated library scenes (default: all but the evaluation scenes)")
    parser.add_argument("--crowds", default="sfm,orca")
    parser.add_argument("--people", type=int, default=None, help="people per scene (default: the scene's default)")
    parser.add_argument("--seconds", type=float, default=120.0)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--map-cells", type=int, default=32)
    parser.add_argument("--stride", type=int, default=1)
    parser.add_argument("--keep-goal-resets", action="store_true", help="keep windows spanning a goal reset")
    parser.add_argument("--workers", type=int, default=1, help="processes for the (crowd, scene) runs")
    args = parser.parse_args(argv)
    if args.workers < 1:
        parser.error(f"--workers must be >= 1, got {args.workers}")
    info = build_sim_dataset(args.out, args.scenes, args.crowds, args.people, args.seconds, args.seed, args.map_cells,
                             log=lambda s: print(s, file=sys.stderr, flush=True), stride=args.stride,
                             cut_at_goal=not args.keep_goal_resets, workers=args.workers)
    print(json.dumps({k: v for k, v in info.items() if k != "runs"}))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
