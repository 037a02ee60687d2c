"""scripts/amp_pace_probe.py and the trip bookkeeping it shares (navzoo.benchmark.pedestrians.Trips)."""

from __future__ import annotations

import importlib.util
from pathlib import Path

import numpy as np

from navzoo.benchmark import pedestrians as P

_SPEC = importlib.util.spec_from_file_location("amp_pace_probe",
                                               Path(__file__).resolve().parents[1] / "scripts" / "amp_pace_probe.py")
probe = importlib.util.module_from_spec(_SPEC)
_SPEC.loader.exec_module(probe)


def test_a_lone_physics_pedestrian_keeps_a_slow_targets_pace():
    row = probe.probe("circle_crossing", 1, 0.5, 20.0, 0)
    assert abs(row["target_speed"] - 0.5) < 0.05  # the rollout walks at the preferred speed ...
    assert 0.8 < row["ratio"] < 1.2 and row["lag_m"] < 0.3  # ... and the body with it
    assert row["success"] >= 1 and row["fall"] == 0


def test_trips_end_at_goals_in_timeouts_and_in_falls():
    wrapped, env = P._make("circle_crossing", 2, "kinematic", 30.0, 0, None, "sfm")
    trips = P.Trips(env, 2)
    trips.limit[1] = 1.0  # person 1's first trip times out after 1 s
    seen = []
    while not env._needs_reset and len({o for _, o, _, _ in seen}) < 2:
        wrapped.step({})
        seen += trips.update(np.zeros(2), np.zeros(2, dtype=bool))
    wrapped.close()
    timeouts = [s for s in seen if s[1] == "timeout"]
    assert timeouts[0][0] == 1 and timeouts[0][2] > 1.0 and timeouts[0][3] == 1.0
    assert any(o == "success" for _, o, _, _ in seen)  # no path error: reaching the goal is a success
    # a large path error makes the goal an off-path trip; a fall ends the person's trips for good
    wrapped, env = P._make("circle_crossing", 2, "kinematic", 30.0, 0, None, "sfm")
    trips = P.Trips(env, 2)
    ended = trips.update(np.array([0.0, 0.0]), np.array([True, False]))
    assert [e[:2] for e in ended] == [(0, "fall")]
    assert trips.done[0] and trips.update(np.zeros(2), np.array([True, False])) == []
    off = []
    while not env._needs_reset and not off:
        wrapped.step({})
        off = [s for s in trips.update(np.array([0.0, 0.6]), np.array([True, False])) if s[1] != "timeout"]
    wrapped.close()
    assert off and off[0][:2] == (1, "off_path")
