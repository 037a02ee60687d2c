"""Scaling studies of the robot policy training (the NavIsaacLab paper's runtime and parallel-training studies).

Two studies of :mod:`navzoo.agents.robot_train` (transformer + SB3 PPO on navzoo scenes), run on this
machine's CPU (the simulator) and ``--device`` (the network):

**1. Runtime scaling** (:func:`runtime_scaling`, ``scaling_study runtime``). For each number N of
parallel env copies of one scene, the throughput of three workloads:

* ``peds``: the pedestrians alone. N copies of the scene built with ``n_robots=0`` (a pedestrian-only
  world, supported by :class:`~navzoo.envs.config.NavConfig`; its episodes end at the time limit), the
  pedestrians walking on the scene's crowd model. No policy, no robot; the copies are stepped in
  ``workers`` processes (``multiprocessing``, fork as SuperSuit; <= 1: in this process). Agents per env = the
  scene's pedestrians.
* ``infer``: robot + pedestrians with policy inference: ``make_mixed_vec_env((scene,), N,
  num_cpus=workers)`` (SuperSuit's vector env, the training one), the actions of every step sampled
  (``deterministic=False``) from a freshly initialised PPO transformer policy on ``device``. Agents
  per env = 1 robot + the pedestrians.
* ``train``: the whole PPO training (rollouts + ``n_epochs`` updates of every ``n_steps`` rollout),
  :func:`navzoo.agents.robot_train.train` for 4 whole rollouts (``TRAIN_ROLLOUTS``; ``seconds`` only
  caps a run that would take 10x longer); the rate is the steady state from the end of the first
  rollout to the end of the last one in its ``metrics.jsonl`` (rollouts and their updates, setup
  excluded); the rate with setup included is ``env_steps_per_s_incl_setup``.

One row per (mode, N): ``env_steps`` (summed over the N copies; one env step = one control step of one
copy), ``wall_s``, ``env_steps_per_s``, ``agents_per_env``, ``agent_steps_per_s`` (= env steps/s x
agents per env: how many robot and pedestrian states are advanced per second), ``n_envs``,
``workers``, ``device``, ``setup_s`` and ``machine`` (CPU count, platform, torch, CUDA device, load
average at the start: a loaded machine gives lower numbers). Reading it: perfect scaling doubles
env steps/s with N; on a machine with C free cores it flattens once N (or ``workers``) exceeds C; the
gap between ``peds`` and ``infer`` is the robot's physics and observation cost plus the network's
forward pass, the gap between ``infer`` and ``train`` is the PPO update.

**2. Parallel training** (:func:`parallel_training`, ``scaling_study parallel``). For R parallel robots
(R env copies, one robot each) and PPO minibatch size B (``min(B, n_steps x R)``, as a rollout holds
``n_steps x R`` samples), one training run of ``sim_steps`` simulator steps (the paper's budget: every
simulator step advances all R robots, so the run collects ``sim_steps x R`` robot steps). One PPO iteration =
one rollout of ``n_steps`` steps of every robot followed by one update of ``n_epochs`` epochs over
it. Per row: ``iterations``, the median wall seconds of one iteration (after the first one, which
holds no update; the elapsed time of each rollout line is ``timesteps / fps``), ``wall_s`` (whole
run, setup included), and ``time_to_target_updates_s_extrapolated`` = median iteration time x
``target_updates`` (default 5000, the paper's), an **extrapolation** from the measured iteration
time, not a measured time; and the final ``ep_rew_mean`` and ``success_rate`` (last rollout line with
a value: SB3's mean over the last 100 finished episodes and the goal rate over the same window;
``None`` when no episode finished within the budget). With a fixed simulator-step budget every R
gets the same number of iterations (``sim_steps / n_steps``), each on R times more samples: the
paper's question is whether the extra robots buy a better policy for the same simulated time.

Rows are appended to the ``--out`` JSONL file as soon as they are measured (a killed run keeps the
finished ones) and printed as one JSON line each on stdout; ``--resume`` skips configurations already
in the file. ``scaling_study plot`` draws both studies (:func:`plot_runtime`, :func:`plot_parallel`).

Usage::

    python -m navzoo.agents.scaling_study runtime --modes peds,infer,train --envs 1,2,4,8,16 --scene home \\
        --seconds 20 --device auto --out results.jsonl --plot runtime.png [--resume]
    python -m navzoo.agents.scaling_study parallel --robots 1,2,4,8,16 --batch-sizes 64,512 --sim-steps 16000 \\
        --scene home --device auto --out parallel.jsonl --plot parallel.png [--resume]
    python -m navzoo.agents.scaling_study plot --runtime results.jsonl --parallel parallel.jsonl --out-dir DIR
"""

from __future__ import annotations

import argparse
import contextlib
import json
import math
import multiprocessing as mp
import os
import platform
import sys
import tempfile
import threading
import time
import warnings
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

import numpy as np
import torch

__all__ = [
    "MODES",
    "ModelSize",
    "add_arguments",
    "agents_per_env",
    "machine_info",
    "main",
    "parallel_training",
    "plot_parallel",
    "plot_runtime",
    "read_jsonl",
    "resolve_device",
    "resolve_scene",
    "run_cli",
    "runtime_scaling",
    "write_jsonl",
]

MODES = ("peds", "infer", "train")
RUNTIME_KEY = ("mode", "n_envs", "scene", "device", "workers")
PARALLEL_KEY = ("robots", "batch_size_requested", "sim_steps", "n_steps", "n_epochs", "scene", "device", "workers",
                "seed")
#: Rows written before the parallel study recorded its seed were all trained with the default seed.
_PARALLEL_DEFAULT_SEED = 0
_BARRIER_TIMEOUT_S = 600.0


@dataclass(frozen=True)
class ModelSize:
    """Shape of the transformer PPO policy (default: the paper's / ``navzoo train robot``'s)."""

    features_dim: int = 128
    heads: int = 4
    blocks: int = 3
    net_arch: tuple[int, ...] = (128, 128)

    def policy_kwargs(self) -> dict[str, Any]:
        from navzoo.agents.transformer import transformer_policy_kwargs

        return transformer_policy_kwargs(features_dim=self.features_dim, n_heads=self.heads,
                                         n_blocks=self.blocks, net_arch=self.net_arch)

    def to_dict(self) -> dict[str, Any]:
        d = asdict(self)
        d["net_arch"] = list(self.net_arch)
        return d


# ---------------------------------------------------------------------------------------------
# Helpers: validation, machine, JSONL.


def resolve_scene(scene: str) -> str:
    """A scene name (``"home"``) or registered id (``"navzoo/Home-v0"``) → the registered id.

    Raises:
        ValueError: for anything else but exactly one known scene (the message names the value).
    """
    from navzoo.agents.robot_train import _scene_names, parse_scenes
    from navzoo.envs.registry import SCENARIOS

    ids = parse_scenes(scene) if isinstance(scene, str) else ()
    if len(ids) != 1 or ids[0] not in SCENARIOS:
        raise ValueError(f"unknown scene {scene!r}: give one scene name or id, such as "
                         f"{', '.join(_scene_names())} or {sorted(SCENARIOS)[0]}")
    return ids[0]


