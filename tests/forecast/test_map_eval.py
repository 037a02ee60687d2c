"""Obstacle scoring of forecasts on agent-frame occupancy crops (navzoo.forecast.map_eval)."""

import numpy as np
import pytest

from navzoo.forecast.map_eval import _parse_models, obstacle_hits, score_on_map


def _crop_with_wall_ahead(c=32, extent=8.0, x_wall=2.0):
    """A crop whose cells with centre x >= x_wall (ahead of the person) are occupied."""
    occ = np.zeros((c, c), np.float32)
    xs = (np.arange(c) + 0.5 - c / 2) * extent / c
    occ[:, xs >= x_wall] = 1.0
    return occ


def test_obstacle_hits_cell_geometry():
    occ = _crop_with_wall_ahead()[None]
    pts = np.array([[[0.0, 0.0], [1.9, 0.0], [2.1, 0.0], [2.1, -3.9], [5.0, 0.0], [-4.1, 0.0]]])
    hit, inside = obstacle_hits(pts, occ)
    # 1.9 m lies in the cell [1.75, 2.0) (centre 1.875, free); 2.1 m in [2.0, 2.25) (occupied)
    assert hit.tolist() == [[False, False, True, True, False, False]]
    assert inside.tolist() == [[True, True, True, True, False, False]]  # 5 m and -4.1 m are beyond the 8 m crop


def test_obstacle_hits_rows_are_y():
    occ = np.zeros((1, 32, 32), np.float32)
    occ[0, 20, 16] = 1.0  # row 20 covers y in [1.0, 1.25), column 16 covers x in [0, 0.25)
    hit, _ = obstacle_hits(np.array([[[0.1, 1.1], [1.1, 0.1]]]), occ)
    assert hit.tolist() == [[True, False]]


def test_score_on_map_counts_samples_and_windows():
    occ = np.stack([_crop_with_wall_ahead(), np.zeros((32, 32), np.float32)])
    t = np.arange(1, 13) * 0.4 + 0.05  # off the cell borders
    fut = np.stack([np.c_[t * 0.3, 0 * t], np.c_[t, 0 * t]])  # window 0 stops short of the wall
    pred = np.repeat(fut[:, None], 2, axis=1).copy()
    pred[0, 1, :, 0] = t  # one sample of window 0 walks into the wall (x >= 2 m)
    r = score_on_map(pred, {"fut": fut, "map": occ})
    assert r["min_ade_m"] == pytest.approx(0.0) and r["min_fde_m"] == pytest.approx(0.0)
    n_crop = int(np.sum(t < 4.0))  # points beyond 4 m ahead leave the 8 m crop
    in_wall = int(np.sum((t >= 2.0) & (t < 4.0)))
    inside = 12 + n_crop + 2 * n_crop  # window 0: the slow sample and the fast one; window 1: two fast samples
    assert r["obstacle_rate"] == pytest.approx(in_wall / inside)
    assert r["windows_in_obstacle"] == pytest.approx(0.5)


def test_parse_models():
    assert _parse_models("shipped,map=runs/x") == {"shipped": None, "map": "runs/x"}
    with pytest.raises(ValueError, match="NAME=DIR"):
        _parse_models("mymodel")
