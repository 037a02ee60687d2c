"""scripts/amp_perturb_policy.py: a copy of an exported AMP policy with seeded noise on its actor's weights."""

import json
import sys
from pathlib import Path

import numpy as np
import pytest
import torch

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "scripts"))

import amp_perturb_policy  # noqa: E402

from navzoo.agents.amp.checkpoint import load_policy  # noqa: E402
from navzoo.agents.amp.pedestrian_policy import default_policy_dir  # noqa: E402


def test_noise_is_seeded_sized_and_leaves_std_and_normaliser(tmp_path):
    src = load_policy(default_policy_dir())
    small = load_policy(amp_perturb_policy.perturbed_policy(default_policy_dir(), tmp_path / "a", 0.01, 1))
    again = load_policy(amp_perturb_policy.perturbed_policy(default_policy_dir(), tmp_path / "b", 0.01, 1))
    large = load_policy(amp_perturb_policy.perturbed_policy(default_policy_dir(), tmp_path / "c", 0.1, 1))
    for k, v in small.actor.state_dict().items():
        assert torch.equal(v, again.actor.state_dict()[k])  # same seed, same copy
        if k == "log_std":
            assert torch.equal(v, src.actor.state_dict()[k])
        else:
            assert not torch.equal(v, src.actor.state_dict()[k])
    for k, v in small.obs_norm.state_dict().items():
        assert torch.equal(v, src.obs_norm.state_dict()[k])
    obs = np.random.default_rng(0).normal(size=(64, int(src.config["obs_dim"]))).astype(np.float32)
    d_small = np.abs(small(obs) - src(obs)).mean()
    d_large = np.abs(large(obs) - src(obs)).mean()
    assert 0 < d_small < d_large
    meta = json.loads((tmp_path / "a" / "config.json").read_text())["perturbed_from"]
    assert meta["scale"] == 0.01 and meta["seed"] == 1 and meta["weights_sha256"] == src.config["weights_sha256"]


@pytest.mark.parametrize("scale", [0.0, -0.1, float("nan")])
def test_bad_scales_are_refused(tmp_path, scale):
    with pytest.raises(ValueError, match="scale must be"):
        amp_perturb_policy.perturbed_policy(default_policy_dir(), tmp_path / "x", scale, 0)
