"""The fixed driver loop of the staggered scheme, compiled with Numba (thesis Fig. 3.6, A.1–A.3).

Per step ``t_{l-1} → t_l``::

    1 predictor            free DOFs: x̌_pd = S x̌_{l-1};  prescribed DOFs: x̂(t_l), v̂(t_l)
    2 provisional history + function evaluation at the predicted state
      (bonds before contacts once bonds exist; contact search on predicted positions)
    3 corrector            free DOFs: x̌_l = x̌_pd + s (f/m Δt²/2 − x̌_pd,3)
    4 final history update at the corrected state (second contact search),
      energies and diagnostics; forces at the corrected state for reactions

A step is transactional: the new Nordsieck array and the new contact list are
written to separate buffers and committed only at the end, so a step that
runs out of buffer space is simply repeated after the driver enlarged them.

Interaction models plug in through flags set once before the loop: a scene
without contact (``has_contact = 0``) never searches for contacts, a scene
without gravity adds no body force.

Boundary conditions per DOF: see :mod:`polydem_cli.boundary.prescribed`.
"""

from __future__ import annotations

from collections import namedtuple

import numpy as np
from numba import literal_unroll, njit, prange

from ..boundary.prescribed import BC_KINDS, FIXED, FREE, RAMP, VELOCITY, prescribed  # noqa: F401
from ..interactions.bonds.beam import BS_ACTIVE, BS_DAMAGED, BS_DISS, BS_E_EL, BS_FAILED, bond_pass
from ..interactions.contact.kernel import (
    ST_D_FRIC,
    ST_D_RATE,
    ST_E_EL,
    ST_MAX_UT_EL,
    ST_MAXA,
    ST_MAXA_A,
    ST_MAXA_B,
    ST_MAXA_RATIO,
    ST_NC,
    ST_NCONT,
    ST_PAIR_A,
    ST_PAIR_B,
    contact_pass,
    copy_history,
)
from ..interactions.protocol import fam_accept, fam_accumulate, fam_elastic, fam_pass, fam_row, fam_work
from ..jit import serial_and_parallel
from .integrators import VERLET1, correct_dof, predict_dof

Particles = namedtuple(
    "Particles",
    ["vert_start", "body_v", "radius", "area", "mass", "inertia", "thickness", "group", "is_large", "large_idx"],
)
Boundary = namedtuple("Boundary", ["kind", "vel", "acc", "x0"])
Monitor = namedtuple("Monitor", ["start", "idx"])
BondLinks = namedtuple("BondLinks", ["start", "partner", "active"])

# ---- history table columns
HISTORY_BASE_COLUMNS = (
    ("time", "s", "simulated time t_l"),
    ("step", "-", "step number l"),
    ("kinetic", "erg", "kinetic energy (2.20) of all particles"),
    ("elastic", "erg", "elastic energy stored in contacts: ½k_n A_n² T + ½k_t (u_t−u_t^pl)² T"),
    ("potential", "erg", "potential energy of the body force, −Σ m g·x"),
    ("dissipated", "erg", "energy dissipated so far (friction, viscous damping, tension cut-off)"),
    ("external_work", "erg", "work done so far by the supports of prescribed DOFs"),
    (
        "energy_total",
        "erg",
        "kinetic + elastic + potential + dissipated − external_work (constant for an exact integrator)",
    ),
    ("n_contacts", "-", "number of contacts"),
    ("max_overlap_area", "cm^2", "largest overlap area A_n"),
    ("max_overlap_ratio", "-", "largest A_n / area of the smaller particle"),
    ("max_ut_elastic", "cm", "largest elastic tangential displacement |u_t − u_t^pl|"),
)
N_BASE = len(HISTORY_BASE_COLUMNS)
BOND_COLUMNS = (
    ("elastic_bonds", "erg", "elastic energy stored in bonds (included in 'elastic')"),
    ("dissipated_damage", "erg", "energy dissipated by bond damage so far (included in 'dissipated')"),
    ("bonds_active", "-", "bonds not yet failed"),
    ("bonds_damaged", "-", "active bonds with 0 < d < 1"),
    ("bonds_failed", "-", "bonds with d = 1 (inactive; the pair interacts by contact)"),
)
N_BOND = len(BOND_COLUMNS)
SET_COLUMNS = (
    ("u1", "cm", "mean x1 displacement of the set"),
    ("u2", "cm", "mean x2 displacement of the set (the prescribed û2 for a driven set)"),
    ("phi", "rad", "mean rotation of the set"),
    ("f1", "dyn", "−Σ interaction force e1 on the set (reaction; thesis f_2 convention)"),
    ("f2", "dyn", "−Σ interaction force e2 on the set; tension positive for a top set pulled up"),
    ("c", "dyn cm", "−Σ interaction moments on the set, each about its particle's centroid"),
)
N_SET = len(SET_COLUMNS)

