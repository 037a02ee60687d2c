"""Property tests of ORCA (navzoo.agents.orca)."""

from __future__ import annotations

import numpy as np
import pytest

from navzoo.agents.orca import OrcaParams, orca_velocities

PARAMS = OrcaParams()


def _pref_towards(pos: np.ndarray, goal: np.ndarray, speed: float, dt: float) -> np.ndarray:
    delta = goal - pos
    dist = np.linalg.norm(delta, axis=1, keepdims=True)
    return np.where(dist > 1e-9, delta / np.maximum(dist, 1e-9) * np.minimum(speed, dist / dt), 0.0)


def _box(half: float) -> np.ndarray:
    c = [(-half, -half), (half, -half), (half, half), (-half, half)]
    return np.array([[c[i], c[(i + 1) % 4]] for i in range(4)], dtype=float)


def _min_gap(pos: np.ndarray, radius: np.ndarray) -> float:
    d = np.linalg.norm(pos[:, None] - pos[None], axis=2) - (radius[:, None] + radius[None])
    d[np.diag_indices(len(pos))] = np.inf
    return float(d.min())


def _simulate(
    pos: np.ndarray,
    goal: np.ndarray,
    *,
    dt: float,
    t_max: float,
    speed: float = 1.2,
    radius: float = 0.3,
    segments: np.ndarray | None = None,
    passive: np.ndarray | None = None,
    params: OrcaParams = PARAMS,
) -> tuple[float, np.ndarray, list[np.ndarray]]:
    """Run ORCA; returns (smallest gap over all steps, arrived mask, trajectory)."""
    n = len(pos)
    all_pos = pos.copy() if passive is None else np.vstack([pos, passive])
    vel = np.zeros_like(all_pos)
    radii = np.full(len(all_pos), radius)
    min_gap = np.inf
    arrived = np.zeros(n, dtype=bool)
    trajectory = []
    for _ in range(int(round(t_max / dt))):
        pref = _pref_towards(all_pos[:n], goal, speed, dt)
        new = orca_velocities(all_pos, vel, pref, radii, speed, dt, params, segments, n_active=n)
        assert new.shape == (n, 2)
        vel[:n] = new
        all_pos[:n] += dt * new
        min_gap = min(min_gap, _min_gap(all_pos, radii))
        arrived |= np.linalg.norm(all_pos[:n] - goal, axis=1) < 0.2
        trajectory.append(all_pos.copy())
    return min_gap, arrived, trajectory


def test_params_validation_names_the_field() -> None:
    with pytest.raises(ValueError, match="time_horizon"):
        OrcaParams(time_horizon=0.0)
    with pytest.raises(ValueError, match="max_neighbors"):
        OrcaParams(max_neighbors=-1)
    with pytest.raises(ValueError, match="max_neighbors"):
        OrcaParams(max_neighbors=2.5)  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="right_bias"):
        OrcaParams(right_bias=-0.1)


def test_input_validation() -> None:
    pos = np.zeros((3, 2))
    with pytest.raises(ValueError, match="n_active"):
        orca_velocities(pos, pos, pos, 0.3, 1.0, 0.1, PARAMS, n_active=4)
    with pytest.raises(ValueError, match="vel"):
        orca_velocities(pos, np.zeros((2, 2)), pos, 0.3, 1.0, 0.1, PARAMS)
    with pytest.raises(ValueError, match="dt"):
        orca_velocities(pos, pos, pos, 0.3, 1.0, -0.1, PARAMS)
    assert orca_velocities(pos, pos, pos, 0.3, 1.0, 0.1, PARAMS, n_active=0).shape == (0, 2)


def test_without_neighbours_new_velocity_is_clipped_preferred_velocity() -> None:
    pos = np.array([[0.0, 0.0], [20.0, 0.0]])  # beyond neighbor_dist of each other
    pref = np.array([[0.3, -0.4], [3.0, 4.0]])
    new = orca_velocities(pos, np.zeros((2, 2)), pref, 0.3, 1.0, 0.1, PARAMS, _box(30.0))
    np.testing.assert_allclose(new[0], pref[0], atol=1e-12)
    np.testing.assert_allclose(new[1], [0.6, 0.8], atol=1e-12)


def test_new_velocity_respects_max_speed() -> None:
    rng = np.random.default_rng(0)
    for _ in range(5):
        n = 40
        pos = rng.uniform(-6.0, 6.0, (n, 2))
        vel = rng.uniform(-1.5, 1.5, (n, 2))
        pref = rng.uniform(-3.0, 3.0, (n, 2))
        max_speed = rng.uniform(0.5, 1.5, n)
        new = orca_velocities(pos, vel, pref, 0.3, max_speed, 0.1, PARAMS, _box(7.0), n_active=30)
        assert new.shape == (30, 2)
        assert np.all(np.linalg.norm(new, axis=1) <= max_speed[:30] + 1e-12)


def test_head_on_swap_without_overlap() -> None:
    pos = np.array([[-4.0, 0.0], [4.0, 0.0]])
    min_gap, arrived, _ = _simulate(pos, pos[::-1].copy(), dt=0.1, t_max=20.0)
    assert min_gap >= -1e-3
    assert arrived.all()


