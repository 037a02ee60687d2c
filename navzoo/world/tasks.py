"""Start/goal task sampling for robots and humans according to a scene's protocol.

All randomness comes from the ``np.random.Generator`` passed in, so a given generator state always yields
the same tasks. Candidates are drawn in small batches and checked vectorised; the first valid candidate
of a batch (in draw order) is taken, which keeps results deterministic.
"""

from __future__ import annotations

import math
from collections.abc import Iterator

import numpy as np
from numpy.typing import ArrayLike
from scipy import ndimage

from navzoo.world import geometry as geo
from navzoo.world.occupancy import OccupancyGrid
from navzoo.world.scene import Scene, SceneError

__all__ = ["TaskSampler"]

_KINDS = ("robot", "human")
_BATCH = 32


class TaskSampler:
    """Sample start/goal pairs that are free, reachable and non-overlapping.

    A valid position for an agent of radius ``r``: its cell is free in the grid inflated by ``r``, its exact
    clearance to every obstacle edge is at least ``r``, and it lies inside the scene bounds. Start and goal
    are valid, in the same connected free component (so the planner can connect them), and at least
    ``min_goal_dist`` apart in straight line.

    Protocols (``scene.protocol.type``):
        * ``regions``: starts uniformly over the free part of the kind's spawn regions (whole free space
          when the list is empty), goals over the free part of its goal regions. Goal regions that contain
          the start are skipped when another goal region can be used, so an agent spawned in one end of a
          corridor heads for the other end.
        * ``circle_crossing`` / ``square_crossing``: CrowdNav's generators (see :meth:`sample`).

    Args:
        scene: the scene.
        grid: its occupancy grid (``scene.occupancy()`` when None).
        agent_radius: radius of the agents being placed (metres).
        max_tries: candidates examined per agent before giving up with :class:`SceneError`.
    """

    def __init__(
        self,
        scene: Scene,
        grid: OccupancyGrid | None = None,
        agent_radius: float = 0.3,
        max_tries: int = 1000,
    ):
        self.scene = scene
        self.grid = grid if grid is not None else scene.occupancy()
        self.agent_radius = float(agent_radius)
        self.max_tries = int(max_tries)
        self.inflated = self.grid.inflate(self.agent_radius)
        self._labels, n_labels = ndimage.label(~self.inflated.occ)
        counts = np.bincount(self._labels.ravel(), minlength=n_labels + 1)
        counts[0] = 0
        self._largest_label = int(np.argmax(counts))
        self._segments = scene.wall_segments()
        # With clearance >= r > half a cell diagonal, the point and its cell centre are on the same side of
        # every edge, so "cell not occupied" is an exact inside-obstacle test; otherwise test polygons.
        self._need_polygon_test = self.agent_radius <= self.grid.resolution * math.sqrt(0.5)
        self._region_cells: dict[str, np.ndarray] = {}
        self._free_cells = np.flatnonzero(~self.inflated.occ)

    # ------------------------------------------------------------------ validity

    def _labels_at(self, pts: np.ndarray) -> np.ndarray:
        """Component label of each point's cell (0 = occupied or off-grid)."""
        rc = self.inflated.world_to_cell(pts)
        h, w = self._labels.shape
        ok = (rc[:, 0] >= 0) & (rc[:, 0] < h) & (rc[:, 1] >= 0) & (rc[:, 1] < w)
        out = np.zeros(pts.shape[0], dtype=np.int64)
        out[ok] = self._labels[rc[ok, 0], rc[ok, 1]]
        return out

    def valid_positions(self, points: ArrayLike) -> np.ndarray:
        """``(N,)`` bool: free for an agent of ``agent_radius`` (inflated grid + exact edge clearance)."""
        pts = geo.as_points(points)
        ok = self._cheap_valid(pts)
        if ok.any():
            ok[ok] = self._exact_valid(pts[ok])
        return ok

    def _cheap_valid(self, pts: np.ndarray) -> np.ndarray:
        """Grid part of :meth:`valid_positions`: cell free in the inflated grid, disc inside the bounds."""
        ok = self.inflated.is_free(pts)
        x0, y0, x1, y1 = self.scene.bounds
        r = self.agent_radius
        ok &= (pts[:, 0] >= x0 + r) & (pts[:, 0] <= x1 - r) & (pts[:, 1] >= y0 + r) & (pts[:, 1] <= y1 - r)
        return ok

    def _exact_valid(self, pts: np.ndarray) -> np.ndarray:
        """Exact part of :meth:`valid_positions`: clearance to every obstacle edge >= agent_radius."""
        ok = np.ones(pts.shape[0], dtype=bool)
        if self._segments.shape[0] and pts.shape[0]:
            ok = geo.min_distance_to_segments(pts, self._segments) >= self.agent_radius
            if self._need_polygon_test and ok.any():
                ok[ok] = self.scene.clearance(pts[ok]) >= self.agent_radius
        return ok

    def _valid_indices(self, mask: np.ndarray, *arrays: np.ndarray) -> Iterator[int]:
        """Indices where ``mask`` holds and every array's point passes the exact test, in increasing order.

        The exact test (distances to all edges) dominates the cost, so it runs lazily on small chunks:
        usually the first candidate that passes the grid checks is the one taken.
        """
        idx = np.flatnonzero(mask)
        for k in range(0, idx.size, 4):
            chunk = idx[k : k + 4]
            ok = np.ones(chunk.size, dtype=bool)
            for arr in arrays:
                ok &= self._exact_valid(arr[chunk])
            yield from chunk[ok].tolist()

    def _first_valid(self, mask: np.ndarray, *arrays: np.ndarray) -> int | None:
        return next(self._valid_indices(mask, *arrays), None)

    def _cells_for(self, names: tuple[str, ...]) -> np.ndarray:
        """Flat indices of free (inflated) cells in the union of the named regions (all free if empty)."""
        if not names:
            return self._free_cells
        key = ",".join(names)
        if key not in self._region_cells:
            mask = np.zeros(self.grid.occ.shape, dtype=bool)
            for name in names:
                mask |= self.inflated.region_mask(self.scene.regions[name])
            self._region_cells[key] = np.flatnonzero(mask & ~self.inflated.occ)
        return self._region_cells[key]

    def _in_regions(self, pts: np.ndarray, names: tuple[str, ...]) -> np.ndarray:
        if not names:
            return np.ones(pts.shape[0], dtype=bool)
        inside = np.zeros(pts.shape[0], dtype=bool)
        for name in names:
            inside |= self.scene.regions[name].contains(pts)
        return inside

    def _draw_in_cells(self, rng: np.random.Generator, cells: np.ndarray, k: int) -> np.ndarray:
        """``k`` points uniform over the union of ``cells`` (uniform cell, then uniform inside it)."""
        pick = cells[rng.integers(0, cells.size, size=k)]
        w = self.grid.occ.shape[1]
        rc = np.stack([pick // w, pick % w], axis=1)
        jitter = rng.uniform(-0.5, 0.5, size=(k, 2)) * self.grid.resolution
        return self.grid.cell_to_world(rc) + jitter

    @staticmethod
    def _far_from(pts: np.ndarray, others: np.ndarray, min_dist: np.ndarray | float) -> np.ndarray:
        if others.shape[0] == 0:
            return np.ones(pts.shape[0], dtype=bool)
        d = np.linalg.norm(pts[:, None, :] - others[None, :, :], axis=2)
        return np.all(d >= np.asarray(min_dist, dtype=np.float64), axis=1)

    def _fail(self, what: str, kind: str, i: int, n: int, detail: str) -> SceneError:
        return SceneError(
            f"could not sample a valid {what} for {kind} {i} of {n} after {self.max_tries} tries "
            f"(agent radius {self.agent_radius:g} m; {detail}); the regions may be too small or too crowded",
            scene=self.scene.name,
        )

    # ------------------------------------------------------------------ public API

    def sample(
        self,
        rng: np.random.Generator,
        n: int,
        kind: str = "human",
        min_goal_dist: float = 2.0,
        min_separation: float | None = None,
        existing_positions: ArrayLike | None = None,
        existing_radii: ArrayLike | None = None,
        existing_goals: ArrayLike | None = None,
        goal_separation: float = 0.0,
        margin: float | None = None,
    ) -> tuple[np.ndarray, np.ndarray]:
        """Sample ``n`` start/goal pairs for agents of ``kind``.

        Args:
            rng: the random generator (the only source of randomness).
            n: number of agents.
            kind: ``"robot"`` or ``"human"`` (selects spawn/goal regions and crossing-protocol rules).
            min_goal_dist: minimum straight-line start-goal distance (metres).
            min_separation: minimum distance between the new starts; default ``2 * agent_radius + margin``.
            existing_positions: ``(E, 2)`` positions of agents already placed (e.g. the robot).
            existing_radii: ``(E,)`` or scalar radii of those agents (default ``agent_radius``); new starts
                keep ``agent_radius + existing_radius + margin`` from them.
            existing_goals: ``(E, 2)`` goals of those agents. The crossing protocols keep new starts (circle)
                or goals (square) away from them as CrowdNav does; the regions protocol applies
                ``goal_separation`` to them.
            goal_separation: regions protocol: minimum distance between goals (new and existing); 0 allows
                several agents to share a destination area freely.
            margin: clearance added to the sum of radii for start separation (metres); ``None``: 0.2 m
                in the crossing protocols (CrowdNav's discomfort distance), else 0.1 m.

        Returns:
            ``(starts (n, 2), goals (n, 2))`` float64 arrays.

        Circle crossing (humans): start ``R (cos a, sin a) + (U(-noise, noise), U(-noise, noise))`` with
        ``a ~ U(0, 2 pi)``,
        goal ``-start``; a human is resampled when its start is closer than the sum of radii + margin to any
        other agent's start or goal. The first robot goes from ``(0, -R)`` to ``(0, R)``, further robots are
        placed like humans. Square crossing (humans): ``sign = +-1``, start ``(sign U(0,1) w/2, (U(0,1) - 0.5)
        w)``, goal ``(-sign U(0,1) w/2, (U(0,1) - 0.5) w)``, start resampled against other starts and goal
        against other goals; robots as in circle crossing with ``R = protocol.radius``. In both, candidates
        must also be valid positions and ``min_goal_dist`` apart (CrowdNav does not check the latter).

        Raises:
            SceneError: when no valid sample is found within ``max_tries`` candidates for an agent.
            ValueError: for an unknown ``kind``.
        """
        if kind not in _KINDS:
            raise ValueError(f"kind must be one of {_KINDS}, got {kind!r}")
        n = int(n)
        r = self.agent_radius
        if margin is None:
            crossing = self.scene.protocol is not None and self.scene.protocol.type in ("circle_crossing", "square_crossing")
            margin = 0.2 if crossing else 0.1
        sep = 2.0 * r + margin if min_separation is None else float(min_separation)
        ex_pos = np.zeros((0, 2)) if existing_positions is None else geo.as_points(existing_positions)
        if ex_pos.shape[0] == 0:
            ex_pos = np.zeros((0, 2))
        if existing_radii is None:
            ex_rad = np.full(ex_pos.shape[0], r)
        else:
            ex_rad = np.broadcast_to(np.asarray(existing_radii, dtype=np.float64), (ex_pos.shape[0],)).copy()
        ex_goals = np.zeros((0, 2)) if existing_goals is None else geo.as_points(existing_goals)
        if ex_goals.shape[0] == 0:
            ex_goals = np.zeros((0, 2))
        ex_goal_rad = ex_rad if ex_goals.shape[0] == ex_pos.shape[0] else np.full(ex_goals.shape[0], r)
        starts = np.zeros((n, 2))
        goals = np.zeros((n, 2))
        proto = self.scene.protocol.type
        for i in range(n):
            # Minimum distances of a new start to: existing agents, then the i starts placed so far.
            start_min = np.concatenate([r + ex_rad + margin, np.full(i, sep)])
            others = np.concatenate([ex_pos, starts[:i]])
            goal_min = np.concatenate([r + ex_goal_rad + margin, np.full(i, sep)])
            other_goals = np.concatenate([ex_goals, goals[:i]])
            if proto == "regions":
                s, g = self._sample_regions(
                    rng, kind, i, n, min_goal_dist, others, start_min, other_goals, goal_separation
                )
            elif proto == "circle_crossing":
                s, g = self._sample_circle(rng, kind, i, n, min_goal_dist, others, start_min, other_goals, goal_min)
            else:
                s, g = self._sample_square(rng, kind, i, n, min_goal_dist, others, start_min, other_goals, goal_min)
            starts[i] = s
            goals[i] = g
        return starts, goals

    def sample_goal(
        self,
        rng: np.random.Generator,
        start: ArrayLike,
        kind: str = "human",
        min_goal_dist: float = 2.0,
    ) -> np.ndarray:
        """A new goal ``(2,)`` for an agent at ``start`` (e.g. a human that reached its goal).

        Regions protocol: like the goals of :meth:`sample` (same component, regions not containing the start
        preferred). Circle crossing: the opposite point ``-start`` when valid, else a random circle point.
        Square crossing: a random point on the half of the square opposite to ``start``'s x sign.

        Unlike :meth:`sample`, ``start`` may be a position where no agent could be placed (an agent pushed
        against a wall): the nearest free component within 1 m is used (the largest one if none). When no
        goal at ``min_goal_dist`` exists, the distance is halved, then dropped, before giving up.
        """
        if kind not in _KINDS:
            raise ValueError(f"kind must be one of {_KINDS}, got {kind!r}")
        s = np.asarray(start, dtype=np.float64).reshape(2)
        label = self._label_near(s) or self._largest_label
        proto = self.scene.protocol
        # An agent in motion may stand where a new agent could not be placed (e.g. closer than its radius to
        # a wall); its component is then the nearest free one. If even the requested distance is impossible,
        # the distance is relaxed rather than failing in the middle of an episode.
        for dist in (min_goal_dist, 0.5 * min_goal_dist, 0.0):
            goal = self._sample_goal_once(rng, s, label, kind, dist)
            if goal is not None:
                return goal
        raise self._fail("goal", kind, 0, 1, f"{proto.type} protocol, from start {s.tolist()}")

    def _label_near(self, point: np.ndarray, search: float = 1.0) -> int:
        """Component label at ``point``, or of the nearest free cell within ``search`` metres (0 if none)."""
        label = int(self._labels_at(point[None])[0])
        if label:
            return label
        g = self.inflated
        rc = g.world_to_cell(point)
        k = int(math.ceil(search / g.resolution))
        h, w = self._labels.shape
        r0, r1 = max(rc[0] - k, 0), min(rc[0] + k + 1, h)
        c0, c1 = max(rc[1] - k, 0), min(rc[1] + k + 1, w)
        if r0 >= r1 or c0 >= c1:
            return 0
        window = self._labels[r0:r1, c0:c1]
        cells = np.argwhere(window > 0)
        if cells.size == 0:
            return 0
        centres = g.cell_to_world(cells + [r0, c0])
        best = cells[int(np.argmin(np.linalg.norm(centres - point, axis=1)))]
        return int(window[best[0], best[1]])

    def _sample_goal_once(
        self, rng: np.random.Generator, s: np.ndarray, label: int, kind: str, min_goal_dist: float
    ) -> np.ndarray | None:
        proto = self.scene.protocol
        if proto.type == "regions":
            return self._sample_goal_regions(rng, s, label, kind, min_goal_dist, np.zeros((0, 2)), 0.0)
        if proto.type == "circle_crossing":
            opposite = -s
            if self._first_valid(self._goal_ok(opposite[None], s, label, min_goal_dist), opposite[None]) is not None:
                return opposite
        for _ in range(math.ceil(self.max_tries / _BATCH)):
            if proto.type == "circle_crossing":
                cand = self._circle_points(rng, _BATCH)
            else:
                sign = -1.0 if s[0] > 0 else 1.0
                cand = np.stack(
                    [sign * rng.random(_BATCH) * proto.width * 0.5, (rng.random(_BATCH) - 0.5) * proto.width], axis=1
                )
            j = self._first_valid(self._goal_ok(cand, s, label, min_goal_dist), cand)
            if j is not None:
                return cand[j]
        return None

    # ------------------------------------------------------------------ protocol implementations

    def _goal_ok(self, cand: np.ndarray, start: np.ndarray, label: int, min_goal_dist: float) -> np.ndarray:
        """Grid-level goal checks (the exact clearance test is left to ``_first_valid``)."""
        ok = self._cheap_valid(cand)
        ok &= np.linalg.norm(cand - start, axis=1) >= min_goal_dist
        ok &= self._labels_at(cand) == label
        return ok

    def _sample_regions(
        self,
        rng: np.random.Generator,
        kind: str,
        i: int,
        n: int,
        min_goal_dist: float,
        others: np.ndarray,
        start_min: np.ndarray,
        other_goals: np.ndarray,
        goal_separation: float,
    ) -> tuple[np.ndarray, np.ndarray]:
        spawn = self.scene.region_list(kind, "spawn")
        cells = self._cells_for(spawn)
        if cells.size == 0:
            raise self._fail("start", kind, i, n, f"spawn regions {list(spawn)} have no free cells")
        tries = 0
        while tries < self.max_tries:
            cand = self._draw_in_cells(rng, cells, _BATCH)
            tries += _BATCH
            ok = self._cheap_valid(cand) & self._in_regions(cand, spawn)
            ok &= self._far_from(cand, others, start_min)
            for j in self._valid_indices(ok, cand):
                label = int(self._labels_at(cand[j : j + 1])[0])
                goal = self._sample_goal_regions(rng, cand[j], label, kind, min_goal_dist, other_goals, goal_separation)
                if goal is not None:
                    return cand[j], goal
                tries += 1  # a start without any admissible goal counts as a failed try
                if tries >= self.max_tries:
                    break
        raise self._fail(
            "start/goal pair",
            kind,
            i,
            n,
            f"spawn regions {list(spawn) or 'whole free space'}, "
            f"goal regions {list(self.scene.region_list(kind, 'goal')) or 'whole free space'}, "
            f"min_goal_dist {min_goal_dist:g} m",
        )

    def _sample_goal_regions(
        self,
        rng: np.random.Generator,
        start: np.ndarray,
        label: int,
        kind: str,
        min_goal_dist: float,
        other_goals: np.ndarray,
        goal_separation: float,
    ) -> np.ndarray | None:
        names = self.scene.region_list(kind, "goal")
        # Prefer goal regions that do not contain the start (go somewhere else), if any is usable.
        away = tuple(nm for nm in names if not self.scene.regions[nm].contains(start[None])[0])
        options = [away, names] if away and len(away) < len(names) else [names]
        w = self.grid.occ.shape[1]
        for allowed in options:
            cells = self._cells_for(allowed)
            if cells.size == 0:
                continue
            rc = np.stack([cells // w, cells % w], axis=1)
            # Prefilter candidate cells: same component, and not obviously too close (the jitter moves a
            # point by at most half a cell diagonal, the exact distance is re-checked below).
            centres = self.grid.cell_to_world(rc)
            slack = self.grid.resolution
            keep = (self._labels.ravel()[cells] == label) & (
                np.linalg.norm(centres - start, axis=1) >= min_goal_dist - slack
            )
            cells = cells[keep]
            if cells.size == 0:
                continue
            for _ in range(max(1, math.ceil(self.max_tries / (4 * _BATCH)))):
                cand = self._draw_in_cells(rng, cells, _BATCH)
                ok = self._goal_ok(cand, start, label, min_goal_dist) & self._in_regions(cand, allowed)
                if goal_separation > 0:
                    ok &= self._far_from(cand, other_goals, goal_separation)
                j = self._first_valid(ok, cand)
                if j is not None:
                    return cand[j]
        return None

    def _circle_points(self, rng: np.random.Generator, k: int) -> np.ndarray:
        proto = self.scene.protocol
        angle = rng.random(k) * 2.0 * np.pi
        noise = rng.uniform(-proto.noise, proto.noise, size=(k, 2))
        return proto.radius * np.stack([np.cos(angle), np.sin(angle)], axis=1) + noise

    def _robot_fixed(
        self, kind: str, i: int, min_goal_dist: float, others: np.ndarray, start_min: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray] | None:
        """CrowdNav's robot task (0, -R) -> (0, R) for the first robot, if it is free of other agents."""
        if kind != "robot" or i != 0:
            return None
        radius = self.scene.protocol.radius
        s = np.array([0.0, -radius])
        g = np.array([0.0, radius])
        label = int(self._labels_at(s[None])[0])
        ok = self._cheap_valid(s[None]) & self._goal_ok(g[None], s, label, min_goal_dist)
        ok &= self._far_from(s[None], others, start_min)
        if self._first_valid(ok, s[None], g[None]) is not None:
            return s, g
        return None

    def _sample_circle(
        self,
        rng: np.random.Generator,
        kind: str,
        i: int,
        n: int,
        min_goal_dist: float,
        others: np.ndarray,
        start_min: np.ndarray,
        other_goals: np.ndarray,
        goal_min: np.ndarray,
    ) -> tuple[np.ndarray, np.ndarray]:
        fixed = self._robot_fixed(kind, i, min_goal_dist, others, start_min)
        if fixed is not None:
            return fixed
        for _ in range(math.ceil(self.max_tries / _BATCH)):
            cand = self._circle_points(rng, _BATCH)
            goal = -cand
            ok = self._cheap_valid(cand) & self._cheap_valid(goal)
            ok &= np.linalg.norm(goal - cand, axis=1) >= min_goal_dist
            ok &= self._labels_at(cand) == self._labels_at(goal)
            # CrowdNav: the start must keep clear of every other agent's start *and* goal.
            ok &= self._far_from(cand, others, start_min) & self._far_from(cand, other_goals, goal_min)
            j = self._first_valid(ok, cand, goal)
            if j is not None:
                return cand[j], goal[j]
        raise self._fail("start", kind, i, n, f"circle_crossing radius {self.scene.protocol.radius:g} m")

    def _sample_square(
        self,
        rng: np.random.Generator,
        kind: str,
        i: int,
        n: int,
        min_goal_dist: float,
        others: np.ndarray,
        start_min: np.ndarray,
        other_goals: np.ndarray,
        goal_min: np.ndarray,
    ) -> tuple[np.ndarray, np.ndarray]:
        fixed = self._robot_fixed(kind, i, min_goal_dist, others, start_min)
        if fixed is not None:
            return fixed
        width = self.scene.protocol.width
        sign = -1.0 if rng.random() > 0.5 else 1.0
        start = None
        for _ in range(math.ceil(self.max_tries / _BATCH)):
            cand = np.stack([rng.random(_BATCH) * width * 0.5 * sign, (rng.random(_BATCH) - 0.5) * width], axis=1)
            j = self._first_valid(self._cheap_valid(cand) & self._far_from(cand, others, start_min), cand)
            if j is not None:
                start = cand[j]
                break
        if start is None:
            raise self._fail("start", kind, i, n, f"square_crossing width {width:g} m")
        label = int(self._labels_at(start[None])[0])
        for _ in range(math.ceil(self.max_tries / _BATCH)):
            cand = np.stack([rng.random(_BATCH) * width * 0.5 * -sign, (rng.random(_BATCH) - 0.5) * width], axis=1)
            ok = self._goal_ok(cand, start, label, min_goal_dist) & self._far_from(cand, other_goals, goal_min)
            j = self._first_valid(ok, cand)
            if j is not None:
                return start, cand[j]
        raise self._fail("goal", kind, i, n, f"square_crossing width {width:g} m")
