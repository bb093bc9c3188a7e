"""The adaptive coupling's mesh work as plain Python: polydem's code before the compiled mesh work
(polydem_cli/coupling/adaptive.py and the mesh functions of mesh.py at 662dd47, 2026-12-05), kept as the reference that tests/test_coupling.py
checks polydem_cli/coupling/meshkern.py against (the issue that asked for compiled mesh code asked for that
check).  Differences from that code: no forked workers; ``modes`` may fix the eigenmode basis (the compiled code
computes it once per orientation, this code once per element: the two deviatoric eigenvalues of an equilateral
triangle are equal, so round-off chose the basis of that pair); solve/mark/element_strains left out."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from polydem_cli.coupling.elements import level1_stiffness, level2_stiffness, shape_gradients
from polydem_cli.coupling.lattice import Lattice, bar_stiffness
from polydem_cli.coupling.mesh import children, corners, lattice_triangles, triangle_edges

# ---- the mesh functions of polydem_cli/coupling/mesh.py at 662dd47


def domain_triangles(nodes: set) -> set:
    """Lattice triangles of the domain: those whose three nodes exist."""
    tri = set()
    for i, j in nodes:
        for o in (0, 1):
            t = (i, j, o, 1)
            if all(c in nodes for c in corners(t)):
                tri.add(t)
    return tri


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


# ---- the model of polydem_cli/coupling/adaptive.py at 662dd47


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
        self,
        lat: Lattice,
        domain: set,
        elements: list,
        kmem,
        k_ref=None,
        weights=None,
        workers=1,
        cache=None,
        modes=None,
    ):
        self.modes = modes
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
        if self.modes is not None:
            modes = self.modes[self.elements[k][2]]
        else:
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


def refine(elements: list, marked: set) -> list:
    """Split the marked elements, then any element with a neighbour of less than half its side (2:1 balance)."""
    els = [c for k, e in enumerate(elements) for c in (children(e) if k in marked else [e])]
    while True:
        nb = neighbours(els)
        bad = {k for k, e in enumerate(els) if e[3] > 1 and any(2 * els[n][3] < e[3] for n in nb[k])}
        if not bad:
            return els
        els = [c for k, e in enumerate(els) for c in (children(e) if k in bad else [e])]
