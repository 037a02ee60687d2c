from __future__ import annotations

import json

import numpy as np
import pytest
import yaml

from navzoo.world.scene import BoxObstacle, CircleObstacle, Scene, SceneError, load_scene
from tests.world.util import base_scene


def test_load_round_trip(tmp_path):
    scene = load_scene(base_scene())
    again = load_scene(scene.to_dict())
    assert again == scene
    assert again.to_dict() == scene.to_dict()
    # YAML and JSON files
    yml = tmp_path / "s.yaml"
    yml.write_text(yaml.safe_dump(scene.to_dict()))
    assert load_scene(yml) == scene
    js = tmp_path / "s.json"
    js.write_text(json.dumps(scene.to_dict()))
    assert load_scene(str(js)) == scene
    assert hash(scene) == hash(again)


def test_defaults_and_geometry():
    scene = load_scene({"name": "minimal", "bounds": [0, 0, 4, 3]})
    assert scene.size == (4.0, 3.0)
    assert scene.protocol.type == "regions"
    assert scene.obstacles == () and scene.regions == {}
    assert scene.wall_segments().shape == (0, 2, 2)
    assert scene.wall_segments(include_bounds=True).shape == (4, 2, 2)
    assert scene.free_area() == pytest.approx(12.0)
    assert scene.free_area(0.5) == pytest.approx(3 * 2, abs=0.3)


def test_obstacle_polygons_and_segments():
    scene = load_scene(base_scene())
    polys = scene.obstacle_polygons()
    assert [p.shape for p in polys] == [(4, 2), (4, 2), (4, 2), (24, 2), (6, 2)]
    seg = scene.wall_segments()
    assert seg.shape == (4 + 4 + 4 + 24 + 6, 2, 2) and seg.dtype == np.float64
    assert not seg.flags.writeable
    owner = scene.wall_segment_owner()
    assert owner.shape == (seg.shape[0],) and owner.tolist() == sorted(owner.tolist())
    assert np.bincount(owner).tolist() == [4, 4, 4, 24, 6]
    assert scene.wall_segment_owner(include_bounds=True)[-4:].tolist() == [-1] * 4
    # walls are boxes along the segment without end caps
    np.testing.assert_allclose(np.sort(polys[0][:, 1]), [0, 0, 2.5, 2.5], atol=1e-12)
    np.testing.assert_allclose(np.sort(polys[0][:, 0]), [4.9, 4.9, 5.1, 5.1], atol=1e-12)


def test_wall_clearance_sign():
    scene = load_scene(base_scene())
    c = scene.clearance([[5, 1], [4, 1], [8, 1.5]])
    assert c[0] < 0 and c[1] == pytest.approx(0.9) and c[2] < 0


def _err(data) -> str:
    with pytest.raises(SceneError) as info:
        load_scene(data)
    return str(info.value)


def test_unknown_key_lists_valid_keys():
    msg = _err(base_scene(colour="red"))
    assert "scene 'test_rooms'" in msg and "unknown key 'colour'" in msg and "time_limit" in msg
    data = base_scene()
    data["obstacles"][2]["colour"] = "red"
    msg = _err(data)
    assert "obstacles[2]" in msg and "unknown key 'colour'" in msg and "yaw" in msg


def test_unknown_obstacle_type():
    data = base_scene()
    data["obstacles"].append({"type": "sphere", "center": [1, 1]})
    msg = _err(data)
    assert "obstacles[5].type" in msg and "sphere" in msg and "polygon" in msg


def test_bad_shape():
    data = base_scene()
    data["obstacles"][2]["size"] = [1, 2, 3]
    msg = _err(data)
    assert "obstacles[2].size" in msg and "expected a list of 2 numbers, got 3 items" in msg
    data = base_scene()
    data["obstacles"][3]["center"] = "middle"
    assert "obstacles[3].center" in _err(data)
    msg = _err(base_scene(bounds=[0, 0, 10]))
    assert "bounds" in msg and "4 numbers" in msg
    msg = _err(base_scene(default_humans=2.5))
    assert "default_humans" in msg and "integer" in msg


