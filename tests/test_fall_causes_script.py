from __future__ import annotations

import json

import pytest

from tests.script_modules import load_script

fc = load_script("fall_causes")


def _event(t, agent=None, wall=None, fallen=None, fallen_m=None):
    return {"t": t, "id": 0, "x": 0.0, "y": 0.0, "since_agent_s": agent, "since_map_s": wall, "since_fallen_s": fallen,
            "fallen_m": fallen_m, "person_m": 1.0}


def _row(seed, scene, success, events, config="kdt"):
    return {"config": config, "crowd": "diffusion", "scene": scene, "pedestrians": 8, "seed": seed,
            "success": success, "fall": len(events), "fall_events": events}


def test_cascades_and_causes(tmp_path, capsys):
    rows = [
        _row(0, "lobby", 100, []),
        _row(1, "lobby", 90, []),
        _row(2, "lobby", 20, [_event(5, agent=0.2), _event(9, fallen=0.1, fallen_m=0.05, agent=0.9),
                              _event(12, fallen=0.3, fallen_m=0.2), _event(30, wall=0.5, fallen_m=4.0)]),
        _row(3, "corridor", 60, [_event(40)]),
    ]
    f = tmp_path / "runs.jsonl"
    # a settings line, a row from before fall events were logged, and the same run twice: read once each
    old = {k: v for k, v in rows[0].items() if k != "fall_events"} | {"seed": 9}
    f.write_text("\n".join(json.dumps(r) for r in [{"settings": {}}, old, *rows, rows[2]]) + "\n")
    read, skipped = fc.read([str(f)])
    assert len(read) == 4 and skipped == 1
    s = fc.summarize(read, within=1.5, near=0.5)
    assert s["falls"] == 5 and s["falls_per_run"] == [4, 1, 0, 0]
    assert s["in_runs_with_3plus"] == pytest.approx(0.8)
    assert s["causes"] == {"fallen body": 2, "person": 1, "wall": 1, "none": 1}
    assert s["near_fallen"] == 2
    # tipped by a lying body 4 s and 3 s after the fall before them: the second counts as knocked over
    assert s["fallen_body_after_s"] == 3.5 and s["fallen_body_within_3s"] == 1
    assert s["slid_m_median"] is None  # these events predate slid_m
    assert s["success_per_run_no_falls"] == 95.0 and s["success_per_run_3plus_falls"] == 20.0
    # --counts: the older row too, by its fall count
    read_all, skipped = fc.read([str(f)], counts=True)
    assert len(read_all) == 5 and skipped == 0
    assert fc.summarize(read_all, within=1.5, near=0.5)["falls"] == 5
    assert fc.main([str(f), "--by-scene", "--json"]) == 0
    lines = [json.loads(x) for x in capsys.readouterr().out.splitlines()]
    assert [(x["scene"], x["falls"]) for x in lines] == [("corridor", 1), ("lobby", 4)]
    assert fc.main([str(f), "--scenes", "corridor", "--json"]) == 0
    (only,) = [json.loads(x) for x in capsys.readouterr().out.splitlines()]
    assert only["runs"] == 1 and only["falls"] == 1


def test_untouched_falls_by_speed(tmp_path, capsys):
    def ev(t, speed, target, wall=None):
        return _event(t, wall=wall) | {"speed_mps": speed, "turn_rad_s": 0.2, "target_speed_mps": target, "lag_m": 0.3}

    rows = [_row(0, "lobby", 10, [ev(5, 0.1, 0.05), ev(9, 0.2, 0.9), ev(12, 1.1, 1.0), ev(20, 0.1, 0.1, wall=0.2)])
            | {"slow_s": 120.0, "moving_s": 600.0},
            _row(1, "lobby", 12, [_event(3)]) | {"slow_s": 60.0, "moving_s": 60.0}]  # an event without motion keys
    s = fc.summarize(rows, within=1.5, near=0.5)
    m = s["untouched_motion"]  # the wall-tipped fall and the one without motion keys are left out
    assert m["falls"] == 3 and m["speed_median"] == 0.2 and m["slow_share"] == pytest.approx(0.67)
    assert m["slow_target_share"] == pytest.approx(0.33) and m["turn_median"] == 0.2 and m["lag_median"] == 0.3
    # 2 slow untouched falls in 3 slow person-minutes, 1 in 11 moving ones
    assert s["untouched_per_minute"] == {"slow": pytest.approx(0.667), "moving": pytest.approx(0.091),
                                         "slow_min": 3.0, "moving_min": 11.0}
    assert fc.summarize([_row(2, "home", 1, [_event(4)])], 1.5, 0.5)["untouched_motion"] is None  # older rows
    f = tmp_path / "runs.jsonl"
    f.write_text("\n".join(json.dumps(r) for r in rows) + "\n")
    assert fc.main([str(f)]) == 0
    assert "0.2, 67 % (33 %), 0.2, 0.3 (3 falls) | 0.667 / 0.091 (3.0 / 11.0)" in capsys.readouterr().out


def test_bad_input_is_named(tmp_path, capsys):
    f = tmp_path / "bad.jsonl"
    f.write_text("{not json\n")
    with pytest.raises(SystemExit):
        fc.main([str(f)])
    assert "bad.jsonl:1" in capsys.readouterr().err
    g = tmp_path / "old.jsonl"
    g.write_text(json.dumps({"scene": "lobby", "fall": 0, "success": 3}) + "\n")
    with pytest.raises(SystemExit):
        fc.main([str(g)])
    assert "no rows with fall_events" in capsys.readouterr().err


def test_paired_cpus(tmp_path, capsys):
    def on(cpu, seed, scene, n, config="kdt"):
        return _row(seed, scene, 50, [_event(10 + k) for k in range(n)], config) | {"cpu": f"{cpu} Model (x)"}

    # the same runs on both kinds of CPU (read apart, not taken for one run twice), one run only on Intel, and a
    # configuration run on one kind only (no pair)
    rows = [on("Intel", 0, "lobby", 3), on("AMD", 0, "lobby", 0), on("Intel", 1, "lobby", 2), on("AMD", 1, "lobby", 0),
            on("Intel", 2, "corridor", 1), on("AMD", 2, "corridor", 1), on("Intel", 3, "corridor", 5),
            on("Intel", 0, "lobby", 1, config="kdtx")]
    f = tmp_path / "runs.jsonl"
    f.write_text("\n".join(json.dumps(r) for r in rows) + "\n")
    read, _ = fc.read([str(f)])
    assert len(read) == 8
    (x,) = fc.paired_cpus(read, draws=20_000)
    assert x["config"] == "kdt" and x["cpus"] == ["AMD", "Intel"] and x["runs"] == 3
    assert x["falls"] == [1, 6] and x["runs_more_falls"] == [0, 2]
    # three paired runs, differences (-3, -2, 0): |sum| >= 5 for 2 of the 4 sign patterns of the nonzero pair
    assert x["p_sign_flip"] == pytest.approx(0.5, abs=0.02)
    same = [r | {"fall_events": [], "fall": 0} for r in read if r["config"] == "kdt"]
    assert fc.paired_cpus(same)[0]["p_sign_flip"] == 1.0
    assert fc.main([str(f), "--paired-cpus", "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["falls"] == [1, 6]
    g = tmp_path / "one_cpu.jsonl"
    g.write_text(json.dumps(rows[0]) + "\n")
    with pytest.raises(SystemExit):
        fc.main([str(g), "--paired-cpus"])
    assert "two kinds of CPU" in capsys.readouterr().err
