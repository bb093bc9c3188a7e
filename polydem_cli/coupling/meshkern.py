"""Compiled mesh work of the adaptive coupling (Sorg 2014): the lattice's bookkeeping as arrays built once per
lattice, and per mesh the element of every lattice triangle, the neighbours, the hanging nodes and the element
matrices of levels 1 and 2, all as array code (Numba).  :mod:`.adaptive` builds its models from these; the
definitions (what a neighbour, a hanging node, a member's weight, a level-2 matrix is) are those of
:mod:`.mesh`, :mod:`.adaptive` and :mod:`.elements`, which say why.

Arrays of a lattice (:class:`LatticeIndex`), in lattice (axial) coordinates shifted by ``off`` so that every
index is ≥ 0 with one spare row and column on each side:

* ``gnode[i, j]`` — the node at (i, j) or −1;
* ``tgrid[i, j, o]`` — the domain's lattice triangle (i, j, o, 1) or −1: its three nodes exist, and for a down
  triangle its anchor node (i, j) too (the domain :func:`.mesh.triangulated` keeps);
* ``mgrid[i, j, d]`` — the member from node (i, j) in direction d (0: +e_i, 1: +e_j, 2: −e_i + e_j) or −1;
* ``count[m]`` — the domain triangles having member m as an edge (1 on the boundary, 2 inside);
* ``mtri[m]`` — those triangles (−1 where absent).

A mesh is an (E, 4) int64 array of super-triangles (i, j, o, s) (:mod:`.mesh`).  Costs per mesh: the element of
every lattice triangle is painted once (the mesh's area in lattice triangles); neighbours and hanging nodes cost
the elements' perimeters; a level-2 element its members.
"""

from __future__ import annotations

from collections import namedtuple
from dataclasses import dataclass

import numpy as np
from numba import njit, prange

from .elements import level1_stiffness

#: unit steps of the three member directions in lattice coordinates (0°, 60°, 120°)
DIRS = np.array([[1, 0], [0, 1], [-1, 1]], np.int64)


@dataclass
class LatticeIndex:
    off: np.ndarray  # (2,) lattice coordinates of grid index (0, 0)
    gnode: np.ndarray  # (NI, NJ)
    tgrid: np.ndarray  # (NI, NJ, 2)
    mgrid: np.ndarray  # (NI, NJ, 3)
    count: np.ndarray  # (m,) float
    mtri: np.ndarray  # (m, 2)
    tij: np.ndarray  # (ntri, 3): i, j, o of every domain triangle (lattice coordinates)

    @property
    def n_triangles(self) -> int:
        return int(self.tij.shape[0])


def lattice_index(lat) -> LatticeIndex:
    """The arrays of the module docstring for lattice ``lat`` (:class:`.lattice.Lattice`); its domain is that of
    :func:`.mesh.domain_set`."""
    ij = np.asarray(lat.ij, np.int64)
    off = ij.min(axis=0) - 1
    shape = tuple(int(v) for v in ij.max(axis=0) - off + 2)
    gnode = -np.ones(shape, np.int64)
    gi, gj = ij[:, 0] - off[0], ij[:, 1] - off[1]
    gnode[gi, gj] = np.arange(len(ij))
    # triangles: up (i, j), (i+1, j), (i, j+1); down (i+1, j), (i+1, j+1), (i, j+1)
    a = gnode[:-1, :-1]
    b = gnode[1:, :-1]
    c = gnode[:-1, 1:]
    d = gnode[1:, 1:]
    up = (a >= 0) & (b >= 0) & (c >= 0)
    dn = (
        (a >= 0) & (b >= 0) & (d >= 0) & (c >= 0)
    )  # and its anchor (i, j), as the first, Python form of the domain had it
    tgrid = -np.ones(shape + (2,), np.int64)
    ti, tj, to = np.nonzero(np.stack([up, dn], axis=2))  # in the order of the tuples (i, j, o, 1)
    tgrid[ti, tj, to] = np.arange(len(ti))
    tij = np.stack([ti + off[0], tj + off[1], to], 1).astype(np.int64)
    mgrid = -np.ones(shape + (3,), np.int64)
    mem = np.asarray(lat.members, np.int64)
    dd = ij[mem[:, 1]] - ij[mem[:, 0]]
    start = mem[:, 0].copy()
    for k, (si, sj) in enumerate(DIRS):
        fwd = (dd[:, 0] == si) & (dd[:, 1] == sj)
        bwd = (dd[:, 0] == -si) & (dd[:, 1] == -sj)
        start[bwd] = mem[bwd, 1]
        sel = fwd | bwd
        mgrid[ij[start[sel], 0] - off[0], ij[start[sel], 1] - off[1], k] = np.flatnonzero(sel)
    count, mtri = _member_triangles(tij, off, mgrid, len(mem))
    ix = LatticeIndex(off, gnode, tgrid, mgrid, count, mtri, tij)
    bad = np.flatnonzero((triangle_members(ix) < 0).any(axis=1))
    if len(bad):
        i, j, o = (int(v) for v in tij[bad[0]])
        raise ValueError(
            f"the lattice lacks a member of its triangle ({i}, {j}, {o}) (and {len(bad) - 1} more): an adaptive mesh "
            "needs every member of a triangle whose nodes exist (coupling/mesh.py triangulated)"
        )
    return ix


def index_of(lat) -> LatticeIndex:
    """:func:`lattice_index` of ``lat``, built once per lattice (kept on it)."""
    ix = lat.__dict__.get("_index")
    if ix is None:
        ix = lattice_index(lat)
        lat.__dict__["_index"] = ix
    return ix


def node_of(ix: LatticeIndex, nd) -> int:
    """The index of lattice node ``nd`` = (i, j), or −1 if the lattice has none there."""
    gi, gj = int(nd[0]) - int(ix.off[0]), int(nd[1]) - int(ix.off[1])
    if 0 <= gi < ix.gnode.shape[0] and 0 <= gj < ix.gnode.shape[1]:
        return int(ix.gnode[gi, gj])
    return -1


