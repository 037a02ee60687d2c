from __future__ import annotations

import numpy as np
import pytest
from scipy import ndimage

from navzoo.world.library import get_scene, list_scenes, scene_info
from navzoo.world.planner import AStarPlanner
from navzoo.world.scene import load_scene
from navzoo.world.tasks import TaskSampler

EXPECTED = {"station", "home", "grocery", "circle_crossing", "square_crossing", "corridor", "doorway", "lobby"}


def test_list_and_unknown_names():
    assert EXPECTED <= set(list_scenes()) and len(list_scenes()) >= 30
    assert list_scenes() == sorted(list_scenes())
    with pytest.raises(ValueError, match="unknown scene 'mall'.*station"):
        get_scene("mall")
    assert get_scene("home") is get_scene("home")


@pytest.mark.parametrize("name", sorted(EXPECTED))
def test_scene_info(name):
    info = scene_info(name)
    assert info["name"] == name and info["description"]
    w, h = info["size_m"]
    assert 0 < info["free_area_m2"] <= w * h
    assert info["n_obstacles"] == len(get_scene(name).obstacles)
    assert info["default_humans"] > 0 and info["time_limit"] > 0
    assert info["protocol"] in ("regions", "circle_crossing", "square_crossing")


@pytest.mark.parametrize("name", sorted(EXPECTED))
def test_library_scene_loads_validates_and_plans(name):
    scene = get_scene(name)
    # the packaged YAML round-trips and passes the full validation, including reachability
    assert load_scene(scene.to_dict()) == scene
    scene.validate_reachability(0.3)
    if scene.protocol.type == "regions":
        assert scene.robot_spawn and scene.robot_goal and scene.human_spawn and scene.human_goal
    # free space of spawn and goal regions connected, and paths planned between sampled tasks
    grid = scene.occupancy()
    planner = AStarPlanner(grid, 0.3)
    labels, _ = ndimage.label(~planner.inflated.occ)
    sampler = TaskSampler(scene, grid, 0.3)
    rng = np.random.default_rng(0)
    r_starts, r_goals = sampler.sample(rng, 2, "robot")
    h_starts, h_goals = sampler.sample(rng, scene.default_humans, "human", existing_positions=r_starts)
    starts, goals = np.r_[r_starts, h_starts], np.r_[r_goals, h_goals]
    for s, g in zip(starts, goals, strict=True):
        rs, rg = grid.world_to_cell(s), grid.world_to_cell(g)
        assert labels[tuple(rs)] == labels[tuple(rg)] != 0
        path = planner.plan(s, g)
        assert path is not None and np.allclose(path[-1], g)


def test_realistic_dimensions():
    assert 35 <= get_scene("station").size[0] <= 45 and 20 <= get_scene("station").size[1] <= 30
    assert 12 <= get_scene("home").size[0] <= 16
    assert get_scene("station").default_humans == 40 and get_scene("home").default_humans == 3
    assert get_scene("circle_crossing").protocol.radius == 4.0 and get_scene("circle_crossing").time_limit == 25
    assert get_scene("square_crossing").protocol.width == 10.0
    home = get_scene("home")
    assert {"living_room", "kitchen", "bedroom", "bathroom", "corridor"} <= set(home.regions)
    assert any(o.type == "polygon" and o.name == "counter" for o in home.obstacles)
    grocery = get_scene("grocery")
    assert sum(o.name == "shelf" for o in grocery.obstacles) >= 6
