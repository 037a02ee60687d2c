"""The motion library: reference clips for the 15-body humanoid, stored as plain arrays, played at any time.

The library shipped in ``navzoo/assets/motions`` (``library.npz`` + ``library.json``) holds every clip
converted from ``../shared/data/mocap`` by :mod:`navzoo.agents.motion_convert` (AMP humanoid clips and
retargeted CMU motion capture), plus a mirrored copy of each, all at 30 frames per second. No pickles:
the arrays are loaded with ``np.load(..., allow_pickle=False)`` and the index is JSON.

Frames and joint order are those of :mod:`navzoo.agents.reference` (z-up world, PyBullet base
orientation of ``humanoid/humanoid.urdf`` at ``globalScaling=0.25``, spherical joints in
:data:`navzoo.agents.motion.SPHERICAL_JOINTS` order, knees and elbows as angles). Every clip starts
at the origin facing +x with its lowest foot touching the ground (z = 0) at least once.

:class:`MotionLibrary` implements :class:`~navzoo.agents.reference.ReferenceMotion`; ``state_at``
interpolates between frames (slerp for rotations, lerp for the rest) for any batch of (clip, time)
queries. Times are clamped to ``[0, duration]``, except for clips flagged ``loop``, which repeat with
their root displaced by one cycle per repetition.
"""

from __future__ import annotations

import hashlib
import importlib.resources
import io
import json
import zipfile
from collections.abc import Iterable, Sequence
from contextlib import ExitStack
from importlib.resources.abc import Traversable
from pathlib import Path

import numpy as np

from navzoo.agents import quat as _quat
from navzoo.agents.motion import CLIP_JOINTS, HUMANOID_SCALE, SPHERICAL_JOINTS
from navzoo.agents.reference import ReferenceState

LIBRARY_FORMAT = "navzoo-motion-library"
LIBRARY_VERSION = 1
DEFAULT_NAME = "library"


# Quaternion helpers, defined in navzoo.agents.quat and re-exported here for this module's callers.
heading_of = _quat.heading
quat_about_z = _quat.quat_about_z
quat_angle = _quat.quat_angle
quat_canonical = _quat.quat_canonical
quat_conj = _quat.quat_conj
quat_from_rotvec = _quat.quat_from_rotvec
quat_mul = _quat.quat_mul
quat_normalize = _quat.quat_normalize
quat_rotate = _quat.quat_rotate
quat_slerp = _quat.quat_slerp
quat_to_rotvec = _quat.quat_to_rotvec

# --------------------------------------------------------------------------------------------------
# The humanoid (humanoid/humanoid.urdf, URDF_MAINTAIN_LINK_ORDER, globalScaling 0.25)
# --------------------------------------------------------------------------------------------------

LINK_NAMES: tuple[str, ...] = (
    "root", "chest", "neck", "right_hip", "right_knee", "right_ankle", "right_shoulder", "right_elbow",
    "right_wrist", "left_hip", "left_knee", "left_ankle", "left_shoulder", "left_elbow", "left_wrist",
)  # fmt: skip
LINK_PARENTS: tuple[int, ...] = (-1, 0, 1, 0, 3, 4, 1, 6, 7, 0, 9, 10, 1, 12, 13)
# Joint origins in the parent link frame (URDF frame: y up, x forward, z to the body's right), metres.
JOINT_ORIGINS = HUMANOID_SCALE * np.array(
    [
        [0.0, 0.0, 0.0],
        [0.0, 0.944604, 0.0],
        [0.0, 0.895576, 0.0],
        [0.0, 0.0, 0.339548],
        [0.0, -1.686184, 0.0],
        [0.0, -1.639480, 0.0],
        [-0.0962, 0.974, 0.73244],
        [0.0, -1.099152, 0.0],
        [0.0, -1.035788, 0.0],
        [0.0, 0.0, -0.339548],
        [0.0, -1.686184, 0.0],
        [0.0, -1.639480, 0.0],
        [-0.0962, 0.974, -0.73244],
        [0.0, -1.099152, 0.0],
        [0.0, -1.035788, 0.0],
    ]
)
REVOLUTE_JOINTS: tuple[int, ...] = tuple(j for j in CLIP_JOINTS if j not in SPHERICAL_JOINTS)  # 4, 7, 10, 13
REVOLUTE_AXIS = np.array([0.0, 0.0, 1.0])  # knees and elbows turn about the link's z (lateral) axis
# The foot (ankle link) collision box and the head (neck link) sphere, in their link frames.
FOOT_BOX_CENTER = HUMANOID_SCALE * np.array([0.18, -0.09, 0.0])
FOOT_BOX_HALF = HUMANOID_SCALE * 0.5 * np.array([0.708, 0.22, 0.36])
HEAD_CENTER = HUMANOID_SCALE * np.array([0.0, 0.7, 0.0])
HEAD_RADIUS = HUMANOID_SCALE * 0.41
FOOT_LINKS = (5, 11)  # right, left ankle links
_FOOT_CORNERS = FOOT_BOX_CENTER + FOOT_BOX_HALF * np.array(
    [[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)], dtype=np.float64
)

