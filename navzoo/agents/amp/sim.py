"""Physics humanoids for the AMP pedestrian controller: N free-base 15-body humanoids in one PyBullet client.

Each humanoid is ``pybullet_data/humanoid/humanoid.urdf`` (DeepMimic's character, ``globalScaling=0.25``,
``URDF_MAINTAIN_LINK_ORDER``, 45 kg: masses are not scaled, so DeepMimic's gains apply unchanged) driven
by joint PD targets set at the control rate (30 Hz) over 120 Hz physics. Measured facts that shape this
module (``docs/amp_sim.md`` has the numbers):

* ``STABLE_PD_CONTROL`` (the default ``pd_mode="stable"``) computes the joint torques *once*, when the
  command is sent, and applies them for the next ``stepSimulation`` only: :meth:`PhysicsHumanoids.step`
  re-sends the command before every physics substep (sent once per control step, the body goes limp
  for the other substeps and collapses). Its torques are not reported back, so
  :meth:`PhysicsHumanoids.joint_power` evaluates the PD law itself.
* Stable PD is stable at 120 Hz (no blow-up in any run) but contact-blind: it predicts the next state
  of a free-floating body, so a joint whose child side is light and loaded through a contact (the
  ankles) delivers a few percent of ``Kp e`` (measured with pybullet's Python SPD: 2.6 N m at 23
  degrees of ankle error, where ``Kp e`` = 158 N m). A standing body is an inverted pendulum on nearly
  free ankles and falls after about 2.3 s at any rate from 120 to 1200 Hz and any gain scale; open-loop
  tracking of the walk falls after about 0.75 s. A policy has to balance it, as in DeepMimic.
* ``pd_mode="motor"`` uses PyBullet's constraint-based ``POSITION_CONTROL`` motors instead (torque-limited
  servos solved together with the contacts): a standing body stands, open-loop walk tracking lasts
  about 1.1 s, at 55-70 % of the throughput (30 solver iterations instead of 10).
* The ground is a box, not a ``GEOM_PLANE``: box-plane contacts keep one point per step and the feet
  sink 7-8 cm into a plane at 120 Hz (open-loop falls after 0.17 s).

Frames and joint order follow :mod:`navzoo.agents.reference`. Collision groups follow
:mod:`navzoo.world.builder`: humans are ``GROUP_HUMAN`` and collide with the scene and ground
(``GROUP_STATIC``), robots (``GROUP_ROBOT``) and other humans; a body's own links collide with each
other except with their parents and ancestors (``URDF_USE_SELF_COLLISION_EXCLUDE_ALL_PARENTS``, as in
pybullet's DeepMimic env), unless ``self_collision=False``.
"""

from __future__ import annotations

import functools
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
import pybullet as p

from navzoo.agents.amp.features import (
    FOOT_LINKS,
    KEY_LINKS,
    N_LINKS,
    REV,
    SPH,
    forward_kinematics,
    load_humanoid_model,
    quat_conj,
    quat_from_rotvec,
    quat_mul,
    quat_rotate,
    quat_to_rotvec,
    yaw_quat,
)
from navzoo.agents.motion import CLIP_JOINTS, HUMANOID_SCALE, HUMANOID_URDF
from navzoo.agents.reference import ReferenceState
from navzoo.sim import quiet
from navzoo.world.builder import GROUP_HUMAN, GROUP_ROBOT, GROUP_STATIC, MASK_ALL

#: Joints driven by the PD controller, in the order of ``setJointMotorControlMultiDofArray`` calls
#: (the DeepMimic clip order: 1 chest, 2 neck, 3 r_hip, 4 r_knee, 5 r_ankle, 6 r_shoulder, 7 r_elbow,
#: 9 l_hip, 10 l_knee, 11 l_ankle, 12 l_shoulder, 13 l_elbow).
CONTROL_JOINTS: tuple[int, ...] = CLIP_JOINTS
_SPH_POS = [CONTROL_JOINTS.index(j) for j in SPH]  # positions of the spherical joints in CONTROL_JOINTS
_REV_POS = [CONTROL_JOINTS.index(j) for j in REV]
_IS_REV = [j in REV for j in CONTROL_JOINTS]

ACTION_DIM = 3 * len(SPH) + len(REV)  # 28
#: Base orientation of a body standing upright facing +x (the URDF is y-up): R_x(+90 deg).
UPRIGHT: tuple[float, float, float, float] = (float(np.sin(np.pi / 4)), 0.0, 0.0, float(np.cos(np.pi / 4)))
GROUND_HALF_SIZE = 500.0  # m, half side of the box ground

_JOINT_NAME = {
    1: "chest",
    2: "neck",
    3: "hip",
    4: "knee",
    5: "ankle",
    6: "shoulder",
    7: "elbow",
    9: "hip",
    10: "knee",
    11: "ankle",
    12: "shoulder",
    13: "elbow",
}


