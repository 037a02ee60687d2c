"""Procedural scenes: rooms-and-doors floor plans and shop/warehouse aisle layouts generated from a seed.

Both generators return a validated :class:`~navzoo.world.scene.Scene` (regions protocol) whose free space
for an agent of radius 0.3 m connects every spawn and goal region (checked on the occupancy grid before
returning). The output depends only on the arguments: the same seed and parameters give the same scene.
All coordinates are rounded to 5 cm.

* :func:`rooms_and_doors`: a rectangular floor split recursively (binary space partition) into rooms of
  at least ``min_room`` metres a side, with 0.12 m interior walls; a random spanning tree of the room
  adjacency graph gets one door per edge (so every room is reachable) and each further adjacency gets a
  door with probability ``loop_prob`` (loops). Optional furniture stands against the walls or in the
  middle of rooms, and is dropped when it would disconnect anything.
* :func:`aisles`: a store or warehouse hall with a front zone (entrances in the south wall, checkouts or
  staged pallets), parallel shelf rows (gondolas 0.9 m, racks 1.2 m or double pallet racks 2.2 m deep)
  with aisles between them, cross aisles cutting the rows, side aisles and a back aisle.

By name, through the scene library: ``get_scene("procedural_rooms_<seed>")`` and
``get_scene("procedural_aisles_<seed>")`` give the default-parameter scene for that seed (see
:func:`from_name`).
"""

from __future__ import annotations

import dataclasses
import math
import re

import numpy as np
from scipy import ndimage

from navzoo.world.occupancy import OccupancyGrid
from navzoo.world.planner import AStarPlanner
from navzoo.world.scene import (
    BoxObstacle,
    CircleObstacle,
    Obstacle,
    Region,
    Scene,
    SceneError,
    WallObstacle,
)

__all__ = ["aisles", "from_name", "rooms_and_doors"]

#: Agent radius for which connectivity is guaranteed (the robot's and pedestrians' default radius).
AGENT_RADIUS = 0.3
#: Grid resolution of the connectivity checks (the library's default).
RESOLUTION = 0.1
# Extra radius used while deciding whether furniture may stay, so that the result keeps some slack.
_CHECK_RADIUS = AGENT_RADIUS + 0.05

_OUTER = 0.2  # outer wall thickness
_INNER = 0.12  # interior wall thickness
_NAME_RE = re.compile(r"^procedural_(rooms|aisles)_(0|[1-9][0-9]*)$")


def _q(x: float, step: float = 0.05) -> float:
    """Round to a multiple of ``step`` (and to 3 decimals, so that YAML dumps stay short)."""
    return round(round(float(x) / step) * step, 3)


def _count(n: int, noun: str) -> str:
    return f"{n} {noun}" + ("" if n == 1 else "s")


def _outer_walls(
    w: float, h: float, height: float, gaps_south: list[tuple[float, float]] | None = None
) -> list[Obstacle]:
    """Four outer walls along the bounds; ``gaps_south`` are door intervals ``(x0, x1)`` in the south wall."""
    t = _OUTER
    walls: list[Obstacle] = []
    x = 0.0
    for g0, g1 in sorted(gaps_south or []):
        if g0 - x > 0.05:
            walls.append(WallObstacle((x, t / 2), (g0, t / 2), t, height))
        x = g1
    if w - x > 0.05:
        walls.append(WallObstacle((x, t / 2), (w, t / 2), t, height))
    walls.append(WallObstacle((0.0, h - t / 2), (w, h - t / 2), t, height))
    walls.append(WallObstacle((t / 2, t), (t / 2, h - t), t, height))
    walls.append(WallObstacle((w - t / 2, t), (w - t / 2, h - t), t, height))
    return walls


