"""Contact pass: search, shared pair geometry, normal and tangential sub-models.

One function serves both evaluations of the staggered scheme (thesis Fig. 3.6,
App. A.2/A.3):

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

Pair parameters come from a table mixed once per pair of parameter classes before
the run (thesis (4.4), (4.8), (4.15), (4.17); family.py ``mixed_table``), so a single
particle can still carry its own k_n (symmetry breaking, thesis §6.2).  Pair convention: I = a (smaller particle number), II = b; ``n`` points from I
to II, ``t = [−n2, n1]`` (open point O-5); II receives the opposite force at
``K`` with its own lever arm.
"""

from __future__ import annotations

from collections import namedtuple

import numpy as np
from numba import njit, prange

from ...jit import loop_njit, named_copy
from ..search import csr_by_key, find_candidates
from .geometry import CONTAINED, NO_CONTACT, pair_geometry, separation_lower_bound, world_vertices
from .normal import area_normal_force
from .tangential import COULOMB, coulomb_update

#: cls: (n,) parameter class of each particle; mix: (C, C, 4) the pair parameters k_n, γ_n, k_t, μ_t of two
#: classes, mixed once by (4.4), (4.8), (4.15), (4.17) (``MIX_*``; family.py ``mixed_table``);
#: buffer: extra distance of the pair list (0: the thesis's search at every evaluation)
ContactParams = namedtuple("ContactParams", ["cls", "mix", "tangential", "area_tol", "cell_size", "buffer"])
MIX_KN = 0
MIX_GN = 1
MIX_KT = 2
MIX_MU = 3
#: work arrays; the per-candidate results (pr_*) are filled in parallel and reduced serially.
#: ``x_build`` (n, 3): positions when the buffered pair list was built; ``cand_gap``: for each
#: listed pair a lower bound of the distance of the two polygons at that moment; ``motion``:
#: per particle a bound of how far any of its points has moved since, |Δx| + r |Δφ|
ContactWork = namedtuple(
    "ContactWork",
    [
        "world_v",
        "cand",
        "cell_count",
        "cell_start",
        "cell_list",
        "cell_of",
        "scratch",
        "iscratch",
        "dscratch",
        "pr_i",
        "pr_f",
        "pr_h",
        "list_meta",
        "x_build",
        "cand_gap",
        "motion",
        "own",  # (n,) 1 for a particle this process owns, 0 for a ghost (engine/distributed.py)
    ],
)
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
ST_REBUILDS = 12  # pair-list builds in this evaluation (0 or 1)
N_STATS = 13

# per-candidate result layout
PI_STATUS = 0  # pr_i[k, 0]: NO_CONTACT / CONTACT / CONTAINED
PF_FX, PF_FY, PF_CA, PF_CB, PF_A, PF_RATIO, PF_EEL, PF_DRATE, PF_DFRIC, PF_UEL = range(10)
PH_UT, PH_UPL, PH_VT = range(3)
#: list_meta: [number of listed pairs, builds so far]
LM_N = 0
LM_BUILDS = 1

#: chunks of the pair stage (each with its own scratch buffers); more chunks than threads balance the load
_NCHUNK = 64


def empty_history(n: int, cap: int) -> ContactHist:
    """A contact history with room for ``cap`` pairs of ``n`` particles and none in it."""
    return ContactHist(
        np.zeros(1, np.int64),
        np.zeros(cap, np.int64),
        np.zeros(cap, np.int64),
        np.zeros(cap),
        np.zeros(cap),
        np.zeros(cap),
        np.zeros(n + 1, np.int64),
        np.zeros(cap, np.int64),
    )


@njit(cache=True)
def _drop_ghost_pairs(cand, nc, own):
    """Keep the candidate pairs with at least one owned particle (a pair of two ghosts of a decomposed run concerns
    other ranks only; engine/distributed.py), in their order; the new count.  A whole scene keeps every pair."""
    m = 0
    for k in range(nc):
        a = cand[k, 0]
        b = cand[k, 1]
        if own[a] != 0 or own[b] != 0:
            cand[m, 0] = a
            cand[m, 1] = b
            m += 1
    return m


