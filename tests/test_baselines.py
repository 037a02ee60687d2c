"""Robot baselines (ORCA, social force, DWA, pure pursuit, stop, random), the registry and the
observation-policy adapters (plain functions and Stable-Baselines3 models)."""

from __future__ import annotations

import numpy as np
import pytest

import navzoo
from navzoo.agents import baselines
from navzoo.agents.baselines import (
    DWAPolicy,
    OrcaRobotPolicy,
    PurePursuitPolicy,
    make_policy,
    policy_names,
    register_policy,
)
from navzoo.agents.dwa import DWAParams, dwa_window
from navzoo.agents.policy import ObservationPolicy, Policy, SB3Policy, stack_observations
from navzoo.agents.robot import RobotSpec
from navzoo.envs.registry import make_raw
from navzoo.envs.wrappers import FrozenAgents, SingleRobotEnv


def _kinematics_of(name: str) -> str:
    return "holonomic" if name.endswith("holonomic") or name == "orca-crowdnav" else "diff_drive"


def _run(env, policy, steps: int | None = None, options=None, seed: int = 0, check=None):
    """Run ``policy`` for the robots until the episode ends (or ``steps``); returns the robots' events."""
    obs, _ = env.reset(seed=seed, options=options)
    nav = env.unwrapped
    policy.reset(nav)
    events: dict[str, str] = {}
    n = 0
    while env.agents and (steps is None or n < steps):
        actions = policy.act(obs, nav)
        if check is not None:
            check(nav, actions)
        obs, _, term, trunc, infos = env.step(actions)
        for a, info in infos.items():
            if term[a] or trunc[a]:
                events[a] = info["event"]
        n += 1
    return events


# ---------------------------------------------------------------------------------------------
# Registry and interface.


def test_registry_names_and_errors():
    names = policy_names()
    for required in ("orca-holonomic", "orca-diffdrive", "sfm", "dwa", "pure-pursuit", "stop", "random"):
        assert required in names
    assert isinstance(make_policy("pure_pursuit"), PurePursuitPolicy)  # "_" and "-" are the same
    assert make_policy("ORCA-Diff-Drive").kinematics == "diff_drive"
    assert isinstance(make_policy("orca-holonomic"), OrcaRobotPolicy)
    with pytest.raises(ValueError, match="valid names: .*orca-holonomic.*pure-pursuit"):
        make_policy("teleport")
    with pytest.raises(TypeError):
        make_policy("dwa", bogus=1)
    for name in names:
        assert isinstance(make_policy(name), Policy)
    with pytest.raises(ValueError, match="already registered"):
        register_policy("dwa", DWAPolicy)


def test_register_a_learned_policy(monkeypatch):
    monkeypatch.setattr(baselines, "_REGISTRY", dict(baselines._REGISTRY))  # undone after the test
    register_policy("zero-net", lambda **kw: ObservationPolicy(lambda batch: np.zeros((len(batch["goal"]), 2))),
                    overwrite=True)
    env = navzoo.make("navzoo/CircleCrossing-v0", n_humans=1)
    events = _run(env, make_policy("zero-net"), steps=3)
    assert events == {}
    assert "zero-net" in policy_names()
    env.close()


def test_kinematics_mismatch_is_reported():
    env = navzoo.make("navzoo/CircleCrossing-v0", n_humans=1)  # holonomic robot
    env.reset(seed=0)
    for name in ("orca-diffdrive", "dwa-diffdrive"):
        with pytest.raises(ValueError, match="'diff_drive' robots but this env's robot is 'holonomic'"):
            make_policy(name).reset(env.unwrapped)
    env.close()


def test_learned_policy_for_other_robots_is_refused():
    class Zero:
        def predict(self, obs, deterministic=True):
            return np.zeros((len(obs["goal"]), 2), np.float32), None

    env = navzoo.make("navzoo/CircleCrossing-v0", n_humans=1)  # holonomic robot
    obs, _ = env.reset(seed=0)
    with pytest.raises(ValueError, match="trained for 'diff_drive' robots but this env's robot is 'holonomic'"):
        SB3Policy(Zero(), kinematics="diff_drive", name="net").act(obs, env)
    assert set(SB3Policy(Zero(), kinematics="holonomic").act(obs, env)) == {"robot_0"}
    assert set(SB3Policy(Zero()).act(obs, env)) == {"robot_0"}  # unknown: not checked
    with pytest.raises(ValueError, match="kinematics must be"):
        SB3Policy(Zero(), kinematics="tracked")
    env.close()


