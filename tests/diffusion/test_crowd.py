"""The diffusion crowd in the env: plans start at the people, follow guidance, run in both body models."""

from __future__ import annotations

import numpy as np
import pytest
import torch
from pettingzoo.test import parallel_api_test

from navzoo.agents.crowd import CrowdPolicy
from navzoo.agents.diffusion.crowd import DiffusionCrowd, _ahead_from_nearest, _ahead_on_path, _in_sight
from navzoo.agents.diffusion.model import DiffusionConfig, TrajectoryDiffusion
from navzoo.agents.diffusion.trainer import TrainConfig, export, train
from navzoo.envs.nav_env import NavEnv
from navzoo.envs.wrappers import FrozenAgents
from tests.amp_helpers import peak_target_pace

CFG = DiffusionConfig(base=8, mults=(1, 2), cond_dim=32, map_cells=32, steps=20, sample_steps=4)


@pytest.fixture(scope="module")
def model_dir(tmp_path_factory):
    """A tiny model trained for a few steps on straight walking (enough to exercise the plumbing)."""
    rng = np.random.default_rng(0)
    n = 64
    speed = rng.uniform(0.8, 1.4, n)
    k, kf = np.arange(-7, 1), np.arange(1, 13)
    w = {"hist": np.stack([k[None] * 0.4 * speed[:, None], np.zeros((n, 8))], -1),
         "fut": np.stack([kf[None] * 0.4 * speed[:, None], np.zeros((n, 12))], -1), "dt": np.full(n, 0.4)}
    tmp = tmp_path_factory.mktemp("diffusion")
    torch.manual_seed(0)
    train(CFG, TrainConfig(steps=30, batch_size=16), w, tmp / "run", log=lambda *_: None)
    return export(tmp / "run/checkpoint", tmp / "model")


def test_ahead_on_path_walks_the_polyline():
    path = np.array([[1.0, 0.0], [1.0, 2.0]])
    np.testing.assert_allclose(_ahead_on_path(path, np.zeros(2), 0.5), [0.5, 0.0])
    np.testing.assert_allclose(_ahead_on_path(path, np.zeros(2), 2.0), [1.0, 1.0])
    np.testing.assert_allclose(_ahead_on_path(path, np.zeros(2), 9.0), [1.0, 2.0])
    # extend: beyond the end along the last segment's line
    np.testing.assert_allclose(_ahead_on_path(path, np.zeros(2), 4.0, extend=True), [1.0, 3.0])


def test_target_is_measured_from_the_nearest_path_point_not_a_missed_waypoint():
    path = np.array([[float(x), 0.0] for x in range(11)])  # 0..10 m along x
    # The person passed waypoints 1..5 half a metre to the side: the env's index is still 1.
    pos = np.array([5.2, 0.5])
    np.testing.assert_allclose(_ahead_from_nearest(path, 1, pos, 3.0), [8.2, 0.0])
    # Near the end: held at the goal, or carried on past it along the last segment.
    np.testing.assert_allclose(_ahead_from_nearest(path, 9, np.array([9.0, 0.2]), 3.0), [10.0, 0.0])
    np.testing.assert_allclose(_ahead_from_nearest(path, 9, np.array([9.0, 0.2]), 3.0, extend=True), [12.0, 0.0])
    # A one-point path (the goal): toward it from the position.
    np.testing.assert_allclose(_ahead_from_nearest(np.array([[4.0, 0.0]]), 0, np.zeros(2), 1.0), [1.0, 0.0])


def _wall_sight(y: float = 1.0):
    """Sight blocked by a wall along y = ``y`` for x < 4 (a U-shaped path: out along y = 0, back along y = 2)."""
    def sight(pos, pts):
        pts = np.asarray(pts).reshape(-1, 2)
        cross = (pos[1] - y) * (pts[:, 1] - y) < 0
        f = (y - pos[1]) / np.where(pts[:, 1] == pos[1], 1e-12, pts[:, 1] - pos[1])
        x = pos[0] + f * (pts[:, 0] - pos[0])
        return ~(cross & (x < 4.0))
    return sight


