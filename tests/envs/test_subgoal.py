"""Robot subgoals, geodesic progress and the wall-proximity option (navzoo.envs.subgoal, NavConfig)."""

from __future__ import annotations

import numpy as np
import pytest

import navzoo
from navzoo.envs import observations as obs_terms
from navzoo.envs.config import NavConfig
from navzoo.envs.rewards import RewardParams, navigation_reward
from navzoo.envs.subgoal import GuidedPolicy, RobotGuide, geodesic_distance
from navzoo.world.occupancy import OccupancyGrid
from navzoo.world.planner import AStarPlanner
from navzoo.world.scene import BoxObstacle, Scene

OPTS = dict(robot_subgoal=3.0, robot_progress="geodesic", wall_proximity=0.2)


def _wall_scene() -> Scene:
    """A 10 x 6 m room split by a wall at x = 5 with a 1.6 m gap at the top (y 4.4 .. 6)."""
    return Scene(name="split", bounds=(0, 0, 10, 6), obstacles=(BoxObstacle((5.0, 2.2), (0.2, 4.4)),))


@pytest.fixture(scope="module")
def room():
    grid = OccupancyGrid.from_scene(_wall_scene(), resolution=0.1)
    return grid, AStarPlanner(grid, 0.3)


def test_geodesic_distance_goes_around_the_wall(room):
    grid, planner = room
    goal = np.array([8.0, 1.0])
    field = planner.distance_to(goal)
    start = np.array([2.0, 1.0])
    d = geodesic_distance(field, grid, start)
    # Up to the gap, through it, down to the goal: far longer than the 6 m straight line.
    assert d > 9.0  # the shortest way around the wall end is ~9.5 m
    assert abs(d - planner.shortest_path_length(start, goal)) < 0.5
    # Continuous: a 1 cm move changes it by about 1 cm at most, and zero at the goal.
    assert abs(geodesic_distance(field, grid, start + [0.01, 0.0]) - d) <= 0.011
    assert geodesic_distance(field, grid, goal) < 0.1
    # Inside the wall (inflated everywhere around) there is nothing to read.
    assert geodesic_distance(field, grid, np.array([5.0, 1.0])) == np.inf


def test_subgoals_are_in_sight_within_lookahead_and_end_at_the_goal(room):
    grid, planner = room
    guide = RobotGuide(grid, np.array([0.3]), lookahead=2.5)
    start, goal = np.array([2.0, 1.0]), np.array([8.0, 1.0])
    guide.reset(start[None], goal[None])
    pos, seen = start.copy(), []
    for _ in range(200):  # walk 0.2 m per step toward the subgoal
        sub = guide.subgoals(pos[None])[0]
        assert np.linalg.norm(sub - pos) <= 2.5 + 1e-9
        assert planner.line_of_sight(pos, sub)
        seen.append(sub)
        if np.linalg.norm(sub - goal) < 1e-9 and np.linalg.norm(pos - goal) < 0.2:
            break
        step = sub - pos
        pos = pos + step / max(np.linalg.norm(step), 1e-9) * min(0.2, np.linalg.norm(step))
    else:
        pytest.fail("following the subgoals never reached the goal")
    assert np.linalg.norm(seen[-1] - goal) < 1e-9
    assert max(s[1] for s in seen) > 4.4  # it went through the gap
    assert guide.replans[0] == 0


def test_subgoal_replans_when_pushed_out_of_sight(room):
    grid, _ = room
    guide = RobotGuide(grid, np.array([0.3]), lookahead=2.0)
    guide.reset(np.array([[2.0, 1.0]]), np.array([[8.0, 1.0]]))
    guide.subgoals(np.array([[2.0, 1.0]]))
    pushed = np.array([8.5, 5.0])  # far from every point of the old path, on the other side
    sub = guide.subgoals(pushed[None])[0]
    assert guide.replans[0] == 1
    assert np.linalg.norm(sub - pushed) <= 2.0 + 1e-9


def test_guide_rejects_bad_input(room):
    grid, _ = room
    with pytest.raises(ValueError, match="lookahead must be a finite number > 0"):
        RobotGuide(grid, np.array([0.3]), lookahead=0.0)
    guide = RobotGuide(grid, np.array([0.3, 0.3]), lookahead=2.0)
    with pytest.raises(ValueError, match="expected 2 positions and goals"):
        guide.reset(np.zeros((1, 2)), np.zeros((1, 2)))


@pytest.mark.parametrize("field, value, message", [
    ("robot_subgoal", 0.0, "robot_subgoal must be None or a finite number > 0"),
    ("robot_subgoal", float("nan"), "robot_subgoal must be None or a finite number > 0"),
    ("robot_progress", "manhattan", "robot_progress must be 'euclidean' or 'geodesic'"),
    ("wall_proximity", -0.1, "wall_proximity must be None or a finite number >= 0"),
    ("wall_proximity", True, "wall_proximity must be None or a finite number >= 0"),
])
def test_config_rejects_bad_guidance_options(field, value, message):
    with pytest.raises(ValueError, match=message):
        NavConfig(**{field: value})


