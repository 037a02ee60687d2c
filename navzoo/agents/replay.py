"""Replay crowd: real ETH/UCY pedestrian tracks played back in a matching open scene.

``NavConfig(crowd_model="replay", replay_scene="eth", replay_start=120.0)`` plays the recording
``eth`` from 120 s on, for the episode's time limit, in the scene ``replay_eth`` (built from the data:
see :func:`replay_scene`). This is SocNavBench's setting: the robot navigates among replayed real
people who **do not react to it** (they walk their recorded paths whatever the robot does, and may
walk into it; that is counted as the robot's collision, as in SocNavBench).

Recordings ship with the package in ``navzoo/assets/tracks/<file stem>.npz`` (arrays only), converted
from the ETH/UCY text files of the shared data set by ``navzoo tracks convert`` (:func:`convert_tracks`);
:func:`load_recording` with a ``data_dir`` reads the text files of that folder instead:

============ ==================== =========================================================
name         file (``all_data/``) notes
============ ==================== =========================================================
eth          biwi_eth             0.667 s per row (the file was resampled, data README quirk 1)
hotel        biwi_hotel           not in the shared data set: a clear error unless added
univ         students001          (students003 if students001 is missing)
zara1        crowds_zara01
zara2        crowds_zara02        not in the shared data set: a clear error unless added
zara3        crowds_zara03
uni_examples uni_examples
============ ==================== =========================================================

The file stems (``biwi_eth``, ``crowds_zara01``, ...) are accepted as aliases of these names.

Time: a row of the file at frame ``f`` is at ``(f - f_0) / frame_step * dt_data`` seconds of the
recording (``f_0`` its first frame). Env step ``k`` shows the recording at ``replay_start + k * dt``.
Each person is **linearly interpolated** between their samples (0.4 s, 0.667 s for eth); their
velocity is the derivative of that interpolant (constant between two samples) and their heading the
direction of that velocity (held from the nearest moving stretch while the person stands still,
below 0.1 m/s). A person is *active* from their first to their last sample (inclusive) and nowhere
otherwise: no extrapolation.

Slots: the env has a fixed number of pedestrian agents ``human_0..human_{H-1}``. Tracks are given to
slots greedily in order of appearance (ties by pedestrian id), each to the lowest-numbered free slot;
a slot becomes free the step after its person's last sample. With ``n_humans=None`` the env gets
exactly the largest number of people present at once in the window, so every track in the window is
played. With a smaller ``n_humans``, a person who appears while every slot is taken is **dropped for
their whole track** (first come, first served: nobody vanishes in mid-walk); ``ReplayCrowd.dropped``
counts them. Extra slots stay inactive.

Inactive slots (not yet appeared, left, or unused) are *parked* 1 km beyond the scene's east wall,
3 m apart: ``env.human_active`` is False for them, and the env leaves them out of every robot's and
person's observation (also in the observation history: a person's past positions from before they
appeared are masked), of collisions, of clearances and rewards, and of the top-down rendering.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from navzoo.forecast.data import Tracks
from navzoo.world.scene import Protocol, Scene, WallObstacle

__all__ = [
    "RECORDINGS",
    "PARK_DISTANCE",
    "Recording",
    "ReplayCrowd",
    "canonical_recording",
    "convert_tracks",
    "load_recording",
    "replay_scene",
    "scene_from_name",
]

#: Recording names and the file stems they map to, in order of preference.
RECORDINGS: dict[str, tuple[str, ...]] = {
    "eth": ("biwi_eth",),
    "hotel": ("biwi_hotel",),
    "univ": ("students001", "students003"),
    "zara1": ("crowds_zara01",),
    "zara2": ("crowds_zara02",),
    "zara3": ("crowds_zara03",),
    "uni_examples": ("uni_examples",),
}
_ALIASES: dict[str, str] = {name: name for name in RECORDINGS}
for _name, _stems in RECORDINGS.items():
    for _stem in _stems:
        _ALIASES.setdefault(_stem, _name)
#: The packaged recordings (``navzoo tracks convert`` writes them from the shared ETH/UCY files).
TRACKS_DIR = Path(__file__).resolve().parents[1] / "assets" / "tracks"
TRACKS_FORMAT = 1
SCENE_PREFIX = "replay_"
#: Free space kept around the recording's bounding box, inside the walls (m).
SCENE_MARGIN = 1.0
WALL_THICKNESS = 0.2
#: Inactive people stand this far east of the scene's bounds (m), 3 m apart.
PARK_DISTANCE = 1000.0
PARK_SPACING = 3.0
#: Below this speed (m/s) a person's heading is held from the nearest moving stretch.
STILL_SPEED = 0.1
_EPS = 1e-9


def canonical_recording(name: str) -> str:
    """The recording name for ``name`` (a name of :data:`RECORDINGS` or a file stem).

    Raises:
        ValueError: for an unknown name, listing the valid ones.
    """
    if isinstance(name, str) and name in _ALIASES:
        return _ALIASES[name]
    raise ValueError(f"unknown replay recording {name!r}; valid recordings: {', '.join(RECORDINGS)} "
                     f"(or the file stems {', '.join(s for v in RECORDINGS.values() for s in v)})")


@dataclass(frozen=True)
class Recording:
    """One ETH/UCY recording in the frame of its replay scene.

    Attributes:
        name: recording name (``"eth"``, ...).
        stem: the file it was read from (its stem, e.g. ``"biwi_eth"``).
        path: that file.
        dt: seconds between two samples of a track.
        offset: (2,) subtracted from the file's coordinates: scene coordinates = file - offset (the
            bounding box of all positions is centred on the origin, to 0.1 m).
        ped: (P,) pedestrian ids.
        t0: (P,) time of each track's first sample (s since the recording's first frame).
        xy: P arrays (T_i, 2) of positions in scene coordinates, one per ``dt``.
        duration: time of the last sample of the recording (s).
        bbox: (xmin, ymin, xmax, ymax) of all positions, scene coordinates.
        walls: (K, 2, 2) wall lines of the real scene (OpenTraj ``map.xml``; only ``eth`` has them), scene
            coordinates; (0, 2, 2) for a recording without a map.
    """

    name: str
    stem: str
    path: Path
    dt: float
    offset: np.ndarray
    ped: np.ndarray
    t0: np.ndarray
    xy: tuple[np.ndarray, ...]
    duration: float
    bbox: tuple[float, float, float, float]
    walls: np.ndarray = field(default_factory=lambda: np.zeros((0, 2, 2)))

    def t1(self) -> np.ndarray:
        """(P,) time of each track's last sample."""
        return self.t0 + np.array([len(x) - 1 for x in self.xy]) * self.dt

    def positions_at(self, t: float) -> dict[int, np.ndarray]:
        """Linearly interpolated positions ``{ped: (2,)}`` of everyone present at recording time ``t``."""
        out = {}
        for i, pid in enumerate(self.ped):
            times = self.t0[i] + np.arange(len(self.xy[i])) * self.dt
            if times[0] - 1e-9 <= t <= times[-1] + 1e-9:
                out[int(pid)] = np.array([np.interp(t, times, self.xy[i][:, 0]), np.interp(t, times, self.xy[i][:, 1])])
        return out


