"""The fine scale of the adaptive discrete–continuum coupling (Sorg 2014): a regular lattice of equilateral
triangles whose nodes are the centres of equal round particles, joined by axial bars.

Geometry: nodes ``x = (i + j/2) a e1 + j (√3/2) a e2`` for integer i, j, spacing ``a`` (the particle
diameter); every node is joined to its nearest neighbours in the directions 0°, 60° and 120°.  Nodes inside a
hole (a rhombus, the examples of the source) are removed with their members.

Members are central-force bars: with elongation ``δ = (u_j − u_i)·n`` along the unit vector n from node i to
node j, the force is ``f = k_s(δ) δ`` with the secant stiffness of the member's law (:mod:`.members`), its
energy ``½ k δ²`` while elastic.  The equilibrium of the lattice under prescribed node displacements is a
sparse linear system, ``K u = f`` (scipy.sparse, small strain: the member directions are those of the
undeformed lattice).  Two displacement components per node; units: the scenario's (cm, dyn, dyn/cm for k).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

SQRT3 = math.sqrt(3.0)
#: the three bar directions of the triangular lattice (unit vectors of 0°, 60°, 120°)
DIRECTIONS = np.array([[1.0, 0.0], [0.5, SQRT3 / 2.0], [-0.5, SQRT3 / 2.0]])


@dataclass
class Lattice:
    """Nodes ``x`` (n, 2), members ``(i, j)`` (m, 2) with unit vectors ``n`` (m, 2) and lengths ``L`` (m,);
    ``ij`` (n, 2): the lattice indices of every node; ``a``: spacing."""

    x: np.ndarray
    members: np.ndarray
    n: np.ndarray
    L: np.ndarray
    ij: np.ndarray
    a: float

    @property
    def n_nodes(self) -> int:
        return int(self.x.shape[0])

    @property
    def n_members(self) -> int:
        return int(self.members.shape[0])

    def node_at(self) -> dict:
        """(i, j) → node index (built once per lattice; do not modify the returned dict)."""
        cached = self.__dict__.get("_node_at")
        if cached is None:
            cached = {(int(i), int(j)): k for k, (i, j) in enumerate(self.ij)}
            self.__dict__["_node_at"] = cached
        return cached


def rhombus_contains(p, center, half_diagonals) -> np.ndarray:
    """Points strictly inside the rhombus with the given centre and half diagonals (along e1, e2)."""
    p = np.atleast_2d(np.asarray(p, float))
    hx, hy = half_diagonals
    return np.abs(p[:, 0] - center[0]) / hx + np.abs(p[:, 1] - center[1]) / hy < 1.0 - 1e-12


def triangular_lattice(a: float, width: float, height: float, hole=None) -> Lattice:
    """The lattice of spacing ``a`` filling the rectangle [0, width] × [0, height] (nodes on or inside it);
    ``hole``: (center, half_diagonals) of a rhombus whose interior nodes are removed."""
    if a <= 0.0:
        raise ValueError("the lattice spacing must be positive")
    dy = SQRT3 / 2.0 * a
    rows = int(math.floor(height / dy + 1e-9)) + 1
    ncol = int(math.floor(width / a + 1e-9)) + 2
    jj, kk = np.meshgrid(np.arange(rows), np.arange(ncol), indexing="ij")  # rows outer, i ascending inner
    ii = kk - jj // 2  # keep the rows over [0, width]: x = (i + j/2) a
    xx = (ii + 0.5 * jj) * a
    inside = (xx >= -1e-9 * a) & (xx <= width + 1e-9 * a)
    x = np.stack([xx[inside], jj[inside] * dy], 1).astype(float)
    ij = np.stack([ii[inside], jj[inside]], 1).astype(np.int64)
    if hole is not None:
        keep = ~rhombus_contains(x, *hole)
        x, ij = x[keep], ij[keep]
    # members: from every node to its neighbours at 0°, 60°, 120° that exist, node by node
    lo = ij.min(axis=0) - 1
    grid = -np.ones(tuple(ij.max(axis=0) - lo + 2), np.int64)
    grid[ij[:, 0] - lo[0], ij[:, 1] - lo[1]] = np.arange(len(ij))
    q = np.stack([grid[ij[:, 0] - lo[0] + di, ij[:, 1] - lo[1] + dj] for di, dj in ((1, 0), (0, 1), (-1, 1))], 1)
    k = np.repeat(np.arange(len(ij)), 3).reshape(-1, 3)
    has = q >= 0
    members = np.stack([k[has], q[has]], 1).astype(np.int64).reshape(-1, 2)
    d = x[members[:, 1]] - x[members[:, 0]]
    L = np.hypot(d[:, 0], d[:, 1])
    return Lattice(x, members, d / L[:, None], L, ij, float(a))


def member_elongation(lat: Lattice, u: np.ndarray) -> np.ndarray:
    """δ = (u_j − u_i)·n of every member for node displacements ``u`` (n, 2)."""
    du = u[lat.members[:, 1]] - u[lat.members[:, 0]]
    return du[:, 0] * lat.n[:, 0] + du[:, 1] * lat.n[:, 1]


def bar_stiffness(a, b, n, k, n_nodes) -> "scipy.sparse.csr_matrix":  # noqa: F821
    """Stiffness (2 n_nodes square, CSR) of central-force bars from node ``a`` to node ``b`` with unit vectors
    ``n`` (m, 2) and stiffnesses ``k`` (m,): k n⊗n on the four node blocks, signs + on the diagonal blocks."""
    from scipy.sparse import coo_matrix

    nn = np.einsum("mi,mj->mij", n, n) * np.asarray(k, float)[:, None, None]
    rows, cols, vals = [], [], []
    for p, sp in ((a, 1.0), (b, -1.0)):
        for q, sq in ((a, 1.0), (b, -1.0)):
            for r in range(2):
                for c in range(2):
                    rows.append(2 * p + r)
                    cols.append(2 * q + c)
                    vals.append(sp * sq * nn[:, r, c])
    n2 = 2 * n_nodes
    return coo_matrix((np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))), shape=(n2, n2)).tocsr()


def assemble(lat: Lattice, k) -> "scipy.sparse.csr_matrix":  # noqa: F821
    """Global stiffness (2n × 2n, CSR) of the bars with (secant) stiffnesses ``k`` (scalar or per member)."""
    k = np.broadcast_to(np.asarray(k, float), (lat.n_members,))
    return bar_stiffness(lat.members[:, 0], lat.members[:, 1], lat.n, k, lat.n_nodes)


#: a pivot below this fraction of the largest marks a mechanism (a rigid-body mode the supports leave free);
#: a removed (saw-tooth) member keeps 1e-9 of its stiffness, far above this
PIVOT_TOL = 1e-13


def factorize(A):
    """Sparse LU of the symmetric positive definite matrix ``A`` (SuperLU through scipy) with a symmetric fill-reducing
    ordering (minimum degree on Aᵀ + A) and diagonal pivots: on the lattice plates 1.4–1.7× faster to factorize than
    SuperLU's default column ordering (docs/performance.md, the adaptive coupling); the fully resolved and the
    adaptive solver both use it."""
    from scipy.sparse.linalg import splu

    return splu(A.tocsc(), permc_spec="MMD_AT_PLUS_A", diag_pivot_thresh=0.0, options={"SymmetricMode": True})


def checked_factor(A):
    """:func:`factorize` ``A``, the free part of a stiffness matrix; ValueError if it is singular (a mechanism)."""
    try:
        lu = factorize(A)
    except RuntimeError as e:  # "Factor is exactly singular"
        raise ValueError(f"the lattice is not supported against rigid motion ({e})") from None
    piv = np.abs(lu.U.diagonal())
    if piv.size and piv.min() <= PIVOT_TOL * piv.max():  # round-off hides an exactly zero pivot
        raise ValueError(
            f"the lattice is not supported against rigid motion (smallest pivot {piv.min():.3g} of the "
            f"largest {piv.max():.3g}): hold more degrees of freedom"
        )
    return lu


def solve_displacements(K, prescribed: dict, n_dofs: int, f=None) -> np.ndarray:
    """Solve ``K u = f`` with the DOFs of ``prescribed`` ({dof: value}) held: returns u (n_dofs,).  Raises
    ValueError if the free part is singular (a mechanism: too few supports)."""
    fixed = np.fromiter(prescribed.keys(), np.int64, len(prescribed))
    val = np.fromiter(prescribed.values(), float, len(prescribed))
    free = np.setdiff1d(np.arange(n_dofs), fixed)
    u = np.zeros(n_dofs)
    u[fixed] = val
    rhs = -(K[free][:, fixed] @ val)
    if f is not None:
        rhs = rhs + f[free]
    lu = checked_factor(K[free][:, free])
    u[free] = lu.solve(rhs)
    if not np.all(np.isfinite(u)):
        raise ValueError("the lattice is not supported against rigid motion (non-finite solution)")
    return u
