"""Robot command model, kinematic humanoid playback and the baseline helpers."""

from __future__ import annotations

import numpy as np
import pybullet as p
import pytest

from navzoo import sim
from navzoo.agents.humanoid import HumanoidBodies
from navzoo.agents.motion import load_deepmimic_cycle, sample_cycle
from navzoo.agents.policy import velocity_to_diff_drive
from navzoo.agents.robot import RobotBodies, RobotSpec, command_velocity


def test_diff_drive_limits_speed_and_acceleration():
    spec = RobotSpec(max_speed=1.0, max_turn_rate=2.0, max_accel=2.0, max_ang_accel=6.0)
    cmd = np.zeros((1, 2))
    yaw = np.array([np.pi / 2])
    speeds = []
    for _ in range(10):
        cmd, world = command_velocity(np.array([[1.0, 1.0]]), cmd, yaw, spec, dt=0.1)
        speeds.append(cmd[0].copy())
    speeds = np.array(speeds)
    # v ramps at 0.2 m/s per 0.1 s step up to 1 m/s; omega at 0.6 rad/s per step up to 2 rad/s.
    np.testing.assert_allclose(speeds[:5, 0], [0.2, 0.4, 0.6, 0.8, 1.0])
    np.testing.assert_allclose(speeds[-1], [1.0, 2.0])
    # Heading pi/2: the world velocity points along +y.
    np.testing.assert_allclose(world[0], [0.0, 1.0, 2.0], atol=1e-12)


def test_holonomic_caps_norm_not_components():
    spec = RobotSpec(kinematics="holonomic", max_speed=1.0, max_accel=100.0)
    cmd, world = command_velocity(np.array([[1.0, 1.0]]), np.zeros((1, 2)), np.zeros(1), spec, dt=0.25)
    assert np.linalg.norm(cmd[0]) == pytest.approx(1.0)
    np.testing.assert_allclose(world[0, :2], cmd[0])


def test_robot_spec_validation():
    with pytest.raises(ValueError, match="radius"):
        RobotSpec(radius=-1)
    with pytest.raises(ValueError, match="kinematics"):
        RobotSpec(kinematics="ackermann")


def test_velocity_to_diff_drive_turns_in_place_for_targets_behind():
    a = velocity_to_diff_drive(np.array([[-1.0, 0.0], [1.0, 0.0]]), np.zeros(2), 1.0, 2.0)
    assert a[0, 0] == pytest.approx(0.0) and abs(a[0, 1]) == pytest.approx(1.0)
    np.testing.assert_allclose(a[1], [1.0, 0.0])


def test_walk_cycle_is_a_loop_at_walking_speed():
    c = load_deepmimic_cycle()
    assert 0.8 < c.speed < 1.3  # the DeepMimic walk is about 1 m/s
    assert c.spherical.shape[1:] == (8, 4) and c.revolute.shape[1:] == (4,)
    s0, r0, h0, _ = sample_cycle(c, np.array([0.0]), np.array([1.0]))
    s1, r1, h1, _ = sample_cycle(c, np.array([1.0 - 1e-9]), np.array([1.0]))
    np.testing.assert_allclose(np.abs(np.sum(s0 * s1, axis=-1)), 1.0, atol=0.05)  # wraps smoothly
    np.testing.assert_allclose(np.linalg.norm(s0, axis=-1), 1.0, atol=1e-9)
    # Standing pose (gait 0): identity joints, zero knees/elbows.
    s, r, h, t = sample_cycle(c, np.array([0.3]), np.array([0.0]))
    np.testing.assert_allclose(s[0], np.tile([0, 0, 0, 1.0], (8, 1)), atol=1e-9)
    np.testing.assert_allclose(r, 0.0)


def test_kinematic_humanoid_follows_pose_and_feet_touch_ground():
    cid = sim.connect()
    try:
        bodies = HumanoidBodies(cid, 3)
        pos = np.array([[0.0, 0.0], [2.0, 1.0], [-3.0, 4.0]])
        yaw = np.array([0.0, np.pi / 2, -1.0])
        bodies.reset(pos, yaw, np.array([0.0, 0.3, 0.6]))
        bodies.advance(np.array([1.0, 1.0, 0.0]), 0.1)
        bodies.pose(pos, yaw, np.array([1.0, 1.0, 0.0]))
        p.performCollisionDetection(physicsClientId=cid)  # refresh the AABBs after posing
        for i, body in enumerate(bodies.ids):
            xyz, _ = p.getBasePositionAndOrientation(body, physicsClientId=cid)
            np.testing.assert_allclose(xyz[:2], pos[i], atol=1e-9)
            lo = min(p.getAABB(body, link, physicsClientId=cid)[0][2] for link in range(-1, 15))
            hi = max(p.getAABB(body, link, physicsClientId=cid)[1][2] for link in range(-1, 15))
            assert -0.05 < lo < 0.12, f"lowest point {lo:.3f} m: feet should be near the ground"
            assert 1.45 < hi < 1.85, f"top {hi:.3f} m: an upright adult"
    finally:
        sim.disconnect(cid)


def test_robot_body_is_stopped_by_a_wall():
    from navzoo.world.builder import build_scene
    from navzoo.world.scene import load_scene

    scene = load_scene({
        "name": "wall", "bounds": [-3, -3, 3, 3],
        "obstacles": [{"type": "box", "center": [1.0, 0.0], "size": [0.2, 4.0], "height": 1.0}],
    })
    cid = sim.connect()
    try:
        p.setGravity(0, 0, -9.81, physicsClientId=cid)
        p.setTimeStep(1 / 60, physicsClientId=cid)
        built = build_scene(scene, cid)
        robots = RobotBodies(cid, RobotSpec(), 1)
        robots.reset(np.array([[0.0, 0.0]]), np.array([0.0]))
        touched = False
        for _ in range(120):
            robots.apply_velocity(np.array([[1.0, 0.0, 0.0]]), np.array([True]))
            p.stepSimulation(physicsClientId=cid)
            touched |= any(b in built.obstacle_ids for b in robots.contacts(0))
        pos, _, _ = robots.read_state()
        assert touched
        assert pos[0, 0] < 1.0 - 0.1 - 0.3 + 0.05  # pressed against the wall, not through it
    finally:
        sim.disconnect(cid)
