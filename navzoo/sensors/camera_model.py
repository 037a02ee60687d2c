"""Pinhole cameras on the robot and a noise model of a 2D human keypoint detector (pure numpy).

Frames and conventions:

* World: x, y on the ground plane, z up. A robot pose is ``(x, y, yaw)``, yaw counter-clockwise from
  world +x (radians).
* Robot: x forward, y left, z up (REP 103). A camera is mounted at ``(mount_x, mount_y, mount_z)`` in
  the robot frame, turned by ``mount_yaw`` (counter-clockwise, so +30 degrees looks front-left) and then
  tilted by ``mount_pitch`` (positive looks down).
* Camera (optical frame): x right, y down, z forward, as in OpenCV. ``depth`` is the z coordinate in
  this frame (distance along the optical axis, not along the ray), which is also what a linearised
  z-buffer (e.g. PyBullet's, after converting it to metres) holds.
* Image: ``u`` to the right, ``v`` down, in pixels; the image covers ``[0, width) x [0, height)`` and
  pixel ``(row, col)`` covers ``[col, col + 1) x [row, row + 1)`` (pixel centres at half-integers, the
  convention of an OpenGL/PyBullet render). The principal point is the image centre
  ``(width / 2, height / 2)`` and ``fx = fy = (width / 2) / tan(hfov / 2)`` (square pixels), so a point
  on the edge of the horizontal field of view projects to ``u = 0`` or ``u = width``.

:class:`KeypointNoise` turns exact projections of the 17 COCO keypoints (:data:`COCO_KEYPOINTS`) into
what a detector such as OpenPose or the PifPaf front-end of Monoloco reports: jittered pixels, missed
keypoints and people, truncation at the image border, confidences and occasional false positives.
:func:`occlusion_visible` decides which keypoints a depth image hides.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, fields
from typing import NamedTuple

import numpy as np

__all__ = [
    "COCO_KEYPOINTS",
    "COCO_SKELETON",
    "NUM_KEYPOINTS",
    "PinholeCamera",
    "default_robot_cameras",
    "KeypointDetections",
    "KeypointNoise",
    "occlusion_visible",
]

COCO_KEYPOINTS: tuple[str, ...] = (
    "nose",
    "left_eye",
    "right_eye",
    "left_ear",
    "right_ear",
    "left_shoulder",
    "right_shoulder",
    "left_elbow",
    "right_elbow",
    "left_wrist",
    "right_wrist",
    "left_hip",
    "right_hip",
    "left_knee",
    "right_knee",
    "left_ankle",
    "right_ankle",
)
"""The 17 COCO person keypoints, in COCO order."""

NUM_KEYPOINTS = len(COCO_KEYPOINTS)

COCO_SKELETON: tuple[tuple[int, int], ...] = (
    (15, 13),
    (13, 11),
    (16, 14),
    (14, 12),
    (11, 12),
    (5, 11),
    (6, 12),
    (5, 6),
    (5, 7),
    (6, 8),
    (7, 9),
    (8, 10),
    (1, 2),
    (0, 1),
    (0, 2),
    (1, 3),
    (2, 4),
    (3, 5),
    (4, 6),
)
"""The 19 limbs of the COCO skeleton as pairs of 0-based indices into :data:`COCO_KEYPOINTS`."""

# Standing person facing the camera, in units of body height: x right (the person's left side appears on
# the image right), y down from the top of the head. Used to draw false-positive skeletons.
_TEMPLATE = np.array(
    [
        [0.0, 0.06],
        [0.02, 0.045],
        [-0.02, 0.045],
        [0.045, 0.055],
        [-0.045, 0.055],
        [0.11, 0.18],
        [-0.11, 0.18],
        [0.14, 0.33],
        [-0.14, 0.33],
        [0.15, 0.46],
        [-0.15, 0.46],
        [0.07, 0.52],
        [-0.07, 0.52],
        [0.07, 0.74],
        [-0.07, 0.74],
        [0.07, 0.95],
        [-0.07, 0.95],
    ]
)
_TEMPLATE_HALF_WIDTH = 0.15
_PERSON_HEIGHT_M = 1.7
_EPS_DEPTH = 1e-9


@dataclass(frozen=True)
class PinholeCamera:
    """An ideal pinhole camera (no distortion) mounted on the robot; see the module docstring for frames.

    Attributes:
        width: Image width (pixels, > 0).
        height: Image height (pixels, > 0).
        hfov_deg: Horizontal field of view (degrees, in (0, 180)).
        mount_x: Forward offset of the optical centre in the robot frame (m).
        mount_y: Left offset of the optical centre in the robot frame (m).
        mount_z: Height of the optical centre above the robot's ground point (m).
        mount_yaw: Yaw of the camera relative to the robot (rad, counter-clockwise: > 0 looks left).
        mount_pitch: Downward tilt of the camera (rad, > 0 looks down, in (-pi/2, pi/2)).
        name: Label for the camera (e.g. ``"front_left"``).
    """

    width: int
    height: int
    hfov_deg: float = 60.0
    mount_x: float = 0.0
    mount_y: float = 0.0
    mount_z: float = 1.0
    mount_yaw: float = 0.0
    mount_pitch: float = 0.0
    name: str = "camera"

    def __post_init__(self) -> None:
        if not (np.isfinite(self.width) and self.width > 0):
            raise ValueError(f"width must be a positive number of pixels, got {self.width!r}")
        if not (np.isfinite(self.height) and self.height > 0):
            raise ValueError(f"height must be a positive number of pixels, got {self.height!r}")
        if not (np.isfinite(self.hfov_deg) and 0.0 < self.hfov_deg < 180.0):
            raise ValueError(f"hfov_deg must be in (0, 180) degrees, got {self.hfov_deg!r}")
        for name in ("mount_x", "mount_y", "mount_z", "mount_yaw"):
            if not np.isfinite(getattr(self, name)):
                raise ValueError(f"{name} must be finite, got {getattr(self, name)!r}")
        if not (np.isfinite(self.mount_pitch) and abs(self.mount_pitch) < math.pi / 2):
            raise ValueError(f"mount_pitch must be in (-pi/2, pi/2) rad, got {self.mount_pitch!r}")

    @property
    def fx(self) -> float:
        """Horizontal focal length (pixels): ``(width / 2) / tan(hfov / 2)``."""
        return (self.width / 2.0) / math.tan(math.radians(self.hfov_deg) / 2.0)

    @property
    def fy(self) -> float:
        """Vertical focal length (pixels), equal to :attr:`fx` (square pixels)."""
        return self.fx

    @property
    def cx(self) -> float:
        """Principal point, horizontal (pixels): the image centre ``width / 2``."""
        return self.width / 2.0

    @property
    def cy(self) -> float:
        """Principal point, vertical (pixels): the image centre ``height / 2``."""
        return self.height / 2.0

    @property
    def vfov_deg(self) -> float:
        """Vertical field of view (degrees) implied by the image size and :attr:`fy`."""
        return math.degrees(2.0 * math.atan((self.height / 2.0) / self.fy))

    def intrinsics(self) -> np.ndarray:
        """The 3x3 intrinsic matrix ``K = [[fx, 0, cx], [0, fy, cy], [0, 0, 1]]``.

        Returns:
            (3, 3) float array.
        """
        return np.array([[self.fx, 0.0, self.cx], [0.0, self.fy, self.cy], [0.0, 0.0, 1.0]])

    def extrinsics(
        self, robot_pose: np.ndarray | tuple[float, float, float]
    ) -> tuple[np.ndarray, np.ndarray]:
        """Rotation and position of the camera for a robot pose.

        Args:
            robot_pose: ``(x, y, yaw)`` of the robot in the world.

        Returns:
            ``(R, t)``: (3, 3) rotation whose rows are the camera's x (right), y (down) and z (forward)
            axes in world coordinates, so ``p_cam = R @ (p_world - t)``, and the (3,) optical centre in
            the world.
        """
        x, y, yaw = (float(v) for v in np.asarray(robot_pose, dtype=float).reshape(3))
        c, s = math.cos(yaw), math.sin(yaw)
        t = np.array(
            [x + c * self.mount_x - s * self.mount_y, y + s * self.mount_x + c * self.mount_y, self.mount_z]
        )
        psi = yaw + self.mount_yaw
        forward_h = np.array([math.cos(psi), math.sin(psi), 0.0])
        left = np.array([-math.sin(psi), math.cos(psi), 0.0])
        up = np.array([0.0, 0.0, 1.0])
        cp, sp = math.cos(self.mount_pitch), math.sin(self.mount_pitch)
        forward = cp * forward_h - sp * up
        up_cam = sp * forward_h + cp * up
        rot = np.stack([-left, -up_cam, forward])
        return rot, t

    def world_to_camera(
        self, points_world: np.ndarray, robot_pose: np.ndarray | tuple[float, float, float]
    ) -> np.ndarray:
        """Express world points in the camera's optical frame (x right, y down, z forward).

        Args:
            points_world: (..., 3) points in the world (m).
            robot_pose: ``(x, y, yaw)`` of the robot in the world.

        Returns:
            (..., 3) points in the camera frame (m); the last coordinate is the depth.
        """
        pts = np.asarray(points_world, dtype=float)
        if pts.shape[-1] != 3:
            raise ValueError(f"points_world must have shape (..., 3), got {pts.shape}")
        rot, t = self.extrinsics(robot_pose)
        return (pts - t) @ rot.T

    def project(
        self, points_world: np.ndarray, robot_pose: np.ndarray | tuple[float, float, float]
    ) -> tuple[np.ndarray, np.ndarray]:
        """Project world points into the image.

        Args:
            points_world: (..., 3) points in the world (m).
            robot_pose: ``(x, y, yaw)`` of the robot in the world.

        Returns:
            ``(uv, depth)``: (..., 2) pixel coordinates (NaN for points not in front of the camera,
            ``depth <= 0``) and (...,) depth, the camera-frame z (m).
        """
        pc = self.world_to_camera(points_world, robot_pose)
        depth = pc[..., 2]
        front = depth > _EPS_DEPTH
        safe = np.where(front, depth, 1.0)
        u = np.where(front, self.fx * pc[..., 0] / safe + self.cx, np.nan)
        v = np.where(front, self.fy * pc[..., 1] / safe + self.cy, np.nan)
        return np.stack([u, v], axis=-1), depth

    def in_image(self, uv: np.ndarray, depth: np.ndarray, margin: float = 0.0) -> np.ndarray:
        """Which projections fall inside the image, in front of the camera.

        Args:
            uv: (..., 2) pixel coordinates.
            depth: (...,) depths (m); only points with ``depth > 0`` count.
            margin: Border (pixels) to keep clear: a point counts when
                ``margin <= u < width - margin`` and ``margin <= v < height - margin``.

        Returns:
            (...,) bool mask.
        """
        uv = np.asarray(uv, dtype=float)
        depth = np.asarray(depth, dtype=float)
        u, v = uv[..., 0], uv[..., 1]
        with np.errstate(invalid="ignore"):
            return (
                (depth > _EPS_DEPTH)
                & (u >= margin)
                & (u < self.width - margin)
                & (v >= margin)
                & (v < self.height - margin)
            )

    def fov_contains(
        self,
        points_world: np.ndarray,
        robot_pose: np.ndarray | tuple[float, float, float],
        margin: float = 0.0,
    ) -> np.ndarray:
        """Whether world points project inside the image (:meth:`project` then :meth:`in_image`).

        Args:
            points_world: (..., 3) points in the world (m).
            robot_pose: ``(x, y, yaw)`` of the robot in the world.
            margin: Border (pixels) to keep clear, as in :meth:`in_image`.

        Returns:
            (...,) bool mask.
        """
        uv, depth = self.project(points_world, robot_pose)
        return self.in_image(uv, depth, margin)


def default_robot_cameras(width: int = 640, height: int = 480) -> tuple[PinholeCamera, PinholeCamera]:
    """The robot's two RGB cameras: 60 degrees horizontal FOV each, turned +30 degrees (front-left) and
    -30 degrees (front-right), 1.0 m above the ground at the robot's centre, level.

    Together they cover 120 degrees in front of the robot, the two fields of view meeting straight ahead.

    Args:
        width: Image width (pixels).
        height: Image height (pixels).

    Returns:
        ``(front_left, front_right)`` cameras.
    """
    yaw = math.radians(30.0)
    return (
        PinholeCamera(width, height, hfov_deg=60.0, mount_z=1.0, mount_yaw=yaw, name="front_left"),
        PinholeCamera(width, height, hfov_deg=60.0, mount_z=1.0, mount_yaw=-yaw, name="front_right"),
    )


class KeypointDetections(NamedTuple):
    """Keypoints reported by the (simulated) detector for one image.

    Attributes:
        uv: (N, 17, 2) pixel coordinates, NaN where the keypoint is not detected.
        detected: (N, 17) bool, keypoint reported (always False for a missed person).
        confidence: (N, 17) scores in [0, 1], 0 where not detected.
        person_detected: (N,) bool, whether the person is reported at all.
        false_positive: (N,) bool, True for spurious skeletons (no real person behind them).
    """

    uv: np.ndarray
    detected: np.ndarray
    confidence: np.ndarray
    person_detected: np.ndarray
    false_positive: np.ndarray


def _image_size(image_size: tuple[int, int] | PinholeCamera) -> tuple[float, float]:
    if isinstance(image_size, PinholeCamera):
        return float(image_size.width), float(image_size.height)
    w, h = image_size
    return float(w), float(h)


@dataclass(frozen=True)
class KeypointNoise:
    """Noise model of a bottom-up 2D keypoint detector (OpenPose / PifPaf) on 640x480 images.

    For a person whose keypoint ``k`` lies at depth ``d_k`` (m):

    * Pixel noise: isotropic Gaussian, std ``sigma_k = pixel_std + pixel_std_per_m * d_k`` (px). Default
      2 px + 0.5 px/m: 3 px at 2 m, 6 px at 8 m. With the default cameras (``fx = 554 px``) a 1.7 m
      person is ~470 px tall at 2 m and ~120 px at 8 m; detectors work on heat maps at 1/8 of the input
      resolution, which bounds the error near a couple of pixels for large people, and far people are
      smaller in the network input and blurrier, so their keypoints are localised worse in absolute
      pixels too (a 6 px error at 8 m is ~5 % of the body height).
    * Keypoint misses: a visible keypoint is dropped with probability
      ``clip(miss_prob + miss_prob_per_m * d_k, 0, 1)`` (default 2 % + 2 %/m: 6 % at 2 m, 18 % at 8 m).
    * Truncation: keypoints whose noisy pixel falls outside the image are not reported.
    * Person misses: the whole person is missed with probability
      ``clip(person_miss_prob + person_miss_prob_per_m * d, 0, 1)``, ``d`` the median depth of the
      visible keypoints (default 2 % + 1 %/m), or when fewer than ``min_keypoints`` keypoints survive.
      Default 5: OpenPose and PifPaf drop instances with only a few parts (low instance score), and
      Monoloco's distance estimate needs several joints spread over the body to be of any use.
    * Confidence: ``(1 - p_miss_k) * exp(-sigma_k / confidence_scale_px)`` plus Gaussian jitter of std
      ``confidence_jitter``, clipped to [0, 1]; it falls with distance (0.81 at 2 m, 0.61 at 8 m by
      default before jitter).
    * False positives: a Poisson number of spurious people per image with mean ``false_positive_rate``
      (default 0.05, one every 20 frames), see :meth:`false_positives`.

    Every random draw comes from the given ``numpy.random.Generator``, in fixed shapes, so the output is
    a function of the seed and the inputs. :meth:`none` gives a noise-free model.

    Attributes:
        pixel_std: Base keypoint pixel noise std (px).
        pixel_std_per_m: Increase of the pixel noise std per metre of depth (px/m).
        miss_prob: Base probability of missing a visible keypoint.
        miss_prob_per_m: Increase of the keypoint miss probability per metre.
        person_miss_prob: Base probability of missing a whole person.
        person_miss_prob_per_m: Increase of the person miss probability per metre.
        min_keypoints: A person with fewer detected keypoints is not reported (0 to 17).
        false_positive_rate: Expected number of spurious people per image.
        confidence_scale_px: Pixel-noise scale of the confidence decay (px, > 0).
        confidence_jitter: Std of the Gaussian jitter added to confidences.
        false_positive_depth_range: Range (m) of the apparent distance that sets a false positive's size.
    """

    pixel_std: float = 2.0
    pixel_std_per_m: float = 0.5
    miss_prob: float = 0.02
    miss_prob_per_m: float = 0.02
    person_miss_prob: float = 0.02
    person_miss_prob_per_m: float = 0.01
    min_keypoints: int = 5
    false_positive_rate: float = 0.05
    confidence_scale_px: float = 20.0
    confidence_jitter: float = 0.05
    false_positive_depth_range: tuple[float, float] = (3.0, 12.0)

    def __post_init__(self) -> None:
        for f in fields(self):
            if f.name in ("min_keypoints", "false_positive_depth_range"):
                continue
            value = getattr(self, f.name)
            if not (np.isfinite(value) and value >= 0.0):
                raise ValueError(f"{f.name} must be a finite number >= 0, got {value!r}")
        for name in ("miss_prob", "person_miss_prob"):
            if getattr(self, name) > 1.0:
                raise ValueError(f"{name} must be a probability in [0, 1], got {getattr(self, name)!r}")
        if self.confidence_scale_px <= 0.0:
            raise ValueError(f"confidence_scale_px must be > 0, got {self.confidence_scale_px!r}")
        if int(self.min_keypoints) != self.min_keypoints or not 0 <= self.min_keypoints <= NUM_KEYPOINTS:
            raise ValueError(
                f"min_keypoints must be an integer in [0, {NUM_KEYPOINTS}], got {self.min_keypoints!r}"
            )
        lo, hi = self.false_positive_depth_range
        if not (np.isfinite(lo) and np.isfinite(hi) and 0.0 < lo <= hi):
            raise ValueError(
                f"false_positive_depth_range must be (lo, hi) with 0 < lo <= hi, got {self.false_positive_depth_range!r}"
            )

    @classmethod
    def none(cls, min_keypoints: int = 0) -> KeypointNoise:
        """A noise-free detector: exact pixels, no misses, no false positives, confidence 1.

        Args:
            min_keypoints: Minimum number of keypoints to report a person (truncation still applies).

        Returns:
            The model.
        """
        return cls(
            pixel_std=0.0,
            pixel_std_per_m=0.0,
            miss_prob=0.0,
            miss_prob_per_m=0.0,
            person_miss_prob=0.0,
            person_miss_prob_per_m=0.0,
            min_keypoints=min_keypoints,
            false_positive_rate=0.0,
            confidence_jitter=0.0,
        )

    def pixel_sigma(self, depth: np.ndarray) -> np.ndarray:
        """Pixel noise std (px) at a depth: ``pixel_std + pixel_std_per_m * max(depth, 0)``.

        Args:
            depth: Depths (m), any shape.

        Returns:
            Stds of the same shape.
        """
        return self.pixel_std + self.pixel_std_per_m * np.maximum(np.asarray(depth, dtype=float), 0.0)

    def keypoint_miss_probability(self, depth: np.ndarray) -> np.ndarray:
        """Probability of missing a visible keypoint at a depth (clipped to [0, 1]).

        Args:
            depth: Depths (m), any shape.

        Returns:
            Probabilities of the same shape.
        """
        d = np.maximum(np.asarray(depth, dtype=float), 0.0)
        return np.clip(self.miss_prob + self.miss_prob_per_m * d, 0.0, 1.0)

    def apply(
        self,
        uv: np.ndarray,
        depth: np.ndarray,
        visible: np.ndarray,
        rng: np.random.Generator,
        *,
        image_size: tuple[int, int] | PinholeCamera,
    ) -> KeypointDetections:
        """Simulate the detector on the true keypoints of the people in one image (no false positives).

        Args:
            uv: (N, 17, 2) exact pixel coordinates of the keypoints (:meth:`PinholeCamera.project`).
            depth: (N, 17) depth of each keypoint, or (N,) one depth per person (m).
            visible: (N, 17) bool, keypoints that can be seen (in front of the camera, not occluded,
                e.g. :meth:`PinholeCamera.in_image` and :func:`occlusion_visible`). Keypoints with a
                non-finite pixel or a depth <= 0 are never detected.
            rng: Source of randomness.
            image_size: ``(width, height)`` in pixels, or the camera, for the truncation.

        Returns:
            :class:`KeypointDetections` with ``false_positive`` all False; it unpacks as
            ``uv, detected, confidence, person_detected, false_positive``.
        """
        uv = np.asarray(uv, dtype=float)
        if uv.ndim != 3 or uv.shape[1:] != (NUM_KEYPOINTS, 2):
            raise ValueError(f"uv must have shape (N, {NUM_KEYPOINTS}, 2), got {uv.shape}")
        n = uv.shape[0]
        depth = np.asarray(depth, dtype=float)
        if depth.shape == (n,):
            depth = np.repeat(depth[:, None], NUM_KEYPOINTS, axis=1)
        if depth.shape != (n, NUM_KEYPOINTS):
            raise ValueError(f"depth must have shape (N,) or (N, {NUM_KEYPOINTS}), got {depth.shape}")
        visible = np.asarray(visible, dtype=bool)
        if visible.shape != (n, NUM_KEYPOINTS):
            raise ValueError(f"visible must have shape (N, {NUM_KEYPOINTS}), got {visible.shape}")
        width, height = _image_size(image_size)

        # Every draw in a fixed shape, so results depend only on the seed and N.
        pixel_noise = rng.standard_normal((n, NUM_KEYPOINTS, 2))
        keypoint_draw = rng.random((n, NUM_KEYPOINTS))
        person_draw = rng.random(n)
        confidence_noise = rng.standard_normal((n, NUM_KEYPOINTS))

        valid = visible & np.isfinite(uv).all(axis=-1) & np.isfinite(depth) & (depth > _EPS_DEPTH)
        d = np.where(valid, depth, 0.0)
        sigma = self.pixel_sigma(d)
        p_miss = self.keypoint_miss_probability(d)
        noisy = uv + sigma[..., None] * pixel_noise
        with np.errstate(invalid="ignore"):
            inside = (
                (noisy[..., 0] >= 0)
                & (noisy[..., 0] < width)
                & (noisy[..., 1] >= 0)
                & (noisy[..., 1] < height)
            )
        keypoint_ok = valid & (keypoint_draw >= p_miss) & inside

        any_valid = valid.any(axis=1)
        person_depth = np.zeros(n)
        if any_valid.any():
            person_depth[any_valid] = np.nanmedian(np.where(valid, depth, np.nan)[any_valid], axis=1)
        p_person = np.clip(self.person_miss_prob + self.person_miss_prob_per_m * person_depth, 0.0, 1.0)
        person_ok = (
            any_valid
            & (person_draw >= p_person)
            & (keypoint_ok.sum(axis=1) >= max(int(self.min_keypoints), 1))
        )

        detected = keypoint_ok & person_ok[:, None]
        conf = (1.0 - p_miss) * np.exp(
            -sigma / self.confidence_scale_px
        ) + self.confidence_jitter * confidence_noise
        conf = np.where(detected, np.clip(conf, 0.0, 1.0), 0.0)
        out_uv = np.where(detected[..., None], noisy, np.nan)
        return KeypointDetections(out_uv, detected, conf, person_ok, np.zeros(n, dtype=bool))

    def false_positives(
        self, rng: np.random.Generator, camera: PinholeCamera | tuple[int, int], fy: float | None = None
    ) -> KeypointDetections:
        """Spurious people for one image.

        Their number is Poisson with mean ``false_positive_rate``. Each is the standing template
        skeleton (randomly mirrored) of a 1.7 m person at an apparent distance drawn uniformly in
        ``false_positive_depth_range`` (height ``fy * 1.7 / d`` px), placed uniformly where its bounding
        box fits in the image (at the top-left when it does not fit), with keypoint jitter of 3 % of its
        height, a random subset of ``max(min_keypoints, 1)`` to 17 keypoints and low confidences,
        uniform in [0.1, 0.5]. A skeleton left with fewer than ``min_keypoints`` keypoints after
        truncation (only possible on images smaller than the skeleton) is dropped.

        Args:
            rng: Source of randomness.
            camera: The camera, or ``(width, height)`` in pixels (then ``fy`` sets the size).
            fy: Vertical focal length (px) when ``camera`` is a size; default that of a 60 degree
                horizontal FOV.

        Returns:
            :class:`KeypointDetections` of the M spurious people, ``false_positive`` all True.
        """
        width, height = _image_size(camera)
        if isinstance(camera, PinholeCamera):
            focal = camera.fy
        else:
            focal = fy if fy is not None else (width / 2.0) / math.tan(math.radians(30.0))
        m = int(rng.poisson(self.false_positive_rate)) if self.false_positive_rate > 0 else 0
        lo, hi = self.false_positive_depth_range
        min_kp = max(int(self.min_keypoints), 1)
        uvs = np.full((m, NUM_KEYPOINTS, 2), np.nan)
        det = np.zeros((m, NUM_KEYPOINTS), dtype=bool)
        conf = np.zeros((m, NUM_KEYPOINTS))
        for i in range(m):
            h = focal * _PERSON_HEIGHT_M / rng.uniform(lo, hi)
            half_w = _TEMPLATE_HALF_WIDTH * h
            left = rng.uniform(0.0, max(width - 2 * half_w, 0.0))
            top = rng.uniform(0.0, max(height - h, 0.0))
            template = _TEMPLATE.copy()
            if rng.random() < 0.5:
                template[:, 0] *= -1.0
            pts = np.column_stack([left + half_w + template[:, 0] * h, top + template[:, 1] * h])
            pts += rng.normal(0.0, 0.03 * h, size=pts.shape)
            k = int(rng.integers(min_kp, NUM_KEYPOINTS + 1))
            keep = np.zeros(NUM_KEYPOINTS, dtype=bool)
            keep[rng.choice(NUM_KEYPOINTS, size=k, replace=False)] = True
            keep &= (pts[:, 0] >= 0) & (pts[:, 0] < width) & (pts[:, 1] >= 0) & (pts[:, 1] < height)
            det[i] = keep
            uvs[i] = np.where(keep[:, None], pts, np.nan)
            conf[i] = np.where(keep, rng.uniform(0.1, 0.5, size=NUM_KEYPOINTS), 0.0)
        person = det.sum(axis=1) >= min_kp
        det &= person[:, None]
        uvs[~det] = np.nan
        conf[~det] = 0.0
        kept = int(person.sum())
        return KeypointDetections(
            uvs[person], det[person], conf[person], np.ones(kept, bool), np.ones(kept, bool)
        )

    def detect(
        self,
        uv: np.ndarray,
        depth: np.ndarray,
        visible: np.ndarray,
        rng: np.random.Generator,
        camera: PinholeCamera,
    ) -> KeypointDetections:
        """:meth:`apply` then :meth:`false_positives`, concatenated (real people first).

        Args:
            uv: (N, 17, 2) exact pixel coordinates of the keypoints.
            depth: (N, 17) or (N,) depths (m).
            visible: (N, 17) bool visibility.
            rng: Source of randomness.
            camera: The camera that took the image.

        Returns:
            :class:`KeypointDetections` of the N real people followed by the M false positives.
        """
        real = self.apply(uv, depth, visible, rng, image_size=camera)
        fake = self.false_positives(rng, camera)
        return KeypointDetections(*(np.concatenate([a, b]) for a, b in zip(real, fake, strict=True)))


def occlusion_visible(
    uv: np.ndarray, depth: np.ndarray, depth_image: np.ndarray, tolerance: float = 0.15
) -> np.ndarray:
    """Which keypoints a depth image does not hide.

    A keypoint is visible when it lies in the image, in front of the camera, and the depth image at its
    pixel (row ``floor(v)``, column ``floor(u)``, see the module docstring) is not closer than
    ``depth - tolerance``; the tolerance lets the person's own surface (which the depth image sees a bit
    in front of the skeleton's joints) not hide their keypoints. Non-finite depth-image values count as
    empty (nothing in the way).

    Args:
        uv: (..., 2) pixel coordinates.
        depth: (...,) keypoint depths (m, camera-frame z, like :meth:`PinholeCamera.project`).
        depth_image: (height, width) metric z-depth image (m) from the same camera.
        tolerance: Slack (m, >= 0): a scalar, or an array broadcasting against ``depth`` (e.g. one
            value per keypoint: joint centres lie inside the limbs, face keypoints on the head's surface).

    Returns:
        (...,) bool mask.
    """
    if np.any(np.asarray(tolerance, dtype=float) < 0) or not np.all(np.isfinite(tolerance)):
        raise ValueError(f"tolerance must be finite and >= 0, got {tolerance!r}")
    uv = np.asarray(uv, dtype=float)
    depth = np.asarray(depth, dtype=float)
    img = np.asarray(depth_image, dtype=float)
    if img.ndim != 2:
        raise ValueError(f"depth_image must have shape (height, width), got {img.shape}")
    height, width = img.shape
    with np.errstate(invalid="ignore"):
        inside = (
            np.isfinite(uv).all(axis=-1)
            & (depth > _EPS_DEPTH)
            & (uv[..., 0] >= 0)
            & (uv[..., 0] < width)
            & (uv[..., 1] >= 0)
            & (uv[..., 1] < height)
        )
    col = np.where(inside, np.floor(np.nan_to_num(uv[..., 0])), 0).astype(int)
    row = np.where(inside, np.floor(np.nan_to_num(uv[..., 1])), 0).astype(int)
    scene = img[row, col]
    with np.errstate(invalid="ignore"):
        occluded = scene < depth - tolerance
    return inside & ~occluded
