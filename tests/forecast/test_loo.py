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
    with pytest.raises(ValueError, match="needs the held-out scene"):
        load_data("loo", None, str(three_scenes))


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


def test_resampling_keeps_the_walk_and_changes_the_time_base(tmp_path: Path) -> None:
    from navzoo.forecast.data import build_windows, read_tracks, resample_tracks

    rows = straight_rows(1, (0.0, 0.0), (0.4, 0.2), 40) + straight_rows(2, (5.0, 1.0), (-0.3, 0.0), 30, frame0=50)
    tracks = read_tracks(write_tracks(tmp_path / "all_data" / "walk.txt", rows))
    same = resample_tracks(tracks, tracks.dt)
    np.testing.assert_allclose(same.xy, tracks.xy)
    np.testing.assert_array_equal(same.ped, tracks.ped)
    slow = resample_tracks(tracks, 0.667)
    assert slow.dt == 0.667 and slow.frame_step == 10
    one = slow.xy[slow.ped == 1]
    # walker 1 moves 0.4 m / 0.4 s in x: at 0.667 s steps, 0.667 m per row, on the same straight line
    np.testing.assert_allclose(np.diff(one[:, 0]), 0.667, atol=1e-9)
    np.testing.assert_allclose(one[:, 1], 0.5 * one[:, 0], atol=1e-9)
    assert len(one) == int(39 * 0.4 / 0.667) + 1
    # the two walkers share the new time grid: walker 2 starts at the first grid time after its first row
    t2 = slow.frame[slow.ped == 2] / 10 * 0.667
    assert t2[0] >= 5 * 0.4 - 1e-9 and t2[0] - 0.667 < 5 * 0.4
    w = build_windows(slow, k_neighbors=2)
    assert w["hist"].shape[0] > 0 and np.all(w["dt"] == 0.667)
    gap = rows[:10] + rows[12:40]
    with pytest.raises(ValueError, match="gap"):
        resample_tracks(read_tracks(write_tracks(tmp_path / "gap.txt", gap)), 0.667)
    with pytest.raises(ValueError, match="positive"):
        resample_tracks(tracks, 0.0)


def test_time_base_augmentation_adds_resampled_training_windows_only(three_scenes: Path) -> None:
    from navzoo.agents.diffusion.train import load_data

    train, val, desc = load_data("loo", "gamma", str(three_scenes), resample_dt=(0.25,))
    plain_train, plain_val, plain = load_data("loo", "gamma", str(three_scenes))
    assert set(desc["train_windows"]) == {"alpha", "beta", "alpha@0.25s", "beta@0.25s"}
    assert desc["val_windows"] == plain["val_windows"] and desc["resample_dt"] == [0.25]
    assert desc["train_windows"]["alpha@0.25s"] > desc["train_windows"]["alpha"]  # more rows at a shorter step
    assert train["hist"].shape[0] == sum(desc["train_windows"].values())
    assert set(np.unique(train["dt"]).round(3)) == {0.25, 0.4}
    # a step equal to the scenes' own adds nothing
    _, _, same = load_data("loo", "gamma", str(three_scenes), resample_dt=(0.4,))
    assert same["train_windows"] == plain["train_windows"]
    with pytest.raises(ValueError, match="positive time steps"):
        load_data("loo", "gamma", str(three_scenes), resample_dt=(-1.0,))


LOO_MODELS = Path(__file__).resolve().parents[2] / "training" / "diffusion_loo_resampled" / "models"
REAL_SCENES = ("biwi_eth", "crowds_zara01", "crowds_zara03", "students001", "uni_examples")


def test_the_committed_fold_models_pass_the_fold_checks() -> None:
    for scene in REAL_SCENES:
        folder = E.loo_model_dir(LOO_MODELS, scene)
        data = json.loads((folder / "config.json").read_text())["data"]
        assert data["resample_dt"] == [0.4, 0.667]
        assert scene not in {k.split("@")[0] for k in data["train_windows"]} | set(data["val_windows"])


def test_the_biwi_eth_fold_beats_the_baselines_on_its_held_out_scene(eth_ucy: Path) -> None:
    result = E.evaluate_forecasts(eth_ucy, split="loo", samples=20, scenes=["biwi_eth"], max_windows=80,
                                  models=["constant_velocity", "sfm", "diffusion"], loo_models=LOO_MODELS)
    d, cv, sf = (result[k] for k in ("diffusion", "constant_velocity", "sfm"))
    assert d["min_ade"] < 0.8 * min(cv["min_ade"], sf["min_ade"])
    assert d["min_fde"] < 0.8 * min(cv["min_fde"], sf["min_fde"])
