"""AMP pedestrians learning among robots (navzoo.rl.amp_joint): the vector env the AMP learner sees, training
from the shipped checkpoint with the discriminator's style reward, resume, evaluation, the CLI dispatch."""

from __future__ import annotations

import json

import numpy as np
import pytest
import torch

from navzoo.agents.amp.features import FEATURE_DIM
from navzoo.agents.amp.sim import ACTION_DIM
from navzoo.rl.amp_joint import AmpJointArgs, NavAmpVecEnv, evaluate, main, train


@pytest.fixture(scope="module")
def vec():
    env = NavAmpVecEnv("navzoo/Lobby-v0", n_envs=2, n_humans=2, n_robots=1, robot_policy="pure-pursuit", seed=3)
    yield env
    env.close()


def test_vec_env_follows_the_amp_learner_protocol(vec):
    assert (vec.num_envs, vec.act_dim, vec.amp_obs_dim) == (4, ACTION_DIM, 2 * FEATURE_DIM)
    assert vec.amp_obs_version == "velocity=finite_difference;ground=-0.002"  # the shipped checkpoint's inputs
    obs = vec.reset(seed=3)
    assert obs.shape == (4, vec.obs_dim) and np.isfinite(obs).all()
    obs2, rew, term, trunc, info = vec.step(np.zeros((4, ACTION_DIM), np.float32))
    assert obs2.shape == obs.shape and rew.shape == (4,) and term.dtype == bool and trunc.dtype == bool
    assert info["amp_obs"].shape == (4, vec.amp_obs_dim) and np.isfinite(info["amp_obs"]).all()
    # each row's |running mean of its feet's fore-aft split| (the stance term's input, for the training log)
    split = info["log/stance_split_m"]
    assert split.shape == (4,) and (split >= 0).all()
    np.testing.assert_allclose(split, np.concatenate([np.abs(e.amp.stance) for e in vec.envs]))
    # the window holds two frames: the newest one differs from the first (the bodies moved)
    w = info["amp_obs"].reshape(4, 2, FEATURE_DIM)
    assert not np.allclose(w[:, 0], w[:, 1])
    ref = vec.sample_reference_amp_obs(5, np.random.default_rng(0))
    assert ref.shape == (5, vec.amp_obs_dim)


def test_bad_actions_and_overrides_are_rejected(vec):
    vec.reset(seed=1)
    with pytest.raises(ValueError, match="finite with shape"):
        vec.step(np.zeros((3, ACTION_DIM)))
    bad = np.zeros((4, ACTION_DIM))
    bad[1, 2] = np.nan
    with pytest.raises(ValueError, match="finite with shape"):
        vec.step(bad)
    with pytest.raises(ValueError, match="may not set 'human_model'"):
        NavAmpVecEnv("navzoo/Lobby-v0", 1, 1, env_overrides={"human_model": "kinematic"})
    with pytest.raises(ValueError, match="n_humans must be an integer >= 1"):
        NavAmpVecEnv("navzoo/Lobby-v0", 1, 0)


def test_a_fall_terminates_its_row_and_restarts_the_copy(vec):
    """Random joint targets topple the bodies: the fallen row is terminated, the other rows of its copy are
    truncated with their last observation in final_obs, and the copy starts a new episode."""
    vec.reset(seed=5)
    vec.reset_stats()
    rng = np.random.default_rng(0)
    for _ in range(300):
        obs, _, term, trunc, info = vec.step(rng.uniform(-1, 1, (4, ACTION_DIM)).astype(np.float32))
        if term.any():
            break
    assert term.any(), "no body fell in 10 s of random joint targets"
    k = int(np.flatnonzero(term)[0]) // 2
    rows = slice(2 * k, 2 * k + 2)
    assert (term[rows] | trunc[rows]).all() and not (term[rows] & trunc[rows]).any()
    assert "final_obs" in info and not np.allclose(info["final_obs"][rows], obs[rows])
    assert vec.stats()["falls"] >= 1


