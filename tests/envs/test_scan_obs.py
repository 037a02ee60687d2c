"""The planar range scan: exact ray casting on hand-made geometry, its config, and the ``"scan"`` observation."""

from __future__ import annotations

import math

import numpy as np
import pytest
from gymnasium import spaces

import navzoo
from navzoo.agents.transformer import flat_layout
from navzoo.envs.config import NavConfig
from navzoo.world.geometry import min_distance_to_segments, ray_segment_distances, segments_intersect

# ---------------------------------------------------------------------------------------------------------
# ray_segment_distances
# ---------------------------------------------------------------------------------------------------------

WALL_X2 = [[2.0, -1.0], [2.0, 1.0]]  # a wall perpendicular to +x, 2 m ahead of the origin


def test_ray_hits_perpendicular_wall_at_its_distance():
    d = ray_segment_distances([[0.0, 0.0]], [0.0], [WALL_X2], 5.0)
    assert d.shape == (1, 1)
    assert d[0, 0] == pytest.approx(2.0, abs=1e-12)
    # An oblique ray to the same wall (it meets it at y = 2 tan 25 deg = 0.93, within the wall).
    d = ray_segment_distances([[0.0, 0.0]], [math.radians(25.0)], [WALL_X2], 5.0)
    assert d[0, 0] == pytest.approx(2.0 / math.cos(math.radians(25.0)), abs=1e-12)
    # The ray through the wall's end point hits it (closed segment).
    d = ray_segment_distances([[0.0, 0.0]], [math.atan2(1.0, 2.0)], [WALL_X2], 5.0)
    assert d[0, 0] == pytest.approx(math.hypot(2.0, 1.0), abs=1e-9)


def test_ray_that_misses_reads_max_range():
    # Backwards, sideways, past the wall's end, and a wall beyond the range.
    ang = [math.pi, math.pi / 2, -math.pi / 2, math.radians(40.0)]
    d = ray_segment_distances([[0.0, 0.0]], ang, [WALL_X2], 5.0)
    np.testing.assert_array_equal(d, [[5.0, 5.0, 5.0, 5.0]])
    d = ray_segment_distances([[0.0, 0.0]], [0.0], [WALL_X2], 1.5)
    np.testing.assert_array_equal(d, [[1.5]])
    # No segments at all.
    d = ray_segment_distances([[0.0, 0.0], [1.0, 1.0]], [0.0, 1.0, 2.0], np.zeros((0, 2, 2)), 3.0)
    np.testing.assert_array_equal(d, np.full((2, 3), 3.0))


def test_ray_parallel_to_segment_misses_it():
    seg = [[[0.0, 1.0], [3.0, 1.0]]]  # parallel to the +x ray, 1 m to its left
    d = ray_segment_distances([[0.0, 0.0]], [0.0, math.pi], seg, 4.0)
    np.testing.assert_array_equal(d, [[4.0, 4.0]])
    # Turned towards it, the same ray hits it at 1 m.
    d = ray_segment_distances([[0.0, 0.0]], [math.pi / 2], seg, 4.0)
    assert d[0, 0] == pytest.approx(1.0, abs=1e-12)


def test_first_segment_along_the_ray_wins_and_segments_behind_do_not_count():
    segs = [[[3.0, -1.0], [3.0, 1.0]], WALL_X2, [[-1.0, -1.0], [-1.0, 1.0]]]
    d = ray_segment_distances([[0.0, 0.0]], [0.0, math.pi], segs, 10.0)
    np.testing.assert_allclose(d, [[2.0, 1.0]], atol=1e-12)
    # An origin on a segment reads 0 along a ray crossing it.
    d = ray_segment_distances([[2.0, 0.0]], [0.0, math.pi], [WALL_X2], 10.0)
    np.testing.assert_allclose(d, [[0.0, 0.0]], atol=1e-12)


