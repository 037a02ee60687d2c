"""The benchmark runner: methods x scenes x crowds x densities x episodes, in parallel, resumable.

``navzoo benchmark`` (and :func:`run_benchmark`) runs every episode of a :class:`BenchmarkSpec` in worker
processes and appends each finished episode at once to ``DIR/episodes.jsonl``:

* **Seeding.** An episode's seed is a hash of (spec seed, scene, crowd, crowd level, episode index) fed to a
  ``SeedSequence`` (:func:`episode_seed`), so it depends neither on the method nor on the worker count or
  order: every method meets the same start, goal and crowd in the same episode, and 1 or 8 workers give the
  same ``episodes.jsonl`` lines (in another order). A fresh policy is built for every episode and the global
  ``random``/``numpy``/``torch`` generators are seeded from the episode seed as well, for learned policies
  that draw from them.
* **Resume.** A rerun with the same ``DIR`` skips the episodes already in ``episodes.jsonl``; a line cut off
  by a kill is dropped. Episodes that failed before (``errors.jsonl``) are tried again.
* **Crashes.** An exception in an episode is recorded in ``DIR/errors.jsonl`` (method, scene, crowd, level,
  episode, seed, traceback) and the run goes on. A worker process that dies (segfault, out of memory, an
  episode running past ``episode_timeout``) breaks the process pool: the episode it was running is recorded
  as an error, the pool is restarted and the other unfinished episodes are run again. The run ends with the
  list of errors and a non-zero exit code instead of hanging.
* **Record.** ``DIR/run.json`` holds the spec, the machine (CPU, cores, load, Python, navzoo's git commit),
  every session's start/end wall time and episodes per hour, and the metric thresholds.

One episode of one method is one line of ``episodes.jsonl``: the cell (method, scene, scene group, crowd,
level, density, n_humans, episode, seed) and every metric of
:func:`navzoo.benchmark.metrics.episode_metrics` under its name (``nan``/``inf`` written as ``null``).
"""

from __future__ import annotations

import argparse
import contextlib
import dataclasses
import gzip
import hashlib
import importlib
import json
import math
import multiprocessing
import os
import platform
import random
import re
import signal
import subprocess
import sys
import time
import traceback
from collections import Counter, OrderedDict, deque
from collections.abc import Callable, Iterable, Mapping, Sequence
from concurrent.futures import FIRST_COMPLETED, Future, ProcessPoolExecutor, wait
from concurrent.futures.process import BrokenProcessPool
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from navzoo.machine import cpu_model  # noqa: F401  (also imported from here by scripts)

__all__ = [
    "BenchmarkSpec",
    "Cell",
    "EpisodeTask",
    "build_tasks",
    "current_episode",
    "episode_key",
    "episode_seed",
    "load_episodes",
    "load_errors",
    "merge_runs",
    "resolve_spec",
    "run_benchmark",
    "run_episode",
    "spec_from_args",
]

EPISODES_FILE = "episodes.jsonl"
ERRORS_FILE = "errors.jsonl"
RUN_FILE = "run.json"
# "diffusion": the trajectory diffusion crowd (docs/crowd.md), the env's ``diffusion_model`` or the shipped one.
# "replay": recorded ETH/UCY people (SocNavBench's setting: they do not react to the robot), only in the replay
# scenes ``replay_<recording>``; every episode plays another time window of the recording, with everyone who walks
# in it (crowd level "recorded": densities and counts do not apply).
CROWD_MODELS = ("sfm", "orca", "orca_rvo2", "diffusion", "replay")
REPLAY_CROWD = "replay"
REPLAY_LEVEL = "recorded"
#: Replay windows start on this grid (s) of recording time.
REPLAY_START_STEP = 1.0
# A crowd of pedestrians trained with RLlib (navzoo.rl.train, humans: learn): "rllib:PATH" with PATH a
# training --out folder, a checkpoint or the "human" module folder. They act on flattened observations.
LEARNED_CROWD_PREFIX = "rllib:"
# NavConfig fields the runner sets per cell or per episode: a spec's ``env`` must not set them.
_RUNNER_FIELDS = ("scene", "n_humans", "crowd_model", "time_limit", "max_episode_steps_override", "n_robots",
                  "replay_scene", "replay_start")
# Spec fields that change the episodes' results: a resumed run must agree on them.
_RESULT_FIELDS = ("seed", "time_limit", "max_steps", "env", "max_humans")
_MAX_STRIKES = 3  # pool breaks with an episode in flight (no culprit known) before it counts as failed


