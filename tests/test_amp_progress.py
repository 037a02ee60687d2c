"""Target progress of physics pedestrians on diffusion plans: the target waits for a blocked body."""

from __future__ import annotations

import numpy as np

from navzoo.envs.amp_humans import progress_index


def _line(n: int = 100, speed: float = 1.0, hz: float = 30.0) -> np.ndarray:
    x = np.arange(n) * speed / hz
    return np.stack([x, np.zeros(n)], axis=1)[None]


def test_a_following_body_keeps_the_time_index():
    paths = _line()
    k = np.zeros(1, dtype=int)
    for t in range(1, 60):
        k = progress_index(k, np.array([t]), paths, paths[:, t], lag=9)
        assert k[0] == t


def test_a_blocked_body_holds_its_target_close_and_resumes():
    paths = _line()
    k = np.zeros(1, dtype=int)
    stuck = paths[:, 5]
    for t in range(1, 60):
        k = progress_index(k, np.array([t]), paths, stuck, lag=9)
    assert k[0] == 5 + 9                       # at most 0.3 s ahead of the body's projection
    # Freed, the body walks again: the target advances one step per step, never past the time index.
    for t in range(60, 70):
        k_before = k[0]
        k = progress_index(k, np.array([t]), paths, paths[:, k_before - 3], lag=9)
        assert k[0] == k_before + 1 and k[0] <= t


def test_the_search_does_not_look_past_the_time_index():
    """A path that loops back near the body later in time does not pull the index forward."""
    x = np.concatenate([np.linspace(0, 2, 50), np.linspace(2, 0, 50)])
    paths = np.stack([x, np.zeros(100)], axis=1)[None]
    k = progress_index(np.array([9]), np.array([10]), paths, np.array([[0.0, 0.0]]), lag=3)
    assert k[0] == 3
