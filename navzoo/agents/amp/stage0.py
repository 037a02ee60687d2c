"""Stage 0 of the AMP pedestrian controller: the checks to pass before any training.

(a) **Feature check**: reference state initialisation (RSI) of simulated humanoids from reference
    frames, then the AMP features of the simulated bodies (:func:`~navzoo.agents.amp.features.amp_features`
    of :meth:`~navzoo.agents.amp.sim.PhysicsHumanoids.read_state`) against the features computed from the
    same frames without simulation (:func:`~navzoo.agents.amp.features.reference_features`, numpy FK).
    The maximum absolute difference must be ~0 (float round-off).
(b) **PD tracking**: from RSI, the PD targets follow the reference pose (the pose the clip has at the
    end of each control step; no policy, no balance feedback). Time until the first fall (capped at
    ``horizon``) per start, and the mean body (link centre of mass) position error over the first second.
(c) **Throughput**: humanoid control steps per second for 1, 4, 16 humanoids in one process
    (targets + ``step`` + ``read_state`` + ``fallen`` + features; and ``step`` alone).
Also: how long a standing body stays up with zero targets (``standing``).

``python -m navzoo.agents.amp.stage0 [--json] [--pd-mode stable|motor] [--physics-hz 120]
[--reference cycle|library] [--starts 19] [--horizon 3] [--target-velocities] [--ground box|plane]
[--gain-scale 1]`` prints the summary.
"""

from __future__ import annotations

import argparse
import json
import os
import time

import numpy as np
import pybullet as p

from navzoo import sim
from navzoo.agents.amp.cycle_reference import CycleReference
from navzoo.agents.amp.features import (
    FEATURE_SLICES,
    amp_features,
    reference_features,
    reference_state_dict,
    to_heading_frame,
)
from navzoo.agents.amp.sim import DEFAULT_GAINS, PDGains, PhysicsHumanoids
from navzoo.agents.reference import ReferenceMotion

SPACING = 3.0  # m between the humanoids of one check (along y), so that they never touch


def sample_starts(
    ref: ReferenceMotion, n: int, seed: int = 0, margin: float = 0.0
) -> tuple[np.ndarray, np.ndarray]:
    """``n`` start (clip, time) pairs: with one clip, evenly spaced over it; otherwise clips in turn
    (shuffled by ``seed``) at uniform random times in ``[0, duration - margin)``."""
    names = ref.clip_names()
    if len(names) == 1:
        d = ref.duration(0)
        return np.zeros(n, dtype=int), np.arange(n) * d / n
    rng = np.random.default_rng(seed)
    order = rng.permutation(len(names))
    clips = order[np.arange(n) % len(names)]
    dur = np.array([ref.duration(int(c)) for c in clips])
    t = rng.uniform(0.0, 1.0, n) * np.maximum(dur - margin, 0.0)
    return clips.astype(int), t


def _humanoids(n: int, ground: str = "box", gain_scale: float = 1.0, **kw) -> tuple[int, PhysicsHumanoids]:
    """A client with n humanoids. ``ground="plane"`` stands them on a ``GEOM_PLANE`` instead of the box;
    ``gain_scale`` multiplies Kp, Kd and the torque limits."""
    cid = sim.connect()
    if gain_scale != 1.0:
        g = kw.get("gains", DEFAULT_GAINS)
        kw["gains"] = PDGains(
            kp={k: v * gain_scale for k, v in g.kp.items()},
            kd={k: v * gain_scale for k, v in g.kd.items()},
            max_torque={k: v * gain_scale for k, v in g.max_torque.items()},
        )
    if ground == "plane":
        plane = p.createMultiBody(
            0.0, p.createCollisionShape(p.GEOM_PLANE, physicsClientId=cid), physicsClientId=cid
        )
        p.changeDynamics(plane, -1, lateralFriction=kw.get("friction", 0.9), physicsClientId=cid)
        return cid, PhysicsHumanoids(cid, n, ground=False, ground_id=plane, **kw)
    if ground != "box":
        raise ValueError(f"ground must be 'box' or 'plane', got {ground!r}")
    return cid, PhysicsHumanoids(cid, n, **kw)


