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

from .elements import level1_stiffness, level2_stiffness, shape_gradients
from .lattice import Lattice, bar_stiffness
from .mesh import (
    Locator,
    children,
    constraints,
    corners,
    lattice_triangles,
    member_triangles,
    neighbours,
    triangle_edges,
)

#: the model whose elements forked worker processes compute (Model._elements)
_FORKED = None


def _eigenmode_job(k):
    m = _FORKED
    ms, w = m.members_of(k)
    return k, m._eigenmode_stiffness(k, ms, w, m.kmem[ms])


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


class Model:
    """A mesh ready for repeated solves: its levels, element matrices, the hanging-node map ``T`` (active DOFs
    from master DOFs) and the interpolation ``P`` (every lattice node's DOFs from the active ones), all sparse.
    ``kmem``: member stiffnesses; a coarse element is level 1 only if all its members have ``k_ref``.

    Building it costs the elements' perimeters plus the members of the level-2 and level-3 elements (a level-1
    element needs only its corners), so a coarse mesh of a large lattice is cheap."""

    def __init__(
        self, lat: Lattice, domain: set, elements: list, kmem, k_ref=None, weights=None, workers=1, cache=None
    ):
        from scipy.sparse import coo_matrix

        self.lat, self.domain, self.elements = lat, domain, list(elements)
        # ``cache``: element matrices and member lists kept across the meshes of one analysis (an element that
        # survives a refinement with its level and its members' stiffnesses is not computed again)
        self.cache = cache if cache is not None else {"own": {}, "ke": {}}
        node = lat.node_at()
        self.node = node
        self.member_of, self.count = weights or _member_weights(lat, domain)
        self.kmem = np.array(np.broadcast_to(np.asarray(kmem, float), (lat.n_members,)))
        self.k_ref = k_ref
        self.locator = Locator(self.elements)
        self.neighbours, on_boundary = neighbours(self.elements, boundary=True)
        # levels: 3 lattice triangles; 2 next to a finer element, on the boundary or holding a member off k_ref
        off = set()
        if k_ref is None:
            off = set(range(len(self.elements)))
        else:
            for m in np.flatnonzero(self.kmem != k_ref):
                off.update(self.elements_of_member(int(m)))
        self.levels = []
        for k, e in enumerate(self.elements):
            if e[3] == 1:
                self.levels.append(3)
            elif on_boundary[k] or k in off or any(self.elements[n][3] < e[3] for n in self.neighbours[k]):
                self.levels.append(2)
            else:
                self.levels.append(1)
        self.own = [None] * len(self.elements)
        hang = constraints(self.elements)
        active = sorted({c for e in self.elements for c in corners(e)})
        ai = {nd: q for q, nd in enumerate(active)}
        masters = [nd for nd in active if nd not in hang]
        self.mi = {nd: q for q, nd in enumerate(masters)}
        self.ai, self.active, self.hang = ai, active, hang
        memo = {}

        def expand(nd):
            if nd in self.mi:
                return {nd: 1.0}
            if nd in memo:
                return memo[nd]
            p, q, t = hang[nd]
            out = {}
            for src, wgt in ((p, 1.0 - t), (q, t)):
                for mm, w in expand(src).items():
                    out[mm] = out.get(mm, 0.0) + wgt * w
            memo[nd] = out
            return out

        r, c, v = [], [], []
        for nd in active:
            for mm, w in expand(nd).items():
                for comp in range(2):
                    r.append(2 * ai[nd] + comp)
                    c.append(2 * self.mi[mm] + comp)
                    v.append(w)
        self.T = coo_matrix((v, (r, c)), shape=(2 * len(active), 2 * len(masters))).tocsr()
        self.corner_nodes = np.array([[node[q] for q in corners(e)] for e in self.elements], np.int64).reshape(-1, 3)
        self.corner_dofs = np.array(
            [[2 * ai[q] + comp for q in corners(e) for comp in range(2)] for e in self.elements], np.int64
        ).reshape(-1, 6)
        self.X = lat.x[self.corner_nodes]
        self.grads = np.array([shape_gradients(X)[0] for X in self.X]).reshape(-1, 3, 2)
        self._P = None  # built on first use (P)
        self.Ke = np.zeros((len(self.elements), 6, 6))
        self.workers = int(workers)
        self._elements(range(len(self.elements)))

    def _elements(self, ks):
        """Compute the matrices of elements ``ks`` (from the cache where an element is unchanged).  The
        heterogeneous level-2 elements are independent sub-problems (a sparse solve each): with ``workers`` > 1
        they are computed by that many forked processes (threads do not help: the sub-problems are small and
        their Python part holds the GIL — measured, docs/reproduction.md)."""
        todo = [k for k in ks if not self._from_cache(k)]
        heavy = [k for k in todo if self.levels[k] == 2 and self._heterogeneous(k)]
        if self.workers > 1 and len(heavy) >= 8 * self.workers:
            import multiprocessing as mp

            global _FORKED
            _FORKED = self
            try:
                with mp.get_context("fork").Pool(self.workers) as pool:
                    size = max(1, len(heavy) // (4 * self.workers))
                    for k, Ke in pool.imap_unordered(_eigenmode_job, heavy, chunksize=size):
                        self.Ke[k] = Ke
                        ms, _ = self.members_of(k)
                        self.cache["ke"][(self.elements[k], self.levels[k])] = (self.kmem[ms].copy(), Ke.copy())
            finally:
                _FORKED = None
            done = set(heavy)
            todo = [k for k in todo if k not in done]
        for k in todo:
            self._element(k)

    def _from_cache(self, k) -> bool:
        """Take element k's matrix from the cache if its level and its members' stiffnesses are unchanged."""
        hit = self.cache["ke"].get((self.elements[k], self.levels[k]))
        if hit is None:
            return False
        if self.levels[k] != 1:
            ms, _ = self.members_of(k)
            if not np.array_equal(hit[0], self.kmem[ms]):
                return False
        self.Ke[k] = hit[1]
        return True

    def _heterogeneous(self, k) -> bool:
        ms, _ = self.members_of(k)
        return self.k_ref is not None and bool(np.any(self.kmem[ms] != self.k_ref))

    @property
    def P(self):
        """Every lattice node's DOFs from the active ones (sparse, built on first use)."""
        if self._P is None:
            from scipy.sparse import coo_matrix

            self._P = self._interpolation(coo_matrix)
        return self._P

    def _interpolation(self, coo_matrix):
        """Every lattice node's displacement from the active nodes: identity for an active node, barycentric in
        its element for a node inside or on the edge of a coarse element (a node on an edge shared by two
        elements gets the same value from either: the field is continuous along element edges, hanging nodes
        included).  Vectorised per (side, orientation) group of elements."""
        lat = self.lat
        ij = lat.ij
        lo = ij.min(axis=0)
        grid = -np.ones(tuple(ij.max(axis=0) - lo + 1), np.int64)
        grid[ij[:, 0] - lo[0], ij[:, 1] - lo[1]] = np.arange(lat.n_nodes)
        act_nodes = np.array([self.node[nd] for nd in self.active], np.int64)
        act_index = np.arange(len(self.active))
        els = np.array(self.elements, np.int64).reshape(-1, 4)
        ks_all, ns_all = [], []
        for s_, o in {(int(e[3]), int(e[2])) for e in els if e[3] > 1}:
            ks = np.flatnonzero((els[:, 3] == s_) & (els[:, 2] == o))
            p, q = np.meshgrid(np.arange(s_ + 1), np.arange(s_ + 1), indexing="ij")
            sel = (p + q <= s_) if o == 0 else (p + q >= s_)
            gi = els[ks, 0][:, None] + p[sel][None, :] - lo[0]
            gj = els[ks, 1][:, None] + q[sel][None, :] - lo[1]
            ok = (gi >= 0) & (gj >= 0) & (gi < grid.shape[0]) & (gj < grid.shape[1])
            n = np.full(gi.shape, -1, np.int64)
            n[ok] = grid[gi[ok], gj[ok]]
            kk = np.broadcast_to(ks[:, None], n.shape)
            keep = n >= 0
            ks_all.append(kk[keep])
            ns_all.append(n[keep])
        rows = [2 * act_nodes, 2 * act_nodes + 1]
        cols = [2 * act_index, 2 * act_index + 1]
        vals = [np.ones(len(act_nodes)), np.ones(len(act_nodes))]
        if ks_all:
            k = np.concatenate(ks_all)
            n = np.concatenate(ns_all)
            n, first = np.unique(n, return_index=True)  # one element per node
            k = k[first]
            inner = ~np.isin(n, act_nodes)
            n, k = n[inner], k[inner]
            lam = np.einsum("ij,ikj->ik", lat.x[n] - self.X[k, 0], self.grads[k])
            lam[:, 0] = 1.0 - lam[:, 1] - lam[:, 2]
            corner_act = self.corner_dofs[:, 0::2] // 2  # (E, 3) active index of each corner
            for b in range(3):
                a = corner_act[k, b]
                for comp in range(2):
                    rows.append(2 * n + comp)
                    cols.append(2 * a + comp)
                    vals.append(lam[:, b])
        return coo_matrix(
            (np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))),
            shape=(2 * lat.n_nodes, 2 * len(self.active)),
        ).tocsr()

    def elements_of_member(self, m: int) -> list:
        """The elements containing member m (one or two)."""
        tris = self.cache.setdefault("tris", {}).get(m)
        if tris is None:  # the member's lattice triangles in the domain (the same for every mesh)
            a, b = self.lat.ij[self.lat.members[m]]
            tris = [t for t in member_triangles(tuple(map(int, a)), tuple(map(int, b))) if t in self.domain]
            self.cache["tris"][m] = tris
        out = []
        for t in tris:
            k = self.locator.element_of(t)
            if k is not None and k not in out:
                out.append(k)
        return out

    def members_of(self, k):
        """(members, weights) of element k: c of a member's lattice triangles in it over all of them."""
        if self.own[k] is None and self.elements[k] in self.cache["own"]:
            self.own[k] = self.cache["own"][self.elements[k]]
        if self.own[k] is None:
            own = {}
            for t in lattice_triangles(self.elements[k]):
                for ed in triangle_edges(t):
                    m = self.member_of[ed]
                    own[m] = own.get(m, 0) + 1
            ms = np.fromiter(own.keys(), np.int64, len(own))
            self.own[k] = (ms, np.array([own[m] / self.count[m] for m in ms]))
            self.cache["own"][self.elements[k]] = self.own[k]
        return self.own[k]

    def _element(self, k):
        key = (self.elements[k], self.levels[k])
        if self.levels[k] == 1:
            km = None
        else:
            ms, w = self.members_of(k)
            km = self.kmem[ms]
        if km is None:
            self.Ke[k] = level1_stiffness(self.X[k], self.k_ref)
        elif self.levels[k] == 2 and self.k_ref is not None and np.any(km != self.k_ref):
            self.Ke[k] = self._eigenmode_stiffness(k, ms, w, km)  # heterogeneous members
        else:
            self.Ke[k] = level2_stiffness(self.X[k], self.lat.n[ms], self.lat.L[ms], km, w)
        self.cache["ke"][key] = (None if km is None else km.copy(), self.Ke[k].copy())

    def _eigenmode_stiffness(self, k, ms, w, km):
        """Level-2 stiffness of an element with heterogeneous members (Sorg 2014): the deformation
        eigenvectors v_i of the homogeneous level-1 element are imposed on the element's boundary nodes
        (linearly along its edges), the lattice inside the element is solved with them, and each eigenvalue
        follows from the equality of the energies, ½ λ_i |v_i|² = E_i:  K_e = Σ λ_i v_i v_iᵀ.  For a
        homogeneous element the inner solution is affine and K_e is the level-1 matrix again."""
        from scipy.sparse.linalg import splu

        lat = self.lat
        lam, vec = np.linalg.eigh(level1_stiffness(self.X[k], self.k_ref))
        modes = vec[:, np.argsort(lam)[3:]]  # the three deformation modes (three rigid ones have λ = 0)
        nodes = np.unique(lat.members[ms].ravel())
        loc = {int(n): q for q, n in enumerate(nodes)}
        g = self.grads[k]
        bary = (lat.x[nodes] - self.X[k, 0]) @ g.T + np.array([1.0, 0.0, 0.0])
        bary[:, 0] = 1.0 - bary[:, 1] - bary[:, 2]
        on_edge = np.any(np.abs(bary) <= 1e-9, axis=1)
        a = np.array([loc[int(n)] for n in lat.members[ms, 0]])
        b = np.array([loc[int(n)] for n in lat.members[ms, 1]])
        Ks = bar_stiffness(a, b, lat.n[ms], km * w, len(nodes))
        n2 = 2 * len(nodes)
        fixed = np.flatnonzero(np.repeat(on_edge, 2))
        free = np.flatnonzero(~np.repeat(on_edge, 2))
        Ksf = Ks[free]
        lu = splu(Ksf[:, free].tocsc()) if free.size else None
        Kfb = Ksf[:, fixed]
        Ke = np.zeros((6, 6))
        for i in range(3):
            v = modes[:, i]
            u = np.zeros(n2)
            ub = bary @ v.reshape(3, 2)  # the mode's linear field at every node of the element
            u[fixed] = ub.ravel()[fixed]
            if free.size:
                u[free] = lu.solve(-(Kfb @ u[fixed]))
            e = 0.5 * float(u @ (Ks @ u))
            Ke += 2.0 * e * np.outer(v, v)  # λ_i = 2 E_i for |v_i| = 1
        return Ke

    @property
    def dofs(self) -> int:
        return self.T.shape[1]

    def set_stiffness(self, kmem):
        """New member stiffnesses: the elements holding a member that changed are recomputed (a level-1 element
        becomes level 2: the homogenised continuum cannot hold a member off the homogeneous stiffness)."""
        kmem = np.asarray(kmem, float)
        elems = set()
        for m in np.flatnonzero(kmem != self.kmem):
            self.kmem[m] = kmem[m]
            for k in self.elements_of_member(int(m)):
                elems.add(k)
                if self.levels[k] == 1:
                    self.levels[k] = 2
        self._elements(sorted(elems))

    def solve(self, prescribed: dict, measure=(), full: bool = True) -> AdaptiveState:
        """Solve for the prescribed DOFs; ``full=False``: ``u`` holds the mesh nodes only (the others zero),
        enough for the strain-jump indicator, without building the interpolation of every lattice node."""
        from scipy.sparse import coo_matrix
        from scipy.sparse.linalg import spsolve

        na = 2 * len(self.active)
        rows = np.repeat(self.corner_dofs, 6, axis=1).ravel()
        cols = np.tile(self.corner_dofs, (1, 6)).ravel()
        Ka = coo_matrix((self.Ke.ravel(), (rows, cols)), shape=(na, na)).tocsr()
        K = (self.T.T @ Ka @ self.T).tocsr()
        n = K.shape[0]
        fixed = {}
        for (nd, comp), val in prescribed.items():
            if nd not in self.mi:
                raise ValueError(f"prescribed node {nd} is not a master node of the mesh")
            fixed[2 * self.mi[nd] + comp] = val
        fx = np.fromiter(fixed.keys(), np.int64, len(fixed))
        fv = np.fromiter(fixed.values(), float, len(fixed))
        free = np.setdiff1d(np.arange(n), fx)
        q = np.zeros(n)
        q[fx] = fv
        q[free] = spsolve(K[free][:, free].tocsc(), -(K[free][:, fx] @ fv))
        r = K @ q
        if full:
            U = (self.P @ (self.T @ q)).reshape(-1, 2)
        else:
            U = np.zeros((self.lat.n_nodes, 2))
            ua = (self.T @ q).reshape(-1, 2)
            U[[self.node[nd] for nd in self.active]] = ua
        st = AdaptiveState(self.elements, list(self.levels), n - len(fixed), 0.5 * float(q @ (K @ q)), U)
        st.reaction = float(sum(r[2 * self.mi[nd] + comp] for nd, comp in measure))
        return st


