"""scripts/narrow_door_paths.py: which scenes' A* paths pass a narrow door."""

from __future__ import annotations

from tests.script_modules import load_script

ndp = load_script("narrow_door_paths")


def test_every_home_path_passes_a_narrow_door_and_no_crossing_path_does():
    home = ndp.count("home", 5, seeds=1)
    assert home["paths"] == home["paths_with_narrow_points"] == 5
    assert home["min_clearance_m"] < 0.5 and 0.0 < home["share_within_1.5m"] < 1.0
    open_scene = ndp.count("square_crossing", 4, seeds=1)
    assert open_scene["paths_with_narrow_points"] == 0 and open_scene["share_within_1.5m"] == 0.0