class DomainView:
    """The lattice's domain triangles (:func:`.mesh.domain_set`) as a read-only set of tuples (i, j, o, 1),
    answered from the array index: no tuple per triangle is kept (a plate of 10⁷ particles has 2·10⁷)."""

    def __init__(self, lat):
        self.ix = index_of(lat)

    def __len__(self) -> int:
        return self.ix.n_triangles

    def __iter__(self):
        for i, j, o in self.ix.tij.tolist():
            yield (i, j, o, 1)

    def __contains__(self, t) -> bool:
        i, j, o, s = t
        if s != 1 or o not in (0, 1):
            return False
        gi, gj = int(i) - int(self.ix.off[0]), int(j) - int(self.ix.off[1])
        g = self.ix.tgrid
        return 0 <= gi < g.shape[0] and 0 <= gj < g.shape[1] and g[gi, gj, o] >= 0


@njit(cache=True)
def _tri_members(i, j, o, off, mgrid, out):
    """The three members (edges) of lattice triangle (i, j, o) into ``out`` (−1 where absent)."""
    gi, gj = i - off[0], j - off[1]
    if o == 0:  # (i, j)–(i+1, j), (i+1, j)–(i, j+1), (i, j+1)–(i, j)
        out[0] = mgrid[gi, gj, 0]
        out[1] = mgrid[gi + 1, gj, 2]
        out[2] = mgrid[gi, gj, 1]
    else:  # (i+1, j)–(i+1, j+1), (i+1, j+1)–(i, j+1), (i, j+1)–(i+1, j)
        out[0] = mgrid[gi + 1, gj, 1]
        out[1] = mgrid[gi, gj + 1, 0]
        out[2] = mgrid[gi + 1, gj, 2]


def triangle_members(ix) -> np.ndarray:
    """(ntri, 3): the members (edges) of every domain triangle (−1 where the lattice lacks one)."""
    return _all_tri_members(ix.tij, ix.off, ix.mgrid)


@njit(cache=True)
def _all_tri_members(tij, off, mgrid):
    out = np.empty((tij.shape[0], 3), np.int64)
    for t in range(tij.shape[0]):
        _tri_members(tij[t, 0], tij[t, 1], tij[t, 2], off, mgrid, out[t])
    return out


@njit(cache=True)
def _member_triangles(tij, off, mgrid, nm):
    count = np.zeros(nm)
    mtri = -np.ones((nm, 2), np.int64)
    ms = np.empty(3, np.int64)
    for t in range(tij.shape[0]):
        _tri_members(tij[t, 0], tij[t, 1], tij[t, 2], off, mgrid, ms)
        for q in range(3):
            m = ms[q]
            if m >= 0:
                mtri[m, int(count[m])] = t
                count[m] += 1.0
    return count, mtri


@njit(cache=True)
def super_triangles(i, j, o, s, off, tgrid, out):
    """The s² lattice triangles of super-triangle (i, j, o, s) into ``out`` (length ≥ s²), in the order of
    :func:`.mesh.lattice_triangles`: each one's index in the domain, or −1 outside it; returns how many are in it."""
    n = 0
    k = 0
    for p in range(s):
        for q in range(s):
            for oo in range(2):
                if o == 0:
                    inside = p + q <= s - 1 if oo == 0 else p + q <= s - 2
                else:
                    inside = p + q >= s if oo == 0 else p + q >= s - 1
                if not inside:
                    continue
                gi, gj = i + p - off[0], j + q - off[1]
                t = -1
                if 0 <= gi < tgrid.shape[0] and 0 <= gj < tgrid.shape[1]:
                    t = tgrid[gi, gj, oo]
                out[k] = t
                k += 1
                if t >= 0:
                    n += 1
    return n


@njit(cache=True)
def element_triangles(e, off, tgrid, out):
    """The domain triangles of element e = (i, j, o, s) into ``out`` (:func:`super_triangles`); returns s², or −1
    if one of them is not in the domain."""
    n = super_triangles(e[0], e[1], e[2], e[3], off, tgrid, out)
    return n if n == e[3] * e[3] else -1


@njit(cache=True)
def paint(els, off, tgrid, ntri):
    """The element of every domain triangle (−1: none); raises if an element leaves the domain or two overlap."""
    te = -np.ones(ntri, np.int64)
    smax = 1
    for k in range(els.shape[0]):
        smax = max(smax, els[k, 3])
    buf = np.empty(smax * smax, np.int64)
    for k in range(els.shape[0]):
        n = element_triangles(els[k], off, tgrid, buf)
        if n < 0:
            raise ValueError("an element of the mesh leaves the domain")
        for q in range(n):
            if te[buf[q]] >= 0:
                raise ValueError("two elements of the mesh overlap")
            te[buf[q]] = k
    return te


@njit(cache=True)
def _corner(e, c):
    i, j, o, s = e[0], e[1], e[2], e[3]
    if o == 0:
        if c == 0:
            return i, j
        if c == 1:
            return i + s, j
        return i, j + s
    if c == 0:
        return i + s, j
    if c == 1:
        return i + s, j + s
    return i, j + s


@njit(cache=True)
def _seg_tris(ai, aj, bi, bj, off, tgrid):
    """The two lattice triangles having the unit segment (a, b) as an edge (``member_triangles`` of tests/coupling_reference.py);
    −1 where not in the domain."""
    if (bi, bj) < (ai, aj):
        ai, aj, bi, bj = bi, bj, ai, aj
    di, dj = bi - ai, bj - aj
    if di == 1 and dj == 0:
        t1 = (ai, aj, 0)
        t2 = (ai, aj - 1, 1)
    elif di == 0 and dj == 1:
        t1 = (ai, aj, 0)
        t2 = (ai - 1, aj, 1)
    else:  # (1, -1)
        t1 = (ai, aj - 1, 0)
        t2 = (ai, aj - 1, 1)
    r1 = -1
    r2 = -1
    gi, gj = t1[0] - off[0], t1[1] - off[1]
    if 0 <= gi < tgrid.shape[0] and 0 <= gj < tgrid.shape[1]:
        r1 = tgrid[gi, gj, t1[2]]
    gi, gj = t2[0] - off[0], t2[1] - off[1]
    if 0 <= gi < tgrid.shape[0] and 0 <= gj < tgrid.shape[1]:
        r2 = tgrid[gi, gj, t2[2]]
    return r1, r2


