"""Weight averaging of exported AMP policies (navzoo.agents.amp.checkpoint.average_policies, `navzoo train amp-average`)."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
import torch

from navzoo.agents.amp.checkpoint import CheckpointError, average_policies, export_policy_files, load_policy
from navzoo.agents.amp.features import FEATURE_DIM, N_RAYS
from navzoo.agents.amp.networks import Actor
from navzoo.agents.amp.normalizer import RunningMeanStd
from navzoo.cli import main as cli_main

OBS, ACT = FEATURE_DIM + 20 + N_RAYS, 28  # the controller's layout (a symmetric policy needs it)


def _policy(path: Path, seed: int, hidden: list[int] | None = None, **extra) -> Path:
    torch.manual_seed(seed)
    hidden = hidden or [16]
    actor = Actor(OBS, ACT, hidden, "relu")
    norm = RunningMeanStd(OBS, clip=5.0)
    norm.update(torch.randn(50, OBS, dtype=torch.float64) * (1 + seed) + seed)
    return export_policy_files(path, actor, norm, {"obs_dim": OBS, "act_dim": ACT, "actor_hidden": hidden,
                                                   "activation": "relu", "trained_iterations": 100 + seed, **extra})


def _tensors(path: Path) -> dict[str, torch.Tensor]:
    return torch.load(path / "policy.pt", weights_only=True)


def test_average_is_the_weighted_mean_of_every_tensor(tmp_path: Path) -> None:
    a, b = _policy(tmp_path / "a", 0), _policy(tmp_path / "b", 1)
    out = average_policies([a, b], tmp_path / "soup", [3.0, 1.0])
    ta, tb, ts = _tensors(a), _tensors(b), _tensors(out)
    assert set(ts) == set(ta)
    for k in ta:
        torch.testing.assert_close(ts[k].double(), 0.75 * ta[k].double() + 0.25 * tb[k].double())
        assert ts[k].dtype == ta[k].dtype
    cfg = json.loads((out / "config.json").read_text())
    assert [s["weight"] for s in cfg["averaged_from"]] == [0.75, 0.25]
    assert cfg["trained_iterations"] == 101 and "steering_trim" not in cfg
    load_policy(out)  # verifies format and sha256


def test_weight_one_reproduces_that_policy(tmp_path: Path) -> None:
    a, b = _policy(tmp_path / "a", 0), _policy(tmp_path / "b", 1)
    out = average_policies([a, b], tmp_path / "soup", [0.0, 1.0])
    obs = np.random.default_rng(0).normal(size=(8, OBS)).astype(np.float32)
    np.testing.assert_allclose(load_policy(out)(obs), load_policy(b)(obs), atol=1e-6)
    # equal weights of two copies of one policy give that policy back
    same = average_policies([a, a], tmp_path / "same")
    np.testing.assert_allclose(load_policy(same)(obs), load_policy(a)(obs), atol=1e-6)


def test_bad_inputs_are_rejected_with_the_reason(tmp_path: Path) -> None:
    a, b = _policy(tmp_path / "a", 0), _policy(tmp_path / "b", 1)
    wide = _policy(tmp_path / "wide", 2, hidden=[32])
    with pytest.raises(ValueError, match="at least two"):
        average_policies([a], tmp_path / "x")
    with pytest.raises(ValueError, match="2 weights for 3"):
        average_policies([a, b, a], tmp_path / "x", [1.0, 1.0])
    with pytest.raises(ValueError, match="finite"):
        average_policies([a, b], tmp_path / "x", [1.0, float("nan")])
    with pytest.raises(ValueError, match="finite"):
        average_policies([a, b], tmp_path / "x", [0.0, 0.0])
    with pytest.raises(CheckpointError, match="actor_hidden"):
        average_policies([a, wide], tmp_path / "x")
    sym = _policy(tmp_path / "sym", 3, symmetric=True)
    with pytest.raises(CheckpointError, match="symmetric"):
        average_policies([a, sym], tmp_path / "x")
    (b / "policy.pt").write_bytes((b / "policy.pt").read_bytes()[:-8])  # corrupted weights
    with pytest.raises(CheckpointError, match="sha256"):
        average_policies([a, b], tmp_path / "x")
    assert not (tmp_path / "x").exists()


def test_cli_writes_the_soup_and_reports_bad_weights(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    a, b = _policy(tmp_path / "a", 0), _policy(tmp_path / "b", 1)
    assert cli_main(["train", "amp-average", str(a), str(b), "--out", str(tmp_path / "soup")]) == 0
    assert json.loads(capsys.readouterr().out)["policy"] == str(tmp_path / "soup")
    with pytest.raises(SystemExit):
        cli_main(["train", "amp-average", str(a), str(b), "--weights", "1,x", "--out", str(tmp_path / "y")])
    assert "amp-average" in capsys.readouterr().err


def test_cli_says_when_the_sources_trims_are_not_carried_over(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    trim = {"rad": 0.025, "n_waypoints": 10, "waypoint_start": 105, "off_for_crowd_models": []}
    a, b = _policy(tmp_path / "a", 0, steering_trim=trim), _policy(tmp_path / "b", 1)
    assert cli_main(["train", "amp-average", str(a), str(b), "--out", str(tmp_path / "soup")]) == 0
    err = capsys.readouterr().err
    assert "no steering trim" in err and f"{a} has 0.025 rad" in err and str(b) not in err
    assert "steering_trim" not in json.loads((tmp_path / "soup" / "config.json").read_text())
    # untrimmed sources: nothing to say
    assert cli_main(["train", "amp-average", str(b), str(b), "--out", str(tmp_path / "soup2")]) == 0
    assert capsys.readouterr().err == ""


def _fake_checkpoint(root: Path, hidden: list[int] | None = None) -> Path:
    from navzoo.agents.amp.checkpoint import save_checkpoint

    torch.manual_seed(7)
    actor = Actor(OBS, ACT, hidden or [16], "relu")
    norm = RunningMeanStd(OBS, clip=5.0)
    tensors = {"actor": actor.state_dict(), "obs_norm": norm.state_dict(),
               "critic": {"w": torch.arange(6.0)}, "actor_opt": {"step": torch.tensor(3.0)}}
    return save_checkpoint(root, 42, tensors, {"counters": {"global_step": 1000}, "config": {"x": 1}})


def test_checkpoint_with_policy_swaps_only_the_actor_and_its_normaliser(tmp_path: Path) -> None:
    from navzoo.agents.amp.checkpoint import checkpoint_with_policy, load_checkpoint

    start = _fake_checkpoint(tmp_path / "ckpts")
    pol = average_policies([_policy(tmp_path / "a", 0), _policy(tmp_path / "b", 1)], tmp_path / "soup")
    out = checkpoint_with_policy(start, pol, tmp_path / "out")
    assert out.name == "ckpt_00000042"
    tensors, meta = load_checkpoint(out)  # verified: format and sha256
    soup = _tensors(pol)
    for k, v in tensors["actor"].items():
        torch.testing.assert_close(v, soup[f"actor.{k}"])
    for k, v in tensors["obs_norm"].items():
        torch.testing.assert_close(v, soup[f"obs_norm.{k}"])
    torch.testing.assert_close(tensors["critic"]["w"], torch.arange(6.0))
    assert meta["counters"] == {"global_step": 1000} and meta["config"] == {"x": 1}
    assert meta["actor_from_policy"]["weights_sha256"] == json.loads((pol / "config.json").read_text())["weights_sha256"]
    # a policy of another architecture does not fit
    wide = _policy(tmp_path / "wide", 2, hidden=[32])
    with pytest.raises(CheckpointError, match="does not fit"):
        checkpoint_with_policy(start, wide, tmp_path / "out2")


def test_the_shipped_training_start_carries_the_shipped_policy(tmp_path: Path) -> None:
    from navzoo.agents.amp.checkpoint import load_checkpoint
    from navzoo.agents.amp.pedestrian_policy import default_policy_dir
    from navzoo.rl.amp_joint import shipped_training_checkpoint

    tensors, meta = load_checkpoint(shipped_training_checkpoint(tmp_path))
    shipped = _tensors(default_policy_dir())
    for k, v in tensors["actor"].items():
        torch.testing.assert_close(v, shipped[f"actor.{k}"])
    assert meta["actor_from_policy"]["checkpoint"] == "ckpt_00005174"
