"""The robot's perception of people: cameras -> 2D keypoints -> Monoloco estimates -> Kalman tracks.

One :class:`RobotPerception` serves every robot of a :class:`~navzoo.envs.nav_env.NavEnv`. Each call of
:meth:`RobotPerception.step` does, for each robot and each of its cameras:

1. **keypoints**: the 17 COCO keypoints of every pedestrian body in the world
   (:func:`navzoo.perception.body_keypoints.humanoid_keypoints`) projected into the camera;
2. **occlusion**: a keypoint counts as visible when the camera's depth image, rendered by PyBullet at
   ``1 / occlusion_downscale`` of the camera's resolution with the robot's own body hidden, is not
   closer than the keypoint (:func:`navzoo.sensors.occlusion_visible`); ``occlusion="none"`` skips the
   rendering and only keeps keypoints inside the image;
3. **detector noise**: :class:`navzoo.sensors.KeypointNoise` (pixel noise, misses, truncation, false
   positives);
4. **Monoloco**: distance with its Laplace spread, direction and body orientation of each detection
   (:class:`navzoo.perception.monoloco.MonolocoEstimator`), in the world;
5. **tracking**: detections of both cameras go to the robot's :class:`~navzoo.perception.PersonTracker`
   with covariances elongated along the line of sight.

The result keeps the ground truth next to each estimate (which person a detection came from), so the
same pass serves the wrapper (:mod:`navzoo.perception.wrapper`) and the evaluation
(:mod:`navzoo.perception.evaluate`). Time spent in each stage is accumulated in :attr:`timing`.
"""

from __future__ import annotations

import time
from collections import defaultdict
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, NamedTuple

import numpy as np

from navzoo.perception.body_keypoints import humanoid_keypoints, humanoid_pose
from navzoo.perception.monoloco import MonolocoEstimator, decode_outputs, keypoint_features, load_estimator
from navzoo.perception.tracker import PersonTracker, Track, radial_covariance
from navzoo.sensors.camera_model import (
    NUM_KEYPOINTS,
    KeypointNoise,
    PinholeCamera,
    default_robot_cameras,
    occlusion_visible,
)

if TYPE_CHECKING:
    from navzoo.envs.nav_env import NavEnv

__all__ = ["CameraObservation", "PerceptionFrame", "RobotPerception", "VisibleKeypoints", "human_body_ids",
           "observe_camera", "people_ground_truth", "visible_keypoints"]

OCCLUSION_MODES = ("render", "none")
# Depth slack of the occlusion test per COCO keypoint (m): face keypoints lie on the head's surface, so
# the head itself hides them when the person looks away (as a detector does not report eyes and nose
# from behind); joint centres lie inside the limbs and the torso, up to about 0.12 m behind the surface
# the depth image sees.
OCCLUSION_TOLERANCE = np.array([0.04] * 5 + [0.15] * 12)


def human_body_ids(env: NavEnv) -> list[int]:
    """PyBullet ids of the pedestrian bodies (index j = pedestrian j = agent ``n_robots + j``)."""
    if env.n_humans == 0:
        return []
    return list(env.amp.ids) if env.amp is not None else list(env.humans.ids)


def people_ground_truth(env: NavEnv) -> dict[str, np.ndarray]:
    """The people the robots could see, from the simulator.

    Returns:
        ``index`` (M,) pedestrian indices (0-based among pedestrians) of the people in the world,
        ``pelvis`` (M, 3), ``yaw`` (M,) body orientation, ``velocity`` (M, 2) world velocity, and
        ``keypoints`` (M, 17, 3).
    """
    ids = human_body_ids(env)
    R = env.n_robots
    present = np.asarray(env.present[R:], dtype=bool) & np.asarray(env.alive[R:], dtype=bool)
    idx = np.flatnonzero(present)
    bodies = [ids[j] for j in idx]
    pelvis, yaw = humanoid_pose(env.client, bodies)
    kp = humanoid_keypoints(env.client, bodies)
    return {"index": idx, "pelvis": pelvis, "yaw": yaw, "velocity": np.asarray(env.vel[R + idx], dtype=float),
            "keypoints": kp}


