"""Door entries: A* paths that cross a door on its axis.

An A* path through a door may approach it at a slant. A walking body that enters a door slantwise
touches a jamb, and the social-force rollout of its target is held back by the jambs (docs/pedestrians.md,
"Door jambs"). :func:`door_entries` finds each short narrow passage along a path (a door, not a
corridor), estimates the door's axis from the jambs, and replaces the path's points near the door by
an entry point, the door's centre and an exit point on that axis.
"""

from __future__ import annotations

import numpy as np

from navzoo.world.occupancy import OccupancyGrid
from navzoo.world.planner import resample_polyline

DOOR_HALF_WIDTH = 0.6  # m: passages whose clearance stays below this are door candidates (doors <= 1.2 m)
DOOR_MAX_LENGTH = 2.0  # m: a narrow stretch longer than this is a corridor, left alone
DOOR_REACH = 0.7  # m: entry and exit points this far from the door's centre, on its axis
# m: path_doors' run_scan adds only doors narrower than this across (one body at a time; in a wider passage, such
# as the held-out bottleneck's 1.2 m one, two bodies pass each other, and holding it as a door cost goals there)
DOOR_SCAN_MAX_WIDTH = 1.1
_STEP = 0.05


def _nearest_segment(line: np.ndarray, p: np.ndarray) -> int:
    """Index i of the segment line[i] -> line[i + 1] nearest to ``p``."""
    a, b = line[:-1], line[1:]
    ab = b - a
    t = np.clip(np.einsum("ij,ij->i", p - a, ab) / np.maximum(np.einsum("ij,ij->i", ab, ab), 1e-12), 0.0, 1.0)
    return int(np.argmin(np.linalg.norm(a + t[:, None] * ab - p, axis=1)))


def door_axis(grid: OccupancyGrid, centre: np.ndarray, clearance: float) -> np.ndarray | None:
    """Unit vector across the door whose narrowest point is ``centre`` (perpendicular to the line of
    the jamb cells within ``clearance`` + 0.2 m), or None when no jambs on two sides are found."""
    res = grid.resolution
    k = int(np.ceil((clearance + 0.2) / res)) + 1
    rc = grid.world_to_cell(centre)
    h, w = grid.occ.shape
    r0, r1, c0, c1 = max(rc[0] - k, 0), min(rc[0] + k + 1, h), max(rc[1] - k, 0), min(rc[1] + k + 1, w)
    cells = np.argwhere(grid.occ[r0:r1, c0:c1]) + [r0, c0]
    if len(cells) < 4:
        return None
    pts = grid.cell_to_world(cells)
    pts = pts[np.linalg.norm(pts - centre, axis=1) <= clearance + 0.2]
    if len(pts) < 4:
        return None
    rel = pts - centre
    _, _, vt = np.linalg.svd(rel - rel.mean(axis=0), full_matrices=False)
    wall = vt[0]  # the jambs lie along the wall line
    side = rel @ wall
    if side.min() > -clearance * 0.5 or side.max() < clearance * 0.5:  # jambs on both sides of the centre
        return None
    return np.array([-wall[1], wall[0]])


def path_doors(path: np.ndarray, start: np.ndarray, grid: OccupancyGrid, half_width: float = DOOR_HALF_WIDTH,
               max_length: float = DOOR_MAX_LENGTH, two_sided: bool = False,
               end_margin: float = 0.0, jamb_search: float = 0.0,
               run_scan: bool = False) -> list[tuple[np.ndarray, np.ndarray, float]]:
    """The doors that ``path`` (K, 2), walked from ``start``, passes, in the order it passes them.

    A door is a stretch of the path no longer than ``max_length`` where the clearance (distance to the
    nearest occupied cell) stays below ``half_width``, with jambs on both sides. Returns, per door, its
    centre (the narrowest point), its axis (unit, across the door, pointing the way the path crosses it:
    :func:`door_axis`) and its clearance there (m).

    :func:`door_axis` accepts a stretch along a single straight wall too (its cells lie on both sides of
    the centre along the wall). ``two_sided`` keeps only passages with an obstacle on either side across
    the axis, each within ``2 * half_width`` of the centre and together less than ``2 * half_width + 0.1``
    m apart: a door or a gap between two obstacles, not a wall walked along. ``end_margin`` leaves out
    doors closer than that to either end of the path (start or goal). ``jamb_search`` (m, with ``two_sided``):
    a path that enters a door slantwise has its narrowest point off the door's jamb line (up to 0.2 m into the
    room beyond a 1.0 m door), where one side finds no jamb; such a door is then looked for at points up to this
    far along its axis, and its centre moves to the first one with jambs on both sides (0: the narrowest point
    only, so such doors are missed; docs/crowd_log.md, "Doors that paths enter slantwise"). The clearance
    returned stays the one at the path's narrowest point. ``run_scan`` (with ``two_sided``): when the narrowest
    point finds no door (no jambs on both sides there, or no axis: a path that hugs a jamb's corner on its way in
    has its narrowest point at the corner, outside the door, where the jamb cells give the wall's direction, not
    the door's), the run's other points are tried, narrowest first, each with its own axis, and the door is
    centred on the first with jambs on both sides and less than ``DOOR_SCAN_MAX_WIDTH`` across (docs/crowd_log.md,
    "Doors missed at the jamb's corner").
    """
    path = np.asarray(path, dtype=np.float64).reshape(-1, 2)
    line = np.concatenate([np.asarray(start, dtype=np.float64).reshape(1, 2), path])
    if len(line) < 2:
        return []
    pts = resample_polyline(line, _STEP)
    d = grid.distance_at(pts)
    narrow = d < half_width
    out = []
    edges = np.flatnonzero(np.diff(np.concatenate([[0], narrow.astype(int), [0]])))
    for a, b in zip(edges[::2], edges[1::2], strict=True):  # narrow runs pts[a:b]
        if (b - a) * _STEP > max_length:
            continue
        m = a + int(np.argmin(d[a:b]))
        if end_margin > 0 and min(np.linalg.norm(pts[m] - line[0]), np.linalg.norm(pts[m] - line[-1])) < end_margin:
            continue  # a door at either end of the path is left out, whatever point of it has the jambs
        found = _door_at(grid, pts, d, m, line, half_width, two_sided, end_margin, jamb_search)
        if found is None and run_scan and two_sided:
            for k in a + np.argsort(d[a:b], kind="stable"):
                if k == m:
                    continue
                door = _door_at(grid, pts, d, int(k), line, half_width, two_sided, end_margin, 0.0)
                if door is not None and _passage_width(grid, door[0], door[1], 2.0 * half_width) < DOOR_SCAN_MAX_WIDTH:
                    found = door
                    break
        if found is not None:
            out.append((found[0].copy(), found[1], float(d[m])))
    return out


