"""Scene description: static 2D world (obstacles extruded to a height, named regions, task protocol).

A scene is loaded from YAML/JSON (see ``docs/scenes.md``) with :func:`load_scene` and is immutable. Every
dataclass validates itself on construction and raises :class:`SceneError` naming the offending field.
Derived geometry (obstacle polygons, edge segments, occupancy grids) is computed lazily and cached on the
instance; the cached numpy arrays are read-only so that they can be shared without copies.
"""

from __future__ import annotations

import json
import math
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any, ClassVar

import numpy as np
import yaml

from navzoo.world import geometry as geo

if TYPE_CHECKING:
    from navzoo.world.occupancy import OccupancyGrid

__all__ = [
    "BoxObstacle",
    "CircleObstacle",
    "Obstacle",
    "PolygonObstacle",
    "Protocol",
    "Region",
    "Scene",
    "SceneError",
    "WallObstacle",
    "load_scene",
]

#: Number of sides of the polygon that stands in for a circle in 2D geometry.
CIRCLE_SIDES = 24


class SceneError(ValueError):
    """Invalid scene description.

    The message reads ``scene '<name>': <field path>: <problem>``, e.g.
    ``scene 'home': obstacles[3].size: expected 2 numbers, got 3``.

    Attributes:
        problem: what is wrong (expected vs actual).
        scene: scene name, when known.
        path: dotted field path such as ``obstacles[3].size``, when the problem belongs to a field.
    """

    def __init__(self, problem: str, *, scene: str | None = None, path: str | None = None):
        self.problem = problem
        self.scene = scene
        self.path = path
        parts = []
        if scene is not None:
            parts.append(f"scene '{scene}'")
        if path:
            parts.append(path)
        parts.append(problem)
        super().__init__(": ".join(parts))

    def located(self, *, scene: str | None = None, prefix: str | None = None) -> SceneError:
        """Return a copy with the scene name set and ``prefix`` prepended to the field path."""
        path = self.path
        if prefix:
            if not path:
                path = prefix
            elif path.startswith("["):
                path = prefix + path
            else:
                path = f"{prefix}.{path}"
        return SceneError(self.problem, scene=scene if scene is not None else self.scene, path=path)


# ---------------------------------------------------------------------------------------------------------
# Coercion helpers: turn loosely-typed YAML values into validated floats/tuples, raising SceneError(path=...)
# ---------------------------------------------------------------------------------------------------------


def _describe(value: Any) -> str:
    text = repr(value)
    if len(text) > 60:
        text = text[:57] + "..."
    return f"{text} ({type(value).__name__})"


def _float(value: Any, path: str, *, positive: bool = False, nonneg: bool = False) -> float:
    # bool is an int subclass; "yes" in YAML would otherwise silently become 1.0.
    if isinstance(value, bool) or not isinstance(value, int | float | np.integer | np.floating):
        raise SceneError(f"expected a number, got {_describe(value)}", path=path)
    out = float(value)
    if not math.isfinite(out):
        raise SceneError(f"expected a finite number, got {out}", path=path)
    if positive and out <= 0.0:
        raise SceneError(f"must be > 0, got {out:g}", path=path)
    if nonneg and out < 0.0:
        raise SceneError(f"must be >= 0, got {out:g}", path=path)
    return out


def _int(value: Any, path: str, *, nonneg: bool = True) -> int:
    if isinstance(value, bool) or not isinstance(value, int | np.integer):
        raise SceneError(f"expected an integer, got {_describe(value)}", path=path)
    if nonneg and value < 0:
        raise SceneError(f"must be >= 0, got {value}", path=path)
    return int(value)


def _str(value: Any, path: str, *, allow_empty: bool = True) -> str:
    if not isinstance(value, str):
        raise SceneError(f"expected a string, got {_describe(value)}", path=path)
    if not allow_empty and not value.strip():
        raise SceneError("must be a non-empty string", path=path)
    return value


def _is_seq(value: Any) -> bool:
    return isinstance(value, Sequence | np.ndarray) and not isinstance(value, str | bytes)


def _vec(value: Any, n: int, path: str, *, positive: bool = False) -> tuple[float, ...]:
    if not _is_seq(value) or len(value) != n:
        got = f"{len(value)} items" if _is_seq(value) else _describe(value)
        raise SceneError(f"expected a list of {n} numbers, got {got}", path=path)
    return tuple(_float(v, f"{path}[{i}]", positive=positive) for i, v in enumerate(value))


def _points(value: Any, path: str, *, min_points: int = 3) -> tuple[tuple[float, float], ...]:
    if not _is_seq(value):
        raise SceneError(f"expected a list of [x, y] points, got {_describe(value)}", path=path)
    pts = [_vec(v, 2, f"{path}[{i}]") for i, v in enumerate(value)]
    # Accept an explicitly closed ring (last == first) by dropping the repeated vertex.
    if len(pts) > min_points and pts[0] == pts[-1]:
        pts = pts[:-1]
    if len(pts) < min_points:
        raise SceneError(f"expected at least {min_points} points, got {len(pts)}", path=path)
    return tuple((p[0], p[1]) for p in pts)


