"""The coarse mesh of the adaptive coupling: triangles whose corners are lattice nodes and whose edges run
along lattice directions ("super-triangles"), refined by splitting into four (Sorg 2014).

Lattice (axial) coordinates: node (i, j) sits at ``((i + j/2) a, j √3/2 a)``.  A super-triangle of side s
(a power of two) is ``(i, j, o, s)``: up (o = 0) with corners (i, j), (i+s, j), (i, j+s); down (o = 1) with
corners (i+s, j), (i+s, j+s), (i, j+s).  Side 1 gives the lattice's own triangles.  Splitting gives four
of side s/2 (three of the same orientation at the corners, one of the other in the middle), whose corners
are lattice nodes again — new nodes always sit at particle centres.

The mesh covers the *domain*: the lattice triangles whose three nodes exist (the plate less its hole).  An
element is a super-triangle all of whose lattice triangles are in the domain; the initial mesh takes the
largest such ones of a tiling by side ``s0`` and splits the others down to the lattice triangles along the
boundary and the hole.  A node of a finer element that lies on the edge of a coarser neighbour is *hanging*:
its displacement is interpolated linearly along that edge (:func:`constraints`).
"""

from __future__ import annotations

import numpy as np

from .lattice import Lattice


def corners(e) -> tuple:
    """The three corner nodes (lattice coordinates) of super-triangle ``e = (i, j, o, s)``."""
    i, j, o, s = e
    if o == 0:
        return ((i, j), (i + s, j), (i, j + s))
    return ((i + s, j), (i + s, j + s), (i, j + s))


def children(e) -> list:
    """The four super-triangles of side s/2 that split ``e``."""
    i, j, o, s = e
    h = s // 2
    if o == 0:
        return [(i, j, 0, h), (i + h, j, 0, h), (i, j + h, 0, h), (i, j, 1, h)]
    return [(i + h, j, 1, h), (i + h, j + h, 1, h), (i, j + h, 1, h), (i + h, j + h, 0, h)]


def lattice_triangles(e) -> list:
    """The lattice triangles (side 1) that make up super-triangle ``e``."""
    i, j, o, s = e
    out = []
    for p in range(s):
        for q in range(s):
            if o == 0:
                if p + q <= s - 1:
                    out.append((i + p, j + q, 0, 1))
                if p + q <= s - 2:
                    out.append((i + p, j + q, 1, 1))
            else:
                if p + q >= s:
                    out.append((i + p, j + q, 0, 1))
                if p + q >= s - 1:
                    out.append((i + p, j + q, 1, 1))
    return out


def triangle_edges(t) -> list:
    """The three edges (pairs of lattice nodes, sorted) of a lattice triangle."""
    a, b, c = corners(t)
    return [tuple(sorted(pq)) for pq in ((a, b), (b, c), (c, a))]


def domain_triangles(nodes: set) -> set:
    """Lattice triangles of the domain: those whose three nodes exist."""
    tri = set()
    for i, j in nodes:
        for o in (0, 1):
            t = (i, j, o, 1)
            if all(c in nodes for c in corners(t)):
                tri.add(t)
    return tri


def domain_set(lat):
    """:func:`domain_triangles` of the lattice's nodes as a set-like view of its array index
    (:class:`.meshkern.DomainView`)."""
    from .meshkern import DomainView

    return DomainView(lat)


def initial_mesh(domain: set, s0: int) -> list:
    """Elements covering the domain: the super-triangles of a tiling of side ``s0`` (a power of two) that lie
    wholly in the domain, the others split recursively down to the lattice triangles of the domain."""
    if s0 < 1 or s0 & (s0 - 1):
        raise ValueError("the coarsest element side must be a power of two")
    ii = [t[0] for t in domain]
    jj = [t[1] for t in domain]
    i_lo, i_hi = min(ii) - s0, max(ii) + s0
    j_lo, j_hi = min(jj) - s0, max(jj) + s0
    out = []

    def place(e):
        lt = lattice_triangles(e)
        inside = sum(t in domain for t in lt)
        if inside == 0:
            return
        if inside == len(lt):
            out.append(e)
            return
        for c in children(e):
            place(c)

    for i in range(i_lo - i_lo % s0, i_hi + 1, s0):
        for j in range(j_lo - j_lo % s0, j_hi + 1, s0):
            place((i, j, 0, s0))
            place((i, j, 1, s0))
    return out


