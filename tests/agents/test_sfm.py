"""Property tests of the social force model (navzoo.agents.sfm)."""

from __future__ import annotations

import numpy as np
import pytest

from navzoo.agents.sfm import SocialForceParams, social_force_velocities, social_forces

PARAMS = SocialForceParams()


def _pref_towards(pos: np.ndarray, goal: np.ndarray, speed: float, dt: float) -> np.ndarray:
    """Preferred velocity towards the goal, slowing down so as not to overshoot it."""
    delta = goal - pos
    dist = np.linalg.norm(delta, axis=1, keepdims=True)
    return np.where(dist > 1e-9, delta / np.maximum(dist, 1e-9) * np.minimum(speed, dist / dt), 0.0)


def _point_segment_dist(p: np.ndarray, a: np.ndarray, b: np.ndarray) -> float:
    ab = b - a
    t = np.clip(np.dot(p - a, ab) / np.dot(ab, ab), 0.0, 1.0)
    return float(np.linalg.norm(p - (a + t * ab)))


def test_params_validation_names_the_field() -> None:
    with pytest.raises(ValueError, match="tau"):
        SocialForceParams(tau=0.0)
    with pytest.raises(ValueError, match="lambda_"):
        SocialForceParams(lambda_=1.5)
    with pytest.raises(ValueError, match="A_wall"):
        SocialForceParams(A_wall=-1.0)
    with pytest.raises(ValueError, match="max_accel"):
        SocialForceParams(max_accel=float("nan"))
    with pytest.raises(ValueError, match="max_substep"):
        SocialForceParams(max_substep=0.0)


def test_input_validation() -> None:
    pos = np.zeros((2, 2))
    with pytest.raises(ValueError, match="vel"):
        social_force_velocities(pos, np.zeros((3, 2)), np.zeros((2, 2)), 0.3, 1.0, 0.1, PARAMS)
    with pytest.raises(ValueError, match="segments"):
        social_force_velocities(pos, pos, pos, 0.3, 1.0, 0.1, PARAMS, np.zeros((3, 2)))
    with pytest.raises(ValueError, match="dt"):
        social_force_velocities(pos, pos, pos, 0.3, 1.0, 0.0, PARAMS)


def test_free_walker_converges_to_preferred_velocity() -> None:
    pos, vel = np.zeros((1, 2)), np.zeros((1, 2))
    pref = np.array([[1.0, 0.5]])
    for _ in range(60):
        vel = social_force_velocities(pos, vel, pref, 0.3, 2.0, 0.1, PARAMS, np.zeros((0, 2, 2)))
        pos = pos + 0.1 * vel
    np.testing.assert_allclose(vel, pref, atol=1e-4)


def test_speed_never_exceeds_max_speed() -> None:
    rng = np.random.default_rng(0)
    n = 30
    pos = rng.uniform(-3.0, 3.0, (n, 2))
    vel = rng.uniform(-1.0, 1.0, (n, 2))
    max_speed = rng.uniform(0.5, 1.5, n)
    segments = np.array([[[-4.0, -4.0], [4.0, -4.0]], [[-4.0, 4.0], [4.0, 4.0]]])
    robots = np.array([[0.0, 0.0], [1.0, 1.0]])
    for _ in range(40):
        pref = rng.uniform(-3.0, 3.0, (n, 2))  # deliberately above max_speed
        vel = social_force_velocities(
            pos, vel, pref, 0.3, max_speed, 0.1, PARAMS, segments, robots, np.ones((2, 2)), 0.3
        )
        assert np.all(np.linalg.norm(vel, axis=1) <= max_speed + 1e-12)
        pos = pos + 0.1 * vel


@pytest.mark.parametrize("dt", [0.1, 0.25])  # 0.25 s is integrated in sub-steps
def test_head_on_swap_reaches_goals_without_overlap(dt: float) -> None:
    radius, speed = 0.3, 1.2
    pos = np.array([[-4.0, 0.0], [4.0, 0.0]])
    goal = pos[::-1].copy()
    vel = np.zeros((2, 2))
    arrived = np.zeros(2, dtype=bool)
    for _ in range(int(20.0 / dt)):
        pref = _pref_towards(pos, goal, speed, dt)
        vel = social_force_velocities(pos, vel, pref, radius, 1.3 * speed, dt, PARAMS, None)
        pos = pos + dt * vel
        assert np.linalg.norm(pos[0] - pos[1]) >= 2 * radius
        arrived |= np.linalg.norm(pos - goal, axis=1) < 0.1
    assert arrived.all()


