"""Samples/s of AMP training's rollout collection (stage 3 + obstacles, the shipped policy acting).

``python scripts/bench_amp_collect.py --workers 1,4,15 [--replan-sync 0,1] [--envs-per-worker 16] [--steps 120] [--warmup 90]``
prints one JSON line per worker count: samples/s over ``steps`` batched control steps after a warm-up,
the per-step wall time, and the machine. Used to find where training's collection time goes
(docs: training/amp/README.md, "Collection speed"). It also times the discriminator's reference windows
of one iteration (``workers x envs_per_worker x --rollout-steps`` windows, median of 3): sampled in the
main process and sharded over the workers (``SubprocVecEnv.sample_reference_amp_obs``).
"""

from __future__ import annotations

import argparse
import json
import os
import time

import numpy as np


def bench(workers: int, envs_per_worker: int, steps: int, warmup: int, door_prob: float, replan_sync: bool,
          rollout_steps: int = 16) -> dict:
    from navzoo.agents.amp.checkpoint import load_policy
    from navzoo.agents.amp.path_env import PathTaskConfig
    from navzoo.agents.amp.train import grounded_locomotion_reference
    from navzoo.agents.amp.vec import SubprocAmpVecEnv
    from navzoo.machine import cpu_model

    policy = load_policy("policies/amp_pedestrian")
    task = PathTaskConfig(stage=3, pd_mode="motor", obstacle_obs=True, boxes_per_patch=4, pair_patches=True,
                          door_prob=door_prob, replan_sync=replan_sync)
    env = SubprocAmpVecEnv(grounded_locomotion_reference, workers, envs_per_worker, task, seed=0)
    try:
        obs = env.reset(seed=0)
        for _ in range(warmup):
            obs = env.step(policy(obs))[0]
        t0 = time.perf_counter()
        t_pol = 0.0
        for _ in range(steps):
            t1 = time.perf_counter()
            act = policy(obs)
            t_pol += time.perf_counter() - t1
            obs = env.step(act)[0]
        wall = time.perf_counter() - t0
        n_ref = workers * envs_per_worker * rollout_steps
        ref_ms = {}
        for shard in (False, True):
            env.shard_reference = shard
            times = []
            for k in range(3):
                t1 = time.perf_counter()
                env.sample_reference_amp_obs(n_ref, np.random.default_rng(k))
                times.append(1000 * (time.perf_counter() - t1))
            ref_ms["sharded" if shard else "main"] = round(float(np.median(times)), 1)
    finally:
        env.close()
    n = workers * envs_per_worker
    return {"workers": workers, "envs_per_worker": envs_per_worker, "samples_per_s": round(n * steps / wall, 1),
            "per_worker_samples_per_s": round(envs_per_worker * steps / wall, 1),
            "ms_per_step": round(1000 * wall / steps, 1), "policy_ms_per_step": round(1000 * t_pol / steps, 1),
            "reference_windows": n_ref, "reference_ms_main": ref_ms["main"], "reference_ms_sharded": ref_ms["sharded"],
            "door_prob": door_prob, "replan_sync": replan_sync, "steps": steps, "warmup": warmup,
            "threads_env": {k: os.environ.get(k) for k in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS")},
            "cpus": os.cpu_count(), "machine": cpu_model()}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--workers", default="1,4,15")
    ap.add_argument("--envs-per-worker", type=int, default=16)
    ap.add_argument("--steps", type=int, default=120)
    ap.add_argument("--warmup", type=int, default=90)
    ap.add_argument("--door-prob", type=float, default=0.0)
    ap.add_argument("--replan-sync", default="1", help="comma list of 0/1 (PathTaskConfig.replan_sync)")
    ap.add_argument("--rollout-steps", type=int, default=16, help="control steps per iteration (reference batch)")
    a = ap.parse_args()
    import torch

    torch.set_num_threads(1)
    for sync in (bool(int(x)) for x in a.replan_sync.split(",")):
        for w in (int(x) for x in a.workers.split(",")):
            print(json.dumps(bench(w, a.envs_per_worker, a.steps, a.warmup, a.door_prob, sync, a.rollout_steps)),
                  flush=True)


if __name__ == "__main__":
    main()
