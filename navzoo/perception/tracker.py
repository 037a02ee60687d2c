"""Multi-person tracking from position detections, and CLEAR-MOT metrics.

:class:`PersonTracker` turns per-frame detections of people (positions on the ground plane, e.g. from
Monoloco, with an optional 2x2 covariance each) into tracks with stable integer ids:

* Model: one :class:`filterpy.kalman.KalmanFilter` per track, constant velocity in 2-D, state
  ``(x, y, vx, vy)``, measurement ``(x, y)``, all in one fixed (world) frame. Process noise is white
  acceleration of spectral density ``process_noise`` (m^2/s^3), discretised exactly for the step
  ``dt`` (``Q_continuous_white_noise``), so the same value fits any frame rate. The measurement
  noise is ``measurement_std`` (m, isotropic) unless ``update`` is given one covariance per detection,
  so that far detections (a monocular detector is most uncertain along the viewing ray, see
  :func:`radial_covariance`) pull the estimate less.
* Association: global nearest neighbour. The cost of pairing a track with a detection is the
  squared Mahalanobis distance of the innovation, ``y^T S^-1 y`` with ``S = H P H^T + R`` (``R`` the
  detection's own covariance); pairs above ``gate`` (the 99 % quantile of chi-square with 2 degrees
  of freedom, 9.21, by default) are never paired. Confirmed tracks are assigned first (Hungarian
  algorithm, ``scipy.optimize.linear_sum_assignment``), tentative tracks then compete for the rest,
  so a fresh clutter track cannot take a detection from an established one.
* Management: every unmatched detection starts a tentative track; it is confirmed at its ``n_init``-th
  hit and deleted at its first miss before that. A confirmed track coasts on its prediction through
  misses and is deleted at its ``max_age``-th consecutive miss. Ids start at 1 and are never reused.
* Attributes: the detection extras given to ``update`` are carried to the matched track (last value).
  ``"orientation"`` (body yaw, radians, or ``(sin, cos)`` pairs as Monoloco gives them) is smoothed on
  the unit circle, ``u <- normalise((1 - a) u + a u_det)`` with ``a = orientation_smoothing``;
  ``"confidence"`` is exposed as :attr:`Track.confidence`.

Detections must already be in the world frame (:func:`to_world` moves sensor-frame positions and
covariances there). The tracker has no randomness: the same inputs give the same tracks.

:func:`clear_mot` scores tracks against ground truth with the CLEAR-MOT metrics (Bernardin and
Stiefelhagen, 2008): MOTA = 1 - (FN + FP + IDSW) / GT and MOTP = mean distance (m) of matched pairs.
"""

from __future__ import annotations

import math
from collections.abc import Hashable, Mapping, Sequence
from dataclasses import asdict, dataclass, field
from typing import Any

import numpy as np
from filterpy.common import Q_continuous_white_noise
from filterpy.kalman import KalmanFilter
from scipy.optimize import linear_sum_assignment

__all__ = [
    "GATE_CHI2_99",
    "Track",
    "PersonTracker",
    "ClearMotResult",
    "clear_mot",
    "radial_covariance",
    "to_world",
]

GATE_CHI2_99 = -2.0 * math.log(0.01)
"""99 % quantile of chi-square with 2 degrees of freedom (9.2103...): closed form, as chi2(2) is exponential."""

_H = np.array([[1.0, 0.0, 0.0, 0.0], [0.0, 1.0, 0.0, 0.0]])
_MISSING = object()


