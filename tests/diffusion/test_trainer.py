"""Diffusion training: resumes exactly, checkpoints are checked, exported models load."""

from __future__ import annotations

import json

import numpy as np
import pytest
import torch

from navzoo.agents.diffusion.model import DiffusionConfig
from navzoo.agents.diffusion.trainer import TrainConfig, export, load_model, train

CFG = DiffusionConfig(base=8, mults=(1, 2), cond_dim=32, map_cells=0, steps=20, sample_steps=4)


def _windows(n: int = 64, seed: int = 0) -> dict[str, np.ndarray]:
    rng = np.random.default_rng(seed)
    speed = rng.uniform(0.5, 1.5, n)
    k = np.arange(-7, 1)
    kf = np.arange(1, 13)
    hist = np.stack([k[None] * 0.4 * speed[:, None], np.zeros((n, 8))], -1)
    fut = np.stack([kf[None] * 0.4 * speed[:, None], np.zeros((n, 12))], -1)
    return {"hist": hist, "fut": fut, "dt": np.full(n, 0.4), "neigh": np.zeros((n, 2, 8, 2)),
            "neigh_mask": np.zeros((n, 2, 8), dtype=bool)}


def test_resume_gives_the_same_weights_as_one_run(tmp_path):
    quiet = lambda *_: None  # noqa: E731
    w = _windows()
    train(CFG, TrainConfig(steps=12, batch_size=8, ckpt_every=5), w, tmp_path / "a", log=quiet)
    train(CFG, TrainConfig(steps=6, batch_size=8, ckpt_every=5), w, tmp_path / "b", log=quiet)
    summary = train(CFG, TrainConfig(steps=12, batch_size=8, ckpt_every=5), w, tmp_path / "b", log=quiet)
    assert summary["step"] == 12
    a = torch.load(tmp_path / "a/checkpoint/state.pt", weights_only=True)
    b = torch.load(tmp_path / "b/checkpoint/state.pt", weights_only=True)
    for k in a["model"]:
        torch.testing.assert_close(a["model"][k], b["model"][k])
    rows = [json.loads(x) for x in (tmp_path / "a/metrics.jsonl").read_text().splitlines()]
    assert rows == [] or all(np.isfinite(r["loss"]) for r in rows)


def test_bad_windows_and_tampered_checkpoints_are_rejected(tmp_path):
    w = _windows()
    bad = dict(w, fut=w["fut"][:10])
    with pytest.raises(ValueError, match="'fut' has 10 rows"):
        train(CFG, TrainConfig(steps=1), bad, tmp_path / "x", log=lambda *_: None)
    nan = dict(w, hist=w["hist"].copy())
    nan["hist"][0, 0, 0] = np.nan
    with pytest.raises(ValueError, match="NaN"):
        train(CFG, TrainConfig(steps=1), nan, tmp_path / "x", log=lambda *_: None)
    train(CFG, TrainConfig(steps=2, batch_size=4), w, tmp_path / "c", log=lambda *_: None)
    other = DiffusionConfig(base=8, mults=(1, 2), cond_dim=32, map_cells=0, steps=30, sample_steps=4)
    with pytest.raises(ValueError, match="was trained with"):
        train(other, TrainConfig(steps=3), w, tmp_path / "c", log=lambda *_: None)
    model_dir = export(tmp_path / "c/checkpoint", tmp_path / "model", card={"data": "synthetic"})
    m = load_model(model_dir)
    b = {"hist": torch.zeros(2, 8, 2), "dt": torch.full((2,), 0.4)}
    assert m.sample(b, 3, generator=torch.Generator().manual_seed(0)).shape == (2, 3, 12, 2)
    with open(model_dir / "model.pt", "ab") as f:
        f.write(b"x")
    with pytest.raises(ValueError, match="sha256"):
        load_model(model_dir)


def test_augment_is_a_similarity_of_each_window_and_drops_neighbours():
    from navzoo.agents.diffusion.trainer import augment

    w = _windows(32)
    w["neigh"] = np.random.default_rng(1).normal(size=(32, 2, 8, 2))
    w["neigh_mask"] = np.ones((32, 2, 8), dtype=bool)
    a = augment(w, np.random.default_rng(0), hist_noise=0.0, drop_neighbor=0.5)
    # A similarity about the origin: ratios of distances between any two points are kept.
    d0 = np.linalg.norm(w["fut"][:, -1], axis=-1) / np.linalg.norm(w["hist"][:, 0], axis=-1)
    d1 = np.linalg.norm(a["fut"][:, -1], axis=-1) / np.linalg.norm(a["hist"][:, 0], axis=-1)
    np.testing.assert_allclose(d0, d1)
    np.testing.assert_allclose(a["hist"][:, -1], 0.0, atol=1e-12)  # the person stays at the origin
    assert 0.2 < 1 - a["neigh_mask"][:, :, 0].mean() < 0.8
    assert np.all(a["neigh"][~a["neigh_mask"]] == 0.0)
    noisy = augment(w, np.random.default_rng(0))
    np.testing.assert_allclose(noisy["hist"][:, -1], 0.0, atol=1e-12)
    assert np.abs(noisy["hist"][:, :-1] - a["hist"][:, :-1]).max() > 0.005


def test_validation_rows_span_every_scene_of_a_large_validation_set():
    from navzoo.agents.diffusion.trainer import validation_rows

    np.testing.assert_array_equal(validation_rows(10, 2048), np.arange(10))
    rows = validation_rows(10_000, 2048)
    assert len(rows) == 2048 and rows[0] == 0 and rows[-1] == 9_999
    assert np.all(np.diff(rows) > 0)
    # windows grouped by scene (5 scenes of 2,000): every scene is validated, about equally
    counts = np.bincount(rows // 2000, minlength=5)
    assert counts.min() >= 400, counts
