"""ETH/UCY pedestrian trajectories: file loading, prediction windows, agent-centric frames, splits.

The files (``../shared/data/trajectories/eth_ucy``) are tab-separated ``frame ped x y`` rows, no
header, x and y in metres; all four columns are parsed as float (some files write ``780.0``). Frame
ids step by 10 per annotated row. One row step is 0.4 s, except in ``biwi_eth`` where it is 0.667 s
(the file was resampled; see ``../shared/data/README.md``, quirk 1): :func:`scene_dt` gives the step
and every window carries its ``dt``. Pedestrian ids are unique within one file only.

A *window* is one pedestrian present in ``obs_len + pred_len`` consecutive annotated frames
(8 + 12 by default: 3.2 s observed, 4.8 s predicted at 0.4 s). Its *neighbours* are the other
pedestrians present at the last observed frame, the ``k_neighbors`` nearest within ``radius`` metres,
with their histories (and futures) and validity masks.

Batch dict (what :func:`build_windows`, :func:`load_split` and the forecasters use), N windows,
K neighbour slots, T = obs_len, H = pred_len; positions in the batch's frame (see below):

============== =============== ==============================================================
key            shape / dtype   meaning
============== =============== ==============================================================
hist           (N, T, 2) f8    observed positions (m); ``hist[:, -1]`` is the current position
fut            (N, H, 2) f8    future positions (m), the prediction target
neigh          (N, K, T, 2) f8 neighbour histories (m); 0 where not valid
neigh_mask     (N, K, T) bool  neighbour present at that frame (all False for an empty slot)
neigh_fut      (N, K, H, 2) f8 neighbour futures (m); 0 where not valid
neigh_fut_mask (N, K, H) bool  neighbour present at that future frame
neigh_ped      (N, K) i8       neighbour pedestrian ids (-1 for an empty slot)
ped            (N,) i8         pedestrian id (unique within its scene file)
frame          (N,) i8         frame id of the last observed step
dt             (N,) f8         seconds per step of the window's scene
scene          (N,) str        scene name (file stem without ``_train``/``_val``)
origin         (N, 2) f8       world position of the batch frame's origin
rot            (N, 2, 2) f8    rotation of the batch frame: ``world = local @ rot + origin``
============== =============== ==============================================================

``build_windows`` returns the world frame (``origin`` 0, ``rot`` identity). :func:`normalize` moves
every window to its agent-centric frame: origin at the last observed position, +x along the last
observed heading (the latest non-zero step of the history; +x of the current frame if the person
stood still for the whole history). :func:`to_world` maps any ``(N, ..., 2)`` array of points of a
batch (e.g. predictions ``(N, S, H, 2)``) back to world coordinates, and :func:`random_rotation`
augments a batch by rotating each window about its origin (distances are preserved and ``to_world``
still undoes everything).

Splits (:func:`split_files`): ``"val"`` trains on ``train/<scene>_train.txt`` and tests on
``val/<scene>_val.txt`` (the files' temporal split); ``"loo"`` (leave one scene out) trains on
``all_data`` of every other scene and tests on ``all_data/<test_scene>.txt``.
"""

from __future__ import annotations

import os
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

__all__ = [
    "DEFAULT_DT",
    "SCENE_DT",
    "POSITION_KEYS",
    "Tracks",
    "default_data_dir",
    "scene_name",
    "scene_dt",
    "read_tracks",
    "resample_tracks",
    "discover",
    "split_files",
    "build_windows",
    "load_windows",
    "load_split",
    "concat",
    "batch_size",
    "subset",
    "heading_rotation",
    "transform",
    "normalize",
    "rotate",
    "random_rotation",
    "to_world",
    "to_local",
    "step_speeds",
]

#: Seconds per annotated row (frame ids stepping by 10) unless the scene is listed in SCENE_DT.
DEFAULT_DT = 0.4
#: Scenes with another time base (biwi_eth was resampled: one row is 0.667 s, quirk 1 of the data README).
SCENE_DT: dict[str, float] = {"biwi_eth": 0.667}
#: Position arrays of a batch and their validity masks (None: always valid); what transforms act on.
POSITION_KEYS: dict[str, str | None] = {
    "hist": None,
    "fut": None,
    "neigh": "neigh_mask",
    "neigh_fut": "neigh_fut_mask",
}
_SPLIT_SUFFIXES = ("_train", "_val")
# A step shorter than this (m) has no usable direction when defining the heading.
_MIN_STEP = 1e-3


