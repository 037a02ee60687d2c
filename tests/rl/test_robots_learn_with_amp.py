"""Robots and AMP pedestrians learning at the same time (navzoo.rl.stepped_ppo, navzoo.rl.amp_joint): SB3 PPO fed
one decision at a time, its bootstrapping and checkpoints, and the joint run that trains, checkpoints and resumes
both learners together."""

from __future__ import annotations

import json

import numpy as np
import pytest
import torch

import navzoo
from navzoo.agents.amp import checkpoint as ckpt
from navzoo.agents.amp.checkpoint import CheckpointError
from navzoo.rl.amp_joint import AmpJointArgs, NavAmpVecEnv, train
from navzoo.rl.stepped_ppo import RobotLearnConfig, SteppedPPO

CROWDNAV = "policies/transformer_ppo_crowdnav"


@pytest.fixture(scope="module")
def spaces():
    env = navzoo.make("navzoo/Lobby-v0", raw=True, flat_obs=True, n_humans=1)
    obs, _ = env.reset(seed=0)
    out = env.observation_space("robot_0"), env.action_space("robot_0"), obs["robot_0"]
    env.close()
    return out


def _learner(spaces, **cfg):
    return SteppedPPO(spaces[0], spaces[1], 2, RobotLearnConfig(**{"n_steps": 4, "n_epochs": 2, **cfg}), seed=0)


def _params(learner):
    return torch.cat([p.detach().flatten().clone() for p in learner.model.policy.parameters()])


def test_a_full_rollout_triggers_one_ppo_update_and_changes_the_weights(spaces):
    L = _learner(spaces)
    obs = np.stack([spaces[2], spaces[2]])
    before = _params(L)
    for t in range(4):
        a = L.act(obs)
        assert a.shape == (2, 2) and np.all(a >= L.action_space.low) and np.all(a <= L.action_space.high)
        L.observe(np.array([1.0, -1.0]), np.array([False, t == 2]), events={1: "goal"} if t == 2 else None)
    assert L.updates == 0 and L.num_timesteps == 8
    L.act(obs)  # the buffer is full: PPO updates before acting
    assert L.updates == 1 and L.last_update["robot_timesteps"] == 8
    assert L.last_update["episodes"] == 1 and L.last_update["success_rate"] == 1.0
    assert not torch.equal(before, _params(L))
    assert L.model.rollout_buffer.pos == 0  # a new rollout started


def test_truncated_rows_are_bootstrapped_and_terminated_rows_are_not(spaces):
    L = _learner(spaces)
    obs = np.stack([spaces[2], spaces[2]])
    L.act(obs)
    final = spaces[2] * 0.5
    with torch.no_grad():
        v = float(L.model.policy.predict_values(torch.as_tensor(final[None]))[0, 0])
    L.observe(np.array([2.0, 3.0]), np.array([True, True]), final_obs={0: final})
    stored = L.model.rollout_buffer.rewards[0]
    assert stored[0] == pytest.approx(2.0 + 0.99 * v, rel=1e-5) and stored[1] == pytest.approx(3.0)
    # the next decision starts new episodes in both rows
    L.act(obs)
    L.observe(np.zeros(2), np.zeros(2, bool))
    assert L.model.rollout_buffer.episode_starts[1].tolist() == [1.0, 1.0]


def test_misuse_and_bad_input_are_rejected(spaces):
    L = _learner(spaces)
    obs = np.stack([spaces[2], spaces[2]])
    with pytest.raises(RuntimeError, match="call act"):
        L.observe(np.zeros(2), np.zeros(2, bool))
    bad = obs.copy()
    bad[0, 3] = np.nan
    with pytest.raises(ValueError, match="finite with shape"):
        L.act(bad)
    with pytest.raises(ValueError, match="finite with shape"):
        L.act(obs[:1])
    L.act(obs)
    with pytest.raises(RuntimeError, match="observe"):
        L.act(obs)
    with pytest.raises(ValueError, match="shape"):
        L.observe(np.zeros(3), np.zeros(3, bool))
    with pytest.raises(ValueError, match="n_steps must be an integer"):
        RobotLearnConfig(n_steps=0)
    with pytest.raises(FileNotFoundError, match="not an exported robot policy"):
        RobotLearnConfig(init_from="/no/such/policy")
    with pytest.raises(TypeError, match="flat Box"):
        SteppedPPO(navzoo.make("navzoo/Lobby-v0", raw=True, n_humans=1).observation_space("robot_0"), spaces[1], 1)


def test_state_round_trips_and_other_networks_are_refused(spaces):
    L = _learner(spaces, init_from=CROWDNAV)
    obs = np.stack([spaces[2], spaces[2]])
    for _ in range(5):
        L.act(obs)
        L.observe(np.ones(2), np.zeros(2, bool))
    state = L.state_dict()
    M = _learner(spaces)
    M.load_state_dict(state)
    assert torch.equal(_params(L), _params(M)) and M.num_timesteps == L.num_timesteps and M.updates == 1
    with pytest.raises(ValueError, match="features_dim"):
        _learner(spaces, features_dim=64, heads=4).load_state_dict(state)


