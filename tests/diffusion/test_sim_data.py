"""Map-aware sim windows (navzoo.forecast.sim_data): format, continuity, map crops in the loop's frame,
augmentation that keeps map and path consistent, file round trip, and the training CLI with --sim-data."""

from __future__ import annotations

import json

import numpy as np
import pytest

from navzoo.agents.diffusion.trainer import augment, warp_maps
from navzoo.forecast import data as fdata
from navzoo.forecast import sim_data as sd


def _cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    return a[..., 0] * b[..., 1] - a[..., 1] * b[..., 0]


SCENE = "l_corridor"  # a 2 m wide L-shaped corridor, not an evaluation scene
C = 32


@pytest.fixture(scope="module")
def rec():
    return sd.record_crowd(SCENE, "sfm", people=6, seconds=24.0, seed=0)


@pytest.fixture(scope="module")
def windows(rec):
    return sd.windows_from_recording(rec, map_cells=C)


def test_default_scenes_leave_out_the_evaluation_scenes():
    from navzoo.agents.diffusion.crowd import MAP_EXTENT
    from navzoo.benchmark.pedestrians import SCENES

    scenes = sd.default_scenes()
    assert SCENE in scenes and len(scenes) >= 10
    assert not set(scenes) & set(SCENES)
    assert sd.MAP_EXTENT == MAP_EXTENT


def test_windows_have_the_keys_and_shapes_of_eth_ucy_windows_plus_a_map(rec, windows):
    tracks = fdata.Tracks(scene="toy", dt=0.4, frame_step=10, frame=np.repeat(np.arange(25) * 10, 2),
                          ped=np.tile([1, 2], 25), xy=np.random.default_rng(0).normal(size=(50, 2)))
    eth = fdata.build_windows(tracks)
    assert set(windows) == set(eth) | {"map", "has_map"}
    n = fdata.batch_size(windows)
    assert n > 50
    for key, value in eth.items():
        assert windows[key].shape[1:] == value.shape[1:], key
        assert windows[key].dtype.kind == value.dtype.kind, key
    assert windows["map"].shape == (n, C, C) and windows["map"].dtype == np.float32
    assert windows["has_map"].dtype == bool and windows["has_map"].all()
    np.testing.assert_array_equal(windows["dt"], 0.4)
    assert set(windows["scene"]) == {f"sim/sfm/{SCENE}"}
    # Agent frame: current position at the origin, last step along +x.
    np.testing.assert_allclose(windows["hist"][:, -1], 0.0, atol=1e-9)
    # Neighbours: the 5 other people when within 10 m, nearest first.
    here = np.linalg.norm(np.where(windows["neigh_mask"][:, :, -1, None], windows["neigh"][:, :, -1], np.inf), axis=-1)
    assert (windows["neigh_mask"][:, :, -1].sum(1) <= 5).all() and windows["neigh_mask"][:, :, -1].any()
    finite = np.where(np.isfinite(here), here, 1e9)
    assert (np.diff(finite, axis=1) >= -1e-9).all()
    assert (windows["neigh_ped"][~windows["neigh_mask"][:, :, -1]] == -1).all()
    # World frame round trip: the recorded positions.
    world = fdata.to_world(np.concatenate([windows["hist"], windows["fut"]], axis=1), windows)
    t0 = windows["frame"] - 7
    np.testing.assert_allclose(world, rec.pos[t0[:, None] + np.arange(20), windows["ped"][:, None]], atol=1e-9)


