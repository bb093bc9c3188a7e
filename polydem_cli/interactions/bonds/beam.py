"""Elasto-damage Timoshenko beam bonds (thesis §5.1.2, §5.2.2).

A massless bar + shear-flexible beam joins the centroids of two initially
touching particles I and II (I = smaller particle number), clamped at both
ends.  Geometry: ``L_h`` centroid distance at t0, ``H_h`` shared edge length,
``T_h = T``; ``A_h = H_h T_h``, ``I_h = T_h H_h³/12``, ``A_h,Q = α_Q A_h`` (α_Q = 5/6),
``G_h = E_h / (2 (1 + ν_h))``, ``η = 12 E_h I_h / (G_h A_h,Q L_h²)`` (5.10).

Co-rotated frame (Fig. 5.5; open point O-15): ``ē1`` along the
current centroid line I→II, ``ē2 = e3 × ē1``; ``ū = ℓ − L_h``;
``θ̄_I = wrap(φ_I − Δβ)``, ``θ̄_II = wrap(φ_II − Δβ)`` with ``Δβ`` the rotation of
the centroid line since t0 and wrap to (−π, π] — so a rigid rotation of the
pair by any angle produces no force.

Mid-span strains (5.9)::

    ε_ax,M = ū / L_h,   γ_M = η/(2(1+η)) (θ̄_I + θ̄_II),   ϰ_M = (θ̄_II − θ̄_I) / L_h

equivalent strain (5.8) ``ε_v = ⟨ε_ax,M + |ϰ_M| H_h/2⟩ + |γ_M|``.

Damage, rate-independent (5.6)–(5.7): ``κ = max_τ ε_v``,
``d = κ_m/κ (κ − κ_0)/(κ_m − κ_0)`` between κ_0 and κ_m.  Rate-dependent
(5.13)–(5.15): ``κ_0,ra = κ_0 (ε̇_ax,M/ε̇_0)^α`` for ``ε̇_ax,M > ε̇_0`` with
``ε̇_ax,M = (ẋ_II − ẋ_I)·ē1 / L_h`` (5.16), auxiliary damage
``d̆(ε_v, κ_0,ra)`` of the form (5.6), ``d = max_τ d̆``.  If κ_0,ra ≥ κ_m the case
distinction of (5.14) is ambiguous (O-14): ``d̆ = 0`` for ε_v ≤ κ_0,ra, else 1.

End forces in the co-rotated frame (5.11), ``k_b = E_h I_h / (L_h³ (1 + η))``::

    f̄1_I = (1 − H d) E_h A_h / L_h ū                   f̄1_II = −f̄1_I
    f̄2_I = −(1 − d) k_b 6 L_h (θ̄_I + θ̄_II)               f̄2_II = −f̄2_I
    c_I  = −(1 − d) k_b L_h² ((4 + η) θ̄_I + (2 − η) θ̄_II)
    c_II = −(1 − d) k_b L_h² ((2 − η) θ̄_I + (4 + η) θ̄_II)

with the Heaviside switch (5.5) H = 1 for ε_ax,M ≥ 0 (axial compression is never
softened).  These are minus the linear bar–Timoshenko stiffness times the end
DOFs; as in the thesis the shear couple uses L_h, not the current chord, so the
total moment balances only to O(ε_ax).

Energy (diagnostics): ``Ψ = (1 − H d) ½ E_h A_h/L_h ū² + (1 − d) ½ k_b L_h² θᵀ[[4+η, 2−η],[2−η, 4+η]]θ``;
damage dissipates ``Y ḋ`` with the energy release rate
``Y = H ½ E_h A_h/L_h ū² + ½ k_b L_h² θᵀ[…]θ``, integrated with the trapezoidal rule.

Units: E_h in g cm⁻¹ s⁻² (1 N/cm² = 1e5), lengths in cm, forces in dyn.
"""

from __future__ import annotations

import math
from collections import namedtuple

import numpy as np
from numba import njit, prange

from ...jit import loop_njit, serial_and_parallel
from .iface_data import empty_iface, new_iface_hist

