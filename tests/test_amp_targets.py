"""Target trajectories of physics pedestrians: waypoints a pushed body skipped, and door jambs."""

from __future__ import annotations

import numpy as np
import pytest

from navzoo.agents.sfm import SocialForceParams, social_force_velocities, social_forces
from navzoo.envs.amp_humans import WAYPOINT_LOOKAHEAD, advance_waypoint
from tests.amp_helpers import peak_target_pace

PATH = np.stack([np.arange(10) * 0.5, np.zeros(10)], axis=1)  # waypoints 0.5 m apart along x


def test_strict_order_without_lookahead():
    # Beside waypoint 4 but 1.0 m from waypoint 2: the strict rule keeps heading for waypoint 2.
    assert advance_waypoint(PATH, 2, np.array([2.0, 0.3]), tol=0.6, lookahead=0) == 2
    # Within the tolerance of the current waypoint: on to the first one beyond it.
    assert advance_waypoint(PATH, 2, np.array([0.9, 0.3]), tol=0.6, lookahead=0) == 3


def test_a_body_pushed_past_its_waypoint_moves_on():
    # The body missed waypoint 2 (1.04 m away) and stands within 0.6 m of waypoints 3, 4 and 5.
    k = advance_waypoint(PATH, 2, np.array([2.0, 0.3]), tol=0.6, lookahead=WAYPOINT_LOOKAHEAD)
    assert k == 6  # past the farthest one within reach, heading on instead of back


def test_lookahead_is_bounded_and_stops_at_the_goal():
    far = np.array([4.0, 0.0])  # near waypoint 8, beyond a lookahead of 4 from waypoint 2
    assert advance_waypoint(PATH, 2, far, tol=0.3, lookahead=4) == 2
    assert advance_waypoint(PATH, 7, np.array([4.5, 0.0]), tol=0.6, lookahead=4) == 9  # last index


def test_in_sight_keeps_the_last_waypoint_the_body_sees():
    # within reach of waypoints 3, 4 and 5, but only waypoints up to x = 1.5 (index 3) are in sight
    pos = np.array([2.0, 0.3])
    assert advance_waypoint(PATH, 2, pos, tol=0.6, lookahead=WAYPOINT_LOOKAHEAD) == 6
    seen = []

    def sight(p, w):
        seen.append(float(w[0]))
        return bool(w[0] <= 1.5)

    assert advance_waypoint(PATH, 2, pos, tol=0.6, lookahead=WAYPOINT_LOOKAHEAD, in_sight=sight) == 3
    assert seen == [3.0, 2.5, 2.0, 1.5]  # asked from the farthest back
    # it never goes back behind the waypoint it had, even one out of sight
    assert advance_waypoint(PATH, 2, pos, tol=0.6, lookahead=WAYPOINT_LOOKAHEAD, in_sight=lambda p, w: False) == 2
    # no move, no question
    assert advance_waypoint(PATH, 2, np.array([-3.0, 0.0]), tol=0.6, lookahead=4, in_sight=lambda p, w: 1 / 0) == 2


def test_waypoint_sight_follows_the_constant_and_sees_through_the_door_only(monkeypatch):
    from navzoo.envs import amp_humans
    from navzoo.envs.nav_env import NavEnv

    env = NavEnv(scene="doorway", n_robots=0, n_humans=1, human_model="amp", crowd_model="sfm", time_limit=5.0)
    env.reset(seed=0)
    assert env.waypoint_sight(0) is None  # off by default
    monkeypatch.setattr(amp_humans, "WAYPOINT_ADVANCE_IN_SIGHT", True)
    sight = env.waypoint_sight(0)
    assert sight(np.array([7.2, 4.0]), np.array([9.0, 4.0]))  # straight through the 1.0 m door
    assert not sight(np.array([7.2, 5.5]), np.array([9.0, 5.5]))  # through the wall beside it
    assert sight(np.array([7.85, 5.0]), np.array([7.0, 5.0]))  # from inside the inflated wall: its nearest free point
    env.close()


def _door(gap: float = 0.9, thickness: float = 0.12) -> np.ndarray:
    """A wall along y = 0 from x = -3 to 3 with a door of ``gap`` centred on x = 0, as closed outlines."""
    segs = []
    h = thickness / 2
    for x0, x1 in ((-3.0, -gap / 2), (gap / 2, 3.0)):
        corners = [(x0, -h), (x1, -h), (x1, h), (x0, h)]
        segs += [[corners[i], corners[(i + 1) % 4]] for i in range(4)]
    return np.asarray(segs, dtype=float)