# ---------------------------------------------------------------------------------------------------------
# The spec
# ---------------------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class BenchmarkSpec:
    """What a benchmark runs (everything that decides the episodes; where and how fast is up to the run).

    Attributes:
        scenes: scene names (``navzoo scenes``, or ``procedural_rooms_<seed>``...).
        methods: robot policy names (:func:`navzoo.agents.baselines.make_policy`). A ``-holonomic`` or
            ``-diffdrive`` suffix also sets the robot's kinematics for that method.
        crowds: crowd models of the pedestrians (``sfm``, ``orca``, ``orca_rvo2``, ``diffusion``: the trajectory
            diffusion crowd, with the env's ``diffusion_model`` or the shipped model), or ``rllib:PATH``:
            pedestrians trained with :mod:`navzoo.rl.train` (the run's ``--out`` folder, a checkpoint or the
            ``human`` module folder); they act on flattened observations, so the env's observation settings
            must be those they were trained with.
        densities: people per m² of the scene's crowd area (``round(d * scene.crowd_area())`` people: the free
            space, or the circle/square of the CrowdNav protocols).
        humans: people per scene (counts), instead of ``densities``; neither = each scene's default.
        episodes: episodes per cell (method x scene x crowd x level).
        seed: base seed of every episode seed (:func:`episode_seed`).
        time_limit: episode time limit (s); None = each scene's own.
        max_steps: hard cap on steps per episode (``max_episode_steps_override``; tests, quick looks).
        save_trajectories: save the arrays (npz) of the first K episodes of each cell.
        videos: save a top-down video (mp4) of the first K episodes of each cell.
        env: further NavConfig overrides for every episode (``robot`` as a dict of RobotSpec fields).
        protocol: the named protocol the spec came from (:mod:`navzoo.benchmark.protocols`), if any.
        imports: modules imported in every worker before it runs (e.g. one that registers a learned
            policy with :func:`navzoo.agents.baselines.register_policy`).
        max_humans: cap on people per scene (densities on big scenes give hundreds).
        episode_timeout: wall seconds after which a running episode's worker is killed and the episode
            recorded as an error (None or 0: no limit).
    """

    scenes: tuple[str, ...]
    methods: tuple[str, ...]
    crowds: tuple[str, ...] = ("sfm",)
    densities: tuple[float, ...] | None = None
    humans: tuple[int, ...] | None = None
    episodes: int = 20
    seed: int = 0
    time_limit: float | None = None
    max_steps: int | None = None
    save_trajectories: int = 0
    videos: int = 0
    env: dict[str, Any] = field(default_factory=dict)
    protocol: str | None = None
    imports: tuple[str, ...] = ()
    max_humans: int | None = None
    episode_timeout: float | None = 600.0

    def __post_init__(self) -> None:
        def bad(name: str, expected: str) -> ValueError:
            return ValueError(f"benchmark spec: {name} must be {expected}, got {getattr(self, name)!r}")

        for name in ("scenes", "methods", "crowds"):
            value = tuple(getattr(self, name))
            if not value or not all(isinstance(v, str) and v.strip() for v in value):
                raise bad(name, "a non-empty list of names")
            object.__setattr__(self, name, tuple(dict.fromkeys(v.strip() for v in value)))
        unknown = [c for c in self.crowds if c not in CROWD_MODELS and not c.startswith(LEARNED_CROWD_PREFIX)]
        if unknown:
            raise ValueError(f"benchmark spec: unknown crowd model(s) {unknown}; valid: {list(CROWD_MODELS)} or "
                             f"'{LEARNED_CROWD_PREFIX}PATH' (pedestrians trained with navzoo.rl.train)")
        if REPLAY_CROWD in self.crowds:
            from navzoo.agents.replay import SCENE_PREFIX

            other = [s for s in self.scenes if not s.startswith(SCENE_PREFIX)]
            if other:
                raise ValueError(f"benchmark spec: crowd 'replay' plays recorded people in their recordings' scenes "
                                 f"only ({SCENE_PREFIX}eth, {SCENE_PREFIX}univ, {SCENE_PREFIX}zara1, ...), not in "
                                 f"{other}; run those scenes with another crowd in a separate benchmark")
        if self.densities is not None and self.humans is not None:
            raise ValueError("benchmark spec: give densities (people per m²) or humans (counts), not both")
        if self.densities is not None:
            d = tuple(self.densities)
            if not d or not all(_is_num(v) and math.isfinite(v) and v >= 0 for v in d):
                raise bad("densities", "a non-empty list of numbers >= 0 (people per m² of free space)")
            object.__setattr__(self, "densities", tuple(dict.fromkeys(float(v) for v in d)))
        if self.humans is not None:
            h = tuple(self.humans)
            if not h or not all(_is_int(v) and v >= 0 for v in h):
                raise bad("humans", "a non-empty list of integers >= 0")
            object.__setattr__(self, "humans", tuple(dict.fromkeys(int(v) for v in h)))
        for name in ("episodes",):
            if not _is_int(getattr(self, name)) or getattr(self, name) < 1:
                raise bad(name, "an integer >= 1")
        for name in ("save_trajectories", "videos"):
            if not _is_int(getattr(self, name)) or getattr(self, name) < 0:
                raise bad(name, "an integer >= 0")
        if not _is_int(self.seed) or self.seed < 0:
            raise bad("seed", "an integer >= 0")
        if self.time_limit is not None and not (_is_num(self.time_limit) and 0 < self.time_limit < math.inf):
            raise bad("time_limit", "None or a number of seconds > 0")
        if self.max_steps is not None and (not _is_int(self.max_steps) or self.max_steps < 1):
            raise bad("max_steps", "None or an integer >= 1")
        if self.max_humans is not None and (not _is_int(self.max_humans) or self.max_humans < 0):
            raise bad("max_humans", "None or an integer >= 0")
        if self.episode_timeout is not None and not (_is_num(self.episode_timeout) and self.episode_timeout >= 0):
            raise bad("episode_timeout", "None or a number of seconds >= 0")
        if not isinstance(self.env, Mapping):
            raise bad("env", "a mapping of NavConfig overrides")
        clash = sorted(set(self.env) & set(_RUNNER_FIELDS))
        if clash:
            raise ValueError(f"benchmark spec: env must not set {clash}: the runner sets them per cell "
                             "(use scenes, crowd, density/humans, time_limit, max_steps)")
        object.__setattr__(self, "env", dict(self.env))
        imports = self.imports
        if isinstance(imports, str):
            imports = _split(imports)
        object.__setattr__(self, "imports", tuple(imports))

    def to_dict(self) -> dict[str, Any]:
        """The spec as plain data (the YAML spec's keys)."""
        d = dataclasses.asdict(self)
        out = {
            "scenes": list(self.scenes),
            "methods": list(self.methods),
            "crowd": list(self.crowds),
            "density": list(self.densities) if self.densities is not None else None,
            "humans": list(self.humans) if self.humans is not None else None,
        }
        for k in ("episodes", "seed", "time_limit", "max_steps", "save_trajectories", "videos", "protocol",
                  "max_humans", "episode_timeout"):
            out[k] = d[k]
        out["env"] = _plain(self.env)
        out["imports"] = list(self.imports)
        return out

    @classmethod
    def from_dict(cls, data: Mapping[str, Any]) -> BenchmarkSpec:
        """A spec from plain data (YAML): the keys of :meth:`to_dict`; unknown keys are rejected by name.

        ``scenes`` may be ``"all"`` (every packaged scene) or a comma-separated string; ``crowds`` and
        ``densities`` are accepted for ``crowd`` and ``density``.
        """
        if not isinstance(data, Mapping):
            raise TypeError(f"benchmark spec must be a mapping, got {type(data).__name__}")
        data = dict(data)
        for alias, key in (("crowds", "crowd"), ("densities", "density")):
            if alias in data:
                data[key] = data.pop(alias)
        valid = set(SPEC_KEYS)
        unknown = sorted(set(data) - valid)
        if unknown:
            raise ValueError(f"unknown benchmark spec key(s) {unknown}; valid keys: {sorted(valid)}")
        missing = [k for k in ("scenes", "methods") if not data.get(k)]
        if missing:
            raise ValueError(f"benchmark spec: missing {missing} (give them, or a protocol that sets them)")
        kwargs: dict[str, Any] = {
            "scenes": tuple(_scene_list(data["scenes"])),
            "methods": tuple(_split(data["methods"])),
        }
        if data.get("crowd") is not None:
            kwargs["crowds"] = tuple(_split(data["crowd"]))
        if data.get("density") is not None:
            kwargs["densities"] = tuple(_numbers(data["density"], float, "density"))
        if data.get("humans") is not None:
            kwargs["humans"] = tuple(_numbers(data["humans"], int, "humans"))
        for k in ("episodes", "seed", "time_limit", "max_steps", "save_trajectories", "videos", "protocol",
                  "max_humans", "episode_timeout", "env", "imports"):
            if data.get(k) is not None:
                kwargs[k] = data[k]
        return cls(**kwargs)

    def result_fields(self) -> dict[str, Any]:
        """The fields that change an episode's result (a resumed run must agree on them)."""
        d = self.to_dict()
        return {k: d[k] for k in _RESULT_FIELDS}


SPEC_KEYS = ("scenes", "methods", "crowd", "density", "humans", "episodes", "seed", "time_limit", "max_steps",
             "save_trajectories", "videos", "env", "protocol", "imports", "max_humans", "episode_timeout")
RUN_KEYS = ("workers", "out")  # also accepted in a spec file: how to run, not what


def resolve_spec(protocol: str | None = None, spec_file: str | Path | None = None,
                 **fields: Any) -> tuple[BenchmarkSpec, dict[str, Any]]:
    """Merge a protocol's defaults, a YAML/JSON spec file and explicit fields (later wins; None = not given).

    Returns the validated spec and the run options found in the file (``workers``, ``out``).
    """
    data: dict[str, Any] = {}
    run_opts: dict[str, Any] = {}
    file_data: dict[str, Any] = {}
    if spec_file is not None:
        path = Path(spec_file)
        if not path.is_file():
            raise FileNotFoundError(f"spec file {str(path)!r} does not exist")
        import yaml

        try:
            loaded = yaml.safe_load(path.read_text(encoding="utf-8"))
        except yaml.YAMLError as exc:
            raise ValueError(f"spec file {str(path)!r} is not valid YAML: {exc}") from exc
        if not isinstance(loaded, dict):
            raise ValueError(f"spec file {str(path)!r} must hold a mapping of spec keys, got {type(loaded).__name__}")
        file_data = dict(loaded)
        for k in RUN_KEYS:
            if k in file_data:
                run_opts[k] = file_data.pop(k)
    proto_name = protocol if protocol is not None else file_data.get("protocol")
    if proto_name:
        from navzoo.benchmark.protocols import get_protocol

        proto = get_protocol(proto_name)
        data.update(proto.spec_fields())
        data["protocol"] = proto.name
    for k, v in file_data.items():
        if k == "env" and isinstance(v, Mapping) and isinstance(data.get("env"), Mapping):
            data["env"] = _merge_env(data["env"], v)
        else:
            data[k] = v
    for k, v in fields.items():
        if v is None:
            continue
        if k == "env" and isinstance(data.get("env"), Mapping):
            data["env"] = _merge_env(data["env"], v)
        else:
            data[k] = v
    if "density" in fields and fields["density"] is not None:
        data.pop("humans", None)  # an explicit density replaces the protocol's/file's counts
    if "humans" in fields and fields["humans"] is not None:
        data.pop("density", None)
    return BenchmarkSpec.from_dict(data), run_opts


def _merge_env(base: Mapping[str, Any], extra: Mapping[str, Any]) -> dict[str, Any]:
    out = dict(base)
    for k, v in extra.items():
        if k == "robot" and isinstance(v, Mapping) and isinstance(out.get("robot"), Mapping):
            out["robot"] = {**out["robot"], **v}
        else:
            out[k] = v
    return out


# ---------------------------------------------------------------------------------------------------------
# Cells, tasks, seeds
# ---------------------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class Cell:
    """One (scene, crowd, crowd level): the episodes every method runs."""

    scene: str
    group: str
    crowd: str
    level: str  # "d0.15" (people per m²), "n10" (count) or "default" (the scene's own)
    density: float  # people per m² of crowd area (nominal for density levels, n / area otherwise)
    n_humans: int
    free_area_m2: float  # the area the density refers to (Scene.crowd_area)


@dataclass(frozen=True)
class EpisodeTask:
    """One episode of one method in one cell (what a worker gets)."""

    method: str
    cell: Cell
    episode: int
    seed: int
    env_kwargs: dict[str, Any]
    save_trajectory: bool
    video: bool
    out: str

    @property
    def key(self) -> tuple[str, str, str, str, int]:
        return (self.method, self.cell.scene, self.cell.crowd, self.cell.level, self.episode)


