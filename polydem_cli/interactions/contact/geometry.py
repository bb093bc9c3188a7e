"""Contact geometry of two convex polygons (thesis §4.1, Figs. 4.2–4.4).

Computed once per pair and handed to the normal and tangential sub-models:

* overlap region ``I ∩ II`` (convex), its area ``A_n``;
* overlap line ``P_a P_b`` between the points where the boundaries cross, its
  width ``B_n = |P_b - P_a|`` and the contact point ``K = (P_a + P_b)/2``;
* normal ``n`` (unit, from I towards II) and tangent ``t = e3 x n = [-n2, n1]``.

Algorithm.  The overlap polygon is obtained by Sutherland–Hodgman clipping of
I against the half-planes of II's edges.  Every output vertex carries the label
of its *outgoing* edge: ``LAB_I`` if that edge lies on the boundary of I, or
``LAB_II`` if it lies on an edge of II.  Walking the overlap polygon
counter-clockwise, a vertex whose incoming edge is on ∂II and outgoing edge on
∂I is where ∂I *enters* II (``P_in``); the reverse is where it *leaves*
(``P_out``).  With two crossings the part of ∂I inside II is one chain from
``P_in`` to ``P_out`` and

    ∂A_n/∂x_I = R(-90°)(P_out - P_in) = B_n n,
    ∂A_n/∂φ_I = B_n (r_I × n),

so (4.3) is the exact negative gradient of the potential (4.2).
Penetration (a particle leaves through the partner's far side, more than two
crossings): the overlap line joins the two crossing points farthest apart
(Tillemans & Herrmann, thesis §4.2.2); ``n`` is its normal oriented along the
summed chain gradient.

Degenerate cases (open points O-6, O-17):

* exactly touching polygons (collinear shared edges, vertex on edge) give an
  overlap of zero or round-off area; a pair is in contact only if
  ``A_n > area_tol`` (a small fraction of the smaller particle's area), so they
  produce no force and no spurious contact;
* a polygon entirely inside the other has no boundary crossing: status
  ``CONTAINED``.  The gradient of ``A_n`` is then zero, so the contact force is
  zero; the engine counts and reports such pairs (policy in ``engine``).

All functions are Numba kernels working on preallocated scratch buffers.
"""

from __future__ import annotations

from collections import namedtuple

import numpy as np
from numba import njit

LAB_I = 0
LAB_II = 1

#: status codes of :func:`pair_geometry`
NO_CONTACT = 0
CONTACT = 1
CONTAINED = 2

#: what :func:`pair_geometry` finds for a pair: ``status`` (NO_CONTACT, CONTACT or CONTAINED);
#: ``overlap_area`` A_n; ``line_width`` B_n = |P_b − P_a|, the width of the overlap line; ``n1, n2`` the unit
#: normal n from I towards II; ``k1, k2`` the contact point K = (P_a + P_b)/2; ``n_cross`` the number of
#: boundary crossings found.  For CONTAINED: B_n = 0, n along the centroid line I → II, K the centroid of
#: the smaller particle; for NO_CONTACT every value is 0.
PairGeometry = namedtuple("PairGeometry", ["status", "overlap_area", "line_width", "n1", "n2", "k1", "k2", "n_cross"])

#: maximal number of boundary crossings kept per pair (convex polygons have at most 2*min(nI, nII))
MAX_CROSSINGS = 64


@njit(cache=True, inline="always")
def _cross(ax, ay, bx, by):
    return ax * by - ay * bx


@njit(cache=True)
def polygon_area(v, n):
    """Shoelace area of the first ``n`` rows of ``v`` (positive if counter-clockwise)."""
    s = 0.0
    for k in range(n):
        k1 = k + 1 if k + 1 < n else 0
        s += v[k, 0] * v[k1, 1] - v[k1, 0] * v[k, 1]
    return 0.5 * s