@njit(cache=True)
def _isort(a, lo, hi):
    """Sort ``a[lo:hi]`` in place (insertion: a few entries, no allocation)."""
    for q in range(lo + 1, hi):
        v = a[q]
        r = q - 1
        while r >= lo and a[r] > v:
            a[r + 1] = a[r]
            r -= 1
        a[r + 1] = v


@njit(cache=True)
def _isort2(a, b, lo, hi):
    """:func:`_isort` of ``a[lo:hi]``, ``b[lo:hi]`` permuted alongside."""
    for q in range(lo + 1, hi):
        v = a[q]
        w = b[q]
        r = q - 1
        while r >= lo and a[r] > v:
            a[r + 1] = a[r]
            b[r + 1] = b[r]
            r -= 1
        a[r + 1] = v
        b[r + 1] = w


@njit(cache=True)
def neighbours(els, off, tgrid, te):
    """Per element the elements it shares an edge piece with (CSR: ``idx[start[k]:start[k+1]]``, ascending) and
    whether an edge piece of it lies on the domain's boundary (``neighbours`` of tests/coupling_reference.py)."""
    ne = els.shape[0]
    cnt = np.zeros(ne + 1, np.int64)
    on_b = np.zeros(ne, np.bool_)
    total = 0
    for k in range(ne):
        total += 3 * els[k, 3]
    idx = np.empty(total, np.int64)
    pos = 0
    for k in range(ne):
        e = els[k]
        s = e[3]
        p0 = pos
        for c in range(3):
            ai, aj = _corner(e, c)
            bi, bj = _corner(e, (c + 1) % 3)
            di, dj = (bi - ai) // s, (bj - aj) // s
            for st in range(s):
                pi, pj = ai + di * st, aj + dj * st
                t1, t2 = _seg_tris(pi, pj, pi + di, pj + dj, off, tgrid)
                e1 = te[t1] if t1 >= 0 else -1
                e2 = te[t2] if t2 >= 0 else -1
                other = e2 if e1 == k else e1
                if other < 0:
                    on_b[k] = True
                elif other != k:
                    idx[pos] = other
                    pos += 1
        _isort(idx, p0, pos)
        n = 0
        for q in range(p0, pos):
            if q == p0 or idx[q] != idx[q - 1]:
                idx[p0 + n] = idx[q]
                n += 1
        pos = p0 + n
        cnt[k + 1] = pos
    return cnt, idx[:pos].copy(), on_b


@njit(cache=True)
def off_elements(kmem, k_ref, mtri, te, ne):
    """Elements holding a member whose stiffness is not ``k_ref``."""
    off = np.zeros(ne, np.bool_)
    for m in range(kmem.shape[0]):
        if kmem[m] != k_ref:
            for q in range(2):
                t = mtri[m, q]
                if t >= 0 and te[t] >= 0:
                    off[te[t]] = True
    return off


@njit(cache=True)
def levels_of(els, start, idx, on_b, off):
    """Level of every element (:mod:`.adaptive`): 3 a lattice triangle; 2 on the boundary, holding a member off
    the reference stiffness or next to a finer element; else 1."""
    ne = els.shape[0]
    lv = np.empty(ne, np.int64)
    for k in range(ne):
        s = els[k, 3]
        if s == 1:
            lv[k] = 3
            continue
        two = on_b[k] or off[k]
        if not two:
            for q in range(start[k], start[k + 1]):
                if els[idx[q], 3] < s:
                    two = True
                    break
        lv[k] = 2 if two else 1
    return lv


@njit(cache=True)
def hanging(els, off, gnode, n_nodes):
    """Hanging nodes (``constraints`` of tests/coupling_reference.py): per lattice node its edge's ends p, q (node indices) and the
    fraction t from p (−1, −1, 0 where it does not hang); ``active``: corner nodes of the elements."""
    active = np.zeros(n_nodes, np.bool_)
    for k in range(els.shape[0]):
        for c in range(3):
            ci, cj = _corner(els[k], c)
            active[gnode[ci - off[0], cj - off[1]]] = True
    hp = -np.ones(n_nodes, np.int64)
    hq = -np.ones(n_nodes, np.int64)
    ht = np.zeros(n_nodes)
    for k in range(els.shape[0]):
        e = els[k]
        s = e[3]
        if s == 1:
            continue
        for c in range(3):
            ai, aj = _corner(e, c)
            bi, bj = _corner(e, (c + 1) % 3)
            di, dj = (bi - ai) // s, (bj - aj) // s
            pa = gnode[ai - off[0], aj - off[1]]
            pb = gnode[bi - off[0], bj - off[1]]
            for st in range(1, s):
                nd = gnode[ai + di * st - off[0], aj + dj * st - off[1]]
                if active[nd] and hp[nd] < 0:
                    hp[nd] = pa
                    hq[nd] = pb
                    ht[nd] = st / s
    return active, hp, hq, ht


def masters(els, ix: LatticeIndex, n_nodes: int) -> int:
    """The master nodes of the mesh ``els`` on a lattice of ``n_nodes`` nodes (its elements' corners that do not
    hang): its DOFs before the supports, halved."""
    active, hp, _, _ = hanging(np.ascontiguousarray(els, np.int64), ix.off, ix.gnode, n_nodes)
    return int(np.count_nonzero(active & (hp < 0)))


