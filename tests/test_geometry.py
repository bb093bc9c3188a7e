"""Polygon mass properties and specimen generators."""

import numpy as np
import pytest

from polydem_cli.geometry.polygon import (
    GeometryError,
    check_convex_polygon,
    hexagon,
    make_shape,
    polygon_area_centroid_inertia,
    rectangle,
    regular_polygon,
)
from polydem_cli.geometry.specimens import hexagon_packing, random_disk_packing, voronoi_specimen


def test_rectangle_properties_closed_form():
    w, h = 3.0, 0.5
    A, c, J = polygon_area_centroid_inertia(rectangle((2.0, -1.0), (w, h)))
    assert A == pytest.approx(w * h, rel=1e-14)
    assert np.allclose(c, [2.0, -1.0], atol=1e-14)
    assert J == pytest.approx(w * h * (w * w + h * h) / 12.0, rel=1e-12)


def test_triangle_properties_closed_form():
    P = np.array([[0.0, 0.0], [4.0, 0.0], [1.0, 3.0]])
    A, c, J = polygon_area_centroid_inertia(P)
    assert A == pytest.approx(6.0)
    assert np.allclose(c, P.mean(axis=0))
    # polar moment about the centroid of a triangle: A/36 * (a^2+b^2+c^2) ... via sides
    a2 = np.sum((P[1] - P[0]) ** 2) + np.sum((P[2] - P[1]) ** 2) + np.sum((P[0] - P[2]) ** 2)
    assert J == pytest.approx(A * a2 / 36.0, rel=1e-12)


def test_nut_mass_and_inertia_match_spec():
    """w = 1.27 cm, T = 0.62 cm, rho = 5.32 -> m = 4.607 g, Theta = 5/12 m s^2 = 1.032 g cm^2."""
    shape, c = make_shape(hexagon(1.27, (3.0, 4.0)))
    m = shape.mass(5.32, 0.62)
    th = shape.inertia(5.32, 0.62)
    s = 1.27 / np.sqrt(3)
    assert np.allclose(c, [3.0, 4.0])
    assert m == pytest.approx(4.607, abs=5e-4)
    assert th == pytest.approx(5.0 / 12.0 * m * s * s, rel=1e-12)
    assert th == pytest.approx(1.032, abs=1e-3)
    assert shape.radius == pytest.approx(s)


def test_convexity_checks():
    sq = rectangle((0, 0), (1, 1))
    assert np.allclose(check_convex_polygon(sq[::-1]), check_convex_polygon(sq))  # clockwise accepted
    with pytest.raises(GeometryError, match="not convex"):
        check_convex_polygon([[0, 0], [2, 0], [1, 0.5], [2, 2], [0, 2]])
    with pytest.raises(GeometryError, match="zero area"):
        check_convex_polygon([[0, 0], [1, 1], [2, 2]])
    with pytest.raises(GeometryError, match="at least 3"):
        check_convex_polygon([[0, 0], [1, 1]])
    with pytest.raises(GeometryError, match="self-intersecting"):
        check_convex_polygon(regular_polygon(5, 1.0)[[0, 2, 4, 1, 3]])


def test_voronoi_is_deterministic_space_filling_and_clipped():
    a = voronoi_specimen(8, 6, 1.0, 0.999, seed=7)
    b = voronoi_specimen(8, 6, 1.0, 0.999, seed=7)
    c = voronoi_specimen(8, 6, 1.0, 0.999, seed=8)
    assert len(a) == 48
    assert all(np.array_equal(p, q) for p, q in zip(a.vertices, b.vertices))
    assert not all(np.array_equal(p, q) for p, q in zip(a.vertices, c.vertices))
    areas = [polygon_area_centroid_inertia(v)[0] for v in a.vertices]
    assert sum(areas) == pytest.approx(48.0, rel=1e-12)
    allv = np.vstack(a.vertices)
    assert allv[:, 0].min() == 0.0 and allv[:, 0].max() == 8.0
    assert allv[:, 1].min() == 0.0 and allv[:, 1].max() == 6.0
    for v in a.vertices:
        check_convex_polygon(v)
    # every shared edge is an edge (two common vertices) of both cells
    for (i, j), e in zip(a.shared_pairs, a.shared_edges):
        for k in (i, j):
            vk = a.vertices[k]
            for p in e:
                assert np.min(np.hypot(*(vk - p).T)) < 1e-12
    # subsets: generating points in the first/last row and column
    assert len(a.subsets["top"]) == 8 and len(a.subsets["left"]) == 6


def test_voronoi_30x30_counts_match_spec():
    """900 cells; a clipped tessellation has ~2586 adjacent pairs (thesis: 2568 beams)."""
    s = voronoi_specimen(30, 30, 1.0, 0.999, seed=0)
    assert len(s) == 900
    assert 2575 <= len(s.shared_pairs) <= 2600
    assert np.all(s.shared_lengths > 0)


def test_hexagon_packing_counts_neighbours_and_defects():
    h = hexagon_packing(1.27, [16, 15], 14)
    assert len(h) == 7 * 16 + 7 * 15 == 217
    cen = np.array([v.mean(axis=0) for v in h.vertices])
    d = np.hypot(*(cen[h.shared_pairs[:, 0]] - cen[h.shared_pairs[:, 1]]).T)
    assert np.allclose(d, 1.27)
    deg = np.bincount(h.shared_pairs.ravel(), minlength=len(h))
    assert deg.max() == 6
    # neighbour directions are 0, +-60, 180 degrees
    ang = np.degrees(np.arctan2(*(cen[h.shared_pairs[:, 1]] - cen[h.shared_pairs[:, 0]]).T[::-1])) % 180
    assert set(np.round(ang).astype(int)) <= {0, 60, 120}
    hd = hexagon_packing(1.27, [16, 15], 14, missing=[[6, 7], [7, 7]])
    assert len(hd) == 215
    with pytest.raises(GeometryError, match="outside"):
        hexagon_packing(1.27, [16, 15], 14, missing=[[1, 15]])


def test_hexagon_packing_with_more_sides_keeps_width_and_places():
    """sides = 24: regular 24-gons of the same width across flats on the same centres (disk-like)."""
    w = 1.27
    h6 = hexagon_packing(w, [4, 4], 3)
    h24 = hexagon_packing(w, [4, 4], 3, sides=24)
    for v6, v24 in zip(h6.vertices, h24.vertices):
        assert len(v24) == 24
        A, c, _ = polygon_area_centroid_inertia(v24)
        assert np.allclose(c, v6.mean(axis=0), atol=1e-12)
        xs = v24[:, 0] - c[0]
        assert xs.max() - xs.min() == pytest.approx(w, rel=1e-12)  # a flat faces +-e1
        R = 0.5 * w / np.cos(np.pi / 24)
        assert A == pytest.approx(0.5 * 24 * R * R * np.sin(2 * np.pi / 24), rel=1e-12)
    assert np.array_equal(h6.shared_pairs, h24.shared_pairs)


def test_random_disk_packing_no_overlap():
    c, r = random_disk_packing(60, (0.3, 0.5), (0, 0, 10, 10), seed=3)
    d = np.hypot(*(c[:, None, :] - c[None, :, :]).transpose(2, 0, 1))
    np.fill_diagonal(d, np.inf)
    assert np.all(d >= r[:, None] + r[None, :] - 1e-12)
