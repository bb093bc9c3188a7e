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

from . import meshkern as mk
from .elements import shape_gradients
from .factor import HeldSolver, add_dense
from .lattice import DIRECTIONS, Lattice
from .mesh import corners


@dataclass
class AdaptiveState:
    elements: np.ndarray  # (E, 4) super-triangles (mesh.py)
    level: np.ndarray = field(default_factory=lambda: np.zeros(0, np.int64))
    dofs: int = 0
    energy: float = 0.0
    u: np.ndarray = None  # displacements of every lattice node (hanging and inner nodes interpolated)
    reaction: float = 0.0


def _keys(els, off):
    """One integer per element (position, orientation, side) to match the elements of two meshes."""
    i, j = els[:, 0] - off[0], els[:, 1] - off[1]
    return ((i * (1 << 24) + j) * 2 + els[:, 2]) * 64 + np.log2(els[:, 3]).astype(np.int64)


class Model:
    """A mesh ready for repeated solves: its levels, element matrices, the hanging-node map ``T`` (active DOFs
    from master DOFs) and the interpolation ``P`` (every lattice node's DOFs from the active ones), all sparse.
    ``kmem``: member stiffnesses; a coarse element is level 1 only if all its members have ``k_ref``.

    The mesh work is array code (:mod:`.meshkern`): the lattice's bookkeeping is built once per lattice, a mesh
    costs the painting of its lattice triangles, its elements' perimeters and the members of its level-2 and
    level-3 elements.  ``cache``: a dict carried across the meshes of one analysis; an element of the previous
    mesh that survives with its level and its members' stiffnesses keeps its matrix.  ``workers``: threads for
    the element matrices (Numba; the results do not depend on it).  ``domain``: the lattice's domain (the
    triangles whose three nodes exist; only checked), ``weights`` is not used (kept for old callers)."""

    def __init__(self, lat: Lattice, domain, elements, kmem, k_ref=None, weights=None, workers=1, cache=None):
        from scipy.sparse import csr_matrix

        self.lat, self.domain = lat, domain
        ix = self.ix = mk.index_of(lat)
        if domain is not None and len(domain) != ix.n_triangles:
            raise ValueError("the adaptive model covers the lattice's whole domain (the triangles of its nodes)")
        self.els = np.ascontiguousarray(np.asarray(elements, np.int64).reshape(-1, 4))
        self._elements = None
        self.cache = cache if cache is not None else {}
        self.kmem = np.array(np.broadcast_to(np.asarray(kmem, float), (lat.n_members,)))
        self.k_ref = k_ref
        els = self.els
        ne = len(els)
        self.te = mk.paint(els, ix.off, ix.tgrid, ix.n_triangles)
        self.nb_start, self.nb_idx, on_b = mk.neighbours(els, ix.off, ix.tgrid, self.te)
        if k_ref is None:
            off = np.ones(ne, bool)
        else:
            off = mk.off_elements(self.kmem, float(k_ref), ix.mtri, self.te, ne)
        self.levels = mk.levels_of(els, self.nb_start, self.nb_idx, on_b, off)
        active, hp, hq, ht = mk.hanging(els, ix.off, ix.gnode, lat.n_nodes)
        ij = lat.ij
        act = np.flatnonzero(active)
        act = act[np.lexsort((ij[act, 1], ij[act, 0]))]  # ordered like the nodes' (i, j)
        na = len(act)
        ai = -np.ones(lat.n_nodes, np.int64)
        ai[act] = np.arange(na)
        hang_a = hp[act] >= 0
        masters = act[~hang_a]
        self.master_of = -np.ones(lat.n_nodes, np.int64)
        self.master_of[masters] = np.arange(len(masters))
        self.act, self.ai_arr, self.hp, self.hq, self.ht = act, ai, hp, hq, ht
        # T: a hanging node follows its edge's ends, which may hang themselves (a chain): substituted until only
        # masters remain (meshkern.master_map; the weights are dyadic fractions: exact)
        t_arrays = mk.dof_map(*mk.master_map(act, self.master_of, hp, hq, ht))
        self.T = csr_matrix(t_arrays[::-1], shape=(2 * na, 2 * len(masters)))
        # corners (mesh.corners) as node indices, their DOFs among the active ones, shape gradients
        i, j, o, sd = els[:, 0], els[:, 1], els[:, 2], els[:, 3]
        up = o == 0
        ci = np.stack([np.where(up, i, i + sd), i + sd, i], 1)
        cj = np.stack([j, np.where(up, j, j + sd), j + sd], 1)
        self.corner_nodes = ix.gnode[ci - ix.off[0], cj - ix.off[1]].reshape(-1, 3)
        ca = ai[self.corner_nodes]
        self.corner_dofs = np.stack(
            [2 * ca[:, 0], 2 * ca[:, 0] + 1, 2 * ca[:, 1], 2 * ca[:, 1] + 1, 2 * ca[:, 2], 2 * ca[:, 2] + 1], 1
        ).reshape(-1, 6)
        self.X = lat.x[self.corner_nodes]
        self.grads = _gradients(self.X)
        self._P = None  # built on first use (P)
        self.Ke = np.zeros((ne, 6, 6))
        self.hetero = np.zeros(ne, bool)
        self.workers = int(workers)
        # the factor of the master system (factor.py), its matrix (updated in place as members change), the
        # stiffnesses at its factorisation and the changes since (factor_state)
        self._held = self._K = self._fac_k = None
        self._log = []
        self._dofs_of = {}  # _support's master DOFs per tuple of (node, component) keys
        self._checks = None  # meshkern.member_checks of this mesh (sla_ratios)
        self._compute(self._reuse())
        self._remember()

    # -- element matrices ----------------------------------------------------------------------------------
    def _reuse(self):
        """Take the matrices of the previous mesh's elements that survive with their level and members'
        stiffnesses (the cache); returns the elements still to compute."""
        old = self.cache.get("mesh")
        todo = np.ones(len(self.els), bool)
        if old is not None and old["lattice"] is self.lat:
            keys = _keys(self.els, self.ix.off)
            pos = np.searchsorted(old["keys"], keys)
            pos = np.minimum(pos, len(old["keys"]) - 1)
            hit = (old["keys"][pos] == keys) & (old["levels"][old["order"][pos]] == self.levels)
            if hit.any():
                changed = old["kmem"] != self.kmem
                if changed.any():  # elements holding a member whose stiffness changed since
                    dirty = mk.off_elements(np.where(changed, 1.0, 0.0), 0.0, self.ix.mtri, self.te, len(self.els))
                    hit &= ~dirty
                src = old["order"][pos[hit]]
                self.Ke[hit] = old["Ke"][src]
                self.hetero[hit] = old["hetero"][src]
                todo = ~hit
        return np.flatnonzero(todo)

    def _remember(self):
        """This mesh for the next one's :meth:`_reuse`.  Its levels, matrices and member stiffnesses are held, not
        copied: :meth:`set_stiffness` changes them together, so they stay consistent with each other."""
        keys = _keys(self.els, self.ix.off)
        order = np.argsort(keys)
        self.cache["mesh"] = {
            "lattice": self.lat,
            "keys": keys[order],
            "order": order,
            "levels": self.levels,
            "Ke": self.Ke,
            "hetero": self.hetero,
            "kmem": self.kmem,
        }

    def _compute(self, ks):
        """Compute the matrices of elements ``ks`` (:func:`.meshkern.element_matrices`)."""
        import numba

        ks = np.ascontiguousarray(ks, np.int64)
        if len(ks):
            ref = self.cache.get("reference")
            if ref is None or ref[0] != self.lat.a:
                ref = (self.lat.a, *mk.reference_matrices(self.lat.a))
                self.cache["reference"] = ref
            ix, lat = self.ix, self.lat
            has_ref = self.k_ref is not None
            threads = numba.get_num_threads()
            numba.set_num_threads(max(1, min(self.workers, numba.config.NUMBA_NUM_THREADS)))
            try:
                mk.element_matrices(
                    ks,
                    mk.MeshArrays(self.els, self.levels, self.X, self.grads),
                    mk.lat_arrays(lat, ix),
                    self.kmem,
                    float(self.k_ref) if has_ref else 0.0,
                    has_ref,
                    ref[1],
                    ref[2],
                    self.Ke,
                    self.hetero,
                )
            finally:
                numba.set_num_threads(threads)

    @property
    def elements(self) -> list:
        """The elements as (i, j, o, s) tuples (:mod:`.mesh`)."""
        if self._elements is None:
            self._elements = [tuple(int(v) for v in e) for e in self.els]
        return self._elements

    @property
    def neighbours(self) -> list:
        """Per element the indices of its neighbours (lists; ``nb_start``/``nb_idx`` hold them as arrays)."""
        s, q = self.nb_start, self.nb_idx
        return [q[s[k] : s[k + 1]].tolist() for k in range(len(self.els))]

    @property
    def active(self) -> list:
        return [tuple(int(v) for v in self.lat.ij[n]) for n in self.act]

    @property
    def mi(self) -> dict:
        """{master node (i, j): its index among the master DOFs' nodes}."""
        ms = np.flatnonzero(self.master_of >= 0)
        return {tuple(int(v) for v in self.lat.ij[n]): int(self.master_of[n]) for n in ms}

    @property
    def hang(self) -> dict:
        """{hanging node: (p, q, t)} in lattice coordinates: the node follows the edge p–q at fraction t from p."""
        ij = self.lat.ij

        def t(n):
            return tuple(int(v) for v in ij[n])

        return {t(n): (t(self.hp[n]), t(self.hq[n]), float(self.ht[n])) for n in np.flatnonzero(self.hp >= 0)}

    def _heterogeneous(self, k) -> bool:
        return bool(self.hetero[k]) if self.levels[k] == 2 else False

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
        included).  The element of a node: that of the first of its lattice triangles."""
        lat, ix = self.lat, self.ix
        na = len(self.act)
        rows = [2 * self.act, 2 * self.act + 1]
        cols = [2 * np.arange(na), 2 * np.arange(na) + 1]
        vals = [np.ones(na), np.ones(na)]
        inner = self.ai_arr < 0
        n = np.flatnonzero(inner)
        if len(n):
            k = _element_of_nodes(n, lat.ij, ix.off, ix.tgrid, self.te)
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
            shape=(2 * lat.n_nodes, 2 * na),
        ).tocsr()

    def elements_of_member(self, m: int) -> list:
        """The elements containing member m (one or two)."""
        out = []
        for t in self.ix.mtri[m]:
            if t >= 0:
                k = int(self.te[t])
                if k >= 0 and k not in out:
                    out.append(k)
        return out

    def elements_of_members(self, ms) -> np.ndarray:
        """The elements containing any of members ``ms`` (unique, ascending)."""
        return _elements_of_members(self.ix, self.te, ms)

    def members_of(self, k):
        """(members, weights) of element k: c of a member's lattice triangles in it over all of them."""
        return mk.element_members(self.els[k], self.ix)

    def sla_ratios(self, U, kk, tooth, TF):
        """Load factors at which members reach their present strength under the unit solution ``U`` (every lattice
        node's displacement; only the active nodes' are read) for stiffnesses ``kk``, teeth ``tooth`` and
        strengths ``TF`` (member, tooth): ``(ratio_e, dir_e, res, ratio_r, f_r, WM)`` —
        :func:`.meshkern.sla_ratios` per coarser element and per member ``res`` of the lattice triangles, and the
        member of each coarser element and direction that limits it (``WM``).  The cost is the mesh's elements
        and resolved members, not the lattice's members."""
        if self._checks is None:
            if np.any(self.ix.count == 0):  # only triangles' members are scanned
                raise ValueError(
                    "a member lies in no lattice triangle: the adaptive saw-tooth analysis needs a trimmed lattice "
                    "(coupling/mesh.py triangulated)"
                )
            kL = np.asarray(kk, float) * self.lat.L
            f0 = np.ascontiguousarray(TF[:, 0], float)
            self._checks = mk.member_checks(self.els, self.te, self.ix.tij, self.ix.off, self.ix.mgrid, kL, f0, tooth)
        res, W, WM = self._checks
        lat = self.lat
        out = mk.sla_ratios(
            self.corner_nodes, self.grads, self.els, W, DIRECTIONS, res, lat.members, lat.n, U, kk, tooth, TF
        )
        return (*out[:2], res, *out[2:], WM)

    @property
    def dofs(self) -> int:
        return self.T.shape[1]

    def set_stiffness(self, kmem):
        """New member stiffnesses: the elements holding a member that changed are recomputed (a level-1 element
        becomes level 2: the homogenised continuum cannot hold a member off the homogeneous stiffness); the change
        of the master matrix goes to the factor and the matrix (:meth:`solve`)."""
        kmem = np.asarray(kmem, float)
        changed = np.flatnonzero(kmem != self.kmem)
        if not len(changed):
            return
        self.kmem[changed] = kmem[changed]
        ks = self.elements_of_members(changed)
        if not len(ks):  # members of no element (a lattice not trimmed to its triangles): the matrix is unchanged
            return
        self.levels[ks[self.levels[ks] == 1]] = 2
        before = self.Ke[ks].copy()
        self._compute(ks)
        if self._K is not None:  # the change of the master matrix, Tᵀ ΔKa T (a few elements: a small block)
            cols, Ad = _dense_rows(self.T, self.corner_dofs[ks].ravel())
            blocks = np.zeros((6 * len(ks), 6 * len(ks)))
            for q, d in enumerate(self.Ke[ks] - before):
                blocks[6 * q : 6 * q + 6, 6 * q : 6 * q + 6] = d
            dK = Ad.T @ blocks @ Ad
            self._held.add_block(cols, dK)
            if not add_dense(self._K, cols, dK):
                self._K = None
            self._log.append((changed, kmem[changed].copy()))

    def _assemble(self):
        """The master system's matrix Tᵀ Ka T (CSR, sorted) from the element matrices, with an entry wherever an
        element couples two DOFs even if its value cancels to 0 (scipy's product drops those; a later change of
        the element must find its entries: :func:`.factor.add_dense`)."""
        from scipy.sparse import csr_matrix

        T, n = self.T, self.dofs
        ptr, idx, val = mk.master_matrix(self.corner_dofs, self.Ke, T.indptr, T.indices, T.data, n)
        K = csr_matrix((val, idx, ptr), shape=(n, n))
        K.has_sorted_indices = True
        return K

    def _support(self, prescribed: dict):
        """(master DOFs held, their values) of ``prescribed`` ({(node, component): value})."""
        keys = tuple(prescribed)
        dofs = self._dofs_of.get(keys)
        if dofs is None:  # once per mesh and set of keys (a solve per saw-tooth event asks again)
            dofs = []
            for nd, comp in keys:
                q = mk.node_of(self.ix, nd)
                if q < 0 or self.master_of[q] < 0:
                    raise ValueError(f"prescribed node {nd} is not a master node of the mesh")
                dofs.append(2 * int(self.master_of[q]) + comp)
            dofs = self._dofs_of[keys] = np.array(dofs, np.int64)
        return dofs, np.fromiter(prescribed.values(), float, len(keys))

    def factor_state(self):
        """(member stiffnesses at the last factorisation, the changes since as rows (change, member, stiffness))
        or (None, None): what :meth:`replay_factor` rebuilds the factor from."""
        if self._fac_k is None:
            return None, None
        rows = [(g, m, k) for g, (ms, kv) in enumerate(self._log) for m, k in zip(ms, kv)]
        return self._fac_k.copy(), np.array(rows, float).reshape(-1, 3)

    def replay_factor(self, prescribed: dict, log):
        """Factorise at the present stiffnesses (those of :meth:`factor_state`) and apply its changes in their
        order: the factor and matrix of the run that recorded them, bit for bit."""
        fx, fv = self._support(prescribed)
        self._held = HeldSolver(fx, fv, self.dofs)
        self._K = self._held.factorise(self._assemble())
        self._fac_k, self._log = self.kmem.copy(), []
        log = np.asarray(log, float).reshape(-1, 3)
        for g in np.unique(log[:, 0]):
            rows = log[log[:, 0] == g]
            kk = self.kmem.copy()
            kk[rows[:, 1].astype(np.int64)] = rows[:, 2]
            self.set_stiffness(kk)

    def solve(self, prescribed: dict, measure=(), full: bool = True) -> AdaptiveState:
        """Solve for the prescribed DOFs; ``full=False``: ``u`` holds the mesh nodes only (the others zero),
        enough for the strain-jump indicator, without building the interpolation of every lattice node.  The
        factor of the master matrix serves the solves that follow as members change (:mod:`.factor`)."""
        fx, fv = self._support(prescribed)
        n = self.dofs
        if self._held is None or not self._held.same_support(fx, fv):
            self._held, self._K = HeldSolver(fx, fv, n), None
        q, r, self._K = self._held.solve(self._K, self._assemble)
        if self._held.fresh:
            self._fac_k, self._log = self.kmem.copy(), []
        if full:
            U = (self.P @ (self.T @ q)).reshape(-1, 2)
        else:
            U = np.zeros((self.lat.n_nodes, 2))
            U[self.act] = (self.T @ q).reshape(-1, 2)
        st = AdaptiveState(self.els, self.levels.copy(), n - len(fx), 0.5 * float(q @ r), U)
        mdofs, _ = self._support(dict.fromkeys(measure, 0.0))
        st.reaction = float(r[mdofs].sum())
        return st