def episode_key(record: Mapping[str, Any]) -> tuple[str, str, str, str, int]:
    """(method, scene, crowd, level, episode) of an ``episodes.jsonl`` / ``errors.jsonl`` record."""
    return (record["method"], record["scene"], record["crowd"], record["level"], int(record["episode"]))


def episode_seed(base_seed: int, scene: str, crowd: str, level: str, episode: int) -> int:
    """The seed of one episode: SHA-256 of ``scene|crowd|level|episode`` and ``base_seed`` into a SeedSequence.

    It depends on nothing else (not the method, the worker or the order), so all methods face the same
    start, goal and crowd in the same episode. A 63-bit integer (``env.reset(seed=...)``).
    """
    digest = hashlib.sha256(f"{scene}|{crowd}|{level}|{int(episode)}".encode()).digest()
    ss = np.random.SeedSequence([int(base_seed), int.from_bytes(digest[:16], "little")])
    return int(ss.generate_state(1, np.uint64)[0] >> np.uint64(1))


def level_label(density: float | None = None, humans: int | None = None) -> str:
    """The crowd level's label: ``d<density>``, ``n<count>`` or ``default``."""
    if density is not None:
        return f"d{density:g}"
    if humans is not None:
        return f"n{int(humans)}"
    return "default"


def method_kinematics(method: str) -> str | None:
    """The robot kinematics a method's name asks for (``-holonomic`` / ``-diffdrive`` suffix, before a
    learned policy's ``-sampled``), else None."""
    from navzoo.agents.baselines import SAMPLED_SUFFIX

    key = method.strip().lower().replace("_", "-").removesuffix(SAMPLED_SUFFIX)
    if key.endswith("-holonomic"):
        return "holonomic"
    if key.endswith("-diffdrive") or key.endswith("-diff-drive"):
        return "diff_drive"
    return None


def density_humans(free_area: float, density: float, max_humans: int | None = None) -> int:
    """People at ``density`` per m² of a scene's crowd area ``free_area`` (m², as ``Scene.crowd_area``
    rounded to 0.1), capped at ``max_humans``: the count the benchmark's density levels run (and ``navzoo
    train robot --density`` trains at)."""
    n = int(round(density * round(float(free_area), 1)))
    return n if max_humans is None else min(n, int(max_humans))


def build_cells(spec: BenchmarkSpec) -> list[Cell]:
    """Every (scene, crowd, level) of the spec, scene-major."""
    from navzoo.benchmark.report import scene_group
    from navzoo.world.library import get_scene

    cells = []
    for scene in spec.scenes:
        sc = get_scene(scene)
        free = round(float(sc.crowd_area()), 1)
        levels: list[tuple[str, float, int]] = []
        if spec.densities is not None:
            for d in spec.densities:
                levels.append((level_label(density=d), d, density_humans(free, d)))
        elif spec.humans is not None:
            for n in spec.humans:
                levels.append((level_label(humans=n), round(n / free, 4) if free else 0.0, n))
        else:
            n = int(sc.default_humans)
            levels.append(("default", round(n / free, 4) if free else 0.0, n))
        for crowd in spec.crowds:
            if crowd == REPLAY_CROWD:  # everyone the window holds; each record gives its episode's count
                cells.append(Cell(scene, scene_group(scene), crowd, REPLAY_LEVEL, 0.0, 0, free))
                continue
            for label, dens, n in levels:
                if spec.max_humans is not None:
                    n = min(n, spec.max_humans)
                cells.append(Cell(scene, scene_group(scene), crowd, label, float(dens), int(n), free))
    return cells


def replay_window(scene: str, seed: int, time_limit: float | None = None) -> float:
    """The recording time (s) at which a replay episode of ``scene`` (``replay_<recording>``) starts.

    Drawn from the episode's seed, so every method of an episode sees the same people: uniform over the starts on
    a :data:`REPLAY_START_STEP` grid whose window ``[start, start + T]`` holds at least one recorded person
    (T = ``time_limit``, else the scene's own limit, at most the recording's length).
    """
    from navzoo.agents.replay import SCENE_PREFIX, load_recording
    from navzoo.world.library import get_scene

    rec = load_recording(scene[len(SCENE_PREFIX):])
    limit = float(time_limit) if time_limit is not None else float(get_scene(scene).time_limit)
    span = min(limit, rec.duration)
    starts = np.arange(0.0, max(rec.duration - span, 0.0) + 1e-9, REPLAY_START_STEP)
    starts = starts[starts < rec.duration]
    t0, t1 = rec.t0, rec.t1()
    busy = starts[[bool(np.any((t0 <= s + span) & (t1 >= s))) for s in starts]]
    pool = busy if busy.size else starts
    return float(np.random.default_rng(int(seed)).choice(pool))


def _env_kwargs(spec: BenchmarkSpec, cell: Cell, method: str) -> dict[str, Any]:
    kw = _plain(spec.env)
    robot = dict(kw.pop("robot", None) or {})
    kin = method_kinematics(method)
    if kin is not None:
        robot["kinematics"] = kin
    if robot:
        kw["robot"] = robot
    if cell.crowd.startswith(LEARNED_CROWD_PREFIX):
        # The learned pedestrians act themselves; the crowd model only names the env's default.
        kw.update(scene=cell.scene, n_humans=cell.n_humans, crowd_model="sfm", human_policy=cell.crowd)
    elif cell.crowd == REPLAY_CROWD:  # n_humans None: a slot for everyone the window holds
        kw.update(scene=cell.scene, n_humans=None, crowd_model=REPLAY_CROWD)
    else:
        kw.update(scene=cell.scene, n_humans=cell.n_humans, crowd_model=cell.crowd)
    if spec.time_limit is not None:
        kw["time_limit"] = float(spec.time_limit)
    if spec.max_steps is not None:
        kw["max_episode_steps_override"] = int(spec.max_steps)
    return kw


def build_tasks(spec: BenchmarkSpec, out: str | Path) -> list[EpisodeTask]:
    """Every episode of the spec, ordered scene, crowd, level, episode, method (so a partial run has whole
    comparisons, and a worker's envs are reused)."""
    tasks = []
    for cell in build_cells(spec):
        for ep in range(spec.episodes):
            seed = episode_seed(spec.seed, cell.scene, cell.crowd, cell.level, ep)
            window = replay_window(cell.scene, seed, spec.time_limit) if cell.crowd == REPLAY_CROWD else None
            for method in spec.methods:
                kw = _env_kwargs(spec, cell, method)
                if window is not None:
                    kw["replay_start"] = window
                tasks.append(EpisodeTask(
                    method=method, cell=cell, episode=ep, seed=seed, env_kwargs=kw,
                    save_trajectory=ep < spec.save_trajectories, video=ep < spec.videos, out=str(out),
                ))
    return tasks


def validate_spec(spec: BenchmarkSpec) -> None:
    """Check names before any work starts: scenes, methods (after the spec's imports), env overrides."""
    from navzoo.agents.baselines import make_policy
    from navzoo.envs.config import NavConfig
    from navzoo.world.library import get_scene

    for module in spec.imports:
        try:
            importlib.import_module(module)
        except ImportError as exc:
            raise ValueError(f"benchmark spec: cannot import {module!r} (imports): {exc}") from exc
    for scene in spec.scenes:
        get_scene(scene)  # ValueError naming the valid scenes
    for method in spec.methods:
        make_policy(method)  # ValueError naming the valid policies
    for crowd in spec.crowds:
        if crowd.startswith(LEARNED_CROWD_PREFIX):
            from navzoo.rl.config import resolve_module_dir

            try:
                resolve_module_dir(crowd[len(LEARNED_CROWD_PREFIX):], "human")
            except FileNotFoundError as exc:
                raise ValueError(f"benchmark spec: crowd {crowd!r}: {exc}") from exc
    env = _plain(spec.env)
    if "diffusion" in spec.crowds:
        from navzoo.agents.diffusion.crowd import model_dir

        try:
            model_dir(env.get("diffusion_model"))
        except FileNotFoundError as exc:
            raise ValueError(f"benchmark spec: crowd 'diffusion' (env.diffusion_model, or $NAVZOO_DIFFUSION_MODEL): "
                             f"{exc}") from exc
    robot = env.pop("robot", None)
    if robot is not None and not isinstance(robot, Mapping):
        raise ValueError(f"benchmark spec: env.robot must be a mapping of RobotSpec fields, got {robot!r}")
    data = {**env, "scene": spec.scenes[0]}
    if robot:
        data["robot"] = dict(robot)
    NavConfig.from_dict(data)  # ValueError naming unknown keys / bad values
    if REPLAY_CROWD in spec.crowds:  # e.g. physics bodies cannot walk recorded tracks
        try:
            NavConfig.from_dict({**data, "crowd_model": REPLAY_CROWD})
        except ValueError as exc:
            raise ValueError(f"benchmark spec: crowd 'replay' with this env: {exc}") from exc