def resolve_device(device: str) -> str:
    """``"auto"`` → ``"cuda"`` if available else ``"cpu"``; ``"cuda"`` without CUDA is an error."""
    if device not in ("cpu", "cuda", "auto"):
        raise ValueError(f"device must be cpu, cuda or auto, got {device!r}")
    if device == "auto":
        return "cuda" if torch.cuda.is_available() else "cpu"
    if device == "cuda" and not torch.cuda.is_available():
        raise ValueError("device 'cuda': CUDA is not available on this machine (use cpu or auto)")
    return device


def _positive_ints(values: Iterable[Any], name: str, lo: int = 1) -> list[int]:
    vals = list(values) if values is not None else []
    if not vals:
        raise ValueError(f"{name} must list at least one integer >= {lo}, got {values!r}")
    for v in vals:
        if not isinstance(v, (int, np.integer)) or isinstance(v, bool) or v < lo:
            raise ValueError(f"{name}: every value must be an integer >= {lo}, got {v!r}")
    return [int(v) for v in vals]


def _check_seconds(seconds: float) -> float:
    if isinstance(seconds, bool) or not isinstance(seconds, (int, float)) or not math.isfinite(seconds) \
            or seconds <= 0:
        raise ValueError(f"seconds must be a finite number > 0, got {seconds!r}")
    return float(seconds)


def _check_workers(workers: int | None) -> None:
    if workers is not None and (not isinstance(workers, (int, np.integer)) or isinstance(workers, bool)
                                or workers < 0):
        raise ValueError(f"workers must be None (default: min(N, cpu count)) or an integer >= 0, got {workers!r}")


def _effective_workers(workers: int | None, n: int) -> int:
    """Worker processes for N copies: None → min(N, cpu count); never more than N; 0 and 1 mean in-process."""
    return min(n, os.cpu_count() or 1) if workers is None else min(int(workers), n)


def machine_info() -> dict[str, Any]:
    """What the numbers depend on: cores, platform, torch, CUDA device, load average now."""
    from navzoo.machine import cpu_model

    info: dict[str, Any] = {
        "cpu": cpu_model(), "cpu_count": os.cpu_count(), "platform": platform.platform(),
        "processor": platform.processor() or None,
        "python": platform.python_version(), "torch": torch.__version__, "torch_threads": torch.get_num_threads(),
        "cuda_device": torch.cuda.get_device_name(0) if torch.cuda.is_available() else None,
    }
    with contextlib.suppress(AttributeError, OSError):
        info["cpu_affinity"] = len(os.sched_getaffinity(0))
    with contextlib.suppress(AttributeError, OSError):
        info["loadavg_1m"] = round(os.getloadavg()[0], 2)
    return info


def agents_per_env(scene: str, n_robots: int = 1) -> tuple[int, int]:
    """(robots, pedestrians) simulated in one copy of ``scene`` (its default pedestrian count)."""
    from navzoo.envs.registry import make_raw

    env = make_raw(resolve_scene(scene), n_robots=n_robots)
    try:
        names = list(env.possible_agents)
    finally:
        env.close()
    return sum(a.startswith("robot_") for a in names), sum(a.startswith("human_") for a in names)


def write_jsonl(rows: Iterable[Mapping[str, Any]], path: str | Path) -> None:
    """Append each row as one JSON line to ``path`` (flushed at once; parent folders created)."""
    p = Path(path)
    p.parent.mkdir(parents=True, exist_ok=True)
    with open(p, "a") as f:
        for row in rows:
            f.write(json.dumps(dict(row)) + "\n")
            f.flush()


def read_jsonl(path: str | Path) -> list[dict[str, Any]]:
    """The rows of a JSONL file (missing file: none; a truncated last line, from a killed run, is skipped)."""
    p = Path(path)
    if not p.is_file():
        return []
    rows = []
    for line in p.read_text().splitlines():
        line = line.strip()
        if not line:
            continue
        try:
            row = json.loads(line)
        except json.JSONDecodeError:
            print(f"scaling_study: skipping unreadable line in {p}: {line[:80]!r}", file=sys.stderr)
            continue
        if isinstance(row, dict):
            rows.append(row)
    return rows


def _key(row: Mapping[str, Any], fields: Sequence[str]) -> tuple:
    return tuple(row.get(f) for f in fields)


def _emit(row: dict[str, Any], out: str | Path | None, echo: bool) -> None:
    if out is not None:
        write_jsonl([row], out)
    if echo:
        print(json.dumps(row), flush=True)


@contextlib.contextmanager
def _torch_threads(threads: int | None):
    before = torch.get_num_threads()
    if threads:
        torch.set_num_threads(int(threads))
    try:
        yield
    finally:
        torch.set_num_threads(before)


# ---------------------------------------------------------------------------------------------
# Study 1: runtime scaling.


def _peds_worker(scene_id: str, seeds: Sequence[int], seconds: float, steps: int | None, warmup_steps: int,
                 barrier: Any | None, queue: Any | None) -> dict[str, Any]:
    """Step ``len(seeds)`` pedestrian-only copies round-robin; returns counts (or puts them on ``queue``)."""
    result: dict[str, Any]
    envs: list[Any] = []
    try:
        torch.set_num_threads(1)
        from navzoo.envs.registry import make

        t0 = time.perf_counter()
        envs = [make(scene_id, n_robots=0) for _ in seeds]
        for env, s in zip(envs, seeds, strict=True):
            env.reset(seed=int(s))

        def one_round() -> int:
            resets = 0
            for env in envs:
                env.step({})
                if not env.unwrapped.agents:  # n_robots=0: the episode ends at the time limit
                    env.reset()
                    resets += 1
            return resets

        for _ in range(warmup_steps):
            one_round()
        setup_s = time.perf_counter() - t0
    except BaseException as exc:
        if barrier is not None:
            barrier.abort()
        for env in envs:
            env.close()
        if queue is None:
            raise
        queue.put({"error": f"{type(exc).__name__}: {exc}"})
        return {}
    try:
        if barrier is not None:
            barrier.wait(_BARRIER_TIMEOUT_S)
        rounds = resets = 0
        start = time.perf_counter()
        while (rounds < steps) if steps is not None else (time.perf_counter() - start < seconds):
            resets += one_round()
            rounds += 1
        wall = time.perf_counter() - start
        result = {"env_steps": rounds * len(envs), "wall_s": wall, "episodes_reset": resets, "setup_s": setup_s}
    except BaseException as exc:
        if queue is None:
            raise
        result = {"error": f"{type(exc).__name__}: {exc}"}
    finally:
        for env in envs:
            env.close()
    if queue is not None:
        queue.put(result)
    return result