@pytest.mark.parametrize("goal_x, speed", [(0.0, 1.2), (1.5, 1.2), (0.0, 2.0)])
def test_wall_is_not_penetrated(goal_x: float, speed: float) -> None:
    dt, radius = 0.1, 0.3
    a, b = np.array([-2.0, 2.0]), np.array([2.0, 2.0])
    segments = np.array([[a, b]])
    pos = np.array([[0.0, 0.0]])
    goal = np.array([[goal_x, 5.0]])  # behind the wall
    vel = np.zeros((1, 2))
    for _ in range(100):
        pref = _pref_towards(pos, goal, speed, dt)
        vel = social_force_velocities(pos, vel, pref, radius, speed, dt, PARAMS, segments)
        pos = pos + dt * vel
        assert pos[0, 1] < 2.0
        assert _point_segment_dist(pos[0], a, b) >= radius


def test_robot_pushes_people_away() -> None:
    pos = np.array([[0.0, 0.0]])
    still = np.zeros((1, 2))
    robot = np.array([[0.8, 0.0]])
    forces = social_forces(pos, still, still, 0.3, PARAMS, None, robot, np.zeros((1, 2)), 0.3)
    assert forces.robots[0, 0] < 0.0
    np.testing.assert_array_equal(forces.people, 0.0)
    vel = social_force_velocities(pos, still, still, 0.3, 1.5, 0.1, PARAMS, None, robot, None, 0.3)
    assert vel[0, 0] < 0.0
    # Without robots in the call, nothing moves a person who wants to stand still.
    np.testing.assert_array_equal(social_force_velocities(pos, still, still, 0.3, 1.5, 0.1, PARAMS), 0.0)
    # A robot coming from behind still pushes, but less than one ahead (anisotropy).
    walking = np.array([[0.5, 0.0]])
    ahead = social_forces(pos, walking, walking, 0.3, PARAMS, None, robot, None, 0.3).robots
    behind = social_forces(pos, walking, walking, 0.3, PARAMS, None, -robot, None, 0.3).robots
    assert 0.0 < behind[0, 0] < -ahead[0, 0]


def test_force_components() -> None:
    rng = np.random.default_rng(1)
    n = 6
    pos = rng.uniform(-2.0, 2.0, (n, 2))
    vel = rng.uniform(-1.0, 1.0, (n, 2))
    pref = rng.uniform(-1.0, 1.0, (n, 2))
    segments = np.array([[[-3.0, -3.0], [3.0, -3.0]]])
    f = social_forces(pos, vel, pref, 0.3, PARAMS, segments)
    np.testing.assert_allclose(f.goal, (pref - vel) / PARAMS.tau)
    np.testing.assert_array_equal(f.robots, 0.0)
    assert np.all(f.walls[:, 1] > 0.0)  # the wall below pushes up
    np.testing.assert_allclose(f.total, f.goal + f.people + f.robots + f.walls)
    # Pairwise repulsion between two people is symmetric when both stand still.
    two = social_forces(np.array([[0.0, 0.0], [0.9, 0.0]]), np.zeros((2, 2)), np.zeros((2, 2)), 0.3, PARAMS)
    np.testing.assert_allclose(two.people[0], -two.people[1])
    assert two.people[0, 0] < 0.0


def test_deterministic_and_inputs_untouched() -> None:
    rng = np.random.default_rng(2)
    n = 20
    args = (
        rng.uniform(-4.0, 4.0, (n, 2)),
        rng.uniform(-1.0, 1.0, (n, 2)),
        rng.uniform(-1.0, 1.0, (n, 2)),
        np.full(n, 0.3),
        np.full(n, 1.5),
        0.1,
        PARAMS,
        np.array([[[-5.0, 0.0], [5.0, 0.0]]]),
        rng.uniform(-4.0, 4.0, (2, 2)),
        rng.uniform(-1.0, 1.0, (2, 2)),
        np.full(2, 0.3),
    )
    copies = [np.copy(a) if isinstance(a, np.ndarray) else a for a in args]
    first = social_force_velocities(*args)
    second = social_force_velocities(*args)
    np.testing.assert_array_equal(first, second)
    for before, after in zip(copies, args, strict=True):
        if isinstance(before, np.ndarray):
            np.testing.assert_array_equal(before, after)


def test_each_obstacle_pushes_once_from_its_nearest_point() -> None:
    from navzoo.world.geometry import circle_polygon, min_distance_to_segments, polygon_edges

    # A column as a 24-gon: with its edges grouped as one wall, the push equals that of a single
    # wall point at the same distance; summed over edges it would be several times larger.
    column = polygon_edges(circle_polygon([0.0, 0.0], 0.4, 24))
    pos = np.array([[0.0, -1.0]])
    zero = np.zeros((1, 2))
    grouped = social_forces(pos, zero, zero, 0.3, PARAMS, column, segment_groups=np.zeros(len(column), int)).walls
    per_edge = social_forces(pos, zero, zero, 0.3, PARAMS, column).walls
    d = float(min_distance_to_segments(pos, column)[0])
    expected = PARAMS.A_wall / PARAMS.B_wall * np.exp(-(d - 0.3) / PARAMS.B_wall)
    np.testing.assert_allclose(grouped[0], [0.0, -expected], rtol=1e-6, atol=1e-9)
    assert np.linalg.norm(per_edge) > 2 * np.linalg.norm(grouped)


