from __future__ import annotations

import numpy as np
import pytest
from scipy import ndimage

from navzoo.world.occupancy import OccupancyGrid
from navzoo.world.scene import load_scene


def _scene(obstacles, bounds=(0, 0, 10, 10)):
    return load_scene({"name": "grid_test", "bounds": list(bounds), "obstacles": obstacles}, check_reachability=False)


def test_box_cell_counts():
    grid = OccupancyGrid.from_scene(_scene([{"type": "box", "center": [5, 5], "size": [1, 1]}]), 0.1)
    assert grid.occ.shape == (100, 100)
    assert grid.occ.sum() == 100
    rows, cols = np.nonzero(grid.occ)
    assert (rows.min(), rows.max(), cols.min(), cols.max()) == (45, 54, 45, 54)
    grid = OccupancyGrid.from_scene(_scene([{"type": "box", "center": [3, 6], "size": [2, 1], "yaw": np.pi / 2}]))
    rows, cols = np.nonzero(grid.occ)
    assert grid.occ.sum() == 200 and cols.max() - cols.min() == 9 and rows.max() - rows.min() == 19


def test_grid_is_cached_and_read_only():
    scene = _scene([{"type": "circle", "center": [5, 5], "radius": 1.0}])
    grid = OccupancyGrid.from_scene(scene)
    assert OccupancyGrid.from_scene(scene) is grid and scene.occupancy() is grid
    with pytest.raises(ValueError):
        grid.occ[0, 0] = True
    # circle area ~ pi r^2 (circumscribed 24-gon: +1.1 %)
    assert grid.occ.sum() * 0.01 == pytest.approx(np.pi * 1.0 * 1.011, rel=0.03)


def test_non_multiple_bounds():
    grid = OccupancyGrid.from_scene(_scene([], bounds=(0, 0, 1.03, 2.0)))
    assert grid.occ.shape == (20, 11)
    assert grid.occ[:, 10].all() and not grid.occ[:, :10].any()  # last column centre (1.05) is outside


@pytest.mark.parametrize("thickness", [0.01, 0.04, 0.09])
def test_thin_walls_are_occupied_and_block(thickness):
    walls = [
        {"type": "wall", "start": [0, 3.02], "end": [10, 3.02], "thickness": thickness},
        {"type": "wall", "start": [0, 4.0], "end": [10, 10.0], "thickness": thickness},  # diagonal
    ]
    grid = OccupancyGrid.from_scene(_scene(walls))
    _, n = ndimage.label(~grid.occ)
    assert n == 3
    # every column has an occupied cell on the horizontal wall's row band
    assert grid.occ[29:32, :].any(axis=0).all()
    # the thin wall stays thin (outline drawing adds at most a cell on each side)
    assert grid.occ[:, 50].sum() <= 2 * 3


@pytest.mark.parametrize("angle_deg", [0, 10, 30, 45, 60, 80])
def test_walls_just_above_the_outline_threshold_still_block(angle_deg):
    # 0.125 m walls are rasterised by cell centres only; they must still split the free space
    a = np.radians(angle_deg)
    d = 20 * np.array([np.cos(a), np.sin(a)])
    wall = {"type": "wall", "start": list(np.array([5.03, 5.01]) - d), "end": list(np.array([5.03, 5.01]) + d),
            "thickness": 0.125}
    grid = OccupancyGrid.from_scene(_scene([wall]))
    _, n = ndimage.label(~grid.occ)
    assert n == 2


def test_inflation_and_distance_field_single_cell():
    occ = np.zeros((41, 41), dtype=bool)
    occ[20, 20] = True
    grid = OccupancyGrid(occ, 0.1, (0.0, 0.0))
    rr, cc = np.mgrid[0:41, 0:41]
    # nearest occupied centre: the cell, or the (occupied) outside ring just beyond the grid
    border = np.minimum.reduce([rr + 1, cc + 1, 41 - rr, 41 - cc])
    exact = 0.1 * np.minimum(np.hypot(rr - 20, cc - 20), border)
    np.testing.assert_allclose(grid.distance_field(), exact, atol=1e-6)
    assert grid.distance_field().dtype == np.float32
    for radius in (0.1, 0.25, 0.5, 1.0):
        inflated = grid.inflate(radius)
        assert inflated.occ.sum() == int((exact <= radius + 1e-9).sum())
    assert grid.inflate(0.0) is grid
    assert grid.inflate(0.5) is grid.inflate(0.5)  # cached


