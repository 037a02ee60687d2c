"""scripts/amp_timeout_trace.py: one JSON line per ended trip, with the timed-out trips described."""

from __future__ import annotations

import argparse
import json

import pytest

from tests.script_modules import load_script

trace = load_script("amp_timeout_trace")


def test_settings_are_typed_and_checked():
    assert trace._value("human_replan_blocked=all") == ("human_replan_blocked", "all")
    assert trace._value("human_door_entries=true") == ("human_door_entries", True)
    assert trace._value("amp_progress_reward=0.5") == ("amp_progress_reward", 0.5)
    with pytest.raises(argparse.ArgumentTypeError, match="NAME=VALUE"):
        trace._value("human_door_entries")


def test_timed_out_trips_of_a_kinematic_crowd_are_described(capsys):
    # seed 0 of the lobby: three social-force people time out before 35 s
    assert trace.main(["--scene", "lobby", "--people", "15", "--seconds", "36", "--bodies", "kinematic"]) == 0
    rows = [json.loads(line) for line in capsys.readouterr().out.splitlines()]
    timeouts = [r for r in rows if r["outcome"] == "timeout"]
    assert rows and {r["outcome"] for r in rows} <= {"success", "off_path", "fall", "timeout"}
    assert len(timeouts) >= 1
    for r in timeouts:
        assert r["duration_s"] >= r["limit_s"] - 0.05
        assert 0.0 <= r["body_slow"] <= 1.0 and r["path_left_m"] > 0 and r["obstacle_m"] >= 0
        assert r["wall_contact"] == r["person_contact"] == 0.0  # kinematic bodies have no contacts


def test_a_fall_record_says_which_contact_came_first():
    """fall_record: the window's means, the people within 1 m and the first contact (wall, person, both, none)."""
    from types import SimpleNamespace

    import numpy as np

    steps, hz = 40, 30.0
    pos = np.zeros((steps, 3, 2))
    pos[:, 0, 0] = np.arange(steps) / hz  # person 0 walks at 1 m/s along x
    pos[:, 1] = [0.5, 0.0]  # person 1 stands; person 0 passes it within 1 m
    pos[:, 2] = [5.0, 5.0]
    tgt = pos + [0.2, 0.0]
    wall = np.zeros((steps, 3), dtype=bool)
    person = np.zeros((steps, 3), dtype=bool)
    wall[30:, 0] = True  # a wall touched 10 steps before the end, a person 5 steps before
    person[35:, 0] = True
    env = SimpleNamespace(pos=pos[-1], grid=SimpleNamespace(distance_at=lambda p: np.full(len(p), 0.3)))
    h = np.arange(3)
    rec = trace.fall_record(env, h, 0, pos, tgt, wall, person, window=20, hz=hz)
    assert rec["first_contact"] == "wall" and rec["first_contact_s"] == round(10 / hz, 2)
    assert rec["window_body_speed"] == 1.0 and rec["window_lag_m"] == 0.2
    assert rec["window_wall_contact"] == 0.5 and rec["window_person_contact"] == 0.25
    assert rec["window_max_within_1m"] == 1 and rec["obstacle_m"] == 0.3
    person[30:, 0] = True
    assert trace.fall_record(env, h, 0, pos, tgt, wall, person, 20, hz)["first_contact"] == "both"
    wall[:35, 0] = False  # the person contact now comes first
    rec = trace.fall_record(env, h, 0, pos, tgt, wall, person, 20, hz)
    assert rec["first_contact"] == "person" and rec["first_contact_s"] == round(10 / hz, 2)
    wall[:] = person[:] = False
    none = trace.fall_record(env, h, 0, pos, tgt, wall, person, 20, hz)
    assert none["first_contact"] == "none" and none["first_contact_s"] is None


def test_a_window_that_is_not_positive_is_refused(capsys):
    with pytest.raises(SystemExit):
        trace.main(["--scene", "lobby", "--fall-window", "0"])
    assert "--fall-window must be > 0 s, got 0.0" in capsys.readouterr().err
