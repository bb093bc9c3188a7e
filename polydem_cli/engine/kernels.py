"""The fixed driver loop of the staggered scheme, compiled with Numba (thesis Fig. 3.6, A.1–A.3).

Per step ``t_{l-1} → t_l``::

    1 predictor            free DOFs: x̌_pd = S x̌_{l-1};  prescribed DOFs: x̂(t_l), v̂(t_l)
    2 provisional history + function evaluation at the predicted state
      (bonds before contacts; contact search on predicted positions)
    3 corrector            free DOFs: x̌_l = x̌_pd + s (f/m Δt²/2 − x̌_pd,3)
    4 final history update at the corrected state (second contact search),
      energies and diagnostics; forces at the corrected state for reactions
    5 the families' halt hooks (a contained pair with the 'abort' policy, the load-drop stop); commit

The interaction models are families (interactions/protocol.py): the tuple ``fams`` of their bundles,
composed once per scene (engine/families.py), is unrolled at compile time, so the loop names no model
and a family a scene does not use costs nothing.

A step is transactional: the new Nordsieck array and every family's new history are written to
separate buffers and committed only at the end, so a step that runs out of buffer space is simply
repeated after the driver let the family grow.

Boundary conditions per DOF: see :mod:`polydem_cli.boundary.prescribed`.
"""

from __future__ import annotations

from collections import namedtuple

import numpy as np
from numba import literal_unroll, njit, prange

from ..boundary.prescribed import BC_KINDS, FIXED, FREE, RAMP, VELOCITY, prescribed  # noqa: F401
from ..interactions.protocol import (
    HALT_ABORT,
    HALT_END,
    HALT_PAUSE,
    fam_accept,
    fam_accumulate,
    fam_begin,
    fam_elastic,
    fam_halt,
    fam_pass,
    fam_row,
    fam_settle,
    fam_work,
)
from ..jit import loop_njit, serial_and_parallel
from .integrators import GEAR5, VERLET1, correct_dof, predict_dof

#: own: 1.0 for a particle this process owns, 0.0 for a ghost copy of another rank's (engine/distributed.py): the
#: energies of the history table count owned particles only (all 1.0 in a serial run: the same sums bit for bit)
Particles = namedtuple("Particles", ["mass", "inertia", "own"])
Boundary = namedtuple("Boundary", ["kind", "vel", "acc", "x0"])
#: the monitored sets: members of set s are idx[start[s]:start[s+1]] (owned ones only on a rank), cnt[s] its size
#: over all ranks (the mean displacement divides by it)
Monitor = namedtuple("Monitor", ["start", "idx", "cnt"])

# ---- history table columns
HISTORY_BASE_COLUMNS = (
    ("time", "s", "simulated time t_l"),
    ("step", "-", "step number l"),
    ("kinetic", "erg", "kinetic energy (2.20) of all particles"),
    ("elastic", "erg", "elastic energy stored in the interactions (contacts, bonds, base friction, disks)"),
    ("potential", "erg", "potential energy of the body force, −Σ m g·x"),
    ("dissipated", "erg", "energy dissipated so far (friction, viscous damping, tension cut-off, damage)"),
    (
        "external_work",
        "erg",
        "work done so far by the supports of prescribed DOFs, the external loads ([[loads]]) and the servo walls",
    ),
    (
        "energy_total",
        "erg",
        "kinetic + elastic + potential + dissipated − external_work (constant for an exact integrator)",
    ),
)
N_BASE = len(HISTORY_BASE_COLUMNS)
SET_COLUMNS = (
    ("u1", "cm", "mean x1 displacement of the set"),
    ("u2", "cm", "mean x2 displacement of the set (the prescribed û2 for a driven set)"),
    ("phi", "rad", "mean rotation of the set"),
    ("f1", "dyn", "−Σ interaction force e1 on the set (reaction; thesis f_2 convention)"),
    ("f2", "dyn", "−Σ interaction force e2 on the set; tension positive for a top set pulled up"),
    ("c", "dyn cm", "−Σ interaction moments on the set, each about its particle's centroid"),
)
N_SET = len(SET_COLUMNS)

# ---- accumulators carried across steps (and checkpointed); the interaction families keep their own
AC_DISS = 0
AC_WEXT = 1
AC_P_PREV = 2
# 3-16: slots of the polygon contact (3-10, 15, 16), bond (11), load-drop (12) and base-friction (13, 14)
# accumulators in checkpoints written before those became families (they restore from there)
N_ACC = 24

