"""Imitation pretraining of the robot policy: demonstrations, DAgger mixing, fitting, export."""

from __future__ import annotations

import argparse
import json

import numpy as np
import pytest

import navzoo
from navzoo.agents.robot_bc import collect, discounted_returns, load_demos, main, pretrain
from navzoo.agents.robot_train import add_arguments, load_policy, run_cli
from navzoo.envs.subgoal import GuidedPolicy

pytestmark = pytest.mark.usefixtures("one_torch_thread")

TINY = ["--features-dim", "16", "--heads", "2", "--blocks", "1", "--net-arch", "16", "--threads", "1",
        "--n-epochs", "1"]
SHORT = {"robot_subgoal": 3.0, "robot_progress": "geodesic", "wall_proximity": 0.2, "max_episode_steps_override": 25}


@pytest.fixture(scope="module")
def tiny_policy(tmp_path_factory):
    """A tiny forward-only policy trained for 32 steps with subgoals (the new training options)."""
    out = tmp_path_factory.mktemp("tiny")
    args = add_arguments(argparse.ArgumentParser()).parse_args(
        ["--out", str(out), "--scenes", "home", "--total-steps", "32", "--forward-only", "--robot-subgoal", "3",
         "--robot-progress", "geodesic", "--wall-proximity", "0.2", *TINY])
    import torch

    torch.set_num_threads(1)
    assert run_cli(args) == 0
    return out / "policy"


def test_discounted_returns_restart_at_episode_ends():
    r = np.array([1.0, 1.0, 1.0, 5.0, 2.0])
    ends = np.array([False, False, True, False, True])
    np.testing.assert_allclose(discounted_returns(r, ends, 0.5), [1.75, 1.5, 1.0, 6.0, 2.0])


def test_training_options_reach_the_exported_policy(tiny_policy):
    cfg = json.loads((tiny_policy / "config.json").read_text())
    assert cfg["training"]["env_overrides"] == {"robot_subgoal": 3.0, "robot_progress": "geodesic",
                                                "wall_proximity": 0.2}
    pol = load_policy(tiny_policy)
    assert isinstance(pol, GuidedPolicy) and pol.lookahead == 3.0
    env = navzoo.make("navzoo/Home-v0", n_humans=1)  # an env without subgoals: the policy plans its own
    obs, _ = env.reset(seed=0)
    pol.reset(env.unwrapped)
    act = pol.act(obs, env.unwrapped)["robot_0"]
    assert act.shape == (2,) and np.isfinite(act).all() and act[0] >= 0.0
    env.close()


def test_bad_training_option_is_rejected(tmp_path):
    args = add_arguments(argparse.ArgumentParser()).parse_args(["--out", str(tmp_path), "--robot-subgoal", "-1"])
    with pytest.raises(ValueError, match="robot_subgoal must be None or a finite number > 0"):
        run_cli(args)


def test_collect_pretrain_and_dagger(tmp_path, tiny_policy, capsys):
    demos = tmp_path / "demos"
    paths = collect(demos, ["navzoo/Home-v0"], episodes=2, seed=3, overrides=SHORT)
    data, metas = load_demos(demos)
    n = len(data["reward"])
    assert paths[0].is_file() and 2 <= data["end"].sum() == 2 and n <= 2 * 25
    from gymnasium import spaces

    from navzoo.agents.transformer import observation_dict_space

    size = spaces.flatten_space(observation_dict_space(6, 8, 32)).shape[0]
    assert data["obs"].shape == (n, size) and data["action"].shape == (n, 2)
    assert (data["action"][:, 0] >= 0).all() and np.abs(data["action"]).max() <= 1.0
    assert data["by_expert"].all() and metas[0]["expert"] == "orca" and metas[0]["steps"] == n
    # Resumable: an existing shard is not redone.
    stamp = paths[0].stat().st_mtime_ns
    collect(demos, ["navzoo/Home-v0"], episodes=2, seed=3, overrides=SHORT)
    assert paths[0].stat().st_mtime_ns == stamp and '"skipped": "exists"' in capsys.readouterr().out
    # DAgger: the learner drives part of the time, the labels stay the expert's.
    dag = collect(demos, ["navzoo/Home-v0"], episodes=2, seed=4, learner=tiny_policy, beta=0.5, overrides=SHORT)
    with np.load(dag[0]) as z:
        assert 0 < z["by_expert"].sum() < len(z["by_expert"])
    # Fit: the expert's actions get likelier, and the export acts like a trained policy.
    summary = pretrain(demos, tmp_path / "bc", init_from=tiny_policy, epochs=4, batch_size=16, lr=1e-3)
    rows = [json.loads(line) for line in (tmp_path / "bc" / "pretrain.jsonl").read_text().splitlines()]
    assert len(rows) == 4 and rows[-1]["train"]["nll"] < rows[0]["train"]["nll"]
    assert summary["episodes"] == 4
    pol = load_policy(tmp_path / "bc" / "policy")
    assert isinstance(pol, GuidedPolicy)
    cfg = json.loads((tmp_path / "bc" / "policy" / "config.json").read_text())
    assert cfg["training"]["env_overrides"]["robot_subgoal"] == 3.0
    assert cfg["action"]["low"][0] == 0.0  # the tiny policy's forward-only box is kept


def test_bad_demonstrations_and_options_are_named(tmp_path, tiny_policy):
    with pytest.raises(FileNotFoundError, match="no demonstration shards"):
        load_demos(tmp_path)
    (tmp_path / "broken.npz").write_bytes(b"not a zip")
    with pytest.raises(ValueError, match="broken.npz is unreadable"):
        load_demos(tmp_path)
    with pytest.raises(ValueError, match="beta must be in"):
        collect(tmp_path / "x", ["navzoo/Home-v0"], episodes=1, beta=0.0)
    with pytest.raises(ValueError, match="needs a learner"):
        collect(tmp_path / "x", ["navzoo/Home-v0"], episodes=1, beta=0.5)
    assert main(["pretrain", "--demos", str(tmp_path / "empty"), "--out", str(tmp_path / "o")]) == 2