def _collect(queue: Any, procs: Sequence[Any], timeout_s: float) -> list[dict[str, Any]]:
    """One result per worker; a worker that died without one (e.g. a crash in PyBullet) is an error."""
    import queue as queue_mod

    results: list[dict[str, Any]] = []
    deadline = time.perf_counter() + timeout_s
    while len(results) < len(procs):
        try:
            results.append(queue.get(timeout=1.0))
        except queue_mod.Empty:
            dead = [p.exitcode for p in procs if p.exitcode not in (None, 0)]
            if dead:
                results.append({"error": f"a worker process exited with status {dead[0]} without a result"})
                break
            if time.perf_counter() > deadline:
                results.append({"error": f"no result from the workers within {timeout_s:.0f} s"})
                break
    return results


def _measure_peds(scene_id: str, n: int, workers: int, seconds: float, steps: int | None, warmup_steps: int,
                  seed: int) -> dict[str, Any]:
    seeds = [seed + i for i in range(n)]
    if workers <= 1:
        res = _peds_worker(scene_id, seeds, seconds, steps, warmup_steps, None, None)
        return {**res, "env_steps_per_s": res["env_steps"] / res["wall_s"]}
    chunks = [list(c) for c in np.array_split(np.array(seeds), workers) if len(c)]
    # fork, as SuperSuit's worker processes (spawn would re-run an unguarded calling script); spawn where
    # the platform has no fork. The workers build their own PyBullet worlds after the fork.
    ctx = mp.get_context("fork" if "fork" in mp.get_all_start_methods() else "spawn")
    barrier = ctx.Barrier(len(chunks) + 1)
    queue = ctx.Queue()
    t0 = time.perf_counter()
    procs = [ctx.Process(target=_peds_worker, args=(scene_id, c, seconds, steps, warmup_steps, barrier, queue),
                         daemon=True) for c in chunks]
    for p in procs:
        p.start()
    try:
        try:
            barrier.wait(_BARRIER_TIMEOUT_S)
        except threading.BrokenBarrierError:
            pass  # a worker failed during setup: its error is on the queue
        setup_s = time.perf_counter() - t0
        results = _collect(queue, procs, _BARRIER_TIMEOUT_S + (steps or 0) + 10 * seconds)
    finally:
        for p in procs:
            p.join(timeout=30)
            if p.is_alive():
                p.terminate()
    errors = [r["error"] for r in results if "error" in r]
    if errors:
        raise RuntimeError(f"peds worker failed ({scene_id}, {n} copies, {workers} workers): {errors[0]}")
    env_steps = sum(r["env_steps"] for r in results)
    wall = max(r["wall_s"] for r in results)
    return {"env_steps": env_steps, "wall_s": wall, "env_steps_per_s": env_steps / wall,
            "episodes_reset": sum(r["episodes_reset"] for r in results), "setup_s": setup_s,
            "worker_env_steps_per_s": [round(r["env_steps"] / r["wall_s"], 2) for r in results]}


def _measure_infer(scene_id: str, n: int, workers: int, seconds: float, steps: int | None, warmup_steps: int,
                   seed: int, device: str, model: ModelSize) -> dict[str, Any]:
    from stable_baselines3 import PPO

    from navzoo.agents.robot_train import make_mixed_vec_env

    t0 = time.perf_counter()
    vec = make_mixed_vec_env((scene_id,), n_envs=n, seed=seed, num_cpus=workers)
    try:
        with warnings.catch_warnings():
            warnings.filterwarnings("ignore", message="The `render_mode` attribute is not defined")
            ppo = PPO("MlpPolicy", vec, n_steps=32, batch_size=32, policy_kwargs=model.policy_kwargs(),
                      device=device, seed=seed, verbose=0)
        obs = vec.reset()
        for _ in range(warmup_steps):
            actions, _ = ppo.predict(obs, deterministic=False)
            obs, _, _, _ = vec.step(actions)
        setup_s = time.perf_counter() - t0
        vsteps = episodes = 0
        policy_s = 0.0
        start = time.perf_counter()
        while (vsteps < steps) if steps is not None else (time.perf_counter() - start < seconds):
            tp = time.perf_counter()
            actions, _ = ppo.predict(obs, deterministic=False)
            policy_s += time.perf_counter() - tp
            obs, _, dones, _ = vec.step(actions)
            episodes += int(np.sum(dones))
            vsteps += 1
        wall = time.perf_counter() - start
    finally:
        vec.close()
    env_steps = vsteps * n  # one robot per copy: each vector step steps every copy once
    return {"env_steps": env_steps, "wall_s": wall, "env_steps_per_s": env_steps / wall, "setup_s": setup_s,
            "policy_s": round(policy_s, 3), "policy_fraction": round(policy_s / wall, 3), "episodes_done": episodes,
            "params": sum(p.numel() for p in ppo.policy.parameters())}


def _metrics(out: Path) -> list[dict[str, Any]]:
    """The rollout lines of a run's ``metrics.jsonl``. A resumed run redoes the rollouts after its last
    checkpoint and appends them again: the rollouts cut off with the earlier session are dropped."""
    lines = [r for r in read_jsonl(out / "metrics.jsonl") if "timesteps" in r and "fps" in r]
    kept: list[dict[str, Any]] = []
    for ln in lines:
        while kept and kept[-1]["timesteps"] >= ln["timesteps"]:
            kept.pop()
        kept.append(ln)
    return kept


def _train_quiet(targs: Any) -> dict[str, Any]:
    """``robot_train.train`` with its JSON lines sent to stderr (stdout carries this study's rows)."""
    from navzoo.agents.robot_train import train

    with contextlib.redirect_stdout(sys.stderr):
        return train(targs)


TRAIN_ROLLOUTS = 4  # rollouts (each with its PPO update) timed per train-mode measurement


