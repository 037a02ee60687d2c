"""Spread AMP training envs over worker processes (one PyBullet client each).

PyBullet simulation is CPU-bound and single-threaded per client, so throughput scales with worker
processes (the device machine has 16 cores). :class:`SubprocVecEnv` runs any env of the learner's
``AmpVecEnv`` protocol, one per worker, e.g. :class:`~navzoo.agents.amp.path_env.AmpPathEnv`
(:class:`SubprocAmpVecEnv`: ``envs_per_worker`` humanoids each) or the pedestrians of navzoo scenes
(:class:`navzoo.rl.amp_joint.NavAmpVecEnv`, a scene per worker). The main process concatenates their
batches. The discriminator's reference windows are sampled by the workers, each its share, from seeds
the learner's generator draws (:meth:`SubprocVecEnv.sample_reference_amp_obs`): in the main process the
15,360 windows of one iteration of 60 workers x 16 humanoids took 0.5 s on the 2-core VM. A worker that
dies is reported with its index and the last command instead of hanging the learner.
"""

from __future__ import annotations

import multiprocessing as mp
import signal
import traceback
from collections.abc import Callable
from functools import partial
from typing import Any

import numpy as np

from navzoo.agents.amp.path_env import AmpPathEnv, PathTaskConfig, amp_obs_version, reference_amp_windows
from navzoo.agents.reference import ReferenceMotion


def _path_env(make_reference: Callable[[], ReferenceMotion], n: int, config: PathTaskConfig, seed: int) -> AmpPathEnv:
    return AmpPathEnv(n, make_reference(), config, seed=seed)


def _worker(conn: Any, make_env: Callable[[], Any]) -> None:
    # Ctrl-C reaches the whole process group; the learner handles it (finishes the iteration and
    # checkpoints, which needs the workers) and closes them.
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    env = None
    try:
        env = make_env()
        conn.send(("ready", (env.num_envs, env.obs_dim, env.act_dim, env.amp_obs_dim)))
        while True:
            cmd, arg = conn.recv()
            if cmd == "reset":
                conn.send(("ok", env.reset(arg)))
            elif cmd == "step":
                conn.send(("ok", env.step(arg)))
            elif cmd == "reference":
                n, seed = arg
                conn.send(("ok", np.asarray(env.sample_reference_amp_obs(n, np.random.default_rng(seed)), np.float32)))
            elif cmd == "counters":
                conn.send(("ok", env.counters()))
            elif cmd == "reset_stats":
                conn.send(("ok", env.reset_stats()))
            elif cmd == "close":
                conn.send(("ok", None))
                break
    except (EOFError, KeyboardInterrupt):
        pass
    except Exception:  # noqa: BLE001 - reported to the parent with the traceback
        conn.send(("error", traceback.format_exc()))
    finally:
        if env is not None:
            env.close()


