"""JointConfig: YAML round trip, policy mapping, and bad configurations rejected with clear errors.

Needs no Ray: configurations are written and checked without it.
"""

from __future__ import annotations

import argparse

import pytest

from navzoo.rl.config import JointConfig, policy_mapping_fn, resolve_module_dir


def test_defaults_learn_both_sides_and_round_trip(tmp_path):
    cfg = JointConfig().validate()
    assert cfg.learning_policies == ["robot", "human"]
    assert cfg.nav_overrides()["flat_obs"] is True
    cfg = JointConfig(env_id="navzoo/Lobby-v0", humans="crowd", n_robots=2, n_humans=4, env={"crowd_model": "orca"})
    for name in ("c.yaml", "c.json"):
        cfg.save(tmp_path / name)
        back = JointConfig.load(tmp_path / name).validate()
        assert back == cfg and back.learning_policies == ["robot"]
    (tmp_path / "nested.yaml").write_text("joint:\n  robots: frozen\n  robot_policy: dwa\n  n_humans: 2\n")
    assert JointConfig.load(tmp_path / "nested.yaml").validate().learning_policies == ["human"]


def test_policy_mapping():
    assert policy_mapping_fn("robot_0") == "robot" and policy_mapping_fn("robot_12", None) == "robot"
    assert policy_mapping_fn("human_3", episode=None, worker=None) == "human"
    with pytest.raises(ValueError, match="robot_<i> or human_<i>"):
        policy_mapping_fn("car_0")


@pytest.mark.parametrize("data, match", [
    ({"robot": "learn"}, "unknown joint config key.*'robot'"),
    ({"robots": "train"}, r"robots must be one of \['learn', 'frozen'\]"),
    ({"humans": "crowd"} | {"robots": "frozen"}, "nothing to train"),
    ({"env_id": "navzoo/Nowhere-v0"}, "unknown env_id"),
    ({"n_humans": -1}, "n_humans must be None or an integer >= 0"),
    ({"n_humans": 0}, "humans: learn needs n_humans >= 1"),
    ({"n_robots": 0, "humans": "crowd"}, "robots: learn needs n_robots >= 1"),
    ({"env": {"n_humans": 3}}, "top level"),
    ({"env": {"flat_obs": False}}, "flat observations"),
    ({"env": {"crowd_modle": "orca"}}, "crowd_modle"),
    ({"robots": "frozen", "robot_policy": "teleport"}, "unknown robot policy 'teleport'"),
    ({"humans": "frozen"}, "human_policy: 'rllib:PATH'"),
    ({"humans": "frozen", "human_policy": "sfm"}, "humans: crowd"),
    ({"humans": "frozen", "human_policy": "rllib:/no/such/run"}, "does not exist"),
    ({"robots": "frozen", "robot_policy": "rllib:/no/such/run"}, "does not exist"),
    ({"robot_init": "policies/transformer_ppo_crowdnav"}, "RLlib robots start fresh"),
    ({"env": {"human_model": "amp"}, "robot_init": "/no/such/policy"}, "exported robot policy folder"),
    ({"env": {"human_model": "amp"}, "humans": "crowd"}, "kinematic pedestrians only"),
    ({"env": {"human_model": "amp"}, "robots": "frozen", "robot_policy": "rllib:x"}, "navzoo policy"),
    ({"env": {"human_model": "amp"}, "humans": "frozen", "human_policy": "rllib:x"}, "'amp' or 'amp:DIR'"),
])
def test_bad_configs_are_rejected(data, match):
    with pytest.raises((ValueError, TypeError, FileNotFoundError), match=match):
        JointConfig.from_dict(data).validate()


def test_robots_and_amp_pedestrians_may_learn_together():
    cfg = JointConfig(env_id="navzoo/Lobby-v0", n_humans=2, env={"human_model": "amp"},
                      robot_init="policies/transformer_ppo_crowdnav").validate()
    assert cfg.learning_policies == ["robot", "human"]
    assert JointConfig.from_dict(cfg.to_dict()).robot_init == "policies/transformer_ppo_crowdnav"


def test_amp_pedestrians_can_be_frozen_on_the_shipped_controller():
    cfg = JointConfig(env_id="navzoo/Lobby-v0", humans="frozen", n_humans=2, env={"human_model": "amp"}).validate()
    assert cfg.learning_policies == ["robot"] and cfg.nav_config().dt == pytest.approx(1 / 30)


def test_resolve_module_dir_errors(tmp_path):
    with pytest.raises(FileNotFoundError, match="does not exist"):
        resolve_module_dir(tmp_path / "missing", "robot")
    with pytest.raises(FileNotFoundError, match="no RLlib module 'human'"):
        resolve_module_dir(tmp_path, "human")