def _find_file(name: str, data_dir: Path | None) -> Path:
    """The recording's file: a packaged ``.npz`` (``data_dir`` None) or a text file of ``data_dir``."""
    if data_dir is None:
        root = TRACKS_DIR
        files = {p.stem: p for p in sorted(root.glob("*.npz"))}
    else:
        from navzoo.forecast.data import discover

        root = Path(data_dir)
        try:
            found = discover(root)
        except FileNotFoundError as exc:
            raise FileNotFoundError(f"replay recording {name!r}: {exc}") from None
        files = found["all"] or found["train"]
    for stem in RECORDINGS[name]:
        if stem in files:
            return files[stem]
    have = [n for n, stems in RECORDINGS.items() if any(s in files for s in stems)]
    where = f"the packaged tracks ({root})" if data_dir is None else str(root)
    raise ValueError(f"replay recording {name!r} ({' or '.join(RECORDINGS[name])}) is not in "
                     f"{where}; recordings available there: {', '.join(have) or 'none'}")


def _read_npz(path: Path) -> tuple[Tracks, np.ndarray]:
    """A packaged recording written by :func:`convert_tracks` (arrays only, no pickles): its tracks and
    its wall lines (K, 2, 2) in the file's frame (none in files written before walls were packaged)."""
    try:
        with np.load(path, allow_pickle=False) as z:
            if int(z["format_version"]) != TRACKS_FORMAT:
                raise ValueError(f"format version {int(z['format_version'])}, expected {TRACKS_FORMAT}")
            walls = z["walls"].astype(np.float64) if "walls" in z.files else np.zeros((0, 4))
            if walls.ndim != 2 or walls.shape[1] != 4 or not np.all(np.isfinite(walls)):
                raise ValueError(f"walls: expected finite (K, 4) segments, got shape {walls.shape}")
            tracks = Tracks(scene=str(z["scene"]), dt=float(z["dt"]), frame_step=int(z["frame_step"]),
                            frame=z["frame"].astype(np.int64), ped=z["ped"].astype(np.int64),
                            xy=z["xy"].astype(np.float64), path=path)
            return tracks, walls.reshape(-1, 2, 2)
    except (KeyError, ValueError, OSError) as exc:
        raise ValueError(f"{path}: not a navzoo track file ({exc}); rebuild the packaged tracks with "
                         "`navzoo tracks convert`") from None