@njit(cache=True)
def master_map(act, master_of, hp, hq, ht):
    """T of :class:`.adaptive.Model` as CSR arrays (indptr, indices, data) over node rows (the active nodes
    ``act``, in order) and master columns: a master node is its own column; a hanging node follows its edge's
    ends (``hp``, ``hq`` at fraction ``ht`` from ``hp``), which may hang themselves — substituted until only
    masters remain.  The weights are products and sums of dyadic fractions: exact, whatever the order."""
    na = act.shape[0]
    indptr = np.zeros(na + 1, np.int64)
    cap = 4 * na + 16
    indices = np.empty(cap, np.int64)
    data = np.empty(cap)
    stack_n = np.empty(64, np.int64)
    stack_w = np.empty(64)
    p = 0
    for r in range(na):
        start = p
        top = 0
        stack_n[0] = act[r]
        stack_w[0] = 1.0
        top = 1
        while top > 0:
            top -= 1
            n = stack_n[top]
            w = stack_w[top]
            if master_of[n] >= 0:
                c = master_of[n]
                found = False
                for q in range(start, p):
                    if indices[q] == c:
                        data[q] += w
                        found = True
                        break
                if not found:
                    if p == cap:
                        cap *= 2
                        ni = np.empty(cap, np.int64)
                        nd = np.empty(cap)
                        ni[:p] = indices[:p]
                        nd[:p] = data[:p]
                        indices, data = ni, nd
                    indices[p] = c
                    data[p] = w
                    p += 1
            else:
                if top + 2 > stack_n.shape[0]:
                    raise ValueError("hanging-node chain too deep")
                stack_n[top] = hp[n]
                stack_w[top] = w * (1.0 - ht[n])
                stack_n[top + 1] = hq[n]
                stack_w[top + 1] = w * ht[n]
                top += 2
        # ascending columns; weights that cancel to 0 dropped (as the sparse substitution did)
        _isort2(indices, data, start, p)
        q = start
        for t in range(start, p):
            if data[t] != 0.0:
                indices[q] = indices[t]
                data[q] = data[t]
                q += 1
        p = q
        indptr[r + 1] = p
    return indptr, indices[:p].copy(), data[:p].copy()


@njit(cache=True)
def dof_map(indptr, indices, data):
    """A node-to-node map's CSR arrays as DOFs: node row r gives rows 2r (x) and 2r + 1 (y), column c columns 2c
    and 2c + 1, the same weights."""
    nr = indptr.shape[0] - 1
    out_ptr = np.zeros(2 * nr + 1, np.int64)
    out_idx = np.empty(2 * indices.shape[0], np.int64)
    out_val = np.empty(2 * indices.shape[0])
    p = 0
    for r in range(nr):
        for comp in range(2):
            for q in range(indptr[r], indptr[r + 1]):
                out_idx[p] = 2 * indices[q] + comp
                out_val[p] = data[q]
                p += 1
            out_ptr[2 * r + comp + 1] = p
    return out_ptr, out_idx, out_val


@njit(cache=True)
def master_matrix(corner_dofs, Ke, t_ptr, t_idx, t_val, n):
    """The master system's matrix Tᵀ Ka T as sorted CSR arrays (indptr, indices, data) from the element matrices
    ``Ke`` on their active DOFs ``corner_dofs`` and T's CSR arrays (DOF rows; ``n`` master DOFs).  An entry
    wherever an element couples two master DOFs, kept even if its value sums to 0 (a later change of the
    element must find it: :func:`.factor.add_dense`); contributions summed in element order."""
    ne = corner_dofs.shape[0]
    cnt = np.zeros(n + 1, np.int64)  # triplets per row
    for e in range(ne):
        nb = 0  # the element's terms per row it touches
        for b in range(6):
            rb = corner_dofs[e, b]
            nb += t_ptr[rb + 1] - t_ptr[rb]
        for a in range(6):
            ra = corner_dofs[e, a]
            for ia in range(t_ptr[ra], t_ptr[ra + 1]):
                cnt[t_idx[ia] + 1] += nb
    for r in range(n):
        cnt[r + 1] += cnt[r]
    nt = cnt[n]
    tc = np.empty(nt, np.int64)
    tv = np.empty(nt)
    fill = cnt[:-1].copy()
    for e in range(ne):
        for a in range(6):
            ra = corner_dofs[e, a]
            for ia in range(t_ptr[ra], t_ptr[ra + 1]):
                ca = t_idx[ia]
                wa = t_val[ia]
                for b in range(6):
                    rb = corner_dofs[e, b]
                    kab = Ke[e, a, b]
                    for ib in range(t_ptr[rb], t_ptr[rb + 1]):
                        q = fill[ca]
                        tc[q] = t_idx[ib]
                        tv[q] = wa * t_val[ib] * kab
                        fill[ca] = q + 1
    indptr = np.zeros(n + 1, np.int64)
    indices = np.empty(nt, np.int64)
    data = np.empty(nt)
    pos = -np.ones(n, np.int64)
    p = 0
    for r in range(n):
        start = p
        for q in range(cnt[r], cnt[r + 1]):
            c = tc[q]
            if pos[c] < start:
                pos[c] = p
                indices[p] = c
                data[p] = tv[q]
                p += 1
            else:
                data[pos[c]] += tv[q]
        _isort2(indices, data, start, p)
        indptr[r + 1] = p
    return indptr, indices[:p].copy(), data[:p].copy()


# ------------------------------------------------------------------------------------------- element matrices


@njit(cache=True)
def _cb_add(Ke, g, nx, ny, L, kw):
    """Ke += kw G Gᵀ with G_b = L (∇N_b·n) n (a Cauchy–Born member, elements.level2_stiffness)."""
    G = np.empty(6)
    for b in range(3):
        gn = g[b, 0] * nx + g[b, 1] * ny
        G[2 * b] = L * gn * nx
        G[2 * b + 1] = L * gn * ny
    for r in range(6):
        for c in range(6):
            Ke[r, c] += kw * G[r] * G[c]


