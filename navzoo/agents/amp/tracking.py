"""Closed-loop tracking of reference clips by the trained AMP pedestrian policy (the paper's protocol).

"We use the learned AMP policy to track the reference motions in a closed-loop manner. During
rollout, the simulated rigid-body states are synchronized with the reference sequence and compared
frame by frame." Here, for every clip:

1. one physics humanoid (:class:`~navzoo.agents.amp.sim.PhysicsHumanoids`, the training settings of
   :class:`~navzoo.agents.amp.path_env.PathTaskConfig`: ``pd_mode="motor"``, 120 Hz physics, 30 Hz
   control, box ground) is put in the clip's first frame, velocities included (reference state
   initialisation). All humanoids of a batch share one PyBullet client, 40 m apart; each clip's
   reference is translated so that it starts at its humanoid's origin, and sim and reference are
   compared in that shifted frame;
2. the policy's target path is the clip's own root trajectory on the ground, sampled at the control
   rate (the observation holds the next 10 points 0.5 s apart, as in training). The policy looks 5 s
   ahead, longer than most clips, so the path must go on after the clip's last frame: by default
   (``path_end="extend"``) it continues at the clip's final root velocity (mean over the last 0.25 s),
   as a clip cut mid-stride would; ``path_end="hold"`` holds the last point instead, which asks the
   policy to stop where the clip does not;
3. the deterministic policy runs for the clip's duration (optionally capped by ``max_seconds``); after
   every control step the 15 rigid bodies of the simulated humanoid are compared with the reference at
   the same time: the *position error* is the mean over the 15 bodies of the distance between link
   frame origins, the *rotation error* the mean over the bodies of the geodesic angle
   ``2 arccos |<q_sim, q_ref>|`` between link orientations. Both sides go through the same forward
   kinematics (:func:`navzoo.agents.motion_lib.humanoid_fk`, fed with the simulator's base pose and
   joint values or with the reference's), so the link definitions match exactly; at t = 0 both errors
   are zero up to round-off;
4. a clip *fails* at the first control step whose (per-step, mean over bodies) position error exceeds
   0.5 m. By default (``stop_on_failure=True``) its rollout ends there, that step included, as in
   termination-based tracking evaluations; ``stop_on_failure=False`` tracks every clip to its end.
   Falls (:meth:`PhysicsHumanoids.fallen`: a non-foot link touching the ground or the root sinking
   below half its standing height) are recorded, but do not end a rollout.

Metrics, per clip: the mean and the maximum over steps of the per-step position error, the mean
rotation error, ``failed`` and ``fell`` (with their first times). Summary:

- ``mean_pos_error_m``: mean over clips of the per-clip mean position error;
- ``max_pos_error_m``: mean over clips of the per-clip *maximum* position error. This is the reading
  of the paper's "maximum rigid-body position error 0.433 m" that fits its own numbers: with 35.4 % of
  the clips failing (a per-step error above 0.5 m), the single largest error over all clips is above
  0.5 m, so 0.433 m can only be an average of per-clip maxima (with rollouts ended at the failure, a
  failed clip's maximum is the first error above 0.5 m). The largest error over everything is
  ``worst_pos_error_m``;
- ``mean_rot_error_rad``: mean over clips of the per-clip mean rotation error;
- ``clip_success_rate`` (share of clips that never fail), ``fall_rate`` (share that fell while tracked),
  ``n_clips``, ``seconds_simulated`` (tracked seconds summed over clips), ``seconds_reference``
  (requested clip seconds, after the cap), ``wall_s``, the same three error means over the successful
  clips only (``success_*``), the settings, and ``per_clip``;
- where the error comes from, per clip and as means over clips: the rotation error's root heading, root tilt
  and pose parts (:func:`rotation_parts`, ``ROT_PART_KEYS``) and the root's offset from the clip's root along
  and across the clip's heading and in height (:func:`root_offsets`, ``ROOT_OFFSET_KEYS``).

With ``stop_on_failure`` (the paper's protocol) every mean covers only the steps before a clip's failure, so a
controller that fails after one second is scored on that second: read the errors next to
``seconds_simulated``, or track whole clips (``stop_on_failure=False``).

Humanoids sharing a client are far apart but not bit-for-bit independent (PyBullet solves the whole
world in one pass): one clip's errors move by a few millimetres with the batch it runs in (measured on
the 78 locomotion clips: batches of 64 vs one client per clip, ``batch_size=1``: summary means within
2 mm / 3 mrad, the same clips failing). Finished clips keep being simulated until their batch ends.

Paper (Table in the AMP pedestrian section): 0.218 m / 0.343 rad / max 0.433 m / 64.6 % of the
evaluated locomotion clips tracked. The policy is not conditioned on the clip's pose, only on its root
path, so errors of a couple of decimetres are inherent to the protocol.

CLI: ``python -m navzoo.agents.amp.tracking [POLICY_DIR] [--motions DIR] [--clips A,B,...]
[--max-seconds S] [--json] [--per-clip]``; the default policy is the shipped
``policies/amp_pedestrian``, the default clips the packaged library's navigation locomotion (the
training set, :func:`navzoo.agents.amp.train.locomotion_reference`).
"""

