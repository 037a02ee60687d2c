"""Robot policies with a range scan: the extractor's scan input, widening a scan-less policy, BC end to end."""

from __future__ import annotations

import json

import numpy as np
import pytest
import torch
from gymnasium import spaces
from stable_baselines3.common.policies import ActorCriticPolicy

import navzoo
from navzoo.agents.robot_bc import collect, load_demos, pretrain
from navzoo.agents.robot_train import init_weights_from, load_policy
from navzoo.agents.transformer import (
    SpatioTemporalExtractor,
    flat_layout,
    observation_dict_space,
    transformer_policy_kwargs,
)
from navzoo.envs.scan import ScanPolicy

pytestmark = pytest.mark.usefixtures("one_torch_thread")

K, T, C, R = 6, 8, 32, 8
SMALL = dict(features_dim=32, n_heads=2, n_blocks=1)
CROWDNAV = "policies/transformer_ppo_crowdnav"


def _env_obs(n: int = 6, rays: int = R, seed: int = 0) -> list[dict[str, np.ndarray]]:
    """``n`` robot Dict observations (with a scan of ``rays``) from a short Home rollout."""
    env = navzoo.make("navzoo/Home-v0", scan_rays=rays, n_humans=3)
    obs, _ = env.reset(seed=seed)
    out = []
    for t in range(n):
        out.append(obs["robot_0"])
        obs, *_ = env.step({"robot_0": np.array([0.7, 0.5 * np.sin(t)], np.float32)})
        assert "robot_0" in obs
    env.close()
    return out


def _widened(model: ActorCriticPolicy, rays: int, **kw) -> ActorCriticPolicy:
    """``model``'s network with a scan input of ``rays`` (as ``robot_bc.pretrain`` builds it; ``kw`` to SB3)."""
    ext = model.features_extractor
    obs_space = spaces.flatten_space(observation_dict_space(ext.k_neighbors, ext.history, ext.map_cells, rays))
    arch = model.net_arch
    return ActorCriticPolicy(obs_space, model.action_space, lr_schedule=lambda _: 1e-4,
                             net_arch=arch if isinstance(arch, dict) else list(arch),
                             activation_fn=model.activation_fn, features_extractor_class=type(ext),
                             features_extractor_kwargs={**ext.config(), "scan_rays": rays},
                             share_features_extractor=model.share_features_extractor, **kw)


# ---------------------------------------------------------------------------------------------------------
# The extractor
# ---------------------------------------------------------------------------------------------------------


@torch.no_grad()
def test_dict_and_flat_extractors_agree_with_a_scan():
    dict_space = observation_dict_space(K, T, C, R)
    flat_space = spaces.flatten_space(dict_space)
    torch.manual_seed(0)
    ext_d = SpatioTemporalExtractor(dict_space, **SMALL).eval()
    ext_f = SpatioTemporalExtractor(flat_space, scan_rays=R, **SMALL).eval()
    assert ext_d.scan_rays == ext_f.scan_rays == R and not ext_d.is_flat and ext_f.is_flat
    assert ext_d.config()["scan_rays"] == R and ext_f.config() == ext_d.config()
    # The scan's output layer starts at zero; make it matter so that the comparison covers it.
    torch.nn.init.normal_(ext_d.scan_encoder[2].weight, std=0.5)
    ext_f.load_state_dict(ext_d.state_dict())

    obs = _env_obs(4)
    batch_d = {k: torch.as_tensor(np.stack([o[k] for o in obs])) for k in dict_space.spaces}
    batch_f = torch.as_tensor(np.stack([spaces.flatten(dict_space, o) for o in obs]))
    out_d, out_f = ext_d(batch_d), ext_f(batch_f)
    assert out_d.shape == (4, 32) and torch.isfinite(out_d).all()
    torch.testing.assert_close(out_d, out_f, rtol=0, atol=1e-6)
    # The scan is read from the right place: changing it changes the output, in both forms alike.
    batch_d["scan"] = 1.0 - batch_d["scan"]
    s, e, _ = flat_layout(K, T, C, R)["scan"]
    batch_f[:, s:e] = 1.0 - batch_f[:, s:e]
    moved_d, moved_f = ext_d(batch_d), ext_f(batch_f)
    assert (moved_d - out_d).abs().max() > 1e-3
    torch.testing.assert_close(moved_d, moved_f, rtol=0, atol=1e-6)


@torch.no_grad()
def test_zero_initialised_scan_branch_does_not_change_the_output():
    torch.manual_seed(1)
    ext = SpatioTemporalExtractor(observation_dict_space(K, T, C, R), **SMALL).eval()
    obs = _env_obs(3)
    batch = {k: torch.as_tensor(np.stack([o[k] for o in obs])) for k in obs[0]}
    ref = ext(batch)
    batch["scan"] = torch.rand_like(batch["scan"])
    torch.testing.assert_close(ext(batch), ref, rtol=0, atol=0)