@dataclass(frozen=True, eq=False)
class Track:
    """A snapshot of one track after an update (later updates do not change it).

    Attributes:
        id: Unique id (>= 1), never reused by the tracker that made it.
        position: (2,) estimated position (m), world frame.
        velocity: (2,) estimated velocity (m/s), world frame.
        covariance: (4, 4) state covariance, state order ``(x, y, vx, vy)``.
        age: Frames since birth, the birth frame counting 1.
        hits: Detections associated with the track, the birth detection included.
        misses: Consecutive frames without a detection up to now (0 if updated this frame).
        confirmed: Whether the track has had ``n_init`` hits.
        orientation: Smoothed body orientation (rad, in (-pi, pi]), None if no detection carried one.
        confidence: ``"confidence"`` extra of the last associated detection, None if not given.
        extras: Every extra of the last associated detection that carried extras, by key.
    """

    id: int
    position: np.ndarray
    velocity: np.ndarray
    covariance: np.ndarray
    age: int
    hits: int
    misses: int
    confirmed: bool
    orientation: float | None = None
    confidence: float | None = None
    extras: dict[str, np.ndarray] = field(default_factory=dict)

    @property
    def position_covariance(self) -> np.ndarray:
        """(2, 2) covariance of the position estimate (m^2)."""
        return self.covariance[:2, :2]

    @property
    def speed(self) -> float:
        """Estimated speed (m/s)."""
        return float(np.hypot(*self.velocity))


class _TrackState:
    """Mutable per-track state inside the tracker."""

    __slots__ = ("id", "kf", "age", "hits", "misses", "confirmed", "heading", "confidence", "extras")

    def __init__(self, track_id: int, kf: KalmanFilter) -> None:
        self.id = track_id
        self.kf = kf
        self.age = 1
        self.hits = 1
        self.misses = 0
        self.confirmed = False
        self.heading: np.ndarray | None = None   # unit vector (cos, sin) of the smoothed orientation
        self.confidence: float | None = None
        self.extras: dict[str, np.ndarray] = {}

    def snapshot(self) -> Track:
        x = self.kf.x.reshape(-1)
        pos, vel, cov = x[:2].copy(), x[2:].copy(), np.array(self.kf.P, dtype=np.float64)
        for a in (pos, vel, cov):
            a.flags.writeable = False
        orientation = None if self.heading is None else float(math.atan2(self.heading[1], self.heading[0]))
        return Track(id=self.id, position=pos, velocity=vel, covariance=cov, age=self.age, hits=self.hits,
                     misses=self.misses, confirmed=self.confirmed, orientation=orientation,
                     confidence=self.confidence, extras={k: v.copy() for k, v in self.extras.items()})


def _positive(name: str, value: float, allow_zero: bool = False) -> float:
    value = float(value)
    ok = value >= 0 if allow_zero else value > 0
    if not (math.isfinite(value) and ok):
        raise ValueError(f"{name} must be a finite number {'>=' if allow_zero else '>'} 0, got {value!r}")
    return value


def _check_covariances(cov: np.ndarray, name: str) -> np.ndarray:
    """Validate a stack (N, 2, 2) of covariances: finite, symmetric, positive definite; returns it symmetrised."""
    if not np.all(np.isfinite(cov)):
        bad = np.flatnonzero(~np.isfinite(cov).all(axis=(1, 2)))
        raise ValueError(f"{name} contain NaN or inf (detections {bad.tolist()})")
    scale = np.maximum(np.abs(cov).max(axis=(1, 2)), 1e-300)
    asym = np.abs(cov - np.swapaxes(cov, 1, 2)).max(axis=(1, 2)) / scale
    if np.any(asym > 1e-9):
        raise ValueError(f"{name} must be symmetric (detections {np.flatnonzero(asym > 1e-9).tolist()} are not)")
    cov = 0.5 * (cov + np.swapaxes(cov, 1, 2))
    if cov.shape[0]:
        low = np.linalg.eigvalsh(cov)[:, 0]
        if np.any(low <= 0):
            i = int(np.flatnonzero(low <= 0)[0])
            raise ValueError(f"{name} must be positive definite: detection {i} has smallest eigenvalue {low[i]:.3g}")
    return cov


def _orientation_vectors(value: np.ndarray, n: int) -> np.ndarray:
    """(N,) angles or (N, 2) ``(sin, cos)`` pairs -> (N, 2) unit vectors ``(cos, sin)``, NaN rows where absent."""
    if value.shape == (n,):
        return np.stack([np.cos(value), np.sin(value)], axis=1)
    if value.shape == (n, 2):
        vec = np.stack([value[:, 1], value[:, 0]], axis=1)
        norm = np.linalg.norm(vec, axis=1, keepdims=True)
        with np.errstate(invalid="ignore", divide="ignore"):
            return np.where(norm > 1e-12, vec / norm, np.nan)
    raise ValueError(f"extras['orientation'] must have shape ({n},) (radians) or ({n}, 2) (sin, cos), "
                     f"got {value.shape}")