def test_training_from_the_shipped_checkpoint_updates_policy_and_discriminator_and_resumes(tmp_path):
    torch.manual_seed(0)
    args = AmpJointArgs(out=str(tmp_path / "run"), env_id="navzoo/Lobby-v0", n_envs=1, n_humans=2, n_robots=1,
                        robot_policy="orca", steps=64, minibatch_size=32, ckpt_every=1)
    first = train(args)
    assert first["start_global_step"] > 1_000_000 and first["global_step"] == first["start_global_step"] + 64
    lines = [json.loads(x) for x in (tmp_path / "run" / "metrics.jsonl").read_text().splitlines()]
    assert len(lines) == 2
    for line in lines:  # the discriminator trains, and its style reward is part of every iteration's reward
        assert line["losses/disc"] > 0 and line["rewards/style"] > 0
        assert line["rewards/total"] == pytest.approx(line["rewards/style"] + 0.5 * line["rewards/task"], rel=1e-3)
        assert 0.0 < line["env/stance_split_m"] < 1.0  # the rollout's mean |split| of the env's info["log/..."]
    assert 0.0 < first["train_stats"]["stance_split_m"] < 1.0
    from navzoo.agents.amp.checkpoint import load_policy
    from navzoo.agents.amp.pedestrian_policy import default_policy_dir

    x = np.random.default_rng(0).normal(size=(8, json.loads((tmp_path / "run" / "policy" / "config.json")
                                                            .read_text())["obs_dim"])).astype(np.float32)
    assert not np.allclose(load_policy(tmp_path / "run" / "policy")(x), load_policy(default_policy_dir())(x))
    second = train(AmpJointArgs(**{**args.__dict__, "steps": 96}))
    assert second["resumed_from"] and second["global_step"] == first["start_global_step"] + 96
    with pytest.raises(ValueError, match="holds a run with other"):
        train(AmpJointArgs(**{**args.__dict__, "n_humans": 3}))


def test_evaluate_reports_falls_contacts_and_robot_outcomes():
    res = evaluate(None, "navzoo/Lobby-v0", 1, 2, 1, "orca", steps=30)
    assert res["pedestrian_steps"] == 60 and 0 <= res["agent_contact_share"] <= 1
    assert res["path_error_m"] > 0 and res["falls_per_pedestrian_minute"] >= 0


def test_navzoo_train_joint_dispatches_amp_pedestrians_to_the_amp_learner(tmp_path, capsys):
    from navzoo.rl.train import main as joint_main

    rc = joint_main(["--env", "navzoo/Lobby-v0", "--robots", "frozen", "--robot-policy", "orca", "--humans", "learn",
                     "--n-humans", "2", "--set", "human_model=amp", "--iterations", "1", "--batch-size", "32",
                     "--out", str(tmp_path / "j")])
    assert rc == 0
    done = json.loads(capsys.readouterr().out.strip().splitlines()[-1])["done"]
    assert done["pedestrian_steps_this_run"] >= 32 and (tmp_path / "j" / "policy" / "config.json").is_file()


def test_cli_errors_name_the_problem(capsys):
    assert main(["evaluate", "--env", "navzoo/Nowhere-v0", "--steps", "1"]) == 2
    assert "unknown navzoo env id" in capsys.readouterr().err


def test_navzoo_train_joint_needs_a_pedestrian_count_for_learning_amp_pedestrians(tmp_path, capsys):
    from navzoo.rl.train import main as joint_main

    with pytest.raises(SystemExit) as exc:  # argparse's error: exit status 2 with the message
        joint_main(["--env", "navzoo/Lobby-v0", "--robots", "frozen", "--humans", "learn", "--set", "human_model=amp",
                    "--out", str(tmp_path / "j")])
    assert exc.value.code == 2 and "give --n-humans" in capsys.readouterr().err
