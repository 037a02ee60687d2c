"""Motion realism: how close a set of generated humanoid poses is to a reference set of motion capture.

The metric of ``../shared/METRICS.md`` ("pedestrian-model quality / motion realism"):

* **poses** as 15 keypoints at 30 Hz, root-centred, heading-aligned and scale-normalised
  (:func:`keypoints_from_state`, :func:`normalize_poses`), flattened to 45-vectors;
* **k-means** with K = 50 and K = 100 on the reference poses (:class:`RealismReference`), then for the
  generated poses: **coverage** (share of the K clusters that receive at least one generated pose),
  **normalised entropy** of the cluster occupancy ``H(p) / log K`` (1: generated poses spread evenly over
  the clusters, 0: all in one), and the mean Euclidean **distance** from each generated pose to its
  nearest centroid (in units of the skeleton scale, see below);
* **MMD** between generated and reference poses with an RBF kernel whose bandwidth is the median
  pairwise distance of the reference poses, reported next to its **floor**: the MMD between two disjoint
  random halves of the reference itself (what a perfect generator would score at that sample size).

Keypoints
---------
The humanoid is the 15-link DeepMimic humanoid (``humanoid/humanoid.urdf`` at ``globalScaling=0.25``).
Its link frame origins are its joint centres, so the keypoints are the link positions given by
:func:`navzoo.agents.motion_lib.humanoid_fk`, in its link order (:data:`KEYPOINT_NAMES`):

=====  ==================  ===================================
index  keypoint            humanoid link (joint centre)
=====  ==================  ===================================
0      pelvis              ``root`` (the base)
1      chest               ``chest`` (lower spine / waist joint)
2      neck                ``neck`` (base of the head)
3, 9   right / left hip    ``right_hip`` / ``left_hip``
4, 10  right / left knee   ``right_knee`` / ``left_knee``
5, 11  right / left foot   ``right_ankle`` / ``left_ankle``
6, 12  right / left        ``right_shoulder`` / ``left_shoulder``
       shoulder
7, 13  right / left elbow  ``right_elbow`` / ``left_elbow``
8, 14  right / left wrist  ``right_wrist`` / ``left_wrist``
=====  ==================  ===================================

METRICS.md lists 13 of them (pelvis, hips, knees, feet, shoulders, elbows, wrists); the humanoid's two
remaining joint centres, chest and neck, make the 15 (they carry the torso's bend and the head's
support point). Feet are the ankle joints.

Normalisation (:func:`normalize_poses`)
---------------------------------------
1. **root-centred**: the pelvis keypoint is subtracted (so the pelvis coordinates are always zero; the
   45-vector keeps them for a fixed layout, they do not affect any distance);
2. **heading-aligned**: rotated about the vertical (z) axis by minus the heading, where the heading is
   the yaw of the horizontal direction perpendicular to the hip line, ``forward = (left_hip -
   right_hip) x z``. The hips are rigidly attached to the root, so this is the yaw of the root's
   forward axis (``navzoo.agents.amp.features.heading`` of the root quaternion) whenever the pelvis is
   not both pitched and rolled; unlike the quaternion it is defined by the keypoints alone, so any
   skeleton's keypoints can be normalised the same way. A vertical hip line (a body lying on its side)
   has no heading and is left unrotated;
3. **scale-normalised**: divided by the pose's own spine length, ``|chest - pelvis| + |neck - chest|``
   (0.46 m for the humanoid). It is a sum of bone lengths, so it does not change with the pose (unlike
   the straight pelvis-to-neck distance, which shrinks when the spine bends), and the metric is
   invariant to the size of the skeleton. Distances to centroids are in spine lengths.

MMD estimate
------------
The biased (V-statistic) estimate ``MMD^2 = mean K(x, x') + mean K(y, y') - 2 mean K(x, y)`` (diagonals
included), with ``K(a, b) = exp(-|a - b|^2 / (2 sigma^2))`` and ``sigma`` the median pairwise distance
of the reference subsample; ``mmd`` is its square root (an RKHS distance in ``[0, sqrt 2]``). The biased
estimate is never negative and carries a positive finite-sample offset, which the split-half floor
measures: compare ``mmd`` with ``mmd_floor``, not with 0. Both sets are subsampled (seeded) to at most
``max_samples`` poses (2000 by default), the halves of the floor too, so floor and value are taken at
the same sample size as long as the reference holds at least ``2 * max_samples`` poses and at least
``max_samples`` poses are generated (fewer poses give a larger offset).

Anchors from the NavIsaacLab paper (their skeleton and reference: AMASS), K = 50, coverage / entropy /
distance: AMASS against itself 1.00 / 0.888 / 0.190; their AMP pedestrians 0.92 / 0.800 / 0.305 with
MMD 0.327; Isaac Sim's animated people 0.34 / 0.641, MMD 0.771. Numbers from this module are not
directly comparable (other skeleton, reference set and scale unit), only their ordering is.

Typical use::

    ref = RealismReference.fit(clip_poses(MotionLibrary.load()))
    realism_metrics(poses_from_state(sim.read_state()), ref)   # one row of poses per humanoid
    library_realism(locomotion_reference(), ref)
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from navzoo.agents.motion_lib import LINK_NAMES, humanoid_fk, quat_normalize

KEYPOINT_NAMES: tuple[str, ...] = (
    "pelvis", "chest", "neck", "right_hip", "right_knee", "right_foot", "right_shoulder", "right_elbow",
    "right_wrist", "left_hip", "left_knee", "left_foot", "left_shoulder", "left_elbow", "left_wrist",
)  # fmt: skip
"""The 15 keypoints, in the humanoid's link order (:data:`navzoo.agents.motion_lib.LINK_NAMES`)."""
KEYPOINT_LINKS: tuple[str, ...] = LINK_NAMES
N_KEYPOINTS = 15
POSE_DIM = 3 * N_KEYPOINTS
PELVIS, CHEST, NECK, RIGHT_HIP, LEFT_HIP = 0, 1, 2, 3, 9
DEFAULT_KS: tuple[int, ...] = (50, 100)
DEFAULT_FPS = 30.0
DEFAULT_MAX_SAMPLES = 2000