def test_extractor_scan_size_checks():
    flat_space = spaces.flatten_space(observation_dict_space(K, T, C, R))
    with pytest.raises(ValueError, match="scan_rays"):  # a flat Box with a scan needs its size
        SpatioTemporalExtractor(flat_space, **SMALL)
    with pytest.raises(ValueError, match="scan_rays"):  # a Dict's scan must match the given size
        SpatioTemporalExtractor(observation_dict_space(K, T, C, R), scan_rays=R + 1, **SMALL)
    plain = SpatioTemporalExtractor(observation_dict_space(K, T, C), **SMALL)
    assert plain.scan_rays == 0 and "scan_rays" not in plain.config() and not hasattr(plain, "scan_encoder")
    for bad in (-1, 2.5, True):
        with pytest.raises(ValueError, match="scan_rays"):
            observation_dict_space(K, T, C, bad)
    lay = flat_layout(K, T, C, R)
    assert list(lay) == ["agents", "agents_mask", "goal", "map", "scan", "velocity"]
    assert lay["scan"][2] == (R,) and lay["velocity"][1] == flat_space.shape[0]


# ---------------------------------------------------------------------------------------------------------
# Widening an exported scan-less policy
# ---------------------------------------------------------------------------------------------------------


def _compare_with_original(wide: ActorCriticPolicy, orig: ActorCriticPolicy) -> None:
    """``wide`` (with a scan) acts and values like ``orig`` (without) on the same Home observations."""
    obs = _env_obs(6)
    with_scan = observation_dict_space(K, T, C, R)
    without = observation_dict_space(K, T, C)
    x_wide = np.stack([spaces.flatten(with_scan, o) for o in obs])
    x_orig = np.stack([spaces.flatten(without, {k: v for k, v in o.items() if k != "scan"}) for o in obs])
    assert x_wide.shape[1] == x_orig.shape[1] + R
    a_wide, _ = wide.predict(x_wide, deterministic=True)
    a_orig, _ = orig.predict(x_orig, deterministic=True)
    assert a_wide.shape == (6, 2)
    np.testing.assert_allclose(a_wide, a_orig, rtol=0, atol=1e-6)
    with torch.no_grad():
        v_wide = wide.predict_values(torch.as_tensor(x_wide))
        v_orig = orig.predict_values(torch.as_tensor(x_orig))
    torch.testing.assert_close(v_wide, v_orig, rtol=0, atol=1e-5)
    # Once the scan branch learns something the actions depend on the scan.
    with torch.no_grad():
        torch.nn.init.normal_(wide.features_extractor.scan_encoder[2].weight, std=0.5)
    a_moved, _ = wide.predict(x_wide, deterministic=True)
    assert np.abs(a_moved - a_orig).max() > 1e-3


def test_init_weights_from_loads_all_but_the_scan_branch():
    orig = load_policy(CROWDNAV).model
    assert orig.features_extractor.scan_rays == 0
    wide = _widened(orig, R)
    missing = init_weights_from(wide, CROWDNAV)
    assert missing and all(".scan_encoder." in k for k in missing)
    assert wide.features_extractor.scan_rays == R
    new, old = wide.state_dict(), orig.state_dict()
    assert set(new) - set(old) == set(missing)
    for k, v in old.items():
        torch.testing.assert_close(new[k], v, rtol=0, atol=0)


def test_widened_policy_acts_like_the_original_when_its_scan_branch_starts_at_zero():
    # SB3's orthogonal initialisation is switched off here, so the extractor's zero output layer survives:
    # the design (zero-initialised scan branch + init_weights_from) keeps the loaded behaviour.
    orig = load_policy(CROWDNAV).model
    wide = _widened(orig, R, ortho_init=False)
    wide.set_training_mode(False)
    init_weights_from(wide, CROWDNAV)
    assert not wide.features_extractor.scan_encoder[2].weight.any()
    _compare_with_original(wide, orig)


def test_widened_policy_acts_like_the_one_it_was_loaded_from():
    orig = load_policy(CROWDNAV).model
    wide = _widened(orig, R)  # exactly as robot_bc.pretrain builds it
    wide.set_training_mode(False)
    init_weights_from(wide, CROWDNAV)
    assert not wide.features_extractor.scan_encoder[2].weight.any(), "the scan branch's output layer is not zero"
    _compare_with_original(wide, orig)