def default_data_dir() -> Path:
    """The shared ETH/UCY folder: ``$NAVZOO_SHARED_DATA/trajectories/eth_ucy`` or ``<repo>/../shared/...``."""
    root = os.environ.get("NAVZOO_SHARED_DATA")
    base = Path(root) if root else Path(__file__).resolve().parents[2].parent / "shared" / "data"
    return base / "trajectories" / "eth_ucy"


def scene_name(path: str | Path) -> str:
    """Scene of a file: its stem without a ``_train`` / ``_val`` suffix (``biwi_eth_val.txt`` -> ``biwi_eth``)."""
    stem = Path(path).stem
    for suffix in _SPLIT_SUFFIXES:
        if stem.endswith(suffix):
            return stem[: -len(suffix)]
    return stem


def scene_dt(scene: str, overrides: Mapping[str, float] | None = None) -> float:
    """Seconds per annotated row of ``scene``: ``overrides``, then :data:`SCENE_DT`, else 0.4 s."""
    table = {**SCENE_DT, **(overrides or {})}
    dt = float(table.get(scene, DEFAULT_DT))
    if not dt > 0.0 or not np.isfinite(dt):
        raise ValueError(f"time step of scene {scene!r} must be a positive number, got {dt!r}")
    return dt


@dataclass(frozen=True)
class Tracks:
    """All rows of one ETH/UCY file, sorted by (frame, ped).

    Attributes:
        scene: Scene name.
        dt: Seconds per annotated row step.
        frame_step: Frame-id increment of one row step (10 in these files).
        frame: (M,) int64 frame ids.
        ped: (M,) int64 pedestrian ids.
        xy: (M, 2) float64 positions (m).
        path: The file read, if any.
    """

    scene: str
    dt: float
    frame_step: int
    frame: np.ndarray
    ped: np.ndarray
    xy: np.ndarray
    path: Path | None = None

    def trajectories(self) -> list[np.ndarray]:
        """Each pedestrian's positions in frame order, a list of (T_i, 2) arrays (tracks are gap-free here)."""
        order = np.lexsort((self.frame, self.ped))
        ped, xy = self.ped[order], self.xy[order]
        cuts = np.flatnonzero(np.diff(ped)) + 1
        return np.split(xy, cuts)


def _integral(name: str, values: np.ndarray, path: Path) -> np.ndarray:
    bad = np.flatnonzero(values != np.round(values))
    if bad.size:
        raise ValueError(f"{path}: {name} ids must be whole numbers, got {values[bad[0]]!r} (data row {bad[0] + 1})")
    return values.astype(np.int64)


def read_tracks(path: str | Path, scene: str | None = None, dt: float | None = None) -> Tracks:
    """Parse one tab/space-separated ``frame ped x y`` file (all columns as float).

    Args:
        path: The file.
        scene: Scene name; default :func:`scene_name` of the path.
        dt: Seconds per row step; default :func:`scene_dt` of the scene.

    Raises:
        FileNotFoundError: If the file does not exist.
        ValueError: On a malformed line (not four numbers, or not finite), non-integral ids, a
            pedestrian listed twice in one frame, frame ids that are not on a common step, or an
            empty file. The message names the file and the line.
    """
    path = Path(path)
    rows: list[list[float]] = []
    with path.open() as fh:
        for lineno, line in enumerate(fh, 1):
            parts = line.split()
            if not parts:
                continue
            if len(parts) != 4:
                raise ValueError(f"{path}:{lineno}: expected 4 columns 'frame ped x y', got {len(parts)}: {line.strip()!r}")
            try:
                values = [float(p) for p in parts]
            except ValueError as exc:
                raise ValueError(f"{path}:{lineno}: not a number in {line.strip()!r}") from exc
            if not all(np.isfinite(values)):
                raise ValueError(f"{path}:{lineno}: non-finite value in {line.strip()!r}")
            rows.append(values)
    if not rows:
        raise ValueError(f"{path}: no trajectory rows")
    data = np.asarray(rows, dtype=np.float64)
    frame = _integral("frame", data[:, 0], path)
    ped = _integral("pedestrian", data[:, 1], path)
    order = np.lexsort((ped, frame))
    frame, ped, xy = frame[order], ped[order], data[order, 2:4]
    dup = np.flatnonzero((np.diff(frame) == 0) & (np.diff(ped) == 0))
    if dup.size:
        raise ValueError(f"{path}: pedestrian {ped[dup[0]]} appears twice in frame {frame[dup[0]]}")
    steps = np.diff(np.unique(frame))
    frame_step = int(np.gcd.reduce(steps)) if steps.size else 1
    scene = scene or scene_name(path)
    return Tracks(scene=scene, dt=scene_dt(scene) if dt is None else float(dt), frame_step=max(frame_step, 1),
                  frame=frame, ped=ped, xy=xy, path=path)