# ---- return codes of run_steps
OK = 0
GROW = 1
ABORTED = 2  # a family's halt hook stopped the run with an error (Family.halt_message says why)
NONFINITE = 3
ENDED = 4  # a family's halt hook ended the run (its end criterion, e.g. the load drop)
PAUSED = 5  # a step was committed and a family's halt hook asks the Python side to act before the next one
DIVERGED = 6  # a decomposed run: this rank's corrected state is not finite though every force was (an overflow)


@njit(cache=True)
def set_prescribed_vector(bck, bcv, bca, x0, t, dt, z):
    """The Nordsieck vector ``z`` (3.13) of a prescribed DOF at time ``t``: its position, velocity·dt and
    acceleration·dt²/2 from the boundary condition; higher entries zero."""
    p, pv, pa = prescribed(bck, bcv, bca, x0, t)
    z[0] = p
    z[1] = pv * dt
    z[2] = pa * 0.5 * dt * dt
    for k in range(3, z.shape[0]):
        z[k] = 0.0


def _predict_impl(kind, nord, nord_pd, bck, bcv, bca, bcx0, t, dt, x, v):
    for i in prange(nord.shape[0]):
        for d in range(3):
            if bck[i, d] == FREE:
                predict_dof(kind, nord[i, d], nord_pd[i, d])
                x[i, d] = nord_pd[i, d, 0]
                v[i, d] = nord_pd[i, d, 1] / dt
            else:
                p, pv, pa = prescribed(bck[i, d], bcv[i, d], bca[i, d], bcx0[i, d], t)
                x[i, d] = p
                v[i, d] = pv


#: predictor and corrector are independent per particle: threaded for large scenes (same
#: arithmetic, so results do not depend on the thread count), serial below PARALLEL_MIN_PARTICLES
_predict_ser, _predict_par = serial_and_parallel(_predict_impl)
PARALLEL_MIN_PARTICLES = 512


@njit(cache=True)
def predict_all(kind, nord, nord_pd, bc, t, dt, x, v):
    """Predictor step (Gear: (3.14); Verlet: its position update) of every particle into ``nord_pd`` (prescribed
    DOFs set exactly), with the predicted positions and velocities in ``x``, ``v``; in parallel above
    ``PARALLEL_MIN_PARTICLES`` particles."""
    if nord.shape[0] >= PARALLEL_MIN_PARTICLES:
        _predict_par(kind, nord, nord_pd, bc.kind, bc.vel, bc.acc, bc.x0, t, dt, x, v)
    else:
        _predict_ser(kind, nord, nord_pd, bc.kind, bc.vel, bc.acc, bc.x0, t, dt, x, v)


def _correct_impl(kind, nord_pd, F, mass, inertia, bck, bcv, bca, bcx0, t, dt, nord_new, x, v):
    for i in prange(nord_pd.shape[0]):
        for d in range(3):
            if bck[i, d] == FREE:
                m = mass[i] if d < 2 else inertia[i]
                correct_dof(kind, nord_pd[i, d], F[i, d] / m, dt, nord_new[i, d])
            else:
                set_prescribed_vector(bck[i, d], bcv[i, d], bca[i, d], bcx0[i, d], t, dt, nord_new[i, d])
            x[i, d] = nord_new[i, d, 0]
            v[i, d] = nord_new[i, d, 1] / dt


_correct_ser, _correct_par = serial_and_parallel(_correct_impl)


@njit(cache=True)
def correct_all(kind, nord_pd, F, mass, inertia, bc, t, dt, nord_new, x, v):
    """Corrector step (Gear: (3.16); Verlet: its velocity update) of every particle from the forces ``F`` into
    ``nord_new`` (prescribed DOFs set exactly), with the corrected positions and velocities in ``x``, ``v``; in
    parallel above ``PARALLEL_MIN_PARTICLES`` particles."""
    if nord_pd.shape[0] >= PARALLEL_MIN_PARTICLES:
        _correct_par(kind, nord_pd, F, mass, inertia, bc.kind, bc.vel, bc.acc, bc.x0, t, dt, nord_new, x, v)
    else:
        _correct_ser(kind, nord_pd, F, mass, inertia, bc.kind, bc.vel, bc.acc, bc.x0, t, dt, nord_new, x, v)


