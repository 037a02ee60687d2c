"""Helpers shared by the AMP discriminator-input tests."""

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