@pytest.mark.parametrize("name", policy_names())
def test_every_policy_acts_for_exactly_the_live_robots(name):
    robot = {"kinematics": _kinematics_of(name)}
    env = navzoo.make("navzoo/CircleCrossing-v0", n_robots=2, n_humans=3, robot=robot, max_episode_steps_override=40)
    space = env.action_space("robot_0")

    def check(nav, actions):
        assert set(actions) == set(nav.agents) - {a for a in nav.agents if a.startswith("human_")}
        for a in actions.values():
            assert a.shape == (2,) and a.dtype == np.float32 and np.isfinite(a).all() and space.contains(a)

    kw = {"seed": 3} if name == "random" else {}
    _run(env, make_policy(name, **kw), steps=15, check=check)
    env.close()


def _robot_0_done(kinematics: str):
    """A CircleCrossing world with two robots of ``kinematics`` where robot_0 reached its goal."""
    env = make_raw("navzoo/CircleCrossing-v0", n_robots=2, n_humans=2, robot={"kinematics": kinematics})
    options = {"robot_starts": [[0.0, -4.0], [-4.0, 0.0]], "robot_goals": [[0.0, -3.5], [4.0, 0.0]],
               "robot_yaws": [np.pi / 2, 0.0],
               "human_starts": [[3.0, 3.0], [-3.0, 3.0]], "human_goals": [[-3.0, -3.0], [3.0, -3.0]]}
    obs, _ = env.reset(seed=0, options=options)
    pp = PurePursuitPolicy()
    while "robot_0" in env.agents:
        acts = {a: np.zeros(2, np.float32) for a in env.agents}
        acts.update(pp.act(obs, env))
        obs, *_ = env.step(acts)
    assert "robot_1" in env.agents
    assert "robot_0" in obs  # its last observation is still there: a policy must not act on it
    return env, obs


def test_done_robots_and_people_get_no_action():
    env, obs = _robot_0_done("holonomic")
    stale = {a: None for a in env.possible_agents}  # robot_0 is done, people are not robots
    learned = [n for n in policy_names() if n.removesuffix(baselines.SAMPLED_SUFFIX) in baselines.LEARNED_POLICIES]
    for name in policy_names():
        if name.endswith("diffdrive") or name in learned:  # diff-drive robots: below
            continue
        assert set(make_policy(name).act(stale, env)) == {"robot_1"}, name
    env.close()
    env, obs = _robot_0_done("diff_drive")
    for name in learned:  # those with weights in this checkout, with the mean and with sampled actions
        policy = make_policy(name)  # networks read real observations (and plan their subgoals on reset)
        policy.reset(env)
        assert set(policy.act(obs, env)) == {"robot_1"}, name
    env.close()


# ---------------------------------------------------------------------------------------------
# Reaching a goal alone.

_LONE = {"robot_starts": [[-3.0, -3.0]], "robot_goals": [[3.0, 2.5]], "robot_yaws": [2.5]}  # facing away


@pytest.mark.parametrize(("name", "kinematics"), [
    ("orca-holonomic", "holonomic"), ("orca-diffdrive", "diff_drive"), ("sfm", "holonomic"),
    ("sfm", "diff_drive"), ("dwa", "holonomic"), ("dwa", "diff_drive"),
])
def test_lone_robot_reaches_goal_in_open_scene(name, kinematics):
    env = make_raw(None, scene="circle_crossing", n_humans=0, robot={"kinematics": kinematics}, time_limit=20.0)
    events = _run(env, make_policy(name), options=_LONE)
    assert events == {"robot_0": "goal"}
    assert env.sim_time < 12.0  # 8 m at 1 m/s, plus turning and accelerating
    env.close()


# ---------------------------------------------------------------------------------------------
# DWA.


def test_dwa_window_shapes_and_limits():
    spec = RobotSpec()
    cand, valid = dwa_window(np.array([[0.5, 0.0], [1.0, 2.0]]), spec, 0.1, DWAParams())
    assert valid.all() and cand.shape[0] == 2
    assert np.all(np.abs(cand[0, :, 0] - 0.5) <= 0.2 + 1e-12) and np.all(np.abs(cand[0, :, 1]) <= 0.6 + 1e-12)
    assert cand[1, :, 0].max() == pytest.approx(1.0) and cand[1, :, 1].max() == pytest.approx(2.0)
    hol = RobotSpec(kinematics="holonomic", max_accel=1.0)
    cmd0 = np.array([[0.8, 0.0]])
    cand, valid = dwa_window(cmd0, hol, 0.1, DWAParams())
    ok = cand[valid]
    assert len(ok) > 10
    assert np.all(np.linalg.norm(ok - cmd0, axis=1) <= 0.1 + 1e-9) and np.all(np.linalg.norm(ok, axis=1) <= 1 + 1e-9)


