"""ETH/UCY loading, windows, neighbours, agent-centric frames and augmentation."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from navzoo.forecast import data as D
from tests.forecast.conftest import straight_rows, write_tracks


def test_read_tracks_parses_float_columns(tmp_path: Path) -> None:
    path = write_tracks(tmp_path / "x_val.txt", [(780.0, 1.0, 8.46, 3.59), (790.0, 1.0, 9.57, 3.79),
                                                 (800.0, 2.0, 13.64, 5.8)])
    tr = D.read_tracks(path)
    assert tr.scene == "x" and tr.dt == pytest.approx(0.4) and tr.frame_step == 10
    assert tr.frame.dtype == np.int64 and tr.frame.tolist() == [780, 790, 800]
    assert tr.ped.tolist() == [1, 1, 2]
    np.testing.assert_allclose(tr.xy[2], [13.64, 5.8])


@pytest.mark.parametrize("line, match", [("0\t1\t2.0\n", "expected 4 columns"), ("0\t1\tabc\t2\n", "not a number"),
                                         ("0\t1.5\t1\t2\n", "whole numbers"), ("0\t1\tnan\t2\n", "non-finite")])
def test_read_tracks_rejects_malformed_lines(tmp_path: Path, line: str, match: str) -> None:
    path = tmp_path / "bad.txt"
    path.write_text("0\t1\t1.0\t2.0\n" + line)
    with pytest.raises(ValueError, match=match):
        D.read_tracks(path)


def test_biwi_eth_time_base_gives_real_walking_speed(eth_ucy: Path) -> None:
    tr = D.read_tracks(eth_ucy / "all_data" / "biwi_eth.txt")
    assert tr.dt == pytest.approx(0.667) and D.scene_dt("biwi_eth") == pytest.approx(0.667)
    median = float(np.median(D.step_speeds(tr)))
    assert 1.2 < median < 1.6, median  # 0.4 s would give ~2.45 m/s
    assert D.scene_dt("crowds_zara01") == pytest.approx(0.4)
    batch = D.load_windows(eth_ucy / "val" / "biwi_eth_val.txt")
    assert np.all(batch["dt"] == pytest.approx(0.667))


def test_window_counts_per_scene(eth_ucy: Path) -> None:
    val = D.load_split(eth_ucy, "val", "test")
    assert sorted(val) == ["biwi_eth", "crowds_zara01", "crowds_zara03", "students001", "uni_examples"]
    for scene, batch in val.items():
        n = D.batch_size(batch)
        assert n > 0, scene
        assert batch["hist"].shape == (n, 8, 2) and batch["fut"].shape == (n, 12, 2)
        assert batch["neigh"].shape == (n, 16, 8, 2) and batch["neigh_mask"].shape == (n, 16, 8)
        assert set(batch["scene"]) == {scene}
    # The usual ETH test set of the 8 + 12 protocol has 364 windows.
    assert D.batch_size(D.load_windows(eth_ucy / "all_data" / "biwi_eth.txt")) == 364
    train, test = D.split_files(eth_ucy, "loo", "uni_examples")
    assert list(test) == ["uni_examples"] and "uni_examples" not in train and len(train) == 4
    with pytest.raises(ValueError, match="unknown test scene"):
        D.split_files(eth_ucy, "loo", "hotel")
    with pytest.raises(ValueError, match="unknown split"):
        D.split_files(eth_ucy, "test")


def test_windows_need_consecutive_frames_and_find_nearest_neighbours(tmp_path: Path) -> None:
    rows = straight_rows(1, (0.0, 0.0), (0.5, 0.0), 21)           # 21 rows -> 2 windows
    rows += straight_rows(2, (0.0, 3.0), (0.5, 0.0), 19)          # 19 rows -> none
    rows += straight_rows(3, (0.0, 1.0), (0.5, 0.0), 8, frame0=0)  # leaves after frame 70
    rows += straight_rows(4, (0.0, 20.0), (0.5, 0.0), 21)         # beyond the 10 m radius of ped 1
    batch = D.build_windows(D.read_tracks(write_tracks(tmp_path / "s.txt", rows)), k_neighbors=3)
    first = np.flatnonzero((batch["ped"] == 1) & (batch["frame"] == 70))
    assert sorted(batch["ped"].tolist()) == [1, 1, 4, 4] and first.size == 1
    i = first[0]
    assert batch["neigh_ped"][i].tolist() == [3, 2, -1]            # nearest first, ped 4 too far
    assert batch["neigh_mask"][i, 0].all() and not batch["neigh_fut_mask"][i, 0].any()
    assert batch["neigh_mask"][i, 1].all() and batch["neigh_fut_mask"][i, 1].sum() == 11
    assert not batch["neigh_mask"][i, 2].any() and np.all(batch["neigh"][i, 2] == 0)
    np.testing.assert_allclose(batch["neigh"][i, 1, -1], [3.5, 3.0])


def _with_neighbour_holes(eth_ucy: Path) -> dict:
    batch = D.load_windows(eth_ucy / "val" / "crowds_zara01_val.txt", normalized=False)
    return D.subset(batch, np.arange(0, D.batch_size(batch), 7))


def test_normalisation_round_trips(eth_ucy: Path) -> None:
    world = _with_neighbour_holes(eth_ucy)
    local = D.normalize(world)
    np.testing.assert_allclose(local["hist"][:, -1], 0.0, atol=1e-12)
    step = local["hist"][:, -1] - local["hist"][:, -2]
    moving = np.linalg.norm(step, axis=1) > 1e-3
    assert moving.mean() > 0.5
    np.testing.assert_allclose(step[moving, 1], 0.0, atol=1e-9)
    assert np.all(step[moving, 0] > 0)
    for key, mask in D.POSITION_KEYS.items():
        back = D.to_world(local[key], local)
        if mask is not None:
            back = np.where(world[mask][..., None], back, 0.0)
        np.testing.assert_allclose(back, world[key], rtol=0, atol=1e-12, err_msg=key)
    np.testing.assert_allclose(D.to_local(world["fut"], local), local["fut"], atol=1e-12)
    samples = np.repeat(local["fut"][:, None], 3, axis=1)
    np.testing.assert_allclose(D.to_world(samples, local)[:, 2], world["fut"], atol=1e-12)


def test_random_rotation_preserves_distances(eth_ucy: Path) -> None:
    world = _with_neighbour_holes(eth_ucy)
    local = D.normalize(world)
    aug = D.random_rotation(local, np.random.default_rng(3))
    assert not np.allclose(aug["fut"], local["fut"])

    def points(b: dict) -> np.ndarray:
        n = D.batch_size(b)
        return np.concatenate([b["hist"], b["fut"], b["neigh"].reshape(n, -1, 2)], axis=1)

    def pairwise(p: np.ndarray) -> np.ndarray:
        return np.linalg.norm(p[:, :, None] - p[:, None, :], axis=-1)

    np.testing.assert_allclose(pairwise(points(aug)), pairwise(points(local)), atol=1e-9)
    np.testing.assert_allclose(D.to_world(aug["fut"], aug), world["fut"], atol=1e-12)
    assert not np.any(aug["neigh"][~aug["neigh_mask"]])


def test_flat_folder_and_concat(tiny_dir: Path) -> None:
    batches = D.load_split(tiny_dir, "loo", "train", test_scene="alpha")
    assert list(batches) == ["beta"]
    both = D.concat([batches["beta"], D.load_split(tiny_dir, "loo", test_scene="alpha")["alpha"]])
    assert D.batch_size(both) == 2 * D.batch_size(batches["beta"]) > 0
    with pytest.raises(ValueError, match="unknown part"):
        D.load_split(tiny_dir, "val", "dev")
