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
