"""Forecast accuracy and trajectory realism (``../shared/METRICS.md``, trajectory realism).

* Displacement errors (m): ADE is the mean over the H predicted steps of the Euclidean error,
  FDE the error at the last step. With S samples per window, minADE and minFDE take the best sample
  per window, each on its own (the sample with the smallest ADE need not have the smallest FDE), as
  in Social-GAN and TRACE; they are then averaged over windows.
* Realism: earth mover's (1-Wasserstein) distance between the distributions of speed,
  acceleration and jerk magnitudes of generated and real trajectories, from finite differences at
  each trajectory's own dt (0.667 s for ``biwi_eth``). The distance is computed on the samples
  themselves, i.e. the limit of histograms with arbitrarily fine bins, so no bin width is chosen.
* Collision rate of a multi-agent rollout: the share of agents whose disc (``radius``) overlaps
  another agent's disc at some step.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

__all__ = [
    "displacement_errors",
    "ade",
    "fde",
    "min_ade",
    "min_fde",
    "kinematics",
    "realism_distances",
    "collision_rate",
]


def displacement_errors(pred: np.ndarray, fut: np.ndarray) -> np.ndarray:
    """Per-step errors (m): ``pred`` (N, H, 2) or (N, S, H, 2) against ``fut`` (N, H, 2) -> (N, [S,] H).

    Raises:
        ValueError: On mismatching shapes or non-finite predictions.
    """
    pred = np.asarray(pred, dtype=np.float64)
    fut = np.asarray(fut, dtype=np.float64)
    if fut.ndim != 3 or fut.shape[2] != 2:
        raise ValueError(f"fut must have shape (N, H, 2), got {fut.shape}")
    if pred.ndim == 3:
        if pred.shape != fut.shape:
            raise ValueError(f"pred {pred.shape} does not match fut {fut.shape}")
        target = fut
    elif pred.ndim == 4:
        if pred.shape[0] != fut.shape[0] or pred.shape[2:] != fut.shape[1:]:
            raise ValueError(f"pred {pred.shape} does not match fut {fut.shape} (expected (N, S, H, 2))")
        target = fut[:, None]
    else:
        raise ValueError(f"pred must have shape (N, H, 2) or (N, S, H, 2), got {pred.shape}")
    if not np.all(np.isfinite(pred)):
        raise ValueError("pred contains NaN or inf")
    return np.linalg.norm(pred - target, axis=-1)


def ade(pred: np.ndarray, fut: np.ndarray) -> np.ndarray:
    """Average displacement error per window (and sample): (N,) or (N, S)."""
    return displacement_errors(pred, fut).mean(axis=-1)


def fde(pred: np.ndarray, fut: np.ndarray) -> np.ndarray:
    """Final displacement error per window (and sample): (N,) or (N, S)."""
    return displacement_errors(pred, fut)[..., -1]


def _samples(pred: np.ndarray) -> np.ndarray:
    pred = np.asarray(pred)
    return pred[:, None] if pred.ndim == 3 else pred


def min_ade(pred: np.ndarray, fut: np.ndarray) -> np.ndarray:
    """Best-of-S ADE per window, (N,); ``pred`` (N, S, H, 2) (a single (N, H, 2) prediction is S = 1)."""
    return ade(_samples(pred), fut).min(axis=1)


def min_fde(pred: np.ndarray, fut: np.ndarray) -> np.ndarray:
    """Best-of-S FDE per window, (N,)."""
    return fde(_samples(pred), fut).min(axis=1)


def _as_tracks(trajs: np.ndarray | Sequence[np.ndarray], dt: float | Sequence[float] | np.ndarray
               ) -> tuple[list[np.ndarray], np.ndarray]:
    if isinstance(trajs, np.ndarray) and trajs.ndim != 3:
        raise ValueError(f"trajectories must be (N, T, 2) or a list of (T_i, 2) arrays, got shape {trajs.shape}")
    tracks = list(trajs)
    dts = np.broadcast_to(np.asarray(dt, dtype=np.float64), (len(tracks),))
    if np.any(~(dts > 0)):
        raise ValueError("dt must be > 0 for every trajectory")
    out = []
    for i, t in enumerate(tracks):
        t = np.asarray(t, dtype=np.float64)
        if t.ndim != 2 or t.shape[1] != 2:
            raise ValueError(f"trajectory {i} must have shape (T, 2), got {t.shape}")
        out.append(t)
    return out, dts


def kinematics(trajs: np.ndarray | Sequence[np.ndarray], dt: float | Sequence[float] | np.ndarray
               ) -> dict[str, np.ndarray]:
    """Pooled speed (m/s), acceleration (m/s^2) and jerk (m/s^3) magnitudes of trajectories.

    Args:
        trajs: (N, T, 2) array or a list of (T_i, 2) arrays (m).
        dt: Seconds per step, a scalar or one per trajectory.

    Returns:
        ``{"speed", "accel", "jerk"}``, each a 1-D array pooled over all trajectories (a trajectory
        of T points contributes T-1 speeds, T-2 accelerations, T-3 jerks).
    """
    tracks, dts = _as_tracks(trajs, dt)
    parts: dict[str, list[np.ndarray]] = {"speed": [], "accel": [], "jerk": []}
    for t, h in zip(tracks, dts, strict=True):
        d = t
        for key in ("speed", "accel", "jerk"):
            d = np.diff(d, axis=0) / h
            parts[key].append(np.linalg.norm(d, axis=1))
    return {key: np.concatenate(v) if v else np.zeros(0) for key, v in parts.items()}


def realism_distances(
    generated: np.ndarray | Sequence[np.ndarray],
    generated_dt: float | Sequence[float] | np.ndarray,
    real: np.ndarray | Sequence[np.ndarray],
    real_dt: float | Sequence[float] | np.ndarray,
) -> dict[str, float]:
    """Earth mover's distances ``{"speed_emd", "accel_emd", "jerk_emd"}`` between generated and real tracks.

    Raises:
        ValueError: If either side has no value of some quantity (trajectories too short).
    """
    from scipy.stats import wasserstein_distance

    gen = kinematics(generated, generated_dt)
    ref = kinematics(real, real_dt)
    out = {}
    for key in ("speed", "accel", "jerk"):
        if gen[key].size == 0 or ref[key].size == 0:
            raise ValueError(f"no {key} values: trajectories need at least 4 points")
        out[f"{key}_emd"] = float(wasserstein_distance(gen[key], ref[key]))
    return out


def collision_rate(positions: np.ndarray, radius: float = 0.2, valid: np.ndarray | None = None) -> float:
    """Share of agents that collide with another agent at some step of a rollout.

    Args:
        positions: (T, A, 2) positions (m) of A agents over T steps.
        radius: Disc radius (m) of every agent; two agents collide when their centres are closer than
            ``2 * radius``.
        valid: Optional (T, A) bool: the agent exists at that step (absent agents never collide).

    Returns:
        Colliding agents / agents that exist at some step (0 if there are none).

    Raises:
        ValueError: On wrong shapes or a negative radius.
    """
    pos = np.asarray(positions, dtype=np.float64)
    if pos.ndim != 3 or pos.shape[2] != 2:
        raise ValueError(f"positions must have shape (T, A, 2), got {pos.shape}")
    if radius < 0:
        raise ValueError(f"radius must be >= 0, got {radius!r}")
    mask = np.ones(pos.shape[:2], bool) if valid is None else np.asarray(valid, bool)
    if mask.shape != pos.shape[:2]:
        raise ValueError(f"valid must have shape {pos.shape[:2]}, got {mask.shape}")
    a = pos.shape[1]
    exists = mask.any(axis=0)
    if a == 0 or not exists.any():
        return 0.0
    dist = np.linalg.norm(pos[:, :, None, :] - pos[:, None, :, :], axis=-1)  # (T, A, A)
    both = mask[:, :, None] & mask[:, None, :] & ~np.eye(a, dtype=bool)[None]
    hit = ((dist < 2.0 * radius) & both).any(axis=(0, 2))
    return float(hit.sum() / exists.sum())
