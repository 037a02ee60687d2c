"""Action blending of exported AMP policies (navzoo.agents.amp.blend, `navzoo train amp-blend`)."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
import torch

from navzoo.agents.amp.blend import BlendedPolicy, write_blend
from navzoo.agents.amp.checkpoint import CheckpointError, export_policy_files, load_policy
from navzoo.agents.amp.features import FEATURE_DIM, N_RAYS
from navzoo.agents.amp.networks import Actor
from navzoo.agents.amp.normalizer import RunningMeanStd
from navzoo.cli import main as cli_main

OBS, ACT = FEATURE_DIM + 20 + N_RAYS, 28


def _policy(path: Path, seed: int, obs: int = OBS, **extra) -> Path:
    torch.manual_seed(seed)
    actor = Actor(obs, ACT, [16], "relu")
    norm = RunningMeanStd(obs, clip=5.0)
    norm.update(torch.randn(50, obs, dtype=torch.float64) * (1 + seed) + seed)
    return export_policy_files(path, actor, norm, {"obs_dim": obs, "act_dim": ACT, "actor_hidden": [16],
                                                   "activation": "relu", "trained_iterations": 100 + seed, **extra})


def _obs(n: int = 8) -> np.ndarray:
    return np.random.default_rng(0).normal(size=(n, OBS)).astype(np.float32)


def test_blend_is_the_weighted_mean_of_the_components_actions(tmp_path: Path) -> None:
    a, b = _policy(tmp_path / "a", 0), _policy(tmp_path / "b", 1)
    cfg = write_blend([a, b], tmp_path / "blend", [3.0, 1.0])
    blend = load_policy(cfg.parent)
    assert isinstance(blend, BlendedPolicy)
    obs = _obs()
    pa, pb = load_policy(a)(obs), load_policy(b)(obs)
    assert not np.allclose(pa, pb)
    np.testing.assert_allclose(blend(obs), np.clip(0.75 * pa + 0.25 * pb, -1, 1), atol=1e-6)
    np.testing.assert_allclose(blend(obs[0]), blend(obs)[0], atol=1e-6)  # one observation, or a batch
    saved = json.loads(cfg.read_text())
    assert saved["format"] == "navzoo-amp-blend" and [c["weight"] for c in saved["components"]] == [3.0, 1.0]
    assert all(not Path(c["path"]).is_absolute() for c in saved["components"])  # the folder can move with its parts
    # weight 0 on one component gives the other back
    only_b = load_policy(write_blend([a, b], tmp_path / "only_b", [0.0, 1.0]).parent)
    np.testing.assert_allclose(only_b(obs), pb, atol=1e-6)


def test_component_trims_apply_and_the_blend_has_its_own(tmp_path: Path) -> None:
    trim = {"rad": 0.1, "n_waypoints": 10, "waypoint_start": FEATURE_DIM}
    a, b = _policy(tmp_path / "a", 0, steering_trim=trim), _policy(tmp_path / "b", 1)
    blend = load_policy(write_blend([a, b], tmp_path / "blend").parent)
    obs = _obs()
    np.testing.assert_allclose(blend(obs), 0.5 * load_policy(a)(obs) + 0.5 * load_policy(b)(obs), atol=1e-6)
    before = blend(obs)
    blend.override(steering_trim=0.05)
    assert blend.steering_trim == 0.05 and not np.allclose(blend(obs), before)
    with pytest.raises(ValueError, match="symmetric"):
        blend.override(symmetric=True)
    with pytest.raises(ValueError, match="within"):
        blend.steering_trim = 3.0


def test_the_pedestrian_policy_drives_a_blend(tmp_path: Path) -> None:
    from navzoo.agents.amp.pedestrian_policy import AmpPedestrianPolicy

    a, b = _policy(tmp_path / "a", 0), _policy(tmp_path / "b", 1)
    ped = AmpPedestrianPolicy(write_blend([a, b], tmp_path / "blend").parent)
    obs = _obs(3)
    acts = ped.act({f"human_{k}": obs[k] for k in range(3)}, env=None)
    np.testing.assert_allclose(np.stack([acts[f"human_{k}"] for k in range(3)]), ped.policy(obs), atol=1e-6)


def test_bad_blends_are_rejected_with_the_reason(tmp_path: Path) -> None:
    a, b = _policy(tmp_path / "a", 0), _policy(tmp_path / "b", 1)
    narrow = _policy(tmp_path / "narrow", 2, obs=OBS - N_RAYS)
    with pytest.raises(ValueError, match="at least two"):
        write_blend([a], tmp_path / "x")
    with pytest.raises(ValueError, match="2 weights for 3"):
        write_blend([a, b, a], tmp_path / "x", [1.0, 1.0])
    with pytest.raises(ValueError, match="finite"):
        write_blend([a, b], tmp_path / "x", [1.0, float("nan")])
    with pytest.raises(ValueError, match="obs_dim"):
        write_blend([a, narrow], tmp_path / "x")
    assert not (tmp_path / "x").exists()
    good = write_blend([a, b], tmp_path / "blend").parent
    with pytest.raises(ValueError, match="not blends"):
        write_blend([good, a], tmp_path / "x")
    # a component replaced after blending, a missing one, a nested blend, a broken list
    cfg = json.loads((good / "config.json").read_text())
    _policy(tmp_path / "b", 5)  # other weights under the same path
    with pytest.raises(CheckpointError, match="other weights"):
        load_policy(good)
    for bad, msg in (({**cfg, "components": [cfg["components"][0], {**cfg["components"][1], "path": "../nowhere"}]},
                      "not an exported AMP policy"),
                     ({**cfg, "components": [cfg["components"][0], {"path": "../blend", "weight": 1}]}, "itself a blend"),
                     ({**cfg, "components": cfg["components"][:1]}, "at least two"),
                     ({**cfg, "components": [cfg["components"][0], {"weight": 1}]}, "'path'"),
                     ({**cfg, "components": [cfg["components"][0], {"path": "../a", "weight": -1}]}, "finite"),
                     ({**cfg, "version": 9}, "version"),
                     ({**cfg, "obs_dim": 7, "components": [cfg["components"][0], {"path": "../a"}]}, "obs_dim 7")):
        (good / "config.json").write_text(json.dumps(bad))
        with pytest.raises(CheckpointError, match=msg):
            load_policy(good)


def test_cli_writes_a_blend(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    a, b = _policy(tmp_path / "a", 0), _policy(tmp_path / "b", 1)
    assert cli_main(["train", "amp-blend", str(a), str(b), "--weights", "1,1", "--out", str(tmp_path / "bl")]) == 0
    out = json.loads(capsys.readouterr().out)
    assert len(out["components"]) == 2 and isinstance(load_policy(out["policy"]), BlendedPolicy)
    with pytest.raises(SystemExit):
        cli_main(["train", "amp-blend", str(a), "--out", str(tmp_path / "one")])
    assert "at least two" in capsys.readouterr().err
