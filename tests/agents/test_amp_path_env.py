"""The AMP path-following task env, its worker-process vector, and the resumable training entry point."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from functools import partial

import numpy as np
import pytest

from navzoo.agents.amp.features import FEATURE_DIM
from navzoo.agents.amp.path_env import AmpPathEnv, PathTaskConfig, reference_amp_windows
from navzoo.agents.amp.train import locomotion_reference
from navzoo.agents.amp.vec import SubprocAmpVecEnv


@pytest.fixture(scope="module")
def reference():
    return locomotion_reference()


def test_dims_rewards_and_auto_reset(reference):
    env = AmpPathEnv(3, reference, PathTaskConfig(episode_seconds=1.0), seed=0)
    obs = env.reset(seed=0)
    assert obs.shape == (3, FEATURE_DIM + 20) and env.act_dim == 28 and env.amp_obs_dim == 2 * FEATURE_DIM
    saw_end = False
    for _ in range(40):  # 1 s episodes at 30 Hz: every env ends at least once
        obs, rew, term, trunc, info = env.step(np.zeros((3, 28)))
        assert np.isfinite(obs).all() and np.isfinite(rew).all()
        assert info["amp_obs"].shape == (3, env.amp_obs_dim)
        if (term | trunc).any():
            saw_end = True
            assert info["final_obs"].shape == obs.shape
        assert (env.t <= env.episode_steps).all()
    assert saw_end
    ref = env.sample_reference_amp_obs(16, np.random.default_rng(0))
    assert ref.shape == (16, env.amp_obs_dim) and np.isfinite(ref).all()
    with pytest.raises(ValueError, match="shape"):
        env.step(np.zeros((3, 27)))
    with pytest.raises(ValueError, match="finite"):
        env.step(np.full((3, 28), np.nan))
    env.close()


def test_the_stance_term_charges_the_running_mean_of_the_feet_split_and_is_logged_at_any_weight(reference):
    from navzoo.agents.amp.features import STANCE_FREE_M, STANCE_TAU_S, foot_split, stance_penalty

    envs = [AmpPathEnv(2, reference, PathTaskConfig(rsi_prob=1.0, stance_reward=w), seed=3) for w in (0.0, 1.5)]
    for e in envs:
        e.reset(seed=3)
    mean = np.zeros(2)
    acts = np.zeros((2, 28))
    acts[:, 0] = 0.6  # a fixed, one-sided joint target
    checked = 0
    for _ in range(45):
        (_, r0, t0, u0, i0), (_, r1, t1, u1, i1) = (e.step(acts) for e in envs)
        mean += (1.0 / (30 * STANCE_TAU_S)) * (foot_split(envs[1].bodies.read_state()) - mean)
        if (t0 | u0 | t1 | u1).any():
            break
        np.testing.assert_array_equal(i0["reward/stance"], i1["reward/stance"])  # the same bodies: only the reward differs
        np.testing.assert_allclose(r1, r0 + 1.5 * i1["reward/stance"], atol=1e-5)
        np.testing.assert_allclose(i1["log/stance_split_m"], np.abs(mean), atol=1e-9)
        np.testing.assert_allclose(i1["reward/stance"], -np.maximum(0.0, np.abs(mean) - STANCE_FREE_M), atol=1e-9)
        checked += 1
    assert checked >= 10 and (np.abs(mean) > 0.001).all()  # the running mean moves with the feet
    np.testing.assert_allclose(stance_penalty(np.array([0.05, -0.3, 0.1])), [0.0, -0.2, 0.0])
    for e in envs:
        e.close()
    for bad in (-1.0, float("nan"), True):
        with pytest.raises(ValueError, match="stance_reward"):
            PathTaskConfig(stance_reward=bad)


def test_paths_start_at_the_body_and_move_at_the_commanded_speeds(reference):
    cfg = PathTaskConfig(stage=1, speed_range=(1.0, 1.0))
    env = AmpPathEnv(2, reference, cfg, seed=3)
    env.reset(seed=3)
    state = env.bodies.read_state()
    np.testing.assert_allclose(env.paths[:, 0], state["root_pos"][:, :2], atol=1e-9)
    speed = np.linalg.norm(np.diff(env.paths, axis=1), axis=2) / env.dt
    np.testing.assert_allclose(speed, 1.0, atol=1e-6)
    env.close()


def test_worker_processes_match_the_protocol(reference):
    vec = SubprocAmpVecEnv(locomotion_reference, workers=2, envs_per_worker=2, seed=0)
    try:
        obs = vec.reset(seed=0)
        assert obs.shape == (4, vec.obs_dim)
        obs, rew, term, trunc, info = vec.step(np.zeros((4, vec.act_dim)))
        assert rew.shape == (4,) and info["amp_obs"].shape == (4, vec.amp_obs_dim)
        assert vec.sample_reference_amp_obs(8, np.random.default_rng(0)).shape == (8, vec.amp_obs_dim)
        # the workers sample the reference windows, each its share, from seeds drawn from the learner's rng
        cfg = vec.config
        windows = partial(reference_amp_windows, reference, window=cfg.amp_window, dt=1.0 / cfg.control_hz,
                          velocity=cfg.amp_velocity, span=cfg.amp_velocity_span)
        seeds = np.random.default_rng(3).integers(0, 2**63 - 1, size=2)
        want = np.concatenate([windows(k, np.random.default_rng(sd)) for k, sd in zip((5, 4), seeds, strict=True)])
        np.testing.assert_array_equal(vec.sample_reference_amp_obs(9, np.random.default_rng(3)), want)
        vec.shard_reference = False  # or in this process, from the rng itself
        np.testing.assert_array_equal(vec.sample_reference_amp_obs(9, np.random.default_rng(3)),
                                      windows(9, np.random.default_rng(3)))
        # Ctrl-C reaches the workers too (process group): they must live on for the learner's checkpoint
        for proc in vec._procs:
            os.kill(proc.pid, signal.SIGINT)
        time.sleep(0.5)
        assert all(proc.is_alive() for proc in vec._procs)
        assert vec.step(np.zeros((4, vec.act_dim)))[0].shape == (4, vec.obs_dim)
    finally:
        vec.close()


def test_train_entry_point_checkpoints_and_resumes(tmp_path):
    cmd = [sys.executable, "-m", "navzoo.agents.amp.train", "--out", str(tmp_path), "--envs-per-worker", "4",
           "--rollout-steps", "8", "--minibatch-size", "32", "--hidden", "64,64", "--ckpt-every", "1", "--json"]
    first = subprocess.run(cmd + ["--total-steps", "64"], capture_output=True, text=True, timeout=300)
    assert first.returncode == 0, first.stderr[-2000:]
    r1 = json.loads(first.stdout.strip().splitlines()[-1])
    assert r1["global_step"] >= 64 and r1["resumed_from"] is None
    second = subprocess.run(cmd + ["--total-steps", "128", "--snapshot-every", "2", "--keep-checkpoints", "5"],
                            capture_output=True, text=True, timeout=300)
    assert second.returncode == 0, second.stderr[-2000:]
    r2 = json.loads(second.stdout.strip().splitlines()[-1])
    assert r2["resumed_from"] is not None and r2["global_step"] >= 128
    assert (tmp_path / "policy" / "policy.pt").is_file() and (tmp_path / "metrics.jsonl").is_file()
    rows = [json.loads(x) for x in (tmp_path / "metrics.jsonl").read_text().splitlines()]
    assert all(0.0 <= row["env/stance_split_m"] < 1.5 for row in rows)  # the stance, logged at weight 0 too
    # Policy snapshots: the branch point (iteration 2) and every 2nd iteration after it; all checkpoints kept.
    assert r1["iteration"] == 2 and r2["iteration"] == 4
    assert sorted(p.name for p in (tmp_path / "snapshots").iterdir()) == ["policy_00000002", "policy_00000004"]
    assert len(list((tmp_path / "checkpoints").glob("ckpt_*"))) == 4
    final = (tmp_path / "policy" / "policy.pt").read_bytes()
    assert (tmp_path / "snapshots" / "policy_00000004" / "policy.pt").read_bytes() == final
    assert (tmp_path / "snapshots" / "policy_00000002" / "policy.pt").read_bytes() != final


def test_shipped_policy_loads_and_walks_a_path_briefly():
    from pathlib import Path

    from navzoo.agents.amp.evaluate import evaluate

    policy_dir = Path(__file__).resolve().parents[2] / "policies" / "amp_pedestrian"
    result = evaluate(str(policy_dir), envs=2, seconds=2.0, stage=1)
    assert result["falls"] == 0 and result["mean_path_error_m"] < 0.5
    parts = result["reward_per_step"]
    assert set(parts) == {"track", "energy", "direction", "stance"}
    assert 0.5 < parts["track"] <= 1.0 and parts["energy"] < 0.0  # close to its path, and joints do work
    assert -1.0 <= parts["direction"] <= 0.0 and parts["stance"] <= 0.0
    # training's exploration noise on the PD targets makes the joints work much harder
    noisy = evaluate(str(policy_dir), envs=2, seconds=2.0, stage=1, action_std=0.055)
    assert noisy["action_std"] == 0.055 and noisy["reward_per_step"]["energy"] < 2 * parts["energy"]
    with pytest.raises(ValueError, match="action_std"):
        evaluate(str(policy_dir), envs=2, seconds=0.1, stage=1, action_std=-0.1)


def test_export_from_a_checkpoint_of_another_env_size(tmp_path):
    from navzoo.agents.amp.checkpoint import load_policy
    from navzoo.agents.amp.learner import AmpConfig, AmpLearner
    from navzoo.agents.amp.toy import CirclingPointMass, ToyConfig
    from navzoo.agents.amp.train import export_from_checkpoint

    env = CirclingPointMass(ToyConfig(num_envs=4))
    learner = AmpLearner(env, AmpConfig(actor_hidden=(16,), critic_hidden=(16,), disc_hidden=(16,), rollout_steps=4,
                                        minibatch_size=16, disc_minibatch_size=8))
    learner.collect(4)
    learner.update()
    ckpt_dir = learner.save_checkpoint(tmp_path / "ckpt")
    out = export_from_checkpoint(ckpt_dir, tmp_path / "policy")
    act = load_policy(out)(np.zeros((7, env.obs_dim), np.float32))  # any batch size
    assert act.shape == (7, env.act_dim) and np.isfinite(act).all()