def convert_tracks(data_dir: str | Path | None = None, out_dir: str | Path | None = None,
                   map_dir: str | Path | None = None) -> list[Path]:
    """Convert the ETH/UCY text files (``all_data/`` of ``data_dir``, default the shared data folder)
    into the packaged ``<stem>.npz`` files of ``out_dir`` (default :data:`TRACKS_DIR`): frame and
    pedestrian ids, positions (float64, as in the files), the time step (biwi_eth 0.667 s), the
    source file's SHA-256, and the scene's wall lines (``walls``, (K, 4): x1, y1, x2, y2 in the file's
    frame) from the OpenTraj ``map.xml`` of ``map_dir`` (default: the ``opentraj`` folder beside
    ``data_dir``; ``"none"``: no walls) where the scene has one (``biwi_eth``). Returns the files
    written. ``navzoo tracks convert`` runs it.

    Raises:
        FileNotFoundError: No ETH/UCY files, or a scene with an OpenTraj map whose ``map.xml`` is missing
            (pass ``map_dir="none"`` to convert without walls).
    """
    import hashlib

    from navzoo.forecast.data import default_data_dir, discover, read_tracks
    from navzoo.forecast.scene_maps import opentraj_walls

    root = Path(data_dir) if data_dir is not None else default_data_dir()
    files = discover(root)["all"]
    if not files:
        raise FileNotFoundError(f"no ETH/UCY files in {root / 'all_data'}")
    no_maps = isinstance(map_dir, str) and map_dir.lower() == "none"
    maps = None if no_maps else (Path(map_dir) if map_dir is not None else root.parent / "opentraj")
    out = Path(out_dir) if out_dir is not None else TRACKS_DIR
    out.mkdir(parents=True, exist_ok=True)
    written = []
    for stem, path in sorted(files.items()):
        tr = read_tracks(path)
        walls = None
        if maps is not None:
            try:
                walls = opentraj_walls(stem, maps)
            except FileNotFoundError as exc:
                raise FileNotFoundError(f"{exc}; pass the OpenTraj folder (--maps DIR) or convert without "
                                        "walls (--maps none)") from None
        walls = np.zeros((0, 4)) if walls is None else np.asarray(walls).reshape(-1, 4)
        target = out / f"{stem}.npz"
        np.savez_compressed(target, format_version=np.int64(TRACKS_FORMAT), scene=np.str_(tr.scene),
                            dt=np.float64(tr.dt), frame_step=np.int64(tr.frame_step), frame=tr.frame.astype(np.int32),
                            ped=tr.ped.astype(np.int32), xy=tr.xy, walls=walls,
                            source_sha256=np.str_(hashlib.sha256(path.read_bytes()).hexdigest()))
        written.append(target)
    return written


