"""What a measurement ran on: the CPU's model name and the versions of the packages that compute its floats.

Runs with physics pedestrians or a diffusion crowd repeat trip for trip only where the floating-point results are
the same. Two installations of the same navzoo on the same VM drew other trips (docs/pedestrians_log.md, "The
protocol's noise"), and CPU kinds may differ too. So result files record the CPU model and the numeric packages'
versions next to their numbers. This module has no heavy imports, so the training, study and benchmark code can
all use it.
"""

from __future__ import annotations

import contextlib
import platform
from importlib import metadata


def cpu_model() -> str:
    """The CPU's model name (``/proc/cpuinfo``; the platform's processor or machine elsewhere)."""
    cpu = platform.processor() or platform.machine()
    with contextlib.suppress(OSError):
        with open("/proc/cpuinfo", encoding="utf-8") as f:
            for line in f:
                if line.startswith("model name"):
                    return line.split(":", 1)[1].strip()
    return cpu


NUMERIC_PACKAGES = ("numpy", "scipy", "torch", "pybullet")


def package_versions(names: tuple[str, ...] = NUMERIC_PACKAGES) -> dict[str, str]:
    """Python's version and each named package's installed version (``"absent"`` where it is not installed), read
    from the installed distributions without importing the packages."""
    out = {"python": platform.python_version()}
    for name in names:
        try:
            out[name] = metadata.version(name)
        except metadata.PackageNotFoundError:
            out[name] = "absent"
    return out
