"""Humanoid self-observation, AMP discriminator features and a numpy forward kinematics (no PyBullet).

Everything here is vectorised over a leading batch axis and works on the state dictionary of
:meth:`navzoo.agents.amp.sim.PhysicsHumanoids.read_state` or on a
:class:`~navzoo.agents.reference.ReferenceState` (through :func:`reference_state_dict`, which adds
the body positions by forward kinematics of the URDF), so the discriminator's "real" samples come
from clips without simulating them.

Frames (see ``docs/amp_sim.md``):

* world: z up; quaternions are (x, y, z, w).
* base: PyBullet's base frame of ``humanoid/humanoid.urdf``; its axes are the body's forward (+x),
  up (+y) and right (+z) axes (the URDF is y-up; standing upright facing +x is the base orientation
  ``R_x(+90 deg)``).
* heading frame: the world frame rotated about z by the body's heading, the yaw of its forward axis
  (:func:`heading`); its x axis points where the body faces, horizontally.

Feature layout of :func:`amp_features` / :func:`self_observation` (105 numbers, IsaacGymEnvs order):

====================  =====  ===========================================================================
slice                 size   content
====================  =====  ===========================================================================
``[0:1]``             1      root height (m, world z)
``[1:7]``             6      root orientation without heading: forward and up axes in the heading frame
``[7:10]``            3      root linear velocity in the heading frame (m/s)
``[10:13]``           3      root angular velocity in the heading frame (rad/s)
``[13:61]``           48     8 spherical joints x 6-D (local x and z axes of the joint's rotation)
``[61:65]``           4      revolute joint angles (rad)
``[65:89]``           24     8 spherical joint angular velocities (child frame, rad/s)
``[89:93]``           4      revolute joint velocities (rad/s)
``[93:105]``          12     right hand, left hand, right foot, left foot positions relative to the root
                             in the heading frame (m); link centres of mass
====================  =====  ===========================================================================
"""

from __future__ import annotations

import functools
import xml.etree.ElementTree as ET
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from navzoo.agents import quat as _quat
from navzoo.agents.motion import HUMANOID_SCALE, N_LINKS, REVOLUTE_JOINTS, SPHERICAL_JOINTS
from navzoo.agents.reference import ReferenceState

# Quaternion helpers, defined in navzoo.agents.quat and re-exported here for this module's callers.
_cross = _quat._cross
heading = _quat.heading
yaw_quat = _quat.quat_about_z
quat_conj = _quat.quat_conj
quat_from_rotvec = _quat.quat_from_rotvec
quat_mul = _quat.quat_mul
quat_rotate = _quat.quat_rotate
quat_to_matrix = _quat.quat_to_matrix
quat_to_rotvec = _quat.quat_to_rotvec

# ----------------------------------------------------------------------------------------------
# Model constants (humanoid/humanoid.urdf with URDF_MAINTAIN_LINK_ORDER: link index = joint index)
# ----------------------------------------------------------------------------------------------

SPH: tuple[int, ...] = (
    SPHERICAL_JOINTS  # (1 chest, 2 neck, 3 r_hip, 5 r_ankle, 6 r_shoulder, 9 l_hip, 11 l_ankle, 12 l_shoulder)
)
REV: tuple[int, ...] = tuple(sorted(REVOLUTE_JOINTS))  # (4 r_knee, 7 r_elbow, 10 l_knee, 13 l_elbow)
#: Key bodies read by the simulator, in this order; the features use the first four (hands, feet).
KEY_BODY_NAMES: tuple[str, ...] = ("right_hand", "left_hand", "right_foot", "left_foot", "head")
KEY_LINKS: tuple[int, ...] = (8, 14, 5, 11, 2)
N_FEATURE_KEYS = 4
FOOT_LINKS: tuple[int, ...] = (5, 11)

FEATURE_DIM = 1 + 6 + 3 + 3 + 6 * len(SPH) + len(REV) + 3 * len(SPH) + len(REV) + 3 * N_FEATURE_KEYS  # 105