# The URDF is y-up: PyBullet's base orientation of an upright body facing +x.
Y_UP_TO_Z_UP = np.array([np.sin(np.pi / 4), 0.0, 0.0, np.cos(np.pi / 4)])

# Left/right swap for mirroring: spherical order (chest, neck, r_hip, r_ankle, r_shoulder, l_hip,
# l_ankle, l_shoulder), revolute order (r_knee, r_elbow, l_knee, l_elbow).
_SPH_SWAP = np.array([0, 1, 5, 6, 7, 2, 3, 4])
_REV_SWAP = np.array([2, 3, 0, 1])
_LR_TAGS = {"left": "right", "right": "left"}

FIELDS = ("root_pos", "root_quat", "sph", "rev", "root_lin_vel", "root_ang_vel", "sph_vel", "rev_vel")
_FIELD_SHAPES = {
    "root_pos": (3,), "root_quat": (4,), "sph": (8, 4), "rev": (4,),
    "root_lin_vel": (3,), "root_ang_vel": (3,), "sph_vel": (8, 3), "rev_vel": (4,),
}  # fmt: skip


# --------------------------------------------------------------------------------------------------
# Kinematics of the humanoid
# --------------------------------------------------------------------------------------------------


def joint_quaternions(sph: np.ndarray, rev: np.ndarray) -> np.ndarray:
    """(..., 15, 4) local joint rotations of all links (identity for the fixed joints)."""
    sph = np.asarray(sph, dtype=np.float64)
    rev = np.asarray(rev, dtype=np.float64)
    q = np.zeros(sph.shape[:-2] + (15, 4))
    q[..., 3] = 1.0
    q[..., list(SPHERICAL_JOINTS), :] = sph
    q[..., list(REVOLUTE_JOINTS), :] = quat_about_z(rev)
    return q


