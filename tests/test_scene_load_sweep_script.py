"""scripts/scene_load_sweep.py: one scene's following results over crowd sizes, written as they end, resumable."""

from __future__ import annotations

import json

import pytest

from tests.script_modules import load_script

sweep = load_script("scene_load_sweep")


def test_bad_options_are_named():
    with pytest.raises(SystemExit, match="crowd sizes"):
        sweep.main(["--people", "5,x"])
    with pytest.raises(SystemExit, match="positive"):
        sweep.main(["--people", "0,3"])
    with pytest.raises(SystemExit, match="distinct"):
        sweep.main(["--people", "3", "--seeds", "0,0"])
    with pytest.raises(SystemExit, match="--seconds"):
        sweep.main(["--people", "3", "--seconds", "0"])


def test_a_kinematic_sweep_writes_each_size_and_resumes(tmp_path, capsys):
    out = tmp_path / "sweep.jsonl"
    args = ["--scene", "station", "--people", "2,4", "--crowd", "sfm", "--bodies", "kinematic", "--seconds", "30",
            "--out", str(out)]
    assert sweep.main(args) == 0
    rows = [json.loads(x) for x in out.read_text().splitlines()]
    assert sorted(r["people"] for r in rows) == [2, 4]
    for r in rows:  # every ended trip is counted once, per limit and per goal
        assert r["success"] + r["off_path"] + r["fall"] + r["timeout"] >= 1
        assert r["fall"] == 0 and sum(r["by_goal"][k] for k in ("success", "off_path", "fall", "timeout")) >= 1
    table = capsys.readouterr().out
    assert "| station, sfm, kinematic | 2 |" in table and "| station, sfm, kinematic | 4 |" in table
    assert sweep.main(args) == 0  # nothing left to run: the file is not extended
    assert len(out.read_text().splitlines()) == 2
    assert sweep.main(["--summary", str(out)]) == 0
    assert "goals per person-minute" in capsys.readouterr().out