def _walk(wall_radius, x0: float, seconds: float = 5.0) -> np.ndarray:
    segs = _door()
    groups = np.repeat(np.arange(2), 4)
    pos, vel = np.array([[x0, -1.0]]), np.zeros((1, 2))
    for _ in range(int(seconds / 0.1)):
        vel = social_force_velocities(pos, vel, np.array([[0.0, 1.2]]), 0.4, 2.0, 0.1, SocialForceParams(), segs,
                                      segment_groups=groups, wall_radius=wall_radius)
        pos = pos + 0.1 * vel
    return pos[0]


def test_a_padded_body_stops_at_a_door_that_its_wall_radius_passes():
    # 0.4 m on both people and walls, entering 0.15 m off the door's axis: the jambs hold it back.
    assert _walk(None, 0.15)[1] < 0.0
    # The same 0.4 m towards people but 0.3 m towards walls walks through.
    assert _walk(0.3, 0.15)[1] > 2.0


def test_wall_radius_changes_only_the_wall_term():
    pos = np.array([[0.0, -0.5], [1.0, -0.6]])
    vel = np.zeros((2, 2))
    pref = np.array([[0.0, 1.0], [0.0, 1.0]])
    segs, groups = _door(), np.repeat(np.arange(2), 4)
    a = social_forces(pos, vel, pref, 0.4, SocialForceParams(), segs, segment_groups=groups)
    b = social_forces(pos, vel, pref, 0.4, SocialForceParams(), segs, segment_groups=groups, wall_radius=0.3)
    np.testing.assert_allclose(a.people, b.people)
    np.testing.assert_allclose(a.goal, b.goal)
    assert np.linalg.norm(b.walls[1]) < np.linalg.norm(a.walls[1])  # a smaller body feels the wall less
    c = social_forces(pos, vel, pref, 0.4, SocialForceParams(), segs, segment_groups=groups, wall_radius=0.4)
    np.testing.assert_allclose(a.walls, c.walls)


def test_wall_radius_shape_is_checked():
    with pytest.raises(ValueError, match="wall_radius"):
        social_forces(np.zeros((2, 2)), np.zeros((2, 2)), np.zeros((2, 2)), 0.3, SocialForceParams(),
                      wall_radius=np.ones(3))


def test_limit_turn_caps_the_heading_rate_and_slows_sharp_turns():
    from navzoo.envs.amp_humans import limit_turn

    v_prev = np.array([[1.2, 0.0], [1.2, 0.0], [0.0, 0.0], [1.0, 0.0]])
    v_new = np.array([[-1.2, 1e-6], [1.1, 0.1], [0.0, 1.0], [0.0, 1.0]])
    out = limit_turn(v_prev, v_new, max_angle=0.2)
    # A U-turn: the heading turns by 0.2 rad and the disc slows to the minimum speed.
    assert np.arctan2(out[0, 1], out[0, 0]) == pytest.approx(0.2, abs=1e-6)
    assert np.linalg.norm(out[0]) == pytest.approx(0.2)
    np.testing.assert_allclose(out[1], v_new[1])  # a turn within the limit is left alone
    np.testing.assert_allclose(out[2], v_new[2])  # starting from standstill: any heading
    # A 90-degree turn: 0.2 rad of it, at half the speed.
    assert np.arctan2(out[3, 1], out[3, 0]) == pytest.approx(0.2, abs=1e-6)
    assert np.linalg.norm(out[3]) == pytest.approx(0.5)
    # Repeated, a U-turn takes pi / 0.2 steps.
    v, steps = v_prev[:1].copy(), 0
    while np.dot(v[0], [-1.0, 0.0]) < 0.99 * np.linalg.norm(v[0]):
        v = limit_turn(v, np.array([[-1.2, 0.0]]), max_angle=0.2)
        steps += 1
    assert steps == int(np.ceil(np.pi / 0.2))


def test_limit_accel_caps_the_speed_up_and_leaves_slowing_down_alone():
    from navzoo.envs.amp_humans import limit_accel

    v_prev = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 0.0], [0.3, 0.4]])
    v_new = np.array([[0.0, 1.3], [0.2, 0.0], [1.05, 0.0], [0.0, 1.5]])
    out = limit_accel(v_prev, v_new, max_dv=0.08)
    np.testing.assert_allclose(out[0], [0.0, 0.08])  # from standstill: 0.08 m/s more, in the new direction
    np.testing.assert_allclose(out[1], v_new[1])  # braking is not limited
    np.testing.assert_allclose(out[2], v_new[2])  # within the limit
    np.testing.assert_allclose(out[3], [0.0, 0.58])  # speed 0.5 -> 0.58, direction of v_new
    assert out is not v_new and np.all(v_new[0] == [0.0, 1.3])  # the input is not changed


