"""Fallen pedestrians as obstacles in the other pedestrians' A* paths.

A physics (AMP) pedestrian that falls stays on the floor for the rest of the episode. Its disc in the
crowd model is where its root is, but the body lies up to a body length around it, and in a door
it blocks the way. With ``NavConfig(human_fallen_obstacles=True)`` the env stamps every fallen body's
footprint (its root and key bodies: head, hands, feet, and the lines from the root to them) into a
copy of the occupancy grid, plans the pedestrians' paths on that grid from then on, and plans again
right away for everyone whose remaining path passes the body. A body is found fallen while it still
slides and rolls, and comes to rest a median 0.3-0.4 m (up to 1.9 m) further on in crowd runs, so the env stamps the fallen bodies
again (on a fresh copy of the bare grid) whenever one has moved more than ``FALLEN_RESTAMP_M`` from
where it was stamped. Where no path avoids the bodies (a single door one lies in, or bodies across a
corridor), a person keeps its old path and walks on into them; with ``NavConfig(human_fallen_wait=True)``
it stands and waits instead, until a later stamp opens a way.
"""

from __future__ import annotations

import numpy as np

from navzoo.world.occupancy import OccupancyGrid
from navzoo.world.planner import resample_polyline

FALLEN_BODY_RADIUS = 0.15  # m: half the thickness of a lying body, around its root-to-limb lines
# m: a lying body whose root or a key body has moved this far from where it was stamped is stamped again (a body is
# found fallen while it still slides and rolls)
FALLEN_RESTAMP_M = 0.2
# NavConfig.human_fallen_wait: new goals drawn for a person before it waits, when fallen bodies cut every way there
FALLEN_GOAL_TRIES = 5
_SAMPLE_M = 0.05


def footprint_points(root_xy: np.ndarray, key_xy: np.ndarray, step: float = _SAMPLE_M) -> np.ndarray:
    """(M, 2) points along the lines from a lying body's root ``(2,)`` to each key body ``(K, 2)``,
    ``step`` metres apart, root and key bodies included."""
    root = np.asarray(root_xy, dtype=np.float64).reshape(2)
    keys = np.asarray(key_xy, dtype=np.float64).reshape(-1, 2)
    return np.concatenate([root[None]] + [resample_polyline(np.stack([root, k]), step)[1:] for k in keys])


def stamp(grid: OccupancyGrid, points: np.ndarray, radius: float = FALLEN_BODY_RADIUS) -> OccupancyGrid:
    """A copy of ``grid`` with every cell whose centre is within ``radius`` of a point occupied."""
    pts = np.asarray(points, dtype=np.float64).reshape(-1, 2)
    occ = np.array(grid.occ, copy=True)
    h, w = occ.shape
    res = grid.resolution
    k = int(np.ceil(radius / res)) + 1
    for rc in np.unique(grid.world_to_cell(pts), axis=0):
        r0, r1 = max(rc[0] - k, 0), min(rc[0] + k + 1, h)
        c0, c1 = max(rc[1] - k, 0), min(rc[1] + k + 1, w)
        if r0 >= r1 or c0 >= c1:
            continue
        rr, cc = np.mgrid[r0:r1, c0:c1]
        centres = grid.cell_to_world(np.stack([rr.ravel(), cc.ravel()], axis=1))
        d = np.min(np.linalg.norm(centres[:, None, :] - pts[None, :, :], axis=2), axis=1)
        near = (d <= radius).reshape(rr.shape)
        occ[r0:r1, c0:c1] |= near
    return OccupancyGrid(occ, grid.resolution, grid.origin)


def path_passes(path: np.ndarray, start: np.ndarray, points: np.ndarray, distance: float,
                step: float = 0.1) -> bool:
    """Whether the polyline from ``start`` through ``path (P, 2)`` comes within ``distance`` of any of
    ``points (M, 2)`` (sampled every ``step`` metres)."""
    line = np.concatenate([np.asarray(start, dtype=np.float64).reshape(1, 2),
                           np.asarray(path, dtype=np.float64).reshape(-1, 2)])
    pts = np.asarray(points, dtype=np.float64).reshape(-1, 2)
    if len(pts) == 0:
        return False
    s = resample_polyline(line, step)
    lo, hi = pts.min(axis=0) - distance, pts.max(axis=0) + distance  # cheap box test first
    s = s[np.all((s >= lo) & (s <= hi), axis=1)]
    if len(s) == 0:
        return False
    return bool(np.min(np.linalg.norm(s[:, None, :] - pts[None, :, :], axis=2)) < distance)
