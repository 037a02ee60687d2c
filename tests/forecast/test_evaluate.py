"""The forecaster registry and ``navzoo eval forecast``."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from navzoo.cli import main
from navzoo.forecast import evaluate as E


class _Truth:
    """A cheating forecaster that returns the ground truth: its errors must be 0."""

    def predict(self, batch: dict, n_samples: int) -> np.ndarray:
        return np.repeat(np.asarray(batch["fut"])[:, None], n_samples, axis=1)


def test_registry_adds_a_model_as_another_key(tiny_dir: Path) -> None:
    seen: list[E.ForecastContext] = []

    def factory(ctx: E.ForecastContext) -> _Truth:
        seen.append(ctx)
        return _Truth()

    E.register_forecaster("truth", factory)
    try:
        with pytest.raises(ValueError, match="already registered"):
            E.register_forecaster("truth", factory)
        result = E.evaluate_forecasts(tiny_dir, split="loo", samples=3, models=["constant_velocity", "truth"])
    finally:
        E.unregister_forecaster("truth")
    assert "truth" not in E.forecaster_names() and "sfm" in E.forecaster_names()
    assert result["truth"] == {"min_ade": 0.0, "min_fde": 0.0}
    assert result["constant_velocity"]["min_ade"] == pytest.approx(0.0, abs=1e-9)  # straight walkers
    assert sorted(result["scenes"]) == ["alpha", "beta"]
    assert [c.test_scene for c in seen] == ["alpha", "beta"]
    assert list(seen[0].train_files) == ["beta"]
    with pytest.raises(ValueError, match="unknown forecaster"):
        E.evaluate_forecasts(tiny_dir, models=["nope"])
    with pytest.raises(ValueError, match="unknown scene"):
        E.evaluate_forecasts(tiny_dir, scenes=["gamma"])


def test_cli_json_keys(tiny_dir: Path, capsys: pytest.CaptureFixture[str]) -> None:
    rc = main(["eval", "forecast", "--data", str(tiny_dir), "--split", "val", "--samples", "2", "--json"])
    assert rc == 0
    out = json.loads(capsys.readouterr().out)
    for model in ("constant_velocity", "sfm"):
        assert set(out[model]) == {"min_ade", "min_fde"}
        assert all(np.isfinite(v) for v in out[model].values())
        for scene in ("alpha", "beta"):
            assert set(out["scenes"][scene][model]) == {"min_ade", "min_fde"}
    assert out["scenes"]["alpha"]["windows"] > 0 and out["config"]["split"] == "val"


def test_cli_reports_bad_split_input(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    (tmp_path / "only_all.txt").write_text("0\t1\t0.0\t0.0\n")
    assert main(["eval", "forecast", "--data", str(tmp_path), "--split", "val"]) == 2
    assert "val" in capsys.readouterr().err


def test_an_interrupted_evaluation_resumes_from_its_out_file(tiny_dir: Path, tmp_path: Path,
                                                              monkeypatch: pytest.MonkeyPatch,
                                                              capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "forecast.json"
    args = ["eval", "forecast", "--data", str(tiny_dir), "--split", "loo", "--samples", "2",
            "--models", "constant_velocity", "--out", str(out), "--json"]
    real = E.score
    calls: list[int] = []

    def crash_on_second_scene(model, batch, n):  # noqa: ANN001, ANN202
        calls.append(1)
        if len(calls) == 2:
            raise KeyboardInterrupt
        return real(model, batch, n)

    monkeypatch.setattr(E, "score", crash_on_second_scene)
    assert main(args) != 0  # the CLI reports the interruption
    partial = json.loads(out.read_text())
    assert partial["partial"] is True and list(partial["scenes"]) == ["alpha"]
    assert partial["constant_velocity"] == partial["scenes"]["alpha"]["constant_velocity"]
    # the rerun scores only the scene that is missing, and the finished file has no "partial" flag
    calls.clear()
    monkeypatch.setattr(E, "score", lambda m, b, n: (calls.append(1), real(m, b, n))[1])
    capsys.readouterr()
    assert main(args) == 0
    assert len(calls) == 1
    final = json.loads(out.read_text())
    assert "partial" not in final and sorted(final["scenes"]) == ["alpha", "beta"]
    assert "resuming" in capsys.readouterr().err
    # a finished file is not reused, nor an interrupted one with other settings
    calls.clear()
    assert main(args) == 0 and len(calls) == 2
    monkeypatch.setattr(E, "score", crash_on_second_scene)
    calls.clear()
    assert main(args) != 0 and json.loads(out.read_text())["partial"] is True
    monkeypatch.setattr(E, "score", lambda m, b, n: (calls.append(1), real(m, b, n))[1])
    calls.clear()
    assert main(args[:7] + ["3"] + args[8:]) == 0 and len(calls) == 2