from __future__ import annotations

import argparse
import json
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from navzoo import sim as nzsim
from navzoo.agents.amp.checkpoint import POLICY_CONFIG, load_policy
from navzoo.agents.amp.features import (
    N_RAYS,
    heading,
    obstacle_observation,
    policy_observation,
)
from navzoo.agents.amp.path_env import PathTaskConfig
from navzoo.agents.amp.sim import PhysicsHumanoids, actions_to_targets
from navzoo.agents.motion_lib import DEFAULT_NAME, LINK_NAMES, MotionLibrary, humanoid_fk
from navzoo.agents.quat import heading as quat_heading
from navzoo.agents.quat import quat_about_z, quat_angle, quat_conj, quat_mul, quat_normalize
from navzoo.agents.reference import ReferenceState
from navzoo.benchmark.realism import poses_from_state
from navzoo.torch_threads import one_torch_thread

#: A clip fails once the per-step mean rigid-body position error exceeds this (m).
FAIL_THRESHOLD_M = 0.5
#: Humanoids per PyBullet client (larger selections run in several batches, one after the other).
DEFAULT_BATCH = 64
#: The shipped policy (repository checkout).
DEFAULT_POLICY_DIR = Path(__file__).resolve().parents[3] / "policies" / "amp_pedestrian"
N_BODIES = 15

StateLike = ReferenceState | dict[str, np.ndarray]
#: Per-clip and summary keys of :func:`rotation_parts`' three errors.
ROT_PART_KEYS = ("mean_root_heading_error_rad", "mean_root_tilt_error_rad", "mean_pose_rot_error_rad")
#: Where the root is against the clip's root (:func:`root_offsets`): along the clip's heading (signed, < 0 behind),
#: across it (unsigned), and in height (signed, < 0 lower).
ROOT_OFFSET_KEYS = ("mean_root_along_error_m", "mean_root_cross_error_m", "mean_root_height_error_m")


# --------------------------------------------------------------------------------------------------
# Errors between a simulated state and a reference state
# --------------------------------------------------------------------------------------------------


def _pose(x: StateLike) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """(root_pos (B, 3), root_quat (B, 4), sph (B, 8, 4), rev (B, 4)) of a batched state or state dict."""
    if isinstance(x, ReferenceState):
        parts = (x.root_pos, x.root_quat, x.sph, x.rev)
    else:
        parts = (x["root_pos"], x["root_quat"], x["sph"], x["rev"])
    root_pos = np.atleast_2d(np.asarray(parts[0], dtype=np.float64))
    b = root_pos.shape[0]
    return (
        root_pos.reshape(b, 3),
        np.asarray(parts[1], dtype=np.float64).reshape(b, 4),
        np.asarray(parts[2], dtype=np.float64).reshape(b, 8, 4),
        np.asarray(parts[3], dtype=np.float64).reshape(b, 4),
    )


def rigid_bodies(state: StateLike) -> tuple[np.ndarray, np.ndarray]:
    """World frames of the 15 rigid bodies: ``(pos (B, 15, 3), quat (B, 15, 4))`` (unit quaternions).

    ``state`` is a batched :class:`ReferenceState` or a :meth:`PhysicsHumanoids.read_state` dict; both
    go through :func:`navzoo.agents.motion_lib.humanoid_fk` (link frame origins and orientations)."""
    root_pos, root_quat, sph, rev = _pose(state)
    pos, quat = humanoid_fk(root_pos, quat_normalize(root_quat), quat_normalize(sph), rev)
    return pos, quat_normalize(quat)


