"""scripts/scene_passages.py: the widest route's gap between a start and a goal, from the occupancy grid."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest

from tests.script_modules import load_script

_SCRIPTS = Path(__file__).resolve().parents[1] / "scripts"
sys.path.insert(0, str(_SCRIPTS))
sp = load_script("scene_passages")

from navzoo.world.library import get_scene  # noqa: E402
from navzoo.world.occupancy import OccupancyGrid  # noqa: E402


def _grid(name: str) -> OccupancyGrid:
    return OccupancyGrid.from_scene(get_scene(name))


@pytest.mark.parametrize(("scene", "start", "goal", "width"), [
    ("doorway", (3.0, 4.0), (12.0, 4.0), 1.0),      # one 1.0 m doorway between the rooms
    ("bottleneck", (3.0, 4.0), (11.0, 4.0), 1.2),   # the 1.2 m passage
])
def test_gap_is_the_door_width(scene, start, goal, width):
    gap = sp.widest_route_gap(_grid(scene), np.array([start]), np.array([goal]))
    assert gap.shape == (1,)
    assert abs(gap[0] - width) <= 0.1 + 1e-9   # centre-to-centre distances: within one grid cell


def test_same_room_is_wider_than_the_door_and_blocked_is_zero():
    grid = _grid("doorway")
    gaps = sp.widest_route_gap(grid, np.array([[3.0, 4.0], [3.0, 4.0]]), np.array([[4.0, 4.5], [8.0, 0.05]]))
    assert gaps[0] > 2.0            # both points in the west room, far from its walls
    assert gaps[1] == 0.0           # the goal lies in the outer wall: no route


def test_bad_points_are_refused():
    grid = _grid("doorway")
    with pytest.raises(ValueError, match="same shape"):
        sp.widest_route_gap(grid, np.zeros((2, 2)), np.zeros((1, 2)))
    with pytest.raises(ValueError, match="outside the grid"):
        sp.widest_route_gap(grid, np.array([[3.0, 4.0]]), np.array([[300.0, 4.0]]))


def test_cli_prints_a_row_per_scene(capsys):
    assert sp.main(["--scenes", "doorway,bottleneck:3", "--seeds", "0"]) == 0
    out = capsys.readouterr().out
    assert "| doorway | 13 | 13 |" in out and "| bottleneck | 3 | 3 |" in out