@functools.cache
def _load(name: str, data_dir: str | None) -> Recording:
    from navzoo.forecast.data import read_tracks
    from navzoo.forecast.scene_maps import opentraj_walls

    path = _find_file(name, Path(data_dir) if data_dir else None)
    if path.suffix == ".npz":
        tracks, walls = _read_npz(path)
    else:  # text files: the walls of the OpenTraj folder beside data_dir, if it is there
        tracks = read_tracks(path)
        try:
            walls = opentraj_walls(path.stem, Path(data_dir).parent / "opentraj")
        except FileNotFoundError:
            walls = None
        walls = np.zeros((0, 2, 2)) if walls is None else walls
    step = (tracks.frame - tracks.frame.min()) // tracks.frame_step
    lo, hi = tracks.xy.min(axis=0), tracks.xy.max(axis=0)
    offset = np.round(0.5 * (lo + hi), 1)
    peds, t0, xys = [], [], []
    for pid in np.unique(tracks.ped):
        sel = np.flatnonzero(tracks.ped == pid)
        k = step[sel]
        order = np.argsort(k)
        k, xy = k[order], tracks.xy[sel][order] - offset
        # The shared files have no gaps; a gap would be bridged by the linear interpolation.
        if len(k) > 1 and np.any(np.diff(k) != 1):
            full = np.arange(k[0], k[-1] + 1)
            xy = np.stack([np.interp(full, k, xy[:, 0]), np.interp(full, k, xy[:, 1])], axis=1)
        peds.append(int(pid))
        t0.append(float(k[0]) * tracks.dt)
        xys.append(xy)
    for arr in xys:
        arr.setflags(write=False)
    blo, bhi = lo - offset, hi - offset
    walls = np.asarray(walls, dtype=np.float64) - offset
    walls.setflags(write=False)
    return Recording(name=name, stem=path.stem, path=path, dt=float(tracks.dt), offset=offset,
                     ped=np.array(peds, dtype=np.int64), t0=np.array(t0), xy=tuple(xys),
                     duration=float(step.max()) * tracks.dt,
                     bbox=(float(blo[0]), float(blo[1]), float(bhi[0]), float(bhi[1])), walls=walls)


def load_recording(name: str, data_dir: str | Path | None = None) -> Recording:
    """The recording ``name`` (see :data:`RECORDINGS`), read once and cached.

    Raises:
        ValueError: unknown name, or its file is not in the data folder.
        FileNotFoundError: no data folder.
    """
    return _load(canonical_recording(name), str(data_dir) if data_dir is not None else None)


# ------------------------------------------------------------------------------------------ scene


def replay_scene(name: str) -> Scene:
    """The open scene matching recording ``name``: ``replay_<name>``.

    Free space covers the bounding box of every recorded position plus :data:`SCENE_MARGIN` (1 m)
    on each side, in the recording's coordinates shifted by ``Recording.offset`` (bounding box
    centred on the origin); 0.2 m walls close it. Inside, the real scene's walls where the data has
    them (``Recording.walls``: ``eth``'s walkway sides and building front with its entrance, from
    OpenTraj's ``map.xml``, as 0.2 m walls centred on the lines); the UCY recordings have none (their
    OpenTraj annotations use another world frame). Robot and pedestrian tasks are sampled anywhere in
    the free space; ``default_humans`` is the median number of people present at once; ``time_limit``
    60 s (or the recording's length if shorter).
    """
    return _replay_scene(canonical_recording(name))


