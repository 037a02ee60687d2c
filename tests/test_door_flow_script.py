"""scripts/door_flow.py: how a one-person door's time is spent, from a stand trace."""

from __future__ import annotations

import json

import numpy as np
import pytest

from tests.script_modules import load_script


def _trace() -> dict:
    """Person 0 walks through the doorway's door (x = 8) at 1 m/s holding it; person 1 waits beside it, standing."""
    samples = []
    for k in range(9):
        t, x = 0.5 * k, 6.0 + 0.5 * k
        samples.append({"t": t, "id": 0, "x": x, "y": 4.0, "speed": 1.0, "door_state": "held",
                        "door_m": float(np.hypot(x - 8.0, 0.0)) + 0.05})
        samples.append({"t": t, "id": 1, "x": 6.6, "y": 3.0, "speed": 0.0, "door_state": "waits",
                        "door_m": float(np.hypot(6.6 - 8.0, 1.0))})
    return {"samples": samples, "every_s": 0.5, "still_mps": 0.15, "goals": 1, "seed": 0, "crowd": "diffusion"}


def test_one_crossing_with_a_waiting_person():
    flow = load_script("door_flow")
    r = flow.flow(_trace(), np.array([8.0, 4.0]), np.array([1.0, 0.0]))
    assert r["crossings"] == 1 and r["per_min"] == pytest.approx(60.0 / 4.5, abs=0.01)
    assert r["busy"] == pytest.approx(3 / 9, abs=1e-3)  # x = 7.5, 8.0, 8.5 are in the door
    assert r["held"] == 1.0 and r["held_empty"] == pytest.approx(6 / 9, abs=1e-3)
    assert r["waits"] == 1.0 and r["waits_empty"] == pytest.approx(6 / 9, abs=1e-3)
    assert r["dwell_s"] == 1.5  # in the door at x = 7.5 (1.5 s), beyond 0.5 m on the other side at x = 9.0 (3.0 s)
    assert r["holder_standing"] == 0.0
    # the other way round, and another door's samples do not count
    other = flow.flow(_trace(), np.array([8.0, 1.0]), np.array([1.0, 0.0]))
    assert other["held"] == 0.0 and other["waits"] == 0.0 and other["busy"] == 0.0 and other["crossings"] == 0
    p = flow.pooled([r, r])
    assert p["traces"] == 2 and p["crossings"] == 2 and p["busy"] == r["busy"] and p["goals"] == 2


def test_unturned_counts_people_bound_across_the_door_without_a_door_turn():
    flow = load_script("door_flow")
    tr = _trace()
    assert flow.flow(tr, np.array([8.0, 4.0]), np.array([1.0, 0.0]))["unturned"] is None  # no goals in the trace
    for s in tr["samples"]:
        s["goal"] = [12.0, 4.0]  # both bound east, across the door
    tr["samples"].append({"t": 0.0, "id": 2, "x": 7.0, "y": 5.0, "speed": 0.0, "door_state": "none", "door_m": 1e9,
                          "goal": [10.0, 6.0]})  # no door turn, its goal across: counts
    tr["samples"].append({"t": 0.0, "id": 3, "x": 7.0, "y": 6.0, "speed": 0.0, "door_state": "none", "door_m": 1e9,
                          "goal": [3.0, 6.0]})  # its goal on its own side: not counted
    tr["samples"].append({"t": 0.0, "id": 4, "x": 2.0, "y": 4.0, "speed": 0.0, "door_state": "none", "door_m": 1e9,
                          "goal": [12.0, 4.0]})  # beyond --reach: not counted
    r = flow.flow(tr, np.array([8.0, 4.0]), np.array([1.0, 0.0]))
    # within 2.5 m and bound across: person 0 at x = 6.0 ... 7.5 (4 samples; at 8.0 it is on the line, beyond it its
    # goal is on its side), person 1 (9 samples), person 2 (1): one of 14 has no door turn
    assert r["unturned"] == pytest.approx(1 / 14, abs=1e-3)
    p = flow.pooled([r, r])
    assert p["unturned"] == r["unturned"]


def test_main_prints_rows_and_refuses_bad_input(tmp_path, capsys):
    flow = load_script("door_flow")
    f = tmp_path / "t.json"
    f.write_text(json.dumps(_trace()))
    assert flow.main([str(f), "--json"]) == 0
    lines = [json.loads(line) for line in capsys.readouterr().out.splitlines()]
    assert lines[0]["crossings"] == 1 and lines[1]["pooled"] == "diffusion"
    assert flow.main([str(f)]) == 0 and "| pooled: diffusion, 1 traces |" in capsys.readouterr().out
    with pytest.raises(SystemExit, match="--normal must not be zero"):
        flow.main([str(f), "--normal", "0,0"])
    with pytest.raises(SystemExit, match="--centre"):
        flow.main([str(f), "--centre", "8"])
    bad = tmp_path / "bad.json"
    bad.write_text(json.dumps({"samples": []}))
    with pytest.raises(SystemExit, match="not a trace"):
        flow.main([str(bad)])