class _Connectivity:
    """Incremental check that extra obstacles keep a set of regions in one free component."""

    def __init__(
        self, bounds: tuple[float, float, float, float], obstacles: list[Obstacle], regions: list[Region]
    ):
        self.bounds = bounds
        base = Scene(name="_procedural", bounds=bounds, obstacles=tuple(obstacles))
        self.occ = np.array(base.occupancy(RESOLUTION).occ)
        self.grid = OccupancyGrid(self.occ, RESOLUTION, (bounds[0], bounds[1]))
        self.masks = [self.grid.region_mask(r) for r in regions]
        self.forbidden = np.zeros_like(self.occ)

    def keep_clear(self, x0: float, y0: float, x1: float, y1: float) -> None:
        """Cells of a rectangle that obstacles may not occupy (doorways, entrances)."""
        region = Region(name="_clear", rect=(x0, y0, x1, y1))
        self.forbidden |= self.grid.region_mask(region)

    def _connected(self, occ: np.ndarray) -> bool:
        inflated = OccupancyGrid(occ, RESOLUTION, self.grid.origin).inflate(_CHECK_RADIUS).occ
        labels, _ = ndimage.label(~inflated)
        common: set[int] | None = None
        for mask in self.masks:
            found = set(np.unique(labels[mask]).tolist()) - {0}
            common = found if common is None else common & found
            if not common:
                return False
        return True

    def try_add(self, obstacle: Obstacle) -> bool:
        """Add ``obstacle`` if it stays inside the bounds, off the kept-clear cells, and keeps connectivity."""
        x0, y0, x1, y1 = self.bounds
        poly = obstacle.polygon()
        if poly[:, 0].min() < x0 or poly[:, 1].min() < y0 or poly[:, 0].max() > x1 or poly[:, 1].max() > y1:
            return False
        cells = Scene(name="_piece", bounds=self.bounds, obstacles=(obstacle,)).occupancy(RESOLUTION).occ
        if np.any(cells & self.forbidden):
            return False
        occ = self.occ | cells
        if not self._connected(occ):
            return False
        self.occ = occ
        return True