#: name -> slice of the 105-D feature vector.
FEATURE_SLICES: dict[str, slice] = {}
_o = 0
for _name, _n in (
    ("root_height", 1),
    ("root_rot", 6),
    ("root_lin_vel", 3),
    ("root_ang_vel", 3),
    ("sph_rot", 6 * len(SPH)),
    ("rev_angle", len(REV)),
    ("sph_vel", 3 * len(SPH)),
    ("rev_vel", len(REV)),
    ("key_pos", 3 * N_FEATURE_KEYS),
):
    FEATURE_SLICES[_name] = slice(_o, _o + _n)
    _o += _n
assert _o == FEATURE_DIM

_EX = np.array([1.0, 0.0, 0.0])
_EY = np.array([0.0, 1.0, 0.0])
_EZ = np.array([0.0, 0.0, 1.0])


# The stance (NavConfig.amp_stance_reward, PathTaskConfig.stance_reward): the running mean, time constant
# STANCE_TAU_S (about a gait cycle, so a walking gait's alternation averages out: a 1.1 s stride of +-0.3 m leaves
# about +-0.05 m while a foot kept ahead does not), of foot_split is charged past a free band of STANCE_FREE_M: the
# reference clips' own gait leaves |mean| at 0.069 m on average over their frames after each clip's first second
# (24 % of those frames above 0.1 m; scripts/amp_stance_split.py), so a normal stride costs little.
STANCE_TAU_S = 1.0
STANCE_FREE_M = 0.1


def foot_split(state: dict[str, np.ndarray]) -> np.ndarray:
    """(N,) the right foot's lead over the left foot along each body's heading (m): positive when the right
    foot is ahead. ``state`` is a simulator state dict (``root_quat``, ``key_pos`` in ``KEY_BODY_NAMES`` order)."""
    h = heading(state["root_quat"])
    key = state["key_pos"]
    d = key[:, KEY_BODY_NAMES.index("right_foot"), :2] - key[:, KEY_BODY_NAMES.index("left_foot"), :2]
    return np.cos(h) * d[:, 0] + np.sin(h) * d[:, 1]


def stance_penalty(running_mean: np.ndarray) -> np.ndarray:
    """The stance term before its weight: minus the excess of ``|running_mean|`` over ``STANCE_FREE_M`` (m)."""
    return -np.maximum(0.0, np.abs(running_mean) - STANCE_FREE_M)


def to_heading_frame(quat: np.ndarray, v: np.ndarray) -> np.ndarray:
    """World vectors ``v`` (N, ..., 3) expressed in the heading frame of base orientations ``quat`` (N, 4)."""
    h = heading(quat)
    c, s = np.cos(h), np.sin(h)
    extra = (1,) * (v.ndim - 2)
    c = c.reshape(c.shape + extra)
    s = s.reshape(s.shape + extra)
    x, y = v[..., 0], v[..., 1]
    return np.stack([c * x + s * y, -s * x + c * y, v[..., 2]], axis=-1)


# ----------------------------------------------------------------------------------------------
# Forward kinematics of humanoid/humanoid.urdf (parsed once, scaled by 0.25)
# ----------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class HumanoidModel:
    """Kinematic tree of the URDF in PyBullet's link order (``URDF_MAINTAIN_LINK_ORDER``).

    Attributes:
        names: (15,) link (= joint) names.
        parent: (15,) parent link index, -1 for the base.
        joint_type: (15,) ``"fixed" | "spherical" | "revolute"``.
        origin_pos: (15, 3) joint origin in the parent's link frame (m, scaled).
        origin_rot: (15, 3, 3) joint origin rotation in the parent's link frame.
        axis: (15, 3) revolute axis in the child frame (zero for other joints).
        com: (15, 3) link centre of mass in the link frame (m, scaled).
        base_com: (3,) base centre of mass in the base link frame (PyBullet's base position).
        mass: (15,) link masses (kg); ``base_mass`` the base's.
    """

    names: tuple[str, ...]
    parent: np.ndarray
    joint_type: tuple[str, ...]
    origin_pos: np.ndarray
    origin_rot: np.ndarray
    axis: np.ndarray
    com: np.ndarray
    base_com: np.ndarray
    mass: np.ndarray
    base_mass: float


