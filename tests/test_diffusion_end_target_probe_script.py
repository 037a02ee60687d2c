"""scripts/diffusion_end_target_probe.py: counts the end targets the old clip would have pulled off the path."""

from __future__ import annotations

import importlib.util
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="module")
def script():
    spec = importlib.util.spec_from_file_location("diffusion_end_target_probe",
                                                  ROOT / "scripts" / "diffusion_end_target_probe.py")
    mod = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = mod
    spec.loader.exec_module(mod)
    return mod


def test_the_probe_counts_plans_and_leaves_the_crowd_as_it_was(script):
    import navzoo.agents.diffusion.crowd as dc

    before = dc._end_targets
    row = script.probe("home", 3, 2.5)
    assert dc._end_targets is before  # the spy is removed again
    assert row["targets"] >= 3  # everyone is planned at the start
    assert 0 <= row["moved"] <= row["on_path"] <= row["targets"]
    assert (row["median_move_m"] is None) == (row["moved"] == 0)


def test_bad_scenes_are_named(script):
    with pytest.raises(SystemExit):
        script.main(["--scenes", "home"])
