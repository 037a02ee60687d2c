"""Do physics pedestrians keep their targets' pace? Body speed against target speed, by preferred speed.

    python scripts/amp_pace_probe.py [--scene circle_crossing] [--people 1] [--speeds 0.4,0.7,1.0,1.3] \
        [--seconds 60] [--seed 0] [--crowd sfm|diffusion|orca]

For each preferred walking speed v (``NavConfig.human_speed = (v, v)``), runs AMP pedestrians on the
targets of one crowd model (``--crowd``, social force by default) in one scene and prints one JSON line:
the mean speed of the target point (from the target trajectory itself, so the jumps back to the body at
each replan do not count), the mean speed of the bodies' roots, their ratio, the mean distance between
body and target (m), the share of steps where a body is more than 0.5 m from its target, and the trips'
outcomes (as in ``navzoo eval pedestrians``: success, off path, fall, timeout). Steps of fallen people and of the first second after a
trip starts are left out.
"""

from __future__ import annotations

import argparse
import json

import numpy as np

from navzoo.benchmark import pedestrians as P


def probe(scene: str, people: int, speed: float, seconds: float, seed: int, crowd: str = "sfm") -> dict:
    wrapped, env = P._make(scene, people, "amp", seconds, seed, None, crowd, env_overrides={"human_speed": (speed, speed)})
    amp, h = env.amp, np.arange(env.n_robots, env.n_total)
    hz = 1.0 / env.config.dt
    trips = P.Trips(env, people)
    ended = {"success": 0, "off_path": 0, "fall": 0, "timeout": 0}
    tgt_v, body_v, lag = [], [], []
    rows = np.arange(people)
    while not env._needs_reset:
        wrapped.step({})
        k = np.minimum(amp.k_prog, amp.path_len - 2)
        v_target = np.linalg.norm(amp.paths[rows, k + 1] - amp.paths[rows, k], axis=1) * hz
        err = np.linalg.norm(env.pos[h] - amp.target_now(), axis=1)
        ok = ~env.human_fallen & ~trips.done & (env.sim_time - trips.start > 1.0)
        tgt_v.append(v_target[ok])
        body_v.append(np.linalg.norm(env.vel[h][ok], axis=1))
        lag.append(err[ok])
        for _, outcome, _, _ in trips.update(err, env.human_fallen):
            ended[outcome] += 1
    wrapped.close()
    tv, bv, lg = (np.concatenate(x) for x in (tgt_v, body_v, lag))
    return {"scene": scene, "people": people, "speed": speed, "seed": seed, "crowd": crowd,
            "target_speed": round(float(tv.mean()), 3), "body_speed": round(float(bv.mean()), 3),
            "ratio": round(float(bv.mean() / max(tv.mean(), 1e-9)), 3), "lag_m": round(float(lg.mean()), 3),
            "lag_over_0.5": round(float((lg > 0.5).mean()), 3), **ended}


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--scene", default="circle_crossing")
    ap.add_argument("--people", type=int, default=1)
    ap.add_argument("--speeds", default="0.4,0.7,1.0,1.3")
    ap.add_argument("--seconds", type=float, default=60.0)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--crowd", default="sfm", choices=("sfm", "diffusion", "orca"),
                    help="the crowd model that makes the targets (default sfm)")
    args = ap.parse_args(argv)
    for v in (float(x) for x in args.speeds.split(",")):
        print(json.dumps(probe(args.scene, args.people, v, args.seconds, args.seed, args.crowd)), flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