@dataclass
class CameraObservation:
    """What one camera's detector reports, with the ground truth behind it.

    Attributes:
        camera: The camera.
        robot_pose: ``(x, y, yaw)`` of the robot when the image was taken.
        uv: (D, 17, 2) detected keypoints (pixels, NaN where missing).
        detected: (D, 17) bool.
        confidence: (D, 17) detector scores.
        person: (D,) pedestrian index of each detection, -1 for a false positive.
        visible_people: pedestrian indices with at least one visible keypoint in this image.
        in_view_people: pedestrian indices whose pelvis projects inside the image (visible or not).
        depth_image: the rendered depth image used for the occlusion test (None with ``occlusion="none"``).
    """

    camera: PinholeCamera
    robot_pose: np.ndarray
    uv: np.ndarray
    detected: np.ndarray
    confidence: np.ndarray
    person: np.ndarray
    visible_people: np.ndarray
    in_view_people: np.ndarray
    depth_image: np.ndarray | None = None


def _scaled(camera: PinholeCamera, downscale: int) -> PinholeCamera:
    from dataclasses import replace

    if downscale == 1:
        return camera
    return replace(camera, width=max(8, camera.width // downscale), height=max(6, camera.height // downscale))


class VisibleKeypoints(NamedTuple):
    """The true keypoints of the people near a robot, as one camera sees them (before detector noise).

    Attributes:
        robot_pose: ``(x, y, yaw)`` of the robot.
        people: (N,) pedestrian indices of the people within range.
        uv: (N, 17, 2) projected keypoints (pixels).
        depth: (N, 17) keypoint depths (m).
        visible: (N, 17) inside the image and not occluded.
        in_view: pedestrian indices whose pelvis projects inside the image.
        depth_image: the rendered occlusion depth image (None with ``occlusion="none"`` or nobody in the image).
    """

    robot_pose: np.ndarray
    people: np.ndarray
    uv: np.ndarray
    depth: np.ndarray
    visible: np.ndarray
    in_view: np.ndarray
    depth_image: np.ndarray | None


def visible_keypoints(env: NavEnv, robot_index: int, camera: PinholeCamera, gt: dict[str, np.ndarray] | None = None,
                      occlusion: str = "render", occlusion_downscale: int = 4, max_range: float = 20.0
                      ) -> VisibleKeypoints:
    """Steps 1-2 of the module docstring for one camera: project the keypoints, test occlusion.

    Arguments as :func:`observe_camera`.
    """
    if occlusion not in OCCLUSION_MODES:
        raise ValueError(f"occlusion must be one of {OCCLUSION_MODES}, got {occlusion!r}")
    gt = people_ground_truth(env) if gt is None else gt
    pose = np.array([env.pos[robot_index, 0], env.pos[robot_index, 1], env.yaw[robot_index]], dtype=float)
    near = np.linalg.norm(gt["pelvis"][:, :2] - pose[:2], axis=1) <= max_range
    kp = gt["keypoints"][near]
    people = gt["index"][near]
    uv, depth = camera.project(kp, pose) if len(kp) else (np.zeros((0, NUM_KEYPOINTS, 2)), np.zeros((0, NUM_KEYPOINTS)))
    inside = camera.in_image(uv, depth)
    depth_image = None
    if occlusion == "render" and inside.any():
        from navzoo.sensors.render import render_camera

        small = _scaled(camera, int(occlusion_downscale))
        depth_image = render_camera(env.client, small, pose, renderer="auto",
                                    hide_body_ids=[env.robots.ids[robot_index]]).depth
        scale = np.array([small.width / camera.width, small.height / camera.height])
        visible = inside & occlusion_visible(uv * scale, depth, depth_image, tolerance=OCCLUSION_TOLERANCE)
    else:
        visible = inside
    pelvis_uv, pelvis_d = camera.project(gt["pelvis"][near], pose) if len(kp) else (np.zeros((0, 2)), np.zeros(0))
    in_view = people[camera.in_image(pelvis_uv, pelvis_d)]
    return VisibleKeypoints(pose, people, uv, depth, visible, in_view, depth_image)


def observe_camera(env: NavEnv, robot_index: int, camera: PinholeCamera, noise: KeypointNoise,
                   rng: np.random.Generator, gt: dict[str, np.ndarray] | None = None,
                   occlusion: str = "render", occlusion_downscale: int = 4, max_range: float = 20.0
                   ) -> CameraObservation:
    """Simulate the keypoint detector of one robot camera (steps 1-3 of the module docstring).

    Args:
        env: The env (its current state).
        robot_index: Which robot carries the camera.
        camera: The camera.
        noise: Detector model.
        rng: Randomness of the detector.
        gt: :func:`people_ground_truth` of this step (computed when None).
        occlusion: ``"render"`` (depth-image test) or ``"none"`` (image bounds only).
        occlusion_downscale: Resolution divisor of the rendered depth image.
        max_range: People farther than this (m) from the robot are not considered at all.

    Returns:
        :class:`CameraObservation`.
    """
    v = visible_keypoints(env, robot_index, camera, gt, occlusion, occlusion_downscale, max_range)
    det = noise.detect(v.uv, v.depth, v.visible, rng, camera)
    person = np.concatenate([v.people, -np.ones(len(det.uv) - len(v.people), dtype=int)])
    keep = det.person_detected
    return CameraObservation(camera, v.robot_pose, det.uv[keep], det.detected[keep], det.confidence[keep],
                             person[keep], v.people[v.visible.any(axis=1)], v.in_view, v.depth_image)


@dataclass
class PerceptionFrame:
    """One robot's perception at one step.

    Attributes:
        robot_index: The robot.
        observations: One :class:`CameraObservation` per camera.
        position: (D, 2) estimated world positions of all detections (cameras concatenated).
        position_cov: (D, 2, 2) their covariances.
        yaw: (D,) estimated body orientations (world).
        distance: (D,) estimated distances from the camera.
        person: (D,) ground-truth pedestrian index of each detection (-1: false positive).
        camera_index: (D,) which camera.
        tracks: confirmed tracks after this step's update.
    """

    robot_index: int
    observations: list[CameraObservation]
    position: np.ndarray
    position_cov: np.ndarray
    yaw: np.ndarray
    distance: np.ndarray
    person: np.ndarray
    camera_index: np.ndarray
    tracks: list[Track] = field(default_factory=list)


def _cross_camera_duplicates(position: np.ndarray, camera: np.ndarray, n_keypoints: np.ndarray,
                             merge_distance: float) -> np.ndarray:
    """Mask of the detections to keep: of two from different cameras within ``merge_distance``, the one
    with more keypoints (a person at the border between two images is seen, truncated, by both)."""
    keep = np.ones(len(position), dtype=bool)
    if len(position) < 2 or merge_distance <= 0:
        return keep
    d = np.linalg.norm(position[:, None] - position[None], axis=2)
    close = (d < merge_distance) & (camera[:, None] != camera[None])
    for a, b in zip(*np.nonzero(np.triu(close, 1)), strict=True):
        if keep[a] and keep[b]:
            keep[b if n_keypoints[a] >= n_keypoints[b] else a] = False
    return keep


class RobotPerception:
    """Cameras, detector model, Monoloco network and one tracker per robot of an env.

    Args:
        cameras: The cameras on each robot (default :func:`navzoo.sensors.default_robot_cameras`).
        noise: Detector model (default :class:`KeypointNoise` with its documented defaults).
        estimator: Monoloco estimator (default: the shipped ``policies/monoloco``).
        occlusion: ``"render"`` or ``"none"`` (see :func:`observe_camera`).
        occlusion_downscale: Resolution divisor of the occlusion depth image.
        max_range: People farther than this are ignored (m).
        lateral_std: Standard deviation (m) across the line of sight given to the tracker, plus
            ``lateral_std_per_m`` per metre of distance.
        tracker_kwargs: Passed to :class:`PersonTracker` (``dt`` defaults to the env's).
        merge_distance: Detections of different cameras closer than this (m) are one person seen at the
            border of both images: only the one with more keypoints goes to the tracker.
        seed: Seed of the detector noise.
    """

    def __init__(self, cameras: Sequence[PinholeCamera] | None = None, noise: KeypointNoise | None = None,
                 estimator: MonolocoEstimator | None = None, occlusion: str = "render",
                 occlusion_downscale: int = 4, max_range: float = 20.0, lateral_std: float = 0.05,
                 lateral_std_per_m: float = 0.02, tracker_kwargs: dict[str, Any] | None = None,
                 merge_distance: float = 0.6, seed: int | None = 0) -> None:
        if occlusion not in OCCLUSION_MODES:
            raise ValueError(f"occlusion must be one of {OCCLUSION_MODES}, got {occlusion!r}")
        if int(occlusion_downscale) != occlusion_downscale or occlusion_downscale < 1:
            raise ValueError(f"occlusion_downscale must be an integer >= 1, got {occlusion_downscale!r}")
        if not (np.isfinite(max_range) and max_range > 0):
            raise ValueError(f"max_range must be > 0, got {max_range!r}")
        self.cameras = list(cameras) if cameras is not None else list(default_robot_cameras())
        if not self.cameras or not all(isinstance(c, PinholeCamera) for c in self.cameras):
            raise ValueError("cameras must be a non-empty sequence of PinholeCamera")
        self.noise = noise if noise is not None else KeypointNoise()
        self.estimator = estimator if estimator is not None else load_estimator()
        self.occlusion = occlusion
        self.occlusion_downscale = int(occlusion_downscale)
        self.max_range = float(max_range)
        self.lateral_std = float(lateral_std)
        self.lateral_std_per_m = float(lateral_std_per_m)
        self.tracker_kwargs = dict(tracker_kwargs or {})
        if not (np.isfinite(merge_distance) and merge_distance >= 0):
            raise ValueError(f"merge_distance must be >= 0, got {merge_distance!r}")
        self.merge_distance = float(merge_distance)
        self.rng = np.random.default_rng(seed)
        self.trackers: dict[int, PersonTracker] = {}
        self.timing: dict[str, float] = defaultdict(float)
        self.calls = 0

    def reset(self, env: NavEnv, seed: int | None = None) -> None:
        """New trackers for the robots of ``env`` (call after ``env.reset``)."""
        if seed is not None:
            self.rng = np.random.default_rng(seed)
        kw = {"dt": float(env.config.dt), **self.tracker_kwargs}
        self.trackers = {i: PersonTracker(**kw) for i in range(env.n_robots)}

    def step(self, env: NavEnv, robots: Sequence[int] | None = None) -> dict[int, PerceptionFrame]:
        """Perceive and track for each robot in ``robots`` (default: the live ones).

        Returns:
            ``{robot_index: PerceptionFrame}``.
        """
        if not self.trackers:
            self.reset(env)
        robots = [i for i in range(env.n_robots) if env.alive[i]] if robots is None else list(robots)
        t0 = time.perf_counter()
        gt = people_ground_truth(env)
        self.timing["keypoints"] += time.perf_counter() - t0
        out = {}
        for i in robots:
            out[i] = self._robot_step(env, int(i), gt)
        self.calls += len(robots)
        return out

    def _robot_step(self, env: NavEnv, i: int, gt: dict[str, np.ndarray]) -> PerceptionFrame:
        obs: list[CameraObservation] = []
        feats, cams = [], []
        for c, cam in enumerate(self.cameras):
            t0 = time.perf_counter()
            o = observe_camera(env, i, cam, self.noise, self.rng, gt, self.occlusion, self.occlusion_downscale,
                               self.max_range)
            self.timing["render_and_detect"] += time.perf_counter() - t0
            obs.append(o)
            feats.append(keypoint_features(o.uv, o.detected, cam))
            cams.append(np.full(len(o.uv), c))
        t0 = time.perf_counter()
        raw = self.estimator.raw(np.concatenate(feats)) if sum(len(f) for f in feats) else np.zeros((0, 6))
        self.timing["network"] += time.perf_counter() - t0
        cam_idx = np.concatenate(cams).astype(int)
        pos, cov, yaw, dist = [], [], [], []
        start = 0
        for o in obs:
            n = len(o.uv)
            est = decode_outputs(raw[start:start + n].astype(np.float64), o.camera, o.robot_pose)
            start += n
            xy = est.position_world[:, :2]
            centre = o.camera.extrinsics(o.robot_pose)[1][:2]
            lat = self.lateral_std + self.lateral_std_per_m * est.distance
            cov.append(radial_covariance(xy, np.maximum(est.distance_std, 0.05), lat, origin=centre)
                       if n else np.zeros((0, 2, 2)))
            pos.append(xy)
            yaw.append(est.yaw_world)
            dist.append(est.distance)
        position = np.concatenate(pos) if pos else np.zeros((0, 2))
        position_cov = np.concatenate(cov) if cov else np.zeros((0, 2, 2))
        yaw_all = np.concatenate(yaw) if yaw else np.zeros(0)
        n_kp = np.concatenate([o.detected.sum(axis=1) for o in obs]) if obs else np.zeros(0, dtype=int)
        fuse = _cross_camera_duplicates(position, cam_idx, n_kp, self.merge_distance)
        t0 = time.perf_counter()
        tracks = self.trackers[i].update(position[fuse], position_cov[fuse], extras={"orientation": yaw_all[fuse]})
        self.timing["tracker"] += time.perf_counter() - t0
        person = np.concatenate([o.person for o in obs]) if obs else np.zeros(0, dtype=int)
        return PerceptionFrame(i, obs, position, position_cov, yaw_all,
                               np.concatenate(dist) if dist else np.zeros(0), person, cam_idx, tracks)

    def ms_per_robot_step(self) -> dict[str, float]:
        """Mean milliseconds per robot step of each stage so far (keypoints are shared by the robots)."""
        n = max(self.calls, 1)
        out = {k: 1000.0 * v / n for k, v in self.timing.items()}
        out["total"] = sum(out.values())
        return out
