"""Trace how physics (AMP) pedestrians stray from their target trajectories between replans.

Runs ``human_model="amp"`` pedestrians on social-force targets (the following protocol's env) in one
scene and prints, for the walking steps (body and target faster than 0.8 m/s): the path error by time
since the last replan, the signed sideways error (+ = target to the body's left), and the angles of the
body's velocity and of the target's direction against the body's heading. This is the measurement
behind the steering trim (docs/pedestrians_log.md, "Steering trim").

``--plan-velocity`` changes the velocity the target rollouts start from: ``instant`` (the env's: the
root's velocity now), ``ema`` (exponential average, time constant 0.5 s) or ``mean1s`` (displacement
over the last second). ``--steering-trim`` overrides the policy's trim (0 = off).

    python scripts/amp_steering_trace.py --scene station --people 3 --seconds 120 --steering-trim 0
"""

from __future__ import annotations

import argparse
import json

import numpy as np


def trace(scene: str, people: int, seconds: float, seed: int, plan_velocity: str, trim: float | None) -> dict:
    from navzoo.benchmark.pedestrians import _make

    wrapped, env = _make(scene, people, "amp", seconds, seed, None, steering_trim=trim)
    amp = env.amp
    planar, control_step, plan_all = amp.planar, amp.control_step, amp.plan_all
    ema, hist = [None], []

    def step(before):
        control_step(before)
        pos, _, vel, _ = planar()
        ema[0] = vel.copy() if ema[0] is None else ema[0] + (1 - np.exp(-(1 / 30) / 0.5)) * (vel - ema[0])
        hist.append(pos.copy())
        del hist[:-31]

    def smoothed():
        pos, yaw, vel, w = planar()
        if plan_velocity == "ema" and ema[0] is not None:
            vel = ema[0].copy()
        elif plan_velocity == "mean1s" and len(hist) > 30:
            vel = hist[-1] - hist[0]
        return pos, yaw, vel, w

    def plan():
        amp.planar = smoothed
        try:
            plan_all()
        finally:
            amp.planar = planar

    if plan_velocity != "instant":
        amp.control_step, amp.plan_all = step, plan
    rows = []
    n = amp.n
    while not env._needs_reset:
        wrapped.step({})
        tgt = amp.target_now()
        pos, yaw, vel, _ = planar()
        k = np.minimum(amp.k_prog, amp.path_len - 6)
        tdir = amp.paths[np.arange(n), k + 5] - amp.paths[np.arange(n), k]
        d = tgt - pos
        side = np.cos(yaw) * d[:, 1] - np.sin(yaw) * d[:, 0]
        wrap = lambda a: (a + np.pi) % (2 * np.pi) - np.pi  # noqa: E731
        rows += [[np.linalg.norm(d[j]), side[j], np.linalg.norm(vel[j]), np.linalg.norm(tdir[j]) * 6,
                  wrap(np.arctan2(vel[j, 1], vel[j, 0]) - yaw[j]), wrap(np.arctan2(tdir[j, 1], tdir[j, 0]) - yaw[j]),
                  (amp.t - amp.plan_t[j]) / 30.0, float(amp.fallen[j])] for j in range(n)]
    wrapped.close()
    a = np.array(rows)
    err, side, bs, ts, vang, tang, since, fallen = a.T
    walk = (fallen == 0) & (bs > 0.8) & (ts > 0.8)
    bins = []
    for lo in np.arange(0.0, 2.0, 0.25):
        m = walk & (since >= lo) & (since < lo + 0.25)
        if m.any():
            bins.append({"since_replan_s": float(lo), "mean_error_m": round(float(err[m].mean()), 3),
                         "mean_abs_sideways_m": round(float(np.abs(side[m]).mean()), 3)})
    standing = fallen == 0
    return {"scene": scene, "people": people, "seconds": seconds, "seed": seed, "plan_velocity": plan_velocity,
            "steering_trim": wrapped.policy.policy.steering_trim,
            "mean_error_m": round(float(err[standing].mean()), 3),
            "share_steps_over_0_5_m": round(float((err[standing] > 0.5).mean()), 4),
            "walking_signed_sideways_m": round(float(side[walk].mean()), 3),
            "walking_velocity_minus_heading_rad": round(float(vang[walk].mean()), 3),
            "walking_target_minus_heading_rad": round(float(tang[walk].mean()), 3),
            "by_time_since_replan": bins}


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--scene", default="station")
    ap.add_argument("--people", type=int, default=3)
    ap.add_argument("--seconds", type=float, default=120.0)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--plan-velocity", choices=("instant", "ema", "mean1s"), default="instant")
    ap.add_argument("--steering-trim", type=float, default=None, help="rad (default: the policy's own)")
    args = ap.parse_args(argv)
    print(json.dumps(trace(args.scene, args.people, args.seconds, args.seed, args.plan_velocity, args.steering_trim)))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
