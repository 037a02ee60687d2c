"""How the position gain of the joint motors shapes what the AMP discriminator sees (no policy involved).

The physics pedestrians' joints are PyBullet ``POSITION_CONTROL`` motors with ``positionGain`` 1 (remove the
whole position error in one 120 Hz substep, within the torque limits). docs/pedestrians_log.md ("What the
discriminator reads") found that with this gain the policy's exploration noise (sigma = exp(-2.9) in action
units, fixed) turns into joint-velocity jitter of 2.6x the clips' spread, which the discriminator reads instead
of the poses. A lower gain makes the servo a first-order lag (a fraction ``g`` of the error per substep) that
smooths a noisy target sequence, at the price of following the targets later.

For every gain and noise level this runs the oracle controller of stage 0 on the training clips: reference
state initialisation at ``--starts`` (clip, time) pairs, then each control step the PD targets are the clip's
pose ``--lead`` control steps ahead (mapped to actions, plus Gaussian noise of ``sigma`` in action units,
clipped to [-1, 1], mapped back), and reports

- ``up_1s``: share of starts still standing after 1 s, ``fall_median_s``;
- ``rot_err_local_1s``: mean rotation error of the 15 link frames relative to the root frame (the pose error
  without the root's drift; rad) over the first second, bodies still up;
- ``rot_err_world_1s``: the same in the world frame (the clip-tracking protocol's measure; includes drift);
- ``jitter_ratio``: per joint DOF, the spread (std over steps and starts) of the simulated joint velocity over
  that of the clip's joint velocity at the same times, median over DOFs (1 = the clips' own spread).

Usage::

    python scripts/amp_motor_gain_probe.py --gains 1,0.5,0.3,0.2 --sigmas 0,0.055 --leads 1,2 --json OUT.json
"""

from __future__ import annotations

import argparse
import json
import time

import numpy as np

from navzoo import sim as amp_sim
from navzoo.agents.amp.sim import PhysicsHumanoids, actions_to_targets, targets_to_actions
from navzoo.agents.amp.stage0 import SPACING, sample_starts
from navzoo.agents.amp.tracking import body_errors, rigid_bodies
from navzoo.agents.amp.train import grounded_locomotion_reference
from navzoo.agents.quat import quat_conj, quat_mul


def _local(pos: np.ndarray, quat: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Link frames relative to the root link (index 0): rotate into the root's frame."""
    q0 = np.broadcast_to(quat_conj(quat[:, :1]), quat.shape)
    return pos - pos[:, :1], quat_mul(q0, quat)


def _joint_vel(s) -> np.ndarray:
    """(B, 28) joint velocities: 8 spherical x 3 (child frame) + 4 revolute."""
    if isinstance(s, dict):
        return np.concatenate([np.asarray(s["sph_vel"]).reshape(len(s["rev_vel"]), -1), s["rev_vel"]], axis=1)
    return np.concatenate([np.asarray(s.sph_vel).reshape(len(s.rev_vel), -1), s.rev_vel], axis=1)


def probe(ref, clips, t, gain: float, sigma: float, lead: int, horizon: float = 2.0, seed: int = 0) -> dict:
    n = len(t)
    rng = np.random.default_rng(seed)
    off = np.c_[np.zeros(n), SPACING * np.arange(n), np.zeros(n)]
    cid = amp_sim.connect()
    hum = PhysicsHumanoids(cid, n, pd_mode="motor", motor_gain=gain)
    steps = int(round(horizon * hum.control_hz))
    up = np.ones(n, dtype=bool)
    fall = np.full(n, horizon)
    rl, rw, vs, vr = [], [], [], []
    try:
        hum.set_state(ref.state_at(clips, t).translated(off))
        for k in range(steps):
            tgt = ref.state_at(clips, t + (k + lead) * hum.control_dt)
            a = targets_to_actions(tgt.sph, tgt.rev)
            if sigma > 0:
                a = a + sigma * rng.standard_normal(a.shape)
            sph, rev = actions_to_targets(np.clip(a, -1.0, 1.0))
            hum.apply_targets(sph, rev)
            hum.step()
            s = hum.read_state()
            now = ref.state_at(clips, t + (k + 1) * hum.control_dt).translated(off)
            newly = hum.fallen() & up
            fall[newly] = (k + 1) * hum.control_dt
            up &= ~newly
            if k < hum.control_hz and up.any():
                ps, qs = rigid_bodies(s)
                pr, qr = rigid_bodies(now)
                rw.append(body_errors(ps, qs, pr, qr)[1][up])
                rl.append(body_errors(*_local(ps, qs), *_local(pr, qr))[1][up])
                vs.append(_joint_vel(s)[up])
                vr.append(_joint_vel(now)[up])
    finally:
        amp_sim.disconnect(cid)
    vs_a, vr_a = np.concatenate(vs), np.concatenate(vr)
    ratio = vs_a.std(axis=0) / np.maximum(vr_a.std(axis=0), 1e-6)
    return {
        "gain": gain, "sigma": sigma, "lead": lead, "n_starts": n,
        "up_1s": float(np.mean(fall >= 1.0 - 1e-9)),
        "fall_median_s": float(np.median(fall)),
        "rot_err_local_1s": float(np.mean(np.concatenate(rl))),
        "rot_err_world_1s": float(np.mean(np.concatenate(rw))),
        "jitter_ratio": float(np.median(ratio)),
    }


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--gains", default="1,0.5,0.3,0.2")
    ap.add_argument("--sigmas", default="0,0.055")
    ap.add_argument("--leads", default="1")
    ap.add_argument("--starts", type=int, default=156, help="(clip, time) starts, clips in turn (78 clips)")
    ap.add_argument("--horizon", type=float, default=2.0)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--json", default=None, help="write the rows to this file (JSON list)")
    a = ap.parse_args(argv)
    ref = grounded_locomotion_reference()
    clips, t = sample_starts(ref, a.starts, seed=a.seed, margin=1.0)
    rows = []
    for lead in [int(x) for x in a.leads.split(",")]:
        for gain in [float(x) for x in a.gains.split(",")]:
            for sigma in [float(x) for x in a.sigmas.split(",")]:
                t0 = time.perf_counter()
                r = probe(ref, clips, t, gain, sigma, lead, a.horizon, a.seed)
                r["wall_s"] = round(time.perf_counter() - t0, 1)
                rows.append(r)
                print(json.dumps(r), flush=True)
    if a.json:
        with open(a.json, "w") as f:
            json.dump(rows, f, indent=1)


if __name__ == "__main__":
    main()