def test_path_points_are_taken_on_the_persons_side_of_a_wall():
    # A U-shaped path: out along y = -0.3, up at x = 5, back along y = 1.6; a wall along y = 1 (x < 4) parts
    # the two legs. A person pushed up against the wall's underside is nearer the back leg (0.61 m) than its own.
    path = np.array([[0.0, -0.3], [5.0, -0.3], [5.0, 1.6], [0.0, 1.6]])
    pos = np.array([2.0, 0.99])
    sight = _wall_sight()
    old = _ahead_from_nearest(path, 1, pos, 1.0)
    assert old[1] == pytest.approx(1.6) and not sight(pos, old)[0]  # measured on the leg behind the wall
    np.testing.assert_allclose(_ahead_from_nearest(path, 1, pos, 1.0, sight=sight), [3.0, -0.3])  # its own leg
    # never farther than the path stays in sight: up the x = 5 leg, sight ends just below y = 1
    far = _ahead_from_nearest(path, 1, pos, np.array([1.0, 4.0, 8.0]), sight=sight)
    np.testing.assert_allclose(far, [[3.0, -0.3], [5.0, 0.7], [5.0, 0.95]], atol=1e-9)
    assert sight(pos, far).all()
    # a floor on the hold: no nearer than 5 m along the path (hidden or not), and never beyond the distance asked
    floored = _ahead_from_nearest(path, 1, pos, np.array([1.0, 4.0, 8.0]), sight=sight, hold_floor=5.0)
    np.testing.assert_allclose(floored, [[3.0, -0.3], [5.0, 0.7], [4.9, 1.6]], atol=1e-9)
    low = _ahead_from_nearest(path, 1, pos, np.array([1.0, 4.0, 8.0]), sight=sight, hold_floor=3.5)
    np.testing.assert_allclose(low, far, atol=1e-9)  # a floor below where sight ends changes nothing
    # without holding them in sight they run on round the bend, still from the person's own leg
    on = _ahead_from_nearest(path, 1, pos, np.array([1.0, 4.0, 8.0]), sight=sight, hold_in_sight=False)
    np.testing.assert_allclose(on, [[3.0, -0.3], [5.0, 0.7], [1.9, 1.6]], atol=1e-9)
    # in the open the points are those without sight
    np.testing.assert_allclose(_ahead_from_nearest(path, 1, np.array([2.0, 0.2]), np.array([1.0, 4.0]), sight=sight),
                               _ahead_from_nearest(path, 1, np.array([2.0, 0.2]), np.array([1.0, 4.0])))
    # a person who sees no point of its path gets the points as without sight
    blind = _ahead_from_nearest(path, 1, pos, 1.0, sight=lambda p, q: np.zeros(len(np.reshape(q, (-1, 2))), bool))
    np.testing.assert_allclose(blind, old)


