"""scripts/amp_checkpoint_tracking.py: exports checkpoints of a training folder (or git history) and tracks clips."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from tests.script_modules import load_script

ROOT = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="module")
def script():
    return load_script("amp_checkpoint_tracking")


def test_sources_are_exported_tracked_and_skipped_when_done(script, tmp_path, monkeypatch):
    calls = []
    monkeypatch.setattr(script, "track_clips", lambda policy, **kw: calls.append(Path(policy)) or {"clip_success_rate": 0.5,
                        "mean_pos_error_m": 0.2, "max_pos_error_m": 0.3, "mean_rot_error_rad": 0.4})
    policy = ROOT / "policies" / "amp_pedestrian"
    out = tmp_path / "rows.jsonl"
    assert script.main([str(policy), "--out", str(out)]) == 0
    assert script.main([str(policy), "--out", str(out)]) == 0  # already there: skipped
    rows = [json.loads(line) for line in out.read_text().splitlines()]
    assert len(rows) == 1 and len(calls) == 1 and calls[0] == policy
    assert rows[0]["source"] == str(policy) and rows[0]["trained_steps"] > 0 and rows[0]["clip_success_rate"] == 0.5


def test_the_path_task_protocol_has_its_own_rows(script, tmp_path, monkeypatch):
    monkeypatch.setattr(script, "track_clips", lambda policy, **kw: {"clip_success_rate": 0.5, "mean_pos_error_m": 0.2,
                                                               "max_pos_error_m": 0.3, "mean_rot_error_rad": 0.4})
    calls = []
    monkeypatch.setattr(script, "evaluate", lambda policy, **kw: calls.append(kw) or {
        "episodes_ended": 3, "falls": 1, "mean_path_error_m": 0.25,
        "reward_per_step": {"track": 0.8, "energy": -0.1, "direction": 0.0, "stance": 0.0}})
    policy = str(ROOT / "policies" / "amp_pedestrian")
    out = tmp_path / "rows.jsonl"
    assert script.main([policy, "--out", str(out)]) == 0
    assert script.main([policy, "--out", str(out), "--protocol", "path3"]) == 0  # not skipped: another protocol
    assert script.main([policy, "--out", str(out), "--protocol", "path3"]) == 0  # skipped
    rows = [json.loads(line) for line in out.read_text().splitlines()]
    assert [r["protocol"] for r in rows] == ["tracking", "path3"] and rows[1]["falls"] == 1
    assert rows[1]["reward_per_step"]["track"] == 0.8
    assert calls == [{"envs": 32, "seconds": 60.0, "stage": 3, "seed": 0}]


def test_full_clip_tracking_does_not_stop_at_failures_and_has_its_own_rows(script, tmp_path, monkeypatch):
    seen = []
    monkeypatch.setattr(script, "track_clips", lambda policy, **kw: seen.append(kw) or {
        "clip_success_rate": 0.5, "mean_pos_error_m": 0.2, "max_pos_error_m": 0.3, "mean_rot_error_rad": 0.4})
    policy = str(ROOT / "policies" / "amp_pedestrian")
    out = tmp_path / "rows.jsonl"
    assert script.main([policy, "--out", str(out)]) == 0
    assert script.main([policy, "--out", str(out), "--protocol", "tracking_full"]) == 0  # not skipped
    rows = [json.loads(line) for line in out.read_text().splitlines()]
    assert [r["protocol"] for r in rows] == ["tracking", "tracking_full"]
    assert seen == [{"stop_on_failure": True}, {"stop_on_failure": False}]


def test_a_training_folder_is_exported_from_its_parts(script, tmp_path):
    """The committed run folder (state.pt.part-*, meta.json) becomes an exported policy of its iteration."""
    run = ROOT / "training" / "amp_scratch"
    if not (run / "meta.json").exists():
        pytest.skip("no committed scratch run")
    policy = script.materialise(str(run), tmp_path)
    config = json.loads((policy / "config.json").read_text())
    meta = json.loads((run / "meta.json").read_text())
    assert config["trained_iterations"] == meta["iteration"] and (policy / "policy.pt").exists()


def test_bad_sources_are_named(script, tmp_path):
    with pytest.raises(SystemExit, match="neither an exported policy"):
        script.materialise(str(tmp_path), tmp_path / "w")
    with pytest.raises(SystemExit, match="git:REV:FOLDER"):
        script.materialise("git:only-one-part", tmp_path / "w")


def test_a_folder_with_a_newer_checkpoint_is_tracked_again(script, tmp_path, monkeypatch):
    """A training folder's row is per checkpoint: after another run the same folder is a new source."""
    monkeypatch.setattr(script, "track_clips", lambda policy, **kw: {"clip_success_rate": 0.5, "mean_pos_error_m": 0.2,
                                                               "max_pos_error_m": 0.3, "mean_rot_error_rad": 0.4})
    policy = str(ROOT / "policies" / "amp_pedestrian")
    out = tmp_path / "rows.jsonl"
    config = json.loads((Path(policy) / "config.json").read_text())
    older = {"source": policy, "protocol": "tracking", "trained_iterations": config["trained_iterations"] - 1}
    out.write_text(json.dumps(older) + "\n")
    assert script.main([policy, "--out", str(out)]) == 0  # the row there is of another checkpoint
    assert script.main([policy, "--out", str(out)]) == 0  # now done
    rows = [json.loads(line) for line in out.read_text().splitlines()]
    assert [r["trained_iterations"] for r in rows] == [older["trained_iterations"], config["trained_iterations"]]