def test_target_accel_limits_how_fast_a_rollout_speeds_up_from_the_body():
    """With TARGET_ACCEL set, a standing person's social-force target covers no more ground in the first
    second than a constant acceleration from rest would (0.5 a t^2), plus one plan step of slack."""
    import navzoo.envs.amp_humans as ah
    from navzoo.envs.nav_env import NavEnv

    def first_second(accel: float) -> float:
        old = ah.TARGET_ACCEL
        ah.TARGET_ACCEL = accel
        env = NavEnv(scene="station", n_robots=0, n_humans=1, human_model="amp", dt=1.0 / 30.0)
        try:
            env.reset(seed=0)
            path = env.amp.paths[0]
            return float(np.linalg.norm(path[ah.CONTROL_HZ] - path[0]))
        finally:
            ah.TARGET_ACCEL = old
            env.close()

    free, limited = first_second(0.0), first_second(0.8)
    assert limited <= 0.5 * 0.8 * 1.0 ** 2 + 0.8 * ah.PLAN_DT + 1e-6
    assert free > limited + 0.1


def _door_clearance(gap: float):
    segs = _door(gap)

    def clearance(points: np.ndarray) -> np.ndarray:
        from navzoo.world import geometry as geo

        return geo.min_distance_to_segments(np.asarray(points, dtype=float), segs)

    return segs, clearance


def _graded_walk(gap: float, x0: float, margin: float = 0.1, seconds: float = 6.0) -> tuple[np.ndarray, list[float]]:
    """A lone 0.4 m rollout disc walking up through the door along a straight path on its axis, with the
    wall radius graded as the physics pedestrians' target rollouts do; returns its end and wall radii."""
    from navzoo.envs.amp_humans import graded_wall_radius, narrow_points

    segs, clearance = _door_clearance(gap)
    groups = np.repeat(np.arange(2), 4)
    path = np.array([[0.0, -2.0], [0.0, 3.0]])
    narrow = [narrow_points(path, clearance, 0.3 + margin + 0.1)]
    pos, vel, radii = np.array([[x0, -2.0]]), np.zeros((1, 2)), []
    for _ in range(int(seconds / 0.1)):
        wall_r = graded_wall_radius(pos, np.array([0.3]), margin, narrow)
        radii.append(float(wall_r[0]))
        vel = social_force_velocities(pos, vel, np.array([[0.0, 1.2]]), 0.4, 2.0, 0.1, SocialForceParams(), segs,
                                      segment_groups=groups, wall_radius=wall_r)
        pos = pos + 0.1 * vel
    return pos[0], radii


def test_narrow_points_are_the_door_stretch_of_a_path():
    from navzoo.envs.amp_humans import narrow_points

    _, clearance = _door_clearance(0.9)
    pts, c = narrow_points(np.array([[0.0, -2.0], [0.0, 2.0]]), clearance, 0.5)
    assert len(pts) > 0 and np.all(np.abs(pts[:, 1]) < 0.5)  # only near the wall's line
    assert c.min() == pytest.approx(0.45, abs=1e-6)  # the door's half width, at its centre
    assert len(narrow_points(np.array([[0.0, -2.0], [0.0, 2.0]]), _door_clearance(1.4)[1], 0.5)[0]) == 0


def test_graded_wall_margin_lets_a_rollout_through_a_door_its_full_margin_stops_at():
    # The same start as test_a_padded_body_stops_at_a_door_that_its_wall_radius_passes: 0.15 m off the axis.
    assert _walk(0.4, 0.15)[1] < 0.0  # the full 0.1 m wall margin: held back by the jambs
    end, radii = _graded_walk(0.9, 0.15)
    assert end[1] > 2.5
    assert min(radii) == pytest.approx(0.35)  # 0.45 m half width - 0.1 m slack
    assert radii[0] == pytest.approx(0.4) and radii[-1] == pytest.approx(0.4)  # full margin away from the door


def test_graded_wall_margin_keeps_the_full_margin_in_a_wide_door():
    _, radii = _graded_walk(1.2, 0.0)
    assert np.allclose(radii, 0.4)