def test_resolve_module_dir_gives_an_absolute_path_for_a_relative_run_folder(tmp_path, monkeypatch):
    # RLlib restores modules from absolute paths only ("URI has empty scheme" otherwise).
    ckpt = tmp_path / "run" / "checkpoints" / "iter_000002"
    mod = ckpt / "learner_group" / "learner" / "rl_module" / "human"
    mod.mkdir(parents=True)
    for name in ("class_and_ctor_args.pkl", "module_state.pkl"):
        (mod / name).write_bytes(b"")
    (tmp_path / "run" / "latest_checkpoint.txt").write_text(str(ckpt.relative_to(tmp_path / "run")))
    monkeypatch.chdir(tmp_path)
    got = resolve_module_dir("run", "human")
    assert got.is_absolute() and got == mod.resolve()


def test_cli_flags_override_the_config_file(tmp_path):
    from navzoo.rl.train import add_arguments, joint_config_from_args, run_cli

    (tmp_path / "j.yaml").write_text("env_id: navzoo/Corridor-v0\nhumans: crowd\nn_humans: 4\n")
    parser = argparse.ArgumentParser()
    add_arguments(parser)
    args = parser.parse_args(["--config", str(tmp_path / "j.yaml"), "--n-humans", "2", "--set", "time_limit=8",
                              "--set", "crowd_model=orca"])
    cfg = joint_config_from_args(args)
    assert (cfg.env_id, cfg.humans, cfg.n_humans, cfg.env) == (
        "navzoo/Corridor-v0", "crowd", 2, {"time_limit": 8, "crowd_model": "orca"})
    errors = []
    assert run_cli(parser.parse_args(["--robots", "frozen", "--humans", "crowd"]), errors.append) == 2
    assert "nothing to train" in errors[0]
    assert run_cli(parser.parse_args(["--env-runners", "-1"]), errors.append) == 2
    assert "--env-runners must be >= 0" in errors[1]
    assert run_cli(parser.parse_args(["--address", "127.0.0.1:1", "--num-cpus", "2"]), errors.append) == 2
    assert run_cli(parser.parse_args(["--num-learners", "-1"]), errors.append) == 2
    assert "--num-learners must be >= 0" in errors[-1]
    assert run_cli(parser.parse_args(["--gpus-per-learner", "nan"]), errors.append) == 2
    assert "--gpus-per-learner" in errors[-1]
    with pytest.raises(SystemExit):
        parser.parse_args(["--humans", "sometimes"])


def test_evaluate_runs_fixed_policies_without_ray():
    from navzoo.rl.evaluate import evaluate

    cfg = JointConfig(robots="frozen", robot_policy="dwa", humans="crowd", n_humans=2, env={"time_limit": 5})
    res = evaluate(cfg, episodes=2, seed=7)
    assert res["episodes"] == 2 and [r["seed"] for r in res["per_episode"]] == [7, 8]
    m = res["mean"]
    assert m["robot_success"] + m["robot_collision"] + m["robot_timeout"] == pytest.approx(1.0)
    assert m["human_speed_mps"] > 0 and m["episode_s"] <= 5.0
    assert evaluate(cfg, episodes=2, seed=7)["per_episode"] == res["per_episode"]  # seeded
    with pytest.raises(ValueError, match="evaluation runs fixed policies"):
        evaluate(JointConfig(), episodes=1)


def test_set_values_are_json_else_words():
    """``--set`` values: JSON where they parse (numbers, true/false, null, lists), else the word itself; a word
    such as ``off`` stays a word (YAML would have read it as False, which NavConfig refuses)."""
    from navzoo.envs.config import NavConfig, parse_override, parse_overrides
    from navzoo.rl.train import _key_value

    got = parse_overrides(["human_replan_blocked=off", "amp_wall_strength=0.3", "human_yielding=true",
                           "n_humans=4", "amp_wall_strength_x=null", "human_speed=[1.0, 1.4]", "scene=a=b"])
    assert got == {"human_replan_blocked": "off", "amp_wall_strength": 0.3, "human_yielding": True, "n_humans": 4,
                   "amp_wall_strength_x": None, "human_speed": [1.0, 1.4], "scene": "a=b"}
    assert _key_value(" human_at_goal =stop") == ("human_at_goal", "stop")
    assert NavConfig(human_replan_blocked=_key_value("human_replan_blocked=off")[1]).human_replan_blocked == "off"
    for item in ("oops", "=3"):
        with pytest.raises(ValueError, match="KEY=VALUE"):
            parse_override(item)
        with pytest.raises(argparse.ArgumentTypeError, match="KEY=VALUE"):
            _key_value(item)


def test_yaml_booleans_in_word_fields_get_a_hint():
    from navzoo.envs.config import NavConfig

    with pytest.raises(ValueError, match=r"human_replan_blocked must be .*got False \(in YAML, quote words"):
        NavConfig(human_replan_blocked=False)
    with pytest.raises(ValueError, match=r"human_at_goal must be .*got 'fly'$"):
        NavConfig(human_at_goal="fly")
