from __future__ import annotations

import numpy as np
import pytest

from navzoo.world import geometry as geo


def test_segment_point_distance_shapes_and_values():
    seg = np.array([[[0, 0], [2, 0]], [[0, 1], [0, 3]]], dtype=float)
    pts = np.array([[1, 1], [3, 0], [-1, 2], [0, 0]], dtype=float)
    d = geo.segment_point_distance(seg, pts)
    assert d.shape == (4, 2)
    np.testing.assert_allclose(d[:, 0], [1, 1, np.hypot(1, 2), 0])
    np.testing.assert_allclose(d[:, 1], [1, np.hypot(3, 1), 1, 1])
    np.testing.assert_allclose(geo.min_distance_to_segments(pts, seg), [1, 1, 1, 0])


def test_degenerate_segment_and_no_segments():
    seg = np.array([[[1, 1], [1, 1]]], dtype=float)
    np.testing.assert_allclose(geo.segment_point_distance(seg, [[4, 5]]), [[5.0]])
    assert np.isinf(geo.min_distance_to_segments([[0, 0]], np.zeros((0, 2, 2))))[0]


def test_segments_intersect_cases():
    a = np.array([[[0, 0], [2, 2]]], dtype=float)
    b = np.array(
        [
            [[0, 2], [2, 0]],  # proper crossing
            [[2, 2], [3, 0]],  # touching at an endpoint
            [[1, 1], [3, 3]],  # collinear overlap
            [[3, 3], [4, 4]],  # collinear, disjoint
            [[0, 1], [1, 2]],  # parallel
            [[5, 0], [6, 1]],  # far away
        ]
    )
    np.testing.assert_array_equal(geo.segments_intersect(a, b)[0], [True, True, True, False, False, False])


def test_segment_segment_distance():
    a = np.array([[[0, 0], [2, 0]]], dtype=float)
    b = np.array([[[1, 1], [1, 3]], [[3, -1], [3, 1]], [[1, -1], [1, 1]]], dtype=float)
    np.testing.assert_allclose(geo.segment_segment_distance(a, b)[0], [1.0, 1.0, 0.0])


def test_swept_circle_hits_segments():
    wall = np.array([[[0, -1], [0, 1]]], dtype=float)
    p0 = np.array([[-1, 0], [-1, 2], [-1, 1.2], [-0.5, 0]])
    p1 = np.array([[1, 0], [1, 2], [1, 1.2], [-0.31, 0]])
    hit = geo.swept_circle_hits_segments(p0, p1, 0.3, wall)
    # crosses the wall; passes 1 m above its end; passes 0.2 m above its end (< r); stops 0.31 m short
    np.testing.assert_array_equal(hit, [True, False, True, False])
    # per-agent radius
    np.testing.assert_array_equal(geo.swept_circle_hits_segments(p0[3:], p1[3:], [0.32], wall), [True])
    assert not geo.swept_circle_hits_segments(p0, p1, 0.3, np.zeros((0, 2, 2))).any()


def test_point_in_polygon_concave():
    l_shape = np.array([[0, 0], [3, 0], [3, 1], [1, 1], [1, 3], [0, 3]], dtype=float)
    pts = np.array([[0.5, 0.5], [2, 0.5], [0.5, 2], [2, 2], [-1, 0.5], [3.5, 0.5]])
    np.testing.assert_array_equal(geo.point_in_polygon(pts, l_shape), [True, True, True, False, False, False])
    # orientation does not matter
    np.testing.assert_array_equal(geo.point_in_polygon(pts, l_shape[::-1]), [True, True, True, False, False, False])