def test_floor_in_sight_reaches_past_a_pillar_not_round_a_wall():
    # A straight path along y = 0 with a pillar's shadow over 3.4 < x < 4.6: the path leaves sight at 3.4 m and
    # is seen again from 4.6 m on.
    path = np.array([[float(x), 0.0] for x in range(11)])
    pos = np.array([0.0, 0.2])

    def pillar(p, pts):
        pts = np.asarray(pts).reshape(-1, 2)
        return ~((pts[:, 0] > 3.4) & (pts[:, 0] < 4.6))

    d = np.array([1.0, 6.0])
    held = _ahead_from_nearest(path, 1, pos, d, sight=pillar)
    np.testing.assert_allclose(held, [[1.0, 0.0], [3.25, 0.0]])  # held where the path leaves sight
    # the floor point 5 m along is in sight again: the floor applies as without floor_in_sight
    for fis in (False, True):
        np.testing.assert_allclose(_ahead_from_nearest(path, 1, pos, d, sight=pillar, hold_floor=5.0,
                                                       floor_in_sight=fis), [[1.0, 0.0], [5.0, 0.0]])
    # a floor point in the shadow: floor_in_sight takes the farthest point seen up to it (here the held one)
    np.testing.assert_allclose(_ahead_from_nearest(path, 1, pos, d, sight=pillar, hold_floor=4.5),
                               [[1.0, 0.0], [4.5, 0.0]])
    np.testing.assert_allclose(_ahead_from_nearest(path, 1, pos, d, sight=pillar, hold_floor=4.5,
                                                   floor_in_sight=True), held)
    # round a wall (the U-shaped path of the test above) the path stays hidden: the points stay where sight ends
    upath = np.array([[0.0, -0.3], [5.0, -0.3], [5.0, 1.6], [0.0, 1.6]])
    upos, sight = np.array([2.0, 0.99]), _wall_sight()
    far = _ahead_from_nearest(upath, 1, upos, np.array([1.0, 4.0, 8.0]), sight=sight)
    floored = _ahead_from_nearest(upath, 1, upos, np.array([1.0, 4.0, 8.0]), sight=sight, hold_floor=5.0,
                                  floor_in_sight=True)
    np.testing.assert_allclose(floored, far, atol=1e-9)
    assert sight(upos, floored).all()


def test_floor_ray_goes_on_along_the_line_of_sight_where_the_path_stays_hidden():
    # The U-shaped path round a wall: sight ends at (5, 0.95), 4.25 m along the path; the floor asks for 5 m.
    upath = np.array([[0.0, -0.3], [5.0, -0.3], [5.0, 1.6], [0.0, 1.6]])
    upos, sight = np.array([2.0, 0.99]), _wall_sight()
    d = np.array([1.0, 4.0, 8.0])
    far = _ahead_from_nearest(upath, 1, upos, d, sight=sight)
    last = far[-1]
    np.testing.assert_allclose(last, [5.0, 0.95], atol=1e-9)
    ray = _ahead_from_nearest(upath, 1, upos, d, sight=sight, hold_floor=5.0, floor_ray=True)
    np.testing.assert_allclose(ray[:2], far[:2], atol=1e-9)  # up to where sight ends: on the path
    u = (last - upos) / np.linalg.norm(last - upos)
    np.testing.assert_allclose(ray[2], last + 0.75 * u, atol=1e-9)  # then 0.75 m on along the line of sight
    assert sight(upos, ray).all()
    # not round the wall along the hidden path (the plain floor), nor held at the jamb (floor_in_sight)
    assert not sight(upos, _ahead_from_nearest(upath, 1, upos, d, sight=sight, hold_floor=5.0)[2:])[0]
    # a scalar distance (the end target) gets the same point
    np.testing.assert_allclose(_ahead_from_nearest(upath, 1, upos, 8.0, sight=sight, hold_floor=5.0, floor_ray=True),
                               ray[2], atol=1e-9)
    # the line stops where it leaves sight: a second wall across x = 5.4 ends the run at the last probe before it
    def boxed(p, pts):
        pts = np.asarray(pts).reshape(-1, 2)
        return sight(p, pts) & (pts[:, 0] < 5.4)
    short = _ahead_from_nearest(upath, 1, upos, d, sight=boxed, hold_floor=5.0, floor_ray=True)
    np.testing.assert_allclose(short[2], last + 0.25 * u, atol=1e-9)
    # past a pillar, where the floor point is seen again, it is the floor along the path (as floor_in_sight)
    path = np.array([[float(x), 0.0] for x in range(11)])

    def pillar(p, pts):
        pts = np.asarray(pts).reshape(-1, 2)
        return ~((pts[:, 0] > 3.4) & (pts[:, 0] < 4.6))

    np.testing.assert_allclose(_ahead_from_nearest(path, 1, np.array([0.0, 0.2]), np.array([1.0, 6.0]), sight=pillar,
                                                   hold_floor=5.0, floor_ray=True), [[1.0, 0.0], [5.0, 0.0]])