def test_negative_sizes():
    data = base_scene()
    data["obstacles"][2]["size"] = [1, -0.5]
    msg = _err(data)
    assert "obstacles[2].size[1]" in msg and "must be > 0, got -0.5" in msg
    data = base_scene()
    data["obstacles"][3]["radius"] = 0
    assert "obstacles[3].radius: must be > 0" in _err(data)
    data = base_scene()
    data["obstacles"][0]["height"] = -1
    assert "obstacles[0].height" in _err(data)
    data = base_scene()
    data["obstacles"][0]["thickness"] = 0.0
    assert "obstacles[0].thickness" in _err(data)
    assert "time_limit" in _err(base_scene(time_limit=0))


def test_self_intersecting_polygon():
    data = base_scene()
    data["obstacles"][4]["points"] = [[7, 4], [9, 5], [9, 4], [7, 5]]
    msg = _err(data)
    assert "obstacles[4].points" in msg and "self-intersecting" in msg
    data = base_scene()
    data["obstacles"][4]["points"] = [[7, 4], [9, 4]]
    assert "at least 3 points" in _err(data)
    data = base_scene()
    data["regions"]["east"] = {"polygon": [[6, 1], [9, 5], [9, 1], [6, 5]]}
    msg = _err(data)
    assert "regions.east.polygon" in msg and "self-intersecting" in msg


def test_zero_length_wall_and_bad_region_rect():
    data = base_scene()
    data["obstacles"][0]["end"] = [5, 0]
    assert "obstacles[0].end: wall has zero length" in _err(data)
    data = base_scene()
    data["regions"]["west"] = {"rect": [4, 0, 1, 5]}
    assert "regions.west.rect" in _err(data)
    data = base_scene()
    data["regions"]["west"] = {"rect": [0, 0, 1, 1], "polygon": [[0, 0], [1, 0], [0, 1]]}
    assert "regions.west" in _err(data)


def test_undefined_region():
    msg = _err(base_scene(robot_goal=["kitchen"]))
    assert "robot_goal[0]" in msg and "region 'kitchen' is not defined" in msg and "east, west" in msg


def test_degenerate_bounds_and_outside_obstacles():
    assert "degenerate bounds" in _err(base_scene(bounds=[0, 0, 0, 5]))
    data = base_scene()
    data["obstacles"].append({"type": "box", "center": [20, 20], "size": [1, 1]})
    msg = _err(data)
    assert "obstacles[5]" in msg and "entirely outside bounds" in msg
    # partially outside is fine
    data = base_scene()
    data["obstacles"].append({"type": "box", "center": [10, 3], "size": [1, 1]})
    load_scene(data)


def test_protocol_validation():
    assert "protocol.type" in _err(base_scene(protocol={"type": "spiral"}))
    msg = _err(base_scene(protocol={"type": "circle_crossing", "radius": 4.0, "width": 3}))
    assert "protocol" in msg and "unknown key 'width'" in msg
    msg = _err(base_scene(protocol={"type": "circle_crossing", "radius": 4.0, "noise": 0.5}))
    assert "protocol.radius" in msg and "does not fit" in msg
    assert "protocol.noise" in _err(base_scene(protocol={"type": "circle_crossing", "noise": -1}))


def test_waypoint_validation():
    assert "waypoints.door" in _err(base_scene(waypoints={"door": [50, 3]}))
    msg = _err(base_scene(waypoints={"inside_wall": [5, 1]}))
    assert "waypoints.inside_wall" in msg and "not free" in msg


def test_unreachable_goal_region():
    data = base_scene(name="closed")
    # close the door: the east room becomes unreachable from the west room
    data["obstacles"].append({"type": "wall", "start": [5, 2.4], "end": [5, 3.6], "thickness": 0.2})
    data["waypoints"] = {}
    msg = _err(data)
    assert msg == (
        "scene 'closed': robot_goal: goal region 'east' is not reachable from spawn region 'west' "
        "for an agent of radius 0.3 m"
    )
    # the check can be skipped, and a smaller agent radius does not change anything here
    load_scene(data, check_reachability=False)


