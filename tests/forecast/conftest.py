"""Shared helpers of the forecast tests: tiny synthetic ETH/UCY-format files."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from navzoo.forecast.data import default_data_dir


def write_tracks(path: Path, rows: list[tuple[float, float, float, float]]) -> Path:
    """Write ``frame ped x y`` rows, tab-separated, floats written as the shared files do."""
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text("".join(f"{f:.1f}\t{p:.1f}\t{x}\t{y}\n" for f, p, x, y in rows))
    return path


def straight_rows(ped: int, start: tuple[float, float], step: tuple[float, float], n: int,
                  frame0: int = 0) -> list[tuple[float, float, float, float]]:
    """A pedestrian walking ``step`` metres per row for ``n`` rows from ``start``."""
    return [(frame0 + 10 * i, ped, start[0] + i * step[0], start[1] + i * step[1]) for i in range(n)]


@pytest.fixture
def eth_ucy() -> Path:
    """The shared ETH/UCY folder (the tests check real numbers from it); skipped where the checkout
    has no ``../shared`` (as the motion-library tests), so a clone elsewhere still runs the rest."""
    root = default_data_dir()
    if not (root / "all_data" / "biwi_eth.txt").is_file():
        pytest.skip(f"../shared/data/trajectories/eth_ucy not available at {root}")
    return root


@pytest.fixture
def tiny_dir(tmp_path: Path) -> Path:
    """A flat folder in the eth_ucy layout with two small scenes of straight walkers."""
    rng = np.random.default_rng(0)
    for scene in ("alpha", "beta"):
        rows = []
        for ped in range(1, 5):
            start = tuple(rng.uniform(0, 8, size=2))
            rows += straight_rows(ped, start, (0.5, 0.1 * ped), 26, frame0=10 * ped)
        write_tracks(tmp_path / "all_data" / f"{scene}.txt", rows)
        write_tracks(tmp_path / "train" / f"{scene}_train.txt", rows)
        write_tracks(tmp_path / "val" / f"{scene}_val.txt", rows)
    return tmp_path