def resample_tracks(tracks: Tracks, dt: float) -> Tracks:
    """The same people on another time base: every track linearly interpolated at the times
    ``k * dt`` (from the file's first row) that fall within it.

    Used to train a forecaster for a scene recorded at another rate than its training scenes (the
    0.667 s rows of ``biwi_eth`` against 0.4 s elsewhere) without touching the held-out scene. Each
    pedestrian's rows must be gap-free (as in these files); a track shorter than one new step
    disappears. The result has ``frame_step`` 10 and synthetic frame ids ``10 k``.

    Raises:
        ValueError: If ``dt`` is not a positive finite number, or a pedestrian's track has a gap.
    """
    dt = float(dt)
    if not (np.isfinite(dt) and dt > 0.0):
        raise ValueError(f"resampling time step must be a positive number, got {dt!r}")
    t_row = (tracks.frame - tracks.frame.min()) / tracks.frame_step * tracks.dt
    order = np.lexsort((tracks.frame, tracks.ped))
    ped, t, xy, frame = tracks.ped[order], t_row[order], tracks.xy[order], tracks.frame[order]
    cuts = np.flatnonzero(np.diff(ped)) + 1
    out_k, out_ped, out_xy = [], [], []
    for idx in np.split(np.arange(ped.size), cuts):
        if idx.size and np.any(np.diff(frame[idx]) != tracks.frame_step):
            raise ValueError(f"{tracks.path or tracks.scene}: pedestrian {ped[idx[0]]} has a gap in its track; "
                             "resampling needs gap-free tracks")
        ts = t[idx]
        k = np.arange(np.ceil(ts[0] / dt - 1e-9), np.floor(ts[-1] / dt + 1e-9) + 1).astype(np.int64)
        if k.size == 0:
            continue
        times = k * dt
        out_k.append(k)
        out_ped.append(np.full(k.size, ped[idx[0]]))
        out_xy.append(np.stack([np.interp(times, ts, xy[idx, 0]), np.interp(times, ts, xy[idx, 1])], axis=1))
    if not out_k:
        raise ValueError(f"{tracks.path or tracks.scene}: no track is longer than one step of {dt} s")
    k_all, ped_all, xy_all = np.concatenate(out_k), np.concatenate(out_ped), np.concatenate(out_xy)
    order = np.lexsort((ped_all, k_all))
    return Tracks(scene=tracks.scene, dt=dt, frame_step=10, frame=10 * k_all[order], ped=ped_all[order],
                  xy=xy_all[order], path=tracks.path)


def discover(data_dir: str | Path) -> dict[str, dict[str, Path]]:
    """The scene files of an ETH/UCY folder, as ``{"all": {...}, "train": {...}, "val": {...}}`` (scene -> path).

    Uses the ``all_data/``, ``train/`` and ``val/`` sub-folders when present; a flat folder of
    ``.txt`` files is sorted by suffix (``*_train.txt``, ``*_val.txt``, the rest as ``all``).

    Raises:
        FileNotFoundError: If the folder does not exist or holds no ``.txt`` file.
    """
    root = Path(data_dir)
    if not root.is_dir():
        raise FileNotFoundError(f"data folder {root} does not exist")
    out: dict[str, dict[str, Path]] = {"all": {}, "train": {}, "val": {}}
    subdirs = {"all": root / "all_data", "train": root / "train", "val": root / "val"}
    if any(d.is_dir() for d in subdirs.values()):
        for part, folder in subdirs.items():
            if folder.is_dir():
                out[part] = {scene_name(p): p for p in sorted(folder.glob("*.txt"))}
    else:
        for p in sorted(root.glob("*.txt")):
            part = "train" if p.stem.endswith("_train") else "val" if p.stem.endswith("_val") else "all"
            out[part][scene_name(p)] = p
    if not any(out.values()):
        raise FileNotFoundError(f"no trajectory .txt files in {root}")
    return out