def test_distance_field_counts_outside_as_occupied():
    grid = OccupancyGrid(np.zeros((10, 20), dtype=bool), 0.5, (0.0, 0.0))
    rr, cc = np.mgrid[0:10, 0:20]
    expected = 0.5 * np.minimum.reduce([rr + 1, cc + 1, 10 - rr, 20 - cc])
    np.testing.assert_allclose(grid.distance_field(), expected)


def test_distance_field_against_analytic_box():
    scene = _scene([{"type": "box", "center": [5, 5], "size": [2, 2]}], bounds=(0, 0, 10, 10))
    grid = OccupancyGrid.from_scene(scene, 0.05)
    pts = np.array([[5, 7.5], [8.0, 5.3], [7.0, 7.0], [4.2, 3.1]])
    truth = np.array([1.5, 2.0, np.hypot(1, 1), 0.9])
    # centre-to-centre distances over-estimate the distance to the boundary by at most one cell
    got = grid.distance_at(pts)
    assert np.all(got >= truth - 1e-6) and np.all(got <= truth + 0.05 + 1e-6)


def test_coordinates_and_queries():
    grid = OccupancyGrid(np.zeros((30, 50), dtype=bool), 0.2, (-5.0, -3.0))
    xy = np.array([[-5.0, -3.0], [-4.81, -2.79], [4.99, 2.99]])
    np.testing.assert_array_equal(grid.world_to_cell(xy), [[0, 0], [1, 0], [29, 49]])
    np.testing.assert_allclose(grid.cell_to_world([[0, 0], [29, 49]]), [[-4.9, -2.9], [4.9, 2.9]])
    rc = np.array([[3, 7], [12, 40]])
    np.testing.assert_array_equal(grid.world_to_cell(grid.cell_to_world(rc)), rc)
    assert grid.world_to_cell([1.0, 1.0]).shape == (2,)
    np.testing.assert_array_equal(grid.is_free([[0, 0], [5.1, 0], [0, -3.1]]), [True, False, False])


def test_distance_at_bilinear():
    occ = np.zeros((11, 11), dtype=bool)
    occ[5, 5] = True
    grid = OccupancyGrid(occ, 1.0, (0.0, 0.0))
    field = grid.distance_field()
    # at cell centres: the field value; between two centres: the mean; outside: 0
    assert grid.distance_at([[7.5, 5.5]])[0] == pytest.approx(field[5, 7])
    assert grid.distance_at([[8.0, 5.5]])[0] == pytest.approx(0.5 * (field[5, 7] + field[5, 8]))
    assert grid.distance_at([[-0.1, 5.0]])[0] == 0.0
    assert grid.distance_at([[0.2, 0.2]])[0] == pytest.approx(field[0, 0])  # clamped near the edge


def test_crop_alignment_and_heading():
    scene = _scene([{"type": "box", "center": [5, 6.5], "size": [0.6, 0.6]}])
    grid = OccupancyGrid.from_scene(scene)
    # yaw 0 with cell-aligned patch: identical to the sub-array
    patch = grid.crop((5.0, 6.0), 0.0, 2.0, 20)
    np.testing.assert_array_equal(patch, grid.occ[50:70, 40:60].astype(np.float32))
    # facing +y, the box 1.5 m ahead appears on the +x (column) side, centred in rows
    patch = grid.crop((5.0, 5.0), np.pi / 2, 4.0, 32)
    assert patch.dtype == np.float32 and patch.shape == (32, 32)
    rows, cols = np.nonzero(patch)
    assert cols.min() > 16 and abs(rows.mean() - 15.5) < 1.0
    # facing -x the box is on the agent's right: -y, i.e. low row indices
    patch = grid.crop((5.0, 6.5 + 0.0), np.pi, 4.0, 32)
    assert patch[14:18, 14:18].all()  # the agent is inside the box here
    patch = grid.crop((6.5, 6.5), np.pi, 4.0, 32)
    rows, cols = np.nonzero(patch)
    assert cols.min() > 16
    # outside the bounds counts as occupied
    patch = grid.crop((0.5, 5.0), 0.0, 4.0, 32)
    assert patch[:, :8].all() and not patch[:, 20:].any()