def feature_check(ref: ReferenceMotion, clips: np.ndarray, t: np.ndarray, **kw) -> dict:
    """(a): max |amp_features(sim after RSI) - reference_features(frame)|, overall and per feature group.

    The simulated bodies stand ``SPACING`` m apart (the features do not depend on the planar position)."""
    n = len(t)
    state = ref.state_at(clips, t)
    off = np.c_[np.zeros(n), SPACING * np.arange(n), np.zeros(n)]
    cid, hum = _humanoids(n, **kw)
    try:
        hum.set_state(state.translated(off))
        f_sim = amp_features(hum.read_state())
    finally:
        sim.disconnect(cid)
    f_ref = reference_features(state)
    diff = np.abs(f_sim - f_ref)
    return {
        "n_frames": n,
        "max_abs_diff": float(diff.max()),
        "max_abs_diff_by_group": {k: float(diff[:, s].max()) for k, s in FEATURE_SLICES.items()},
    }


def tracking_check(
    ref: ReferenceMotion,
    clips: np.ndarray,
    t: np.ndarray,
    horizon: float = 3.0,
    target_velocities: bool = False,
    **kw,
) -> dict:
    """(b): PD tracking of the reference poses from RSI, one humanoid per start.

    Returns fall times (s, ``horizon`` when it did not fall), their median / mean / min and the
    fraction of starts that stay up at least 1 s, the mean body position error (m, mean over the 15
    links' centres of mass and the first second, all starts; world frame, and relative to the root in
    the heading frame, i.e. without the drift of the root), the largest joint speed seen while up
    (rad/s; a blow-up shows here) and the deepest foot penetration into the ground while up during the
    first second (m).
    """
    n = len(t)
    off = np.c_[np.zeros(n), SPACING * np.arange(n), np.zeros(n)]
    cid, hum = _humanoids(n, **kw)
    steps = int(round(horizon * hum.control_hz))
    fall = np.full(n, float(horizon))
    up = np.ones(n, dtype=bool)
    errs, errs_local = [], []
    max_speed = 0.0
    max_pen = 0.0
    try:
        hum.set_state(ref.state_at(clips, t).translated(off))
        for k in range(steps):
            tk = t + (k + 1) * hum.control_dt
            target = ref.state_at(clips, tk)
            if target_velocities:
                hum.apply_targets(target.sph, target.rev, target.sph_vel, target.rev_vel)
            else:
                hum.apply_targets(target.sph, target.rev)
            hum.step()
            s = hum.read_state()
            if k < hum.control_hz:
                rd = reference_state_dict(target.translated(off))
                errs.append(np.linalg.norm(s["body_pos"] - rd["body_pos"], axis=-1).mean(axis=-1))
                loc_sim = to_heading_frame(s["root_quat"], s["body_pos"] - s["root_pos"][:, None])
                loc_ref = to_heading_frame(rd["root_quat"], rd["body_pos"] - rd["root_pos"][:, None])
                errs_local.append(np.linalg.norm(loc_sim - loc_ref, axis=-1).mean(axis=-1))
            if up.any():
                speeds = np.concatenate([np.linalg.norm(s["sph_vel"], axis=-1), np.abs(s["rev_vel"])], axis=1)
                max_speed = max(max_speed, float(speeds[up].max()))
                for i in np.flatnonzero(up) if k < hum.control_hz else ():
                    for foot in (5, 11):
                        max_pen = max(max_pen, -p.getAABB(hum.ids[i], foot, physicsClientId=cid)[0][2])
            newly = hum.fallen() & up
            fall[newly] = (k + 1) * hum.control_dt
            up &= ~newly
    finally:
        sim.disconnect(cid)
    return {
        "n_starts": n,
        "horizon_s": horizon,
        "target_velocities": target_velocities,
        "fall_time_s": [round(float(x), 3) for x in fall],
        "fall_time_median_s": float(np.median(fall)),
        "fall_time_mean_s": float(fall.mean()),
        "fall_time_min_s": float(fall.min()),
        "frac_up_1s": float(np.mean(fall >= 1.0 - 1e-9)),
        "body_pos_error_1s_m": float(np.mean(errs)),
        "body_pos_error_root_frame_1s_m": float(np.mean(errs_local)),
        "max_joint_speed_rad_s": max_speed,
        "max_foot_penetration_m": max_pen,
    }