@pytest.mark.parametrize("robot", [{}, {"kinematics": "holonomic", "max_accel": 1.0}])
def test_dwa_never_commands_beyond_the_acceleration_window(robot):
    # Default robot limits (diff drive: 2 m/s^2, 6 rad/s^2), social-force people who see the robot.
    env = navzoo.make(None, scene="circle_crossing", n_humans=5, robot=robot)
    spec = env.unwrapped.config.robot
    dt = env.unwrapped.config.dt
    checked = []

    def check(nav, actions):
        a = np.asarray(actions["robot_0"], dtype=np.float64)
        prev = nav.cmd[0]
        if spec.kinematics == "diff_drive":
            cmd = a * [spec.max_speed, spec.max_turn_rate]
            assert abs(cmd[0] - prev[0]) <= spec.max_accel * dt + 1e-5
            assert abs(cmd[1] - prev[1]) <= spec.max_ang_accel * dt + 1e-5
            assert -1e-6 <= cmd[0] <= spec.max_speed + 1e-6
        else:
            cmd = a * spec.max_speed
            assert np.linalg.norm(cmd - prev) <= spec.max_accel * dt + 1e-5
            assert np.linalg.norm(cmd) <= spec.max_speed + 1e-5
        checked.append(np.linalg.norm(cmd))

    _run(env, DWAPolicy(), steps=120, seed=1, check=check)
    assert len(checked) > 30 and max(checked) > 0.5  # it did move
    env.close()


_WALL_SCENE = """
name: wall_ahead
bounds: [0, 0, 10, 6]
obstacles:
  - {type: wall, start: [5, 0], end: [5, 6], thickness: 0.2, height: 1.0}
regions: {}
protocol: {type: regions}
default_humans: 0
time_limit: 20.0
"""


@pytest.mark.parametrize("moving", [False, True])
def test_dwa_stops_or_turns_before_a_wall_directly_ahead(tmp_path, moving):
    # The wall closes the scene, so there is no A* path: the goal pulls straight through the wall.
    path = tmp_path / "wall.yaml"
    path.write_text(_WALL_SCENE)
    env = make_raw(None, scene=str(path), n_humans=0, time_limit=8.0)
    options = {"robot_starts": [[3.6, 3.0]], "robot_goals": [[7.0, 3.0]], "robot_yaws": [0.0]}
    env.reset(seed=0, options=options)
    assert len(env.paths[0]) == 1  # straight at the goal
    policy = DWAPolicy()
    policy.reset(env)
    if moving:  # already at full speed toward the wall, 1.1 m away (braking needs 0.35 m)
        env.cmd[0] = [1.0, 0.0]
    min_gap = np.inf
    while env.agents:
        obs = {a: None for a in env.agents}
        _, _, term, _, infos = env.step(policy.act(obs, env))
        min_gap = min(min_gap, 4.9 - env.pos[0, 0] - env.radius[0])
        if term.get("robot_0"):
            pytest.fail(f"DWA ended with {infos['robot_0']['event']}")
    assert min_gap > 0.0
    env.close()
    # The same setup drives pure pursuit into the wall: the test is not vacuous.
    env = make_raw(None, scene=str(path), n_humans=0, time_limit=8.0)
    events = _run(env, PurePursuitPolicy(), options=options)
    assert events == {"robot_0": "collision_obstacle"}
    env.close()


# ---------------------------------------------------------------------------------------------
# Pure pursuit ignores people.


def test_pure_pursuit_collides_head_on_where_orca_and_dwa_do_not():
    # CrowdNav circle crossing, invisible robot: one person walks the robot's line the other way.
    options = {"robot_starts": [[0.0, -4.0]], "robot_goals": [[0.0, 4.0]],
               "human_starts": [[0.0, 4.0]], "human_goals": [[0.0, -4.0]]}
    outcome = {}
    for name in ("pure-pursuit", "orca-holonomic", "dwa"):
        env = navzoo.make("navzoo/CircleCrossing-v0", n_humans=1)
        outcome[name] = _run(env, make_policy(name), options=options, seed=0)["robot_0"]
        env.close()
    assert outcome == {"pure-pursuit": "collision_human", "orca-holonomic": "goal", "dwa": "goal"}


# ---------------------------------------------------------------------------------------------
# Observation-only policies.