#: static bond data, one entry per bond (arrays of length n_b)
BondParams = namedtuple(
    "BondParams",
    [
        "a",
        "b",  # particle indices, a < b (I = a, II = b)
        "L",
        "H",
        "T",  # L_h, H_h, T_h (cm)
        "EA",
        "kb",
        "eta",
        "gamma_fac",  # E_h A_h, k_b = E I/(L³(1+η)), η, η/(2(1+η))
        "kappa0",
        "kappam",  # κ_0, κ_m
        "eps0dot",
        "alpha",  # rate dependence (α = 0: rate-independent)
        "ux0",
        "uy0",  # unit vector along the centroid line at t0
        "rate_dependent",  # 1 if the rate-dependent model is used (scene-wide flag)
        "rate_c",  # weight of the new rate in the filtered strain rate, 1 - exp(-Δt/τ); 1: the thesis's (5.16)
        "iface",  # the edge-interface model's data (interface.py IfaceParams; model 0 and empty arrays for beams)
    ],
)

#: bond history (arrays of length n_b) — lives with the bond (GUIDE practice 6).
#: ``kappa`` (5.7), ``d`` (5.6) or (5.15), ``active`` (not failed), ``Y`` the energy release rate at the last
#: step (for the dissipation), ``rate_f``: the filtered axial strain rate of the option ``bonds.rate_filter``;
#: ``eval_active``: active at the present evaluation (a bond whose provisional damage reaches 1 admits its
#: pair to that evaluation's contact search, O-13); ``fail_step``: step at which the bond failed (−1: not
#: failed); ``fail_strain`` (n_b, 3): the parts of the equivalent strain (5.8) at that step, ε_ax,M (signed),
#: |ϰ_M| H_h/2, |γ_M| (the failure mode, §7.3); ``clock`` (1,): the step being computed
#: ``iface``: the edge-interface model's per-element history (interface.py IfaceHist; (0, 0) arrays for beams)
BondHist = namedtuple(
    "BondHist", ["kappa", "d", "active", "Y", "eval_active", "fail_step", "fail_strain", "clock", "rate_f", "iface"]
)
#: the history a final pass computes (committed by :func:`accept_history` when the step is accepted, so
#: that a step the driver repeats after a buffer overflow starts again from the same state)
BondHistNew = namedtuple("BondHistNew", ["kappa", "d", "active", "Y", "rate_f", "iface"])

# indices into the bond statistics array
BS_E_EL = 0  # elastic energy in bonds, erg
BS_DISS = 1  # damage dissipation during this step, erg
BS_ACTIVE = 2
BS_DAMAGED = 3  # 0 < d < 1
BS_FAILED = 4
BS_AMBIG = 5  # bonds with κ_0,ra ≥ κ_m this step (O-14)
BS_FRIC = 6  # the edge-interface model: friction work of broken interface elements this step, erg (part of BS_DISS)
N_BSTATS = 7

TWO_PI = 2.0 * math.pi


@njit(cache=True, inline="always")
def wrap_angle(a):
    """Map an angle to (−π, π]."""
    a = a - TWO_PI * math.floor((a + math.pi) / TWO_PI)  # [−π, π)
    return math.pi if a <= -math.pi else a


@njit(cache=True, inline="always")
def damage_of(kappa, kappa0, kappam):
    """(5.6); also the auxiliary damage d̆(ε_v, κ_0,ra) of (5.14) with κ → ε_v, κ_0 → κ_0,ra."""
    if kappa <= kappa0:
        return 0.0
    if kappa >= kappam:
        return 1.0
    return kappam / kappa * (kappa - kappa0) / (kappam - kappa0)


@njit(cache=True, inline="always")
def kappa0_rate(eps_rate, kappa0, eps0dot, alpha):
    """(5.13): κ_0,ra = κ_0 (ε̇/ε̇_0)^α above the threshold rate ε̇_0, else κ_0."""
    if alpha == 0.0 or eps_rate <= eps0dot:
        return kappa0
    return kappa0 * (eps_rate / eps0dot) ** alpha