@njit(cache=True)
def first_nonfinite(a):
    """The first row of ``a`` (n, 3) with an entry that is not finite, or −1: one sum over every entry, the entries
    looked at only when it is not finite (finite entries near 1e308 may overflow it)."""
    s = 0.0
    for i in range(a.shape[0]):
        s += a[i, 0] + a[i, 1] + a[i, 2]
    if np.isfinite(s):
        return -1
    for i in range(a.shape[0]):
        if not (np.isfinite(a[i, 0]) and np.isfinite(a[i, 1]) and np.isfinite(a[i, 2])):
            return i
    return -1


@njit(cache=True)
def correct_checked(kind, nord_pd, F, P, bc, t, dt, nord_new, x, v):
    """Corrector (3.16) into ``nord_new`` and the new (x, v); the first particle with a non-finite position or
    velocity, or −1 (verlet1 corrects the velocity with this step's force and the position only at the next
    prediction: a non-finite force shows in the velocity first, and no step may commit it; Verlet alike)."""
    correct_all(kind, nord_pd, F, P.mass, P.inertia, bc, t, dt, nord_new, x, v)
    i = first_nonfinite(x)
    j = first_nonfinite(v)
    return j if i < 0 or 0 <= j < i else i


@loop_njit
def evaluate(final, x, v, dt, P, gravity, ext, fams, F):
    """Generalised forces f_sys (3.4) at (x, v): body force and external loads, then every interaction
    family in registry order — bonds (5.1), contacts (4.1), particle-base friction (4.32), ... — as in
    thesis Fig. A.2 (bonds first, so that the contact search sees which pairs are still bonded, §4.1).

    Returns 0, or −(capacity needed) when a family ran out of room (the driver lets it grow and repeats
    the step), or — a decomposed run only — 1 + the first row of F with a non-finite force on this rank (F's row
    count if only another rank had one, or a sum over the ranks is not finite; the halo's ``settle``)."""
    n = x.shape[0]
    for i in range(n):
        F[i, 0] = P.mass[i] * gravity[0] + ext[i, 0]
        F[i, 1] = P.mass[i] * gravity[1] + ext[i, 1]
        F[i, 2] = ext[i, 2]
    # No return inside the unrolled loop: numba compiled one but the loop then gave 0 where a family asked
    # for more room (2026-12-02, test_disks).  Every family's pass runs even after one asked for room (the step is
    # repeated anyway), so that every family writes its part of the sums over the ranks that the settle hook makes.
    res = np.int64(0)
    for fam in literal_unroll(fams):
        r = fam_pass(fam, final, x, v, dt, F)
        if r < 0 and res >= 0:
            res = r
    # a decomposed run: every rank repeats the step if any ran out of room, and stops if any has a non-finite force,
    # agreed in one reduction with the sums over the ranks the families asked for (the first element's settle hook)
    return fam_settle(fams[0], res, F)


@njit(cache=True, inline="always")
def _nonfinite(r, n, info):
    """After an evaluation that returned ``r`` > 0 (a decomposed run: some rank's force is not finite): this rank's
    row, or −1 for another rank's, into ``info[2]``."""
    i = r - 1
    info[2] = i if i < n else -1
    return NONFINITE


@njit(cache=True, inline="always")
def _unfinished(bad, info):
    """A non-finite corrected state at particle ``bad``: NONFINITE in a serial run; in a decomposed one (``info[3]``)
    the ranks agreed on finite forces, so this rank alone has it and the others are not told (DIVERGED)."""
    info[2] = bad
    return DIVERGED if info[3] != 0 else NONFINITE


@njit(cache=True)
def support_power(x, v, F, P, bc, t, ext):
    """Power of the supports on prescribed DOFs, Σ (m â − f) v̂, and of the external loads, Σ f_ext v."""
    p = 0.0
    n = x.shape[0]
    for i in range(n):
        for d in range(3):
            p += ext[i, d] * v[i, d]
            k = bc.kind[i, d]
            if k == FREE or k == FIXED:
                continue
            xx, vv, aa = prescribed(k, bc.vel[i, d], bc.acc[i, d], bc.x0[i, d], t)
            m = P.mass[i] if d < 2 else P.inertia[i]
            p += (m * aa - F[i, d]) * vv
    return p


@njit(cache=True)
def kinetic_potential(x, v, P, gravity):
    """(kinetic energy, potential energy of gravity) of all particles, erg."""
    ek = 0.0
    ep = 0.0
    for i in range(x.shape[0]):
        w = P.own[i]
        ek += w * (0.5 * P.mass[i] * (v[i, 0] * v[i, 0] + v[i, 1] * v[i, 1]) + 0.5 * P.inertia[i] * v[i, 2] * v[i, 2])
        ep -= w * (P.mass[i] * (gravity[0] * x[i, 0] + gravity[1] * x[i, 1]))
    return ek, ep


