"""scripts/amp_timeout_trace.py: one JSON line per ended trip, with the timed-out trips described."""

from __future__ import annotations

import argparse
import importlib.util
import json
from pathlib import Path

import pytest

_SPEC = importlib.util.spec_from_file_location("amp_timeout_trace",
                                               Path(__file__).resolve().parents[1] / "scripts" / "amp_timeout_trace.py")
trace = importlib.util.module_from_spec(_SPEC)
_SPEC.loader.exec_module(trace)


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
