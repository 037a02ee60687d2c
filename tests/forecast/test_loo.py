"""Leave-one-scene-out folds of the diffusion model: what a fold trains and validates on, and how
``navzoo eval forecast --split loo --loo-models DIR`` picks and checks each fold's model."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from navzoo.cli import main
from navzoo.forecast import evaluate as E
from navzoo.forecast.data import load_windows

from .conftest import straight_rows, write_tracks

SCENES = ("alpha", "beta", "gamma")


@pytest.fixture
def three_scenes(tmp_path: Path) -> Path:
    """Three scenes whose train/, val/ and all_data/ files hold different numbers of walkers, so the
    window counts tell which file a fold read."""
    rng = np.random.default_rng(1)
    for k, scene in enumerate(SCENES):
        parts: dict[str, list] = {"train": [], "val": [], "all": []}
        for part, walkers in (("train", 3 + k), ("val", 1 + k)):
            for ped in range(walkers):
                pid = ped + (100 if part == "val" else 0)
                start = tuple(rng.uniform(0, 8, size=2))
                rows = straight_rows(pid, start, (0.4, 0.05 * (ped + 1)), 24, frame0=10 * ped)
                parts[part] += rows
                parts["all"] += rows
        write_tracks(tmp_path / "train" / f"{scene}_train.txt", parts["train"])
        write_tracks(tmp_path / "val" / f"{scene}_val.txt", parts["val"])
        write_tracks(tmp_path / "all_data" / f"{scene}.txt", parts["all"])
    return tmp_path


def _count(path: Path) -> int:
    return int(load_windows(path)["hist"].shape[0])


def test_a_fold_trains_and_validates_on_the_other_scenes_only(three_scenes: Path) -> None:
    from navzoo.agents.diffusion.train import load_data

    train, val, desc = load_data("loo", "gamma", str(three_scenes))
    assert desc["split"] == "loo" and desc["test_scene"] == "gamma"
    assert set(desc["train_windows"]) == set(desc["val_windows"]) == {"alpha", "beta"}
    for s in ("alpha", "beta"):
        assert desc["train_windows"][s] == _count(three_scenes / "train" / f"{s}_train.txt")
        assert desc["val_windows"][s] == _count(three_scenes / "val" / f"{s}_val.txt")
    # the held-out scene is in neither part, and the training part is not the whole recordings
    assert train["hist"].shape[0] == sum(desc["train_windows"].values())
    assert val["hist"].shape[0] == sum(desc["val_windows"].values())
    assert train["hist"].shape[0] < sum(_count(three_scenes / "all_data" / f"{s}.txt") for s in ("alpha", "beta"))


def test_a_fold_without_the_other_scenes_val_files_is_refused(three_scenes: Path) -> None:
    from navzoo.agents.diffusion.train import load_data

    (three_scenes / "val" / "beta_val.txt").unlink()
    with pytest.raises(ValueError, match=r"\['beta'\]"):
        load_data("loo", "gamma", str(three_scenes))
    with pytest.raises(ValueError, match="unknown test scene"):
        load_data("loo", "delta", str(three_scenes))


def _fake_model(folder: Path, split: str, test_scene: str | None, seen: tuple[str, ...]) -> Path:
    folder.mkdir(parents=True, exist_ok=True)
    data = {"split": split, "test_scene": test_scene, "train_windows": {s: 10 for s in seen},
            "val_windows": {s: 2 for s in seen}}
    (folder / "config.json").write_text(json.dumps({"format": "navzoo-trajectory-diffusion", "data": data}))
    return folder


def test_loo_model_dir_checks_the_fold(tmp_path: Path) -> None:
    good = _fake_model(tmp_path / "gamma", "loo", "gamma", ("alpha", "beta"))
    assert E.loo_model_dir(tmp_path, "gamma") == good
    with pytest.raises(FileNotFoundError, match="fold of 'alpha'"):
        E.loo_model_dir(tmp_path, "alpha")
    _fake_model(tmp_path / "beta", "loo", "gamma", ("alpha", "beta"))
    with pytest.raises(ValueError, match="test scene 'gamma'"):
        E.loo_model_dir(tmp_path, "beta")
    _fake_model(tmp_path / "alpha", "val", None, SCENES)
    with pytest.raises(ValueError, match="split 'val'"):
        E.loo_model_dir(tmp_path, "alpha")
    _fake_model(tmp_path / "alpha", "loo", "alpha", SCENES)  # claims the fold but lists the scene as seen
    with pytest.raises(ValueError, match="saw 'alpha'"):
        E.loo_model_dir(tmp_path, "alpha")
    (tmp_path / "alpha" / "config.json").write_text("{not json")
    with pytest.raises(ValueError, match="not a model config"):
        E.loo_model_dir(tmp_path, "alpha")


def test_loo_models_only_with_the_loo_split(three_scenes: Path, tmp_path: Path) -> None:
    with pytest.raises(ValueError, match="loo_models is for split 'loo'"):
        E.evaluate_forecasts(three_scenes, split="val", samples=2, models=["constant_velocity"], loo_models=tmp_path)


def test_trained_folds_are_evaluated_each_on_its_own_scene(three_scenes: Path, tmp_path: Path,
                                                           capsys: pytest.CaptureFixture[str]) -> None:
    from navzoo.agents.diffusion.train import main as train_main

    models = tmp_path / "models"
    for scene in ("alpha", "gamma"):
        assert train_main(["--out", str(tmp_path / "run" / scene), "--data", str(three_scenes), "--split", "loo",
                           "--test-scene", scene, "--steps", "4", "--batch-size", "8", "--eval-every", "2",
                           "--ckpt-every", "2", "--base", "8", "--export", str(models / scene), "--json"]) == 0
    capsys.readouterr()
    assert main(["eval", "forecast", "--data", str(three_scenes), "--split", "loo", "--scenes", "alpha,gamma",
                 "--loo-models", str(models), "--samples", "2", "--models", "constant_velocity,diffusion",
                 "--json"]) == 0
    result = json.loads(capsys.readouterr().out)
    assert sorted(result["scenes"]) == ["alpha", "gamma"]
    assert np.isfinite(result["diffusion"]["min_ade"]) and result["config"]["loo_models"] == str(models)
    # beta's fold has no model: the evaluation names the missing folder instead of using another fold's
    with pytest.raises(FileNotFoundError, match="fold of 'beta'"):
        E.evaluate_forecasts(three_scenes, split="loo", samples=2, models=["diffusion"], scenes=["beta"],
                             loo_models=models)
