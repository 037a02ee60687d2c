"""Obstacle maps of the real recordings: OpenTraj rasters as occupancy grids, and map crops for windows.

The trajectory diffusion model takes an occupancy crop around each person (8 m, 32 cells, agent frame;
``navzoo.agents.diffusion.crowd.MAP_EXTENT``). In navzoo scenes the crop comes from the scene's grid.
For the ETH/UCY recordings it comes from the OpenTraj obstacle maps (``../shared/data/trajectories/opentraj``)
where one exists in the same world frame as the ``eth_ucy`` file, and is "no map" (``has_map`` False,
the model's learned no-map input) otherwise:

============== ======================= =============================================================
scene          map                     why
============== ======================= =============================================================
biwi_eth       ``ETH/seq_eth/map.png`` its ``obsmat.txt`` positions are the ``eth_ucy`` file's (to the
                                       2nd decimal); ``H.txt`` maps image (row, col) to world metres
UCY scenes     none                    the UCY files of ``eth_ucy`` use another world frame than the
                                       OpenTraj annotations (x and y swapped, scale off by 3-8 %,
                                       quirk 2 of the data README), and OpenTraj has no raster for them
============== ======================= =============================================================

:func:`opentraj_grid` rasterises ``map.png``: every pixel brighter than ``threshold`` is projected to
the world through ``H`` (with 2 x 2 sub-pixel samples, so no line breaks up where the perspective
stretches pixels) and marks its cell, then the drawn lines (1-3 pixels, a few centimetres) are thickened
by ``wall_radius`` so that the crop's nearest-cell sampling (0.25 m cells) cannot step over them. The
grid covers the image's footprint on the ground plus ``margin`` metres of free space on every side: the
map only says where the camera saw obstacles, so what lies beyond the image is free, not occupied (the
crop treats cells off a grid as occupied; the margin keeps every crop of a recorded person on the grid).
"""

from __future__ import annotations

from collections.abc import Mapping
from functools import lru_cache
from pathlib import Path
from typing import Any

import numpy as np

from navzoo.forecast.sim_data import MAP_EXTENT, map_heading
from navzoo.world.occupancy import OccupancyGrid

__all__ = ["OPENTRAJ_MAPS", "MAP_EXTENT", "MAP_CELLS", "default_map_dir", "opentraj_grid", "opentraj_walls",
           "map_crops", "attach_maps"]

#: eth_ucy scene -> OpenTraj folder holding ``map.png`` and ``H.txt`` in the same world frame.
OPENTRAJ_MAPS: dict[str, str] = {"biwi_eth": "ETH/seq_eth"}
#: Crop cells: the shipped diffusion model's (its side is ``MAP_EXTENT``, the simulated windows' 8 m).
MAP_CELLS = 32


def default_map_dir() -> Path:
    """The shared OpenTraj folder, beside the ETH/UCY one: ``.../trajectories/opentraj``."""
    from navzoo.forecast.data import default_data_dir

    return default_data_dir().parent / "opentraj"


def opentraj_walls(scene: str, map_dir: str | Path | None = None) -> np.ndarray | None:
    """The wall lines of ``scene``'s OpenTraj ``map.xml`` (K, 2, 2) in the world frame of the ``eth_ucy``
    file (metres; each row a segment's two end points), or None if the scene has no OpenTraj map.

    For ``biwi_eth`` these are the walkway's two side walls and the building front, broken by the
    entrance: the lines that :func:`opentraj_grid` rasterises from ``map.png`` (both are checked against
    each other in ``tests/forecast/test_scene_maps.py``). The ``thickness`` attribute of a line is a
    drawing width in pixels, not metres, and is ignored.

    Raises:
        FileNotFoundError: If the scene has a map but its ``map.xml`` is missing.
        ValueError: If ``map.xml`` is not XML, or a ``Line`` lacks a finite coordinate.
    """
    if scene not in OPENTRAJ_MAPS:
        return None
    folder = Path(map_dir) if map_dir is not None else default_map_dir()
    path = folder / OPENTRAJ_MAPS[scene] / "map.xml"
    if not path.is_file():
        raise FileNotFoundError(f"OpenTraj map file {path} is missing")
    return _opentraj_walls(str(path.resolve()))


@lru_cache(maxsize=8)
def _opentraj_walls(path: str) -> np.ndarray:
    import xml.etree.ElementTree as ET

    try:
        root = ET.parse(path).getroot()
    except ET.ParseError as exc:
        raise ValueError(f"{path}: not an XML file ({exc})") from None
    rows = []
    # Tags carry the OpenTraj namespace ({https://github.com/amiryanj/OpenTraj}Line); match the local name.
    for k, el in enumerate(e for e in root.iter() if e.tag.rsplit("}", 1)[-1] == "Line"):
        try:
            row = [float(el.attrib[a]) for a in ("x1", "y1", "x2", "y2")]
        except (KeyError, ValueError):
            raise ValueError(f"{path}: Line {k} needs numeric x1, y1, x2, y2; got {dict(el.attrib)}") from None
        if not np.all(np.isfinite(row)):
            raise ValueError(f"{path}: Line {k} has a non-finite coordinate: {row}")
        rows.append(row)
    walls = np.array(rows, dtype=np.float64).reshape(-1, 2, 2)
    walls.setflags(write=False)
    return walls