def test_room_closed_by_thin_walls_is_unreachable():
    # a 4 cm thick wall covers no cell centre but must still block
    data = base_scene(name="thin")
    data["obstacles"] = [
        {"type": "wall", "start": [5, 0], "end": [5, 6], "thickness": 0.04},
    ]
    data["waypoints"] = {}
    msg = _err(data)
    assert "not reachable" in msg
    with pytest.raises(SceneError, match="not reachable"):
        load_scene(data, radius=0.0)


def test_region_without_free_space():
    data = base_scene()
    data["regions"]["tiny"] = {"rect": [4.8, 0.5, 5.2, 1.5]}  # on the wall
    data["robot_goal"] = ["tiny"]
    msg = _err(data)
    assert "robot_goal[0]" in msg and "region 'tiny' has no free space for an agent of radius 0.3 m" in msg


def test_narrow_door_depends_on_radius():
    data = base_scene(name="narrow")
    data["obstacles"][1]["start"] = [5, 3.0]  # 0.5 m door
    data["waypoints"] = {}
    with pytest.raises(SceneError, match="not reachable"):
        load_scene(data, radius=0.3)
    load_scene(data, radius=0.15)


def test_direct_construction_validates():
    with pytest.raises(SceneError, match="size"):
        BoxObstacle(center=(0, 0), size=(1, 0))
    with pytest.raises(SceneError, match="scene 'x': bounds"):
        Scene(name="x", bounds=(0, 0, 1))
    scene = Scene(name="x", bounds=[0, 0, 2, 2], obstacles=[BoxObstacle((1, 1), (0.5, 0.5))])
    assert isinstance(scene.obstacles, tuple) and scene.bounds == (0.0, 0.0, 2.0, 2.0)


def test_yaml_file_errors(tmp_path):
    bad = tmp_path / "broken.yaml"
    bad.write_text("name: [unclosed\n")
    with pytest.raises(SceneError, match="scene 'broken'"):
        load_scene(bad)
    listy = tmp_path / "listy.yaml"
    listy.write_text("- 1\n- 2\n")
    with pytest.raises(SceneError, match="top level"):
        load_scene(listy)
    noname = tmp_path / "noname.yaml"
    noname.write_text("bounds: [0, 0, 1, 1]\n")
    with pytest.raises(SceneError, match="scene 'noname': missing required key 'name'"):
        load_scene(noname)


def test_exposed_corners_are_the_convex_vertices_not_closed_off():
    """A lone wall has four exposed corners; where a second wall abuts its middle (a T), the two vertices where they
    meet are closed off and only the free ends count."""
    lone = Scene(name="lone", bounds=(0, 0, 4, 4), obstacles=(BoxObstacle((2.0, 1.0), (2.0, 0.2)),))
    assert {tuple(np.round(v, 2)) for v in lone.exposed_corners()} == {(1.0, 0.9), (3.0, 0.9), (1.0, 1.1), (3.0, 1.1)}
    tee = Scene(name="tee", bounds=(0, 0, 4, 4),
                obstacles=(BoxObstacle((2.0, 1.0), (2.0, 0.2)), BoxObstacle((2.0, 2.0), (0.2, 1.8))))
    got = {tuple(np.round(v, 2)) for v in tee.exposed_corners()}
    assert got == {(1.0, 0.9), (3.0, 0.9), (1.0, 1.1), (3.0, 1.1), (1.9, 2.9), (2.1, 2.9)}
    assert Scene(name="empty", bounds=(0, 0, 4, 4)).exposed_corners().shape == (0, 2)
    pillar = Scene(name="pillar", bounds=(0, 0, 4, 4), obstacles=(CircleObstacle((2.0, 2.0), 0.4),))
    assert pillar.exposed_corners().shape == (0, 2)  # a round obstacle has no corner to cut
    assert not lone.exposed_corners().flags.writeable
