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

_CFG = AmpConfig(seed=0, actor_hidden=(32,), critic_hidden=(32,), disc_hidden=(32,), rollout_steps=4,
                 minibatch_size=8)


def _small_checkpoint(root):
    """A tiny trained learner's checkpoint (no obstacle rays), an observation of its env and its actions there."""
    env = AmpPathEnv(2, locomotion_reference(), PathTaskConfig(stage=1), seed=0)
    learner = AmpLearner(env, _CFG)
    learner.collect(4)
    learner.update()
    src = learner.save_checkpoint(root)
    obs = env.reset(seed=1)
    before = learner.act(obs)
    env.close()
    return src, obs, before, env.obs_dim


def test_widened_checkpoint_loads_and_acts_the_same(tmp_path):
    src, obs, before, obs_dim = _small_checkpoint(tmp_path / "a")

    dst = widen_checkpoint(src, tmp_path / "b", obs_dim + N_RAYS)
    wide_env = AmpPathEnv(2, locomotion_reference(), PathTaskConfig(stage=3, obstacle_obs=True, boxes_per_patch=2, pair_patches=True),
                          seed=0)
    assert wide_env.obs_dim == obs_dim + N_RAYS
    wide = AmpLearner(wide_env, _CFG)
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


def test_widen_cli_takes_a_split_training_folder_and_exports_the_policy(tmp_path):
    from navzoo.agents.amp.checkpoint import META_FILE, STATE_FILE, load_policy
    from navzoo.agents.amp.train import export_from_checkpoint
    from navzoo.agents.amp.widen import main

    src, obs, _, narrow_dim = _small_checkpoint(tmp_path / "a")
    # a committed training folder: the state in parts, as the device tool returns it
    folder = tmp_path / "training_run"
    folder.mkdir()
    data = (src / STATE_FILE).read_bytes()
    third = len(data) // 3 + 1
    for k in range(3):
        (folder / f"{STATE_FILE}.part-a{'abc'[k]}").write_bytes(data[k * third:(k + 1) * third])
    (folder / META_FILE).write_bytes((src / META_FILE).read_bytes())

    assert main([str(folder), str(tmp_path / "wide"), "--obs-dim", str(narrow_dim + N_RAYS),
                 "--export", str(tmp_path / "policy")]) == 0
    wide = load_policy(tmp_path / "policy")
    narrow = load_policy(export_from_checkpoint(src, tmp_path / "narrow_policy"))
    assert wide.obs_dim == narrow_dim + N_RAYS and narrow.obs_dim == narrow_dim
    rays = np.random.default_rng(0).random((2, N_RAYS)).astype(np.float32)
    np.testing.assert_allclose(wide(np.concatenate([obs, rays], axis=1)), narrow(obs), atol=1e-5)
    with pytest.raises(CheckpointError):  # a part missing: the joined state fails its sha256 check
        (folder / f"{STATE_FILE}.part-ab").unlink()
        main([str(folder), str(tmp_path / "wide2"), "--obs-dim", str(narrow_dim + N_RAYS)])