def test_init_from_starts_from_the_exported_weights(spaces):
    from navzoo.agents.robot_train import load_policy

    L = _learner(spaces, init_from=CROWDNAV, forward_only=True)
    ref = load_policy(CROWDNAV).model
    got = dict(L.model.policy.state_dict())
    for k, v in ref.state_dict().items():
        assert torch.allclose(got[k], v.float()), k
    assert L.action_space.low[0] == 0.0  # forward-only speed command


def test_robots_and_amp_pedestrians_learn_together_checkpoint_and_resume(tmp_path):
    out = tmp_path / "run"
    learn = {"n_steps": 4, "n_epochs": 1, "init_from": CROWDNAV, "forward_only": True}
    args = AmpJointArgs(out=str(out), env_id="navzoo/Lobby-v0", n_envs=1, n_humans=1, n_robots=2, steps=128,
                        rollout_steps=16, minibatch_size=16, ckpt_every=2, robot_learn=learn)
    s1 = train(args)
    # both sides learned: AMP iterations (8 x 16 steps) and robot PPO updates (2 robots decide every 3 steps)
    assert s1["pedestrian_steps_this_run"] >= 128 and s1["robot_updates"] >= 4
    # 1 pedestrian per copy: one env step per pedestrian step; every 3rd step is a decision of both robots, and
    # all but the last (still open) decision are recorded
    decisions = -(-s1["pedestrian_steps_this_run"] // 3)
    assert s1["robot_timesteps"] == 2 * (decisions - 1)
    lines = [json.loads(x) for x in (out / "robot_metrics.jsonl").read_text().splitlines()]
    assert len(lines) == s1["robot_updates"] and all(np.isfinite(x["value_loss"]) for x in lines)
    # AMP side: the discriminator keeps giving the style reward
    amp_lines = [json.loads(x) for x in (out / "metrics.jsonl").read_text().splitlines()]
    assert all("rewards/style" in x for x in amp_lines)
    # the robots' state rides inside the AMP checkpoint
    tensors, _ = ckpt.load_checkpoint(ckpt.latest_checkpoint(out / "checkpoints"))
    assert tensors["companion"]["robot_learner"]["num_timesteps"] == s1["robot_timesteps"]
    # the exported robot policy loads as a frozen robot policy
    env = NavAmpVecEnv("navzoo/Lobby-v0", 1, 1, n_robots=1, robot_policy=f"sb3:{out / 'robot_policy'}")
    env.reset(seed=0)
    env.step(np.zeros((1, env.act_dim), np.float32))
    env.close()
    # resume: both learners continue from the checkpoint
    s2 = train(AmpJointArgs(**{**args.__dict__, "steps": 192}))
    assert s2["resumed_from"] is not None and s2["robot_timesteps"] > s1["robot_timesteps"]
    # a run whose robots were frozen cannot be resumed with learning robots (and vice versa)
    with pytest.raises(ValueError, match="robot_policy"):
        train(AmpJointArgs(**{**args.__dict__, "robot_learn": None, "robot_policy": "orca", "steps": 256}))


def test_a_checkpoint_without_robot_state_is_refused_by_learning_robots(tmp_path):
    from navzoo.agents.amp.learner import AmpLearner
    from navzoo.rl.amp_joint import _learner_config, shipped_training_checkpoint

    start = shipped_training_checkpoint(tmp_path)
    _, meta = ckpt.load_checkpoint(start)
    env = NavAmpVecEnv("navzoo/Lobby-v0", 1, 1, n_robots=1, robot_learn=RobotLearnConfig(n_steps=4))
    try:
        learner = AmpLearner(env, _learner_config(AmpJointArgs(), meta.get("config") or {}))
        learner.load_checkpoint(start, any_num_envs=True)  # starting from the shipped controller is fine
        saved = learner.save_checkpoint(tmp_path / "frozen_robots_ckpts")
        tensors = torch.load(saved / ckpt.STATE_FILE, weights_only=True)
        del tensors["companion"]
        torch.save(tensors, saved / ckpt.STATE_FILE)
        m = json.loads((saved / ckpt.META_FILE).read_text())
        m["state_sha256"] = ckpt.sha256_file(saved / ckpt.STATE_FILE)
        (saved / ckpt.META_FILE).write_text(json.dumps(m))
        with pytest.raises(CheckpointError, match="no learning robots' state"):
            learner.load_checkpoint(saved)
    finally:
        env.close()


def test_navzoo_train_joint_runs_robots_and_amp_pedestrians_learning(tmp_path, capsys):
    from navzoo.rl.train import main

    rc = main(["--env", "navzoo/Lobby-v0", "--robots", "learn", "--humans", "learn", "--n-humans", "1",
               "--robot-init", CROWDNAV, "--set", "human_model=amp", "--iterations", "1", "--batch-size", "120",
               "--envs-per-runner", "1", "--out", str(tmp_path / "j")])
    assert rc == 0
    done = json.loads(capsys.readouterr().out.strip().splitlines()[-1])["done"]
    assert done["robot_updates"] >= 1 and (tmp_path / "j" / "robot_policy" / "config.json").is_file()
