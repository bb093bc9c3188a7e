"""Overlap polygon, A_n, B_n, n and K against an independent computation."""

import numpy as np
import pytest

from polydem_cli.geometry.polygon import hexagon, polygon_area_centroid_inertia, rectangle, regular_polygon
from polydem_cli.interactions.contact.geometry import CONTACT, CONTAINED, NO_CONTACT, pair_geometry_py

from independent import crossings, inside, overlap_area, random_convex, rotate_about


def _random_pairs(n, seed):
    rng = np.random.default_rng(seed)
    out = []
    while len(out) < n:
        P = random_convex(rng)
        Q = random_convex(rng)
        ang = rng.uniform(0, 2 * np.pi)
        d = rng.uniform(0.3, 1.6)
        Q = Q + d * np.array([np.cos(ang), np.sin(ang)])
        off = rng.uniform(-20, 20, 2)  # away from the origin: no reliance on small coordinates
        out.append((P + off, Q + off))
    return out


def test_random_pairs_agree_with_independent_computation():
    checked = 0
    for P, Q in _random_pairs(500, 1):
        st, g = pair_geometry_py(P, Q)
        A_ref = overlap_area(P, Q)
        scale = polygon_area_centroid_inertia(P)[0]
        if A_ref < 1e-9 * scale:
            assert st == NO_CONTACT or g["A"] < 1e-8 * scale
            continue
        c = crossings(P, Q)
        assert st == (CONTACT if len(c) else CONTAINED)
        assert g["A"] == pytest.approx(A_ref, rel=1e-10)
        if len(c) != 2:
            continue  # penetration cases are tested separately
        Pa, Pb = c
        B_ref = np.hypot(*(Pb - Pa))
        assert g["B"] == pytest.approx(B_ref, rel=1e-10)
        assert np.allclose(g["K"], 0.5 * (Pa + Pb), rtol=0, atol=1e-10)
        # normal: perpendicular to the overlap line, pointing where moving I increases the overlap
        h = 1e-6
        dA = np.array(
            [
                (overlap_area(P + [h, 0], Q) - overlap_area(P - [h, 0], Q)) / (2 * h),
                (overlap_area(P + [0, h], Q) - overlap_area(P - [0, h], Q)) / (2 * h),
            ]
        )
        t = (Pb - Pa) / B_ref
        n_ref = np.array([t[1], -t[0]])
        if n_ref @ dA < 0:
            n_ref = -n_ref
        assert np.allclose(g["n"], n_ref, atol=1e-10)
        # exact gradient identity dA/dx_I = B n (finite differences, so a looser tolerance)
        assert np.allclose(dA, g["B"] * g["n"], rtol=1e-5, atol=1e-7 * B_ref)
        # and dA/dphi_I = B (r_I x n) about the centroid of I
        cI = g["cI"]
        dAphi = (overlap_area(rotate_about(P, cI, h), Q) - overlap_area(rotate_about(P, cI, -h), Q)) / (2 * h)
        r = g["K"] - cI
        assert dAphi == pytest.approx(g["B"] * (r[0] * g["n"][1] - r[1] * g["n"][0]), rel=1e-5, abs=1e-7)
        checked += 1
    assert checked > 200


def test_swapping_I_and_II_gives_opposite_force_and_consistent_moments():
    for P, Q in _random_pairs(100, 2):
        s1, g1 = pair_geometry_py(P, Q)
        s2, g2 = pair_geometry_py(Q, P)
        assert s1 == s2
        if s1 != CONTACT:
            continue
        assert g2["A"] == pytest.approx(g1["A"], rel=1e-12)
        assert g2["B"] == pytest.approx(g1["B"], rel=1e-9, abs=1e-12)
        if g1["n_cross"] == 2:
            assert np.allclose(g2["n"], -g1["n"], atol=1e-9)
            assert np.allclose(g2["K"], g1["K"], atol=1e-10)
            # force on I from (I, II) is -k A B n; from (II, I) the force on II is -k A B (-n): opposite
            fI = -g1["A"] * g1["B"] * g1["n"]
            fII = -g2["A"] * g2["B"] * g2["n"]
            assert np.allclose(fI, -fII, atol=1e-12)
            # moments about each centroid are r x f with the same contact point
            rI, rII = g1["K"] - g1["cI"], g1["K"] - g1["cII"]
            mI = rI[0] * fI[1] - rI[1] * fI[0]
            mII = rII[0] * fII[1] - rII[1] * fII[0]
            # total angular momentum balance about the origin: (cI x fI + mI) + (cII x fII + mII) = 0
            cross = lambda a, b: a[0] * b[1] - a[1] * b[0]  # noqa: E731
            tot = (cross(g1["cI"], fI) + mI) + (cross(g1["cII"], fII) + mII)
            assert abs(tot) < 1e-10