# ---- accumulators carried across steps (and checkpointed)
AC_DISS = 0
AC_WEXT = 1
AC_P_PREV = 2
AC_DRATE_PREV = 3
AC_MAXA_RATIO = 4
AC_MAXA = 5
AC_NCONT = 6
AC_MAX_UT = 7
AC_CONT_A = 8
AC_CONT_B = 9
AC_CONT_STEP = 10
AC_DISS_DMG = 11
AC_PEAK = 12  # running peak of |f2| on the load-drop set
# 13, 14: base friction's accumulators in checkpoints written before it became a family (its own now)
AC_MAXA_A = 15  # the pair that reached AC_MAXA_RATIO
AC_MAXA_B = 16
N_ACC = 24

# ---- return codes of run_steps
OK = 0
GROW = 1
CONTAINED_ABORT = 2
NONFINITE = 3
ENDED = 4  # the end_load_drop criterion was met


@njit(cache=True)
def set_prescribed_vector(bck, bcv, bca, x0, t, dt, z):
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
    if nord_pd.shape[0] >= PARALLEL_MIN_PARTICLES:
        _correct_par(kind, nord_pd, F, mass, inertia, bc.kind, bc.vel, bc.acc, bc.x0, t, dt, nord_new, x, v)
    else:
        _correct_ser(kind, nord_pd, F, mass, inertia, bc.kind, bc.vel, bc.acc, bc.x0, t, dt, nord_new, x, v)


@njit(cache=True)
def correct_checked(kind, nord_pd, F, P, bc, t, dt, nord_new, x, v):
    """Corrector (3.16) into ``nord_new`` and the new (x, v); the first particle with a non-finite position, or −1."""
    correct_all(kind, nord_pd, F, P.mass, P.inertia, bc, t, dt, nord_new, x, v)
    for i in range(nord_pd.shape[0]):
        if not (np.isfinite(x[i, 0]) and np.isfinite(x[i, 1]) and np.isfinite(x[i, 2])):
            return i
    return -1