def edge_nodes(p, q) -> list:
    """The lattice nodes strictly between nodes p and q (along a lattice direction), with their fraction t
    from p."""
    di, dj = q[0] - p[0], q[1] - p[1]
    n = max(abs(di), abs(dj))
    return [((p[0] + di * k // n, p[1] + dj * k // n), k / n) for k in range(1, n)]


def constraints(elements: list) -> dict:
    """Hanging nodes: {node: (p, q, t)} — the node lies strictly inside the edge p–q of an element (which
    does not have it as a corner), so u = (1 − t) u_p + t u_q."""
    active = {c for e in elements for c in corners(e)}
    hang = {}
    for e in elements:
        cs = corners(e)
        for p, q in ((cs[0], cs[1]), (cs[1], cs[2]), (cs[2], cs[0])):
            if e[3] == 1:
                continue
            for nd, t in edge_nodes(p, q):
                if nd in active and nd not in hang:
                    hang[nd] = (p, q, t)
    return hang


def neighbours(elements: list, boundary: bool = False):
    """Per element, the indices of the elements it shares an edge piece with; with ``boundary`` also whether
    an edge piece of it lies on the domain's boundary (shared with no element).  Cost: the elements'
    perimeters, not their areas (vectorised: every unit segment of every element's edges as one integer key;
    a segment lies on the edges of at most two elements, which are then neighbours)."""
    els = np.array(elements, np.int64).reshape(-1, 4)
    ne = len(els)
    if ne == 0:
        return ([], []) if boundary else []
    lo = els[:, :2].min(axis=0) - 1
    span = int((els[:, :2].max(axis=0) - lo).max() + els[:, 3].max() + 2)
    ks, keys = [], []
    for s_ in np.unique(els[:, 3]):
        idx = np.flatnonzero(els[:, 3] == s_)
        i, j, o = els[idx, 0] - lo[0], els[idx, 1] - lo[1], els[idx, 2]
        up = o == 0
        # corners: up (i, j), (i+s, j), (i, j+s); down (i+s, j), (i+s, j+s), (i, j+s)
        ci = np.stack([np.where(up, i, i + s_), np.where(up, i + s_, i + s_), i], axis=1)
        cj = np.stack([j, np.where(up, j, j + s_), j + s_], axis=1)
        k = np.arange(s_)
        for a, b in ((0, 1), (1, 2), (2, 0)):
            di, dj = (ci[:, b] - ci[:, a]) // s_, (cj[:, b] - cj[:, a]) // s_
            pi = ci[:, a][:, None] + di[:, None] * k[None, :]
            pj = cj[:, a][:, None] + dj[:, None] * k[None, :]
            ka = pi * span + pj
            kb = (pi + di[:, None]) * span + (pj + dj[:, None])
            keys.append((np.minimum(ka, kb) * (span * span) + np.maximum(ka, kb)).ravel())
            ks.append(np.repeat(idx, s_))
    keys = np.concatenate(keys)
    ks = np.concatenate(ks)
    order = np.argsort(keys, kind="stable")
    keys, ks = keys[order], ks[order]
    same = keys[1:] == keys[:-1]
    a, b = ks[:-1][same], ks[1:][same]
    pairs = np.unique(np.concatenate([np.stack([a, b], 1), np.stack([b, a], 1)]), axis=0)
    pairs = pairs[pairs[:, 0] != pairs[:, 1]]
    starts = np.searchsorted(pairs[:, 0], np.arange(ne + 1))
    out = [pairs[starts[e] : starts[e + 1], 1].tolist() for e in range(ne)]
    if not boundary:
        return out
    shared = np.zeros(len(keys), bool)
    shared[1:] |= same
    shared[:-1] |= same
    on_b = np.zeros(ne, bool)
    on_b[ks[~shared]] = True
    return out, on_b.tolist()


def member_triangles(a, b) -> list:
    """The two lattice triangles (side 1) that have the segment between neighbouring nodes a and b as an edge
    (whether both lie in the domain is for the caller to check)."""
    if b < a:
        a, b = b, a
    i, j = a
    d = (b[0] - i, b[1] - j)
    if d == (1, 0):
        return [(i, j, 0, 1), (i, j - 1, 1, 1)]
    if d == (0, 1):
        return [(i, j, 0, 1), (i - 1, j, 1, 1)]
    if d == (1, -1):  # the 120° direction, seen from its end with the smaller coordinates
        return [(i, j - 1, 0, 1), (i, j - 1, 1, 1)]
    raise ValueError(f"nodes {a} and {b} are not neighbours")


class Locator:
    """Which element of a mesh contains a lattice triangle: the super-triangles of a mesh made by
    :func:`initial_mesh` and :func:`children` sit on tilings of their side, so the candidates are one per side."""

    def __init__(self, elements: list):
        self.index = {e: k for k, e in enumerate(elements)}
        self.sides = sorted({e[3] for e in elements})

    def element_of(self, t):
        i, j, o, _ = t
        for s in self.sides:
            I, J = i - i % s, j - j % s
            p, q = i - I, j - J
            up = (p + q <= s - 1) if o == 0 else (p + q <= s - 2)
            k = self.index.get((I, J, 0 if up else 1, s))
            if k is not None:
                return k
        return None


def triangulated(lat):
    """The lattice without the nodes and members that belong to no lattice triangle of the domain (a node at
    a corner of the jagged edge held by a single bar): the lattice the coarse mesh can represent.  Array code
    over the lattice's index (:func:`.meshkern.lattice_index`, the domain of :func:`domain_triangles`)."""
    from .meshkern import lattice_index, triangle_members

    ix = lattice_index(lat)
    t = ix.tij
    up = t[:, 2] == 0
    ci = np.stack([np.where(up, t[:, 0], t[:, 0] + 1), t[:, 0] + 1, t[:, 0]], 1)  # corners (corners())
    cj = np.stack([t[:, 1], np.where(up, t[:, 1], t[:, 1] + 1), t[:, 1] + 1], 1)
    keep = np.zeros(lat.n_nodes, bool)
    keep[ix.gnode[ci - ix.off[0], cj - ix.off[1]].ravel()] = True
    keep_nodes = np.flatnonzero(keep)
    tm = triangle_members(ix).ravel()
    keep = np.zeros(lat.n_members, bool)
    keep[tm[tm >= 0]] = True
    keep_m = np.flatnonzero(keep)
    new = -np.ones(lat.n_nodes, np.int64)
    new[keep_nodes] = np.arange(len(keep_nodes))
    mem = new[lat.members[keep_m]].reshape(-1, 2)
    return Lattice(lat.x[keep_nodes], mem, lat.n[keep_m], lat.L[keep_m], lat.ij[keep_nodes], lat.a)
