"""Which particles of a specimen touch, and along which edge: a geometric fact, not a generator's claim.

Two convex polygons A and B (vertices counter-clockwise) *touch along an edge* when an edge of A and an
edge of B lie on one line with opposite directions and their extents overlap by more than ``tol``.  The
line then separates the two polygons (A lies to the left of its own counter-clockwise edge, B to the left
of its own, i.e. to the right of A's), so such a pair touches without overlapping; the common part of
the two edges is the shared edge whose length is the beam height of the bond network (thesis §5.1.2,
Fig. 5.1).  Pairs with a gap, pairs meeting only at a vertex, and overlapping pairs share no edge.

Used by the generators that build touching particles without a tessellation (hexagon packings); the
Voronoi generator takes its shared edges from the tessellation itself, and the tests compare the two.
Plain NumPy, run once while a specimen is built (candidate pairs from a k-d tree of the bounding
circles, then all edge pairs of each candidate pair at once, in blocks).
"""

from __future__ import annotations

import numpy as np

#: candidate pairs handled at once (memory: about 1 kB per pair for hexagons)
_BLOCK = 50_000


def touching_edges(vertices, tol: float | None = None):
    """Shared edges of the touching pairs among ``vertices`` (list of (n_k, 2) counter-clockwise arrays).

    ``tol`` [length]: the largest distance of an edge from the other's line that still counts as on it,
    and the shortest overlap that counts as an edge (default 1e-9 of the mean bounding diameter).
    Returns ``(pairs (m, 2) int64 with i < j, lengths (m,), edges (m, 2, 2))`` sorted by pair; a pair
    whose polygons share two edges (impossible for convex polygons that do not overlap) counts once.
    """
    from scipy.spatial import cKDTree

    n = len(vertices)
    empty = (np.zeros((0, 2), np.int64), np.zeros(0), np.zeros((0, 2, 2)))
    if n < 2:
        return empty
    nv = np.array([len(v) for v in vertices])
    m = int(nv.max())
    P = np.full((n, m, 2), np.nan)
    for i, v in enumerate(vertices):
        P[i, : len(v)] = v
    cen = np.array([np.asarray(v).mean(axis=0) for v in vertices])
    rad = np.array([np.max(np.hypot(*(np.asarray(v) - c).T)) for v, c in zip(vertices, cen)])
    if tol is None:
        tol = 1e-9 * 2.0 * float(rad.mean())
    # edge k of polygon i: P[i, k] -> P[i, (k + 1) mod n_i]
    nxt = (np.arange(m)[None, :] + 1) % nv[:, None]
    Q = P[np.arange(n)[:, None], nxt]
    valid = np.arange(m)[None, :] < nv[:, None]
    cand = cKDTree(cen).query_pairs(2.0 * float(rad.max()) + tol, output_type="ndarray")
    if len(cand):
        cand = cand[np.hypot(*(cen[cand[:, 0]] - cen[cand[:, 1]]).T) <= rad[cand[:, 0]] + rad[cand[:, 1]] + tol]
    out_p, out_l, out_e = [], [], []
    for s in range(0, len(cand), _BLOCK):
        c = np.sort(cand[s : s + _BLOCK], axis=1)
        a0, a1 = P[c[:, 0]][:, :, None], Q[c[:, 0]][:, :, None]  # (p, m, 1, 2): edges of A
        b0, b1 = P[c[:, 1]][:, None], Q[c[:, 1]][:, None]  # (p, 1, m, 2): edges of B
        da = a1 - a0
        la = np.hypot(da[..., 0], da[..., 1])
        ua = da / np.where(la > 0, la, 1.0)[..., None]
        nrm = np.stack([-ua[..., 1], ua[..., 0]], axis=-1)
        # distances of B's edge ends from A's edge line, and their positions along it
        off0 = np.sum((b0 - a0) * nrm, axis=-1)
        off1 = np.sum((b1 - a0) * nrm, axis=-1)
        t0 = np.sum((b0 - a0) * ua, axis=-1)
        t1 = np.sum((b1 - a0) * ua, axis=-1)
        lo = np.maximum(0.0, np.minimum(t0, t1))
        hi = np.minimum(la, np.maximum(t0, t1))
        with np.errstate(invalid="ignore"):
            ok = (
                valid[c[:, 0]][:, :, None]
                & valid[c[:, 1]][:, None, :]
                & (np.abs(off0) <= tol)
                & (np.abs(off1) <= tol)
                & (t1 < t0)  # opposite directions
                & (hi - lo > tol)
            )
        ip, ka, kb = np.nonzero(ok)
        ip, first = np.unique(ip, return_index=True)
        ka, kb = ka[first], kb[first]
        if not len(ip):
            continue
        A0, U = a0[ip, ka, 0], ua[ip, ka, 0]
        l0, l1 = lo[ip, ka, kb], hi[ip, ka, kb]
        out_p.append(c[ip])
        out_l.append(l1 - l0)
        out_e.append(np.stack([A0 + l0[:, None] * U, A0 + l1[:, None] * U], axis=1))
    if not out_p:
        return empty
    pairs, lengths, edges = np.concatenate(out_p), np.concatenate(out_l), np.concatenate(out_e)
    order = np.lexsort((pairs[:, 1], pairs[:, 0]))
    return pairs[order].astype(np.int64), lengths[order], edges[order]