def solve(lat: Lattice, domain: set, elements: list, k, prescribed: dict, measure=(), k_ref=None) -> AdaptiveState:
    """Assemble and solve the mesh ``elements`` (:class:`Model`).  ``k``: member stiffness, a scalar or one per
    member (secant stiffnesses of damaged members); a coarse element is level 1 only if all its members have
    ``k_ref`` (the homogeneous stiffness; default: k if scalar), else level 2.  ``prescribed``: {(node (i, j),
    component): value} on mesh nodes; ``measure``: (node, component) whose reactions are summed into
    ``reaction``."""
    if k_ref is None and np.ndim(k) == 0:
        k_ref = float(k)
    return Model(lat, domain, elements, k, k_ref).solve(prescribed, measure)


def element_strains(lat: Lattice, elements: list, U: np.ndarray, model=None) -> np.ndarray:
    """The constant strain [ε11, ε22, ε12] of every element from its corner displacements."""
    if model is None:
        node = lat.node_at()
        idx = np.array([[node[c] for c in corners(e)] for e in elements], np.int64).reshape(-1, 3)
        g = np.array([shape_gradients(lat.x[i])[0] for i in idx]).reshape(-1, 3, 2)
    else:
        idx, g = model.corner_nodes, model.grads
    G = np.einsum("ebi,ebj->eij", U[idx], g)  # ∇u per element: Σ_b U_b ⊗ ∇N_b
    return np.column_stack([G[:, 0, 0], G[:, 1, 1], 0.5 * (G[:, 0, 1] + G[:, 1, 0])])