def test_per_agent_angles():
    # A vertical wall x = 2 and a horizontal wall y = 3, both long.
    segs = [[[2.0, -10.0], [2.0, 10.0]], [[-10.0, 3.0], [10.0, 3.0]]]
    origins = [[0.0, 0.0], [5.0, 0.0]]
    ang = [[0.0, math.pi / 2], [math.pi, -math.pi / 2]]
    d = ray_segment_distances(origins, ang, segs, 8.0)
    assert d.shape == (2, 2)
    np.testing.assert_allclose(d, [[2.0, 3.0], [3.0, 8.0]], atol=1e-12)
    # Shared (R,) angles equal the same angles given per agent.
    shared = np.array([0.3, 1.2, -2.0])
    np.testing.assert_array_equal(ray_segment_distances(origins, shared, segs, 8.0),
                                  ray_segment_distances(origins, np.tile(shared, (2, 1)), segs, 8.0))


def test_random_rays_stop_exactly_at_the_first_crossing():
    rng = np.random.default_rng(0)
    segs = rng.uniform(-5, 5, size=(12, 2, 2))
    origins = rng.uniform(-4, 4, size=(6, 2))
    ang = rng.uniform(-np.pi, np.pi, size=(6, 20))
    d = ray_segment_distances(origins, ang, segs, 6.0)
    assert d.shape == (6, 20) and (d >= 0).all() and (d <= 6.0).all()
    hits = 0
    for n in range(6):
        for r in range(20):
            u = np.array([np.cos(ang[n, r]), np.sin(ang[n, r])])
            short = np.stack([origins[n], origins[n] + (d[n, r] - 1e-6) * u])
            assert not segments_intersect(short, segs).any()  # nothing before the reading
            if d[n, r] < 6.0:
                hits += 1
                end = origins[n] + d[n, r] * u
                assert min_distance_to_segments(end, segs)[0] < 1e-9  # the reading is on a segment
            else:
                long = np.stack([origins[n], origins[n] + 6.0 * u])
                assert not segments_intersect(long, segs).any()
    assert hits > 20  # the check is not vacuous


@pytest.mark.parametrize("angles", [np.zeros((3, 4)), np.zeros((2, 3, 4)), np.zeros(())])
def test_bad_angle_shapes_are_rejected(angles):
    with pytest.raises(ValueError, match="angles"):
        ray_segment_distances(np.zeros((2, 2)), angles, [WALL_X2], 4.0)


@pytest.mark.parametrize("max_range", [0.0, -1.0, float("nan"), float("inf")])
def test_bad_max_range_is_rejected(max_range):
    with pytest.raises(ValueError, match="max_range"):
        ray_segment_distances([[0.0, 0.0]], [0.0], [WALL_X2], max_range)


def test_bad_origins_and_segments_are_rejected():
    with pytest.raises(ValueError):
        ray_segment_distances(np.zeros((2, 3)), [0.0], [WALL_X2], 4.0)
    with pytest.raises(ValueError):
        ray_segment_distances([[0.0, 0.0]], [0.0], np.zeros((2, 3, 2)), 4.0)


# ---------------------------------------------------------------------------------------------------------
# NavConfig
# ---------------------------------------------------------------------------------------------------------


def test_config_defaults_and_valid_values():
    assert NavConfig().scan_rays == 0 and NavConfig().scan_range == 4.0
    cfg = NavConfig(scan_rays=8, scan_range=2.5)
    assert (cfg.scan_rays, cfg.scan_range) == (8, 2.5)
    assert NavConfig(scan_range=3).scan_range == 3


@pytest.mark.parametrize("value", [-1, 2.5, True, "8", None])
def test_config_rejects_bad_scan_rays(value):
    with pytest.raises(ValueError, match="scan_rays"):
        NavConfig(scan_rays=value)


