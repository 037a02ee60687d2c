"""navzoo: PettingZoo multi-agent environments for human-aware robot navigation on PyBullet."""

from __future__ import annotations

__version__ = "0.1.0"

import navzoo.sim  # noqa: E402,F401  (imports pybullet quietly, before anything else does)
from navzoo.envs.config import NavConfig  # noqa: E402
from navzoo.envs.registry import SCENARIOS, make, make_raw, register_all  # noqa: E402

register_all()

__all__ = ["NavConfig", "SCENARIOS", "make", "make_raw", "__version__"]
