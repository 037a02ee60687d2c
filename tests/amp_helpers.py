"""Helpers shared by the AMP tests."""

from __future__ import annotations

from typing import Any

import numpy as np


class FixedTimes:
    """A reference motion library whose ``sample_times`` always returns the given clips and times, so that
    reference windows can be compared with bodies played back at the same clip times."""

    def __init__(self, lib: Any, clips: np.ndarray, times: np.ndarray) -> None:
        self.lib, self.clips, self.times = lib, clips, times

    def sample_times(self, rng: np.random.Generator, n: int) -> tuple[np.ndarray, np.ndarray]:
        return self.clips, self.times

    def __getattr__(self, name: str) -> Any:
        return getattr(self.lib, name)


def peak_target_pace(env: Any, monkeypatch: Any, constant: str, values: tuple[float, ...]) -> dict[float, np.ndarray]:
    """Per person, the fastest pace (m/s) of the physics pedestrians' target paths replanned now with the
    ``navzoo.envs.amp_humans`` constant ``constant`` set to each of ``values``."""
    from navzoo.envs import amp_humans

    peak = {}
    for value in values:
        monkeypatch.setattr(amp_humans, constant, value)
        env.amp.plan_all()
        pace = np.linalg.norm(np.diff(env.amp.paths, axis=1), axis=2) * amp_humans.CONTROL_HZ
        peak[value] = pace.max(axis=1)
    return peak


def threads_seen(monkeypatch: Any, module: Any, name: str, call: Any) -> tuple[list[int], int]:
    """Run ``call()`` from a caller with two torch threads, with ``module.name`` wrapped to record the thread
    count it runs under: (the counts seen, one per call of it; the caller's count afterwards)."""
    import torch

    seen: list[int] = []
    real = getattr(module, name)
    monkeypatch.setattr(module, name, lambda *a, **k: seen.append(torch.get_num_threads()) or real(*a, **k))
    before = torch.get_num_threads()
    torch.set_num_threads(2)
    try:
        call()
        return seen, torch.get_num_threads()
    finally:
        torch.set_num_threads(before)