@loop_njit
def record_row(row, t, step, x, v, F, P, bc, gravity, acc, mon, fams):
    """Write one history-table row at time ``t``: time, step, the energies (kinetic, gravity, elastic of every
    family, accumulated work and dissipation), each family's columns and the force and displacement sums of every
    monitored set."""
    ek, ep = kinetic_potential(x, v, P, gravity)
    eel = 0.0
    off = N_BASE
    for fam in literal_unroll(fams):  # one loop over the families: each costs its own compile (one_step's comment)
        eel += fam_elastic(fam)
        off = fam_row(fam, row, off)
    row[0] = t
    row[1] = step
    row[2] = ek
    row[3] = eel
    row[4] = ep
    row[5] = acc[AC_DISS]
    row[6] = acc[AC_WEXT]
    row[7] = ek + eel + ep + acc[AC_DISS] - acc[AC_WEXT]
    nsets = mon.start.shape[0] - 1
    for s in range(nsets):
        base = off + N_SET * s
        for c in range(N_SET):
            row[base + c] = 0.0
        cnt = mon.cnt[s]
        for q in range(mon.start[s], mon.start[s + 1]):
            i = mon.idx[q]
            for d in range(3):
                row[base + d] += (x[i, d] - bc.x0[i, d]) / cnt
                row[base + 3 + d] -= F[i, d]


@loop_njit
def begin_families(fams, step, t):
    """Every family's ``begin`` hook for step ``step`` at time ``t``: before an evaluation outside the loop (a
    decomposed run's restored state after a redistribution, engine/distributed.py), so that a family's per-step
    values (a ramped load's fraction) are those of the step the state belongs to."""
    for fam in literal_unroll(fams):
        fam_begin(fam, step, t)


@njit(cache=True)
def start_nordsieck(kind, nord, F, P, bc, dt):
    """The second-order entries of the Nordsieck vectors at t0 from the forces ``F`` there, ẍ0 = f(x0, ẋ0)/m
    (thesis §3.3.1); prescribed DOFs set exactly."""
    n = nord.shape[0]
    for i in range(n):
        for d in range(3):
            if bc.kind[i, d] == FREE:
                m = P.mass[i] if d < 2 else P.inertia[i]
                nord[i, d, 2] = F[i, d] / m * 0.5 * dt * dt
            else:
                set_prescribed_vector(bc.kind[i, d], bc.vel[i, d], bc.acc[i, d], bc.x0[i, d], 0.0, dt, nord[i, d])