def test_windows_are_continuous_and_never_span_a_goal_reset(rec, windows):
    world = fdata.to_world(np.concatenate([windows["hist"], windows["fut"]], axis=1), windows)
    step = np.linalg.norm(np.diff(world, axis=1), axis=-1)
    assert step.max() <= 2.0 * 0.4 + 1e-9  # human_max_speed x 0.4 s
    assert rec.goals[-1].sum() > 0  # people did reach goals in this run ...
    frames = (windows["frame"] - 7)[:, None] + np.arange(20)
    g = rec.goals[frames, windows["ped"][:, None]]
    assert (g == g[:, :1]).all()  # ... but no window spans one
    # A synthetic teleport and goal reset cut the windows around them; a neighbour across its teleport is masked.
    F, P = 40, 2
    pos = np.stack([np.stack([np.arange(F) * 0.5, np.zeros(F)], -1), np.stack([np.arange(F) * 0.5, np.ones(F)], -1)], 1)
    pos[25:, 1] += 5.0
    goals = np.zeros((F, P), np.int64)
    goals[10:, 0] = 1
    tele = np.zeros((F, P), bool)
    tele[25, 1] = True
    toy = sd.Recording("toy", "sfm", pos, goals, tele, rec.grid, 0, 0.0)
    w = sd.windows_from_recording(toy, map_cells=8, normalized=False)
    start0 = w["frame"][w["ped"] == 0] - 7
    start1 = w["frame"][w["ped"] == 1] - 7
    assert set(start0) == set(range(10, 21))  # person 0: a goal reset between frames 9 and 10
    assert set(start1) == set(range(0, 6))  # person 1: a teleport between frames 24 and 25
    keep = sd.windows_from_recording(toy, map_cells=8, cut_at_goal=False, normalized=False)
    assert set(keep["frame"][keep["ped"] == 0] - 7) == set(range(21))
    i = np.flatnonzero((w["ped"] == 0) & (w["frame"] == 27))[0]  # observed 20..27: person 1 teleported at 25
    np.testing.assert_array_equal(w["neigh_mask"][i, 0], np.arange(20, 28) >= 25)


def test_map_is_the_loops_crop_in_the_windows_agent_frame(rec, windows):
    # The diffusion crowd's crop (crowd.py plan_now): crop_many(current position, heading of normalize's rot).
    local = windows
    heading = np.arctan2(local["rot"][:, 0, 1], local["rot"][:, 0, 0])
    centre = fdata.to_world(np.zeros((fdata.batch_size(local), 1, 2)), local)[:, 0]
    np.testing.assert_array_equal(local["map"], rec.grid.crop_many(centre, heading, 8.0, C))
    # And the convention, independently: cell [r, c] is the agent-frame point (x_c, y_r).
    u = (np.arange(C) + 0.5 - C / 2) * 8.0 / C
    x, y = np.meshgrid(u, u)
    pts = np.repeat(np.stack([x, y], -1).reshape(1, -1, 2), len(heading), 0)
    occ = ~rec.grid.is_free(fdata.to_world(pts, local)).reshape(-1, C, C)
    assert (occ == (local["map"] > 0.5)).mean() > 0.999


