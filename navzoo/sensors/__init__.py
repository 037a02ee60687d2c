"""Robot sensors: camera geometry and a 2D human keypoint detector model (pure numpy).

* :mod:`navzoo.sensors.camera_model` -- :class:`PinholeCamera` (robot-mounted pinhole camera, optical
  frame x right / y down / z forward, projection and image tests), :func:`default_robot_cameras` (two
  60 degree cameras at +-30 degrees), the COCO keypoint layout, :class:`KeypointNoise` (detector pixel
  noise, misses, truncation, confidences and false positives) and :func:`occlusion_visible`.
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

__all__ = [
    "COCO_KEYPOINTS",
    "COCO_SKELETON",
    "NUM_KEYPOINTS",
    "KeypointDetections",
    "KeypointNoise",
    "PinholeCamera",
    "default_robot_cameras",
    "occlusion_visible",
]
