from __future__ import annotations

import gzip
import json

import pytest

from tests.script_modules import load_script

rf = load_script("amp_recorded_falls")


def _rows(n, share=0.5, fall_rec=0.001, fall_gen=0.002, start=100):
    return [{"iteration": start + i, "env/recorded": share, "env/fall_recorded": fall_rec,
             "env/fall_generated": fall_gen, "env/stance_split_m": 0.1} for i in range(n)]


def test_falls_per_minute_of_each_kind_per_block_and_overall():
    out = rf.blocks(_rows(90), every=40)
    assert [(b["from"], b["to"], b["iterations"]) for b in out] == [(100, 139, 40), (140, 189, 50), (100, 189, 90)]
    for b in out:
        # 0.001 falls per step over half the rows: 0.002 per recorded step, x 1800 steps a minute
        assert b["falls_per_min_recorded"] == pytest.approx(3.6)
        assert b["falls_per_min_generated"] == pytest.approx(7.2)
        assert b["recorded_share"] == 0.5


def test_the_command_reads_gzip_metrics_and_names_a_run_without_recorded_logs(tmp_path, capsys):
    f = tmp_path / "metrics.jsonl.gz"
    with gzip.open(f, "wt") as g:
        g.write("".join(json.dumps(r) + "\n" for r in _rows(45)))
    assert rf.main([str(f), "--every", "20"]) == 0
    lines = capsys.readouterr().out.splitlines()
    assert lines[2].startswith("| 100-119 | 0.50 | 3.6 | 7.2 |") and lines[-1].startswith("| 100-144 |")
    plain = tmp_path / "plain.jsonl"
    plain.write_text(json.dumps({"iteration": 1, "env/stance_split_m": 0.1}) + "\n")
    with pytest.raises(SystemExit):
        rf.main([str(plain)])
    assert "no iterations with env/recorded" in capsys.readouterr().err
