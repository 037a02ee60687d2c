"""Discriminator velocities over several control steps (PoseHistory, amp_velocity_span): the policy's and the
reference's windows stay computed the same way, the span averages out per-step jitter, and a checkpoint
trained on one-step velocities is continued on other spans only with a fresh discriminator."""

from __future__ import annotations

import json

import numpy as np
import pytest

from navzoo.agents.amp.checkpoint import CheckpointError
from navzoo.agents.amp.features import (
    FEATURE_DIM,
    FEATURE_SLICES,
    PoseHistory,
    amp_features,
    finite_difference_velocities,
    quat_from_rotvec,
)
from navzoo.agents.amp.path_env import AmpPathEnv, PathTaskConfig, amp_obs_version, reference_amp_windows
from navzoo.agents.amp.train import grounded_locomotion_reference
from tests.amp_helpers import FixedTimes

DT = 1.0 / 30.0
REV, REV_V = FEATURE_SLICES["rev_angle"], FEATURE_SLICES["rev_vel"]


@pytest.fixture(scope="module")
def reference():
    return grounded_locomotion_reference()


def _poses(rng: np.random.Generator, n: int) -> dict[str, np.ndarray]:
    return {"root_pos": rng.normal(size=(n, 3)), "root_quat": quat_from_rotvec(rng.normal(0, 0.5, (n, 3))),
            "sph": quat_from_rotvec(rng.normal(0, 0.5, (n, 8, 3))), "rev": rng.normal(size=(n, 4))}


def test_span_one_is_the_one_step_difference_and_longer_spans_reach_back():
    rng = np.random.default_rng(0)
    seq = [_poses(rng, 3) for _ in range(7)]
    one, three = PoseHistory(3, 1), PoseHistory(3, 3)
    one.reset(seq[0])
    three.reset(seq[0])
    for t in range(1, 7):
        got1, got3 = one.velocities(seq[t], DT), three.velocities(seq[t], DT)
        want1 = finite_difference_velocities(seq[t - 1], seq[t], DT)
        back = min(t, 3)  # right after the reset only the steps since then
        want3 = finite_difference_velocities(seq[t - back], seq[t], back * DT)
        for key in ("root_lin_vel", "root_ang_vel", "sph_vel", "rev_vel"):
            np.testing.assert_allclose(got1[key], want1[key], atol=1e-12)
            np.testing.assert_allclose(got3[key], want3[key], atol=1e-12)
    # resetting one body restarts only its history
    three.reset(seq[6], np.array([1]))
    nxt = _poses(rng, 3)
    got = three.velocities(nxt, DT)["rev_vel"]
    np.testing.assert_allclose(got[1], (nxt["rev"][1] - seq[6]["rev"][1]) / DT)
    np.testing.assert_allclose(got[0], (nxt["rev"][0] - seq[4]["rev"][0]) / (3 * DT))


def test_a_longer_span_averages_out_per_step_jitter():
    """A joint turning at 2 rad/s with 0.02 rad of independent jitter per step: the one-step velocity is off by
    about 0.02 * sqrt(2) / dt = 0.85 rad/s, the 6-step one about a sixth of that."""
    rng = np.random.default_rng(1)
    n, steps = 64, 60
    errs = {}
    for span in (1, 6):
        hist = PoseHistory(n, span)
        pose = _poses(np.random.default_rng(2), n)
        pose["rev"][:] = 0.0
        hist.reset(pose)
        e = []
        for t in range(1, steps):
            cur = dict(pose, rev=np.full((n, 4), 2.0 * t * DT) + rng.normal(0, 0.02, (n, 4)))
            v = hist.velocities(cur, DT)["rev_vel"]
            if t >= span:
                e.append(v - 2.0)
        errs[span] = float(np.std(np.concatenate(e)))
    assert 0.7 < errs[1] < 1.0 and errs[6] < errs[1] / 4.5, errs


