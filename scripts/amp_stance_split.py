"""The feet's fore-aft split of AMP pedestrians in crowds, against the reference clips.

Both trained lineages walk with one foot kept ahead of the other (docs/pedestrians_log.md, "Where the realism gap
lies"). The optional stance term of the task reward (``NavConfig.amp_stance_reward``) charges the running mean
(time constant ``features.STANCE_TAU_S``, 1 s) of the right foot's lead over the left along the heading
(``features.foot_split``). This script measures that split for exported policies walking the following
protocol's scenes on social-force targets, and for the clips themselves:

    python scripts/amp_stance_split.py --source shipped=policies/amp_pedestrian --source s1=DIR \\
        --scenes lobby:15,square_crossing:10,corridor:12 --seconds 60 --seed 0 --out F.json

Per source: over the standing bodies moving at >= ``--min-speed`` m/s after their first second, the mean of
the signed split (m, + = right foot ahead), the mean absolute running mean, and the share of samples whose
running mean leaves the term's free band (``STANCE_FREE_M``). The clips row runs the same running mean over
every clip (ankle joint centres from forward kinematics; the simulator's rows use the feet's centres of mass,
which differ by the same offset for both feet when they point the same way) after each clip's first second.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np

from navzoo.agents.amp.features import STANCE_FREE_M, STANCE_TAU_S, foot_split
from navzoo.benchmark.pedestrians import _make, parse_scene_counts
from navzoo.envs.amp_humans import CONTROL_HZ


def run_scene(scene: str, n: int, seconds: float, seed: int, policy_dir: str, min_speed: float,
              trim: float | None = None) -> dict[str, np.ndarray]:
    """Per-sample signed split and running mean (both m) of the moving, standing bodies of one scene."""
    wrapped, env = _make(scene, n, "amp", seconds, seed, policy_dir, steering_trim=trim)
    h = np.arange(env.n_robots, env.n_total)
    split, mean = [], []
    steps = 0
    while not env._needs_reset:
        wrapped.step({})
        steps += 1
        if steps * env.amp.control_steps < CONTROL_HZ:  # the running mean starts at 0: skip its first second
            continue
        keep = ~env.human_fallen & (np.linalg.norm(env.vel[h], axis=1) >= min_speed)
        if keep.any():
            split.append(foot_split(env.amp.state())[keep])
            mean.append(env.amp.stance[keep].copy())
    wrapped.close()
    return {"split": np.concatenate(split) if split else np.zeros(0),
            "mean": np.concatenate(mean) if mean else np.zeros(0)}


def clip_split(lib) -> dict[str, np.ndarray]:
    """The same samples for every clip of a motion library (its frames, after each clip's first second)."""
    from scipy.signal import lfilter

    from navzoo.agents.amp.features import KEY_LINKS
    from navzoo.agents.motion_lib import humanoid_fk

    split, mean = [], []
    a = 1.0 / (lib.fps * STANCE_TAU_S)
    skip = int(round(lib.fps))
    for c in range(len(lib)):
        fr = lib.frames(c)
        pos, _ = humanoid_fk(fr["root_pos"], fr["root_quat"], fr["sph"], fr["rev"])
        s = foot_split({"root_quat": fr["root_quat"], "key_pos": pos[:, list(KEY_LINKS)]})
        m = lfilter([a], [1.0, a - 1.0], s)  # the running mean m += a (s - m), from 0, as the simulator's
        split.append(s[skip:])
        mean.append(m[skip:])
    return {"split": np.concatenate(split), "mean": np.concatenate(mean)}


def summarise(samples: dict[str, np.ndarray]) -> dict[str, float]:
    s, m = samples["split"], samples["mean"]
    if not len(s):
        return {"n": 0}
    return {"n": int(len(s)), "mean_split_m": float(s.mean()), "mean_abs_running_mean_m": float(np.abs(m).mean()),
            "share_outside_free_band": float((np.abs(m) > STANCE_FREE_M).mean())}


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--source", action="append", default=[], metavar="LABEL=POLICY_DIR", required=True)
    ap.add_argument("--scenes", default="lobby:15,square_crossing:10,corridor:12", help="scene:pedestrians,...")
    ap.add_argument("--seconds", type=float, default=60.0)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--min-speed", type=float, default=0.5, help="m/s: only moving bodies are sampled")
    ap.add_argument("--trim", type=float, default=None, help="steering trim (rad); default: the policy's own")
    ap.add_argument("--no-clips", action="store_true", help="skip the reference clips' row")
    ap.add_argument("--out", default=None)
    args = ap.parse_args(argv)
    try:
        scenes = parse_scene_counts(args.scenes)
    except ValueError as e:
        ap.error(str(e))
    sources = []
    for src in args.source:
        label, sep, path = src.partition("=")
        if not sep or not label or not Path(path, "config.json").is_file():
            ap.error(f"--source takes LABEL=POLICY_DIR with an exported policy there, got {src!r}")
        sources.append((label, path))
    out: dict = {"command": "python scripts/amp_stance_split.py " + " ".join(argv if argv is not None else sys.argv[1:]),
                 "stance_tau_s": STANCE_TAU_S, "free_band_m": STANCE_FREE_M, "sources": {}}
    if not args.no_clips:
        from navzoo.agents import motion_lib

        out["clips"] = summarise(clip_split(motion_lib.load()))
        print(f"clips: {out['clips']}", flush=True)
    for label, path in sources:
        t0 = time.time()
        per = {name: run_scene(name, n, args.seconds, args.seed, path, args.min_speed, args.trim) for name, n in scenes}
        pooled = {k: np.concatenate([v[k] for v in per.values()]) for k in ("split", "mean")}
        out["sources"][label] = {"policy": path, "all": summarise(pooled),
                                 "by_scene": {name: summarise(v) for name, v in per.items()},
                                 "wall_s": round(time.time() - t0, 1)}
        print(f"{label}: {out['sources'][label]['all']} in {out['sources'][label]['wall_s']} s", flush=True)
    if args.out:
        Path(args.out).parent.mkdir(parents=True, exist_ok=True)
        Path(args.out).write_text(json.dumps(out, indent=1))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
