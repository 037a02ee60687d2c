"""Occupancy grid of a scene: rasterisation, inflation, distance field and egocentric crops.

Grid convention: ``occ[row, col]`` with ``row`` along +y and ``col`` along +x; cell ``(r, c)`` covers
``[ox + c*res, ox + (c+1)*res) x [oy + r*res, oy + (r+1)*res)`` and its centre is at
``(ox + (c + 0.5)*res, oy + (r + 0.5)*res)``. Everything outside the grid counts as occupied.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import lru_cache
from typing import TYPE_CHECKING, Any

import cv2
import numpy as np
from numpy.typing import ArrayLike
from scipy import ndimage

from navzoo.world import geometry as geo

if TYPE_CHECKING:
    from navzoo.world.scene import Region, Scene

__all__ = ["OccupancyGrid"]

# Sub-pixel precision for cv2 drawing (coordinates are passed as fixed point with this many fraction bits).
_SHIFT = 8
# Footprints narrower than this many cells (2 * area / perimeter, i.e. the width of a long wall) also get
# their outline drawn; see OccupancyGrid.from_scene.
_THIN = 1.2


@dataclass(frozen=True, eq=False)
class OccupancyGrid:
    """Boolean occupancy grid (True = occupied). Immutable: ``occ`` is made read-only.

    Attributes:
        occ: ``(H, W)`` bool array, row index = y, column index = x.
        resolution: cell side in metres.
        origin: world ``(x, y)`` of the grid's lower-left corner (the corner of cell ``(0, 0)``).
    """

    occ: np.ndarray
    resolution: float = 0.1
    origin: tuple[float, float] = (0.0, 0.0)
    _cache: dict[Any, Any] = field(default_factory=dict, init=False, repr=False)

    def __post_init__(self) -> None:
        occ = np.array(self.occ, dtype=bool, copy=True)
        if occ.ndim != 2 or occ.size == 0:
            raise ValueError(f"occ must be a non-empty 2D array, got shape {occ.shape}")
        if not self.resolution > 0:
            raise ValueError(f"resolution must be > 0, got {self.resolution}")
        occ.setflags(write=False)
        object.__setattr__(self, "occ", occ)
        object.__setattr__(self, "resolution", float(self.resolution))
        object.__setattr__(self, "origin", (float(self.origin[0]), float(self.origin[1])))

    # ------------------------------------------------------------------ construction

    @classmethod
    def from_scene(cls, scene: Scene, resolution: float = 0.1) -> OccupancyGrid:
        """Rasterise a scene's obstacles (cached on the scene per resolution).

        A cell is occupied if its centre is inside an obstacle footprint or outside the scene bounds.
        A footprint at least 1.2 cells wide always covers a cell centre in every column (or row) it
        crosses, which gives an 8-connected barrier: nothing 4-connected (the planner's and the
        reachability check's connectivity) leaks through. Thinner obstacles (``2 * area / perimeter <
        1.2 * resolution``: thin walls, small posts) are additionally drawn as their outline with
        4-connected cv2 lines, so that they always leave a gap-free barrier even when they cover no cell
        centre (at the price of up to one extra cell on each side).
        """
        key = ("occupancy", float(resolution))
        cached = scene._cache.get(key)
        if cached is not None:
            return cached
        res = float(resolution)
        x0, y0, x1, y1 = scene.bounds
        # The small tolerance keeps bounds that are an exact multiple of the resolution from gaining a
        # spurious extra column through float round-off (e.g. 14 / 0.1 = 140.00000000000003).
        width = max(1, int(np.ceil((x1 - x0) / res - 1e-6)))
        height = max(1, int(np.ceil((y1 - y0) / res - 1e-6)))
        occ = np.zeros((height, width), dtype=np.uint8)
        for poly in scene.obstacle_polygons():
            _fill_centres(occ, poly, (x0, y0), res)
            area = abs(geo.polygon_area(poly))
            if 2.0 * area / geo.polygon_perimeter(poly) < _THIN * res:
                pix = np.round(((poly - (x0, y0)) / res - 0.5) * (1 << _SHIFT)).astype(np.int32)
                cv2.polylines(occ, [pix], isClosed=True, color=1, thickness=1, lineType=cv2.LINE_4, shift=_SHIFT)
        # Cells whose centre falls beyond the bounds (when the size is not a multiple of res) are outside.
        cx = x0 + (np.arange(width) + 0.5) * res
        cy = y0 + (np.arange(height) + 0.5) * res
        occ[:, cx > x1] = 1
        occ[cy > y1, :] = 1
        grid = cls(occ.astype(bool), res, (x0, y0))
        scene._cache[key] = grid
        return grid

    # ------------------------------------------------------------------ basic properties

    @property
    def shape(self) -> tuple[int, int]:
        """``(H, W)``."""
        return self.occ.shape  # type: ignore[return-value]

    @property
    def extent(self) -> tuple[float, float, float, float]:
        """``(xmin, ymin, xmax, ymax)`` covered by the grid."""
        h, w = self.occ.shape
        return (self.origin[0], self.origin[1], self.origin[0] + w * self.resolution, self.origin[1] + h * self.resolution)

    def cell_centers(self) -> tuple[np.ndarray, np.ndarray]:
        """World x of each column ``(W,)`` and y of each row ``(H,)``."""
        h, w = self.occ.shape
        return (
            self.origin[0] + (np.arange(w) + 0.5) * self.resolution,
            self.origin[1] + (np.arange(h) + 0.5) * self.resolution,
        )

    # ------------------------------------------------------------------ derived grids

    def _edt_cells(self) -> np.ndarray:
        """Distance (in cells, float64) from each cell centre to the nearest occupied cell centre."""
        if "edt" not in self._cache:
            # Pad with an occupied ring so that the outside of the grid counts as an obstacle.
            padded = np.pad(~self.occ, 1, constant_values=False)
            self._cache["edt"] = ndimage.distance_transform_edt(padded)[1:-1, 1:-1]
        return self._cache["edt"]

    def distance_field(self) -> np.ndarray:
        """Metres from each cell centre to the nearest occupied cell centre, float32 ``(H, W)`` (read-only).

        Zero on occupied cells; the outside of the grid counts as occupied. Being centre-to-centre, it
        over-estimates the true clearance to an obstacle boundary by up to one cell.
        """
        if "dist" not in self._cache:
            dist = (self._edt_cells() * self.resolution).astype(np.float32)
            dist.setflags(write=False)
            self._cache["dist"] = dist
        return self._cache["dist"]

    def inflate(self, radius: float) -> OccupancyGrid:
        """Grid where every cell whose centre is within ``radius`` of an occupied cell centre is occupied.

        Cached per radius; ``inflate(0)`` returns ``self``.
        """
        radius = float(radius)
        if radius < 0:
            raise ValueError(f"radius must be >= 0, got {radius}")
        if radius == 0.0:
            return self
        key = ("inflate", radius)
        if key not in self._cache:
            # Compare in cell units with a tiny tolerance so that radius == k * resolution is inclusive.
            occ = self._edt_cells() <= radius / self.resolution + 1e-9
            self._cache[key] = OccupancyGrid(occ, self.resolution, self.origin)
        return self._cache[key]

    def region_mask(self, region: Region) -> np.ndarray:
        """``(H, W)`` bool: cells whose centre lies inside ``region`` (cached per region, read-only)."""
        key = ("region", region)
        if key not in self._cache:
            mask = np.zeros(self.occ.shape, dtype=bool)
            verts = region.vertices()
            sub = _bbox_cells(verts, self.origin, self.resolution, self.occ.shape)
            if sub is not None:
                r0, r1, c0, c1 = sub
                xs, ys = self.cell_centers()
                gx, gy = np.meshgrid(xs[c0:c1], ys[r0:r1])
                inside = region.contains(np.stack([gx.ravel(), gy.ravel()], axis=1))
                mask[r0:r1, c0:c1] = inside.reshape(gx.shape)
            mask.setflags(write=False)
            self._cache[key] = mask
        return self._cache[key]

    # ------------------------------------------------------------------ coordinate transforms and queries

    def world_to_cell(self, xy: ArrayLike) -> np.ndarray:
        """Integer ``(row, col)`` of the cell containing each point; shape ``(..., 2)`` like the input.

        Points outside the grid get out-of-range indices (check with :meth:`in_bounds`).
        """
        p = np.asarray(xy, dtype=np.float64)
        col = np.floor((p[..., 0] - self.origin[0]) / self.resolution)
        row = np.floor((p[..., 1] - self.origin[1]) / self.resolution)
        return np.stack([row, col], axis=-1).astype(np.int64)

    def cell_to_world(self, rc: ArrayLike) -> np.ndarray:
        """World ``(x, y)`` of the centre of each ``(row, col)`` cell; shape ``(..., 2)``."""
        c = np.asarray(rc, dtype=np.float64)
        x = self.origin[0] + (c[..., 1] + 0.5) * self.resolution
        y = self.origin[1] + (c[..., 0] + 0.5) * self.resolution
        return np.stack([x, y], axis=-1)

    def in_bounds(self, xy: ArrayLike) -> np.ndarray:
        """Bool array: which points lie on the grid."""
        rc = self.world_to_cell(xy)
        h, w = self.occ.shape
        return (rc[..., 0] >= 0) & (rc[..., 0] < h) & (rc[..., 1] >= 0) & (rc[..., 1] < w)

    def is_free(self, xy: ArrayLike) -> np.ndarray:
        """Bool array: point's cell is on the grid and not occupied."""
        rc = self.world_to_cell(xy)
        h, w = self.occ.shape
        inside = (rc[..., 0] >= 0) & (rc[..., 0] < h) & (rc[..., 1] >= 0) & (rc[..., 1] < w)
        r = np.clip(rc[..., 0], 0, h - 1)
        c = np.clip(rc[..., 1], 0, w - 1)
        return inside & ~self.occ[r, c]

    def distance_at(self, xy: ArrayLike) -> np.ndarray:
        """Bilinear interpolation of :meth:`distance_field` at world points; 0 outside the grid."""
        p = np.asarray(xy, dtype=np.float64)
        field_ = self.distance_field()
        h, w = field_.shape
        fc = (p[..., 0] - self.origin[0]) / self.resolution - 0.5
        fr = (p[..., 1] - self.origin[1]) / self.resolution - 0.5
        # Between the outermost cell centres and the grid edge the value is held constant (clamping).
        fc_c = np.clip(fc, 0.0, w - 1.0)
        fr_c = np.clip(fr, 0.0, h - 1.0)
        c0 = np.minimum(np.floor(fc_c).astype(np.int64), max(w - 2, 0))
        r0 = np.minimum(np.floor(fr_c).astype(np.int64), max(h - 2, 0))
        c1 = np.minimum(c0 + 1, w - 1)
        r1 = np.minimum(r0 + 1, h - 1)
        tc = fc_c - c0
        tr = fr_c - r0
        val = (
            field_[r0, c0] * (1 - tr) * (1 - tc)
            + field_[r0, c1] * (1 - tr) * tc
            + field_[r1, c0] * tr * (1 - tc)
            + field_[r1, c1] * tr * tc
        )
        return np.where(self.in_bounds(p), val, 0.0)

    def crop(self, center_xy: ArrayLike, yaw: float, size_m: float, out_cells: int) -> np.ndarray:
        """Egocentric, heading-aligned local occupancy patch, float32 ``(out_cells, out_cells)``.

        The patch is a ``size_m`` x ``size_m`` square centred on the agent. It uses the same convention as
        the global grid but in the agent frame: ``patch[i, j]`` samples the point at local coordinates
        ``x_l = (j + 0.5 - n/2) * s``, ``y_l = (i + 0.5 - n/2) * s`` (``s = size_m / n``), so the agent's
        heading (+x) points towards increasing column index ("right") and its left (+y) towards increasing
        row index; shown with ``imshow(origin="lower")`` the heading points right. Values are 1.0 for
        occupied or off-grid cells and 0.0 for free ones (nearest-cell sampling).
        """
        return self.crop_many(np.asarray(center_xy, dtype=np.float64).reshape(1, 2), np.array([yaw]), size_m, out_cells)[0]

    def crop_many(self, centers_xy: ArrayLike, yaws: ArrayLike, size_m: float, out_cells: int) -> np.ndarray:
        """:meth:`crop` for N agents at once: ``(N, out_cells, out_cells)`` float32."""
        offsets = _crop_offsets(float(size_m), int(out_cells))  # (n*n, 2) local x, y
        centers = np.asarray(centers_xy, dtype=np.float64).reshape(-1, 2)
        yaws = np.asarray(yaws, dtype=np.float64).reshape(-1)
        c, s = np.cos(yaws)[:, None], np.sin(yaws)[:, None]
        wx = centers[:, :1] + c * offsets[None, :, 0] - s * offsets[None, :, 1]
        wy = centers[:, 1:] + s * offsets[None, :, 0] + c * offsets[None, :, 1]
        col = np.floor((wx - self.origin[0]) / self.resolution).astype(np.int64)
        row = np.floor((wy - self.origin[1]) / self.resolution).astype(np.int64)
        h, w = self.occ.shape
        inside = (row >= 0) & (row < h) & (col >= 0) & (col < w)
        vals = np.ones(row.shape, dtype=np.float32)
        vals[inside] = self.occ[row[inside], col[inside]]
        return vals.reshape(-1, out_cells, out_cells)