METRIC_KEYS: tuple[str, ...] = (
    "coverage_k50", "entropy_k50", "dist_k50", "coverage_k100", "entropy_k100", "dist_k100",
    "mmd", "mmd_floor", "n_generated",
)  # fmt: skip


# --------------------------------------------------------------------------------------------------
# Poses
# --------------------------------------------------------------------------------------------------


def _as_float(name: str, a: Any) -> np.ndarray:
    try:
        x = np.asarray(a, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"{name} is not a numeric array: {exc}") from exc
    if not np.all(np.isfinite(x)):
        raise ValueError(f"{name} has non-finite values (NaN or inf)")
    return x


def keypoints_from_state(
    root_pos: np.ndarray, root_quat: np.ndarray, sph: np.ndarray, rev: np.ndarray
) -> np.ndarray:
    """World keypoints (N, 15, 3) of N humanoid states (order :data:`KEYPOINT_NAMES`).

    Args:
        root_pos: (N, 3) base positions; root_quat: (N, 4) base orientations (x, y, z, w);
            sph: (N, 8, 4) spherical joint quaternions; rev: (N, 4) knee and elbow angles — the fields of
            a :class:`~navzoo.agents.reference.ReferenceState` or of ``PhysicsHumanoids.read_state()``.
            A single state without the leading axis is accepted too.

    Raises:
        ValueError: wrong shapes, inconsistent N, non-finite values or zero quaternions.
    """
    root_pos = _as_float("root_pos", root_pos)
    root_quat = _as_float("root_quat", root_quat)
    sph = _as_float("sph", sph)
    rev = _as_float("rev", rev)
    if root_pos.ndim == 1:
        root_pos, root_quat, sph, rev = root_pos[None], root_quat[None], sph[None], rev[None]
    n = root_pos.shape[0]
    for name, a, tail in (
        ("root_pos", root_pos, (3,)),
        ("root_quat", root_quat, (4,)),
        ("sph", sph, (8, 4)),
        ("rev", rev, (4,)),
    ):
        if a.shape != (n,) + tail:
            raise ValueError(f"{name} has shape {a.shape}, expected {(n,) + tail} (N = {n} from root_pos)")
    for name, q in (("root_quat", root_quat), ("sph", sph)):
        if q.size and np.linalg.norm(q, axis=-1).min() < 1e-9:
            raise ValueError(f"{name} has zero quaternions")
    if n == 0:
        return np.zeros((0, N_KEYPOINTS, 3))
    pos, _ = humanoid_fk(root_pos, quat_normalize(root_quat), quat_normalize(sph), rev)
    return pos


