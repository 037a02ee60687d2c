from __future__ import annotations

import math

import numpy as np
import pytest

from navzoo.world.occupancy import OccupancyGrid
from navzoo.world.planner import AStarPlanner, path_length
from navzoo.world.scene import load_scene


def _octile(a, b):
    dx, dy = abs(b[0] - a[0]), abs(b[1] - a[1])
    return max(dx, dy) + (math.sqrt(2) - 1) * min(dx, dy)


def _assert_collision_free(planner: AStarPlanner, path: np.ndarray) -> None:
    """Independent check: dense samples along every segment are free in the inflated grid."""
    res = planner.inflated.resolution
    for a, b in zip(path[:-1], path[1:], strict=True):
        n = max(2, int(np.ceil(np.linalg.norm(b - a) / (res / 8))) + 1)
        pts = a + np.linspace(0, 1, n)[:, None] * (b - a)
        assert planner.inflated.is_free(pts).all(), f"segment {a} -> {b} crosses inflated space"


def _wall_gap_scene(gap: bool = True):
    obstacles = [{"type": "wall", "start": [5, 0], "end": [5, 7], "thickness": 0.2}]
    obstacles.append({"type": "wall", "start": [5, 8 if gap else 6.9], "end": [5, 10], "thickness": 0.2})
    return load_scene({"name": "gap", "bounds": [0, 0, 10, 10], "obstacles": obstacles}, check_reachability=False)


def test_open_grid_raw_path_is_octile_optimal():
    grid = OccupancyGrid(np.zeros((50, 60), dtype=bool), 0.1, (0.0, 0.0))
    planner = AStarPlanner(grid, 0.0)
    for (r0, c0), (r1, c1) in [((5, 5), (20, 40)), ((45, 2), (3, 55)), ((10, 10), (10, 50)), ((0, 0), (49, 59))]:
        start = grid.cell_to_world([r0, c0])
        goal = grid.cell_to_world([r1, c1])
        raw = planner.plan_raw(start, goal)
        assert path_length(raw) == pytest.approx(0.1 * _octile((r0, c0), (r1, c1)))
        # on an open grid, smoothing recovers the straight line
        assert planner.shortest_path_length(start, goal) == pytest.approx(np.linalg.norm(goal - start))


def test_wall_with_one_gap_length():
    scene = _wall_gap_scene()
    planner = AStarPlanner(scene.occupancy(), 0.3)
    start, goal = np.array([2.0, 2.0]), np.array([8.0, 2.0])
    path = planner.plan(start, goal, spacing=0.5)
    assert path is not None
    # around the top of the lower wall (corners at (4.9, 7) and (5.1, 7)) with ~0.3 m clearance
    expected = 2 * np.hypot(2.9, 5.3) + 0.2
    assert path_length(path) == pytest.approx(expected, abs=0.25)
    assert path[:, 1].max() > 6.9  # really goes through the gap
    _assert_collision_free(planner, path)


def test_unreachable_returns_none():
    scene = _wall_gap_scene(gap=False)
    planner = AStarPlanner(scene.occupancy(), 0.3)
    assert planner.plan((2, 2), (8, 2)) is None
    assert planner.shortest_path_length((2, 2), (8, 2)) == math.inf
    assert path_length(None) == math.inf
    # reachable on the same side
    assert planner.plan((2, 2), (2, 8)) is not None


def test_snapping():
    scene = _wall_gap_scene()
    planner = AStarPlanner(scene.occupancy(), 0.3)
    # 0.15 m from the wall face: inside inflated space, snapped to a free cell
    path = planner.plan((4.75, 3.0), (2.0, 3.0))
    assert path is not None and planner.inflated.is_free(path[0:1]).all()
    assert np.linalg.norm(path[0] - [4.75, 3.0]) <= 0.5
    np.testing.assert_allclose(path[-1], [2.0, 3.0])
    # outside the bounds by more than the snap radius: no path
    assert planner.plan((-1.0, 3.0), (2.0, 3.0)) is None


def test_paths_avoid_inflated_obstacles_and_smoothing_never_lengthens():
    scene = load_scene("navzoo/world/scenes/home.yaml")
    planner = AStarPlanner(scene.occupancy(), 0.3)
    rng = np.random.default_rng(3)
    free = np.argwhere(~planner.inflated.occ)
    done = 0
    for _ in range(12):
        a, b = planner.inflated.cell_to_world(free[rng.integers(0, len(free), 2)])
        raw = planner.plan_raw(a, b)
        if raw is None:
            continue
        path = planner.plan(a, b, spacing=0.4)
        _assert_collision_free(planner, path)
        assert path_length(path) <= path_length(raw) + 1e-9
        steps = np.linalg.norm(np.diff(path, axis=0), axis=1)
        assert steps.max() <= 0.4 + 1e-9 and steps.min() > 0
        np.testing.assert_array_equal(path[0], a)
        np.testing.assert_array_equal(path[-1], b)
        done += 1
    assert done >= 8


def test_resampling_spacing_straight_line():
    grid = OccupancyGrid(np.zeros((40, 40), dtype=bool), 0.1, (0.0, 0.0))
    planner = AStarPlanner(grid, 0.0)
    path = planner.plan((0.5, 0.5), (3.5, 0.5), spacing=0.5)
    np.testing.assert_allclose(path[:, 0], np.arange(0.5, 3.51, 0.5))
    path = planner.plan((0.5, 0.5), (3.2, 0.5), spacing=1.0)  # 2.7 m -> 3 pieces of 0.9 m
    np.testing.assert_allclose(np.diff(path[:, 0]), [0.9, 0.9, 0.9])
    same = planner.plan((0.52, 0.51), (0.55, 0.53))
    assert same.shape[0] == 2


def test_distance_field_matches_astar():
    scene = _wall_gap_scene()
    grid = scene.occupancy()
    planner = AStarPlanner(grid, 0.3)
    goal_rc = np.array([20, 80])
    field = planner.distance_to(grid.cell_to_world(goal_rc))
    assert field.shape == grid.occ.shape and np.isinf(field[planner.inflated.occ]).all()
    for rc in ([20, 20], [90, 10], [60, 45]):
        raw = planner.plan_raw(grid.cell_to_world(rc), grid.cell_to_world(goal_rc))
        assert field[tuple(rc)] == pytest.approx(path_length(raw))
    assert planner.distance_to(grid.cell_to_world(goal_rc)) is field  # cached


def test_plans_through_a_200x200_zigzag_maze():
    # worst case for A*: a zig-zag maze that forces exploring almost every cell (its speed is measured by
    # scripts/bench_world.py, docs/scenes.md, not bounded here)
    occ = np.zeros((200, 200), dtype=bool)
    for k, x in enumerate(range(20, 200, 30)):
        if k % 2 == 0:
            occ[0:180, x : x + 3] = True
        else:
            occ[20:200, x : x + 3] = True
    planner = AStarPlanner(OccupancyGrid(occ, 0.1, (0.0, 0.0)), 0.2)
    path = planner.plan((0.5, 0.5), (19.5, 19.5))
    assert path is not None
    _assert_collision_free(planner, path)
    # six walls of 18 m, passed alternately at the top and the bottom: the path snakes through every gap
    assert path_length(path) > 6 * 15
    open_planner = AStarPlanner(OccupancyGrid(np.zeros((200, 200), dtype=bool), 0.1, (0.0, 0.0)), 0.2)
    straight = open_planner.plan((0.5, 0.5), (19.5, 19.5))
    assert straight is not None and path_length(straight) == pytest.approx(19 * math.sqrt(2), abs=0.2)
