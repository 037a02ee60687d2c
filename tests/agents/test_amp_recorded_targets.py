"""Recorded crowd targets in the AMP path task (PathTaskConfig.recorded_targets / recorded_prob)."""

from __future__ import annotations

import numpy as np
import pytest

from navzoo.agents.amp.features import heading
from navzoo.agents.amp.path_env import AmpPathEnv, PathTaskConfig, load_recorded_targets
from navzoo.agents.amp.train import locomotion_reference

DT = 1.0 / 30


def _write(path, up_steps=90, dt=DT, **changes):
    k = np.arange(226)[:, None] * DT
    ahead = np.concatenate([1.0 * k, 0 * k], axis=1)  # 1 m/s along the recorded body's heading (0 rad) ...
    left = np.concatenate([0 * k, 0.5 * k], axis=1)  # ... then, from step 60, 0.5 m/s to its left
    arrays = {"person_start": np.array([0, 2]), "up_steps": np.array([up_steps]), "step": np.array([0, 60]),
              "plan_t": np.array([0, 60]), "heading": np.array([0.0, 0.0], dtype=np.float32),
              "paths": np.stack([ahead, left]).astype(np.float32), "dt": np.float64(dt)}
    arrays.update(changes)
    np.savez(path, **arrays)
    return str(path)


@pytest.fixture(scope="module")
def reference():
    return locomotion_reference()


def test_an_episode_walks_the_recorded_updates_turned_to_the_body(tmp_path, reference):
    f = _write(tmp_path / "rec.npz")
    env = AmpPathEnv(2, reference, PathTaskConfig(episode_seconds=3.0, rsi_prob=0.0, recorded_targets=f,
                                                  recorded_prob=1.0), seed=0)
    env.reset(seed=0)
    state = env.bodies.read_state()
    head = heading(state["root_quat"])
    assert (env._rec_person == 0).all() and (env._rec_offset == 0).all()  # the recording is one episode long
    for i in range(2):
        assert np.allclose(env.paths[i, 0], state["root_pos"][i, :2])  # it starts at the body ...
        d = env.paths[i, 30] - env.paths[i, 0]  # ... and goes 1 m ahead of it in 1 s, whatever its heading
        assert np.allclose(d, [np.cos(head[i]), np.sin(head[i])], atol=1e-6)
    # the second update comes at step 60: from the body then, 0.5 m/s to the left of the first heading
    env.t[:] = 60
    env._step_recorded(state)
    for i in range(2):
        assert np.allclose(env.paths[i, 60], state["root_pos"][i, :2])
        d = env.paths[i, 90] - env.paths[i, 60]
        assert np.allclose(d, 0.5 * np.array([-np.sin(head[i]), np.cos(head[i])]), atol=1e-6)
        assert env._rec_next[i] == env._rec_end[i] == 2  # nothing left to come
    env.close()


def test_recorded_episodes_are_the_share_asked_and_get_no_generated_replans(tmp_path, reference):
    f = _write(tmp_path / "rec.npz", up_steps=400)
    env = AmpPathEnv(40, reference, PathTaskConfig(stage=3, episode_seconds=3.0, rsi_prob=0.0, recorded_targets=f,
                                                   recorded_prob=0.5), seed=1)
    env.reset(seed=1)
    walks = env._rec_person >= 0
    assert 8 <= walks.sum() <= 32 and not env._crowd[walks].any()
    assert (env._rec_offset[walks] <= 400 - env.episode_steps).all()
    env.close()


def test_bad_recordings_and_settings_are_named(tmp_path):
    with pytest.raises(ValueError, match="needs recorded_targets"):
        PathTaskConfig(recorded_prob=0.5)
    with pytest.raises(ValueError, match="recorded_prob"):
        PathTaskConfig(recorded_prob=1.5, recorded_targets="x.npz")
    with pytest.raises(ValueError, match="cannot read"):
        load_recorded_targets(str(tmp_path / "missing.npz"))
    with pytest.raises(ValueError, match="missing"):
        np.savez(tmp_path / "partial.npz", step=np.zeros(2))
        load_recorded_targets(str(tmp_path / "partial.npz"))
    with pytest.raises(ValueError, match="not the task's"):
        load_recorded_targets(_write(tmp_path / "slow.npz", dt=0.1))
    with pytest.raises(ValueError, match="person_start"):
        load_recorded_targets(_write(tmp_path / "gap.npz", person_start=np.array([0, 3])))
    with pytest.raises(ValueError, match="finite"):
        load_recorded_targets(_write(tmp_path / "nan.npz", heading=np.array([0.0, np.nan])))
    rec = load_recorded_targets(_write(tmp_path / "ok.npz"))
    assert rec.paths.shape == (2, 226, 2) and list(rec.step) == [0, 60]


def test_several_recordings_are_pooled_and_short_paths_held_at_their_end(tmp_path):
    a = _write(tmp_path / "a.npz")
    short = np.zeros((1, 100, 2), dtype=np.float32)
    short[0, :, 1] = np.arange(100) * DT  # 1 m/s to the left, 100 points
    b = _write(tmp_path / "b.npz", up_steps=50, person_start=np.array([0, 1]), step=np.array([0]),
               plan_t=np.array([5]), heading=np.array([0.5], dtype=np.float32), paths=short)
    rec = load_recorded_targets(f"{a}, {b}")
    assert list(rec.person_start) == [0, 2, 3] and list(rec.up_steps) == [90, 50]
    assert list(rec.step) == [0, 60, 0] and list(rec.plan_t) == [0, 60, 5]
    assert np.allclose(rec.heading, [0.0, 0.0, 0.5])
    assert rec.paths.shape == (3, 226, 2)
    assert np.array_equal(rec.paths[:2], load_recorded_targets(a).paths)
    assert np.array_equal(rec.paths[2, :100], short[0]) and np.all(rec.paths[2, 100:] == short[0, -1])
    with pytest.raises(ValueError, match="empty file name"):
        load_recorded_targets(f"{a},")
    with pytest.raises(ValueError, match="cannot read"):
        load_recorded_targets(f"{a},{tmp_path / 'none.npz'}")


def test_training_names_a_bad_recording_before_it_starts(tmp_path):
    from navzoo.agents.amp.train import TrainArgs, run

    with pytest.raises(ValueError, match="cannot read"):
        run(TrainArgs(out=str(tmp_path / "run"), recorded_targets=str(tmp_path / "none.npz"), recorded_prob=0.3))