def _measure_train(scene_id: str, n: int, workers: int, seconds: float, seed: int, device: str, threads: int | None,
                   model: ModelSize, n_steps: int, n_epochs: int) -> dict[str, Any]:
    from navzoo.agents.robot_train import TrainArgs

    with tempfile.TemporaryDirectory(prefix="navzoo_scaling_train_") as tmp:
        # TRAIN_ROLLOUTS whole rollouts (so every rate below spans rollouts *and* updates); ``seconds``
        # only caps a run that would take far longer.
        targs = TrainArgs(out=tmp, scenes=(scene_id,), n_envs=n, num_cpus=workers,
                          total_steps=n_steps * n * TRAIN_ROLLOUTS, n_steps=n_steps, n_epochs=n_epochs,
                          time_limit_s=max(10.0 * seconds, 60.0), device=device, threads=threads,
                          seed=seed, save_every=10**12, keep=1, features_dim=model.features_dim, heads=model.heads,
                          blocks=model.blocks, net_arch=tuple(model.net_arch))
        t0 = time.perf_counter()
        summary = _train_quiet(targs)
        wall = time.perf_counter() - t0
        lines = _metrics(Path(tmp))
    row: dict[str, Any] = {"batch_size": targs.batch_size, "n_steps": n_steps, "n_epochs": n_epochs,
                           "rollouts": len(lines), "timesteps_total": summary.get("timesteps"),
                           "train_elapsed_s": summary.get("elapsed_s"), "wall_s_incl_setup": round(wall, 3)}
    if len(lines) >= 2 and lines[-1]["elapsed_s"] > lines[0]["elapsed_s"]:
        # steady state: from the end of the first rollout to the end of the last one (rollouts + updates)
        span = lines[-1]["elapsed_s"] - lines[0]["elapsed_s"]
        steps = lines[-1]["timesteps"] - lines[0]["timesteps"]
        row.update(env_steps=int(steps), wall_s=round(span, 3), env_steps_per_s=steps / span,
                   env_steps_per_s_incl_setup=lines[-1]["timesteps"] / max(lines[-1]["elapsed_s"], 1e-9),
                   first_rollout_steps_per_s=float(lines[0]["fps"]),
                   rate_source=f"steady state over rollouts 2..{len(lines)} of metrics.jsonl (each followed by its "
                               "update): (timesteps_last - timesteps_first) / (elapsed_last - elapsed_first)")
    elif lines and lines[-1]["fps"] > 0:
        last = lines[-1]
        learn_s = last["timesteps"] / last["fps"]  # fresh run: fps = timesteps / seconds since learning started
        row.update(env_steps=int(last["timesteps"]), wall_s=learn_s, env_steps_per_s=float(last["fps"]),
                   env_steps_per_s_incl_setup=last["timesteps"] / max(last["elapsed_s"], 1e-9),
                   setup_s=round(max(last["elapsed_s"] - learn_s, 0.0), 3),
                   first_rollout_steps_per_s=float(lines[0]["fps"]),
                   rate_source="fps of the last metrics.jsonl line (learning only, updates included)")
    else:
        steps_done = int(summary.get("timesteps") or 0)
        if steps_done <= 0:
            raise RuntimeError(f"train mode ({scene_id}, {n} copies): no step done in {seconds} s; increase seconds")
        row.update(env_steps=steps_done, wall_s=wall, env_steps_per_s=steps_done / wall,
                   env_steps_per_s_incl_setup=steps_done / wall, setup_s=None,
                   rate_source="no rollout finished within the time limit: timesteps / wall time of the whole "
                               "train() call (setup, partial rollout, no update); increase seconds")
    return row


def runtime_scaling(mode: str, n_envs_list: Sequence[int], scene: str = "home", seconds: float = 20.0,
                    device: str = "auto", workers: int | None = None, *, steps: int | None = None,
                    warmup_steps: int = 3, seed: int = 0, threads: int | None = 1, n_steps: int = 32,
                    n_epochs: int = 6, model: ModelSize | None = None, out: str | Path | None = None,
                    resume: bool = False, echo: bool = False) -> list[dict[str, Any]]:
    """Environment and agent steps per second of ``mode`` for each number of parallel env copies.

    Args:
        mode: ``"peds"`` (pedestrians only, ``n_robots=0``), ``"infer"`` (robot + pedestrians, actions
            from a fresh transformer PPO policy) or ``"train"`` (PPO training, updates included).
        n_envs_list: numbers N of parallel env copies of ``scene``.
        scene: scene name (``"home"``) or id (``"navzoo/Home-v0"``).
        seconds: timed wall seconds per measurement (``train``: 4 whole rollouts are timed instead; this only caps a run at 10x it).
        device: torch device of the policy (``cpu``, ``cuda``, ``auto``); ``peds`` runs no network and
            is recorded as ``cpu``.
        workers: worker processes (None: ``min(N, os.cpu_count())``; 0 or 1: in this process; capped at N).
        steps: ``peds``/``infer``: step exactly this many rounds of every copy instead of ``seconds``.
        warmup_steps: untimed steps after the reset (``peds``/``infer``).
        seed: copy i is seeded ``seed + i``.
        threads: torch intra-op threads during the measurement (1 on a small shared CPU).
        n_steps, n_epochs: PPO rollout length and epochs (``train``; the paper's 32 and 6).
        model: policy shape (default :class:`ModelSize`, the paper's).
        out: JSONL file each row is appended to as soon as it is measured.
        resume: skip the configurations already in ``out`` (same mode, n_envs, scene, device, workers).
        echo: print each row as one JSON line on stdout.

    Returns:
        The rows measured by this call (skipped ones are not repeated).

    Raises:
        ValueError: for an unknown mode, scene or device, or non-positive counts (named in the message).
    """
    if mode not in MODES:
        raise ValueError(f"unknown mode {mode!r}; modes: {', '.join(MODES)}")
    ns = _positive_ints(n_envs_list, "n_envs_list")
    scene_id = resolve_scene(scene)
    seconds = _check_seconds(seconds)
    _check_workers(workers)
    if steps is not None:
        _positive_ints([steps], "steps")
    _positive_ints([warmup_steps], "warmup_steps", lo=0)
    _positive_ints([n_steps], "n_steps", lo=2)
    _positive_ints([n_epochs], "n_epochs")
    if resume and out is None:
        raise ValueError("resume needs an out file")
    dev = "cpu" if mode == "peds" else resolve_device(device)
    model = model or ModelSize()
    robots, peds = agents_per_env(scene_id, n_robots=0 if mode == "peds" else 1)
    done = {_key(r, RUNTIME_KEY) for r in read_jsonl(out)} if resume and out is not None else set()
    rows: list[dict[str, Any]] = []
    for n in ns:
        w = _effective_workers(workers, n)
        if (mode, n, scene_id, dev, w) in done:
            print(f"scaling_study: resume: skipping {mode} n_envs={n} workers={w} {scene_id} {dev} "
                  f"(already in {out})", file=sys.stderr)
            continue
        info = machine_info()
        with _torch_threads(threads):
            info["torch_threads"] = torch.get_num_threads()
            if mode == "peds":
                res = _measure_peds(scene_id, n, w, seconds, steps, warmup_steps, seed)
                note = ("pedestrian-only world (n_robots=0, supported by NavConfig): no robot, no policy; "
                        "copies stepped in worker processes (multiprocessing)" if w > 1 else
                        "pedestrian-only world (n_robots=0, supported by NavConfig): no robot, no policy; "
                        "copies stepped in this process")
            elif mode == "infer":
                res = _measure_infer(scene_id, n, w, seconds, steps, warmup_steps, seed, dev, model)
                note = ("make_mixed_vec_env + fresh PPO transformer policy, model.predict(deterministic=False) "
                        "every step; policy_fraction = share of the wall time in predict")
            else:
                res = _measure_train(scene_id, n, w, seconds, seed, dev, threads, model, n_steps, n_epochs)
                note = ("robot_train.train with time_limit_s=seconds (setup included in the limit); "
                        "env_steps_per_s = last metrics fps (learning incl. updates, setup excluded)")
        apn = robots + peds
        row: dict[str, Any] = {
            "study": "runtime", "mode": mode, "scene": scene_id, "n_envs": n, "workers": w, "device": dev,
            "seconds_requested": seconds, "env_steps": int(res["env_steps"]), "wall_s": round(res["wall_s"], 4),
            "env_steps_per_s": round(res["env_steps_per_s"], 3),
            "agent_steps_per_s": round(res["env_steps_per_s"] * apn, 3),
            "agents_per_env": apn, "robots_per_env": robots, "peds_per_env": peds,
            "setup_s": None if res.get("setup_s") is None else round(res["setup_s"], 3),
            **{k: v for k, v in res.items() if k not in ("env_steps", "wall_s", "env_steps_per_s", "setup_s")},
            "model": model.to_dict() if mode != "peds" else None, "note": note, "machine": info,
            "time": time.strftime("%Y-%m-%dT%H:%M:%S"),
        }
        if "env_steps_per_s_incl_setup" in row:
            row["env_steps_per_s_incl_setup"] = round(row["env_steps_per_s_incl_setup"], 3)
        _emit(row, out, echo)
        rows.append(row)
    return rows