# ---------------------------------------------------------------------------------------------------------
# One episode (runs in a worker)
# ---------------------------------------------------------------------------------------------------------

_ENV_CACHE: OrderedDict[str, Any] = OrderedDict()
_ENV_CACHE_SIZE = 2
_INFLIGHT_DIR: str | None = None
_CURRENT: dict[str, Any] | None = None


def current_episode() -> dict[str, Any] | None:
    """The episode this process is running (method, scene, crowd, level, n_humans, episode, seed), else None.

    For policies that want to know where they are (logging, per-episode behaviour in tests).
    """
    return None if _CURRENT is None else dict(_CURRENT)


def _get_env(kwargs: Mapping[str, Any], render: bool) -> Any:
    """A worker's env for these settings (reused: ``reset(seed)`` makes an episode independent of history)."""
    from navzoo.envs.registry import make

    key = json.dumps({"kw": kwargs, "render": render}, sort_keys=True, default=str)
    env = _ENV_CACHE.get(key)
    if env is not None:
        _ENV_CACHE.move_to_end(key)
        return env
    while len(_ENV_CACHE) >= _ENV_CACHE_SIZE:
        _, old = _ENV_CACHE.popitem(last=False)
        with contextlib.suppress(Exception):
            old.close()
    kw = dict(kwargs)
    learned = kw.pop("human_policy", None)
    if learned is None:
        env = make(None, render_mode="rgb_array" if render else None, **kw)
    else:
        from navzoo.envs.wrappers import FrozenAgents
        from navzoo.rl.joint import FlatObsPolicy, RLModulePolicy

        raw = make(None, render_mode="rgb_array" if render else None, raw=True, **kw)
        policy = FlatObsPolicy(RLModulePolicy(learned[len(LEARNED_CROWD_PREFIX):], "human"))
        env = FrozenAgents(raw, lambda a: a.startswith("human_"), policy)
    _ENV_CACHE[key] = env
    return env


def _drop_env(kwargs: Mapping[str, Any], render: bool) -> None:
    key = json.dumps({"kw": kwargs, "render": render}, sort_keys=True, default=str)
    env = _ENV_CACHE.pop(key, None)
    if env is not None:
        with contextlib.suppress(Exception):
            env.close()


def close_envs() -> None:
    """Close this process's cached envs."""
    while _ENV_CACHE:
        _, env = _ENV_CACHE.popitem()
        with contextlib.suppress(Exception):
            env.close()


def _seed_globals(seed: int) -> None:
    random.seed(seed)
    np.random.seed(seed % 2**32)
    torch = sys.modules.get("torch")
    if torch is not None:
        torch.manual_seed(seed % 2**63)


def _seed_policy(policy: Any, seed: int) -> None:
    """Give a policy with its own generator a per-episode one (``RandomPolicy``) or call its ``seed``."""
    if callable(getattr(policy, "seed", None)):
        policy.seed(seed)
    elif isinstance(getattr(policy, "rng", None), np.random.Generator):
        policy.rng = np.random.default_rng(seed)


def _safe_name(text: str) -> str:
    return re.sub(r"[^A-Za-z0-9._-]+", "_", text)


def artifact_path(task_or_record: EpisodeTask | Mapping[str, Any], suffix: str) -> Path:
    """Relative path of an episode's trajectory / video: ``<method>/<scene>/<crowd>_<level>_ep0007<suffix>``."""
    if isinstance(task_or_record, EpisodeTask):
        m, s, c, lv, ep = task_or_record.key
    else:
        m, s, c, lv, ep = episode_key(task_or_record)
    return Path(_safe_name(m)) / _safe_name(s) / f"{_safe_name(c)}_{_safe_name(lv)}_ep{int(ep):04d}{suffix}"


def run_episode(task: EpisodeTask) -> dict[str, Any]:
    """Run one episode and return its ``episodes.jsonl`` record (writes its npz / mp4 if asked).

    The episode runs on one torch thread, as in the worker processes, so that torch models (the diffusion crowd,
    learned policies) give the same numbers in this process (``workers=0``) as in any number of workers."""
    from navzoo.torch_threads import one_torch_thread

    with one_torch_thread():
        return _run_episode(task)


def _run_episode(task: EpisodeTask) -> dict[str, Any]:
    from navzoo.agents.baselines import make_policy
    from navzoo.benchmark.metrics import episode_metrics

    global _CURRENT
    t0 = time.perf_counter()
    c = task.cell
    _CURRENT = {"method": task.method, "scene": c.scene, "crowd": c.crowd, "level": c.level,
                "n_humans": c.n_humans, "episode": task.episode, "seed": task.seed}
    env = _get_env(task.env_kwargs, task.video)
    try:
        nav = env.unwrapped
        _seed_globals(task.seed)
        policy = make_policy(task.method)
        _seed_policy(policy, task.seed)
        obs, _ = env.reset(seed=task.seed)
        policy.reset(nav)
        R = nav.n_robots
        if R != 1:
            raise ValueError(f"the benchmark runs one robot per episode, the env has {R}")
        start, goal = nav.pos[0].copy(), nav.goal[0].copy()
        reference = np.asarray(nav.paths[0], dtype=np.float64).copy()
        rec: dict[str, list[np.ndarray]] = {k: [] for k in ("rp", "ryaw", "rvel", "hp", "hvel", "hyaw", "hact")}

        def snap() -> None:
            rec["rp"].append(nav.pos[0].copy())
            rec["ryaw"].append(float(nav.yaw[0]))
            rec["rvel"].append(nav.vel[0].copy())
            rec["hp"].append(nav.pos[R:].copy())
            rec["hvel"].append(nav.vel[R:].copy())
            rec["hyaw"].append(nav.yaw[R:].copy())
            rec["hact"].append(np.asarray(nav.human_active, dtype=bool).copy())  # replay: False while parked

        snap()
        frames = _VideoWriter(task, nav) if task.video else None
        event = None
        robot = nav.possible_agents[0]
        try:
            if frames is not None:
                frames.add(env.render())
            while env.agents:
                actions = policy.act(obs, nav)
                obs, _, terms, truncs, infos = env.step(actions)
                snap()
                if frames is not None:
                    frames.add(env.render())
                if robot in infos and (terms.get(robot) or truncs.get(robot)):
                    event = infos[robot].get("event")
        finally:
            if frames is not None:
                frames.close()
        dt = float(nav.config.dt)
        time_limit = float(nav.max_steps * dt)
        rp, hp = np.array(rec["rp"]), np.array(rec["hp"]).reshape(len(rec["rp"]), nav.n_humans, 2)
        hvel = np.array(rec["hvel"]).reshape(hp.shape)
        hyaw = np.array(rec["hyaw"]).reshape(hp.shape[:2])
        hact = np.array(rec["hact"], dtype=bool).reshape(hp.shape[:2])
        metrics = episode_metrics(
            rp, hp, float(nav.radius[0]), nav.radius[R:], dt, event or "timeout",
            goal=goal, shortest_path=float(nav.shortest_path_length[0]), time_limit=time_limit,
            v_pref=float(nav.v_pref[0]), robot_yaw=np.array(rec["ryaw"]), robot_vel=np.array(rec["rvel"]),
            human_vel=hvel, human_yaw=hyaw, reference_path=reference, segments=nav.segments,
            human_present=hact if nav.replay is not None else None,
        )
        metrics.pop("thresholds", None)  # the same for every episode: in run.json
        if nav.amp is not None:
            # physics pedestrians (env human_model "amp"): how many fell during the episode, whatever the cause
            # (a fallen body stays down); an episode that ends at the robot's first contact cannot show a fall
            # that contact causes later
            metrics["people_fallen"] = int(np.count_nonzero(nav.human_fallen))
        if task.save_trajectory:
            path = Path(task.out) / "trajectories" / artifact_path(task, ".npz")
            path.parent.mkdir(parents=True, exist_ok=True)
            np.savez_compressed(
                path, robot_pos=rp, robot_yaw=np.array(rec["ryaw"]), robot_vel=np.array(rec["rvel"]),
                human_pos=hp, human_vel=hvel, human_yaw=hyaw, human_present=hact, start=start, goal=goal,
                reference_path=reference,
                robot_radius=float(nav.radius[0]), human_radius=nav.radius[R:].copy(), dt=dt,
                scene=task.cell.scene, method=task.method, event=metrics["event"], seed=task.seed,
                episode=task.episode,
            )
    except BaseException:
        _drop_env(task.env_kwargs, task.video)  # an env that raised mid-episode is not trusted again
        raise
    finally:
        _CURRENT = None
    cell = task.cell
    record = {
        "method": task.method, "scene": cell.scene, "group": cell.group, "crowd": cell.crowd,
        "level": cell.level, "density": cell.density, "n_humans": cell.n_humans, "episode": task.episode,
        "seed": task.seed, "start": [float(v) for v in start], "goal": [float(v) for v in goal],
        "dt": dt, **metrics,
    }
    if cell.crowd == REPLAY_CROWD:  # the window's people (slots) and where in the recording it starts
        record.update(n_humans=int(nav.n_humans), density=round(nav.n_humans / cell.free_area_m2, 4)
                      if cell.free_area_m2 else 0.0, replay_start=float(nav.config.replay_start),
                      people_in_window=len(nav.replay.assignment))
    return {"record": _json_safe(record), "wall_s": time.perf_counter() - t0}