class PersonTracker:
    """Kalman-filter multi-person tracker with Mahalanobis gating and Hungarian association.

    See the module docstring for the model. Typical use, once per sensor frame::

        tracker = PersonTracker(dt=0.1)
        for positions, covs in frames:          # (N, 2) and (N, 2, 2), world frame
            for track in tracker.update(positions, covs):
                ...

    Args:
        dt: Seconds between frames (default for :meth:`update`).
        process_noise: Spectral density q (m^2/s^3) of the white acceleration noise; the velocity
            variance grows by q per second. Lower it for steadier walkers, raise it for agile ones.
        measurement_std: Standard deviation (m, per axis) of a detection without its own covariance.
        init_velocity_std: Standard deviation (m/s, per axis) of the velocity of a new track (its
            velocity starts at 0).
        gate: Largest squared Mahalanobis distance at which a detection may join a track.
        n_init: Hits that confirm a track (1 confirms at birth).
        max_age: A confirmed track is deleted at its ``max_age``-th consecutive miss (it coasts through
            ``max_age - 1`` missed frames).
        orientation_smoothing: Weight in (0, 1] of a new orientation against the track's (1 = no smoothing).

    Attributes:
        frame: Updates since construction or the last :meth:`reset`.

    Raises:
        ValueError: On a parameter out of range.
    """

    def __init__(
        self,
        dt: float = 0.1,
        process_noise: float = 0.5,
        measurement_std: float = 0.3,
        init_velocity_std: float = 1.5,
        gate: float = GATE_CHI2_99,
        n_init: int = 3,
        max_age: int = 5,
        orientation_smoothing: float = 0.3,
    ) -> None:
        self.dt = _positive("dt", dt)
        self.process_noise = _positive("process_noise", process_noise, allow_zero=True)
        self.measurement_std = _positive("measurement_std", measurement_std)
        self.init_velocity_std = _positive("init_velocity_std", init_velocity_std)
        self.gate = _positive("gate", gate)
        if int(n_init) != n_init or n_init < 1:
            raise ValueError(f"n_init must be an integer >= 1, got {n_init!r}")
        if int(max_age) != max_age or max_age < 1:
            raise ValueError(f"max_age must be an integer >= 1, got {max_age!r}")
        self.n_init = int(n_init)
        self.max_age = int(max_age)
        a = float(orientation_smoothing)
        if not 0.0 < a <= 1.0:
            raise ValueError(f"orientation_smoothing must be in (0, 1], got {orientation_smoothing!r}")
        self.orientation_smoothing = a
        self._tracks: list[_TrackState] = []
        self._next_id = 1
        self.frame = 0

    # ------------------------------------------------------------------ public API

    @property
    def tracks(self) -> list[Track]:
        """Confirmed tracks (coasting ones included, see :attr:`Track.misses`), by id."""
        return [t.snapshot() for t in self._tracks if t.confirmed]

    @property
    def all_tracks(self) -> list[Track]:
        """Confirmed and tentative tracks, by id."""
        return [t.snapshot() for t in self._tracks]

    def reset(self, restart_ids: bool = False) -> None:
        """Drop every track. Ids continue from where they were unless ``restart_ids`` (then the next is 1)."""
        self._tracks = []
        self.frame = 0
        if restart_ids:
            self._next_id = 1

    def update(
        self,
        detections: np.ndarray,
        covariances: np.ndarray | None = None,
        extras: Mapping[str, np.ndarray] | None = None,
        *,
        dt: float | None = None,
    ) -> list[Track]:
        """Advance one frame: predict every track by ``dt``, associate the detections, update, manage.

        Args:
            detections: (N, 2) positions (m), world frame; N may be 0 (an empty array of any shape).
            covariances: (N, 2, 2) measurement covariances (m^2), one per detection, or one (2, 2) for
                all; None uses ``measurement_std``.
            extras: Per-detection attributes, each an array with N rows: ``"orientation"`` ((N,)
                radians or (N, 2) ``(sin, cos)``; NaN = not observed), ``"confidence"`` ((N,)), and any
                other key, carried to the matched track as is.
            dt: Seconds since the previous frame, if not the tracker's ``dt``.

        Returns:
            The confirmed tracks after the update (as :attr:`tracks`).

        Raises:
            ValueError: On wrong shapes, NaN or inf positions, covariances that are not symmetric
                positive definite, extras without N rows, or ``dt <= 0``. The tracker is unchanged then.
        """
        step = self.dt if dt is None else _positive("dt", dt)
        z, cov, ext = self._check_inputs(detections, covariances, extras)
        heading = _orientation_vectors(ext["orientation"], len(z)) if "orientation" in ext else None

        self.frame += 1
        F = np.eye(4)
        F[0, 2] = F[1, 3] = step
        Q = Q_continuous_white_noise(2, dt=step, spectral_density=self.process_noise, block_size=2,
                                     order_by_dim=False)
        for t in self._tracks:
            t.kf.predict(F=F, Q=Q)
            t.age += 1

        free = list(range(len(z)))
        matches: list[tuple[_TrackState, int]] = []
        for group in ([t for t in self._tracks if t.confirmed], [t for t in self._tracks if not t.confirmed]):
            pairs = self._associate(group, z[free], cov[free])
            matches += [(group[i], free[j]) for i, j in pairs]
            taken = {free[j] for _, j in pairs}
            free = [j for j in free if j not in taken]

        matched = set()
        for t, j in matches:
            t.kf.update(z[j].reshape(2, 1), R=cov[j])
            t.hits += 1
            t.misses = 0
            if t.hits >= self.n_init:
                t.confirmed = True
            self._take_extras(t, j, ext, heading)
            matched.add(t.id)

        kept = []
        for t in self._tracks:
            if t.id not in matched:
                t.misses += 1
                if not t.confirmed or t.misses >= self.max_age:
                    continue
            kept.append(t)
        for j in free:
            kept.append(self._birth(z[j], cov[j], ext, heading, j))
        self._tracks = kept
        return self.tracks

    # ------------------------------------------------------------------ internals

    def _check_inputs(self, detections: Any, covariances: Any, extras: Mapping[str, Any] | None
                      ) -> tuple[np.ndarray, np.ndarray, dict[str, np.ndarray]]:
        z = np.asarray(detections, dtype=np.float64)
        if z.size == 0:
            z = z.reshape(0, 2)
        if z.ndim != 2 or z.shape[1] != 2:
            raise ValueError(f"detections must have shape (N, 2), got {z.shape}")
        if not np.all(np.isfinite(z)):
            bad = np.flatnonzero(~np.isfinite(z).all(axis=1))
            raise ValueError(f"detections contain NaN or inf (rows {bad.tolist()})")
        n = len(z)
        if covariances is None:
            cov = np.broadcast_to(np.eye(2) * self.measurement_std**2, (n, 2, 2)).copy()
        else:
            cov = np.asarray(covariances, dtype=np.float64)
            if cov.shape == (2, 2):
                cov = np.broadcast_to(cov, (n, 2, 2)).copy()
            elif cov.shape != (n, 2, 2) and not (n == 0 and cov.size == 0):
                raise ValueError(f"covariances must have shape ({n}, 2, 2) or (2, 2), got {cov.shape}")
            cov = _check_covariances(cov.reshape(n, 2, 2), "covariances")
        ext: dict[str, np.ndarray] = {}
        for key, value in (extras or {}).items():
            arr = np.asarray(value)
            if arr.ndim == 0 or arr.shape[0] != n:
                raise ValueError(f"extras[{key!r}] must have {n} rows (one per detection), got shape {arr.shape}")
            ext[key] = arr
        if "orientation" in ext:
            ext["orientation"] = ext["orientation"].astype(np.float64)
            _orientation_vectors(ext["orientation"], n)   # shape check before any state changes
        if "confidence" in ext:
            if ext["confidence"].shape != (n,):
                raise ValueError(f"extras['confidence'] must have shape ({n},), got {ext['confidence'].shape}")
            ext["confidence"] = ext["confidence"].astype(np.float64)
        return z, cov, ext

    def _associate(self, tracks: list[_TrackState], z: np.ndarray, cov: np.ndarray) -> list[tuple[int, int]]:
        """Gated Hungarian assignment; returns (track index, detection index) pairs."""
        if not tracks or len(z) == 0:
            return []
        x = np.stack([t.kf.x.reshape(-1)[:2] for t in tracks])             # (T, 2)
        hph = np.stack([t.kf.P[:2, :2] for t in tracks])                   # (T, 2, 2)
        S = hph[:, None] + cov[None]                                         # (T, D, 2, 2)
        y = z[None] - x[:, None]                                             # (T, D, 2)
        d2 = np.einsum("tdi,tdi->td", y, np.linalg.solve(S, y[..., None])[..., 0])
        ok = d2 <= self.gate
        if not ok.any():
            return []
        # a forbidden pair costs more than any set of allowed ones, so the assignment first maximises
        # the number of gated pairs, then minimises their total distance; forbidden pairs are dropped
        big = self.gate * (min(d2.shape) + 1) + 1.0
        rows, cols = linear_sum_assignment(np.where(ok, d2, big))
        return [(int(i), int(j)) for i, j in zip(rows, cols, strict=True) if ok[i, j]]

    def _birth(self, z: np.ndarray, cov: np.ndarray, ext: dict[str, np.ndarray], heading: np.ndarray | None,
               j: int) -> _TrackState:
        kf = KalmanFilter(dim_x=4, dim_z=2)
        kf.x = np.array([[z[0]], [z[1]], [0.0], [0.0]])
        kf.P = np.zeros((4, 4))
        kf.P[:2, :2] = cov
        kf.P[2:, 2:] = np.eye(2) * self.init_velocity_std**2
        kf.H = _H.copy()
        kf.R = np.eye(2) * self.measurement_std**2
        t = _TrackState(self._next_id, kf)
        self._next_id += 1
        t.confirmed = self.n_init <= 1
        self._take_extras(t, j, ext, heading)
        return t

    def _take_extras(self, t: _TrackState, j: int, ext: dict[str, np.ndarray], heading: np.ndarray | None) -> None:
        if not ext:
            return
        t.extras = {k: np.array(v[j]) for k, v in ext.items()}
        if "confidence" in ext:
            t.confidence = float(ext["confidence"][j])
        if heading is not None and np.all(np.isfinite(heading[j])):
            u = heading[j]
            if t.heading is not None:
                a = self.orientation_smoothing
                v = (1.0 - a) * t.heading + a * u
                norm = float(np.hypot(*v))
                u = v / norm if norm > 1e-9 else u       # exactly opposite: take the new one
            t.heading = u