# ---------------------------------------------------------------------------------------------
# Study 2: parallel training.


def _iteration_times(lines: Sequence[Mapping[str, Any]], train_elapsed_s: float | None) -> tuple[list[float], str]:
    """Wall seconds of the PPO iterations from the rollout lines of a fresh run.

    Line k is written at the end of rollout k (before update k); its time since learning started is
    ``timesteps / fps`` (more precise than ``elapsed_s``, rounded to 0.1 s). The difference between
    lines k and k+1 is update k + rollout k+1: one whole iteration. With a single line the one
    iteration is estimated as its rollout time plus the rest of the run (the final update,
    checkpoint and export).
    """
    if len(lines) >= 2 and all(ln.get("learn_s") is not None for ln in lines):
        # learn_s: seconds since this session's learning started; it falls back at a resume, and the
        # interval across a resume (restart, reload) is no iteration
        t = [float(ln["learn_s"]) for ln in lines]
        diffs = [b - a for a, b in zip(t, t[1:], strict=False) if b > a]
        return diffs, ("median of differences between rollout lines (learn_s, within each session)"
                       + ("; resumed" if len(diffs) < len(t) - 1 else ""))
    t = [ln["timesteps"] / ln["fps"] for ln in lines if ln.get("fps")]
    if len(t) >= 2:
        return [b - a for a, b in zip(t, t[1:], strict=False)], "median of differences between rollout lines"
    if len(t) == 1 and train_elapsed_s is not None:
        rest = max(float(train_elapsed_s) - float(lines[0]["elapsed_s"]), 0.0)
        return [t[0] + rest], ("one iteration only: its rollout (timesteps/fps) + the rest of the run after the "
                               "rollout line (update, checkpoint, export; elapsed_s has 0.1 s resolution)")
    return [], "no rollout line"


def _last_value(lines: Sequence[Mapping[str, Any]], key: str) -> Any:
    for ln in reversed(lines):
        if ln.get(key) is not None:
            return ln[key]
    return None