@njit(cache=True, inline="always")
def beam_kinematics(xa, ya, pa, xb, yb, pb, L, ux0, uy0):
    """Co-rotated kinematics: (ē1x, ē1y, ℓ, ū, θ̄_I, θ̄_II)."""
    dx = xb - xa
    dy = yb - ya
    ell = math.sqrt(dx * dx + dy * dy)
    ex = dx / ell
    ey = dy / ell
    # rotation of the centroid line since t0
    dbeta = math.atan2(ux0 * ey - uy0 * ex, ux0 * ex + uy0 * ey)
    return ex, ey, ell, ell - L, wrap_angle(pa - dbeta), wrap_angle(pb - dbeta)


@njit(cache=True, inline="always")
def mid_span_strains(u, tha, thb, L, H, gamma_fac):
    """(5.9), (5.8): (ε_ax,M, ϰ_M, γ_M, ε_v)."""
    eps = u / L
    kap = (thb - tha) / L
    gam = gamma_fac * (tha + thb)
    ev = eps + abs(kap) * 0.5 * H
    if ev < 0.0:
        ev = 0.0
    return eps, kap, gam, ev + abs(gam)


#: per-bond scratch of one evaluation (computed in parallel, reduced serially in bond order)
#: f: (nb, 4) fx, fy, c_I, c_II; e: (nb, 4) see W_*; cnt: (nb,) 1 where this process counts the bond in the
#: statistics (energies, counts), 0 where another rank does (a bond across a subdomain boundary is evaluated on
#: both sides, engine/distributed.py); all 1 in a serial run
#: cs: (n, 2) cos and sin of each particle's angle at the evaluation (the edge-interface model's table, computed
#: once per particle instead of per bond; (0, 2) for beams)
#: sg: (n, 3) each particle's mean stress σ_xx, σ_yy, σ_xy from its interfaces' tractions (Love–Weber), iv: (n,)
#: 1/(A T) of each particle, pm: (nb, 6) each interface's first element point relative to particle I's centroid,
#: the step between its points and the e-weighted sum of its elements' forces (the first moment of its tractions)
#: — the interface's ``crack_criterion = "principal"`` (interface.py); (0, …) otherwise
BondWork = namedtuple("BondWork", ["f", "e", "cnt", "cs", "sg", "iv", "pm"])
W_STATE = 0  # 0 inactive before, 1 active, 2 active and damaged, 3 failed in this update
W_EEL = 1
W_DISS = 2
W_AMBIG = 3


