"""Clearance-graded planning (AStarPlanner.plan_graded) and the robots' subgoal sight lines that use it."""

from __future__ import annotations

import numpy as np
import pytest

from navzoo.envs.subgoal import RobotGuide
from navzoo.world.geometry import min_distance_to_segments
from navzoo.world.planner import AStarPlanner, path_length
from navzoo.world.scene import load_scene

R, C = 0.3, 0.3  # robot radius, wanted clearance: a 1.0 m gap is too narrow for R + C on both sides


def _gap_scene(gap_low: float = 7.0, gap_high: float = 8.0):
    obstacles = [{"type": "wall", "start": [5, 0], "end": [5, gap_low], "thickness": 0.2},
                 {"type": "wall", "start": [5, gap_high], "end": [5, 10], "thickness": 0.2}]
    return load_scene({"name": "gap", "bounds": [0, 0, 10, 10], "obstacles": obstacles}, check_reachability=False)


def _clearance(scene, path: np.ndarray) -> float:
    """Smallest distance from the dense polyline to the scene's edges."""
    pts = np.concatenate([np.linspace(a, b, 40) for a, b in zip(path[:-1], path[1:], strict=True)])
    return float(min_distance_to_segments(pts, scene.wall_segments(include_bounds=True)).min())


def _assert_free(planner: AStarPlanner, path: np.ndarray) -> None:
    for a, b in zip(path[:-1], path[1:], strict=True):
        pts = a + np.linspace(0, 1, 200)[:, None] * (b - a)
        assert planner.inflated.is_free(pts).all(), f"segment {a} -> {b} crosses inflated space"


def test_a_gap_too_narrow_for_the_clearance_is_crossed_in_its_middle():
    scene = _gap_scene()
    grid = scene.occupancy()
    bare, padded = AStarPlanner(grid, R), AStarPlanner(grid, R + C)
    start, goal = np.array([2.0, 2.0]), np.array([8.0, 2.0])
    assert padded.plan(start, goal) is None  # why the graded planner exists
    hug = bare.plan(start, goal)
    graded = bare.plan_graded(start, goal, C)
    assert graded is not None
    _assert_free(bare, graded)
    # The bare path grazes the wall end at the radius; the graded one crosses the gap near its middle.
    assert _clearance(scene, hug) < R + 0.05
    assert _clearance(scene, graded) > R + 0.12
    at_wall = graded[np.argmin(np.abs(graded[:, 0] - 5.0))]
    assert abs(at_wall[1] - 7.5) < 0.15
    assert path_length(graded) < 1.1 * path_length(hug)
    assert np.allclose(graded[0], start) and np.allclose(graded[-1], goal)


def test_in_open_space_the_graded_path_keeps_most_of_the_clearance():
    scene = load_scene({"name": "box", "bounds": [0, 0, 10, 6],
                        "obstacles": [{"type": "box", "center": [5, 3], "size": [2, 2]}]}, check_reachability=False)
    bare = AStarPlanner(scene.occupancy(), R)
    path = bare.plan_graded(np.array([1.0, 3.2]), np.array([9.0, 3.2]), C)
    assert path is not None
    hug = bare.plan(np.array([1.0, 3.2]), np.array([9.0, 3.2]))
    assert _clearance(scene, hug) < R + 0.05
    # Shortcuts may enter a tenth of the band (0.03 m), and the field is measured between cell centres.
    assert _clearance(scene, path) > R + C - 0.1


def test_graded_planning_rejects_bad_arguments():
    bare = AStarPlanner(_gap_scene().occupancy(), R)
    for bad in (0.0, -0.1, float("nan"), float("inf")):
        with pytest.raises(ValueError, match="clearance"):
            bare.plan_graded([2, 2], [8, 2], bad)
    with pytest.raises(ValueError, match="weight"):
        bare.plan_graded([2, 2], [8, 2], C, weight=-1.0)
    with pytest.raises(ValueError, match="spacing"):
        bare.plan_graded([2, 2], [8, 2], C, spacing=0.0)
    assert bare.plan_graded([2, 2], [8, 2], C) is not None
    assert AStarPlanner(_gap_scene(7.0, 7.1).occupancy(), R).plan_graded([2, 2], [8, 2], C) is None  # closed


def test_clearance_penalty_is_zero_far_from_walls_and_one_at_the_edge_of_free_space():
    bare = AStarPlanner(_gap_scene().occupancy(), R)
    pen = bare.clearance_penalty(C)
    d = bare.grid.distance_field()
    assert np.all(pen[d > R + C + 1e-6] == 0.0)
    assert np.all(pen[d < R - 1e-6] == 1.0)
    inside = (d > R) & (d < R + C)
    assert inside.any() and np.all((pen[inside] > 0) & (pen[inside] < 1))
    assert bare.penalty_along([2, 2], [2, 8], C) == 0.0
    assert bare.penalty_along([4.5, 2], [4.5, 8], C) > 0.5  # runs along the wall


def test_subgoal_sight_lines_do_not_cut_the_corner_of_the_gap():
    """A robot driving straight at its subgoal keeps the path's clearance at the gap (no corner cutting)."""
    scene = _gap_scene()
    grid = scene.occupancy()
    guide = RobotGuide(grid, np.array([R]), lookahead=4.0, clearance=C)
    pos = np.array([[2.0, 2.0]])
    guide.reset(pos, np.array([[8.0, 2.0]]))
    path_clear = _clearance(scene, guide.paths[0])
    for _ in range(200):
        sub = guide.subgoals(pos)[0]
        assert _clearance(scene, np.stack([pos[0], sub])) > path_clear - 0.05
        step = sub - pos[0]
        n = np.linalg.norm(step)
        if n < 0.05:
            break
        pos = pos + step / n * min(0.2, n)
    assert np.linalg.norm(pos[0] - [8.0, 2.0]) < 0.1  # it got there by pure pursuit of the subgoals
