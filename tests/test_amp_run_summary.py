"""Per-run summaries of the AMP training history (scripts/amp_run_summary.py)."""

from __future__ import annotations

import gzip
import json

import pytest

from tests.script_modules import load_script

summary = load_script("amp_run_summary")


def _row(it: int, wall: float, fps: float, task: float = 0.3) -> dict:
    return {"iteration": it, "global_step": it * 10, "wall_s": wall, "perf/fps": fps, "perf/collect_s": 1000 / fps,
            "perf/update_s": 0.3, "rewards/task": task, "rewards/style": 0.5}


def test_runs_split_where_the_wall_clock_restarts_and_skip_drops_their_starts(tmp_path, capsys):
    rows = [_row(1, 1.0, 3000), _row(2, 2.0, 1000), _row(3, 3.0, 1000),  # run 1: fast first iteration
            _row(4, 0.5, 5000, 0.9), _row(5, 1.5, 2000, 0.1), _row(6, 2.5, 2000, 0.2)]  # run 2 (resumed)
    path = tmp_path / "metrics.jsonl.gz"
    with gzip.open(path, "wt") as f:
        f.writelines(json.dumps(r) + "\n" for r in rows)
    summary.main(["--metrics", str(path), "--last", "0", "--skip", "1"])
    out = [json.loads(line) for line in capsys.readouterr().out.splitlines()]
    assert [(o["first_iteration"], o["last_iteration"]) for o in out] == [(1, 3), (4, 6)]
    assert [o["fps_median"] for o in out] == [1000, 2000]
    assert out[1]["task_reward_mean"] == pytest.approx(0.15)
    assert out[1]["last_global_step"] == 60
    summary.main(["--metrics", str(path), "--last", "1", "--skip", "0"])
    only = [json.loads(line) for line in capsys.readouterr().out.splitlines()]
    assert len(only) == 1 and only[0]["fps_median"] == 2000 and only[0]["iterations_summarised"] == 3


def test_missing_or_empty_metrics_are_refused(tmp_path):
    with pytest.raises(SystemExit, match="no metrics file"):
        summary.main(["--metrics", str(tmp_path / "nope.jsonl.gz")])
    (tmp_path / "empty.jsonl").write_text("")
    with pytest.raises(SystemExit, match="holds no iterations"):
        summary.main(["--metrics", str(tmp_path / "empty.jsonl")])