def test_the_stance_protocol_measures_the_feet_offset_from_the_clips(script, tmp_path, monkeypatch):
    """Poses that are the clips' own with the right foot moved 0.3 forward and the left 0.2 back (spine lengths) read
    as a split of 0.5; the clips themselves are the zero, and their MMD to themselves is at the floor."""
    from navzoo.agents.amp.tracking import load_motions
    from navzoo.benchmark import realism

    lib = load_motions(None)
    ref = realism.clip_poses(lib, fps=realism.DEFAULT_FPS)
    speeds = realism.clip_root_speeds(lib, realism.DEFAULT_FPS)
    names = list(realism.KEYPOINT_NAMES)
    for shift, expect in (((0.3, -0.2), (0.3, -0.2, 0.5)), ((0.0, 0.0), (0.0, 0.0, 0.0))):
        poses = ref.copy().reshape(len(ref), realism.N_KEYPOINTS, 3)
        poses[:, names.index("right_foot"), 0] += shift[0]
        poses[:, names.index("left_foot"), 0] += shift[1]
        flat = poses.reshape(len(ref), -1)

        def fake(policy, motions, stop_on_failure, pose_sink, _p=flat):
            assert stop_on_failure is False
            pose_sink.append((_p, speeds))
            return {"clip_success_rate": 0.5, "mean_pos_error_m": 0.2, "mean_rot_error_rad": 0.4, "fall_rate": 0.1}

        monkeypatch.setattr(script, "track_clips", fake)
        row = script.stance(tmp_path)
        assert (row["right_foot_fwd"], row["left_foot_fwd"], row["foot_split"]) == pytest.approx(expect, abs=1e-9)
        assert row["walking_poses"] == int((speeds >= 0.9).sum()) and row["fall_rate"] == 0.1
        if shift == (0.0, 0.0):
            assert row["tracking_mmd"] < 0.05
        else:
            assert row["tracking_mmd"] > 0.05


def test_export_dir_keeps_each_sources_policy_under_a_stable_name(script, tmp_path):
    """--export-dir writes the exported policy of every source under DIR/policy_<source>, runs no protocol, and refuses
    to overwrite; an exported policy folder is copied as it is."""
    shipped = ROOT / "policies" / "amp_pedestrian"
    assert script.export_name("git:3ea0b4b:training/amp") == "policy_git_3ea0b4b_training_amp"
    assert script.main(["--export-dir", str(tmp_path / "x"), str(shipped)]) == 0
    dest = tmp_path / "x" / script.export_name(str(shipped))
    assert (dest / "policy.pt").read_bytes() == (shipped / "policy.pt").read_bytes()
    assert sorted(p.name for p in (tmp_path / "x").iterdir()) == [dest.name]  # the work folder is gone
    with pytest.raises(SystemExit, match="exists"):
        script.main(["--export-dir", str(tmp_path / "x"), str(shipped)])
    with pytest.raises(SystemExit):  # neither --out nor --export-dir
        script.main([str(shipped)])
