"""Diffusion plans replaced by straight lines, for tests of the physics pedestrians' target rollouts."""

from __future__ import annotations

import numpy as np


def straight_plans(monkeypatch, crowd, start: np.ndarray, velocity: np.ndarray) -> None:
    """From now on, every plan of ``crowd`` (a :class:`~navzoo.agents.diffusion.crowd.DiffusionCrowd`) runs in a
    straight line from ``start`` (n, 2) at ``velocity`` (n, 2) m/s, however often it replans."""
    times = np.arange(crowd.plan.shape[1]) * 0.4

    def plan_now(env, who=None):
        crowd.plan = start[:, None] + times[None, :, None] * velocity[:, None]
        crowd.plan_t0 = np.full(len(start), env.sim_time)
        return crowd.plan

    monkeypatch.setattr(crowd, "plan_now", plan_now)