def test_in_sight_follows_the_scene_walls():
    env = NavEnv(scene="home", n_robots=0, n_humans=1)
    env.reset(seed=0)
    sight = _in_sight(env)
    pos = np.array([9.3, 5.4])  # under the home's wall at y = 6, away from its door
    seen = sight(pos, np.array([[9.3, 6.75], [10.5, 5.4], [11.3, 5.0]]))
    assert seen.tolist() == [False, True, True]
    env.close()


def test_missing_model_is_a_clear_error(tmp_path):
    with pytest.raises(FileNotFoundError, match="navzoo train diffusion"):
        DiffusionCrowd(tmp_path)
    with pytest.raises(ValueError, match="n_samples"):
        DiffusionCrowd(TrajectoryDiffusion(CFG), n_samples=0)


def test_kinematic_diffusion_crowd_plans_from_the_people_and_walks(model_dir):
    env = NavEnv(scene="lobby", n_robots=1, n_humans=6, crowd_model="diffusion", diffusion_model=str(model_dir),
                 diffusion_samples=2, time_limit=8.0)
    w = FrozenAgents(env, lambda a: a.startswith("human_"), CrowdPolicy("diffusion"))
    w.reset(seed=3)
    start = env.pos[1:].copy()
    plan = env.diffusion.plan_now(env)
    assert plan.shape == (6, 13, 2) and np.isfinite(plan).all()
    np.testing.assert_allclose(plan[:, 0], start, atol=1e-6)
    for _ in range(40):
        w.step({"robot_0": np.zeros(2, dtype=np.float32)})
    assert env.diffusion.plans_made >= 2  # replanned every 2 s
    assert np.linalg.norm(env.pos[1:] - start, axis=1).mean() > 1.0  # people walk (4 s at ~1.2 m/s)
    # Same seed, same plans.
    w.reset(seed=3)
    np.testing.assert_allclose(env.diffusion.plan_now(env), plan)
    w.close()


def test_diffusion_crowd_passes_the_parallel_api_with_amp_bodies(model_dir):
    env = NavEnv(scene="lobby", n_robots=1, n_humans=2, crowd_model="diffusion", diffusion_model=str(model_dir),
                 human_model="amp", dt=1 / 30, max_episode_steps_override=40)
    parallel_api_test(env, num_cycles=40)
    env.reset(seed=0)
    assert env.amp.paths.shape[0] == 2 and np.isfinite(env.amp.paths).all()
    np.testing.assert_allclose(env.amp.paths[:, 0], env.pos[1:], atol=0.05)
    env.close()


def test_crowd_model_name_is_validated():
    with pytest.raises(ValueError, match="'diffusion'"):
        NavEnv(scene="lobby", crowd_model="trace")
    with pytest.raises(ValueError, match="diffusion_samples"):
        NavEnv(scene="lobby", crowd_model="diffusion", diffusion_samples=0)
    with pytest.raises(ValueError, match="diffusion_walker"):
        NavEnv(scene="lobby", crowd_model="diffusion", diffusion_walker="rvo")


def test_amp_target_paths_start_at_the_bodies_and_ramp_up_from_their_speed(model_dir):
    from navzoo.agents.diffusion.crowd import ACCEL_LIMIT, AMP_SPEED_FACTOR

    env = NavEnv(scene="lobby", n_robots=0, n_humans=3, crowd_model="diffusion", diffusion_model=str(model_dir),
                 human_model="amp", dt=1 / 30, time_limit=10.0)
    env.reset(seed=0)  # bodies at rest; the model's plans start at walking pace (walking-in histories)
    paths = env.diffusion.plan_positions(env, 1 / 30, 60)
    np.testing.assert_allclose(paths[:, 0], env.pos, atol=0.05)  # starts at the bodies
    pace = np.linalg.norm(np.diff(paths, axis=1), axis=2) * 30
    v0 = np.linalg.norm(env.vel, axis=1)
    t = np.arange(1, 61) / 30
    assert (pace <= AMP_SPEED_FACTOR * env.v_pref[:, None] + 1e-6).all()
    assert (pace <= v0[:, None] + ACCEL_LIMIT * t[None] + 1e-6).all()
    env.close()