def _check_simple(points: tuple[tuple[float, float], ...], path: str) -> None:
    arr = np.asarray(points, dtype=np.float64)
    if geo.polygon_is_simple(arr):
        return
    edges = geo.polygon_edges(arr)
    hit = geo.segments_intersect(edges, edges)
    k = len(points)
    for i in range(k):
        for j in range(i + 2, k):
            if (i == 0 and j == k - 1) or not hit[i, j]:
                continue
            raise SceneError(
                f"polygon is self-intersecting: edge {i} ({list(points[i])} -> {list(points[(i + 1) % k])}) "
                f"touches edge {j} ({list(points[j])} -> {list(points[(j + 1) % k])})",
                path=path,
            )
    if abs(geo.polygon_area(arr)) <= 1e-9:
        raise SceneError("polygon has zero area (all points collinear or repeated)", path=path)
    raise SceneError("polygon is not simple (repeated vertex or edge folding back on itself)", path=path)


def _names(value: Any, path: str) -> tuple[str, ...]:
    if value is None:
        return ()
    if isinstance(value, str):
        return (value,)
    if not _is_seq(value):
        raise SceneError(f"expected a list of region names, got {_describe(value)}", path=path)
    return tuple(_str(v, f"{path}[{i}]", allow_empty=False) for i, v in enumerate(value))


def _check_keys(data: Any, valid: Iterable[str], required: Iterable[str], path: str) -> None:
    if not isinstance(data, Mapping):
        raise SceneError(f"expected a mapping, got {_describe(data)}", path=path or None)
    valid = sorted(valid)
    for key in data:
        if key not in valid:
            raise SceneError(f"unknown key '{key}'; valid keys: {', '.join(valid)}", path=path or None)
    for key in required:
        if key not in data:
            raise SceneError(f"missing required key '{key}'", path=path or None)


def _readonly(arr: np.ndarray) -> np.ndarray:
    arr.setflags(write=False)
    return arr


# ---------------------------------------------------------------------------------------------------------
# Obstacles
# ---------------------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class BoxObstacle:
    """A rectangle of ``size = (sx, sy)`` metres centred on ``center``, rotated by ``yaw`` radians."""

    center: tuple[float, float]
    size: tuple[float, float]
    yaw: float = 0.0
    height: float = 1.0
    name: str | None = None

    type: ClassVar[str] = "box"
    keys: ClassVar[tuple[str, ...]] = ("type", "center", "size", "yaw", "height", "name")
    required: ClassVar[tuple[str, ...]] = ("type", "center", "size")

    def __post_init__(self) -> None:
        object.__setattr__(self, "center", _vec(self.center, 2, "center"))
        object.__setattr__(self, "size", _vec(self.size, 2, "size", positive=True))
        object.__setattr__(self, "yaw", _float(self.yaw, "yaw"))
        object.__setattr__(self, "height", _float(self.height, "height", positive=True))
        if self.name is not None:
            _str(self.name, "name")

    def polygon(self) -> np.ndarray:
        """Footprint ``(4, 2)``, counter-clockwise."""
        return geo.box_corners(self.center, self.size, self.yaw)

    def to_dict(self) -> dict[str, Any]:
        out: dict[str, Any] = {"type": "box", "center": list(self.center), "size": list(self.size)}
        out["yaw"] = self.yaw
        out["height"] = self.height
        if self.name is not None:
            out["name"] = self.name
        return out


@dataclass(frozen=True)
class WallObstacle:
    """A straight wall: a box of width ``thickness`` along the segment ``start``-``end`` (no end caps)."""

    start: tuple[float, float]
    end: tuple[float, float]
    thickness: float = 0.15
    height: float = 2.5
    name: str | None = None

    type: ClassVar[str] = "wall"
    keys: ClassVar[tuple[str, ...]] = ("type", "start", "end", "thickness", "height", "name")
    required: ClassVar[tuple[str, ...]] = ("type", "start", "end")

    def __post_init__(self) -> None:
        object.__setattr__(self, "start", _vec(self.start, 2, "start"))
        object.__setattr__(self, "end", _vec(self.end, 2, "end"))
        object.__setattr__(self, "thickness", _float(self.thickness, "thickness", positive=True))
        object.__setattr__(self, "height", _float(self.height, "height", positive=True))
        if self.name is not None:
            _str(self.name, "name")
        if self.start == self.end:
            raise SceneError(f"wall has zero length (start == end == {list(self.start)})", path="end")

    @property
    def length(self) -> float:
        return float(math.hypot(self.end[0] - self.start[0], self.end[1] - self.start[1]))

    def polygon(self) -> np.ndarray:
        """Footprint ``(4, 2)``, counter-clockwise."""
        return geo.wall_corners(self.start, self.end, self.thickness)

    def to_dict(self) -> dict[str, Any]:
        out: dict[str, Any] = {"type": "wall", "start": list(self.start), "end": list(self.end)}
        out["thickness"] = self.thickness
        out["height"] = self.height
        if self.name is not None:
            out["name"] = self.name
        return out


