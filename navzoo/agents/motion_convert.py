"""Convert the reference motion of ``../shared/data/mocap`` into navzoo's motion library.

Usage (the ``navzoo motions convert`` command wraps :func:`add_arguments` and :func:`run`)::

    python -m navzoo.agents.motion_convert --src ../shared/data/mocap --out navzoo/assets/motions [--json]

Sources and method (``docs/motions.md`` has the details and the measured errors):

- ``amp_humanoid/amp_humanoid_{walk,run,hop}.npy``: already on the same 15-body humanoid (z-up MJCF
  frames). Read with a restricted unpickler; local rotations change frame as ``C^-1 q C`` with
  ``C = R_x(+90 deg)``, the base orientation is ``q_root C``; knees and elbows are projected onto the
  URDF's 1-DoF axis (the projection residual goes into the ankle, so the foot keeps its orientation).
- CMU clips listed in ``cmu/clips.csv`` (ASF/AMC and BVH; ``cmu_bvh/*.bvh`` are excluded as not
  navigation locomotion, see ``EXCLUDED_BVH``): parsed by
  :mod:`navzoo.agents.mocap_io`, then retargeted by aligning bone directions (thigh, shin, foot, upper
  arm, forearm, neck) with the mocap's and taking twist (and the pelvis and chest orientations) from
  the mocap's global joint orientations; knees and elbows are solved in their bending plane.
- Every clip: root trajectory scaled by leg length, start at the origin facing +x, lowest foot on the
  ground, resampled to 30 fps (slerp), finite-difference velocities, plus a mirrored copy.
"""

from __future__ import annotations

import argparse
import csv
import hashlib
import json
import sys
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation

from navzoo.agents import mocap_io
from navzoo.agents.mocap_io import MocapClip, MocapFormatError
from navzoo.agents.motion import HUMANOID_SCALE, HUMANOID_URDF
from navzoo.agents.motion_lib import (
    FIELDS,
    JOINT_ORIGINS,
    Y_UP_TO_Z_UP,
    MotionLibrary,
    compute_velocities,
    foot_corners,
    head_top,
    heading_of,
    humanoid_fk,
    mirror_frames,
    mirror_tags,
    quat_about_z,
    quat_angle,
    quat_canonical,
    quat_conj,
    quat_from_rotvec,
    quat_mul,
    quat_normalize,
    quat_rotate,
    quat_slerp,
)

OUT_FPS = 30.0
CMU_FPS = 120.0

LICENCE_AMP = (
    "AMP humanoid motion from IsaacGymEnvs, BSD-3-Clause (c) NVIDIA Corporation (LICENSE-IsaacGymEnvs.txt); "
    "made from the CMU Graphics Lab Motion Capture Database (mocap.cs.cmu.edu, NSF EIA-0196217). See NOTICE.md."
)
LICENCE_CMU = (
    "CMU Graphics Lab Motion Capture Database (mocap.cs.cmu.edu), free for research and commercial use, "
    "not to be resold as a data set; created with funding from NSF EIA-0196217. See NOTICE.md."
)
LICENCE_BVH11 = (
    LICENCE_CMU + " BVH conversion by B. Hahne; file from the bvh11 repository (MIT, (c) 2018 Yuki Koyama)."
)

AMP_CLIPS = {
    "walk": {"tags": ["walk"], "description": "AMP humanoid walk"},
    "run": {"tags": ["run"], "description": "AMP humanoid run"},
    "hop": {"tags": ["hop"], "description": "AMP humanoid hop"},
}
# BVH files of cmu_bvh/ (not in clips.csv) to convert, with their tags; the others are excluded, with
# the reason found on inspection (docs/motions.md).
EXTRA_BVH: dict[str, dict] = {}
EXCLUDED_BVH = {
    "131_01": "'start, walk, stop' is a stylised performance, not navigation locomotion: the subject kneels "
    "(hips at 0.57 m, left knee 0.13 m above the floor at t = 3 s), raises the right hand above the head "
    "(t = 2 s, 7-8 s) and walks with high knee lifts",
    "131_03": "'start, hop, stop': hopping, not navigation locomotion",
}
# First frame to keep, by clip (data/README.md: frame 0 of cmu/07/*.bvh is an added T-pose; 07_12's
# frame 1 is an all-zero glitch). Glitches near either end found by find_glitches are cut off as well.
START_FRAME_07 = 1
START_FRAME = {"07_12": 2}
# Findings of the inspection of individual clips (docs/motions.md), added to their "notes".
CLIP_NOTES = {
    "16_47": "checked (rendered playback and gait): a walk, not a run; the root is highest when the feet pass "
    "(height/feet-separation correlation -0.76, like all walks); the mocap's right foot stands 3 cm higher than "
    "the left throughout (right ankle 0.114 m vs 0.080-0.093 m in subject 16's other clips): tag uneven_feet",
}

# Mocap (y up, subject facing +z, subject's left +x) -> navzoo world (z up, facing +x, left +y).
_M = np.array([[0.0, 0.0, 1.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]])
_MQ = Rotation.from_matrix(_M).as_quat()
_C = Y_UP_TO_Z_UP  # URDF y-up body frames -> z-up (the AMP/MJCF frames and the world)

_DOWN = np.array([0.0, -1.0, 0.0])
_UP = np.array([0.0, 1.0, 0.0])
_EZ = np.array([0.0, 0.0, 1.0])
# Feet: a flat foot of the mocap must give a flat foot of the humanoid. The CMU calibration (rest) poses
# are not flat-footed (the legs are splayed 20 degrees and the feet roll with them; the ankle -> toe
# bone is only 13 degrees down where a standing foot has it about 20 degrees down), so each
# skeleton's foot offset is calibrated on the frames where the mocap foot stands still (see
# foot_calibration).
FLAT_FOOT_SPEED = 0.15  # m/s: ankle and toe joints both slower than this ...
FLAT_FOOT_HEIGHT = 0.03  # m: ... and within this of their lowest height in the clip
MIN_FLAT_FRAMES = 10
UNEVEN_FEET_M = 0.02  # stance heights of the two feet differing by more than this: tag "uneven_feet"

# Target leg length (hip -> knee -> ankle) of the humanoid.
LEG_LENGTH = float(np.linalg.norm(JOINT_ORIGINS[4]) + np.linalg.norm(JOINT_ORIGINS[5]))

# Semantic joints of the CMU skeletons: the first alias present in a file is used.
_ALIASES: dict[str, tuple[str, ...]] = {
    "hips": ("root", "Hips"),
    "chest": ("thorax", "Spine1", "Chest2"),
    "neck": ("lowerneck", "Neck"),
    "head": ("head", "Head"),
    "head_end": ("head_end", "Head_end"),
}
for _s, _S, _a in (("l", "Left", "L"), ("r", "Right", "R")):
    _ALIASES.update(
        {
            f"{_s}_hip": (f"{_s}femur", f"{_S}UpLeg", f"{_S}Hip"),
            f"{_s}_knee": (f"{_s}tibia", f"{_S}Leg", f"{_S}Knee"),
            f"{_s}_ankle": (f"{_s}foot", f"{_S}Foot", f"{_S}Ankle"),
            f"{_s}_toe": (f"{_s}toes", f"{_S}ToeBase", f"{_S}Toe"),
            f"{_s}_shoulder": (f"{_s}humerus", f"{_S}Arm", f"{_S}Shoulder"),
            f"{_s}_elbow": (f"{_s}radius", f"{_S}ForeArm", f"{_S}Elbow"),
            f"{_s}_wrist": (f"{_s}wrist", f"{_S}Hand", f"{_S}Wrist"),
        }
    )
# Parent-child pairs that must hold (guards against a wrong alias, e.g. BVH "LeftShoulder" = clavicle).
_CHAINS = [
    (f"{s}_{a}", f"{s}_{b}")
    for s in "lr"
    for a, b in (
        ("hip", "knee"),
        ("knee", "ankle"),
        ("ankle", "toe"),
        ("shoulder", "elbow"),
        ("elbow", "wrist"),
    )
]
_CHAINS += [("head", "head_end")]