@njit(cache=True)
def evaluate(
    final,
    x,
    v,
    dt,
    P,
    gravity,
    has_contact,
    cp,
    cw,
    hold,
    hnew,
    bonds,
    F,
    stats,
    has_bonds,
    bp,
    bh,
    bw,
    bstats,
    ext,
    fams,
):
    """Generalised forces f_sys (3.4) at (x, v): body force and external loads, bonds (5.1),
    contacts (4.1), particle-base friction (4.32) — in the order of thesis Fig. A.2.

    Bonds come first so that the contact search sees which pairs are (still)
    bonded (thesis §4.1).  Returns 0 or -needed capacity.
    """
    n = x.shape[0]
    for i in range(n):
        F[i, 0] = P.mass[i] * gravity[0] + ext[i, 0]
        F[i, 1] = P.mass[i] * gravity[1] + ext[i, 1]
        F[i, 2] = ext[i, 2]
    if final:
        for k in range(stats.shape[0]):
            stats[k] = 0.0
        stats[ST_PAIR_A] = -1.0
        stats[ST_PAIR_B] = -1.0
        stats[ST_MAXA_A] = -1.0
        stats[ST_MAXA_B] = -1.0
    if has_bonds:
        bond_pass(final, x, v, bp, bh, bw, F, bstats)
    if has_contact:
        r = contact_pass(
            final,
            x,
            v,
            dt,
            P.vert_start,
            P.body_v,
            P.radius,
            P.area,
            P.thickness,
            P.group,
            P.is_large,
            P.large_idx,
            cp,
            cw,
            hold,
            hnew,
            bonds.start,
            bonds.partner,
            bonds.active,
            F,
            stats,
        )
        if r < 0:
            return r
    elif final:
        hnew.meta[0] = 0
    # the other interaction families (interactions/protocol.py).  No return inside the unrolled loop: numba
    # compiled one but the loop then gave 0 where a family asked for more room (2026-12-02, test_disks)
    res = np.int64(0)
    for fam in literal_unroll(fams):
        if res >= 0:
            r = fam_pass(fam, final, x, v, dt, F)
            if r < 0:
                res = r
    return res


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
    ek = 0.0
    ep = 0.0
    for i in range(x.shape[0]):
        ek += 0.5 * P.mass[i] * (v[i, 0] * v[i, 0] + v[i, 1] * v[i, 1]) + 0.5 * P.inertia[i] * v[i, 2] * v[i, 2]
        ep -= P.mass[i] * (gravity[0] * x[i, 0] + gravity[1] * x[i, 1])
    return ek, ep


@njit(cache=True)
def record_row(row, t, step, x, v, F, P, bc, gravity, stats, acc, mon, has_bonds, bstats, fams):
    ek, ep = kinetic_potential(x, v, P, gravity)
    eel = stats[ST_E_EL] + (bstats[BS_E_EL] if has_bonds else 0.0)
    for fam in literal_unroll(fams):
        eel += fam_elastic(fam)
    row[0] = t
    row[1] = step
    row[2] = ek
    row[3] = eel
    row[4] = ep
    row[5] = acc[AC_DISS]
    row[6] = acc[AC_WEXT]
    row[7] = ek + eel + ep + acc[AC_DISS] - acc[AC_WEXT]
    row[8] = stats[ST_NC]
    row[9] = stats[ST_MAXA]
    row[10] = stats[ST_MAXA_RATIO]
    row[11] = stats[ST_MAX_UT_EL]
    off = N_BASE
    if has_bonds:
        row[off] = bstats[BS_E_EL]
        row[off + 1] = acc[AC_DISS_DMG]
        row[off + 2] = bstats[BS_ACTIVE]
        row[off + 3] = bstats[BS_DAMAGED]
        row[off + 4] = bstats[BS_FAILED]
        off += N_BOND
    for fam in literal_unroll(fams):
        off = fam_row(fam, row, off)
    nsets = mon.start.shape[0] - 1
    for s in range(nsets):
        base = off + N_SET * s
        for c in range(N_SET):
            row[base + c] = 0.0
        cnt = mon.start[s + 1] - mon.start[s]
        for q in range(mon.start[s], mon.start[s + 1]):
            i = mon.idx[q]
            for d in range(3):
                row[base + d] += (x[i, d] - bc.x0[i, d]) / cnt
                row[base + 3 + d] -= F[i, d]