def make_work(n: int, nv_total: int, max_nv: int, cap: int, ncell_cap: int, own=None) -> ContactWork:
    """Work arrays of the contact pass: world vertices, the candidate list and its cells, the per-chunk clipping
    scratch, the per-pair results, for ``n`` particles of ``nv_total`` vertices in all (at most ``max_nv`` each),
    ``cap`` pairs and ``ncell_cap`` cells.  ``own``: which particles this process owns (default all): a pair counts
    in the statistics on the rank owning its smaller index."""
    sc = 2 * (2 * max_nv) + 8
    return ContactWork(
        np.zeros((nv_total, 2)),
        np.zeros((cap, 2), np.int64),
        np.zeros(ncell_cap, np.int64),
        np.zeros(ncell_cap + 1, np.int64),
        np.zeros(max(n, 1), np.int64),
        np.zeros(max(n, 1), np.int64),
        np.zeros((_NCHUNK, 3, sc, 2)),
        np.zeros((_NCHUNK, 4, sc), np.int64),
        np.zeros((_NCHUNK, sc)),
        np.zeros((cap, 1), np.int64),
        np.zeros((cap, 10)),
        np.zeros((cap, 3)),
        np.array([-1, 0], np.int64),
        np.zeros((max(n, 1), 3)),
        np.zeros(cap),
        np.zeros(max(n, 1)),
        np.ones(max(n, 1), np.int64) if own is None else np.asarray(own, np.int64),
    )


@loop_njit
def _build_index(h, n):
    """CSR table of ``h`` keyed by the first particle (``h.start``, ``h.perm``)."""
    csr_by_key(h.a, h.meta[0], n, h.start, h.perm)