def _door_at(grid: OccupancyGrid, pts: np.ndarray, d: np.ndarray, m: int, line: np.ndarray, half_width: float,
             two_sided: bool, end_margin: float, jamb_search: float) -> tuple[np.ndarray, np.ndarray] | None:
    """The door (centre, axis along the crossing) of :func:`path_doors` taken at path point ``pts[m]``, or None."""
    axis = door_axis(grid, pts[m], float(d[m]))
    if axis is None:
        return None
    heading = pts[min(m + 4, len(pts) - 1)] - pts[max(m - 4, 0)]
    axis = axis if heading @ axis >= 0 else -axis
    centre = pts[m]
    if end_margin > 0 and min(np.linalg.norm(centre - line[0]), np.linalg.norm(centre - line[-1])) < end_margin:
        return None
    if two_sided:
        centre = _jamb_centre(grid, centre, axis, half_width, jamb_search)
        if centre is None:
            return None
    return centre, axis


def _jamb_centre(grid: OccupancyGrid, centre: np.ndarray, axis: np.ndarray, half_width: float,
                 search: float) -> np.ndarray | None:
    """``centre`` when the passage across ``axis`` there is narrower than ``2 * half_width + 0.1`` m with an
    obstacle on either side; else the nearest point up to ``search`` m along the axis (either way, in steps of
    half a cell) where it is; None when there is none."""
    limit = 2.0 * half_width + 0.1
    if _passage_width(grid, centre, axis, 2.0 * half_width) < limit:
        return centre
    step = 0.5 * grid.resolution
    for k in range(1, int(np.floor(search / step + 1e-9)) + 1):
        for sgn in (1.0, -1.0):
            p = centre + sgn * k * step * axis
            if _passage_width(grid, p, axis, 2.0 * half_width) < limit:
                return p
    return None


def _passage_width(grid: OccupancyGrid, centre: np.ndarray, axis: np.ndarray, reach: float) -> float:
    """Free width (m) across ``axis`` at ``centre``: the distance between the first occupied cells on
    either side within ``reach``; inf when one side has none."""
    side = np.array([-axis[1], axis[0]])
    s = np.arange(0.0, reach + 1e-9, 0.5 * grid.resolution)
    out = 0.0
    for sgn in (1.0, -1.0):
        free = grid.is_free(centre[None, :] + sgn * s[:, None] * side[None, :])
        hit = np.flatnonzero(~free)
        if not hit.size:
            return float("inf")
        out += float(s[hit[0]])
    return out


def door_entries(path: np.ndarray, start: np.ndarray, grid: OccupancyGrid, radius: float,
                 half_width: float = DOOR_HALF_WIDTH, max_length: float = DOOR_MAX_LENGTH,
                 reach: float = DOOR_REACH) -> np.ndarray:
    """``path`` (K, 2), walked from ``start``, with its doors crossed on their axes.

    The doors are those of :func:`path_doors`. The path points within ``reach`` + 0.25 m of a door's
    centre are replaced by ``centre -/+ reach * axis`` around the centre, when both new points keep
    ``radius`` from every wall and the door is not at either end of the path; other doors are left.
    """
    path = np.asarray(path, dtype=np.float64).reshape(-1, 2)
    start = np.asarray(start, dtype=np.float64).reshape(1, 2)
    out = path
    for centre, axis, clearance in path_doors(path, start, grid, half_width, max_length, end_margin=reach + 0.25):
        entry, exit_ = centre - reach * axis, centre + reach * axis
        probe = np.linspace(0.0, 1.0, 15)[:, None]
        across = np.concatenate([entry + probe * (centre - entry), centre + probe * (exit_ - centre)])
        if grid.distance_at(across).min() < min(radius, clearance) - 1e-9 or \
                grid.distance_at(np.stack([entry, exit_])).min() < radius:
            continue
        keep = np.linalg.norm(out - centre, axis=1) >= reach + 0.25
        if not keep[-1]:  # the goal itself is near the door: leave it
            continue
        i = _nearest_segment(np.concatenate([start, out]), centre)  # the door lies after out[i - 1]
        idx = np.arange(len(out))
        out = np.concatenate([out[keep & (idx < i)], entry[None], centre[None], exit_[None], out[keep & (idx >= i)]])
    return out
