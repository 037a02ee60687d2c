"""The 17 COCO keypoints of navzoo's humanoid pedestrians, in the world, from their PyBullet link frames.

The pedestrian body is pybullet_data's 15-body DeepMimic humanoid (``navzoo.agents.motion``; scale
0.25, about 1.64 m tall). Each link frame sits at its parent joint; the URDF is y-up with +x forward
and +z to the body's right, so in a link's frame "up" is +y, "forward" +x and "right" +z. The COCO
keypoints map onto it as follows:

* shoulders, elbows, wrists, hips, knees, ankles: the world positions of the matching joints
  (links ``right_shoulder`` 6, ``right_elbow`` 7, ``right_wrist`` 8, ``right_hip`` 3, ``right_knee`` 4,
  ``right_ankle`` 5, and the left ones 12, 13, 14, 9, 10, 11);
* nose, eyes and ears: fixed points on the head sphere (radius 0.1 m, centre 0.175 m above the neck
  joint) in the ``neck`` link's frame: nose 0.1 m in front of the centre, eyes 0.085 m in front,
  0.03 m up and 0.035 m to each side, ears 0.095 m to each side.

The same bodies are used by the kinematic and the physics (AMP) pedestrians, so one function serves
both. The person's ground-truth *body orientation* is the heading of the pelvis (base link): the yaw
of its forward axis projected on the ground.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import pybullet as p
from scipy.spatial.transform import Rotation

from navzoo.sensors.camera_model import COCO_KEYPOINTS, NUM_KEYPOINTS

__all__ = ["HEAD_OFFSETS", "JOINT_LINKS", "humanoid_keypoints", "humanoid_pose"]

# COCO index -> humanoid link whose joint position is that keypoint.
JOINT_LINKS: dict[str, int] = {
    "left_shoulder": 12,
    "right_shoulder": 6,
    "left_elbow": 13,
    "right_elbow": 7,
    "left_wrist": 14,
    "right_wrist": 8,
    "left_hip": 9,
    "right_hip": 3,
    "left_knee": 10,
    "right_knee": 4,
    "left_ankle": 11,
    "right_ankle": 5,
}
NECK_LINK = 2
# Face keypoints in the neck link's frame (x forward, y up, z right), metres at scale 0.25.
HEAD_OFFSETS: dict[str, tuple[float, float, float]] = {
    "nose": (0.100, 0.175, 0.0),
    "left_eye": (0.085, 0.205, -0.035),
    "right_eye": (0.085, 0.205, 0.035),
    "left_ear": (0.0, 0.185, -0.095),
    "right_ear": (0.0, 0.185, 0.095),
}

_COCO_INDEX = {name: k for k, name in enumerate(COCO_KEYPOINTS)}
_LINKS = sorted(set(JOINT_LINKS.values()) | {NECK_LINK})
_LINK_ROW = {link: r for r, link in enumerate(_LINKS)}
_JOINT_KP = np.array([_COCO_INDEX[n] for n in JOINT_LINKS])
_JOINT_ROW = np.array([_LINK_ROW[JOINT_LINKS[n]] for n in JOINT_LINKS])
_HEAD_KP = np.array([_COCO_INDEX[n] for n in HEAD_OFFSETS])
_HEAD_OFF = np.array(list(HEAD_OFFSETS.values()))
assert len(_JOINT_KP) + len(_HEAD_KP) == NUM_KEYPOINTS


def humanoid_keypoints(client: int, body_ids: Sequence[int]) -> np.ndarray:
    """World positions of the 17 COCO keypoints of each humanoid.

    Args:
        client: PyBullet client id.
        body_ids: Humanoid body unique ids (the env's ``humans.ids`` or ``amp.ids``).

    Returns:
        (N, 17, 3) float64 world coordinates (m), in :data:`navzoo.sensors.COCO_KEYPOINTS` order.
    """
    n = len(body_ids)
    out = np.zeros((n, NUM_KEYPOINTS, 3))
    if n == 0:
        return out
    pos = np.zeros((n, len(_LINKS), 3))
    neck_q = np.zeros((n, 4))
    for i, body in enumerate(body_ids):
        states = p.getLinkStates(int(body), _LINKS, computeForwardKinematics=True, physicsClientId=client)
        if states is None:
            raise ValueError(f"body {body} is not a humanoid of client {client}")
        for r, s in enumerate(states):
            pos[i, r] = s[4]
        neck_q[i] = states[_LINK_ROW[NECK_LINK]][5]
    out[:, _JOINT_KP] = pos[:, _JOINT_ROW]
    head = Rotation.from_quat(neck_q).as_matrix()  # (N, 3, 3)
    out[:, _HEAD_KP] = pos[:, _LINK_ROW[NECK_LINK]][:, None, :] + np.einsum("nij,kj->nki", head, _HEAD_OFF)
    return out


def humanoid_pose(client: int, body_ids: Sequence[int]) -> tuple[np.ndarray, np.ndarray]:
    """Pelvis position and body orientation (heading of the pelvis's forward axis) of each humanoid.

    Args:
        client: PyBullet client id.
        body_ids: Humanoid body unique ids.

    Returns:
        ``(position (N, 3), yaw (N,))``.
    """
    n = len(body_ids)
    pos = np.zeros((n, 3))
    quat = np.zeros((n, 4))
    quat[:, 3] = 1.0
    for i, body in enumerate(body_ids):
        xyz, q = p.getBasePositionAndOrientation(int(body), physicsClientId=client)
        pos[i], quat[i] = xyz, q
    fwd = Rotation.from_quat(quat).apply(np.array([1.0, 0.0, 0.0])) if n else np.zeros((0, 3))
    return pos, np.arctan2(fwd[:, 1], fwd[:, 0]) if n else np.zeros(0)
