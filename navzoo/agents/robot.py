"""Robot bases: the command model (pure functions) and their PyBullet bodies.

A robot is a real dynamic PyBullet body (a cylinder, by default close to a Nova Carter / AgileX
Scout Mini footprint) that collides with the scene, people and other robots. Each control step the
normalised action is turned into a velocity command under speed and acceleration limits, and the
command is applied as the body's base velocity at every physics substep, so contacts act on it.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

import numpy as np
import pybullet as p

from navzoo.world.builder import GROUP_HUMAN, GROUP_ROBOT, GROUP_STATIC

Kinematics = Literal["diff_drive", "holonomic"]


@dataclass(frozen=True)
class RobotSpec:
    """Physical and command limits of one robot model.

    Attributes:
        radius: footprint radius (m).
        height: body height (m), only for the 3D body.
        mass: body mass (kg).
        max_speed: maximum linear speed (m/s); action 1.0 maps to it.
        max_turn_rate: maximum angular speed (rad/s) of a differential-drive base.
        max_accel: linear acceleration limit (m/s^2).
        max_ang_accel: angular acceleration limit (rad/s^2).
        kinematics: ``"diff_drive"`` (action = (v, omega)) or ``"holonomic"`` (action = (vx, vy) in the
            world frame, CrowdNav's holonomic robot).
    """

    radius: float = 0.3
    height: float = 0.4
    mass: float = 30.0
    max_speed: float = 1.0
    max_turn_rate: float = 2.0
    max_accel: float = 2.0
    max_ang_accel: float = 6.0
    kinematics: Kinematics = "diff_drive"

    def __post_init__(self) -> None:
        for name in ("radius", "height", "mass", "max_speed", "max_turn_rate", "max_accel", "max_ang_accel"):
            value = getattr(self, name)
            if not (isinstance(value, (int, float)) and np.isfinite(value) and value > 0):
                raise ValueError(f"RobotSpec.{name} must be a finite number > 0, got {value!r}")
        if self.kinematics not in ("diff_drive", "holonomic"):
            raise ValueError(
                f"RobotSpec.kinematics must be 'diff_drive' or 'holonomic', got {self.kinematics!r}"
            )


def command_velocity(
    action: np.ndarray,
    prev_cmd: np.ndarray,
    yaw: np.ndarray,
    spec: RobotSpec,
    dt: float,
) -> tuple[np.ndarray, np.ndarray]:
    """Turn normalised actions into limited velocity commands, vectorised over robots.

    Args:
        action: (R, 2) actions in [-1, 1] (already clipped).
        prev_cmd: (R, 2) previous command in the action's own units: (v, omega) for diff drive,
            (vx, vy) world frame for holonomic.
        yaw: (R,) current headings (rad).
        spec: the robot model.
        dt: control period (s).

    Returns:
        ``(cmd, world)``: the new command (R, 2) in the same units as ``prev_cmd`` and the
        world-frame planar velocity plus yaw rate (R, 3) = (vx, vy, omega).
    """
    action = np.asarray(action, dtype=np.float64)
    if spec.kinematics == "diff_drive":
        target = action * np.array([spec.max_speed, spec.max_turn_rate])
        step = np.array([spec.max_accel, spec.max_ang_accel]) * dt
        cmd = prev_cmd + np.clip(target - prev_cmd, -step, step)
        world = np.stack([cmd[:, 0] * np.cos(yaw), cmd[:, 0] * np.sin(yaw), cmd[:, 1]], axis=1)
        return cmd, world
    # Holonomic: the action is a world-frame velocity; its norm is capped at max_speed (a disc, not
    # a square, so diagonal moves are no faster) and its change at max_accel * dt.
    target = action * spec.max_speed
    norm = np.linalg.norm(target, axis=1, keepdims=True)
    target = np.where(norm > spec.max_speed, target * spec.max_speed / np.maximum(norm, 1e-12), target)
    delta = target - prev_cmd
    dnorm = np.linalg.norm(delta, axis=1, keepdims=True)
    max_step = spec.max_accel * dt
    delta = np.where(dnorm > max_step, delta * max_step / np.maximum(dnorm, 1e-12), delta)
    cmd = prev_cmd + delta
    # A holonomic robot faces where it moves (for rendering and observations); it keeps its heading
    # when (nearly) at rest.
    speed = np.linalg.norm(cmd, axis=1)
    desired = np.where(speed > 0.05, np.arctan2(cmd[:, 1], cmd[:, 0]), yaw)
    omega = np.clip(wrap_angle(desired - yaw) / dt, -spec.max_turn_rate, spec.max_turn_rate)
    world = np.concatenate([cmd, omega[:, None]], axis=1)
    return cmd, world


def wrap_angle(a: np.ndarray | float) -> np.ndarray:
    """Wrap angles to [-pi, pi)."""
    return (np.asarray(a) + np.pi) % (2 * np.pi) - np.pi


class RobotBodies:
    """The PyBullet bodies of all robots of one world (created once, moved on reset)."""

    def __init__(self, client: int, spec: RobotSpec, n: int) -> None:
        self.client = client
        self.spec = spec
        self.n = n
        col = p.createCollisionShape(p.GEOM_CYLINDER, radius=spec.radius, height=spec.height, physicsClientId=client)
        vis = p.createVisualShape(
            p.GEOM_CYLINDER, radius=spec.radius, length=spec.height, rgbaColor=[0.15, 0.35, 0.85, 1], physicsClientId=client
        )
        self.ids: list[int] = []
        for i in range(n):
            body = p.createMultiBody(
                baseMass=spec.mass,
                baseCollisionShapeIndex=col,
                baseVisualShapeIndex=vis,
                basePosition=[10.0 * i, -1000.0, spec.height / 2],
                physicsClientId=client,
            )
            # Zero friction: the base is driven by setting its velocity, so ground friction would
            # only add drag and tipping torques. Contacts with people and walls still push it.
            p.changeDynamics(body, -1, lateralFriction=0.0, spinningFriction=0.0, rollingFriction=0.0,
                             linearDamping=0.0, angularDamping=0.0, physicsClientId=client)
            p.setCollisionFilterGroupMask(body, -1, GROUP_ROBOT, GROUP_STATIC | GROUP_ROBOT | GROUP_HUMAN,
                                          physicsClientId=client)
            self.ids.append(body)
        self._z = spec.height / 2 + 1e-3

    def reset(self, pos: np.ndarray, yaw: np.ndarray) -> None:
        """Place robot i at ``pos[i]`` facing ``yaw[i]``, at rest."""
        for i in range(self.n):
            self.place(i, pos[i], float(yaw[i]))

    def place(self, i: int, xy: np.ndarray, yaw: float) -> None:
        body = self.ids[i]
        quat = p.getQuaternionFromEuler([0.0, 0.0, yaw])
        p.resetBasePositionAndOrientation(body, [float(xy[0]), float(xy[1]), self._z], quat, physicsClientId=self.client)
        p.resetBaseVelocity(body, [0, 0, 0], [0, 0, 0], physicsClientId=self.client)

    def remove(self, i: int) -> None:
        """Take a finished robot out of the world: no collisions, parked far away."""
        body = self.ids[i]
        p.setCollisionFilterGroupMask(body, -1, 0, 0, physicsClientId=self.client)
        p.resetBasePositionAndOrientation(body, [10.0 * i, -1000.0, self._z], [0, 0, 0, 1], physicsClientId=self.client)
        p.resetBaseVelocity(body, [0, 0, 0], [0, 0, 0], physicsClientId=self.client)

    def restore(self, i: int) -> None:
        p.setCollisionFilterGroupMask(self.ids[i], -1, GROUP_ROBOT, GROUP_STATIC | GROUP_ROBOT | GROUP_HUMAN,
                                      physicsClientId=self.client)

    def apply_velocity(self, world_vel: np.ndarray, active: np.ndarray) -> None:
        """Set the base velocity (vx, vy, omega) of every active robot (called at each substep)."""
        for i in np.flatnonzero(active):
            vx, vy, w = world_vel[i]
            p.resetBaseVelocity(self.ids[i], [vx, vy, 0.0], [0.0, 0.0, w], physicsClientId=self.client)

    def read_state(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Positions (R, 2), yaws (R,), tilt flags (R,) bool, one PyBullet query per robot."""
        pos = np.empty((self.n, 2))
        yaw = np.empty(self.n)
        tilt = np.zeros(self.n, dtype=bool)
        for i, body in enumerate(self.ids):
            xyz, quat = p.getBasePositionAndOrientation(body, physicsClientId=self.client)
            roll, pitch, yaw[i] = p.getEulerFromQuaternion(quat)
            pos[i] = xyz[:2]
            tilt[i] = abs(roll) > 1e-3 or abs(pitch) > 1e-3 or abs(xyz[2] - self._z) > 0.02
        return pos, yaw, tilt

    def straighten(self, i: int, xy: np.ndarray, yaw: float) -> None:
        """Keep the base planar: undo roll, pitch and height drift from contacts, keep x, y, yaw."""
        body = self.ids[i]
        lin, ang = p.getBaseVelocity(body, physicsClientId=self.client)
        quat = p.getQuaternionFromEuler([0.0, 0.0, yaw])
        p.resetBasePositionAndOrientation(body, [float(xy[0]), float(xy[1]), self._z], quat, physicsClientId=self.client)
        p.resetBaseVelocity(body, [lin[0], lin[1], 0.0], [0.0, 0.0, ang[2]], physicsClientId=self.client)

    def contacts(self, i: int, tolerance: float = 1e-3) -> list[int]:
        """Body ids touching robot i after the last physics step.

        PyBullet's contact manifold also keeps points that are up to its contact margin *apart*
        (positive distance): only points at distance <= ``tolerance`` count as touching.
        """
        return [c[2] for c in p.getContactPoints(bodyA=self.ids[i], physicsClientId=self.client) if c[8] <= tolerance]