def test_physics_pedestrians_plan_the_home_doors_with_the_graded_margin():
    """In the home (0.9 m doors) the paths through a door get narrow points with the door's half width."""
    from navzoo.envs.nav_env import NavEnv

    env = NavEnv(scene="home", n_robots=0, n_humans=3, human_model="amp", dt=1.0 / 30.0)
    try:
        env.reset(seed=0)
        narrow = env.amp.narrow_passages([env.paths[i] for i in range(3)], env.radius[:3])
        through_door = [c for _, c in narrow if len(c)]
        assert through_door, "no person's path in the home passes a door"
        assert min(float(c.min()) for c in through_door) < 0.46
    finally:
        env.close()


def test_a_body_that_swerved_past_all_its_next_waypoints_moves_on_only_where_it_sees_the_next():
    from navzoo.envs.amp_humans import passed

    # Waypoint 2 is at x = 1.0; the body went round a group 0.8 m to the side and is now at x = 3.2:
    # beyond the tolerance of waypoints 2..6, so the tolerance and lookahead rules keep waypoint 2.
    pos = np.array([3.2, 0.8])
    assert advance_waypoint(PATH, 2, pos, tol=0.6, lookahead=4) == 2
    assert passed(PATH, 2, pos) and not passed(PATH, 7, pos)
    # With a line of sight everywhere it moves past every waypoint it is beyond: on to waypoint 7 (x = 3.5).
    assert advance_waypoint(PATH, 2, pos, tol=0.6, lookahead=4, visible=lambda a, b: True) == 7
    # A wall between it and the next waypoints keeps the old rule, and so does the strict order.
    assert advance_waypoint(PATH, 2, pos, tol=0.6, lookahead=4, visible=lambda a, b: False) == 2
    assert advance_waypoint(PATH, 2, pos, tol=0.6, lookahead=0, visible=lambda a, b: True) == 2


def test_skipping_passed_waypoints_is_an_env_option_off_by_default():
    import navzoo.envs.amp_humans as ah
    from navzoo.envs.nav_env import NavEnv

    assert ah.SKIP_PASSED_WAYPOINTS is False
    env = NavEnv(scene="station", n_robots=0, n_humans=1, human_model="amp", dt=1.0 / 30.0)
    try:
        env.reset(seed=0)
        assert env.waypoint_visibility(0) is None
        ah.SKIP_PASSED_WAYPOINTS = True
        see = env.waypoint_visibility(0)
        path = env.paths[0]
        assert see is not None and see(path[0], path[1])  # consecutive A* waypoints see each other
    finally:
        ah.SKIP_PASSED_WAYPOINTS = False
        env.close()


def test_keep_apart_rollouts_hold_the_margin_without_pushing_walkers_aside():
    """Two people walking side by side 0.9 m apart: rollouts on radii widened by the margin push them apart;
    with KEEP_APART the social repulsion is that of the bare discs, and the push keeps the margin."""
    import navzoo.envs.amp_humans as ah
    from navzoo.envs.nav_env import NavEnv

    def rollouts(keep: bool) -> np.ndarray:
        old, old_pass = ah.KEEP_APART, ah.PASS_MARGIN
        ah.KEEP_APART, ah.PASS_MARGIN = keep, False  # against the margin on the radius of every pair
        env = NavEnv(scene="circle_crossing", n_robots=0, n_humans=2, human_model="amp", dt=1.0 / 30.0)
        try:
            env.reset(seed=0, options={"human_starts": [[-3.0, 0.45], [-3.0, -0.45]],
                                       "human_goals": [[3.0, 0.45], [3.0, -0.45]]})
            return env.amp.paths.copy()
        finally:
            ah.KEEP_APART, ah.PASS_MARGIN = old, old_pass
            env.close()

    wide, keep = rollouts(False), rollouts(True)
    gap = {name: np.linalg.norm(p[0] - p[1], axis=1) for name, p in (("wide", wide), ("keep", keep))}
    assert gap["keep"].min() >= 2 * 0.3 + 2 * ah.PLAN_MARGIN - 0.02
    assert gap["keep"][-1] < gap["wide"][-1] - 0.05


