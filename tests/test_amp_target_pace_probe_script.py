"""scripts/amp_target_pace_probe.py: body speed against target speed, per scene."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from tests.script_modules import load_script

ROOT = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="module")
def script():
    return load_script("amp_target_pace_probe")


def test_summary_splits_walking_and_standing_targets(script):
    v_tgt = np.array([1.2, 1.2, 0.1, 0.1])
    v_body = np.array([0.6, 1.2, 0.0, 0.2])
    out = script.summary(v_body, v_tgt)
    assert out["samples"] == 4
    assert out["target_share_walking"] == pytest.approx(0.5) and out["target_share_under_0.3"] == pytest.approx(0.5)
    assert out["body_over_target_walking"] == pytest.approx(0.75)  # (0.6 + 1.2) / (1.2 + 1.2)
    assert out["body_median_target_standing"] == pytest.approx(0.1)
    assert out["body_share_under_0.3"] == pytest.approx(0.5)
    # kinematic rule-based crowds have no target: body figures only
    assert "target_median" not in script.summary(v_body, np.full(4, np.nan))


def test_probe_measures_a_short_kinematic_run_and_restores_the_crowd(script):
    import navzoo.agents.diffusion.crowd as dc

    init = dc.DiffusionCrowd.__init__
    row = script.probe("station", 2, 3.0, 0, None, "sfm", "kinematic", path_in_sight=False)
    assert dc.DiffusionCrowd.__init__ is init
    assert row["v_body"].size > 0 and np.isfinite(row["v_body"]).all() and (row["v_body"] >= 0).all()
    assert np.isnan(row["v_target"]).all()  # social force walks kinematic bodies without a target trajectory
    assert len(row["pref_speed"]) == 2