# ---------------------------------------------------------------------- sensor-frame helpers


def radial_covariance(positions: np.ndarray, radial_std: float | np.ndarray, lateral_std: float | np.ndarray,
                      origin: Sequence[float] | np.ndarray = (0.0, 0.0)) -> np.ndarray:
    """Covariances elongated along the line of sight, as a monocular detector's errors are.

    Args:
        positions: (N, 2) detected positions (m).
        radial_std: Standard deviation (m) along the ray from ``origin`` to each detection (e.g. Monoloco's
            Laplace scale b of the distance times sqrt(2)), scalar or (N,).
        lateral_std: Standard deviation (m) across the ray, scalar or (N,).
        origin: (2,) sensor position in the frame of ``positions``.

    Returns:
        (N, 2, 2) covariances ``R(phi) diag(radial^2, lateral^2) R(phi)^T``, ``phi`` the bearing of each
        detection from ``origin`` (0 for a detection at the origin).

    Raises:
        ValueError: On wrong shapes or a non-positive standard deviation.
    """
    p = np.asarray(positions, dtype=np.float64)
    if p.ndim != 2 or p.shape[1] != 2:
        raise ValueError(f"positions must have shape (N, 2), got {p.shape}")
    n = len(p)
    try:
        sr = np.broadcast_to(np.asarray(radial_std, dtype=np.float64), (n,))
        sl = np.broadcast_to(np.asarray(lateral_std, dtype=np.float64), (n,))
    except ValueError as err:
        raise ValueError(f"radial_std and lateral_std must be scalars or have shape ({n},)") from err
    if not (np.all(sr > 0) and np.all(sl > 0) and np.all(np.isfinite(sr)) and np.all(np.isfinite(sl))):
        raise ValueError("radial_std and lateral_std must be finite and > 0")
    d = p - np.asarray(origin, dtype=np.float64).reshape(2)
    phi = np.arctan2(d[:, 1], d[:, 0])
    c, s = np.cos(phi), np.sin(phi)
    rot = np.stack([np.stack([c, -s], axis=1), np.stack([s, c], axis=1)], axis=1)   # (N, 2, 2)
    diag = np.zeros((n, 2, 2))
    diag[:, 0, 0], diag[:, 1, 1] = sr**2, sl**2
    return rot @ diag @ np.swapaxes(rot, 1, 2)


