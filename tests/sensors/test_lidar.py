"""The 2D lidar: ranges, angles and hit bodies on known geometry, noise seeding, and a navzoo env."""

from __future__ import annotations

import math

import numpy as np
import pybullet as p
import pytest

import navzoo
from navzoo import sim
from navzoo.sensors import Lidar2D, LidarScan, render_robot_lidar
from navzoo.sensors.lidar import ray_visible
from navzoo.world.builder import GROUP_HUMAN, GROUP_ROBOT


@pytest.fixture()
def client():
    cid = sim.connect()
    yield cid
    sim.disconnect(cid)


def _box(cid: int, half, pos, yaw: float = 0.0) -> int:
    col = p.createCollisionShape(p.GEOM_BOX, halfExtents=list(half), physicsClientId=cid)
    orn = p.getQuaternionFromEuler([0.0, 0.0, yaw])
    return p.createMultiBody(0, col, -1, basePosition=list(pos), baseOrientation=orn, physicsClientId=cid)


def _robot(cid: int, xy=(0.0, 0.0), radius: float = 0.3, height: float = 0.4) -> int:
    col = p.createCollisionShape(p.GEOM_CYLINDER, radius=radius, height=height, physicsClientId=cid)
    return p.createMultiBody(30.0, col, -1, basePosition=[xy[0], xy[1], height / 2], physicsClientId=cid)


def test_angles() -> None:
    full = Lidar2D(n_rays=8).angles
    assert full == pytest.approx(np.radians([-180, -135, -90, -45, 0, 45, 90, 135]))
    assert Lidar2D().angles.shape == (360,) and (np.diff(Lidar2D().angles) > 0).all()
    assert Lidar2D(n_rays=5, fov_deg=90.0).angles == pytest.approx(np.radians([-45, -22.5, 0, 22.5, 45]))
    assert Lidar2D(n_rays=1, fov_deg=90.0).angles == pytest.approx([0.0])


def test_range_to_wall_angles_and_empty_rays(client: int) -> None:
    wall = _box(client, [0.5, 5.0, 1.0], [3.0, 0.0, 1.0])  # face at x = 2.5, 10 m wide
    robot = _robot(client)
    lidar = Lidar2D(n_rays=360, max_range=10.0)
    scan = lidar.scan(client, (0.0, 0.0, 0.0))
    assert isinstance(scan, LidarScan)
    assert scan.ranges.shape == scan.angles.shape == scan.hit_body.shape == (360,)
    assert robot not in scan.hit_body  # the rays start inside the robot's own (convex) body
    front = np.abs(scan.angles) < math.atan2(5.0, 2.5) - 0.01
    assert (scan.hit_body[front] == wall).all()
    assert scan.ranges[front] * np.cos(scan.angles[front]) == pytest.approx(
        np.full(front.sum(), 2.5), abs=1e-3
    )
    assert scan.ranges[scan.angles == 0.0] == pytest.approx([2.5], abs=1e-3)
    # Everything else: nothing within 10 m.
    back = np.abs(scan.angles) > math.atan2(5.0, 2.5) + 0.01
    assert (scan.hit_body[back] == -1).all() and (scan.ranges[back] == 10.0).all()
    # Hit points in the robot frame lie on the wall's face; no-hit rows are NaN.
    pts = scan.to_points()
    assert pts[front, 0] == pytest.approx(np.full(front.sum(), 2.5), abs=1e-3)
    assert np.isnan(pts[back]).all()
    # A wall beyond max_range is not seen.
    short = Lidar2D(n_rays=36, max_range=2.0).scan(client, (0.0, 0.0, 0.0))
    assert (short.hit_body == -1).all() and (short.ranges == 2.0).all()