def test_new_goal_replans_only_that_person_and_plans_blend(model_dir):
    env = NavEnv(scene="lobby", n_robots=0, n_humans=4, crowd_model="diffusion", diffusion_model=str(model_dir),
                 diffusion_samples=2, time_limit=8.0)
    w = FrozenAgents(env, lambda a: a.startswith("human_"), CrowdPolicy("diffusion"))
    w.reset(seed=1)
    for _ in range(5):
        w.step({})
    crowd = env.diffusion
    before, t0_before, made = crowd.plan.copy(), crowd.plan_t0.copy(), crowd.plans_made
    env.goals_reached[2] += 1  # person 2 got a new goal (as the env does when it reaches one)
    crowd.maybe_plan(env)
    assert crowd.plans_made == made + 1
    keep = [0, 1, 3]
    np.testing.assert_array_equal(crowd.plan[keep], before[keep])  # the others keep their plans
    np.testing.assert_array_equal(crowd.plan_t0[keep], t0_before[keep])
    assert crowd.plan_t0[2] == crowd.hist_time > t0_before[2]
    # Blending: with an endless blend the new plan continues the old one's motion from its row 0.
    crowd.blend_s = 1e9
    old = crowd._plans_at(crowd.hist_time + np.arange(13) * 0.4)
    plan = crowd.plan_now(env)
    np.testing.assert_allclose(plan - plan[:, :1], old - old[:, :1], atol=1e-6)
    np.testing.assert_allclose(plan[:, 0], crowd.hist[:, -1], atol=1e-6)  # still starts at the last history point
    w.close()
    with pytest.raises(ValueError, match="blend_s"):
        DiffusionCrowd(TrajectoryDiffusion(CFG), blend_s=-1.0)
    with pytest.raises(ValueError, match="smooth_weight"):
        DiffusionCrowd(TrajectoryDiffusion(CFG), smooth_weight=-1.0)


def test_agent_buffer_sets_the_people_guidance_clearance(model_dir, monkeypatch):
    import navzoo.agents.diffusion.crowd as dc

    seen = []
    original = dc.agent_collision_cost

    def spy(*args, **kwargs):
        seen.append(kwargs.get("buffer"))
        return original(*args, **kwargs)

    monkeypatch.setattr(dc, "agent_collision_cost", spy)
    env = NavEnv(scene="lobby", n_robots=0, n_humans=3, crowd_model="diffusion", diffusion_model=str(model_dir),
                 diffusion_samples=1, time_limit=2.0)
    env.reset(seed=0)
    assert env.diffusion.agent_buffer == 0.2  # TRACE's clearance by default
    env.diffusion.agent_buffer = 0.05
    env.diffusion.plan_now(env)
    assert seen and seen[-1] == 0.05
    env.close()
    with pytest.raises(ValueError, match="agent_buffer"):
        DiffusionCrowd(TrajectoryDiffusion(CFG), agent_buffer=-0.1)
    with pytest.raises(ValueError, match="hold_floor_s"):
        DiffusionCrowd(TrajectoryDiffusion(CFG), hold_floor_s=float("nan"))


def test_amp_targets_toward_diffusion_plans_keep_to_the_speed_cap(model_dir, monkeypatch):
    """The rollouts toward the plans go at most DIFFUSION_SPEED_CAP x the preferred speed (default 1.0:
    faster targets run away from the bodies, docs/crowd_log.md "A speed cap of 1.0 for diffusion targets")."""
    from navzoo.envs import amp_humans

    assert amp_humans.DIFFUSION_SPEED_CAP == 1.0
    env = NavEnv(scene="circle_crossing", n_robots=0, n_humans=1, crowd_model="diffusion",
                 diffusion_model=str(model_dir), human_model="amp", dt=1 / 30, time_limit=10.0)
    env.reset(seed=0)
    peak = peak_target_pace(env, monkeypatch, "DIFFUSION_SPEED_CAP", (0.4, 3.0))
    env.close()
    v_pref = float(env.v_pref[0])
    assert peak[0.4][0] <= 0.4 * v_pref * 1.05
    assert peak[3.0][0] > 0.4 * v_pref * 1.5  # the plans are faster: the cap is what held them


