"""What a measurement ran on: the CPU's model name.

Runs with physics pedestrians or a diffusion crowd repeat trip for trip only on one kind of CPU (floating-point
results differ between CPU kinds), so result files record the CPU model next to their numbers. This module has no
heavy imports, so the training, study and benchmark code can all use it.
"""

from __future__ import annotations

import contextlib
import platform


def cpu_model() -> str:
    """The CPU's model name (``/proc/cpuinfo``; the platform's processor or machine elsewhere)."""
    cpu = platform.processor() or platform.machine()
    with contextlib.suppress(OSError):
        with open("/proc/cpuinfo", encoding="utf-8") as f:
            for line in f:
                if line.startswith("model name"):
                    return line.split(":", 1)[1].strip()
    return cpu
