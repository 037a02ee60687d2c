"""Reference motion clips for the 15-body humanoid and their kinematic playback.

The kinematic pedestrians (the fast mode and the "animation replay" baseline) play a looping walk
cycle whose phase advances with the distance walked, so feet neither slide nor moonwalk at any speed.
The clip used by default is DeepMimic's ``humanoid3d_walk`` that ships inside ``pybullet_data``
(the same 15-body humanoid as ``humanoid/humanoid.urdf``), so kinematic mode needs no extra data.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pybullet_data
from scipy.spatial.transform import Rotation

# The pedestrian body: pybullet_data's 15-body DeepMimic humanoid, loaded with globalScaling=0.25
# (about 1.64 m tall) and URDF_MAINTAIN_LINK_ORDER (link index = joint index).
HUMANOID_URDF = "humanoid/humanoid.urdf"
HUMANOID_SCALE = 0.25
N_LINKS = 15

# Joint indices of humanoid/humanoid.urdf (URDF_MAINTAIN_LINK_ORDER) in the order DeepMimic clips
# store them; the wrists (8, 14) are fixed joints.
CLIP_JOINTS: tuple[int, ...] = (1, 2, 3, 4, 5, 6, 7, 9, 10, 11, 12, 13)
REVOLUTE_JOINTS: frozenset[int] = frozenset({4, 7, 10, 13})  # knees and elbows: one angle each
SPHERICAL_JOINTS: tuple[int, ...] = tuple(j for j in CLIP_JOINTS if j not in REVOLUTE_JOINTS)

# The DeepMimic clips are y-up; navzoo is z-up. Rotating +90 deg about x maps clip y to world z and
# keeps the clip's forward axis (+x) as the body's forward axis.
_Y_UP_TO_Z_UP = Rotation.from_euler("x", np.pi / 2)


@dataclass(frozen=True)
class WalkCycle:
    """One looping locomotion cycle, stored as arrays ready for vectorised playback.

    Attributes:
        spherical: (F, 8, 4) local joint quaternions (x, y, z, w) of the spherical joints.
        revolute: (F, 4) angles (rad) of knees and elbows.
        root_height: (F,) pelvis height (m).
        root_tilt: (F, 4) root orientation without its heading, z-up frame, quaternion (x, y, z, w).
        cycle_length: distance (m) the root advances over one cycle.
        duration: seconds per cycle at the recorded speed.
    """

    spherical: np.ndarray
    revolute: np.ndarray
    root_height: np.ndarray
    root_tilt: np.ndarray
    cycle_length: float
    duration: float

    @property
    def speed(self) -> float:
        """Walking speed of the recording (m/s)."""
        return self.cycle_length / self.duration

    @property
    def n_frames(self) -> int:
        return self.revolute.shape[0]


def load_deepmimic_cycle(path: str | Path | None = None) -> WalkCycle:
    """Load a looping DeepMimic clip (default: pybullet_data's ``humanoid3d_walk.txt``)."""
    path = Path(path) if path is not None else Path(pybullet_data.getDataPath()) / "data/motions/humanoid3d_walk.txt"
    try:
        frames = np.asarray(json.loads(path.read_text())["Frames"], dtype=np.float64)
    except (OSError, KeyError, ValueError) as exc:
        raise ValueError(f"cannot read DeepMimic clip {path}: {exc}") from exc
    if frames.ndim != 2 or frames.shape[1] != 44:
        raise ValueError(f"DeepMimic clip {path}: expected frames of 44 numbers, got shape {frames.shape}")
    # The last frame repeats the first pose one cycle later: drop it from the pose table but use it
    # for the cycle length.
    dur = float(frames[:-1, 0].sum())
    disp = frames[-1, [1, 3]] - frames[0, [1, 3]]
    cycle_length = float(np.linalg.norm(disp))
    poses = frames[:-1]
    n = poses.shape[0]
    q = poses[:, 8:]
    sph, rev = [], []
    k = 0
    for j in CLIP_JOINTS:
        if j in REVOLUTE_JOINTS:
            rev.append(q[:, k])
            k += 1
        else:
            w, x, y, z = q[:, k], q[:, k + 1], q[:, k + 2], q[:, k + 3]
            sph.append(np.stack([x, y, z, w], axis=1))
            k += 4
    spherical = np.stack(sph, axis=1)
    revolute = np.stack(rev, axis=1)
    root_q = poses[:, [5, 6, 7, 4]]  # (w, x, y, z) -> (x, y, z, w)
    root_world = _Y_UP_TO_Z_UP * Rotation.from_quat(root_q)
    # Split off the heading (yaw about world z relative to the walking direction) so that the body
    # can be turned to any heading while keeping the clip's natural sway.
    # Clip axis z maps to world -y under the +90 deg rotation about x.
    heading_dir = float(np.arctan2(-disp[1], disp[0]))
    tilt = Rotation.from_euler("z", -np.full((n, 1), heading_dir)) * root_world
    return WalkCycle(
        spherical=spherical,
        revolute=revolute,
        root_height=poses[:, 2].copy(),
        root_tilt=tilt.as_quat(),
        cycle_length=cycle_length,
        duration=dur,
    )


_IDENTITY = np.array([0.0, 0.0, 0.0, 1.0])


def sample_cycle(cycle: WalkCycle, phase: np.ndarray, gait: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Poses of N humanoids at cycle phases ``phase`` in [0, 1), blended toward standing by ``gait``.

    Args:
        cycle: the walk cycle.
        phase: (N,) cycle phases.
        gait: (N,) in [0, 1]: 1 = full walking pose, 0 = neutral standing pose (used when people
            stop, so that a standing person does not freeze mid-stride).

    Returns:
        ``(spherical (N, 8, 4), revolute (N, 4), root_height (N,), root_tilt (N, 4))``.
    """
    f = (np.asarray(phase) % 1.0) * cycle.n_frames
    i0 = np.floor(f).astype(int) % cycle.n_frames
    i1 = (i0 + 1) % cycle.n_frames
    a = (f - np.floor(f))[:, None]
    g = np.clip(np.asarray(gait, dtype=np.float64), 0.0, 1.0)[:, None]
    sph = _nlerp(cycle.spherical[i0], cycle.spherical[i1], a[:, :, None])
    sph = _nlerp(np.broadcast_to(_IDENTITY, sph.shape), sph, g[:, :, None])
    rev = ((1 - a) * cycle.revolute[i0] + a * cycle.revolute[i1]) * g
    stand_h = float(cycle.root_height.max())
    h = ((1 - a[:, 0]) * cycle.root_height[i0] + a[:, 0] * cycle.root_height[i1]) * g[:, 0] + stand_h * (1 - g[:, 0])
    tilt = _nlerp(cycle.root_tilt[i0], cycle.root_tilt[i1], a)
    # Standing upright: the y-up -> z-up rotation alone, no sway.
    tilt = _nlerp(np.broadcast_to(_Y_UP_TO_Z_UP.as_quat(), tilt.shape), tilt, g)
    return sph, rev, h, tilt


def _nlerp(q0: np.ndarray, q1: np.ndarray, t: np.ndarray) -> np.ndarray:
    """Normalised linear interpolation of quaternions along the shortest arc (vectorised)."""
    sign = np.where(np.sum(q0 * q1, axis=-1, keepdims=True) < 0, -1.0, 1.0)
    q = (1 - t) * q0 + t * sign * q1
    return q / np.linalg.norm(q, axis=-1, keepdims=True)
