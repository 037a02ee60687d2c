"""Left/right mirror maps of the AMP controller (navzoo.agents.amp.symmetry)."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from navzoo.agents.amp import symmetry
from navzoo.agents.amp.features import (
    FEATURE_DIM,
    N_RAYS,
    amp_features,
    heading,
    obstacle_observation,
    policy_observation,
    reference_state_dict,
    task_observation,
)
from navzoo.agents.amp.sim import actions_to_targets
from navzoo.agents.motion_lib import MotionLibrary, mirror_frames
from navzoo.agents.reference import ReferenceState

FLIP_Y = np.array([1.0, -1.0])


@pytest.fixture(scope="module")
def lib() -> MotionLibrary:
    return MotionLibrary.load()


def _state(frames: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
    ref = ReferenceState(**{k: frames[k] for k in ("root_pos", "root_quat", "sph", "rev", "root_lin_vel",
                                                   "root_ang_vel", "sph_vel", "rev_vel")})
    return reference_state_dict(ref)


@pytest.mark.parametrize("clip", ["cmu_16_23", "amp_walk"])
def test_self_observation_of_the_mirrored_state_is_the_mirrored_observation(lib, clip):
    fr = lib.frames(clip)
    own = amp_features(_state(fr))
    mirrored = amp_features(_state(mirror_frames(fr)))
    m = symmetry.self_observation_mirror()
    np.testing.assert_allclose(m(own), mirrored, atol=1e-6)
    # Not trivially true: the clip is not symmetric itself.
    assert np.abs(own - mirrored).max() > 0.1


def test_target_points_and_rays_mirror_with_the_world():
    rng = np.random.default_rng(0)
    n = 64
    root = rng.uniform(-3, 3, (n, 2))
    yaw = rng.uniform(-np.pi, np.pi, n)
    quat = np.stack([np.zeros(n), np.zeros(n), np.sin(yaw / 2), np.cos(yaw / 2)], axis=1)
    wp = root[:, None] + rng.uniform(-4, 4, (n, 10, 2))
    segments = rng.uniform(-5, 5, (12, 2, 2))
    discs = rng.uniform(-4, 4, (9, 2))
    root3 = np.concatenate([root, np.ones((n, 1))], axis=1)
    task = task_observation(root3, quat, wp)
    rays = obstacle_observation(root, heading(quat), segments, discs, 0.3)
    assert (rays > 0).mean() > 0.2  # the rays see something
    m_quat = quat * np.array([-1.0, 1.0, -1.0, 1.0])  # yaw -> -yaw
    m_task = task_observation(root3 * np.array([1.0, -1.0, 1.0]), m_quat, wp * FLIP_Y)
    m_rays = obstacle_observation(root * FLIP_Y, heading(m_quat), segments * FLIP_Y, discs * FLIP_Y, 0.3)
    obs = np.concatenate([np.zeros((n, FEATURE_DIM)), task, rays], axis=1)
    mirrored = symmetry.observation_mirror(obs.shape[1])(obs)
    np.testing.assert_allclose(mirrored[:, FEATURE_DIM:FEATURE_DIM + 20], m_task, atol=1e-9)
    np.testing.assert_allclose(mirrored[:, FEATURE_DIM + 20:], m_rays, atol=1e-9)


def test_full_observation_mirror_matches_policy_observation(lib):
    fr = lib.frames("cmu_16_23")
    st, mst = _state(fr), _state(mirror_frames(fr))
    n = st["root_pos"].shape[0]
    wp = st["root_pos"][:, None, :2] + np.linspace(0.5, 5.0, 10)[None, :, None] * np.array([1.0, 0.4])
    rays = np.random.default_rng(1).uniform(0, 1, (n, N_RAYS))
    obs = policy_observation(st, wp, rays)
    m = symmetry.observation_mirror(obs.shape[1])
    m_rays = rays[:, (-np.arange(N_RAYS)) % N_RAYS]
    np.testing.assert_allclose(m(obs), policy_observation(mst, wp * FLIP_Y, m_rays), atol=1e-5)


def test_action_mirror_gives_mirrored_pd_targets():
    rng = np.random.default_rng(2)
    a = rng.uniform(-1, 1, (32, 28))
    sph, rev = actions_to_targets(a)
    m_sph, m_rev = actions_to_targets(symmetry.action_mirror()(a))
    want = mirror_frames({"sph": sph, "rev": rev})
    np.testing.assert_allclose(np.abs(np.sum(m_sph * want["sph"], axis=-1)), 1.0, atol=1e-9)
    np.testing.assert_allclose(m_rev, want["rev"], atol=1e-12)


@pytest.mark.parametrize("dim", [FEATURE_DIM + 20, FEATURE_DIM + 20 + N_RAYS])
def test_mirrors_are_involutions_and_work_on_tensors(dim):
    for m in (symmetry.observation_mirror(dim), symmetry.action_mirror()):
        x = np.random.default_rng(3).normal(size=(5, m.dim)).astype(np.float32)
        np.testing.assert_array_equal(m(m(x)), x)
        np.testing.assert_allclose(m(torch.from_numpy(x)).numpy(), m(x))
        np.testing.assert_array_equal(m.matrix() @ x[0], m(x[0]))


def test_unknown_observation_sizes_are_refused():
    with pytest.raises(ValueError, match="cannot mirror an observation of 130 columns"):
        symmetry.observation_mirror(130)
    with pytest.raises(ValueError, match="permutation"):
        symmetry.SignedPermutation(np.array([0, 0]), np.array([1.0, 1.0]))


def test_symmetric_actor_is_equivariant():
    from navzoo.agents.amp.networks import Actor
    from navzoo.agents.amp.normalizer import RunningMeanStd

    dim = FEATURE_DIM + 20 + N_RAYS
    torch.manual_seed(0)
    actor = Actor(dim, 28, [64, 64], "relu")
    torch.nn.init.normal_(actor.mean.weight, std=0.3)  # the default head starts near zero
    norm = RunningMeanStd(dim)
    norm.update(torch.randn(256, dim) * 2 + 1)
    sym = symmetry.SymmetricActor(actor, norm, dim)
    x = torch.randn(16, dim)
    with torch.no_grad():
        out, out_m = sym(x), sym(sym.obs_mirror(x))
        plain = actor(norm.normalize(x))
    torch.testing.assert_close(out_m, sym.act_mirror(out), atol=1e-6, rtol=1e-5)
    assert (plain - sym.act_mirror(actor(norm.normalize(sym.obs_mirror(x))))).abs().max() > 1e-3


def test_shipped_policy_made_symmetric_is_equivariant_and_drops_the_trim():
    from navzoo.agents.amp.pedestrian_policy import AmpPedestrianPolicy

    policy = AmpPedestrianPolicy(symmetric=True).policy
    assert policy.symmetric and policy.steering_trim == 0.0
    obs = np.random.default_rng(4).normal(size=(8, policy.obs_dim)).astype(np.float32)
    mo, ma = symmetry.observation_mirror(policy.obs_dim), symmetry.action_mirror()
    np.testing.assert_allclose(policy(mo(obs)), ma(policy(obs)), atol=1e-5)
    with pytest.raises(ValueError, match="steering_trim must be 0 when symmetric is on"):
        policy.steering_trim = 0.1
    with pytest.raises(ValueError, match="steering_trim must be 0"):
        AmpPedestrianPolicy(symmetric=True, steering_trim=0.1)
    plain = AmpPedestrianPolicy().policy  # the shipped config: trimmed, not symmetric
    assert not plain.symmetric and plain.steering_trim > 0
    with pytest.raises(ValueError, match="symmetric needs steering_trim 0"):
        plain.symmetric = True
    with pytest.raises(ValueError, match="symmetric must be true or false"):
        plain.override(steering_trim=0.0, symmetric=False)
        plain.symmetric = "yes"
