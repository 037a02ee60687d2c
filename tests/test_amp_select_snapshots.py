"""Checkpoint selection over a training run's policy snapshots (scripts/amp_select_snapshots.py)."""

from __future__ import annotations

import json
import shutil
import sys
from pathlib import Path

import pytest

from tests.script_modules import load_script

_SCRIPTS = Path(__file__).resolve().parents[1] / "scripts"
sys.path.insert(0, str(_SCRIPTS))
select = load_script("amp_select_snapshots")
SHIPPED = Path(__file__).resolve().parents[1] / "policies" / "amp_pedestrian"


def _snapshots(tmp_path: Path, iterations: list[int]) -> Path:
    snaps = tmp_path / "snapshots"
    for it in iterations:
        (snaps / f"policy_{it:08d}").mkdir(parents=True)
        shutil.copy(SHIPPED / "config.json", snaps / f"policy_{it:08d}" / "config.json")
    (snaps / "notes").mkdir()  # not a policy: ignored
    return snaps


def test_short_protocol_shortlists_and_the_full_protocol_chooses(tmp_path, monkeypatch):
    snaps = _snapshots(tmp_path, [100, 125, 150, 175])
    # success per candidate: the short protocol likes it150 and it175; the full one prefers it150
    short = {"it100": 2, "it125": 5, "it150": 8, "it175": 9, "baseline": 6}
    full = {"it150": 7, "it175": 4, "baseline": 6}
    calls, configs = [], []

    def fake_main(argv):
        a = dict(zip(argv[::2], argv[1::2], strict=True))
        names = [c.split(":")[0] for c in a["--configs"].split(",")]
        table = short if a["--seconds"] == "60.0" else full
        calls.append((a["--seconds"], names))
        configs.extend(a["--configs"].split(","))
        with open(a["--out"], "a") as f:
            for n in names:
                for seed in a["--seeds"].split(","):
                    f.write(json.dumps({"config": n, "seed": int(seed), "scene": "s", "success": table[n],
                                        "off_path": 10 - table[n], "fall": 0, "timeout": 0}) + "\n")
        return 0

    monkeypatch.setattr(select.ata, "main", fake_main)
    out = tmp_path / "sel"
    assert select.main(["--snapshots", str(snaps), "--baseline", str(SHIPPED), "--trim", "0.025", "--out", str(out)]) == 0
    result = json.loads((out / "selection.json").read_text())
    assert calls[0] == ("60.0", ["it100", "it125", "it150", "it175", "baseline"])
    assert calls[1] == ("200.0", ["it175", "it150", "baseline"])  # the top 2 of the short protocol + baseline
    assert result["short_ranking"] == ["it175", "it150", "it125", "it100"]
    assert result["chosen"] == "it150" and result["chosen_policy"].endswith("policy_00000150")
    assert result["candidates"]["it150"]["full"] == {"success": 0.7, "trips": 20, "runs": 2}
    assert result["candidates"]["it100"]["full"] is None
    # the configurations: the shipped target settings, the shared trim and each snapshot's folder
    assert configs[0] == f"it100:0.1:0.1:4:2.0:0:0.025:{snaps / 'policy_00000100'}"
    assert configs[4] == f"baseline:0.1:0.1:4:2.0:0:0.025:{SHIPPED}"


def test_a_tie_keeps_the_baseline(tmp_path, monkeypatch):
    snaps = _snapshots(tmp_path, [10])

    def fake_main(argv):
        a = dict(zip(argv[::2], argv[1::2], strict=True))
        with open(a["--out"], "a") as f:
            for c in a["--configs"].split(","):
                f.write(json.dumps({"config": c.split(":")[0], "seed": 0, "scene": "s", "success": 5,
                                    "off_path": 5, "fall": 0, "timeout": 0}) + "\n")
        return 0

    monkeypatch.setattr(select.ata, "main", fake_main)
    select.main(["--snapshots", str(snaps), "--baseline", str(SHIPPED), "--out", str(tmp_path / "sel")])
    assert json.loads((tmp_path / "sel" / "selection.json").read_text())["chosen"] == "baseline"


def test_bad_arguments_are_named(tmp_path, capsys):
    empty = tmp_path / "none"
    empty.mkdir()
    for argv, match in (([], "no policy snapshots"), (["--top", "0"], "--top"), (["--trim", "0.9"], "--trim"),
                        (["--baseline", str(empty)], "baseline")):
        with pytest.raises(SystemExit):
            select.main(["--snapshots", str(empty), "--out", str(tmp_path / "o"), *argv])
        assert match in capsys.readouterr().err


def test_a_real_short_protocol_run(tmp_path):
    snaps = tmp_path / "snapshots"
    shutil.copytree(SHIPPED, snaps / "policy_00005174")
    out = tmp_path / "sel"
    argv = ["--snapshots", str(snaps), "--out", str(out), "--scenes", "station", "--short-seconds", "2",
            "--full-seeds", "", "--workers", "1"]
    assert select.main(argv) == 0
    rows = [json.loads(x) for x in (out / "short.jsonl").read_text().splitlines()]
    assert [(r["config"], r["scene"], r["seed"]) for r in rows] == [("it5174", "station", 2)]
    result = json.loads((out / "selection.json").read_text())
    assert result["chosen"] is None and result["short_ranking"] == ["it5174"]
    assert select.main(argv) == 0  # a rerun resumes: nothing is run twice
    assert len((out / "short.jsonl").read_text().splitlines()) == 1