@functools.cache
def _replay_scene(name: str) -> Scene:
    rec = load_recording(name)
    x0, y0, x1, y1 = rec.bbox
    fx0, fy0, fx1, fy1 = x0 - SCENE_MARGIN, y0 - SCENE_MARGIN, x1 + SCENE_MARGIN, y1 + SCENE_MARGIN
    w = WALL_THICKNESS
    bx0, by0, bx1, by1 = fx0 - w, fy0 - w, fx1 + w, fy1 + w
    h = 0.5 * w
    walls = (
        WallObstacle((bx0, fy0 - h), (bx1, fy0 - h), thickness=w, name="south"),
        WallObstacle((bx0, fy1 + h), (bx1, fy1 + h), thickness=w, name="north"),
        WallObstacle((fx0 - h, fy0), (fx0 - h, fy1), thickness=w, name="west"),
        WallObstacle((fx1 + h, fy0), (fx1 + h, fy1), thickness=w, name="east"),
    ) + tuple(WallObstacle(tuple(a), tuple(b), thickness=w, name=f"map_{k}")
              for k, (a, b) in enumerate(np.round(rec.walls, 3).tolist()))
    steps = np.arange(int(round(rec.duration / rec.dt)) + 1) * rec.dt
    t1 = rec.t1()
    counts = ((rec.t0[None, :] <= steps[:, None] + 1e-9) & (t1[None, :] >= steps[:, None] - 1e-9)).sum(axis=1)
    scene = Scene(
        name=f"{SCENE_PREFIX}{rec.name}",
        bounds=(bx0, by0, bx1, by1),
        obstacles=walls,
        protocol=Protocol(type="regions"),
        default_humans=max(1, int(np.median(counts))),
        time_limit=float(min(60.0, max(rec.duration, 1.0))),
        description=(f"Open scene of the {rec.name} recording ({rec.stem}): {fx1 - fx0:.1f} x {fy1 - fy0:.1f} m of "
                     f"free space around every recorded position, walls around it"
                     + (f", {len(rec.walls)} walls of the real scene inside (OpenTraj map)" if len(rec.walls) else "")
                     + f"; coordinates = file - {rec.offset.tolist()}."),
    )
    scene.validate_reachability()
    return scene


def scene_from_name(name: str) -> Scene | None:
    """The replay scene called ``replay_<recording>``, or None if ``name`` does not start with ``replay_``."""
    if not name.startswith(SCENE_PREFIX):
        return None
    return replay_scene(name[len(SCENE_PREFIX):])


# ------------------------------------------------------------------------------------------ crowd


def _segment_headings(xy: np.ndarray, dt: float) -> tuple[np.ndarray, np.ndarray]:
    """Per-segment velocity (S, 2) and heading (S,) of one track, headings held while standing still."""
    if len(xy) < 2:
        return np.zeros((1, 2)), np.zeros(1)
    v = np.diff(xy, axis=0) / dt
    speed = np.linalg.norm(v, axis=1)
    yaw = np.arctan2(v[:, 1], v[:, 0])
    moving = np.flatnonzero(speed >= STILL_SPEED)
    if moving.size == 0:
        return v, np.zeros(len(v))
    # Nearest moving segment (earlier one on ties) for the still ones.
    idx = np.arange(len(v))
    nearest = moving[np.clip(np.searchsorted(moving, idx), 0, moving.size - 1)]
    before = moving[np.clip(np.searchsorted(moving, idx, side="right") - 1, 0, moving.size - 1)]
    use = np.where(np.abs(before - idx) <= np.abs(nearest - idx), before, nearest)
    return v, yaw[use]


