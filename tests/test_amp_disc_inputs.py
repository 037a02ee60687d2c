"""Discriminator inputs: reference and policy windows are computed the same way, and a checkpoint whose
discriminator was trained on other inputs is resumed only with a fresh discriminator."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from navzoo.agents.amp.checkpoint import CheckpointError, load_checkpoint
from navzoo.agents.amp.features import FEATURE_DIM, FEATURE_SLICES
from navzoo.agents.amp.learner import AmpConfig, AmpLearner
from navzoo.agents.amp.path_env import (
    GROUND_CONTACT_Z,
    AmpPathEnv,
    PathTaskConfig,
    ground_clips,
    reference_amp_windows,
)
from navzoo.agents.amp.toy import RandomAmpVecEnv
from navzoo.agents.amp.train import grounded_locomotion_reference, locomotion_reference
from navzoo.agents.motion_lib import foot_heights, humanoid_fk
from tests.amp_helpers import FixedTimes

DT = 1.0 / 30.0
REV, REV_V = FEATURE_SLICES["rev_angle"], FEATURE_SLICES["rev_vel"]
H, LIN = FEATURE_SLICES["root_height"], FEATURE_SLICES["root_lin_vel"]


@pytest.fixture(scope="module")
def reference():
    return grounded_locomotion_reference()


def _fd_residual(w: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Last frame's knee/elbow rates and root z velocity minus the difference of the window's last two frames."""
    f0, f1 = w[:, -2 * FEATURE_DIM:-FEATURE_DIM], w[:, -FEATURE_DIM:]
    rev = f1[:, REV_V] - (f1[:, REV] - f0[:, REV]) / DT
    z = f1[:, LIN.start + 2] - (f1[:, H.start] - f0[:, H.start]) / DT
    return rev, z


def test_policy_windows_velocities_are_the_pose_differences(reference):
    """With motor PD, the simulator's joint velocities at the end of a control step have little to do with
    the motion between control steps (rms 4.2 rad/s apart for knees and elbows in rollouts of checkpoint
    3315, against 0.3 rad/s in the reference windows): the discriminator's velocities are differences."""
    env = AmpPathEnv(3, reference, PathTaskConfig(stage=1, episode_seconds=100.0), seed=0)
    env.reset(seed=0)
    rng = np.random.default_rng(0)
    for t in range(12):
        _, _, term, trunc, info = env.step(rng.uniform(-0.6, 0.6, (3, env.act_dim)))
        if t == 0 or (term | trunc).any():
            continue  # the first frame of an episode keeps its start velocities
        rev, z = _fd_residual(info["amp_obs"].astype(np.float64))
        assert np.abs(rev).max() < 1e-2 and np.abs(z).max() < 1e-3, (rev, z)
    env.close()


def test_reference_windows_velocities_are_the_pose_differences(reference):
    w = reference_amp_windows(reference, 256, np.random.default_rng(0), 2, DT, "finite_difference").astype(np.float64)
    rev, z = _fd_residual(w)
    assert np.abs(rev).max() < 1e-2 and np.abs(z).max() < 1e-3
    # the legacy inputs: the library's central differences, not consistent with the window
    old = reference_amp_windows(reference, 256, np.random.default_rng(0), 2, DT, "physics").astype(np.float64)
    assert np.sqrt(np.mean(_fd_residual(old)[0] ** 2)) > 0.1


def test_kinematic_playback_through_the_policy_path_equals_the_reference_windows(reference):
    """Bodies set to reference states one control step apart give, through the env's own feature path,
    exactly the reference windows of the same clip times."""
    env = AmpPathEnv(4, reference, PathTaskConfig(stage=1), seed=0)
    rng = np.random.default_rng(3)
    clips, times = reference.sample_times(rng, 4)
    times = np.maximum(times, 3 * DT)
    # reference windows for these clip times: the sampler's clips/times replayed

    want = reference_amp_windows(FixedTimes(reference, clips, times), 4, rng, 2, DT, "finite_difference")
    from navzoo.agents.amp.features import amp_features, finite_difference_velocities

    frames = []
    prev = None
    for k in (2, 1, 0):
        env.bodies.set_state(reference.state_at(clips, times - k * DT))
        s = {key: v.copy() for key, v in env.bodies.read_state().items()}
        if prev is not None:
            frames.append(amp_features(finite_difference_velocities(prev, s, DT)))
        prev = s
    np.testing.assert_allclose(np.concatenate(frames, axis=1), want, atol=1e-5)
    env.close()


