"""TRACE-style trajectory diffusion for data-driven crowds (see docs/crowd.md)."""

from navzoo.agents.diffusion.model import DiffusionConfig, TrajectoryDiffusion, integrate

__all__ = ["DiffusionConfig", "TrajectoryDiffusion", "integrate"]