def test_amp_targets_look_0p4_s_ahead_on_the_diffusion_plans(model_dir, monkeypatch):
    """DIFFUSION_LOOKAHEAD_S (0.4 s since 2026-12-01): a rollout heads for its plan's point that far ahead, so a
    plan that runs ahead of the body pulls its target at (distance to that point) / lookahead."""
    from navzoo.envs import amp_humans

    assert amp_humans.DIFFUSION_LOOKAHEAD_S == 0.4
    env = NavEnv(scene="circle_crossing", n_robots=0, n_humans=1, crowd_model="diffusion",
                 diffusion_model=str(model_dir), human_model="amp", dt=1 / 30, time_limit=10.0)
    env.reset(seed=0)
    monkeypatch.setattr(amp_humans, "DIFFUSION_SPEED_CAP", 10.0)  # the pace of the plan alone
    here = env.amp.planar()[0][0].copy()
    # a plan that walks east at 0.5 m/s from 0.3 m east of the body
    monkeypatch.setattr(env.diffusion, "_plans_at", lambda t: (here + np.array([0.3, 0.0])
                        + np.array([0.5, 0.0]) * (np.atleast_1d(t) - env.sim_time)[:, None])[None])
    first = {}
    for look in (0.4, 1.6):
        monkeypatch.setattr(amp_humans, "DIFFUSION_LOOKAHEAD_S", look)
        env.amp.plan_all()
        first[look] = (env.amp.paths[0, 3] - env.amp.paths[0, 0]) / (3 / 30)  # the first 0.1 s, m/s
    env.close()
    # preferred velocity (0.3 + 0.5 look) / look east: 1.25 m/s at 0.4 s, 0.69 m/s at 1.6 s (social force relaxes
    # toward it from the body's own velocity, so compare the direction and the order)
    assert first[0.4][0] > first[1.6][0] > 0.0
    assert abs(first[0.4][1]) < 0.3 * first[0.4][0]


def test_end_targets_stay_on_the_path_and_only_targets_past_the_goal_are_clipped():
    """Doorway: a person in the west room whose path goes through the door to a goal behind the dividing wall.
    Its end target 5 m ahead is still on the path in the west room: it stays there (clipped from the goal it
    would have crossed the wall). Near the goal the target is carried past it and stops short of the south wall."""
    from navzoo.agents.diffusion.crowd import _clip_to_free, _end_targets

    env = NavEnv(scene="doorway", n_robots=0, n_humans=2, crowd_model="sfm", time_limit=5.0)
    env.reset(seed=0)
    env.pos[0], env.goal[0] = np.array([2.0, 1.0]), np.array([9.0, 1.5])
    corners = np.array([[2.0, 1.0], [7.5, 4.0], [8.5, 4.0], [9.0, 1.5]])
    env.paths[0] = np.vstack([np.linspace(a, b, 8, endpoint=False) for a, b in zip(corners[:-1], corners[1:], strict=True)]
                             + [corners[-1:]])[1:]  # waypoints every ~0.1-0.8 m, as A* paths are spaced
    env.pos[1], env.goal[1] = np.array([9.0, 2.5]), np.array([9.0, 1.5])
    env.paths[1] = np.array([[9.0, 1.5]])
    env.wp_index[:] = 0
    env.v_pref[:] = 5.0 / 4.8
    people = np.array([0, 1])
    target = _end_targets(env, people, 4.8, extend=True)
    d = np.array([5.5, 3.0]) / np.hypot(5.5, 3.0)
    along = (target[0] - corners[0]) @ d
    np.testing.assert_allclose(target[0], corners[0] + along * d, atol=1e-9)  # on the path's first leg,
    assert 5.0 <= along < np.hypot(5.5, 3.0)  # in the west room, 5 m on from the first waypoint
    clipped = _clip_to_free(env, env.goal[:1], target[:1], env.config.human_radius + 0.1)[0]
    assert clipped[0] > 8.0  # what clipping from the goal did: across the dividing wall
    assert target[1][0] == pytest.approx(9.0) and 0.5 <= target[1][1] < 1.5  # past the goal, short of the wall
    assert env.grid.distance_at(target[1][None])[0] >= env.config.human_radius + 0.1 - 1e-9
    held = _end_targets(env, people, 4.8, extend=False)
    np.testing.assert_allclose(held[0], target[0])
    np.testing.assert_allclose(held[1], [9.0, 1.5])  # held at the goal
    # turns allowed: a carried target blocked straight ahead turns toward the open side
    env.pos[1] = np.array([9.0, 1.5]) + np.array([0.0, 1.0])
    free = _end_targets(env, people, 4.8, extend=True, past_goal_turn_deg=90.0)
    np.testing.assert_allclose(free[0], target[0])
    assert np.linalg.norm(free[1] - env.goal[1]) > np.linalg.norm(target[1] - env.goal[1]) + 1.0
    env.close()
    with pytest.raises(ValueError, match="past_goal_turn_deg"):
        DiffusionCrowd(TrajectoryDiffusion(CFG), past_goal_turn_deg=-1.0)