def split_files(data_dir: str | Path, split: str, test_scene: str | None = None) -> tuple[dict[str, Path], dict[str, Path]]:
    """Train and test files (scene -> path) of a split.

    Args:
        data_dir: An ETH/UCY folder (see :func:`discover`).
        split: ``"val"`` (train files / val files of every scene) or ``"loo"`` (``all_data`` of every
            scene but ``test_scene`` / ``all_data`` of ``test_scene``).
        test_scene: The held-out scene of ``"loo"``; ignored for ``"val"``.

    Raises:
        ValueError: On an unknown split, a missing or unknown test scene, or a split whose files
            are not in the folder.
    """
    files = discover(data_dir)
    if split == "val":
        if not files["val"]:
            raise ValueError(f"split 'val' needs val/<scene>_val.txt files, none in {data_dir}")
        return dict(files["train"]), dict(files["val"])
    if split == "loo":
        scenes = files["all"]
        if not scenes:
            raise ValueError(f"split 'loo' needs all_data/<scene>.txt files, none in {data_dir}")
        if test_scene is None:
            raise ValueError(f"split 'loo' needs the held-out scene (--test-scene); scenes: {sorted(scenes)}")
        if test_scene not in scenes:
            raise ValueError(f"unknown test scene {test_scene!r} for split 'loo'; scenes: {sorted(scenes)}")
        return {s: p for s, p in scenes.items() if s != test_scene}, {test_scene: scenes[test_scene]}
    raise ValueError(f"unknown split {split!r}; expected 'val' or 'loo'")


def _empty_batch(obs_len: int, pred_len: int, k: int) -> dict[str, Any]:
    return {
        "hist": np.zeros((0, obs_len, 2)), "fut": np.zeros((0, pred_len, 2)),
        "neigh": np.zeros((0, k, obs_len, 2)), "neigh_mask": np.zeros((0, k, obs_len), bool),
        "neigh_fut": np.zeros((0, k, pred_len, 2)), "neigh_fut_mask": np.zeros((0, k, pred_len), bool),
        "neigh_ped": np.zeros((0, k), np.int64), "ped": np.zeros(0, np.int64), "frame": np.zeros(0, np.int64),
        "dt": np.zeros(0), "scene": np.zeros(0, dtype="<U1"), "origin": np.zeros((0, 2)),
        "rot": np.zeros((0, 2, 2)),
    }