@njit(cache=True)
def _local_node(e, ni, nj):
    """Local index of lattice node (ni, nj) in element e: rows of constant q, p ascending."""
    i, j, o, s = e[0], e[1], e[2], e[3]
    p, q = ni - i, nj - j
    if o == 0:  # p, q ≥ 0, p + q ≤ s: row q holds s + 1 − q nodes
        return q * (s + 1) - (q * (q - 1)) // 2 + p
    # down: p, q ≤ s, p + q ≥ s: row q holds q + 1 nodes, p from s − q
    return (q * (q + 1)) // 2 + (p - (s - q))


#: the lattice arrays the element matrices read: ``off``, ``tgrid``, ``mgrid``, ``tij``, ``count`` of the
#: :class:`LatticeIndex`, the nodes' ``ij`` and ``x``, the members' node pairs ``members``, unit vectors ``n`` and
#: lengths ``L`` (:class:`.lattice.Lattice`)
LatArrays = namedtuple("LatArrays", ["off", "tgrid", "mgrid", "tij", "count", "ij", "x", "members", "n", "L"])
#: a mesh's elements (E, 4), levels (E,), corner positions (E, 3, 2) and shape gradients (E, 3, 2)
MeshArrays = namedtuple("MeshArrays", ["els", "lv", "X", "grads"])


def lat_arrays(lat, ix) -> LatArrays:
    """The :data:`LatArrays` of lattice ``lat`` and its index ``ix``."""
    return LatArrays(ix.off, ix.tgrid, ix.mgrid, ix.tij, ix.count, lat.ij, lat.x, lat.members, lat.n, lat.L)


@njit(cache=True)
def _inner_lattice(e, tris, nt, la, kmem):
    """The stiffness (dense, 2 DOFs per node) of the members of element ``e`` (each weighted by the element's share
    of it), over its nodes numbered by :func:`_local_node`, and the lattice node of every local node.  Dense: an
    element of side s has (s+1)(s+2)/2 nodes, 45 at the examples' coarsest side 8 (a 90 × 90 matrix); at side 64
    the matrix would take 150 MB and its solve seconds (a sparse solve there: not done)."""
    s = e[3]
    nl = (s + 1) * (s + 2) // 2
    Ks = np.zeros((2 * nl, 2 * nl))
    gidx = np.empty(nl, np.int64)
    ms = np.empty(3, np.int64)
    for q in range(nt):
        t = tris[q]
        _tri_members(la.tij[t, 0], la.tij[t, 1], la.tij[t, 2], la.off, la.mgrid, ms)
        for r in range(3):
            m = ms[r]
            a, b = la.members[m, 0], la.members[m, 1]
            ia = _local_node(e, la.ij[a, 0], la.ij[a, 1])
            ib = _local_node(e, la.ij[b, 0], la.ij[b, 1])
            gidx[ia] = a
            gidx[ib] = b
            kw = kmem[m] / la.count[m]
            nx, ny = la.n[m, 0], la.n[m, 1]
            for rr in range(2):
                for cc in range(2):
                    v = kw * (nx if rr == 0 else ny) * (nx if cc == 0 else ny)
                    Ks[2 * ia + rr, 2 * ia + cc] += v
                    Ks[2 * ib + rr, 2 * ib + cc] += v
                    Ks[2 * ia + rr, 2 * ib + cc] -= v
                    Ks[2 * ib + rr, 2 * ia + cc] -= v
    return Ks, gidx


@njit(cache=True)
def _mode_fields(gidx, la, X0, g, V):
    """The three modes ``V`` (6, 3) as linear fields on the element's boundary nodes (zero inside) and the local
    indices of the inner nodes' DOFs (a node is on the boundary where a barycentric coordinate vanishes)."""
    nl = gidx.shape[0]
    U = np.zeros((2 * nl, 3))
    free = np.empty(2 * nl, np.int64)
    nf = 0
    for a in range(nl):
        nd = gidx[a]
        dx, dy = la.x[nd, 0] - X0[0], la.x[nd, 1] - X0[1]
        l1 = dx * g[1, 0] + dy * g[1, 1]
        l2 = dx * g[2, 0] + dy * g[2, 1]
        l0 = 1.0 - l1 - l2
        if abs(l0) <= 1e-9 or abs(l1) <= 1e-9 or abs(l2) <= 1e-9:
            for i in range(3):
                for c in range(2):
                    U[2 * a + c, i] = l0 * V[c, i] + l1 * V[2 + c, i] + l2 * V[4 + c, i]
        else:
            free[nf] = 2 * a
            free[nf + 1] = 2 * a + 1
            nf += 2
    return U, free[:nf]


@njit(cache=True)
def _eigenmode_matrix(e, tris, nt, la, kmem, X0, g, V, out):
    """Sorg's level-2 matrix of a heterogeneous element (adaptive.py, ``Model``): each deformation mode v_i of the
    level-1 element imposed on the boundary, the inner lattice solved (dense), λ_i = 2 E_i: K_e = Σ λ_i v_i v_iᵀ."""
    Ks, gidx = _inner_lattice(e, tris, nt, la, kmem)
    U, free = _mode_fields(gidx, la, X0, g, V)
    nf = free.shape[0]
    if nf > 0:
        Kff = np.empty((nf, nf))
        R = np.zeros((nf, 3))
        for r in range(nf):
            for c in range(nf):
                Kff[r, c] = Ks[free[r], free[c]]
            for c in range(Ks.shape[0]):
                for i in range(3):
                    R[r, i] -= Ks[free[r], c] * U[c, i]
        sol = np.linalg.solve(Kff, R)
        for r in range(nf):
            for i in range(3):
                U[free[r], i] = sol[r, i]
    KU = Ks @ U
    out[:, :] = 0.0
    for i in range(3):
        en = 0.0
        for r in range(U.shape[0]):
            en += U[r, i] * KU[r, i]
        for r in range(6):
            for c in range(6):
                out[r, c] += en * V[r, i] * V[c, i]  # 2 E_i = uᵀ K u


