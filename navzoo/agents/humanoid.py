"""Pedestrian bodies: the 15-body humanoid of ``pybullet_data/humanoid/humanoid.urdf`` in PyBullet.

In *kinematic* mode (this module) the root follows the pedestrian's planar motion and the joints
play a reference walk cycle whose phase advances with the distance walked. The bodies are fixed-base
multibodies, posed every control step, that collide with robots (the robots feel them as solid); they
do not collide with each other or with the scene, because their motion is scripted. The AMP
controller drives the same bodies through joint PD targets instead (dynamic base, all collisions).
"""

from __future__ import annotations

import numpy as np
import pybullet as p
from scipy.spatial.transform import Rotation

from navzoo.agents.motion import (
    CLIP_JOINTS,
    HUMANOID_SCALE,
    HUMANOID_URDF,
    N_LINKS,
    REVOLUTE_JOINTS,
    WalkCycle,
    load_deepmimic_cycle,
    sample_cycle,
)
from navzoo.sim import quiet
from navzoo.world.builder import GROUP_HUMAN, GROUP_ROBOT


class HumanoidBodies:
    """All pedestrian bodies of one world, posed kinematically from arrays."""

    def __init__(self, client: int, n: int, cycle: WalkCycle | None = None) -> None:
        self.client = client
        self.n = n
        self.cycle = cycle if cycle is not None else load_deepmimic_cycle()
        self.ids: list[int] = []
        with quiet():  # the URDF importer prints a warning per joint without an <axis>
            for i in range(n):
                body = p.loadURDF(
                    HUMANOID_URDF,
                    [3.0 * i, -2000.0, 1.0],
                    useFixedBase=True,
                    globalScaling=HUMANOID_SCALE,
                    flags=p.URDF_MAINTAIN_LINK_ORDER,
                    physicsClientId=client,
                )
                self.ids.append(body)
        for body in self.ids:
            for link in range(-1, N_LINKS):
                p.setCollisionFilterGroupMask(body, link, GROUP_HUMAN, GROUP_ROBOT, physicsClientId=client)
            # Kinematic bodies are posed each step: the default velocity motors of the revolute
            # joints would only cost solver time.
            p.setJointMotorControlArray(
                body, sorted(REVOLUTE_JOINTS), p.VELOCITY_CONTROL, forces=[0.0] * len(REVOLUTE_JOINTS),
                physicsClientId=client,
            )
        self.phase = np.zeros(n)

    def reset(self, pos: np.ndarray, yaw: np.ndarray, phase: np.ndarray) -> None:
        self.phase = np.asarray(phase, dtype=np.float64) % 1.0
        self.pose(pos, yaw, np.zeros(self.n))

    def advance(self, speed: np.ndarray, dt: float) -> None:
        """Advance each walk cycle by the distance walked this step."""
        self.phase = (self.phase + np.asarray(speed) * dt / self.cycle.cycle_length) % 1.0

    def pose(self, pos: np.ndarray, yaw: np.ndarray, speed: np.ndarray) -> None:
        """Pose every body at planar position ``pos`` (N, 2), heading ``yaw`` (N,), at speed ``speed``.

        The joint pose is computed for all bodies at once; PyBullet then needs two calls per body
        (base pose, joint states), the minimum its API allows.
        """
        gait = np.clip(np.asarray(speed) / 0.4, 0.0, 1.0)
        sph, rev, height, tilt = sample_cycle(self.cycle, self.phase, gait)
        root = (Rotation.from_euler("z", np.asarray(yaw)[:, None]) * Rotation.from_quat(tilt)).as_quat()
        sph_l = sph.tolist()
        rev_l = rev.tolist()
        root_l = root.tolist()
        for i, body in enumerate(self.ids):
            p.resetBasePositionAndOrientation(
                body, [float(pos[i, 0]), float(pos[i, 1]), float(height[i])], root_l[i], physicsClientId=self.client
            )
            s, r = sph_l[i], rev_l[i]
            targets = [s[0], s[1], s[2], [r[0]], s[3], s[4], [r[1]], s[5], [r[2]], s[6], s[7], [r[3]]]
            p.resetJointStatesMultiDof(body, CLIP_JOINTS, targets, physicsClientId=self.client)