@njit(cache=True)
def clip_labelled(wv, sI, nI, sII, nII, eps, bufA, labA, bufB, labB, dist, cx=0.0, cy=0.0, rI=-1.0):
    """Sutherland–Hodgman clip of polygon I by the half-planes of polygon II.

    The vertices of I are rows ``sI .. sI+nI-1`` of ``wv``, those of II rows
    ``sII .. sII+nII-1`` (offsets rather than slices: a slice is a new array
    object, reference-counted, at every call).
    Returns ``(m, which)``: the clipped polygon has ``m`` vertices and lives in
    ``bufA/labA`` if ``which == 0`` else in ``bufB/labB``.  ``lab[k]`` is the
    label of the edge from vertex k to vertex k+1.  A point counts as inside a
    half-plane if its signed distance is >= ``-eps``.  A half-plane that holds
    the whole current polygon leaves it untouched (no copy); ``dist`` is scratch.
    With the bounding circle of I (centre ``cx, cy``, radius ``rI`` ≥ 0) a
    half-plane holding the whole circle is skipped after one cross product.
    """
    m = nI
    for k in range(nI):
        bufA[k, 0] = wv[sI + k, 0]
        bufA[k, 1] = wv[sI + k, 1]
        labA[k] = LAB_I
    which = 0
    for e in range(nII):
        e1 = sII + (e + 1 if e + 1 < nII else 0)
        ax = wv[sII + e, 0]
        ay = wv[sII + e, 1]
        dx = wv[e1, 0] - ax
        dy = wv[e1, 1] - ay
        ln = np.sqrt(dx * dx + dy * dy)
        tol = -eps * ln  # distances below are scaled by the edge length
        if rI >= 0.0 and _cross(dx, dy, cx - ax, cy - ay) >= (rI + eps) * ln:
            continue  # the bounding circle of I lies inside this half-plane
        if which == 0:
            src, slab, dst, dlab = bufA, labA, bufB, labB
        else:
            src, slab, dst, dlab = bufB, labB, bufA, labA
        allin = True
        anyin = False
        for k in range(m):
            d = _cross(dx, dy, src[k, 0] - ax, src[k, 1] - ay)
            dist[k] = d
            if d >= tol:
                anyin = True
            else:
                allin = False
        if allin:
            continue
        if not anyin:
            return 0, which
        out = 0
        ds = dist[0]
        for k in range(m):
            k1 = k + 1 if k + 1 < m else 0
            de = dist[k1]
            s_in = ds >= tol
            e_in = de >= tol
            if s_in:
                if e_in:
                    dst[out, 0] = src[k1, 0]
                    dst[out, 1] = src[k1, 1]
                    dlab[out] = slab[k1]
                    out += 1
                else:
                    t = ds / (ds - de)
                    dst[out, 0] = src[k, 0] + t * (src[k1, 0] - src[k, 0])
                    dst[out, 1] = src[k, 1] + t * (src[k1, 1] - src[k, 1])
                    dlab[out] = LAB_II
                    out += 1
            else:
                if e_in:
                    t = ds / (ds - de)
                    dst[out, 0] = src[k, 0] + t * (src[k1, 0] - src[k, 0])
                    dst[out, 1] = src[k, 1] + t * (src[k1, 1] - src[k, 1])
                    dlab[out] = slab[k]
                    out += 1
                    dst[out, 0] = src[k1, 0]
                    dst[out, 1] = src[k1, 1]
                    dlab[out] = slab[k1]
                    out += 1
            ds = de
        m = out
        which = 1 - which
    return m, which


@njit(cache=True)
def _dedupe(buf, lab, m, eps):
    """Merge consecutive vertices closer than ``eps`` (the merged vertex keeps the later label)."""
    if m == 0:
        return 0
    out = 0
    for k in range(m):
        if out > 0:
            dx = buf[k, 0] - buf[out - 1, 0]
            dy = buf[k, 1] - buf[out - 1, 1]
            if dx * dx + dy * dy <= eps * eps:
                lab[out - 1] = lab[k]
                continue
        buf[out, 0] = buf[k, 0]
        buf[out, 1] = buf[k, 1]
        lab[out] = lab[k]
        out += 1
    # wrap-around: last vertex equal to the first
    while out > 1:
        dx = buf[out - 1, 0] - buf[0, 0]
        dy = buf[out - 1, 1] - buf[0, 1]
        if dx * dx + dy * dy <= eps * eps:
            # the first vertex absorbs the last; the edge leaving the pair is the first's
            out -= 1
        else:
            break
    return out