class _VideoWriter:
    """mp4 (OpenCV, ``mp4v``) of the env's top-down frames, plus the last frame as a PNG poster."""

    def __init__(self, task: EpisodeTask, nav: Any) -> None:
        self.path = Path(task.out) / "videos" / artifact_path(task, ".mp4")
        self.path.parent.mkdir(parents=True, exist_ok=True)
        self.fps = max(1, int(round(1.0 / float(nav.config.dt))))
        self.writer = None
        self.last = None

    def add(self, frame: np.ndarray | None) -> None:
        import cv2

        if frame is None:
            return
        if self.writer is None:
            h, w = frame.shape[:2]
            self.writer = cv2.VideoWriter(str(self.path), cv2.VideoWriter_fourcc(*"mp4v"), self.fps, (w, h))
        bgr = cv2.cvtColor(frame, cv2.COLOR_RGB2BGR)
        self.writer.write(bgr)
        self.last = bgr

    def close(self) -> None:
        import cv2

        if self.writer is not None:
            self.writer.release()
        if self.last is not None:
            cv2.imwrite(str(self.path.with_suffix(".png")), self.last)


def _inflight_path(pid: int) -> Path | None:
    return Path(_INFLIGHT_DIR) / f"{pid}.json" if _INFLIGHT_DIR else None


def execute_task(task: EpisodeTask) -> dict[str, Any]:
    """Run a task, catching its exception: ``{"ok": True, "record", "wall_s"}`` or ``{"ok": False, "error"}``.

    In a worker, the task is announced in ``DIR/.inflight/<pid>.json`` while it runs, so that the main
    process can name the episode if the worker dies.
    """
    marker = _inflight_path(os.getpid())
    if marker is not None:
        marker.write_text(json.dumps({"key": list(task.key), "start": time.time()}))
    try:
        try:
            return {"ok": True, **run_episode(task)}
        except Exception as exc:  # noqa: BLE001 - any failure of a policy or env is recorded, not fatal
            return {"ok": False, "error": {"type": type(exc).__name__, "message": str(exc),
                                           "traceback": traceback.format_exc()}}
    finally:
        if marker is not None:
            with contextlib.suppress(OSError):
                marker.unlink()


def _init_worker(imports: Sequence[str], inflight_dir: str) -> None:
    """Worker setup: one torch thread, Ctrl-C left to the main process, SIGTERM drops the inflight marker."""
    global _INFLIGHT_DIR
    _INFLIGHT_DIR = inflight_dir
    signal.signal(signal.SIGINT, signal.SIG_IGN)

    def on_term(signum: int, frame: Any) -> None:  # terminated by the pool (another worker died): not a culprit
        marker = _inflight_path(os.getpid())
        if marker is not None:
            with contextlib.suppress(OSError):
                marker.unlink()
        os._exit(128 + signum)

    signal.signal(signal.SIGTERM, on_term)
    os.environ.setdefault("OMP_NUM_THREADS", "1")
    try:
        import torch

        torch.set_num_threads(1)
    except ImportError:
        pass
    for module in imports:
        importlib.import_module(module)


# ---------------------------------------------------------------------------------------------------------
# Output files
# ---------------------------------------------------------------------------------------------------------