@pytest.mark.parametrize("value", [0, 0.0, -2.0, float("nan"), float("inf"), True, "4"])
def test_config_rejects_bad_scan_range(value):
    with pytest.raises(ValueError, match="scan_range"):
        NavConfig(scan_range=value)


def test_make_rejects_bad_scan_options():
    with pytest.raises(ValueError, match="scan_rays"):
        navzoo.make("navzoo/CircleCrossing-v0", scan_rays=-3)
    with pytest.raises(ValueError, match="scan_range"):
        navzoo.make("navzoo/CircleCrossing-v0", scan_rays=8, scan_range=float("nan"))


# ---------------------------------------------------------------------------------------------------------
# The "scan" observation
# ---------------------------------------------------------------------------------------------------------


def test_no_scan_by_default():
    env = navzoo.make("navzoo/Home-v0", n_humans=1)
    obs, _ = env.reset(seed=0)
    assert "scan" not in env.observation_space("robot_0").spaces
    assert "scan" not in obs["robot_0"]
    with pytest.raises(ValueError, match="rays"):
        env.unwrapped.range_scan([0])  # no scan configured and no ray count given
    env.close()


def test_scan_space_and_observation():
    env = navzoo.make("navzoo/Home-v0", scan_rays=36, n_robots=2, n_humans=2)
    nav = env.unwrapped
    space = env.observation_space("robot_0")
    box = space["scan"]
    assert box.shape == (36,) and box.dtype == np.float32
    assert (box.low == 0).all() and (box.high == 1).all()
    obs, _ = env.reset(seed=1)
    rng = np.random.default_rng(0)
    for _ in range(4):
        for a in ("robot_0", "robot_1"):
            s = obs[a]["scan"]
            assert s.shape == (36,) and s.dtype == np.float32
            assert (s >= 0).all() and (s <= 1).all() and s.min() < 1.0  # a home has walls within 4 m
            assert space.contains(obs[a])
            # The observation is the current state's scan (not a stale one), ray i at yaw + 2 pi i / R.
            i = nav.agent_index(a)
            ang = nav.yaw[i] + 2 * np.pi * np.arange(36) / 36
            ref = ray_segment_distances(nav.pos[i], ang[None], nav.segments, 4.0)[0] / 4.0
            np.testing.assert_allclose(s, ref, atol=1e-6)
            np.testing.assert_array_equal(s, nav.range_scan([i])[0])
        assert not np.array_equal(obs["robot_0"]["scan"], obs["robot_1"]["scan"])
        acts = {a: rng.uniform(-1, 1, 2).astype(np.float32) for a in obs}
        obs, *_ = env.step(acts)
        assert "robot_0" in obs and "robot_1" in obs
    env.close()


def test_kinematic_pedestrians_get_the_scan_too():
    env = navzoo.make("navzoo/Home-v0", raw=True, scan_rays=12, n_humans=2)
    obs, _ = env.reset(seed=0)
    for a in ("human_0", "human_1"):
        assert env.observation_space(a)["scan"].shape == (12,)
        s = obs[a]["scan"]
        assert s.shape == (12,) and s.dtype == np.float32
        np.testing.assert_array_equal(s, env.range_scan([env.agent_index(a)])[0])
    env.close()


def test_scan_directions_in_an_open_square():
    # CircleCrossing: no obstacles, only the bounds [-10, 10]^2. Ray 0 points along the heading, ray R/4
    # to the left (counter-clockwise), and each reads the distance to the square's edge.
    env = navzoo.make("navzoo/CircleCrossing-v0", scan_rays=8, scan_range=30.0, n_humans=1)
    obs, _ = env.reset(seed=0)
    nav = env.unwrapped
    (x, y), yaw = nav.pos[0], nav.yaw[0]
    expected = []
    for i in range(8):
        c, s = math.cos(yaw + 2 * math.pi * i / 8), math.sin(yaw + 2 * math.pi * i / 8)
        ts = [(10 - x) / c if c > 1e-12 else (-10 - x) / c if c < -1e-12 else math.inf,
              (10 - y) / s if s > 1e-12 else (-10 - y) / s if s < -1e-12 else math.inf]
        expected.append(min(ts) / 30.0)
    np.testing.assert_allclose(obs["robot_0"]["scan"], expected, atol=1e-6)
    env.close()