def to_world(positions: np.ndarray, covariances: np.ndarray | None, pose: Sequence[float] | np.ndarray
             ) -> tuple[np.ndarray, np.ndarray | None]:
    """Move sensor-frame detections to the world frame.

    Args:
        positions: (N, 2) positions (m) in the sensor frame.
        covariances: (N, 2, 2) covariances in the sensor frame, or None.
        pose: Sensor pose ``(x, y, yaw)`` in the world frame (m, m, rad).

    Returns:
        ``(R p + t, R C R^T)``, R the rotation by ``yaw`` and t = ``(x, y)`` (None stays None).
        Orientations move by adding ``yaw``.

    Raises:
        ValueError: On wrong shapes.
    """
    p = np.asarray(positions, dtype=np.float64)
    if p.size == 0:
        p = p.reshape(0, 2)
    if p.ndim != 2 or p.shape[1] != 2:
        raise ValueError(f"positions must have shape (N, 2), got {p.shape}")
    pose = np.asarray(pose, dtype=np.float64)
    if pose.shape != (3,):
        raise ValueError(f"pose must be (x, y, yaw), got shape {pose.shape}")
    c, s = math.cos(pose[2]), math.sin(pose[2])
    rot = np.array([[c, -s], [s, c]])
    world = p @ rot.T + pose[:2]
    if covariances is None:
        return world, None
    cov = np.asarray(covariances, dtype=np.float64)
    if cov.shape != (len(p), 2, 2):
        raise ValueError(f"covariances must have shape ({len(p)}, 2, 2), got {cov.shape}")
    return world, rot @ cov @ rot.T