def test_occupancy_is_non_trivial_in_a_corridor(windows):
    m = windows["map"]
    assert 0.2 < m.mean() < 0.95
    centre = m[:, C // 2 - 1:C // 2 + 1, C // 2 - 1:C // 2 + 1]
    assert (centre.max(axis=(1, 2)) == 0).mean() > 0.95  # people stand in free space
    # A 2 m corridor: walls within 1.5 m on the left (rows above the centre) and the right of most people.
    near_left = m[:, C // 2:C // 2 + 6, C // 2 - 2:C // 2 + 2].max(axis=(1, 2))
    near_right = m[:, C // 2 - 6:C // 2, C // 2 - 2:C // 2 + 2].max(axis=(1, 2))
    assert (near_left * near_right).mean() > 0.5


def test_warp_maps_mirror_is_a_row_flip_and_turns_match_the_loops_crop(rec, windows):
    n = fdata.batch_size(windows)
    m = windows["map"]
    np.testing.assert_array_equal(warp_maps(m, np.repeat(np.eye(2)[None], n, 0)), m)
    np.testing.assert_array_equal(warp_maps(m, np.repeat(np.diag([1.0, -1.0])[None], n, 0)), m[:, ::-1, :])
    # p' = R(a) p: the same world seen from a heading turned by -a.
    a = np.random.default_rng(0).uniform(-np.radians(15), np.radians(15), n)
    R = np.stack([np.stack([np.cos(a), -np.sin(a)], -1), np.stack([np.sin(a), np.cos(a)], -1)], -2)
    heading = np.arctan2(windows["rot"][:, 0, 1], windows["rot"][:, 0, 0])
    centre = fdata.to_world(np.zeros((n, 1, 2)), windows)[:, 0]
    truth = rec.grid.crop_many(centre, heading - a, 8.0, C)
    inner = slice(4, C - 4)  # corners come from beyond the old crop
    assert (warp_maps(m, R)[:, inner, inner] == truth[:, inner, inner]).mean() > 0.95


def test_augment_keeps_the_wall_on_the_same_side_of_the_path():
    # A person walking along +x, turning right, with a wall 1 m to the left (the outside of the turn).
    n = 400
    k = np.arange(-7, 1) * 0.5
    hist = np.repeat(np.stack([k, np.zeros(8)], -1)[None], n, 0)
    s = np.arange(1, 13) * 0.5
    fut = np.repeat(np.stack([s, -0.04 * s ** 2], -1)[None], n, 0)
    u = (np.arange(C) + 0.5 - C / 2) * 8.0 / C
    wall = np.broadcast_to((u >= 1.0)[:, None], (C, C)).astype(np.float32)  # rows with y >= 1 m
    w = {"hist": hist, "fut": fut, "dt": np.full(n, 0.4), "neigh": np.zeros((n, 1, 8, 2)),
         "neigh_mask": np.zeros((n, 1, 8), bool), "map": np.repeat(wall[None], n, 0), "has_map": np.ones(n, bool)}
    a = augment(w, np.random.default_rng(0), hist_noise=0.0)
    mirrored = np.zeros(n, bool)
    for i in range(n):
        d = a["hist"][i, -1] - a["hist"][i, 0]
        turn = _cross(d, a["fut"][i, -1] - a["fut"][i, 5])
        r, c = np.nonzero(a["map"][i] > 0.5)
        cells = np.stack([u[c], u[r]], -1)
        assert np.sign(_cross(d, cells.mean(0))) == -np.sign(turn)  # wall on the outside of the turn
        scale = np.linalg.norm(a["hist"][i, 0]) / np.linalg.norm(hist[i, 0])
        clearance = np.abs(cells @ np.array([-d[1], d[0]]) / np.linalg.norm(d)).min()
        assert abs(clearance - scale * 1.0) < 0.3  # the wall as far from the path as the path is scaled
        mirrored[i] = _cross(d, a["fut"][i, -1]) > 0
    assert 0.3 < mirrored.mean() < 0.7  # both mirrored and plain windows were checked
    # Without a map the augmentation draws the same random numbers as before (same trajectories).
    b = augment({k_: v for k_, v in w.items() if k_ not in ("map", "has_map")}, np.random.default_rng(0), hist_noise=0.0)
    np.testing.assert_array_equal(a["fut"], b["fut"])
    assert "map" not in b


def test_with_map_lets_eth_windows_concatenate(windows):
    eth = {k: v[:3] for k, v in windows.items() if k not in ("map", "has_map")}
    eth["scene"] = np.full(3, "biwi_eth")
    with pytest.raises(ValueError, match="keys"):
        fdata.concat([eth, windows])
    both = fdata.concat([sd.with_map(eth, C), windows])
    assert both["map"].shape == (3 + fdata.batch_size(windows), C, C)
    assert not both["has_map"][:3].any() and both["has_map"][3:].all() and not both["map"][:3].any()
    with pytest.raises(ValueError, match="map of shape"):
        sd.with_map(windows, 16)


@pytest.fixture(scope="module")
def sim_file(tmp_path_factory):
    path = tmp_path_factory.mktemp("sim") / "sim.npz"
    info = sd.build_sim_dataset(path, scenes="l_corridor,t_junction", crowds="sfm", people=3, seconds=14.0,
                                map_cells=16, log=None)
    return path, info


def test_save_load_round_trip(sim_file):
    path, info = sim_file
    with np.load(path, allow_pickle=False) as z:  # arrays only
        assert "info_json" in z.files and z["map"].dtype == np.uint8
    w, meta = sd.load_sim_dataset(path)
    again = sd.simulate_windows("l_corridor,t_junction", "sfm", people=3, seconds=14.0, map_cells=16)
    assert set(w) == set(again)
    for key in again:
        np.testing.assert_array_equal(w[key], again[key], err_msg=key)  # deterministic and lossless
        assert w[key].dtype == again[key].dtype, key
    assert meta["windows"] == info["windows"] == fdata.batch_size(w) > 0
    assert meta["scenes"] == ["l_corridor", "t_junction"] and meta["crowds"] == ["sfm"]
    assert [r["scene"] for r in meta["runs"]] == meta["scenes"] and meta["map_cells"] == 16


@pytest.mark.skipif(not fdata.default_data_dir().is_dir(), reason="ETH/UCY data not available (the CLI trains on it too)")
def test_train_cli_with_sim_data(sim_file, tmp_path):
    from navzoo.cli import main

    path, info = sim_file
    out = tmp_path / "run"
    rc = main(["train", "diffusion", "--sim-data", str(path), "--map-cells", "16", "--steps", "3", "--batch-size", "16",
               "--sim-val-frac", "0.5", "--out", str(out), "--export", str(tmp_path / "model")])
    assert rc == 0
    meta = json.loads((out / "checkpoint/meta.json").read_text())
    assert meta["model_config"]["map_cells"] == 16
    sim = meta["data"]["sim_data"]
    assert sim["held_out_scenes"] == ["l_corridor"] and sim["crowds"] == ["sfm"] and sim["seconds"] == 14.0
    assert sum(sim["train_windows"].values()) + sum(sim["val_windows"].values()) == info["windows"]
    assert meta["windows"] == sum(meta["data"]["train_windows"].values()) + sum(sim["train_windows"].values())
    rows = [json.loads(x) for x in (out / "metrics.jsonl").read_text().splitlines()]
    assert np.isfinite(rows[-1]["val_loss"]) and np.isfinite(rows[-1]["val_loss_sim"])
    card = json.loads((tmp_path / "model/config.json").read_text())
    assert card["data"]["sim_data"]["path"] == str(path)
    from navzoo.agents.diffusion.trainer import load_model

    assert load_model(tmp_path / "model").cfg.map_cells == 16
    from navzoo.agents.diffusion.train import load_sim_data

    with pytest.raises(ValueError, match="--map-cells 16"):  # the CLI reports it as an error, exit code 2
        load_sim_data(str(path), 32)
    tr, va, desc = load_sim_data(str(path), 0, val_frac=0.0)  # no map input: maps dropped, nothing held out
    assert "map" not in tr and va is None and desc["held_out_scenes"] == []


def test_parallel_build_is_identical(sim_file, tmp_path):
    path, info = sim_file
    par = tmp_path / "parallel.npz"
    info2 = sd.build_sim_dataset(par, scenes="l_corridor,t_junction", crowds="sfm", people=3, seconds=14.0,
                                 map_cells=16, log=None, workers=2)
    assert [r["scene"] for r in info2["runs"]] == [r["scene"] for r in info["runs"]] == ["l_corridor", "t_junction"]
    a, _ = sd.load_sim_dataset(path)
    b, _ = sd.load_sim_dataset(par)
    for key in a:
        np.testing.assert_array_equal(a[key], b[key], err_msg=key)