def hip_heading(kp: np.ndarray) -> np.ndarray:
    """Heading (N,) rad of keypoint sets (N, 15, 3): yaw of ``(left_hip - right_hip) x z`` (0 if undefined)."""
    lat = kp[:, LEFT_HIP, :2] - kp[:, RIGHT_HIP, :2]
    fx, fy = lat[:, 1], -lat[:, 0]
    ok = np.hypot(fx, fy) > 1e-9
    return np.where(ok, np.arctan2(fy, np.where(ok, fx, 1.0)), 0.0)


def spine_length(kp: np.ndarray) -> np.ndarray:
    """Per-pose skeleton scale (N,): ``|chest - pelvis| + |neck - chest|``."""
    return np.linalg.norm(kp[:, CHEST] - kp[:, PELVIS], axis=-1) + np.linalg.norm(
        kp[:, NECK] - kp[:, CHEST], axis=-1
    )


def normalize_poses(kp: np.ndarray) -> np.ndarray:
    """Root-centred, heading-aligned, scale-normalised poses (N, 45) from world keypoints (N, 15, 3).

    See the module docstring for the three steps. The result is invariant to translating the pose, to
    rotating it about the vertical axis and to scaling it. Layout: keypoint-major, ``[k * 3 + xyz]``,
    x forward, y to the left, z up.

    Raises:
        ValueError: wrong shape, non-finite values, or a degenerate skeleton (zero spine length).
    """
    kp = _as_float("keypoints", kp)
    if kp.ndim != 3 or kp.shape[1:] != (N_KEYPOINTS, 3):
        raise ValueError(f"keypoints have shape {kp.shape}, expected (N, {N_KEYPOINTS}, 3)")
    if kp.shape[0] == 0:
        return np.zeros((0, POSE_DIM))
    scale = spine_length(kp)
    if scale.min() < 1e-9:
        raise ValueError("keypoints have a degenerate skeleton (zero spine length)")
    h = hip_heading(kp)
    c, s = np.cos(h)[:, None], np.sin(h)[:, None]
    rel = kp - kp[:, PELVIS : PELVIS + 1]
    x, y = rel[..., 0], rel[..., 1]
    out = np.stack([c * x + s * y, -s * x + c * y, rel[..., 2]], axis=-1) / scale[:, None, None]
    return out.reshape(kp.shape[0], POSE_DIM)


def poses_from_state(state: Any) -> np.ndarray:
    """Normalised poses (N, 45) of a :class:`~navzoo.agents.reference.ReferenceState` or a
    ``read_state()``-like dict (fields ``root_pos``, ``root_quat``, ``sph``, ``rev``)."""
    if isinstance(state, Mapping):
        missing = [k for k in ("root_pos", "root_quat", "sph", "rev") if k not in state]
        if missing:
            raise ValueError(f"state dict lacks {missing}")
        f = (state["root_pos"], state["root_quat"], state["sph"], state["rev"])
    else:
        f = (state.root_pos, state.root_quat, state.sph, state.rev)
    return normalize_poses(keypoints_from_state(*f))


def clip_times(library: Any, clip: int, fps: float = DEFAULT_FPS) -> np.ndarray:
    """Sample times of one clip at ``fps``: ``0, 1/fps, ...`` up to its duration."""
    d = library.duration(clip)
    return np.arange(int(np.floor(d * fps + 1e-6)) + 1) / fps