# ---------------------------------------------------------------------- CLEAR-MOT


@dataclass(frozen=True)
class ClearMotResult:
    """CLEAR-MOT scores of a sequence.

    Attributes:
        mota: 1 - (fn + fp + idsw) / num_gt (NaN if there is no ground-truth object); can be negative.
        motp: Mean distance (m) between matched objects and hypotheses (NaN without matches); lower is better.
        fn: Ground-truth objects not matched (misses), summed over frames.
        fp: Hypotheses not matched (false positives), summed over frames.
        idsw: ID switches (mismatches): matches whose hypothesis differs from the object's last one.
        matches: Matched pairs, summed over frames (ID switches included).
        num_gt: Ground-truth objects, summed over frames.
    """

    mota: float
    motp: float
    fn: int
    fp: int
    idsw: int
    matches: int
    num_gt: int

    def as_dict(self) -> dict[str, float]:
        """The fields as a plain dict."""
        return asdict(self)


def _frame_points(frame: Mapping[Hashable, Any], what: str, t: int) -> tuple[list[Hashable], np.ndarray]:
    if not isinstance(frame, Mapping):
        raise ValueError(f"{what} frame {t} must be a mapping {{id: (x, y)}}, got {type(frame).__name__}")
    ids = list(frame)
    pts = np.zeros((len(ids), 2))
    for i, k in enumerate(ids):
        p = np.asarray(frame[k], dtype=np.float64)
        if p.shape != (2,) or not np.all(np.isfinite(p)):
            raise ValueError(f"{what} frame {t}, id {k!r}: position must be a finite (x, y) pair, got {frame[k]!r}")
        pts[i] = p
    return ids, pts