@njit(cache=True)
def _segments_intersect(ax, ay, bx, by, cx, cy, dx, dy, eps):
    """True if segments AB and CD intersect or touch (within ``eps`` length tolerance)."""
    ux = bx - ax
    uy = by - ay
    wx = dx - cx
    wy = dy - cy
    lu = np.sqrt(ux * ux + uy * uy)
    lw = np.sqrt(wx * wx + wy * wy)
    o1 = _cross(ux, uy, cx - ax, cy - ay) / lu
    o2 = _cross(ux, uy, dx - ax, dy - ay) / lu
    o3 = _cross(wx, wy, ax - cx, ay - cy) / lw
    o4 = _cross(wx, wy, bx - cx, by - cy) / lw
    if (o1 > eps and o2 > eps) or (o1 < -eps and o2 < -eps):
        return False
    if (o3 > eps and o4 > eps) or (o3 < -eps and o4 < -eps):
        return False
    if abs(o1) <= eps and abs(o2) <= eps:
        # collinear: overlap of the projections onto AB
        t0 = ((cx - ax) * ux + (cy - ay) * uy) / lu
        t1 = ((dx - ax) * ux + (dy - ay) * uy) / lu
        lo = min(t0, t1)
        hi = max(t0, t1)
        return hi >= -eps and lo <= lu + eps
    return True


@njit(cache=True)
def _point_in_convex(px, py, wv, s0, n, eps):
    """True if (px, py) lies in the convex polygon of rows ``s0 .. s0+n-1`` of ``wv``."""
    for k in range(n):
        k0 = s0 + k
        k1 = s0 + (k + 1 if k + 1 < n else 0)
        ex = wv[k1, 0] - wv[k0, 0]
        ey = wv[k1, 1] - wv[k0, 1]
        if _cross(ex, ey, px - wv[k0, 0], py - wv[k0, 1]) < -eps * np.sqrt(ex * ex + ey * ey):
            return False
    return True


@njit(cache=True, inline="always")
def _edges_near(wv, s0, n, cx, cy, r, eps, sel):
    """Stage (c) for one polygon (rows ``s0 .. s0+n-1`` of ``wv``): the rows of the edges whose
    circle (centre = edge midpoint, radius = half the edge length) meets the circle (cx, cy, r + eps)
    go to ``sel``; returns how many."""
    m = 0
    for k in range(n):
        k0 = s0 + k
        k1 = s0 + (k + 1 if k + 1 < n else 0)
        mx = 0.5 * (wv[k0, 0] + wv[k1, 0])
        my = 0.5 * (wv[k0, 1] + wv[k1, 1])
        hx = 0.5 * (wv[k1, 0] - wv[k0, 0])
        hy = 0.5 * (wv[k1, 1] - wv[k0, 1])
        rr = np.sqrt(hx * hx + hy * hy) + r + eps
        if (mx - cx) ** 2 + (my - cy) ** 2 <= rr * rr:
            sel[m] = k0
            m += 1
    return m


@njit(cache=True)
def _boundaries_may_cross(wv, sI, nI, sII, nII, cIx, cIy, rI, cIIx, cIIy, rII, eps, selI, selII):
    """Stages (c) and (d) of the linked-cell search (thesis Fig. 4.2).

    (c) keep the edges of II whose circle (centre = edge midpoint, radius = half
    the edge length) overlaps the bounding circle of I, and vice versa;
    (d) test the kept edges pairwise for intersection.  Returns True at the
    first intersection found.  Vertices as in :func:`clip_labelled`.
    """
    kI = _edges_near(wv, sI, nI, cIIx, cIIy, rII, eps, selI)
    if kI == 0:
        return False
    kII = _edges_near(wv, sII, nII, cIx, cIy, rI, eps, selII)
    if kII == 0:
        return False
    for a in range(kI):
        i0 = selI[a]
        i1 = i0 + 1 if i0 + 1 < sI + nI else sI
        for b in range(kII):
            j0 = selII[b]
            j1 = j0 + 1 if j0 + 1 < sII + nII else sII
            if _segments_intersect(
                wv[i0, 0], wv[i0, 1], wv[i1, 0], wv[i1, 1], wv[j0, 0], wv[j0, 1], wv[j1, 0], wv[j1, 1], eps
            ):
                return True
    return False