def _pairs_impl(x, v, dt, g, cp, cw, hold, links):
    """Geometry and force of every listed pair, independent across pairs (chunks in prange).

    ``g``, ``cp``, ``cw``, ``hold``, ``links``: the polygons, pair parameters, work arrays, contact history
    of the last step and bonded pairs, as :func:`contact_pass` receives them (namedtuples).  Their arrays are
    bound to locals here, before the ``prange``: numba silently drops writes made through a namedtuple
    field inside ``prange`` (numba issues #5872, #7135, #10338); writes through a local array are kept.
    Each chunk has its own scratch buffers.
    """
    ncand = cw.list_meta[LM_N]
    vert_start = g.vert_start
    radius = g.radius
    area = g.area
    thickness = g.thickness
    tang = cp.tangential
    area_tol = cp.area_tol
    cls = cp.cls
    mix = cp.mix
    cand = cw.cand
    wv = cw.world_v
    scratch = cw.scratch
    iscratch = cw.iscratch
    dscratch = cw.dscratch
    pr_i = cw.pr_i
    pr_f = cw.pr_f
    pr_h = cw.pr_h
    gap = cw.cand_gap
    motion = cw.motion
    hb = hold.b
    hut = hold.ut
    hupl = hold.upl
    hvt = hold.vt
    hstart = hold.start
    hperm = hold.perm
    bstart = links.start
    bpartner = links.partner
    bactive = links.active
    nch = scratch.shape[0]
    per = (ncand + nch - 1) // nch
    for c in prange(nch):
        lo = c * per
        hi = min(ncand, lo + per)
        bufA = scratch[c, 0]
        bufB = scratch[c, 1]
        crs = scratch[c, 2]
        dist = dscratch[c]
        labA = iscratch[c, 0]
        labB = iscratch[c, 1]
        selI = iscratch[c, 2]
        selII = iscratch[c, 3]
        for k in range(lo, hi):
            pr_i[k, 0] = NO_CONTACT
            a = cand[k, 0]
            b = cand[k, 1]
            if bstart.shape[0] > a + 1:  # pairs joined by an active bond do not interact by contact
                bonded = False
                for q in range(bstart[a], bstart[a + 1]):
                    if bpartner[q] == b and bactive[q]:
                        bonded = True
                        break
                if bonded:
                    continue
            # the polygons were this far apart when the list was built and have not moved enough since
            # to touch (0 when they touched then, or without a buffered list): no overlap, no contact
            if gap[k] > motion[a] + motion[b]:
                continue
            # contact history of the pair (tangential model): also tells that it touched last step
            h = -1
            if tang == COULOMB:
                for q in range(hstart[a], hstart[a + 1]):
                    kk = hperm[q]
                    if hb[kk] == b:
                        h = kk
                        break
            sa = vert_start[a]
            sb = vert_start[b]
            pg = pair_geometry(
                wv,
                sa,
                vert_start[a + 1] - sa,
                sb,
                vert_start[b + 1] - sb,
                x[a, 0],
                x[a, 1],
                radius[a],
                x[b, 0],
                x[b, 1],
                radius[b],
                area[a],
                area[b],
                area_tol,
                bufA,
                bufB,
                crs,
                dist,
                labA,
                labB,
                selI,
                selII,
                h >= 0,
            )
            st = pg.status
            pr_i[k, 0] = st
            if st == NO_CONTACT:
                continue
            A = pg.overlap_area
            pr_f[k, PF_A] = A
            pr_f[k, PF_RATIO] = A / min(area[a], area[b])
            if st == CONTAINED:
                continue
            B = pg.line_width
            n1 = pg.n1
            n2 = pg.n2
            t1 = -n2
            t2 = n1
            raX = pg.k1 - x[a, 0]
            raY = pg.k2 - x[a, 1]
            rbX = pg.k1 - x[b, 0]
            rbY = pg.k2 - x[b, 1]
            # relative velocity of II with respect to I at K (4.7)
            vx = v[b, 0] - v[a, 0] - v[b, 2] * rbY + v[a, 2] * raY
            vy = v[b, 1] - v[a, 1] + v[b, 2] * rbX - v[a, 2] * raX
            vn = vx * n1 + vy * n2
            vt = vx * t1 + vy * t2
            T = min(thickness[a], thickness[b])
            ca = cls[a]
            cb = cls[b]
            kn = mix[ca, cb, MIX_KN]
            fn, fel = area_normal_force(A, B, vn, kn, mix[ca, cb, MIX_GN], T)
            ft = 0.0
            eel = 0.5 * kn * A * A * T
            dfric = 0.0
            uel = 0.0
            if tang == COULOMB:
                kt = mix[ca, cb, MIX_KT]
                if h >= 0:
                    ut0 = hut[h]
                    upl0 = hupl[h]
                    vt0 = hvt[h]
                else:
                    ut0 = 0.0
                    upl0 = 0.0
                    vt0 = 0.0
                ut, upl, ft, dl = coulomb_update(ut0, upl0, vt0, vt, dt, kt, mix[ca, cb, MIX_MU], fel, T)
                pr_h[k, PH_UT] = ut
                pr_h[k, PH_UPL] = upl
                pr_h[k, PH_VT] = vt
                uel = ut - upl
                eel += 0.5 * kt * uel * uel * T
                dfric = abs(ft) * dl
            fx = fn * n1 + ft * t1
            fy = fn * n2 + ft * t2
            pr_f[k, PF_FX] = fx
            pr_f[k, PF_FY] = fy
            pr_f[k, PF_CA] = raX * fy - raY * fx
            pr_f[k, PF_CB] = rbX * fy - rbY * fx
            pr_f[k, PF_EEL] = eel
            pr_f[k, PF_DRATE] = (fn - fel) * vn
            pr_f[k, PF_DFRIC] = dfric
            pr_f[k, PF_UEL] = abs(uel)