def test_init_weights_from_rejects_another_network():
    # Another K: another observation space.
    space = spaces.flatten_space(observation_dict_space(4, T, C, R))
    other_k = ActorCriticPolicy(space, spaces.Box(np.array([0.0, -1.0], np.float32), np.ones(2, np.float32)),
                                lr_schedule=lambda _: 1e-4, **transformer_policy_kwargs(k_neighbors=4, scan_rays=R))
    with pytest.raises(ValueError, match="does not fit"):
        init_weights_from(other_k, CROWDNAV)
    # The same observation, another width.
    space = spaces.flatten_space(observation_dict_space(K, T, C, R))
    narrow = ActorCriticPolicy(space, spaces.Box(np.array([0.0, -1.0], np.float32), np.ones(2, np.float32)),
                               lr_schedule=lambda _: 1e-4,
                               **transformer_policy_kwargs(features_dim=64, scan_rays=R))
    with pytest.raises(ValueError, match="network shape"):
        init_weights_from(narrow, CROWDNAV)


# ---------------------------------------------------------------------------------------------------------
# Behaviour cloning with a scan, end to end
# ---------------------------------------------------------------------------------------------------------

SHORT = {"robot_subgoal": 3.0, "scan_rays": R, "max_episode_steps_override": 10}


@pytest.fixture(scope="module")
def scan_bc(tmp_path_factory):
    """Demos with a scan (2 short Home episodes) and a policy pretrained on them from the scan-less CrowdNav one."""
    torch.set_num_threads(1)
    root = tmp_path_factory.mktemp("scan_bc")
    paths = collect(root / "demos", ["navzoo/Home-v0"], episodes=2, seed=0, overrides=SHORT)
    summary = pretrain(root / "demos", root / "bc", init_from=CROWDNAV, epochs=1, batch_size=8, lr=1e-3)
    return root, paths, summary


def test_collected_demos_hold_the_scan(scan_bc):
    root, paths, summary = scan_bc
    data, metas = load_demos(root / "demos")
    size = spaces.flatten_space(observation_dict_space(K, T, C, R)).shape[0]
    n = len(data["reward"])
    assert data["obs"].shape == (n, size) and n <= 20 and data["end"].sum() == 2
    assert metas[0]["overrides"]["scan_rays"] == R
    s, e, _ = flat_layout(K, T, C, R)["scan"]
    scans = data["obs"][:, s:e]
    assert (scans >= 0).all() and (scans <= 1).all() and scans.min() < 1.0
    assert summary["episodes"] == 2


def test_pretrained_scan_policy_is_exported_and_wrapped(scan_bc):
    root, _, _ = scan_bc
    cfg = json.loads((root / "bc" / "policy" / "config.json").read_text())
    assert cfg["observation"]["scan_rays"] == R
    assert cfg["features_extractor"]["kwargs"]["scan_rays"] == R
    assert cfg["training"]["env_overrides"]["scan_rays"] == R
    assert cfg["action"]["low"] == [0.0, -1.0]  # the CrowdNav policy's forward-only box
    pol = load_policy(root / "bc" / "policy")
    assert isinstance(pol, ScanPolicy) and pol.rays == R and pol.scan_range == 4.0
    ext = pol.model.features_extractor
    assert ext.scan_rays == R
    assert ext.scan_encoder[2].weight.abs().max() > 0  # trained away from its zero start
    # An exported scan policy cannot initialise a network with another ray count.
    with pytest.raises(ValueError, match="does not fit"):
        init_weights_from(_widened(load_policy(CROWDNAV).model, R + 4), root / "bc" / "policy")


def _drive(policy_dir, steps: int = 8, **env_kw) -> np.ndarray:
    pol = load_policy(policy_dir)
    env = navzoo.make("navzoo/Home-v0", n_humans=2, **env_kw)
    obs, _ = env.reset(seed=7)
    nav = env.unwrapped
    pol.reset(nav)
    actions = []
    for _ in range(steps):
        act = pol.act(obs, nav)
        assert set(act) == {"robot_0"} and act["robot_0"].shape == (2,)
        actions.append(act["robot_0"])
        obs, *_ = env.step(act)
        if "robot_0" not in obs:
            break
    env.close()
    return np.array(actions)


def test_scan_policy_acts_alike_with_and_without_the_envs_scan(scan_bc):
    root, _, _ = scan_bc
    policy_dir = root / "bc" / "policy"
    ref = _drive(policy_dir, scan_rays=R)  # the env's own scan, passed through
    assert len(ref) >= 4
    for kw in ({}, {"flat_obs": True}, {"scan_rays": R, "scan_range": 2.0, "flat_obs": True},
               {"scan_rays": 2 * R}):
        np.testing.assert_allclose(_drive(policy_dir, **kw), ref, rtol=0, atol=1e-5, err_msg=str(kw))
