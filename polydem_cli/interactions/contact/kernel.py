"""Contact pass: search, shared pair geometry, normal and tangential sub-models.

One function serves both evaluations of the staggered scheme (thesis Fig. 3.6,
App. A.2/A.3; SPEC.md §4.3):

* ``final = False`` — provisional history and function evaluation at the
  predicted state: forces only, the provisional ``u_t``, ``u_t^pl`` are not kept;
* ``final = True`` — final history update at the corrected state: the new
  contact list with ``(u_t, u_t^pl, v_t)`` per pair is written to ``hnew``;
  energies, dissipation and diagnostics are accumulated; the forces at the
  corrected state are returned too (used for reactions and the work of supports).

History lives with the contact (GUIDE practice 6): ``hold``/``hnew`` hold
parallel arrays over contacts, indexed per particle pair ``(a, b)``, ``a < b``,
through a CSR table keyed by ``a``.  A pair missing from ``hold`` starts a new
contact with ``u_t = u_t^pl = v_t = 0`` (footnotes 2–3 of thesis §4.3.2); pairs no
longer in contact drop out.

Pair parameters are mixed from per-particle values in the kernel (thesis (4.4),
(4.8), (4.15), (4.17)), so a single particle can carry its own k_n (symmetry
breaking, thesis §6.2).  Pair convention: I = a (smaller particle number), II = b; ``n`` points from I
to II, ``t = [−n2, n1]`` (open point O-5); II receives the opposite force at
``K`` with its own lever arm.
"""
from __future__ import annotations

from collections import namedtuple

import numpy as np
from numba import njit

from ...engine.search import find_candidates
from .geometry import CONTACT, CONTAINED, NO_CONTACT, pair_geometry, world_vertices
from .normal import area_normal_force, harmonic_pair, mean_pair
from .tangential import COULOMB, coulomb_update

#: kn, gn, kt, mu: per-particle values (n,), mixed per pair by (4.4), (4.8), (4.15), (4.17)
ContactParams = namedtuple("ContactParams", ["kn", "gn", "kt", "mu", "tangential", "area_tol",
                                             "cell_size"])
ContactWork = namedtuple("ContactWork", ["world_v", "cand", "cell_count", "cell_start", "cell_list",
                                         "cell_of", "scratch", "iscratch", "geo"])
ContactHist = namedtuple("ContactHist", ["meta", "a", "b", "ut", "upl", "vt", "start", "perm"])

#: indices into the ``stats`` array filled by a final pass
ST_E_EL = 0  # elastic energy stored in contacts (normal + tangential), g cm² s⁻²
ST_D_RATE = 1  # dissipation rate of the normal model (viscous / cut-off), erg/s
ST_D_FRIC = 2  # friction dissipation during this step, erg
ST_NC = 3  # number of contacts
ST_MAXA = 4  # largest overlap area A_n, cm²
ST_MAXA_RATIO = 5  # largest A_n / (smaller particle area)
ST_NCONT = 6  # pairs found with one polygon inside the other
ST_MAX_UT_EL = 7  # largest |u_t − u_t^pl|, cm
ST_PAIR_A = 8  # first pair found contained (for the warning), -1 if none
ST_PAIR_B = 9
ST_MAXA_A = 10  # the pair with the largest A_n / smaller area
ST_MAXA_B = 11
N_STATS = 12


def empty_history(n: int, cap: int) -> ContactHist:
    return ContactHist(np.zeros(1, np.int64), np.zeros(cap, np.int64), np.zeros(cap, np.int64),
                       np.zeros(cap), np.zeros(cap), np.zeros(cap), np.zeros(n + 1, np.int64),
                       np.zeros(cap, np.int64))


def make_work(n: int, nv_total: int, max_nv: int, cap: int, ncell_cap: int) -> ContactWork:
    sc = 2 * (2 * max_nv) + 8
    return ContactWork(np.zeros((nv_total, 2)), np.zeros((cap, 2), np.int64),
                       np.zeros(ncell_cap, np.int64), np.zeros(ncell_cap + 1, np.int64),
                       np.zeros(max(n, 1), np.int64), np.zeros(max(n, 1), np.int64),
                       np.zeros((4, sc, 2)), np.zeros((4, sc), np.int64), np.zeros(8))


@njit(cache=True)
def _lookup(h, a, b):
    """Index of pair (a, b) in history ``h`` or -1."""
    for q in range(h.start[a], h.start[a + 1]):
        k = h.perm[q]
        if h.b[k] == b:
            return k
    return -1


@njit(cache=True)
def _build_index(h, n):
    """CSR table of ``h`` keyed by the first particle (counting sort, no allocation)."""
    m = h.meta[0]
    for i in range(n + 1):
        h.start[i] = 0
    for k in range(m):
        h.start[h.a[k] + 1] += 1
    for i in range(n):
        h.start[i + 1] += h.start[i]
    for k in range(m):  # scatter, using start[a] as a moving pointer ...
        a = h.a[k]
        h.perm[h.start[a]] = k
        h.start[a] += 1
    for i in range(n, 0, -1):  # ... then shift the pointers back
        h.start[i] = h.start[i - 1]
    h.start[0] = 0


