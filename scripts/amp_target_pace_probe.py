"""Where the physics pedestrians' slow pace comes from: body speed against target speed, per step.

Runs the following protocol's scenes (``navzoo.benchmark.pedestrians``), AMP bodies on a crowd model's
targets, and records at every control step each standing person's body speed and the speed of its
target point (both over 0.4 s, the realism metrics' time base), plus the person's preferred speed.
It prints, per scene and pooled, the median body and target speeds, the share of person-time whose
target stands (< 0.3 m/s), and the body's speed as a share of its target's while the target walks
(>= 0.8 m/s). With ``--bodies kinematic`` the kinematic crowd is measured the same way (no targets).

    python scripts/amp_target_pace_probe.py --scenes station:3,square_crossing:10,lobby:15 --seconds 60 --out F.json

``--path-in-sight 0`` runs the diffusion crowd as before its ``path_in_sight`` setting (docs/crowd_log.md, "Path points
in sight").
"""

from __future__ import annotations

import argparse
import json
import sys
import time

import numpy as np


def probe(scene: str, n: int, seconds: float, seed: int, policy: str | None, crowd: str, bodies: str,
          path_in_sight: bool = True) -> dict:
    from navzoo.benchmark.matched_realism import diffusion_settings_for_new_crowds
    from navzoo.benchmark.pedestrians import _make, target_points
    from navzoo.torch_threads import one_torch_thread

    with one_torch_thread(), diffusion_settings_for_new_crowds({"path_in_sight": float(path_in_sight)}):
        wrapped, env = _make(scene, n, bodies, seconds, seed, policy, crowd)
        R = env.n_robots
        h = np.arange(R, env.n_total)
        lag = max(1, round(0.4 / float(env.config.dt)))
        pos, tgt, down = [env.pos[h].copy()], [], []
        t0 = time.time()
        while not env._needs_reset:
            wrapped.step({})
            pos.append(env.pos[h].copy())
            t = target_points(env)
            tgt.append(np.full((n, 2), np.nan) if t is None else np.asarray(t, dtype=float).copy())
            down.append(np.asarray(env.human_fallen, dtype=bool).copy() if env.amp is not None
                        else np.zeros(n, dtype=bool))
        pref = np.asarray(env.v_pref[h], dtype=float)
        wrapped.close()
    pos, tgt, down = np.asarray(pos)[1:], np.asarray(tgt), np.asarray(down)
    dt = lag * float(env.config.dt)
    v_body = np.linalg.norm(pos[lag:] - pos[:-lag], axis=-1) / dt
    v_tgt = np.linalg.norm(tgt[lag:] - tgt[:-lag], axis=-1) / dt
    ok = ~(down[lag:] | down[:-lag])
    print(f"{scene} ({n}, {seconds:.0f} s): {time.time() - t0:.0f} s", file=sys.stderr, flush=True)
    return {"scene": scene, "people": n, "v_body": v_body[ok], "v_target": v_tgt[ok],
            "pref_speed": pref.tolist()}


def summary(v_body: np.ndarray, v_tgt: np.ndarray) -> dict:
    out = {"samples": int(v_body.size), "body_median": float(np.median(v_body)),
           "body_mean": float(v_body.mean()), "body_share_under_0.3": float((v_body < 0.3).mean())}
    if np.isfinite(v_tgt).any():
        walking = v_tgt >= 0.8
        out |= {"target_median": float(np.nanmedian(v_tgt)), "target_mean": float(np.nanmean(v_tgt)),
                "target_share_under_0.3": float((v_tgt < 0.3).mean()),
                "target_share_walking": float(walking.mean()),
                "body_over_target_walking": float(v_body[walking].mean() / v_tgt[walking].mean())
                if walking.any() else None,
                "body_median_target_walking": float(np.median(v_body[walking])) if walking.any() else None,
                "body_median_target_standing": float(np.median(v_body[v_tgt < 0.3])) if (v_tgt < 0.3).any()
                else None}
    return out


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--scenes", default="station:3,square_crossing:10,lobby:15", help="scene:people,...")
    ap.add_argument("--seconds", type=float, default=60.0)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--policy", default=None, help="exported AMP policy (default: the shipped one)")
    ap.add_argument("--crowd", default="sfm", choices=("sfm", "orca", "diffusion"))
    ap.add_argument("--bodies", default="amp", choices=("amp", "kinematic"))
    ap.add_argument("--path-in-sight", type=int, choices=(0, 1), default=1,
                    help="the diffusion crowd's path_in_sight setting (default 1, on; docs/crowd.md)")
    ap.add_argument("--workers", type=int, default=1)
    ap.add_argument("--out", default=None)
    args = ap.parse_args()
    from navzoo.benchmark.pedestrians import parse_scene_counts

    try:
        scenes = parse_scene_counts(args.scenes)
    except ValueError as e:
        ap.error(str(e))
    jobs = [(name, k, args.seconds, args.seed, args.policy, args.crowd, args.bodies, bool(args.path_in_sight))
            for name, k in scenes]
    if args.workers > 1:
        import multiprocessing as mp

        with mp.get_context("spawn").Pool(min(args.workers, len(jobs))) as pool:
            rows = pool.starmap(probe, jobs)
    else:
        rows = [probe(*j) for j in jobs]
    res = {"settings": vars(args), "scenes": {r["scene"]: summary(r["v_body"], r["v_target"]) for r in rows},
           "pooled": summary(np.concatenate([r["v_body"] for r in rows]), np.concatenate([r["v_target"] for r in rows]))}
    for r in rows:
        res["scenes"][r["scene"]]["pref_speed"] = r["pref_speed"]
    text = json.dumps(res, indent=1)
    print(text)
    if args.out:
        with open(args.out, "w") as f:
            f.write(text + "\n")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