def _dense_rows(A, rows):
    """(the columns with an entry in ``rows`` of the CSR matrix ``A``, ascending; those rows on those columns as a
    dense array) — ``A[rows][:, cols].toarray()`` without scipy's per-call overhead (a few rows per event)."""
    lo, hi = A.indptr[rows], A.indptr[rows + 1]
    cnt = hi - lo
    at = np.repeat(lo - np.cumsum(cnt) + cnt, cnt) + np.arange(cnt.sum())
    cols, inv = np.unique(A.indices[at], return_inverse=True)
    D = np.zeros((len(rows), len(cols)))
    np.add.at(D, (np.repeat(np.arange(len(rows)), cnt), inv), A.data[at])
    return cols, D


def _gradients(X):
    """∇N (E, 3, 2) of the linear triangles ``X`` (E, 3, 2) (elements.shape_gradients, vectorised)."""
    x1, y1 = X[:, 0, 0], X[:, 0, 1]
    x2, y2 = X[:, 1, 0], X[:, 1, 1]
    x3, y3 = X[:, 2, 0], X[:, 2, 1]
    det = (x2 - x1) * (y3 - y1) - (x3 - x1) * (y2 - y1)
    g = np.stack([np.stack([y2 - y3, x3 - x2], 1), np.stack([y3 - y1, x1 - x3], 1), np.stack([y1 - y2, x2 - x1], 1)], 1)
    return g / det[:, None, None]