@njit(cache=True)
def contact_pass(final, x, v, dt, vert_start, body_v, radius, area, thickness, group, is_large,
                 large_idx, cp, cw, hold, hnew, bond_start, bond_partner, bond_active, F, stats):
    """Add contact forces to ``F``; in a final pass also update the history (see module doc).

    Returns 0, or ``-needed`` if the candidate buffer is too small (nothing was
    committed; the caller enlarges the buffers and repeats the step).
    """
    n = x.shape[0]
    world_vertices(x, vert_start, body_v, cw.world_v)
    nc = find_candidates(x, radius, is_large, large_idx, cp.cell_size, cw.cell_count, cw.cell_start,
                         cw.cell_list, cw.cell_of, cw.cand, bond_start, bond_partner, bond_active, 0.0)
    if nc < 0:
        return nc
    tang = cp.tangential
    m = 0
    e_el = 0.0
    d_rate = 0.0
    d_fric = 0.0
    ncont = 0
    maxA = 0.0
    maxAr = 0.0
    mpa = -1
    mpb = -1
    max_ut = 0.0
    pa = -1
    pb = -1
    wv = cw.world_v
    geo = cw.geo
    for k in range(nc):
        a = cw.cand[k, 0]
        b = cw.cand[k, 1]
        sa = vert_start[a]
        sb = vert_start[b]
        st = pair_geometry(wv[sa:vert_start[a + 1]], vert_start[a + 1] - sa,
                           wv[sb:vert_start[b + 1]], vert_start[b + 1] - sb,
                           x[a, :2], radius[a], x[b, :2], radius[b], area[a], area[b],
                           cp.area_tol, cw.scratch, cw.iscratch, geo)
        if st == NO_CONTACT:
            continue
        A = geo[0]
        if final:
            if A > maxA:
                maxA = A
            r = A / min(area[a], area[b])
            if r > maxAr:
                maxAr = r
                mpa = a
                mpb = b
        if st == CONTAINED:
            # zero force (A_n is locally constant); counted and reported by the driver
            if final:
                ncont += 1
                if pa < 0:
                    pa = a
                    pb = b
            continue
        B = geo[1]
        n1 = geo[2]
        n2 = geo[3]
        t1 = -n2
        t2 = n1
        raX = geo[4] - x[a, 0]
        raY = geo[5] - x[a, 1]
        rbX = geo[4] - x[b, 0]
        rbY = geo[5] - x[b, 1]
        # relative velocity of II with respect to I at K (4.7)
        vx = v[b, 0] - v[a, 0] - v[b, 2] * rbY + v[a, 2] * raY
        vy = v[b, 1] - v[a, 1] + v[b, 2] * rbX - v[a, 2] * raX
        vn = vx * n1 + vy * n2
        vt = vx * t1 + vy * t2
        T = min(thickness[a], thickness[b])
        kn = harmonic_pair(cp.kn[a], cp.kn[b])
        fn, fel = area_normal_force(A, B, vn, kn, mean_pair(cp.gn[a], cp.gn[b]), T)
        ft = 0.0
        if tang == COULOMB:
            kt = harmonic_pair(cp.kt[a], cp.kt[b])
            h = _lookup(hold, a, b)
            if h >= 0:
                ut0 = hold.ut[h]
                upl0 = hold.upl[h]
                vt0 = hold.vt[h]
            else:
                ut0 = 0.0
                upl0 = 0.0
                vt0 = 0.0
            ut, upl, ft, dl = coulomb_update(ut0, upl0, vt0, vt, dt, kt, harmonic_pair(cp.mu[a], cp.mu[b]), fel, T)
            if final:
                hnew.a[m] = a
                hnew.b[m] = b
                hnew.ut[m] = ut
                hnew.upl[m] = upl
                hnew.vt[m] = vt
                m += 1
                uel = ut - upl
                e_el += 0.5 * kt * uel * uel * T
                d_fric += abs(ft) * dl
                if abs(uel) > max_ut:
                    max_ut = abs(uel)
        if final:
            stats[ST_NC] += 1
            e_el += 0.5 * kn * A * A * T
            d_rate += (fn - fel) * vn
        fx = fn * n1 + ft * t1
        fy = fn * n2 + ft * t2
        F[a, 0] += fx
        F[a, 1] += fy
        F[a, 2] += raX * fy - raY * fx
        F[b, 0] -= fx
        F[b, 1] -= fy
        F[b, 2] -= rbX * fy - rbY * fx
    if final:
        hnew.meta[0] = m
        _build_index(hnew, n)
        stats[ST_E_EL] += e_el
        stats[ST_D_RATE] += d_rate
        stats[ST_D_FRIC] += d_fric
        stats[ST_MAXA] = max(stats[ST_MAXA], maxA)
        if maxAr > stats[ST_MAXA_RATIO]:
            stats[ST_MAXA_RATIO] = maxAr
            stats[ST_MAXA_A] = mpa
            stats[ST_MAXA_B] = mpb
        stats[ST_NCONT] += ncont
        stats[ST_MAX_UT_EL] = max(stats[ST_MAX_UT_EL], max_ut)
        if pa >= 0 and stats[ST_PAIR_A] < 0:
            stats[ST_PAIR_A] = pa
            stats[ST_PAIR_B] = pb
    return 0


@njit(cache=True)
def copy_history(src, dst, n):
    m = src.meta[0]
    dst.meta[0] = m
    for k in range(m):
        dst.a[k] = src.a[k]
        dst.b[k] = src.b[k]
        dst.ut[k] = src.ut[k]
        dst.upl[k] = src.upl[k]
        dst.vt[k] = src.vt[k]
        dst.perm[k] = src.perm[k]
    for i in range(n + 1):
        dst.start[i] = src.start[i]