def _bond_kernel_impl(final, x, v, bp, bh, bn, bw):
    """Per-bond forces; in a final pass also the new history (``*n_``); independent across bonds (prange).

    ``bp``, ``bh``, ``bn``, ``bw``: the family's parameters, old and new history, work arrays (namedtuples,
    interactions/bonds/family.py).  Their arrays are bound to locals here, before the ``prange``: numba
    silently drops writes made through a namedtuple field inside ``prange`` (numba issues #5872, #7135,
    #10338); writes through a local array are kept (tests/test_parallel.py, tests/test_regression.py).
    """
    rate = bp.rate_dependent
    a_ = bp.a
    b_ = bp.b
    L_ = bp.L
    H_ = bp.H
    gf_ = bp.gamma_fac
    ux_ = bp.ux0
    uy_ = bp.uy0
    EA_ = bp.EA
    kb_ = bp.kb
    eta_ = bp.eta
    k0_ = bp.kappa0
    km_ = bp.kappam
    e0_ = bp.eps0dot
    al_ = bp.alpha
    rc_ = bp.rate_c
    kap_ = bh.kappa
    d_ = bh.d
    act_ = bh.active
    Y_ = bh.Y
    eact_ = bh.eval_active
    fstep_ = bh.fail_step
    fstr_ = bh.fail_strain
    clock = bh.clock
    rf_ = bh.rate_f
    kn_ = bn.kappa
    dn_ = bn.d
    an_ = bn.active
    Yn_ = bn.Y
    rfn_ = bn.rate_f
    wf = bw.f
    we = bw.e
    for k in prange(a_.shape[0]):
        wf[k, 0] = 0.0
        wf[k, 1] = 0.0
        wf[k, 2] = 0.0
        wf[k, 3] = 0.0
        we[k, W_EEL] = 0.0
        we[k, W_DISS] = 0.0
        we[k, W_AMBIG] = 0.0
        if not act_[k]:
            eact_[k] = False
            we[k, W_STATE] = 0.0
            if final:
                kn_[k] = kap_[k]
                dn_[k] = d_[k]
                an_[k] = False
                Yn_[k] = Y_[k]
                rfn_[k] = rf_[k]
            continue
        i = a_[k]
        j = b_[k]
        L = L_[k]
        ex, ey, ell, u, tha, thb = beam_kinematics(
            x[i, 0], x[i, 1], x[i, 2], x[j, 0], x[j, 1], x[j, 2], L, ux_[k], uy_[k]
        )
        eps, kap, gam, ev = mid_span_strains(u, tha, thb, L, H_[k], gf_[k])
        kappa_new = max(kap_[k], ev)
        rf_new = rf_[k]
        if rate:
            erate = ((v[j, 0] - v[i, 0]) * ex + (v[j, 1] - v[i, 1]) * ey) / L  # (5.16)
            if rc_[k] < 1.0:  # option bonds.rate_filter: exponentially filtered rate, time constant τ
                erate = rf_[k] + rc_[k] * (erate - rf_[k])
                rf_new = erate
            k0 = kappa0_rate(erate, k0_[k], e0_[k], al_[k])
            km = km_[k]
            if k0 >= km:  # (5.14) ambiguous (O-14)
                db = 0.0 if ev <= k0 else 1.0
                we[k, W_AMBIG] = 1.0
            else:
                db = damage_of(ev, k0, km)
            d = max(d_[k], db)
        else:
            d = damage_of(kappa_new, k0_[k], km_[k])
        Hs = 1.0 if eps >= 0.0 else 0.0
        EA_L = EA_[k] / L
        kb = kb_[k]
        eta = eta_[k]
        L2 = L * L
        if d >= 1.0:
            eact_[k] = False
            if final:
                w_ax = 0.5 * EA_L * u * u
                Y = Hs * w_ax + 0.5 * kb * L2 * ((4.0 + eta) * (tha * tha + thb * thb) + 2.0 * (2.0 - eta) * tha * thb)
                # release rate over the last damage increment, plus the axial energy a bond failing
                # under compression still stores (H = 0): the bond disappears with it
                we[k, W_DISS] = 0.5 * (Y_[k] + Y) * (1.0 - d_[k]) + (1.0 - Hs) * w_ax
                kn_[k] = kappa_new
                dn_[k] = 1.0
                an_[k] = False
                Yn_[k] = 0.0
                rfn_[k] = rf_new
                fstep_[k] = clock[0]
                fstr_[k, 0] = eps
                fstr_[k, 1] = abs(kap) * 0.5 * H_[k]
                fstr_[k, 2] = abs(gam)
            we[k, W_STATE] = 3.0
            continue
        eact_[k] = True
        f1 = (1.0 - Hs * d) * EA_L * u
        f2 = -(1.0 - d) * kb * 6.0 * L * (tha + thb)
        wf[k, 0] = f1 * ex - f2 * ey  # ē2 = [−ē1y, ē1x]
        wf[k, 1] = f1 * ey + f2 * ex
        wf[k, 2] = -(1.0 - d) * kb * L2 * ((4.0 + eta) * tha + (2.0 - eta) * thb)
        wf[k, 3] = -(1.0 - d) * kb * L2 * ((2.0 - eta) * tha + (4.0 + eta) * thb)
        we[k, W_STATE] = 2.0 if d > 0.0 else 1.0
        if final:
            # undamaged energies: axial and bending/shear parts (for Ψ and the release rate Y)
            w_ax = 0.5 * EA_L * u * u
            w_b = 0.5 * kb * L2 * ((4.0 + eta) * (tha * tha + thb * thb) + 2.0 * (2.0 - eta) * tha * thb)
            Y = Hs * w_ax + w_b
            if d > d_[k]:
                we[k, W_DISS] = 0.5 * (Y_[k] + Y) * (d - d_[k])
            kn_[k] = kappa_new
            dn_[k] = d
            an_[k] = True
            Yn_[k] = Y
            rfn_[k] = rf_new
            we[k, W_EEL] = (1.0 - Hs * d) * w_ax + (1.0 - d) * w_b