def opentraj_grid(scene: str, map_dir: str | Path | None = None, resolution: float = 0.05,
                  threshold: int = 0, wall_radius: float = 0.15, margin: float = 8.0) -> OccupancyGrid | None:
    """Occupancy grid (world frame of the ``eth_ucy`` file) of ``scene``'s OpenTraj map, or None without one.

    Args:
        scene: ETH/UCY scene name (file stem, e.g. ``"biwi_eth"``).
        map_dir: OpenTraj folder (default :func:`default_map_dir`).
        resolution: Cell side (m).
        threshold: Pixels of ``map.png`` above this value are obstacles.
        wall_radius: Drawn lines are thickened by this radius (m).
        margin: Free space (m) added around the image's footprint.

    Raises:
        FileNotFoundError: If the scene has a map but its files are missing.
        ValueError: On an unreadable image or homography, or out-of-range arguments.
    """
    if scene not in OPENTRAJ_MAPS:
        return None
    if not resolution > 0 or wall_radius < 0 or margin < 0:
        raise ValueError(f"need resolution > 0, wall_radius >= 0, margin >= 0; got {resolution}, {wall_radius}, {margin}")
    folder = Path(map_dir) if map_dir is not None else default_map_dir()
    return _opentraj_grid(str((folder / OPENTRAJ_MAPS[scene]).resolve()), float(resolution), int(threshold),
                          float(wall_radius), float(margin))


@lru_cache(maxsize=8)
def _opentraj_grid(folder: str, resolution: float, threshold: int, wall_radius: float,
                   margin: float) -> OccupancyGrid:
    import cv2

    image_path, h_path = Path(folder) / "map.png", Path(folder) / "H.txt"
    for path in (image_path, h_path):
        if not path.is_file():
            raise FileNotFoundError(f"OpenTraj map file {path} is missing")
    image = cv2.imread(str(image_path), cv2.IMREAD_GRAYSCALE)
    if image is None or image.ndim != 2:
        raise ValueError(f"{image_path} is not a readable grey-scale image")
    try:
        H = np.loadtxt(h_path, dtype=np.float64)
    except ValueError as err:
        raise ValueError(f"{h_path} is not a 3 x 3 homography: {err}") from err
    if H.shape != (3, 3) or not np.isfinite(H).all() or abs(np.linalg.det(H)) < 1e-12:
        raise ValueError(f"{h_path} is not an invertible 3 x 3 homography (shape {H.shape})")

    def to_world(rc: np.ndarray) -> np.ndarray:
        p = np.c_[rc, np.ones(len(rc))] @ H.T
        return p[:, :2] / p[:, 2:]

    rows, cols = image.shape
    corners = to_world(np.array([[0.0, 0.0], [0.0, cols], [rows, 0.0], [rows, cols]]))
    lo, hi = corners.min(axis=0) - margin, corners.max(axis=0) + margin
    shape = np.ceil((hi - lo) / resolution).astype(np.int64)[::-1]  # (rows = y, cols = x)
    occ = np.zeros(shape, dtype=bool)
    r, c = np.nonzero(image > threshold)
    if r.size:
        sub = np.array([[0.25, 0.25], [0.25, 0.75], [0.75, 0.25], [0.75, 0.75]])
        rc = (np.stack([r, c], axis=1)[:, None, :] + sub[None]).reshape(-1, 2)
        xy = to_world(rc)
        cell = np.floor((xy - lo) / resolution).astype(np.int64)
        ok = (cell >= 0).all(axis=1) & (cell[:, 0] < shape[1]) & (cell[:, 1] < shape[0])
        occ[cell[ok, 1], cell[ok, 0]] = True
    grid = OccupancyGrid(occ, resolution, (float(lo[0]), float(lo[1])))
    return grid.inflate(wall_radius) if wall_radius > 0 and r.size else grid


def map_crops(batch: Mapping[str, Any], grid: OccupancyGrid, map_extent: float = MAP_EXTENT,
              map_cells: int = MAP_CELLS) -> np.ndarray:
    """``(N, C, C)`` float32 occupancy crops of an agent-centric batch (:func:`navzoo.forecast.data.normalize`).

    Each crop is centred on the window's current position (``origin``) and turned to its frame's heading,
    exactly as the env's diffusion crowd and :mod:`navzoo.forecast.sim_data` crop a scene's grid.
    """
    origin = np.asarray(batch["origin"], dtype=np.float64).reshape(-1, 2)
    return np.asarray(grid.crop_many(origin, map_heading(batch), float(map_extent), int(map_cells)), np.float32)


def attach_maps(batch: Mapping[str, Any], scene: str, map_dir: str | Path | None = None,
                map_extent: float = MAP_EXTENT, map_cells: int = MAP_CELLS) -> dict[str, Any]:
    """A copy of an agent-centric ``batch`` with ``map`` (N, C, C) and ``has_map`` (N,): the scene's crops
    where it has a map (:data:`OPENTRAJ_MAPS`), zeros with ``has_map`` False otherwise."""
    out = dict(batch)
    n = int(np.asarray(batch["hist"]).shape[0])
    grid = opentraj_grid(scene, map_dir)
    if grid is None or n == 0:
        out["map"] = np.zeros((n, map_cells, map_cells), np.float32)
        out["has_map"] = np.zeros(n, bool)
    else:
        out["map"] = map_crops(batch, grid, map_extent, map_cells)
        out["has_map"] = np.ones(n, bool)
    return out
