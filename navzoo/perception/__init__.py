"""Perception of people for the robot: multi-person tracking of detections and its metrics.

* :mod:`navzoo.perception.tracker` -- :class:`PersonTracker` (constant-velocity Kalman filters,
  Mahalanobis-gated Hungarian association, track birth, confirmation and deletion), the sensor-frame
  helpers :func:`radial_covariance` and :func:`to_world`, and the CLEAR-MOT metrics :func:`clear_mot`.
"""

from __future__ import annotations

from navzoo.perception.tracker import (
    GATE_CHI2_99,
    ClearMotResult,
    PersonTracker,
    Track,
    clear_mot,
    radial_covariance,
    to_world,
)

__all__ = [
    "GATE_CHI2_99",
    "ClearMotResult",
    "PersonTracker",
    "Track",
    "clear_mot",
    "radial_covariance",
    "to_world",
]