@dataclass(frozen=True)
class PolygonObstacle:
    """A simple polygon footprint (convex or not) extruded to ``height``."""

    points: tuple[tuple[float, float], ...]
    height: float = 1.0
    name: str | None = None

    type: ClassVar[str] = "polygon"
    keys: ClassVar[tuple[str, ...]] = ("type", "points", "height", "name")
    required: ClassVar[tuple[str, ...]] = ("type", "points")

    def __post_init__(self) -> None:
        object.__setattr__(self, "points", _points(self.points, "points"))
        object.__setattr__(self, "height", _float(self.height, "height", positive=True))
        if self.name is not None:
            _str(self.name, "name")
        _check_simple(self.points, "points")

    def polygon(self) -> np.ndarray:
        """Footprint ``(K, 2)``, counter-clockwise (reversed if given clockwise)."""
        return geo.ensure_ccw(np.asarray(self.points, dtype=np.float64))

    def to_dict(self) -> dict[str, Any]:
        out: dict[str, Any] = {"type": "polygon", "points": [list(p) for p in self.points]}
        out["height"] = self.height
        if self.name is not None:
            out["name"] = self.name
        return out


@dataclass(frozen=True)
class CircleObstacle:
    """A disc of ``radius`` (a column, a round table) extruded to ``height``."""

    center: tuple[float, float]
    radius: float
    height: float = 1.0
    name: str | None = None

    type: ClassVar[str] = "circle"
    keys: ClassVar[tuple[str, ...]] = ("type", "center", "radius", "height", "name")
    required: ClassVar[tuple[str, ...]] = ("type", "center", "radius")

    def __post_init__(self) -> None:
        object.__setattr__(self, "center", _vec(self.center, 2, "center"))
        object.__setattr__(self, "radius", _float(self.radius, "radius", positive=True))
        object.__setattr__(self, "height", _float(self.height, "height", positive=True))
        if self.name is not None:
            _str(self.name, "name")

    def polygon(self) -> np.ndarray:
        """Circumscribed 24-gon ``(24, 2)``, counter-clockwise."""
        return geo.circle_polygon(self.center, self.radius, CIRCLE_SIDES)

    def to_dict(self) -> dict[str, Any]:
        out: dict[str, Any] = {"type": "circle", "center": list(self.center), "radius": self.radius}
        out["height"] = self.height
        if self.name is not None:
            out["name"] = self.name
        return out


Obstacle = BoxObstacle | WallObstacle | PolygonObstacle | CircleObstacle
_OBSTACLE_TYPES: dict[str, type] = {
    cls.type: cls for cls in (BoxObstacle, WallObstacle, PolygonObstacle, CircleObstacle)
}


def _parse_obstacle(data: Any, path: str) -> Obstacle:
    if not isinstance(data, Mapping):
        raise SceneError(f"expected a mapping with a 'type' key, got {_describe(data)}", path=path)
    if "type" not in data:
        raise SceneError(f"missing required key 'type' (one of {', '.join(_OBSTACLE_TYPES)})", path=path)
    kind = data["type"]
    cls = _OBSTACLE_TYPES.get(kind) if isinstance(kind, str) else None
    if cls is None:
        raise SceneError(
            f"unknown obstacle type {_describe(kind)}; valid types: {', '.join(_OBSTACLE_TYPES)}",
            path=f"{path}.type",
        )
    _check_keys(data, cls.keys, cls.required, path)
    kwargs = {k: v for k, v in data.items() if k != "type"}
    try:
        return cls(**kwargs)
    except SceneError as err:
        raise err.located(prefix=path) from None


