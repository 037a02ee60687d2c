"""Baseline forecasters of pedestrian futures: constant velocity and social force.

Every forecaster follows :class:`Forecaster`: ``predict(batch, n_samples)`` returns ``(N, S, H, 2)``
future positions in the batch's own frame (agent-centric after :func:`navzoo.forecast.data.normalize`),
for the batch dict documented in :mod:`navzoo.forecast.data`. Both baselines work in any frame,
because they only use differences and rotations of the given positions.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any, Protocol, runtime_checkable

import numpy as np

from navzoo.agents.sfm import SocialForceParams, social_force_velocities

__all__ = ["Forecaster", "ConstantVelocity", "SocialForceForecaster"]


@runtime_checkable
class Forecaster(Protocol):
    """A model of pedestrian futures."""

    def predict(self, batch: Mapping[str, Any], n_samples: int) -> np.ndarray:
        """Future positions ``(N, n_samples, H, 2)`` (m) in the batch's frame, H = the batch's ``fut`` length."""
        ...


def _check(batch: Mapping[str, Any], n_samples: int) -> tuple[np.ndarray, int]:
    if n_samples < 1:
        raise ValueError(f"n_samples must be >= 1, got {n_samples!r}")
    hist = np.asarray(batch["hist"], dtype=np.float64)
    if hist.ndim != 3 or hist.shape[1] < 2 or hist.shape[2] != 2:
        raise ValueError(f"batch['hist'] must have shape (N, T >= 2, 2), got {hist.shape}")
    horizon = np.asarray(batch["fut"]).shape[1] if "fut" in batch else 12
    return hist, int(horizon)


class ConstantVelocity:
    """Keep the last observed step: ``p_k = p_T + k (p_T - p_{T-1})``.

    Deterministic: the S samples are identical copies, so minADE over samples equals ADE.

    Args:
        horizon: Predicted steps when the batch has no ``fut`` (default: ``fut``'s length, else 12).
    """

    def __init__(self, horizon: int | None = None) -> None:
        self.horizon = horizon

    def predict(self, batch: Mapping[str, Any], n_samples: int) -> np.ndarray:
        """See :class:`Forecaster`."""
        hist, horizon = _check(batch, n_samples)
        horizon = self.horizon or horizon
        step = hist[:, -1] - hist[:, -2]
        k = np.arange(1, horizon + 1, dtype=np.float64)
        path = hist[:, -1, None, :] + k[None, :, None] * step[:, None, :]  # (N, H, 2)
        return np.repeat(path[:, None], n_samples, axis=1)


class SocialForceForecaster:
    """Roll navzoo's social force model (:func:`navzoo.agents.sfm.social_force_velocities`) forward.

    Per window: the person starts at its last observed position with its last observed velocity
    ``(p_T - p_{T-1}) / dt``; its preferred velocity points along the observed mean velocity
    ``(p_T - p_1) / ((T - 1) dt)`` with the observed mean speed (mean of the step speeds). The
    neighbours present at the last observed frame move on at their last velocity (0 if only that
    frame is known) and do not react (they are the model's "others"). The state is integrated over
    H steps of the window's dt (the model sub-steps internally at ``params.max_substep``).

    Samples: sample 0 is the unperturbed model; samples 1.. scale the preferred speed by
    ``max(0, 1 + speed_std * e1)`` and turn the preferred direction by ``angle_std * e2`` rad with
    ``e1, e2 ~ N(0, 1)`` drawn from ``seed`` (the same draws on every call), so min-over-samples
    explores plausible intentions. The defaults (20 % speed, 0.25 rad ~ 14 deg) were set a priori,
    not tuned on the test data.

    Windows are independent: they are batched into one model call by placing them ``spacing`` metres
    apart (far beyond ``params.neighbor_dist``), ``chunk`` (window, sample) pairs per call.

    Args:
        params: Social force parameters (default: navzoo's :class:`SocialForceParams`).
        radius: Body radius of every person (m).
        max_speed: Speed limit (m/s); raised per person to its preferred speed if that is higher.
        speed_std: Relative standard deviation of the preferred speed over samples.
        angle_std: Standard deviation (rad) of the preferred direction over samples.
        seed: Seed of the perturbations.
        chunk: (window, sample) pairs per model call (the model is dense in people x neighbours).
        spacing: Distance (m) between the independent problems of one call.
    """

    def __init__(
        self,
        params: SocialForceParams | None = None,
        radius: float = 0.2,
        max_speed: float = 2.5,
        speed_std: float = 0.2,
        angle_std: float = 0.25,
        seed: int = 0,
        chunk: int = 12,
        spacing: float = 1000.0,
    ) -> None:
        if radius < 0 or max_speed <= 0 or speed_std < 0 or angle_std < 0 or chunk < 1 or spacing <= 0:
            raise ValueError(
                f"SocialForceForecaster needs radius >= 0, max_speed > 0, speed_std >= 0, angle_std >= 0, "
                f"chunk >= 1, spacing > 0; got {radius}, {max_speed}, {speed_std}, {angle_std}, {chunk}, {spacing}")
        self.params = params or SocialForceParams()
        self.radius = float(radius)
        self.max_speed = float(max_speed)
        self.speed_std = float(speed_std)
        self.angle_std = float(angle_std)
        self.seed = int(seed)
        self.chunk = int(chunk)
        self.spacing = float(spacing)

    def preferred_velocity(self, hist: np.ndarray, dt: np.ndarray) -> np.ndarray:
        """Unperturbed preferred velocities (N, 2): mean-velocity direction at the mean step speed."""
        disp = hist[:, -1] - hist[:, 0]
        norm = np.linalg.norm(disp, axis=1, keepdims=True)
        direction = np.divide(disp, norm, out=np.zeros_like(disp), where=norm > 1e-6)
        speed = np.linalg.norm(np.diff(hist, axis=1), axis=2).mean(axis=1) / dt
        return direction * speed[:, None]

    def predict(self, batch: Mapping[str, Any], n_samples: int) -> np.ndarray:
        """See :class:`Forecaster`."""
        hist, horizon = _check(batch, n_samples)
        n = hist.shape[0]
        dt = np.broadcast_to(np.asarray(batch["dt"], dtype=np.float64), (n,))
        if np.any(dt <= 0):
            raise ValueError("batch['dt'] must be > 0")
        pref = self.preferred_velocity(hist, dt)
        rng = np.random.default_rng(self.seed)
        scale = np.maximum(0.0, 1.0 + self.speed_std * rng.standard_normal((n, n_samples)))
        turn = self.angle_std * rng.standard_normal((n, n_samples))
        scale[:, 0], turn[:, 0] = 1.0, 0.0
        c, s = np.cos(turn), np.sin(turn)
        pref_s = scale[..., None] * np.stack([c * pref[:, None, 0] - s * pref[:, None, 1],
                                              s * pref[:, None, 0] + c * pref[:, None, 1]], axis=-1)  # (N, S, 2)
        vel0 = (hist[:, -1] - hist[:, -2]) / dt[:, None]

        k = np.asarray(batch["neigh"]).shape[1] if "neigh" in batch else 0
        if k:
            neigh = np.asarray(batch["neigh"], dtype=np.float64)
            mask = np.asarray(batch["neigh_mask"], dtype=bool)
            n_pos = neigh[:, :, -1]
            n_valid = mask[:, :, -1]
            n_vel = np.where((mask[:, :, -1] & mask[:, :, -2])[..., None],
                             (neigh[:, :, -1] - neigh[:, :, -2]) / dt[:, None, None], 0.0)
        out = np.empty((n, n_samples, horizon, 2))
        # Problems are (window, sample) pairs; one model call needs one dt, so group by dt.
        for value in np.unique(dt):
            windows = np.flatnonzero(dt == value)
            pairs = np.stack(np.meshgrid(windows, np.arange(n_samples), indexing="ij"), axis=-1).reshape(-1, 2)
            for start in range(0, pairs.shape[0], self.chunk):
                w, smp = pairs[start:start + self.chunk].T
                b = w.size
                offset = np.zeros((b, 2))
                offset[:, 0] = self.spacing * np.arange(b)
                pos = hist[w, -1] + offset
                vel = vel0[w].copy()
                pv = pref_s[w, smp]
                max_speed = np.maximum(self.max_speed, np.linalg.norm(pv, axis=1))
                if k:
                    sel = n_valid[w]  # (b, K)
                    o_pos = (n_pos[w] + offset[:, None, :])[sel]
                    o_vel = n_vel[w][sel]
                else:
                    o_pos = o_vel = np.zeros((0, 2))
                for step in range(horizon):
                    vel = social_force_velocities(
                        pos, vel, pv, self.radius, max_speed, float(value), self.params,
                        others_pos=o_pos if o_pos.size else None,
                        others_vel=o_vel if o_pos.size else None,
                        others_radius=self.radius,
                    )
                    pos = pos + float(value) * vel
                    o_pos = o_pos + float(value) * o_vel
                    out[w, smp, step] = pos - offset
        return out
