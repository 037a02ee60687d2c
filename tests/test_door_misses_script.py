"""scripts/door_misses.py: paths that cross a door the door turns did not find on them."""

from __future__ import annotations

import numpy as np
import pytest

from tests.script_modules import load_script


def test_crossings_and_misses():
    dm = load_script("door_misses")
    centres = np.array([[8.0, 4.0], [3.0, 3.0]])
    line = np.array([[5.0, 4.1], [8.0, 4.1], [11.0, 4.1]])  # through the first door, far from the second
    assert dm.crossings(line, centres) == [0]
    assert dm.crossings(np.array([[7.8, 4.0], [11.0, 4.0]]), centres) == []  # starts in the door: left out
    assert dm.crossings(np.array([[5.0, 5.0], [11.0, 5.0]]), centres) == []  # passes 1 m away
    recs = [
        {"t": 0.0, "person": 0, "line": line, "found": [np.array([8.05, 4.0])], "jamb": [], "scan": []},  # found
        {"t": 1.0, "person": 1, "line": line, "found": [], "jamb": [], "scan": [np.array([7.95, 3.95])]},  # missed
        {"t": 2.0, "person": 2, "line": np.array([[5.0, 7.0], [11.0, 7.0]]), "found": [], "jamb": [], "scan": []},
    ]
    r = dm.misses(recs, centres)
    assert (r["paths"], r["crossings"], r["missed"], r["jamb_search_finds"], r["run_scan_finds"]) == (3, 2, 1, 0, 1)
    assert r["missed_paths"][0]["person"] == 1 and r["missed_paths"][0]["run_scan_finds"]


def test_a_short_run_records_every_path(capsys):
    dm = load_script("door_misses")
    r = dm.run("doorway", 3, "sfm", 2.0, 0)
    assert r["paths"] >= 3 and len(r["doors"]) >= 1  # every person's first path; the door registered
    assert r["missed"] <= r["crossings"] <= r["paths"] * len(r["doors"])
    with pytest.raises(SystemExit):
        dm.main(["--people", "0"])
