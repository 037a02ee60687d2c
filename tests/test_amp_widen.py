"""Widening a training checkpoint to the obstacle observation keeps the policy's behaviour."""

from __future__ import annotations

import numpy as np
import pytest

from navzoo.agents.amp.checkpoint import CheckpointError
from navzoo.agents.amp.features import N_RAYS
from navzoo.agents.amp.learner import AmpConfig, AmpLearner
from navzoo.agents.amp.path_env import AmpPathEnv, PathTaskConfig
from navzoo.agents.amp.train import locomotion_reference
from navzoo.agents.amp.widen import widen_checkpoint


def test_widened_checkpoint_loads_and_acts_the_same(tmp_path):
    ref = locomotion_reference()
    cfg = AmpConfig(seed=0, actor_hidden=(32,), critic_hidden=(32,), disc_hidden=(32,), rollout_steps=4,
                    minibatch_size=8)
    env = AmpPathEnv(2, ref, PathTaskConfig(stage=1), seed=0)
    learner = AmpLearner(env, cfg)
    learner.collect(4)
    learner.update()
    src = learner.save_checkpoint(tmp_path / "a")
    obs = env.reset(seed=1)
    before = learner.act(obs)
    env.close()

    dst = widen_checkpoint(src, tmp_path / "b", env.obs_dim + N_RAYS)
    wide_env = AmpPathEnv(2, ref, PathTaskConfig(stage=3, obstacle_obs=True, boxes_per_patch=2, pair_patches=True),
                          seed=0)
    assert wide_env.obs_dim == env.obs_dim + N_RAYS
    wide = AmpLearner(wide_env, cfg)
    wide.load_checkpoint(dst)
    rays = np.random.default_rng(0).random((2, N_RAYS)).astype(np.float32)
    after = wide.act(np.concatenate([obs, rays], axis=1))
    np.testing.assert_allclose(after, before, atol=1e-5)  # the new inputs start with zero weights
    stats = wide.collect(4)  # and it trains on
    assert np.isfinite(wide.update()["losses/actor"]) and isinstance(stats, dict)
    wide_env.close()
    with pytest.raises(ValueError, match="must exceed"):
        widen_checkpoint(dst, tmp_path / "c", 10)
    with pytest.raises(CheckpointError):
        widen_checkpoint(tmp_path / "nothing", tmp_path / "d", 200)
