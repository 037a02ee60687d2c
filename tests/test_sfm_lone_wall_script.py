"""scripts/sfm_lone_wall.py: one social-force person alone, with the default and a softer wall potential."""

import sys
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "scripts"))

import sfm_lone_wall  # noqa: E402


def test_the_default_walls_hold_a_lone_person_in_the_cluttered_room_and_softer_ones_let_it_through():
    default = sfm_lone_wall.lone_goals("cluttered_room", 0, 30.0, 1.0, 0.1)
    soft = sfm_lone_wall.lone_goals("cluttered_room", 0, 30.0, 0.3, 0.1)
    assert default == 0 and soft >= 1
    assert sfm_lone_wall.lone_goals("lobby", 0, 30.0, 1.0, 0.1) >= 1  # the default walls are fine in an open scene


@pytest.mark.parametrize("bad", ["1.0", "a:b", "1.0:0", ""])
def test_bad_wall_lists_are_refused_by_name(bad):
    with pytest.raises(ValueError, match="--walls"):
        sfm_lone_wall.parse_walls(bad)


def test_a_crowd_run_reports_goals_speed_and_wall_proximity(capsys):
    row = sfm_lone_wall.run_sfm("doorway", 4, 0, 10.0, 1.0, 0.1)
    assert set(row) >= {"goals", "mean_speed", "near_wall_share"} and row["people"] == 4
    assert 0.1 < row["mean_speed"] < 2.0 and 0.0 <= row["near_wall_share"] <= 1.0
    assert sfm_lone_wall.crowd_scenes("heldout,doorway")["cluttered_room"] == 6
    assert sfm_lone_wall.main(["--crowd", "--scenes", "station", "--seeds", "0", "--seconds", "5",
                               "--walls", "1.0:0.1,0.3:0.1"]) == 0
    out = capsys.readouterr().out
    assert "| station (3) |" in out and "A_wall 0.3" in out and "| all goals |" in out


def test_walls_softer_only_near_others_are_a_setting_of_their_own(capsys):
    assert sfm_lone_wall.parse_walls("1.0:0.1,1.0:0.1:1.5:0.3") == [(1.0, 0.1), (1.0, 0.1, 1.5, 0.3)]
    for bad in ("1.0:0.1:1.5", "1.0:0.1:0:0.3", "1.0:0.1:1.5:nan"):
        with pytest.raises(ValueError, match="NEAR:A_NEAR"):
            sfm_lone_wall.parse_walls(bad)
    with pytest.raises(SystemExit):
        sfm_lone_wall.main(["--walls", "1.0:0.1:1.5:0.3", "--seeds", "0", "--seconds", "1"])  # a lone person
    assert "use it with --crowd" in capsys.readouterr().err
    plain = sfm_lone_wall.run_sfm("doorway", 6, 0, 15.0, 1.0, 0.1)
    near = sfm_lone_wall.run_sfm("doorway", 6, 0, 15.0, 1.0, 0.1, 1.5, 0.3)
    assert "wall_near_range" not in plain and (near["wall_near_range"], near["A_wall_near"]) == (1.5, 0.3)
    assert sfm_lone_wall.wall_key(near) == (1.0, 0.1, 1.5, 0.3) and sfm_lone_wall.wall_key(plain) == (1.0, 0.1)
    # the people of the doorway meet within 15 s, so the softer walls near others change their walk
    assert (near["mean_speed"], near["near_wall_share"]) != (plain["mean_speed"], plain["near_wall_share"])
    table = sfm_lone_wall.markdown({"scenes": {"doorway": 6}, "seeds": [0], "seconds": 15.0,
                                    "walls": [[1.0, 0.1], [1.0, 0.1, 1.5, 0.3]], "runs": [plain, near]})
    assert "A_wall 1, B_wall 0.1, 0.3 within 1.5 m of another" in table
    assert f"| doorway (6) | {plain['goals']} / " in table
