"""FIFO replay buffer of past policy discriminator inputs (AMP's guard against forgetting).

A ring buffer of ``capacity`` rows. Once it has been filled, each new row is kept with probability
``keep_prob`` (IsaacGymEnvs ``amp_replay_keep_prob``), so the buffer spans a long history of policies;
rows that are kept overwrite the oldest. All randomness comes from the caller's ``numpy`` generator,
so sampling is reproducible and independent of the device.
"""

from __future__ import annotations

import numpy as np
import torch


class ReplayBuffer:
    """Ring buffer of float32 rows on ``device``.

    Args:
        capacity: maximum number of rows.
        dim: row width.
        device: where the rows live (the discriminator's device).
        keep_prob: probability of keeping an incoming row once ``total_seen >= capacity``.
    """

    def __init__(self, capacity: int, dim: int, device: torch.device | str = "cpu", keep_prob: float = 1.0):
        if capacity <= 0 or dim <= 0:
            raise ValueError(f"capacity and dim must be positive, got capacity={capacity}, dim={dim}")
        if not 0.0 < keep_prob <= 1.0:
            raise ValueError(f"keep_prob must be in (0, 1], got {keep_prob}")
        self.capacity = int(capacity)
        self.dim = int(dim)
        self.keep_prob = float(keep_prob)
        self.device = torch.device(device)
        self._data = torch.zeros((self.capacity, self.dim), dtype=torch.float32, device=self.device)
        self._head = 0  # next row to write
        self._size = 0
        self.total_seen = 0

    def __len__(self) -> int:
        return self._size

    def push(self, rows: torch.Tensor | np.ndarray, rng: np.random.Generator | None = None) -> int:
        """Append rows (FIFO); returns how many were stored.

        ``rng`` is needed only when ``keep_prob < 1`` (to draw which rows to keep once full).
        Non-finite rows are dropped: a NaN in the buffer would poison every later discriminator step.
        """
        rows = torch.as_tensor(rows, dtype=torch.float32).to(self.device).reshape(-1, self.dim)
        n_in = rows.shape[0]
        rows = rows[torch.isfinite(rows).all(dim=1)]
        if self.keep_prob < 1.0 and self.total_seen >= self.capacity:
            if rng is None:
                raise ValueError("ReplayBuffer.push: keep_prob < 1 needs an rng")
            keep = torch.from_numpy(rng.random(rows.shape[0]) < self.keep_prob).to(self.device)
            rows = rows[keep]
        self.total_seen += n_in
        if rows.shape[0] > self.capacity:
            rows = rows[-self.capacity :]
        n = rows.shape[0]
        first = min(n, self.capacity - self._head)
        self._data[self._head : self._head + first] = rows[:first]
        if n > first:
            self._data[: n - first] = rows[first:]
        self._head = (self._head + n) % self.capacity
        self._size = min(self._size + n, self.capacity)
        return n

    def sample(self, n: int, rng: np.random.Generator) -> torch.Tensor:
        """``n`` rows drawn uniformly with replacement. Raises ``RuntimeError`` when empty."""
        if self._size == 0:
            raise RuntimeError("ReplayBuffer.sample: the buffer is empty")
        idx = torch.from_numpy(rng.integers(0, self._size, size=n)).to(self.device)
        return self._data[idx]

    def chronological(self) -> torch.Tensor:
        """All stored rows, oldest first."""
        if self._size < self.capacity:
            return self._data[: self._size]
        return torch.cat([self._data[self._head :], self._data[: self._head]])

    def state_dict(self, max_rows: int | None = None, seed: int = 0) -> dict[str, torch.Tensor]:
        """Tensors that restore the buffer.

        With ``max_rows`` at least the stored size, the raw ring is saved and :meth:`load_state_dict`
        restores it exactly (same sampling afterwards). Otherwise a uniform random subset of
        ``max_rows`` rows (chosen with ``seed``, kept in chronological order) is saved: a *sample* of
        the buffer, enough to keep the discriminator honest after a resume.
        """
        meta = torch.tensor([self._head, self._size, self.total_seen], dtype=torch.int64)
        if max_rows is None or self._size <= max_rows:
            return {"data": self._data[: self._size].cpu().clone(), "meta": meta}
        keep = np.sort(np.random.default_rng(seed).choice(self._size, size=max_rows, replace=False))
        rows = self.chronological()[torch.from_numpy(keep).to(self.device)].cpu().clone()
        meta = torch.tensor([max_rows % self.capacity, max_rows, self.total_seen], dtype=torch.int64)
        return {"data": rows, "meta": meta}

    def load_state_dict(self, state: dict[str, torch.Tensor]) -> None:
        data, meta = state["data"], state["meta"]
        head, size, total = (int(v) for v in meta.tolist())
        if data.ndim != 2 or data.shape[1] != self.dim or data.shape[0] != size or size > self.capacity:
            raise ValueError(
                f"replay state of shape {tuple(data.shape)} (size {size}) does not fit a buffer of "
                f"capacity {self.capacity} and dim {self.dim}"
            )
        self._data.zero_()
        self._data[:size] = data.to(self.device, torch.float32)
        self._head, self._size, self.total_seen = head % self.capacity, size, total