def test_ramped_distances_change_pace_at_the_given_rate():
    from navzoo.agents.diffusion.crowd import ramped_distances

    t = np.array([0.5, 1.0, 2.0, 4.0])
    # off: the preferred pace from the first step
    np.testing.assert_allclose(ramped_distances(np.array([0.2]), np.array([1.2]), 0.0, t), [[0.6, 1.2, 2.4, 4.8]])
    # 0.2 -> 1.2 m/s at 0.5 m/s^2 takes 2 s (1.4 m), then 1.2 m/s
    d = ramped_distances(np.array([0.2, 1.2, 1.6]), np.array([1.2, 1.2, 1.2]), 0.5, t)
    np.testing.assert_allclose(d[0], [0.2 * 0.5 + 0.25 * 0.25, 0.2 + 0.25, 1.4, 1.4 + 2.4])
    np.testing.assert_allclose(d[1], 1.2 * t)  # already at pace
    np.testing.assert_allclose(d[2], [1.6 * 0.5 - 0.25 * 0.25, 1.6 * 0.8 - 0.25 * 0.64 + 1.2 * 0.2,
                                      1.6 * 0.8 - 0.25 * 0.64 + 1.2 * 1.2,
                                      1.6 * 0.8 - 0.25 * 0.64 + 1.2 * 3.2])  # slows down, 0.8 s
    assert np.all(np.diff(d, axis=1) > 0)


def test_pace_ramp_spaces_the_path_guidance_from_the_current_speed(model_dir, monkeypatch):
    import navzoo.agents.diffusion.crowd as dc

    refs = []
    original = dc.path_cost

    def spy(points, *args, **kwargs):
        refs.append(points.numpy().copy())
        return original(points, *args, **kwargs)

    monkeypatch.setattr(dc, "path_cost", spy)
    env = NavEnv(scene="corridor", n_robots=0, n_humans=1, crowd_model="diffusion", diffusion_model=str(model_dir),
                 diffusion_samples=1, time_limit=2.0)
    env.reset(seed=0)
    assert env.diffusion.pace_ramp == 0.0  # off by default
    env.diffusion.hist[:] = env.pos[:, None, :] - np.array([0.0, 1e-3]) * np.arange(8)[::-1, None]  # nearly still
    env.diffusion.plan_now(env)
    env.diffusion.pace_ramp = 0.5
    env.diffusion.plan_now(env)
    env.close()
    plain, ramped = (np.linalg.norm(np.diff(r[0], axis=0), axis=-1)[:4] for r in refs)  # spacing along the path
    v = env.v_pref[0]
    np.testing.assert_allclose(plain, 0.4 * v, atol=1e-4)  # the corridor's path is straight here
    v0 = 1e-3 / 0.4
    np.testing.assert_allclose(ramped, v0 * 0.4 + 0.5 * 0.4 ** 2 * (np.arange(1, 5) + 0.5), atol=1e-4)
    with pytest.raises(ValueError, match="pace_ramp"):
        DiffusionCrowd(TrajectoryDiffusion(CFG), pace_ramp=-1.0)


