"""The reference-motion interface shared by the motion library, kinematic playback and the AMP controller.

A reference state describes the 15-body humanoid of ``pybullet_data/humanoid/humanoid.urdf`` (loaded
with ``globalScaling=0.25``, ``URDF_MAINTAIN_LINK_ORDER``) in navzoo's z-up world:

- ``root_pos`` (3,): base position (m), world frame, z up.
- ``root_quat`` (4,): base orientation (x, y, z, w) *as PyBullet's base orientation* of that URDF,
  i.e. it already contains the URDF's y-up -> z-up rotation (standing upright facing +x with zero
  joint angles = ``Rotation.from_euler("x", pi/2)``).
- ``sph`` (8, 4): local joint quaternions (x, y, z, w) of the spherical joints in the order
  :data:`navzoo.agents.motion.SPHERICAL_JOINTS` = (1 chest, 2 neck, 3 right_hip, 5 right_ankle,
  6 right_shoulder, 9 left_hip, 11 left_ankle, 12 left_shoulder), as ``resetJointStatesMultiDof``
  takes them.
- ``rev`` (4,): angles (rad) of the revolute joints (4 right_knee, 7 right_elbow, 10 left_knee,
  13 left_elbow).
- ``root_lin_vel`` (3,), ``root_ang_vel`` (3,): world frame (m/s, rad/s).
- ``sph_vel`` (8, 3): joint angular velocities in each joint's local (child) frame (rad/s), as
  PyBullet reports for spherical joints; ``rev_vel`` (4,) (rad/s).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import Protocol, runtime_checkable

import numpy as np


@dataclass(frozen=True)
class ReferenceState:
    """One humanoid pose and its velocities (see the module docstring for frames and order)."""

    root_pos: np.ndarray
    root_quat: np.ndarray
    sph: np.ndarray
    rev: np.ndarray
    root_lin_vel: np.ndarray
    root_ang_vel: np.ndarray
    sph_vel: np.ndarray
    rev_vel: np.ndarray

    def translated(self, offset: np.ndarray) -> ReferenceState:
        """The same state(s) moved by ``offset`` ((..., 3), broadcast against ``root_pos``); nothing turns."""
        return dataclasses.replace(self, root_pos=np.asarray(self.root_pos) + np.asarray(offset))


@runtime_checkable
class ReferenceMotion(Protocol):
    """A set of clips that can be sampled at any time (vectorised over queries)."""

    def clip_names(self) -> list[str]: ...

    def duration(self, clip: int) -> float: ...

    def state_at(self, clip: np.ndarray, t: np.ndarray) -> ReferenceState:
        """Batched states: every field gets a leading (B,) axis for B (clip, time) queries."""
        ...
