"""scripts/plot_success_contacts.py: success against wall contacts per setting, pooled per seed."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from tests.script_modules import load_script

plot = load_script("plot_success_contacts")


def _row(scene: str, seed: int, success: int, timeout: int, map_trips: int) -> dict:
    return {"scene": scene, "seed": seed, "success": success, "off_path": 0, "fall": 0, "timeout": timeout,
            "map_trips": map_trips, "agent_trips": 0}


def _write(path: Path, rows: list[dict]) -> str:
    path.write_text("".join(json.dumps(r) + "\n" for r in rows))
    return str(path)


def test_each_setting_is_the_mean_over_seeds_of_its_pooled_scene_runs(tmp_path, capsys):
    # seed 0: 8 of 10 trips succeed, 1 touches a wall; seed 1: 6 of 10, 3 touch one -> 70 ± 10 %, 20 ± 10 %
    a = _write(tmp_path / "a.jsonl", [_row("home", 0, 3, 2, 1), _row("lobby", 0, 5, 0, 0),
                                      _row("home", 1, 1, 4, 3), _row("lobby", 1, 5, 0, 0)])
    b = _write(tmp_path / "b.jsonl", [_row("home", 0, 5, 0, 0), _row("lobby", 0, 5, 0, 0)])
    out = tmp_path / "p.png"
    assert plot.main(["--setting", f"a={a}", "--setting", f"b={b}", "--scenes", "home,lobby",
                      "--paper", "88.67,2.40", "--out", str(out)]) == 0
    rows = [json.loads(x) for x in capsys.readouterr().out.splitlines()]
    assert rows[0] == {"setting": "a", "scenes": "home,lobby", "seeds": [0, 1], "trips": 20,
                       "success": [70.0, 10.0], "map_contact": [20.0, 10.0]}
    assert rows[1]["seeds"] == [0] and rows[1]["success"] == [100.0, 0.0]
    assert out.stat().st_size > 10_000
    capsys.readouterr()
    assert plot.main(["--setting", f"a={a}", "--scenes", "home,lobby", "--seeds", "1"]) == 0
    assert json.loads(capsys.readouterr().out)["success"] == [60.0, 0.0]


def test_bad_settings_and_missing_rows_are_named(tmp_path, capsys):
    a = _write(tmp_path / "a.jsonl", [_row("home", 0, 3, 2, 1)])
    with pytest.raises(SystemExit):
        plot.main(["--setting", "no-equals-sign"])
    assert "--setting takes LABEL=GLOB" in capsys.readouterr().err
    with pytest.raises(SystemExit, match="setting 'a', scenes 'heldout': no rows of scenes"):
        plot.main(["--setting", f"a={a}", "--scenes", "heldout"])
    with pytest.raises(SystemExit, match="setting 'a', scenes 'home': no rows on the chosen seeds"):
        plot.main(["--setting", f"a={a}", "--scenes", "home", "--seeds", "3"])
    with pytest.raises(SystemExit):
        plot.main(["--setting", f"a={a}", "--paper", "88.67"])
    assert "--paper takes SUCCESS,MAP" in capsys.readouterr().err
