"""Fallen bodies as planning obstacles: footprint, grid stamping, path test (navzoo.envs.fallen)."""

from __future__ import annotations

import numpy as np

from navzoo.envs.fallen import footprint_points, path_passes, stamp
from navzoo.world.occupancy import OccupancyGrid
from navzoo.world.planner import AStarPlanner


def test_footprint_covers_the_lines_from_root_to_limbs():
    pts = footprint_points([1.0, 1.0], [[2.0, 1.0], [1.0, 0.5]], step=0.05)
    assert np.allclose(pts[0], [1.0, 1.0])
    assert any(np.allclose(p, [2.0, 1.0]) for p in pts) and any(np.allclose(p, [1.0, 0.5]) for p in pts)
    gaps = np.linalg.norm(np.diff(pts[1:21], axis=0), axis=1)  # along the first line
    assert gaps.max() <= 0.05 + 1e-9
    assert (np.abs(pts[1:21, 1] - 1.0) < 1e-12).all()


def test_stamp_occupies_the_cells_near_the_body_only_and_keeps_the_original():
    grid = OccupancyGrid(np.zeros((40, 60), dtype=bool), 0.1, (0.0, 0.0))
    body = footprint_points([3.0, 2.0], [[3.8, 2.0]])
    out = stamp(grid, body, radius=0.15)
    assert not grid.occ.any()  # the scene's grid is untouched
    assert out.resolution == grid.resolution and out.origin == grid.origin
    occupied = out.cell_to_world(np.argwhere(out.occ))
    d = np.min(np.linalg.norm(occupied[:, None] - body[None], axis=2), axis=1)
    assert d.max() <= 0.15 + 1e-9
    assert out.is_free(np.array([3.4, 2.4])) and not out.is_free(np.array([3.4, 2.0]))


def test_path_passes_and_a_planner_goes_around_a_stamped_body():
    grid = OccupancyGrid(np.zeros((40, 60), dtype=bool), 0.1, (0.0, 0.0))
    body = footprint_points([3.0, 2.0], [[3.0, 2.4], [3.0, 1.6]])  # across the straight line y = 2
    straight = AStarPlanner(grid, 0.3).plan([0.5, 2.0], [5.5, 2.0])
    assert path_passes(straight, [0.5, 2.0], body, 0.45)
    around = AStarPlanner(stamp(grid, body), 0.3).plan([0.5, 2.0], [5.5, 2.0])
    assert around is not None and not path_passes(around, [0.5, 2.0], body, 0.4)  # radius + body - a cell
    assert not path_passes(np.zeros((0, 2)), [0.5, 0.5], body, 0.45)  # far away, no path left
    assert not path_passes(straight, [0.5, 2.0], np.zeros((0, 2)), 0.45)
