"""One factorisation for many solves: a sequentially linear analysis changes a member or two per saw-tooth event,
a low-rank change of the stiffness matrix, so a factor of the matrix as it was serves the changed one through the
Woodbury identity (Woodbury 1950; Hager, SIAM Review 31 (1989) 221–239):

    (K₀ + U C Uᵀ)⁻¹ b = y − Z (C⁻¹ + Uᵀ Z)⁻¹ Uᵀ y,     y = K₀⁻¹ b,   Z = K₀⁻¹ U

with one triangular solve pair per rank-one term when it is added (a column of Z) and one per right-hand side.
The fully resolved and the adaptive solver both keep one (:mod:`.stepper`, :mod:`.adaptive`); each solve is
checked by its residual against the current matrix and the factor is renewed when the residual, or the number of
terms, grows too large: when the terms' columns Z hold as many numbers as the factor (:func:`term_limit`), the
Woodbury part of a solve reads as much memory as its triangular solves.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from .lattice import checked_factor

#: rank-one terms a factor serves at least before the matrix is factorised again (:func:`term_limit`)
MIN_TERMS = 48
#: largest relative residual ‖A x − b‖ / ‖b‖ accepted from an updated factor (a fresh one gives 1e-15)
RESIDUAL = 1e-10


def term_limit(fac) -> int:
    """The rank-one terms ``fac`` (:class:`UpdatedFactor`) serves before its matrix is factorised again: the
    factor's nonzeros per row (at least :data:`MIN_TERMS`), where the columns Z (n per term) hold as many numbers as
    L and U. A solve then costs at most about twice its triangular solves (and the small dense solve with S), and a
    factorisation (10–50 solves on the plates here) is shared by more events the larger its fill: 80 × 48, 7,524
    DOFs: 87 terms; 240 × 144: 152 (48 before; docs/performance.md, "The factor's renewal")."""
    return max(MIN_TERMS, int(fac.lu.nnz) // max(fac.n, 1))


class UpdatedFactor:
    """A factor of ``A`` (sparse, symmetric positive definite) and the rank-one terms ``c u uᵀ`` added since
    (:meth:`add`); :meth:`solve` solves with the sum."""

    def __init__(self, A):
        self.lu = checked_factor(A)
        self.n = A.shape[0]
        self.c = []
        # every term's u, its entries in one list (term, index, value): Uᵀ y in one pass over them (solve)
        self._ut, self._ui, self._uv = np.zeros(0, np.int64), np.zeros(0, np.int64), np.zeros(0)
        self._Z = np.zeros((self.n, 0), order="F")  # K₀⁻¹ U in its first ``terms`` columns (room doubled as needed)
        self.S = np.zeros((0, 0))  # C⁻¹ + Uᵀ Z
        self._b = self._y = None  # the last right-hand side and K₀⁻¹ of it (solve)
        self.limit = term_limit(self)

    @property
    def terms(self) -> int:
        return len(self.c)

    @property
    def Z(self):
        return self._Z[:, : self.terms]

    def add(self, idx, vals, c: float):
        """Add the term ``c u uᵀ`` with ``u`` zero but at ``idx`` (values ``vals``)."""
        idx = np.asarray(idx, np.int64)
        vals = np.asarray(vals, float)
        u = np.zeros(self.n)
        u[idx] = vals
        z = self.lu.solve(u)
        r = self.terms
        S = np.zeros((r + 1, r + 1))
        S[:r, :r] = self.S
        row = vals @ self.Z[idx, :] if r else np.zeros(0)  # u_newᵀ Z
        S[r, :r] = row
        S[:r, r] = row  # symmetric: u_iᵀ K₀⁻¹ u_new = u_newᵀ K₀⁻¹ u_i
        S[r, r] = 1.0 / c + vals @ z[idx]
        self.S = S
        if self._Z.shape[1] <= r:  # double the room (no copy of Z per term)
            # (at most the limit's columns: Z then holds no more numbers than the factor)
            Z = np.empty((self.n, max(r + 1, min(max(4, 2 * self._Z.shape[1]), self.limit))), order="F")
            Z[:, :r] = self._Z[:, :r]
            self._Z = Z
        self._Z[:, r] = z
        self.c.append(float(c))
        self._ut = np.concatenate([self._ut, np.full(len(idx), r, np.int64)])
        self._ui = np.concatenate([self._ui, idx])
        self._uv = np.concatenate([self._uv, vals])

    def solve(self, b):
        # the prescribed displacements' right-hand side stays the same from event to event unless a changed member
        # touches a held DOF: K₀⁻¹ b is then the last one (the same numbers), one triangular solve pair saved
        if self._b is not None and np.array_equal(b, self._b):
            y = self._y
        else:
            y = self.lu.solve(b)
            self._b, self._y = b.copy(), y
        if not self.terms:
            return y
        Uy = np.bincount(self._ut, weights=self._uv * y[self._ui], minlength=self.terms)
        return y - self.Z @ np.linalg.solve(self.S, Uy)


class HeldSolver:
    """Equilibrium ``K u = 0`` on the free DOFs with the DOFs ``fixed`` held at ``val`` (``n`` DOFs in all), for a
    sequence of matrices: the factor of an earlier one serves while the changes since are added to it
    (:meth:`add`, :meth:`add_block`) and its residual stays below :data:`RESIDUAL`; else ``K`` is factorised again
    (then the check of a mechanism applies, :func:`.lattice.checked_factor`)."""

    def __init__(self, fixed, val, n: int):
        self.fixed = np.asarray(fixed, np.int64)
        self.val = np.asarray(val, float)
        self.n = int(n)
        mask = np.ones(self.n, bool)
        mask[self.fixed] = False
        self.free = np.flatnonzero(mask)
        self.free_of = -np.ones(self.n, np.int64)
        self.free_of[self.free] = np.arange(len(self.free))
        self.fac = None
        self.factorisations = 0
        self.fresh = False

    def same_support(self, fixed, val) -> bool:
        return np.array_equal(self.fixed, fixed) and np.array_equal(self.val, val)

    def _room(self, k: int) -> bool:
        if self.fac is None:
            return False
        if self.fac.terms + k > self.fac.limit:
            self.fac = None  # cheaper to factorise again
            return False
        return True

    def add(self, dofs, vals, c: float):
        """The matrix changed by ``c u uᵀ``, u zero but at the global DOFs ``dofs``."""
        if not self._room(1):
            return
        pos = self.free_of[np.asarray(dofs, np.int64)]
        keep = pos >= 0
        vals = np.asarray(vals, float)[keep]
        if np.any(vals != 0.0):
            self.fac.add(pos[keep], vals, c)

    def add_block(self, dofs, D, tol=1e-12):
        """The matrix changed by the symmetric block ``D`` on the global DOFs ``dofs``: its eigenvectors with an
        eigenvalue above ``tol`` of the largest, as rank-one terms."""
        if self.fac is None or not D.size:
            return
        lam, V = np.linalg.eigh(0.5 * (D + D.T))
        big = np.flatnonzero(np.abs(lam) > tol * max(float(np.abs(lam).max()), 1e-300))
        if not self._room(len(big)):
            return
        for q in big:
            self.add(dofs, V[:, q], lam[q])

    def solve(self, K, rebuild):
        """(u, K u, K): the displacements of every DOF, the forces and the matrix solved with.  ``K``: the matrix
        the terms added since the last factorisation lead to (None: there is none yet); where the factor does
        not serve it, ``rebuild()`` assembles the matrix afresh and that is factorised (``fresh`` is then True):
        so the state after a factorisation follows from the stiffnesses at that moment alone, and a resumed run
        that factorises there and adds the same terms continues bit for bit (:mod:`.stepper`)."""
        self.fresh = False
        u = np.zeros(self.n)
        u[self.fixed] = self.val
        if self.fac is not None and K is not None:
            rhs = -(K @ u)[self.free]
            u[self.free] = self.fac.solve(rhs)
            Ku = K @ u
            if np.linalg.norm(Ku[self.free]) <= RESIDUAL * max(float(np.linalg.norm(rhs)), 1e-300):
                return u, Ku, K
            u[self.free] = 0.0
        K = self.factorise(rebuild())
        rhs = -(K @ u)[self.free]
        u[self.free] = self.fac.solve(rhs)
        return u, K @ u, K

    def factorise(self, K):
        """Factorise ``K`` (sorted CSR) afresh; returns it."""
        K.sort_indices()
        self.fac = UpdatedFactor(K[self.free][:, self.free])
        self.factorisations += 1
        self.fresh = True
        return K


def add_dense(K, dofs, D):
    """``K[dofs, dofs] += D`` in place on the CSR matrix ``K`` (sorted indices) where its pattern holds the nonzero
    entries of ``D`` (a member's or an element's stiffness changed: the matrices are assembled with its entries,
    ``Model._assemble``); returns False, with ``K`` untouched, where the pattern lacks one."""
    dofs = np.ascontiguousarray(dofs, np.int64)
    return _add_dense(K.indptr, K.indices, K.data, dofs, np.ascontiguousarray(D, float))


@njit(cache=True)
def _find(indices, lo, hi, c):
    """The position of column c in the sorted ``indices[lo:hi]``, or −1."""
    end = hi
    while lo < hi:
        mid = (lo + hi) // 2
        if indices[mid] < c:
            lo = mid + 1
        else:
            hi = mid
    return lo if lo < end and indices[lo] == c else -1


@njit(cache=True)
def _add_dense(indptr, indices, data, dofs, D):
    n = dofs.shape[0]
    for pass_ in range(2):  # check every entry first: nothing is changed unless all are found
        for a in range(n):
            r = dofs[a]
            for b in range(n):
                if D[a, b] == 0.0:  # exact zeros: DOFs of two elements that share no master (no entry needed)
                    continue
                p = _find(indices, indptr[r], indptr[r + 1], dofs[b])
                if p < 0:
                    return False
                if pass_ == 1:
                    data[p] += D[a, b]
    return True
