"""scripts/amp_protocol_noise.py: the protocol's spread between a reference policy and its untrained copies."""

import json
import math

import pytest

from tests.script_modules import load_script

pn = load_script("amp_protocol_noise")


def _row(config, scene, seed, success, timeout, fall=0):
    return {"config": config, "scene": scene, "seed": seed, "success": success, "off_path": 0, "fall": fall,
            "timeout": timeout, "map_trips": 0, "agent_trips": 0, "err_sum": 1.0, "err_n": 10, "by_goal": {}}


def test_seed_rates_pool_trips_and_keep_only_complete_seeds():
    rows = [_row("ref", "a", 0, 9, 1), _row("ref", "b", 0, 1, 9),   # 10 / 20
            _row("c1", "a", 0, 6, 4), _row("c1", "b", 0, 6, 14),    # 12 / 30
            _row("ref", "a", 1, 5, 5), _row("ref", "b", 1, 5, 5),
            _row("c1", "a", 1, 5, 5)]                                # seed 1: c1 lacks scene b
    rates = pn.seed_rates(rows, ["ref", "c1"], ("a", "b"))
    assert rates == {"ref": {0: 0.5}, "c1": {0: 0.4}}
    with pytest.raises(ValueError, match="no rows of configuration 'c2'"):
        pn.seed_rates(rows, ["ref", "c2"], ("a", "b"))
    with pytest.raises(ValueError, match=r"no seed on which ref, c1 all ran the 2 scenes \(seeds with rows: \[1\]\)"):
        pn.seed_rates(rows, ["ref", "c1"], ("a", "b"), seeds=[1])


def test_other_metrics_and_per_goal_counts():
    rows = [_row("ref", "a", 0, 9, 1, fall=2), _row("c1", "a", 0, 6, 4)]
    rows[0]["by_goal"] = {"success": 8, "off_path": 0, "fall": 2, "timeout": 0, "map_trips": 1, "agent_trips": 0}
    rows[1]["by_goal"] = {"success": 6, "off_path": 0, "fall": 0, "timeout": 2, "map_trips": 0, "agent_trips": 0}
    assert pn.seed_rates(rows, ["ref", "c1"], ("a",), metric="fall_rate") == {"ref": {0: 2 / 12}, "c1": {0: 0.0}}
    assert pn.seed_rates(rows, ["ref", "c1"], ("a",), metric="per_goal_success_rate") == {"ref": {0: 0.8},
                                                                                         "c1": {0: 0.75}}
    assert pn.seed_rates(rows, ["ref", "c1"], ("a",), metric="per_goal_map_collision_rate")["ref"] == {0: 0.1}
    with pytest.raises(ValueError, match="unknown metric 'falls'"):
        pn.seed_rates(rows, ["ref", "c1"], ("a",), metric="falls")
    rows[1]["by_goal"] = {}
    with pytest.raises(ValueError, match="rows of 'c1' on seed 0 have no per-goal counts"):
        pn.seed_rates(rows, ["ref", "c1"], ("a",), metric="per_goal_success_rate")


def test_seeds_needed_for_chosen_differences():
    rates = {"ref": {0: 0.010, 1: 0.020, 2: 0.012}, "c1": {0: 0.014, 1: 0.012, 2: 0.016}}
    res = pn.noise(rates, "ref", ["c1"], differences=(0.5, 1))
    assert set(res["seeds_needed"]) == {"0.5", "1"}
    assert res["seeds_needed"]["0.5"] >= res["seeds_needed"]["1"] >= 2


def test_noise_separates_seed_effect_from_the_residual():
    # policy x seed grid: seed effects (0, +10, -10 points), the reference 2 points above its copies, and a residual
    # of +-1 point that alternates
    base = {0: 0.60, 1: 0.70, 2: 0.50}
    rates = {"ref": {s: b + 0.02 for s, b in base.items()},
             "c1": {s: b + (0.01 if s % 2 == 0 else -0.01) for s, b in base.items()},
             "c2": {s: b - (0.01 if s % 2 == 0 else -0.01) for s, b in base.items()}}
    res = pn.noise(rates, "ref", ["c1", "c2"])
    assert res["seeds"] == [0, 1, 2]
    assert res["diff_by_seed"] == [2.0, 2.0, 2.0]
    assert res["diff_mean"] == pytest.approx(2.0) and res["diff_se"] == pytest.approx(0.0, abs=1e-9)
    assert res["seed_sd"] == pytest.approx(10.0, rel=1e-6)
    # residuals (policy and seed means taken out): ref 0; c1 +2/3, -4/3, +2/3; c2 the opposite: sum of squares 16/3
    # over (3-1)(3-1) = 4 degrees of freedom
    assert res["residual_sd"] == pytest.approx(math.sqrt(4 / 3), rel=1e-6)
    n = res["seeds_needed"]
    assert n["2"] >= n["3"] >= n["5"] >= n["8"] >= 1


def test_equal_policies_have_no_difference_and_one_seed_no_spread():
    rates = {"ref": {0: 0.6, 1: 0.7}, "c1": {0: 0.6, 1: 0.7}}
    res = pn.noise(rates, "ref", ["c1"])
    assert res["diff_mean"] == 0 and res["residual_sd"] == 0 and res["seeds_needed"]["2"] == 2  # two at least
    one = pn.noise({"ref": {3: 0.6}, "c1": {3: 0.5}}, "ref", ["c1"])
    assert one["diff_by_seed"] == [10.0] and math.isnan(one["residual_sd"]) and one["seeds_needed"] == {}


def test_cli_prints_the_table_and_refuses_bad_input(tmp_path, capsys):
    scenes = ("station", "home", "grocery", "circle_crossing", "square_crossing", "corridor", "doorway", "lobby")
    rows = [_row(c, sc, s, 5 + (c == "ref") + s, 5) for c in ("ref", "c1", "c2") for sc in scenes for s in (0, 1)]
    f = tmp_path / "r.jsonl"
    f.write_text("".join(json.dumps(r) + "\n" for r in rows))
    assert pn.main(["--files", str(tmp_path / "*.jsonl"), "--reference", "ref", "--controls", "c1,c2"]) == 0
    out = capsys.readouterr().out
    assert "| 0 | 0.545 | 0.500 | 0.500 | 0.500 |" in out and "over 2 seeds" in out
    assert pn.main(["--files", str(f), "--reference", "ref", "--controls", "c1,c2", "--json"]) == 0
    res = json.loads(capsys.readouterr().out)
    assert res["seeds"] == [0, 1] and res["diff_mean"] > 0
    for argv, msg in ((["--files", str(tmp_path / "none*.jsonl"), "--reference", "ref", "--controls", "c1"],
                       "no result files match"),
                      (["--files", str(f), "--reference", "ref", "--controls", "ref"], "other than the reference"),
                      (["--files", str(f), "--reference", "ref", "--controls", "c9"], "no rows of configuration 'c9'"),
                      (["--files", str(f), "--reference", "ref", "--controls", "c1", "--scenes", "nowhere"],
                       "nowhere"),
                      (["--files", str(f), "--reference", "ref", "--controls", "c1", "--differences", "0,1"],
                       "--differences must be positive"),
                      (["--files", str(f), "--reference", "ref", "--controls", "c1", "--metric", "falls"],
                       "invalid choice")):
        with pytest.raises(SystemExit):
            pn.main(argv)
        assert msg in capsys.readouterr().err