def test_grounded_clips_put_the_feet_where_the_physics_body_stands():
    """The converted clips touch z = 0 only at their lowest frame: the median lowest foot point was +9.9 mm
    (physics: -1.8 mm), a 1.2 cm root-height offset the discriminator could read."""
    lib = locomotion_reference()
    grounded = ground_clips(lib)
    for library, lo, hi in ((lib, 0.004, 0.03), (grounded, GROUND_CONTACT_Z - 1e-6, GROUND_CONTACT_Z + 1e-6)):
        a = library.arrays
        low = foot_heights(*humanoid_fk(a["root_pos"], a["root_quat"], a["sph"], a["rev"])).min(axis=-1)
        med = [np.median(low[library.offsets[c]:library.offsets[c + 1]]) for c in range(len(library))]
        assert lo <= min(med) and max(med) <= hi, (min(med), max(med))
    # only the height moves; the rest of every frame is the same
    np.testing.assert_allclose(grounded.arrays["sph"], lib.arrays["sph"], atol=1e-12)
    np.testing.assert_array_equal(grounded.arrays["root_pos"][:, :2], lib.arrays["root_pos"][:, :2])
    assert grounded.meta["ground_contact_z"] == GROUND_CONTACT_Z


def _learner(version: str | None) -> AmpLearner:
    env = RandomAmpVecEnv(num_envs=8, obs_dim=12, act_dim=3, amp_obs_dim=10)
    if version is not None:
        env.amp_obs_version = version
    cfg = AmpConfig(actor_hidden=(16,), critic_hidden=(16,), disc_hidden=(16,), rollout_steps=4, minibatch_size=16,
                    disc_minibatch_size=8, replay_size=100, ckpt_replay_rows=100)
    return AmpLearner(env, cfg)


def test_resume_with_other_discriminator_inputs_needs_a_fresh_discriminator(tmp_path):
    old = _learner(None)  # a checkpoint without a recorded version: the legacy physics-velocity inputs
    old.collect(4)
    old.update()
    path = old.save_checkpoint(tmp_path)
    tensors, _ = load_checkpoint(path)

    new = _learner("velocity=finite_difference;ground=-0.002")
    with pytest.raises(CheckpointError, match="reset_disc"):
        new.load_checkpoint(path)
    new.load_checkpoint(path, reset_disc=True)
    for key, module in (("actor", new.actor), ("critic", new.critic), ("obs_norm", new.obs_norm),
                        ("value_norm", new.value_norm)):
        for name, value in module.state_dict().items():
            assert torch.equal(value, tensors[key][name]), (key, name)
    assert not torch.equal(new.disc.logits.weight, tensors["disc"]["logits.weight"])
    assert len(new.replay) == 0 and float(new.amp_norm.count) == 0.0
    assert new.disc_resets == [old.iteration] and new.iteration == old.iteration
    new.collect(4)
    assert np.isfinite(new.update()["losses/disc"])
    again = new.save_checkpoint(tmp_path / "b")

    later = _learner("velocity=finite_difference;ground=-0.002")
    later.load_checkpoint(again)  # same inputs: resumes without a reset, and remembers where it happened
    assert later.disc_resets == [old.iteration]
    assert torch.equal(later.disc.logits.weight, new.disc.logits.weight)
    legacy = _learner("velocity=physics;ground=None")
    legacy.load_checkpoint(path)  # the legacy inputs resume the legacy checkpoint as before
