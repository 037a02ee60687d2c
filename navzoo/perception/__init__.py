"""Perception of people for the robot: keypoints -> Monoloco estimates -> Kalman tracks, and a wrapper.

* :mod:`navzoo.perception.body_keypoints` -- the 17 COCO keypoints and the body orientation of the
  humanoid pedestrians, from their PyBullet link frames.
* :mod:`navzoo.perception.monoloco` -- :class:`MonolocoNet` (2D keypoints -> distance with a Laplace
  spread, direction, body orientation), :func:`load_estimator` for the shipped ``policies/monoloco``.
* :mod:`navzoo.perception.tracker` -- :class:`PersonTracker` (constant-velocity Kalman filters,
  Mahalanobis-gated Hungarian association, track birth, confirmation and deletion), the sensor-frame
  helpers :func:`radial_covariance` and :func:`to_world`, and the CLEAR-MOT metrics :func:`clear_mot`.
* :mod:`navzoo.perception.pipeline` -- :class:`RobotPerception`: cameras, occlusion, detector noise,
  network and tracker for every robot of an env.
* :mod:`navzoo.perception.wrapper` -- :class:`PerceptionWrapper`: robots observe tracked instead of
  true people, in the ground-truth observation format.
* :mod:`navzoo.perception.dataset`, :mod:`navzoo.perception.train` (``navzoo train perception``),
  :mod:`navzoo.perception.evaluate` (``navzoo eval perception``), :mod:`navzoo.perception.navigation`,
  :mod:`navzoo.perception.video`.

The heavy parts (torch, PyBullet rendering) are imported on first use of the classes below.
"""

from __future__ import annotations

from typing import Any

from navzoo.perception.tracker import (
    GATE_CHI2_99,
    ClearMotResult,
    PersonTracker,
    Track,
    clear_mot,
    radial_covariance,
    to_world,
)

_LAZY = {
    "MonolocoNet": "navzoo.perception.monoloco",
    "MonolocoEstimator": "navzoo.perception.monoloco",
    "load_estimator": "navzoo.perception.monoloco",
    "RobotPerception": "navzoo.perception.pipeline",
    "PerceptionWrapper": "navzoo.perception.wrapper",
    "humanoid_keypoints": "navzoo.perception.body_keypoints",
}


def __getattr__(name: str) -> Any:
    if name in _LAZY:
        import importlib

        return getattr(importlib.import_module(_LAZY[name]), name)
    raise AttributeError(f"module 'navzoo.perception' has no attribute {name!r}")


__all__ = [
    "GATE_CHI2_99",
    "ClearMotResult",
    "MonolocoEstimator",
    "MonolocoNet",
    "PerceptionWrapper",
    "PersonTracker",
    "RobotPerception",
    "Track",
    "clear_mot",
    "humanoid_keypoints",
    "load_estimator",
    "radial_covariance",
    "to_world",
]