def window_arrays(
    grid: np.ndarray, piece: np.ndarray, t0: np.ndarray, p: np.ndarray, obs_len: int, pred_len: int, k: int,
    radius: float,
) -> tuple[dict[str, np.ndarray], np.ndarray, np.ndarray, np.ndarray]:
    """The trajectory arrays of windows (``obs_len + pred_len`` frames) starting at frames ``t0`` for
    persons ``p`` (the caller checks that each person is there for the whole window).

    ``grid`` (F, P, 2) holds every person's position per frame (NaN where absent) and ``piece``
    (F, P) a track-piece id: a neighbour counts at a step where it is present and on the same piece
    as at the last observed frame. Neighbours are the ``k`` nearest present within ``radius`` at
    the last observed frame, nearest first.

    Returns the keys ``hist``, ``fut``, ``neigh``, ``neigh_mask``, ``neigh_fut``, ``neigh_fut_mask``,
    and the neighbours' person indices (N, k), their ``ok`` flags (N, k) and the last observed frames (N,).
    """
    n, n_p = t0.size, grid.shape[1]
    length = obs_len + pred_len
    steps = t0[:, None] + np.arange(length)  # (N, L)
    track = grid[steps, p[:, None]]  # (N, L, 2)
    t_last = t0 + obs_len - 1
    dist = np.linalg.norm(grid[t_last] - track[:, obs_len - 1][:, None, :], axis=2)  # (N, P)
    dist = np.where(np.isnan(dist), np.inf, dist)
    dist[np.arange(n), p] = np.inf
    dist[dist > radius] = np.inf
    k_eff = min(k, n_p)
    nearest = np.argsort(dist, axis=1, kind="stable")[:, :k_eff]  # (N, k_eff)
    ok = np.isfinite(np.take_along_axis(dist, nearest, axis=1))
    neigh_track = grid[steps[:, None, :], nearest[:, :, None]]  # (N, k_eff, L, 2)
    same_piece = piece[steps[:, None, :], nearest[:, :, None]] == piece[t_last[:, None], nearest][..., None]
    valid = ~np.isnan(neigh_track[..., 0]) & same_piece & ok[..., None]
    neigh_track = np.where(valid[..., None], neigh_track, 0.0)
    pad = k - k_eff
    if pad:
        neigh_track = np.concatenate([neigh_track, np.zeros((n, pad, length, 2))], axis=1)
        valid = np.concatenate([valid, np.zeros((n, pad, length), bool)], axis=1)
        ok = np.concatenate([ok, np.zeros((n, pad), bool)], axis=1)
        nearest = np.concatenate([nearest, np.zeros((n, pad), np.int64)], axis=1)
    core = {
        "hist": track[:, :obs_len].copy(),
        "fut": track[:, obs_len:].copy(),
        "neigh": neigh_track[:, :, :obs_len].copy(),
        "neigh_mask": valid[:, :, :obs_len].copy(),
        "neigh_fut": neigh_track[:, :, obs_len:].copy(),
        "neigh_fut_mask": valid[:, :, obs_len:].copy(),
    }
    return core, nearest, ok, t_last


def build_windows(
    tracks: Tracks,
    obs_len: int = 8,
    pred_len: int = 12,
    k_neighbors: int = 16,
    radius: float = 10.0,
    stride: int = 1,
) -> dict[str, Any]:
    """All prediction windows of one scene, in the world frame (see the module doc for the keys).

    Args:
        tracks: The scene's rows (:func:`read_tracks`).
        obs_len: Observed steps T (>= 2).
        pred_len: Predicted steps H (>= 1).
        k_neighbors: Neighbour slots K (>= 0): the K nearest pedestrians present at the last observed
            frame, nearest first.
        radius: Neighbours farther than this (m) from the person at the last observed frame are left out.
        stride: Start a window every ``stride`` row steps (1: every frame, the usual protocol).

    Raises:
        ValueError: On out-of-range arguments.
    """
    if obs_len < 2 or pred_len < 1 or k_neighbors < 0 or stride < 1:
        raise ValueError(f"need obs_len >= 2, pred_len >= 1, k_neighbors >= 0, stride >= 1; got "
                         f"{obs_len}, {pred_len}, {k_neighbors}, {stride}")
    if not radius > 0:
        raise ValueError(f"radius must be > 0, got {radius!r}")
    length = obs_len + pred_len
    f_idx = (tracks.frame - tracks.frame.min()) // tracks.frame_step
    peds, p_idx = np.unique(tracks.ped, return_inverse=True)
    n_f, n_p = int(f_idx.max()) + 1, peds.size
    grid = np.full((n_f, n_p, 2), np.nan)
    grid[f_idx, p_idx] = tracks.xy
    present = ~np.isnan(grid[..., 0])

    # Windows: (t0, p) with p present at every frame t0 .. t0 + length - 1.
    counts = np.concatenate([np.zeros((1, n_p), np.int64), np.cumsum(present, axis=0)])
    if n_f < length:
        batch = _empty_batch(obs_len, pred_len, k_neighbors)
        return batch
    full = (counts[length:] - counts[:-length]) == length  # (n_f - length + 1, P)
    full[np.arange(full.shape[0]) % stride != 0] = False
    t0, p = np.nonzero(full)
    n = t0.size
    if n == 0:
        return _empty_batch(obs_len, pred_len, k_neighbors)
    core, nearest, ok, t_last = window_arrays(grid, np.zeros(grid.shape[:2], np.int64), t0, p, obs_len,
                                              pred_len, k_neighbors, radius)
    frame0 = tracks.frame.min()
    return {
        **core,
        "neigh_ped": np.where(ok, peds[nearest], -1).astype(np.int64),
        "ped": peds[p].astype(np.int64),
        "frame": (frame0 + t_last * tracks.frame_step).astype(np.int64),
        "dt": np.full(n, tracks.dt),
        "scene": np.full(n, tracks.scene),
        "origin": np.zeros((n, 2)),
        "rot": np.broadcast_to(np.eye(2), (n, 2, 2)).copy(),
    }