class ReplayCrowd:
    """The recorded people of one time window, assigned to the env's pedestrian slots.

    Args:
        recording: recording name (:data:`RECORDINGS`).
        start: recording time of env time 0 (s), ``0 <= start < duration``.
        dt: env control period (s).
        n_steps: episode length in steps; the window is ``[start, start + n_steps * dt]``.
        n_humans: pedestrian slots; ``None`` = the largest number of people present at once in the
            window (then no track is dropped).
        data_dir: ETH/UCY folder (default: :func:`navzoo.forecast.data.default_data_dir`).

    After construction, for every env step ``k`` in ``0..n_steps`` and slot ``j``: ``pos[k, j]``,
    ``vel[k, j]``, ``yaw[k, j]``, ``active[k, j]``, ``track[k, j]`` (index of the recording's track
    in that slot, -1 when parked) and ``goal[k, j]`` (the last position of the slot's current track).
    """

    def __init__(self, recording: str, start: float, dt: float, n_steps: int, n_humans: int | None = None,
                 data_dir: str | Path | None = None) -> None:
        rec = load_recording(recording, data_dir)
        if not (isinstance(start, (int, float)) and math.isfinite(start) and start >= 0):
            raise ValueError(f"replay_start must be a finite number >= 0, got {start!r}")
        if start >= rec.duration:
            raise ValueError(f"replay_start={start:g} s is beyond the end of recording {rec.name!r} ({rec.stem}, "
                             f"{rec.duration:.1f} s long); use 0 <= replay_start < {rec.duration:.1f}")
        self.recording = rec
        self.start = float(start)
        self.dt = float(dt)
        self.n_steps = int(n_steps)
        K = self.n_steps
        tau = self.start + np.arange(K + 1) * self.dt  # recording time of each env step
        self.times = tau
        t0, t1 = rec.t0, rec.t1()
        first = np.ceil((t0 - self.start) / self.dt - _EPS).astype(np.int64)
        last = np.floor((t1 - self.start) / self.dt + _EPS).astype(np.int64)
        first, last = np.maximum(first, 0), np.minimum(last, K)
        in_window = np.flatnonzero(first <= last)
        self.window_tracks = in_window
        counts = np.zeros(K + 2, dtype=np.int64)
        np.add.at(counts, first[in_window], 1)
        np.add.at(counts, last[in_window] + 1, -1)
        self.max_concurrent = int(np.cumsum(counts)[: K + 1].max()) if in_window.size else 0
        H = self.max_concurrent if n_humans is None else int(n_humans)
        self.n_slots = H

        # Greedy slot assignment in order of appearance (interval colouring: optimal when H suffices).
        order = in_window[np.lexsort((rec.ped[in_window], first[in_window]))]
        free_from = np.zeros(H, dtype=np.int64)
        self.assignment: list[tuple[int, int]] = []  # (slot, track)
        self.dropped: list[int] = []  # tracks (indices into the recording) that found no free slot
        for tr in order:
            slots = np.flatnonzero(free_from <= first[tr])
            if slots.size == 0:
                self.dropped.append(int(tr))
                continue
            j = int(slots[0])
            free_from[j] = last[tr] + 1
            self.assignment.append((j, int(tr)))

        x0, y0, x1, y1 = replay_scene(rec.name).bounds
        self.park = np.stack([np.full(H, x1 + PARK_DISTANCE), PARK_SPACING * np.arange(H) + y0], axis=1)
        self.pos = np.repeat(self.park[None], K + 1, axis=0)
        self.goal = self.pos.copy()
        self.vel = np.zeros((K + 1, H, 2))
        self.yaw = np.zeros((K + 1, H))
        self.active = np.zeros((K + 1, H), dtype=bool)
        self.track = np.full((K + 1, H), -1, dtype=np.int64)
        for j, tr in self.assignment:
            ks = np.arange(first[tr], last[tr] + 1)
            xy = rec.xy[tr]
            times = t0[tr] + np.arange(len(xy)) * rec.dt
            t = np.clip(tau[ks], times[0], times[-1])
            self.pos[ks, j, 0] = np.interp(t, times, xy[:, 0])
            self.pos[ks, j, 1] = np.interp(t, times, xy[:, 1])
            seg_v, seg_yaw = _segment_headings(xy, rec.dt)
            seg = np.clip(np.floor((t - times[0]) / rec.dt + _EPS).astype(np.int64), 0, len(seg_v) - 1)
            self.vel[ks, j] = seg_v[seg]
            self.yaw[ks, j] = seg_yaw[seg]
            self.active[ks, j] = True
            self.track[ks, j] = tr
            self.goal[ks, j] = xy[-1]
        # Parked slots keep the heading of their last (or next) person, so a parked body does not spin.
        for j in range(H):
            act = np.flatnonzero(self.active[:, j])
            if act.size:
                idx = act[np.clip(np.searchsorted(act, np.arange(K + 1)), 0, act.size - 1)]
                self.yaw[~self.active[:, j], j] = self.yaw[idx[~self.active[:, j]], j]

    def step_index(self, k: int) -> int:
        """The schedule row of env step ``k`` (steps past the window stay at its last row)."""
        return min(max(int(k), 0), self.n_steps)

    def __repr__(self) -> str:
        return (f"ReplayCrowd({self.recording.name!r}, start={self.start:g}, dt={self.dt:g}, steps={self.n_steps}, "
                f"slots={self.n_slots}, tracks={len(self.assignment)}, dropped={len(self.dropped)})")
