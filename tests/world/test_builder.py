from __future__ import annotations

import numpy as np
import pybullet as p
import pytest

from navzoo.world.builder import GROUP_HUMAN, GROUP_ROBOT, GROUP_STATIC, MASK_ALL, build_scene
from navzoo.world.library import get_scene, list_scenes
from navzoo.world.scene import load_scene


@pytest.fixture
def client():
    cid = p.connect(p.DIRECT)
    p.setGravity(0, 0, -9.81, physicsClientId=cid)
    yield cid
    p.disconnect(physicsClientId=cid)


def _push_sphere(cid: int, start, velocity, target: int, steps: int = 240) -> tuple[bool, np.ndarray]:
    """Launch a dynamic sphere (r = 0.3 m) and report whether it touched ``target`` and where it ended."""
    shape = p.createCollisionShape(p.GEOM_SPHERE, radius=0.3, physicsClientId=cid)
    sphere = p.createMultiBody(1.0, shape, -1, start, physicsClientId=cid)
    p.resetBaseVelocity(sphere, velocity, physicsClientId=cid)
    touched = False
    for _ in range(steps):
        p.stepSimulation(physicsClientId=cid)
        touched |= bool(p.getContactPoints(sphere, target, physicsClientId=cid))
    pos = np.array(p.getBasePositionAndOrientation(sphere, physicsClientId=cid)[0])
    p.removeBody(sphere, physicsClientId=cid)
    return touched, pos


def test_group_constants():
    assert (GROUP_STATIC, GROUP_ROBOT, GROUP_HUMAN) == (1, 2, 4) and MASK_ALL == 0xFFFF


@pytest.mark.parametrize("name", list_scenes())
def test_builds_every_library_scene(client, name):
    scene = get_scene(name)
    bodies = build_scene(scene, client)
    assert len(bodies.obstacle_ids) == len(scene.obstacles)
    assert bodies.ground_id is not None and bodies.body_ids[0] == bodies.ground_id
    assert p.getNumBodies(physicsClientId=client) == len(scene.obstacles) + 1
    for body in bodies.obstacle_ids:
        assert p.getBodyInfo(body, physicsClientId=client) is not None
        assert p.getDynamicsInfo(body, -1, physicsClientId=client)[0] == 0.0  # static
    bodies.remove()
    assert p.getNumBodies(physicsClientId=client) == 0


def test_sphere_collides_with_wall_box_circle_and_concave_polygon(client):
    scene = load_scene(
        {
            "name": "contacts",
            "bounds": [-6, -6, 6, 6],
            "obstacles": [
                {"type": "wall", "start": [-4, -4], "end": [-4, 4], "thickness": 0.15, "height": 2.5},
                {"type": "polygon", "points": [[0, 0], [3, 0], [3, 0.6], [0.6, 0.6], [0.6, 3], [0, 3]], "height": 0.9},
                {"type": "circle", "center": [-2, -3], "radius": 0.4, "height": 1.0},
                {"type": "box", "center": [3, -3], "size": [1, 0.5], "yaw": 0.5, "height": 1.0},
            ],
        },
        check_reachability=False,
    )
    bodies = build_scene(scene, client)
    wall, poly, circle, box = bodies.obstacle_ids
    touched, pos = _push_sphere(client, [-2.5, 0, 0.3], [-3, 0, 0], wall)
    assert touched and pos[0] > -4 + 0.075 + 0.25
    # the vertical arm of the L (a non-convex polygon): stopped by the arm, not by its convex hull
    touched, pos = _push_sphere(client, [2.0, 1.5, 0.3], [-3, 0, 0], poly)
    assert touched and pos[0] == pytest.approx(0.9, abs=0.05)
    touched, _ = _push_sphere(client, [-2, -1, 0.3], [0, -3, 0], circle)
    assert touched
    touched, _ = _push_sphere(client, [3, -1, 0.3], [0, -3, 0], box)
    assert touched
    # the ground holds a sphere dropped on it
    touched, pos = _push_sphere(client, [4, 4, 1.0], [0, 0, 0], bodies.ground_id)
    assert touched and pos[2] == pytest.approx(0.3, abs=0.02)


def _cross_wall(cid: int, group: int, mask: int, filter_mode: int | None) -> bool:
    """Does a sphere with (group, mask) get through a static wall? (gravity off, 0.5 s at 3 m/s)"""
    if filter_mode is not None:
        p.setPhysicsEngineParameter(collisionFilterMode=filter_mode, physicsClientId=cid)
    p.setGravity(0, 0, 0, physicsClientId=cid)
    scene = load_scene(
        {"name": "filter", "bounds": [0, 0, 4, 4], "obstacles": [{"type": "wall", "start": [2, 0], "end": [2, 4]}]},
        check_reachability=False,
    )
    bodies = build_scene(scene, cid, ground=False)
    assert bodies.ground_id is None and bodies.body_ids == bodies.obstacle_ids
    shape = p.createCollisionShape(p.GEOM_SPHERE, radius=0.3, physicsClientId=cid)
    sphere = p.createMultiBody(1.0, shape, -1, [1.0, 2.0, 1.0], physicsClientId=cid)
    p.setCollisionFilterGroupMask(sphere, -1, group, mask, physicsClientId=cid)
    p.resetBaseVelocity(sphere, [3, 0, 0], physicsClientId=cid)
    for _ in range(240):
        p.stepSimulation(physicsClientId=cid)
    x = p.getBasePositionAndOrientation(sphere, physicsClientId=cid)[0][0]
    bodies.remove()
    p.removeBody(sphere, physicsClientId=cid)
    return x > 2.5


@pytest.mark.parametrize(
    ("group", "mask", "mode", "crosses"),
    [
        (GROUP_ROBOT, GROUP_STATIC | GROUP_HUMAN, None, False),  # robots hit the scene
        (GROUP_HUMAN, GROUP_ROBOT, None, False),  # default OR mode: static mask 0xFFFF accepts every group
        (0, 0, None, True),  # group 0 / mask 0 takes a body out of all collisions (any mode)
        (GROUP_HUMAN, GROUP_ROBOT, 0, True),  # AND mode: the dynamic body's mask decides
        (GROUP_ROBOT, GROUP_STATIC, 0, False),
    ],
)
def test_collision_filter_on_static_bodies(client, group, mask, mode, crosses):
    assert _cross_wall(client, group, mask, mode) is crosses


def test_builds_100_mixed_obstacles(client):
    # build speed is measured by scripts/bench_world.py (docs/scenes.md), not bounded here
    rng = np.random.default_rng(0)
    obstacles = [
        {"type": "box", "center": list(rng.uniform(1, 19, 2)), "size": [0.5, 0.5], "yaw": float(rng.uniform(0, 3))}
        for _ in range(60)
    ]
    obstacles += [{"type": "circle", "center": list(rng.uniform(1, 19, 2)), "radius": 0.3} for _ in range(30)]
    obstacles += [
        {"type": "polygon", "points": (np.array([[0, 0], [1, 0], [1, 0.3], [0.3, 0.3], [0.3, 1], [0, 1]]) + c).tolist()}
        for c in rng.uniform(1, 18, (10, 2))
    ]
    scene = load_scene({"name": "many", "bounds": [0, 0, 20, 20], "obstacles": obstacles}, check_reachability=False)
    bodies = build_scene(scene, client)
    assert len(bodies.obstacle_ids) == 100
