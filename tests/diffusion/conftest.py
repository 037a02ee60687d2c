"""Keep torch to one thread per test process (pytest -n 2 on two cores)."""

import torch

torch.set_num_threads(1)