def standing_check(horizon: float = 10.0, **kw) -> dict:
    """Two bodies in :meth:`PhysicsHumanoids.standing_state` (default lean; headings 0 and 2 rad), zero
    targets: time until each falls (``horizon`` when it does not)."""
    cid, hum = _humanoids(2, **kw)
    fall = np.full(2, float(horizon))
    try:
        hum.set_state(hum.standing_state(np.array([[0.0, 0.0], [0.0, SPACING]]), np.array([0.0, 2.0])))
        up = np.ones(2, dtype=bool)
        for k in range(int(round(horizon * hum.control_hz))):
            hum.step()
            newly = hum.fallen() & up
            fall[newly] = (k + 1) * hum.control_dt
            up &= ~newly
            if not up.any():
                break
    finally:
        sim.disconnect(cid)
    return {"horizon_s": horizon, "fall_time_s": [round(float(x), 3) for x in fall]}


def throughput(ref: ReferenceMotion, sizes: tuple[int, ...] = (1, 4, 16), seconds: float = 2.0, **kw) -> dict:
    """(c): humanoid control steps per second (N x steps / wall time) for N humanoids in one client,
    tracking the reference (fallen bodies re-initialised), for the full loop and for ``step()`` alone."""
    out = {}
    for n in sizes:
        clips, t = sample_starts(ref, n)
        off = np.c_[np.zeros(n), SPACING * np.arange(n), np.zeros(n)]
        cid, hum = _humanoids(n, **kw)
        try:
            hum.set_state(ref.state_at(clips, t).translated(off))
            k = 0
            sim_time = 0.0
            t0 = time.perf_counter()
            while time.perf_counter() - t0 < seconds:
                tk = t + (k + 1) * hum.control_dt
                target = ref.state_at(clips, tk)
                hum.apply_targets(target.sph, target.rev)
                ts = time.perf_counter()
                hum.step()
                sim_time += time.perf_counter() - ts
                amp_features(hum.read_state())
                hum.joint_power()
                fl = hum.fallen()
                if fl.any():
                    idx = np.flatnonzero(fl)
                    t[idx] = tk[idx]
                    hum.set_state(ref.state_at(clips[idx], t[idx]).translated(off[idx]), idx)
                k += 1
            wall = time.perf_counter() - t0
        finally:
            sim.disconnect(cid)
        out[str(n)] = {"steps_per_s": n * k / wall, "step_only_steps_per_s": n * k / sim_time}
    return out


def _machine() -> dict:
    from navzoo.machine import cpu_model

    return {"nproc": os.cpu_count(), "cpu": cpu_model(), "pybullet": p.getAPIVersion()}


def run_stage0(
    ref: ReferenceMotion | None = None,
    *,
    starts: int = 19,
    horizon: float = 3.0,
    target_velocities: bool = False,
    sizes: tuple[int, ...] = (1, 4, 16),
    throughput_seconds: float = 2.0,
    standing_horizon: float = 10.0,
    seed: int = 0,
    **humanoid_kw,
) -> dict:
    """Run (a), (b), (c) and a standing check, and return the summary dict. ``humanoid_kw`` go to
    :class:`PhysicsHumanoids` (``physics_hz``, ``pd_mode``, ...) except ``ground`` ("box" | "plane") and
    ``gain_scale``; ``ref`` defaults to :class:`CycleReference`."""
    ref = ref if ref is not None else CycleReference()
    # With several clips, start at least 1 s before a clip's end where the clip allows it.
    clips, t = sample_starts(ref, starts, seed=seed, margin=1.0)
    t_start = time.perf_counter()
    summary = {
        "reference": type(ref).__name__,
        "n_clips": len(ref.clip_names()),
        "config": {
            "physics_hz": humanoid_kw.get("physics_hz", 120),
            "control_hz": humanoid_kw.get("control_hz", 30),
            "pd_mode": humanoid_kw.get("pd_mode", "stable"),
            **{k: v for k, v in humanoid_kw.items() if k not in ("physics_hz", "control_hz", "pd_mode")},
        },
        "features": feature_check(ref, clips, t, **humanoid_kw),
        "tracking": tracking_check(
            ref, clips, t, horizon=horizon, target_velocities=target_velocities, **humanoid_kw
        ),
        "standing": standing_check(standing_horizon, **humanoid_kw),
    }
    if sizes:
        summary["throughput"] = throughput(ref, tuple(sizes), throughput_seconds, **humanoid_kw)
    summary["machine"] = _machine()
    summary["wall_s"] = time.perf_counter() - t_start
    return summary


