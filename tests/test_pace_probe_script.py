"""scripts/amp_pace_probe.py and the trip bookkeeping it shares (navzoo.benchmark.pedestrians.Trips)."""

from __future__ import annotations

import numpy as np

from navzoo.benchmark import pedestrians as P
from tests.script_modules import load_script

probe = load_script("amp_pace_probe")


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


def test_goal_trips_count_a_stuck_person_once_and_never_hide_a_fall():
    """One trip per goal: a person past its limit is one timeout however many limits pass; reaching the
    goal late is still that timeout; a fall is a fall even after the limit; at the scene's end only goal
    trips past their limit count."""
    wrapped, env = P._make("circle_crossing", 2, "kinematic", 60.0, 0, None, "sfm")
    trips = P.Trips(env, 2)
    per_limit, per_goal = [], []
    while not env._needs_reset and not per_goal:
        trips.limit[1] = trips.goal_limit[1] = 0.5  # person 1 is "stuck": every limit passes
        wrapped.step({})
        per_limit += [e[1] for e in trips.update(np.zeros(2), np.zeros(2, dtype=bool)) if e[0] == 1]
        per_goal += [o for j, o in trips.goal_ended if j == 1]
    assert per_goal == ["timeout"]  # reached its goal, late: one goal trip, a timeout
    assert per_limit.count("timeout") >= 3 and per_limit[-1] == "success"  # the per-limit rule: many trips
    assert not trips.goal_late[1] and trips.goal_start[1] == env.sim_time  # the next goal's trip has begun
    trips.goal_limit[1] = 0.0  # now late again ...
    ended = trips.update(np.zeros(2), np.array([False, True]))  # ... and falls: a fall, not a timeout
    assert [e[:2] for e in ended] == [(1, "fall")] and trips.goal_ended == [(1, "fall")]
    assert trips.finish() == []  # person 0 within its limit: under way, not counted; person 1 is done
    trips.goal_limit[0] = 0.0
    assert trips.finish() == [0]
    wrapped.close()
