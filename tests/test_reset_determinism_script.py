"""scripts/amp_reset_determinism.py: with sorted overlapping pairs a reused physics world repeats a fresh one."""

from __future__ import annotations

import importlib.util
from pathlib import Path

_SPEC = importlib.util.spec_from_file_location(
    "amp_reset_determinism", Path(__file__).resolve().parents[1] / "scripts" / "amp_reset_determinism.py")
rd = importlib.util.module_from_spec(_SPEC)
_SPEC.loader.exec_module(rd)


def test_sorted_pairs_make_a_reused_world_repeat_a_fresh_one():
    out = rd.measure("station", 4, 30)
    assert set(out) == {"reused_vs_fresh_m", "reused_vs_fresh_m_sorted_pairs", "fresh_sorted_vs_unsorted_m"}
    assert out["reused_vs_fresh_m_sorted_pairs"] == 0.0
    assert all(v >= 0.0 for v in out.values())
