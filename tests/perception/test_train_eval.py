"""``navzoo train perception`` (tiny, resumable) and ``navzoo eval perception`` with the shipped network."""

from __future__ import annotations

import json

import numpy as np
import pytest

from navzoo.cli import main as cli_main
from navzoo.perception.dataset import load_dataset
from navzoo.perception.evaluate import evaluate
from navzoo.perception.monoloco import DEFAULT_MODEL_DIR, load_estimator


def test_train_perception_tiny_run_and_resume(tmp_path, capsys):
    out = tmp_path / "p"
    args = ["train", "perception", "--out", str(out), "--scenes", "corridor,cafe", "--steps", "40",
            "--epochs", "2", "--batch-size", "64", "--hidden", "32", "--blocks", "1"]
    assert cli_main(args) == 0
    data = load_dataset(out / "data" / "corridor.npz")
    assert len(data["distance"]) > 20 and data["features"].shape[1] == 51
    assert np.all(data["distance"] > 0.3)
    rows = [json.loads(x) for x in (out / "metrics.jsonl").read_text().splitlines()]
    assert [r["epoch"] for r in rows] == [1, 2]
    est = load_estimator(out / "model")
    assert est.meta["architecture"]["hidden"] == 32
    # More epochs resume from the saved state: the data are reused and only epoch 3 runs.
    assert cli_main(args[:-8] + ["--epochs", "3", "--batch-size", "64", "--hidden", "32", "--blocks", "1"]) == 0
    rows = [json.loads(x) for x in (out / "metrics.jsonl").read_text().splitlines()]
    assert [r["epoch"] for r in rows] == [1, 2, 3]
    assert "resumed_at_epoch" in capsys.readouterr().out


def test_train_perception_rejects_bad_options(tmp_path):
    with pytest.raises(SystemExit):
        cli_main(["train", "perception", "--out", str(tmp_path), "--scenes", "atlantis"])
    with pytest.raises(SystemExit):
        cli_main(["train", "perception", "--out", str(tmp_path), "--epochs", "0"])


@pytest.mark.skipif(not (DEFAULT_MODEL_DIR / "model.pt").is_file(), reason="no shipped perception model")
def test_shipped_network_localises_people_in_a_held_out_scene():
    """The shipped network on a scene and crowd it was not trained on: errors far below chance."""
    r = evaluate(("doorway",), steps=60, seed=5)
    assert r["detections"] > 30
    near = [b for b in r["by_distance"] if b["bin_m"][1] <= 6.0 and b["n"]]
    assert near and all(b["mean_rel"] < 0.25 for b in near)
    assert r["orientation_error_rad"] < 0.8   # uniform guessing: pi / 2
    assert 0.0 <= r["precision"] <= 1.0 and 0.0 < r["recall"] <= 1.0
    for key in ("localization_error_m", "orientation_error_rad", "recall", "precision", "mota", "id_switches",
                "velocity_error_mps", "ms_per_robot_step"):
        assert key in r


@pytest.mark.skipif(not (DEFAULT_MODEL_DIR / "model.pt").is_file(), reason="no shipped perception model")
def test_eval_perception_cli_json(capsys):
    assert cli_main(["eval", "perception", "--quick", "--steps", "20", "--nav-episodes", "0", "--json"]) == 0
    r = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    assert r["frames"] == 20 and r["ms_per_robot_step"] > 0


def test_navigation_comparison_runs_a_learned_policy_in_a_preset():
    """A registered env id keeps its preset; the method's -diffdrive suffix sets the robot; the learned
    CrowdNav policy reads the perceived people from its observations."""
    from navzoo.perception.navigation import run_episode

    rows = [run_episode("transformer-ppo-crowdnav-diffdrive", "navzoo/CircleCrossing-v0", 0, perceived)
            for perceived in (False, True)]
    for r in rows:
        assert r["event"] in ("goal", "timeout") or r["event"].startswith("collision")
        assert r["time_s"] > 0 and np.isfinite(r["min_distance_m"])
    assert rows[0]["event"] == "goal"  # the ground-truth episode of seed 0 (the policy succeeds in 99 %)
