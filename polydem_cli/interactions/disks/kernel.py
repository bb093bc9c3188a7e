"""Disk contact pass: cohesive frictionless disks and plane walls with the Luding–Herrmann law.

Per evaluation (both passes of the staggered step, interactions/protocol.py):

* disk–disk pairs from a buffered pair list built by the linked-cell search (interactions/search.py;
  polygons are left out of the mesh, there is no polygon clipping) with every pair whose gap is below the
  buffer, rebuilt when a disk or a wall has moved half the buffer: overlap (LH 1.5)
  ``δ = r_a + r_b − |x_a − x_b|``, normal ``n`` from b to a;
* disk–wall pairs of the same list (every disk within the buffer of a wall's face): a wall is a particle
  whose face is the
  plane through ``x_w + off n_w`` with unit normal ``n_w`` pointing into the packing; ``δ = r_i − dist``
  (the same law, open point O-18 of the paper), the wall feels the opposite force (its reaction);
* the force on the first particle is ``(f_hys + γ_0 dδ/dt) n`` (LH 1.6, 1.7) with ``δ_max`` per contact, the
  second receives the opposite; background damping ``−γ_b v`` (LH 1.9) on every disk.

History: the final pass writes the contacts with their new ``δ_max`` to ``hnew`` (in the order found); the
step's ``accept`` sorts them into ``hold`` keyed by the first particle (a CSR table), where the next passes
look a pair up.  A pair not in ``hold`` is a new contact (``δ_max = 0``); a pair no longer overlapping drops
out (δ_max reset, interactions/disks/law.py).

Energies of a final pass: stored energy Σ E(δ, δ_max) (law.py), the dissipation rate of the viscous and
background terms (integrated by the trapezoidal rule in the family's accumulate hook) and the hysteretic
dissipation of the step, Σ [D(δ_max,new) − D(δ_max,old)] with D(m) = ½ k_1 m² − E(m, m): virgin loading is
the law's only irreversible branch, so this is exact, not a quadrature.
"""

from __future__ import annotations

from collections import namedtuple

import numpy as np
from numba import njit

from ...jit import loop_njit
from ..search import csr_by_key, find_candidates
from .law import lh_constants, lh_energy_c, lh_hysteretic_c

#: disk: (m,) particle indices of the disks; r: (n,) disk radius (0 elsewhere); excl: (n,) True for every
#: particle that is not a disk (kept out of the search mesh); wall: (nw,) particle indices of the walls,
#: wall_n (nw, 2) unit normals into the packing, wall_off (nw,) face offset from the wall's centre along n
DiskParams = namedtuple(
    "DiskParams",
    ["disk", "r", "excl", "wall", "wall_n", "wall_off", "k1", "k2", "kc", "g0", "gb", "cell_size", "buffer", "keep"],
)
#: meta: [number of contacts]; (a, b, dmax) per contact; start: CSR by a (n+1), valid in hold only
DiskHist = namedtuple("DiskHist", ["meta", "a", "b", "dmax", "start"])
#: cand (cap, 2) pairs of the buffered list; cell arrays of the search; perm: history sort order; need:
#: [capacity asked for by the last pass]; per wall (last final pass): wf the disks' force on it along its
#: outward normal, wface the coordinate of its face; wcand (nw n, 2): (wall slot, disk) pairs of the buffered
#: list; x_build (n, 2): positions when the list was built; list_meta: [disk pairs in the list (-1: no valid
#: list), builds so far, wall pairs in the list]; own (n,) (empty: every particle, a serial run, which then pays no
#: test per pair): 1 for a particle this process owns, 0 for a ghost of a
#: decomposed run (engine/distributed.py): a pair of two ghosts is skipped, a disk–wall pair evaluated only where
#: the disk is owned (the wall's force is then summed over the ranks), statistics counted on the rank owning the
#: pair's smaller index (the disk's, against a wall)
DiskWork = namedtuple(
    "DiskWork",
    [
        "cand",
        "cell_count",
        "cell_start",
        "cell_list",
        "cell_of",
        "perm",
        "noint",
        "nobool",
        "need",
        "wf",
        "wface",
        "wcand",
        "x_build",
        "list_meta",
        "own",
    ],
)