#: the same kernel compiled twice: threaded for large networks, serial below PARALLEL_MIN_BONDS
#: (starting the threads costs more than it saves on small networks); identical arithmetic either way
_bond_kernel_ser, _bond_kernel_par = serial_and_parallel(_bond_kernel_impl)
PARALLEL_MIN_BONDS = 1000


@loop_njit
def bond_pass(final, x, v, bp, bh, bn, bw, F, bstats):
    """Provisional (``final = False``) or final bond update and forces (Figs. A.2/A.3).

    Provisional: d from the stored history ``bh`` and the predicted state, forces; a
    bond whose provisional damage reaches 1 gives no force and admits its pair
    to this evaluation's contact search (open point O-13).  Final: the new κ (or
    d) into ``bn`` (failed bonds inactive for good from the next step on), energies and dissipation;
    :func:`accept_history` commits ``bn`` when the step is accepted.

    The per-bond work runs in parallel; forces are then added to ``F`` serially
    in bond order, so the result does not depend on the number of threads.
    """
    if bp.a.shape[0] >= PARALLEL_MIN_BONDS:
        _bond_kernel_par(final, x, v, bp, bh, bn, bw)
    else:
        _bond_kernel_ser(final, x, v, bp, bh, bn, bw)
    namb = add_bond_forces(final, bp, bw, F, bstats)
    if final:
        bstats[BS_AMBIG] = namb


@loop_njit
def add_bond_forces(final, bp, bw, F, bstats):
    """Add the per-bond end forces of a pass (``bw.f``: f_x, f_y, c_I of particle I, c_II) to ``F`` serially in bond
    order (the same result with any number of threads), count the bonds by state (``bw.e[:, W_STATE]``) and, in a
    final pass, put the elastic energy (``W_EEL``), the dissipation (``W_DISS``) and the counts of the bonds this
    process counts into ``bstats``; returns the sum of ``bw.e[:, 3]`` over those bonds (the beams' ambiguous-rate
    count, the interfaces' friction work).  Shared by the beams (:func:`bond_pass`) and the edge interfaces
    (interface.py ``iface_pass``)."""
    e_el = 0.0
    diss = 0.0
    extra = 0.0
    nact = 0
    ndam = 0
    nfail = 0
    for k in range(bp.a.shape[0]):
        st = bw.e[k, W_STATE]
        if st >= 1.0 and st < 3.0:
            i = bp.a[k]
            j = bp.b[k]
            F[i, 0] += bw.f[k, 0]
            F[i, 1] += bw.f[k, 1]
            F[i, 2] += bw.f[k, 2]
            F[j, 0] -= bw.f[k, 0]
            F[j, 1] -= bw.f[k, 1]
            F[j, 2] += bw.f[k, 3]
            nact += bw.cnt[k]
            if st == 2.0:
                ndam += bw.cnt[k]
        else:
            nfail += bw.cnt[k]
        if final and bw.cnt[k]:
            e_el += bw.e[k, W_EEL]
            diss += bw.e[k, W_DISS]
            extra += bw.e[k, W_AMBIG]
    if final:
        bstats[BS_E_EL] = e_el
        bstats[BS_DISS] = diss
        bstats[BS_ACTIVE] = nact
        bstats[BS_DAMAGED] = ndam
        bstats[BS_FAILED] = nfail
    return extra


