"""The halo exchange of a run decomposed over MPI ranks, as the first element of the compiled loop's family tuple
(engine/families.py ``compose``): its ``pass_`` refreshes the ghosts before every force evaluation, and its ``settle``
ends every evaluation with one reduction that takes the ranks' decisions together — the room the families need, a
non-finite force, ghosts that may be outrun — with the sums over the ranks the families ask for (engine/distributed.py
says how).  So the ranks meet twice per force evaluation, and at no other time within a step.  Every scene's tuple starts
with a Halo bundle — an inert one (zero-length ``acc``: its hooks are skipped) in a serial run — so that the loop
has one type, one compiled and cached specialisation, for serial and decomposed runs alike: Numba's cache holding
two specialisations of the loop made a later process crash when it loaded one (2026-12-02, and again with the
first decomposed loop, 2026-12-05).
"""

from __future__ import annotations

from collections import namedtuple

import numpy as np
from numba import njit

from .. import mpicall
from ..interactions.protocol import GO_ON, HALT_PAUSE, LEDGER_HEAD, register_hooks
from ..jit import loop_njit
from .kernels import first_nonfinite

#: the halo exchange: nbr: neighbour ranks; send_start/send_idx: local indices of owned particles to send to
#: neighbour q (send_idx[send_start[q]:send_start[q+1]]); recv_*: local indices of ghosts each neighbour sends;
#: sbuf/rbuf: w = 6 + fwd.shape[1] doubles per particle; red (1): 1 when the part must be remade (this rank's after the final pass, the
#: ranks' after ``settle``); mine: local indices of the owned particles (large ones aside); xref: their (x1, x2) when the part was made;
#: rad: their bounding radii; lim: [(e/2)², e/2, R_max + reach + 1.5 e] (``_outrun``) with e half the ghost layer's
#: margin; boxes (P, 4): every rank's box (x_lo, x_hi, y_lo, y_hi); wstart/wrank: per owned particle
#: (CSR) the ranks near its box that do not hold it (the ranks it must keep away from: see ``_outrun``); lsum/tsum
#: (LEDGER_HEAD + k): this rank's part and the ranks' sum of the evaluation's reduction (``settle``): [0] the room,
#: [1] a non-finite force, [2] ghosts outrun, then the families' sums; tpart/tdof (k): the F entry each sum is added to (−1: none, the family reads it); acc: [exchanges
#: made] (non-empty: never inert); fwd (n, k): a family's per-particle field sent with the positions, the owners' rows
#: overwriting the ghosts' (``Family.ghost_field``; k = 0: none)
Halo = namedtuple(
    "Halo",
    [
        "mpi",
        "nbr",
        "send_start",
        "send_idx",
        "recv_start",
        "recv_idx",
        "sbuf",
        "rbuf",
        "red",
        "mine",
        "xref",
        "rad",
        "lim",
        "boxes",
        "wstart",
        "wrank",
        "lsum",
        "tsum",
        "tpart",
        "tdof",
        "acc",
        "fwd",
    ],
)
TAG = 36


@loop_njit
def exchange(h, final, x, v):
    """Positions and velocities of the owned particles to the neighbours that hold them as ghosts, and of the
    ghosts from their owners (non-blocking sends and receives, then one wait); before a final evaluation also the
    rows of the field a family asked to have on its ghosts (``fwd``: what it computed for its own particles in the
    provisional pass, for its final pass; Family.ghost_field).  ``final`` is the same on every rank, so sender and
    receiver agree on the message's width."""
    nf = h.fwd.shape[1] if final else 0
    w = 6 + nf
    k = 0
    for q in range(h.nbr.shape[0]):
        r0, r1 = h.recv_start[q], h.recv_start[q + 1]
        if r1 > r0:
            mpicall.irecv(h.mpi, h.rbuf[w * r0 : w * r1], w * (r1 - r0), h.nbr[q], TAG, k)
            k += 1
    for q in range(h.nbr.shape[0]):
        s0, s1 = h.send_start[q], h.send_start[q + 1]
        if s1 > s0:
            for m in range(s0, s1):
                i = h.send_idx[m]
                for d in range(3):
                    h.sbuf[w * m + d] = x[i, d]
                    h.sbuf[w * m + 3 + d] = v[i, d]
                for d in range(nf):
                    h.sbuf[w * m + 6 + d] = h.fwd[i, d]
            mpicall.isend(h.mpi, h.sbuf[w * s0 : w * s1], w * (s1 - s0), h.nbr[q], TAG, k)
            k += 1
    mpicall.waitall(h.mpi, k)
    for m in range(h.recv_idx.shape[0]):
        i = h.recv_idx[m]
        for d in range(3):
            x[i, d] = h.rbuf[w * m + d]
            v[i, d] = h.rbuf[w * m + 3 + d]
        for d in range(nf):
            h.fwd[i, d] = h.rbuf[w * m + 6 + d]
    h.acc[0] += 1.0