def _element_of_nodes(n, ij, off, tgrid, te):
    """The element of each node ``n``: that of the first of its six lattice triangles in the domain (up (i, j),
    down (i−1, j), up (i−1, j), down (i, j−1), up (i, j−1), down (i−1, j−1) — any one holding the node)."""
    i, j = ij[n, 0] - off[0], ij[n, 1] - off[1]
    k = -np.ones(len(n), np.int64)
    for di, dj, o in ((0, 0, 0), (-1, 0, 1), (-1, 0, 0), (0, -1, 1), (0, -1, 0), (-1, -1, 1)):
        t = tgrid[i + di, j + dj, o]
        cand = np.where(t >= 0, te[np.maximum(t, 0)], -1)
        take = (k < 0) & (cand >= 0)
        k[take] = cand[take]
    return k


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


def mark(lat: Lattice, elements, U: np.ndarray, tol: float, model=None, buffer: int = 0, cracked=None) -> set:
    """Elements to split: strain jump to a neighbour above ``tol`` × the largest element strain (side > 1), and
    ``buffer`` rings around them: each ring adds the neighbours of the same or a larger side (side > 1).
    ``cracked``: members that have taken a saw-tooth (damaged); the elements holding them are left out of the
    largest strain (not of the jumps).

    Why (a stated choice; the source leaves the indicator's scale open): the "strain" of a lattice triangle with a
    damaged member is mostly its crack's opening, which grows without bound as the crack does; measured against it,
    the jumps in the still elastic plate would count for ever less, and the mesh around a growing crack stayed too
    coarse (too stiff): the homogeneous whole fracture at 240 × 144 dissipated 3.5 % more than the lattice, 0.9 %
    with the scale taken from the elements without a crack (docs/reproduction.md).

    Why a buffer (stated choice, the usual one of block-structured refinement): where the resolved region meets a
    coarse one along a line of moderate strain (the loaded edge, an aggregate's rim), refining the marked element
    exposes the same jump at the next one, and the edge of the refined region creeps one element per stage: 13
    stages on the 120 × 72 homogeneous plate, the last nine adding 6 DOFs each (docs/performance.md).  One ring
    takes the next element along at once."""
    els = np.asarray(elements, np.int64).reshape(-1, 4)
    skip = np.zeros(len(els), bool)
    if cracked is not None and len(cracked):
        ix = mk.index_of(lat)
        te = model.te if model is not None else mk.paint(els, ix.off, ix.tgrid, ix.n_triangles)
        skip[_elements_of_members(ix, te, cracked)] = True
    if model is not None:  # the compiled form of what follows
        if len(model.els) != len(els):
            raise ValueError(f"mark: the model has {len(model.els)} elements, the mesh {len(els)}")
        U = np.ascontiguousarray(U, float)
        m = model
        flag = mk.marked(m.corner_nodes, m.grads, U, m.nb_start, m.nb_idx, m.els, float(tol), int(buffer), skip)
        return set(np.flatnonzero(flag).tolist())
    eps = element_strains(lat, elements, U, model)
    start, kj, _ = mk.mesh_neighbours(els)
    ki = np.repeat(np.arange(len(els)), np.diff(start))  # every (element, neighbour) pair
    d = eps[kj] - eps[ki]
    jump = np.zeros(len(els))
    np.maximum.at(jump, ki, np.sqrt(d[:, 0] ** 2 + d[:, 1] ** 2 + 2 * d[:, 2] ** 2))
    norm = np.sqrt(eps[:, 0] ** 2 + eps[:, 1] ** 2 + 2 * eps[:, 2] ** 2)[~skip]
    scale = float(norm.max()) if norm.size else 0.0
    if scale == 0.0:
        return set()
    coarse = els[:, 3] > 1
    flag = (jump > tol * scale) & coarse
    for _ in range(int(buffer)):
        pair = flag[ki] & (els[kj, 3] >= els[ki, 3])  # (marked element, neighbour as large or larger)
        grown = flag.copy()
        grown[kj[pair]] = True
        flag = grown & coarse
    return set(np.flatnonzero(flag).tolist())