def _load_reference(name: str) -> ReferenceMotion:
    if name == "cycle":
        return CycleReference()
    if name == "library":
        from navzoo.agents import motion_lib  # the motion library (real mocap), when installed

        return motion_lib.load()
    raise ValueError(f"unknown reference {name!r} (cycle | library)")


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(
        prog="python -m navzoo.agents.amp.stage0", description=__doc__.split("\n\n")[0]
    )
    ap.add_argument("--json", action="store_true", help="print the summary as one JSON object")
    ap.add_argument(
        "--reference", default="cycle", help="cycle (DeepMimic walk) | library (navzoo motion library)"
    )
    ap.add_argument("--pd-mode", default="stable", choices=("stable", "motor"))
    ap.add_argument("--physics-hz", type=int, default=120)
    ap.add_argument("--control-hz", type=int, default=30)
    ap.add_argument("--solver-iterations", type=int, default=None)
    ap.add_argument("--starts", type=int, default=19, help="start frames for (a) and (b)")
    ap.add_argument("--horizon", type=float, default=3.0, help="seconds of tracking per start")
    ap.add_argument(
        "--target-velocities", action="store_true", help="also give the PD the reference velocities"
    )
    ap.add_argument("--sizes", default="1,4,16", help="humanoid counts for the throughput ('' to skip)")
    ap.add_argument("--throughput-seconds", type=float, default=2.0)
    ap.add_argument("--standing-horizon", type=float, default=10.0, help="seconds of the standing check")
    ap.add_argument(
        "--ground", default="box", choices=("box", "plane"), help="ground shape (box: the default)"
    )
    ap.add_argument("--gain-scale", type=float, default=1.0, help="multiply Kp, Kd and the torque limits")
    ap.add_argument(
        "--no-self-collision", action="store_true", help="a body's links do not collide with each other"
    )
    ap.add_argument("--seed", type=int, default=0)
    a = ap.parse_args(argv)
    kw = {"physics_hz": a.physics_hz, "control_hz": a.control_hz, "pd_mode": a.pd_mode}
    if a.solver_iterations is not None:
        kw["solver_iterations"] = a.solver_iterations
    if a.no_self_collision:
        kw["self_collision"] = False
    if a.ground != "box":
        kw["ground"] = a.ground
    if a.gain_scale != 1.0:
        kw["gain_scale"] = a.gain_scale
    summary = run_stage0(
        _load_reference(a.reference),
        starts=a.starts,
        horizon=a.horizon,
        target_velocities=a.target_velocities,
        sizes=tuple(int(x) for x in a.sizes.split(",") if x.strip()),
        throughput_seconds=a.throughput_seconds,
        standing_horizon=a.standing_horizon,
        seed=a.seed,
        **kw,
    )
    if a.json:
        print(json.dumps(summary))
    else:
        tr = summary["tracking"]
        print(json.dumps({k: v for k, v in summary.items() if k != "tracking"}, indent=2))
        print(json.dumps({"tracking": {k: v for k, v in tr.items() if k != "fall_time_s"}}, indent=2))
        print("fall times (s):", tr["fall_time_s"])
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