def _rpy_matrix(rpy: np.ndarray) -> np.ndarray:
    r, p_, y = rpy
    cr, sr, cp, sp, cy, sy = np.cos(r), np.sin(r), np.cos(p_), np.sin(p_), np.cos(y), np.sin(y)
    rx = np.array([[1, 0, 0], [0, cr, -sr], [0, sr, cr]])
    ry = np.array([[cp, 0, sp], [0, 1, 0], [-sp, 0, cp]])
    rz = np.array([[cy, -sy, 0], [sy, cy, 0], [0, 0, 1]])
    return rz @ ry @ rx


def _floats(s: str | None, n: int = 3) -> np.ndarray:
    return np.array([float(x) for x in s.split()]) if s else np.zeros(n)


@functools.lru_cache(maxsize=4)
def load_humanoid_model(path: str | None = None, scale: float = HUMANOID_SCALE) -> HumanoidModel:
    """Parse ``pybullet_data/humanoid/humanoid.urdf`` (cached) into a :class:`HumanoidModel`."""
    if path is None:
        import pybullet_data  # data files only; no physics import

        path = str(Path(pybullet_data.getDataPath()) / "humanoid" / "humanoid.urdf")
    # pybullet_data's file ends in a NUL byte, which XML parsers reject.
    root = ET.fromstring(Path(path).read_bytes().rstrip(b"\0 \t\r\n"))
    links = {ln.get("name"): ln for ln in root.findall("link")}
    joints = root.findall("joint")

    def inertial(link: ET.Element) -> tuple[np.ndarray, float]:
        ine = link.find("inertial")
        if ine is None:
            return np.zeros(3), 0.0
        org = ine.find("origin")
        m = ine.find("mass")
        return _floats(org.get("xyz") if org is not None else None) * scale, float(
            m.get("value")
        ) if m is not None else 0.0

    child_names = {j.find("child").get("link") for j in joints}
    base_names = [n for n in links if n not in child_names]
    if len(base_names) != 1:
        raise ValueError(f"{path}: expected one root link, found {base_names}")
    base_com, base_mass = inertial(links[base_names[0]])
    index = {base_names[0]: -1}
    names, parent, jtype, opos, orot, axis, com, mass = [], [], [], [], [], [], [], []
    for i, j in enumerate(joints):
        child = j.find("child").get("link")
        index[child] = i
        names.append(j.get("name"))
        parent.append(index[j.find("parent").get("link")])
        jtype.append(j.get("type"))
        org = j.find("origin")
        opos.append(_floats(org.get("xyz") if org is not None else None) * scale)
        orot.append(_rpy_matrix(_floats(org.get("rpy") if org is not None else None)))
        ax = j.find("axis")
        a = _floats(ax.get("xyz")) if (ax is not None and j.get("type") == "revolute") else np.zeros(3)
        axis.append(a / np.linalg.norm(a) if np.any(a) else a)
        c, m = inertial(links[child])
        com.append(c)
        mass.append(m)
    return HumanoidModel(
        names=tuple(names),
        parent=np.array(parent),
        joint_type=tuple(jtype),
        origin_pos=np.array(opos),
        origin_rot=np.array(orot),
        axis=np.array(axis),
        com=np.array(com),
        base_com=base_com,
        mass=np.array(mass),
        base_mass=base_mass,
    )