@njit(cache=True)
def _element_matrix(k, mesh, la, kmem, k_ref, has_ref, K1, modes, Ke, hetero):
    e = mesh.els[k]
    o, s = e[2], e[3]
    if mesh.lv[k] == 1:
        Ke[k] = K1[o] * k_ref
        hetero[k] = False
        return
    tris = np.empty(s * s, np.int64)
    nt = element_triangles(e, la.off, la.tgrid, tris)
    ms = np.empty(3, np.int64)
    het = False
    if has_ref:
        for q in range(nt):
            t = tris[q]
            _tri_members(la.tij[t, 0], la.tij[t, 1], la.tij[t, 2], la.off, la.mgrid, ms)
            for r in range(3):
                if kmem[ms[r]] != k_ref:
                    het = True
    hetero[k] = het
    if mesh.lv[k] == 2 and het:
        _eigenmode_matrix(e, tris, nt, la, kmem, mesh.X[k, 0], mesh.grads[k], modes[o], Ke[k])
        return
    Ke[k] = 0.0
    for q in range(nt):
        t = tris[q]
        _tri_members(la.tij[t, 0], la.tij[t, 1], la.tij[t, 2], la.off, la.mgrid, ms)
        for r in range(3):
            m = ms[r]
            _cb_add(Ke[k], mesh.grads[k], la.n[m, 0], la.n[m, 1], la.L[m], kmem[m] / la.count[m])


@njit(cache=True, parallel=True)
def element_matrices(ks, mesh, la, kmem, k_ref, has_ref, K1, modes, Ke, hetero):
    """The 6×6 matrices of elements ``ks`` into ``Ke``: level 1 ``K1[o]`` × k_ref (the constant-strain triangle of
    the homogenised lattice does not depend on its size); level 3 and homogeneous level 2 Cauchy–Born over the
    members, each weighted by the element's share of its lattice triangles; a level-2 element holding a member off
    ``k_ref`` by Sorg's eigenmodes ``modes[o]`` (the level-1 element's three deformation modes), its inner lattice
    solved densely.  ``hetero[k]``: whether it held one.  ``mesh``: :data:`MeshArrays`, ``la``: :data:`LatArrays`.
    Elements in parallel (the results do not depend on the thread count)."""
    for q in prange(ks.shape[0]):
        _element_matrix(ks[q], mesh, la, kmem, k_ref, has_ref, K1, modes, Ke, hetero)


def reference_matrices(a: float):
    """(K1, modes) per orientation: the level-1 matrix of the unit-stiffness homogenised lattice for the up (0)
    and down (1) lattice triangle of spacing ``a`` (any size gives the same matrix), and its three deformation
    eigenvectors (columns, ascending eigenvalue; the three rigid modes left out) — computed once, so that every
    element of an orientation uses the same basis (two of the three eigenvalues are equal for an equilateral
    triangle: the basis of that pair is otherwise set by round-off)."""
    h = np.sqrt(3.0) / 2.0 * a
    tri = (
        np.array([[0.0, 0.0], [a, 0.0], [0.5 * a, h]]),  # up: (i, j), (i+1, j), (i, j+1)
        np.array([[a, 0.0], [1.5 * a, h], [0.5 * a, h]]),  # down: (i+1, j), (i+1, j+1), (i, j+1)
    )
    K1 = np.stack([level1_stiffness(X, 1.0) for X in tri])
    modes = []
    for K in K1:
        lam, vec = np.linalg.eigh(K)
        modes.append(np.ascontiguousarray(vec[:, np.argsort(lam)[3:]]))
    return K1, np.stack(modes)


def mesh_grid(els):
    """(off, tgrid, ntri): every lattice triangle of the bounding box of mesh ``els`` numbered densely.  The mesh
    covers its domain, so a triangle no element paints lies outside it: neighbours and the boundary follow from
    the elements alone (:func:`neighbours`)."""
    lo = np.array([els[:, 0].min(), els[:, 1].min()], np.int64) - 1
    hi = np.array([(els[:, 0] + els[:, 3]).max(), (els[:, 1] + els[:, 3]).max()], np.int64) + 1
    shape = (int(hi[0] - lo[0] + 1), int(hi[1] - lo[1] + 1), 2)
    tgrid = np.arange(shape[0] * shape[1] * 2, dtype=np.int64).reshape(shape)
    return lo, tgrid, int(tgrid.size)


def mesh_neighbours(els):
    """:func:`neighbours` of a mesh without its lattice (:func:`mesh_grid`): (start, idx, on_boundary)."""
    els = np.ascontiguousarray(els, np.int64).reshape(-1, 4)
    if len(els) == 0:
        return np.zeros(1, np.int64), np.zeros(0, np.int64), np.zeros(0, bool)
    off, tgrid, ntri = mesh_grid(els)
    te = paint(els, off, tgrid, ntri)
    return neighbours(els, off, tgrid, te)


@njit(cache=True)
def unbalanced(els, start, idx):
    """Elements with a neighbour of less than half their side (the 2:1 balance of :func:`.adaptive.refine`)."""
    bad = np.zeros(els.shape[0], np.bool_)
    for k in range(els.shape[0]):
        s = els[k, 3]
        if s == 1:
            continue
        for q in range(start[k], start[k + 1]):
            if 2 * els[idx[q], 3] < s:
                bad[k] = True
                break
    return bad