def test_keep_apart_is_checked() -> None:
    with pytest.raises(ValueError, match="keep_apart"):
        SocialForceParams(keep_apart=-0.1)
    with pytest.raises(ValueError, match="keep_range"):
        SocialForceParams(keep_range=0.0)


def test_keep_apart_leaves_the_social_repulsion_and_holds_the_room() -> None:
    radius, dt = 0.3, 0.1
    keep = SocialForceParams(keep_apart=0.1)
    # at 2 m the push is nil: the same forces as the bare radii, about half those of radii widened by 0.1 m
    pos, vel = np.array([[-1.0, 0.0], [1.0, 0.0]]), np.array([[1.0, 0.0], [-1.0, 0.0]])
    bare = social_forces(pos, vel, vel, radius, PARAMS).people
    np.testing.assert_allclose(social_forces(pos, vel, vel, radius, keep).people, bare, atol=1e-9)
    wide = social_forces(pos, vel, vel, radius + 0.1, PARAMS).people
    np.testing.assert_allclose(np.linalg.norm(wide, axis=1) / np.linalg.norm(bare, axis=1), np.exp(0.2 / 0.3), rtol=1e-6)
    # two people pulled at one point (2 m/s): on bare radii they end up within 2 x 0.1 m of touching;
    # the push holds that room
    closest = {}
    for name, params in (("bare", PARAMS), ("keep", keep)):
        pos, goal, vel = np.array([[-2.0, 0.0], [2.0, 0.0]]), np.zeros((2, 2)), np.zeros((2, 2))
        closest[name] = np.inf
        for _ in range(100):
            vel = social_force_velocities(pos, vel, _pref_towards(pos, goal, 2.0, dt), radius, 2.0, dt, params, None)
            pos = pos + dt * vel
            closest[name] = min(closest[name], float(np.linalg.norm(pos[0] - pos[1])))
    assert closest["bare"] < 2 * radius + 2 * 0.1 <= closest["keep"]


def test_pass_margin_is_checked() -> None:
    with pytest.raises(ValueError, match="pass_margin"):
        SocialForceParams(pass_margin=-0.1)
    with pytest.raises(ValueError, match="pass_speed"):
        SocialForceParams(pass_speed=0.0)


def test_pass_margin_keeps_room_from_people_passed_not_from_people_walked_with() -> None:
    radius = 0.3
    passing = SocialForceParams(pass_margin=0.1, pass_speed=1.0)
    # walking together, one behind the other and side by side at one velocity: the bare radii's forces
    pos = np.array([[0.0, 0.0], [0.8, 0.0], [0.0, 0.7]])
    vel = np.tile([1.2, 0.0], (3, 1))
    np.testing.assert_allclose(social_forces(pos, vel, vel, radius, passing).people,
                               social_forces(pos, vel, vel, radius, PARAMS).people, atol=1e-12)
    # meeting head-on at 2 m/s relative speed (above pass_speed): the forces of radii widened by the margin
    pos, vel = np.array([[-1.0, 0.1], [1.0, -0.1]]), np.array([[1.0, 0.0], [-1.0, 0.0]])
    np.testing.assert_allclose(social_forces(pos, vel, vel, radius, passing).people,
                               social_forces(pos, vel, vel, radius + 0.1, PARAMS).people, rtol=1e-9)
    # overtaking at 0.5 m/s: half the margin, so a repulsion between the bare and the widened radii's
    pos, vel = np.array([[0.0, 0.0], [1.0, 0.0]]), np.array([[1.2, 0.0], [0.7, 0.0]])
    f = [np.linalg.norm(social_forces(pos, vel, vel, r, prm).people[0])
         for r, prm in ((radius, PARAMS), (radius, passing), (radius + 0.05, PARAMS), (radius + 0.1, PARAMS))]
    assert f[0] < f[1] < f[3]
    np.testing.assert_allclose(f[1], f[2], rtol=1e-9)


