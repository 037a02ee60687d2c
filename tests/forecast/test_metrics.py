"""Displacement errors, realism distances and collision rate on cases with known answers."""

from __future__ import annotations

import numpy as np
import pytest

from navzoo.forecast.metrics import (
    ade,
    collision_rate,
    displacement_errors,
    fde,
    kinematics,
    min_ade,
    min_fde,
    realism_distances,
)


def test_min_ade_min_fde_hand_made() -> None:
    fut = np.zeros((2, 3, 2))
    fut[:, :, 0] = [1.0, 2.0, 3.0]
    pred = np.repeat(fut[:, None], 2, axis=1).copy()
    pred[0, 0, :, 1] += [3.0, 3.0, 0.0]   # ADE 2, FDE 0
    pred[0, 1, :, 1] += [0.0, 0.0, 1.5]   # ADE 0.5, FDE 1.5
    pred[1, 0, :, 1] += 1.0               # ADE 1, FDE 1
    pred[1, 1, :, 0] += 2.0               # ADE 2, FDE 2
    np.testing.assert_allclose(ade(pred, fut), [[2.0, 0.5], [1.0, 2.0]])
    np.testing.assert_allclose(fde(pred, fut), [[0.0, 1.5], [1.0, 2.0]])
    np.testing.assert_allclose(min_ade(pred, fut), [0.5, 1.0])   # best samples chosen separately
    np.testing.assert_allclose(min_fde(pred, fut), [0.0, 1.0])
    np.testing.assert_allclose(min_ade(pred[:, 0], fut), [2.0, 1.0])  # one sample = plain ADE


def test_displacement_errors_reject_mismatch() -> None:
    with pytest.raises(ValueError, match="does not match"):
        displacement_errors(np.zeros((2, 4, 12, 2)), np.zeros((2, 11, 2)))
    with pytest.raises(ValueError, match="NaN"):
        displacement_errors(np.full((1, 12, 2), np.nan), np.zeros((1, 12, 2)))


def test_kinematics_use_each_trajectorys_dt() -> None:
    t = np.arange(6, dtype=float)
    line = np.stack([t, 0 * t], axis=1)            # 1 m per step
    accel = np.stack([0.5 * t**2, 0 * t], axis=1)  # second difference 1 m per step^2
    k = kinematics([line, accel], [0.5, 0.667])
    np.testing.assert_allclose(k["speed"][:5], 2.0)
    np.testing.assert_allclose(k["accel"][:4], 0.0, atol=1e-12)
    np.testing.assert_allclose(k["accel"][4:], 1 / 0.667**2)
    np.testing.assert_allclose(k["jerk"][3:], 0.0, atol=1e-9)
    assert k["speed"].size == 10 and k["jerk"].size == 6


def test_emd_zero_for_identical_sets_and_shift_for_faster_walkers() -> None:
    rng = np.random.default_rng(0)
    real = np.cumsum(rng.normal(0.5, 0.1, size=(30, 15, 2)), axis=1)
    same = realism_distances(real, 0.4, list(real), np.full(30, 0.4))
    assert same == {"speed_emd": 0.0, "accel_emd": 0.0, "jerk_emd": 0.0}
    t = np.arange(10, dtype=float)[:, None]
    slow = [np.hstack([1.0 * t * 0.4, 0 * t])]
    fast = [np.hstack([1.5 * t * 0.4, 0 * t])]
    d = realism_distances(fast, 0.4, slow, 0.4)
    assert d["speed_emd"] == pytest.approx(0.5)
    assert d["accel_emd"] == pytest.approx(0.0, abs=1e-9)
    with pytest.raises(ValueError, match="at least 4 points"):
        realism_distances([np.zeros((3, 2))], 0.4, slow, 0.4)


def test_collision_rate() -> None:
    pos = np.zeros((3, 4, 2))
    pos[:, :, 0] = [0.0, 5.0, 10.0, 20.0]
    pos[1, 1, 0] = 10.3          # agent 1 touches agent 2 at step 1 (0.3 m < 2 * 0.2 m)
    assert collision_rate(pos, radius=0.2) == pytest.approx(0.5)
    assert collision_rate(pos, radius=0.1) == pytest.approx(0.0)
    valid = np.ones((3, 4), bool)
    valid[1, 2] = False          # agent 2 is absent at that step
    assert collision_rate(pos, radius=0.2, valid=valid) == pytest.approx(0.0)
    with pytest.raises(ValueError, match="positions"):
        collision_rate(np.zeros((3, 2)))
