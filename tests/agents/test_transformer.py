"""The spatio-temporal transformer extractor: shapes, masking, invariances, causality, SB3 wiring."""

from __future__ import annotations

import numpy as np
import pytest
import torch
from gymnasium import spaces

from navzoo.agents.transformer import (
    FactorizedBlock,
    SpatioTemporalExtractor,
    flat_layout,
    observation_dict_space,
    transformer_policy_kwargs,
)

K, T, C = 6, 8, 32
SMALL = dict(features_dim=32, n_heads=2, n_blocks=2)


pytestmark = pytest.mark.usefixtures("one_torch_thread")


def _extractor(space=None, seed: int = 0, **kw) -> SpatioTemporalExtractor:
    torch.manual_seed(seed)
    ext = SpatioTemporalExtractor(space if space is not None else observation_dict_space(K, T, C), **{**SMALL, **kw})
    return ext.eval()


def _batch(b: int = 4, seed: int = 0, k: int = K, t: int = T, c: int = C) -> dict[str, torch.Tensor]:
    g = torch.Generator().manual_seed(seed)
    mask = (torch.rand(b, k, t, generator=g) > 0.3).float()
    mask[:, :, -1] = 1.0
    mask[:, -2:] = 0.0  # two empty slots
    agents = torch.randn(b, k, t, 7, generator=g) * mask[..., None]
    return {"goal": torch.randn(b, 5, generator=g), "velocity": torch.randn(b, 3, generator=g),
            "agents": agents, "agents_mask": mask, "map": (torch.rand(b, c, c, generator=g) > 0.8).float()}


@torch.no_grad()
def test_shape_and_no_nan_when_everything_is_masked():
    ext = _extractor()
    obs = _batch()
    obs["agents_mask"].zero_()
    obs["agents"].normal_()  # garbage under the mask
    out = ext(obs)
    assert out.shape == (4, 32)
    assert torch.isfinite(out).all()


@torch.no_grad()
def test_padded_entries_do_not_matter():
    ext = _extractor()
    obs = _batch()
    ref = ext(obs)
    noisy = {k: v.clone() for k, v in obs.items()}
    pad = noisy["agents_mask"] < 0.5
    noisy["agents"][pad] = torch.randn(int(pad.sum()), 7) * 10
    assert torch.allclose(ext(noisy), ref, atol=1e-5)


@torch.no_grad()
def test_permuting_people_slots_leaves_output_unchanged():
    ext = _extractor()
    obs = _batch()
    perm = torch.tensor([3, 0, 5, 1, 4, 2])
    permuted = dict(obs, agents=obs["agents"][:, perm], agents_mask=obs["agents_mask"][:, perm])
    assert torch.allclose(ext(permuted), ext(obs), atol=1e-5)


@torch.no_grad()
def test_temporal_attention_is_causal():
    torch.manual_seed(0)
    block = FactorizedBlock(16, 2).eval()
    x = torch.randn(2, 4, T, 16)
    valid = torch.ones(2, 4, T, dtype=torch.bool)
    valid[0, 2, :3] = False
    ref = block(x, valid)
    t = 5
    changed = x.clone()
    changed[:, 1, t] += 3.0
    out = block(changed, valid)
    assert torch.allclose(out[:, :, :t], ref[:, :, :t], atol=1e-6)  # earlier steps: no agent sees the change
    assert not torch.allclose(out[:, 1, t], ref[:, 1, t])


@torch.no_grad()
def test_dict_and_flat_paths_agree_and_match_the_env_space():
    import navzoo

    dict_space = navzoo.make("navzoo/Home-v0").observation_space("robot_0")
    flat_space = navzoo.make("navzoo/Home-v0", flat_obs=True).observation_space("robot_0")
    assert dict_space == observation_dict_space(K, T, C)
    assert flat_space == spaces.flatten_space(dict_space)
    assert flat_layout(K, T, C)["agents"][0] == 0  # gymnasium sorts the Dict's keys
    ext_d, ext_f = _extractor(dict_space), _extractor(flat_space)
    ext_f.load_state_dict(ext_d.state_dict())
    obs = _batch(3)
    flat = np.stack([spaces.flatten(dict_space, {k: v[i].numpy() for k, v in obs.items()}) for i in range(3)])
    assert torch.allclose(ext_d(obs), ext_f(torch.as_tensor(flat)), atol=1e-6)


@torch.no_grad()
def test_orientation_is_used_as_given():
    """cos/sin of the body orientation (e.g. from the perception wrapper) is an input of its own."""
    ext = _extractor()
    obs = _batch()
    turned = {k: v.clone() for k, v in obs.items()}
    turned["agents"][:, 0, :, 4:6] = torch.tensor([0.0, 1.0]) * turned["agents_mask"][:, 0, :, None]
    assert not torch.allclose(ext(turned), ext(obs))


def test_bad_spaces_and_sizes_are_rejected():
    with pytest.raises(ValueError, match="does not fit K=6, T=8"):
        SpatioTemporalExtractor(spaces.Box(-1, 1, (100,), np.float32))
    with pytest.raises(ValueError, match="divisible"):
        SpatioTemporalExtractor(observation_dict_space(), features_dim=30, n_heads=4)
    with pytest.raises(ValueError, match="history=4 does not match"):
        SpatioTemporalExtractor(observation_dict_space(), history=4)
    with pytest.raises(ValueError, match="net_arch"):
        transformer_policy_kwargs(net_arch=(0,))
    # Non-default K/T through the flat Box: given explicitly, C is derived.
    ext = SpatioTemporalExtractor(spaces.flatten_space(observation_dict_space(4, 3, 16)), k_neighbors=4, history=3,
                                  **SMALL)
    assert (ext.k_neighbors, ext.history, ext.map_cells) == (4, 3, 16)


def test_ppo_learns_a_step_on_the_flat_vec_env():
    from stable_baselines3 import PPO

    from navzoo.envs.vector import sb3_vec_env

    vec = sb3_vec_env("navzoo/Home-v0", n_envs=1, seed=0)
    try:
        model = PPO("MlpPolicy", vec, n_steps=32, batch_size=32, n_epochs=1, seed=0, device="cpu",
                    policy_kwargs=transformer_policy_kwargs(**SMALL, net_arch=(32,)))
        model.learn(64)
        assert model.num_timesteps >= 64
        assert isinstance(model.policy.features_extractor, SpatioTemporalExtractor)
    finally:
        vec.close()


def test_ppo_multi_input_policy_on_dict_observations():
    from stable_baselines3 import PPO
    from stable_baselines3.common.vec_env import DummyVecEnv

    import navzoo
    from navzoo.envs.wrappers import SingleRobotEnv

    vec = DummyVecEnv([lambda: SingleRobotEnv(navzoo.make("navzoo/Home-v0"))])
    try:
        model = PPO("MultiInputPolicy", vec, n_steps=32, batch_size=32, n_epochs=1, seed=0, device="cpu",
                    policy_kwargs=transformer_policy_kwargs(**SMALL, net_arch=(32,)))
        model.learn(32)
        assert model.num_timesteps >= 32
    finally:
        vec.close()