class SubprocVecEnv:
    """Vectorised AMP envs, one per worker process, behind the ``AmpVecEnv`` protocol: the batch is the
    workers' rows one after the other.

    Args:
        make_envs: one picklable callable per worker (e.g. a ``functools.partial`` of a module-level
            function) that builds that worker's env, which has ``num_envs``, ``obs_dim``, ``act_dim``,
            ``amp_obs_dim``, ``reset`` and ``step`` (``counters`` / ``reset_stats`` if :meth:`counters` is used).
        sample_reference: ``(n, rng) -> (n, amp_obs_dim)`` reference windows for the discriminator,
            sampled in this process (no simulation needed) with one worker or ``shard_reference=False``.
        amp_obs_version: the discriminator inputs' version (checked against checkpoints).
        shard_reference: sample the reference windows in the workers (each env's own
            ``sample_reference_amp_obs``, which must then exist and draw from the same reference motion
            as ``sample_reference``).
    """

    def __init__(self, make_envs: list[Callable[[], Any]], sample_reference: Callable[[int, np.random.Generator], np.ndarray],
                 amp_obs_version: Any, shard_reference: bool = True) -> None:
        if not make_envs:
            raise ValueError("SubprocVecEnv needs at least one worker")
        self.workers = len(make_envs)
        ctx = mp.get_context("spawn")
        self._conns, self._procs = [], []
        for make_env in make_envs:
            parent, child = ctx.Pipe()
            proc = ctx.Process(target=_worker, args=(child, make_env), daemon=True)
            proc.start()
            child.close()
            self._conns.append(parent)
            self._procs.append(proc)
        try:
            dims = [self._recv(w, "start") for w in range(self.workers)]
        except RuntimeError:
            self.close()  # the workers that did start
            raise
        if len({d[1:] for d in dims}) != 1:
            self.close()
            raise ValueError(f"the workers' envs differ in (obs_dim, act_dim, amp_obs_dim): {[d[1:] for d in dims]}")
        self._sizes = [int(d[0]) for d in dims]
        self._bounds = np.concatenate([[0], np.cumsum(self._sizes)])
        self.num_envs = int(self._bounds[-1])
        self.obs_dim, self.act_dim, self.amp_obs_dim = dims[0][1:]
        self._sample_reference = sample_reference
        self.shard_reference = bool(shard_reference)
        self.amp_obs_version = amp_obs_version

    def _recv(self, w: int, what: str) -> Any:
        try:
            if not self._conns[w].poll(600):
                raise RuntimeError(f"AMP worker {w} did not answer '{what}' within 600 s")
            kind, payload = self._conns[w].recv()
        except EOFError as exc:
            raise RuntimeError(f"AMP worker {w} (pid {self._procs[w].pid}) died during '{what}' "
                               f"(exit code {self._procs[w].exitcode})") from exc
        if kind == "error":
            raise RuntimeError(f"AMP worker {w} failed during '{what}':\n{payload}")
        return payload

    def reset(self, seed: int | None = None) -> np.ndarray:
        for w, c in enumerate(self._conns):
            c.send(("reset", None if seed is None else seed + w))
        return np.concatenate([self._recv(w, "reset") for w in range(self.workers)])

    def step(self, actions: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, dict[str, Any]]:
        b = self._bounds
        for w, c in enumerate(self._conns):
            c.send(("step", np.asarray(actions[b[w]:b[w + 1]])))
        parts = [self._recv(w, "step") for w in range(self.workers)]
        obs = np.concatenate([p[0] for p in parts])
        rew = np.concatenate([p[1] for p in parts])
        term = np.concatenate([p[2] for p in parts])
        trunc = np.concatenate([p[3] for p in parts])
        info: dict[str, Any] = {}
        for key in parts[0][4]:
            if key == "final_obs":
                continue
            info[key] = np.concatenate([p[4][key] for p in parts])
        if any("final_obs" in p[4] for p in parts):
            info["final_obs"] = np.concatenate([p[4].get("final_obs", p[0]) for p in parts])
        return obs, rew, term, trunc, info

    def sample_reference_amp_obs(self, n: int, rng: np.random.Generator) -> np.ndarray:
        """``n`` reference windows (n, amp_obs_dim). With ``shard_reference`` (and more than one worker),
        worker ``w`` samples the ``w``-th of near-equal shares with its own generator, seeded from ``rng``
        (one draw per worker); the windows are independent draws from the reference either way, and a
        given ``rng`` state gives the same windows on every run (a resumed run included)."""
        if not self.shard_reference or self.workers == 1:
            return self._sample_reference(n, rng)
        shares = [len(part) for part in np.array_split(np.arange(int(n)), self.workers)]
        seeds = rng.integers(0, 2**63 - 1, size=self.workers)
        for c, k, seed in zip(self._conns, shares, seeds, strict=True):
            c.send(("reference", (k, int(seed))))
        parts = [self._recv(w, "reference") for w in range(self.workers)]
        return np.concatenate(parts).reshape(int(n), self.amp_obs_dim)

    def counters(self) -> list[dict[str, Any]]:
        """Every worker env's ``counters()`` (statistics since its last ``reset_stats``)."""
        for c in self._conns:
            c.send(("counters", None))
        return [self._recv(w, "counters") for w in range(self.workers)]

    def reset_stats(self) -> None:
        for c in self._conns:
            c.send(("reset_stats", None))
        for w in range(self.workers):
            self._recv(w, "reset_stats")

    def close(self) -> None:
        for w, c in enumerate(self._conns):
            try:
                c.send(("close", None))
                self._recv(w, "close")
            except (OSError, RuntimeError, BrokenPipeError):
                pass
        for p in self._procs:
            p.join(timeout=10)
            if p.is_alive():
                p.terminate()


class SubprocAmpVecEnv(SubprocVecEnv):
    """``workers`` processes x ``envs_per_worker`` humanoids of :class:`AmpPathEnv`.

    Args:
        make_reference: builds the reference motions (called in every worker and once here; must be
            picklable, e.g. a module-level function).
        workers, envs_per_worker: process count and humanoids per process.
        config: task settings.
        seed: worker ``w`` seeds its generator with ``seed + w``.
    """

    def __init__(self, make_reference: Callable[[], ReferenceMotion], workers: int, envs_per_worker: int,
                 config: PathTaskConfig | None = None, seed: int = 0) -> None:
        self.config = config or PathTaskConfig()
        self.envs_per_worker = int(envs_per_worker)
        reference = make_reference()
        cfg = self.config
        super().__init__(
            [partial(_path_env, make_reference, self.envs_per_worker, cfg, seed + w) for w in range(int(workers))],
            partial(reference_amp_windows, reference, window=cfg.amp_window, dt=1.0 / cfg.control_hz,
                    velocity=cfg.amp_velocity, span=cfg.amp_velocity_span),
            amp_obs_version(cfg, reference))
        self._reference = reference
