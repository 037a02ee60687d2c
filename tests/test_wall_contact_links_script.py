"""scripts/amp_wall_contact_links.py: which body parts of the physics pedestrians touch the walls, and where."""

from __future__ import annotations

import json

import numpy as np
import pytest

from tests.script_modules import load_script

links = load_script("amp_wall_contact_links")


def _door(x0: float, x1: float):
    """Clearance of a passage between walls at x = x0 and x = x1 (a stand-in for ``Scene.clearance``)."""
    return lambda pts: np.minimum(pts[:, 0] - x0, x1 - pts[:, 0])


def test_the_width_across_the_motion_and_the_offset_from_its_middle():
    clearance = _door(-0.45, 0.45)  # a 0.9 m door; walking along +y, left is -x
    left, right = links.side_distances(clearance, np.array([0.2, 0.0]), np.array([0.0, 1.0]))
    assert left == pytest.approx(0.64, abs=0.021) and right == pytest.approx(0.24, abs=0.021)
    assert links.passage_class(left + right) == "door"
    assert links.off_centre(clearance, np.array([0.2, 0.0]), np.array([0.0, 1.0])) == pytest.approx(0.2, abs=0.021)
    # walking along the walls instead: both rays run free, capped
    assert links.side_distances(clearance, np.array([0.0, 0.0]), np.array([1.0, 0.0]))[1] == links.MAX_SIDE_M
    assert [links.passage_class(w) for w in (0.9, 1.5, 2.5)] == ["door", "passage", "open"]


def test_contact_runs_become_events_and_short_gaps_are_bridged():
    f = frozenset({"hand"})
    touching = [{0: f}, {0: f}, {}, {0: f, 1: f}, {}, {}, {}, {1: f}]
    assert links.events_from_steps(touching) == [(0, 0, 1), (0, 3, 3), (1, 3, 3), (1, 7, 7)]
    assert links.events_from_steps(touching, gap=1) == [(0, 0, 3), (1, 3, 3), (1, 7, 7)]
    assert links.events_from_steps(touching, gap=3) == [(0, 0, 3), (1, 3, 7)]
    assert links.events_from_steps([]) == []


def test_the_summary_counts_first_parts_per_passage_class():
    def ev(passage, parts, off):
        return {"passage": passage, "where": "corner" if off < 0.2 else "wall", "first_links": parts,
                "pelvis_wall_m": 0.3, "target_wall_m": 0.4, "body_off_m": off,
                "target_off_m": 0.0, "side_m": -0.3, "ahead_m": 0.0, "people_1m": 0, "duration_s": 0.5,
                "fall": False, "speed": off, "target_speed": 1.0 - off, "target_m": off, "goal_m": 2.0 * off}

    s = links.summarize([ev("door", ["hand"], 0.1), ev("door", ["foot", "hand"], 0.3), ev("open", ["foot"], 1.0)])
    assert s["events"] == 3 and "passage" not in s
    assert s["door"]["events"] == 2 and s["door"]["first_part_share"] == {"hand": 1.0, "foot": 0.5}
    assert s["door"]["median_body_off_m"] == pytest.approx(0.2)
    assert s["door"]["slow_share_target_still"] == 0.0 and s["door"]["slow_median_target_m"] == pytest.approx(0.1)
    assert s["all"]["slow_share_people_1m"] == 0.0
    assert s["all"]["slow_share_near_goal"] == 1.0  # the one slow event (0.1 m/s) is 0.2 m from its goal
    assert s["door"]["share_slow"] == pytest.approx(0.5) and s["all"]["speed_quartiles"] == pytest.approx([0.2, 0.3, 0.65])
    assert s["all"]["first_part_share"]["foot"] == pytest.approx(0.667, abs=1e-3)
    assert s["corner"]["events"] == 1 and s["wall"]["events"] == 2 and s["all"]["share_corner"] == pytest.approx(1 / 3, abs=1e-3)


def test_a_short_run_names_the_parts_that_touch(tmp_path):
    # seed 0 of the home, 12 s: the bodies brush walls and door frames within seconds
    out = tmp_path / "home.json"
    assert links.main(["--scene", "home", "--people", "5", "--seconds", "12", "--out", str(out)]) == 0
    result = json.loads(out.read_text())
    assert result["events"], "no wall contact in 12 s of the home"
    for e in result["events"]:
        assert set(e["first_links"]) <= set(e["links"]) <= set(links.PARTS) and e["first_links"]
        assert 0.0 < e["pelvis_wall_m"] < 1.0  # a body touching a wall has its pelvis near one, never inside
        assert e["passage"] == links.passage_class(e["width_m"]) and e["duration_s"] > 0
        assert e["where"] == ("corner" if e["corner_m"] is not None and e["corner_m"] < links.CORNER_M else "wall")
        assert e["target_wall_m"] > -0.05  # targets are planned outside the obstacles
        assert 0.0 <= e["speed"] < 3.0  # the body's own speed, also when it stands
        assert 0.0 <= e["target_speed"] < 2.5 and 0.0 <= e["target_m"] < 2.0 and e["goal_m"] >= 0.0
    assert links.summarize(result["events"]) == result["summary"]
    assert links.main(["--summary", str(out)]) == 0


def test_bad_arguments_are_refused_by_name(tmp_path, capsys):
    with pytest.raises(SystemExit):
        links.main(["--people", "0"])
    assert "--people" in capsys.readouterr().err
    with pytest.raises(SystemExit):
        links.main(["--set", "amp_wall_margin"])
    assert "KEY=VALUE" in capsys.readouterr().err
    bad = tmp_path / "bad.json"
    bad.write_text("{}")
    with pytest.raises(SystemExit):
        links.main(["--summary", str(bad)])
    assert "not a result file" in capsys.readouterr().err