#: only the threaded compilation: numba compiles a prange body as a function of its own whose array
#: arguments are marked ``noalias``; for this kernel that is 2x faster than the plain serial
#: compilation even on one thread and for 33 candidates (docs/performance.md), so there is no
#: serial variant.  The thread count is numba's (``--threads``); one thread costs ~1 µs per call.
_pairs = njit(cache=True, parallel=True)(named_copy(_pairs_impl, "_pairs_threaded"))


@loop_njit
def _list_valid(x, radius, cw, half_buffer):
    """The buffered pair list holds every overlapping pair while no particle has moved more than
    half the buffer since it was built (bounding circles are centred on the centroids).

    Also fills ``cw.motion``: a bound of the distance any point of particle i has moved since
    the build, |Δx_i| + r_i |Δφ_i| (a rigid rotation by Δφ moves a point at distance ρ ≤ r by
    2ρ|sin(Δφ/2)| ≤ r|Δφ|).  Two polygons whose distance was g at the build cannot overlap while
    motion_a + motion_b < g.
    """
    if cw.list_meta[LM_N] < 0:
        return False
    lim = half_buffer * half_buffer
    for i in range(x.shape[0]):
        dx = x[i, 0] - cw.x_build[i, 0]
        dy = x[i, 1] - cw.x_build[i, 1]
        d2 = dx * dx + dy * dy
        if d2 > lim:
            return False
        cw.motion[i] = np.sqrt(d2) + radius[i] * abs(x[i, 2] - cw.x_build[i, 2])
    return True


#: a listed pair is skipped only if its polygons were farther apart than the motion since the build
#: plus this fraction of the sum of the bounding radii (round-off of the world vertices is ~1e-16 of
#: the coordinates)
GAP_MARGIN = 1e-9


def _gaps_impl(ncand, cand, wv, vert_start, radius, gap):
    """``gap[k]``: lower bound of the distance of the polygons of listed pair k (0 if they touch)."""
    for k in prange(ncand):
        a = cand[k, 0]
        b = cand[k, 1]
        sa = vert_start[a]
        sb = vert_start[b]
        g = separation_lower_bound(wv, sa, vert_start[a + 1] - sa, sb, vert_start[b + 1] - sb)
        g -= GAP_MARGIN * (radius[a] + radius[b])
        gap[k] = g if g > 0.0 else 0.0


_gaps = njit(cache=True, parallel=True)(named_copy(_gaps_impl, "_gaps_threaded"))