@loop_njit
def accept_history(bn, bh):
    """The step is accepted: the history of its final pass becomes the bonds' history."""
    for k in range(bh.kappa.shape[0]):
        bh.kappa[k] = bn.kappa[k]
        bh.d[k] = bn.d[k]
        bh.active[k] = bn.active[k]
        bh.Y[k] = bn.Y[k]
        bh.rate_f[k] = bn.rate_f[k]


@njit(cache=True)
def bond_strains(x, bp, out):
    """Per bond: ε_ax,M, |ϰ_M| H_h/2, |γ_M|, ε_v at state ``x`` (for frames, Figs. 5.9/5.11)."""
    for k in range(bp.a.shape[0]):
        i = bp.a[k]
        j = bp.b[k]
        ex, ey, ell, u, tha, thb = beam_kinematics(
            x[i, 0], x[i, 1], x[i, 2], x[j, 0], x[j, 1], x[j, 2], bp.L[k], bp.ux0[k], bp.uy0[k]
        )
        eps, kap, gam, ev = mid_span_strains(u, tha, thb, bp.L[k], bp.H[k], bp.gamma_fac[k])
        out[k, 0] = eps
        out[k, 1] = abs(kap) * 0.5 * bp.H[k]
        out[k, 2] = abs(gam)
        out[k, 3] = ev


def beam_constants(L, H, T, E, nu, shear_factor=5.0 / 6.0):
    """Cross-section constants of (5.2), (5.10): (EA, k_b, η, η/(2(1+η)))."""
    L, H, T, E, nu = (np.asarray(q, float) for q in (L, H, T, E, nu))
    A = H * T
    I = T * H**3 / 12.0
    G = E / (2.0 * (1.0 + nu))
    AQ = shear_factor * A
    eta = 12.0 * E * I / (G * AQ * L * L)
    kb = E * I / (L**3 * (1.0 + eta))
    return E * A, kb, eta, eta / (2.0 * (1.0 + eta))


def empty_params() -> BondParams:
    """Beam parameters of no bond (a scene without bonds)."""
    z = np.zeros(0)
    zi = np.zeros(0, np.int64)
    return BondParams(zi, zi, z, z, z, z, z, z, z, z, z, z, z, z, z, 0, z, empty_iface())


def new_work(nb: int, cnt=None, n: int = 0, iv=None) -> BondWork:
    """Work arrays of ``nb`` bonds (per-bond end forces of the provisional and the final pass); ``cnt``: which
    bonds this process counts in the statistics (default all); ``n``: particles of the interface model's rotation
    table (0 for beams); ``iv`` (n,): 1/(A T) of each particle where the interfaces' crack criterion needs the
    particles' stresses (None: it does not)."""
    m = 0 if iv is None else n
    return BondWork(
        np.zeros((nb, 4)),
        np.zeros((nb, 4)),
        np.ones(nb, np.int64) if cnt is None else cnt,
        np.zeros((n, 2)),
        np.zeros((m, 3)),
        np.zeros(m) if iv is None else np.asarray(iv, float),
        np.zeros((nb if m else 0, 6)),
    )


def new_history_new(nb: int, ne: int = 0) -> BondHistNew:
    """The history written by a final pass for ``nb`` bonds (all intact, undamaged); ``ne``: elements per
    interface (0: beams)."""
    return BondHistNew(
        np.zeros(nb),
        np.zeros(nb),
        np.ones(nb, np.bool_),
        np.zeros(nb),
        np.zeros(nb),
        new_iface_hist(nb if ne else 0, ne),
    )


def new_history(nb: int, ne: int = 0) -> BondHist:
    """The accepted history of ``nb`` intact, undamaged bonds (no failure recorded); ``ne``: elements per interface
    (0: beams)."""
    return BondHist(
        np.zeros(nb),
        np.zeros(nb),
        np.ones(nb, np.bool_),
        np.zeros(nb),
        np.ones(nb, np.bool_),
        -np.ones(nb, np.int64),
        np.zeros((nb, 3)),
        np.zeros(1, np.int64),
        np.zeros(nb),
        new_iface_hist(nb if ne else 0, ne),
    )