def test_robot_pose_and_mount(client: int) -> None:
    wall = _box(client, [5.0, 0.5, 1.0], [0.0, 4.0, 1.0])  # face at y = 3.5
    lidar = Lidar2D(n_rays=4)  # rays at -180, -90, 0, 90 degrees
    # Robot at (1, 1) facing +x: the wall is to its left (robot angle +90 degrees), 2.5 m away.
    scan = lidar.scan(client, (1.0, 1.0, 0.0))
    assert scan.hit_body.tolist() == [-1, -1, -1, wall]
    assert scan.ranges[3] == pytest.approx(2.5, abs=1e-3)
    # Facing +y it is straight ahead; a lidar mounted 0.5 m forward is 0.5 m closer.
    scan = Lidar2D(n_rays=4, mount_x=0.5).scan(client, (1.0, 1.0, math.pi / 2))
    assert scan.hit_body.tolist() == [-1, -1, wall, -1]
    assert scan.ranges[2] == pytest.approx(2.0, abs=1e-3)
    assert scan.to_points()[2] == pytest.approx([2.5, 0.0], abs=1e-3)  # robot frame: from the robot's centre
    # The scan plane's height matters: a 0.3 m high box is seen at 0.2 m, not at 0.5 m.
    low = _box(client, [0.2, 0.2, 0.15], [2.0, 1.0, 0.15])
    assert Lidar2D(n_rays=4, height=0.2).scan(client, (1.0, 1.0, 0.0)).hit_body[2] == low
    assert Lidar2D(n_rays=4, height=0.5).scan(client, (1.0, 1.0, 0.0)).hit_body[2] == -1


def test_ignore_body_and_min_range(client: int) -> None:
    wall = _box(client, [0.5, 5.0, 1.0], [-3.0, 0.0, 1.0])  # behind the robot, face at x = -2.5
    robot = _robot(client)
    # A lidar 0.5 m in front of the centre is outside the robot's body and sees it straight behind.
    lidar = Lidar2D(n_rays=4, mount_x=0.5)
    scan = lidar.scan(client, (0.0, 0.0, 0.0))
    assert scan.hit_body[0] == robot and scan.ranges[0] == pytest.approx(0.2, abs=1e-3)
    scan = lidar.scan(client, (0.0, 0.0, 0.0), ignore_body_ids=[robot])
    assert scan.hit_body[0] == wall and scan.ranges[0] == pytest.approx(3.0, abs=1e-3)
    # A dead zone longer than the way through the body hides it too.
    scan = Lidar2D(n_rays=4, mount_x=0.5, min_range=0.9).scan(client, (0.0, 0.0, 0.0))
    assert scan.hit_body[0] == wall and scan.ranges[0] == pytest.approx(3.0, abs=1e-3)


def test_noise_is_seeded_and_only_on_hits(client: int) -> None:
    _box(client, [0.5, 5.0, 1.0], [3.0, 0.0, 1.0])
    lidar = Lidar2D(n_rays=360, noise_std=0.05, max_range=10.0)
    a = lidar.scan(client, (0.0, 0.0, 0.0), rng=np.random.default_rng(7))
    b = lidar.scan(client, (0.0, 0.0, 0.0), rng=np.random.default_rng(7))
    c = lidar.scan(client, (0.0, 0.0, 0.0), rng=np.random.default_rng(8))
    clean = Lidar2D(n_rays=360, max_range=10.0).scan(client, (0.0, 0.0, 0.0))
    assert np.array_equal(a.ranges, b.ranges)
    assert not np.array_equal(a.ranges, c.ranges)
    hit = clean.hit_body >= 0
    assert np.array_equal(a.hit_body, clean.hit_body)
    assert (a.ranges[~hit] == 10.0).all()
    err = a.ranges[hit] - clean.ranges[hit]
    assert 0.03 < err.std() < 0.07 and abs(err.mean()) < 0.02
    with pytest.raises(ValueError, match="rng"):
        lidar.scan(client, (0.0, 0.0, 0.0))


def test_validation(client: int) -> None:
    for kwargs, match in [
        (dict(n_rays=0), "n_rays"),
        (dict(n_rays=2.5), "n_rays"),
        (dict(n_rays=True), "n_rays"),
        (dict(n_rays="many"), "n_rays"),
        (dict(fov_deg=0.0), "fov_deg"),
        (dict(fov_deg=400.0), "fov_deg"),
        (dict(max_range=-1.0), "max_range"),
        (dict(max_range=math.inf), "max_range"),
        (dict(min_range=-0.1), "min_range"),
        (dict(min_range=2.0, max_range=1.0), "min_range"),
        (dict(noise_std=-0.1), "noise_std"),
        (dict(height=math.nan), "height"),
        (dict(mount_x=math.inf), "mount_x"),
    ]:
        with pytest.raises(ValueError, match=match):
            Lidar2D(**kwargs)
    lidar = Lidar2D(n_rays=8)
    with pytest.raises(ValueError, match=r"shape \(3,\)"):
        lidar.scan(client, (0.0, 0.0))
    with pytest.raises(ValueError, match="finite"):
        lidar.scan(client, (0.0, math.inf, 0.0))
    with pytest.raises(ValueError, match="not connected"):
        lidar.scan(client + 1000, (0.0, 0.0, 0.0))
    with pytest.raises(ValueError, match="Generator"):
        lidar.scan(client, (0.0, 0.0, 0.0), rng=np.random.RandomState(0))