@loop_njit
def contact_pass(final, x, v, dt, g, cp, cw, hold, hnew, links, F, stats):
    """Add contact forces to ``F``; in a final pass also update the history (see module doc).

    ``g``: the polygons (``vert_start``, ``body_v``, ``radius``, ``area``, ``thickness``, ``is_large``,
    ``large_idx``); ``cp``: :class:`ContactParams`; ``cw``: :class:`ContactWork`; ``hold``/``hnew``: the
    contact history (:class:`ContactHist`) of the last step and of this one; ``links``: the pairs joined by
    a bond (``start``, ``partner``, ``active``).  ``g`` and ``links`` are the family's ``Polygons`` and
    ``BondLinks`` (contact/family.py); any namedtuple with those fields does.

    Stages (a)–(b) build the list of potential pairs — at every evaluation
    (``cp.buffer == 0``, the thesis) or, with a buffer distance, only when a
    particle has moved more than half the buffer since the list was built (the
    thesis's suggestion, §4.1); pairs joined by an active bond are skipped.
    Stages (c)–(d) and the force of every listed pair run in parallel for long
    lists; forces and history are then reduced serially in list order, so the
    result does not depend on the number of threads.

    Returns 0, or ``-needed`` if the candidate buffer is too small (nothing was
    committed; the caller enlarges the buffers and repeats the step).
    """
    n = x.shape[0]
    world_vertices(x, g.vert_start, g.body_v, cw.world_v)
    rebuilt = 0
    if cp.buffer <= 0.0 or not _list_valid(x, g.radius, cw, 0.5 * cp.buffer):
        nc = find_candidates(
            x,
            g.radius,
            g.is_large,
            g.large_idx,
            cp.cell_size,
            cw.cell_count,
            cw.cell_start,
            cw.cell_list,
            cw.cell_of,
            cw.cand,
            links.start,
            links.partner,
            links.active,
            cp.buffer,
            cp.buffer > 0.0,
        )
        if nc < 0:
            cw.list_meta[LM_N] = -1
            return nc
        nc = _drop_ghost_pairs(cw.cand, nc, cw.own)
        cw.list_meta[LM_N] = nc
        cw.list_meta[LM_BUILDS] += 1
        rebuilt = 1
        for i in range(n):
            cw.x_build[i, 0] = x[i, 0]
            cw.x_build[i, 1] = x[i, 1]
            cw.x_build[i, 2] = x[i, 2]
            cw.motion[i] = 0.0
        if cp.buffer > 0.0:
            _gaps(nc, cw.cand, cw.world_v, g.vert_start, g.radius, cw.cand_gap)
        else:  # a list rebuilt at every evaluation: nothing to skip
            for k in range(nc):
                cw.cand_gap[k] = 0.0
    nc = cw.list_meta[LM_N]
    _pairs(x, v, dt, g, cp, cw, hold, links)
    # serial reduction in list order
    tang = cp.tangential
    m = 0
    e_el = 0.0
    d_rate = 0.0
    d_fric = 0.0
    ncont = 0
    ncontact = 0
    maxA = 0.0
    maxAr = 0.0
    mpa = -1
    mpb = -1
    max_ut = 0.0
    pa = -1
    pb = -1
    for k in range(nc):
        st = cw.pr_i[k, 0]
        if st == NO_CONTACT:
            continue
        a = cw.cand[k, 0]
        b = cw.cand[k, 1]
        counted = final and cw.own[a if a < b else b] != 0  # statistics on one rank only
        if counted:
            A = cw.pr_f[k, PF_A]
            if A > maxA:
                maxA = A
            r = cw.pr_f[k, PF_RATIO]
            if r > maxAr:
                maxAr = r
                mpa = a
                mpb = b
        if st == CONTAINED:
            # zero force (A_n is locally constant); counted and reported by the driver
            if counted:
                ncont += 1
                if pa < 0:
                    pa = a
                    pb = b
            continue
        fx = cw.pr_f[k, PF_FX]
        fy = cw.pr_f[k, PF_FY]
        F[a, 0] += fx
        F[a, 1] += fy
        F[a, 2] += cw.pr_f[k, PF_CA]
        F[b, 0] -= fx
        F[b, 1] -= fy
        F[b, 2] -= cw.pr_f[k, PF_CB]
        if counted:
            ncontact += 1
            e_el += cw.pr_f[k, PF_EEL]
            d_rate += cw.pr_f[k, PF_DRATE]
            d_fric += cw.pr_f[k, PF_DFRIC]
            if cw.pr_f[k, PF_UEL] > max_ut:
                max_ut = cw.pr_f[k, PF_UEL]
        if final:
            if tang == COULOMB:
                hnew.a[m] = a
                hnew.b[m] = b
                hnew.ut[m] = cw.pr_h[k, PH_UT]
                hnew.upl[m] = cw.pr_h[k, PH_UPL]
                hnew.vt[m] = cw.pr_h[k, PH_VT]
                m += 1
    if final:
        hnew.meta[0] = m
        _build_index(hnew, n)
        stats[ST_NC] += ncontact
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
        stats[ST_REBUILDS] += rebuilt
        if pa >= 0 and stats[ST_PAIR_A] < 0:
            stats[ST_PAIR_A] = pa
            stats[ST_PAIR_B] = pb
    return 0


@loop_njit
def copy_history(src, dst, n):
    """Copy the first ``src.meta[0]`` contacts of history ``src`` (pairs, tangential state) and its index over ``n``
    particles into ``dst``."""
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