@njit(cache=True)
def initial_state(
    kind,
    nord,
    x,
    v,
    dt,
    P,
    bc,
    gravity,
    has_contact,
    cp,
    cw,
    hold,
    hnew,
    bonds,
    F,
    stats,
    acc,
    has_bonds,
    bp,
    bh,
    bw,
    bstats,
    ext,
    fams,
):
    """Complete the Nordsieck vectors at t0 so that ẍ0 = f(x0, ẋ0)/m (thesis §3.3.1).

    Also evaluates the diagnostics at t0 (contacts present initially, energy).
    Returns 0 or -needed capacity.
    """
    n = x.shape[0]
    for i in range(n):
        for d in range(3):
            x[i, d] = nord[i, d, 0]
            v[i, d] = nord[i, d, 1] / dt
    r = evaluate(
        True,
        x,
        v,
        dt,
        P,
        gravity,
        has_contact,
        cp,
        cw,
        hold,
        hnew,
        bonds,
        F,
        stats,
        has_bonds,
        bp,
        bh,
        bw,
        bstats,
        ext,
        fams,
    )
    if r < 0:
        return r
    for fam in literal_unroll(fams):
        fam_accept(fam)
    for i in range(n):
        for d in range(3):
            if bc.kind[i, d] == FREE:
                m = P.mass[i] if d < 2 else P.inertia[i]
                nord[i, d, 2] = F[i, d] / m * 0.5 * dt * dt
            else:
                set_prescribed_vector(bc.kind[i, d], bc.vel[i, d], bc.acc[i, d], bc.x0[i, d], 0.0, dt, nord[i, d])
    # the contact list at t0 starts the history (new contacts, u_t = 0)
    copy_history(hnew, hold, n)
    acc[AC_P_PREV] = support_power(x, v, F, P, bc, 0.0, ext)
    acc[AC_DRATE_PREV] = stats[ST_D_RATE]
    acc[AC_MAXA_RATIO] = max(acc[AC_MAXA_RATIO], stats[ST_MAXA_RATIO])
    acc[AC_MAXA] = max(acc[AC_MAXA], stats[ST_MAXA])
    return 0