def test_shapes():
    box = geo.box_corners((1, 2), (2, 1), np.pi / 2)
    np.testing.assert_allclose(np.sort(box[:, 0]), [0.5, 0.5, 1.5, 1.5], atol=1e-12)
    np.testing.assert_allclose(np.sort(box[:, 1]), [1, 1, 3, 3], atol=1e-12)
    assert geo.polygon_area(box) > 0
    wall = geo.wall_corners((0, 0), (4, 0), 0.2)
    assert geo.polygon_area(wall) == pytest.approx(0.8)
    circle = geo.circle_polygon((0, 0), 1.0, 24)
    assert circle.shape == (24, 2)
    # circumscribed: every point of the unit disc is inside, edges touch the circle
    assert geo.min_distance_to_segments([[0, 0]], geo.polygon_edges(circle))[0] == pytest.approx(1.0)
    assert geo.polygon_area(circle) > np.pi
    with pytest.raises(ValueError):
        geo.wall_corners((1, 1), (1, 1), 0.1)


def test_polygon_is_simple():
    assert geo.polygon_is_simple([[0, 0], [1, 0], [1, 1], [0, 1]])
    assert geo.polygon_is_simple([[0, 0], [3, 0], [3, 1], [1, 1], [1, 3], [0, 3]])
    assert not geo.polygon_is_simple([[0, 0], [1, 1], [1, 0], [0, 1]])  # bow tie
    assert not geo.polygon_is_simple([[0, 0], [1, 0], [2, 0]])  # zero area
    assert not geo.polygon_is_simple([[0, 0], [2, 0], [2, 2], [1, 0], [0, 2]])  # vertex touching an edge


@pytest.mark.parametrize(
    "poly",
    [
        [[0, 0], [1, 0], [0, 1]],
        [[0, 0], [3, 0], [3, 1], [1, 1], [1, 3], [0, 3]],  # L
        [[0, 0], [4, 0], [4, 3], [3, 3], [3, 1], [1, 1], [1, 3], [0, 3]],  # U
        [[0, 0], [2, 0], [2, 2], [1, 1], [0, 2]],  # notch
        [[0, 0], [1, 0], [2, 0], [2, 1], [0, 1]],  # collinear vertex
        [[0, 3], [1, 1], [3, 0], [1, -1], [0, -3], [-1, -1], [-3, 0], [-1, 1]],  # star
    ],
)
def test_triangulate_polygon_covers_area(poly):
    p = np.asarray(poly, dtype=float)
    for candidate in (p, p[::-1]):
        tris = geo.triangulate_polygon(candidate)
        areas = [geo.polygon_area(candidate[t]) for t in tris]
        assert all(a >= -1e-12 for a in areas)  # counter-clockwise
        assert sum(areas) == pytest.approx(abs(geo.polygon_area(candidate)))
        # every triangle centroid lies inside the polygon
        centroids = candidate[tris].mean(axis=1)
        nondegenerate = np.array(areas) > 1e-9
        assert geo.point_in_polygon(centroids[nondegenerate], candidate).all()


def test_nearest_point_per_group():
    square = geo.polygon_edges([[0, 0], [1, 0], [1, 1], [0, 1]])
    circle = geo.polygon_edges(geo.circle_polygon((5, 0), 1.0, 24))
    segments = np.concatenate([square, circle])
    group = np.r_[np.zeros(4, int), np.ones(24, int)]
    pts = np.array([[0.5, -1.0], [2.0, 0.0], [5.0, 3.0]])
    dist, closest = geo.nearest_point_per_group(pts, segments, group)
    assert dist.shape == (3, 2) and closest.shape == (3, 2, 2)
    np.testing.assert_allclose(dist[:, 0], [1.0, 1.0, np.hypot(4, 2)])
    np.testing.assert_allclose(dist[:, 1], [np.hypot(4.5, 1) - 1, 2.0, 2.0], atol=0.01)
    np.testing.assert_allclose(closest[0, 0], [0.5, 0.0])
    np.testing.assert_allclose(closest[1, 0], [1.0, 0.0], atol=1e-12)
    np.testing.assert_allclose(closest[2, 1], [5.0, 1.0], atol=1e-12)
    np.testing.assert_allclose(np.linalg.norm(closest - pts[:, None], axis=2), dist)
    np.testing.assert_allclose(dist.min(axis=1), geo.min_distance_to_segments(pts, segments))