def humanoid_fk(
    root_pos: np.ndarray, root_quat: np.ndarray, sph: np.ndarray, rev: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """World link frames of the humanoid (PyBullet's ``worldLinkFramePosition/Orientation``).

    Args:
        root_pos (..., 3), root_quat (..., 4): base pose; sph (..., 8, 4), rev (..., 4): joints.

    Returns:
        ``(pos (..., 15, 3), quat (..., 15, 4))``: link frame origins (= joint positions) and
        orientations, link order of ``URDF_MAINTAIN_LINK_ORDER`` (:data:`LINK_NAMES`).
    """
    root_pos = np.asarray(root_pos, dtype=np.float64)
    local = joint_quaternions(sph, rev)
    lead = root_pos.shape[:-1]
    pos = np.zeros(lead + (15, 3))
    quat = np.zeros(lead + (15, 4))
    for j in range(15):
        pj = LINK_PARENTS[j]
        if pj < 0:
            ppos, pq = root_pos, np.asarray(root_quat, dtype=np.float64)
        else:
            ppos, pq = pos[..., pj, :], quat[..., pj, :]
        pos[..., j, :] = ppos + quat_rotate(pq, JOINT_ORIGINS[j])
        quat[..., j, :] = quat_mul(pq, local[..., j, :])
    return pos, quat


def foot_corners(link_pos: np.ndarray, link_quat: np.ndarray) -> np.ndarray:
    """World positions (..., 2, 8, 3) of the 8 corners of the right and left foot boxes."""
    out = []
    for j in FOOT_LINKS:
        q = link_quat[..., j, None, :]
        out.append(
            link_pos[..., j, None, :] + quat_rotate(np.broadcast_to(q, q.shape[:-2] + (8, 4)), _FOOT_CORNERS)
        )
    return np.stack(out, axis=-3)


def foot_heights(link_pos: np.ndarray, link_quat: np.ndarray) -> np.ndarray:
    """Height (..., 2) of the lowest point of the right and left foot boxes."""
    return foot_corners(link_pos, link_quat)[..., 2].min(axis=-1)


def head_top(link_pos: np.ndarray, link_quat: np.ndarray) -> np.ndarray:
    """Height (...) of the top of the head sphere (the crown)."""
    c = link_pos[..., 2, :] + quat_rotate(link_quat[..., 2, :], HEAD_CENTER)
    return c[..., 2] + HEAD_RADIUS


# --------------------------------------------------------------------------------------------------
# Frame arrays: velocities and mirroring
# --------------------------------------------------------------------------------------------------


def _rate(log_fwd: np.ndarray, dt: float) -> np.ndarray:
    """Per-frame rates from per-interval increments (T-1, ...): central average inside, one-sided at ends."""
    v = np.empty((log_fwd.shape[0] + 1,) + log_fwd.shape[1:])
    v[0] = log_fwd[0]
    v[-1] = log_fwd[-1]
    v[1:-1] = 0.5 * (log_fwd[:-1] + log_fwd[1:])
    return v / dt


def compute_velocities(frames: dict[str, np.ndarray], fps: float) -> dict[str, np.ndarray]:
    """Finite-difference velocities of one clip's poses (``root_pos``, ``root_quat``, ``sph``, ``rev``).

    Linear velocities and knee/elbow rates are central differences (one-sided at the ends). The root
    angular velocity is in the world frame, from ``log(q[i+1] q[i]^-1)``; joint angular velocities are
    in each joint's child frame, from ``log(q[i]^-1 q[i+1])`` (PyBullet's convention for spherical
    joints), averaged over the intervals before and after each frame.
    """
    dt = 1.0 / fps
    pos, rq, sph, rev = (
        np.asarray(frames[k], dtype=np.float64) for k in ("root_pos", "root_quat", "sph", "rev")
    )
    if pos.shape[0] < 2:
        z = np.zeros
        return {
            "root_lin_vel": z((1, 3)),
            "root_ang_vel": z((1, 3)),
            "sph_vel": z((1, 8, 3)),
            "rev_vel": z((1, 4)),
        }
    return {
        "root_lin_vel": _rate(np.diff(pos, axis=0), dt),
        "root_ang_vel": _rate(quat_to_rotvec(quat_mul(rq[1:], quat_conj(rq[:-1]))), dt),
        "sph_vel": _rate(quat_to_rotvec(quat_mul(quat_conj(sph[:-1]), sph[1:])), dt),
        "rev_vel": _rate(np.diff(rev, axis=0), dt),
    }


def mirror_frames(frames: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
    """Reflect poses and velocities through the world x-z plane (y -> -y) and swap left and right.

    The URDF's sagittal plane is its x-y plane (z points to the body's right), so a local joint
    rotation ``R`` becomes ``S R S`` with ``S = diag(1, 1, -1)``: quaternion ``(-x, -y, z, w)``;
    knee and elbow angles (about z) keep their values. The base orientation becomes
    ``S_w R S`` with ``S_w = diag(1, -1, 1)``. Angular velocities are pseudovectors: ``-S w``.
    Mirroring twice is the identity.
    """
    out: dict[str, np.ndarray] = {}
    sw = np.array([1.0, -1.0, 1.0])
    if "root_pos" in frames:
        out["root_pos"] = np.asarray(frames["root_pos"]) * sw
    if "root_quat" in frames:
        q = np.asarray(frames["root_quat"], dtype=np.float64) * np.array([-1.0, 1.0, -1.0, 1.0])
        out["root_quat"] = quat_mul(q, np.array([1.0, 0.0, 0.0, 0.0]))
    if "sph" in frames:
        out["sph"] = (np.asarray(frames["sph"]) * np.array([-1.0, -1.0, 1.0, 1.0]))[..., _SPH_SWAP, :]
    if "rev" in frames:
        out["rev"] = np.asarray(frames["rev"])[..., _REV_SWAP]
    if "root_lin_vel" in frames:
        out["root_lin_vel"] = np.asarray(frames["root_lin_vel"]) * sw
    if "root_ang_vel" in frames:
        out["root_ang_vel"] = np.asarray(frames["root_ang_vel"]) * np.array([-1.0, 1.0, -1.0])
    if "sph_vel" in frames:
        out["sph_vel"] = (np.asarray(frames["sph_vel"]) * np.array([-1.0, -1.0, 1.0]))[..., _SPH_SWAP, :]
    if "rev_vel" in frames:
        out["rev_vel"] = np.asarray(frames["rev_vel"])[..., _REV_SWAP]
    return out


def mirror_tags(tags: Iterable[str]) -> list[str]:
    """Swap ``left``/``right`` in tags (``veer_left`` -> ``veer_right``)."""
    out = []
    for t in tags:
        parts = t.split("_")
        out.append("_".join(_LR_TAGS.get(p, p) for p in parts))
    return out


# --------------------------------------------------------------------------------------------------
# The library
# --------------------------------------------------------------------------------------------------


def _default_dir() -> Traversable:
    return importlib.resources.files("navzoo").joinpath("assets", "motions")


def _resolve(path: str | Path | None) -> tuple[Path, Path] | None:
    """(npz, json) paths for a directory, a ``.json`` or ``.npz`` path, or a stem; None = packaged."""
    if path is None:
        return None
    p = Path(path)
    if p.is_dir():
        p = p / f"{DEFAULT_NAME}.json"
    if p.suffix in (".json", ".npz"):
        p = p.with_suffix("")
    return p.with_suffix(".npz"), p.with_suffix(".json")


def _write_npz(path: Path, arrays: dict[str, np.ndarray]) -> None:
    """``np.savez_compressed`` with fixed zip timestamps, so the same library gives the same bytes."""
    with zipfile.ZipFile(path, "w", compression=zipfile.ZIP_DEFLATED) as zf:
        for name, arr in arrays.items():
            buf = io.BytesIO()
            np.lib.format.write_array(buf, np.ascontiguousarray(arr), allow_pickle=False)
            info = zipfile.ZipInfo(f"{name}.npy", date_time=(1980, 1, 1, 0, 0, 0))
            info.compress_type = zipfile.ZIP_DEFLATED
            zf.writestr(info, buf.getvalue())


class MotionLibrary:
    """A set of reference clips at a common frame rate (implements ``ReferenceMotion``).

    Args:
        arrays: the frames of all clips concatenated: ``root_pos (N, 3)``, ``root_quat (N, 4)``,
            ``sph (N, 8, 4)``, ``rev (N, 4)``, ``root_lin_vel (N, 3)``, ``root_ang_vel (N, 3)``,
            ``sph_vel (N, 8, 3)``, ``rev_vel (N, 4)``.
        offsets: (C + 1,) first frame of each clip (and N at the end).
        clips: one metadata dict per clip (``name``, ``tags``, ``mirrored``, ``loop``, ``source``, ...).
        fps: frame rate of every clip.
        meta: library-wide metadata (licences, ...).
    """

    def __init__(
        self,
        arrays: dict[str, np.ndarray],
        offsets: np.ndarray,
        clips: list[dict],
        fps: float,
        meta: dict | None = None,
    ) -> None:
        self._fps = float(fps)
        if not self._fps > 0:
            raise ValueError(f"fps must be positive, got {fps}")
        self.offsets = np.asarray(offsets, dtype=np.int64)
        n = int(self.offsets[-1]) if self.offsets.size else 0
        if self.offsets.ndim != 1 or self.offsets.size != len(clips) + 1 or self.offsets[0] != 0:
            raise ValueError(
                f"offsets must be (C + 1,) starting at 0 for {len(clips)} clips, got {self.offsets.shape}"
            )
        if np.any(np.diff(self.offsets) < 2):
            raise ValueError("every clip needs at least 2 frames")
        self.arrays: dict[str, np.ndarray] = {}
        for k in FIELDS:
            if k not in arrays:
                raise ValueError(f"missing array {k!r}")
            a = np.asarray(arrays[k], dtype=np.float64)
            if a.shape != (n,) + _FIELD_SHAPES[k]:
                raise ValueError(f"array {k!r} has shape {a.shape}, expected {(n,) + _FIELD_SHAPES[k]}")
            if not np.all(np.isfinite(a)):
                raise ValueError(f"array {k!r} has non-finite values")
            self.arrays[k] = a
        # float32 storage: renormalise the quaternions.
        self.arrays["root_quat"] = quat_normalize(self.arrays["root_quat"])
        self.arrays["sph"] = quat_normalize(self.arrays["sph"])
        self.clips = [dict(c) for c in clips]
        self.meta = dict(meta or {})
        self._n_frames = np.diff(self.offsets)
        self._durations = (self._n_frames - 1) / self._fps
        self._loop = np.array([bool(c.get("loop", False)) for c in self.clips])
        self._index = {c["name"]: i for i, c in enumerate(self.clips)}
        if len(self._index) != len(self.clips):
            raise ValueError("clip names must be unique")
        self._cycle = self._cycle_transforms()

    # --- ReferenceMotion --------------------------------------------------------------------------

    def clip_names(self) -> list[str]:
        return [c["name"] for c in self.clips]

    def duration(self, clip: int) -> float:
        return float(self._durations[self._check(clip)])

    def state_at(self, clip: np.ndarray, t: np.ndarray) -> ReferenceState:
        """States at times ``t`` (B,) s of clips ``clip`` (B,); every field gets a leading (B,) axis."""
        clip = np.atleast_1d(np.asarray(clip))
        t = np.atleast_1d(np.asarray(t, dtype=np.float64))
        clip, t = np.broadcast_arrays(clip, t)
        clip = clip.astype(np.int64)
        if clip.size and (clip.min() < 0 or clip.max() >= len(self.clips)):
            raise IndexError(f"clip index out of range [0, {len(self.clips)})")
        if not np.all(np.isfinite(t)):
            raise ValueError("times must be finite")
        dur = self._durations[clip]
        t = np.maximum(t, 0.0)
        loop = self._loop[clip]
        cycles = np.where(loop, np.floor(t / dur), 0.0)
        t = np.where(loop, t - cycles * dur, np.minimum(t, dur))
        f = t * self._fps
        i0 = np.minimum(np.floor(f).astype(np.int64), self._n_frames[clip] - 2)
        a = np.clip(f - i0, 0.0, 1.0)
        g0 = self.offsets[clip] + i0
        g1 = g0 + 1
        A = self.arrays
        lerp = {}
        for k in ("root_pos", "rev", "root_lin_vel", "root_ang_vel", "rev_vel", "sph_vel"):
            x0, x1 = A[k][g0], A[k][g1]
            w = a.reshape(a.shape + (1,) * (x0.ndim - 1))
            lerp[k] = (1.0 - w) * x0 + w * x1
        root_quat = quat_slerp(A["root_quat"][g0], A["root_quat"][g1], a)
        sph = quat_slerp(A["sph"][g0], A["sph"][g1], a[:, None])
        root_pos = lerp["root_pos"]
        lin, ang = lerp["root_lin_vel"], lerp["root_ang_vel"]
        if np.any(cycles > 0):
            root_pos, root_quat, lin, ang = self._apply_cycles(clip, cycles, root_pos, root_quat, lin, ang)
        return ReferenceState(
            root_pos=root_pos,
            root_quat=root_quat,
            sph=sph,
            rev=lerp["rev"],
            root_lin_vel=lin,
            root_ang_vel=ang,
            sph_vel=lerp["sph_vel"],
            rev_vel=lerp["rev_vel"],
        )

    # --- loops --------------------------------------------------------------------------------------

    def _cycle_transforms(self) -> np.ndarray:
        """Per clip, the planar rigid motion (yaw, tx, ty) taking the first frame's root to the last's."""
        out = np.zeros((len(self.clips), 3))
        for c in np.flatnonzero(self._loop):
            i0, i1 = self.offsets[c], self.offsets[c + 1] - 1
            yaw = heading_of(self.arrays["root_quat"][i1]) - heading_of(self.arrays["root_quat"][i0])
            p0, p1 = self.arrays["root_pos"][i0, :2], self.arrays["root_pos"][i1, :2]
            cs, sn = np.cos(yaw), np.sin(yaw)
            rp0 = np.array([cs * p0[0] - sn * p0[1], sn * p0[0] + cs * p0[1]])
            out[c] = [yaw, *(p1 - rp0)]
        return out

    def _apply_cycles(self, clip, cycles, pos, quat, lin, ang):
        """Apply each clip's cycle transform ``cycles`` times (x -> r x + b, in complex form)."""
        yaw, bx, by = self._cycle[clip].T
        r = np.exp(1j * yaw)
        rk = np.exp(1j * yaw * cycles)
        b = bx + 1j * by
        geo = np.where(
            np.abs(1 - r) < 1e-9, cycles + 0j, (1 - rk) / np.where(np.abs(1 - r) < 1e-9, 1.0, 1 - r)
        )
        z = (pos[:, 0] + 1j * pos[:, 1]) * rk + b * geo
        pos = np.stack([z.real, z.imag, pos[:, 2]], axis=-1)
        qz = quat_about_z(yaw * cycles)
        return pos, quat_mul(qz, quat), quat_rotate(qz, lin), quat_rotate(qz, ang)

    # --- queries ---------------------------------------------------------------------------------

    def __len__(self) -> int:
        return len(self.clips)

    @property
    def fps(self) -> float:
        return self._fps

    @property
    def num_frames(self) -> int:
        return int(self.offsets[-1])

    def _check(self, clip: int | str) -> int:
        if isinstance(clip, str):
            return self.clip_index(clip)
        c = int(clip)
        if not 0 <= c < len(self.clips):
            raise IndexError(f"clip {clip} out of range [0, {len(self.clips)})")
        return c

    def clip_index(self, name: str) -> int:
        try:
            return self._index[name]
        except KeyError:
            raise KeyError(f"no clip named {name!r}") from None

    def n_frames(self, clip: int | str) -> int:
        return int(self._n_frames[self._check(clip)])

    def durations(self) -> np.ndarray:
        return self._durations.copy()

    def info(self, clip: int | str) -> dict:
        """The clip's metadata (a copy)."""
        return dict(self.clips[self._check(clip)])

    def tags(self, clip: int | str) -> list[str]:
        return list(self.clips[self._check(clip)].get("tags", []))

    def is_mirrored(self, clip: int | str) -> bool:
        return bool(self.clips[self._check(clip)].get("mirrored", False))

    def frames(self, clip: int | str) -> dict[str, np.ndarray]:
        """The stored frames of one clip (copies)."""
        c = self._check(clip)
        s = slice(self.offsets[c], self.offsets[c + 1])
        return {k: v[s].copy() for k, v in self.arrays.items()}

    def speed(self, clip: int | str) -> float:
        """Mean planar root speed (m/s): the root's path length on the ground over the duration."""
        c = self._check(clip)
        p = self.arrays["root_pos"][self.offsets[c] : self.offsets[c + 1], :2]
        return float(np.linalg.norm(np.diff(p, axis=0), axis=1).sum() / self._durations[c])

    def select(
        self,
        tags: str | Iterable[str] | None = None,
        mirrored: bool | None = None,
        exclude_tags: str | Iterable[str] | None = None,
        names: Iterable[str] | None = None,
    ) -> MotionLibrary:
        """A library of the clips that have any of ``tags`` (None: all), none of ``exclude_tags``, whose
        ``mirrored`` flag matches (None: both) and, if given, whose name is in ``names``.

        Raises:
            ValueError: no clip matches.
        """
        want = {tags} if isinstance(tags, str) else (set(tags) if tags is not None else None)
        drop = {exclude_tags} if isinstance(exclude_tags, str) else set(exclude_tags or ())
        keep_names = set(names) if names is not None else None
        keep = []
        for i, c in enumerate(self.clips):
            ct = set(c.get("tags", []))
            if want is not None and not (ct & want):
                continue
            if ct & drop:
                continue
            if mirrored is not None and bool(c.get("mirrored", False)) != mirrored:
                continue
            if keep_names is not None and c["name"] not in keep_names:
                continue
            keep.append(i)
        if not keep:
            raise ValueError(
                f"no clip matches tags={tags!r}, exclude_tags={exclude_tags!r}, mirrored={mirrored!r}"
            )
        idx = np.concatenate([np.arange(self.offsets[i], self.offsets[i + 1]) for i in keep])
        offsets = np.concatenate([[0], np.cumsum(self._n_frames[keep])])
        return MotionLibrary(
            {k: v[idx] for k, v in self.arrays.items()},
            offsets,
            [self.clips[i] for i in keep],
            self._fps,
            self.meta,
        )

    def sample_times(self, rng: np.random.Generator, n: int) -> tuple[np.ndarray, np.ndarray]:
        """``n`` (clip, time) pairs: clips drawn with probability proportional to their duration, times
        uniform over the clip (so every second of motion is equally likely)."""
        w = self._durations / self._durations.sum()
        clip = rng.choice(len(self.clips), size=int(n), p=w)
        t = rng.uniform(0.0, 1.0, size=int(n)) * self._durations[clip]
        return clip.astype(np.int64), t

    def summary(self) -> dict:
        """Counts, durations and speed ranges per tag."""
        by_tag: dict[str, dict] = {}
        for i, c in enumerate(self.clips):
            for tg in c.get("tags", []):
                d = by_tag.setdefault(tg, {"clips": 0, "seconds": 0.0, "speeds": []})
                d["clips"] += 1
                d["seconds"] += float(self._durations[i])
                d["speeds"].append(self.speed(i))
        for d in by_tag.values():
            s = d.pop("speeds")
            d["seconds"] = round(d["seconds"], 2)
            d["speed_min"] = round(min(s), 3)
            d["speed_max"] = round(max(s), 3)
        return {
            "clips": len(self.clips),
            "mirrored": int(sum(bool(c.get("mirrored")) for c in self.clips)),
            "frames": self.num_frames,
            "seconds": round(float(self._durations.sum()), 2),
            "fps": self._fps,
            "by_tag": dict(sorted(by_tag.items())),
        }

    # --- kinematic playback ------------------------------------------------------------------

    def play(
        self,
        client: int,
        body_ids: Sequence[int],
        clip: int | np.ndarray,
        t: float | np.ndarray,
        origin: np.ndarray | None = None,
        set_velocities: bool = True,
    ) -> ReferenceState:
        """Pose PyBullet humanoids (``humanoid/humanoid.urdf``, ``URDF_MAINTAIN_LINK_ORDER``) at clip times.

        Args:
            client: PyBullet client id.
            body_ids: the bodies (e.g. ``HumanoidBodies.ids``); one (clip, t) per body, broadcast.
            clip, t: clip indices and times.
            origin: optional (B, 3) or (3,) offset added to the root positions.
            set_velocities: also set base and joint velocities (ignored by fixed-base bodies).

        Returns:
            The states that were applied (origin included).
        """
        import pybullet as p

        b = len(body_ids)
        clip = np.broadcast_to(np.asarray(clip), (b,))
        t = np.broadcast_to(np.asarray(t, dtype=np.float64), (b,))
        s = self.state_at(clip, t)
        pos = (
            s.root_pos
            if origin is None
            else s.root_pos + np.broadcast_to(np.asarray(origin, dtype=np.float64), (b, 3))
        )
        s = ReferenceState(
            pos, s.root_quat, s.sph, s.rev, s.root_lin_vel, s.root_ang_vel, s.sph_vel, s.rev_vel
        )
        joints = list(CLIP_JOINTS)
        for i, body in enumerate(body_ids):
            p.resetBasePositionAndOrientation(
                body, pos[i].tolist(), s.root_quat[i].tolist(), physicsClientId=client
            )
            sph, rev = s.sph[i].tolist(), s.rev[i].tolist()
            targets = [
                sph[0],
                sph[1],
                sph[2],
                [rev[0]],
                sph[3],
                sph[4],
                [rev[1]],
                sph[5],
                [rev[2]],
                sph[6],
                sph[7],
                [rev[3]],
            ]
            if set_velocities:
                p.resetBaseVelocity(
                    body, s.root_lin_vel[i].tolist(), s.root_ang_vel[i].tolist(), physicsClientId=client
                )
                sv, rv = s.sph_vel[i].tolist(), s.rev_vel[i].tolist()
                vels = [
                    sv[0],
                    sv[1],
                    sv[2],
                    [rv[0]],
                    sv[3],
                    sv[4],
                    [rv[1]],
                    sv[5],
                    [rv[2]],
                    sv[6],
                    sv[7],
                    [rv[3]],
                ]
                p.resetJointStatesMultiDof(
                    body, joints, targets, targetVelocities=vels, physicsClientId=client
                )
            else:
                p.resetJointStatesMultiDof(body, joints, targets, physicsClientId=client)
        return s

    # --- storage -------------------------------------------------------------------------------

    def save(self, path: str | Path) -> tuple[Path, Path]:
        """Write ``<stem>.npz`` (float32 arrays, no pickles) and ``<stem>.json`` (the index).

        ``path`` is a directory (files ``library.npz``/``library.json`` inside), or a ``.json``/``.npz``
        path or stem. Returns the two paths.
        """
        p = Path(path)
        if p.suffix not in (".json", ".npz") and not p.exists():
            p.mkdir(parents=True, exist_ok=True)
        npz_path, json_path = _resolve(p)  # type: ignore[misc]
        arrays = {k: self.arrays[k].astype(np.float32) for k in FIELDS}
        arrays["offsets"] = self.offsets.astype(np.int64)
        _write_npz(npz_path, arrays)
        digest = hashlib.sha256(npz_path.read_bytes()).hexdigest()
        index = {
            "format": LIBRARY_FORMAT,
            "version": LIBRARY_VERSION,
            "fps": self._fps,
            "frames": self.num_frames,
            "arrays": npz_path.name,
            "arrays_sha256": digest,
            **{
                k: v
                for k, v in self.meta.items()
                if k not in ("format", "version", "fps", "frames", "arrays", "arrays_sha256", "clips")
            },
            "clips": self.clips,
        }
        json_path.write_text(json.dumps(index, indent=1, sort_keys=False) + "\n")
        return npz_path, json_path

    @classmethod
    def load(cls, path: str | Path | None = None, verify: bool = True) -> MotionLibrary:
        """Load a library (default: the one packaged in ``navzoo/assets/motions``).

        Args:
            path: a directory holding ``library.json``/``library.npz``, or the ``.json``/``.npz`` path.
            verify: check the arrays' sha256 against the index.
        """
        with ExitStack() as stack:
            res = _resolve(path)
            if res is None:
                d = _default_dir()
                npz_path = stack.enter_context(importlib.resources.as_file(d.joinpath(f"{DEFAULT_NAME}.npz")))
                json_path = stack.enter_context(
                    importlib.resources.as_file(d.joinpath(f"{DEFAULT_NAME}.json"))
                )
            else:
                npz_path, json_path = res
            for f in (npz_path, json_path):
                if not Path(f).is_file():
                    raise FileNotFoundError(
                        f"motion library file not found: {f} (build it with `navzoo motions convert`)"
                    )
            try:
                index = json.loads(Path(json_path).read_text())
            except (OSError, ValueError) as exc:
                raise ValueError(f"cannot read motion library index {json_path}: {exc}") from exc
            if index.get("format") != LIBRARY_FORMAT or index.get("version") != LIBRARY_VERSION:
                raise ValueError(
                    f"{json_path}: not a {LIBRARY_FORMAT} v{LIBRARY_VERSION} index "
                    f"(format={index.get('format')!r}, version={index.get('version')!r})"
                )
            raw = Path(npz_path).read_bytes()
            if (
                verify
                and index.get("arrays_sha256")
                and hashlib.sha256(raw).hexdigest() != index["arrays_sha256"]
            ):
                raise ValueError(
                    f"{npz_path}: sha256 does not match {json_path} (files from different builds?)"
                )
            with np.load(npz_path, allow_pickle=False) as z:
                arrays = {k: z[k] for k in z.files}
        if "offsets" not in arrays:
            raise ValueError(f"{npz_path}: no 'offsets' array")
        offsets = arrays.pop("offsets")
        meta = {k: v for k, v in index.items() if k != "clips"}
        try:
            return cls(arrays, offsets, index["clips"], index["fps"], meta)
        except (KeyError, ValueError) as exc:
            raise ValueError(f"motion library {json_path}: {exc}") from exc

    @classmethod
    def from_clips(
        cls, clips: list[tuple[dict, dict[str, np.ndarray]]], fps: float, meta: dict | None = None
    ) -> MotionLibrary:
        """Build a library from ``(metadata, frames)`` pairs (frames as in :meth:`frames`)."""
        lengths = [fr["root_pos"].shape[0] for _, fr in clips]
        arrays = {k: np.concatenate([fr[k] for _, fr in clips], axis=0) for k in FIELDS}
        return cls(arrays, np.concatenate([[0], np.cumsum(lengths)]), [m for m, _ in clips], fps, meta)


def load(path: str | Path | None = None) -> MotionLibrary:
    """Shortcut for :meth:`MotionLibrary.load`."""
    return MotionLibrary.load(path)