ST_E_EL = 0  # stored energy Σ E(δ, δ_max)
ST_D_RATE = 1  # viscous + background dissipation rate
ST_D_HYS = 2  # hysteretic dissipation of this step
ST_NC = 3  # disk-disk contacts
ST_NW = 4  # disk-wall contacts
ST_MAX_REL = 5  # largest δ / r of the smaller disk
ST_NATT = 6  # contacts on an attractive branch (f_hys < 0)
ST_DT = 7  # the step's dt (for the trapezoidal rule of the accumulate hook)
N_DSTATS = 8


def empty_history(n: int, cap: int) -> DiskHist:
    """A disk-contact history with room for ``cap`` pairs of ``n`` particles and none in it."""
    return DiskHist(
        np.zeros(1, np.int64),
        np.zeros(cap, np.int64),
        np.zeros(cap, np.int64),
        np.zeros(cap),
        np.zeros(n + 1, np.int64),
    )


def make_work(n: int, cap: int, nw: int = 0, own=None) -> DiskWork:
    """Work arrays of the disk pass for ``n`` particles, ``cap`` pairs and ``nw`` walls (cell list and pair lists);
    ``own``: which particles this process owns (default, or all of them: an empty array, tested nowhere)."""
    ncell = max(64, 4 * n + 64)
    return DiskWork(
        np.zeros((cap, 2), np.int64),
        np.zeros(ncell, np.int64),
        np.zeros(ncell + 1, np.int64),
        np.zeros(max(n, 1), np.int64),
        np.zeros(max(n, 1), np.int64),
        np.zeros(max(cap, 1), np.int64),
        np.zeros(0, np.int64),
        np.zeros(0, np.bool_),
        np.zeros(1, np.int64),
        np.zeros(nw),
        np.zeros(nw),
        np.zeros((max(nw * n, 1), 2), np.int64),
        np.zeros((max(n, 1), 2)),
        np.array([-1, 0, 0], np.int64),
        np.zeros(0, np.int64) if own is None or np.all(own) else np.asarray(own, np.int64),
    )


@njit(cache=True, inline="always")
def _dissipated(m, k1, k2, kc, c0, cmin):
    """D(m): energy dissipated by loading a fresh contact along k_1 to δ_max = m (``c0, cmin``: lh_constants)."""
    return 0.5 * k1 * m * m - lh_energy_c(m, m, k2, kc, c0, cmin)


@njit(cache=True)
def _moved(x, x_build, idx, lim):
    """Has any particle of ``idx`` moved farther than sqrt(lim) since ``x_build``?"""
    for k in range(idx.shape[0]):
        i = idx[k]
        dx = x[i, 0] - x_build[i, 0]
        dy = x[i, 1] - x_build[i, 1]
        if dx * dx + dy * dy > lim:
            return True
    return False


@njit(cache=True)
def _store(x, x_build, idx):
    for k in range(idx.shape[0]):
        i = idx[k]
        x_build[i, 0] = x[i, 0]
        x_build[i, 1] = x[i, 1]


@njit(cache=True, inline="always")
def _remember(a, b, hs, hb, hd, na, nb, nd, nmeta):
    """Option ``delta_max_memory = "pair"``: an open pair carries its δ_max (if any) into the new history."""
    for j in range(hs[a], hs[a + 1]):
        if hb[j] == b:
            if hd[j] > 0.0:
                m = nmeta[0]
                if m < na.shape[0]:
                    na[m] = a
                    nb[m] = b
                    nd[m] = hd[j]
                nmeta[0] = m + 1
            return