def parallel_training(robots_list: Sequence[int], batch_sizes: Sequence[int], sim_steps: int, scene: str = "home",
                      device: str = "auto", *, target_updates: int = 5000, workers: int | None = None,
                      n_steps: int = 32, n_epochs: int = 6, seed: int = 0, threads: int | None = 1,
                      model: ModelSize | None = None, time_limit_s: float | None = None,
                      out: str | Path | None = None, resume: bool = False, runs_dir: str | Path | None = None,
                      echo: bool = False) -> list[dict[str, Any]]:
    """Training time per PPO iteration and final reward for R parallel robots and minibatch size B.

    For each (R in ``robots_list``, B in ``batch_sizes``) one fresh training run of ``sim_steps`` simulator
    steps (``sim_steps x R`` robot steps) on R copies of ``scene`` (one robot each), minibatch
    ``min(B, n_steps x R)``.

    Args:
        robots_list: numbers R of parallel robots (env copies).
        batch_sizes: PPO minibatch sizes B (>= 2; capped at the rollout size n_steps x R).
        sim_steps: simulator steps of every run (each advances all R robots; rounded up to whole rollouts).
        scene: scene name or id.
        device: torch device for PPO (``cpu``, ``cuda``, ``auto``).
        target_updates: policy updates (iterations) the time is extrapolated to (the paper: 5000).
        workers: worker processes for the copies (None: ``min(R, os.cpu_count())``; 0/1: in this process).
        n_steps, n_epochs: PPO rollout length per robot and epochs per update (paper: 32, 6).
        seed: training seed.
        threads: torch intra-op threads.
        model: policy shape (default :class:`ModelSize`).
        time_limit_s: optional wall limit of each run (a run stopped early has fewer iterations; with
            ``runs_dir`` it is continued by the next call instead, and gives no row until it is complete).
        out: JSONL file each row is appended to when its run finishes.
        resume: skip the configurations already in ``out``.
        runs_dir: keep each run's training folder here (checkpoints every 25 iterations) instead of a
            temporary one, so that a run cut off by ``time_limit_s``, a crash or Ctrl-C continues from its
            last checkpoint when the same configuration is run again (runs longer than one session).
        echo: print each row as one JSON line on stdout.

    Returns:
        The rows of the runs finished by this call.

    Raises:
        ValueError: for empty lists, non-positive counts, batch sizes < 2, unknown scene or device.
    """
    from navzoo.agents.robot_train import TrainArgs

    rs = _positive_ints(robots_list, "robots_list")
    bs = _positive_ints(batch_sizes, "batch_sizes", lo=2)
    _positive_ints([sim_steps], "sim_steps")
    _positive_ints([target_updates], "target_updates")
    _positive_ints([n_steps], "n_steps", lo=2)
    _positive_ints([n_epochs], "n_epochs")
    _check_workers(workers)
    if time_limit_s is not None:
        _check_seconds(time_limit_s)
    if resume and out is None:
        raise ValueError("resume needs an out file")
    scene_id = resolve_scene(scene)
    dev = resolve_device(device)
    model = model or ModelSize()
    _, peds = agents_per_env(scene_id, n_robots=1)
    earlier = read_jsonl(out) if resume and out is not None else []
    earlier = [r for r in earlier if r.get("study") == "parallel"]
    done = {_parallel_key(r) for r in earlier}
    # A requested batch that the rollout cap turns into the batch of another requested size is the same
    # training run (same seed, same settings): it is measured once, and its row is written again for the
    # other size, marked with ``same_run_as_batch_size_requested``.
    measured: dict[tuple, dict[str, Any]] = {}
    for row in earlier:
        if "batch_size" in row and "same_run_as_batch_size_requested" not in row:
            measured.setdefault(_run_key(row), row)
    rows: list[dict[str, Any]] = []
    for r in rs:
        w = _effective_workers(workers, r)
        for b in bs:
            rollout = n_steps * r
            batch = min(b, rollout)
            config = {"robots": r, "batch_size_requested": b, "batch_size": batch, "sim_steps": int(sim_steps),
                      "n_steps": n_steps, "n_epochs": n_epochs, "scene": scene_id, "device": dev, "workers": w,
                      "seed": seed}
            if _parallel_key(config) in done:
                print(f"scaling_study: resume: skipping robots={r} batch={b} sim_steps={sim_steps} {scene_id} {dev} "
                      f"seed={seed} (already in {out})", file=sys.stderr)
                continue
            same = measured.get(_run_key(config))
            if same is not None:
                row = {**same, "batch_size_requested": b,
                       "same_run_as_batch_size_requested": same["batch_size_requested"],
                       "note": same["note"] + f"; the same run as batch {same['batch_size_requested']} (both capped "
                                              f"at {batch}), measured once"}
                print(f"scaling_study: robots={r} batch={b} is capped at {batch}, the same run as batch "
                      f"{same['batch_size_requested']}: row copied, not trained again", file=sys.stderr)
                _emit(row, out, echo)
                rows.append(row)
                continue
            info = machine_info()
            with contextlib.ExitStack() as stack:
                if runs_dir is None:
                    run_dir = stack.enter_context(tempfile.TemporaryDirectory(prefix="navzoo_scaling_parallel_"))
                    save_every = 10**12
                else:
                    name = (f"{scene_id.replace('/', '_')}_r{r}_b{b}_sim{int(sim_steps)}_n{n_steps}_e{n_epochs}_{dev}"
                            f"_w{w}_seed{seed}")
                    run_dir = str(Path(runs_dir) / name)
                    save_every = 25 * rollout
                targs = TrainArgs(out=run_dir, scenes=(scene_id,), n_envs=r, num_cpus=w,
                                  total_steps=int(sim_steps) * r, n_steps=n_steps, n_epochs=n_epochs,
                                  batch_size=batch, device=dev, threads=threads, seed=seed, save_every=save_every,
                                  keep=1, time_limit_s=time_limit_s, features_dim=model.features_dim,
                                  heads=model.heads, blocks=model.blocks, net_arch=tuple(model.net_arch))
                with _torch_threads(threads):
                    info["torch_threads"] = threads or torch.get_num_threads()
                    t0 = time.perf_counter()
                    summary = _train_quiet(targs)
                    wall = time.perf_counter() - t0
                lines = _metrics(Path(run_dir))
            unfinished = runs_dir is not None and summary.get("reason") != "total_steps"
            if unfinished:
                print(f"scaling_study: robots={r} batch={b}: stopped ({summary.get('reason')}) at "
                      f"{summary.get('timesteps')} of {int(sim_steps) * r} robot steps; run the same command again "
                      f"to continue it from {run_dir}", file=sys.stderr)
            if summary.get("reason") == "interrupted":
                raise KeyboardInterrupt  # Ctrl-C (or SIGINT from a time limit) stops the study, not one run
            if unfinished:
                continue
            iters, source = _iteration_times(lines, summary.get("elapsed_s"))
            med = float(np.median(iters)) if iters else None
            first_rollout_s = lines[0]["timesteps"] / lines[0]["fps"] if lines and lines[0].get("fps") else None
            row: dict[str, Any] = {
                "study": "parallel", "robots": r, "batch_size_requested": b, "batch_size": batch, "seed": seed,
                "scene": scene_id, "device": dev, "workers": w, "sim_steps": int(sim_steps),
                "n_steps": n_steps, "n_epochs": n_epochs, "rollout_size": rollout,
                "gradient_steps_per_iteration": n_epochs * math.ceil(rollout / batch),
                "iterations": len(lines), "iterations_expected": math.ceil(sim_steps / n_steps),
                "timesteps": summary.get("timesteps"), "stop_reason": summary.get("reason"),
                "wall_s": round(wall, 3), "train_elapsed_s": summary.get("elapsed_s"),
                "iteration_s_median": None if med is None else round(med, 4),
                "iteration_s_all": [round(x, 4) for x in iters], "iteration_s_source": source,
                "first_rollout_s": None if first_rollout_s is None else round(first_rollout_s, 4),
                "target_updates": target_updates,
                "time_to_target_updates_s_extrapolated": None if med is None else round(med * target_updates, 1),
                "final_fps": lines[-1]["fps"] if lines else None,
                "agent_steps_per_s": round(lines[-1]["fps"] * (1 + peds), 3) if lines else None,
                "agents_per_env": 1 + peds,
                "ep_rew_mean": _last_value(lines, "ep_rew_mean"), "success_rate": _last_value(lines, "success_rate"),
                "collision_rate": _last_value(lines, "collision_rate"), "episodes": _last_value(lines, "episodes"),
                "model": model.to_dict(), "machine": info, "time": time.strftime("%Y-%m-%dT%H:%M:%S"),
                "note": (f"time_to_target_updates_s_extrapolated = median iteration time x {target_updates}, "
                         "extrapolated, not measured; one iteration = one rollout of n_steps x robots steps + one "
                         f"{n_epochs}-epoch update; with a fixed sim-step budget more robots give fewer iterations; "
                         "ep_rew_mean/success_rate are None when no episode finished"
                         + ("; batch size capped at the rollout size" if batch < b else "")),
            }
            _emit(row, out, echo)
            rows.append(row)
            measured.setdefault(_run_key(row), row)
    return rows


def _parallel_key(row: Mapping[str, Any]) -> tuple:
    """A parallel-study row's configuration (:data:`PARALLEL_KEY`; rows without a seed have the default)."""
    return _key({"seed": _PARALLEL_DEFAULT_SEED, **row}, PARALLEL_KEY)


def _run_key(row: Mapping[str, Any]) -> tuple:
    """What makes two parallel-study rows the same training run: the key with the effective batch size."""
    return (row["robots"], row["batch_size"], row["sim_steps"], row["n_steps"], row["n_epochs"], row["scene"],
            row["device"], row["workers"], row.get("seed", _PARALLEL_DEFAULT_SEED))


# ---------------------------------------------------------------------------------------------
# Plots.


def _pyplot() -> Any:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def _save_figure(fig: Any, path: str | Path, dpi: int) -> Path:
    from navzoo.world.plot import save_figure as save  # imports pyplot: only after _pyplot() chose Agg

    return save(fig, path, dpi=dpi)


