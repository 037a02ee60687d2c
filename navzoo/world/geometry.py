"""Vectorised 2D geometry used by the static world (pure numpy, no state).

Conventions:
    * points are ``(N, 2)`` float arrays ``[x, y]`` in metres,
    * segments are ``(M, 2, 2)`` float arrays ``[[x0, y0], [x1, y1]]``,
    * polygons are ``(K, 2)`` float arrays of vertices, without repeating the first vertex at the end.

All functions accept anything ``np.asarray`` understands and never modify their inputs.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike

__all__ = [
    "as_points",
    "as_segments",
    "box_corners",
    "circle_polygon",
    "ensure_ccw",
    "closest_points_on_segments",
    "min_distance_to_segments",
    "nearest_point_per_group",
    "point_in_polygon",
    "polygon_area",
    "polygon_edges",
    "polygon_is_simple",
    "polygon_perimeter",
    "segment_point_distance",
    "segment_segment_distance",
    "segments_intersect",
    "swept_circle_hits_segments",
    "triangulate_polygon",
    "wall_corners",
]

# Tolerance for orientation tests. Scenes are specified in metres with centimetre precision, so 1e-12 m^2
# is far below anything meaningful while still absorbing float round-off on exactly collinear input.
_EPS = 1e-12


def as_points(points: ArrayLike) -> np.ndarray:
    """Return ``points`` as a float64 ``(N, 2)`` array (a single ``(2,)`` point becomes ``(1, 2)``)."""
    arr = np.asarray(points, dtype=np.float64)
    if arr.ndim == 1:
        arr = arr[None, :]
    if arr.ndim != 2 or arr.shape[1] != 2:
        raise ValueError(f"expected points of shape (N, 2), got {arr.shape}")
    return arr


def as_segments(segments: ArrayLike) -> np.ndarray:
    """Return ``segments`` as a float64 ``(M, 2, 2)`` array (a single ``(2, 2)`` segment becomes ``(1, 2, 2)``)."""
    arr = np.asarray(segments, dtype=np.float64)
    if arr.ndim == 2 and arr.shape == (2, 2):
        arr = arr[None]
    if arr.size == 0:
        return np.zeros((0, 2, 2))
    if arr.ndim != 3 or arr.shape[1:] != (2, 2):
        raise ValueError(f"expected segments of shape (M, 2, 2), got {arr.shape}")
    return arr


# ---------------------------------------------------------------------------------------------------------
# Shapes
# ---------------------------------------------------------------------------------------------------------


def box_corners(center: ArrayLike, size: ArrayLike, yaw: float = 0.0) -> np.ndarray:
    """Corners ``(4, 2)`` of a rotated rectangle, counter-clockwise."""
    cx, cy = np.asarray(center, dtype=np.float64)
    hx, hy = 0.5 * np.asarray(size, dtype=np.float64)
    local = np.array([[-hx, -hy], [hx, -hy], [hx, hy], [-hx, hy]])
    c, s = np.cos(yaw), np.sin(yaw)
    rot = np.array([[c, -s], [s, c]])
    return local @ rot.T + np.array([cx, cy])


def wall_corners(start: ArrayLike, end: ArrayLike, thickness: float) -> np.ndarray:
    """Corners ``(4, 2)`` of a wall: a rectangle of width ``thickness`` centred on the segment start-end.

    The rectangle spans exactly from ``start`` to ``end`` lengthwise (no end caps), so the width of a door
    between two collinear walls is simply the gap between their end points.
    """
    p0 = np.asarray(start, dtype=np.float64)
    p1 = np.asarray(end, dtype=np.float64)
    d = p1 - p0
    length = float(np.hypot(*d))
    if length == 0.0:
        raise ValueError("wall has zero length")
    yaw = float(np.arctan2(d[1], d[0]))
    return box_corners(0.5 * (p0 + p1), (length, thickness), yaw)


def circle_polygon(center: ArrayLike, radius: float, n: int = 24) -> np.ndarray:
    """A regular ``n``-gon ``(n, 2)`` *circumscribing* the circle, counter-clockwise.

    Circumscribing (vertices at ``radius / cos(pi / n)``) keeps the polygon conservative: every point of the
    true disc is inside it, so distances computed from polygon edges never overestimate clearance.
    """
    cx, cy = np.asarray(center, dtype=np.float64)
    r = radius / np.cos(np.pi / n)
    # Offset by half a step so that the polygon's edge midpoints (where it touches the circle) lie on the
    # axes: a column next to an axis-aligned wall then has a flat side facing it.
    ang = (np.arange(n) + 0.5) * (2.0 * np.pi / n)
    return np.stack([cx + r * np.cos(ang), cy + r * np.sin(ang)], axis=1)


def polygon_area(polygon: ArrayLike) -> float:
    """Signed area (shoelace): positive for counter-clockwise vertex order."""
    p = as_points(polygon)
    x, y = p[:, 0], p[:, 1]
    return 0.5 * float(np.dot(x, np.roll(y, -1)) - np.dot(y, np.roll(x, -1)))


def polygon_perimeter(polygon: ArrayLike) -> float:
    """Perimeter of a closed polygon."""
    p = as_points(polygon)
    return float(np.linalg.norm(np.roll(p, -1, axis=0) - p, axis=1).sum())


def ensure_ccw(polygon: ArrayLike) -> np.ndarray:
    """Return a copy of ``polygon`` with counter-clockwise vertex order."""
    p = as_points(polygon).copy()
    return p[::-1].copy() if polygon_area(p) < 0 else p


def polygon_edges(polygon: ArrayLike) -> np.ndarray:
    """Edges ``(K, 2, 2)`` of a closed polygon, edge ``i`` going from vertex ``i`` to vertex ``i + 1``."""
    p = as_points(polygon)
    return np.stack([p, np.roll(p, -1, axis=0)], axis=1)


# ---------------------------------------------------------------------------------------------------------
# Predicates and distances
# ---------------------------------------------------------------------------------------------------------


def point_in_polygon(points: ArrayLike, polygon: ArrayLike) -> np.ndarray:
    """Even-odd (crossing number) test; returns ``(N,)`` bool. Points exactly on an edge may go either way."""
    pts = as_points(points)
    poly = as_points(polygon)
    x, y = pts[:, 0:1], pts[:, 1:2]  # (N, 1) against (K,) edges below
    x0, y0 = poly[:, 0], poly[:, 1]
    x1, y1 = np.roll(x0, -1), np.roll(y0, -1)
    # Half-open rule on y (y0 <= y < y1 or y1 <= y < y0) counts a vertex on the ray exactly once.
    straddles = (y0 <= y) != (y1 <= y)
    with np.errstate(divide="ignore", invalid="ignore"):
        x_cross = x0 + (y - y0) * (x1 - x0) / (y1 - y0)
    crossings = straddles & (x < x_cross)
    return (np.count_nonzero(crossings, axis=1) % 2) == 1


def segment_point_distance(segments: ArrayLike, points: ArrayLike) -> np.ndarray:
    """Euclidean distance from every point to every segment; returns ``(N, M)``."""
    seg = as_segments(segments)
    pts = as_points(points)
    a = seg[:, 0]  # (M, 2)
    ab = seg[:, 1] - a
    denom = np.einsum("md,md->m", ab, ab)
    ap = pts[:, None, :] - a[None, :, :]  # (N, M, 2)
    with np.errstate(divide="ignore", invalid="ignore"):
        t = np.einsum("nmd,md->nm", ap, ab) / denom
    # Degenerate (zero-length) segments have denom == 0: treat them as their start point.
    t = np.clip(np.nan_to_num(t, nan=0.0, posinf=0.0, neginf=0.0), 0.0, 1.0)
    closest = ap - t[:, :, None] * ab[None, :, :]
    return np.hypot(closest[..., 0], closest[..., 1])


def closest_points_on_segments(segments: ArrayLike, points: ArrayLike) -> np.ndarray:
    """Closest point of every segment to every point; returns ``(N, M, 2)``."""
    seg = as_segments(segments)
    pts = as_points(points)
    a = seg[:, 0]
    ab = seg[:, 1] - a
    denom = np.einsum("md,md->m", ab, ab)
    with np.errstate(divide="ignore", invalid="ignore"):
        t = np.einsum("nmd,md->nm", pts[:, None, :] - a[None], ab) / denom
    t = np.clip(np.nan_to_num(t, nan=0.0, posinf=0.0, neginf=0.0), 0.0, 1.0)
    return a[None] + t[:, :, None] * ab[None]


def nearest_point_per_group(
    points: ArrayLike, segments: ArrayLike, group: ArrayLike
) -> tuple[np.ndarray, np.ndarray]:
    """Distance to, and location of, the nearest point of each *group* of segments (e.g. each obstacle).

    Pedestrian models should feel one repulsion per obstacle, from its nearest point; summing over all
    edges would count a 24-gon column ~5 times and a wall's far side as well.

    Args:
        points: ``(N, 2)``.
        segments: ``(M, 2, 2)``.
        group: ``(M,)`` group id of each segment; segments of a group must be contiguous (as returned by
            :meth:`navzoo.world.scene.Scene.wall_segment_owner`).

    Returns:
        ``(dist (N, G), closest (N, G, 2))`` with groups in order of appearance.
    """
    pts = as_points(points)
    seg = as_segments(segments)
    gid = np.asarray(group)
    if seg.shape[0] == 0:
        return np.zeros((pts.shape[0], 0)), np.zeros((pts.shape[0], 0, 2))
    starts = np.flatnonzero(np.r_[True, gid[1:] != gid[:-1]])
    cp = closest_points_on_segments(seg, pts)  # (N, M, 2)
    diff = pts[:, None, :] - cp
    dist = np.hypot(diff[..., 0], diff[..., 1])
    gmin = np.minimum.reduceat(dist, starts, axis=1)  # (N, G)
    index_of = np.repeat(np.arange(starts.size), np.diff(np.r_[starts, seg.shape[0]]))
    m = seg.shape[0]
    # first segment attaining the group minimum: max over (m - index) where the minimum is attained
    score = np.where(dist <= gmin[:, index_of], m - np.arange(m)[None, :], 0)
    first = m - np.maximum.reduceat(score, starts, axis=1)  # (N, G) segment indices
    closest = np.take_along_axis(cp, first[..., None], axis=1)
    return gmin, closest


def min_distance_to_segments(points: ArrayLike, segments: ArrayLike) -> np.ndarray:
    """Distance ``(N,)`` from each point to the closest segment (``inf`` when there are no segments)."""
    pts = as_points(points)
    seg = as_segments(segments)
    if seg.shape[0] == 0:
        return np.full(pts.shape[0], np.inf)
    return segment_point_distance(seg, pts).min(axis=1)


def _orient(a: np.ndarray, b: np.ndarray, c: np.ndarray) -> np.ndarray:
    """Twice the signed area of triangle (a, b, c), broadcasting over leading dimensions."""
    return (b[..., 0] - a[..., 0]) * (c[..., 1] - a[..., 1]) - (b[..., 1] - a[..., 1]) * (c[..., 0] - a[..., 0])


def _on_segment(a: np.ndarray, b: np.ndarray, p: np.ndarray) -> np.ndarray:
    """For p collinear with a-b: is p within the bounding box of the segment?"""
    return (
        (np.minimum(a[..., 0], b[..., 0]) - _EPS <= p[..., 0])
        & (p[..., 0] <= np.maximum(a[..., 0], b[..., 0]) + _EPS)
        & (np.minimum(a[..., 1], b[..., 1]) - _EPS <= p[..., 1])
        & (p[..., 1] <= np.maximum(a[..., 1], b[..., 1]) + _EPS)
    )


def segments_intersect(a: ArrayLike, b: ArrayLike) -> np.ndarray:
    """Do closed segments ``a`` ``(N, 2, 2)`` and ``b`` ``(M, 2, 2)`` intersect (touching counts)? ``(N, M)`` bool."""
    sa = as_segments(a)[:, None]  # (N, 1, 2, 2)
    sb = as_segments(b)[None, :]  # (1, M, 2, 2)
    a0, a1, b0, b1 = sa[..., 0, :], sa[..., 1, :], sb[..., 0, :], sb[..., 1, :]
    d1 = _orient(b0, b1, a0)
    d2 = _orient(b0, b1, a1)
    d3 = _orient(a0, a1, b0)
    d4 = _orient(a0, a1, b1)
    proper = (((d1 > _EPS) & (d2 < -_EPS)) | ((d1 < -_EPS) & (d2 > _EPS))) & (
        ((d3 > _EPS) & (d4 < -_EPS)) | ((d3 < -_EPS) & (d4 > _EPS))
    )
    touch = (
        ((np.abs(d1) <= _EPS) & _on_segment(b0, b1, a0))
        | ((np.abs(d2) <= _EPS) & _on_segment(b0, b1, a1))
        | ((np.abs(d3) <= _EPS) & _on_segment(a0, a1, b0))
        | ((np.abs(d4) <= _EPS) & _on_segment(a0, a1, b1))
    )
    return proper | touch


def segment_segment_distance(a: ArrayLike, b: ArrayLike) -> np.ndarray:
    """Minimum distance between closed segments ``a`` ``(N, 2, 2)`` and ``b`` ``(M, 2, 2)``; returns ``(N, M)``.

    Zero when they intersect, otherwise the minimum of the four endpoint-to-segment distances (in 2D the
    closest pair of two disjoint segments always involves an endpoint).
    """
    sa = as_segments(a)
    sb = as_segments(b)
    d = np.minimum(
        np.minimum(segment_point_distance(sb, sa[:, 0]), segment_point_distance(sb, sa[:, 1])),
        np.minimum(segment_point_distance(sa, sb[:, 0]).T, segment_point_distance(sa, sb[:, 1]).T),
    )
    return np.where(segments_intersect(sa, sb), 0.0, d)


def swept_circle_hits_segments(
    p0: ArrayLike, p1: ArrayLike, radius: float | ArrayLike, segments: ArrayLike
) -> np.ndarray:
    """Does a disc of ``radius`` moving straight from ``p0`` to ``p1`` touch any segment? ``(N,)`` bool.

    The swept disc is the set of points within ``radius`` of the motion segment, so it touches a wall
    segment iff the segment-segment distance is below ``radius``. ``radius`` may be a scalar or ``(N,)``.
    A disc already entirely inside a polygon without touching its edges does not count as a hit.
    """
    a = as_points(p0)
    b = as_points(p1)
    seg = as_segments(segments)
    if seg.shape[0] == 0:
        return np.zeros(a.shape[0], dtype=bool)
    motion = np.stack([a, b], axis=1)
    dist = segment_segment_distance(motion, seg).min(axis=1)
    return dist < np.asarray(radius, dtype=np.float64)


def ray_segment_distances(
    origins: ArrayLike, angles: ArrayLike, segments: ArrayLike, max_range: float
) -> np.ndarray:
    """Distance along each ray to the first segment it crosses, ``(N, R)``, at most ``max_range``.

    ``origins`` are ``(N, 2)`` points and ``angles`` ``(N, R)`` (or ``(R,)``, shared) world angles in
    radians. Exact 2D ray-segment intersection (a planar range scan of line geometry); a ray that meets
    nothing within ``max_range`` reads ``max_range``. Segments touched at the origin read 0.
    """
    o = as_points(origins)
    ang = np.asarray(angles, dtype=np.float64)
    if ang.ndim == 1:
        ang = np.broadcast_to(ang, (o.shape[0], ang.shape[0]))
    if ang.ndim != 2 or ang.shape[0] != o.shape[0]:
        raise ValueError(f"angles must be (R,) or (N, R) with N = {o.shape[0]}, got {ang.shape}")
    if not (np.isfinite(max_range) and max_range > 0):
        raise ValueError(f"max_range must be a finite number > 0, got {max_range!r}")
    out = np.full(ang.shape, float(max_range))
    seg = as_segments(segments)
    if seg.shape[0] == 0 or ang.size == 0:
        return out
    d = np.stack([np.cos(ang), np.sin(ang)], axis=-1)[:, :, None, :]  # (N, R, 1, 2)
    a = seg[None, None, :, 0, :]  # (1, 1, M, 2)
    e = seg[None, None, :, 1, :] - a  # segment direction
    w = a - o[:, None, None, :]  # origin -> segment start, (N, 1, M, 2)
    den = d[..., 0] * e[..., 1] - d[..., 1] * e[..., 0]  # cross(d, e)
    with np.errstate(divide="ignore", invalid="ignore"):
        t = (w[..., 0] * e[..., 1] - w[..., 1] * e[..., 0]) / den  # distance along the ray
        u = (w[..., 0] * d[..., 1] - w[..., 1] * d[..., 0]) / den  # position along the segment
    hit = (np.abs(den) > 1e-12) & (t >= 0.0) & (u >= 0.0) & (u <= 1.0)
    t = np.where(hit, t, np.inf).min(axis=-1)
    return np.minimum(out, t)


# ---------------------------------------------------------------------------------------------------------
# Polygon validity and triangulation
# ---------------------------------------------------------------------------------------------------------


def polygon_is_simple(polygon: ArrayLike) -> bool:
    """True if the closed polygon has >= 3 vertices, non-zero area and no two non-adjacent edges touch."""
    p = as_points(polygon)
    k = p.shape[0]
    if k < 3 or abs(polygon_area(p)) <= _EPS:
        return False
    edges = polygon_edges(p)
    # Zero-length edges (repeated vertices) make the vertex order ambiguous.
    if np.any(np.all(edges[:, 0] == edges[:, 1], axis=1)):
        return False
    hit = segments_intersect(edges, edges)
    idx = np.arange(k)
    adjacent = (np.abs(idx[:, None] - idx[None, :]) <= 1) | (np.abs(idx[:, None] - idx[None, :]) == k - 1)
    if k == 3:
        return True
    # Adjacent edges share one vertex by construction; they are only a problem if they fold back onto each
    # other (collinear and overlapping), i.e. if the shared vertex is a 180 degree spike.
    prev_dir = p - np.roll(p, 1, axis=0)
    next_dir = np.roll(p, -1, axis=0) - p
    cross = prev_dir[:, 0] * next_dir[:, 1] - prev_dir[:, 1] * next_dir[:, 0]
    dot = np.einsum("kd,kd->k", prev_dir, next_dir)
    if np.any((np.abs(cross) <= _EPS) & (dot < 0)):
        return False
    return not bool(np.any(hit & ~adjacent))


def triangulate_polygon(polygon: ArrayLike) -> np.ndarray:
    """Ear-clipping triangulation of a simple polygon; returns ``(K - 2, 3)`` vertex indices.

    Triangles are counter-clockwise whatever the input orientation. O(K^2) per ear on average, which is
    fine for furniture footprints (tens of vertices).

    Raises:
        ValueError: if the polygon is not simple (no ear can be found).
    """
    p = as_points(polygon)
    k = p.shape[0]
    if k < 3:
        raise ValueError("a polygon needs at least 3 vertices")
    order = list(range(k)) if polygon_area(p) > 0 else list(range(k - 1, -1, -1))
    triangles: list[tuple[int, int, int]] = []
    guard = 0
    while len(order) > 3:
        m = len(order)
        found = False
        for i in range(m):
            ia, ib, ic = order[(i - 1) % m], order[i], order[(i + 1) % m]
            a, b, c = p[ia], p[ib], p[ic]
            cross = (b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0])
            if cross <= _EPS:
                continue  # reflex or degenerate vertex: not an ear
            others = [j for j in order if j not in (ia, ib, ic)]
            if others:
                q = p[others]
                # A vertex inside or on the candidate triangle blocks the ear (closed test so that
                # vertices touching the diagonal are rejected as well).
                d1 = _orient(a, b, q)
                d2 = _orient(b, c, q)
                d3 = _orient(c, a, q)
                if np.any((d1 >= -_EPS) & (d2 >= -_EPS) & (d3 >= -_EPS)):
                    continue
            triangles.append((ia, ib, ic))
            del order[i]
            found = True
            break
        if not found:
            # Collinear leftovers (zero-area ears) can remain on polygons with collinear vertices; clip the
            # first convex-or-flat vertex rather than failing on an otherwise valid polygon.
            guard += 1
            if guard > k:
                raise ValueError("polygon is not simple; ear clipping found no ear")
            flat = [
                i
                for i in range(m)
                if abs(float(_orient(p[order[(i - 1) % m]], p[order[i]], p[order[(i + 1) % m]]))) <= _EPS
            ]
            if not flat:
                raise ValueError("polygon is not simple; ear clipping found no ear")
            del order[flat[0]]
    triangles.append((order[0], order[1], order[2]))
    return np.asarray(triangles, dtype=np.int64)