@njit(cache=True)
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
    has_contact,
    cp,
    cw,
    hold,
    hnew,
    bonds,
    stats,
    acc,
    mon,
    rec_every,
    rows,
    info,
    abort_on_contained,
    has_bonds,
    bp,
    bh,
    bw,
    bstats,
    bh_save,
    drop_idx,
    drop_frac,
    drop_arm,
    ext,
    fams,
):
    """Advance from step ``step0`` to ``step_stop`` (or until a buffer/row limit or an error).

    A history row is recorded after every step divisible by ``rec_every`` into
    ``rows`` (stops early when ``rows`` is full).  ``info`` receives
    ``[last completed step, rows written, needed capacity or offending index]``.
    Returns a status code (OK, GROW, CONTAINED_ABORT, NONFINITE).
    """
    n = nord.shape[0]
    nrows = 0
    info[0] = step0
    info[1] = 0
    info[2] = 0
    step = step0
    while step < step_stop:
        l = step + 1
        t = l * dt
        if has_bonds:
            bh.clock[0] = l
        # 1 predictor
        predict_all(kind, nord, nord_pd, bc, t, dt, x, v)
        single = kind == VERLET1  # one evaluation, at the predicted state (integrators.py, verlet1)
        if not single:
            # 2 provisional history + function evaluation
            r = evaluate(
                False,
                x,
                v,
                dt,
                P,
                gravity,
                has_contact,
                cp,
                cw,
                hold,
                hnew,
                bonds,
                F,
                stats,
                has_bonds,
                bp,
                bh,
                bw,
                bstats,
                ext,
                fams,
            )
            if r < 0:
                info[2] = -r
                return GROW
            # 3 corrector (into nord_new; committed below)
            bad = correct_checked(kind, nord_pd, F, P, bc, t, dt, nord_new, x, v)
            if bad >= 0:
                info[2] = bad
                return NONFINITE
        # 4 final history update at the corrected state (verlet1: at the predicted one; bond history is saved
        #   first so that a step repeated after a buffer overflow starts from the same bond state)
        if has_bonds and has_contact:
            save_bonds(bh, bh_save)
        r = evaluate(
            True,
            x,
            v,
            dt,
            P,
            gravity,
            has_contact,
            cp,
            cw,
            hold,
            hnew,
            bonds,
            F,
            stats,
            has_bonds,
            bp,
            bh,
            bw,
            bstats,
            ext,
            fams,
        )
        if r < 0:
            if has_bonds and has_contact:
                save_bonds(bh_save, bh)
            info[2] = -r
            return GROW
        if single:
            bad = correct_checked(kind, nord_pd, F, P, bc, t, dt, nord_new, x, v)
            if bad >= 0:
                info[2] = bad
                return NONFINITE
        if stats[ST_NCONT] > 0 and abort_on_contained:
            info[2] = int(stats[ST_PAIR_A])
            acc[AC_CONT_A] = stats[ST_PAIR_A]
            acc[AC_CONT_B] = stats[ST_PAIR_B]
            acc[AC_CONT_STEP] = l
            return CONTAINED_ABORT
        # commit
        for i in range(n):
            for d in range(3):
                for k in range(6):
                    nord[i, d, k] = nord_new[i, d, k]
        copy_history(hnew, hold, n)
        for fam in literal_unroll(fams):
            fam_accept(fam)
            acc[AC_DISS] += fam_accumulate(fam)
            acc[AC_WEXT] += fam_work(fam)
        # energies and diagnostics (trapezoidal rule for rates)
        p = support_power(x, v, F, P, bc, t, ext)
        acc[AC_WEXT] += 0.5 * dt * (acc[AC_P_PREV] + p)
        acc[AC_P_PREV] = p
        acc[AC_DISS] += 0.5 * dt * (acc[AC_DRATE_PREV] + stats[ST_D_RATE]) + stats[ST_D_FRIC]
        if has_bonds:
            acc[AC_DISS] += bstats[BS_DISS]
            acc[AC_DISS_DMG] += bstats[BS_DISS]
        acc[AC_DRATE_PREV] = stats[ST_D_RATE]
        if stats[ST_MAXA_RATIO] > acc[AC_MAXA_RATIO]:
            acc[AC_MAXA_RATIO] = stats[ST_MAXA_RATIO]
            acc[AC_MAXA_A] = stats[ST_MAXA_A]
            acc[AC_MAXA_B] = stats[ST_MAXA_B]
        acc[AC_MAXA] = max(acc[AC_MAXA], stats[ST_MAXA])
        acc[AC_MAX_UT] = max(acc[AC_MAX_UT], stats[ST_MAX_UT_EL])
        if stats[ST_NCONT] > 0:
            acc[AC_NCONT] += stats[ST_NCONT]
            if acc[AC_CONT_STEP] <= 0:
                acc[AC_CONT_A] = stats[ST_PAIR_A]
                acc[AC_CONT_B] = stats[ST_PAIR_B]
                acc[AC_CONT_STEP] = l
        step = l
        info[0] = step
        ended = False
        if drop_frac > 0.0 and l >= drop_arm:
            f2 = 0.0
            for q in range(drop_idx.shape[0]):
                f2 -= F[drop_idx[q], 1]
            f2 = abs(f2)
            if f2 > acc[AC_PEAK]:
                acc[AC_PEAK] = f2
            ended = acc[AC_PEAK] > 0.0 and f2 < drop_frac * acc[AC_PEAK]
        if ended or (rec_every > 0 and l % rec_every == 0):
            record_row(rows[nrows], t, l, x, v, F, P, bc, gravity, stats, acc, mon, has_bonds, bstats, fams)
            nrows += 1
            info[1] = nrows
        if ended:
            return ENDED
        if nrows >= rows.shape[0]:
            return OK
    return OK


@njit(cache=True)
def save_bonds(src, dst):
    for k in range(src.kappa.shape[0]):
        dst.kappa[k] = src.kappa[k]
        dst.d[k] = src.d[k]
        dst.active[k] = src.active[k]
        dst.Y[k] = src.Y[k]
        dst.eval_active[k] = src.eval_active[k]
        dst.fail_step[k] = src.fail_step[k]
        dst.fail_strain[k, 0] = src.fail_strain[k, 0]
        dst.fail_strain[k, 1] = src.fail_strain[k, 1]
        dst.fail_strain[k, 2] = src.fail_strain[k, 2]
        dst.rate_f[k] = src.rate_f[k]
