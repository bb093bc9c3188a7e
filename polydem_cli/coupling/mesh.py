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
its displacement is interpolated linearly along that edge.  The mesh work itself (initial mesh, neighbours,
hanging nodes, refinement) is compiled array code in :mod:`.meshkern`; tests/test_coupling.py checks it against
the mesh's geometry (coverage, 2:1 balance, the hanging nodes on their edges) and hand-written references.
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


def domain_set(lat):
    """The domain (the lattice triangles whose three nodes exist, a down triangle's anchor (i, j) too) as a set-like view of its array index
    (:class:`.meshkern.DomainView`)."""
    from .meshkern import DomainView

    return DomainView(lat)


def triangulated(lat):
    """The lattice without the nodes and members that belong to no lattice triangle of the domain (a node at
    a corner of the jagged edge held by a single bar): the lattice the coarse mesh can represent.  Array code
    over the lattice's index (:func:`.meshkern.lattice_index`, the domain of :func:`domain_set`)."""
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
