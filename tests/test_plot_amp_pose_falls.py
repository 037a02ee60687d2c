"""scripts/plot_amp_pose_falls.py: pose error against falls over whole clips, per tracked policy."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from tests.script_modules import load_script

ROOT = Path(__file__).resolve().parents[1]
ppf = load_script("plot_amp_pose_falls")


def _row(source, protocol, it, pose=0.4, falls=0.1, clips=0.5):
    return {"source": source, "protocol": protocol, "trained_iterations": it, "trained_steps": it * 3840,
            "mean_pose_rot_error_rad": pose, "fall_rate": falls, "mean_rot_error_rad": pose + 0.1,
            "clip_success_rate": clips}


def test_pairs_whole_clip_rows_with_the_same_checkpoints_paper_row():
    rows = [_row("a", "tracking", 10, clips=0.7), _row("a", "tracking_full", 10, pose=0.3, falls=0.2),
            _row("a", "tracking_full", 20, pose=0.5, falls=0.0),  # a later checkpoint of the same folder
            _row("b", "tracking", 5), _row("c", "path3", 5)]
    points = ppf.pose_and_falls(rows)
    assert [(p["source"], p["pose_rad"], p["falls"], p["clips_tracked"]) for p in points] == [
        ("a", 0.3, 0.2, 0.7), ("a", 0.5, 0.0, None)]  # b has no whole-clip row; a's second has no paper row
    assert points[0]["samples_m"] == round(10 * 3840 / 1e6, 2)
    assert ppf.pose_and_falls(rows, only=["b"]) == []
    with pytest.raises(ValueError, match="lacks"):
        ppf.pose_and_falls([{"source": "d", "protocol": "tracking_full", "fall_rate": 0.1}])


def test_short_names():
    assert ppf.short_name("training/amp_bc/policies/policy_00005617") == "5617"
    assert ppf.short_name("training/amp_bc/policies/ab3_all_00004781") == "ab3_all_00004781"
    assert ppf.short_name("policies/amp_pedestrian") == "amp_pedestrian"


def test_command_draws_and_rejects_bad_labels_and_empty_selections(tmp_path, capsys):
    f = tmp_path / "rows.jsonl"
    f.write_text("\n".join(json.dumps(r) for r in (_row("x/policy_00000007", "tracking_full", 7),
                                                    _row("y", "tracking_full", 3))))
    png = tmp_path / "p.png"
    assert ppf.main([str(f), "--label", "y=shipped", "--out", str(png)]) == 0
    assert png.stat().st_size > 1000
    assert len(capsys.readouterr().out.splitlines()) == 2
    with pytest.raises(SystemExit):
        ppf.main([str(f), "--label", "noequals"])
    with pytest.raises(SystemExit):
        ppf.main([str(f), "--only", "zzz"])
    assert "no whole-clip" in capsys.readouterr().err
