"""Run a block on one torch thread and give the caller's setting back.

Closed-loop evaluations sum floats in the policy's (and the diffusion model's) forward passes; with another
thread count those sums round differently, and a rollout that runs long enough walks other trips or tracks
other clips. The protocols therefore run on one thread whoever calls them (a pool worker, a 2-core VM's main
process, a 16-core device), so that one kind of CPU repeats its figures.
"""

from __future__ import annotations

from collections.abc import Iterator
from contextlib import contextmanager


@contextmanager
def one_torch_thread() -> Iterator[None]:
    import torch

    threads = torch.get_num_threads()
    torch.set_num_threads(1)
    try:
        yield
    finally:
        torch.set_num_threads(threads)