@lru_cache(maxsize=32)
def _crop_offsets(size_m: float, n: int) -> np.ndarray:
    step = size_m / n
    coords = (np.arange(n) + 0.5 - 0.5 * n) * step
    lx, ly = np.meshgrid(coords, coords)  # lx varies along columns, ly along rows
    out = np.stack([lx.ravel(), ly.ravel()], axis=1)
    out.setflags(write=False)
    return out


def _bbox_cells(
    poly: np.ndarray, origin: tuple[float, float], res: float, shape: tuple[int, int]
) -> tuple[int, int, int, int] | None:
    """Row/col slice bounds of cells whose centre may lie inside ``poly``; None if off-grid."""
    lo = poly.min(axis=0)
    hi = poly.max(axis=0)
    c0 = max(int(np.floor((lo[0] - origin[0]) / res - 0.5)), 0)
    c1 = min(int(np.ceil((hi[0] - origin[0]) / res - 0.5)) + 1, shape[1])
    r0 = max(int(np.floor((lo[1] - origin[1]) / res - 0.5)), 0)
    r1 = min(int(np.ceil((hi[1] - origin[1]) / res - 0.5)) + 1, shape[0])
    if c0 >= c1 or r0 >= r1:
        return None
    return r0, r1, c0, c1


def _fill_centres(occ: np.ndarray, poly: np.ndarray, origin: tuple[float, float], res: float) -> None:
    """Mark cells whose centre lies inside ``poly`` (exact point-in-polygon over the polygon's bbox)."""
    sub = _bbox_cells(poly, origin, res, occ.shape)
    if sub is None:
        return
    r0, r1, c0, c1 = sub
    xs = origin[0] + (np.arange(c0, c1) + 0.5) * res
    ys = origin[1] + (np.arange(r0, r1) + 0.5) * res
    gx, gy = np.meshgrid(xs, ys)
    inside = geo.point_in_polygon(np.stack([gx.ravel(), gy.ravel()], axis=1), poly)
    occ[r0:r1, c0:c1] |= inside.reshape(gx.shape).astype(np.uint8)