def test_walls_near_another_person_use_their_own_strength() -> None:
    """``wall_near_range``: a person with another within range feels walls with ``A_wall_near``; one alone with
    ``A_wall``; off (0) by default."""
    from navzoo.agents.sfm import SocialForceParams, social_forces

    wall = np.array([[[-5.0, 0.0], [5.0, 0.0]]])  # a wall along y = 0
    pos = np.array([[0.0, 0.35], [0.8, 0.35], [4.0, 0.35]])  # two people 0.8 m apart, one alone, all 0.35 m off
    vel = np.zeros((3, 2))
    kw = dict(pos=pos, vel=vel, pref_vel=vel, radius=0.25, segments=wall)
    full = social_forces(params=SocialForceParams(), **kw).walls
    soft = social_forces(params=SocialForceParams(wall_near_range=1.5, A_wall_near=0.3), **kw).walls
    np.testing.assert_allclose(soft[:2], 0.3 * full[:2])  # the pair: softer
    np.testing.assert_allclose(soft[2], full[2])  # alone: the full wall
    assert full[0, 1] > 0  # pushed off the wall
    np.testing.assert_allclose(social_forces(params=SocialForceParams(A_wall_near=0.3), **kw).walls, full)  # off
    with pytest.raises(ValueError, match="wall_near_range"):
        SocialForceParams(wall_near_range=-1.0)


def test_walls_near_another_person_can_phase_in() -> None:
    """``wall_near_ramp``: the softer walls blend in linearly between ``wall_near_range + wall_near_ramp`` and
    ``wall_near_range`` of the nearest other person, instead of switching at ``wall_near_range``."""
    from navzoo.agents.sfm import SocialForceParams, social_forces

    wall = np.array([[[-10.0, 0.0], [10.0, 0.0]]])
    # nearest others at 1.0 m (within range), 2.0 m (half the ramp beyond 1.5 m) and far away
    pos = np.array([[0.0, 0.35], [1.0, 0.35], [3.0, 0.35], [9.0, 0.35]])
    vel = np.zeros((4, 2))
    kw = dict(pos=pos, vel=vel, pref_vel=vel, radius=0.25, segments=wall)
    full = social_forces(params=SocialForceParams(), **kw).walls
    ramp = social_forces(params=SocialForceParams(wall_near_range=1.5, A_wall_near=0.3, wall_near_ramp=1.0), **kw).walls
    np.testing.assert_allclose(ramp[:2], 0.3 * full[:2])  # within range: the softer walls
    np.testing.assert_allclose(ramp[2], 0.65 * full[2])  # person 2 is 2.0 m from person 1: halfway, 0.3 + 0.5 * 0.7
    np.testing.assert_allclose(ramp[3], full[3])  # alone
    switch = social_forces(params=SocialForceParams(wall_near_range=1.5, A_wall_near=0.3), **kw).walls
    np.testing.assert_allclose(switch[2], full[2])  # without a ramp, 2.0 m is out of range
    # with no wall strength at all for people alone, the blend still gives the share of the softer walls
    zero = social_forces(params=SocialForceParams(A_wall=0.0, wall_near_range=1.5, A_wall_near=0.3,
                                                  wall_near_ramp=1.0), **kw).walls
    np.testing.assert_allclose(zero[2], 0.5 * 0.3 * full[2])
    np.testing.assert_allclose(zero[3], 0.0)
    with pytest.raises(ValueError, match="wall_near_ramp"):
        SocialForceParams(wall_near_ramp=-1.0)


def test_ignore_leaves_out_the_pairs_named_and_only_those() -> None:
    pos = np.array([[0.0, 0.0], [0.8, 0.0], [0.0, 0.8]])
    zeros = np.zeros((3, 2))
    full = social_forces(pos, zeros, zeros, 0.3, PARAMS)
    ignore = np.zeros((3, 3), dtype=bool)
    ignore[0, 1] = True  # person 0 does not feel person 1; person 1 still feels person 0
    part = social_forces(pos, zeros, zeros, 0.3, PARAMS, ignore=ignore)
    only_2 = social_forces(pos[[0, 2]], zeros[:2], zeros[:2], 0.3, PARAMS)
    np.testing.assert_allclose(part.people[0], only_2.people[0])
    np.testing.assert_allclose(part.people[1:], full.people[1:])
    assert np.linalg.norm(part.people[0] - full.people[0]) > 0.1
    np.testing.assert_allclose(social_forces(pos, zeros, zeros, 0.3, PARAMS, ignore=np.ones((3, 3), bool)).people, 0.0)
    # the velocities pass it on: person 0 walks on as if person 1 were not there
    pref = np.array([[1.0, 0.0], [0.0, 0.0], [0.0, 0.0]])
    v = social_force_velocities(pos[:2], zeros[:2], pref[:2], 0.3, 2.0, 0.1, PARAMS, ignore=ignore[:2, :2])
    alone = social_force_velocities(pos[:1], zeros[:1], pref[:1], 0.3, 2.0, 0.1, PARAMS)
    np.testing.assert_allclose(v[0], alone[0])
    with pytest.raises(ValueError, match="ignore"):
        social_forces(pos, zeros, zeros, 0.3, PARAMS, ignore=np.zeros((2, 2), dtype=bool))
    with pytest.raises(ValueError, match="ignore"):
        social_forces(pos, zeros, zeros, 0.3, PARAMS, ignore=np.zeros((3, 3)))