def plot_runtime(rows: Sequence[Mapping[str, Any]], path_png: str | Path) -> Path:
    """Env steps/s and agent steps/s vs parallel envs (log2 x axis), one line per mode (and device, scene).

    Raises:
        ValueError: when ``rows`` holds no runtime row.
    """
    rows = [r for r in rows if r.get("study", "runtime") == "runtime" and "mode" in r and "n_envs" in r]
    if not rows:
        raise ValueError("plot_runtime: no runtime rows to plot")
    plt = _pyplot()
    scenes = {r["scene"] for r in rows}
    devices = {r["device"] for r in rows if r["mode"] != "peds"}
    workers_differ = len({(r["mode"], r["n_envs"], r["scene"], r["device"]) for r in rows}) < len(rows)
    groups: dict[tuple, list[Mapping[str, Any]]] = {}
    for r in rows:
        label = [r["mode"]]
        if len(devices) > 1 and r["mode"] != "peds":
            label.append(r["device"])
        if len(scenes) > 1:
            label.append(r["scene"].split("/")[-1])
        if workers_differ:
            label.append("in-process" if r["workers"] <= 1 else "workers")
        groups.setdefault(tuple(label), []).append(r)
    fig, axes = plt.subplots(1, 2, figsize=(11, 4.2))
    for label, grp in sorted(groups.items()):
        grp = sorted(grp, key=lambda r: r["n_envs"])
        xs = [r["n_envs"] for r in grp]
        for ax, key in zip(axes, ("env_steps_per_s", "agent_steps_per_s"), strict=True):
            ax.plot(xs, [r[key] for r in grp], marker="o", label=" ".join(label))
    ns = sorted({r["n_envs"] for r in rows})
    for ax, title in zip(axes, ("environment steps / s (sum over copies)", "agent steps / s (robots + pedestrians)"),
                         strict=True):
        ax.set_xscale("log", base=2)
        ax.set_xticks(ns, [str(n) for n in ns])
        ax.set_yscale("log")
        ax.set_xlabel("parallel environments")
        ax.set_title(title)
        ax.grid(True, which="both", alpha=0.3)
        ax.legend()
    m = rows[0].get("machine", {})
    fig.suptitle(f"runtime scaling, {', '.join(sorted(s.split('/')[-1] for s in scenes))} — {m.get('cpu_count')} CPUs"
                 + (f", {m['cuda_device']}" if m.get("cuda_device") else ""), fontsize=10)
    fig.tight_layout()
    return _save_figure(fig, path_png, dpi=120)


def plot_parallel(rows: Sequence[Mapping[str, Any]], path_png: str | Path) -> Path:
    """Two panels vs robots, one line per batch size: median iteration time (right axis: the extrapolated
    hours to the target updates) and final mean episode reward.

    Raises:
        ValueError: when ``rows`` holds no parallel-training row.
    """
    rows = [r for r in rows if r.get("study") == "parallel" and "robots" in r]
    if not rows:
        raise ValueError("plot_parallel: no parallel-training rows to plot")
    plt = _pyplot()
    fig, (ax_t, ax_r) = plt.subplots(1, 2, figsize=(11, 4.2))
    by_batch: dict[int, list[Mapping[str, Any]]] = {}
    for r in rows:
        by_batch.setdefault(int(r["batch_size_requested"]), []).append(r)
    any_reward = False
    for b, grp in sorted(by_batch.items()):
        grp = sorted(grp, key=lambda r: r["robots"])
        pts = [(r["robots"], r["iteration_s_median"]) for r in grp if r.get("iteration_s_median") is not None]
        if pts:
            ax_t.plot(*zip(*pts, strict=True), marker="o", label=f"batch {b}")
        pts = [(r["robots"], r["ep_rew_mean"]) for r in grp if r.get("ep_rew_mean") is not None]
        if pts:
            any_reward = True
            ax_r.plot(*zip(*pts, strict=True), marker="o", label=f"batch {b}")
    robots = sorted({r["robots"] for r in rows})
    target = int(rows[0].get("target_updates", 5000))
    for ax in (ax_t, ax_r):
        ax.set_xscale("log", base=2)
        ax.set_xticks(robots, [str(n) for n in robots])
        ax.set_xlabel("parallel robots")
        ax.grid(True, alpha=0.3)
    ax_t.set_ylabel("wall s per PPO iteration (median)")
    ax_t.set_title("time per iteration (rollout + update)")
    sec = ax_t.secondary_yaxis("right", functions=(lambda s: s * target / 3600.0, lambda h: h * 3600.0 / target))
    sec.set_ylabel(f"h to {target} updates (extrapolated)")
    sims = sorted({r["sim_steps"] for r in rows})
    ax_r.set_ylabel("final mean episode reward")
    ax_r.set_title(f"reward after {', '.join(str(s) for s in sims)} simulator steps")
    if not any_reward:
        ax_r.text(0.5, 0.5, "no episode finished\nwithin the budget", ha="center", va="center",
                  transform=ax_r.transAxes)
    for ax in (ax_t, ax_r):
        if ax.get_legend_handles_labels()[0]:
            ax.legend()
    fig.suptitle(f"parallel training, {rows[0]['scene'].split('/')[-1]}, device {rows[0]['device']}", fontsize=10)
    fig.tight_layout()
    return _save_figure(fig, path_png, dpi=120)


# ---------------------------------------------------------------------------------------------
# Command line.


def _int_list(lo: int = 1) -> Callable[[str], list[int]]:
    def parse(text: str) -> list[int]:
        try:
            vals = [int(v) for v in text.split(",") if v.strip()]
        except ValueError as exc:
            raise argparse.ArgumentTypeError(f"expected comma-separated integers such as 1,2,4, got {text!r}") from exc
        if not vals:
            raise argparse.ArgumentTypeError(f"expected at least one integer, got {text!r}")
        bad = [v for v in vals if v < lo]
        if bad:
            raise argparse.ArgumentTypeError(f"every value must be >= {lo}, got {bad[0]} in {text!r}")
        return vals

    return parse


def _modes(text: str) -> list[str]:
    vals = [v.strip() for v in text.split(",") if v.strip()]
    bad = [v for v in vals if v not in MODES]
    if bad or not vals:
        raise argparse.ArgumentTypeError(f"unknown mode {bad[0] if bad else text!r}; modes: {','.join(MODES)}")
    return vals


def _pos_float(text: str) -> float:
    try:
        v = float(text)
    except ValueError as exc:
        raise argparse.ArgumentTypeError(f"expected a number, got {text!r}") from exc
    if not (math.isfinite(v) and v > 0):
        raise argparse.ArgumentTypeError(f"expected a number > 0, got {text!r}")
    return v


def _pos_int(lo: int) -> Callable[[str], int]:
    def parse(text: str) -> int:
        try:
            v = int(text)
        except ValueError as exc:
            raise argparse.ArgumentTypeError(f"expected an integer, got {text!r}") from exc
        if v < lo:
            raise argparse.ArgumentTypeError(f"expected an integer >= {lo}, got {text!r}")
        return v

    return parse