@loop_njit
def _list_valid(x, p, w):
    """The buffered list (pairs whose gap was below the buffer at its build) holds every overlapping pair
    while no disk and no wall has moved more than half the buffer since then."""
    if w.list_meta[0] < 0:
        return False
    lim = 0.25 * p.buffer * p.buffer
    return not (_moved(x, w.x_build, p.disk, lim) or _moved(x, w.x_build, p.wall, lim))


@njit(cache=True)
def _wall_gap(x, p, q, i):
    """Distance of disk i's surface from the face of wall slot q (negative: overlap)."""
    wq = p.wall[q]
    dist = (x[i, 0] - x[wq, 0]) * p.wall_n[q, 0] + (x[i, 1] - x[wq, 1]) * p.wall_n[q, 1] - p.wall_off[q]
    return dist - p.r[i]


@loop_njit
def disk_pass(final, x, v, dt, p, hold, hnew, w, F, stats):
    """Add the disk and disk–wall forces at (x, v) to F; in the final pass write hnew and the statistics.
    Returns 0, or −(capacity needed) when the candidate or history buffer is too small (``w.need``).

    The disk–disk and disk–wall pairs come from a buffered list (``p.buffer`` > 0: rebuilt, by the
    linked-cell search and a scan of the walls, only when a disk or a wall has moved more than half the
    buffer; 0: rebuilt at every evaluation)."""
    if p.buffer <= 0.0 or not _list_valid(x, p, w):
        nc = find_candidates(
            x,
            p.r,
            p.excl,
            w.noint,
            p.cell_size,
            w.cell_count,
            w.cell_start,
            w.cell_list,
            w.cell_of,
            w.cand,
            w.noint,
            w.noint,
            w.nobool,
            p.buffer,
            True,
        )
        if nc < 0:
            w.list_meta[0] = -1
            w.need[0] = -nc
            return nc
        nwp = 0
        for q in range(p.wall.shape[0]):
            for k in range(p.disk.shape[0]):
                i = p.disk[k]
                if _wall_gap(x, p, q, i) < p.buffer:
                    w.wcand[nwp, 0] = q
                    w.wcand[nwp, 1] = i
                    nwp += 1
        w.list_meta[0] = nc
        w.list_meta[1] += 1
        w.list_meta[2] = nwp
        _store(x, w.x_build, p.disk)
        _store(x, w.x_build, p.wall)
    nc = w.list_meta[0]
    if final:
        for k in range(N_DSTATS):
            stats[k] = 0.0
        stats[ST_DT] = dt
        hnew.meta[0] = 0
    # One loop over the listed disk pairs, then the listed disk-wall pairs, with the bundle's arrays taken
    # out of their namedtuples first: a helper taking them (or the namedtuples) per pair cost a reference
    # count on each array at every call, 12x the pair's own work (2026-12-02).
    # (the wall gap of _wall_gap is written out below for the same reason)
    r, cand, wcand = p.r, w.cand, w.wcand
    wall, wall_n, wall_off, wf = p.wall, p.wall_n, p.wall_off, w.wf
    k1, k2, kc, g0, keep, own = p.k1, p.k2, p.kc, p.g0, p.keep, w.own
    split = own.shape[0] > 0  # a rank's part of a decomposed run (else every particle is owned)
    c0, cmin = lh_constants(k1, k2, kc)
    hs, hb, hd = hold.start, hold.b, hold.dmax
    na, nb, nd, nmeta = hnew.a, hnew.b, hnew.dmax, hnew.meta
    if final:
        for q in range(wall.shape[0]):
            wq = wall[q]
            wf[q] = 0.0
            nx = wall_n[q, 0]
            w.wface[q] = (x[wq, 0] + wall_off[q] * nx) if nx != 0.0 else (x[wq, 1] + wall_off[q] * wall_n[q, 1])
    nwp = w.list_meta[2]
    for k in range(nc + nwp):
        if k < nc:  # disk a, disk b
            a = cand[k, 0]
            b = cand[k, 1]
            counted = True
            if split:
                if own[a] == 0 and own[b] == 0:  # two ghosts: their owners evaluate it
                    continue
                counted = own[a if a < b else b] != 0
            dx = x[a, 0] - x[b, 0]
            dy = x[a, 1] - x[b, 1]
            d = np.sqrt(dx * dx + dy * dy)
            delta = r[a] + r[b] - d
            if delta <= 0.0 or d == 0.0:
                if keep and final and d != 0.0:  # option: the pair keeps its δ_max while it stays listed
                    _remember(a, b, hs, hb, hd, na, nb, nd, nmeta)
                continue
            nx = dx / d
            ny = dy / d
            rel = delta / min(r[a], r[b])
        else:  # disk a, wall b (slot q)
            q = wcand[k - nc, 0]
            a = wcand[k - nc, 1]
            if split and own[a] == 0:  # a ghost disk: the wall's force from it is summed on the disk's owner
                continue
            counted = True
            b = wall[q]
            nx = wall_n[q, 0]
            ny = wall_n[q, 1]
            delta = r[a] - ((x[a, 0] - x[b, 0]) * nx + (x[a, 1] - x[b, 1]) * ny - wall_off[q])
            if delta <= 0.0:
                if keep and final:
                    _remember(a, b, hs, hb, hd, na, nb, nd, nmeta)
                continue
            rel = delta / r[a]
        ddot = -((v[a, 0] - v[b, 0]) * nx + (v[a, 1] - v[b, 1]) * ny)
        dm_old = 0.0
        for j in range(hs[a], hs[a + 1]):  # the pair's δ_max of the last step (CSR of hold, keyed by a)
            if hb[j] == b:
                dm_old = hd[j]
                break
        fh, dm_new = lh_hysteretic_c(delta, dm_old, k1, k2, kc, c0)
        f = fh + g0 * ddot
        F[a, 0] += f * nx
        F[a, 1] += f * ny
        F[b, 0] -= f * nx
        F[b, 1] -= f * ny
        if final:
            m = nmeta[0]
            if m < na.shape[0]:
                na[m] = a
                nb[m] = b
                nd[m] = dm_new
            nmeta[0] = m + 1
            if not counted:
                continue
            stats[ST_E_EL] += lh_energy_c(delta, dm_new, k2, kc, c0, cmin)
            if dm_new != dm_old:  # loading along k_1 (on the other branches the difference is exactly 0)
                stats[ST_D_HYS] += _dissipated(dm_new, k1, k2, kc, c0, cmin) - _dissipated(dm_old, k1, k2, kc, c0, cmin)
            stats[ST_D_RATE] += g0 * ddot * ddot
            stats[ST_MAX_REL] = max(stats[ST_MAX_REL], rel)
            if fh < 0.0:
                stats[ST_NATT] += 1.0
            if k < nc:
                stats[ST_NC] += 1.0
            else:
                stats[ST_NW] += 1.0
                wf[q] += f
    if p.gb > 0.0:
        for k in range(p.disk.shape[0]):
            i = p.disk[k]
            F[i, 0] -= p.gb * v[i, 0]
            F[i, 1] -= p.gb * v[i, 1]
            if final and (not split or own[i] != 0):
                stats[ST_D_RATE] += p.gb * (v[i, 0] * v[i, 0] + v[i, 1] * v[i, 1])
    if final and hnew.meta[0] > hnew.a.shape[0]:
        w.need[0] = hnew.meta[0]
        return -hnew.meta[0]
    return 0


@loop_njit
def accept_history(hnew, hold, perm):
    """hold ← hnew sorted by the first particle, with its CSR index (``perm``: work array of hnew's capacity)."""
    m = hnew.meta[0]
    csr_by_key(hnew.a, m, hold.start.shape[0] - 1, hold.start, perm)
    for j in range(m):
        k = perm[j]
        hold.a[j] = hnew.a[k]
        hold.b[j] = hnew.b[k]
        hold.dmax[j] = hnew.dmax[k]
    hold.meta[0] = m
