"""navzoo: PettingZoo multi-agent environments for human-aware robot navigation on PyBullet."""

from __future__ import annotations

__version__ = "0.1.0"