# -------------------------------------------------------------------------------------- navzoo env
@pytest.fixture(scope="module")
def lobby():
    env = navzoo.make("navzoo/Lobby-v0", raw=True, n_robots=2)
    # Robot 0 at (9, 6) facing +x, robot 1 1.5 m to its left, person 0 2.5 m ahead, the others away.
    starts = np.array([[11.5, 6.0], [15.0, 3.0]] + [[x, 12.0] for x in range(5, 15)], dtype=float)
    env.reset(
        seed=0,
        options=dict(
            robot_starts=[[9.0, 6.0], [9.0, 7.5]],
            robot_goals=[[18.0, 9.0], [2.0, 9.0]],
            robot_yaws=[0.0, 0.0],
            human_starts=starts,
            human_goals=starts + [1.0, 0.0],
        ),
    )
    yield env
    env.close()


def test_env_lidar_sees_people_robots_and_walls(lobby) -> None:
    env = lobby
    lidar = Lidar2D(max_range=12.0)
    scan = render_robot_lidar(env, 0, lidar)
    me, other = env.robots.ids
    person = env.humans.ids[0]
    assert me not in scan.hit_body
    # The other robot, 1.5 m to the left (its 0.3 m radius cylinder): 1.2 m at +90 degrees.
    left = np.argmin(np.abs(scan.angles - math.pi / 2))
    assert scan.hit_body[left] == other and scan.ranges[left] == pytest.approx(1.2, abs=1e-3)
    # The kinematic person straight ahead is hit (legs at 0.3 m), about 2.5 m away.
    on_person = scan.hit_body == person
    assert on_person.any()
    assert (np.abs(scan.angles[on_person]) < 0.2).all()
    assert (np.abs(scan.ranges[on_person] - 2.5) < 0.4).all()
    assert set(scan.hit_body.tolist()) & set(env.bodies.obstacle_ids)
    # PyBullet's own ray test misses the kinematic people (their mask excludes the ray's group) ...
    pose = (env.pos[0, 0], env.pos[0, 1], env.yaw[0])
    plain = lidar.scan(env.client, pose)
    assert not set(plain.hit_body.tolist()) & set(env.humans.ids)
    # ... also right after a lidar scan (their collision filters were put back).
    assert np.array_equal(lidar.scan(env.client, pose).hit_body, plain.hit_body)
    with ray_visible(env.client, {person: (GROUP_HUMAN, GROUP_ROBOT)}):
        assert person in lidar.scan(env.client, pose).hit_body
    assert person not in lidar.scan(env.client, pose).hit_body
    # Robot 1's own scan sees robot 0 at -90 degrees.
    scan1 = render_robot_lidar(env, 1, lidar)
    right = np.argmin(np.abs(scan1.angles + math.pi / 2))
    assert scan1.hit_body[right] == me and other not in scan1.hit_body
    with pytest.raises(ValueError, match="robot_index"):
        render_robot_lidar(env, 2)
    with pytest.raises(TypeError, match="Lidar2D"):
        render_robot_lidar(env, 0, lidar=object())


def test_env_scans_do_not_change_the_simulation() -> None:
    def rollout(scan: bool) -> np.ndarray:
        env = navzoo.make("navzoo/Lobby-v0", raw=True, n_robots=2)
        env.reset(seed=1)
        rng = np.random.default_rng(0)
        traj = []
        for _ in range(15):
            if scan:
                render_robot_lidar(env, 0)
                render_robot_lidar(env, 1)
            actions = {
                a: rng.uniform(-1, 1, env.action_space(a).shape).astype(np.float32) for a in env.agents
            }
            env.step(actions)
            traj.append(env.pos.copy())
            if not env.agents:
                break
        env.close()
        return np.array(traj)

    assert np.array_equal(rollout(False), rollout(True))
