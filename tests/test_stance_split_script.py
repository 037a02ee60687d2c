"""scripts/amp_stance_split.py: the feet's fore-aft split of AMP pedestrians in a scene and of the clips."""

from __future__ import annotations

import json

import numpy as np
import pytest

from tests.script_modules import load_script

split = load_script("amp_stance_split")


def test_the_clips_alternate_their_feet_and_stay_mostly_inside_the_free_band():
    from navzoo.agents import motion_lib

    row = split.summarise(split.clip_split(motion_lib.load()))
    assert abs(row["mean_split_m"]) < 1e-6  # every clip has its mirror image in the library
    assert 0.03 < row["mean_abs_running_mean_m"] < split.STANCE_FREE_M
    assert row["share_outside_free_band"] < 0.3


def test_the_shipped_policy_keeps_its_right_foot_ahead_and_bad_arguments_are_named(tmp_path):
    from navzoo.agents.amp.pedestrian_policy import default_policy_dir

    out = tmp_path / "s.json"
    assert split.main(["--source", f"shipped={default_policy_dir()}", "--scenes", "square_crossing:3",
                       "--seconds", "6", "--no-clips", "--out", str(out)]) == 0
    row = json.loads(out.read_text())["sources"]["shipped"]["all"]
    assert row["n"] > 20 and row["mean_split_m"] > 0.15 and row["mean_abs_running_mean_m"] > 0.15
    assert row["share_outside_free_band"] > 0.5
    with pytest.raises(SystemExit):
        split.main(["--source", "nodir=/no/such/policy"])
    with pytest.raises(SystemExit):
        split.main(["--source", f"x={default_policy_dir()}", "--scenes", "lobby"])
    assert np.isfinite(row["mean_split_m"])
