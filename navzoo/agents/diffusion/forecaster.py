"""The diffusion model as a :class:`navzoo.forecast.baselines.Forecaster` (for ``navzoo eval forecast``)."""

from __future__ import annotations

import os
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np
import torch

from navzoo.agents.diffusion.model import TrajectoryDiffusion

__all__ = ["DiffusionForecaster", "MODEL_ENV"]

MODEL_ENV = "NAVZOO_DIFFUSION_MODEL"  # model directory used by `navzoo eval forecast` (default: shipped)


class DiffusionForecaster:
    """Samples ``n_samples`` futures per window (no guidance: the data gives no goals).

    A model with a map input uses the batch's ``map`` / ``has_map`` (agent-frame occupancy crops of
    :mod:`navzoo.forecast.sim_data`) where the batch has them, its "no map" embedding otherwise.

    Args:
        model: a model or an exported model directory; None = ``$NAVZOO_DIFFUSION_MODEL`` or the
            shipped ``policies/trajectory_diffusion``.
        seed: seed of the sampling noise.
        batch: windows per forward pass.
    """

    def __init__(self, model: TrajectoryDiffusion | str | Path | None = None, seed: int = 0, batch: int = 1024,
                 device: str = "cpu") -> None:
        if not isinstance(model, TrajectoryDiffusion):
            from navzoo.agents.diffusion.crowd import default_model_dir
            from navzoo.agents.diffusion.trainer import load_model

            folder = Path(model or os.environ.get(MODEL_ENV) or default_model_dir())
            if not (folder / "model.pt").is_file():
                raise FileNotFoundError(f"no trajectory diffusion model in {folder}; train one with "
                                        f"`navzoo train diffusion --export DIR` or set ${MODEL_ENV}")
            model = load_model(folder, device)
        self.model = model.eval()
        self.seed = int(seed)
        self.batch = int(batch)
        self.device = device

    def predict(self, batch: Mapping[str, Any], n_samples: int) -> np.ndarray:
        """Future positions (N, n_samples, 12, 2) in the batch's (agent-centric) frame."""
        if n_samples < 1:
            raise ValueError(f"n_samples must be >= 1, got {n_samples!r}")
        hist = np.asarray(batch["hist"], dtype=np.float64)
        n = hist.shape[0]
        keys = [k for k in ("hist", "neigh", "neigh_mask", "dt") if k in batch]
        # Occupancy crops are always in the window's agent frame (navzoo.forecast.sim_data), so they pass
        # through the normalisation unchanged; models without a map input ignore them.
        maps = [k for k in ("map", "has_map") if k in batch] if self.model.cfg.map_cells else []
        g = torch.Generator(device="cpu").manual_seed(self.seed)
        out = []
        # The model works in agent-centric frames: move each window's history so that its last point
        # is the origin and its heading +x (a no-op for normalised batches), then map back.
        from navzoo.forecast import data as fdata

        local = fdata.normalize({**{k: batch[k] for k in keys}, "origin": np.zeros((n, 2)),
                                 "rot": np.repeat(np.eye(2)[None], n, axis=0)})
        for i in range(0, n, self.batch):
            sl = slice(i, i + self.batch)
            src = {**{k: local[k] for k in keys}, **{k: batch[k] for k in maps}}
            t = {k: torch.as_tensor(np.asarray(v)[sl], dtype=torch.bool if k in ("neigh_mask", "has_map") else torch.float32,
                                    device=self.device) for k, v in src.items()}
            with torch.no_grad():
                out.append(self.model.sample(t, n_samples, generator=g).cpu().numpy().astype(np.float64))
        pred = np.concatenate(out) if out else np.zeros((0, n_samples, self.model.cfg.horizon, 2))
        return fdata.to_world(pred, local)