@njit(cache=True, inline="always")
def pair_geometry(
    wv,
    sI,
    nI,
    sII,
    nII,
    cIx,
    cIy,
    rI,
    cIIx,
    cIIy,
    rII,
    areaI,
    areaII,
    area_tol_rel,
    bufA,
    bufB,
    cross,
    dist,
    labA,
    labB,
    selI,
    selII,
    known_contact,
):
    """Contact kinematics of polygons I and II (vertices counter-clockwise, world frame).

    Parameters
    ----------
    wv : (nv, 2) world vertices of all particles; I is rows ``sI .. sI+nI-1``, II rows ``sII .. sII+nII-1``
    cIx, cIy, cIIx, cIIy : centroids; rI, rII : bounding-circle radii
    areaI, areaII : particle areas (for the area tolerance)
    area_tol_rel : a pair is in contact only if A_n > area_tol_rel * min(areaI, areaII)
    bufA, bufB, cross : (cap, 2) float work arrays, cap >= 2 (nI + nII) + 4; dist : (cap,) float
    labA, labB, selI, selII : (cap,) int work arrays
    known_contact : the pair was in contact at the last step: skip the stage (c)/(d) filter, which
        only spares non-touching pairs the clipping (the result is the same either way)

    All buffers are passed in (no array object is created per call: the kernel runs
    for millions of pairs per second, and every view costs reference counting).

    Returns
    -------
    PairGeometry : status (NO_CONTACT, CONTACT or CONTAINED), A_n, B_n, n, K, number of crossings
    """
    eps = 1e-12 * (rI + rII)
    if not known_contact and not _boundaries_may_cross(
        wv, sI, nI, sII, nII, cIx, cIy, rI, cIIx, cIIy, rII, eps, selI, selII
    ):
        # no boundary crossing: disjoint, or one polygon inside the other
        inside = False
        if areaI <= areaII:
            inside = _point_in_convex(wv[sI, 0], wv[sI, 1], wv, sII, nII, eps) and _point_in_convex(
                cIx, cIy, wv, sII, nII, eps
            )
        else:
            inside = _point_in_convex(wv[sII, 0], wv[sII, 1], wv, sI, nI, eps) and _point_in_convex(
                cIIx, cIIy, wv, sI, nI, eps
            )
        if not inside:
            return PairGeometry(NO_CONTACT, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0)
    m, which = clip_labelled(wv, sI, nI, sII, nII, eps, bufA, labA, bufB, labB, dist, cIx, cIy, rI)
    if which == 0:
        buf, lab = bufA, labA
    else:
        buf, lab = bufB, labB
    m = _dedupe(buf, lab, m, eps)
    if m < 3:
        return PairGeometry(NO_CONTACT, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0)
    A = polygon_area(buf, m)
    if not (A > area_tol_rel * min(areaI, areaII)):
        return PairGeometry(NO_CONTACT, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0)
    # crossings: label changes along the overlap polygon
    ncr = 0
    gx = 0.0  # summed chain gradient R(-90)(P_out - P_in)
    gy = 0.0
    nin = 0
    nout = 0
    for k in range(m):
        lin = lab[k - 1] if k > 0 else lab[m - 1]
        lout = lab[k]
        if lin != lout and ncr < MAX_CROSSINGS:
            cross[ncr, 0] = buf[k, 0]
            cross[ncr, 1] = buf[k, 1]
            ncr += 1
            if lout == LAB_I:  # entering II
                gx -= buf[k, 1]
                gy += buf[k, 0]
                nin += 1
            else:  # leaving II
                gx += buf[k, 1]
                gy -= buf[k, 0]
                nout += 1
    if ncr == 0:
        # one polygon inside the other: A_n is locally constant, no force
        dx = cIIx - cIx
        dy = cIIy - cIy
        d = np.sqrt(dx * dx + dy * dy)
        if d > 0.0:
            n1 = dx / d
            n2 = dy / d
        else:
            n1 = 1.0
            n2 = 0.0
        k1 = cIIx if areaII <= areaI else cIx
        k2 = cIIy if areaII <= areaI else cIy
        return PairGeometry(CONTAINED, A, 0.0, n1, n2, k1, k2, ncr)
    # overlap line: the two crossing points farthest apart (exactly P_in, P_out if ncr == 2)
    ia = 0
    ib = 1 if ncr > 1 else 0
    best = -1.0
    for a in range(ncr):
        for b in range(a + 1, ncr):
            dx = cross[b, 0] - cross[a, 0]
            dy = cross[b, 1] - cross[a, 1]
            d2 = dx * dx + dy * dy
            if d2 > best:
                best = d2
                ia = a
                ib = b
    px = cross[ib, 0] - cross[ia, 0]
    py = cross[ib, 1] - cross[ia, 1]
    B = np.sqrt(px * px + py * py)
    k1 = 0.5 * (cross[ia, 0] + cross[ib, 0])
    k2 = 0.5 * (cross[ia, 1] + cross[ib, 1])
    if B > eps:
        n1 = py / B
        n2 = -px / B
        if n1 * gx + n2 * gy < 0.0:
            n1 = -n1
            n2 = -n2
    else:
        # degenerate overlap line: direction of the centroids, zero width
        dx = cIIx - cIx
        dy = cIIy - cIy
        d = np.sqrt(dx * dx + dy * dy)
        n1 = dx / d if d > 0 else 1.0
        n2 = dy / d if d > 0 else 0.0
        B = 0.0
    return PairGeometry(CONTACT, A, B, n1, n2, k1, k2, ncr)