def test_pass_margin_rollouts_keep_room_from_people_met_not_from_people_walked_with(monkeypatch):
    """PASS_MARGIN: two people walking side by side are not pushed apart as radii widened by the margin push
    them; two people who meet head-on on close lines pass as far apart as with the widened radii."""
    import navzoo.envs.amp_humans as ah
    from navzoo.envs.nav_env import NavEnv

    assert ah.PASS_MARGIN is True  # on by default

    def rollouts(on: bool, starts, goals) -> np.ndarray:
        monkeypatch.setattr(ah, "PASS_MARGIN", on)
        env = NavEnv(scene="circle_crossing", n_robots=0, n_humans=2, human_model="amp", dt=1.0 / 30.0)
        try:
            env.reset(seed=0, options={"human_starts": starts, "human_goals": goals})
            return env.amp.paths.copy()
        finally:
            env.close()

    side = ([[-3.0, 0.45], [-3.0, -0.45]], [[3.0, 0.45], [3.0, -0.45]])
    # each has the other on its right: keeping right would take them across each other's line
    meet = ([[-3.0, 0.2], [3.0, -0.2]], [[3.0, 0.2], [-3.0, -0.2]])
    default_bias = ah.SFM_SIDE_BIAS
    monkeypatch.setattr(ah, "SFM_SIDE_BIAS", 0.1)  # the mechanism, with the kinematic crowd's keep-right gain
    gap = {(name, on): np.linalg.norm(np.subtract(*rollouts(on, *pair)), axis=1)
           for name, pair in (("side", side), ("meet", meet)) for on in (False, True)}
    assert gap["side", True][-1] < gap["side", False][-1] - 0.05
    assert gap["meet", True].min() == pytest.approx(gap["meet", False].min(), abs=0.03)
    # with the default, stronger gain (0.4) such a pair passes nearer than the widened radii would keep it (0.93 m
    # against 1.09 m between centres), but the discs widened by the planning margin still do not touch
    monkeypatch.setattr(ah, "SFM_SIDE_BIAS", default_bias)
    met = np.linalg.norm(np.subtract(*rollouts(True, *meet)), axis=1).min()
    assert 2 * (0.3 + ah.PLAN_MARGIN) < met < gap["meet", True].min()


def test_target_speed_cap_holds_social_force_rollouts_to_the_preferred_speed(monkeypatch):
    from navzoo.envs import amp_humans
    from navzoo.envs.nav_env import NavEnv

    assert amp_humans.TARGET_SPEED_CAP == 0.0  # off by default
    env = NavEnv(scene="circle_crossing", n_robots=0, n_humans=8, human_model="amp", dt=1 / 30, time_limit=10.0)
    env.reset(seed=0)
    peak = peak_target_pace(env, monkeypatch, "TARGET_SPEED_CAP", (0.0, 0.5))
    v_pref = env.v_pref.copy()
    env.close()
    assert (peak[0.5] <= 0.5 * v_pref * 1.01 + 1e-6).all()
    assert (peak[0.0] > 0.5 * v_pref * 1.3).all()  # uncapped, the rollouts walk at about the preferred speed


def _lead_of_targets_over_standing_bodies(monkeypatch, **constants) -> float:
    """How far (m) social-force targets run ahead of two bodies that stand still for a second after a reset."""
    from navzoo.envs import amp_humans
    from navzoo.envs.nav_env import NavEnv

    for name, value in constants.items():
        monkeypatch.setattr(amp_humans, name, value)
    env = NavEnv(scene="circle_crossing", n_robots=0, n_humans=2, human_model="amp", dt=1 / 30, time_limit=10.0)
    env.reset(seed=0)
    amp = env.amp
    for _ in range(30):  # zero actions: the bodies stand (or sag) while their targets run on
        env.step({a: np.zeros(env.action_space(a).shape, dtype=np.float32) for a in env.agents})
    lead = float(np.linalg.norm(amp.target_now() - amp.planar()[0], axis=1).max())
    env.close()
    return lead


def test_lag_limit_holds_social_force_targets_by_default(monkeypatch):
    from navzoo.envs import amp_humans

    assert amp_humans.LAG_LIMIT_RULES is True  # one pacing rule for every target generator
    free = _lead_of_targets_over_standing_bodies(monkeypatch, LAG_LIMIT_RULES=False)
    held = _lead_of_targets_over_standing_bodies(monkeypatch, LAG_LIMIT_RULES=True)
    assert held < 0.7 * free  # measured: 1.52 m ahead of a standing body by time alone, 0.84 m with the limit


