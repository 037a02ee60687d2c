"""scripts/amp_fall_times.py: falls and the median fall time of tracking rows."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from tests.script_modules import load_script

ROOT = Path(__file__).resolve().parents[1]
aft = load_script("amp_fall_times")


def _row(source, protocol, falls):
    clips = [{"fell": t is not None, "fall_time_s": t} for t in falls]  # as tracking writes them: None unless fell
    return {"source": source, "protocol": protocol, "per_clip": clips}


def test_counts_falls_and_takes_the_median_of_fallen_clips_only(tmp_path, capsys):
    assert aft.fall_times(_row("a", "tracking_full", [1.0, None, 2.0, 4.0])) == {
        "source": "a", "falls": 3, "clips": 4, "median_fall_s": 2.0, "quartiles_fall_s": [1.5, 3.0]}
    none = aft.fall_times(_row("b", "tracking_full", [None, None]))
    assert none["falls"] == 0 and none["median_fall_s"] is None
    with pytest.raises(ValueError, match="no per-clip results"):
        aft.fall_times({"source": "c", "per_clip": []})
    f = tmp_path / "rows.jsonl"
    f.write_text("\n".join(json.dumps(r) for r in (_row("a", "tracking_full", [1.0]), _row("b", "tracking", [2.0]))))
    assert aft.main([str(f)]) == 0
    out = [json.loads(x) for x in capsys.readouterr().out.splitlines()]
    assert [o["source"] for o in out] == ["a"]  # only the chosen protocol's rows