# ---------------------------------------------------------------------------------------------------------
# Regions and protocol
# ---------------------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class Region:
    """A named area given either as an axis-aligned ``rect = (xmin, ymin, xmax, ymax)`` or a ``polygon``."""

    name: str
    rect: tuple[float, float, float, float] | None = None
    polygon: tuple[tuple[float, float], ...] | None = None

    def __post_init__(self) -> None:
        _str(self.name, "name", allow_empty=False)
        if (self.rect is None) == (self.polygon is None):
            raise SceneError("expected exactly one of 'rect' or 'polygon'")
        if self.rect is not None:
            rect = _vec(self.rect, 4, "rect")
            if not (rect[0] < rect[2] and rect[1] < rect[3]):
                raise SceneError(
                    f"expected xmin < xmax and ymin < ymax, got {list(rect)}", path="rect"
                )
            object.__setattr__(self, "rect", rect)
        else:
            pts = _points(self.polygon, "polygon")
            _check_simple(pts, "polygon")
            object.__setattr__(self, "polygon", pts)

    def vertices(self) -> np.ndarray:
        """The region outline ``(K, 2)``, counter-clockwise."""
        if self.rect is not None:
            x0, y0, x1, y1 = self.rect
            return np.array([[x0, y0], [x1, y0], [x1, y1], [x0, y1]], dtype=np.float64)
        return geo.ensure_ccw(np.asarray(self.polygon, dtype=np.float64))

    def contains(self, points: Any) -> np.ndarray:
        """``(N,)`` bool: which points lie inside the region."""
        pts = geo.as_points(points)
        if self.rect is not None:
            x0, y0, x1, y1 = self.rect
            return (pts[:, 0] >= x0) & (pts[:, 0] <= x1) & (pts[:, 1] >= y0) & (pts[:, 1] <= y1)
        return geo.point_in_polygon(pts, self.vertices())

    @property
    def area(self) -> float:
        return abs(geo.polygon_area(self.vertices()))

    def to_dict(self) -> dict[str, Any]:
        if self.rect is not None:
            return {"rect": list(self.rect)}
        return {"polygon": [list(p) for p in self.polygon or ()]}


_PROTOCOL_KEYS: dict[str, tuple[str, ...]] = {
    "regions": ("type",),
    "circle_crossing": ("type", "radius", "noise"),
    "square_crossing": ("type", "width", "radius"),
}


@dataclass(frozen=True)
class Protocol:
    """How start/goal tasks are generated.

    * ``regions``: starts/goals sampled in the scene's spawn/goal regions (default).
    * ``circle_crossing`` (CrowdNav): humans start on a circle of ``radius`` with uniform ``+-noise`` on x
      and y and head for the opposite point; the robot goes from ``(0, -radius)`` to ``(0, radius)``.
    * ``square_crossing`` (CrowdNav): humans start and finish on opposite halves of a square of side
      ``width`` centred on the origin; the robot goes from ``(0, -radius)`` to ``(0, radius)``.

    Only the parameters of the chosen type are meaningful (and serialised).
    """

    type: str = "regions"
    radius: float = 4.0
    noise: float = 0.5
    width: float = 10.0

    def __post_init__(self) -> None:
        if not isinstance(self.type, str) or self.type not in _PROTOCOL_KEYS:
            raise SceneError(
                f"unknown protocol type {_describe(self.type)}; valid types: {', '.join(_PROTOCOL_KEYS)}",
                path="type",
            )
        object.__setattr__(self, "radius", _float(self.radius, "radius", positive=True))
        object.__setattr__(self, "noise", _float(self.noise, "noise", nonneg=True))
        object.__setattr__(self, "width", _float(self.width, "width", positive=True))

    @classmethod
    def from_dict(cls, data: Any) -> Protocol:
        if not isinstance(data, Mapping):
            raise SceneError(f"expected a mapping like {{type: regions}}, got {_describe(data)}")
        kind = data.get("type", "regions")
        if not isinstance(kind, str) or kind not in _PROTOCOL_KEYS:
            raise SceneError(
                f"unknown protocol type {_describe(kind)}; valid types: {', '.join(_PROTOCOL_KEYS)}",
                path="type",
            )
        _check_keys(data, _PROTOCOL_KEYS[kind], (), "")
        return cls(**dict(data))

    def to_dict(self) -> dict[str, Any]:
        return {k: getattr(self, k) for k in _PROTOCOL_KEYS[self.type]}


# ---------------------------------------------------------------------------------------------------------
# Scene
# ---------------------------------------------------------------------------------------------------------

_SCENE_KEYS = (
    "name",
    "description",
    "bounds",
    "obstacles",
    "regions",
    "robot_spawn",
    "robot_goal",
    "human_spawn",
    "human_goal",
    "waypoints",
    "protocol",
    "default_humans",
    "time_limit",
)
_REGION_LISTS = ("robot_spawn", "robot_goal", "human_spawn", "human_goal")