def body_errors(
    pos_a: np.ndarray, quat_a: np.ndarray, pos_b: np.ndarray, quat_b: np.ndarray, per_body: bool = False
) -> tuple[np.ndarray, np.ndarray]:
    """Mean over bodies of the position error (m) and geodesic rotation error (rad) of link frames
    (..., 15, 3) / (..., 15, 4): two arrays of shape (...), or with ``per_body`` of shape (..., 15)."""
    pos_err = np.linalg.norm(np.asarray(pos_a) - np.asarray(pos_b), axis=-1)
    # 2 arccos |<q_a, q_b>|, computed as the angle of q_a^-1 q_b (accurate near zero).
    rot_err = quat_angle(quat_mul(quat_conj(np.asarray(quat_a)), np.asarray(quat_b)))
    return (pos_err, rot_err) if per_body else (pos_err.mean(axis=-1), rot_err.mean(axis=-1))


def rotation_parts(quat_a: np.ndarray, quat_b: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Where a rotation error comes from, for link frames (..., 15, 4) (body 0 = the root link):

    - the root's heading error (rad, |yaw difference| wrapped to [0, pi]);
    - the root's tilt error (rad): the geodesic angle between the two root orientations with their
      headings removed (leaning, rolling);
    - the pose error (rad): the mean over the 14 other links of the geodesic angle between their
      orientations relative to their own root, i.e. the rotation error of the two poses put on one root.

    Three arrays of shape (...). A body that walks the clip's pose with a turned root has a pose error of 0."""
    qa = np.asarray(quat_a, dtype=np.float64)
    qb = np.asarray(quat_b, dtype=np.float64)
    ha, hb = quat_heading(qa[..., 0, :]), quat_heading(qb[..., 0, :])
    yaw = np.abs(np.angle(np.exp(1j * (ha - hb))))
    tilt_a = quat_mul(quat_about_z(-ha), qa[..., 0, :])
    tilt_b = quat_mul(quat_about_z(-hb), qb[..., 0, :])
    tilt = quat_angle(quat_mul(quat_conj(tilt_a), tilt_b))
    loc_a = quat_mul(np.broadcast_to(quat_conj(qa[..., :1, :]), qa[..., 1:, :].shape), qa[..., 1:, :])
    loc_b = quat_mul(np.broadcast_to(quat_conj(qb[..., :1, :]), qb[..., 1:, :].shape), qb[..., 1:, :])
    pose = quat_angle(quat_mul(quat_conj(loc_a), loc_b)).mean(axis=-1)
    return yaw, tilt, pose


def root_offsets(root_pos: np.ndarray, ref_root_pos: np.ndarray, ref_root_quat: np.ndarray
                 ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The root's offset from the reference root in the reference's heading frame: (along (B,), signed, > 0
    ahead of the reference; across (B,), unsigned; height (B,), signed, > 0 above it). Tells a controller that
    lags or runs ahead of the clip (along), one that veers (across) and one that crouches (height) apart,
    where the position error only gives their sum over the bodies."""
    e = np.asarray(root_pos, dtype=np.float64) - np.asarray(ref_root_pos, dtype=np.float64)
    yaw = quat_heading(np.asarray(ref_root_quat, dtype=np.float64))
    c, s = np.cos(yaw), np.sin(yaw)
    return e[..., 0] * c + e[..., 1] * s, np.abs(-e[..., 0] * s + e[..., 1] * c), e[..., 2]


def rigid_body_errors(state: StateLike, reference: StateLike) -> tuple[np.ndarray, np.ndarray]:
    """Per humanoid (B,): mean over the 15 rigid bodies of the link position error (m) and of the
    geodesic link rotation error ``2 arccos |<q1, q2>|`` (rad) between ``state`` and ``reference``
    (each a batched :class:`ReferenceState` or a ``read_state()`` dict)."""
    pa, qa = rigid_bodies(state)
    pb, qb = rigid_bodies(reference)
    if pa.shape != pb.shape:
        raise ValueError(f"state and reference batch sizes differ: {pa.shape[0]} vs {pb.shape[0]}")
    return body_errors(pa, qa, pb, qb)


# --------------------------------------------------------------------------------------------------
# Inputs
# --------------------------------------------------------------------------------------------------


def load_motions(motions: str | Path | MotionLibrary | None) -> MotionLibrary:
    """The clips to track: a :class:`MotionLibrary` as is, a library folder (or its ``.json``) loaded
    whole, or (None) the packaged library's navigation locomotion, as in training."""
    if motions is None:
        from navzoo.agents.amp.train import locomotion_reference

        return locomotion_reference()
    if isinstance(motions, MotionLibrary):
        if len(motions) == 0:
            raise ValueError("the motion library holds no clips")
        return motions
    path = Path(motions)
    if not path.exists():
        raise FileNotFoundError(f"motion folder not found: {path}")
    if path.is_dir() and not (path / f"{DEFAULT_NAME}.json").is_file():
        raise FileNotFoundError(
            f"no motion library in {path}: expected {DEFAULT_NAME}.json and {DEFAULT_NAME}.npz "
            "(build one with `navzoo motions convert`)"
        )
    lib = MotionLibrary.load(path)
    if len(lib) == 0:
        raise ValueError(f"the motion library in {path} holds no clips")
    return lib


def _clip_indices(lib: MotionLibrary, clips: Sequence[int | str] | int | str | None) -> list[int]:
    if clips is None:
        return list(range(len(lib)))
    if isinstance(clips, (int, str, np.integer)):
        clips = [clips]
    out = []
    for c in clips:
        if isinstance(c, str):
            if c not in lib.clip_names():
                raise ValueError(f"no clip named {c!r} in the motion library ({len(lib)} clips)")
            out.append(lib.clip_index(c))
        elif isinstance(c, (int, np.integer)) and not isinstance(c, bool):
            if not 0 <= int(c) < len(lib):
                raise ValueError(f"clip index {c} out of range [0, {len(lib)})")
            out.append(int(c))
        else:
            raise TypeError(f"clips must be indices or names, got {c!r}")
    if not out:
        raise ValueError("no clips selected")
    return out


def _load_policy_dir(policy_dir: str | Path, device: str = "cpu") -> Any:
    root = Path(policy_dir)
    if not root.exists():
        raise FileNotFoundError(f"policy directory not found: {root}")
    if root.is_dir() and not (root / POLICY_CONFIG).is_file():
        raise FileNotFoundError(
            f"{root} is not an exported AMP policy: no {POLICY_CONFIG} (export one with "
            "AmpLearner.export_policy or navzoo.agents.amp.train.export_from_checkpoint)"
        )
    return load_policy(root, device=device)


# --------------------------------------------------------------------------------------------------
# Tracking
# --------------------------------------------------------------------------------------------------



#: ``path_end="extend"``: the clip's final root velocity is its mean over this last stretch (s).
END_VELOCITY_WINDOW_S = 0.25
PATH_ENDS = ("hold", "extend")


def clip_end_motion(lib: Any, clip: np.ndarray, full: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Each clip's last root position on the ground (n, 2) and its final root velocity (n, 2), the mean over its
    last :data:`END_VELOCITY_WINDOW_S`: where and how a target path goes on after the clip ends."""
    w = np.minimum(END_VELOCITY_WINDOW_S, full)
    end = np.asarray(lib.state_at(clip, full).root_pos)[:, :2]
    before = np.asarray(lib.state_at(clip, full - w).root_pos)[:, :2]
    return end, (end - before) / np.maximum(w, 1e-9)[:, None]


def _extend_paths(paths: np.ndarray, lib: MotionLibrary, clip: np.ndarray, full: np.ndarray, shift: np.ndarray,
                  times: np.ndarray) -> np.ndarray:
    """Target paths (n, L, 2) whose points after each clip's end continue at the clip's final root velocity
    (:func:`clip_end_motion`) instead of holding the last point."""
    end, vel = clip_end_motion(lib, clip, full)
    end = end + shift
    after = times[None, :] > full[:, None]  # (n, L)
    extra = end[:, None, :] + vel[:, None, :] * (times[None, :] - full[:, None])[..., None]
    return np.where(after[..., None], extra, paths)


def _base_obs_dim(cfg: PathTaskConfig) -> int:
    """Policy inputs without obstacle rays: self-observation + target waypoints."""
    return 105 + 2 * cfg.n_waypoints


def _track_batch(
    policy: Any,
    lib: MotionLibrary,
    idx: list[int],
    max_seconds: float | None,
    cfg: PathTaskConfig,
    fail_threshold: float,
    stop_on_failure: bool,
    path_end: str = "extend",
    pose_sink: list | None = None,
) -> list[dict[str, Any]]:
    """Track clips ``idx`` with one humanoid each in one PyBullet client (``pose_sink``: see :func:`track_clips`)."""
    n = len(idx)
    hz = cfg.control_hz
    dt = 1.0 / hz
    clip = np.asarray(idx, dtype=np.int64)
    full = np.array([lib.duration(c) for c in idx])
    dur = full if max_seconds is None else np.minimum(full, float(max_seconds))
    n_steps = np.maximum(1, np.floor(dur * hz + 1e-6).astype(int))
    max_steps = int(n_steps.max())
    stride = int(round(cfg.waypoint_dt * hz))
    path_len = max_steps + stride * cfg.n_waypoints + 1

    # Origins on a grid centred on the world origin (the box ground is 1 km wide).
    cols = int(np.ceil(np.sqrt(n)))
    k = np.arange(n)
    origins = np.stack([(k % cols) * cfg.spacing, (k // cols) * cfg.spacing], axis=1).astype(float)
    origins -= origins.mean(axis=0)

    # Reference at every control step (times clamped to each clip's real end; a capped clip's path goes on
    # as the clip does), shifted to the origins; the path after a clip's end is extended or held (path_end).
    times = np.minimum(np.arange(path_len)[None, :] * dt, full[:, None])  # (n, L)
    ref = lib.state_at(np.repeat(clip, path_len), times.reshape(-1))
    first = np.asarray(ref.root_pos).reshape(n, path_len, 3)[:, 0]
    shift = np.concatenate([origins - first[:, :2], np.zeros((n, 1))], axis=1)
    ref = ref.translated(np.repeat(shift, path_len, axis=0))
    paths = np.asarray(ref.root_pos).reshape(n, path_len, 3)[..., :2]
    if path_end == "extend":
        paths = _extend_paths(paths, lib, clip, full, shift[:, :2], np.arange(path_len) * dt)
    ref_root = (np.asarray(ref.root_pos).reshape(n, path_len, 3), np.asarray(ref.root_quat).reshape(n, path_len, 4))
    ref_pos, ref_quat = rigid_bodies(ref)
    ref_pos = ref_pos.reshape(n, path_len, N_BODIES, 3)
    ref_quat = ref_quat.reshape(n, path_len, N_BODIES, 4)
    start = lib.state_at(clip, np.zeros(n)).translated(shift)  # first frames, velocities included

    pos_err = np.full((n, max_steps), np.nan)
    rot_err = np.full((n, max_steps), np.nan)
    rot_body = np.full((n, max_steps, N_BODIES), np.nan)  # per-body geodesic errors
    rot_parts = np.full((n, max_steps, 3), np.nan)  # root heading, root tilt, pose (rotation_parts)
    root_off = np.full((n, max_steps, 3), np.nan)  # along, across, height (root_offsets)
    fail_step = np.full(n, -1)
    fall_step = np.full(n, -1)
    tracked = np.zeros(n, dtype=int)
    wp_offsets = stride * np.arange(1, cfg.n_waypoints + 1)

    client = nzsim.connect()
    try:
        bodies = PhysicsHumanoids(client, n, physics_hz=cfg.physics_hz, control_hz=hz, pd_mode=cfg.pd_mode)
        bodies.set_state(start)
        state = bodies.read_state()
        for step in range(1, max_steps + 1):
            t = step - 1  # the observation at time t looks at the path points t + stride * j
            wp = paths[:, np.minimum(t + wp_offsets, path_len - 1)]
            rays = None
            if getattr(policy, "obs_dim", 0) == _base_obs_dim(cfg) + N_RAYS:  # obstacle rays: open ground
                root = state["root_pos"][:, :2]
                rays = obstacle_observation(root, heading(state["root_quat"]), None, root, 0.3, self_disc=np.arange(n))
            obs = policy_observation(state, wp, rays)
            sph, rev = actions_to_targets(np.clip(np.asarray(policy(obs), dtype=np.float64), -1.0, 1.0))
            bodies.apply_targets(sph, rev)
            bodies.step()
            state = bodies.read_state()
            active = (step <= n_steps) & (fail_step < 0 if stop_on_failure else True)
            sim_pos, sim_quat = rigid_bodies(state)
            pb, rb = body_errors(sim_pos, sim_quat, ref_pos[:, step], ref_quat[:, step], per_body=True)
            pe = pb.mean(axis=-1)
            pos_err[active, step - 1] = pe[active]
            rot_err[active, step - 1] = rb[active].mean(axis=-1)
            rot_body[active, step - 1] = rb[active]
            rot_parts[active, step - 1] = np.stack(rotation_parts(sim_quat, ref_quat[:, step]), axis=-1)[active]
            off = root_offsets(state["root_pos"], ref_root[0][:, step], ref_root[1][:, step])
            root_off[active, step - 1] = np.stack(off, axis=-1)[active]
            tracked[active] = step
            fallen = bodies.fallen()
            fall_step[active & fallen & (fall_step < 0)] = step
            up = active & ~fallen
            if pose_sink is not None and up.any():
                pose_sink.append((poses_from_state({k: state[k][up] for k in ("root_pos", "root_quat", "sph", "rev")}),
                                  np.linalg.norm(state["root_lin_vel"][up, :2], axis=1)))
            fail_step[active & (pe > fail_threshold) & (fail_step < 0)] = step
            still = (step + 1 <= n_steps) & ((fail_step < 0) if stop_on_failure else True)
            if not still.any():
                break
    finally:
        nzsim.disconnect(client)

    out = []
    for i, c in enumerate(idx):
        pe = pos_err[i, : tracked[i]]
        re = rot_err[i, : tracked[i]]
        out.append({
            "name": lib.clip_names()[c],
            "index": int(c),
            "duration_s": float(dur[i]),
            "clip_duration_s": float(full[i]),
            "tracked_s": float(tracked[i] * dt),
            "mean_pos_error_m": float(np.mean(pe)),
            "max_pos_error_m": float(np.max(pe)),
            "mean_rot_error_rad": float(np.mean(re)),
            "max_rot_error_rad": float(np.max(re)),
            "mean_rot_error_by_body_rad": np.mean(rot_body[i, : tracked[i]], axis=0).tolist(),
            **dict(zip(ROT_PART_KEYS, np.mean(rot_parts[i, : tracked[i]], axis=0).tolist(), strict=True)),
            **dict(zip(ROOT_OFFSET_KEYS, np.mean(root_off[i, : tracked[i]], axis=0).tolist(), strict=True)),
            "failed": bool(fail_step[i] > 0),
            "fail_time_s": float(fail_step[i] * dt) if fail_step[i] > 0 else None,
            "fell": bool(fall_step[i] > 0),
            "fall_time_s": float(fall_step[i] * dt) if fall_step[i] > 0 else None,
        })
    return out


def track_clips(
    policy_dir: str | Path | Any = DEFAULT_POLICY_DIR,
    motions: str | Path | MotionLibrary | None = None,
    clips: Sequence[int | str] | int | str | None = None,
    max_seconds: float | None = None,
    seed: int = 0,
    *,
    config: PathTaskConfig | None = None,
    fail_threshold: float = FAIL_THRESHOLD_M,
    stop_on_failure: bool = True,
    batch_size: int = DEFAULT_BATCH,
    device: str = "cpu",
    path_end: str = "extend",
    steering_trim: float | None = None,
    symmetric: bool | None = None,
    pose_sink: list | None = None,
) -> dict[str, Any]:
    """Track reference clips with the deterministic AMP policy in closed loop (see the module doc).

    Args:
        policy_dir: an exported policy (``config.json`` + ``policy.pt``), or a policy already loaded
            (:func:`~navzoo.agents.amp.checkpoint.load_policy`'s result, or a wrapper of it that maps
            observations to actions and has its ``obs_dim``).
        motions: a :class:`MotionLibrary`, a library folder, or None: the packaged library's
            navigation locomotion (the training clips).
        clips: indices or names of the clips to track (default: all of ``motions``).
        max_seconds: track at most this long per clip (None: each clip's full duration).
        seed: seeds numpy and torch (the policy is deterministic and the physics has no noise; kept
            so that runs are reproducible if either ever draws random numbers).
        config: simulation settings (default: :class:`PathTaskConfig`'s, the training ones); only the
            physics/control rates, ``pd_mode``, ``spacing`` and the observation's waypoints are used.
        fail_threshold: per-step mean position error (m) above which a clip fails.
        stop_on_failure: end a clip's rollout at its failure (that step counts in its metrics).
        batch_size: humanoids per PyBullet client.
        device: torch device of the policy.
        path_end: what the target path does after the clip's last frame (the policy looks 5 s ahead, longer
            than most clips): ``"extend"`` (default) continues it at the clip's final root velocity, as a
            clip cut mid-stride walks on; ``"hold"`` holds its last point, i.e. tells the policy to stop
            there, which the clip does not do (the reading until 2026-11-23: with it most failures come in
            the clips' last 10 %). Only the observed targets differ; the comparison with the clip ends with
            the clip either way.
        steering_trim: rad; overrides the policy's steering trim (0 = off; None: the policy's own,
            see :mod:`navzoo.agents.amp.steering`).
        symmetric: make the policy left/right symmetric (:mod:`navzoo.agents.amp.symmetry`; drops the
            steering trim); None: the policy's own setting.
        pose_sink: a list; if given, every control step of every tracked, standing body appends
            (normalised poses (B, 45) as :func:`navzoo.benchmark.realism.poses_from_state`, horizontal root
            speeds (B,) m/s), for the realism of the tracking rollouts.

    Returns:
        The summary dict (keys in the module doc), with ``per_clip`` a list of per-clip dicts. The rollouts run
        on one torch thread whatever the caller's setting, so the result does not depend on the thread count.

    Raises:
        FileNotFoundError: missing policy directory or motion folder / library files.
        ValueError: empty or unknown clip selection, non-positive ``max_seconds`` or ``batch_size``.
    """
    if max_seconds is not None and not (np.isfinite(max_seconds) and max_seconds > 0):
        raise ValueError(f"max_seconds must be positive, got {max_seconds!r}")
    if int(batch_size) < 1:
        raise ValueError(f"batch_size must be >= 1, got {batch_size!r}")
    if not fail_threshold > 0:
        raise ValueError(f"fail_threshold must be positive, got {fail_threshold!r}")
    if path_end not in PATH_ENDS:
        raise ValueError(f"path_end must be one of {PATH_ENDS}, got {path_end!r}")
    cfg = config or PathTaskConfig()
    policy = _load_policy_dir(policy_dir, device) if isinstance(policy_dir, str | Path) else policy_dir
    if steering_trim is not None or symmetric is not None:  # checked by AmpPolicy
        policy.override(steering_trim, symmetric)
    obs_dim = _base_obs_dim(cfg)
    if getattr(policy, "obs_dim", obs_dim) not in (obs_dim, obs_dim + N_RAYS):
        raise ValueError(
            f"policy {policy_dir} expects {policy.obs_dim} observations, this task gives {obs_dim} "
            f"(n_waypoints={cfg.n_waypoints})"
        )
    lib = load_motions(motions)
    idx = _clip_indices(lib, clips)
    np.random.seed(seed)
    import torch

    torch.manual_seed(seed)

    t0 = time.perf_counter()
    per_clip: list[dict[str, Any]] = []
    # one torch thread, however many the caller has: the policy's float sums, and so a few clips' outcomes,
    # depend on the thread count (on the 2-core VM, 2 threads against 1 moved 3 of 78 clips of one checkpoint)
    with one_torch_thread():
        for b in range(0, len(idx), int(batch_size)):
            per_clip += _track_batch(policy, lib, idx[b : b + int(batch_size)], max_seconds, cfg,
                                     float(fail_threshold), bool(stop_on_failure), path_end, pose_sink)
    wall = time.perf_counter() - t0

    def mean(key: str, rows: list[dict[str, Any]]) -> float | None:
        return float(np.mean([r[key] for r in rows])) if rows else None

    ok = [r for r in per_clip if not r["failed"]]
    return {
        "mean_pos_error_m": mean("mean_pos_error_m", per_clip),
        "max_pos_error_m": mean("max_pos_error_m", per_clip),
        "worst_pos_error_m": float(max(r["max_pos_error_m"] for r in per_clip)),
        "mean_rot_error_rad": mean("mean_rot_error_rad", per_clip),
        "clip_success_rate": len(ok) / len(per_clip),
        "fall_rate": float(np.mean([r["fell"] for r in per_clip])),
        "n_clips": len(per_clip),
        "n_failed": len(per_clip) - len(ok),
        "n_fell": int(sum(r["fell"] for r in per_clip)),
        "success_mean_pos_error_m": mean("mean_pos_error_m", ok),
        "success_max_pos_error_m": mean("max_pos_error_m", ok),
        "success_mean_rot_error_rad": mean("mean_rot_error_rad", ok),
        # where the rotation error comes from (rotation_parts), means over clips of the per-clip means
        **{k: mean(k, per_clip) for k in ROT_PART_KEYS},
        # where the root is against the clip's (root_offsets), means over clips of the per-clip means
        **{k: mean(k, per_clip) for k in ROOT_OFFSET_KEYS},
        # mean over clips of each body's mean rotation error (the mean of these is mean_rot_error_rad)
        "mean_rot_error_by_body_rad": dict(zip(LINK_NAMES, np.mean([r["mean_rot_error_by_body_rad"] for r in per_clip],
                                                                  axis=0).tolist(), strict=True)),
        "seconds_simulated": float(sum(r["tracked_s"] for r in per_clip)),
        "seconds_reference": float(sum(r["duration_s"] for r in per_clip)),
        "wall_s": wall,
        "max_seconds": None if max_seconds is None else float(max_seconds),
        "fail_threshold_m": float(fail_threshold),
        "stop_on_failure": bool(stop_on_failure),
        "path_end": path_end,
        "pd_mode": cfg.pd_mode,
        "policy_dir": str(policy_dir) if isinstance(policy_dir, str | Path) else type(policy_dir).__name__,
        "per_clip": per_clip,
    }


# --------------------------------------------------------------------------------------------------
# CLI
# --------------------------------------------------------------------------------------------------


def _parse_clips(text: str | None) -> list[int | str] | None:
    if text is None:
        return None
    out: list[int | str] = []
    for part in text.split(","):
        part = part.strip()
        if part:
            out.append(int(part) if part.lstrip("-").isdigit() else part)
    return out


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("policy_dir", nargs="?", default=str(DEFAULT_POLICY_DIR),
                        help="exported policy directory (default: the shipped policies/amp_pedestrian)")
    parser.add_argument("--motions", default=None,
                        help="motion library folder (default: the packaged library's locomotion clips)")
    parser.add_argument("--clips", default=None, help="comma-separated clip names or indices (default: all)")
    parser.add_argument("--max-seconds", type=float, default=None, help="track at most this long per clip")
    parser.add_argument("--fail-threshold", type=float, default=FAIL_THRESHOLD_M)
    parser.add_argument("--no-stop-on-failure", action="store_true",
                        help="track failed clips to their end (default: a clip's rollout ends at its failure)")
    parser.add_argument("--path-end", choices=PATH_ENDS, default="extend",
                        help="target path after a clip's last frame: extend it at the clip's final root velocity "
                             "(default) or hold its last point (a stop the clip does not make)")
    parser.add_argument("--batch-size", type=int, default=DEFAULT_BATCH)
    parser.add_argument("--steering-trim", type=float, default=None,
                        help="rad; overrides the policy's steering trim (0 = off; default: the policy's own)")
    parser.add_argument("--symmetric", action="store_true",
                        help="make the policy left/right symmetric (averaged with its mirror image; drops the trim)")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--json", action="store_true", help="print the summary as JSON")
    parser.add_argument("--per-clip", action="store_true", help="include the per-clip results")
    args = parser.parse_args(argv)
    try:
        result = track_clips(args.policy_dir, args.motions, _parse_clips(args.clips), args.max_seconds, args.seed,
                             fail_threshold=args.fail_threshold, stop_on_failure=not args.no_stop_on_failure,
                             batch_size=args.batch_size, path_end=args.path_end, steering_trim=args.steering_trim,
                             symmetric=True if args.symmetric else None)
    except (FileNotFoundError, ValueError, TypeError) as e:
        parser.exit(2, f"error: {e}\n")
    if not args.per_clip:
        result.pop("per_clip")
    if args.json:
        print(json.dumps(result))
    else:
        rows = result.pop("per_clip", None)
        by_body = result.pop("mean_rot_error_by_body_rad")
        for key, value in result.items():
            print(f"{key:28s} {value:.4f}" if isinstance(value, float) else f"{key:28s} {value}")
        print("mean_rot_error_by_body_rad   " + "  ".join(f"{k} {v:.3f}" for k, v in by_body.items()))
        for r in rows or ():
            status = "FAIL" if r["failed"] else "ok"
            print(f"  {r['name']:28s} {r['tracked_s']:5.2f}/{r['duration_s']:5.2f} s  pos {r['mean_pos_error_m']:.3f} "
                  f"max {r['max_pos_error_m']:.3f} m  rot {r['mean_rot_error_rad']:.3f} rad  {status}"
                  f"{'  fell' if r['fell'] else ''}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