def load_windows(
    path: str | Path,
    normalized: bool = True,
    dt: float | None = None,
    **window_kwargs: Any,
) -> dict[str, Any]:
    """Windows of one file (:func:`read_tracks` + :func:`build_windows`), agent-centric unless ``normalized=False``."""
    batch = build_windows(read_tracks(path, dt=dt), **window_kwargs)
    return normalize(batch) if normalized else batch


def load_split(
    data_dir: str | Path | None = None,
    split: str = "val",
    part: str = "test",
    test_scene: str | None = None,
    normalized: bool = True,
    **window_kwargs: Any,
) -> dict[str, dict[str, Any]]:
    """Windows of every scene of one side of a split, as ``{scene: batch}``.

    Args:
        data_dir: ETH/UCY folder; default :func:`default_data_dir`.
        split: ``"val"`` or ``"loo"`` (see :func:`split_files`).
        part: ``"train"`` or ``"test"``.
        test_scene: Held-out scene of ``"loo"``.
        normalized: Agent-centric frames (default) or world frame.
        **window_kwargs: Passed to :func:`build_windows` (obs_len, pred_len, k_neighbors, radius, stride).

    Raises:
        ValueError: On an unknown split, part or scene.
    """
    if part not in ("train", "test"):
        raise ValueError(f"unknown part {part!r}; expected 'train' or 'test'")
    train, test = split_files(data_dir or default_data_dir(), split, test_scene)
    files = train if part == "train" else test
    return {scene: load_windows(path, normalized=normalized, **window_kwargs) for scene, path in files.items()}


def batch_size(batch: Mapping[str, Any]) -> int:
    """Number of windows N of a batch."""
    return int(np.asarray(batch["hist"]).shape[0])


def concat(batches: Iterable[Mapping[str, Any]]) -> dict[str, Any]:
    """Concatenate batches along the window axis (they must have the same keys and K).

    Raises:
        ValueError: If no batch is given or their keys differ.
    """
    batches = list(batches)
    if not batches:
        raise ValueError("concat needs at least one batch")
    keys = set(batches[0])
    for i, b in enumerate(batches[1:], 1):
        if set(b) != keys:
            raise ValueError(f"batch {i} has keys {sorted(b)}, batch 0 has {sorted(keys)}")
    return {key: np.concatenate([np.asarray(b[key]) for b in batches], axis=0) for key in batches[0]}


def subset(batch: Mapping[str, Any], index: np.ndarray | slice | Sequence[int]) -> dict[str, Any]:
    """The windows ``index`` (indices, boolean mask or slice) of a batch."""
    return {key: np.asarray(value)[index] for key, value in batch.items()}


def heading_rotation(theta: np.ndarray) -> np.ndarray:
    """World-to-local rotations (N, 2, 2) that turn the directions ``theta`` (rad) onto +x."""
    c, s = np.cos(theta), np.sin(theta)
    return np.stack([np.stack([c, s], axis=-1), np.stack([-s, c], axis=-1)], axis=-2)


def _apply(points: np.ndarray, origin: np.ndarray, rot: np.ndarray) -> np.ndarray:
    """local = (p - origin) @ rot.T for (N, ..., 2) points."""
    n = points.shape[0]
    shaped = (points.reshape(n, -1, 2) - origin[:, None, :])
    return np.einsum("nij,nmj->nmi", rot, shaped).reshape(points.shape)