def clear_mot(gt_frames: Sequence[Mapping[Hashable, Any]], hyp_frames: Sequence[Mapping[Hashable, Any]],
              threshold: float = 0.5) -> ClearMotResult:
    """CLEAR-MOT metrics of hypotheses (tracks) against ground truth, with Euclidean distance.

    Per frame, following Bernardin and Stiefelhagen (2008): (1) each object keeps its last matched
    hypothesis (from any earlier frame, as py-motmetrics does) if both are present and at most
    ``threshold`` apart; (2) the remaining objects and hypotheses are paired by the Hungarian
    algorithm on distance, pairs farther than ``threshold`` apart excluded (as many pairs as possible,
    then the smallest total distance); a new pair whose object was last matched to another hypothesis
    is an ID switch; (3) unpaired objects are misses (FN), unpaired hypotheses false positives (FP).

    Args:
        gt_frames: Per frame, ``{object id: (x, y)}`` of the ground truth (m).
        hyp_frames: Per frame, ``{hypothesis id: (x, y)}``, e.g. ``{t.id: t.position for t in tracks}``.
        threshold: Largest distance (m) of a match.

    Returns:
        The scores, see :class:`ClearMotResult`.

    Raises:
        ValueError: On sequences of different lengths, a non-positive threshold or bad positions.
    """
    if len(gt_frames) != len(hyp_frames):
        raise ValueError(f"gt_frames and hyp_frames differ in length ({len(gt_frames)} != {len(hyp_frames)})")
    threshold = _positive("threshold", threshold)
    last: dict[Hashable, Hashable] = {}     # object id -> hypothesis id of its last match
    fn = fp = idsw = n_match = n_gt = 0
    dist_sum = 0.0
    for t, (gt, hyp) in enumerate(zip(gt_frames, hyp_frames, strict=True)):
        oids, opos = _frame_points(gt, "gt", t)
        hids, hpos = _frame_points(hyp, "hyp", t)
        n_gt += len(oids)
        dist = np.linalg.norm(opos[:, None] - hpos[None], axis=-1) if oids and hids else np.zeros((len(oids), 0))
        h_index = {h: j for j, h in enumerate(hids)}
        o_free = np.ones(len(oids), bool)
        h_free = np.ones(len(hids), bool)
        # (1) keep earlier correspondences that are still valid
        for i, o in enumerate(oids):
            j = h_index.get(last.get(o, _MISSING), -1)
            if j >= 0 and h_free[j] and dist[i, j] <= threshold:
                o_free[i] = h_free[j] = False
                n_match += 1
                dist_sum += float(dist[i, j])
        # (2) optimal assignment of the rest
        oi, hj = np.flatnonzero(o_free), np.flatnonzero(h_free)
        if len(oi) and len(hj):
            sub = dist[np.ix_(oi, hj)]
            ok = sub <= threshold
            if ok.any():
                big = threshold * (min(sub.shape) + 1) + 1.0
                for r, c in zip(*linear_sum_assignment(np.where(ok, sub, big)), strict=True):
                    if not ok[r, c]:
                        continue
                    i, j = int(oi[r]), int(hj[c])
                    o, h = oids[i], hids[j]
                    if o in last and last[o] != h:
                        idsw += 1
                    last[o] = h
                    o_free[i] = h_free[j] = False
                    n_match += 1
                    dist_sum += float(dist[i, j])
        fn += int(o_free.sum())
        fp += int(h_free.sum())
    mota = 1.0 - (fn + fp + idsw) / n_gt if n_gt else float("nan")
    motp = dist_sum / n_match if n_match else float("nan")
    return ClearMotResult(mota=float(mota), motp=float(motp), fn=fn, fp=fp, idsw=idsw, matches=n_match, num_gt=n_gt)