def clip_poses(
    library: Any,
    fps: float = DEFAULT_FPS,
    clips: Iterable[int | str] | None = None,
    return_clip_ids: bool = False,
) -> np.ndarray | tuple[np.ndarray, np.ndarray]:
    """Normalised poses (M, 45) of every frame of a library's clips, resampled at ``fps`` (30 Hz).

    Args:
        library: a :class:`~navzoo.agents.motion_lib.MotionLibrary` (anything with ``state_at``,
            ``duration`` and ``len``; clip names need ``clip_index``).
        clips: clip indices or names (default: all), in that order.
        return_clip_ids: also return the (M,) clip index of each pose.
    """
    if not fps > 0:
        raise ValueError(f"fps must be positive, got {fps}")
    if clips is None:
        idx = list(range(len(library)))
    else:
        idx = [library.clip_index(c) if isinstance(c, str) else int(c) for c in clips]
    if not idx:
        raise ValueError("no clips selected")
    cid, ts = [], []
    for c in idx:
        t = clip_times(library, c, fps)
        cid.append(np.full(t.shape, c, dtype=np.int64))
        ts.append(t)
    cid_a, t_a = np.concatenate(cid), np.concatenate(ts)
    poses = poses_from_state(library.state_at(cid_a, t_a))
    return (poses, cid_a) if return_clip_ids else poses


def clip_root_speeds(library: Any, fps: float = DEFAULT_FPS) -> np.ndarray:
    """Horizontal root speed (M,) m/s of every frame of :func:`clip_poses` (all clips, same order): the central
    difference over each clip's own frames at ``fps`` (one-sided at its ends; 0 for a one-frame clip)."""
    out = []
    for c in range(len(library)):
        t = clip_times(library, c, fps)
        xy = np.asarray(library.state_at(np.full(t.shape, c), t).root_pos)[:, :2]
        out.append(np.linalg.norm(np.gradient(xy, 1.0 / fps, axis=0), axis=1) if len(t) > 1 else np.zeros(len(t)))
    return np.concatenate(out)


# --------------------------------------------------------------------------------------------------
# k-means and kernels
# --------------------------------------------------------------------------------------------------


def _sq_dists(a: np.ndarray, b: np.ndarray, aa: np.ndarray | None = None, bb: np.ndarray | None = None):
    """Squared Euclidean distances (len(a), len(b)); ``aa``, ``bb``: precomputed squared row norms."""
    aa = (a * a).sum(1) if aa is None else aa
    bb = (b * b).sum(1) if bb is None else bb
    d = a @ b.T
    d *= -2.0
    d += aa[:, None]
    d += bb[None, :]
    return np.maximum(d, 0.0, out=d)


def _nearest(
    x: np.ndarray, c: np.ndarray, xx: np.ndarray | None = None, chunk: int = 8192
) -> tuple[np.ndarray, np.ndarray]:
    """Index and squared distance of each row of ``x``'s nearest row of ``c``."""
    xx = (x * x).sum(1) if xx is None else xx
    cc = (c * c).sum(1)
    lab = np.empty(x.shape[0], dtype=np.int64)
    d2 = np.empty(x.shape[0])
    for i in range(0, x.shape[0], chunk):
        d = _sq_dists(x[i : i + chunk], c, xx[i : i + chunk], cc)
        lab[i : i + chunk] = d.argmin(1)
        d2[i : i + chunk] = d[np.arange(d.shape[0]), lab[i : i + chunk]]
    return lab, d2


def _kmeans_pp(x: np.ndarray, xx: np.ndarray, k: int, rng: np.random.Generator) -> np.ndarray:
    """k-means++ seeding (D^2 sampling, 2 + log k candidates per step, the best one kept)."""
    n = x.shape[0]
    trials = 2 + int(np.log(k))
    centers = np.empty((k, x.shape[1]))
    first = int(rng.integers(n))
    centers[0] = x[first]
    d2 = _sq_dists(x[first : first + 1], x, xx[first : first + 1], xx)[0]
    for j in range(1, k):
        tot = d2.sum()
        if tot <= 0:
            cand = rng.integers(n, size=trials)
        else:
            cand = np.searchsorted(np.cumsum(d2), rng.uniform(0, tot, size=trials))
            cand = np.minimum(cand, n - 1)
        dc = np.minimum(d2[None, :], _sq_dists(x[cand], x, xx[cand], xx))
        best = int(dc.sum(1).argmin())
        centers[j] = x[cand[best]]
        d2 = dc[best]
    return centers