@pytest.mark.parametrize("env_id", ["navzoo/Home-v0", "navzoo/Grocery-v0"])
def test_min_over_many_rays_is_the_clearance(env_id):
    rays, rng_m = 360, 4.0
    env = navzoo.make(env_id, raw=True, scan_rays=rays, scan_range=rng_m)
    obs, _ = env.reset(seed=2)
    rng = np.random.default_rng(1)
    near = 0
    for _ in range(3):
        clear = min_distance_to_segments(env.pos, env.segments)
        for a, o in obs.items():
            i = env.agent_index(a)
            scan_min = float(o["scan"].min()) * rng_m
            if clear[i] < rng_m:
                near += 1
                assert scan_min >= clear[i] - 1e-5  # no ray reads closer than the nearest edge
                assert scan_min == pytest.approx(clear[i], abs=0.02)
            else:
                assert (o["scan"] == 1.0).all()
        obs, *_ = env.step({a: rng.uniform(-1, 1, env.action_space(a).shape).astype(np.float32) for a in obs})
    assert near >= 5
    env.close()


def test_flat_observation_holds_the_scan():
    r = 10
    plain = navzoo.make("navzoo/Home-v0", flat_obs=True, n_humans=2)
    flat = navzoo.make("navzoo/Home-v0", flat_obs=True, scan_rays=r, n_humans=2)
    dict_env = navzoo.make("navzoo/Home-v0", scan_rays=r, n_humans=2)
    n0 = plain.observation_space("robot_0").shape[0]
    assert flat.observation_space("robot_0").shape == (n0 + r,)
    o_plain, _ = plain.reset(seed=3)
    o_flat, _ = flat.reset(seed=3)
    o_dict, _ = dict_env.reset(seed=3)
    f = o_flat["robot_0"]
    assert f.shape == (n0 + r,) and f.dtype == np.float32
    cfg = flat.unwrapped.config
    lay = flat_layout(cfg.k_neighbors, cfg.history, cfg.map_cells, r)
    s, e, _ = lay["scan"]
    np.testing.assert_array_equal(f[s:e], o_dict["robot_0"]["scan"])
    # Gymnasium's own flattening of the Dict observation, and the scan-less one with the scan cut out.
    np.testing.assert_array_equal(f, spaces.flatten(dict_env.observation_space("robot_0"), o_dict["robot_0"]))
    np.testing.assert_array_equal(np.concatenate([f[:s], f[e:]]), o_plain["robot_0"])
    for env in (plain, flat, dict_env):
        env.close()


def test_scan_does_not_change_the_dynamics():
    def rollout(**kw):
        env = navzoo.make("navzoo/Home-v0", n_humans=3, **kw)
        obs, _ = env.reset(seed=4)
        nav = env.unwrapped
        states, rewards = [], []
        for t in range(8):
            act = np.array([0.6, 0.4 * math.sin(t)], dtype=np.float32)
            obs, rew, term, trunc, _ = env.step({a: act for a in obs})
            states.append(np.concatenate([nav.pos.ravel(), nav.yaw.ravel()]))
            rewards.append(rew.get("robot_0"))
            if not obs:
                break
        env.close()
        return np.array(states), rewards

    s0, r0 = rollout()
    s1, r1 = rollout(scan_rays=24)
    s2, r2 = rollout(scan_rays=7, scan_range=1.0, flat_obs=True)
    assert len(s0) >= 3
    np.testing.assert_array_equal(s0, s1)
    np.testing.assert_array_equal(s0, s2)
    assert r0 == r1 == r2
