"""Constant-velocity and social-force forecasters."""

from __future__ import annotations

import numpy as np
import pytest

from navzoo.forecast import data as D
from navzoo.forecast.baselines import ConstantVelocity, Forecaster, SocialForceForecaster


def _straight_batch(n: int = 4, k: int = 2, dt: float = 0.4) -> dict:
    """Straight constant-speed walkers in varied directions and speeds, no neighbours (world frame)."""
    rng = np.random.default_rng(1)
    angle = rng.uniform(-np.pi, np.pi, n)
    speed = rng.uniform(0.5, 1.8, n)
    vel = speed[:, None] * np.stack([np.cos(angle), np.sin(angle)], axis=1)
    start = rng.uniform(-5, 5, (n, 2))
    t = np.arange(20) * dt
    track = start[:, None] + t[None, :, None] * vel[:, None]
    return {
        "hist": track[:, :8], "fut": track[:, 8:], "neigh": np.zeros((n, k, 8, 2)),
        "neigh_mask": np.zeros((n, k, 8), bool), "neigh_fut": np.zeros((n, k, 12, 2)),
        "neigh_fut_mask": np.zeros((n, k, 12), bool), "dt": np.full(n, dt), "origin": np.zeros((n, 2)),
        "rot": np.broadcast_to(np.eye(2), (n, 2, 2)).copy(),
    }


def test_constant_velocity_is_exact_on_straight_tracks() -> None:
    batch = _straight_batch()
    model = ConstantVelocity()
    assert isinstance(model, Forecaster)
    pred = model.predict(batch, 5)
    assert pred.shape == (4, 5, 12, 2)
    np.testing.assert_allclose(pred, np.repeat(batch["fut"][:, None], 5, axis=1), atol=1e-12)
    local = D.normalize(batch)
    np.testing.assert_allclose(model.predict(local, 1)[:, 0], local["fut"], atol=1e-12)


def test_constant_velocity_rejects_bad_input() -> None:
    with pytest.raises(ValueError, match="n_samples"):
        ConstantVelocity().predict(_straight_batch(), 0)
    with pytest.raises(ValueError, match="hist"):
        ConstantVelocity().predict({"hist": np.zeros((3, 1, 2))}, 1)


@pytest.mark.parametrize("dt", [0.4, 0.667])
def test_sfm_without_neighbours_walks_straight(dt: float) -> None:
    batch = D.normalize(_straight_batch(dt=dt))
    pred = SocialForceForecaster().predict(batch, 3)
    assert pred.shape == (4, 3, 12, 2)
    # Sample 0 is the unperturbed model: observed velocity == preferred velocity, nothing else acts.
    np.testing.assert_allclose(pred[:, 0], batch["fut"], atol=1e-9)
    # Perturbed samples stay straight lines from the person (constant preferred velocity).
    for s in (1, 2):
        d = pred[:, s, 1:] - pred[:, s, :-1]
        assert np.all(np.linalg.norm(d, axis=-1) > 0)
        assert not np.allclose(pred[:, s], pred[:, 0])


def test_sfm_samples_are_reproducible_and_neighbours_repel() -> None:
    batch = D.normalize(_straight_batch(n=1, k=1))
    a = SocialForceForecaster(seed=4).predict(batch, 6)
    np.testing.assert_array_equal(a, SocialForceForecaster(seed=4).predict(batch, 6))
    # A person standing 0.5 m ahead on the path: the walker is pushed aside / slowed.
    blocked = dict(batch)
    blocked["neigh"] = np.zeros((1, 1, 8, 2))
    blocked["neigh"][0, 0, :, 0] = 1.0
    blocked["neigh_mask"] = np.ones((1, 1, 8), bool)
    free = SocialForceForecaster().predict(batch, 1)[0, 0]
    pushed = SocialForceForecaster().predict(blocked, 1)[0, 0]
    assert np.abs(pushed - free).max() > 0.1