def _common(p: argparse.ArgumentParser) -> None:
    p.add_argument("--scene", default="home", help="scene name or id (home, navzoo/Home-v0, ...)")
    p.add_argument("--device", default="auto", choices=["cpu", "cuda", "auto"], help="torch device of the policy")
    p.add_argument("--workers", type=_pos_int(0), default=None,
                   help="worker processes for the env copies (default: min(N, cpu count); 0 or 1: in-process)")
    p.add_argument("--threads", type=_pos_int(1), default=1, help="torch intra-op threads (1 on a small shared CPU)")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--n-steps", type=_pos_int(2), default=32, help="PPO rollout length per robot (paper: 32)")
    p.add_argument("--n-epochs", type=_pos_int(1), default=6, help="PPO epochs per update (paper: 6)")
    p.add_argument("--features-dim", type=_pos_int(1), default=ModelSize.features_dim, help="transformer width D")
    p.add_argument("--heads", type=_pos_int(1), default=ModelSize.heads)
    p.add_argument("--blocks", type=_pos_int(1), default=ModelSize.blocks)
    p.add_argument("--net-arch", type=_int_list(1), default=list(ModelSize.net_arch), help="actor/critic widths")
    p.add_argument("--out", required=True, help="JSONL file the rows are appended to")
    p.add_argument("--plot", default=None, help="PNG drawn from all the rows of --out at the end")
    p.add_argument("--resume", action="store_true", help="skip configurations already in --out")


def add_arguments(parser: argparse.ArgumentParser) -> argparse.ArgumentParser:
    """Sub-commands ``runtime``, ``parallel`` and ``plot`` of the scaling study."""
    sub = parser.add_subparsers(dest="study", required=True, metavar="{runtime,parallel,plot}")
    rt = sub.add_parser("runtime", help="env and agent steps/s vs parallel envs (peds, infer, train)",
                        description="Runtime scaling: env and agent steps/s vs number of parallel env copies.")
    rt.add_argument("--modes", type=_modes, default=list(MODES), help="comma-separated: peds,infer,train")
    rt.add_argument("--envs", type=_int_list(1), default=[1, 2, 4, 8, 16], help="parallel env copies, e.g. 1,2,4,8,16")
    rt.add_argument("--seconds", type=_pos_float, default=20.0, help="timed wall seconds per measurement")
    rt.add_argument("--steps", type=_pos_int(1), default=None,
                    help="peds/infer: step this many rounds instead of --seconds")
    rt.add_argument("--warmup-steps", type=_pos_int(0), default=3)
    _common(rt)
    pt = sub.add_parser("parallel", help="time per PPO iteration and final reward vs parallel robots and batch size",
                        description="Parallel training: iteration time and final reward vs robots and batch size.")
    pt.add_argument("--robots", type=_int_list(1), default=[1, 2, 4, 8, 16], help="parallel robots, e.g. 1,2,4,8,16")
    pt.add_argument("--batch-sizes", type=_int_list(2), default=[64, 512], help="PPO minibatch sizes, e.g. 64,512")
    pt.add_argument("--sim-steps", type=_pos_int(1), default=16000, help="simulator steps of every run; each advances all R robots (paper: 16000)")
    pt.add_argument("--target-updates", type=_pos_int(1), default=5000,
                    help="updates the iteration time is extrapolated to (paper: 5000)")
    pt.add_argument("--time-limit-s", type=_pos_float, default=None, help="optional wall limit of each run")
    pt.add_argument("--runs-dir", default=None,
                    help="keep the runs' training folders here (checkpointed) so that a run stopped by "
                         "--time-limit-s, a crash or Ctrl-C continues when the command is run again")
    _common(pt)
    pl = sub.add_parser("plot", help="draw the figures from the JSONL files",
                        description="Plot runtime.png and/or parallel.png from the studies' JSONL files.")
    pl.add_argument("--runtime", default=None, help="runtime study JSONL")
    pl.add_argument("--parallel", default=None, help="parallel-training study JSONL")
    pl.add_argument("--out-dir", required=True, help="folder for runtime.png and parallel.png")
    return parser


def _model_from(args: argparse.Namespace) -> ModelSize:
    if args.features_dim % args.heads:
        raise ValueError(f"--features-dim ({args.features_dim}) must be divisible by --heads ({args.heads})")
    return ModelSize(features_dim=args.features_dim, heads=args.heads, blocks=args.blocks,
                     net_arch=tuple(args.net_arch))


def run_cli(args: argparse.Namespace, error: Callable[[str], Any] | None = None) -> int:
    """Run a sub-command from parsed options; bad values go to ``error`` (e.g. ``parser.error``) or raise."""
    try:
        if args.study == "plot":
            if not args.runtime and not args.parallel:
                raise ValueError("plot: give --runtime and/or --parallel")
            for path in (args.runtime, args.parallel):
                if path and not Path(path).is_file():
                    raise ValueError(f"plot: no such file {path!r}")
        else:
            resolve_scene(args.scene)
            resolve_device(args.device)
            model = _model_from(args)
    except ValueError as exc:
        if error is not None:
            error(str(exc))
        raise
    if args.study == "plot":
        out_dir = Path(args.out_dir)
        if args.runtime:
            print(json.dumps({"plot": str(plot_runtime(read_jsonl(args.runtime), out_dir / "runtime.png"))}))
        if args.parallel:
            print(json.dumps({"plot": str(plot_parallel(read_jsonl(args.parallel), out_dir / "parallel.png"))}))
        return 0
    if args.study == "runtime":
        for mode in args.modes:
            runtime_scaling(mode, args.envs, args.scene, args.seconds, args.device, args.workers, steps=args.steps,
                            warmup_steps=args.warmup_steps, seed=args.seed, threads=args.threads,
                            n_steps=args.n_steps, n_epochs=args.n_epochs, model=model, out=args.out,
                            resume=args.resume, echo=True)
        if args.plot:
            print(json.dumps({"plot": str(plot_runtime(read_jsonl(args.out), args.plot))}))
        return 0
    parallel_training(args.robots, args.batch_sizes, args.sim_steps, args.scene, args.device,
                      target_updates=args.target_updates, workers=args.workers, n_steps=args.n_steps,
                      n_epochs=args.n_epochs, seed=args.seed, threads=args.threads, model=model,
                      time_limit_s=args.time_limit_s, out=args.out, resume=args.resume, runs_dir=args.runs_dir,
                      echo=True)
    if args.plot:
        print(json.dumps({"plot": str(plot_parallel(read_jsonl(args.out), args.plot))}))
    return 0


def main(argv: Sequence[str] | None = None) -> int:
    """``python -m navzoo.agents.scaling_study``."""
    parser = add_arguments(argparse.ArgumentParser(prog="navzoo scaling-study",
                                                   description=__doc__.split("\n\n")[0]))
    args = parser.parse_args(argv)
    return run_cli(args, parser.error)


if __name__ == "__main__":
    raise SystemExit(main())
