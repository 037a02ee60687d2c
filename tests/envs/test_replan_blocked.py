"""Pedestrians pushed round a corner plan a new A* path (NavConfig.human_replan_blocked)."""

from __future__ import annotations

import numpy as np
import pytest

from navzoo.envs.config import NavConfig
from navzoo.envs.nav_env import REPLAN_EVERY_S, REPLAN_HIDDEN_S, NavEnv
from navzoo.envs.wrappers import FrozenAgents

# In the lobby's seating area, between a sofa (x 16-18, y 5.2-6.0) and the coffee table (centre (17, 4.3),
# radius 0.4): the straight line to a goal east of the table runs through the table. A social-force
# pedestrian pulled at that goal stays pressed against the table (a kinematic one stood there for 150 s in
# the 200 s lobby protocol).
START, GOAL = [16.27, 4.74], [19.04, 3.65]


class _Frozen:
    """The env stepped as the benchmarks do: its pedestrian driven by the crowd model or the AMP policy."""

    def __init__(self, mode: str, human_model: str) -> None:
        kw = {"dt": 1 / 30} if human_model == "amp" else {}
        self.env = NavEnv(scene="lobby", n_robots=0, n_humans=1, human_model=human_model, human_replan_blocked=mode,
                          max_episode_steps_override=900, **kw)
        if human_model == "amp":
            from navzoo.agents.amp.pedestrian_policy import AmpPedestrianPolicy

            policy = AmpPedestrianPolicy()
        else:
            from navzoo.agents.crowd import CrowdPolicy

            policy = CrowdPolicy("sfm")
        self.wrapped = FrozenAgents(self.env, lambda a: a.startswith("human_"), policy)
        self.wrapped.reset(seed=0, options={"human_starts": [START], "human_goals": [GOAL]})

    def step(self) -> None:
        self.wrapped.step({})


def _pushed_off(mode: str, human_model: str = "kinematic") -> tuple[NavEnv, _Frozen]:
    run = _Frozen(mode, human_model)
    env = run.env
    env.paths[0] = np.array([GOAL])  # its path went elsewhere; the crowd pushed it here; the goal is next
    env.wp_index[0] = 0
    return env, run


def _sees(env: NavEnv, point) -> bool:
    planner = env._planner(float(env.radius[0]))
    return planner.line_of_sight(planner._snap(env.pos[0])[0], point)


def test_the_config_names_a_bad_mode():
    with pytest.raises(ValueError, match="human_replan_blocked"):
        NavConfig(human_replan_blocked="yes")


def test_a_pedestrian_whose_waypoint_is_hidden_plans_again_and_reaches_its_goal():
    env, run = _pushed_off("all")
    assert not _sees(env, GOAL)
    steps = int(np.ceil(REPLAN_HIDDEN_S / env.config.dt)) + 1
    for _ in range(steps):
        run.step()
    path = env.paths[0]
    assert len(path) > 1 and np.allclose(path[-1], GOAL, atol=0.1)
    assert _sees(env, path[min(int(env.wp_index[0]), len(path) - 1)])
    for _ in range(200):  # 20 s
        run.step()
        if env.goals_reached[0]:
            break
    assert env.goals_reached[0] == 1
    env.close()


def test_off_and_the_default_for_kinematic_pedestrians_keep_the_path_and_stay_stuck():
    for mode in ("off", "amp"):  # "amp": physics pedestrians only
        env, run = _pushed_off(mode)
        for _ in range(100):  # 10 s
            run.step()
        np.testing.assert_array_equal(env.paths[0], [GOAL])
        assert env.goals_reached[0] == 0 and np.linalg.norm(env.pos[0] - START) < 1.5
        env.close()


def test_replans_are_spaced_and_a_visible_waypoint_resets_the_clock():
    env, run = _pushed_off("all")
    times = []
    for _ in range(40):
        before = env.paths[0]
        run.step()
        if env.paths[0] is not before:
            times.append(env.sim_time)
        env.paths[0] = np.array([GOAL])  # pushed off again at every step: still at most one plan per period
        env.wp_index[0] = 0
    assert len(times) >= 1 and np.all(np.diff(times) >= REPLAN_EVERY_S - 1e-9)
    env.close()


def test_physics_pedestrians_roll_out_new_targets_on_a_replan():
    env, run = _pushed_off("amp", human_model="amp")
    steps = int(np.ceil(REPLAN_HIDDEN_S / env.config.dt)) + 1
    for _ in range(steps):
        run.step()
    assert len(env.paths[0]) > 1  # replanned ...
    assert env.amp.plan_t[0] == env.amp.t  # ... and its targets rolled out again at that step
    env.close()