def test_start_lag_holds_only_the_first_plan_of_a_trip(monkeypatch):
    from navzoo.envs import amp_humans
    from navzoo.envs.nav_env import NavEnv

    assert amp_humans.START_LAG is False
    # START_LAG matters only without the lag limit on every plan (LAG_LIMIT_RULES, on by default), which holds
    # the first plan of a trip too
    free = _lead_of_targets_over_standing_bodies(monkeypatch, START_LAG=False, LAG_LIMIT_RULES=False)
    held = _lead_of_targets_over_standing_bodies(monkeypatch, START_LAG=True, LAG_LIMIT_RULES=False)  # a reset starts every trip
    assert held < 0.7 * free
    always = _lead_of_targets_over_standing_bodies(monkeypatch, START_LAG=False, LAG_LIMIT_RULES=True)
    assert always == pytest.approx(held, abs=1e-6)
    env = NavEnv(scene="circle_crossing", n_robots=0, n_humans=2, human_model="amp", dt=1 / 30, time_limit=10.0)
    env.reset(seed=0)
    amp = env.amp
    assert amp.starting.all()
    amp.plan_all()  # a regular replan: nobody got a new goal since the last plan
    assert not amp.starting.any()
    env.goals_reached[env.n_robots] += 1  # the first person got a new goal
    amp.plan_all()
    assert amp.starting.tolist() == [True, False]
    env.close()


def test_start_replan_plans_once_more_after_a_replan_that_new_goals_asked_for(monkeypatch):
    from navzoo.envs import amp_humans
    from navzoo.envs.nav_env import NavEnv

    assert amp_humans.START_REPLAN_S == 0.0
    env = NavEnv(scene="circle_crossing", n_robots=0, n_humans=2, human_model="amp", dt=1 / 30, time_limit=10.0)
    env.reset(seed=0)
    amp = env.amp
    amp.after_step(replan=True)
    assert amp.extra_replan == -1  # off
    monkeypatch.setattr(amp_humans, "START_REPLAN_S", 0.5)
    amp.t += 1
    amp.after_step(replan=True)
    t0 = amp.t
    assert amp.extra_replan == t0 + 15 and (amp.plan_t == t0).all()
    amp.t += 14
    amp.after_step(replan=False)
    assert (amp.plan_t == t0).all()  # not yet
    amp.t += 1
    amp.after_step(replan=False)
    assert (amp.plan_t == t0 + 15).all() and amp.extra_replan == -1  # once, then the regular period
    env.close()


def test_event_replan_own_gives_new_targets_only_to_the_people_of_the_event(monkeypatch):
    from navzoo.envs import amp_humans
    from navzoo.envs.nav_env import NavEnv

    assert amp_humans.EVENT_REPLAN_OWN is False
    env = NavEnv(scene="circle_crossing", n_robots=0, n_humans=3, human_model="amp", dt=1 / 30, time_limit=10.0)
    env.reset(seed=0)
    amp = env.amp
    for _ in range(10):  # walk a little, so that a new rollout differs from the plan of the reset
        env.step({a: env.action_space(a).sample() * 0 for a in env.agents})
    t_before = amp.plan_t.copy()
    who = np.array([False, True, False])
    amp.t += 1
    amp.after_step(replan=who)  # off: an event re-rolls everyone
    assert (amp.plan_t == amp.t).all() and (amp.k_prog == 0).all()
    monkeypatch.setattr(amp_humans, "EVENT_REPLAN_OWN", True)
    for _ in range(5):
        env.step({a: env.action_space(a).sample() * 0 for a in env.agents})
    paths, plan_t, k_prog = amp.paths.copy(), amp.plan_t.copy(), amp.k_prog.copy()
    assert (k_prog > 0).all() and (plan_t > t_before).all()
    amp.t += 1
    amp.after_step(replan=who)
    assert amp.plan_t.tolist() == [plan_t[0], amp.t, plan_t[2]]
    assert amp.k_prog.tolist() == [k_prog[0], 0, k_prog[2]]
    np.testing.assert_array_equal(amp.paths[[0, 2]], paths[[0, 2]])  # the others keep their targets
    assert not np.allclose(amp.paths[1], paths[1])
    amp.after_step(replan=np.zeros(3, dtype=bool))  # no event, not due: nothing changes
    assert amp.plan_t.tolist() == [plan_t[0], amp.t, plan_t[2]]
    amp.t = int(amp.plan_t.min()) + amp.replan_steps  # the oldest plan is due: everyone plans again
    amp.after_step(replan=who)
    assert (amp.plan_t == amp.t).all()
    with pytest.raises(ValueError, match="replan must be"):
        amp.after_step(replan=np.zeros(2, dtype=bool))
    env.close()
