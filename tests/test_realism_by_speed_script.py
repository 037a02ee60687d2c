"""Realism split by speed (scripts/amp_realism_by_speed.py): option parsing, speed bands, keypoint residuals."""

from __future__ import annotations

import numpy as np
import pytest

from navzoo.benchmark import realism
from tests.script_modules import load_script

rbs = load_script("amp_realism_by_speed")


def test_bands_are_checked_and_closed_at_both_ends():
    assert rbs.parse_bands("0.3,0.9") == [0.0, 0.3, 0.9, float("inf")]
    assert rbs.band_labels([0.0, 0.3, float("inf")]) == ["0-0.3", ">=0.3"]
    for bad in ("0.9,0.3", "0,1", "fast", ""):
        with pytest.raises(SystemExit, match="--bands"):
            rbs.parse_bands(bad)


def test_scene_and_source_options_name_the_problem(tmp_path):
    assert rbs.parse_scenes("lobby:15,corridor:12") == [("lobby", 15), ("corridor", 12)]
    with pytest.raises(SystemExit, match="SCENE:PEOPLE"):
        rbs.parse_scenes("lobby")
    assert rbs.parse_source("kinematic") == ("kinematic", None)
    with pytest.raises(SystemExit, match="no config.json"):
        rbs.parse_source(f"x={tmp_path}")
    (tmp_path / "config.json").write_text("{}")
    assert rbs.parse_source(f"x={tmp_path}") == ("x", str(tmp_path))
    with pytest.raises(SystemExit, match="LABEL=POLICY_DIR"):
        rbs.parse_source("policies/amp_pedestrian")


def _poses(n: int, seed: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    kp = rng.normal(size=(n, realism.N_KEYPOINTS, 3))
    kp[:, realism.CHEST, 2] += 3.0  # a spine to scale by
    return realism.normalize_poses(kp)


def test_keypoint_residuals_vanish_on_the_reference_and_grow_with_an_offset():
    ref = _poses(300, 0)
    rng = np.random.default_rng(1)
    same = rbs.keypoint_residuals(ref, ref, rng)
    assert max(same.values()) < 1e-6
    moved = ref.copy().reshape(-1, realism.N_KEYPOINTS, 3)
    moved[:, realism.KEYPOINT_NAMES.index("left_wrist"), 2] += 5.0  # far beyond any reference frame's wrist
    res = rbs.keypoint_residuals(moved.reshape(len(ref), -1), ref, rng)
    assert res["left_wrist"] > 4.0
    assert max(v for k, v in res.items() if k != "left_wrist") < res["left_wrist"] / 4


def test_keypoint_residuals_can_exclude_the_poses_own_clip():
    ref = _poses(200, 2)
    ids = np.repeat(np.arange(4), 50)
    res = rbs.keypoint_residuals(ref, ref, np.random.default_rng(0), exclude_same=ids, ref_ids=ids)
    assert min(v for k, v in res.items() if k != "pelvis") > 0.01  # no pose is matched to itself


def test_score_splits_poses_by_speed_and_skips_small_bands():
    ref_poses = _poses(400, 3)
    ref = realism.RealismReference.fit(ref_poses, seed=0, max_samples=200)
    speeds = np.r_[np.full(350, 1.2), np.full(50, 0.1)]
    out = rbs.score(ref_poses, speeds, [0.0, 0.3, float("inf")], ref)
    assert out["all"]["n"] == 400 and out["0-0.3"]["n"] == 50 and out[">=0.3"]["n"] == 350
    assert out["0-0.3"]["share"] == pytest.approx(0.125)
    assert "mmd" in out[">=0.3"] and "mmd" not in out["0-0.3"]  # fewer than 100 poses: no metrics


def test_posture_bias_is_the_mean_walking_offset_and_removing_it_lowers_the_mmd():
    ref_poses = _poses(600, 4)
    ref = realism.RealismReference.fit(ref_poses, seed=0, max_samples=300)
    fast = np.full(len(ref_poses), 1.2)
    shift = np.zeros(realism.POSE_DIM)
    shift[realism.KEYPOINT_NAMES.index("right_foot") * 3] = 0.7  # the right foot ahead, on average
    gen = _poses(600, 5) + shift
    out = rbs.posture(gen, fast, ref_poses, fast, ref, walk=0.9)
    assert out["bias"]["right_foot"][0] == pytest.approx(0.7, abs=0.15)
    assert abs(out["bias"]["left_foot"][0]) < 0.15
    assert out["mmd_bias_removed"] < realism.realism_metrics(gen, ref)["mmd"]
    assert rbs.posture(gen, np.zeros(len(gen)), ref_poses, fast, ref, walk=0.9) == {}  # no walking poses