@dataclass(frozen=True)
class Scene:
    """A validated static world. Build it with :func:`load_scene` (or directly from typed values).

    Attributes:
        name: identifier used in error messages and the scene library.
        bounds: ``(xmin, ymin, xmax, ymax)`` in metres; everything outside is occupied.
        obstacles: walls and furniture footprints.
        regions: named areas, referenced by the spawn/goal lists.
        robot_spawn, robot_goal, human_spawn, human_goal: region names (empty = whole free space).
        waypoints: named fixed points.
        protocol: task generation protocol.
        default_humans: crowd size used by the scenario preset.
        time_limit: default episode limit in seconds.
    """

    name: str
    bounds: tuple[float, float, float, float]
    obstacles: tuple[Obstacle, ...] = ()
    regions: Mapping[str, Region] = field(default_factory=dict)
    robot_spawn: tuple[str, ...] = ()
    robot_goal: tuple[str, ...] = ()
    human_spawn: tuple[str, ...] = ()
    human_goal: tuple[str, ...] = ()
    waypoints: Mapping[str, tuple[float, float]] = field(default_factory=dict)
    protocol: Protocol = field(default_factory=Protocol)
    default_humans: int = 5
    time_limit: float = 60.0
    description: str = ""
    _cache: dict[Any, Any] = field(default_factory=dict, init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        try:
            self._validate()
        except SceneError as err:
            raise err.located(scene=str(self.name)) from None

    def _validate(self) -> None:
        _str(self.name, "name", allow_empty=False)
        _str(self.description, "description")
        bounds = _vec(self.bounds, 4, "bounds")
        if not (bounds[0] < bounds[2] and bounds[1] < bounds[3]):
            raise SceneError(
                f"degenerate bounds: expected xmin < xmax and ymin < ymax, got {list(bounds)}", path="bounds"
            )
        object.__setattr__(self, "bounds", bounds)

        if not _is_seq(self.obstacles):
            raise SceneError(f"expected a list of obstacles, got {_describe(self.obstacles)}", path="obstacles")
        for i, obs in enumerate(self.obstacles):
            if not isinstance(obs, tuple(_OBSTACLE_TYPES.values())):
                raise SceneError(f"expected an obstacle, got {_describe(obs)}", path=f"obstacles[{i}]")
        object.__setattr__(self, "obstacles", tuple(self.obstacles))
        bounds_poly = np.array(
            [[bounds[0], bounds[1]], [bounds[2], bounds[1]], [bounds[2], bounds[3]], [bounds[0], bounds[3]]]
        )
        for i, obs in enumerate(self.obstacles):
            if not _polygons_overlap(obs.polygon(), bounds_poly):
                raise SceneError(
                    f"{obs.type} obstacle lies entirely outside bounds {list(bounds)}", path=f"obstacles[{i}]"
                )

        if not isinstance(self.regions, Mapping):
            raise SceneError(f"expected a mapping of regions, got {_describe(self.regions)}", path="regions")
        for key, region in self.regions.items():
            if not isinstance(region, Region) or region.name != key:
                raise SceneError(f"expected Region(name={key!r}), got {_describe(region)}", path=f"regions.{key}")
        object.__setattr__(self, "regions", dict(self.regions))

        for list_name in _REGION_LISTS:
            names = _names(getattr(self, list_name), list_name)
            for j, region_name in enumerate(names):
                if region_name not in self.regions:
                    defined = ", ".join(sorted(self.regions)) or "none"
                    raise SceneError(
                        f"region '{region_name}' is not defined; defined regions: {defined}",
                        path=f"{list_name}[{j}]",
                    )
            object.__setattr__(self, list_name, names)

        if not isinstance(self.waypoints, Mapping):
            raise SceneError(f"expected a mapping name -> [x, y], got {_describe(self.waypoints)}", path="waypoints")
        waypoints: dict[str, tuple[float, float]] = {}
        for key, value in self.waypoints.items():
            _str(key, "waypoints", allow_empty=False)
            xy = _vec(value, 2, f"waypoints.{key}")
            if not (bounds[0] <= xy[0] <= bounds[2] and bounds[1] <= xy[1] <= bounds[3]):
                raise SceneError(f"point {list(xy)} is outside bounds {list(bounds)}", path=f"waypoints.{key}")
            waypoints[key] = (xy[0], xy[1])
        object.__setattr__(self, "waypoints", waypoints)

        if not isinstance(self.protocol, Protocol):
            raise SceneError(f"expected a Protocol, got {_describe(self.protocol)}", path="protocol")
        self._validate_protocol_fits(bounds)
        object.__setattr__(self, "default_humans", _int(self.default_humans, "default_humans"))
        object.__setattr__(self, "time_limit", _float(self.time_limit, "time_limit", positive=True))

    def _validate_protocol_fits(self, bounds: tuple[float, ...]) -> None:
        proto = self.protocol
        if proto.type == "circle_crossing":
            reach = proto.radius + proto.noise
            what = f"circle_crossing circle of radius {proto.radius:g} m (+ noise {proto.noise:g} m)"
            path = "protocol.radius"
        elif proto.type == "square_crossing":
            reach = max(0.5 * proto.width, proto.radius)
            what = f"square_crossing square of width {proto.width:g} m and robot at (0, +-{proto.radius:g}) m"
            path = "protocol.width" if 0.5 * proto.width >= proto.radius else "protocol.radius"
        else:
            return
        if not (bounds[0] < -reach and bounds[2] > reach and bounds[1] < -reach and bounds[3] > reach):
            raise SceneError(f"{what} does not fit in bounds {list(bounds)}", path=path)

    def __hash__(self) -> int:
        return hash((self.name, self.bounds, self.obstacles))

    # ------------------------------------------------------------------ serialisation

    def to_dict(self) -> dict[str, Any]:
        """Plain-python representation; ``load_scene(scene.to_dict()) == scene``."""
        return {
            "name": self.name,
            "description": self.description,
            "bounds": list(self.bounds),
            "obstacles": [o.to_dict() for o in self.obstacles],
            "regions": {k: r.to_dict() for k, r in self.regions.items()},
            "robot_spawn": list(self.robot_spawn),
            "robot_goal": list(self.robot_goal),
            "human_spawn": list(self.human_spawn),
            "human_goal": list(self.human_goal),
            "waypoints": {k: list(v) for k, v in self.waypoints.items()},
            "protocol": self.protocol.to_dict(),
            "default_humans": self.default_humans,
            "time_limit": self.time_limit,
        }

    # ------------------------------------------------------------------ geometry

    @property
    def size(self) -> tuple[float, float]:
        """``(width, height)`` of the bounds in metres."""
        return (self.bounds[2] - self.bounds[0], self.bounds[3] - self.bounds[1])

    def obstacle_polygons(self) -> list[np.ndarray]:
        """Footprint of each obstacle as a counter-clockwise ``(K, 2)`` array (read-only).

        Boxes and walls are 4-gons, circles circumscribed 24-gons, polygons their own vertices.
        """
        if "polygons" not in self._cache:
            self._cache["polygons"] = [_readonly(o.polygon()) for o in self.obstacles]
        return list(self._cache["polygons"])

    def exposed_corners(self, probe: float = 0.15, min_turn: float = math.pi / 6) -> np.ndarray:
        """Convex corners of the obstacles that a passer-by can cut, as a read-only ``(K, 2)`` array: the footprint
        vertices where the outline turns by at least ``min_turn`` (30 degrees; so not the vertices of the 24-gons
        that stand for round obstacles) and with free space over more than half a turn around them (door jambs'
        ends, the corners of shelves and tables), not those closed off by a neighbouring obstacle (where two walls
        meet). Each vertex is probed at 8 points ``probe`` m around it; at least 5 must be outside every obstacle
        (``clearance`` > 0)."""
        key = ("corners", float(probe), float(min_turn))
        if key not in self._cache:
            sharp = []
            for q in self.obstacle_polygons():
                q = np.asarray(q, dtype=float)
                e_in, e_out = q - np.roll(q, 1, axis=0), np.roll(q, -1, axis=0) - q
                cos = np.sum(e_in * e_out, axis=1) / np.maximum(
                    np.linalg.norm(e_in, axis=1) * np.linalg.norm(e_out, axis=1), 1e-12)
                sharp.append(q[np.arccos(np.clip(cos, -1.0, 1.0)) >= min_turn])
            verts = np.concatenate(sharp) if sharp else np.zeros((0, 2))
            if len(verts):
                ang = np.arange(8) * np.pi / 4 + np.pi / 8
                ring = probe * np.stack([np.cos(ang), np.sin(ang)], axis=1)
                free = (self.clearance((verts[:, None] + ring[None]).reshape(-1, 2)) > 0).reshape(len(verts), 8)
                verts = verts[free.sum(axis=1) >= 5]
            self._cache[key] = _readonly(verts)
        return self._cache[key]

    def wall_segments(self, include_bounds: bool = False) -> np.ndarray:
        """Every obstacle edge as a float64 ``(M, 2, 2)`` array (read-only).

        Args:
            include_bounds: also append the 4 edges of the scene bounds (useful where the bounds act as
                walls, e.g. open CrowdNav scenes).
        """
        key = ("segments", include_bounds)
        if key not in self._cache:
            polys = self.obstacle_polygons()
            parts = [geo.polygon_edges(p) for p in polys]
            if include_bounds:
                x0, y0, x1, y1 = self.bounds
                parts.append(geo.polygon_edges(np.array([[x0, y0], [x1, y0], [x1, y1], [x0, y1]])))
            seg = np.concatenate(parts, axis=0) if parts else np.zeros((0, 2, 2))
            self._cache[key] = _readonly(np.ascontiguousarray(seg, dtype=np.float64))
        return self._cache[key]

    def wall_segment_owner(self, include_bounds: bool = False) -> np.ndarray:
        """Index ``(M,)`` of the obstacle each :meth:`wall_segments` edge belongs to (-1 for bounds edges).

        An obstacle's edges are contiguous, so this is the ``group`` argument of
        :func:`navzoo.world.geometry.nearest_point_per_group` (one repulsion per obstacle).
        """
        key = ("owner", include_bounds)
        if key not in self._cache:
            counts = [p.shape[0] for p in self.obstacle_polygons()]
            owner = np.repeat(np.arange(len(counts), dtype=np.int64), counts)
            if include_bounds:
                owner = np.concatenate([owner, np.full(4, -1, dtype=np.int64)])
            self._cache[key] = _readonly(owner)
        return self._cache[key]

    def occupancy(self, resolution: float = 0.1) -> OccupancyGrid:
        """The (cached) occupancy grid of this scene; see :meth:`OccupancyGrid.from_scene`."""
        from navzoo.world.occupancy import OccupancyGrid

        return OccupancyGrid.from_scene(self, resolution)

    def free_area(self, radius: float = 0.0, resolution: float = 0.1) -> float:
        """Area in m^2 of the positions free for a disc of ``radius`` (from the occupancy grid)."""
        grid = self.occupancy(resolution).inflate(radius)
        return float(np.count_nonzero(~grid.occ)) * resolution * resolution

    def crowd_area(self) -> float:
        """Area in m^2 that a crowd density (people per m^2) refers to.

        The free space (:meth:`free_area`, radius 0) for region scenes. The CrowdNav protocols place
        people on a circle or in a square regardless of the room around it, so there it is the protocol's
        area: pi * radius^2 for ``circle_crossing``, width^2 for ``square_crossing``.
        """
        proto = self.protocol
        if proto is not None and proto.type == "circle_crossing":
            return math.pi * proto.radius**2
        if proto is not None and proto.type == "square_crossing":
            return proto.width**2
        return self.free_area(0.0)

    def region_list(self, kind: str, role: str) -> tuple[str, ...]:
        """Region names for ``kind`` in ``{"robot", "human"}`` and ``role`` in ``{"spawn", "goal"}``."""
        if kind not in ("robot", "human") or role not in ("spawn", "goal"):
            raise ValueError(f"expected kind robot|human and role spawn|goal, got {kind!r}, {role!r}")
        return getattr(self, f"{kind}_{role}")

    def clearance(self, points: Any) -> np.ndarray:
        """Exact distance ``(N,)`` from each point to the nearest obstacle edge; negative inside an obstacle.

        Bounds are not counted (use the occupancy grid for those).
        """
        pts = geo.as_points(points)
        dist = geo.min_distance_to_segments(pts, self.wall_segments())
        inside = np.zeros(pts.shape[0], dtype=bool)
        for poly in self.obstacle_polygons():
            lo, hi = poly.min(axis=0), poly.max(axis=0)
            near = np.all((pts >= lo) & (pts <= hi), axis=1)
            if near.any():
                inside[near] |= geo.point_in_polygon(pts[near], poly)
        return np.where(inside, -dist, dist)

    def validate_reachability(self, radius: float = 0.3, resolution: float = 0.1) -> None:
        """Check that every spawn/goal region has free space for a disc of ``radius`` and that, for robots and
        humans, every goal region is reachable from every spawn region; also checks waypoints and the
        fixed positions of crossing protocols.

        Uses the occupancy grid inflated by ``radius`` and 4-connected components of its free cells (the
        planner forbids corner cutting, so 4-connectivity is exactly what it can traverse).

        Raises:
            SceneError: naming the region / waypoint and the problem.
        """
        from scipy import ndimage

        grid = self.occupancy(resolution).inflate(radius)
        free = ~grid.occ
        if not free.any():
            raise SceneError(f"no free space at all for an agent of radius {radius:g} m", scene=self.name)
        labels, _ = ndimage.label(free)
        components: dict[str, set[int]] = {}
        for list_name in _REGION_LISTS:
            for j, region_name in enumerate(getattr(self, list_name)):
                if region_name in components:
                    continue
                mask = grid.region_mask(self.regions[region_name]) & free
                if not mask.any():
                    raise SceneError(
                        f"region '{region_name}' has no free space for an agent of radius {radius:g} m",
                        scene=self.name,
                        path=f"{list_name}[{j}]",
                    )
                components[region_name] = set(np.unique(labels[mask]).tolist())
        for kind in ("robot", "human"):
            spawns = getattr(self, f"{kind}_spawn")
            goals = getattr(self, f"{kind}_goal")
            if not spawns or not goals:
                continue  # "whole free space" on one side: any free cell of the other side is reachable
            for goal in goals:
                for spawn in spawns:
                    if not components[goal] & components[spawn]:
                        raise SceneError(
                            f"goal region '{goal}' is not reachable from spawn region '{spawn}' "
                            f"for an agent of radius {radius:g} m",
                            scene=self.name,
                            path=f"{kind}_goal",
                        )
        if self.waypoints:
            names = list(self.waypoints)
            pts = np.array([self.waypoints[n] for n in names])
            clear = self.clearance(pts)
            for name, c in zip(names, clear, strict=True):
                if c < radius:
                    raise SceneError(
                        f"point {list(self.waypoints[name])} is not free for an agent of radius {radius:g} m "
                        f"(clearance {c:.2f} m)",
                        scene=self.name,
                        path=f"waypoints.{name}",
                    )
        if self.protocol.type in ("circle_crossing", "square_crossing"):
            r = self.protocol.radius
            pts = np.array([[0.0, -r], [0.0, r]])
            if np.any(self.clearance(pts) < radius) or not np.all(grid.is_free(pts)):
                raise SceneError(
                    f"robot start (0, {-r:g}) or goal (0, {r:g}) is not free for an agent of radius {radius:g} m",
                    scene=self.name,
                    path="protocol.radius",
                )
            start_label, goal_label = labels[tuple(grid.world_to_cell(pts).T)]
            if start_label != goal_label:
                raise SceneError(
                    f"robot goal (0, {r:g}) is not reachable from robot start (0, {-r:g}) "
                    f"for an agent of radius {radius:g} m",
                    scene=self.name,
                    path="protocol.radius",
                )


def _polygons_overlap(a: np.ndarray, b: np.ndarray) -> bool:
    """Do two simple polygons share any area or boundary point?"""
    if np.any(geo.point_in_polygon(a, b)) or np.any(geo.point_in_polygon(b, a)):
        return True
    return bool(np.any(geo.segments_intersect(geo.polygon_edges(a), geo.polygon_edges(b))))


# ---------------------------------------------------------------------------------------------------------
# Loading
# ---------------------------------------------------------------------------------------------------------


def scene_from_dict(data: Mapping[str, Any], *, default_name: str = "<unnamed>") -> Scene:
    """Build a :class:`Scene` from a plain mapping (the parsed YAML/JSON), validating every field."""
    name = data.get("name") if isinstance(data, Mapping) else None
    scene_name = name if isinstance(name, str) and name.strip() else default_name
    try:
        _check_keys(data, _SCENE_KEYS, ("name", "bounds"), "")
        obstacles_raw = data.get("obstacles") or []
        if not _is_seq(obstacles_raw):
            raise SceneError(f"expected a list of obstacles, got {_describe(obstacles_raw)}", path="obstacles")
        obstacles = tuple(_parse_obstacle(o, f"obstacles[{i}]") for i, o in enumerate(obstacles_raw))

        regions_raw = data.get("regions") or {}
        if not isinstance(regions_raw, Mapping):
            raise SceneError(f"expected a mapping name -> {{rect|polygon}}, got {_describe(regions_raw)}", path="regions")
        regions: dict[str, Region] = {}
        for key, value in regions_raw.items():
            path = f"regions.{key}"
            if not isinstance(key, str) or not key.strip():
                raise SceneError(f"region names must be non-empty strings, got {_describe(key)}", path="regions")
            _check_keys(value, ("rect", "polygon"), (), path)
            try:
                regions[key] = Region(name=key, rect=value.get("rect"), polygon=value.get("polygon"))
            except SceneError as err:
                raise err.located(prefix=path) from None

        protocol_raw = data.get("protocol")
        try:
            protocol = Protocol() if protocol_raw is None else Protocol.from_dict(protocol_raw)
        except SceneError as err:
            raise err.located(prefix="protocol") from None

        kwargs: dict[str, Any] = {
            "name": data["name"],
            "bounds": data["bounds"],
            "obstacles": obstacles,
            "regions": regions,
            "protocol": protocol,
        }
        for key in (*_REGION_LISTS, "waypoints", "default_humans", "time_limit", "description"):
            if key in data and data[key] is not None:
                kwargs[key] = data[key]
        return Scene(**kwargs)
    except SceneError as err:
        raise err.located(scene=err.scene or scene_name) from None


def load_scene(
    source: str | Path | Mapping[str, Any],
    *,
    check_reachability: bool = True,
    radius: float = 0.3,
) -> Scene:
    """Load and validate a scene from a YAML/JSON file path or an already-parsed mapping.

    Args:
        source: path to a ``.yaml``/``.yml``/``.json`` file, or a mapping with the scene fields.
        check_reachability: also run :meth:`Scene.validate_reachability` (occupancy-grid based, a few ms).
        radius: agent radius used by the reachability check.

    Raises:
        SceneError: for any invalid field, with the scene name and field path in the message.
        FileNotFoundError: if the path does not exist.
    """
    if isinstance(source, Mapping):
        data: Any = source
        default_name = "<dict>"
    else:
        path = Path(source)
        text = path.read_text(encoding="utf-8")
        default_name = path.stem
        try:
            data = json.loads(text) if path.suffix.lower() == ".json" else yaml.safe_load(text)
        except (json.JSONDecodeError, yaml.YAMLError) as err:
            raise SceneError(f"cannot parse {path.name}: {err}", scene=default_name) from None
        if not isinstance(data, Mapping):
            raise SceneError(f"expected a mapping at the top level of {path.name}, got {_describe(data)}", scene=default_name)
    scene = scene_from_dict(data, default_name=default_name)
    if check_reachability:
        scene.validate_reachability(radius)
    return scene
