from __future__ import annotations

import numpy as np
import pytest

from navzoo.world.library import get_scene
from navzoo.world.planner import AStarPlanner
from navzoo.world.scene import SceneError, load_scene
from navzoo.world.tasks import TaskSampler
from tests.world.util import base_scene


def _pairwise_min(a: np.ndarray, b: np.ndarray | None = None) -> float:
    b = a if b is None else b
    d = np.linalg.norm(a[:, None] - b[None], axis=2)
    if b is a:
        d[np.diag_indices(len(a))] = np.inf
    return float(d.min()) if d.size else np.inf


@pytest.fixture(scope="module")
def rooms():
    return load_scene(base_scene())


def test_deterministic_for_a_seed(rooms):
    s1 = TaskSampler(rooms, rooms.occupancy(), 0.3).sample(np.random.default_rng(7), 5, "human")
    s2 = TaskSampler(rooms, rooms.occupancy(), 0.3).sample(np.random.default_rng(7), 5, "human")
    s3 = TaskSampler(rooms, rooms.occupancy(), 0.3).sample(np.random.default_rng(8), 5, "human")
    np.testing.assert_array_equal(s1[0], s2[0])
    np.testing.assert_array_equal(s1[1], s2[1])
    assert not np.array_equal(s1[0], s3[0])


def test_regions_tasks_are_valid(rooms):
    radius = 0.3
    sampler = TaskSampler(rooms, rooms.occupancy(), radius)
    planner = AStarPlanner(rooms.occupancy(), radius)
    rng = np.random.default_rng(0)
    robots = sampler.sample(rng, 2, "robot", min_goal_dist=3.0)
    starts, goals = sampler.sample(rng, 6, "human", existing_positions=robots[0], existing_radii=[0.5, 0.5])
    for s, g in (robots, (starts, goals)):
        assert s.shape == g.shape and s.dtype == np.float64
        assert sampler.valid_positions(np.r_[s, g]).all()
        assert (rooms.clearance(np.r_[s, g]) >= radius).all()
        for a, b in zip(s, g, strict=True):
            assert planner.plan(a, b) is not None  # reachable
    assert (np.linalg.norm(robots[1] - robots[0], axis=1) >= 3.0).all()
    assert (np.linalg.norm(goals - starts, axis=1) >= 2.0).all()
    # robots: spawn in 'west', goal in 'east'
    assert rooms.regions["west"].contains(robots[0]).all() and rooms.regions["east"].contains(robots[1]).all()
    # separation: new starts 2r + 0.1 apart, and r + 0.5 + 0.1 from the existing robots
    assert _pairwise_min(starts) >= 2 * radius + 0.1
    assert _pairwise_min(starts, robots[0]) >= radius + 0.5 + 0.1


def test_goal_region_other_than_the_start_region():
    corridor = get_scene("corridor")
    sampler = TaskSampler(corridor, corridor.occupancy(), 0.3)
    starts, goals = sampler.sample(np.random.default_rng(1), 10, "human")
    west, east = corridor.regions["west_end"], corridor.regions["east_end"]
    assert np.array_equal(west.contains(starts), east.contains(goals))
    assert np.array_equal(east.contains(starts), west.contains(goals))
    assert west.contains(starts).any() and east.contains(starts).any()


def test_goal_separation_and_min_separation(rooms):
    sampler = TaskSampler(rooms, rooms.occupancy(), 0.25)
    starts, goals = sampler.sample(np.random.default_rng(2), 6, "human", min_separation=1.2, goal_separation=1.0)
    assert _pairwise_min(starts) >= 1.2 and _pairwise_min(goals) >= 1.0


def test_sample_goal(rooms):
    sampler = TaskSampler(rooms, rooms.occupancy(), 0.3)
    rng = np.random.default_rng(4)
    start = np.array([2.0, 1.0])
    goals = np.array([sampler.sample_goal(rng, start, "human", 3.0) for _ in range(10)])
    assert sampler.valid_positions(goals).all()
    assert (np.linalg.norm(goals - start, axis=1) >= 3.0).all()
    assert rooms.regions["east"].contains(goals).all()  # the start is in 'west'