@loop_njit
def one_step(kind, l, dt, nord, nord_pd, nord_new, x, v, F, P, bc, gravity, acc, info, ext, fams):
    """Step ``l - 1 → l`` (``l`` = 0: the initial state, below); returns OK, GROW, ABORTED, NONFINITE, ENDED, PAUSED or DIVERGED (the step was committed
    for OK, ENDED and PAUSED).  A function of its own, called once per step: numba places some temporaries of the unrolled
    family tuple on the stack inside the loop body, so a loop over steps written out in one function grew
    the stack by about a kilobyte per family and step (a 2-disk scene overflowed 8 MiB after ~5,500
    steps); here that space is released when the step returns."""
    n = nord.shape[0]
    t = l * dt
    # "Step 0" is the initial state: it completes the Nordsieck vectors at t0 so that ẍ0 = f(x0, ẋ0)/m (thesis
    # §3.3.1) and evaluates the diagnostics there (contacts present initially, energy); the families accept it as
    # their first history.  Here rather than in a function of its own: every compiled function that walks the
    # families is a unit Numba links, optimises and generates machine code for with all their code in it (about
    # 25 s of a cold compile each, 2026-12-06), and each loop over the families in it costs its compile too, so
    # step 0 shares this function's loops.  Simulation.initialize enters it through run_steps.
    init = l == 0
    if init:
        for i in range(n):
            for d in range(3):
                x[i, d] = nord[i, d, 0]
                v[i, d] = nord[i, d, 1] / dt
    for fam in literal_unroll(fams):
        fam_begin(fam, l, t)
    single = kind == VERLET1  # one evaluation, at the predicted state (integrators.py, verlet1)
    if not init:
        # 1 predictor
        predict_all(kind, nord, nord_pd, bc, t, dt, x, v)
        if not single:
            # 2 provisional history + function evaluation.  ``final`` as np.bool_, a run-time bool: a literal True
            # and False would each compile evaluate again (Numba specialises on literal arguments) beside the bool
            # one Python calls (engine/distributed.py)
            r = evaluate(np.bool_(False), x, v, dt, P, gravity, ext, fams, F)
            if r < 0:
                info[2] = -r
                return GROW
            if r > 0:
                return _nonfinite(r, n, info)
            # 3 corrector (into nord_new; committed below)
            bad = correct_checked(kind, nord_pd, F, P, bc, t, dt, nord_new, x, v)
            if bad >= 0:
                return _unfinished(bad, info)
    # 4 final history update at the corrected state (verlet1: at the predicted one; step 0: at t0); the families
    #   write their new history beside the old one, so a step repeated after a buffer overflow starts again
    r = evaluate(np.bool_(True), x, v, dt, P, gravity, ext, fams, F)
    if r < 0:
        info[2] = -r
        return GROW
    if (init or single) and r > 0:
        return _nonfinite(r, n, info)
    if single and not init:
        bad = correct_checked(kind, nord_pd, F, P, bc, t, dt, nord_new, x, v)
        if bad >= 0:
            return _unfinished(bad, info)
    # (Gear, Verlet: a non-finite force at the corrected state is the next step's to find, as in a serial run)
    # 5 the families' halt hooks, then commit.  A decomposed run's ranks take the same decision without meeting
    #   again: each hook decides from what the evaluation's reduction gave every rank alike (protocol.py halt)
    halt = np.int64(0)
    if not init:
        for fam in literal_unroll(fams):
            h = fam_halt(fam)
            if h > halt:
                halt = h
        if halt == HALT_ABORT:
            return ABORTED
        w = 6 if kind == GEAR5 else 3  # ORDER_WIDTH: the entries beyond stay 0
        for i in range(n):
            for d in range(3):
                for k in range(w):
                    nord[i, d, k] = nord_new[i, d, k]
    for fam in literal_unroll(fams):
        fam_accept(fam)
        if not init:
            acc[AC_DISS] += fam_accumulate(fam)
            acc[AC_WEXT] += fam_work(fam)
    if init:
        start_nordsieck(kind, nord, F, P, bc, dt)
        acc[AC_P_PREV] = support_power(x, v, F, P, bc, 0.0, ext)
        return OK
    # work of the supports (trapezoidal rule)
    p = support_power(x, v, F, P, bc, t, ext)
    acc[AC_WEXT] += 0.5 * dt * (acc[AC_P_PREV] + p)
    acc[AC_P_PREV] = p
    if halt == HALT_END:
        return ENDED
    return PAUSED if halt == HALT_PAUSE else OK


@loop_njit
def run_steps(
    kind,
    step0,
    step_stop,
    dt,
    nord,
    nord_pd,
    nord_new,
    x,
    v,
    F,
    P,
    bc,
    gravity,
    acc,
    mon,
    rec_every,
    rows,
    info,
    ext,
    fams,
):
    """Advance from step ``step0`` to ``step_stop`` (or until a buffer/row limit, an error or a family's halt).

    A history row is recorded after every step divisible by ``rec_every`` into
    ``rows`` (stops early when ``rows`` is full).  ``info`` receives
    ``[last completed step, rows written, needed capacity or offending index]``; ``info[3]`` is set by the caller:
    1 in a run decomposed over ranks (a non-finite corrected state is then DIVERGED, see ``one_step``), else 0.
    Returns a status code (OK, GROW, ABORTED, NONFINITE, ENDED, PAUSED, DIVERGED).
    """
    nrows = 0
    info[0] = step0
    info[1] = 0
    info[2] = 0
    step = step0
    while step < step_stop:
        l = step + 1
        st = one_step(kind, l, dt, nord, nord_pd, nord_new, x, v, F, P, bc, gravity, acc, info, ext, fams)
        if st != OK and st != ENDED and st != PAUSED:
            return st
        step = l
        info[0] = step
        ended = st == ENDED
        if ended or (rec_every > 0 and l % rec_every == 0):
            record_row(rows[nrows], l * dt, l, x, v, F, P, bc, gravity, acc, mon, fams)
            nrows += 1
            info[1] = nrows
        if ended:
            return ENDED
        if st == PAUSED:
            return PAUSED
        if nrows >= rows.shape[0]:
            return OK
    return OK
