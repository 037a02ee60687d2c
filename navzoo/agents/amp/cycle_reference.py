"""A :class:`~navzoo.agents.reference.ReferenceMotion` over the DeepMimic walk cycle shipped with pybullet_data.

Used by the tests and by the stage-0 check until the motion library (real mocap) lands; everything
downstream takes any ``ReferenceMotion``.

The cycle loops forever: the pose repeats every ``duration`` seconds while the root advances along
+x at the clip's mean speed (``cycle_length / duration``), facing +x, with the clip's own height and
tilt (heading removed, see :func:`navzoo.agents.motion.load_deepmimic_cycle`). Velocities are finite
differences between consecutive frames: constant over each frame interval, the exact derivative of the
piecewise-linear (nlerp) pose playback.

pybullet_data's ``humanoid3d_walk`` is two mirrored half cycles stitched together, and the pose jumps
at both seams (frames 18 -> 19 and 37 -> 0: the root turns 7 degrees and a shoulder 29 degrees in one
frame, i.e. 3.8 and 15 rad/s). Such *glitch* intervals (a joint or the root turning faster than
3 rad/s and more than three times as fast as in both neighbouring intervals) get the mean velocity of
their neighbours instead of the jump's, so that reference state initialisation there does not launch
the limbs; the pose itself still crosses the seam within one frame.
"""

from __future__ import annotations

import numpy as np

from navzoo.agents.amp.features import quat_conj, quat_mul, quat_to_rotvec
from navzoo.agents.motion import WalkCycle, load_deepmimic_cycle, sample_cycle
from navzoo.agents.reference import ReferenceState


class CycleReference:
    """One looping clip (``clip_names() == ["humanoid3d_walk"]``) from a :class:`WalkCycle`.

    Args:
        cycle: the cycle to play (default: pybullet_data's ``humanoid3d_walk``).
        origin: (x, y) of the root at t = 0.
    """

    def __init__(self, cycle: WalkCycle | None = None, origin: tuple[float, float] = (0.0, 0.0)) -> None:
        self.cycle = cycle if cycle is not None else load_deepmimic_cycle()
        self.origin = np.asarray(origin, dtype=np.float64)
        self.frame_dt = self.cycle.duration / self.cycle.n_frames
        self._seg_vel, self.glitch_frames = _segment_velocities(self.cycle)

    def clip_names(self) -> list[str]:
        return ["humanoid3d_walk"]

    def duration(self, clip: int) -> float:
        if int(clip) != 0:
            raise IndexError(f"CycleReference has one clip, got clip {clip}")
        return float(self.cycle.duration)

    @property
    def speed(self) -> float:
        return self.cycle.speed

    def _pose(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        t = np.asarray(t, dtype=np.float64)
        sph, rev, height, tilt = sample_cycle(self.cycle, t / self.cycle.duration, np.ones_like(t))
        pos = np.stack(
            [self.origin[0] + self.cycle.speed * t, np.full_like(t, self.origin[1]), height], axis=-1
        )
        return pos, tilt, sph, rev

    def state_at(self, clip: np.ndarray, t: np.ndarray) -> ReferenceState:
        """Batched states at times ``t`` (B,) of clips ``clip`` (B,) (all must be 0)."""
        clip = np.atleast_1d(np.asarray(clip))
        t = np.atleast_1d(np.asarray(t, dtype=np.float64))
        clip, t = np.broadcast_arrays(clip, t)
        if np.any(clip != 0):
            raise IndexError("CycleReference has one clip (index 0)")
        pos, quat, sph, rev = self._pose(t)
        # The same frame index as sample_cycle's.
        k = np.floor((t / self.cycle.duration % 1.0) * self.cycle.n_frames).astype(int) % self.cycle.n_frames
        dz, ang, sph_vel, rev_vel = (v[k] for v in self._seg_vel)
        lin = np.stack([np.full_like(t, self.cycle.speed), np.zeros_like(t), dz], axis=-1)
        return ReferenceState(
            root_pos=pos,
            root_quat=quat,
            sph=sph,
            rev=rev,
            root_lin_vel=lin,
            root_ang_vel=ang,
            sph_vel=sph_vel,
            rev_vel=rev_vel,
        )


def _segment_velocities(c: WalkCycle) -> tuple[tuple[np.ndarray, ...], tuple[int, ...]]:
    """Per frame interval k -> k+1 (cyclic): root vertical speed (F,), world root angular velocity
    (F, 3), child-frame joint angular velocities (F, 8, 3), revolute speeds (F, 4); glitch intervals
    replaced by the mean of their neighbours. Returns the velocities and the glitch intervals."""
    dt = c.duration / c.n_frames
    nxt = lambda a: np.roll(a, -1, axis=0)  # noqa: E731
    dz = (nxt(c.root_height) - c.root_height) / dt
    ang = quat_to_rotvec(quat_mul(nxt(c.root_tilt), quat_conj(c.root_tilt))) / dt
    sph = quat_to_rotvec(quat_mul(quat_conj(c.spherical), nxt(c.spherical))) / dt
    rev = (nxt(c.revolute) - c.revolute) / dt
    speed = np.concatenate(
        [np.linalg.norm(ang, axis=-1)[:, None], np.linalg.norm(sph, axis=-1), np.abs(rev)], axis=1
    )
    neigh = np.maximum(np.roll(speed, 1, axis=0), np.roll(speed, -1, axis=0))
    glitch = np.any((speed > 3.0) & (speed > 3.0 * neigh), axis=1)
    out = []
    for v in (dz, ang, sph, rev):
        v = v.copy()
        fixed = 0.5 * (np.roll(v, 1, axis=0) + np.roll(v, -1, axis=0))
        v[glitch] = fixed[glitch]
        out.append(v)
    return tuple(out), tuple(int(k) for k in np.flatnonzero(glitch))