def transform(batch: Mapping[str, Any], origin: np.ndarray, rot: np.ndarray) -> dict[str, Any]:
    """Move a batch into a new frame given in the batch's current frame.

    The new coordinates are ``local = rot @ (p - origin)`` for every position of :data:`POSITION_KEYS`
    (invalid neighbour entries stay 0), and ``batch["origin"]`` / ``batch["rot"]`` are composed so that
    :func:`to_world` keeps mapping back to the world frame.

    Args:
        batch: A batch dict.
        origin: (N, 2) new origin, in the current frame.
        rot: (N, 2, 2) current-to-new rotation matrices.

    Raises:
        ValueError: On wrong shapes.
    """
    n = batch_size(batch)
    origin = np.asarray(origin, dtype=np.float64)
    rot = np.asarray(rot, dtype=np.float64)
    if origin.shape != (n, 2) or rot.shape != (n, 2, 2):
        raise ValueError(f"origin must be ({n}, 2) and rot ({n}, 2, 2), got {origin.shape} and {rot.shape}")
    out = dict(batch)
    for key, mask_key in POSITION_KEYS.items():
        if key not in batch:
            continue
        moved = _apply(np.asarray(batch[key], dtype=np.float64), origin, rot)
        if mask_key is not None:
            moved = np.where(np.asarray(batch[mask_key])[..., None], moved, 0.0)
        out[key] = moved
    old_rot = np.asarray(batch["rot"], dtype=np.float64)
    # world = p_cur @ R1 + o1 and p_cur = p_new @ R2 + o2  =>  world = p_new @ (R2 R1) + (o2 @ R1 + o1)
    out["origin"] = np.einsum("nj,njk->nk", origin, old_rot) + np.asarray(batch["origin"], dtype=np.float64)
    out["rot"] = np.einsum("nij,njk->nik", rot, old_rot)
    return out


def normalize(batch: Mapping[str, Any]) -> dict[str, Any]:
    """Agent-centric frame: origin at ``hist[:, -1]``, +x along the last observed heading.

    The heading is the direction of the latest history step longer than 1 mm; a person who stood
    still for the whole history keeps the current frame's orientation.
    """
    hist = np.asarray(batch["hist"], dtype=np.float64)
    steps = np.diff(hist, axis=1)  # (N, T-1, 2)
    moving = np.linalg.norm(steps, axis=2) > _MIN_STEP
    last = steps.shape[1] - 1 - np.argmax(moving[:, ::-1], axis=1)
    step = steps[np.arange(hist.shape[0]), last]
    theta = np.where(moving.any(axis=1), np.arctan2(step[:, 1], step[:, 0]), 0.0)
    return transform(batch, hist[:, -1], heading_rotation(theta))


def rotate(batch: Mapping[str, Any], angles: np.ndarray) -> dict[str, Any]:
    """Rotate every window counter-clockwise by ``angles`` (N,) rad about its frame's origin."""
    n = batch_size(batch)
    angles = np.broadcast_to(np.asarray(angles, dtype=np.float64), (n,))
    return transform(batch, np.zeros((n, 2)), heading_rotation(-angles))


def random_rotation(batch: Mapping[str, Any], rng: np.random.Generator) -> dict[str, Any]:
    """Training augmentation: rotate each window by an angle drawn uniformly from [0, 2 pi)."""
    return rotate(batch, rng.uniform(0.0, 2.0 * np.pi, size=batch_size(batch)))


def to_world(points: np.ndarray, batch: Mapping[str, Any]) -> np.ndarray:
    """Map (N, ..., 2) points given in the batch's frame (e.g. samples (N, S, H, 2)) to world coordinates."""
    points = np.asarray(points, dtype=np.float64)
    n = points.shape[0]
    rot = np.asarray(batch["rot"], dtype=np.float64)
    world = np.einsum("nmj,njk->nmk", points.reshape(n, -1, 2), rot) + np.asarray(batch["origin"])[:, None, :]
    return world.reshape(points.shape)


def to_local(points: np.ndarray, batch: Mapping[str, Any]) -> np.ndarray:
    """Inverse of :func:`to_world`: (N, ..., 2) world points into the batch's frame."""
    points = np.asarray(points, dtype=np.float64)
    return _apply(points, np.asarray(batch["origin"], dtype=np.float64), np.asarray(batch["rot"], dtype=np.float64))


def step_speeds(tracks: Tracks) -> np.ndarray:
    """Speeds (m/s) of every consecutive pair of rows of a pedestrian, using the scene's dt."""
    order = np.lexsort((tracks.frame, tracks.ped))
    ped, frame, xy = tracks.ped[order], tracks.frame[order], tracks.xy[order]
    same = (np.diff(ped) == 0) & (np.diff(frame) == tracks.frame_step)
    return np.linalg.norm(np.diff(xy, axis=0), axis=1)[same] / tracks.dt