def _finish(
    name: str,
    description: str,
    bounds: tuple[float, float, float, float],
    obstacles: list[Obstacle],
    regions: dict[str, Region],
    robot_spawn: list[str],
    robot_goal: list[str],
    human_spawn: list[str],
    human_goal: list[str],
    waypoints: dict[str, tuple[float, float]],
    humans_per_m2: float,
    max_humans: int,
) -> Scene:
    scene = Scene(
        name=name,
        description=description,
        bounds=bounds,
        obstacles=tuple(obstacles),
        regions=regions,
        robot_spawn=tuple(robot_spawn),
        robot_goal=tuple(robot_goal),
        human_spawn=tuple(human_spawn),
        human_goal=tuple(human_goal),
        waypoints=waypoints,
    )
    free = scene.free_area(0.0, RESOLUTION)
    humans = int(np.clip(round(humans_per_m2 * free), 2, max_humans))
    # Time limit: 2.5 s per metre of the longest geodesic from the centre of one of the first three robot
    # spawn/goal regions to any reachable cell (an upper bound on most tasks), at least 30 s.
    grid = scene.occupancy(RESOLUTION)
    planner = AStarPlanner(grid, AGENT_RADIUS)
    free_cells = ~planner.inflated.occ
    longest = 0.0
    for key in list(dict.fromkeys(robot_spawn + robot_goal))[:3]:
        cells = np.argwhere(grid.region_mask(regions[key]) & free_cells)
        dist = planner.distance_to(grid.cell_to_world(cells[len(cells) // 2]))
        longest = max(longest, float(dist[np.isfinite(dist)].max()))
    time_limit = float(max(30, 5 * math.ceil(2.5 * longest / 5)))
    out = dataclasses.replace(scene, default_humans=humans, time_limit=time_limit)
    out.validate_reachability(AGENT_RADIUS, RESOLUTION)
    return out


# ---------------------------------------------------------------------------------------------------------
# Rooms and doors
# ---------------------------------------------------------------------------------------------------------


def rooms_and_doors(
    seed: int,
    *,
    width: float | None = None,
    height: float | None = None,
    min_room: float = 3.0,
    max_room: float = 8.0,
    door_width: float = 0.9,
    loop_prob: float = 0.3,
    furniture: bool = True,
    name: str | None = None,
) -> Scene:
    """A floor of rectangular rooms joined by doors, generated from ``seed``.

    Args:
        seed: random seed (``numpy.random.default_rng(seed)`` is the only source of randomness).
        width, height: floor size in metres (default: drawn from the seed, 10-24 x 8-18 m).
        min_room: smallest room side in metres; must be at least ``2 * (door_width + 0.4)`` so that every
            wall between two sibling partitions has room for a door.
        max_room: rooms with a side longer than this are always split further.
        door_width: clear width of the doors (>= 0.8 m for the 0.3 m agents).
        loop_prob: probability of a door in each wall between adjacent rooms beyond the spanning tree.
        furniture: place furniture (never blocking a door or disconnecting a room).
        name: scene name (default ``procedural_rooms_<seed>``).

    Returns:
        A validated scene; every room is a region named ``room_<k>``, used as spawn and goal region for
        robots and people, and each door centre is a waypoint ``door_<k>``.
    """
    seed = int(seed)
    rng = np.random.default_rng(seed)
    if door_width < 0.8:
        raise ValueError(f"door_width must be >= 0.8 m, got {door_width}")
    if min_room < 2 * (door_width + 0.4):
        raise ValueError(
            f"min_room must be >= 2 * (door_width + 0.4) = {2 * (door_width + 0.4):g} m, got {min_room}"
        )
    if max_room < 2 * min_room:
        raise ValueError(f"max_room must be >= 2 * min_room, got {max_room} < {2 * min_room}")
    w = _q(rng.uniform(10.0, 24.0), 0.5) if width is None else float(width)
    h = _q(rng.uniform(8.0, 18.0), 0.5) if height is None else float(height)
    if min(w, h) < min_room + 2 * _OUTER:
        raise ValueError(f"floor {w:g} x {h:g} m is too small for rooms of {min_room:g} m")
    name = f"procedural_rooms_{seed}" if name is None else name

    # Binary space partition of the inner rectangle. A wall is (axis, c, a0, a1): axis 0 = vertical wall at
    # x = c spanning y in [a0, a1]; axis 1 = horizontal wall at y = c spanning x in [a0, a1].
    rooms: list[tuple[float, float, float, float]] = []
    splits: list[tuple[int, float, float, float]] = []
    stack = [(_OUTER, _OUTER, w - _OUTER, h - _OUTER)]
    while stack:
        x0, y0, x1, y1 = stack.pop()
        rw, rh = x1 - x0, y1 - y0
        can = [rw >= 2 * min_room, rh >= 2 * min_room]
        must = max(rw, rh) > max_room
        if not any(can) or (not must and rng.random() < 0.5):
            rooms.append((x0, y0, x1, y1))
            continue
        if all(can):
            axis = 0 if rng.random() < rw / (rw + rh) else 1
        else:
            axis = 0 if can[0] else 1
        lo, hi = (x0, x1) if axis == 0 else (y0, y1)
        c = _q(rng.uniform(lo + min_room, hi - min_room), 0.1)
        c = min(max(c, lo + min_room), hi - min_room)
        if axis == 0:
            splits.append((0, c, y0, y1))
            stack += [(x0, y0, c, y1), (c, y0, x1, y1)]
        else:
            splits.append((1, c, x0, x1))
            stack += [(x0, y0, x1, c), (x0, c, x1, y1)]

    # Candidate doors: every pair of rooms sharing a wall over at least door_width + 0.4 m.
    need = door_width + 0.4
    candidates: list[tuple[int, int, int, float, float, float]] = []  # (i, j, axis, c, lo, hi)
    for i, a in enumerate(rooms):
        for j in range(i + 1, len(rooms)):
            b = rooms[j]
            for axis in (0, 1):
                lo_k, hi_k = (0, 2) if axis == 0 else (1, 3)
                other_lo, other_hi = (1, 3) if axis == 0 else (0, 2)
                if abs(a[hi_k] - b[lo_k]) < 1e-6:
                    c = a[hi_k]
                elif abs(b[hi_k] - a[lo_k]) < 1e-6:
                    c = a[lo_k]
                else:
                    continue
                lo, hi = max(a[other_lo], b[other_lo]), min(a[other_hi], b[other_hi])
                if hi - lo >= need - 1e-9:
                    candidates.append((i, j, axis, c, lo, hi))
    order = rng.permutation(len(candidates))
    parent = list(range(len(rooms)))

    def find(k: int) -> int:
        while parent[k] != k:
            parent[k] = parent[parent[k]]
            k = parent[k]
        return k

    doors: list[tuple[int, float, float, float]] = []  # (axis, c, d0, d1)
    for k in order:
        i, j, axis, c, lo, hi = candidates[k]
        ri, rj = find(i), find(j)
        tree_edge = ri != rj
        extra = rng.random() < loop_prob  # drawn for every edge, so the stream does not depend on the tree
        if not (tree_edge or extra):
            continue
        if tree_edge:
            parent[ri] = rj
        d0 = _q(lo + 0.2 + rng.random() * max(0.0, hi - lo - need), 0.01)
        doors.append((axis, c, d0, round(d0 + door_width, 3)))
    if len({find(k) for k in range(len(rooms))}) != 1:  # cannot happen when min_room >= 2 * need
        raise SceneError("internal error: rooms are not connected", scene=name)

    wall_h = 2.6
    obstacles: list[Obstacle] = _outer_walls(w, h, wall_h)
    for axis, c, a0, a1 in splits:
        pieces = [(a0, a1)]
        for d_axis, d_c, d0, d1 in doors:
            if d_axis != axis or abs(d_c - c) > 1e-6:
                continue
            pieces = [
                p for s0, s1 in pieces for p in ((s0, min(s1, d0)), (max(s0, d1), s1)) if p[1] - p[0] > 0.05
            ]
        for s0, s1 in pieces:
            start, end = ((c, s0), (c, s1)) if axis == 0 else ((s0, c), (s1, c))
            obstacles.append(WallObstacle(start, end, _INNER, wall_h))

    regions: dict[str, Region] = {}
    inset = _INNER / 2 + 0.1
    for k, (x0, y0, x1, y1) in enumerate(rooms):
        regions[f"room_{k}"] = Region(
            name=f"room_{k}", rect=(_q(x0 + inset), _q(y0 + inset), _q(x1 - inset), _q(y1 - inset))
        )
    waypoints = {}
    for k, (axis, c, d0, d1) in enumerate(doors):
        mid = _q((d0 + d1) / 2, 0.01)
        waypoints[f"door_{k}"] = (c, mid) if axis == 0 else (mid, c)

    if furniture:
        bounds = (0.0, 0.0, w, h)
        check = _Connectivity(bounds, obstacles, list(regions.values()))
        for axis, c, d0, d1 in doors:  # 1 m deep clear zone on both sides of each door
            if axis == 0:
                check.keep_clear(c - 1.0, d0 - 0.1, c + 1.0, d1 + 0.1)
            else:
                check.keep_clear(d0 - 0.1, c - 1.0, d1 + 0.1, c + 1.0)
        for x0, y0, x1, y1 in rooms:
            x0, y0, x1, y1 = x0 + _INNER / 2, y0 + _INNER / 2, x1 - _INNER / 2, y1 - _INNER / 2
            area = (x1 - x0) * (y1 - y0)
            for _ in range(int(rng.integers(1, 2 + int(area // 10)))):
                piece = _room_piece(rng, x0, y0, x1, y1)
                if piece is not None and check.try_add(piece):
                    obstacles.append(piece)

    names = list(regions)
    return _finish(
        name,
        f"Procedural rooms and doors (seed {seed}): {w:g} x {h:g} m floor, {len(rooms)} rooms, {len(doors)} doors "
        f"of {door_width:g} m.",
        (0.0, 0.0, w, h),
        obstacles,
        regions,
        names,
        names,
        names,
        names,
        waypoints,
        humans_per_m2=0.04,
        max_humans=30,
    )


def _room_piece(rng: np.random.Generator, x0: float, y0: float, x1: float, y1: float) -> Obstacle | None:
    """One piece of furniture for the room ``[x0, x1] x [y0, y1]`` (inner faces of its walls)."""
    kind = rng.choice(["wall", "wall", "table", "round"])
    if kind == "wall":  # cabinet, shelf, sofa or bed against a random wall
        length = _q(rng.uniform(0.8, 2.0))
        depth = _q(rng.uniform(0.4, 0.9))
        side = int(rng.integers(4))
        if side in (0, 1):  # south / north wall
            if x1 - x0 < length + 0.2:
                return None
            cx = _q(rng.uniform(x0 + length / 2, x1 - length / 2))
            cy = y0 + depth / 2 if side == 0 else y1 - depth / 2
            return BoxObstacle((cx, _q(cy, 0.01)), (length, depth), 0.0, 1.0, "cabinet")
        if y1 - y0 < length + 0.2:
            return None
        cy = _q(rng.uniform(y0 + length / 2, y1 - length / 2))
        cx = x0 + depth / 2 if side == 2 else x1 - depth / 2
        return BoxObstacle((_q(cx, 0.01), cy), (depth, length), 0.0, 1.0, "cabinet")
    margin = 0.9
    if x1 - x0 < 2 * margin + 0.6 or y1 - y0 < 2 * margin + 0.6:
        return None
    if kind == "table":
        size = (_q(rng.uniform(0.8, 1.8)), _q(rng.uniform(0.6, 1.0)))
        yaw = _q(rng.choice([0.0, 0.0, math.pi / 2, rng.uniform(-0.6, 0.6)]), 0.01)
        r = 0.5 * math.hypot(*size)
        if x1 - x0 < 2 * (margin + r) or y1 - y0 < 2 * (margin + r):
            return None
        cx = _q(rng.uniform(x0 + margin + r, x1 - margin - r))
        cy = _q(rng.uniform(y0 + margin + r, y1 - margin - r))
        return BoxObstacle((cx, cy), size, yaw, 0.75, "table")
    radius = _q(rng.uniform(0.3, 0.6))
    if x1 - x0 < 2 * (margin + radius) or y1 - y0 < 2 * (margin + radius):
        return None
    cx = _q(rng.uniform(x0 + margin + radius, x1 - margin - radius))
    cy = _q(rng.uniform(y0 + margin + radius, y1 - margin - radius))
    return CircleObstacle((cx, cy), radius, 0.75, "round_table")


# ---------------------------------------------------------------------------------------------------------
# Aisles
# ---------------------------------------------------------------------------------------------------------

#: Shelf kinds for :func:`aisles`: depth of a shelf row (m), aisle width range (m), shelf height (m), name.
_SHELVES = {
    "gondola": (0.9, (1.2, 2.0), 1.6, "gondola"),
    "rack": (1.2, (1.6, 2.6), 2.4, "shelf_rack"),
    "pallet_rack": (2.2, (2.6, 3.4), 6.0, "pallet_rack"),
}


def aisles(
    seed: int,
    *,
    width: float | None = None,
    height: float | None = None,
    shelf: str | None = None,
    aisle_width: float | None = None,
    cross_aisles: int | None = None,
    name: str | None = None,
) -> Scene:
    """A store or warehouse hall with parallel shelf rows, generated from ``seed``.

    Layout (south to north): a front zone 3.5-5.5 m deep with one or two entrances in the south wall and
    checkouts (stores) or staged pallets (warehouses), the shelf rows running north-south with aisles
    between them and side aisles along the west and east walls, 0-2 cross aisles cutting the rows, and a
    back aisle 1.5-2.5 m deep along the north wall. A few shelf segments are left out at random.

    Args:
        seed: random seed (``numpy.random.default_rng(seed)`` is the only source of randomness).
        width, height: hall size in metres (default: drawn from the seed, 16-36 x 14-26 m).
        shelf: ``"gondola"`` (0.9 m deep), ``"rack"`` (1.2 m) or ``"pallet_rack"`` (2.2 m, double-sided
            warehouse racks); default drawn from the seed.
        aisle_width: clear aisle width between rows (default drawn from the shelf kind's range); >= 1.2 m.
        cross_aisles: number of cross aisles (default 0-2 from the seed; each shelf segment stays >= 3 m).
        name: scene name (default ``procedural_aisles_<seed>``).

    Returns:
        A validated scene with regions ``entrance_<k>``, ``front``, ``aisle_<k>`` (between rows and along
        the side walls), ``back_aisle`` and ``cross_aisle_<k>``; robots go from the entrances to the aisles
        and the back aisle, people between all of them. Entrances are waypoints ``entrance_<k>``.
    """
    seed = int(seed)
    rng = np.random.default_rng(seed)
    kind = str(rng.choice(list(_SHELVES))) if shelf is None else shelf
    if kind not in _SHELVES:
        raise ValueError(f"shelf must be one of {', '.join(_SHELVES)}, got {shelf!r}")
    depth, (a_lo, a_hi), shelf_h, shelf_name = _SHELVES[kind]
    w = _q(rng.uniform(16.0, 36.0), 0.5) if width is None else float(width)
    h = _q(rng.uniform(14.0, 26.0), 0.5) if height is None else float(height)
    aisle = _q(rng.uniform(a_lo, a_hi), 0.1) if aisle_width is None else float(aisle_width)
    if aisle < 1.2:
        raise ValueError(f"aisle_width must be >= 1.2 m, got {aisle}")
    front = _q(rng.uniform(3.5, 5.5), 0.1)
    back = _q(rng.uniform(1.5, 2.5), 0.1)
    side = _q(rng.uniform(max(1.5, aisle), max(2.5, aisle + 0.5)), 0.1)
    y0, y1 = _OUTER + front, h - _OUTER - back
    if y1 - y0 < 3.0 or w < 2 * (_OUTER + side) + depth:
        raise ValueError(f"hall {w:g} x {h:g} m is too small for shelf rows")
    name = f"procedural_aisles_{seed}" if name is None else name

    # Shelf rows: as many as fit between the side aisles, centred.
    span = w - 2 * (_OUTER + side)
    n_rows = max(1, int((span + aisle) // (depth + aisle)))
    used = n_rows * depth + (n_rows - 1) * aisle
    left = _q(_OUTER + side + (span - used) / 2, 0.01)
    row_x = [_q(left + depth / 2 + k * (depth + aisle), 0.01) for k in range(n_rows)]

    # Cross aisles: split [y0, y1] into segments of >= 3 m.
    max_cross = int((y1 - y0 - 3.0) // (3.0 + aisle + 0.4))
    n_cross = (
        int(rng.integers(0, min(2, max_cross) + 1))
        if cross_aisles is None
        else min(int(cross_aisles), max_cross)
    )
    cross_w = _q(aisle + 0.4, 0.1)
    seg_len = (y1 - y0 - n_cross * cross_w) / (n_cross + 1)
    segments: list[tuple[float, float]] = []
    cross: list[tuple[float, float]] = []
    y = y0
    for k in range(n_cross + 1):
        jitter = 0.0 if k == n_cross else _q(rng.uniform(-0.25, 0.25) * (seg_len - 3.0), 0.1)
        top = y1 if k == n_cross else _q(y + seg_len + jitter, 0.1)
        segments.append((y, top))
        if k < n_cross:
            cross.append((top, _q(top + cross_w, 0.1)))
            y = cross[-1][1]

    # Entrances in the south wall (2.0-3.0 m wide), one or two.
    n_ent = 1 if w < 22 else int(rng.integers(1, 3))
    ent_w = _q(rng.uniform(2.0, 3.0), 0.1)
    slots = np.linspace(_OUTER + 0.5, w - _OUTER - 0.5 - ent_w, 8)
    picks = sorted(rng.choice(len(slots), size=n_ent, replace=False).tolist())
    if n_ent == 2 and picks[1] - picks[0] < 3:
        picks = [0, len(slots) - 1]
    entrances = [(_q(slots[p], 0.1), _q(slots[p] + ent_w, 0.1)) for p in picks]

    obstacles: list[Obstacle] = _outer_walls(w, h, 4.0 if kind != "pallet_rack" else 8.0, entrances)
    n_shelves = 0
    for x in row_x:
        for s0, s1 in segments:
            if n_rows * len(segments) > 3 and rng.random() < 0.08:
                continue  # a missing shelf segment: an open bay
            obstacles.append(
                BoxObstacle(
                    (x, _q((s0 + s1) / 2, 0.01)), (depth, _q(s1 - s0, 0.01)), 0.0, shelf_h, shelf_name
                )
            )
            n_shelves += 1

    regions: dict[str, Region] = {}
    ent_names = []
    for k, (e0, e1) in enumerate(entrances):
        regions[f"entrance_{k}"] = Region(
            name=f"entrance_{k}", rect=(e0, _OUTER + 0.1, e1, _q(_OUTER + min(2.0, front - 0.5)))
        )
        ent_names.append(f"entrance_{k}")
    regions["front"] = Region(name="front", rect=(_OUTER + 0.2, _OUTER + 0.2, w - _OUTER - 0.2, _q(y0 - 0.1)))
    aisle_names = []
    edges = [_OUTER] + [v for x in row_x for v in (x - depth / 2, x + depth / 2)] + [w - _OUTER]
    for k in range(0, len(edges), 2):
        a0, a1 = edges[k] + 0.1, edges[k + 1] - 0.1
        regions[f"aisle_{k // 2}"] = Region(name=f"aisle_{k // 2}", rect=(_q(a0, 0.01), y0, _q(a1, 0.01), y1))
        aisle_names.append(f"aisle_{k // 2}")
    regions["back_aisle"] = Region(
        name="back_aisle", rect=(_OUTER + 0.2, _q(y1 + 0.1), w - _OUTER - 0.2, _q(h - _OUTER - 0.1))
    )
    cross_names = []
    for k, (c0, c1) in enumerate(cross):
        regions[f"cross_aisle_{k}"] = Region(
            name=f"cross_aisle_{k}", rect=(_OUTER + 0.2, c0, w - _OUTER - 0.2, c1)
        )
        cross_names.append(f"cross_aisle_{k}")

    # Front-zone fittings: checkouts (stores) or staged pallets (warehouses), never in front of an entrance.
    check = _Connectivity((0.0, 0.0, w, h), obstacles, list(regions.values()))
    for e0, e1 in entrances:
        check.keep_clear(e0 - 0.3, 0.0, e1 + 0.3, _OUTER + 2.5)
    check.keep_clear(0.0, y0 - 1.0, w, y0)  # the front row of the aisles stays open
    if kind != "pallet_rack":
        n_fit = int(rng.integers(3, 7))
        xs = np.linspace(_OUTER + 1.5, w - _OUTER - 1.5, n_fit + 2)[1:-1]
        length = _q(min(2.5, front - 1.8), 0.1)
        for x in xs:
            piece = BoxObstacle(
                (_q(x, 0.1), _q(_OUTER + 0.9 + length / 2, 0.01)), (0.8, length), 0.0, 0.9, "checkout"
            )
            if length >= 1.0 and check.try_add(piece):
                obstacles.append(piece)
    else:
        for _ in range(int(rng.integers(3, 9))):
            x = _q(rng.uniform(_OUTER + 1.0, w - _OUTER - 1.0), 0.1)
            y = _q(rng.uniform(_OUTER + 0.8, y0 - 1.5), 0.1)
            piece = BoxObstacle((x, y), (1.2, 1.0), _q(rng.choice([0.0, math.pi / 2]), 0.01), 1.2, "pallet")
            if check.try_add(piece):
                obstacles.append(piece)

    waypoints = {
        f"entrance_{k}": (_q((e0 + e1) / 2, 0.01), _q(_OUTER + 0.35, 0.01))
        for k, (e0, e1) in enumerate(entrances)
    }
    store = "store" if kind != "pallet_rack" else "warehouse"
    return _finish(
        name,
        f"Procedural {store} aisles (seed {seed}): {w:g} x {h:g} m hall, {n_rows} rows of {kind.replace('_', ' ')}s "
        f"({depth:g} m deep, {n_shelves} segments), {aisle:g} m aisles, {_count(n_cross, 'cross aisle')}, "
        f"{_count(len(entrances), 'entrance')}.",
        (0.0, 0.0, w, h),
        obstacles,
        regions,
        ent_names,
        aisle_names + ["back_aisle"],
        ent_names + ["front"] + aisle_names + ["back_aisle"] + cross_names,
        ent_names + aisle_names + ["back_aisle"],
        waypoints,
        humans_per_m2=0.03,
        max_humans=40,
    )


def from_name(name: str) -> Scene | None:
    """The procedural scene called ``procedural_rooms_<seed>`` or ``procedural_aisles_<seed>`` (default
    parameters), or None for any other name."""
    match = _NAME_RE.match(name)
    if match is None:
        return None
    kind, seed = match.group(1), int(match.group(2))
    return rooms_and_doors(seed) if kind == "rooms" else aisles(seed)
