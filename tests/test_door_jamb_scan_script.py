"""scripts/door_jamb_scan.py: doors that sampled paths enter slantwise."""

from __future__ import annotations

import pytest

from tests.script_modules import load_script

js = load_script("door_jamb_scan")


def test_scene_sets_and_unknown_scenes():
    assert "doorway" in js.scenes_for("protocol") and "warehouse_aisles" in js.scenes_for("heldout")
    assert len(js.scenes_for("all")) == len(js.scenes_for("protocol")) + len(js.scenes_for("heldout"))
    assert js.scenes_for("home, doorway") == ["home", "doorway"]
    with pytest.raises(ValueError, match="no_such_scene"):
        js.scenes_for("home,no_such_scene")


def test_a_short_scan_of_the_doorway():
    r = js.scan("doorway", 12, 0.3)
    assert r["scene"] == "doorway" and r["paths"] == 12 and 0 <= r["changed"] <= 12
    assert 0 < r["with_doors"] <= r["with_doors_search"] <= 12  # the search only adds doors there
    for key in r["new_doors"]:
        x, y = (float(v) for v in key.split(","))
        assert abs(x - 8.0) < 0.3 and abs(y - 4.0) < 0.3  # the scene's one door
    assert js.scan("doorway", 12, 0.3) == r  # seeded