def test_observation_policy_batched_equals_per_agent_on_dict_obs():
    env = navzoo.make("navzoo/CircleCrossing-v0", n_robots=3, n_humans=2)
    obs, _ = env.reset(seed=0)
    w = np.random.default_rng(0).normal(size=(5, 2))

    def single(o):
        return np.tanh(o["goal"] @ w + o["agents"].sum())

    def batched(b):
        return np.tanh(b["goal"] @ w + b["agents"].sum(axis=(1, 2, 3))[:, None])

    batch = stack_observations([obs[a] for a in env.agents])
    assert batch["agents"].shape == (3,) + obs["robot_0"]["agents"].shape
    a1 = ObservationPolicy(single, batched=False).act(obs, env.unwrapped)
    a2 = ObservationPolicy(batched).act(obs, env.unwrapped)
    assert set(a1) == set(a2) == {"robot_0", "robot_1", "robot_2"}
    for a in a1:
        np.testing.assert_allclose(a1[a], a2[a], rtol=1e-6)
    with pytest.raises(ValueError, match="one action per agent"):
        ObservationPolicy(lambda b: np.zeros((1, 2))).act(obs, env.unwrapped)
    env.close()


def test_sb3_adapter_matches_model_predict():
    from stable_baselines3 import PPO

    single = SingleRobotEnv(navzoo.make("navzoo/CircleCrossing-v0", flat_obs=True, n_humans=2))
    model = PPO("MlpPolicy", single, n_steps=16, batch_size=16, seed=0, device="cpu")
    env = navzoo.make("navzoo/CircleCrossing-v0", flat_obs=True, n_robots=3, n_humans=2)
    policy = SB3Policy(model)
    obs, _ = env.reset(seed=1)
    policy.reset(env.unwrapped)
    for _ in range(5):
        actions = policy.act(obs, env.unwrapped)
        assert set(actions) == set(env.agents)
        for a, act in actions.items():
            expected, _ = model.predict(obs[a], deterministic=True)
            np.testing.assert_allclose(act, expected, rtol=1e-5, atol=1e-6)
        obs, *_ = env.step(actions)
    env.close()
    # Frozen robots on a learned model, through the same interface as the baselines.
    frozen = FrozenAgents(make_raw("navzoo/CircleCrossing-v0", flat_obs=True, n_humans=2),
                          lambda a: a.startswith("robot_"), policy)
    obs, _ = frozen.reset(seed=0)
    obs, *_ = frozen.step({a: np.zeros(2, np.float32) for a in frozen.agents})
    assert set(obs) <= {"human_0", "human_1"}
    frozen.close()
    single.close()


def test_sb3_adapter_with_dict_observations():
    from stable_baselines3 import PPO

    single = SingleRobotEnv(navzoo.make("navzoo/CircleCrossing-v0", n_humans=2))
    model = PPO("MultiInputPolicy", single, n_steps=16, batch_size=16, seed=0, device="cpu")
    env = navzoo.make("navzoo/CircleCrossing-v0", n_robots=2, n_humans=2)
    obs, _ = env.reset(seed=2)
    actions = SB3Policy(model).act(obs, env.unwrapped)
    for a in env.agents:
        np.testing.assert_allclose(actions[a], model.predict(obs[a], deterministic=True)[0], rtol=1e-5, atol=1e-6)
    env.close()
    single.close()


def test_orca_crowdnav_is_rvo2_with_crowdnav_margins():
    pol = make_policy("orca-crowdnav")
    assert isinstance(pol, OrcaRobotPolicy) and pol.crowdnav and pol.kinematics == "holonomic"
    assert pol.params.right_bias == 0.0 and pol.params.one_step_safety is False
    with pytest.raises(ValueError, match="radius margin"):
        OrcaRobotPolicy(crowdnav=True, radius_margin=0.1)
    # A person standing on the robot's straight path: navzoo's holonomic ORCA passes at the sum of
    # radii (0.6 m), CrowdNav's (discs 0.01 m larger each) keeps 2 cm more.
    env = navzoo.make("navzoo/CircleCrossing-v0", n_humans=1, raw=True)
    gaps = {}
    for name in ("orca-holonomic", "orca-crowdnav"):
        env.reset(seed=0, options={"robot_starts": [[0.0, -2.0]], "robot_goals": [[0.0, 4.0]],
                                   "human_starts": [[0.0, 0.0]], "human_goals": [[0.0, 0.0]]})
        p = make_policy(name)
        p.reset(env)
        d = np.inf
        for _ in range(40):
            env.step({**p.act({"robot_0": None}, env), "human_0": np.zeros(2, dtype=np.float32)})
            d = min(d, float(np.linalg.norm(env.pos[0] - env.pos[1])))
            if not env.agents or "robot_0" not in env.agents:
                break
        gaps[name] = d
    assert gaps["orca-crowdnav"] > gaps["orca-holonomic"] + 0.01, gaps
    env.close()
