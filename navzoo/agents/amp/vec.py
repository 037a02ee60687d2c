"""Spread :class:`~navzoo.agents.amp.path_env.AmpPathEnv` over worker processes (one PyBullet client each).

PyBullet simulation is CPU-bound and single-threaded per client, so throughput scales with worker
processes (the device machine has 16 cores). Each worker hosts ``envs_per_worker`` humanoids; the main
process concatenates their batches and samples the discriminator's reference windows itself. A worker
that dies is reported with its index and the last command instead of hanging the learner.
"""

from __future__ import annotations

import multiprocessing as mp
import signal
import traceback
from collections.abc import Callable
from typing import Any

import numpy as np

from navzoo.agents.amp.path_env import AmpPathEnv, PathTaskConfig, amp_obs_version, reference_amp_windows
from navzoo.agents.reference import ReferenceMotion


def _worker(conn: Any, make_reference: Callable[[], ReferenceMotion], n: int, config: PathTaskConfig,
            seed: int) -> None:
    # Ctrl-C reaches the whole process group; the learner handles it (finishes the iteration and
    # checkpoints, which needs the workers) and closes them.
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    env = None
    try:
        env = AmpPathEnv(n, make_reference(), config, seed=seed)
        conn.send(("ready", (env.obs_dim, env.act_dim, env.amp_obs_dim)))
        while True:
            cmd, arg = conn.recv()
            if cmd == "reset":
                conn.send(("ok", env.reset(arg)))
            elif cmd == "step":
                conn.send(("ok", env.step(arg)))
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


class SubprocAmpVecEnv:
    """``workers`` processes x ``envs_per_worker`` humanoids behind the ``AmpVecEnv`` protocol.

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
        self.workers = int(workers)
        self.envs_per_worker = int(envs_per_worker)
        self.num_envs = self.workers * self.envs_per_worker
        ctx = mp.get_context("spawn")
        self._conns, self._procs = [], []
        for w in range(self.workers):
            parent, child = ctx.Pipe()
            proc = ctx.Process(target=_worker, args=(child, make_reference, self.envs_per_worker, self.config, seed + w),
                               daemon=True)
            proc.start()
            child.close()
            self._conns.append(parent)
            self._procs.append(proc)
        dims = [self._recv(w, "start") for w in range(self.workers)]
        self.obs_dim, self.act_dim, self.amp_obs_dim = dims[0]
        # The discriminator's real samples come from the clips here (no simulation needed).
        self._reference = make_reference()
        self.amp_obs_version = amp_obs_version(self.config, self._reference)

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
        k = self.envs_per_worker
        for w, c in enumerate(self._conns):
            c.send(("step", np.asarray(actions[w * k:(w + 1) * k])))
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
        return reference_amp_windows(self._reference, n, rng, self.config.amp_window, 1.0 / self.config.control_hz,
                                     self.config.amp_velocity)

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
