"""Grid A* path planner shared by robots and pedestrians.

Search runs on the occupancy grid inflated by the agent radius (so the agent is a point), 8-connected
without corner cutting (a diagonal move needs both orthogonal neighbours free), which makes it equivalent
to 4-connected reachability. The raw cell path is then shortened by line-of-sight shortcutting (a
conservative supercover check on the inflated grid) and resampled at a fixed spacing.
"""

from __future__ import annotations

import heapq
import math
from typing import Any

import numpy as np
from numpy.typing import ArrayLike
from scipy import ndimage

from navzoo.world.occupancy import OccupancyGrid

__all__ = ["AStarPlanner", "path_length"]

_SQRT2 = math.sqrt(2.0)


def path_length(path: ArrayLike | None) -> float:
    """Length in metres of a polyline ``(K, 2)``; 0 for fewer than 2 points, ``inf`` for ``None``."""
    if path is None:
        return math.inf
    p = np.asarray(path, dtype=np.float64)
    if p.shape[0] < 2:
        return 0.0
    return float(np.linalg.norm(np.diff(p, axis=0), axis=1).sum())


class AStarPlanner:
    """A* on an occupancy grid for a disc-shaped agent.

    Args:
        grid: the scene's (non-inflated) occupancy grid.
        agent_radius: the grid is inflated once by this radius (metres).
        snap_radius: a start/goal inside inflated space is moved to the nearest free cell centre within
            this distance (metres); beyond it planning fails.

    Attributes:
        inflated: the inflated grid the search runs on.
    """

    def __init__(self, grid: OccupancyGrid, agent_radius: float, snap_radius: float = 0.5):
        self.grid = grid
        self.agent_radius = float(agent_radius)
        self.snap_radius = float(snap_radius)
        self.inflated = grid.inflate(self.agent_radius)
        h, w = self.inflated.occ.shape
        self._h, self._w = h, w
        # Search on a grid padded with a ring of occupied cells so that neighbour indices never leave
        # the array and no bounds checks are needed in the inner loop.
        self._wp = w + 2
        free_p = np.pad(~self.inflated.occ, 1, constant_values=False)
        wp = self._wp
        # Moves as (flat offset, d_row, d_col, cost in cells); for each cell a bitmask of the moves that are allowed from it
        # (target free and, for diagonals, both orthogonal neighbours free: no corner cutting). The inner
        # A* loop then iterates over a pre-built tuple of allowed moves per mask value, with no checks.
        moves = [(1, 0, 1, 1.0), (-1, 0, -1, 1.0), (wp, 1, 0, 1.0), (-wp, -1, 0, 1.0),
                 (wp + 1, 1, 1, _SQRT2), (wp - 1, 1, -1, _SQRT2), (-wp + 1, -1, 1, _SQRT2), (-wp - 1, -1, -1, _SQRT2)]
        hp = h + 2

        def shifted(dr: int, dc: int) -> np.ndarray:
            out = np.zeros_like(free_p)
            out[max(0, -dr) : hp - max(0, dr), max(0, -dc) : wp - max(0, dc)] = free_p[
                max(0, dr) : hp - max(0, -dr), max(0, dc) : wp - max(0, -dc)
            ]
            return out  # out[r, c] = free_p[r + dr, c + dc] (False beyond the padding)

        mask = np.zeros(free_p.shape, dtype=np.int64)
        for bit, (_, dr, dc, _) in enumerate(moves):
            ok = free_p & shifted(dr, dc)
            if dr and dc:
                ok &= shifted(dr, 0) & shifted(0, dc)
            mask |= ok.astype(np.int64) << bit
        self._mask_list: list[int] = mask.ravel().tolist()
        self._moves_by_mask = tuple(
            tuple((off, cost) for bit, (off, _, _, cost) in enumerate(moves) if m >> bit & 1) for m in range(256)
        )
        n = free_p.size
        self._row_list: list[int] = (np.arange(n) // wp).tolist()
        self._col_list: list[int] = (np.arange(n) % wp).tolist()
        labels, _ = ndimage.label(~self.inflated.occ)
        self._labels = labels
        self._graph = None
        self._field_cache: dict[tuple[int, int], np.ndarray] = {}
        self._graded_cache: dict[tuple[Any, ...], Any] = {}  # clearance penalties and cost factors

    # ------------------------------------------------------------------ helpers

    def _snap(self, xy: np.ndarray) -> tuple[np.ndarray, tuple[int, int]] | None:
        """Return (point, cell) for a free point, or the nearest free cell centre within snap_radius."""
        g = self.inflated
        if bool(g.is_free(xy)):
            rc = g.world_to_cell(xy)
            return xy, (int(rc[0]), int(rc[1]))
        rc = g.world_to_cell(xy)
        k = int(math.ceil(self.snap_radius / g.resolution)) + 1
        r0, r1 = max(rc[0] - k, 0), min(rc[0] + k + 1, self._h)
        c0, c1 = max(rc[1] - k, 0), min(rc[1] + k + 1, self._w)
        if r0 >= r1 or c0 >= c1:
            return None
        rr, cc = np.mgrid[r0:r1, c0:c1]
        free = ~g.occ[r0:r1, c0:c1]
        if not free.any():
            return None
        centres = g.cell_to_world(np.stack([rr[free], cc[free]], axis=1))
        d = np.linalg.norm(centres - xy, axis=1)
        i = int(np.argmin(d))
        if d[i] > self.snap_radius:
            return None
        return centres[i], (int(rr[free][i]), int(cc[free][i]))

    def sight_from(self, pos: ArrayLike, p1: ArrayLike) -> bool | None:
        """:meth:`line_of_sight` to ``p1`` from the nearest free point to ``pos`` (``pos`` itself when free; a body
        pressed against a wall stands in the inflated obstacle); None when no free point lies within ``snap_radius``."""
        start = self._snap(np.asarray(pos, dtype=np.float64).reshape(2))
        return None if start is None else self.line_of_sight(start[0], p1)

    def line_of_sight(self, p0: ArrayLike, p1: ArrayLike) -> bool:
        """True if every cell touched by the segment p0-p1 is free in the inflated grid.

        Supercover: cells between consecutive grid-line crossings, plus the (up to four) cells around each
        crossing point, so a segment through a grid corner must have all four cells free -- consistent with
        the search's no-corner-cutting rule.
        """
        g = self.inflated
        a = np.asarray(p0, dtype=np.float64)
        b = np.asarray(p1, dtype=np.float64)
        res = g.resolution
        fa = (a - g.origin) / res  # continuous cell coordinates (x, y)
        fb = (b - g.origin) / res
        d = fb - fa
        ts = [np.array([0.0, 1.0])]
        for axis in (0, 1):
            if d[axis] != 0.0:
                lo, hi = sorted((fa[axis], fb[axis]))
                lines = np.arange(math.floor(lo) + 1, math.ceil(hi))
                if lines.size:
                    ts.append((lines - fa[axis]) / d[axis])
        t = np.unique(np.concatenate(ts))
        mids = 0.5 * (t[1:] + t[:-1]) if t.size > 1 else t
        pts = [fa + mids[:, None] * d]
        cross = t[(t > 0.0) & (t < 1.0)]
        if cross.size:
            cp = fa + cross[:, None] * d
            eps = 1e-6
            for ox, oy in ((eps, eps), (eps, -eps), (-eps, eps), (-eps, -eps)):
                pts.append(cp + (ox, oy))
        pts.append(np.stack([fa, fb]))
        q = np.floor(np.concatenate(pts)).astype(np.int64)
        inside = (q[:, 0] >= 0) & (q[:, 0] < self._w) & (q[:, 1] >= 0) & (q[:, 1] < self._h)
        if not inside.all():
            return False
        return not bool(g.occ[q[:, 1], q[:, 0]].any())

    def _astar(self, start: int, goal: int, mult: list[float] | None = None) -> list[int] | None:
        """A* over padded flat indices; returns the list of flat indices start..goal or None.

        ``mult``: optional per-cell cost factors (>= 1, padded flat indices): a move into cell ``nb``
        costs its length times ``mult[nb]`` (the octile heuristic stays admissible).
        """
        rows, cols = self._row_list, self._col_list
        masks, by_mask = self._mask_list, self._moves_by_mask
        gr, gc = rows[goal], cols[goal]
        n = len(masks)
        g_cost = [math.inf] * n
        parent = [-1] * n
        closed = bytearray(n)
        g_cost[start] = 0.0
        k = _SQRT2 - 2.0
        dr, dc = abs(rows[start] - gr), abs(cols[start] - gc)
        h0 = dr + dc + k * min(dr, dc)
        # Heap entries (f, h, index): ties on f are broken towards the goal (smaller h), which keeps
        # the expansion count low on open grids without affecting optimality.
        heap: list[tuple[float, float, int]] = [(h0, h0, start)]
        push, pop = heapq.heappush, heapq.heappop
        while heap:
            cur = pop(heap)[2]
            if closed[cur]:
                continue
            if cur == goal:
                path = [cur]
                while cur != start:
                    cur = parent[cur]
                    path.append(cur)
                path.reverse()
                return path
            closed[cur] = 1
            gcur = g_cost[cur]
            for off, cost in by_mask[masks[cur]]:
                nb = cur + off
                ng = gcur + (cost if mult is None else cost * mult[nb])
                if ng < g_cost[nb] and not closed[nb]:
                    g_cost[nb] = ng
                    parent[nb] = cur
                    dr = rows[nb] - gr
                    if dr < 0:
                        dr = -dr
                    dc = cols[nb] - gc
                    if dc < 0:
                        dc = -dc
                    h = dr + dc + k * (dr if dr < dc else dc)
                    push(heap, (ng + h, h, nb))
        return None

    def _shortcut(self, pts: np.ndarray, visible: Any = None) -> np.ndarray:
        """Line-of-sight shortcutting ("string pulling"); never increases the length.

        From each kept point, the farthest visible later point is searched by exponential then binary
        search (O(log K) line-of-sight checks per kept point). Consecutive input points are visible from
        each other by construction, and only tested-visible shortcuts are taken, so the output is valid;
        replacing a sub-path by a straight segment never makes it longer. ``visible(i, j)`` replaces the
        line-of-sight test between points ``i`` and ``j`` (default: :meth:`line_of_sight`).
        """
        if visible is None:

            def visible(i: int, j: int) -> bool:
                return self.line_of_sight(pts[i], pts[j])

        n = pts.shape[0]
        if n <= 2:
            return pts
        out = [pts[0]]
        a = 0
        while a < n - 1:
            lo, hi, step = a + 1, n, 2
            while lo < n - 1:
                cand = min(a + step, n - 1)
                if visible(a, cand):
                    lo = cand
                    step *= 2
                else:
                    hi = cand
                    break
            while hi - lo > 1:
                mid = (lo + hi) // 2
                if visible(a, mid):
                    lo = mid
                else:
                    hi = mid
            out.append(pts[lo])
            a = lo
        return np.asarray(out)

    # ------------------------------------------------------------------ public API

    def plan_raw(self, start_xy: ArrayLike, goal_xy: ArrayLike) -> np.ndarray | None:
        """Unsmoothed A* path: start point, the centres of the intermediate cells, goal point ``(K, 2)``.

        Start/goal in inflated space are snapped (see class docstring); returns None if snapping fails or
        the goal is unreachable.
        """
        return self._raw_path(start_xy, goal_xy)

    def _raw_path(self, start_xy: ArrayLike, goal_xy: ArrayLike, mult: list[float] | None = None) -> np.ndarray | None:
        """:meth:`plan_raw` with optional per-cell cost factors (see :meth:`_astar`)."""
        s = self._snap(np.asarray(start_xy, dtype=np.float64).reshape(2))
        g = self._snap(np.asarray(goal_xy, dtype=np.float64).reshape(2))
        if s is None or g is None:
            return None
        (s_xy, s_rc), (g_xy, g_rc) = s, g
        if self._labels[s_rc] != self._labels[g_rc]:
            return None  # different connected components: skip the (exhaustive) search
        wp = self._wp
        si = (s_rc[0] + 1) * wp + (s_rc[1] + 1)
        gi = (g_rc[0] + 1) * wp + (g_rc[1] + 1)
        cells = self._astar(si, gi, mult)
        if cells is None:  # pragma: no cover - labels already guarantee connectivity
            return None
        idx = np.asarray(cells, dtype=np.int64)
        rc = np.stack([idx // wp - 1, idx % wp - 1], axis=1)
        centres = self.inflated.cell_to_world(rc)
        if centres.shape[0] == 1:
            return np.stack([s_xy, g_xy])
        return np.concatenate([s_xy[None], centres[1:-1], g_xy[None]], axis=0)

    def plan(self, start_xy: ArrayLike, goal_xy: ArrayLike, spacing: float = 0.5) -> np.ndarray | None:
        """Shortest collision-free path for the agent, smoothed and resampled.

        Args:
            start_xy: start position ``(2,)``.
            goal_xy: goal position ``(2,)``.
            spacing: maximum distance between consecutive output points (metres). Each straight piece of
                the smoothed path is split into equal parts no longer than ``spacing``; the corners of the
                smoothed path are kept so that the segments between output points stay collision-free.

        Returns:
            ``(K, 2)`` float64 array whose first point is the start and last point is the exact goal (or
            their snapped replacements when they were inside inflated space), or None if no path exists.
        """
        if spacing <= 0:
            raise ValueError(f"spacing must be > 0, got {spacing}")
        raw = self.plan_raw(start_xy, goal_xy)
        if raw is None:
            return None
        corners = self._shortcut(raw)
        return resample_polyline(corners, float(spacing))

    # ------------------------------------------------------------------ clearance-graded planning

    def clearance_penalty(self, clearance: float) -> np.ndarray:
        """Per-cell penalty in [0, 1] for being closer than ``agent_radius + clearance`` to an obstacle.

        ``clip((agent_radius + clearance - d) / clearance, 0, 1)`` with ``d`` the cell centre's distance
        to the nearest occupied cell (:meth:`OccupancyGrid.distance_field`): 0 where the agent keeps the
        full clearance, rising to 1 at the edge of its free space. Cached per clearance (read-only).
        """
        clearance = float(clearance)
        if not (math.isfinite(clearance) and clearance > 0):
            raise ValueError(f"clearance must be a finite number > 0 (m), got {clearance!r}")
        key = ("penalty", clearance)
        if key not in self._graded_cache:
            d = self.grid.distance_field().astype(np.float64)
            pen = np.clip((self.agent_radius + clearance - d) / clearance, 0.0, 1.0)
            pen.setflags(write=False)
            self._graded_cache[key] = pen
        return self._graded_cache[key]

    def penalty_along(self, p0: ArrayLike, p1: ArrayLike, clearance: float, step: float | None = None) -> float:
        """Largest :meth:`clearance_penalty` of the cells under the segment ``p0``-``p1`` (sampled every
        half cell, or every ``step`` m)."""
        pen = self.clearance_penalty(clearance)
        a = np.asarray(p0, dtype=np.float64).reshape(2)
        b = np.asarray(p1, dtype=np.float64).reshape(2)
        step = 0.5 * self.grid.resolution if step is None else float(step)
        n = max(int(math.ceil(float(np.linalg.norm(b - a)) / step)), 1)
        pts = a + np.linspace(0.0, 1.0, n + 1)[:, None] * (b - a)
        rc = self.grid.world_to_cell(pts)
        r = np.clip(rc[:, 0], 0, self._h - 1)
        c = np.clip(rc[:, 1], 0, self._w - 1)
        return float(pen[r, c].max())

    def plan_graded(self, start_xy: ArrayLike, goal_xy: ArrayLike, clearance: float, spacing: float = 0.5,
                    weight: float = 4.0) -> np.ndarray | None:
        """Like :meth:`plan`, but keeping ``clearance`` (m) beyond the agent's radius wherever the free
        space allows it, and centring the path in passages too narrow for it.

        Planning on a grid inflated by ``radius + clearance`` fails as soon as one door on the way is
        narrower than that; falling back to the bare radius then gives a path that hugs every wall and
        corner at exactly the radius. Here the search runs on the bare-radius grid, and a move into a
        cell costs ``1 + weight * penalty`` times its length (:meth:`clearance_penalty`), so that the
        path pays for every metre it spends near obstacles and, in a door, runs along its middle. The
        shortcutting only takes straight segments whose penalty stays within that of the cells they
        replace (plus a tenth of the band), so it does not cut corners back into the band.

        Returns ``None`` when no path exists for the bare radius.
        """
        if spacing <= 0:
            raise ValueError(f"spacing must be > 0, got {spacing}")
        if not (math.isfinite(weight) and weight >= 0):
            raise ValueError(f"weight must be a finite number >= 0, got {weight!r}")
        pen = self.clearance_penalty(clearance)
        key = ("mult", float(clearance), float(weight))
        if key not in self._graded_cache:
            self._graded_cache[key] = (1.0 + weight * np.pad(pen, 1, constant_values=1.0)).ravel().tolist()
        raw = self._raw_path(start_xy, goal_xy, self._graded_cache[key])
        if raw is None:
            return None
        pts_rc = self.grid.world_to_cell(raw)
        pt_pen = pen[np.clip(pts_rc[:, 0], 0, self._h - 1), np.clip(pts_rc[:, 1], 0, self._w - 1)]

        def visible(i: int, j: int) -> bool:
            if not self.line_of_sight(raw[i], raw[j]):
                return False
            return self.penalty_along(raw[i], raw[j], clearance) <= float(pt_pen[i:j + 1].max()) + 0.1

        corners = self._shortcut(raw, visible)
        return resample_polyline(corners, float(spacing))

    def path_length(self, path: ArrayLike | None) -> float:
        """Length of a polyline (``inf`` for None)."""
        return path_length(path)

    def shortest_path_length(self, start_xy: ArrayLike, goal_xy: ArrayLike) -> float:
        """Length of the smoothed shortest path (metres), ``inf`` if unreachable. Used for SPL."""
        raw = self.plan_raw(start_xy, goal_xy)
        if raw is None:
            return math.inf
        return path_length(self._shortcut(raw))

    def distance_to(self, goal_xy: ArrayLike) -> np.ndarray:
        """Grid geodesic distance (metres) from every cell centre to ``goal_xy``'s cell, float64 ``(H, W)``.

        Dijkstra over the same 8-connected, no-corner-cutting graph as :meth:`plan` (scipy csgraph, C
        speed), cached per goal cell; ``inf`` for occupied or unreachable cells. Useful when many agents
        share a goal: descend the field instead of planning one by one.
        """
        from scipy.sparse.csgraph import dijkstra

        snapped = self._snap(np.asarray(goal_xy, dtype=np.float64).reshape(2))
        if snapped is None:
            return np.full((self._h, self._w), np.inf)
        rc = snapped[1]
        if rc not in self._field_cache:
            graph = self._build_graph()
            dist = dijkstra(graph, directed=False, indices=rc[0] * self._w + rc[1])
            field_ = (dist * self.inflated.resolution).reshape(self._h, self._w)
            field_[self.inflated.occ] = np.inf
            field_.setflags(write=False)
            if len(self._field_cache) >= 64:
                self._field_cache.pop(next(iter(self._field_cache)))
            self._field_cache[rc] = field_
        return self._field_cache[rc]

    def _build_graph(self) -> Any:  # a scipy.sparse CSR matrix
        if self._graph is None:
            from scipy.sparse import coo_matrix

            h, w = self._h, self._w
            free = ~self.inflated.occ
            idx = np.arange(h * w).reshape(h, w)
            rows, cols, costs = [], [], []
            # Each undirected edge once: cell (r, c) -> (r + dr, c + dc) with dr >= 0.
            for dr, dc, cost in ((0, 1, 1.0), (1, 0, 1.0), (1, 1, _SQRT2), (1, -1, _SQRT2)):
                ca0, ca1 = max(0, -dc), w - max(0, dc)
                src_sl = (slice(0, h - dr), slice(ca0, ca1))
                dst_sl = (slice(dr, h), slice(ca0 + dc, ca1 + dc))
                ok = free[src_sl] & free[dst_sl]
                if dr and dc:  # diagonal: both orthogonal neighbours must be free (no corner cutting)
                    ok &= free[dr:h, ca0:ca1] & free[0 : h - dr, ca0 + dc : ca1 + dc]
                rows.append(idx[src_sl][ok])
                cols.append(idx[dst_sl][ok])
                costs.append(np.full(int(ok.sum()), cost))
            r = np.concatenate(rows)
            c = np.concatenate(cols)
            v = np.concatenate(costs)
            self._graph = coo_matrix((v, (r, c)), shape=(h * w, h * w)).tocsr()
        return self._graph


def resample_polyline(corners: np.ndarray, spacing: float) -> np.ndarray:
    """Split each segment of the polyline into equal pieces no longer than ``spacing``."""
    out = [corners[:1]]
    for a, b in zip(corners[:-1], corners[1:], strict=True):
        seg_len = float(np.hypot(*(b - a)))
        if seg_len == 0.0:
            continue
        k = max(1, int(math.ceil(seg_len / spacing - 1e-9)))
        t = np.arange(1, k + 1)[:, None] / k
        pts = a + t * (b - a)
        pts[-1] = b  # exact corner/goal, free of round-off
        out.append(pts)
    return np.concatenate(out, axis=0)