@njit(cache=True)
def _element_gradient(corner_nodes, grads, U, k):
    """∇u of element k, Σ_b U_b ⊗ ∇N_b, as (∂u1/∂x1, ∂u1/∂x2, ∂u2/∂x1, ∂u2/∂x2)."""
    g00 = g01 = g10 = g11 = 0.0
    for b in range(3):
        n = corner_nodes[k, b]
        g00 += U[n, 0] * grads[k, b, 0]
        g01 += U[n, 0] * grads[k, b, 1]
        g10 += U[n, 1] * grads[k, b, 0]
        g11 += U[n, 1] * grads[k, b, 1]
    return g00, g01, g10, g11


@njit(cache=True)
def marked(corner_nodes, grads, U, start, idx, els, tol, buffer, cracked):
    """The mask of :func:`.adaptive.mark`: elements of side > 1 whose largest strain jump to a neighbour exceeds
    ``tol`` × the largest element strain (the norm √(Δε11² + Δε22² + 2 Δε12²) compared squared) among the elements
    not flagged in ``cracked`` (bool per element; empty: none), then ``buffer`` rings of their neighbours of the same
    or a larger side (side > 1)."""
    ne = els.shape[0]
    eps = np.zeros((ne, 3))
    big = 0.0
    skip = cracked.shape[0] == ne
    for k in range(ne):
        g00, g01, g10, g11 = _element_gradient(corner_nodes, grads, U, k)
        eps[k, 0] = g00
        eps[k, 1] = g11
        eps[k, 2] = 0.5 * (g01 + g10)
        v = g00 * g00 + g11 * g11 + 2.0 * eps[k, 2] * eps[k, 2]
        if v > big and not (skip and cracked[k]):
            big = v
    flag = np.zeros(ne, np.bool_)
    if big == 0.0:
        return flag
    lim = tol * tol * big
    for k in range(ne):
        if els[k, 3] == 1:
            continue
        for q in range(start[k], start[k + 1]):
            n = idx[q]
            d0 = eps[n, 0] - eps[k, 0]
            d1 = eps[n, 1] - eps[k, 1]
            d2 = eps[n, 2] - eps[k, 2]
            if d0 * d0 + d1 * d1 + 2.0 * d2 * d2 > lim:
                flag[k] = True
                break
    for _ in range(buffer):
        grown = flag.copy()
        for k in range(ne):
            if flag[k]:
                for q in range(start[k], start[k + 1]):
                    n = idx[q]
                    if els[n, 3] >= els[k, 3] and els[n, 3] > 1:
                        grown[n] = True
        flag = grown
    return flag


#: the direction (0: 0°, 1: 60°, 2: 120°) of the q-th member of :func:`_tri_members` of an up / a down triangle
_TRI_DIR = np.array([[0, 2, 1], [1, 0, 2]], np.int64)


@njit(cache=True)
def member_checks(els, te, tij, off, mgrid, kL, f0, tooth):
    """What a saw-tooth step of the adaptive solver needs to find its critical member without every member's
    elongation (:meth:`.adaptive.Model.sla_ratios`): the members of the lattice triangles (level-3 elements),
    ascending, and per coarser element and direction the largest ``kL / f0`` (stiffness × length over strength)
    of its members not in a lattice triangle, with that member (``W``, ``WM``; 0 and −1 where none).  Those
    members are intact — a member is damaged only in a lattice triangle, and a mesh is only ever refined — which
    is checked (``tooth``)."""
    ntri = tij.shape[0]
    inres = np.zeros(kL.shape[0], np.bool_)
    ms = np.empty(3, np.int64)
    for t in range(ntri):
        e = te[t]
        if e < 0 or els[e, 3] != 1:
            continue
        _tri_members(tij[t, 0], tij[t, 1], tij[t, 2], off, mgrid, ms)
        for q in range(3):
            if ms[q] >= 0:
                inres[ms[q]] = True
    ne = els.shape[0]
    W = np.zeros((ne, 3))
    WM = -np.ones((ne, 3), np.int64)
    for t in range(ntri):
        e = te[t]
        if e < 0 or els[e, 3] == 1:
            continue
        _tri_members(tij[t, 0], tij[t, 1], tij[t, 2], off, mgrid, ms)
        o = tij[t, 2]
        for q in range(3):
            m = ms[q]
            if m < 0 or inres[m]:
                continue
            if tooth[m] != 0:
                raise ValueError("a damaged member outside the lattice triangles of the mesh")
            d = _TRI_DIR[o, q]
            w = kL[m] / f0[m]
            if w > W[e, d]:
                W[e, d] = w
                WM[e, d] = m
    return np.flatnonzero(inres), W, WM


@njit(cache=True)
def sla_ratios(corner_nodes, grads, els, W, dirs, res, members, n, U, kk, tooth, TF):
    """The load factors at which members reach their present strength under the unit solution ``U`` (node
    displacements; the active nodes suffice): per coarser element the smallest over its members outside the
    lattice triangles (from its constant strain: a member's elongation is L n·ε·n there) and its direction
    (``W`` of :func:`member_checks`); per member of the lattice triangles ``res`` from its nodes, with its force
    under the unit solution.  ∞ where nothing is in tension (or a member has no tooth left)."""
    ne = els.shape[0]
    ratio_e = np.full(ne, np.inf)
    dir_e = -np.ones(ne, np.int64)
    for k in range(ne):
        if els[k, 3] == 1:
            continue
        g00, g01, g10, g11 = _element_gradient(corner_nodes, grads, U, k)
        e12 = 0.5 * (g01 + g10)
        for d in range(3):
            if W[k, d] <= 0.0:
                continue
            nx, ny = dirs[d, 0], dirs[d, 1]
            ed = nx * nx * g00 + ny * ny * g11 + 2.0 * nx * ny * e12
            if ed > 0.0:
                r = 1.0 / (W[k, d] * ed)
                if r < ratio_e[k]:
                    ratio_e[k] = r
                    dir_e[k] = d
    nt = TF.shape[1]
    ratio_r = np.full(res.shape[0], np.inf)
    f_r = np.zeros(res.shape[0])
    for q in range(res.shape[0]):
        m = res[q]
        if tooth[m] >= nt:
            continue
        a, b = members[m, 0], members[m, 1]
        f = kk[m] * ((U[b, 0] - U[a, 0]) * n[m, 0] + (U[b, 1] - U[a, 1]) * n[m, 1])
        f_r[q] = f
        if f > 0.0:
            ratio_r[q] = TF[m, tooth[m]] / f
    return ratio_e, dir_e, ratio_r, f_r


