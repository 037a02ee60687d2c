"""scripts/amp_reset_determinism.py: a reused physics world repeats a fresh one; restoreState alone does so only with
sorted overlapping pairs."""

from __future__ import annotations

from tests.script_modules import load_script

rd = load_script("amp_reset_determinism")


def test_a_reset_world_repeats_a_fresh_one():
    out = rd.measure("station", 4, 30, timing=False)
    assert set(out) == {"reused_vs_fresh_m", "restored_only_vs_fresh_m", "restored_only_sorted_pairs_vs_fresh_m",
                        "fresh_sorted_vs_unsorted_m"}
    assert out["reused_vs_fresh_m"] == 0.0
    assert out["restored_only_sorted_pairs_vs_fresh_m"] == 0.0
    assert all(v >= 0.0 for v in out.values())


def test_a_reused_kinematic_world_repeats_a_fresh_one_without_a_rebuild():
    out = rd.measure_kinematic("station", 3, 20)
    assert out == {"kinematic_sfm_reused_vs_fresh_m": 0.0, "kinematic_diffusion_reused_vs_fresh_m": 0.0}