def kmeans(
    x: np.ndarray, k: int, seed: int = 0, n_init: int = 4, max_iter: int = 300
) -> tuple[np.ndarray, np.ndarray, float]:
    """Seeded k-means (k-means++ seeding, Lloyd iterations, best of ``n_init`` runs by inertia).

    Deterministic for a given ``seed``. Lloyd iterations run until the assignment no longer changes
    (or ``max_iter``). Empty clusters are re-seeded with the points farthest from their centroids, so at
    convergence every cluster holds at least one point.

    Returns:
        ``(centroids (k, D), labels (N,), inertia)``.
    """
    x = np.asarray(x, dtype=np.float64)
    n = x.shape[0]
    if not 1 <= k <= n:
        raise ValueError(f"k-means needs 1 <= K <= number of points, got K = {k}, {n} points")
    if np.unique(x, axis=0).shape[0] < k:
        raise ValueError(f"k-means with K = {k} needs at least {k} distinct points")
    rng = np.random.default_rng(seed)
    xx = (x * x).sum(1)
    best: tuple[np.ndarray, np.ndarray, float] | None = None
    for _ in range(n_init):
        c = _kmeans_pp(x, xx, k, rng)
        lab, d2 = _nearest(x, c, xx)
        for _ in range(max_iter):
            counts = np.bincount(lab, minlength=k)
            sums = np.stack([np.bincount(lab, weights=x[:, d], minlength=k) for d in range(x.shape[1])], 1)
            nz = counts > 0
            c = c.copy()
            c[nz] = sums[nz] / counts[nz, None]
            if not nz.all():
                far = np.argsort(-d2, kind="stable")
                for j, i in zip(np.flatnonzero(~nz), far, strict=False):
                    c[j] = x[i]
            new, d2 = _nearest(x, c, xx)
            if np.array_equal(new, lab) and nz.all():
                break
            lab = new
        inertia = float(d2.sum())
        if best is None or inertia < best[2]:
            best = (c, lab, inertia)
    assert best is not None
    return best


def _kernel_mean(a: np.ndarray, b: np.ndarray, gamma: float, chunk: int = 2048) -> float:
    """Mean of ``exp(-gamma |a_i - b_j|^2)`` over all pairs."""
    tot = 0.0
    for i in range(0, a.shape[0], chunk):
        tot += float(np.exp(-gamma * _sq_dists(a[i : i + chunk], b)).sum())
    return tot / (a.shape[0] * b.shape[0])


def median_pairwise_distance(x: np.ndarray) -> float:
    """Median Euclidean distance over all pairs ``i < j`` of rows of ``x``."""
    d2 = _sq_dists(x, x)
    iu = np.triu_indices(x.shape[0], k=1)
    return float(np.sqrt(np.median(d2[iu])))


def mmd_rbf(x: np.ndarray, y: np.ndarray, sigma: float, kyy: float | None = None) -> float:
    """Biased MMD (square root of the V-statistic MMD^2) with an RBF kernel of bandwidth ``sigma``.

    ``kyy``: the precomputed mean kernel value of ``y`` with itself.
    """
    gamma = 1.0 / (2.0 * sigma * sigma)
    kxx = _kernel_mean(x, x, gamma)
    kyy = _kernel_mean(y, y, gamma) if kyy is None else kyy
    kxy = _kernel_mean(x, y, gamma)
    return float(np.sqrt(max(kxx + kyy - 2.0 * kxy, 0.0)))


def _subsample(x: np.ndarray, m: int, rng: np.random.Generator) -> np.ndarray:
    if x.shape[0] <= m:
        return x
    return x[np.sort(rng.choice(x.shape[0], size=m, replace=False))]


def _check_poses(name: str, poses: Any) -> np.ndarray:
    x = np.asarray(poses)
    if x.ndim != 2 or x.shape[1] != POSE_DIM:
        raise ValueError(
            f"{name} poses have shape {x.shape}, expected (N, {POSE_DIM}) normalised poses "
            "(see normalize_poses / clip_poses)"
        )
    if x.shape[0] == 0:
        raise ValueError(f"{name} poses are empty (0 poses)")
    return _as_float(f"{name} poses", x)


