"""Every packaged scene and a few procedural ones: valid, connected, reachable, plannable (issue 4)."""

from __future__ import annotations

import re

import numpy as np
import pytest
from scipy import ndimage

from navzoo.world.library import get_scene, list_scenes, scene_info
from navzoo.world.planner import AStarPlanner
from navzoo.world.procedural import aisles, from_name, rooms_and_doors
from navzoo.world.scene import Scene, load_scene
from navzoo.world.tasks import TaskSampler

RADIUS = 0.3  # robot and pedestrian radius (navzoo defaults)
ORIGINAL = {
    "circle_crossing",
    "corridor",
    "doorway",
    "grocery",
    "home",
    "lobby",
    "square_crossing",
    "station",
}
PROCEDURAL_SEEDS = (0, 1, 2, 17)


def _used_regions(scene: Scene) -> list[str]:
    return list(dict.fromkeys(scene.robot_spawn + scene.robot_goal + scene.human_spawn + scene.human_goal))


def _check_connected(scene: Scene) -> None:
    """Free space for a 0.3 m disc: every spawn/goal region has free cells in one common component (so each
    region is reachable from every other), and that component holds nearly all the free space."""
    grid = scene.occupancy()
    free = ~grid.inflate(RADIUS).occ
    labels, n = ndimage.label(free)  # 4-connectivity, as the planner and validate_reachability
    assert n >= 1
    sizes = np.bincount(labels.ravel())[1:]
    main = int(np.argmax(sizes)) + 1
    # small pockets (behind furniture, in corners) are allowed; they must stay marginal
    assert sizes[main - 1] >= 0.95 * sizes.sum(), f"{scene.name}: free space split into {n} sizeable parts"
    for name in _used_regions(scene):
        in_region = labels[grid.region_mask(scene.regions[name]) & free]
        assert in_region.size, f"{scene.name}: region {name!r} has no free space"
        assert main in set(in_region.tolist()), f"{scene.name}: region {name!r} not connected to the rest"
    if scene.protocol.type != "regions":
        r = scene.protocol.radius
        rc = grid.world_to_cell(np.array([[0.0, -r], [0.0, r]]))
        assert labels[tuple(rc[0])] == labels[tuple(rc[1])] == main


def _check_tasks(scene: Scene, n_humans: int = 6) -> None:
    """Tasks sampled with a fixed seed are planned by A*; robot tasks fit the scene's time limit."""
    grid = scene.occupancy()
    planner = AStarPlanner(grid, RADIUS)
    sampler = TaskSampler(scene, grid, RADIUS)
    rng = np.random.default_rng(0)
    r_starts, r_goals = sampler.sample(rng, 2, "robot")
    # the scenario preset places default_humans people: the spawn regions must hold them all
    h_starts, h_goals = sampler.sample(rng, scene.default_humans, "human", existing_positions=r_starts)
    for k, (s, g) in enumerate(
        zip(np.r_[r_starts, h_starts[:n_humans]], np.r_[r_goals, h_goals[:n_humans]], strict=True)
    ):
        path = planner.plan(s, g)
        assert path is not None, f"{scene.name}: no path {s} -> {g}"
        assert np.allclose(path[0], s) and np.allclose(path[-1], g)
        length = planner.path_length(path)
        assert length >= np.linalg.norm(g - s) - 1e-6
        if k < 2:  # robot: at most 0.7 m/s needed on the planned path
            assert length <= 0.7 * scene.time_limit, (
                f"{scene.name}: {length:.1f} m path, {scene.time_limit:g} s limit"
            )
    if scene.protocol.type == "regions":
        for pts, names in ((r_starts, scene.robot_spawn), (r_goals, scene.robot_goal)):
            inside = np.zeros(len(pts), dtype=bool)
            for name in names:
                inside |= scene.regions[name].contains(pts)
            assert inside.all()


# ---------------------------------------------------------------------------------------------------------
# Packaged scenes
# ---------------------------------------------------------------------------------------------------------


def test_library_has_at_least_30_scenes():
    names = list_scenes()
    assert len(names) >= 30
    assert names == sorted(names) and len(set(names)) == len(names)
    assert ORIGINAL <= set(names)
    assert all(re.fullmatch(r"[a-z][a-z0-9_]*", n) for n in names)
    # varied scale: from a small flat to a station-sized hall
    areas = [np.prod(get_scene(n).size) for n in names]
    assert min(areas) <= 50 and max(areas) >= 1000
    assert not any(n.startswith("procedural_") for n in names)