def test_circle_of_twenty_swaps_antipodes_without_collisions() -> None:
    n = 20
    angle = np.linspace(0.0, 2.0 * np.pi, n, endpoint=False)
    start = 5.0 * np.stack([np.cos(angle), np.sin(angle)], axis=1)
    # An exactly C20-symmetric start is a fixed point of any deterministic rule (RVO2 jams
    # there too); +-1 cm of seeded jitter makes the scenario representative.
    start += np.random.default_rng(0).uniform(-0.01, 0.01, start.shape)
    min_gap, arrived, _ = _simulate(start, -start, dt=0.1, t_max=40.0, segments=_box(7.0))
    assert min_gap >= -1e-3
    assert arrived.mean() >= 0.9


def test_passive_robot_in_the_way_is_avoided() -> None:
    robot = np.array([[0.0, 0.0]])
    min_gap, arrived, trajectory = _simulate(
        np.array([[-4.0, 0.0]]), np.array([[4.0, 0.0]]), dt=0.1, t_max=20.0, passive=robot
    )
    assert arrived.all()
    assert min_gap >= -1e-3
    np.testing.assert_array_equal(trajectory[-1][1], robot[0])  # passive agents are not moved
    lateral = max(abs(p[0, 1]) for p in trajectory)
    assert lateral >= 0.55  # went around the robot (combined radius 0.6)


def test_passive_neighbour_gets_full_responsibility() -> None:
    # Two agents on a collision course: with an active neighbour each takes half of the
    # avoidance; with a passive one the active agent alone must leave the velocity obstacle.
    pos = np.array([[0.0, 0.0], [3.0, 0.2]])
    vel = np.array([[1.0, 0.0], [-1.0, 0.0]])
    params = OrcaParams(right_bias=0.0, one_step_safety=False)
    shared = orca_velocities(pos, vel, vel, 0.3, 1.5, 0.1, params, n_active=2)
    alone = orca_velocities(pos, vel, vel, 0.3, 1.5, 0.1, params, n_active=1)
    np.testing.assert_allclose(alone[0] - vel[0], 2.0 * (shared[0] - vel[0]), atol=1e-12)
    # The relative velocity with the passive agent is now collision-free for time_horizon.
    rel_pos, rel_vel = pos[1] - pos[0], alone[0] - vel[1]
    t = np.clip(rel_pos @ rel_vel / (rel_vel @ rel_vel), 0.0, params.time_horizon)
    assert np.linalg.norm(t * rel_vel - rel_pos) >= 0.6 - 1e-9


def test_wall_in_the_way_is_walked_around_not_through() -> None:
    a, b = np.array([0.0, -1.0]), np.array([0.0, 1.0])
    segments = np.array([[a, b]])
    _, arrived, trajectory = _simulate(
        np.array([[-3.0, 0.0]]), np.array([[3.0, 0.0]]), dt=0.1, t_max=20.0, segments=segments
    )
    assert arrived.all()
    for p in trajectory:
        t = np.clip(np.dot(p[0] - a, b - a) / np.dot(b - a, b - a), 0.0, 1.0)
        assert np.linalg.norm(p[0] - (a + t * (b - a))) >= 0.3 - 1e-3


def test_one_step_safety_prevents_new_overlaps_in_dense_crowds() -> None:
    rng = np.random.default_rng(3)
    dt, radius = 0.25, 0.3
    for _ in range(10):
        # Rejection-sample 30 non-overlapping agents in a 6 x 6 m square, all rushing inwards.
        pos = np.zeros((0, 2))
        while len(pos) < 30:
            p = rng.uniform(-3.0, 3.0, 2)
            if len(pos) == 0 or np.min(np.linalg.norm(pos - p, axis=1)) > 2 * radius:
                pos = np.vstack([pos, p])
        vel = -pos / np.linalg.norm(pos, axis=1, keepdims=True) * 1.2
        new = orca_velocities(pos, vel, vel, radius, 1.2, dt, PARAMS, n_active=25)
        after = pos.copy()
        after[:25] += dt * new
        after[25:] += dt * vel[25:]  # passive agents move as predicted
        d = np.linalg.norm(after[:25, None] - after[None], axis=2)
        d[np.arange(25), np.arange(25)] = np.inf
        # A passive agent that reaches an active one even if the latter stands still cannot
        # be avoided within one step; those pairs are exempt (the active agent still flees).
        still = pos.copy()
        still[25:] += dt * vel[25:]
        unavoidable = np.linalg.norm(still[:25, None] - still[None], axis=2) < 2 * radius
        unavoidable[:, :25] = False
        d[unavoidable] = np.inf
        assert d.min() >= 2 * radius - 1e-9


def test_deterministic_and_inputs_untouched() -> None:
    rng = np.random.default_rng(4)
    n = 25
    pos = rng.uniform(-6.0, 6.0, (n, 2))
    vel = rng.uniform(-1.0, 1.0, (n, 2))
    pref = rng.uniform(-1.5, 1.5, (n, 2))
    segments = _box(7.0)
    before = [a.copy() for a in (pos, vel, pref, segments)]
    first = orca_velocities(pos, vel, pref, 0.3, 1.2, 0.1, PARAMS, segments, n_active=20)
    second = orca_velocities(pos, vel, pref, 0.3, 1.2, 0.1, PARAMS, segments, n_active=20)
    np.testing.assert_array_equal(first, second)
    for b, a in zip(before, (pos, vel, pref, segments), strict=True):
        np.testing.assert_array_equal(a, b)