def _elements_of_members(ix, te, ms) -> np.ndarray:
    """The elements (``te``: the element of every lattice triangle, :func:`.meshkern.paint`) holding any of members
    ``ms`` (unique, ascending)."""
    t = ix.mtri[np.asarray(ms, np.int64)].ravel()
    k = te[t[t >= 0]]
    return np.unique(k[k >= 0])


def refine(elements, marked) -> np.ndarray:
    """Split the marked elements, then any element with a neighbour of less than half its side (2:1 balance);
    the mesh as an (E, 4) array (:mod:`.meshkern`: :func:`~.meshkern.split`, :func:`~.meshkern.unbalanced`)."""
    els = np.asarray(elements, np.int64).reshape(-1, 4)
    which = np.zeros(len(els), bool)
    which[np.fromiter(marked, np.int64, len(marked))] = True
    if not len(els):
        return els.copy()
    if np.any(which & (els[:, 3] < 2)):
        raise ValueError(f"element {int(np.flatnonzero(which & (els[:, 3] < 2))[0])} is a lattice triangle (side 1)")
    return mk.refined(np.ascontiguousarray(els), which)


def resolve_members(lat: Lattice, elements, members) -> np.ndarray:
    """The mesh refined (:func:`refine`) until every element holding one of ``members`` (bool per member) is a
    lattice triangle."""
    ix = mk.index_of(lat)
    flag = np.where(np.asarray(members, bool), 0.0, 1.0)
    els = np.asarray(elements, np.int64).reshape(-1, 4)
    while True:
        te = mk.paint(els, ix.off, ix.tgrid, ix.n_triangles)
        held = mk.off_elements(flag, 1.0, ix.mtri, te, len(els))
        marked = np.flatnonzero(held & (els[:, 3] > 1))
        if not len(marked):
            return els
        els = refine(els, set(marked.tolist()))