def forward_kinematics(
    root_pos: np.ndarray,
    root_quat: np.ndarray,
    sph: np.ndarray,
    rev: np.ndarray,
    model: HumanoidModel | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """World link poses of B humanoids.

    Args:
        root_pos: (B, 3) PyBullet base positions; root_quat (B, 4) base orientations.
        sph: (B, 8, 4) spherical joint quaternions (order ``SPH``); rev (B, 4) revolute angles (order ``REV``).

    Returns:
        ``(com_pos (B, 15, 3), link_rot (B, 15, 3, 3))``: each link's centre of mass (what PyBullet's
        ``getLinkState`` returns first) and its link-frame rotation in the world.
    """
    m = model if model is not None else load_humanoid_model()
    root_pos = np.asarray(root_pos, dtype=np.float64)
    b = root_pos.shape[0]
    base_rot = quat_to_matrix(np.asarray(root_quat, dtype=np.float64))
    base_pos = root_pos - np.einsum("bij,j->bi", base_rot, m.base_com)
    joint_rot = np.broadcast_to(np.eye(3), (b, N_LINKS, 3, 3)).copy()
    joint_rot[:, list(SPH)] = quat_to_matrix(np.asarray(sph, dtype=np.float64))
    rev = np.asarray(rev, dtype=np.float64)
    for k, j in enumerate(REV):
        joint_rot[:, j] = _axis_angle_matrix(m.axis[j], rev[:, k])
    rot = np.empty((b, N_LINKS, 3, 3))
    pos = np.empty((b, N_LINKS, 3))
    for j in range(N_LINKS):
        pj = m.parent[j]
        prot, ppos = (base_rot, base_pos) if pj < 0 else (rot[:, pj], pos[:, pj])
        pos[:, j] = ppos + np.einsum("bij,j->bi", prot, m.origin_pos[j])
        rot[:, j] = prot @ m.origin_rot[j] @ joint_rot[:, j]
    com = pos + np.einsum("bkij,kj->bki", rot, m.com)
    return com, rot


def _axis_angle_matrix(axis: np.ndarray, angle: np.ndarray) -> np.ndarray:
    """(B, 3, 3) rotations by ``angle`` (B,) about the unit ``axis`` (Rodrigues)."""
    k = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
    s = np.sin(angle)[:, None, None]
    c = np.cos(angle)[:, None, None]
    return np.eye(3) + s * k + (1 - c) * (k @ k)


# ----------------------------------------------------------------------------------------------
# Features
# ----------------------------------------------------------------------------------------------


def reference_state_dict(ref: ReferenceState, model: HumanoidModel | None = None) -> dict[str, np.ndarray]:
    """A batched :class:`ReferenceState` as a ``read_state()``-like dict, with body positions by FK."""
    root_pos = np.atleast_2d(np.asarray(ref.root_pos, dtype=np.float64))
    b = root_pos.shape[0]
    root_quat = np.asarray(ref.root_quat, dtype=np.float64).reshape(b, 4)
    sph = np.asarray(ref.sph, dtype=np.float64).reshape(b, len(SPH), 4)
    rev = np.asarray(ref.rev, dtype=np.float64).reshape(b, len(REV))
    body_pos, _ = forward_kinematics(root_pos, root_quat, sph, rev, model)
    return {
        "root_pos": root_pos,
        "root_quat": root_quat,
        "root_lin_vel": np.asarray(ref.root_lin_vel, dtype=np.float64).reshape(b, 3),
        "root_ang_vel": np.asarray(ref.root_ang_vel, dtype=np.float64).reshape(b, 3),
        "sph": sph,
        "sph_vel": np.asarray(ref.sph_vel, dtype=np.float64).reshape(b, len(SPH), 3),
        "rev": rev,
        "rev_vel": np.asarray(ref.rev_vel, dtype=np.float64).reshape(b, len(REV)),
        "body_pos": body_pos,
        "key_pos": body_pos[:, list(KEY_LINKS)],
    }


def amp_features(state: dict[str, np.ndarray]) -> np.ndarray:
    """Per-frame AMP discriminator features (N, 105) of a ``read_state()`` dict (layout: module doc)."""
    q = np.asarray(state["root_quat"], dtype=np.float64)
    n = q.shape[0]
    h_inv = yaw_quat(-heading(q))
    q_local = quat_mul(h_inv, q)
    root_rot = np.concatenate([quat_rotate(q_local, _EX), quat_rotate(q_local, _EY)], axis=-1)
    lin = to_heading_frame(q, np.asarray(state["root_lin_vel"], dtype=np.float64))
    ang = to_heading_frame(q, np.asarray(state["root_ang_vel"], dtype=np.float64))
    sph = np.asarray(state["sph"], dtype=np.float64)
    sph_rot = np.concatenate([quat_rotate(sph, _EX), quat_rotate(sph, _EZ)], axis=-1).reshape(n, -1)
    key = (
        np.asarray(state["key_pos"], dtype=np.float64)[:, :N_FEATURE_KEYS]
        - np.asarray(state["root_pos"])[:, None]
    )
    key = to_heading_frame(q, key).reshape(n, -1)
    return np.concatenate(
        [
            np.asarray(state["root_pos"], dtype=np.float64)[:, 2:3],
            root_rot,
            lin,
            ang,
            sph_rot,
            np.asarray(state["rev"], dtype=np.float64).reshape(n, -1),
            np.asarray(state["sph_vel"], dtype=np.float64).reshape(n, -1),
            np.asarray(state["rev_vel"], dtype=np.float64).reshape(n, -1),
            key,
        ],
        axis=-1,
    )


#: How the discriminator's velocity features are computed (``PathTaskConfig.amp_velocity``):
#: ``"finite_difference"``: backward differences of the poses one control step apart, for reference
#: and policy frames alike (:func:`finite_difference_velocities`); ``"physics"``: the simulator's
#: instantaneous velocities for policy frames and the library's central differences for reference
#: frames (the original inputs; measured mismatch in ``training/amp/README.md``).
AMP_VELOCITY_MODES: tuple[str, ...] = ("finite_difference", "physics")


def finite_difference_velocities(prev: dict[str, np.ndarray], cur: dict[str, np.ndarray], dt: float | np.ndarray
                                 ) -> dict[str, np.ndarray]:
    """``cur`` (a ``read_state()``-like dict) with its four velocity fields replaced by backward
    differences from ``prev`` over ``dt`` (same conventions as the simulator and the motion library):
    root linear velocity (world), root angular velocity ``log(q1 q0^-1) / dt`` (world), spherical joint
    velocities ``log(q0^-1 q1) / dt`` (child frame), revolute joint rates.

    The discriminator compares reference and policy frames through this one function, so that both
    sides' velocities mean the same thing: the motion between two control steps. (The simulator's
    instantaneous velocities do not: torque-limited position motors reach a new target within the
    first physics substep and report near-zero joint velocities at the end of the control step.)
    ``dt`` may also be an array (N,): one time step per body (:class:`PoseHistory`).
    """
    dt = np.asarray(dt, dtype=np.float64)

    def per(x: np.ndarray) -> np.ndarray:
        return x / dt.reshape(dt.shape + (1,) * (x.ndim - dt.ndim))

    out = dict(cur)
    out["root_lin_vel"] = per(np.asarray(cur["root_pos"], np.float64) - np.asarray(prev["root_pos"], np.float64))
    out["root_ang_vel"] = per(quat_to_rotvec(quat_mul(np.asarray(cur["root_quat"], np.float64),
                                                      quat_conj(np.asarray(prev["root_quat"], np.float64)))))
    out["sph_vel"] = per(quat_to_rotvec(quat_mul(quat_conj(np.asarray(prev["sph"], np.float64)),
                                                 np.asarray(cur["sph"], np.float64))))
    out["rev_vel"] = per(np.asarray(cur["rev"], np.float64) - np.asarray(prev["rev"], np.float64))
    return out


#: The pose fields of a ``read_state()`` dict that finite-difference velocities are computed from.
POSE_SHAPES: dict[str, tuple[int, ...]] = {"root_pos": (3,), "root_quat": (4,), "sph": (8, 4), "rev": (4,)}


class PoseHistory:
    """The last ``span`` poses of N bodies, for discriminator velocities over ``span`` control steps.

    ``span = 1`` gives :func:`finite_difference_velocities` from one control step to the next (the inputs
    of every controller trained up to 2026-11-27). A longer span averages the velocity over ``span``
    steps, ``(pose_t - pose_{t-span}) / (span dt)``: the per-step jitter that the fixed action noise puts
    into the joints (the position motors reach each new target within a physics substep) shrinks about
    ``span`` times, while the gait's own velocities, which change over a stride (about 1 s), barely
    change. Right after a reset a body has fewer poses: its velocities span the steps it has
    (``min(span, steps since reset)``), from the reset pose on.
    """

    def __init__(self, n: int, span: int = 1) -> None:
        if isinstance(span, bool) or not isinstance(span, int | np.integer) or span < 1:
            raise ValueError(f"velocity span must be an integer >= 1 (control steps), got {span!r}")
        self.n, self.span = int(n), int(span)
        # ring[-j] is the pose j control steps before the current one
        self._ring = {k: np.zeros((self.span, self.n) + shape) for k, shape in POSE_SHAPES.items()}
        self._age = np.zeros(self.n, dtype=np.int64)

    def reset(self, state: dict[str, np.ndarray], idx: np.ndarray | None = None) -> None:
        """Start bodies ``idx`` (default: all) over from the pose in ``state`` (all N bodies' rows)."""
        rows = slice(None) if idx is None else np.asarray(idx)
        for k in POSE_SHAPES:
            self._ring[k][:, rows] = np.asarray(state[k], np.float64)[rows]
        self._age[rows] = 0

    def velocities(self, state: dict[str, np.ndarray], dt: float) -> dict[str, np.ndarray]:
        """``state`` with its velocity fields replaced by differences over ``min(span, age + 1)`` steps of
        ``dt``; then remembers ``state``'s pose as the newest."""
        steps = np.minimum(self._age + 1, self.span)
        bodies = np.arange(self.n)
        prev = {k: ring[self.span - steps, bodies] for k, ring in self._ring.items()}
        out = finite_difference_velocities(prev, state, steps * float(dt))
        for k, ring in self._ring.items():
            ring[:-1] = ring[1:].copy()
            ring[-1] = np.asarray(state[k], np.float64)
        self._age += 1
        return out


def self_observation(state: dict[str, np.ndarray]) -> np.ndarray:
    """The policy's humanoid self-observation (N, 105): the same layout as :func:`amp_features`
    (IsaacGymEnvs uses one function for both); kept separate so either can grow on its own."""
    return amp_features(state)


def reference_features(ref: ReferenceState, model: HumanoidModel | None = None) -> np.ndarray:
    """AMP features (B, 105) of a batched reference state, body positions by forward kinematics."""
    return amp_features(reference_state_dict(ref, model))


def task_observation(root_pos: np.ndarray, root_quat: np.ndarray, waypoints: np.ndarray) -> np.ndarray:
    """Waypoints (N, K, 2) relative to the root, in the heading frame, flattened to (N, 2K)."""
    root_pos = np.asarray(root_pos, dtype=np.float64)
    wp = np.asarray(waypoints, dtype=np.float64)
    d = wp - root_pos[:, None, :2]
    h = heading(root_quat)
    c, s = np.cos(h)[:, None], np.sin(h)[:, None]
    local = np.stack([c * d[..., 0] + s * d[..., 1], -s * d[..., 0] + c * d[..., 1]], axis=-1)
    return local.reshape(local.shape[0], -1)


#: Obstacle observation: ``N_RAYS`` horizontal rays from the root, evenly spaced from the heading
#: direction counter-clockwise, each reporting ``1 - min(d, RAY_RANGE) / RAY_RANGE`` for the distance
#: d to the first wall segment or body disc it meets (0 = nothing within range, 1 = touching).
N_RAYS = 16
RAY_RANGE = 3.0  # m


def obstacle_observation(
    root_xy: np.ndarray,
    heading_yaw: np.ndarray,
    segments: np.ndarray | None = None,
    discs_xy: np.ndarray | None = None,
    discs_r: np.ndarray | float = 0.3,
    self_disc: np.ndarray | None = None,
) -> np.ndarray:
    """Ray-cast obstacle features (N, N_RAYS) of N bodies at ``root_xy`` (N, 2) facing ``heading_yaw``.

    Args:
        segments: wall segments (M, 2, 2) in the world frame (None or M = 0: no walls).
        discs_xy / discs_r: other bodies as discs (K, 2) / (K,) or a scalar radius (people, robots).
        self_disc: (N,) index into the discs of each ray origin's own disc (skipped), or -1.
    """
    o = np.asarray(root_xy, dtype=np.float64).reshape(-1, 2)
    n = o.shape[0]
    ang = np.asarray(heading_yaw, dtype=np.float64).reshape(n, 1) + (2 * np.pi / N_RAYS) * np.arange(N_RAYS)
    d = np.stack([np.cos(ang), np.sin(ang)], axis=-1)  # (N, R, 2)
    best = np.full((n, N_RAYS), RAY_RANGE)
    if segments is not None and len(segments):
        seg = np.asarray(segments, dtype=np.float64).reshape(-1, 2, 2)
        a, e = seg[:, 0], seg[:, 1] - seg[:, 0]  # (M, 2)
        # Only segments that come within range of some origin matter.
        ap = o[:, None, :] - a[None]  # (N, M, 2)
        t_proj = np.clip(np.sum(ap * e[None], axis=-1) / np.maximum(np.sum(e * e, axis=-1), 1e-12)[None], 0, 1)
        near = np.linalg.norm(ap - t_proj[..., None] * e[None], axis=-1).min(axis=0) < RAY_RANGE
        if near.any():
            a, e = a[near], e[near]
            w = a[None, None] - o[:, None, None, :]  # (N, 1, M, 2)
            dd = d[:, :, None, :]  # (N, R, 1, 2)
            denom = dd[..., 0] * e[None, None, :, 1] - dd[..., 1] * e[None, None, :, 0]  # cross(d, e)
            ok = np.abs(denom) > 1e-12
            safe = np.where(ok, denom, 1.0)
            t = (w[..., 0] * e[None, None, :, 1] - w[..., 1] * e[None, None, :, 0]) / safe  # cross(w, e) / cross(d, e)
            u = (w[..., 0] * dd[..., 1] - w[..., 1] * dd[..., 0]) / safe  # cross(w, d) / cross(d, e)
            hit = ok & (t >= 0) & (u >= 0) & (u <= 1)
            best = np.minimum(best, np.where(hit, t, RAY_RANGE).min(axis=-1))
    if discs_xy is not None and len(discs_xy):
        c = np.asarray(discs_xy, dtype=np.float64).reshape(-1, 2)
        r = np.broadcast_to(np.asarray(discs_r, dtype=np.float64), (c.shape[0],))
        w = c[None] - o[:, None]  # (N, K, 2)
        dist = np.linalg.norm(w, axis=-1)
        tc = np.einsum("nrx,nkx->nrk", d, w)  # (N, R, K)
        h2 = dist[:, None, :] ** 2 - tc**2
        inside = dist[:, None, :] < r[None, None]
        t = np.where(inside, 0.0, tc - np.sqrt(np.maximum(r[None, None] ** 2 - h2, 0.0)))
        hit = inside | ((h2 <= r[None, None] ** 2) & (t >= 0))
        if self_disc is not None:
            own = np.asarray(self_disc).reshape(n)
            mask = np.zeros((n, c.shape[0]), dtype=bool)
            valid = own >= 0
            mask[np.flatnonzero(valid), own[valid]] = True
            hit &= ~mask[:, None, :]
        best = np.minimum(best, np.where(hit, t, RAY_RANGE).min(axis=-1))
    return 1.0 - best / RAY_RANGE


def policy_observation(state: dict[str, np.ndarray], waypoints: np.ndarray, rays: np.ndarray | None = None) -> np.ndarray:
    """The controller's input (N, 105 + 2K [+ N_RAYS]) float32: self-observation, the K target points
    in the heading frame and, for obstacle-aware policies, the rays of :func:`obstacle_observation`."""
    parts = [self_observation(state), task_observation(state["root_pos"], state["root_quat"], waypoints)]
    if rays is not None:
        parts.append(rays)
    return np.concatenate(parts, axis=1).astype(np.float32)