@njit(cache=True)
def split(els, which):
    """The mesh with the elements ``which`` (bool) replaced in place by their four children (:func:`.mesh.children`,
    the same order)."""
    n = els.shape[0]
    m = n
    for k in range(n):
        if which[k]:
            m += 3
    out = np.empty((m, 4), np.int64)
    p = 0
    for k in range(n):
        if not which[k]:
            out[p] = els[k]
            p += 1
            continue
        i, j, o, h = els[k, 0], els[k, 1], els[k, 2], els[k, 3] // 2
        if o == 0:
            kids = ((i, j, 0), (i + h, j, 0), (i, j + h, 0), (i, j, 1))
        else:
            kids = ((i + h, j, 1), (i + h, j + h, 1), (i, j + h, 1), (i + h, j + h, 0))
        for c in range(4):
            out[p, 0], out[p, 1], out[p, 2], out[p, 3] = kids[c][0], kids[c][1], kids[c][2], h
            p += 1
    return out


@njit(cache=True)
def refined(els, which):
    """:func:`split` of ``which``, then of every element with a neighbour of less than half its side until none
    is left (the 2:1 balance of :func:`.adaptive.refine`; neighbours as :func:`mesh_neighbours` finds them)."""
    els = split(els, which)
    while True:
        lo0, lo1 = els[0, 0], els[0, 1]
        hi0, hi1 = els[0, 0] + els[0, 3], els[0, 1] + els[0, 3]
        for k in range(els.shape[0]):
            lo0 = min(lo0, els[k, 0])
            lo1 = min(lo1, els[k, 1])
            hi0 = max(hi0, els[k, 0] + els[k, 3])
            hi1 = max(hi1, els[k, 1] + els[k, 3])
        off = np.array([lo0 - 1, lo1 - 1], np.int64)
        n0, n1 = hi0 - lo0 + 3, hi1 - lo1 + 3
        tgrid = np.arange(n0 * n1 * 2).reshape((n0, n1, 2))
        te = paint(els, off, tgrid, n0 * n1 * 2)
        start, idx, _ = neighbours(els, off, tgrid, te)
        bad = unbalanced(els, start, idx)
        if not bad.any():
            return els
        els = split(els, bad)


def element_members(e, ix):
    """(members, weights) of element ``e``: its lattice triangles' edges, each weighted by its share c / count of
    the domain triangles that have it (:meth:`.adaptive.Model.members_of`)."""
    e = np.asarray(e, np.int64)
    tris = np.empty(int(e[3]) ** 2, np.int64)
    n = element_triangles(e, ix.off, ix.tgrid, tris)
    ms = np.empty((n, 3), np.int64)
    for q in range(n):
        t = ix.tij[tris[q]]
        _tri_members(t[0], t[1], t[2], ix.off, ix.mgrid, ms[q])
    m, c = np.unique(ms.ravel(), return_counts=True)
    return m, c / ix.count[m]


@njit(cache=True)
def _initial_mesh(s0, tij, off, tgrid):
    i_lo, i_hi = tij[:, 0].min() - s0, tij[:, 0].max() + s0
    j_lo, j_hi = tij[:, 1].min() - s0, tij[:, 1].max() + s0
    out = np.empty((tij.shape[0], 4), np.int64)  # never more elements than lattice triangles
    n = 0
    stack = np.empty((4 * 64 + 2, 4), np.int64)
    buf = np.empty(s0 * s0, np.int64)
    i0 = i_lo - (i_lo % s0)  # Python's floor modulo, as the Python initial mesh tiles
    j0 = j_lo - (j_lo % s0)
    for ti in range(i0, i_hi + 1, s0):
        for tj in range(j0, j_hi + 1, s0):
            for to in range(2):
                top = 0
                stack[0, 0], stack[0, 1], stack[0, 2], stack[0, 3] = ti, tj, to, s0
                top = 1
                while top > 0:
                    top -= 1
                    i, j, o, s = stack[top, 0], stack[top, 1], stack[top, 2], stack[top, 3]
                    c = super_triangles(i, j, o, s, off, tgrid, buf)
                    if c == 0:
                        continue
                    if c == s * s:
                        out[n, 0], out[n, 1], out[n, 2], out[n, 3] = i, j, o, s
                        n += 1
                        continue
                    h = s // 2  # children (mesh.children), pushed last first so that they are placed in order
                    if o == 0:
                        kids = ((i, j, 1, h), (i, j + h, 0, h), (i + h, j, 0, h), (i, j, 0, h))
                    else:
                        kids = ((i + h, j + h, 0, h), (i, j + h, 1, h), (i + h, j + h, 1, h), (i + h, j, 1, h))
                    for k in range(4):
                        stack[top, 0], stack[top, 1], stack[top, 2], stack[top, 3] = kids[k]
                        top += 1
    return out[:n].copy()


def initial_mesh_of(lat, s0: int) -> np.ndarray:
    """Elements covering the lattice's domain, (E, 4): the super-triangles of a tiling of side ``s0`` (a power of two)
    that lie wholly in the domain, the others split recursively (depth first, :func:`.mesh.children` order) down to
    the lattice triangles of the domain (tests/coupling_reference.py ``initial_mesh``: the same elements, same order)."""
    if s0 < 1 or s0 & (s0 - 1):
        raise ValueError("the coarsest element side must be a power of two")
    ix = index_of(lat)
    return _initial_mesh(int(s0), ix.tij, ix.off, ix.tgrid)