def _occupancy(labels: np.ndarray, k: int) -> tuple[float, float]:
    """(coverage, normalised entropy) of cluster labels."""
    counts = np.bincount(labels, minlength=k)
    p = counts[counts > 0] / labels.shape[0]
    ent = float(-(p * np.log(p)).sum() / np.log(k)) if k > 1 else 0.0
    return float((counts > 0).sum() / k), max(ent, 0.0) + 0.0  # + 0.0: no -0.0


# --------------------------------------------------------------------------------------------------
# The reference and the metrics
# --------------------------------------------------------------------------------------------------


@dataclass
class RealismReference:
    """What the metric needs from the reference poses, fitted once by :meth:`fit`.

    Attributes:
        centroids: K -> (K, 45) k-means centroids, for each K of ``ks``.
        sigma: RBF bandwidth, the median pairwise distance of ``mmd_sample``.
        mmd_sample: (<= max_samples, 45) the reference subsample the MMD is computed against.
        mmd_floor: MMD between two disjoint random halves of the reference (each subsampled to
            ``max_samples``), the value an ideal generator would get.
        self_metrics: the reference scored against itself (coverage 1, its own occupancy entropy and
            mean distance to the nearest centroid, ``mmd`` = the floor), the anchor row of a report.
        n_reference, seed, max_samples: as fitted.
    """

    centroids: dict[int, np.ndarray]
    sigma: float
    mmd_sample: np.ndarray
    mmd_floor: float
    n_reference: int
    seed: int = 0
    max_samples: int = DEFAULT_MAX_SAMPLES
    self_metrics: dict[str, float] = field(default_factory=dict)
    _kyy: float = field(default=float("nan"), repr=False)

    @property
    def ks(self) -> tuple[int, ...]:
        return tuple(self.centroids)

    @classmethod
    def fit(
        cls,
        poses: np.ndarray,
        ks: Sequence[int] = DEFAULT_KS,
        seed: int = 0,
        max_samples: int = DEFAULT_MAX_SAMPLES,
        groups: np.ndarray | None = None,
        n_init: int = 4,
    ) -> RealismReference:
        """Fit on reference poses (N, 45) (e.g. :func:`clip_poses` of a library).

        Args:
            ks: the k-means sizes (50 and 100 by default; the metric keys name them).
            seed: seeds the k-means, the subsamples and the split halves; the same seed and poses give
                the same reference.
            max_samples: cap on the poses per side of an MMD (cost grows with its square).
            groups: optional (N,) group label per pose (e.g. the clip ids of ``clip_poses(...,
                return_clip_ids=True)``): the floor's halves then split whole groups rather than poses,
                a stricter floor (neighbouring frames of a clip are nearly identical).
        """
        x = _check_poses("reference", poses)
        if max_samples < 2:
            raise ValueError(f"max_samples must be >= 2, got {max_samples}")
        ks = tuple(int(k) for k in ks)
        if not ks or min(ks) < 1 or len(set(ks)) != len(ks):
            raise ValueError(f"ks must be distinct positive cluster counts, got {ks}")
        if x.shape[0] < 4:
            raise ValueError(f"need at least 4 reference poses, got {x.shape[0]}")
        centroids, self_metrics = {}, {}
        for k in ks:
            k_seed = int(np.random.SeedSequence([seed, 1, k]).generate_state(1)[0])
            c, lab, _ = kmeans(x, k, seed=k_seed, n_init=n_init)
            centroids[k] = c
            cov, ent = _occupancy(lab, k)
            _, d2 = _nearest(x, c)
            self_metrics[f"coverage_k{k}"] = cov
            self_metrics[f"entropy_k{k}"] = ent
            self_metrics[f"dist_k{k}"] = float(np.sqrt(d2).mean())
        sample = _subsample(x, max_samples, np.random.default_rng([seed, 2]))
        sigma = median_pairwise_distance(sample)
        if not sigma > 0:
            raise ValueError("reference poses are (nearly) all identical: median pairwise distance is 0")
        kyy = _kernel_mean(sample, sample, 1.0 / (2.0 * sigma * sigma))
        rng = np.random.default_rng([seed, 3])
        if groups is None:
            perm = rng.permutation(x.shape[0])
            a_idx, b_idx = np.sort(perm[: x.shape[0] // 2]), np.sort(perm[x.shape[0] // 2 :])
        else:
            g = np.asarray(groups)
            if g.shape != (x.shape[0],):
                raise ValueError(f"groups has shape {g.shape}, expected ({x.shape[0]},)")
            uniq = np.unique(g)
            if uniq.size < 2:
                raise ValueError("groups: need at least 2 groups for a split-half floor")
            ga = rng.permutation(uniq)[: uniq.size // 2]
            in_a = np.isin(g, ga)
            a_idx, b_idx = np.flatnonzero(in_a), np.flatnonzero(~in_a)
        half_a = _subsample(x[a_idx], max_samples, rng)
        half_b = _subsample(x[b_idx], max_samples, rng)
        floor = mmd_rbf(half_a, half_b, sigma)
        self_metrics["mmd"] = floor
        self_metrics["mmd_floor"] = floor
        self_metrics["n_generated"] = int(x.shape[0])
        return cls(
            centroids=centroids,
            sigma=sigma,
            mmd_sample=sample,
            mmd_floor=floor,
            n_reference=int(x.shape[0]),
            seed=int(seed),
            max_samples=int(max_samples),
            self_metrics=self_metrics,
            _kyy=kyy,
        )

    @classmethod
    def from_library(
        cls,
        library: Any,
        fps: float = DEFAULT_FPS,
        clips: Iterable[int | str] | None = None,
        split_by_clip: bool = False,
        **kwargs: Any,
    ) -> RealismReference:
        """:meth:`fit` on :func:`clip_poses` of a library (``split_by_clip``: the floor splits clips)."""
        poses, cid = clip_poses(library, fps=fps, clips=clips, return_clip_ids=True)
        return cls.fit(poses, groups=cid if split_by_clip else None, **kwargs)


def realism_metrics(
    generated: np.ndarray, reference: RealismReference, seed: int | None = None
) -> dict[str, float]:
    """Realism of generated poses (N, 45) against a fitted reference.

    Returns:
        ``coverage_k{K}``, ``entropy_k{K}``, ``dist_k{K}`` for each K of the reference (50 and 100 by
        default), ``mmd`` (biased estimate, square root, generated subsampled to ``max_samples`` with
        ``seed``, default the reference's), ``mmd_floor`` (the reference's split-half value) and
        ``n_generated``. All generated poses enter the k-means metrics.

    Raises:
        ValueError: ``generated`` is not (N, 45), is empty, or holds NaN/inf.
    """
    x = _check_poses("generated", generated)
    out: dict[str, float] = {}
    for k, c in reference.centroids.items():
        lab, d2 = _nearest(x, c)
        cov, ent = _occupancy(lab, k)
        out[f"coverage_k{k}"] = cov
        out[f"entropy_k{k}"] = ent
        out[f"dist_k{k}"] = float(np.sqrt(d2).mean())
    rng = np.random.default_rng(reference.seed if seed is None else seed)
    gen = _subsample(x, reference.max_samples, rng)
    kyy = reference._kyy if np.isfinite(reference._kyy) else None
    out["mmd"] = mmd_rbf(gen, reference.mmd_sample, reference.sigma, kyy=kyy)
    out["mmd_floor"] = float(reference.mmd_floor)
    out["n_generated"] = int(x.shape[0])
    return out


def library_realism(
    library: Any,
    reference: RealismReference,
    fps: float = DEFAULT_FPS,
    clips: Iterable[int | str] | None = None,
    seed: int | None = None,
) -> dict[str, float]:
    """:func:`realism_metrics` of all frames of a library's clips (resampled at ``fps``)."""
    return realism_metrics(clip_poses(library, fps=fps, clips=clips), reference, seed=seed)


__all__ = [
    "KEYPOINT_NAMES",
    "METRIC_KEYS",
    "RealismReference",
    "clip_poses",
    "clip_root_speeds",
    "hip_heading",
    "keypoints_from_state",
    "kmeans",
    "library_realism",
    "median_pairwise_distance",
    "mmd_rbf",
    "normalize_poses",
    "poses_from_state",
    "realism_metrics",
    "spine_length",
]