@dataclass(frozen=True)
class PDGains:
    """Per-joint stable-PD gains and torque limits, keyed by joint kind (left and right share).

    Attributes:
        kp: position gain (N m / rad); kd: velocity gain (N m s / rad); max_torque: per-axis torque
        limit (N m), passed to PyBullet as ``forces``.
    """

    kp: dict[str, float]
    kd: dict[str, float]
    max_torque: dict[str, float]

    @staticmethod
    def deepmimic() -> PDGains:
        """DeepMimic's ``humanoid3d_ctrl.txt`` (= pybullet ``humanoid_stable_pd.py``): Kd = Kp / 10."""
        kp = {
            "chest": 1000.0,
            "neck": 100.0,
            "hip": 500.0,
            "knee": 500.0,
            "ankle": 400.0,
            "shoulder": 400.0,
            "elbow": 300.0,
        }
        tq = {
            "chest": 200.0,
            "neck": 50.0,
            "hip": 200.0,
            "knee": 150.0,
            "ankle": 90.0,
            "shoulder": 100.0,
            "elbow": 60.0,
        }
        return PDGains(kp=kp, kd={k: v / 10.0 for k, v in kp.items()}, max_torque=tq)

    def arrays(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(kp, kd, max_torque), each (12,) in ``CONTROL_JOINTS`` order."""
        names = [_JOINT_NAME[j] for j in CONTROL_JOINTS]
        return (
            np.array([self.kp[n] for n in names]),
            np.array([self.kd[n] for n in names]),
            np.array([self.max_torque[n] for n in names]),
        )


DEFAULT_GAINS = PDGains.deepmimic()

# ----------------------------------------------------------------------------------------------
# Action space
# ----------------------------------------------------------------------------------------------

#: Spherical joints (order ``SPH``: chest, neck, r_hip, r_ankle, r_shoulder, l_hip, l_ankle,
#: l_shoulder): an action component a in [-1, 1] is ``scale * a`` rad of rotation vector about the
#: joint's local x, y, z axis (x forward, y up, z to the body's right). Every scale is < pi / sqrt(3),
#: so the whole action cube maps to rotation angles below pi and the mapping is invertible there.
SPH_ACTION_SCALE = np.array([1.2, 1.0, 1.8, 1.0, 1.8, 1.8, 1.0, 1.8])
#: Revolute joints (order ``REV``: r_knee, r_elbow, l_knee, l_elbow): angle = offset + scale * a, so
#: knees span [-2.8, 0.2] rad and elbows [-0.2, 2.8] rad (URDF limits: knee [-3.14, 0], elbow [0, 3.14]).
REV_ACTION_OFFSET = np.array([-1.3, 1.3, -1.3, 1.3])
REV_ACTION_SCALE = np.array([1.5, 1.5, 1.5, 1.5])


def actions_to_targets(a: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Policy actions (N, 28) -> PD targets ``(sph (N, 8, 4) quaternions, rev (N, 4) angles)``.

    ``a[:, :24]`` are 8 spherical joints x 3 exponential-map components (order ``SPH``), scaled by
    :data:`SPH_ACTION_SCALE`; ``a[:, 24:]`` the 4 revolute joints (order ``REV``), mapped by
    :data:`REV_ACTION_OFFSET` + :data:`REV_ACTION_SCALE` * a. No clipping here: clip to [-1, 1] before
    calling to stay within the documented ranges.
    """
    a = np.asarray(a, dtype=np.float64)
    n = a.shape[0]
    rotvec = a[:, : 3 * len(SPH)].reshape(n, len(SPH), 3) * SPH_ACTION_SCALE[:, None]
    rev = REV_ACTION_OFFSET + REV_ACTION_SCALE * a[:, 3 * len(SPH) :]
    return quat_from_rotvec(rotvec), rev


def targets_to_actions(sph: np.ndarray, rev: np.ndarray) -> np.ndarray:
    """Inverse of :func:`actions_to_targets` (the rotation vector of the shortest arc; exact for
    actions in [-1, 1])."""
    sph = np.asarray(sph, dtype=np.float64)
    n = sph.shape[0]
    a_sph = quat_to_rotvec(sph) / SPH_ACTION_SCALE[:, None]
    a_rev = (np.asarray(rev, dtype=np.float64) - REV_ACTION_OFFSET) / REV_ACTION_SCALE
    return np.concatenate([a_sph.reshape(n, -1), a_rev], axis=-1)


# ----------------------------------------------------------------------------------------------
# Bodies
# ----------------------------------------------------------------------------------------------


def _joint_lists(sph: np.ndarray, rev: np.ndarray) -> list[list[list[float]]]:
    """Per humanoid, per CONTROL_JOINT, the PyBullet target list ([x, y, z, w] or [angle])."""
    sph_l = np.asarray(sph, dtype=np.float64).tolist()
    rev_l = np.asarray(rev, dtype=np.float64).tolist()
    out = []
    for s, r in zip(sph_l, rev_l, strict=True):
        out.append([s[0], s[1], s[2], [r[0]], s[3], s[4], [r[1]], s[5], [r[2]], s[6], s[7], [r[3]]])
    return out


def _vel_lists(sph_vel: np.ndarray, rev_vel: np.ndarray) -> list[list[list[float]]]:
    sv = np.asarray(sph_vel, dtype=np.float64).tolist()
    rv = np.asarray(rev_vel, dtype=np.float64).tolist()
    out = []
    for s, r in zip(sv, rv, strict=True):
        out.append([s[0], s[1], s[2], [r[0]], s[3], s[4], [r[1]], s[5], [r[2]], s[6], s[7], [r[3]]])
    return out


class PhysicsHumanoids:
    """N dynamic humanoids in one PyBullet client, driven by joint PD targets.

    Args:
        client: an open PyBullet client. Its time step is set to ``1 / physics_hz``, its gravity to
            -9.81 m/s^2 along z and its ``numSolverIterations`` to ``solver_iterations`` (client-wide
            settings shared with anything else in the client).
        n: number of humanoids.
        physics_hz, control_hz: physics and control rates; ``physics_hz`` must be a multiple of
            ``control_hz``. One :meth:`step` runs ``physics_hz // control_hz`` physics substeps.
        gains: PD gains and torque limits (``pd_mode="motor"`` uses only the torque limits).
        ground: create a ground in the client: a static box whose top face is z = 0 (not a
            ``GEOM_PLANE``: box-plane contacts in Bullet give one contact point per step, and at 120 Hz
            the feet sink 7-8 cm into a plane; box-box contacts keep full manifolds).
        ground_id: an existing ground body for :meth:`fallen` when ``ground=False``.
        self_collision: the humanoid's own links collide (except with ancestors), as in pybullet's
            DeepMimic env.
        friction: lateral friction of every humanoid link and of the created ground (DeepMimic's 0.9).
        solver_iterations: the client's ``numSolverIterations``; default 10 for ``"stable"`` (DeepMimic's
            value) and 30 for ``"motor"`` (motors are solver constraints and go soft with fewer: with 20 a
            standing body sways and falls within 9 s, with 30 it stands).
        fall_height_ratio: :meth:`fallen` flags a root below this fraction of the standing root height.
        pd_mode: ``"stable"``: PyBullet's ``STABLE_PD_CONTROL`` with ``gains`` (re-sent before every
            physics substep, since PyBullet applies stable-PD torques for one step only);
            ``"motor"``: PyBullet's constraint-based ``POSITION_CONTROL`` motors (velocity servo towards
            the target, ``motor_gain`` of the position error per physics step, limited by the same torque
            limits, solved together with the contacts). See ``docs/amp_sim.md`` for the measured
            difference: stable PD is contact-blind and makes loaded ankles nearly limp.
        motor_gain: position gain of ``"motor"`` mode (PyBullet's ``positionGain``, 0..1: the fraction of
            the position error the motor tries to remove in one physics step).
        ground_half_size: half side (m) of the created box ground, centred on the origin; bodies placed beyond it
            have no floor.

    Bodies are parked standing at ``(3 i, -1000, h)`` until :meth:`set_state` places them.
    """

    def __init__(
        self,
        client: int,
        n: int,
        physics_hz: int = 120,
        control_hz: int = 30,
        gains: PDGains = DEFAULT_GAINS,
        ground: bool = True,
        *,
        ground_id: int | None = None,
        self_collision: bool = True,
        friction: float = 0.9,
        solver_iterations: int | None = None,
        fall_height_ratio: float = 0.5,
        pd_mode: str = "stable",
        motor_gain: float = 1.0,
        ground_half_size: float = GROUND_HALF_SIZE,
    ) -> None:
        if n < 1:
            raise ValueError(f"need at least one humanoid, got n={n}")
        if physics_hz % control_hz != 0:
            raise ValueError(f"physics_hz ({physics_hz}) must be a multiple of control_hz ({control_hz})")
        if pd_mode not in ("stable", "motor"):
            raise ValueError(f"pd_mode must be 'stable' or 'motor', got {pd_mode!r}")
        self.client = client
        self.n = n
        self.physics_hz = int(physics_hz)
        self.control_hz = int(control_hz)
        self.substeps = self.physics_hz // self.control_hz
        self.dt = 1.0 / self.physics_hz
        self.control_dt = 1.0 / self.control_hz
        self.pd_mode = pd_mode
        self.motor_gain = float(motor_gain)
        self.gains = gains
        self.kp, self.kd, self.max_torque = gains.arrays()
        self._kp_l = self.kp.tolist()
        self._kd_l = self.kd.tolist()
        self._motor_kp_l = [self.motor_gain] * len(CONTROL_JOINTS)
        self._motor_kd_l = [1.0] * len(CONTROL_JOINTS)
        self._forces_l = [
            [t] if r else [t, t, t] for t, r in zip(self.max_torque.tolist(), _IS_REV, strict=True)
        ]
        self._zero_vel_l = [[0.0] if r else [0.0, 0.0, 0.0] for r in _IS_REV]
        self.fall_height_ratio = float(fall_height_ratio)
        if solver_iterations is None:
            solver_iterations = 10 if pd_mode == "stable" else 30
        self.solver_iterations = int(solver_iterations)

        p.setGravity(0, 0, -9.81, physicsClientId=client)
        p.setTimeStep(self.dt, physicsClientId=client)
        p.setPhysicsEngineParameter(numSolverIterations=self.solver_iterations, physicsClientId=client)

        self.ground_id: int | None = ground_id
        self._own_ground = bool(ground)
        if ground:
            col = p.createCollisionShape(
                p.GEOM_BOX, halfExtents=[ground_half_size, ground_half_size, 0.5], physicsClientId=client
            )
            self.ground_id = p.createMultiBody(0.0, col, -1, [0, 0, -0.5], physicsClientId=client)
            p.setCollisionFilterGroupMask(self.ground_id, -1, GROUP_STATIC, MASK_ALL, physicsClientId=client)
            p.changeDynamics(self.ground_id, -1, lateralFriction=friction, physicsClientId=client)

        flags = p.URDF_MAINTAIN_LINK_ORDER
        if self_collision:
            flags |= p.URDF_USE_SELF_COLLISION | p.URDF_USE_SELF_COLLISION_EXCLUDE_ALL_PARENTS
        self.ids: list[int] = []
        with quiet():  # the URDF importer prints a warning per joint without an <axis>
            for i in range(n):
                self.ids.append(
                    p.loadURDF(
                        HUMANOID_URDF,
                        [3.0 * i, -1000.0, 1.0],
                        UPRIGHT,
                        useFixedBase=False,
                        globalScaling=HUMANOID_SCALE,
                        flags=flags,
                        physicsClientId=client,
                    )
                )
        mask = GROUP_STATIC | GROUP_ROBOT | GROUP_HUMAN
        for body in self.ids:
            for link in range(-1, N_LINKS):
                p.setCollisionFilterGroupMask(body, link, GROUP_HUMAN, mask, physicsClientId=client)
                p.changeDynamics(
                    body,
                    link,
                    lateralFriction=friction,
                    linearDamping=0.0,
                    angularDamping=0.0,
                    physicsClientId=client,
                )
            # Switch off PyBullet's default joint motors (velocity motors with a force limit on the
            # revolute joints): the PD controller alone drives the joints.
            for j, r in zip(CONTROL_JOINTS, _IS_REV, strict=True):
                if r:
                    p.setJointMotorControl2(
                        body, j, p.VELOCITY_CONTROL, targetVelocity=0, force=0, physicsClientId=client
                    )
                else:
                    p.setJointMotorControlMultiDof(
                        body,
                        j,
                        p.POSITION_CONTROL,
                        targetPosition=[0, 0, 0, 1],
                        targetVelocity=[0, 0, 0],
                        positionGain=0,
                        velocityGain=1,
                        force=[0, 0, 0],
                        physicsClientId=client,
                    )
        # Standing root height: base z minus the lowest point of the feet, zero pose.
        b0 = self.ids[0]
        base_z = p.getBasePositionAndOrientation(b0, physicsClientId=client)[0][2]
        foot_min = min(p.getAABB(b0, f, physicsClientId=client)[0][2] for f in FOOT_LINKS)
        self.standing_height = float(base_z - foot_min)
        for i, body in enumerate(self.ids):
            p.resetBasePositionAndOrientation(
                body, [3.0 * i, -1000.0, self.standing_height + 0.01], UPRIGHT, physicsClientId=client
            )

        ident = np.zeros((n, len(SPH), 4))
        ident[..., 3] = 1.0
        self._target_sph = ident
        self._target_rev = np.zeros((n, len(REV)))
        self._target_sph_vel = np.zeros((n, len(SPH), 3))
        self._target_rev_vel = np.zeros((n, len(REV)))
        self._targets_l = _joint_lists(self._target_sph, self._target_rev)
        self._target_vel_l = [self._zero_vel_l] * n
        self._motors_dirty = True
        self._state: dict[str, np.ndarray] | None = None
        self._torque: np.ndarray | None = None  # motor mode: (N, 28) applied torques of the last substep
        self._fresh = np.zeros(n, dtype=bool)  # re-initialised since the last step (no torque applied yet)
        self._push_force = np.zeros((n, 3))  # external force on the pelvis (world frame, N)
        self._push_left = np.zeros(n, dtype=int)  # physics substeps it still acts for

    # -- state -------------------------------------------------------------------------------------

    def set_state(self, ref: ReferenceState, idx: np.ndarray | list[int] | None = None) -> None:
        """Reference state initialisation of humanoids ``idx`` (default: all) from a batched ``ref``
        (leading axis = ``len(idx)``): base pose and velocity, joint positions and velocities. Their PD
        targets become the reference pose with zero target velocity."""
        idx = np.arange(self.n) if idx is None else np.atleast_1d(np.asarray(idx, dtype=int))
        b = len(idx)
        root_pos = np.asarray(ref.root_pos, dtype=np.float64).reshape(b, 3).tolist()
        root_quat = np.asarray(ref.root_quat, dtype=np.float64).reshape(b, 4)
        root_quat = (root_quat / np.linalg.norm(root_quat, axis=-1, keepdims=True)).tolist()
        lin = np.asarray(ref.root_lin_vel, dtype=np.float64).reshape(b, 3).tolist()
        ang = np.asarray(ref.root_ang_vel, dtype=np.float64).reshape(b, 3).tolist()
        sph = np.asarray(ref.sph, dtype=np.float64).reshape(b, len(SPH), 4)
        sph = sph / np.linalg.norm(sph, axis=-1, keepdims=True)
        rev = np.asarray(ref.rev, dtype=np.float64).reshape(b, len(REV))
        pos_l = _joint_lists(sph, rev)
        vel_l = _vel_lists(np.reshape(ref.sph_vel, (b, len(SPH), 3)), np.reshape(ref.rev_vel, (b, len(REV))))
        cid = self.client
        for k, i in enumerate(idx.tolist()):
            body = self.ids[i]
            p.resetBasePositionAndOrientation(body, root_pos[k], root_quat[k], physicsClientId=cid)
            p.resetBaseVelocity(body, lin[k], ang[k], physicsClientId=cid)
            p.resetJointStatesMultiDof(
                body, CONTROL_JOINTS, pos_l[k], targetVelocities=vel_l[k], physicsClientId=cid
            )
            self._targets_l[i] = pos_l[k]
            self._target_vel_l[i] = self._zero_vel_l
        self._target_sph[idx] = sph
        self._target_rev[idx] = rev
        self._target_sph_vel[idx] = 0.0
        self._target_rev_vel[idx] = 0.0
        self._motors_dirty = True
        self._fresh[idx] = True
        self._push_left[idx] = 0
        self._state = None
        self._torque = None

    def apply_targets(
        self,
        sph: np.ndarray,
        rev: np.ndarray,
        sph_vel: np.ndarray | None = None,
        rev_vel: np.ndarray | None = None,
    ) -> None:
        """Set the PD targets of every humanoid: ``sph`` (N, 8, 4) quaternions (order ``SPH``), ``rev``
        (N, 4) angles (order ``REV``); optional target velocities ``sph_vel`` (N, 8, 3) (child frame) and
        ``rev_vel`` (N, 4), zero when omitted (the policy's case, as in DeepMimic). They hold until the
        next call (or :meth:`set_state`)."""
        sph = np.asarray(sph, dtype=np.float64).reshape(self.n, len(SPH), 4)
        sph = sph / np.linalg.norm(sph, axis=-1, keepdims=True)
        rev = np.asarray(rev, dtype=np.float64).reshape(self.n, len(REV))
        self._target_sph = sph.copy()
        self._target_rev = rev.copy()
        self._targets_l = _joint_lists(sph, rev)
        if sph_vel is None and rev_vel is None:
            self._target_sph_vel = np.zeros((self.n, len(SPH), 3))
            self._target_rev_vel = np.zeros((self.n, len(REV)))
            self._target_vel_l = [self._zero_vel_l] * self.n
        else:
            sv = (
                np.zeros((self.n, len(SPH), 3))
                if sph_vel is None
                else np.reshape(sph_vel, (self.n, len(SPH), 3))
            )
            rv = np.zeros((self.n, len(REV))) if rev_vel is None else np.reshape(rev_vel, (self.n, len(REV)))
            self._target_sph_vel = np.array(sv, dtype=np.float64)
            self._target_rev_vel = np.array(rv, dtype=np.float64)
            self._target_vel_l = _vel_lists(sv, rv)
        self._motors_dirty = True

    def step(self, before_substep: Callable[[], None] | None = None) -> None:
        """One control step: ``substeps`` physics steps. Stable PD: the command of every body is re-sent
        before each substep (N calls + 1 ``stepSimulation`` per substep). Motors: sent once.
        ``before_substep`` runs before every physics step (e.g. to drive other bodies of the client)."""
        cid = self.client
        joints = CONTROL_JOINTS
        forces = self._forces_l
        if self.pd_mode == "stable":
            stable = p.STABLE_PD_CONTROL
            kp, kd = self._kp_l, self._kd_l
            for _ in range(self.substeps):
                for body, tgt, tv in zip(self.ids, self._targets_l, self._target_vel_l, strict=True):
                    p.setJointMotorControlMultiDofArray(
                        body,
                        joints,
                        stable,
                        targetPositions=tgt,
                        targetVelocities=tv,
                        positionGains=kp,
                        velocityGains=kd,
                        forces=forces,
                        physicsClientId=cid,
                    )
                self._apply_pushes()
                if before_substep is not None:
                    before_substep()
                p.stepSimulation(physicsClientId=cid)
        else:
            if self._motors_dirty:
                for body, tgt, tv in zip(self.ids, self._targets_l, self._target_vel_l, strict=True):
                    p.setJointMotorControlMultiDofArray(
                        body,
                        joints,
                        p.POSITION_CONTROL,
                        targetPositions=tgt,
                        targetVelocities=tv,
                        positionGains=self._motor_kp_l,
                        velocityGains=self._motor_kd_l,
                        forces=forces,
                        physicsClientId=cid,
                    )
                self._motors_dirty = False
            for _ in range(self.substeps):
                self._apply_pushes()
                if before_substep is not None:
                    before_substep()
                p.stepSimulation(physicsClientId=cid)
        self._fresh[:] = False
        self._state = None
        self._torque = None

    def push(self, idx: np.ndarray | list[int], force: np.ndarray, seconds: float) -> None:
        """Push humanoids ``idx`` with a constant world-frame ``force`` (len(idx), 3) in N on the pelvis
        (at its centre of mass) for ``seconds`` of simulated time, starting with the next :meth:`step`.
        A new push replaces one still acting. PyBullet clears external forces after every physics step,
        so the force is re-applied before each substep."""
        idx = np.asarray(idx, dtype=int).reshape(-1)
        force = np.asarray(force, dtype=float).reshape(idx.size, 3)
        if not np.isfinite(force).all() or not np.isfinite(seconds) or seconds < 0:
            raise ValueError("push force must be finite and seconds >= 0")
        self._push_force[idx] = force
        self._push_left[idx] = int(round(seconds * self.physics_hz))

    def _apply_pushes(self) -> None:
        active = np.flatnonzero(self._push_left > 0)
        for i in active:
            body = self.ids[i]
            pos = p.getBasePositionAndOrientation(body, physicsClientId=self.client)[0]
            p.applyExternalForce(body, -1, self._push_force[i].tolist(), pos, p.WORLD_FRAME,
                                 physicsClientId=self.client)
        self._push_left[active] -= 1

    def read_state(self) -> dict[str, np.ndarray]:
        """State of every humanoid (four PyBullet calls per body), as float64 arrays:

        ``root_pos`` (N, 3), ``root_quat`` (N, 4) (x, y, z, w), ``root_lin_vel`` (N, 3), ``root_ang_vel``
        (N, 3) (world frame); ``sph`` (N, 8, 4) local joint quaternions and ``sph_vel`` (N, 8, 3) their
        child-frame angular velocities (order ``SPH``); ``rev``, ``rev_vel`` (N, 4) (order ``REV``);
        ``body_pos`` (N, 15, 3) every link's centre of mass (world); ``key_pos`` (N, 5, 3) the key
        bodies ``KEY_BODY_NAMES`` = right hand, left hand, right foot, left foot, head.
        The result is cached until the next :meth:`step` or :meth:`set_state`; treat it as read-only.
        """
        if self._state is not None:
            return self._state
        cid = self.client
        n = self.n
        root_pos = np.empty((n, 3))
        root_quat = np.empty((n, 4))
        lin = np.empty((n, 3))
        ang = np.empty((n, 3))
        q_l, v_l, t_l, body_l = [], [], [], []
        links = list(range(N_LINKS))
        for i, body in enumerate(self.ids):
            pos, orn = p.getBasePositionAndOrientation(body, physicsClientId=cid)
            lv, av = p.getBaseVelocity(body, physicsClientId=cid)
            root_pos[i] = pos
            root_quat[i] = orn
            lin[i] = lv
            ang[i] = av
            js = p.getJointStatesMultiDof(body, CONTROL_JOINTS, physicsClientId=cid)
            q_l.append([c for s in js for c in s[0]])
            v_l.append([c for s in js for c in s[1]])
            t_l.append([c for s in js for c in s[3]])
            ls = p.getLinkStates(body, links, computeForwardKinematics=1, physicsClientId=cid)
            body_l.append([s[0] for s in ls])
        sph, rev, sph_vel, rev_vel = _split_joints(np.asarray(q_l), np.asarray(v_l))
        if self.pd_mode == "motor":
            self._torque = np.asarray(t_l, dtype=np.float64)
        body_pos = np.asarray(body_l, dtype=np.float64)
        self._state = {
            "root_pos": root_pos,
            "root_quat": root_quat,
            "root_lin_vel": lin,
            "root_ang_vel": ang,
            "sph": sph,
            "sph_vel": sph_vel,
            "rev": rev,
            "rev_vel": rev_vel,
            "body_pos": body_pos,
            "key_pos": body_pos[:, list(KEY_LINKS)],
        }
        return self._state

    def standing_state(self, xy: np.ndarray, yaw: np.ndarray, lean: float | None = None) -> ReferenceState:
        """Standing reference states (zero joints except the ankles, zero velocities) at planar positions
        ``xy`` (B, 2) facing ``yaw`` (B,), feet flat on z = 0 (1 mm above).

        ``lean`` (rad, forward) tilts the body about the ankles, the ankles keeping the feet flat. The
        default is the pose each actuator model holds longest (measured, see ``docs/amp_sim.md``):
        ``"stable"``: the centre of mass right above the ankle joints (about 1.4 mrad), the balance point
        of a body whose ankles give way under stable PD; ``"motor"``: 0.04 rad, the centre of mass over
        the middle of the feet.
        """
        xy = np.asarray(xy, dtype=np.float64).reshape(-1, 2)
        b = xy.shape[0]
        yaw = np.broadcast_to(np.asarray(yaw, dtype=np.float64), (b,))
        if lean is None:
            lean = _balanced_lean() if self.pd_mode == "stable" else 0.04
        sph = np.zeros((b, len(SPH), 4))
        sph[..., 3] = 1.0
        ankle = np.array([0.0, 0.0, np.sin(0.5 * lean), np.cos(0.5 * lean)])  # about the body's right axis
        for j in (5, 11):
            sph[:, SPH.index(j)] = ankle
        tilt = quat_mul(np.array([0.0, np.sin(0.5 * lean), 0.0, np.cos(0.5 * lean)]), np.asarray(UPRIGHT))
        quat = quat_mul(yaw_quat(yaw), np.broadcast_to(tilt, (b, 4)))
        rev = np.zeros((b, len(REV)))
        # Root height: the ankle frame drops by the lean; the feet stay flat.
        zero = np.zeros((1, 3))
        ident = np.zeros((1, len(SPH), 4))
        ident[..., 3] = 1.0
        a0 = forward_kinematics(zero, np.asarray(UPRIGHT)[None], ident, np.zeros((1, len(REV))))[0][0, 5, 2]
        a1 = forward_kinematics(zero, tilt[None], sph[:1], rev[:1])[0][0, 5, 2]
        z = self.standing_height + a0 - a1 + 0.001
        return ReferenceState(
            root_pos=np.c_[xy, np.full(b, z)],
            root_quat=quat,
            sph=sph,
            rev=rev,
            root_lin_vel=np.zeros((b, 3)),
            root_ang_vel=np.zeros((b, 3)),
            sph_vel=np.zeros((b, len(SPH), 3)),
            rev_vel=np.zeros((b, len(REV))),
        )

    # -- terminations and rewards --------------------------------------------------------------------

    def fallen(self) -> np.ndarray:
        """(N,) bool: a non-foot link touches the ground (contacts of the last physics step), or the root
        is below ``fall_height_ratio`` x the standing root height."""
        out = self.read_state()["root_pos"][:, 2] < self.fall_height_ratio * self.standing_height
        if self.ground_id is not None:
            index = {b: i for i, b in enumerate(self.ids)}
            for c in p.getContactPoints(bodyA=self.ground_id, physicsClientId=self.client):
                i = index.get(c[2])
                if i is not None and c[4] not in FOOT_LINKS:
                    out[i] = True
        return out

    def joint_power(self) -> np.ndarray:
        """(N,) sum over joints of |tau . omega| (W) at the current state.

        ``"motor"`` mode: PyBullet's reported motor torques of the last physics substep (zero for bodies
        re-initialised since the last step).
        ``"stable"`` mode: PyBullet does not report stable-PD torques, so tau is the PD law evaluated
        here, ``clip(Kp e + Kd (omega_target - omega) - Kp dt omega, +-max_torque)`` per axis (the stable-PD
        torque without its acceleration term), with ``e`` the rotation vector from the current to the
        target joint rotation (child frame) or the angle error. Zero at rest (omega = 0), never negative.
        """
        s = self.read_state()
        w_s, w_r = s["sph_vel"], s["rev_vel"]
        if self.pd_mode == "motor" and self._torque is not None:
            _, _, tau_s, tau_r = _split_joints(np.zeros((self.n, 36)), self._torque)
            tau_s[self._fresh] = 0.0  # torques PyBullet reports for a re-initialised body are stale
            tau_r[self._fresh] = 0.0
        else:
            kp_s, kd_s, lim_s = (
                self.kp[_SPH_POS, None],
                self.kd[_SPH_POS, None],
                self.max_torque[_SPH_POS, None],
            )
            kp_r, kd_r, lim_r = self.kp[_REV_POS], self.kd[_REV_POS], self.max_torque[_REV_POS]
            e_s = quat_to_rotvec(quat_mul(quat_conj(s["sph"]), self._target_sph))
            tau_s = np.clip(kp_s * (e_s - self.dt * w_s) + kd_s * (self._target_sph_vel - w_s), -lim_s, lim_s)
            e_r = self._target_rev - s["rev"]
            tau_r = np.clip(kp_r * (e_r - self.dt * w_r) + kd_r * (self._target_rev_vel - w_r), -lim_r, lim_r)
        return np.abs(np.sum(tau_s * w_s, axis=-1)).sum(axis=-1) + np.abs(tau_r * w_r).sum(axis=-1)

    def exclude_collisions(self, body: int) -> None:
        """Stop every humanoid colliding with ``body`` (e.g. the scene's ``GEOM_PLANE`` ground when this
        object brings its own box ground): one ``setCollisionFilterPair`` per link pair."""
        nb = p.getNumJoints(body, physicsClientId=self.client)
        for h in self.ids:
            for link in range(-1, N_LINKS):
                for other in range(-1, nb):
                    p.setCollisionFilterPair(h, body, link, other, 0, physicsClientId=self.client)

    @property
    def targets(self) -> tuple[np.ndarray, np.ndarray]:
        """Current PD targets ``(sph (N, 8, 4), rev (N, 4))``."""
        return self._target_sph.copy(), self._target_rev.copy()

    def remove(self) -> None:
        """Delete the humanoids (and the ground this object created) from the client."""
        for body in self.ids:
            p.removeBody(body, physicsClientId=self.client)
        if self._own_ground and self.ground_id is not None:
            p.removeBody(self.ground_id, physicsClientId=self.client)
            self.ground_id = None
        self.ids = []
        self._state = None


@functools.lru_cache(maxsize=1)
def _balanced_lean() -> float:
    """Forward lean (rad) that puts the zero pose's centre of mass above the ankle joints."""
    m = load_humanoid_model()
    ident = np.zeros((1, len(SPH), 4))
    ident[..., 3] = 1.0
    com, _ = forward_kinematics(
        np.zeros((1, 3)), np.asarray(UPRIGHT)[None], ident, np.zeros((1, len(REV))), m
    )
    total = m.mass.sum() + m.base_mass
    c = (com[0] * m.mass[:, None]).sum(axis=0) / total
    # The ankle joint is the ankle link's frame origin: its centre of mass minus its inertial offset.
    ankle = com[0, 5] - quat_rotate(np.asarray(UPRIGHT), m.com[5])  # zero pose: link frames are the base's
    return float(np.arctan2(ankle[0] - c[0], c[2] - ankle[2]))


def _split_joints(q: np.ndarray, v: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Split flat per-body joint positions / velocities (CONTROL_JOINTS order) into SPH / REV arrays."""
    n = q.shape[0]
    qi, vi = [], []
    qo = vo = 0
    for r in _IS_REV:
        qi.append(list(range(qo, qo + (1 if r else 4))))
        vi.append(list(range(vo, vo + (1 if r else 3))))
        qo += 1 if r else 4
        vo += 1 if r else 3
    sph = q[:, [c for k in _SPH_POS for c in qi[k]]].reshape(n, len(SPH), 4)
    rev = q[:, [qi[k][0] for k in _REV_POS]]
    sph_vel = v[:, [c for k in _SPH_POS for c in vi[k]]].reshape(n, len(SPH), 3)
    rev_vel = v[:, [vi[k][0] for k in _REV_POS]]
    return sph, rev, sph_vel, rev_vel


def state_to_reference(state: dict[str, np.ndarray]) -> ReferenceState:
    """A ``read_state()`` dict as a batched :class:`ReferenceState` (e.g. to restore a snapshot)."""
    return ReferenceState(
        root_pos=state["root_pos"],
        root_quat=state["root_quat"],
        sph=state["sph"],
        rev=state["rev"],
        root_lin_vel=state["root_lin_vel"],
        root_ang_vel=state["root_ang_vel"],
        sph_vel=state["sph_vel"],
        rev_vel=state["rev_vel"],
    )