def test_exactly_touching_collinear_edges_is_no_contact():
    a = hexagon(1.27, (0.0, 0.0))
    b = hexagon(1.27, (1.27, 0.0))  # shares a full vertical edge
    assert pair_geometry_py(a, b)[0] == NO_CONTACT
    c = hexagon(1.27, (0.635, 1.27 * np.sqrt(3) / 2))  # +60 degree neighbour
    assert pair_geometry_py(a, c)[0] == NO_CONTACT
    sq1, sq2 = rectangle((0, 0), (1, 1)), rectangle((1.0, 0.3), (1, 1))  # partially shared edge
    assert pair_geometry_py(sq1, sq2)[0] == NO_CONTACT


def test_vertex_on_edge_and_vertex_on_vertex_touching_is_no_contact():
    sq = rectangle((0, 0), (1, 1))
    diamond = regular_polygon(4, 0.5, 0.0, (1.0, 0.2))  # left vertex exactly on the right edge
    assert pair_geometry_py(sq, diamond)[0] == NO_CONTACT
    d1 = regular_polygon(4, 0.5, 0.0, (0, 0))
    d2 = regular_polygon(4, 0.5, 0.0, (1.0, 0))  # tip on tip
    assert pair_geometry_py(d1, d2)[0] == NO_CONTACT


def test_vertex_on_vertex_small_overlap():
    d1 = regular_polygon(4, 0.5, 0.0, (0, 0))
    d2 = regular_polygon(4, 0.5, 0.0, (0.99, 0))
    st, g = pair_geometry_py(d1, d2)
    assert st == CONTACT
    # overlap is a square of diagonal 0.01 -> area 0.5 * 0.01^2, overlap line = other diagonal
    assert g["A"] == pytest.approx(0.5 * 0.01**2, rel=1e-9)
    assert g["B"] == pytest.approx(0.01, rel=1e-9)
    assert np.allclose(g["n"], [1, 0], atol=1e-12)
    assert np.allclose(g["K"], [0.495, 0], atol=1e-12)


def test_overlapping_parallel_edges():
    """Face-to-face hexagons pushed together by delta: overlap line spans the face plus the bevels."""
    delta = 0.01
    a = hexagon(1.27, (0.0, 0.0))
    b = hexagon(1.27, (1.27 - delta, 0.0))
    st, g = pair_geometry_py(a, b)
    assert st == CONTACT
    assert g["A"] == pytest.approx(overlap_area(a, b), rel=1e-10)
    s = 1.27 / np.sqrt(3)
    assert g["B"] == pytest.approx(s + delta * np.tan(np.pi / 6), rel=1e-10)
    assert np.allclose(g["n"], [1, 0], atol=1e-12)
    # squares with collinear horizontal edges sliding past each other (Fig. 4.5 situation)
    sq1 = rectangle((0, 0), (1, 1))
    sq2 = rectangle((0.0, 0.99), (1, 1))  # same x: vertical edges coincide
    st, g = pair_geometry_py(sq1, sq2)
    assert st == CONTACT
    assert g["A"] == pytest.approx(0.01, rel=1e-10)
    assert g["B"] == pytest.approx(1.0, rel=1e-10)
    assert np.allclose(g["n"], [0, 1], atol=1e-12)


