"""Linked-cell search for potential contact pairs (thesis §4.1 stages (a)–(b), Fig. 4.2).

(a) A square mesh of cell size ``h_ks`` is laid over the centroids; each particle
    is sorted into the cell holding its centroid (counting sort, O(n)).
(b) Bounding circles (centre = centroid, radius = largest centroid–vertex
    distance) are tested against those of the particles in the surrounding
    cells.  The stencil reaches ``ceil((r_i + r_max)/h_ks)`` cells in every
    direction, so no pair whose circles overlap is missed whatever the ratio of
    particle size to cell size (open point O-8).  Only partners with a smaller
    particle number are considered, so each pair appears once, as ``(a, b)``
    with ``a < b``.

Particles much larger than the typical one (load plates; flag ``is_large``) are
kept out of the mesh — they would blow up the stencil — and tested against all
other particles in an explicit pass (O(n_large · n)).

Stages (c) and (d) run per pair inside
:func:`polydem_cli.interactions.contact.geometry.pair_geometry`.

A particle whose position is not finite takes part in no pair (and in neither the mesh's bounds nor its
cells): the engine stops such a state, and the search stays within its arrays whatever positions it is given
(the cell size, from the particles' radii, is taken as positive and finite).

Pairs joined by an active bond are not entered (thesis §4.1 / §5.1.2): the
caller passes a CSR list of bonded partners (empty when the scene has no bonds).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit


@njit(cache=True)
def _bonded(a, b, bond_start, bond_partner, bond_active):
    """True if an active bond joins particles a < b (CSR keyed by the smaller index)."""
    if bond_start.shape[0] <= a + 1:
        return False
    for k in range(bond_start[a], bond_start[a + 1]):
        if bond_partner[k] == b and bond_active[k]:
            return True
    return False


@njit(cache=True)
def csr_by_key(key, m, n, start, perm):
    """Counting sort of the first ``m`` entries by ``key`` (in 0..n-1), no allocation: ``start`` (n+1) becomes
    the CSR index (entries of key i at sorted positions start[i] .. start[i+1]-1) and ``perm[j]`` the entry
    at sorted position j; entries of one key keep their order.  Used for the per-contact history tables."""
    for i in range(n + 1):
        start[i] = 0
    for k in range(m):
        start[key[k] + 1] += 1
    for i in range(n):
        start[i + 1] += start[i]
    for k in range(m):  # scatter, using start[a] as a moving pointer ...
        a = key[k]
        perm[start[a]] = k
        start[a] += 1
    for i in range(n, 0, -1):  # ... then shift the pointers back
        start[i] = start[i - 1]
    start[0] = 0


@njit(cache=True)
def find_candidates(
    x,
    radius,
    is_large,
    large_idx,
    cell_size,
    cell_count,
    cell_start,
    cell_list,
    cell_of,
    cand,
    bond_start,
    bond_partner,
    bond_active,
    pad,
    include_bonded,
):
    """Fill ``cand`` with potential contact pairs; return their number.

    If ``cand`` is too small the pairs beyond its capacity are only counted and
    ``-count`` is returned (the caller enlarges the buffer and repeats the step).

    Parameters
    ----------
    x : (n, 3) positions (x1, x2, φ)
    radius : (n,) bounding-circle radii
    is_large : (n,) bool; large_idx : indices of large particles
    cell_size : requested h_ks (cm); enlarged automatically if the centroids are
        spread over more cells than ``cell_count`` can hold
    cell_count, cell_start, cell_list, cell_of : work arrays (capacity ncell_cap, ncell_cap+1, n, n)
    pad : extra distance added to the sum of radii (0 for the thesis search; > 0 for a buffered list)
    include_bonded : keep pairs joined by an active bond (a buffered list outlives bond failures;
        the pair stage skips bonded pairs at every evaluation)
    """
    n = x.shape[0]
    cap = cand.shape[0]
    ncell_cap = cell_count.shape[0]
    nc = 0
    # ---- stage (a): mesh over the small particles
    xmin = np.inf
    ymin = np.inf
    xmax = -np.inf
    ymax = -np.inf
    rmax = 0.0
    nsmall = 0
    for i in range(n):
        if is_large[i] or not (math.isfinite(x[i, 0]) and math.isfinite(x[i, 1])):
            continue
        nsmall += 1
        xmin = min(xmin, x[i, 0])
        xmax = max(xmax, x[i, 0])
        ymin = min(ymin, x[i, 1])
        ymax = max(ymax, x[i, 1])
        rmax = max(rmax, radius[i])
    if nsmall > 0:
        h = cell_size
        sx = xmax - xmin
        sy = ymax - ymin
        if math.isfinite(sx) and math.isfinite(sy):
            # the mesh's size in floating point: no integer conversion of a spread beyond the integers
            while (math.floor(sx / h) + 1.0) * (math.floor(sy / h) + 1.0) > ncell_cap:
                h *= 1.5
            nx = int(sx / h) + 1
            ny = int(sy / h) + 1
        else:  # spread beyond the floating-point range: one cell (the engine stops such a state)
            h = math.inf
            nx = ny = 1
        ncell = nx * ny
        for c in range(ncell):
            cell_count[c] = 0
        for i in range(n):
            if is_large[i] or not (math.isfinite(x[i, 0]) and math.isfinite(x[i, 1])):
                cell_of[i] = -1  # a large particle: its own pass below; a non-finite position: no pairs
                continue
            fx = (x[i, 0] - xmin) / h
            fy = (x[i, 1] - ymin) / h
            cx = int(fx) if fx < nx else nx - 1  # (a NaN, from a spread beyond the range, to the last cell)
            cy = int(fy) if fy < ny else ny - 1
            c = cy * nx + cx
            cell_of[i] = c
            cell_count[c] += 1
        cell_start[0] = 0
        for c in range(ncell):
            cell_start[c + 1] = cell_start[c] + cell_count[c]
            cell_count[c] = 0
        for i in range(n):
            c = cell_of[i]
            if c >= 0:
                cell_list[cell_start[c] + cell_count[c]] = i
                cell_count[c] += 1
        # ---- stage (b): bounding circles in the stencil, partners with smaller number
        for i in range(n):
            c = cell_of[i]
            if c < 0:
                continue
            cy = c // nx
            cx = c - cy * nx
            s = int(np.ceil((radius[i] + rmax + pad) / h))
            gy0 = max(cy - s, 0)
            gy1 = min(cy + s, ny - 1)
            gx0 = max(cx - s, 0)
            gx1 = min(cx + s, nx - 1)
            for gy in range(gy0, gy1 + 1):
                for gx in range(gx0, gx1 + 1):
                    cc = gy * nx + gx
                    for q in range(cell_start[cc], cell_start[cc + 1]):
                        j = cell_list[q]
                        if j >= i:
                            continue
                        dx = x[i, 0] - x[j, 0]
                        dy = x[i, 1] - x[j, 1]
                        rr = radius[i] + radius[j] + pad
                        if dx * dx + dy * dy <= rr * rr:
                            if not include_bonded and _bonded(j, i, bond_start, bond_partner, bond_active):
                                continue
                            if nc < cap:
                                cand[nc, 0] = j
                                cand[nc, 1] = i
                            nc += 1
    # ---- large particles against everything
    for q in range(large_idx.shape[0]):
        L = large_idx[q]
        for j in range(n):
            if j == L or (is_large[j] and j > L):
                continue
            dx = x[L, 0] - x[j, 0]
            dy = x[L, 1] - x[j, 1]
            rr = radius[L] + radius[j] + pad
            if dx * dx + dy * dy <= rr * rr:
                a = min(L, j)
                b = max(L, j)
                if not include_bonded and _bonded(a, b, bond_start, bond_partner, bond_active):
                    continue
                if nc < cap:
                    cand[nc, 0] = a
                    cand[nc, 1] = b
                nc += 1
    if nc > cap:
        return -nc
    return nc


def large_particle_mask(radius: np.ndarray, factor: float = 4.0) -> np.ndarray:
    """Particles whose bounding radius exceeds ``factor`` times the median radius."""
    if len(radius) == 0:
        return np.zeros(0, bool)
    med = float(np.median(radius))
    return radius > factor * med
