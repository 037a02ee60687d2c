"""Robot sensors: camera geometry, a 2D human keypoint detector model, rendered cameras and a 2D lidar.

* :mod:`navzoo.sensors.camera_model` -- :class:`PinholeCamera` (robot-mounted pinhole camera, optical
  frame x right / y down / z forward, projection and image tests), :func:`default_robot_cameras` (two
  60 degree cameras at +-30 degrees), the COCO keypoint layout, :class:`KeypointNoise` (detector pixel
  noise, misses, truncation, confidences and false positives) and :func:`occlusion_visible` (pure numpy).
* :mod:`navzoo.sensors.render` -- :func:`render_camera` renders a :class:`PinholeCamera` in a PyBullet
  world into :class:`CameraImages` (RGB, metric z-depth, body-id and link segmentation) pixel-aligned
  with :meth:`PinholeCamera.project`; :func:`render_robot_cameras` does it for a robot of a NavEnv
  without its own body; TinyRenderer by default, EGL after :func:`enable_egl`.
* :mod:`navzoo.sensors.lidar` -- :class:`Lidar2D`, a planar lidar cast with PyBullet ray tests
  (:class:`LidarScan`: ranges, angles, hit bodies, optional seeded range noise);
  :func:`render_robot_lidar` scans from a robot of a NavEnv and sees walls, obstacles, robots and
  (kinematic or AMP) pedestrians.
"""

from __future__ import annotations

from navzoo.sensors.camera_model import (
    COCO_KEYPOINTS,
    COCO_SKELETON,
    NUM_KEYPOINTS,
    KeypointDetections,
    KeypointNoise,
    PinholeCamera,
    default_robot_cameras,
    occlusion_visible,
)
from navzoo.sensors.lidar import Lidar2D, LidarScan, render_robot_lidar
from navzoo.sensors.render import (
    CameraImages,
    egl_enabled,
    egl_works,
    enable_egl,
    forget_egl,
    render_camera,
    render_robot_cameras,
)

__all__ = [
    "COCO_KEYPOINTS",
    "COCO_SKELETON",
    "NUM_KEYPOINTS",
    "CameraImages",
    "KeypointDetections",
    "KeypointNoise",
    "Lidar2D",
    "LidarScan",
    "PinholeCamera",
    "default_robot_cameras",
    "egl_enabled",
    "egl_works",
    "enable_egl",
    "forget_egl",
    "occlusion_visible",
    "render_camera",
    "render_robot_cameras",
    "render_robot_lidar",
]
