"""Episode metrics on hand-made trajectories with known answers (navzoo.benchmark.metrics)."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from navzoo.benchmark import metrics as M


def line(start, end, n):
    """n + 1 evenly spaced points from start to end, (n+1, 2)."""
    return np.linspace(np.asarray(start, float), np.asarray(end, float), n + 1)


def still(p, n):
    return np.tile(np.asarray(p, float), (n + 1, 1))


# ---------------------------------------------------------------------------------------------------------
# Outcome
# ---------------------------------------------------------------------------------------------------------


def test_outcome_from_event():
    assert M.outcome_from_event("goal") == {
        "success": True,
        "collision": False,
        "human_collision": False,
        "obstacle_collision": False,
        "robot_collision": False,
        "timeout": False,
    }
    o = M.outcome_from_event("collision_human")
    assert o["collision"] and o["human_collision"] and not o["obstacle_collision"] and not o["success"]
    o = M.outcome_from_event("collision_obstacle")
    assert o["collision"] and o["obstacle_collision"] and not o["human_collision"]
    assert M.outcome_from_event("collision_robot")["robot_collision"]
    assert M.outcome_from_event("timeout")["timeout"]
    assert not any(M.outcome_from_event("nan_state").values())


def test_event_from_flags_collision_beats_goal():
    assert M.event_from_flags(reached=True) == "goal"
    assert M.event_from_flags(reached=True, human_collision=True) == "collision_human"
    assert (
        M.event_from_flags(reached=False, obstacle_collision=True, robot_collision=True)
        == "collision_obstacle"
    )
    assert M.event_from_flags(reached=False, timed_out=True) == "timeout"
    assert M.event_from_flags(reached=False) == "running"


def test_swept_collision_catches_tunnelling_through_a_standing_person():
    # One fast step from (-1, 0) to (1, 0); person at (0, 0.4), radii 0.3 + 0.2 = 0.5.
    rp = np.array([[-1.0, 0.0], [1.0, 0.0]])
    hp = np.array([[[0.0, 0.4]], [[0.0, 0.4]]])
    end_gaps = M.person_gaps(rp, hp, 0.3, 0.2)
    assert (end_gaps > 0.5).all()  # end positions are far apart
    assert M.swept_person_gaps(rp, hp, 0.3, 0.2)[0, 0] == pytest.approx(-0.1)
    assert M.swept_person_collisions(rp, hp, 0.3, 0.2).tolist() == [[True]]
    assert M.swept_person_collisions(rp, hp, 0.3, 0.2, tolerance=0.2).tolist() == [[False]]


def test_swept_collision_both_moving():
    # Robot (-1,0)->(1,0), person (1,0.4)->(-1,0.4): they cross; ends 2.04 m apart, closest 0.4 m (< 0.5).
    rp = np.array([[-1.0, 0.0], [1.0, 0.0]])
    hp = np.array([[[1.0, 0.4]], [[-1.0, 0.4]]])
    assert (M.person_gaps(rp, hp, 0.3, 0.2) > 1.5).all()
    assert M.swept_person_gaps(rp, hp, 0.3, 0.2)[0, 0] == pytest.approx(0.4 - 0.5)
    # Same paths, person offset to 0.6: a near miss, no collision.
    hp2 = hp + np.array([0.0, 0.2])
    assert not M.swept_person_collisions(rp, hp2, 0.3, 0.2).any()


def test_swept_obstacle_collision():
    wall = np.array([[[0.0, -1.0], [0.0, 1.0]]])
    rp = np.array([[-1.0, 0.0], [1.0, 0.0], [1.0, 2.0]])
    hits = M.swept_obstacle_collisions(rp, 0.3, wall)
    assert hits.tolist() == [True, False]  # the first step passes through the thin wall


def test_classify_trajectory():
    goal = np.array([4.0, 0.0])
    rp = line([0, 0], [4, 0], 8)  # dt 0.5: 1 m/s, reaches the goal at step 8 (within 0.3 at x=4)
    assert M.classify_trajectory(rp, goal, None, 0.3, 0.2, 0.5, 25.0) == {"event": "goal", "end_step": 8}
    # A person standing on the path at x=2 (swept hit during step 4: x 1.5 -> 2.0).
    hp = np.tile([[2.0, 0.0]], (9, 1, 1))
    assert M.classify_trajectory(rp, goal, hp, 0.3, 0.2, 0.5, 25.0)["event"] == "collision_human"
    wall = np.array([[[3.0, -1.0], [3.0, 1.0]]])
    c = M.classify_trajectory(rp, goal, None, 0.3, 0.2, 0.5, 25.0, segments=wall)
    assert c["event"] == "collision_obstacle" and c["end_step"] == 6  # disc edge touches x=3 from x=2.7
    short = rp[:5]
    assert M.classify_trajectory(short, goal, None, 0.3, 0.2, 0.5, 2.0)["event"] == "timeout"
    assert M.classify_trajectory(short, goal, None, 0.3, 0.2, 0.5, 25.0)["event"] == "running"
    # Goal tolerance 0.75 (NavIsaacLab): the goal is reached at x = 3.5, one step earlier.
    c = M.classify_trajectory(rp, goal, None, 0.3, 0.2, 0.5, 25.0, goal_tolerance=0.75)
    assert c == {"event": "goal", "end_step": 7}


def test_stuck():
    dt = 0.5
    drive = line([0, 0], [5, 0], 10)  # 5 s
    jitter = np.array([5.0, 0.0]) + 0.05 * np.stack([np.sin(np.arange(1, 21)), np.zeros(20)], axis=1)  # 10 s
    rp = np.vstack([drive, jitter])
    assert M.is_stuck(rp, dt)
    yaw = np.zeros(len(rp))
    assert M.is_stuck(rp, dt, yaw)
    yaw_turn = yaw.copy()
    yaw_turn[-20:] = np.radians(np.linspace(1, 20, 20))  # turned 20 deg over the last 10 s
    assert not M.is_stuck(rp, dt, yaw_turn)
    assert M.is_stuck(rp, dt, yaw_turn, min_turn_deg=25.0)
    moving = np.vstack([drive, line([5, 0], [5.3, 0], 20)[1:]])  # 0.3 m in the last 10 s
    assert not M.is_stuck(moving, dt)
    assert not M.is_stuck(still([0, 0], 10), dt)  # 5 s episode: shorter than the window


# ---------------------------------------------------------------------------------------------------------
# Efficiency
# ---------------------------------------------------------------------------------------------------------


def test_path_length_ratio_spl_and_times():
    rp = np.array([[0.0, 0.0], [3.0, 4.0], [6.0, 0.0]])  # 10 m for 6 m straight
    assert M.path_length(rp) == pytest.approx(10.0)
    assert M.path_length_ratio(rp, [6.0, 0.0]) == pytest.approx(10.0 / 6.0)
    assert M.spl(True, 10.0, 8.0) == pytest.approx(0.8)
    assert M.spl(False, 10.0, 8.0) == 0.0
    assert M.spl(True, 7.99, 8.0) == 1.0  # a path shorter than l* (discretisation) caps at 1
    assert M.extra_time_to_goal(12.0, 8.0, 1.0) == pytest.approx(4.0)
    assert M.navigation_time(40, 0.25, True) == 10.0
    assert math.isnan(M.navigation_time(40, 0.25, False))
    assert M.mean_navigation_time([10.0, 25.0, 12.0], [True, False, True], 25.0) == pytest.approx(11.0)
    assert M.mean_navigation_time([25.0, 25.0], [False, False], 25.0) == 25.0


# ---------------------------------------------------------------------------------------------------------
# Smoothness
# ---------------------------------------------------------------------------------------------------------


def test_constant_speed_line_has_no_acceleration_or_jerk():
    rp = line([0, 0], [3, 4], 20)  # 5 m in 20 steps of 0.1 s: 2.5 m/s
    s = M.motion_stats(rp, 0.1)
    assert s["mean_speed"] == pytest.approx(2.5) and s["max_speed"] == pytest.approx(2.5)
    for k in ("mean_accel", "max_accel", "mean_jerk", "max_jerk"):
        assert s[k] == pytest.approx(0.0, abs=1e-9)
    assert M.heading_change(M.motion_headings(rp)) == pytest.approx(0.0)


def test_known_acceleration_and_jerk():
    dt = 0.1
    t = np.arange(11) * dt
    rp = np.stack([0.5 * 2.0 * t**2, np.zeros_like(t)], axis=1)  # constant 2 m/s^2
    assert M.accelerations(rp, dt) == pytest.approx(np.full(9, 2.0))
    assert M.jerks(rp, dt) == pytest.approx(np.zeros(8), abs=1e-6)
    rp3 = np.stack([t**3, np.zeros_like(t)], axis=1)  # x = t^3: jerk 6 m/s^3 exactly by third differences
    assert M.jerks(rp3, dt) == pytest.approx(np.full(8, 6.0))


def test_circle_heading_change_and_centripetal_acceleration():
    n, r, dt = 36, 2.0, 0.1
    th = np.linspace(0, 2 * np.pi, n + 1)
    rp = r * np.stack([np.cos(th), np.sin(th)], axis=1)
    yaw = th + np.pi / 2  # tangent
    assert M.heading_change(yaw) == pytest.approx(2 * np.pi)
    # Motion headings of the 36 chords: 35 turns of 10 degrees.
    assert M.path_turning(rp) == pytest.approx(2 * np.pi * (n - 1) / n)
    step = 2 * np.pi / n
    assert M.accelerations(rp, dt) == pytest.approx(np.full(n - 1, 4 * r * np.sin(step / 2) ** 2 / dt**2))


def test_standing_jitter_adds_no_heading_change():
    rp = np.vstack(
        [
            line([0, 0], [1, 0], 10),
            np.array([1.0, 0.0]) + 1e-4 * np.random.default_rng(0).normal(size=(20, 2)),
        ]
    )
    assert M.path_turning(rp, min_step=1e-3) == pytest.approx(0.0, abs=1e-6)


def test_path_irregularity_straight_is_zero():
    rp = line([0, 0], [4, 0], 40)
    assert M.path_irregularity(rp, goal=[4.0, 0.0]) == 0.0
    far = rp + np.array([100.0, -50.0])  # and translation does not matter (it does in SocNavBench's)
    assert M.path_irregularity(far, goal=[104.0, -50.0]) == 0.0


def test_path_irregularity_detour_known_value():
    # Detour (0,0) -> (2,2) -> (4,0) where the straight line is free: one 90 degree turn over 4 sqrt(2) m.
    rp = np.vstack([line([0, 0], [2, 2], 10), line([2, 2], [4, 0], 10)[1:]])
    assert M.path_irregularity(rp, goal=[4.0, 0.0]) == pytest.approx((np.pi / 2) / (4 * np.sqrt(2)))
    # The same path with a zig-zag reference (turning pi/2) needs nothing extra.
    assert M.path_irregularity(rp, reference_path=[[2.0, 2.0], [4.0, 0.0]]) == pytest.approx(0.0)


def test_path_irregularity_corner_the_shortest_path_must_turn():
    # Shortest path (0,0) -> (4,0) -> (4,4) around a corner: turning pi/2 is needed.
    ref = np.array([[4.0, 0.0], [4.0, 4.0]])  # NavEnv's convention: waypoints after the start
    exact = np.vstack([line([0, 0], [4, 0], 8), line([4, 0], [4, 4], 8)[1:]])
    assert M.path_irregularity(exact, ref) == pytest.approx(0.0, abs=1e-12)
    # A rounded corner (quarter circle radius 1 about (3, 1)) turns the same pi/2: no extra.
    a = np.linspace(-np.pi / 2, 0, 10)
    arc = np.stack([3 + np.cos(a), 1 + np.sin(a)], axis=1)
    rounded = np.vstack([line([0, 0], [3, 0], 6), arc[1:], line([4, 1], [4, 4], 6)[1:]])
    assert M.path_turning(rounded) == pytest.approx(np.pi / 2)
    assert M.path_irregularity(rounded, ref) == pytest.approx(0.0, abs=1e-9)
    # A wiggle on top (+30, -60, +30 degrees) costs its 2 pi/3 extra radians per metre.
    wig = np.vstack(
        [
            line([0, 0], [1, 0], 4),
            [[1 + np.cos(np.pi / 6), 0.5]],
            line([1 + 2 * np.cos(np.pi / 6), 0], [4, 0], 4),
            line([4, 0], [4, 4], 8)[1:],
        ]
    )
    expected = (np.pi / 2 + 2 * np.pi / 3 - np.pi / 2) / M.path_length(wig)
    assert M.path_irregularity(wig, ref) == pytest.approx(expected)


# ---------------------------------------------------------------------------------------------------------
# Social
# ---------------------------------------------------------------------------------------------------------


def pass_by():
    """Robot along y = 0 from x = -2 to 2 (0.5 m steps, dt 0.5); person standing at (0, 0.6);
    radii 0.3 + 0.2: the gap is exactly 0.1 m at x = 0."""
    rp = line([-2, 0], [2, 0], 8)
    hp = np.tile([[0.0, 0.6]], (9, 1, 1))
    return rp, hp


def test_min_distance_and_discomfort_on_a_pass_at_0_1_m():
    rp, hp = pass_by()
    assert M.min_person_distance(rp, hp, 0.3, 0.2) == pytest.approx(0.1)
    s = M.discomfort_stats(rp, hp, 0.3, 0.2)
    # Swept (CrowdNav's dmin): both steps touching x = 0 come within 0.1 m; the neighbours' closest is 0.28 m.
    assert s["steps"] == 2 and s["total_steps"] == 8
    assert s["frequency"] == pytest.approx(0.25) and s["mean_min_gap_m"] == pytest.approx(0.1)
    assert M.discomfort(rp, hp, 0.3, 0.2) == (2, 8)
    assert M.discomfort(rp, hp, 0.3, 0.2, swept=False) == (1, 8)  # only the sample at x = 0
    assert M.discomfort(rp, hp, 0.3, 0.2, threshold=0.3) == (4, 8)


def test_discomfort_pooled_over_episodes():
    rp, hp = pass_by()
    a = M.discomfort_stats(rp, hp, 0.3, 0.2)  # 2 of 8 steps, gap 0.1
    b = M.discomfort_stats(line([-2, 0], [2, 0], 12), np.tile([[0.0, 5.0]], (13, 1, 1)), 0.3, 0.2)  # 0 of 12
    pooled = M.aggregate_discomfort([a, b])
    assert pooled["discomfort_frequency"] == pytest.approx(2 / 20)
    assert pooled["discomfort_mean_min_gap_m"] == pytest.approx(0.1)


def test_no_people():
    rp = line([0, 0], [4, 0], 8)
    empty = np.zeros((9, 0, 2))
    assert M.min_person_distance(rp, empty, 0.3, 0.2) == float("inf")
    assert M.discomfort(rp, empty, 0.3, np.zeros(0)) == (0, 8)
    assert M.proxemic_shares(rp, empty, 0.3, 0.2)["public"] == 1.0
    assert M.intrusion_time_ratio(rp, empty, 0.3, 0.2, 0.5) == 0.0
    assert M.ttc_stats(rp, empty, 0.3, 0.2, 0.5)["min_ttc_s"] == float("inf")
    assert M.personal_space_cost(rp, empty, 0.3, 0.2, 0.5)["total"] == 0.0
    assert M.social_work(rp, empty, 0.3, 0.2, 0.5)["social_work"] == 0.0
    assert M.pedestrian_disturbance_local(rp, empty, 0.3, 0.2, 0.5)["encounters"] == 0


def test_proxemic_shares():
    # Robot still at the origin; two people, the closer one decides; radii 0.25 + 0.25 (centre = gap + 0.5).
    gaps = np.array([9.0, 0.3, 0.3, 1.0, 2.0, 2.0, 2.0, 5.0, 5.0])  # sample 0 is not a step
    far = np.full(9, 20.0)
    hp = np.stack([np.stack([gaps + 0.5, np.zeros(9)], 1), np.stack([np.zeros(9), far])[::-1].T], axis=1)
    s = M.proxemic_shares(still([0, 0], 8), hp, 0.25, 0.25)
    assert s == pytest.approx({"intimate": 2 / 8, "personal": 1 / 8, "social": 3 / 8, "public": 2 / 8})
    assert sum(s.values()) == pytest.approx(1.0)
    # Boundaries (zero radii, so no rounding): a gap of exactly 0.45 is personal, 1.2 social, 3.6 public.
    edge = np.array([9.0, 0.45, 1.2, 3.6])
    hp2 = np.stack([edge, np.zeros(4)], 1)[:, None, :]
    assert M.proxemic_shares(still([0, 0], 3), hp2, 0.0, 0.0) == pytest.approx(
        {"intimate": 0.0, "personal": 1 / 3, "social": 1 / 3, "public": 1 / 3}
    )


def test_intrusion_when_a_person_walks_into_the_robots_spot_1s_later():
    # Robot still at the origin (r 0.3); person (r 0.2) walks through it along x at 2 m/s, dt 0.25:
    # x_t = 2 - 0.5 t; centre distance < 0.5 only at t = 4 (x = 0, 1 s in). Samples 1..3 see it within
    # their next 1.25 s (5 samples), sample 4 itself is a collision, not a future intrusion.
    dt = 0.25
    x = 2.0 - 0.5 * np.arange(9)
    hp = np.stack([x, np.zeros(9)], 1)[:, None, :]
    assert M.intrusion_time_ratio(still([0, 0], 8), hp, 0.3, 0.2, dt) == pytest.approx(3 / 8)
    # A 0.5 s horizon (2 samples ahead) only catches samples 2 and 3.
    assert M.intrusion_time_ratio(still([0, 0], 8), hp, 0.3, 0.2, dt, horizon_s=0.5) == pytest.approx(2 / 8)


def test_time_to_collision_head_on():
    # Robot at 0 moving +x at 1 m/s, person at x = 5 moving -x at 1 m/s; radii 0.3 + 0.2: 4.5 m gap
    # closing at 2 m/s -> 2.25 s.
    assert M.time_to_collision([5.0, 0.0], [-2.0, 0.0], 0.5) == pytest.approx(2.25)
    assert M.time_to_collision([5.0, 0.0], [2.0, 0.0], 0.5) == np.inf  # separating
    assert M.time_to_collision([5.0, 1.0], [-2.0, 0.0], 0.5) == np.inf  # passes 1 m apart
    assert M.time_to_collision([0.3, 0.0], [2.0, 0.0], 0.5) == 0.0  # already overlapping
    # Offset 0.3 m: touches when the lateral 0.3 and longitudinal 0.4 make 0.5 -> (5 - 0.4) / 2.
    assert M.time_to_collision([5.0, 0.3], [-2.0, 0.0], 0.5) == pytest.approx(2.3)


def test_ttc_stats_over_an_episode():
    dt = 0.25
    n = 8
    t = np.arange(n + 1) * dt
    rp = np.stack([t, np.zeros(n + 1)], 1)  # +x at 1 m/s
    hp = np.stack([6.0 - t, np.zeros(n + 1)], 1)[:, None, :]  # -x at 1 m/s from x = 6
    s = M.ttc_stats(rp, hp, 0.3, 0.2, dt)
    gap = 6.0 - 2 * t[1:] - 0.5
    assert s["ttc"] == pytest.approx(gap / 2.0)
    assert s["min_ttc_s"] == pytest.approx((6.0 - 4.0 - 0.5) / 2.0)  # at t = 2 s
    # TTC 2.5, 2.25, ..., 1.0, 0.75 s: one sample below 1 s (1.0 is not below), five below 2 s.
    assert s["below"] == pytest.approx(1 / 8)
    assert M.ttc_stats(rp, hp, 0.3, 0.2, dt, threshold_s=2.0)["below"] == pytest.approx(5 / 8)
    # Given velocities win over finite differences: a standing person seen as standing.
    hv = np.zeros_like(hp)
    assert M.ttc_stats(rp, hp, 0.3, 0.2, dt, human_vel=hv)["ttc"][0] == pytest.approx((6.0 - 0.5 - 0.5) / 1.0)


def one_sample(robot_xy, person_xy, person_vel):
    rp = np.array([robot_xy, robot_xy], float)
    hp = np.array([[person_xy], [person_xy]], float)
    hv = np.array([[person_vel], [person_vel]], float)
    return rp, hp, hv


def test_personal_space_cost_asymmetric():
    # Person at the origin walking +x at 1 m/s: sigma = max(2 * 1, 0.5) = 2 front, 2/3 rear, 0.5 sides.
    # Radii 0.25 + 0.25 and a centre distance of 1.5: a 1 m gap.
    def cost(robot_xy, vel=(1.0, 0.0), **kw):
        rp, hp, hv = one_sample(robot_xy, (0.0, 0.0), vel)
        return M.personal_space_cost(rp, hp, 0.25, 0.25, 0.1, human_vel=hv, **kw)["total"]

    front, rear, side = cost((1.5, 0.0)), cost((-1.5, 0.0)), cost((0.0, 1.5))
    assert front == pytest.approx(math.exp(-1 / 8))
    assert rear == pytest.approx(math.exp(-9 / 8))
    assert side == pytest.approx(math.exp(-2.0))
    assert front > rear > side
    assert cost((0.0, -1.5)) == pytest.approx(side)  # left and right alike
    # Standing person: sigma 0.5 front (and isotropic until seen moving).
    assert cost((1.5, 0.0), vel=(0.0, 0.0)) == pytest.approx(math.exp(-1 / (2 * 0.25)))
    assert cost((0.0, 1.5), vel=(0.0, 0.0)) == pytest.approx(math.exp(-1 / (2 * 0.25)))
    # Contact costs 1; centre-to-centre offsets on request.
    assert cost((0.5, 0.0)) == pytest.approx(1.0)
    assert cost((1.5, 0.0), edge_to_edge=False) == pytest.approx(math.exp(-2.25 / 8))


def test_personal_space_cost_sums_over_steps_and_people():
    rp = still([0.0, 0.0], 4)
    hp = np.tile(
        [
            [[1.5, 0.0]],
        ],
        (5, 1, 1),
    )  # standing, 1 m gap -> exp(-2) per sample each
    hp2 = np.concatenate([hp, hp], axis=1)
    c = M.personal_space_cost(rp, hp2, 0.25, 0.25, 0.1)
    assert c["per_step"] == pytest.approx(np.full(4, 2 * math.exp(-2)))
    assert c["total"] == pytest.approx(8 * math.exp(-2)) and c["mean"] == pytest.approx(2 * math.exp(-2))


def test_pedestrian_disturbance_rerun():
    dt = 0.1
    t = np.arange(11) * dt
    ref = np.stack([t, np.zeros(11)], 1)[:, None, :]  # +x at 1 m/s
    assert M.pedestrian_disturbance_rerun(ref, ref, dt) == pytest.approx(
        {
            "path_deviation_m": 0.0,
            "max_path_deviation_m": 0.0,
            "speed_change_mps": 0.0,
            "heading_change_rad": 0.0,
        }
    )
    shifted = ref + np.array([0.0, 0.3])
    d = M.pedestrian_disturbance_rerun(shifted, ref, dt)
    assert d["path_deviation_m"] == pytest.approx(0.3) and d["speed_change_mps"] == pytest.approx(0.0)
    slow = np.stack([0.5 * t, np.zeros(11)], 1)[:, None, :]  # half speed
    d = M.pedestrian_disturbance_rerun(slow, ref, dt)
    assert d["speed_change_mps"] == pytest.approx(0.5)
    assert d["max_path_deviation_m"] == pytest.approx(0.5) and d["heading_change_rad"] == pytest.approx(0.0)
    turned = np.stack([np.zeros(11), t], 1)[:, None, :]  # +y instead of +x
    assert M.pedestrian_disturbance_rerun(turned, ref, dt)["heading_change_rad"] == pytest.approx(np.pi / 2)
    # Rerun recorded longer: only the common samples count.
    assert M.pedestrian_disturbance_rerun(ref[:6], ref, dt)["path_deviation_m"] == 0.0


def test_pedestrian_disturbance_local():
    dt = 0.1
    n = 14
    x = np.arange(n + 1) * dt  # +x at 1 m/s
    y = np.zeros(n + 1)
    far = np.array([100.0, 100.0])
    # Robot near (2 m to the side) during samples 5..9 only.
    rp = np.array([[x[t], 2.0] if 5 <= t <= 9 else far for t in range(n + 1)])
    straight = np.stack([x, y], 1)[:, None, :]
    d = M.pedestrian_disturbance_local(rp, straight, 0.3, 0.2, dt)
    assert d == pytest.approx(
        {
            "lateral_deviation_m": 0.0,
            "max_lateral_deviation_m": 0.0,
            "velocity_loss_mps": 0.0,
            "encounters": 1,
        }
    )
    # Sidestep: 0.1 m per sample sideways from sample 6 on (0.4 m by sample 9), forward speed kept.
    side = np.stack([x, np.where(np.arange(n + 1) >= 6, 0.1 * (np.arange(n + 1) - 5), 0.0).clip(max=0.4)], 1)[
        :, None, :
    ]
    d = M.pedestrian_disturbance_local(rp, side, 0.3, 0.2, dt)
    assert d["lateral_deviation_m"] == pytest.approx(0.4) and d["velocity_loss_mps"] == pytest.approx(0.0)
    # Slowing to 0.5 m/s from sample 5 on: loss 0.5 m/s at each of the 5 encounter samples.
    xs = np.where(np.arange(n + 1) <= 4, x, 0.4 + 0.05 * (np.arange(n + 1) - 4))
    slow = np.stack([xs, y], 1)[:, None, :]
    rp_slow = np.array([[xs[t], 2.0] if 5 <= t <= 9 else far for t in range(n + 1)])
    d = M.pedestrian_disturbance_local(rp_slow, slow, 0.3, 0.2, dt)
    assert d["velocity_loss_mps"] == pytest.approx(0.5) and d["lateral_deviation_m"] == pytest.approx(0.0)
    assert M.pedestrian_disturbance_local(rp, straight, 0.3, 0.2, dt, radius=1.0)["encounters"] == 0


def test_social_work_static_pair_known_value():
    from navzoo.agents.sfm import SocialForceParams

    p = SocialForceParams()
    # Robot (r 0.3) and person (r 0.2) standing 1.5 m apart: the ellipse degenerates to the circle, each
    # pushes the other with A/B exp(-(d - (r1 + r2)) / B), no anisotropy or keep-right term (no heading).
    d, n, dt = 1.5, 4, 0.25
    rp = still([0.0, 0.0], n)
    hp = np.tile([[[d, 0.0]]], (n + 1, 1, 1))
    f = p.A / p.B * math.exp(-(d - 0.5) / p.B)
    w = M.social_work(rp, hp, 0.3, 0.2, dt)
    assert w["on_robot"] == pytest.approx(f * n * dt)
    assert w["on_people"] == pytest.approx(f * n * dt)
    assert w["social_work"] == pytest.approx(2 * f * n * dt)
    # Beyond the model's neighbour distance (5 m) nothing acts.
    far = np.tile([[[6.0, 0.0]]], (n + 1, 1, 1))
    assert M.social_work(rp, far, 0.3, 0.2, dt)["social_work"] == 0.0


def test_social_work_matches_the_sfm_robot_term_step_by_step():
    from navzoo.agents.sfm import SocialForceParams, social_forces

    rng = np.random.default_rng(3)
    n, h, dt = 6, 4, 0.2
    rp = np.cumsum(rng.normal(0, 0.2, (n + 1, 2)), axis=0)
    hp = rng.uniform(-2, 2, (1, h, 2)) + np.cumsum(rng.normal(0, 0.2, (n + 1, h, 2)), axis=0)
    hr = np.array([0.2, 0.25, 0.3, 0.22])
    p = SocialForceParams()
    rv = np.vstack([np.diff(rp, axis=0)[:1], np.diff(rp, axis=0)]) / dt
    hv = np.concatenate([np.diff(hp, axis=0)[:1], np.diff(hp, axis=0)]) / dt
    on_robot = on_people = 0.0
    for t in range(1, n + 1):
        xr, vr = rp[t : t + 1], rv[t : t + 1]
        fr = social_forces(xr, vr, vr, 0.3, p, others_pos=hp[t], others_vel=hv[t], others_radius=hr).robots
        fh = social_forces(hp[t], hv[t], hv[t], hr, p, others_pos=xr, others_vel=vr, others_radius=0.3).robots
        on_robot += np.linalg.norm(fr[0]) * dt
        on_people += np.linalg.norm(fh, axis=1).sum() * dt
    w = M.social_work(rp, hp, 0.3, hr, dt)
    assert w["on_robot"] == pytest.approx(on_robot) and w["on_people"] == pytest.approx(on_people)
    assert on_robot > 0 and on_people > 0


def test_social_work_grows_when_closer_and_approaching():
    n, dt = 4, 0.25
    rp = still([0.0, 0.0], n)
    near = M.social_work(rp, np.tile([[[1.0, 0.0]]], (n + 1, 1, 1)), 0.3, 0.2, dt)["social_work"]
    far = M.social_work(rp, np.tile([[[2.0, 0.0]]], (n + 1, 1, 1)), 0.3, 0.2, dt)["social_work"]
    assert near > far > 0
    hv = np.tile([[[-1.0, 0.0]]], (n + 1, 1, 1))  # walking at the robot: the ellipse flattens
    coming = M.social_work(rp, np.tile([[[2.0, 0.0]]], (n + 1, 1, 1)), 0.3, 0.2, dt, human_vel=hv)[
        "social_work"
    ]
    assert coming > far


# ---------------------------------------------------------------------------------------------------------
# Multi-robot and aggregation
# ---------------------------------------------------------------------------------------------------------


def test_multi_robot_summary():
    s = M.multi_robot_summary(["goal", "collision_human", "goal"], [10, 5, 20], 0.25)
    assert s["success_rate"] == pytest.approx(2 / 3) and s["collision_rate"] == pytest.approx(1 / 3)
    assert not s["all_success"] and s["any_collision"]
    assert s["aggregated_time_s"] == 5.0 and math.isnan(s["all_success_time_s"])
    assert s["per_robot"][1]["human_collision"]
    ok = M.multi_robot_summary(["goal", "goal"], [12, 30], 0.25)
    assert ok["all_success"] and ok["all_success_time_s"] == 7.5


def test_mean_ci():
    c = M.mean_ci([1, 2, 3, 4, 5])
    half = 2.7764451051977987 * math.sqrt(2.5) / math.sqrt(5)  # t(0.975, 4) * s / sqrt(n)
    assert c["mean"] == 3.0 and c["half_width"] == pytest.approx(half) and c["n"] == 5
    assert c["low"] == pytest.approx(3 - half) and c["high"] == pytest.approx(3 + half)
    z = M.mean_ci([1, 2, 3, 4, 5], method="normal")
    assert z["half_width"] == pytest.approx(1.959963984540054 * math.sqrt(2.5) / math.sqrt(5))
    skip = M.mean_ci([1.0, float("nan"), 3.0, float("inf")])
    assert skip["n"] == 2 and skip["mean"] == 2.0
    assert math.isnan(M.mean_ci([4.0])["half_width"]) and M.mean_ci([])["n"] == 0


def test_aggregate_episodes():
    rp, hp = pass_by()
    ok = M.episode_metrics(rp, hp, 0.3, 0.2, 0.5, "goal", shortest_path=4.0, time_limit=25.0)
    far = np.tile([[0.0, 9.0]], (9, 1, 1))
    bad = M.episode_metrics(rp, far, 0.3, 0.2, 0.5, "timeout", shortest_path=4.0, time_limit=25.0)
    agg = M.aggregate_episodes([ok, bad])
    m = agg["metrics"]
    assert agg["n_episodes"] == 2
    assert m["success"]["mean"] == 0.5 and m["timeout"]["mean"] == 0.5
    assert m["nav_time_s"]["mean"] == pytest.approx(4.0) and m["nav_time_s"]["n"] == 1
    assert m["discomfort_frequency"]["mean"] == pytest.approx(2 / 16)  # pooled over 16 steps
    assert m["discomfort_mean_min_gap_m"]["mean"] == pytest.approx(0.1)
    none = M.aggregate_episodes([bad, bad])["metrics"]
    assert none["nav_time_s"]["mean"] == 25.0 and none["nav_time_s"]["n"] == 0  # the limit if no success


# ---------------------------------------------------------------------------------------------------------
# Per-episode dicts
# ---------------------------------------------------------------------------------------------------------

NAMES = [
    "success",
    "collision",
    "human_collision",
    "obstacle_collision",
    "timeout",
    "stuck",
    "nav_time_s",
    "path_length_m",
    "path_length_ratio",
    "spl",
    "extra_time_s",
    "mean_speed",
    "max_speed",
    "mean_accel",
    "max_accel",
    "mean_jerk",
    "max_jerk",
    "heading_change_rad",
    "path_irregularity",
    "min_distance_m",
    "discomfort_steps",
    "discomfort_frequency",
    "discomfort_mean_min_gap_m",
    "proxemic_intimate",
    "proxemic_personal",
    "proxemic_social",
    "intrusion_time_ratio",
    "min_ttc_s",
    "ttc_below_1s",
    "personal_space_cost",
    "disturbance_lateral_m",
    "disturbance_velocity_loss_mps",
    "disturbance_rerun_path_deviation_m",
    "social_work",
    "thresholds",
]


def test_episode_metrics_full_dict():
    rp, hp = pass_by()
    m = M.episode_metrics(
        rp,
        hp,
        0.3,
        0.2,
        0.5,
        "goal",
        goal=[2.0, 0.0],
        shortest_path=4.0,
        time_limit=25.0,
        v_pref=1.0,
        human_pos_rerun=hp,
    )
    for k in NAMES:
        assert k in m, k
    assert m["success"] and not m["stuck"]
    assert m["nav_time_s"] == 4.0 and m["path_length_m"] == pytest.approx(4.0)
    assert m["path_length_ratio"] == pytest.approx(1.0) and m["spl"] == pytest.approx(1.0)
    assert m["extra_time_s"] == pytest.approx(0.0)
    assert m["min_distance_m"] == pytest.approx(0.1) and m["discomfort_steps"] == 2
    assert m["path_irregularity"] == 0.0 and m["mean_accel"] == pytest.approx(0.0)
    assert m["disturbance_rerun_path_deviation_m"] == 0.0
    assert m["thresholds"]["discomfort_m"] == 0.2 and m["thresholds"]["goal_tolerance_m"] == 0.3
    assert m["thresholds"]["proxemic_zones_m"] == [0.45, 1.2, 3.6]
    json.loads(json.dumps(m))  # serialisable as is


def test_episode_metrics_classifies_and_thresholds():
    rp = line([0, 0], [4, 0], 8)
    hp = np.tile([[2.0, 0.0]], (9, 1, 1))
    m = M.episode_metrics(rp, hp, 0.3, 0.2, 0.5, goal=[4.0, 0.0], time_limit=25.0)
    assert m["event"] == "collision_human" and m["collision"] and m["swept_human_collision"]
    assert m["steps"] == 4  # step 4 (x 1.5 -> 2.0) runs into the person at x = 2
    assert math.isnan(m["nav_time_s"]) and m["spl"] != m["spl"]  # no l*: nan
    th = M.Thresholds(discomfort_m=0.5, goal_tolerance_m=0.75)
    m2 = M.episode_metrics(
        rp, np.zeros((9, 0, 2)), 0.3, 0.2, 0.5, goal=[4.0, 0.0], time_limit=25.0, thresholds=th
    )
    assert m2["event"] == "goal" and m2["steps"] == 7  # within 0.75 m at x = 3.5: the episode ends there
    assert m2["nav_time_s"] == 3.5 and m2["path_length_m"] == pytest.approx(3.5)
    assert m2["thresholds"]["goal_tolerance_m"] == 0.75 and m2["thresholds"]["discomfort_m"] == 0.5
    with pytest.raises(ValueError):
        M.episode_metrics(rp, hp, 0.3, 0.2, 0.5)


def test_thresholds_are_validated():
    with pytest.raises(ValueError, match="proxemic_zones_m"):
        M.Thresholds(proxemic_zones_m=(1.2, 0.45, 3.6))
    with pytest.raises(ValueError, match="intrusion_horizon_s"):
        M.Thresholds(intrusion_horizon_s=0.0)
    with pytest.raises(ValueError, match="ttc_s"):
        M.Thresholds(ttc_s=float("nan"))
    with pytest.raises(TypeError):
        M.Thresholds(discomfort=0.3)  # unknown field


def test_episode_metrics_end_step_and_stuck_timeout():
    dt = 0.5
    rp = np.vstack([line([0, 0], [2, 0], 4), still([2, 0], 24)[1:]])  # 2 s driving, then 12 s standing
    m = M.episode_metrics(rp, None, 0.3, 0.2, dt, "timeout", goal=[8.0, 0.0], time_limit=14.0)
    assert m["timeout"] and m["stuck"] and m["time_s"] == 14.0
    assert math.isnan(m["nav_time_s"]) and m["path_length_ratio"] == pytest.approx(2 / 8)
    cut = M.episode_metrics(rp, None, 0.3, 0.2, dt, "goal", end_step=4, shortest_path=2.0)
    assert cut["steps"] == 4 and cut["nav_time_s"] == 2.0 and cut["spl"] == pytest.approx(1.0)
    assert not cut["stuck"]  # stuck is only reported within timeouts


def test_episode_summary_keeps_its_original_keys():
    rp, hp = pass_by()
    s = M.episode_summary(rp, hp, 0.3, np.array([0.2]), 0.5, "timeout", 4.0, 25.0)
    for k in (
        "event",
        "success",
        "collision",
        "human_collision",
        "obstacle_collision",
        "timeout",
        "navigation_time_s",
        "path_length_m",
        "shortest_path_m",
        "path_length_ratio",
        "spl",
        "min_person_distance_m",
        "discomfort_steps",
        "discomfort_frequency",
        "steps",
    ):
        assert k in s, k
    assert s["navigation_time_s"] == 25.0 and s["steps"] == 8
    assert s["min_person_distance_m"] == pytest.approx(0.1)
    assert s["spl"] == 0.0 and s["shortest_path_m"] == 4.0
    assert math.isnan(s["path_length_ratio"])  # failed and no goal given: no straight line to compare to
    ok = M.episode_summary(
        rp, hp, 0.3, 0.2, 0.5, "goal", 4.0, 25.0, discomfort_threshold=0.05, goal=[2.0, 0.0]
    )
    assert (
        ok["navigation_time_s"] == 4.0
        and ok["discomfort_steps"] == 0
        and ok["path_length_ratio"] == pytest.approx(1.0)
    )
    assert ok["thresholds"]["discomfort_m"] == 0.05
    json.loads(json.dumps(s))


def test_people_who_appear_are_not_swept_along_their_jump():
    """The replay crowd keeps absent people far away: with ``present`` the jump into the scene, which crosses the
    robot here, is no collision and no near pass; without it, it is (the reason ``present`` exists)."""
    from navzoo.benchmark.metrics import discomfort_stats, min_person_distance, swept_person_collisions

    T = 10
    robot = np.zeros((T + 1, 2))  # the robot stands at the origin
    person = np.zeros((T + 1, 1, 2))
    person[:5, 0] = (-1000.0, 0.0)  # parked far west, then appears 3 m east: the jump crosses the robot
    person[5:, 0] = (3.0, 0.0)
    present = np.zeros((T + 1, 1), dtype=bool)
    present[5:] = True
    assert swept_person_collisions(robot, person, 0.3, 0.3).any()
    assert not swept_person_collisions(robot, person, 0.3, 0.3, present=present).any()
    assert min_person_distance(robot, person, 0.3, 0.3, present=present) == pytest.approx(2.4)
    assert discomfort_stats(robot, person, 0.3, 0.3, 0.2, present=present)["steps"] == 0
    # a person who appears on top of the robot is still a collision, at the step they appear
    person[5:, 0] = (0.2, 0.0)
    hits = swept_person_collisions(robot, person, 0.3, 0.3, present=present)
    assert hits[4, 0] and not hits[:4].any()
    # and a person who leaves (absent at the step's end) has no gap in that step
    present[8:] = False
    person[8:, 0] = (-1000.0, 0.0)
    gaps = M.swept_person_gaps(robot, person, 0.3, 0.3, present)
    assert np.isinf(gaps[7:, 0]).all() and np.isfinite(gaps[4:7, 0]).all()
