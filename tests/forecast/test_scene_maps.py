"""OpenTraj obstacle maps as occupancy grids and map crops of ETH/UCY windows (navzoo.forecast.scene_maps)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from navzoo.forecast import data as D
from navzoo.forecast import evaluate as E
from navzoo.forecast import scene_maps as M

# Image (row, col) -> world: x = 0.05 col, y = 0.05 row (a 200 x 200 image covers 10 m x 10 m).
_H = np.array([[0.0, 0.05, 0.0], [0.05, 0.0, 0.0], [0.0, 0.0, 1.0]])


def _write_map(folder: Path, wall_col: int = 100) -> Path:
    import cv2

    folder.mkdir(parents=True, exist_ok=True)
    image = np.zeros((200, 200), np.uint8)
    image[:, wall_col] = 255  # a one-pixel line: the wall x = 0.05 * wall_col for y in [0, 10)
    cv2.imwrite(str(folder / "map.png"), image)
    np.savetxt(folder / "H.txt", _H)
    return folder


@pytest.fixture
def alpha_map(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    """An OpenTraj folder whose map (a wall at x = 5 m) belongs to the synthetic scene ``alpha``."""
    root = tmp_path / "opentraj"
    _write_map(root / "A" / "seq_alpha")
    monkeypatch.setitem(M.OPENTRAJ_MAPS, "alpha", "A/seq_alpha")
    return root


def test_grid_marks_the_drawn_line_thickened_and_leaves_the_rest_free(alpha_map: Path) -> None:
    grid = M.opentraj_grid("alpha", alpha_map, wall_radius=0.15, margin=8.0)
    assert grid is not None
    on_wall = np.array([[5.0, 0.5], [5.0, 5.0], [5.0, 9.9], [5.12, 5.0], [4.9, 5.0]])
    assert not grid.is_free(on_wall).any()
    free = np.array([[4.6, 5.0], [5.5, 5.0], [1.0, 1.0], [-6.0, 5.0], [15.0, 16.0]])  # incl. beyond the image
    assert grid.is_free(free).all()
    assert M.opentraj_grid("beta", alpha_map) is None  # no map for that scene
    with pytest.raises(FileNotFoundError, match="map.png"):
        M.opentraj_grid("alpha", alpha_map.parent / "elsewhere")
    with pytest.raises(ValueError, match="resolution"):
        M.opentraj_grid("alpha", alpha_map, resolution=0.0)


def test_bad_homography_is_refused(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    folder = _write_map(tmp_path / "ot" / "B")
    np.savetxt(folder / "H.txt", np.zeros((3, 3)))
    monkeypatch.setitem(M.OPENTRAJ_MAPS, "bad", "B")
    with pytest.raises(ValueError, match="invertible"):
        M.opentraj_grid("bad", tmp_path / "ot")


def test_crops_are_in_the_agent_frame(alpha_map: Path) -> None:
    # Two windows at (4, 5): one heading +x (the wall 1 m ahead), one heading -x (the wall 1 m behind).
    rot_fwd, rot_back = np.eye(2), np.array([[-1.0, 0.0], [0.0, -1.0]])
    batch = {"hist": np.zeros((2, 8, 2)), "origin": np.array([[4.0, 5.0], [4.0, 5.0]]),
             "rot": np.stack([rot_fwd, rot_back])}
    out = M.attach_maps(batch, "alpha", alpha_map)
    assert out["map"].shape == (2, M.MAP_CELLS, M.MAP_CELLS) and out["has_map"].tolist() == [True, True]
    cell = M.MAP_EXTENT / M.MAP_CELLS
    x_local = (np.arange(M.MAP_CELLS) + 0.5 - M.MAP_CELLS / 2) * cell  # column centres (m ahead)
    ahead = x_local[out["map"][0].max(axis=0) > 0.5]
    behind = x_local[out["map"][1].max(axis=0) > 0.5]
    assert ahead.size and np.all((ahead > 0.6) & (ahead < 1.4))
    assert behind.size and np.all((behind > -1.4) & (behind < -0.6))
    none = M.attach_maps(batch, "beta", alpha_map)
    assert not none["has_map"].any() and not none["map"].any()


def test_eval_forecast_passes_maps_only_when_asked_and_scores_obstacles(tiny_dir: Path, alpha_map: Path) -> None:
    seen: dict[str, list] = {"opentraj": [], "none": []}

    class Spy:
        def __init__(self, maps: str) -> None:
            self.maps = maps

        def predict(self, batch: dict, n_samples: int) -> np.ndarray:
            seen[self.maps].append((str(batch["scene"][0]), bool(np.any(batch.get("has_map", False)))))
            return np.repeat(np.asarray(batch["fut"])[:, None], n_samples, axis=1)

    results = {}
    for maps in ("opentraj", "none"):
        E.register_forecaster("spy", lambda ctx, m=maps: Spy(m))
        try:
            results[maps] = E.evaluate_forecasts(tiny_dir, samples=2, models=["spy", "constant_velocity"], maps=maps,
                                                 map_dir=alpha_map)
        finally:
            E.unregister_forecaster("spy")
    assert sorted(seen["opentraj"]) == [("alpha", True), ("beta", False)]
    assert sorted(seen["none"]) == [("alpha", False), ("beta", False)]
    for maps, result in results.items():
        alpha, beta = result["scenes"]["alpha"], result["scenes"]["beta"]
        assert alpha["map"] is (maps == "opentraj") and beta["map"] is False
        # the truth forecaster's obstacle rate is the ground truth's own; beta has no map to score on
        assert alpha["spy"]["obstacle_rate"] == pytest.approx(alpha["ground_truth_obstacle_rate"])
        assert "obstacle_rate" not in beta["spy"] and "ground_truth_obstacle_rate" not in beta
        assert set(result["spy"]) == {"min_ade", "min_fde"} and result["config"]["maps"] == maps
    # constant velocity ignores maps: the same numbers either way
    assert results["opentraj"]["constant_velocity"] == results["none"]["constant_velocity"]
    with pytest.raises(FileNotFoundError, match="--maps none"):
        E.evaluate_forecasts(tiny_dir, samples=1, models=["constant_velocity"], maps="opentraj",
                             map_dir=alpha_map.parent / "missing")
    with pytest.raises(ValueError, match="maps option"):
        E.evaluate_forecasts(tiny_dir, samples=1, models=["constant_velocity"], maps="osm")


def test_the_real_eth_map_matches_its_recorded_walls(eth_ucy: Path) -> None:
    map_dir = eth_ucy.parent / "opentraj"
    if not (map_dir / M.OPENTRAJ_MAPS["biwi_eth"] / "map.png").is_file():
        pytest.skip("the OpenTraj ETH map is not available")
    grid = M.opentraj_grid("biwi_eth", map_dir)
    # map.xml's walls (world metres): x = 14.2 for y in [-0.7, 4.9] and [6.4, 13], y = -0.66 and 12.8
    assert not grid.is_free(np.array([[14.19, 2.0], [14.2, 10.0], [7.0, -0.66], [7.0, 12.8]])).any()
    assert grid.is_free(np.array([[14.2, 5.6], [7.0, 6.0]])).all()  # the entrance gap, the walkway
    tracks = D.read_tracks(eth_ucy / "all_data" / "biwi_eth.txt")
    assert grid.is_free(tracks.xy).mean() > 0.999  # the recorded people walk in the free space


def test_diffusion_training_data_with_real_maps(eth_ucy: Path, tmp_path: Path) -> None:
    import json

    from navzoo.agents.diffusion.train import load_data
    from navzoo.cli import main

    if not (eth_ucy.parent / "opentraj" / M.OPENTRAJ_MAPS["biwi_eth"] / "map.png").is_file():
        pytest.skip("the OpenTraj ETH map is not available")
    train_w, val_w, desc = load_data("val", maps="opentraj", map_cells=16)
    assert train_w["map"].shape[1:] == (16, 16)
    eth = train_w["scene"] == "biwi_eth"
    assert train_w["has_map"][eth].all() and not train_w["has_map"][~eth].any()
    assert not train_w["map"][~eth].any() and train_w["map"][eth].any()
    assert desc["real_map_windows"]["biwi_eth"] == int(eth.sum()) and desc["real_map_windows"]["students001"] == 0
    assert val_w["has_map"][val_w["scene"] == "biwi_eth"].all()
    with pytest.raises(ValueError, match="--map-cells"):
        load_data("val", maps="opentraj", map_cells=0)
    with pytest.raises(ValueError, match="maps option"):
        load_data("val", maps="osm", map_cells=16)
    out = tmp_path / "run"
    assert main(["train", "diffusion", "--map-cells", "16", "--real-maps", "opentraj", "--steps", "2",
                 "--batch-size", "8", "--eval-every", "2", "--out", str(out)]) == 0
    meta = json.loads((out / "checkpoint/meta.json").read_text())
    assert meta["data"]["real_maps"] == "opentraj" and meta["data"]["real_map_windows"]["biwi_eth"] == int(eth.sum())


def test_opentraj_walls_read_the_map_lines_and_reject_bad_files(tmp_path: Path) -> None:
    assert M.opentraj_walls("crowds_zara01") is None  # no OpenTraj map in this frame
    folder = tmp_path / M.OPENTRAJ_MAPS["biwi_eth"]
    with pytest.raises(FileNotFoundError, match="map.xml"):
        M.opentraj_walls("biwi_eth", tmp_path)
    folder.mkdir(parents=True)
    (folder / "map.xml").write_text('<?xml version="1.0"?><Trial xmlns="https://github.com/amiryanj/OpenTraj">'
                                    '<obstacles><obstacle><TrialObstacle><Lines>'
                                    '<Line x1="0" y1="1" x2="2.5" y2="-1" thickness="1" /></Lines>'
                                    '</TrialObstacle></obstacle></obstacles></Trial>')
    np.testing.assert_array_equal(M.opentraj_walls("biwi_eth", tmp_path), [[[0.0, 1.0], [2.5, -1.0]]])
    other = tmp_path / "b"
    (other / M.OPENTRAJ_MAPS["biwi_eth"]).mkdir(parents=True)
    (other / M.OPENTRAJ_MAPS["biwi_eth"] / "map.xml").write_text('<Trial><Line x1="0" y1="nan" x2="1" y2="1"/></Trial>')
    with pytest.raises(ValueError, match="non-finite"):
        M.opentraj_walls("biwi_eth", other)
    (other / M.OPENTRAJ_MAPS["biwi_eth"] / "map.xml").write_text('<Trial><Line x1="0" y1="1"/>')
    with pytest.raises(ValueError, match="not an XML file"):
        M.opentraj_walls("biwi_eth", other)