@njit(cache=True, inline="always")
def _box_distance(px, py, b):
    dx = max(b[0] - px, px - b[1], 0.0)
    dy = max(b[2] - py, py - b[3], 0.0)
    return np.sqrt(dx * dx + dy * dy)


@loop_njit
def _outrun(h, x):
    """Must the part be remade, because the ghosts may soon no longer hold every partner of an owned particle?

    With e half the ghost layer's margin, the ghosts of every rank hold every partner of its particles while
    (A) each particle lies within e of its owner's box and (B) each lies farther than its radius + R_max + reach + e
    from the box of every rank that does not hold it: a partner j of an owned i lies within e + R_i + R_j + reach
    of the box of i's owner.  Both hold when the part is made (j is not held only if farther than
    R_j + R_max + reach + 2e from the box).  The test asks for them with half the slack: (A') within e/2 of the own
    box (``lim[1]``), (B') farther than R + R_max + reach + 1.5e (``lim[2]`` + R): the step on which it first fails
    (and which is committed before the part is remade) still satisfies (A) and (B) unless a particle moved more
    than e/2 in that one step.  A particle that has moved less than e/2 since the cut satisfies (A') and (B'); only
    one that has moved farther is tested, against its own box and the near ranks that do not hold it (``wrank``).
    So a particle swept along a boundary, or deep inside its box, does not make the part remade."""
    e2, e, near = h.lim[0], h.lim[1], h.lim[2]
    me = h.mpi.rank[0]
    for m in range(h.mine.shape[0]):
        i = h.mine[m]
        dx = x[i, 0] - h.xref[m, 0]
        dy = x[i, 1] - h.xref[m, 1]
        if dx * dx + dy * dy <= e2:
            continue
        if _box_distance(x[i, 0], x[i, 1], h.boxes[me]) > e:
            return True
        for k in range(h.wstart[m], h.wstart[m + 1]):
            if _box_distance(x[i, 0], x[i, 1], h.boxes[h.wrank[k]]) <= h.rad[m] + near:
                return True
    return False


@loop_njit
def _halo_pass(fam, final, x, v, dt, F):
    exchange(fam, final, x, v)
    # this rank's part of the decision to remake the parts, summed over the ranks by settle (the halt reads it)
    fam.red[0] = 1.0 if final and _outrun(fam, x) else 0.0
    return 0


@loop_njit
def _halo_halt(fam):
    """Pause after the step once the ghosts of some rank may no longer hold every interaction partner (``_outrun``,
    agreed in ``settle``): the Python side then redistributes the particles (engine/distributed.py)."""
    return HALT_PAUSE if fam.red[0] > 0.0 else GO_ON


@loop_njit
def _halo_settle(fam, value, F):
    """The evaluation's one reduction (protocol.py ``settle``): the room (``value`` < 0: a family asked for some;
    the step is repeated on every rank), a non-finite force on this rank (checked here, before the reduction, so
    that no rank corrects, commits or checkpoints positions the others would not: a finite force gives a finite
    corrected state) and this rank's ghosts outrun (its pass), summed over the ranks with the families' sums, each
    then added to its F entry (what counts is the owner's: a ghost's force is discarded, its state comes from its
    owner at the next exchange)."""
    bad = first_nonfinite(F)
    fam.lsum[0] = float(value)
    fam.lsum[1] = 1.0 if bad >= 0 else 0.0
    fam.lsum[2] = fam.red[0]
    mpicall.allreduce(fam.mpi, fam.lsum, fam.tsum, mpicall.SUM)
    nonfinite = fam.tsum[1] > 0.0
    for k in range(fam.tpart.shape[0]):
        s = fam.tsum[LEDGER_HEAD + k]
        if not np.isfinite(s):
            nonfinite = True
        p = fam.tpart[k]
        if p >= 0:
            F[p, fam.tdof[k]] += s
    fam.red[0] = 1.0 if fam.tsum[2] > 0.0 else 0.0  # the halt pauses on every rank alike
    if fam.tsum[0] < 0.0:
        return np.int64(fam.tsum[0])  # the ranks' needs summed
    if nonfinite:
        return np.int64(1 + (bad if bad >= 0 else F.shape[0]))
    return np.int64(0)


register_hooks(Halo, pass_=_halo_pass, settle=_halo_settle, halt=_halo_halt)


def inert_halo() -> Halo:
    """The Halo of a serial run: nothing to exchange, hooks skipped (zero-length ``acc``), no MPI."""
    zi = np.zeros(0, np.int64)
    api = mpicall.inert_api()
    return Halo(
        api,
        zi,
        np.zeros(1, np.int64),
        zi,
        np.zeros(1, np.int64),
        zi,
        np.zeros(1),
        np.zeros(1),
        np.zeros(1),
        zi,
        np.zeros((0, 2)),
        np.zeros(0),
        np.zeros(3),
        np.zeros((1, 4)),
        np.zeros(1, np.int64),
        zi,
        np.zeros(1),
        np.zeros(1),
        zi,
        zi,
        np.zeros(0),
        np.zeros((0, 0)),
    )
