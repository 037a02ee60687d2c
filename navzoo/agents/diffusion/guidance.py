"""Test-time guidance costs for :meth:`TrajectoryDiffusion.sample` (TRACE's "clean" guidance).

Each factory returns ``cost(pos, index) -> (N,)`` where ``pos`` is ``(N, H, 2)`` sampled future
positions in the agent frame and ``index`` (N,) maps every sample to its person in the batch (a
person has S samples). Costs are differentiable in ``pos``; the sampler moves its x0 estimate down
their gradient. :func:`combine` adds several.
"""

from __future__ import annotations

from collections.abc import Callable

import torch
from torch import Tensor
from torch.nn import functional as F

Cost = Callable[[Tensor, Tensor], Tensor]

__all__ = ["Cost", "agent_collision_cost", "combine", "map_collision_cost", "path_cost", "smoothness_cost", "target_cost"]


def target_cost(target: Tensor, weight: float = 1.0, step: int = -1, valid: Tensor | None = None) -> Cost:
    """Squared distance (m²) of the position at ``step`` to each person's ``target (B, 2)`` (agent
    frame); people with ``valid`` False (B,) get no pull."""

    def cost(pos: Tensor, index: Tensor) -> Tensor:
        d2 = ((pos[:, step] - target[index]) ** 2).sum(-1)
        if valid is not None:
            d2 = d2 * valid[index].float()
        return weight * d2

    return cost


def path_cost(points: Tensor, weight: float = 1.0, valid: Tensor | None = None) -> Cost:
    """Mean squared distance (m²) of every step's position to the matching point of a reference path
    ``points (B, H, 2)`` (agent frame): keeps the whole plan near the A* path (which goes around
    walls) instead of only its end point; people with ``valid`` False (B,) get no pull."""

    def cost(pos: Tensor, index: Tensor) -> Tensor:
        d2 = ((pos - points[index]) ** 2).sum(-1).mean(-1)
        if valid is not None:
            d2 = d2 * valid[index].float()
        return weight * d2

    return cost


def smoothness_cost(start: Tensor, weight: float = 1.0) -> Cost:
    """Sum over steps of the squared second difference of positions (m²), the plan's acceleration
    times dt², starting from each person's last two history points ``start (B, 2, 2)`` (agent frame,
    older first), so that the plan also continues the person's current velocity."""

    def cost(pos: Tensor, index: Tensor) -> Tensor:
        p = torch.cat([start[index].to(pos.dtype), pos], dim=1)  # (N, 2 + H, 2)
        acc = p[:, 2:] - 2.0 * p[:, 1:-1] + p[:, :-2]
        return weight * (acc ** 2).sum(dim=(1, 2))

    return cost


def agent_collision_cost(others: Tensor, mask: Tensor, radius: float = 0.6, buffer: float = 0.2,
                         weight: float = 10.0) -> Cost:
    """Penetration of discs: sum over steps and others of ``relu(radius + buffer - d)²``.

    Args:
        others: (B, M, H, 2) other people's future positions in each person's agent frame.
        mask: (B, M) which others exist.
        radius: sum of the two radii (m); ``buffer`` is extra clearance (TRACE: 0.2 m).
    """

    def cost(pos: Tensor, index: Tensor) -> Tensor:
        o = others[index]  # (N, M, H, 2)
        d = (pos[:, None] - o).norm(dim=-1)  # (N, M, H)
        pen = F.relu(radius + buffer - d) ** 2 * mask[index].float()[..., None]
        return weight * pen.sum(dim=(1, 2))

    return cost


def map_collision_cost(distance: Tensor, extent: float, radius: float = 0.3, buffer: float = 0.1,
                       weight: float = 10.0) -> Cost:
    """Penetration of walls from a local distance field.

    Args:
        distance: (B, C, C) distance to the nearest obstacle (m) on a square crop of side ``extent``
            metres centred on each person, in the agent frame (row = y, column = x, increasing).
        radius, buffer: the body's radius and the clearance kept (m).
    """
    half = extent / 2.0

    def cost(pos: Tensor, index: Tensor) -> Tensor:
        grid = (pos / half).unsqueeze(1)  # (N, 1, H, 2), x -> columns, y -> rows, in [-1, 1]
        field = distance[index].unsqueeze(1)  # (N, 1, C, C)
        d = F.grid_sample(field, grid, mode="bilinear", padding_mode="border", align_corners=False)[:, 0, 0]
        return weight * (F.relu(radius + buffer - d) ** 2).sum(-1)

    return cost


def combine(*costs: Cost | None) -> Cost | None:
    """The sum of the given costs (None entries skipped); None when there are none."""
    live = [c for c in costs if c is not None]
    if not live:
        return None

    def cost(pos: Tensor, index: Tensor) -> Tensor:
        return torch.stack([c(pos, index) for c in live]).sum(0)

    return cost
