"""Running mean / variance of a feature vector, merged batch by batch (Chan et al.'s parallel rule).

Statistics are float64 buffers of an ``nn.Module`` so that they travel with ``state_dict`` and
``.to(device)``; normalised outputs are float32. The variance is the population variance (``ddof=0``),
as ``numpy.var``.
"""

from __future__ import annotations

import numpy as np
import torch
from torch import nn


def merge_moments(
    mean_a: torch.Tensor,
    var_a: torch.Tensor,
    count_a: float,
    mean_b: torch.Tensor,
    var_b: torch.Tensor,
    count_b: float,
) -> tuple[torch.Tensor, torch.Tensor, float]:
    """Mean, population variance and count of the union of two sets given their own moments.

    Exact (up to rounding) for any split, including an empty side (count 0).
    """
    total = count_a + count_b
    if total == 0:
        return mean_a, var_a, 0.0
    delta = mean_b - mean_a
    mean = mean_a + delta * (count_b / total)
    m2 = var_a * count_a + var_b * count_b + delta.square() * (count_a * count_b / total)
    return mean, m2 / total, float(total)


class RunningMeanStd(nn.Module):
    """Running statistics of ``(N, dim)`` batches and the normalisation they define.

    ``normalize(x) = clip((x - mean) / sqrt(var + eps), -clip, clip)``. A constant feature (var 0)
    normalises to 0 instead of blowing up.

    Args:
        dim: feature dimension.
        eps: added to the variance before the square root.
        clip: clip of the normalised value (rl_games clips at 5); ``None`` = no clip.
    """

    mean: torch.Tensor
    var: torch.Tensor
    count: torch.Tensor

    def __init__(self, dim: int, eps: float = 1e-5, clip: float | None = 5.0) -> None:
        super().__init__()
        if dim <= 0:
            raise ValueError(f"dim must be positive, got {dim}")
        self.dim = int(dim)
        self.eps = float(eps)
        self.clip = None if clip is None else float(clip)
        self.register_buffer("mean", torch.zeros(dim, dtype=torch.float64))
        self.register_buffer("var", torch.ones(dim, dtype=torch.float64))
        self.register_buffer("count", torch.zeros((), dtype=torch.float64))

    @torch.no_grad()
    def update(self, x: torch.Tensor | np.ndarray) -> None:
        """Fold a batch ``(N, dim)`` into the statistics (non-finite rows are rejected)."""
        x = torch.as_tensor(x, device=self.mean.device).reshape(-1, self.dim).to(torch.float64)
        if x.shape[0] == 0:
            return
        if not torch.isfinite(x).all():
            bad = (~torch.isfinite(x)).any(dim=1).nonzero().flatten()[:5].tolist()
            raise ValueError(f"RunningMeanStd.update: non-finite values in rows {bad} (of {x.shape[0]})")
        b_mean = x.mean(dim=0)
        b_var = x.var(dim=0, unbiased=False)
        mean, var, count = merge_moments(self.mean, self.var, float(self.count), b_mean, b_var, x.shape[0])
        self.mean.copy_(mean)
        self.var.copy_(var)
        self.count.fill_(count)

    @property
    def std(self) -> torch.Tensor:
        return torch.sqrt(self.var + self.eps)

    def normalize(self, x: torch.Tensor) -> torch.Tensor:
        # float32 arithmetic: the statistics are kept in float64, the hot path need not be.
        y = (x.to(torch.float32) - self.mean.to(torch.float32)) / self.std.to(torch.float32)
        if self.clip is not None:
            y = y.clamp(-self.clip, self.clip)
        return y

    def denormalize(self, y: torch.Tensor) -> torch.Tensor:
        return y.to(torch.float32) * self.std.to(torch.float32) + self.mean.to(torch.float32)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        return self.normalize(x)

    def extra_repr(self) -> str:
        return f"dim={self.dim}, eps={self.eps}, clip={self.clip}"
