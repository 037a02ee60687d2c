"""scripts/amp_replan_trace.py: each person's plan and target rollout at the replans of one run."""

from __future__ import annotations

import json

import pytest

from tests.script_modules import load_script

rt = load_script("amp_replan_trace")


def test_rows_cover_every_person_at_each_replan_in_the_window(tmp_path):
    out = tmp_path / "replan.json"
    assert rt.main(["--scene", "circle_crossing", "--people", "2", "--seed", "0", "--from", "1.5",
                    "--until", "4.5", "--const", "STALL_WARP_S=1.0", "--json", str(out)]) == 0
    d = json.loads(out.read_text())
    assert d["const"] == {"STALL_WARP_S": 1.0}
    times = sorted({r["t"] for r in d["rows"]})
    assert times and all(1.5 <= t <= 4.5 for t in times)  # only the replans inside the window
    assert len(d["rows"]) == 2 * len(times)  # one row per person and replan
    for r in d["rows"]:
        assert r["plan_speed"] >= 0 and 0 <= r["rollout_reach_2s_m"] < 5.0 and r["still_s"] >= 0
        assert len(r["pos"]) == len(r["goal"]) == len(r["plan_dir"]) == 2


def test_bad_windows_and_crowds_are_named():
    with pytest.raises(ValueError, match="--from"):
        rt.trace("circle_crossing", 2, 0, 5.0, 1.0)
    with pytest.raises(ValueError, match="no diffusion plans"):
        rt.trace("circle_crossing", 2, 0, 0.0, 1.0, crowd="sfm")
    with pytest.raises(SystemExit):
        rt.main(["--const", "NOT_A_CONSTANT=1"])