def test_orca_walker_carries_the_bodies_along_their_plans(model_dir, monkeypatch):
    import navzoo.agents.crowd as crowd_mod
    from navzoo.agents.diffusion.crowd import ORCA_WALKER
    from navzoo.agents.orca import OrcaParams

    calls = []
    orca = crowd_mod.orca_velocities

    def spy(*args, **kwargs):
        calls.append(args[6])  # the OrcaParams
        return orca(*args, **kwargs)

    monkeypatch.setattr(crowd_mod, "orca_velocities", spy)

    def walk(walker, policy):
        env = NavEnv(scene="lobby", n_robots=1, n_humans=4, crowd_model="diffusion", diffusion_model=str(model_dir),
                     diffusion_samples=1, diffusion_walker=walker, time_limit=3.0)
        wrapped = FrozenAgents(env, lambda a: a.startswith("human_"), policy)
        wrapped.reset(seed=0)
        start = env.pos[1:].copy()
        for _ in range(20):
            wrapped.step({"robot_0": np.zeros(2, dtype=np.float32)})
        moved = np.linalg.norm(env.pos[1:] - start, axis=1)
        gap = min(np.linalg.norm(env.pos[i] - env.pos[j]) for i in range(5) for j in range(i + 1, 5))
        wrapped.close()
        return moved, gap

    moved, _ = walk("sfm", CrowdPolicy("diffusion"))
    assert not calls and moved.min() > 0.3  # social force by default
    moved, gap = walk("orca", CrowdPolicy("diffusion"))
    assert calls and all(p == ORCA_WALKER for p in calls)
    assert moved.min() > 0.3 and gap > 2 * 0.3 - 1e-6  # the people walk, no two bodies overlap (robot included)
    calls.clear()
    own = OrcaParams(time_horizon=3.0)
    walk("orca", CrowdPolicy("diffusion", orca_params=own))
    assert calls and all(p == own for p in calls)  # parameters given to the policy win
    calls.clear()
    moved, _ = walk("hybrid", CrowdPolicy("diffusion"))  # the hybrid walker: the same ORCA, with a robot among them
    assert calls and all(p == ORCA_WALKER for p in calls) and moved.min() > 0.3


def test_hybrid_walker_hands_the_people_orca_holds_still_to_social_force(model_dir, monkeypatch):
    import navzoo.agents.crowd as crowd_mod
    from navzoo.agents.diffusion.crowd import StallSwitch

    def jammed(*args, n_active, **kwargs):  # an ORCA that holds everybody still, as in a deadlocked door
        return np.zeros((n_active, 2))

    monkeypatch.setattr(crowd_mod, "orca_velocities", jammed)

    def walk(walker):
        env = NavEnv(scene="lobby", n_robots=0, n_humans=3, crowd_model="diffusion", diffusion_model=str(model_dir),
                     diffusion_samples=1, diffusion_walker=walker, time_limit=4.0)
        policy = CrowdPolicy("diffusion")
        wrapped = FrozenAgents(env, lambda a: a.startswith("human_"), policy)
        wrapped.reset(seed=0)
        start, track = env.pos.copy(), []
        for _ in range(30):
            wrapped.step({})
            track.append(np.linalg.norm(env.pos - start, axis=1))
        wrapped.close()
        return np.array(track), policy

    track, _ = walk("orca")
    assert track.max() < 1e-9  # ORCA alone: nobody moves
    track, policy = walk("hybrid")
    assert isinstance(policy._switch, StallSwitch) and policy._switch.use.all()
    assert track[8].max() < 1e-9  # patience (1 s) first
    assert track[-1].min() > 0.5  # then social force walks them
    policy.reset(None)
    assert policy._switch is None  # a new episode starts without anybody switched