BONES = (
    "neck",
    "r_thigh",
    "r_shin",
    "r_upper_arm",
    "r_forearm",
    "l_thigh",
    "l_shin",
    "l_upper_arm",
    "l_forearm",
)


def _sha256(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


def _unit(v: np.ndarray) -> np.ndarray:
    n = np.linalg.norm(v, axis=-1, keepdims=True)
    return v / np.maximum(n, 1e-12)


def quat_between(u: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Shortest-arc rotations taking unit vectors ``u`` to ``v`` (broadcast, (..., 3) -> (..., 4))."""
    u, v = np.broadcast_arrays(np.asarray(u, dtype=np.float64), np.asarray(v, dtype=np.float64))
    c = np.cross(u, v)
    d = np.sum(u * v, axis=-1, keepdims=True)
    q = np.concatenate([c, 1.0 + d], axis=-1)
    anti = (1.0 + d[..., 0]) < 1e-9
    if np.any(anti):
        # 180 degrees about any axis perpendicular to u.
        ax = np.cross(u[anti], np.array([1.0, 0.0, 0.0]))
        bad = np.linalg.norm(ax, axis=-1) < 1e-6
        ax[bad] = np.cross(u[anti][bad], np.array([0.0, 1.0, 0.0]))
        q[anti] = np.concatenate([_unit(ax), np.zeros(ax.shape[:-1] + (1,))], axis=-1)
    return quat_normalize(q)


def _angle_between(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Angles (deg) between vectors (..., 3)."""
    a, b = _unit(a), _unit(b)
    return np.degrees(np.arctan2(np.linalg.norm(np.cross(a, b), axis=-1), np.sum(a * b, axis=-1)))


# ----------------------------------------------------------------------------------------------------
# AMP humanoid clips
# ----------------------------------------------------------------------------------------------------

# URDF link -> AMP body (by name: root/chest/neck/shoulder/elbow/wrist/hip/knee/ankle <->
# pelvis/torso/head/upper_arm/lower_arm/hand/thigh/shin/foot).
_AMP_NAMES = {
    "root": "pelvis", "chest": "torso", "neck": "head", "shoulder": "upper_arm", "elbow": "lower_arm",
    "wrist": "hand", "hip": "thigh", "knee": "shin", "ankle": "foot",
}  # fmt: skip
_URDF_LINKS = (
    "root", "chest", "neck", "right_hip", "right_knee", "right_ankle", "right_shoulder", "right_elbow",
    "right_wrist", "left_hip", "left_knee", "left_ankle", "left_shoulder", "left_elbow", "left_wrist",
)  # fmt: skip


def amp_body_of_link(names: list[str]) -> list[int]:
    """For each URDF link, the index of the AMP body of the same role in ``names``."""
    out = []
    for link in _URDF_LINKS:
        side, _, part = link.rpartition("_")
        amp = (f"{side}_" if side else "") + _AMP_NAMES[part]
        if amp not in names:
            raise MocapFormatError(
                f"AMP skeleton has no body {amp!r} (for URDF link {link!r}); bodies: {names}"
            )
        out.append(names.index(amp))
    return out


def _project_hinge(q_local: np.ndarray, lo: float, hi: float) -> tuple[np.ndarray, np.ndarray]:
    """Angle about the URDF z axis that best aligns the child bone (-y) of local rotations ``q_local``.

    Returns ``(angle, residual_deg)``: the residual is the angle between the projected and the
    original child bone direction.
    """
    d = quat_rotate(q_local, _DOWN)
    theta = np.clip(np.arctan2(d[..., 0], -d[..., 1]), lo, hi)
    dp = quat_rotate(quat_about_z(theta), _DOWN)
    return theta, _angle_between(d, dp)


def convert_amp(motion: mocap_io.AmpMotion) -> tuple[dict[str, np.ndarray], dict]:
    """Poses of an AMP clip on the URDF humanoid at the clip's own frame rate (no alignment yet)."""
    amp_of = amp_body_of_link(motion.node_names)
    q = motion.rotation
    cq = np.broadcast_to(_C, q.shape[:1] + (4,))
    local_pb = [quat_mul(quat_mul(quat_conj(cq), q[:, amp_of[j]]), cq) for j in range(15)]
    root_quat = quat_mul(q[:, amp_of[0]], cq)
    knee_lim, elbow_lim = (-np.pi, 0.0), (0.0, np.pi)
    rev, resid = [], {}
    for j, lim in ((4, knee_lim), (7, elbow_lim), (10, knee_lim), (13, elbow_lim)):
        theta, r = _project_hinge(local_pb[j], *lim)
        rev.append(theta)
        resid[_URDF_LINKS[j]] = r
        if j in (4, 10):
            # Keep the foot's orientation: the knee's off-axis part goes into the ankle.
            local_pb[j + 1] = quat_mul(quat_mul(quat_conj(quat_about_z(theta)), local_pb[j]), local_pb[j + 1])
    sph = np.stack([local_pb[j] for j in (1, 2, 3, 5, 6, 9, 11, 12)], axis=1)
    frames = {
        "root_pos": motion.root_translation.copy(),
        "root_quat": quat_canonical(root_quat),
        "sph": quat_canonical(sph),
        "rev": np.stack(rev, axis=1),
    }
    # Check: the clip's own FK against the humanoid's, body by body (both skeletons have the same
    # segment lengths; the scale fitted below reports it).
    amp_pos, _ = motion.fk()
    pos, _ = humanoid_fk(frames["root_pos"], frames["root_quat"], frames["sph"], frames["rev"])
    amp_pos = amp_pos[:, amp_of]
    rel_a = amp_pos - amp_pos[:, :1]
    rel_h = pos - pos[:, :1]
    scale = float(np.sum(rel_a * rel_h) / np.sum(rel_h * rel_h))
    err = np.linalg.norm(rel_h * scale - rel_a, axis=-1)
    diag = {
        "fk_scale": round(scale, 5),
        "fk_err_mean_m": float(err.mean()),
        "fk_err_max_m": float(err.max()),
        "fk_err_per_body_m": {_URDF_LINKS[j]: round(float(err[:, j].mean()), 5) for j in range(15)},
        "hinge_residual_deg": {
            k: {"mean": round(float(v.mean()), 3), "max": round(float(v.max()), 3)} for k, v in resid.items()
        },
    }
    return frames, diag


# ----------------------------------------------------------------------------------------------------
# CMU retargeting
# ----------------------------------------------------------------------------------------------------


def resolve_joints(clip: MocapClip) -> dict[str, int]:
    """Semantic joint -> joint index of ``clip``'s skeleton (raises naming the file if one is missing)."""
    out = {}
    for key, names in _ALIASES.items():
        hit = next((n for n in names if n in clip.index), None)
        if hit is None:
            raise MocapFormatError(f"{clip.path}: no joint for {key!r} (tried {', '.join(names)})")
        out[key] = clip.index[hit]
    for a, b in _CHAINS:
        if clip.parents[out[b]] != out[a]:
            raise MocapFormatError(
                f"{clip.path}: joint {clip.names[out[b]]!r} ({b}) is not a child of {clip.names[out[a]]!r} ({a})"
            )
    return out


def find_glitches(clip: MocapClip, step_min: float = 0.015, ratio: float = 4.0) -> np.ndarray:
    """Frames ``i`` where a joint the retargeting uses jumps between frames ``i`` and ``i + 1``: a step
    longer than ``step_min`` (m) and ``ratio`` times the median step of the 7 frames around it (plus
    5 mm). Single-frame marker glitches of the CMU data show up this way."""
    from scipy.ndimage import median_filter

    jn = resolve_joints(clip)
    pos, _ = clip.fk()
    pos = pos[:, sorted(set(jn.values()))]
    step = np.linalg.norm(np.diff(pos, axis=0), axis=-1)
    med = median_filter(step, size=(7, 1), mode="nearest")
    return np.unique(np.nonzero((step > step_min) & (step > ratio * med + 0.005))[0])


def trim_edge_glitches(clip: MocapClip, edge_s: float = 0.1) -> tuple[int, int, list[int]]:
    """(start, stop, glitches): frames to keep so that no glitch lies within ``edge_s`` of either end
    (glitches there are cut off), and the glitch frames left inside (reported, not repaired)."""
    g = find_glitches(clip)
    edge = int(round(edge_s * clip.fps))
    n = clip.n_frames
    start = int(g[g < edge].max()) + 1 if np.any(g < edge) else 0
    stop = int(g[g >= n - 1 - edge].min()) + 1 if np.any(g >= n - 1 - edge) else n
    inner = [int(i) for i in g if start <= i < stop - 1]
    return start, stop, inner


@dataclass
class _Source:
    """A CMU clip in the navzoo world frame (z up): joint positions, global rotations, rest pose."""

    jn: dict[str, int]
    pos: np.ndarray  # (T, J, 3)
    rot: np.ndarray  # (T, J, 4)
    rest: np.ndarray  # (J, 3) rest-pose joint positions
    fps: float

    def p(self, key: str) -> np.ndarray:
        return self.pos[:, self.jn[key]]

    def g(self, key: str) -> np.ndarray:
        return self.rot[:, self.jn[key]]


def _source(clip: MocapClip) -> _Source:
    jn = resolve_joints(clip)
    p_m, g_m = clip.fk()
    mq = np.broadcast_to(_MQ, g_m.shape)
    rest = np.zeros_like(clip.offsets)
    for j, par in enumerate(clip.parents):
        rest[j] = clip.offsets[j] + (rest[par] if par >= 0 else 0.0)
    return _Source(jn, p_m @ _M.T, quat_mul(quat_mul(mq, g_m), quat_conj(mq)), rest @ _M.T, clip.fps)


def _flat_frames(src: _Source, side: str) -> np.ndarray:
    """Frames where the mocap's ``side`` foot stands flat and still on the ground."""
    a, b = src.p(f"{side}_ankle"), src.p(f"{side}_toe")
    va = np.linalg.norm(np.gradient(a[:, :2], 1.0 / src.fps, axis=0), axis=1)
    vb = np.linalg.norm(np.gradient(b[:, :2], 1.0 / src.fps, axis=0), axis=1)
    low = (a[:, 2] < a[:, 2].min() + FLAT_FOOT_HEIGHT) & (b[:, 2] < b[:, 2].min() + FLAT_FOOT_HEIGHT)
    return np.flatnonzero((va < FLAT_FOOT_SPEED) & (vb < FLAT_FOOT_SPEED) & low)


def _level(r: np.ndarray) -> np.ndarray:
    """The level foot orientation (URDF y up, sole horizontal) with the heading of foot orientations ``r``."""
    f = quat_rotate(r, np.array([1.0, 0.0, 0.0]))
    yaw = np.arctan2(f[:, 1], f[:, 0])
    return quat_mul(quat_about_z(yaw), np.broadcast_to(_C, r.shape))


def foot_calibration(clip: MocapClip) -> dict[str, tuple[np.ndarray, int]]:
    """Per foot (``"l"``, ``"r"``): the sum of the offsets that make the humanoid's foot level on the
    mocap's flat-foot frames (quaternions in the foot frame, sign-aligned, to be pooled over the clips of
    one skeleton and normalised) and the number of such frames."""
    src = _source(clip)
    out = {}
    for s in "lr":
        idx = _flat_frames(src, s)
        if idx.size == 0:
            out[s] = (np.zeros(4), 0)
            continue
        raw = quat_mul(src.g(f"{s}_ankle")[idx], np.broadcast_to(_C, (idx.size, 4)))
        off = quat_mul(quat_conj(raw), _level(raw))
        off = np.where(off[:, 3:] < 0, -off, off)
        out[s] = (off.sum(axis=0), int(idx.size))
    return out


def pool_foot_calibrations(cals: list[dict[str, tuple[np.ndarray, int]]]) -> dict[str, np.ndarray]:
    """Average foot offsets over clips of one skeleton (identity for a foot with too few flat frames)."""
    out = {}
    for s in "lr":
        tot = sum(c[s][0] for c in cals)
        n = sum(c[s][1] for c in cals)
        out[s] = quat_normalize(tot) if n >= MIN_FLAT_FRAMES else np.array([0.0, 0.0, 0.0, 1.0])
    return out


@dataclass
class Retargeted:
    frames: dict[str, np.ndarray]  # root_pos, root_quat, sph, rev at the source rate
    bone_err_deg: dict[str, np.ndarray]  # per bone, per frame
    pos_err_m: dict[
        str, np.ndarray
    ]  # per joint, per frame: position relative to the root vs the scaled mocap
    foot_tilt_deg: np.ndarray  # humanoid foot tilt from level on the mocap's flat-foot frames
    hinge_clipped: int
    scale: float
    planted_skate_mps: float  # humanoid heel/toe speed where the mocap's is planted
    planted_skate_src_mps: float  # the mocap joints' own speed on those frames


def _hinge_solve(r_up, d1, d2, knee: bool):
    """Twist the upper bone about itself so its hinge bends in the plane of (d1, d2); solve the angle.

    The twist correction fades in between 5 and 20 degrees of bend (the plane is undefined for a
    straight limb, where the mocap's own twist is kept).
    """
    n = quat_rotate(r_up, _EZ)
    d2p = d2 - np.sum(d2 * d1, axis=-1, keepdims=True) * d1
    s = np.linalg.norm(d2p, axis=-1)
    bend = np.arctan2(s, np.sum(d1 * d2, axis=-1))
    n_star = _unit(np.cross(d1, d2p)) * (-1.0 if knee else 1.0)
    phi = np.arctan2(np.sum(np.cross(n, n_star) * d1, axis=-1), np.sum(n * n_star, axis=-1))
    x = np.clip((np.degrees(bend) - 5.0) / 15.0, 0.0, 1.0)
    w = x * x * (3 - 2 * x)
    r_up = quat_mul(quat_from_rotvec(d1 * (w * phi)[:, None]), r_up)
    dl = quat_rotate(quat_conj(r_up), d2)
    theta = np.arctan2(dl[:, 0], -dl[:, 1])
    lo, hi = (-np.pi, 0.0) if knee else (0.0, np.pi)
    clipped = int(np.sum((theta < lo - 1e-9) | (theta > hi + 1e-9)))
    theta = np.clip(theta, lo, hi)
    r_low = quat_mul(r_up, quat_about_z(theta))
    return r_up, theta, r_low, clipped


def retarget_cmu(clip: MocapClip, foot_offsets: dict[str, np.ndarray] | None = None) -> Retargeted:
    """Retarget a CMU clip onto the humanoid at the clip's frame rate (world z up, not yet aligned).

    Args:
        clip: the mocap clip.
        foot_offsets: per foot, the flat-foot calibration of the clip's skeleton
            (:func:`pool_foot_calibrations`); default: calibrated on this clip alone.
    """
    if foot_offsets is None:
        foot_offsets = pool_foot_calibrations([foot_calibration(clip)])
    src = _source(clip)
    t = clip.n_frames
    w = _C
    wt = np.broadcast_to(w, (t, 4))

    def dir_body(a: str, b: str, twist: str, u: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Orientation whose bone ``u`` (URDF frame) points from joint a to b, twist from joint ``twist``."""
        d_rest = _unit(src.rest[src.jn[b]] - src.rest[src.jn[a]])
        q_off = quat_mul(quat_between(quat_rotate(w, u), d_rest), w)
        cand = quat_mul(src.g(twist), np.broadcast_to(q_off, (t, 4)))
        d = _unit(src.p(b) - src.p(a))
        return quat_mul(quat_between(quat_rotate(cand, u), d), cand), d

    r_root = quat_mul(src.g("hips"), wt)
    r_chest = quat_mul(src.g("chest"), wt)
    r_neck, d_neck = dir_body("neck", "head_end", "head", _UP)
    glob = {"neck": (r_neck, d_neck)}
    rev = {}
    clipped = 0
    tilt = []
    for s in "rl":
        r_th, d1 = dir_body(f"{s}_hip", f"{s}_knee", f"{s}_hip", _DOWN)
        d2 = _unit(src.p(f"{s}_ankle") - src.p(f"{s}_knee"))
        r_th, th_k, r_sh, c1 = _hinge_solve(r_th, d1, d2, knee=True)
        r_ft = quat_mul(quat_mul(src.g(f"{s}_ankle"), wt), np.broadcast_to(foot_offsets[s], (t, 4)))
        r_ua, d3 = dir_body(f"{s}_shoulder", f"{s}_elbow", f"{s}_shoulder", _DOWN)
        d4 = _unit(src.p(f"{s}_wrist") - src.p(f"{s}_elbow"))
        r_ua, th_e, r_fa, c2 = _hinge_solve(r_ua, d3, d4, knee=False)
        clipped += c1 + c2
        glob.update(
            {
                f"{s}_thigh": (r_th, d1), f"{s}_shin": (r_sh, d2), f"{s}_foot": (r_ft, None),
                f"{s}_upper_arm": (r_ua, d3), f"{s}_forearm": (r_fa, d4),
            }
        )  # fmt: skip
        rev[f"{s}_knee"], rev[f"{s}_elbow"] = th_k, th_e
        flat = _flat_frames(src, s)
        tilt.append(_angle_between(quat_rotate(r_ft[flat], _UP), np.array([0.0, 0.0, 1.0])))

    def local(parent: np.ndarray, child: np.ndarray) -> np.ndarray:
        return quat_mul(quat_conj(parent), child)

    sph = np.stack(
        [
            local(r_root, r_chest),
            local(r_chest, r_neck),
            local(r_root, glob["r_thigh"][0]),
            local(glob["r_shin"][0], glob["r_foot"][0]),
            local(r_chest, glob["r_upper_arm"][0]),
            local(r_root, glob["l_thigh"][0]),
            local(glob["l_shin"][0], glob["l_foot"][0]),
            local(r_chest, glob["l_upper_arm"][0]),
        ],
        axis=1,
    )
    revs = np.stack([rev["r_knee"], rev["r_elbow"], rev["l_knee"], rev["l_elbow"]], axis=1)
    # Root: the midpoint of the hip joints, scaled by the leg-length ratio.
    rest, jn = src.rest, src.jn
    src_leg = np.mean(
        [
            np.linalg.norm(rest[jn[f"{s}_knee"]] - rest[jn[f"{s}_hip"]])
            + np.linalg.norm(rest[jn[f"{s}_ankle"]] - rest[jn[f"{s}_knee"]])
            for s in "lr"
        ]
    )
    scale = LEG_LENGTH / src_leg
    mid_hip = 0.5 * (src.p("l_hip") + src.p("r_hip"))
    frames = {
        "root_pos": scale * mid_hip,
        "root_quat": quat_canonical(quat_normalize(r_root)),
        "sph": quat_canonical(quat_normalize(sph)),
        "rev": revs,
    }
    # Bone-direction errors of the result (by the humanoid's own FK) against the mocap.
    lp, lq = humanoid_fk(frames["root_pos"], frames["root_quat"], frames["sph"], frames["rev"])
    tgt = {"neck": quat_rotate(lq[:, 2], _UP)}
    for s, side in (("r", 0), ("l", 6)):
        hip, knee, ankle, sh, el, wr = (3 + side, 4 + side, 5 + side, 6 + side, 7 + side, 8 + side)
        tgt[f"{s}_thigh"] = lp[:, knee] - lp[:, hip]
        tgt[f"{s}_shin"] = lp[:, ankle] - lp[:, knee]
        tgt[f"{s}_upper_arm"] = lp[:, el] - lp[:, sh]
        tgt[f"{s}_forearm"] = lp[:, wr] - lp[:, el]
    errs = {b: _angle_between(tgt[b], glob[b][1]) for b in BONES}
    # Diagnostic (not aligned by construction): pelvis -> neck base, the whole trunk.
    errs["trunk"] = _angle_between(lp[:, 2] - lp[:, 0], src.p("neck") - mid_hip)
    # Joint positions relative to the root against the mocap's, scaled by the leg-length ratio: what
    # remains are the differences of proportions (arm and trunk lengths) and of the trunk's shape.
    pos_err = {}
    for key, link in (
        ("r_knee", 4),
        ("r_ankle", 5),
        ("r_elbow", 7),
        ("r_wrist", 8),
        ("l_knee", 10),
        ("l_ankle", 11),
        ("l_elbow", 13),
        ("l_wrist", 14),
        ("neck", 2),
    ):
        pos_err[key] = np.linalg.norm((lp[:, link] - lp[:, 0]) - scale * (src.p(key) - mid_hip), axis=-1)
    return Retargeted(
        frames, errs, pos_err, np.concatenate(tilt), clipped, float(scale), *_planted_skate(src, lp, lq)
    )


def _planted_skate(
    src: _Source, lp: np.ndarray, lq: np.ndarray, v_max: float = 0.2, dh: float = 0.03
) -> tuple[float, float]:
    """Foot skating caused by retargeting: on the frames where the mocap's ankle (heel) or toe joint is
    planted (slower than ``v_max`` horizontally, within ``dh`` of its lowest height), the mean horizontal
    speed of the humanoid's heel (back bottom edge) or toe (front bottom edge), and of the mocap joint."""
    corners = foot_corners(lp, lq)  # (T, 2 [r, l], 8, 3); corner 4*(front) + 2*(top) + (side)
    tgt, ref = [], []
    for f, s in ((0, "r"), (1, "l")):
        for joint, edge in (("ankle", (0, 1)), ("toe", (4, 5))):
            j = src.p(f"{s}_{joint}")
            vj = np.linalg.norm(np.gradient(j[:, :2], 1.0 / src.fps, axis=0), axis=1)
            planted = (vj < v_max) & (j[:, 2] < j[:, 2].min() + dh)
            e = corners[:, f, list(edge), :2].mean(axis=1)
            ve = np.linalg.norm(np.gradient(e, 1.0 / src.fps, axis=0), axis=1)
            tgt.append(ve[planted])
            ref.append(vj[planted])
    t, r = np.concatenate(tgt), np.concatenate(ref)
    return (float(t.mean()) if t.size else 0.0), (float(r.mean()) if r.size else 0.0)


# ----------------------------------------------------------------------------------------------------
# Post-processing shared by all sources
# ----------------------------------------------------------------------------------------------------


def align_start(frames: dict[str, np.ndarray], fps: float, window_s: float = 0.5) -> dict[str, np.ndarray]:
    """Rotate about z and translate so the root starts at (0, 0) facing +x (mean heading over the
    first ``window_s`` seconds, which averages out the pelvis' sway)."""
    n = max(1, min(frames["root_pos"].shape[0], int(round(window_s * fps))))
    h = heading_of(frames["root_quat"][:n])
    yaw0 = float(np.arctan2(np.sin(h).mean(), np.cos(h).mean()))
    qz = quat_about_z(np.array(-yaw0))
    p = frames["root_pos"].copy()
    p[:, :2] -= p[0, :2]
    out = dict(frames)
    out["root_pos"] = quat_rotate(np.broadcast_to(qz, p.shape[:1] + (4,)), p)
    out["root_quat"] = quat_mul(qz, frames["root_quat"])
    return out


def ground(
    frames: dict[str, np.ndarray],
    fps: float,
    percentile: float = 5.0,
    window_s: float = 0.6,
    min_drift: float = 0.01,
) -> tuple[dict[str, np.ndarray], dict]:
    """Put the feet on the ground: remove a linear vertical drift, then shift the root so that the
    ``percentile``-th percentile of the lowest foot point (per frame, both feet) is at z = 0.

    A low percentile rather than the minimum keeps single-frame mocap glitches (a foot marker jumping
    for a few frames) from lifting the whole clip; the remaining penetration is reported per clip
    (``metrics.foot_min_h_m``). The drift is the slope of a line fitted to the lower foot's minima over
    consecutive windows of ``window_s`` (each window holds at least one stance, even when running); it
    is removed only if it amounts to more than ``min_drift`` over the clip (the AMP walk climbs 7 cm in
    2.5 s, subject 07's floor rises 2-4 cm/s along the walk).
    """
    lp, lq = humanoid_fk(frames["root_pos"], frames["root_quat"], frames["sph"], frames["rev"])
    h = foot_corners(lp, lq)[..., 2].min(axis=(-1, -2))
    n = h.shape[0]
    t = np.arange(n) / fps
    w = max(2, int(round(window_s * fps)))
    idx = np.array([i + int(np.argmin(h[i : i + w])) for i in range(0, n - w // 2, w)])
    slope = 0.0
    if idx.size >= 3:
        slope = float(np.polyfit(t[idx], h[idx], 1)[0])
        if abs(slope) * t[-1] < min_drift:
            slope = 0.0
    z = -slope * (t - t.mean())
    dz = -float(np.percentile(h + z, percentile))
    out = dict(frames)
    out["root_pos"] = frames["root_pos"] + np.stack([np.zeros(n), np.zeros(n), z + dz], axis=1)
    return out, {"ground_offset_m": round(dz, 4), "ground_drift_m_per_s": round(slope, 4)}


def resample(frames: dict[str, np.ndarray], fps_in: float, fps_out: float) -> dict[str, np.ndarray]:
    """Resample poses to ``fps_out`` (slerp for quaternions, lerp otherwise), keeping the duration's
    whole frames."""
    n = frames["root_pos"].shape[0]
    dur = (n - 1) / fps_in
    m = int(np.floor(dur * fps_out + 1e-6)) + 1
    f = np.arange(m) * (fps_in / fps_out)
    i0 = np.minimum(np.floor(f + 1e-9).astype(int), n - 2)
    a = np.clip(f - i0, 0.0, 1.0)
    i1 = i0 + 1
    return {
        "root_pos": (1 - a)[:, None] * frames["root_pos"][i0] + a[:, None] * frames["root_pos"][i1],
        "root_quat": quat_canonical(quat_slerp(frames["root_quat"][i0], frames["root_quat"][i1], a)),
        "sph": quat_canonical(quat_slerp(frames["sph"][i0], frames["sph"][i1], a[:, None])),
        "rev": (1 - a)[:, None] * frames["rev"][i0] + a[:, None] * frames["rev"][i1],
    }


def finish(
    frames: dict[str, np.ndarray], fps_in: float, fps_out: float = OUT_FPS
) -> tuple[dict[str, np.ndarray], dict]:
    """Align, ground, resample and add velocities. Returns (frames, ground correction)."""
    fr = align_start(frames, fps_in)
    fr, dz = ground(fr, fps_in)
    fr = resample(fr, fps_in, fps_out) if abs(fps_in - fps_out) > 1e-9 else fr
    fr.update(compute_velocities(fr, fps_out))
    return {k: fr[k] for k in FIELDS}, dz


def clip_metrics(frames: dict[str, np.ndarray], fps: float, contact_h: float = 0.02) -> dict:
    """Locomotion measures of one finished clip (world frame, z up).

    - ``speed_mps``: root path length on the ground / duration; ``median_speed_mps`` of the per-frame
      planar root speed.
    - ``foot_skate_mps`` (median) and ``foot_skate_mean_mps``: horizontal speed of a foot's lowest
      point while that foot is in contact (lowest point < ``contact_h`` above the ground). The mean
      includes the landing frames (a heel touching down while still moving forward); the median is the
      typical slip of a planted foot. ``foot_lower_h_mean_m``: mean height of the lower foot.
    - ``flight_frac``: fraction of frames with both feet above ``contact_h`` + 1 cm (runs > 0, walks 0);
      ``double_support_frac``: both feet in contact.
    - ``head_top_m``: median crown height.
    """
    lp, lq = humanoid_fk(frames["root_pos"], frames["root_quat"], frames["sph"], frames["rev"])
    corners = foot_corners(lp, lq)  # (T, 2, 8, 3)
    h = corners[..., 2].min(axis=-1)  # (T, 2)
    k = corners[..., 2].argmin(axis=-1)  # (T, 2)
    # Velocity of the same corner point (central difference), per foot and frame.
    cv = np.gradient(corners[..., :2], 1.0 / fps, axis=0)  # (T, 2, 8, 2)
    ti, fi = np.meshgrid(np.arange(h.shape[0]), np.arange(2), indexing="ij")
    v = np.linalg.norm(cv[ti, fi, k], axis=-1)
    contact = h < contact_h
    pxy = frames["root_pos"][:, :2]
    step = np.linalg.norm(np.diff(pxy, axis=0), axis=1)
    dur = (pxy.shape[0] - 1) / fps
    planar = np.linalg.norm(frames["root_lin_vel"][:, :2], axis=1)
    # Stance height of each foot (ankle link slower than 0.3 m/s): a walk has both near the ground.
    va = np.linalg.norm(np.gradient(lp[:, [5, 11], :2], 1.0 / fps, axis=0), axis=-1)
    stance_h = [
        float(np.median(h[va[:, k] < 0.3, k])) if np.any(va[:, k] < 0.3) else float("nan") for k in range(2)
    ]
    # Gait: in a walk the root is highest when the feet pass each other (inverted pendulum), in a run
    # it is lowest then (spring-mass): the correlation of root height and feet separation is < 0 / > 0.
    sep = np.linalg.norm(lp[:, 5, :2] - lp[:, 11, :2], axis=1)
    zr = frames["root_pos"][:, 2]
    zr = zr - np.polyval(np.polyfit(np.arange(zr.size), zr, 1), np.arange(zr.size))
    gait_corr = float(np.corrcoef(zr, sep)[0, 1]) if np.std(sep) > 1e-6 and np.std(zr) > 1e-6 else 0.0
    hd = heading_of(frames["root_quat"])
    turn = np.degrees(np.sum(np.angle(np.exp(1j * np.diff(hd)))))
    return {
        "duration_s": round(dur, 4),
        "speed_mps": round(float(step.sum() / dur), 4),
        "median_speed_mps": round(float(np.median(planar)), 4),
        "net_displacement_m": round(float(np.linalg.norm(pxy[-1] - pxy[0])), 4),
        "heading_change_deg": round(float(turn), 2),
        "foot_skate_mps": round(float(np.median(v[contact])) if contact.any() else 0.0, 4),
        "foot_skate_mean_mps": round(float(v[contact].mean()) if contact.any() else 0.0, 4),
        "foot_contact_frac": round(float(contact.any(axis=1).mean()), 4),
        "double_support_frac": round(float(contact.all(axis=1).mean()), 4),
        "flight_frac": round(float((h > contact_h + 0.01).all(axis=1).mean()), 4),
        "foot_lower_h_mean_m": round(float(h.min(axis=1).mean()), 4),
        "foot_min_h_m": round(float(h.min()), 4),
        "head_top_median_m": round(float(np.median(head_top(lp, lq))), 4),
        "stance_h_right_m": round(stance_h[0], 4),
        "stance_h_left_m": round(stance_h[1], 4),
        "gait_height_sep_corr": round(gait_corr, 3),
    }


def _loop_quality(frames: dict[str, np.ndarray]) -> float:
    """Mean joint rotation difference (rad) between the last and the first frame."""
    a = quat_angle(quat_mul(quat_conj(frames["sph"][0]), frames["sph"][-1])).mean()
    b = np.abs(frames["rev"][-1] - frames["rev"][0]).mean()
    return float((8 * a + 4 * b) / 12)


# ----------------------------------------------------------------------------------------------------
# The whole conversion
# ----------------------------------------------------------------------------------------------------


# Tags implied by clips.csv's tags (so that select(tags="walk") finds slow and brisk walks too).
_IMPLIED_TAGS = {"walk_slow": "walk", "walk_fast": "walk"}


def _tags(csv_tags: str) -> list[str]:
    tags = ["cmu"]
    for t in (t.strip() for t in csv_tags.split(";")):
        if t and t not in tags:
            tags.append(t)
        if t in _IMPLIED_TAGS and _IMPLIED_TAGS[t] not in tags:
            tags.insert(1, _IMPLIED_TAGS[t])
    return tags


def _read_clips_csv(path: Path) -> list[dict]:
    if not path.is_file():
        raise MocapFormatError(f"clip list not found: {path}")
    try:
        with open(path, newline="") as f:
            rows = list(csv.DictReader(f))
    except (OSError, csv.Error, UnicodeDecodeError) as exc:
        raise MocapFormatError(f"cannot read clip list {path}: {exc}") from exc
    need = {"subject", "clip", "format", "cmu_description", "tags", "mean_speed_mps", "sha256"}
    if not rows or not need <= set(rows[0]):
        raise MocapFormatError(f"{path}: expected columns {sorted(need)}")
    return rows


def _check_sha(path: Path, expected: str | None) -> str:
    if not path.is_file():
        raise MocapFormatError(f"mocap file not found: {path}")
    digest = _sha256(path)
    if expected and digest != expected:
        raise MocapFormatError(
            f"{path}: sha256 {digest[:12]}... does not match clips.csv ({expected[:12]}...)"
        )
    return digest


def _pybullet_fk_check(frames: dict[str, np.ndarray], stride: int = 1) -> float:
    """Max distance (m) between :func:`humanoid_fk` link frames and PyBullet's for the given poses."""
    import pybullet as p

    from navzoo.sim import connect, disconnect, quiet

    cid = connect()
    try:
        with quiet():
            body = p.loadURDF(
                HUMANOID_URDF,
                [0, 0, 1],
                globalScaling=HUMANOID_SCALE,
                flags=p.URDF_MAINTAIN_LINK_ORDER,
                physicsClientId=cid,
            )
        lib_pos, _ = humanoid_fk(frames["root_pos"], frames["root_quat"], frames["sph"], frames["rev"])
        joints = [1, 2, 3, 4, 5, 6, 7, 9, 10, 11, 12, 13]
        worst = 0.0
        for i in range(0, frames["root_pos"].shape[0], stride):
            p.resetBasePositionAndOrientation(
                body, frames["root_pos"][i].tolist(), frames["root_quat"][i].tolist(), physicsClientId=cid
            )
            s, r = frames["sph"][i].tolist(), frames["rev"][i].tolist()
            p.resetJointStatesMultiDof(
                body,
                joints,
                [s[0], s[1], s[2], [r[0]], s[3], s[4], [r[1]], s[5], [r[2]], s[6], s[7], [r[3]]],
                physicsClientId=cid,
            )
            st = p.getLinkStates(body, list(range(15)), computeForwardKinematics=True, physicsClientId=cid)
            pb = np.array([x[4] for x in st])
            worst = max(worst, float(np.abs(pb - lib_pos[i]).max()))
        return worst
    finally:
        disconnect(cid)


def build_library(
    src: str | Path, fps: float = OUT_FPS, mirror: bool = True, pybullet_check: bool = True
) -> tuple[MotionLibrary, dict]:
    """Convert everything under ``src`` (``../shared/data/mocap``). Returns the library and a summary."""
    src = Path(src)
    if not src.is_dir():
        raise MocapFormatError(f"mocap source folder not found: {src}")
    clips: list[tuple[dict, dict[str, np.ndarray]]] = []
    excluded: list[dict] = []
    amp_diag: dict = {}

    def add(meta: dict, frames: dict[str, np.ndarray]) -> None:
        meta["n_frames"] = int(frames["root_pos"].shape[0])
        meta["duration_s"] = round((meta["n_frames"] - 1) / fps, 4)
        meta["metrics"] = m = clip_metrics(frames, fps)
        if (
            abs(m["stance_h_right_m"] - m["stance_h_left_m"]) > UNEVEN_FEET_M
            and "uneven_feet" not in meta["tags"]
        ):
            meta["tags"] = [*meta["tags"], "uneven_feet"]
        clips.append((meta, frames))

    # --- AMP humanoid -------------------------------------------------------------------------------
    amp_dir = src / "amp_humanoid"
    for key, info in AMP_CLIPS.items():
        path = amp_dir / f"amp_humanoid_{key}.npy"
        motion = mocap_io.load_amp_npy(path)
        frames, diag = convert_amp(motion)
        if pybullet_check:
            diag["pybullet_fk_max_err_m"] = _pybullet_fk_check(frames)
        out, dz = finish(frames, motion.fps, fps)
        loop_err = _loop_quality(out)
        diag["loop_pose_diff_rad"] = round(loop_err, 4)
        amp_diag[key] = diag
        add(
            {
                "name": f"amp_{key}",
                "source": f"amp_humanoid/{path.name}",
                "source_sha256": _sha256(path),
                "format": "amp_npy",
                "description": info["description"],
                "tags": ["amp", *info["tags"]],
                "fps": fps,
                "source_fps": motion.fps,
                "source_frames": [0, motion.n_frames],
                "mirrored": False,
                "loop": False,
                "licence": LICENCE_AMP,
                **dz,
                "scale": 1.0,
                "validation": {
                    k: diag[k]
                    for k in (
                        "fk_err_mean_m",
                        "fk_err_max_m",
                        "pybullet_fk_max_err_m",
                        "hinge_residual_deg",
                        "loop_pose_diff_rad",
                    )
                    if k in diag
                },
            },
            out,
        )

    # --- CMU (clips.csv) ---------------------------------------------------------------------------
    cmu = src / "cmu"
    rows = _read_clips_csv(cmu / "clips.csv")
    skeletons: dict[str, tuple[mocap_io.AsfSkeleton, str]] = {}
    for row in rows:
        if row["format"] == "asf":
            path = cmu / row["subject"] / f"{row['clip']}.asf"
            sha = _check_sha(path, row["sha256"])
            skeletons[row["subject"]] = (mocap_io.parse_asf(path), sha)
    cmu_jobs = []
    for row in rows:
        fmt = row["format"]
        if fmt == "asf":
            continue
        name = row["clip"]
        path = cmu / row["subject"] / f"{name}.{fmt}"
        sha = _check_sha(path, row["sha256"])
        meta = {
            "name": f"cmu_{name}",
            "source": f"cmu/{row['subject']}/{path.name}",
            "source_sha256": sha,
            "format": fmt,
            "subject": row["subject"],
            "description": row["cmu_description"],
            "tags": _tags(row["tags"]),
            "csv_mean_speed_mps": float(row["mean_speed_mps"]) if row["mean_speed_mps"] else None,
            "licence": LICENCE_CMU,
        }
        if row.get("notes"):
            meta["notes"] = row["notes"]
        if fmt == "amc":
            if row["subject"] not in skeletons:
                raise MocapFormatError(f"{path}: no skeleton {row['subject']}.asf listed in clips.csv")
            sk, sk_sha = skeletons[row["subject"]]
            meta["skeleton"] = f"cmu/{row['subject']}/{row['subject']}.asf"
            meta["skeleton_sha256"] = sk_sha
            clip = mocap_io.parse_amc(path, sk, fps=CMU_FPS)
            start = 0
            meta["_start"] = 0
        elif fmt == "bvh":
            clip = mocap_io.parse_bvh(path)
            start = START_FRAME.get(name, START_FRAME_07)
            meta["_start"] = start
        else:
            raise MocapFormatError(f"{cmu / 'clips.csv'}: unknown format {fmt!r} for clip {name}")
        cmu_jobs.append((meta, clip.slice(start), row["subject"]))
    for path in sorted((src / "cmu_bvh").glob("*.bvh")):
        name = path.stem
        if name in EXCLUDED_BVH:
            excluded.append({"file": f"cmu_bvh/{path.name}", "reason": EXCLUDED_BVH[name]})
            continue
        if name not in EXTRA_BVH:
            excluded.append({"file": f"cmu_bvh/{path.name}", "reason": "not a known locomotion clip"})
            continue
        meta = {
            "name": f"cmu_{name}",
            "source": f"cmu_bvh/{path.name}",
            "source_sha256": _sha256(path),
            "format": "bvh",
            "subject": name.split("_")[0],
            "description": EXTRA_BVH[name]["description"],
            "tags": ["cmu", *EXTRA_BVH[name]["tags"]],
            "csv_mean_speed_mps": None,
            "licence": LICENCE_BVH11,
        }
        cmu_jobs.append((meta, mocap_io.parse_bvh(path), f"bvh_{name}"))

    # Flat-foot calibration per skeleton (a subject's ASF, or a BVH file's own skeleton).
    for k, (meta, clip, key) in enumerate(cmu_jobs):
        if clip.n_frames < 2:
            raise MocapFormatError(f"{clip.path}: fewer than 2 frames")
        jump = np.linalg.norm(np.diff(clip.root_pos, axis=0), axis=1).max() * clip.fps
        if jump > 15.0:
            raise MocapFormatError(
                f"{clip.path}: root jumps at {jump:.1f} m/s between two frames (glitch frame?)"
            )
        a, b, inner = trim_edge_glitches(clip)
        if b - a < clip.fps:
            raise MocapFormatError(f"{clip.path}: under a second left after cutting glitches at the ends")
        base = int(meta.get("_start", 0))
        meta["_start"] = base + a
        if a > 0 or b < clip.n_frames:
            meta["trimmed_glitch_frames"] = [a, clip.n_frames - b]  # frames cut at the start, at the end
        if inner:
            meta["glitch_frames"] = [base + i for i in inner]  # source-file frame numbers
        cmu_jobs[k] = (meta, clip.slice(a, b), key)
    cals: dict[str, list] = {}
    for _, clip, key in cmu_jobs:
        cals.setdefault(key, []).append(foot_calibration(clip))
    foot_off = {k: pool_foot_calibrations(v) for k, v in cals.items()}
    calib = {
        k: {"flat_frames": {s: int(sum(c[s][1] for c in cals[k])) for s in "lr"},
            "offset_deg": {s: round(float(np.degrees(quat_angle(foot_off[k][s]))), 2) for s in "lr"}}
        for k in cals
    }  # fmt: skip

    bone_errs: dict[str, list[np.ndarray]] = {b: [] for b in (*BONES, "trunk")}
    tilts = []
    pos_errs: dict[str, list[np.ndarray]] = {}
    for meta, clip, key in cmu_jobs:
        short = meta["name"].removeprefix("cmu_")
        if short in CLIP_NOTES:
            meta["notes"] = "; ".join(x for x in (meta.get("notes"), CLIP_NOTES[short]) if x)
        start = int(meta.pop("_start", 0))
        rt = retarget_cmu(clip, foot_off[key])
        for b, e in rt.bone_err_deg.items():
            bone_errs[b].append(e)
        tilts.append(rt.foot_tilt_deg)
        for k, e in rt.pos_err_m.items():
            pos_errs.setdefault(k, []).append(e)
        out, dz = finish(rt.frames, clip.fps, fps)
        all_e = np.concatenate([rt.bone_err_deg[b] for b in BONES])
        meta.update(
            {
                "fps": fps,
                "source_fps": round(clip.fps, 3),
                "source_frames": [start, start + clip.n_frames],
                "mirrored": False,
                "loop": False,
                **dz,
                "scale": round(rt.scale, 4),
                "validation": {
                    "bone_dir_err_mean_deg": round(float(all_e.mean()), 3),
                    "bone_dir_err_max_deg": round(float(all_e.max()), 3),
                    "trunk_dir_err_mean_deg": round(float(rt.bone_err_deg["trunk"].mean()), 3),
                    "joint_pos_err_mean_m": round(
                        float(np.mean([e.mean() for e in rt.pos_err_m.values()])), 4
                    ),
                    "flat_foot_tilt_mean_deg": round(float(rt.foot_tilt_deg.mean()), 3)
                    if rt.foot_tilt_deg.size
                    else None,
                    "hinge_clipped_frames": rt.hinge_clipped,
                    "planted_skate_mps": round(rt.planted_skate_mps, 4),
                    "planted_skate_src_mps": round(rt.planted_skate_src_mps, 4),
                },
            }
        )
        add(meta, out)

    # --- mirrored copies -----------------------------------------------------------------------------
    originals = list(clips)
    if mirror:
        for meta, frames in originals:
            m = dict(meta)
            m["name"] = f"{meta['name']}_mirrored"
            m["mirrored"] = True
            m["mirror_of"] = meta["name"]
            m["tags"] = mirror_tags(meta["tags"])
            mf = mirror_frames(frames)
            add(m, mf)
    lib = MotionLibrary.from_clips(
        clips,
        fps,
        meta={
            "humanoid": "pybullet_data humanoid/humanoid.urdf, globalScaling 0.25, URDF_MAINTAIN_LINK_ORDER",
            "frames_doc": "navzoo.agents.reference (z-up world; root_quat is PyBullet's base orientation)",
            "generator": "python -m navzoo.agents.motion_convert",
            "notice": "NOTICE.md",
        },
    )
    summary = _summary(lib, src, excluded, amp_diag, bone_errs)
    summary["validation"]["foot_calibration"] = calib
    t_all = np.concatenate(tilts) if tilts else np.zeros(1)
    summary["validation"]["cmu_flat_foot_tilt_deg"] = _stats(t_all)
    summary["validation"]["cmu_joint_pos_err_m"] = {k: _stats(np.concatenate(v)) for k, v in pos_errs.items()}
    return lib, summary


def _stats(x: np.ndarray) -> dict:
    return {
        "mean": round(float(np.mean(x)), 4),
        "p95": round(float(np.percentile(x, 95)), 4),
        "max": round(float(np.max(x)), 4),
    }


def _summary(lib: MotionLibrary, src: Path, excluded: list[dict], amp_diag: dict, bone_errs: dict) -> dict:
    base = lib.summary()
    per_clip = []
    speed_ratio = []
    for c in lib.clips:
        if c.get("mirrored"):
            continue
        m = c["metrics"]
        row = {
            "name": c["name"],
            "tags": c["tags"],
            "duration_s": m["duration_s"],
            "speed_mps": m["speed_mps"],
            "median_speed_mps": m["median_speed_mps"],
            "foot_skate_mps": m["foot_skate_mps"],
            "flight_frac": m["flight_frac"],
            **({"csv_mean_speed_mps": c["csv_mean_speed_mps"]} if c.get("csv_mean_speed_mps") else {}),
            **c.get("validation", {}),
        }
        if c.get("csv_mean_speed_mps") and "07_12" not in c["name"]:
            speed_ratio.append(m["speed_mps"] / c["csv_mean_speed_mps"])
            row["speed_ratio_vs_csv"] = round(speed_ratio[-1], 4)
        per_clip.append(row)
    originals = [c for c in lib.clips if not c.get("mirrored")]
    cmu = [c for c in originals if c.get("format") in ("amc", "bvh")]
    walk = [c for c in cmu if "walk" in c["tags"] or "walk_slow" in c["tags"]]
    speeds = [lib.speed(i) for i in range(len(lib))]
    validation = {
        "amp_fk": {
            k: {
                "fk_err_mean_m": float(f"{d['fk_err_mean_m']:.3g}"),
                "fk_err_max_m": float(f"{d['fk_err_max_m']:.3g}"),
                "pybullet_vs_numpy_fk_max_m": round(d.get("pybullet_fk_max_err_m", float("nan")), 7),
                "fk_scale": d["fk_scale"],
                "hinge_residual_deg": d["hinge_residual_deg"],
            }
            for k, d in amp_diag.items()
        },
        "cmu_bone_dir_err_deg": {b: _stats(np.concatenate(e)) for b, e in bone_errs.items() if e},
        "cmu_bone_dir_err_all_deg": _stats(np.concatenate([np.concatenate(bone_errs[b]) for b in BONES]))
        if cmu
        else {},
        "cmu_foot_skate_mps": _stats([c["metrics"]["foot_skate_mps"] for c in cmu]) if cmu else {},
        "walk_foot_skate_mps": _stats([c["metrics"]["foot_skate_mps"] for c in walk]) if walk else {},
        "cmu_planted_skate_mps": _stats([c["validation"]["planted_skate_mps"] for c in cmu]) if cmu else {},
        "cmu_planted_skate_src_mps": _stats([c["validation"]["planted_skate_src_mps"] for c in cmu])
        if cmu
        else {},
        "speed_ratio_vs_csv": _stats(speed_ratio) if speed_ratio else {},
        "speed_ratio_vs_csv_min": round(float(min(speed_ratio)), 4) if speed_ratio else None,
        "hinge_clipped_frames": int(sum(c["validation"].get("hinge_clipped_frames", 0) for c in cmu)),
    }
    return {
        "src": str(src),
        "clips": base["clips"],
        "original_clips": len(originals),
        "mirrored_clips": base["mirrored"],
        "frames": base["frames"],
        "fps": base["fps"],
        "seconds": base["seconds"],
        "minutes": round(base["seconds"] / 60.0, 2),
        "original_seconds": round(sum(c["duration_s"] for c in originals), 2),
        "speed_range_mps": [round(min(speeds), 3), round(max(speeds), 3)],
        "by_tag": base["by_tag"],
        "excluded": excluded,
        "validation": validation,
        "per_clip": per_clip,
    }


NOTICE = """# Notices for the motion library (`library.npz`, `library.json`)

The clips in this folder are converted (retargeted, resampled, mirrored) from the motion data in
`../shared/data/mocap` by `python -m navzoo.agents.motion_convert` (see `docs/motions.md`). Each
clip's entry in `library.json` names its source file, the source's sha256 and its licence.

## CMU Graphics Lab Motion Capture Database (all clips)

All clips derive from the CMU Graphics Lab Motion Capture Database. The database is free for use in
research and commercial projects worldwide; it may be shipped inside a product but not resold as a
data set.

> The data used in this project was obtained from mocap.cs.cmu.edu.
> The database was created with funding from NSF EIA-0196217.
{bvh11}
## AMP humanoid clips (`amp_walk*`, `amp_run*`, `amp_hop*`)

Motion assets of IsaacGymEnvs (NVIDIA), created from animations in the CMU dataset
(`amp_motions-acknowledgement.txt`):

{ack}

They are distributed under the following licence (`LICENSE-IsaacGymEnvs.txt`):

{lic}
"""

_BVH11_SECTION = """
Clips from `cmu_bvh/` ({names}): BVH conversion of the CMU data by B. Hahne (no further
restrictions), as kept in the bvh11 repository, under this licence (`LICENSE-bvh11.txt`):

{text}
"""


def _indent(text: str) -> str:
    return "\n".join(("    " + ln) if ln.strip() else "" for ln in text.strip("\n").splitlines())


def write_notice(src: Path, out: Path, bvh11_clips: list[str] | None = None) -> Path:
    """Write ``NOTICE.md`` with the licence texts the shipped clips require (the bvh11 licence only
    if clips from ``cmu_bvh/`` are shipped)."""

    def read(rel: str) -> str:
        f = src / rel
        if not f.is_file():
            raise MocapFormatError(f"licence file not found: {f}")
        return _indent(f.read_text())

    bvh11 = ""
    if bvh11_clips:
        bvh11 = _BVH11_SECTION.format(
            names=", ".join(f"`{n}`" for n in bvh11_clips), text=read("cmu_bvh/LICENSE-bvh11.txt")
        )
    path = out / "NOTICE.md"
    path.write_text(
        NOTICE.format(
            lic=read("amp_humanoid/LICENSE-IsaacGymEnvs.txt"),
            ack=read("amp_humanoid/amp_motions-acknowledgement.txt"),
            bvh11=bvh11,
        )
    )
    return path


def summary_markdown(summary: dict) -> str:
    """The library-contents table of ``docs/motions.md``: per tag, the converted clips (originals), their
    total duration and planar speed range, and the clip count with the mirrored copies (whose tags have
    left and right swapped)."""
    rows: dict[str, list] = {}
    for r in summary["per_clip"]:
        for t in r["tags"]:
            d = rows.setdefault(t, [0, 0.0, []])
            d[0] += 1
            d[1] += r["duration_s"]
            d[2].append(r["speed_mps"])
    lines = [
        "| tag | clips | with mirrored | duration (s) | planar speed (m/s) |",
        "|---|---:|---:|---:|---|",
    ]
    for tag in sorted(set(rows) | set(summary["by_tag"])):
        n, sec, sp = rows.get(tag, [0, 0.0, []])
        rng = f"{min(sp):.2f}–{max(sp):.2f}" if sp else "–"
        lines.append(
            f"| {tag} | {n} | {summary['by_tag'].get(tag, {}).get('clips', 0)} | {sec:.1f} | {rng} |"
        )
    lines.append(
        f"| **all** | {summary['original_clips']} | {summary['clips']} | {summary['original_seconds']:.1f} | "
        f"{summary['speed_range_mps'][0]:.2f}–{summary['speed_range_mps'][1]:.2f} |"
    )
    return "\n".join(lines)


# ----------------------------------------------------------------------------------------------------
# Command line
# ----------------------------------------------------------------------------------------------------


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Options of ``navzoo motions convert`` (``--json`` is skipped if the parser already has it)."""
    parser.add_argument(
        "--src", default="../shared/data/mocap", help="the mocap folder (default: ../shared/data/mocap)"
    )
    parser.add_argument(
        "--out", default="navzoo/assets/motions", help="output folder for library.npz/.json and NOTICE.md"
    )
    parser.add_argument("--fps", type=float, default=OUT_FPS, help="frame rate of the library (default: 30)")
    parser.add_argument("--no-mirror", action="store_true", help="do not add mirrored copies")
    parser.add_argument(
        "--no-pybullet-check", action="store_true", help="skip the PyBullet FK check of the AMP clips"
    )
    parser.add_argument("--markdown", action="store_true", help="also print the contents table as Markdown")
    try:
        parser.add_argument("--json", action="store_true", help="print the full summary as JSON")
    except argparse.ArgumentError:
        pass


def run(args: argparse.Namespace) -> dict:
    """Convert, write the library and return the summary (clips, frames, durations, validation).

    Raises:
        MocapFormatError (a ``ValueError``): a source file is missing or malformed (the message names it).
    """
    src = Path(args.src)
    lib, summary = build_library(
        src,
        fps=float(getattr(args, "fps", OUT_FPS)),
        mirror=not getattr(args, "no_mirror", False),
        pybullet_check=not getattr(args, "no_pybullet_check", False),
    )
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    npz, js = lib.save(out)
    bvh11 = [c["name"] for c in lib.clips if c["source"].startswith("cmu_bvh/") and not c.get("mirrored")]
    notice = write_notice(src, out, bvh11)
    summary["files"] = {str(f): f.stat().st_size for f in (npz, js, notice)}
    summary["out"] = str(out)
    return summary


def format_summary(s: dict) -> str:
    """A few human-readable lines of a :func:`run` summary."""
    v = s["validation"]
    lines = [
        f"{s['clips']} clips ({s['original_clips']} + {s['mirrored_clips']} mirrored), {s['frames']} frames at "
        f"{s['fps']:g} fps, {s['minutes']} min; planar speeds {s['speed_range_mps'][0]}-{s['speed_range_mps'][1]} m/s"
    ]
    for k, d in v["amp_fk"].items():
        lines.append(
            f"  AMP {k}: body positions vs the clip's FK: mean {d['fk_err_mean_m']:.1e} m, max {d['fk_err_max_m']:.1e} m; "
            f"PyBullet vs numpy FK: max {d['pybullet_vs_numpy_fk_max_m']:.1e} m"
        )
    if v["cmu_bone_dir_err_all_deg"]:
        e = v["cmu_bone_dir_err_all_deg"]
        t = v["cmu_bone_dir_err_deg"]["trunk"]
        lines += [
            f"  CMU bone-direction error: mean {e['mean']} deg, p95 {e['p95']}, max {e['max']}; trunk mean {t['mean']} deg",
            f"  CMU foot skating added by retargeting: {v['cmu_planted_skate_mps']['mean']} m/s "
            f"(mocap's own: {v['cmu_planted_skate_src_mps']['mean']} m/s)",
            f"  speed / clips.csv: {v['speed_ratio_vs_csv']}",
        ]
    for x in s["excluded"]:
        lines.append(f"  excluded {x['file']}: {x['reason']}")
    for f, size in s.get("files", {}).items():
        lines.append(f"  wrote {f} ({size / 1e6:.2f} MB)")
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        prog="python -m navzoo.agents.motion_convert", description=__doc__.split("\n\n")[0]
    )
    add_arguments(parser)
    args = parser.parse_args(argv)
    try:
        summary = run(args)
    except (MocapFormatError, FileNotFoundError) as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    if args.json:
        print(json.dumps(summary, indent=1))
    else:
        print(format_summary(summary))
    if args.markdown:
        print(summary_markdown(summary))
    return 0


if __name__ == "__main__":
    sys.exit(main())