def _json_safe(value: Any) -> Any:
    """JSON-ready: numpy scalars to Python, nan/inf to None (strict JSON)."""
    if isinstance(value, Mapping):
        return {str(k): _json_safe(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_json_safe(v) for v in value]
    if isinstance(value, (bool, np.bool_)):
        return bool(value)
    if isinstance(value, (int, np.integer)):
        return int(value)
    if isinstance(value, (float, np.floating)):
        v = float(value)
        return v if math.isfinite(v) else None
    if isinstance(value, np.ndarray):
        return _json_safe(value.tolist())
    return value


def _read_jsonl(path: Path) -> list[dict[str, Any]]:
    if not path.is_file():
        return []
    if path.name.endswith(".gz"):  # a committed run (benchmarks/*/episodes.jsonl.gz)
        with gzip.open(path, "rt", encoding="utf-8") as f:
            text = f.read()
    else:
        text = path.read_text(encoding="utf-8")
    out = []
    for line in text.splitlines():
        line = line.strip()
        if not line:
            continue
        try:
            obj = json.loads(line)
        except json.JSONDecodeError:
            continue  # a line cut off by a kill
        if isinstance(obj, dict):
            out.append(obj)
    return out


def _episodes_in(path: Path) -> list[dict[str, Any]]:
    recs: dict[tuple, dict[str, Any]] = {}
    for r in _read_jsonl(path):
        with contextlib.suppress(KeyError, TypeError, ValueError):
            recs[episode_key(r)] = r
    return list(recs.values())


def load_episodes(out: str | Path) -> list[dict[str, Any]]:
    """The finished episodes of a run directory (one record per episode key, the last one written)."""
    return _episodes_in(Path(out) / EPISODES_FILE)


def load_errors(out: str | Path, unresolved: bool = True) -> list[dict[str, Any]]:
    """Error records of a run directory; ``unresolved``: only those of episodes with no result since."""
    errs = _read_jsonl(Path(out) / ERRORS_FILE)
    if not unresolved:
        return errs
    done = {episode_key(r) for r in load_episodes(out)}
    latest: dict[tuple, dict[str, Any]] = {}
    for e in errs:
        with contextlib.suppress(KeyError, TypeError, ValueError):
            if episode_key(e) not in done:
                latest[episode_key(e)] = e
    return list(latest.values())


def _source_episodes(src: Path) -> list[dict[str, Any]]:
    """The episodes of a run directory, or of a folder holding a committed ``episodes.jsonl.gz``."""
    for path in (src / EPISODES_FILE, src / (EPISODES_FILE + ".gz")):
        if path.is_file():
            return _episodes_in(path)
    raise FileNotFoundError(f"{src}: no {EPISODES_FILE} or {EPISODES_FILE}.gz (not a benchmark run)")


def merge_runs(sources: Sequence[str | Path], out: str | Path) -> dict[str, Any]:
    """Merge benchmark runs of different methods into one run directory ``out`` for one report.

    Typical use: a new method run on its own (same scenes, levels, episodes and seed) next to a committed
    baseline run, without rerunning the baselines. Episodes of the same key are the same start, goal and
    crowd in every run (:func:`episode_seed`), so the rows compare like with like. A source is a run
    directory or a folder with ``episodes.jsonl.gz`` (and ``run.json``).

    Raises:
        ValueError: fewer than two sources; runs whose result-changing fields (seed, time limit, step cap,
            env options, people cap) differ; or the same episode in two sources.
        FileNotFoundError: a source without episodes.
    """
    if len(sources) < 2:
        raise ValueError("merge_runs needs at least two runs")
    out = Path(out)
    episodes: dict[tuple, tuple[str, dict[str, Any]]] = {}
    docs: list[tuple[str, dict[str, Any]]] = []
    for src in map(Path, sources):
        if src.resolve() == out.resolve():
            raise ValueError(f"the merged run {out} cannot also be a source")
        doc = json.loads((src / RUN_FILE).read_text(encoding="utf-8")) if (src / RUN_FILE).is_file() else {}
        if doc.get("spec"):
            fields = {k: doc["spec"].get(k) for k in _RESULT_FIELDS}  # run.json holds BenchmarkSpec.to_dict()
            for name, first in docs:
                if first.get("spec"):
                    other = {k: first["spec"].get(k) for k in _RESULT_FIELDS}
                    diff = [k for k in fields if fields[k] != other[k]]
                    if diff:
                        raise ValueError(f"{src} and {name} differ in {', '.join(diff)} "
                                         f"({', '.join(f'{k}: {fields[k]!r} vs {other[k]!r}' for k in diff)}): "
                                         "their episodes are not comparable")
        docs.append((str(src), doc))
        for r in _source_episodes(src):
            key = episode_key(r)
            if key in episodes:
                raise ValueError(f"episode {key} is in both {episodes[key][0]} and {src}")
            episodes[key] = (str(src), r)
    specs = [d["spec"] for _, d in docs if d.get("spec")]
    spec: dict[str, Any] = dict(specs[0]) if specs else {}
    for k in ("scenes", "methods", "crowd", "density", "humans"):
        vals: list[Any] = []
        for sp in specs:
            for v in sp.get(k) or []:
                if v not in vals:
                    vals.append(v)
        if vals:
            spec[k] = sorted(vals) if k in ("density", "humans") else vals
    if specs:
        spec["episodes"] = max(int(sp.get("episodes") or 0) for sp in specs)
    sessions = [dict(s, run=name) for name, d in docs for s in d.get("sessions", [])]
    methods = {name: sorted({r["method"] for n, r in episodes.values() if n == name}) for name, _ in docs}
    doc = {"created": time.strftime("%Y-%m-%dT%H:%M:%S%z"),
           "merged_from": [{"run": name, "methods": methods[name], "machine": d.get("machine")} for name, d in docs],
           "spec": spec, "machine": None,
           "thresholds": next((d["thresholds"] for _, d in docs if d.get("thresholds")), None),
           "episodes_total": len(episodes), "sessions": sessions, "episodes_done": len(episodes)}
    out.mkdir(parents=True, exist_ok=True)
    tmp = out / (EPISODES_FILE + ".tmp")
    with open(tmp, "w", encoding="utf-8") as f:
        for _, r in episodes.values():
            f.write(json.dumps(r, allow_nan=False) + "\n")
    os.replace(tmp, out / EPISODES_FILE)
    _write_json(out / RUN_FILE, doc)
    return doc


def _repair_tail(path: Path) -> None:
    """Drop a last line cut off by a kill, so that appended lines start on a line of their own."""
    if not path.is_file() or path.stat().st_size == 0:
        return
    with open(path, "r+b") as f:
        end = f.seek(0, os.SEEK_END)
        f.seek(end - 1)
        if f.read(1) == b"\n":
            return
        pos = end
        while pos > 0:  # back to the last newline, 64 kB at a time
            start = max(0, pos - 65536)
            f.seek(start)
            chunk = f.read(pos - start)
            i = chunk.rfind(b"\n")
            if i >= 0:
                f.truncate(start + i + 1)
                return
            pos = start
        f.truncate(0)


class _Appender:
    """Appends JSON lines, each flushed and fsynced at once (a kill loses at most the line being written)."""

    def __init__(self, path: Path) -> None:
        _repair_tail(path)
        self.f = open(path, "a", encoding="utf-8")  # noqa: SIM115 - closed in close()

    def write(self, obj: Mapping[str, Any]) -> None:
        self.f.write(json.dumps(_json_safe(obj), allow_nan=False) + "\n")
        self.f.flush()
        os.fsync(self.f.fileno())

    def close(self) -> None:
        self.f.close()


def _write_json(path: Path, obj: Any) -> None:
    tmp = path.with_name(path.name + ".tmp")
    tmp.write_text(json.dumps(_json_safe(obj), indent=2, allow_nan=False) + "\n", encoding="utf-8")
    os.replace(tmp, path)


def machine_info() -> dict[str, Any]:
    """CPU model, cores, load average, OS, Python, the numeric packages' versions, navzoo version and git commit (when
    in a checkout)."""
    import navzoo
    from navzoo.machine import package_versions

    info: dict[str, Any] = {
        "cpu": cpu_model(),
        "cores": os.cpu_count(),
        "platform": platform.platform(),
        "python": platform.python_version(),
        "navzoo": getattr(navzoo, "__version__", None),
        "hostname": platform.node(),
        "packages": package_versions(),
    }
    info["load_average"] = _loadavg()
    root = Path(navzoo.__file__).resolve().parent.parent
    try:
        commit = subprocess.run(["git", "-C", str(root), "rev-parse", "HEAD"], capture_output=True, text=True,
                                timeout=10)
        if commit.returncode == 0:
            info["git_commit"] = commit.stdout.strip()
            dirty = subprocess.run(["git", "-C", str(root), "status", "--porcelain", "--untracked-files=no"],
                                   capture_output=True, text=True, timeout=10)
            info["git_dirty"] = bool(dirty.stdout.strip())
    except (OSError, subprocess.SubprocessError):
        pass
    return info


# ---------------------------------------------------------------------------------------------------------
# Progress
# ---------------------------------------------------------------------------------------------------------


class _Progress:
    """A progress bar with ETA on stderr (tqdm if installed, else a line every few seconds)."""

    def __init__(self, total: int, done_before: int, desc: str, enabled: bool) -> None:
        self.total, self.n, self.errors = total, 0, 0
        self.enabled = enabled and total > 0
        self.t0 = time.perf_counter()
        self.last_print = 0.0
        self.bar = None
        if not self.enabled:
            return
        if done_before:
            print(f"{desc}: {done_before} episodes already done, {total} to run", file=sys.stderr)
        try:
            from tqdm import tqdm

            self.bar = tqdm(total=total, desc=desc, unit="ep", file=sys.stderr, dynamic_ncols=True, smoothing=0.05)
        except ImportError:
            self.desc = desc

    def update(self, ok: bool) -> None:
        self.n += 1
        self.errors += 0 if ok else 1
        if not self.enabled:
            return
        if self.bar is not None:
            self.bar.update(1)
            if self.errors:
                self.bar.set_postfix(errors=self.errors, refresh=False)
            return
        now = time.perf_counter()
        if now - self.last_print < 5.0 and self.n < self.total:
            return
        self.last_print = now
        el = now - self.t0
        rate = self.n / el if el > 0 else 0.0
        eta = (self.total - self.n) / rate if rate > 0 else float("nan")
        print(f"{self.desc}: {self.n}/{self.total} episodes ({100 * self.n / self.total:.0f} %), "
              f"{self.errors} errors, {3600 * rate:.0f} ep/h, elapsed {_hms(el)}, ETA {_hms(eta)}",
              file=sys.stderr, flush=True)

    def close(self) -> None:
        if self.bar is not None:
            self.bar.close()


def _hms(s: float) -> str:
    if not math.isfinite(s):
        return "?"
    s = int(round(s))
    return f"{s // 3600:d}:{s % 3600 // 60:02d}:{s % 60:02d}"


# ---------------------------------------------------------------------------------------------------------
# The run
# ---------------------------------------------------------------------------------------------------------


class _Terminated(Exception):
    """SIGTERM in the main process: stop like Ctrl-C (write run.json, stop the workers)."""


def run_benchmark(
    spec: BenchmarkSpec,
    out: str | Path,
    workers: int | None = None,
    progress: bool = True,
    max_episodes: int | None = None,
    command: Sequence[str] | None = None,
) -> dict[str, Any]:
    """Run (or resume) a benchmark into ``out``.

    Args:
        spec: what to run.
        out: the run directory (created; an existing one is resumed: its finished episodes are skipped).
        workers: worker processes (default: the CPU count); 0 runs the episodes in this process (no crash
            isolation, for debugging).
        progress: progress bar and ETA on stderr.
        max_episodes: run at most this many of the missing episodes now (a partial run; rerun to go on).
        command: the command line, recorded in ``run.json``.

    Returns:
        A summary: ``out``, ``status`` (``complete`` | ``partial`` | ``interrupted``), ``episodes_total``,
        ``episodes_done`` (all sessions), ``episodes_run`` and ``errors`` (this session), ``skipped``,
        ``wall_s``, ``episodes_per_hour``.

    Raises:
        ValueError: a bad spec, or ``out`` holds a run whose result-changing fields differ.
        KeyboardInterrupt: Ctrl-C or SIGTERM, after recording the session (the run resumes from there).
    """
    if not isinstance(spec, BenchmarkSpec):
        raise TypeError(f"spec must be a BenchmarkSpec, got {type(spec).__name__}")
    if workers is None:
        workers = os.cpu_count() or 1
    if not _is_int(workers) or workers < 0:
        raise ValueError(f"workers must be an integer >= 0, got {workers!r}")
    if max_episodes is not None and (not _is_int(max_episodes) or max_episodes < 0):
        raise ValueError(f"max_episodes must be None or an integer >= 0, got {max_episodes!r}")
    validate_spec(spec)
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    run_path = out / RUN_FILE
    run_doc: dict[str, Any] = {}
    if run_path.is_file():
        try:
            run_doc = json.loads(run_path.read_text(encoding="utf-8"))
        except json.JSONDecodeError as exc:
            raise ValueError(f"{run_path} is not valid JSON ({exc}); use another --out") from exc
        old = BenchmarkSpec.from_dict(run_doc["spec"]).result_fields() if "spec" in run_doc else None
        new = spec.result_fields()
        if old is not None and old != new:
            diff = {k: (old[k], new[k]) for k in new if old.get(k) != new[k]}
            raise ValueError(f"{out} holds a run with different settings {diff} (old, new): its episodes would "
                             "not be comparable; use another --out")
    tasks = build_tasks(spec, out)
    finished = {episode_key(r) for r in load_episodes(out)}
    todo = [t for t in tasks if t.key not in finished]
    skipped = len(tasks) - len(todo)
    if max_episodes is not None:
        todo = todo[:max_episodes]
    from navzoo.benchmark.metrics import Thresholds

    session = {
        "start": _now(), "end": None, "status": "running", "workers": workers, "command": list(command or []),
        "episodes_to_run": len(todo), "episodes_run": 0, "errors": 0, "wall_s": None, "episodes_per_hour": None,
        "load_average_start": _loadavg(),
    }
    run_doc.setdefault("created", session["start"])
    run_doc.update({
        "spec": spec.to_dict(), "machine": machine_info(), "thresholds": Thresholds().as_dict(),
        "episodes_total": len(tasks), "files": {"episodes": EPISODES_FILE, "errors": ERRORS_FILE},
    })
    run_doc.setdefault("sessions", []).append(session)
    _write_json(run_path, run_doc)

    episodes_file = _Appender(out / EPISODES_FILE)
    errors_file = _Appender(out / ERRORS_FILE)
    bar = _Progress(len(todo), skipped, f"benchmark {out.name}", progress)
    errors: list[dict[str, Any]] = []
    method_wall: Counter[str] = Counter()
    method_n: Counter[str] = Counter()
    counts = {"ok": 0}

    def on_result(task: EpisodeTask, res: Mapping[str, Any]) -> None:
        if res.get("ok"):
            episodes_file.write(res["record"])
            counts["ok"] += 1
            method_wall[task.method] += float(res.get("wall_s", 0.0))
            method_n[task.method] += 1
            bar.update(True)
        else:
            on_error(task, res["error"])

    def on_error(task: EpisodeTask, err: Mapping[str, Any]) -> None:
        c = task.cell
        rec = {"method": task.method, "scene": c.scene, "crowd": c.crowd, "level": c.level,
               "n_humans": c.n_humans, "episode": task.episode, "seed": task.seed, "time": _now(), **err}
        errors_file.write(rec)
        errors.append(rec)
        bar.update(False)

    t0 = time.perf_counter()
    status = "interrupted"
    old_term = None
    if _in_main_thread():
        def raise_term(signum: int, frame: Any) -> None:
            raise _Terminated()

        old_term = signal.signal(signal.SIGTERM, raise_term)
    try:
        if workers == 0:
            for task in todo:
                on_result(task, execute_task(task))
        else:
            _run_pool(todo, workers, spec, out, on_result, on_error)
        status = "complete" if len(todo) + skipped == len(tasks) else "partial"
    except _Terminated:
        raise KeyboardInterrupt("terminated (SIGTERM)") from None
    finally:
        if old_term is not None:
            signal.signal(signal.SIGTERM, old_term)
        if workers == 0:
            close_envs()
        bar.close()
        episodes_file.close()
        errors_file.close()
        wall = time.perf_counter() - t0
        n_run = counts["ok"] + len(errors)
        session.update({
            "end": _now(), "status": status, "episodes_run": counts["ok"], "errors": len(errors), "wall_s": wall,
            "episodes_per_hour": 3600.0 * n_run / wall if wall > 0 and n_run else None,
            "episode_wall_s_by_method": {m: method_wall[m] / method_n[m] for m in method_n},
            "load_average_end": _loadavg(),
        })
        done_now = load_episodes(out)
        run_doc["episodes_done"] = len({episode_key(r) for r in done_now} & {t.key for t in tasks})
        run_doc["updated"] = session["end"]
        _write_json(run_path, run_doc)
    return {
        "out": str(out), "status": status, "episodes_total": len(tasks), "episodes_done": run_doc["episodes_done"],
        "episodes_run": counts["ok"], "skipped": skipped, "errors": errors, "wall_s": session["wall_s"],
        "episodes_per_hour": session["episodes_per_hour"],
    }


def _run_pool(todo: list[EpisodeTask], workers: int, spec: BenchmarkSpec, out: Path,
              on_result: Callable[[EpisodeTask, Mapping[str, Any]], None],
              on_error: Callable[[EpisodeTask, Mapping[str, Any]], None]) -> None:
    """Run ``todo`` in a spawn process pool, restarting it when a worker dies (see the module docstring)."""
    inflight = out / ".inflight"
    inflight.mkdir(exist_ok=True)
    queue: deque[EpisodeTask] = deque(todo)
    by_key = {t.key: t for t in todo}
    strikes: Counter[tuple] = Counter()
    ctx = multiprocessing.get_context("spawn")
    timeout = spec.episode_timeout or None
    window = 2 * workers
    try:
        while queue:
            for f in inflight.glob("*.json"):
                f.unlink(missing_ok=True)
            ex = ProcessPoolExecutor(max_workers=min(workers, len(queue)), mp_context=ctx, initializer=_init_worker,
                                     initargs=(tuple(spec.imports), str(inflight)))
            futs: dict[Future, EpisodeTask] = {}
            procs: dict[int, Any] = {}
            killed: dict[int, str] = {}
            lost: list[EpisodeTask] = []  # in flight when the pool broke
            try:
                while (queue or futs) and not lost:
                    while queue and len(futs) < window:
                        task = queue.popleft()
                        try:
                            futs[ex.submit(execute_task, task)] = task
                        except BrokenProcessPool:  # a worker died since the last wait: restart as below
                            lost.append(task)
                            break
                        procs.update(getattr(ex, "_processes", None) or {})
                    if lost:
                        break
                    done, _ = wait(list(futs), timeout=1.0, return_when=FIRST_COMPLETED)
                    for f in done:
                        task = futs.pop(f)
                        exc = f.exception()
                        if exc is None:
                            strikes.pop(task.key, None)
                            on_result(task, f.result())
                        elif isinstance(exc, BrokenProcessPool):
                            lost.append(task)
                        else:  # the result could not be sent back (e.g. not picklable)
                            on_error(task, {"type": type(exc).__name__, "message": str(exc),
                                            "traceback": "".join(traceback.format_exception(exc))})
                    if timeout and not lost:
                        killed.update(_kill_overdue(inflight, timeout))
            except BaseException:
                for p in procs.values():  # Ctrl-C / SIGTERM: stop the workers now, the run resumes later
                    with contextlib.suppress(Exception):
                        p.kill()
                ex.shutdown(wait=False, cancel_futures=True)
                raise
            if not lost:
                ex.shutdown(wait=True)
                continue
            # A worker died: the executor failed every pending future and terminated the other workers
            # (whose SIGTERM handler removed their inflight markers). The markers left name the culprits.
            ex.shutdown(wait=True, cancel_futures=True)
            for f, task in futs.items():
                if f.done() and not f.cancelled() and f.exception() is None:
                    on_result(task, f.result())
                else:
                    lost.append(task)
            culprits: dict[int, tuple[tuple, float]] = {}
            for marker in inflight.glob("*.json"):
                with contextlib.suppress(OSError, ValueError, KeyError, TypeError, json.JSONDecodeError):
                    info = json.loads(marker.read_text())
                    culprits[int(marker.stem)] = ((*info["key"][:4], int(info["key"][4])), float(info["start"]))
                marker.unlink(missing_ok=True)
            failed: set[tuple] = set()
            for pid, (key, start) in culprits.items():
                task = by_key.get(key)
                if task is None or key in failed:
                    continue
                code = getattr(procs.get(pid), "exitcode", None)
                msg = killed.get(pid) or f"worker process {pid} died while running this episode (exit code {code})"
                on_error(task, {"type": "WorkerDied", "message": msg, "exit_code": code,
                                "traceback": f"{msg}; it had run {time.time() - start:.1f} s"})
                failed.add(key)
            if not culprits:  # no marker left (e.g. a worker killed between episodes): strikes for all
                for task in lost:
                    strikes[task.key] += 1
                    if strikes[task.key] >= _MAX_STRIKES and task.key not in failed:
                        on_error(task, {"type": "WorkerDied", "message": f"the worker pool broke {_MAX_STRIKES} "
                                        "times while this episode was in flight", "traceback": ""})
                        failed.add(task.key)
            order = {t.key: i for i, t in enumerate(todo)}  # the others run again, in spec order
            queue = deque(sorted([t for t in [*lost, *queue] if t.key not in failed], key=lambda t: order[t.key]))
    finally:
        for f in inflight.glob("*.json"):
            f.unlink(missing_ok=True)
        with contextlib.suppress(OSError):
            inflight.rmdir()


def _kill_overdue(inflight: Path, timeout: float) -> dict[int, str]:
    """SIGKILL the workers whose episode has run longer than ``timeout`` s (the pool then restarts)."""
    killed = {}
    now = time.time()
    for marker in inflight.glob("*.json"):
        with contextlib.suppress(OSError, ValueError, KeyError, json.JSONDecodeError):
            info = json.loads(marker.read_text())
            if now - float(info["start"]) > timeout:
                pid = int(marker.stem)
                os.kill(pid, signal.SIGKILL)
                killed[pid] = f"episode timed out after {timeout:g} s (worker process {pid} killed)"
    return killed


def _loadavg() -> list[float] | None:
    try:
        return [round(v, 2) for v in os.getloadavg()]
    except (OSError, AttributeError):
        return None


def _now() -> str:
    return time.strftime("%Y-%m-%dT%H:%M:%S%z")


def _in_main_thread() -> bool:
    import threading

    return threading.current_thread() is threading.main_thread()


# ---------------------------------------------------------------------------------------------------------
# Small parsers
# ---------------------------------------------------------------------------------------------------------


def _is_int(v: Any) -> bool:
    return isinstance(v, (int, np.integer)) and not isinstance(v, bool)


def _is_num(v: Any) -> bool:
    return isinstance(v, (int, float, np.integer, np.floating)) and not isinstance(v, bool)


def _split(value: Any) -> list[str]:
    if isinstance(value, str):
        return [v.strip() for v in value.split(",") if v.strip()]
    if isinstance(value, Iterable):
        return [str(v).strip() for v in value if str(v).strip()]
    raise ValueError(f"expected a list or a comma-separated string, got {value!r}")


def _numbers(value: Any, kind: type, name: str) -> list[Any]:
    items = _split(value) if isinstance(value, str) else list(value if isinstance(value, Iterable) else [value])
    try:
        out = [kind(v) if isinstance(v, str) else v for v in items]
    except ValueError as exc:
        raise ValueError(f"benchmark spec: {name} must be comma-separated numbers, got {value!r}") from exc
    if kind is int and not all(_is_int(v) for v in out):
        raise ValueError(f"benchmark spec: {name} must be integers, got {value!r}")
    return out


def _scene_list(value: Any) -> list[str]:
    names = _split(value)
    if names == ["all"]:
        from navzoo.world.library import list_scenes

        return list_scenes()
    return names


def _plain(obj: Any) -> Any:
    """Mappings/sequences as plain dicts/lists (tuples included), for JSON and cache keys."""
    if isinstance(obj, Mapping):
        return {str(k): _plain(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [_plain(v) for v in obj]
    return obj


# ---------------------------------------------------------------------------------------------------------
# Command line (``navzoo benchmark``)
# ---------------------------------------------------------------------------------------------------------


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """The ``navzoo benchmark`` options (None = not given, so a spec file or protocol fills it in)."""
    from navzoo.benchmark.protocols import protocol_names

    parser.add_argument("--spec", default=None, help="YAML spec with the same fields (command-line options win)")
    parser.add_argument("--protocol", default=None,
                        help=f"a named protocol that sets scenes, crowd, people, robot and limits: {', '.join(protocol_names())}")
    parser.add_argument("--scenes", default=None, help="comma-separated scene names, or 'all' (see `navzoo scenes`)")
    parser.add_argument("--methods", default=None, help="comma-separated robot policies (orca, dwa, sfm, pure-pursuit, ...)")
    parser.add_argument("--crowd", default=None, help="comma-separated crowd models: sfm, orca, orca_rvo2, diffusion, replay "
                        "(recorded people, in the replay_* scenes only), or rllib:PATH (pedestrians trained with "
                        "navzoo train joint) (default sfm)")
    level = parser.add_mutually_exclusive_group()
    level.add_argument("--density", default=None, help="people per m² of free space (of the circle/square for the CrowdNav protocols), e.g. 0.05,0.15,0.3")
    level.add_argument("--humans", default=None, help="people per scene (counts), e.g. 5,10")
    parser.add_argument("--episodes", type=int, default=None, help="episodes per cell (default 20)")
    parser.add_argument("--seed", type=int, default=None, help="base seed (default 0)")
    parser.add_argument("--time-limit", type=float, default=None, help="episode time limit in s (default: the scene's)")
    parser.add_argument("--max-steps", type=int, default=None, help="hard cap on steps per episode (quick looks)")
    parser.add_argument("--max-humans", type=int, default=None, help="cap on people per scene")
    parser.add_argument("--save-trajectories", type=int, default=None, metavar="K",
                        help="save the arrays of the first K episodes of each cell (npz)")
    parser.add_argument("--videos", type=int, default=None, metavar="K",
                        help="save a top-down video of the first K episodes of each cell (mp4)")
    parser.add_argument("--import", dest="imports", default=None, metavar="MODULES",
                        help="comma-separated modules each worker imports first (to register learned policies)")
    parser.add_argument("--episode-timeout", type=float, default=None,
                        help="kill an episode after this many wall seconds and record it as an error (default 600; 0 = never)")
    parser.add_argument("--workers", type=int, default=None, help="worker processes (default: all cores; 0 = in-process)")
    parser.add_argument("--out", default=None, help="run directory (default runs/benchmark); an existing one is resumed")
    parser.add_argument("--max-episodes", type=int, default=None, help="run at most this many episodes now (rerun to go on)")
    parser.add_argument("--no-progress", action="store_true", help="no progress bar")
    parser.add_argument("--json", action="store_true", help="print the run summary as one JSON object on stdout")


def spec_from_args(args: argparse.Namespace) -> tuple[BenchmarkSpec, dict[str, Any]]:
    """The spec and run options (``workers``, ``out``) of parsed ``navzoo benchmark`` arguments."""
    spec, run_opts = resolve_spec(
        protocol=args.protocol, spec_file=args.spec, scenes=args.scenes, methods=args.methods, crowd=args.crowd,
        density=args.density, humans=args.humans, episodes=args.episodes, seed=args.seed,
        time_limit=args.time_limit, max_steps=args.max_steps, max_humans=args.max_humans,
        save_trajectories=args.save_trajectories, videos=args.videos, imports=args.imports,
        episode_timeout=args.episode_timeout,
    )
    if args.workers is not None:
        run_opts["workers"] = args.workers
    if args.out is not None:
        run_opts["out"] = args.out
    run_opts.setdefault("out", "runs/benchmark")
    return spec, run_opts


def run_cli(args: argparse.Namespace) -> int:
    """``navzoo benchmark``: 0 when every episode ran, 1 when some failed (listed on stderr)."""
    spec, run_opts = spec_from_args(args)
    summary = run_benchmark(spec, run_opts["out"], workers=run_opts.get("workers"), progress=not args.no_progress,
                            max_episodes=args.max_episodes, command=["navzoo", *sys.argv[1:]])
    errors = summary["errors"]
    if args.json:
        print(json.dumps(_json_safe({**summary, "errors": [{k: v for k, v in e.items() if k != "traceback"}
                                                           for e in errors]})))
    else:
        rate = summary["episodes_per_hour"]
        print(f"{summary['status']}: {summary['episodes_done']}/{summary['episodes_total']} episodes in "
              f"{summary['out']} ({summary['episodes_run']} run now, {summary['skipped']} already done"
              + (f", {rate:.0f} episodes/h" if rate else "") + f"); `navzoo report {summary['out']}` for the tables")
    if errors:
        print(f"navzoo benchmark: {len(errors)} episode(s) failed (details in {Path(summary['out']) / ERRORS_FILE}):",
              file=sys.stderr)
        for e in errors[:20]:
            print(f"  {e['method']} on {e['scene']} ({e['crowd']}, {e['level']}) episode {e['episode']} seed {e['seed']}: "
                  f"{e['type']}: {e['message']}", file=sys.stderr)
        if len(errors) > 20:
            print(f"  ... and {len(errors) - 20} more", file=sys.stderr)
        return 1
    return 0