def test_penetration_uses_farthest_crossings():
    """A thin bar through a square: four crossings; overlap line = farthest pair (Tillemans & Herrmann)."""
    sq = rectangle((0, 0), (1, 1))
    bar = rotate_about(rectangle((0.1, 0.0), (0.2, 3.0)), np.array([0.1, 0.0]), 0.2)  # through bottom and top
    st, g = pair_geometry_py(sq, bar)
    assert st == CONTACT
    assert g["n_cross"] == 4
    assert g["A"] == pytest.approx(overlap_area(sq, bar), rel=1e-12)
    c = crossings(sq, bar)
    d = np.hypot(*(c[:, None, :] - c[None, :, :]).transpose(2, 0, 1))
    i, j = np.unravel_index(np.argmax(d), d.shape)
    assert g["B"] == pytest.approx(d[i, j], rel=1e-12)
    assert np.allclose(g["K"], 0.5 * (c[i] + c[j]), atol=1e-12)
    assert abs(np.dot(g["n"], c[j] - c[i])) < 1e-12
    # a vertex leaving through the far side: a long triangle poking through a square
    tri = np.array([[-2.0, 0.2], [-2.0, -0.2], [0.3, 0.0]])
    st, g = pair_geometry_py(tri, sq)
    assert st == CONTACT and g["n_cross"] == 2 and np.isfinite(g["B"])
    tri2 = np.array([[-2.0, 0.2], [-2.0, -0.2], [0.7, 0.0]])  # tip exits on the right
    st, g = pair_geometry_py(tri2, sq)
    assert st == CONTACT and g["n_cross"] == 4
    assert g["A"] == pytest.approx(overlap_area(tri2, sq), rel=1e-10)
    assert np.all(np.isfinite(g["n"])) and abs(np.linalg.norm(g["n"]) - 1) < 1e-12


def test_full_containment_is_flagged_not_a_crash():
    big = rectangle((0, 0), (4, 4))
    small = regular_polygon(3, 0.3, 0.1, (0.5, -0.2))
    for P, Q in ((big, small), (small, big)):
        st, g = pair_geometry_py(P, Q)
        assert st == CONTAINED
        assert g["A"] == pytest.approx(polygon_area_centroid_inertia(small)[0], rel=1e-12)
        assert g["B"] == 0.0
        assert np.all(np.isfinite(g["n"])) and np.all(np.isfinite(g["K"]))
    # identical polygons on top of each other: contained (no crossing), no NaN
    st, g = pair_geometry_py(big, big.copy())
    assert st in (CONTAINED, CONTACT) and np.all(np.isfinite(g["n"]))


def test_disjoint_is_no_contact():
    assert pair_geometry_py(rectangle((0, 0), (1, 1)), rectangle((3, 0), (1, 1)))[0] == NO_CONTACT
    assert pair_geometry_py(rectangle((0, 0), (1, 1)), rectangle((1.0001, 0), (1, 1)))[0] == NO_CONTACT


def _segment_distance(p, a, b):
    ab = b - a
    t = np.clip(np.dot(p - a, ab) / np.dot(ab, ab), 0.0, 1.0)
    return float(np.hypot(*(p - (a + t * ab))))


def _polygon_distance(P, Q):
    """Euclidean distance of two disjoint convex polygons: the smallest vertex-edge distance."""
    d = np.inf
    for A, B in ((P, Q), (Q, P)):
        for p in A:
            for k in range(len(B)):
                d = min(d, _segment_distance(p, B[k], B[(k + 1) % len(B)]))
    return d


def test_separation_lower_bound_of_the_buffered_list():
    """The pair gap kept with the buffered pair list is a lower bound of the true distance, and
    positive exactly for disjoint polygons (else a skipped pair could be a missed contact)."""
    from polydem_cli.geometry.polygon import check_convex_polygon
    from polydem_cli.interactions.contact.geometry import separation_lower_bound

    rng = np.random.default_rng(7)
    disjoint = 0
    for _ in range(400):
        P = check_convex_polygon(random_convex(rng))
        Q = check_convex_polygon(random_convex(rng)) + rng.uniform(-3, 3, 2)
        wv = np.ascontiguousarray(np.vstack([P, Q]), dtype=float)
        g = separation_lower_bound(wv, 0, len(P), len(P), len(Q))
        overlapping = overlap_area(P, Q) > 0 or inside(P[0], Q) or inside(Q[0], P)
        if overlapping:
            assert g <= 1e-12
            continue
        d = _polygon_distance(P, Q)
        assert g <= d + 1e-12
        if d > 1e-9:
            disjoint += 1
            assert g > 0.0
            # separating axes of two polygons bound the distance to within the angle of the best axis
            assert g >= 0.2 * d
    assert disjoint > 100