@njit(cache=True, inline="always")
def separation_lower_bound(wv, sI, nI, sII, nII):
    """Largest separation of two convex polygons along an edge normal of either (separating axis
    theorem): a lower bound of their distance, > 0 only if they are disjoint.

    Vertices as in :func:`clip_labelled` (counter-clockwise rows of ``wv``).  Used by the
    buffered pair list to skip pairs that cannot touch before their particles have moved by
    this much (the clipping of stages (c)/(d) then returns no contact anyway).
    """
    best = -np.inf
    for side in range(2):
        s0, n0, s1, n1 = (sI, nI, sII, nII) if side == 0 else (sII, nII, sI, nI)
        for k in range(n0):
            k1 = k + 1 if k + 1 < n0 else 0
            px = wv[s0 + k, 0]
            py = wv[s0 + k, 1]
            ex = wv[s0 + k1, 0] - px
            ey = wv[s0 + k1, 1] - py
            el = np.sqrt(ex * ex + ey * ey)
            if el <= 0.0:
                continue
            nx = ey / el  # outward normal of a counter-clockwise edge
            ny = -ex / el
            m = np.inf
            for j in range(n1):
                d = nx * (wv[s1 + j, 0] - px) + ny * (wv[s1 + j, 1] - py)
                if d < m:
                    m = d
            if m > best:
                best = m
    return best


@njit(cache=True)
def world_vertices(x, vert_start, body_v, world_v):
    """x_k = x + R(φ) X̃_k for every particle."""
    n = x.shape[0]
    for i in range(n):
        c = np.cos(x[i, 2])
        s = np.sin(x[i, 2])
        for k in range(vert_start[i], vert_start[i + 1]):
            X = body_v[k, 0]
            Y = body_v[k, 1]
            world_v[k, 0] = x[i, 0] + c * X - s * Y
            world_v[k, 1] = x[i, 1] + s * X + c * Y


def pair_geometry_py(vI, vII, area_tol_rel=1e-12):
    """Convenience wrapper for tests and tools: returns (status, dict)."""
    from ...geometry.polygon import check_convex_polygon, polygon_area_centroid_inertia

    vI = np.ascontiguousarray(check_convex_polygon(vI), dtype=np.float64)  # counter-clockwise
    vII = np.ascontiguousarray(check_convex_polygon(vII), dtype=np.float64)

    aI, cI, _ = polygon_area_centroid_inertia(vI)
    aII, cII, _ = polygon_area_centroid_inertia(vII)
    rI = float(np.max(np.hypot(*(vI - cI).T)))
    rII = float(np.max(np.hypot(*(vII - cII).T)))
    cap = 2 * (len(vI) + len(vII)) + 8
    f = np.zeros((3, cap, 2))
    i = np.zeros((4, cap), dtype=np.int64)
    wv = np.vstack([vI, vII])
    pg = pair_geometry(
        wv,
        0,
        len(vI),
        len(vI),
        len(vII),
        cI[0],
        cI[1],
        rI,
        cII[0],
        cII[1],
        rII,
        aI,
        aII,
        area_tol_rel,
        f[0],
        f[1],
        f[2],
        np.zeros(cap),
        i[0],
        i[1],
        i[2],
        i[3],
        False,
    )
    return int(pg.status), {
        "A": pg.overlap_area,
        "B": pg.line_width,
        "n": np.array([pg.n1, pg.n2]),
        "K": np.array([pg.k1, pg.k2]),
        "n_cross": int(pg.n_cross),
        "cI": cI,
        "cII": cII,
    }
