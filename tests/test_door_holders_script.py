"""scripts/door_holders.py: how fast door holders go near their door, and where they stand."""

from __future__ import annotations

import gzip
import json
import sys

import pytest

from tests.script_modules import load_script


def _row(zone, speed, along=None, right=None, plan=1.0):
    return {"t": 0.0, "id": 0, "zone": zone, "speed": speed, "target_speed": speed + 0.1, "rollout_pace": speed + 0.2,
            "plan_pace": plan, "along": along, "right": right, "near_1_2": 0}


def test_summary_medians_by_zone_and_the_busiest_cells_of_the_door_frame():
    holders = load_script("door_holders")
    rows = [_row("door", 0.2, -0.45, 0.9), _row("door", 0.3, -0.55, 1.1), _row("door", 0.25, -0.5, 0.95),
            _row("door", 0.9, -1.0, 0.0), _row("open", 1.0), _row("open", 1.2, plan=None)]
    s = holders.summarize([{"goals": 3, "rows": rows}, {"goals": 2, "rows": []}])
    assert s["runs"] == 2 and s["goals"] == 5
    assert s["zones"]["door"]["samples"] == 4 and s["zones"]["door"]["speed"] == pytest.approx(0.275)
    assert s["zones"]["open"]["speed"] == pytest.approx(1.1) and s["zones"]["open"]["plan_pace"] == 1.0
    top = s["cells"][0]  # the three holders pressed against the wall beside the opening share a cell
    assert (top["along"], top["right"], top["samples"]) == (-0.5, 1.0, 3) and top["speed"] == pytest.approx(0.25)
    assert len(s["cells"]) == 2


def test_summary_reads_gzipped_files(tmp_path, capsys, monkeypatch):
    holders = load_script("door_holders")
    f = tmp_path / "run.json.gz"
    with gzip.open(f, "wt") as out:
        json.dump({"goals": 4, "rows": [_row("door", 0.2, -0.5, 1.0)]}, out)
    monkeypatch.setattr(sys, "argv", ["door_holders.py", "--summary", str(f)])
    holders.main()
    s = json.loads(capsys.readouterr().out)
    assert s["goals"] == 4 and s["cells"][0]["samples"] == 1


def test_bad_arguments_are_refused(capsys, monkeypatch):
    holders = load_script("door_holders")
    for argv in (["--centre", "8,x", "--out", "o.json"], ["--const", "NOPE=1", "--out", "o.json"], []):
        with pytest.raises(SystemExit):
            monkeypatch.setattr(sys, "argv", ["door_holders.py", *argv])
            holders.main()
    err = capsys.readouterr().err
    assert "--centre" in err and "NOPE" in err and "--out is required" in err