def test_impossible_requests_raise(rooms):
    sampler = TaskSampler(rooms, rooms.occupancy(), 0.3, max_tries=200)
    with pytest.raises(SceneError, match="scene 'test_rooms': could not sample"):
        sampler.sample(np.random.default_rng(0), 3, "human", min_goal_dist=50.0)
    with pytest.raises(SceneError, match="too crowded"):
        sampler.sample(np.random.default_rng(0), 200, "robot")
    with pytest.raises(ValueError, match="kind"):
        sampler.sample(np.random.default_rng(0), 1, "dog")


def test_circle_crossing():
    scene = get_scene("circle_crossing")
    sampler = TaskSampler(scene, scene.occupancy(), 0.3)
    rng = np.random.default_rng(5)
    r_start, r_goal = sampler.sample(rng, 1, "robot")
    np.testing.assert_array_equal(r_start, [[0.0, -4.0]])
    np.testing.assert_array_equal(r_goal, [[0.0, 4.0]])
    starts, goals = sampler.sample(rng, 8, "human", existing_positions=r_start, existing_goals=r_goal)
    np.testing.assert_array_equal(goals, -starts)  # opposite points
    radii = np.linalg.norm(starts, axis=1)
    noise = scene.protocol.noise
    assert (radii >= 4.0 - noise * np.sqrt(2)).all() and (radii <= 4.0 + noise * np.sqrt(2)).all()
    others = np.r_[r_start, r_goal]
    assert _pairwise_min(starts) >= 0.7 and _pairwise_min(starts, others) >= 0.7
    assert _pairwise_min(starts, goals) >= 0.7
    # a second robot is placed like a human
    two = sampler.sample(np.random.default_rng(0), 2, "robot")
    np.testing.assert_array_equal(two[0][0], [0.0, -4.0])
    np.testing.assert_allclose(two[1][1], -two[0][1])
    assert np.array_equal(sampler.sample_goal(rng, starts[0], "human"), -starts[0])


def test_square_crossing():
    scene = get_scene("square_crossing")
    sampler = TaskSampler(scene, scene.occupancy(), 0.3)
    rng = np.random.default_rng(6)
    starts, goals = sampler.sample(rng, 8, "human")
    w = scene.protocol.width
    assert (np.abs(np.r_[starts, goals]) <= w / 2).all()
    assert (np.sign(starts[:, 0]) == -np.sign(goals[:, 0])).all()
    assert _pairwise_min(starts) >= 0.7 and _pairwise_min(goals) >= 0.7
    r_start, r_goal = sampler.sample(rng, 1, "robot")
    np.testing.assert_array_equal(r_start, [[0.0, -4.0]])
    np.testing.assert_array_equal(r_goal, [[0.0, 4.0]])
    g = sampler.sample_goal(rng, starts[0], "human")
    assert np.sign(g[0]) == -np.sign(starts[0, 0])


def test_zero_agents(rooms):
    s, g = TaskSampler(rooms, None, 0.3).sample(np.random.default_rng(0), 0, "human")
    assert s.shape == (0, 2) and g.shape == (0, 2)


def test_sample_goal_from_a_position_against_a_wall(rooms):
    sampler = TaskSampler(rooms, rooms.occupancy(), 0.3)
    rng = np.random.default_rng(9)
    against_wall = np.array([4.82, 1.0])  # 0.08 m from the dividing wall: not a valid start
    assert not sampler.valid_positions(against_wall[None])[0]
    goal = sampler.sample_goal(rng, against_wall, "human", 2.0)
    assert sampler.valid_positions(goal[None])[0]
    assert AStarPlanner(rooms.occupancy(), 0.3).plan(against_wall, goal) is not None
    # an impossible distance is relaxed instead of failing mid-episode
    far = sampler.sample_goal(rng, np.array([2.0, 1.0]), "human", 100.0)
    assert sampler.valid_positions(far[None])[0]