def test_reference_windows_span_the_same_steps_as_the_policy_path(reference):
    """Bodies played back through PoseHistory give exactly the reference windows of the same clip times."""
    rng = np.random.default_rng(3)
    clips, times = reference.sample_times(rng, 5)
    times = np.maximum(times, 6 * DT)


    from navzoo.agents.amp.features import reference_state_dict

    want = reference_amp_windows(FixedTimes(reference, clips, times), 5, rng, 2, DT, "finite_difference", span=4)
    hist = PoseHistory(5, 4)
    frames = []
    for k in (5, 4, 3, 2, 1, 0):
        s = reference_state_dict(reference.state_at(clips, times - k * DT))
        if k == 5:
            hist.reset(s)
            continue
        f = amp_features(hist.velocities(s, DT))
        if k <= 1:
            frames.append(f)
    np.testing.assert_allclose(np.concatenate(frames, axis=1), want, atol=1e-5)
    # span 1 is the one-step window the shipped controller was trained on
    one = reference_amp_windows(FixedTimes(reference, clips, times), 5, rng, 2, DT, "finite_difference")
    four = want.reshape(5, 2, FEATURE_DIM)
    assert not np.allclose(one.reshape(5, 2, FEATURE_DIM)[:, :, REV_V], four[:, :, REV_V])
    np.testing.assert_allclose(one.reshape(5, 2, FEATURE_DIM)[:, :, REV], four[:, :, REV])  # same poses


def test_the_path_env_feeds_span_step_velocities_to_the_discriminator(reference):
    env = AmpPathEnv(2, reference, PathTaskConfig(stage=1, episode_seconds=100.0, amp_velocity_span=3), seed=0)
    assert env.amp_obs_version == "velocity=finite_difference;span=3;ground=-0.002"
    env.reset(seed=0)
    rng = np.random.default_rng(0)
    angles = []
    for t in range(8):
        _, _, term, trunc, info = env.step(rng.uniform(-0.6, 0.6, (2, env.act_dim)))
        assert not (term | trunc).any()
        last = info["amp_obs"][:, -FEATURE_DIM:].astype(np.float64)
        angles.append(last[:, REV])
        if t >= 3:
            np.testing.assert_allclose(last[:, REV_V], (angles[t] - angles[t - 3]) / (3 * DT), atol=2e-3)
    env.close()


def test_span_settings_are_checked_and_recorded(reference):
    for bad in (0, -1, True, 1.5):
        with pytest.raises(ValueError, match="amp_velocity_span"):
            PathTaskConfig(amp_velocity_span=bad)
    with pytest.raises(ValueError, match="finite_difference"):
        PathTaskConfig(amp_velocity="physics", amp_velocity_span=2)
    with pytest.raises(ValueError, match="span"):
        PoseHistory(3, 0)
    with pytest.raises(ValueError, match="finite_difference"):
        reference_amp_windows(reference, 4, np.random.default_rng(0), 2, DT, "physics", span=2)
    # span 1 keeps the version string of every checkpoint trained so far
    assert amp_obs_version(PathTaskConfig(), reference) == "velocity=finite_difference;ground=-0.002"
    assert amp_obs_version(PathTaskConfig(amp_velocity_span=4), reference) == \
        "velocity=finite_difference;span=4;ground=-0.002"


def test_scene_training_on_another_span_needs_a_fresh_discriminator(tmp_path):
    from navzoo.rl.amp_joint import AmpJointArgs, NavAmpVecEnv, SubprocNavAmpVecEnv, train

    for bad in (0, True):  # refused before any worker process starts
        with pytest.raises(ValueError, match="amp_velocity_span"):
            SubprocNavAmpVecEnv("navzoo/Lobby-v0", 1, 2, workers=2, amp_velocity_span=bad)
        with pytest.raises(ValueError, match="amp_velocity_span"):
            NavAmpVecEnv("navzoo/Lobby-v0", 1, 2, n_robots=0, amp_velocity_span=bad)
    env = NavAmpVecEnv("navzoo/Lobby-v0", n_envs=1, n_humans=2, n_robots=0, seed=0, amp_velocity_span=4)
    assert env.amp_obs_version == "velocity=finite_difference;span=4;ground=-0.002"
    env.close()
    args = AmpJointArgs(out=str(tmp_path / "run"), env_id="navzoo/Lobby-v0", n_envs=1, n_humans=2, n_robots=0,
                        steps=32, minibatch_size=32, ckpt_every=1, amp_velocity_span=4)
    with pytest.raises(CheckpointError, match="reset_disc"):
        train(args)
    out = train(AmpJointArgs(**{**args.__dict__, "out": str(tmp_path / "fresh"), "reset_disc": True}))
    assert out["global_step"] == out["start_global_step"] + 32
    line = json.loads((tmp_path / "fresh" / "metrics.jsonl").read_text().splitlines()[-1])
    assert line["losses/disc"] > 0 and line["rewards/style"] > 0
    # the same command resumes the run, with the discriminator it trained (no second reset)
    again = train(AmpJointArgs(**{**args.__dict__, "out": str(tmp_path / "fresh"), "reset_disc": True, "steps": 64}))
    assert again["resumed_from"] and again["global_step"] == out["start_global_step"] + 64
