"""scripts/ablation_scene_weighted.py: scenes compared on the seeds both settings ran, pooled with fixed weights."""

from __future__ import annotations

import json

import pytest

from tests.script_modules import load_script

sw = load_script("ablation_scene_weighted")


def _row(scene, seed, success, timeout, goal_success=None):
    g = success if goal_success is None else goal_success
    counts = {"off_path": 0, "fall": 0, "timeout": timeout, "map_trips": 0, "agent_trips": 0}
    return {"scene": scene, "seed": seed, "success": success, **counts, "by_goal": {"success": g, **counts}}


def _write(path, rows):
    path.write_text("".join(json.dumps(r) + "\n" for r in rows))
    return str(path)


def test_scenes_on_more_seeds_do_not_weigh_more_and_pairs_are_by_seed(tmp_path, capsys):
    # "wide": 10 trips per run, seeds 0-1 only; "deep": 10 trips per run, seeds 0-3 (B also ran seed 9, A did not)
    a = [_row("wide", 0, 8, 2), _row("wide", 1, 8, 2)] + [_row("deep", k, 5, 5) for k in range(4)]
    b = [_row("wide", 0, 9, 1), _row("wide", 1, 7, 3)] + [_row("deep", k, 7, 3) for k in range(4)]
    b.append(_row("deep", 9, 0, 10))  # not paired: left out
    res = sw.compare(sw.load([_write(tmp_path / "a.jsonl", a)]), sw.load([_write(tmp_path / "b.jsonl", b)]), [0, 1])
    assert res["scenes"]["deep"]["seeds"] == [0, 1, 2, 3]
    assert res["scenes"]["deep"]["per_limit"] == {"a": 0.5, "b": 0.7}
    assert res["scenes"]["wide"]["weight"]["per_limit"] == pytest.approx(0.5)  # 20 trips each on seeds 0-1
    assert res["per_limit"]["a"] == pytest.approx(0.5 * 0.8 + 0.5 * 0.5)
    assert res["per_limit"]["b"] == pytest.approx(0.5 * 0.8 + 0.5 * 0.7)
    p = res["scenes"]["wide"]["paired_success_diff"]
    assert (p["mean"], p["b_ahead"], p["a_ahead"]) == (0.0, 1, 1)
    sw.main(["--a", str(tmp_path / "a.jsonl"), "--b", str(tmp_path / "b.jsonl"), "--weight-seeds", "0,1"])
    assert "| weighted pool | | | 0.650 | 0.750 |" in capsys.readouterr().out


def test_a_run_in_two_files_and_no_files_are_refused(tmp_path):
    f1 = _write(tmp_path / "x.jsonl", [_row("s", 0, 1, 1)])
    f2 = _write(tmp_path / "y.jsonl", [_row("s", 0, 1, 1)])
    with pytest.raises(SystemExit, match="more than one file"):
        sw.load([f1, f2])
    with pytest.raises(SystemExit, match="no result files"):
        sw.load([str(tmp_path / "none*.jsonl")])


def test_by_seed_pools_each_seeds_scenes_and_pairs_the_settings(tmp_path, capsys):
    a = [_row(s, k, 5, 5) for s in ("x", "y") for k in range(3)]
    b = [_row("x", k, 5 + k, 5 - k) for k in range(3)] + [_row("y", k, 5, 5) for k in range(3)]
    b.append(_row("x", 7, 9, 1))  # a seed A did not run: left out
    res = sw.by_seed(sw.load([_write(tmp_path / "a.jsonl", a)]), sw.load([_write(tmp_path / "b.jsonl", b)]))
    assert res["seeds"] == [0, 1, 2]
    assert res["b"] == pytest.approx([0.5, 0.55, 0.6])  # 20 trips per seed, seed k adds k successes
    assert res["diff_points"] == [0.0, 5.0, 10.0]
    assert res["diff_mean_points"] == pytest.approx(5.0) and res["diff_se_points"] == pytest.approx(5.0 / 3 ** 0.5)
    assert res["a_sd_points"] == 0.0
    # the scene comparison gives each scene's successes seed by seed
    scenes = sw.compare(sw.load([str(tmp_path / "a.jsonl")]), sw.load([str(tmp_path / "b.jsonl")]), [0])["scenes"]
    assert scenes["x"]["success_by_seed"] == {"a": {0: 5, 1: 5, 2: 5}, "b": {0: 5, 1: 6, 2: 7}}
    sw.main(["--by-seed", "--a", str(tmp_path / "a.jsonl"), "--b", str(tmp_path / "b.jsonl")])
    assert "B - A: +5.00 ± 2.89 points" in capsys.readouterr().out


def test_scenes_keeps_only_the_named_scenes(tmp_path, capsys):
    """``--scenes protocol|heldout|S,S``: the comparison of one scene set only; a filter that keeps nothing is refused."""
    a = [_row(s, k, 5, 5) for s in ("lobby", "bottleneck") for k in range(2)]
    b = [_row("lobby", k, 5, 5) for k in range(2)] + [_row("bottleneck", k, 9, 1) for k in range(2)]
    fa, fb = _write(tmp_path / "a.jsonl", a), _write(tmp_path / "b.jsonl", b)
    sw.main(["--by-seed", "--scenes", "protocol", "--a", fa, "--b", fb])
    assert "B - A: +0.00" in capsys.readouterr().out  # the lobby only
    sw.main(["--by-seed", "--scenes", "heldout", "--a", fa, "--b", fb])
    assert "B - A: +40.00" in capsys.readouterr().out  # the bottleneck only
    with pytest.raises(SystemExit, match="no rows of scenes"):
        sw.load([fa], ("station",))
    with pytest.raises(SystemExit):
        sw.main(["--scenes", "atlantis", "--a", fa, "--b", fb])
    assert "atlantis" in capsys.readouterr().err


def test_pairs_run_on_different_cpus_are_named_and_left_out_with_same_cpu(tmp_path, capsys):
    """Another kind of CPU walks other trips: such pairs are named on stderr, and ``--same-cpu`` drops them."""
    a = [{**_row("x", k, 5, 5), "cpu": "Intel"} for k in range(3)] + [_row("x", 3, 5, 5)]
    b = [{**_row("x", 0, 9, 1), "cpu": "AMD"}] + [{**_row("x", k, 5, 5), "cpu": "Intel"} for k in (1, 2)]
    b.append(_row("x", 3, 6, 4))  # no CPU recorded: kept
    fa, fb = _write(tmp_path / "a.jsonl", a), _write(tmp_path / "b.jsonl", b)
    ra, rb = sw.load([fa]), sw.load([fb])
    assert sw.cpu_mismatches(ra, rb) == [("x", 0, "Intel", "AMD")]
    sw.main(["--by-seed", "--a", fa, "--b", fb])
    out = capsys.readouterr()
    assert "1 of 4 paired runs ran on different CPUs (A on Intel, B on AMD; seeds 0)" in out.err
    assert "B - A: +12.50" in out.out  # seed 0 (+40 points) and seed 3 (+10) in
    sw.main(["--by-seed", "--same-cpu", "--a", fa, "--b", fb])
    out = capsys.readouterr()
    assert "left out (--same-cpu)" in out.err and "B - A: +3.33" in out.out  # seeds 1-3 only
    sw.main(["--by-seed", "--a", fa, "--b", fa])
    assert capsys.readouterr().err == ""
