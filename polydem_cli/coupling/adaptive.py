"""Adaptive discrete–continuum solution of a lattice problem (Sorg 2014), linear elastic members.

Degrees of freedom: the displacements of the *active* nodes, the corners of the mesh's elements
(:mod:`.mesh`); a hanging node follows its coarse edge linearly, ``u = T q``, so the system is
``Tᵀ K T q = Tᵀ f`` with the prescribed DOFs held.

Element stiffness by level (:mod:`.elements`):

* level 3 — a lattice triangle (side 1): its three members;
* level 2 — a coarser element next to a finer one, or on the domain's boundary: Cauchy–Born over the members
  it covers;
* level 1 — the other coarse elements: the homogenised continuum.

Every member is shared by the elements that cover it in proportion to its lattice triangles: a member lies
in one or two lattice triangles of the domain, and an element owning c of them takes the weight c/(their
number) — 1 inside an element, ½ on an edge between two, 1 on the domain's boundary.  With every element
refined to the lattice triangles the assembled stiffness is the lattice's own (tests/test_coupling.py).

Refinement indicator (stated choice): the jump of the constant element strain across element edges,
``η_e = max_neighbours ‖ε_e − ε_n‖ / ‖ε‖_max`` (Frobenius norms, the largest element strain of the
solution as the scale); elements with ``η_e > tol`` and side > 1 are split into four, their neighbours
of more than twice their side too (a 2:1 balance, so a hanging node has coarse neighbours on one level
only); repeat until no element is marked.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .elements import level1_stiffness, level2_stiffness
from .lattice import Lattice
from .mesh import children, constraints, corners, lattice_triangles, neighbours, triangle_edges


@dataclass
class AdaptiveState:
    elements: list
    level: list = field(default_factory=list)
    dofs: int = 0
    energy: float = 0.0
    u: np.ndarray = None  # displacements of every lattice node (hanging and inner nodes interpolated)
    reaction: float = 0.0


def _member_weights(lat: Lattice, domain: set):
    """(member index of each lattice edge, number of domain lattice triangles per member)."""
    where = {(int(a), int(b)): m for m, (a, b) in enumerate(lat.members)}
    node = lat.node_at()
    count = np.zeros(lat.n_members)
    index = {}
    for t in domain:
        for p, q in triangle_edges(t):
            a, b = node[p], node[q]
            m = where.get((a, b), where.get((b, a)))
            index[(p, q)] = m
            count[m] += 1
    return index, count


def element_levels(elements: list, boundary_members: set, member_of) -> list:
    nb = neighbours(elements)
    lev = []
    for k, e in enumerate(elements):
        if e[3] == 1:
            lev.append(3)
            continue
        finer = any(elements[n][3] < e[3] for n in nb[k])
        on_boundary = any(member_of[ed] in boundary_members for t in lattice_triangles(e) for ed in triangle_edges(t))
        lev.append(2 if finer or on_boundary else 1)
    return lev


def solve(lat: Lattice, domain: set, elements: list, k: float, prescribed: dict, measure=()) -> AdaptiveState:
    """Assemble and solve the mesh ``elements`` (linear elastic members of stiffness k).  ``prescribed``:
    {(node (i, j), component): value} on active nodes; ``measure``: (node, component) whose reactions are
    summed into ``reaction``."""
    from scipy.sparse import coo_matrix
    from scipy.sparse.linalg import spsolve

    node = lat.node_at()
    member_of, count = _member_weights(lat, domain)
    boundary = {m for m in range(lat.n_members) if count[m] == 1}
    levels = element_levels(elements, boundary, member_of)
    hang = constraints(elements)
    active = sorted({c for e in elements for c in corners(e)})
    masters = [nd for nd in active if nd not in hang]
    mi = {nd: q for q, nd in enumerate(masters)}
    # T: active node -> combination of masters (hanging chains resolved recursively)
    memo = {}

    def expand(nd):
        if nd in mi:
            return {nd: 1.0}
        if nd in memo:
            return memo[nd]
        p, q, t = hang[nd]
        out = {}
        for src, wgt in ((p, 1.0 - t), (q, t)):
            for m, w in expand(src).items():
                out[m] = out.get(m, 0.0) + wgt * w
        memo[nd] = out
        return out

    rows, cols, vals = [], [], []
    for e, lev in zip(elements, levels):
        cs = corners(e)
        X = lat.x[[node[c] for c in cs]]
        if lev == 1:
            Ke = level1_stiffness(X, k)
        else:
            own = {}
            for t in lattice_triangles(e):
                for ed in triangle_edges(t):
                    m = member_of[ed]
                    own[m] = own.get(m, 0) + 1
            ms = np.fromiter(own.keys(), np.int64, len(own))
            w = np.array([own[m] / count[m] for m in ms])
            Ke = level2_stiffness(X, lat.n[ms], lat.L[ms], np.full(len(ms), k), w)
        # scatter through T
        comb = [expand(c) for c in cs]
        for a in range(3):
            for b in range(3):
                for ma, wa in comb[a].items():
                    for mb, wb in comb[b].items():
                        for r in range(2):
                            for c2 in range(2):
                                rows.append(2 * mi[ma] + r)
                                cols.append(2 * mi[mb] + c2)
                                vals.append(wa * wb * Ke[2 * a + r, 2 * b + c2])
    n = 2 * len(masters)
    K = coo_matrix((vals, (rows, cols)), shape=(n, n)).tocsr()
    fixed = {}
    for (nd, comp), val in prescribed.items():
        if nd not in mi:
            raise ValueError(f"prescribed node {nd} is not a master node of the mesh")
        fixed[2 * mi[nd] + comp] = val
    fx = np.fromiter(fixed.keys(), np.int64, len(fixed))
    fv = np.fromiter(fixed.values(), float, len(fixed))
    free = np.setdiff1d(np.arange(n), fx)
    q = np.zeros(n)
    q[fx] = fv
    q[free] = spsolve(K[free][:, free].tocsc(), -(K[free][:, fx] @ fv))
    r = K @ q
    # every lattice node's displacement: masters, hanging, and inner nodes interpolated in their element
    U = np.zeros((lat.n_nodes, 2))
    uq = q.reshape(-1, 2)
    for nd in active:
        U[node[nd]] = sum(w * uq[mi[m]] for m, w in expand(nd).items())
    for e in elements:
        if e[3] == 1:
            continue
        cs = corners(e)
        Xc = lat.x[[node[c] for c in cs]]
        Uc = U[[node[c] for c in cs]]
        inner = {c for t in lattice_triangles(e) for c in corners(t)} - set(cs)
        for nd in inner:
            if nd in mi or nd in hang:
                continue
            lam = np.linalg.solve(np.vstack([Xc.T, np.ones(3)]), np.append(lat.x[node[nd]], 1.0))
            U[node[nd]] = lam @ Uc
    st = AdaptiveState(elements, levels, n - len(fixed), 0.5 * float(q @ (K @ q)), U)
    st.reaction = float(sum(r[2 * mi[nd] + comp] for nd, comp in measure))
    return st


def element_strains(lat: Lattice, elements: list, U: np.ndarray) -> np.ndarray:
    """The constant strain [ε11, ε22, ε12] of every element from its corner displacements."""
    from .elements import shape_gradients

    node = lat.node_at()
    out = np.zeros((len(elements), 3))
    for k, e in enumerate(elements):
        idx = [node[c] for c in corners(e)]
        g, _ = shape_gradients(lat.x[idx])
        G = U[idx].T @ g  # ∇u
        out[k] = (G[0, 0], G[1, 1], 0.5 * (G[0, 1] + G[1, 0]))
    return out


def mark(lat: Lattice, elements: list, U: np.ndarray, tol: float) -> set:
    """Elements to split: strain jump to a neighbour above ``tol`` × the largest element strain (side > 1)."""
    eps = element_strains(lat, elements, U)
    norm = np.sqrt(eps[:, 0] ** 2 + eps[:, 1] ** 2 + 2 * eps[:, 2] ** 2)
    scale = float(norm.max()) if norm.size else 0.0
    if scale == 0.0:
        return set()
    nb = neighbours(elements)
    out = set()
    for k, e in enumerate(elements):
        if e[3] == 1:
            continue
        d = eps[nb[k]] - eps[k]
        jump = np.sqrt(d[:, 0] ** 2 + d[:, 1] ** 2 + 2 * d[:, 2] ** 2).max() if nb[k] else 0.0
        if jump > tol * scale:
            out.add(k)
    return out


def refine(elements: list, marked: set) -> list:
    """Split the marked elements, then any element with a neighbour of less than half its side (2:1 balance)."""
    els = [c for k, e in enumerate(elements) for c in (children(e) if k in marked else [e])]
    while True:
        nb = neighbours(els)
        bad = {k for k, e in enumerate(els) if e[3] > 1 and any(2 * els[n][3] < e[3] for n in nb[k])}
        if not bad:
            return els
        els = [c for k, e in enumerate(els) for c in (children(e) if k in bad else [e])]