def test_wall_proximity_reward_term():
    base = dict(d_goal=np.full(3, 5.0), d_goal_prev=np.full(3, 5.5), reached=np.zeros(3, bool),
                collided=np.zeros(3, bool), omega=np.zeros(3))
    d_people = np.array([2.0, 2.0, 0.5])
    d_walls = np.array([0.5, 0.1, 2.0])
    # Walls like people (the paper): both near ones penalised, no progress term.
    paper, _ = navigation_reward(d_obs=np.minimum(d_people, d_walls), **base)
    same, _ = navigation_reward(d_obs=d_people, d_walls=d_walls, **base)
    np.testing.assert_allclose(paper, same)
    np.testing.assert_allclose(paper, [0.5 * (0.5 - 0.9), 0.5 * (0.1 - 0.9), 0.5 * (0.5 - 0.9)])
    # 0.2 m for walls: the first robot (0.5 m from a wall) earns its progress again.
    _, terms = navigation_reward(d_obs=d_people, d_walls=d_walls, params=RewardParams(wall_proximity_distance=0.2),
                                 **base)
    np.testing.assert_allclose(terms["progress"], [3.2 * 0.5, 0.0, 0.0])
    np.testing.assert_allclose(terms["proximity"], [0.0, 0.5 * (0.1 - 0.2), 0.5 * (0.5 - 0.9)])


def test_env_observes_the_subgoal_and_rewards_geodesic_progress():
    env = navzoo.make("navzoo/Home-v0", n_humans=0, **OPTS)
    nav = env.unwrapped
    obs, _ = env.reset(seed=3)
    sub = nav.robot_subgoals[0]
    expect = obs_terms.goal_features(nav.pos[:1], nav.yaw[:1], sub[None])[0]
    np.testing.assert_allclose(obs["robot_0"]["goal"], expect, atol=1e-5)
    assert np.linalg.norm(sub - nav.pos[0]) <= 3.0 + 1e-6
    assert nav.d_progress[0] >= nav.d_goal[0] - 0.15  # a path is never shorter than the straight line
    before = nav.d_progress[0]
    _, rew, _, _, info = env.step({"robot_0": np.array([0.0, 0.0], np.float32)})  # stand still
    assert abs(nav.d_progress[0] - before) < 1e-9
    assert info["robot_0"]["reward/progress"] == 0.0
    env.close()


def test_default_env_is_unchanged_by_the_options_code():
    env = navzoo.make("navzoo/Home-v0", n_humans=2)
    nav = env.unwrapped
    obs, _ = env.reset(seed=1)
    assert nav.robot_guide is None
    expect = obs_terms.goal_features(nav.pos[:1], nav.yaw[:1], nav.goal[:1])[0]
    np.testing.assert_allclose(obs["robot_0"]["goal"], expect, atol=1e-5)
    env.close()


class _Recorder:
    """A stand-in learned policy: remembers the goal features it was given."""

    name = "recorder"

    def __init__(self) -> None:
        self.goals: list[np.ndarray] = []

    def reset(self, env) -> None:
        return None

    def controlled(self, observations, env=None):
        return [a for a in observations if a.startswith("robot_") and (env is None or a in env.agents)]

    def act(self, observations, env):
        out = {}
        for a in self.controlled(observations, env):
            o = observations[a]
            self.goals.append(np.asarray(o["goal"] if isinstance(o, dict) else o[layout_goal()], np.float32))
            out[a] = np.array([0.6, 0.2], np.float32)
        return out


def layout_goal() -> slice:
    from navzoo.agents.transformer import flat_layout

    s, e, _ = flat_layout(6, 8, 32)["goal"]
    return slice(s, e)


@pytest.mark.parametrize("flat", [False, True])
def test_guided_policy_sees_what_the_training_env_shows(flat):
    """In an env without subgoals the wrapped policy gets the same goal features as in one with them."""
    from navzoo.agents.transformer import flat_layout

    goals = {}
    for own in (True, False):
        env = navzoo.make("navzoo/Home-v0", n_humans=1, flat_obs=flat, **(OPTS if own else {}))
        nav = env.unwrapped
        rec = _Recorder()
        pol = GuidedPolicy(rec, 3.0, flat_layout(6, 8, 32))
        obs, _ = env.reset(seed=5)
        pol.reset(nav)
        assert (pol.guide is None) == own
        for _ in range(15):
            acts = pol.act({a: obs[a] for a in env.agents}, nav)
            acts.update({a: np.zeros(2, np.float32) for a in env.agents if a.startswith("human")})
            obs, *_ = env.step(acts)
            if "robot_0" not in obs:
                break
        goals[own] = np.stack(rec.goals)
        env.close()
    np.testing.assert_allclose(goals[True], goals[False], atol=1e-5)


def test_guided_policy_needs_reset():
    from navzoo.agents.transformer import flat_layout

    env = navzoo.make("navzoo/Home-v0", n_humans=0)
    obs, _ = env.reset(seed=0)
    pol = GuidedPolicy(_Recorder(), 3.0, flat_layout(6, 8, 32))
    with pytest.raises(RuntimeError, match="before reset"):
        pol.act(obs, env.unwrapped)
    env.close()