def mark(lat: Lattice, elements: list, U: np.ndarray, tol: float, model=None) -> set:
    """Elements to split: strain jump to a neighbour above ``tol`` × the largest element strain (side > 1)."""
    eps = element_strains(lat, elements, U, model)
    norm = np.sqrt(eps[:, 0] ** 2 + eps[:, 1] ** 2 + 2 * eps[:, 2] ** 2)
    scale = float(norm.max()) if norm.size else 0.0
    if scale == 0.0:
        return set()
    nb = model.neighbours if model is not None else neighbours(elements)
    ki = np.repeat(np.arange(len(nb)), [len(q) for q in nb])  # every (element, neighbour) pair
    kj = np.fromiter((q for qs in nb for q in qs), np.int64, len(ki))
    d = eps[kj] - eps[ki]
    jump = np.zeros(len(elements))
    np.maximum.at(jump, ki, np.sqrt(d[:, 0] ** 2 + d[:, 1] ** 2 + 2 * d[:, 2] ** 2))
    side = np.fromiter((e[3] for e in elements), np.int64, len(elements))
    return set(np.flatnonzero((jump > tol * scale) & (side > 1)).tolist())


def refine(elements: list, marked: set) -> list:
    """Split the marked elements, then any element with a neighbour of less than half its side (2:1 balance)."""
    els = [c for k, e in enumerate(elements) for c in (children(e) if k in marked else [e])]
    while True:
        nb = neighbours(els)
        bad = {k for k, e in enumerate(els) if e[3] > 1 and any(2 * els[n][3] < e[3] for n in nb[k])}
        if not bad:
            return els
        els = [c for k, e in enumerate(els) for c in (children(e) if k in bad else [e])]