@pytest.mark.parametrize("name", list_scenes())
def test_packaged_scene(name):
    scene = get_scene(name)
    assert scene.name == name and scene.description
    assert load_scene(scene.to_dict()) == scene  # round trip, full validation including reachability
    w, h = scene.size
    assert 5 <= w <= 45 and 3 <= h <= 45
    info = scene_info(name)
    assert 0 < info["free_area_m2"] <= w * h
    assert 1 <= scene.default_humans <= 0.2 * info["free_area_m2"]
    assert 20 <= scene.time_limit <= 150
    if scene.protocol.type == "regions":
        assert scene.robot_spawn and scene.robot_goal and scene.human_spawn and scene.human_goal
        assert len(set(scene.robot_spawn + scene.robot_goal)) >= 2  # tasks cross the scene
    _check_connected(scene)
    _check_tasks(scene)
    _check_dense_crowd(scene)


def _check_dense_crowd(scene: Scene, density: float = 0.3, cap: int = 40, seeds: int = 5) -> None:
    """The benchmark's densest level (0.3 people per m² of crowd area, at most 40) fits in the scene."""
    n = min(cap, int(round(density * round(scene.crowd_area(), 1))))
    sampler = TaskSampler(scene, scene.occupancy(), RADIUS)
    for seed in range(seeds):
        rng = np.random.default_rng(seed)
        r_starts, r_goals = sampler.sample(rng, 1, "robot", min_goal_dist=3.0)
        h_starts, _ = sampler.sample(
            rng, n, "human", min_goal_dist=3.0, existing_positions=r_starts, existing_goals=r_goals
        )
        assert len(h_starts) == n


# ---------------------------------------------------------------------------------------------------------
# Procedural scenes
# ---------------------------------------------------------------------------------------------------------


@pytest.mark.parametrize("seed", PROCEDURAL_SEEDS)
@pytest.mark.parametrize("kind", ["rooms", "aisles"])
def test_procedural_scene(kind, seed):
    make = rooms_and_doors if kind == "rooms" else aisles
    scene = make(seed)
    assert scene.name == f"procedural_{kind}_{seed}"
    assert make(seed) == scene  # deterministic per seed
    assert get_scene(scene.name) == scene and get_scene(scene.name) is get_scene(scene.name)
    assert load_scene(scene.to_dict()) == scene
    assert scene.protocol.type == "regions" and scene.default_humans >= 2 and scene.time_limit >= 30
    assert len(scene.robot_spawn) >= 1 and len(scene.robot_goal) >= 2
    _check_connected(scene)
    _check_tasks(scene)


def test_procedural_variety_and_parameters():
    rooms = [rooms_and_doors(s) for s in range(6)]
    assert len({r.size for r in rooms}) > 1 and len({len(r.regions) for r in rooms}) > 1
    assert rooms_and_doors(3) != rooms_and_doors(4)
    sized = rooms_and_doors(5, width=12, height=9, furniture=False, name="flat")
    assert sized.name == "flat" and sized.size == (12, 9)
    assert all(o.type == "wall" for o in sized.obstacles)
    # at least a spanning tree of doors (one waypoint per door)
    assert len(sized.regions) >= 2 and len(sized.waypoints) >= len(sized.regions) - 1
    hall = aisles(2, width=20, height=16, shelf="gondola", aisle_width=1.4, cross_aisles=1)
    assert hall.size == (20, 16) and "cross_aisle_0" in hall.regions
    assert sum(o.name == "gondola" for o in hall.obstacles) >= 6
    _check_connected(hall)
    with pytest.raises(ValueError, match="min_room"):
        rooms_and_doors(0, min_room=1.5)
    with pytest.raises(ValueError, match="shelf"):
        aisles(0, shelf="crate")
    assert from_name("procedural_rooms_3") == rooms_and_doors(3)
    assert from_name("procedural_rooms_03") is None and from_name("home") is None
    with pytest.raises(ValueError, match="unknown scene 'procedural_halls_1'.*procedural_rooms_<seed>"):
        get_scene("procedural_halls_1")
