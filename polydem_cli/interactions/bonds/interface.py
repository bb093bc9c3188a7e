"""Edge-interface bonds: the shared edge of two bonded polygons as a cohesive-frictional interface
(``[bonds] model = "interface"``), beside the thesis's beams (beam.py), which stay the default.

The law is assembled from three published pieces; the symbols are those of the sources.

* **The interface discretised into elements** (Potyondy 2012, "A flat-jointed bonded-particle material for hard
  rock", ARMA 12-501, §2: the flat joint's interface of ``N_r`` elements, each bonded or broken on its own, a
  broken element frictional): the shared edge of length ``H_h`` (and thickness ``T``) is cut into ``n_e`` equal
  elements of area ``A_e = H_h T / n_e``, each with one integration point at its middle.  An element's point is
  a material point of both polygons at t0; its relative displacement is ``δ = x_II(point) − x_I(point)``, split
  in the interface's frame into the opening ``u_n = δ·n`` (``n`` the edge normal from I to II, turned by the mean
  rotation of the two particles since t0 — the bisector of the normal turned with each — as the flat joint's
  interface between its two notional surfaces) and
  the slip ``u_s = δ·t``, ``t = e3 × n``.  A rigid motion of the
  pair gives δ = 0, so no force; a relative rotation loads the elements unevenly, so a partly broken interface
  still carries moment.
* **Damage of the bonded part, friction of the broken part** (Alfano & Sacco 2006, "Combining interface damage
  and friction in a cohesive-zone model", IJNME 68:542, eqs. (2)-(5)): an element of damage ``D`` is a fraction
  ``1 − D`` intact (elastic, ``σ̄ = k_n u_n``, ``τ̄ = k_s u_s``) and a fraction ``D`` of faces in unilateral
  contact with Coulomb friction (``σ_c = k_n ⟨u_n⟩₋``, ``|τ_c| ≤ μ_r (−σ_c)``, the slip ``s_p`` of the return
  mapping):  ``σ = (1 − D) σ̄ + D σ_c``, ``τ = (1 − D) τ̄ + D τ_c``.  Compression is never softened
  (``σ = k_n u_n`` for ``u_n < 0`` at any D, as the beam's Heaviside switch (5.5)).
* **A strength surface that couples tension and shear and lets the shear strength grow with compression**
  (Cusatis et al. 2011, "Lattice Discrete Particle Model (LDPM) for failure behavior of concrete. I", CCC 33:881,
  eqs. (10)-(14): the facet's effective stress against a boundary of tension-shear and compression-shear
  branches).  Here: a tension-shear parabola ``σ/f_t + (τ/c)² = 1`` for ``σ ≥ 0`` joined at ``σ = 0`` to the
  Mohr-Coulomb line ``|τ| = c − μ σ`` for ``σ < 0``.  The intact part's stress ``(σ̄, τ̄)`` is measured against
  it by the factor ``r`` it lies outside the surface along its own ray:
  ``r = ½ (σ̄/f_t + √((σ̄/f_t)² + 4 (τ̄/c)²))`` for σ̄ ≥ 0, ``r = (|τ̄| + μ σ̄)/c`` for σ̄ < 0 (both ``|τ̄|/c`` at
  σ̄ = 0).  The history ``κ = max_τ r`` drives a linear softening in the effective displacement, the form of the
  beams' (5.6) with ``κ_0 = 1``: ``D = κ_f (κ − 1)/(κ (κ_f − 1))`` between 1 and ``κ_f``, irreversible.
  The end ``κ_f`` makes the cohesive energy dissipated on a proportional path ``G``: the triangle under the
  softening has the area ``κ_f W_0`` with ``W_0`` the released energy density at onset, so
  ``κ_f = G/W_0`` with ``G = G_I + (G_II − G_I) ψ`` and ``ψ`` the share of shear in the released energy
  ``Y = ½ ⟨σ̄⟩₊²/k_n + ½ τ̄²/k_s − ½ τ_c²/k_s`` (the energy the intact fraction gives up to the frictional one).
  Under compression ``κ_f`` is pure shear's, ``κ_f = 2 k_s G_II/c²``: the dissipated cohesive energy grows with
  the onset stress squared (confined shear is more ductile, as LDPM's compression-shear softening).  A
  direction where ``G < W_0`` (only mixed directions can, the scenario refuses pure modes that would) breaks
  brittlely, ``κ_f = 1``.

Damage dissipates ``Y dD`` (trapezoidal rule over the step), friction ``D A_e τ_c Δs_p``.  The stiffnesses
per area are ``k_n = E/L_h`` (the beam's axial ``E_h A_h/L_h`` spread over the edge) and ``k_s = α k_n`` with
``α = (1 − 3ν)/(1 + ν)``, the ratio that gives a regular triangular lattice of normal and shear springs the
Poisson ratio ν in plane stress (Griffiths & Mustoe 2001, IJNME 50:1759, eq. (23)); on an irregular Voronoi
network the macroscopic E and ν differ, and ``polydem calibrate`` fits them.

A bond hands its pair over to polygon contact (thesis §4.1, O-13) when every element is broken (D = 1) and
either every element is open (``u_n ≥ 0``: the faces have parted) or an element has slid by more than a
quarter of the edge (its material points no longer face each other); until then the broken elements carry
compression and friction as the flat joint's do.

Units: stresses in g cm⁻¹ s⁻² (1 N/mm² = 1e7), k_n, k_s in g cm⁻² s⁻², energies per area in g s⁻² (1 N/m = 1e3).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit, prange

from ...jit import loop_njit, serial_and_parallel
from .beam import BS_AMBIG, BS_FRIC, add_bond_forces, damage_of
from .iface_data import MODEL_BEAM, MODEL_INTERFACE, IfaceHist, IfaceParams, empty_iface, new_iface_hist  # noqa: F401


def stiffness_ratio(nu):
    """α = k_s/k_n = (1 − 3ν)/(1 + ν): the regular triangular lattice's ν in plane stress (Griffiths & Mustoe
    2001, eq. (23)); ν ≤ 1/3."""
    nu = np.asarray(nu, float)
    return (1.0 - 3.0 * nu) / (1.0 + nu)


def element_points(edges, xa, xb, ne: int):
    """The element points (midpoints of ``ne`` equal parts of each shared edge, (nb, 2, 2) end points) relative to
    the centroids ``xa``, ``xb`` (nb, 2) of I and II, and each edge's unit normal pointing from I to II."""
    edges = np.asarray(edges, float)
    s = (np.arange(ne) + 0.5) / ne
    P = edges[:, None, 0, :] + s[None, :, None] * (edges[:, None, 1, :] - edges[:, None, 0, :])
    t = edges[:, 1] - edges[:, 0]
    n = np.column_stack([-t[:, 1], t[:, 0]]) / np.hypot(t[:, 0], t[:, 1])[:, None]
    flip = np.einsum("ij,ij->i", n, np.asarray(xb, float) - np.asarray(xa, float)) < 0
    n[flip] *= -1.0
    return P - np.asarray(xa, float)[:, None, :], P - np.asarray(xb, float)[:, None, :], n


def _turn(v, phi):
    """Vectors v (..., 2) turned by the angles phi (broadcast over v's leading axes)."""
    c, s = np.cos(phi), np.sin(phi)
    return np.stack([c * v[..., 0] - s * v[..., 1], s * v[..., 0] + c * v[..., 1]], axis=-1)


def body_frame(rI, rII, n, phi0):
    """The element points (nb, n_e, 2) and the edge normal (nb, 2) of the scene at t0 in each particle's body frame
    (turned back by its angle at t0, ``phi0`` (nb, 2)): (rI, rII, normal in I's and in II's frame (nb, 2, 2))."""
    rIb = _turn(rI, -phi0[:, :1])
    rIIb = _turn(rII, -phi0[:, 1:])
    return rIb, rIIb, np.stack([_turn(n, -phi0[:, 0]), _turn(n, -phi0[:, 1])], axis=1)


@njit(cache=True, inline="always")
def strength_ratio(sn, ss, ft, coh, mu):
    """r: how far the intact stress (σ̄, τ̄) lies out along its ray against the strength surface (module doc)."""
    if sn >= 0.0:
        a = sn / ft
        b = ss / coh
        return 0.5 * (a + math.sqrt(a * a + 4.0 * b * b))
    r = (abs(ss) + mu * sn) / coh
    return r if r > 0.0 else 0.0


@njit(cache=True, inline="always")
def softening_end(sn, ss, r, kn, ks, ft, coh, GI, GII):
    """κ_f = G/W_0 of the element's present direction (module doc), at least 1."""
    if sn < 0.0 or r <= 0.0:
        kf = 2.0 * ks * GII / (coh * coh)
    else:
        wn = 0.5 * sn * sn / kn
        ws = 0.5 * ss * ss / ks
        w = wn + ws
        if w <= 0.0:
            return 1.0
        G = GI + (GII - GI) * ws / w
        kf = G * r * r / w
    return kf if kf > 1.0 else 1.0


@njit(cache=True, inline="always")
def element_law(un, us, D0, kap0, sp0, kn, ks, ft, coh, ift, ico, mu, mur, GI, GII, rp):  # noqa: PLR0913 - scalars, inline
    """One element: (σ, τ, D, κ, s_p, σ̄, τ̄, σ_c, τ_c) from the opening ``un``, the slip ``us`` and the committed
    history (D0, κ0, s_p0) (module doc); ``ift``, ``ico``: 1/f_t, 1/c.  The damage grows only while the element loads (r above its history κ),
    along the present direction's softening; κ is recorded once beyond the onset (r > 1).  An element inside the
    surface needs no square root (the check is the surface's own inequality).  ``rp``: the ratio σ_I/f_p of the
    largest principal stress of the element's two particles' mean stress to the crack strength
    (``crack_criterion = "principal"``; 0 otherwise): above 1 the material between the two particles has cracked
    across, whatever the edge's own orientation, and the element breaks (D = 1; brittle, as the flat joint's
    elements, Potyondy 2012); its faces then carry compression and friction as any broken element's."""
    sn = kn * un
    ss = ks * us
    kap = kap0
    D = D0
    if sn >= 0.0:
        a = sn * ift
        b = ss * ico
        out = a + b * b > 1.0
    else:
        out = abs(ss) + mu * sn > coh
    if out:
        r = strength_ratio(sn, ss, ft, coh, mu)
        if r > kap0:
            kap = r
            Dn = damage_of(r, 1.0, softening_end(sn, ss, r, kn, ks, ft, coh, GI, GII))
            if Dn > D:
                D = Dn
    if rp > 1.0:
        if rp > kap:
            kap = rp
        D = 1.0
    # broken fraction: unilateral contact and Coulomb friction (return mapping on s_p)
    sc = sn if un < 0.0 else 0.0
    tc = ks * (us - sp0)
    lim = -mur * sc
    sp = sp0
    if abs(tc) > lim:
        tc = lim if tc > 0.0 else -lim
        sp = us - tc / ks
    return (1.0 - D) * sn + D * sc, (1.0 - D) * ss + D * tc, D, kap, sp, sn, ss, sc, tc


def _iface_kernel_impl(final, x, bp, bh, bn, bw):  # noqa: PLR0915 - one compiled loop over bonds and elements
    """Per-bond forces of the interface law (the beams' BondWork layout: fx, fy, c_I, c_II of particle I); in a
    final pass also the new history (``bn``, ``bn_e``: per bond and per element).  Arrays bound to locals before
    the ``prange`` (numba drops writes through a namedtuple field inside it; beam.py)."""
    ip = bp.iface
    ie = bh.iface
    ien = bn.iface
    a_ = bp.a
    b_ = bp.b
    L_ = bp.L
    rI_ = ip.rI
    rII_ = ip.rII
    n0_ = ip.n0
    Ae_ = ip.Ae
    kn_ = ip.kn
    ks_ = ip.ks
    ft_ = ip.ft
    co_ = ip.coh
    mu_ = ip.mu
    mr_ = ip.mur
    GI_ = ip.GI
    GII_ = ip.GII
    smax_ = ip.slip_max
    D_ = ie.D
    K_ = ie.kap
    S_ = ie.sp
    C_ = ie.cp
    Y_ = ie.Y
    Dn_ = ien.D
    Kn_ = ien.kap
    Sn_ = ien.sp
    Cn_ = ien.cp
    cap_ = ip.cap
    Yn_ = ien.Y
    act_ = bh.active
    eact_ = bh.eval_active
    fstep_ = bh.fail_step
    fstr_ = bh.fail_strain
    clock = bh.clock
    kapb_ = bh.kappa
    db_ = bh.d
    Yb_ = bh.Y
    knb_ = bn.kappa
    dnb_ = bn.d
    anb_ = bn.active
    Ynb_ = bn.Y
    wf = bw.f
    we = bw.e
    cs = bw.cs
    sg = bw.sg
    pm_ = bw.pm
    principal = ip.principal != 0
    fp_ = ip.fp
    ne = rI_.shape[1]
    for p in prange(cs.shape[0]):  # each particle's rotation once (a particle has about six bonds)
        cs[p, 0] = math.cos(x[p, 2])
        cs[p, 1] = math.sin(x[p, 2])
    for k in prange(a_.shape[0]):
        wf[k, 0] = 0.0
        wf[k, 1] = 0.0
        wf[k, 2] = 0.0
        wf[k, 3] = 0.0
        we[k, 1] = 0.0
        we[k, 2] = 0.0
        we[k, 3] = 0.0
        if not act_[k]:
            eact_[k] = False
            we[k, 0] = 0.0
            if final:
                knb_[k] = kapb_[k]
                dnb_[k] = db_[k]
                anb_[k] = False
                Ynb_[k] = Yb_[k]
                for e in range(ne):
                    Dn_[k, e] = D_[k, e]
                    Kn_[k, e] = K_[k, e]
                    Sn_[k, e] = S_[k, e]
                    Cn_[k, e] = C_[k, e]
                    Yn_[k, e] = Y_[k, e]
            continue
        i = a_[k]
        j = b_[k]
        xi = x[i, 0]
        yi = x[i, 1]
        xj = x[j, 0]
        yj = x[j, 1]
        dx = xj - xi
        dy = yj - yi
        ci = cs[i, 0]
        si = cs[i, 1]
        cj = cs[j, 0]
        sj = cs[j, 1]
        # the interface turns with the mean rotation of its two faces: the bisector of the normal turned with I and
        # the normal turned with II (exactly the mean angle while their rotations differ by less than pi)
        nx = ci * n0_[k, 0, 0] - si * n0_[k, 0, 1] + cj * n0_[k, 1, 0] - sj * n0_[k, 1, 1]
        ny = si * n0_[k, 0, 0] + ci * n0_[k, 0, 1] + sj * n0_[k, 1, 0] + cj * n0_[k, 1, 1]
        nn = math.sqrt(nx * nx + ny * ny)
        if nn > 1e-9:
            nx /= nn
            ny /= nn
        else:  # the two faces turned half a turn against each other: I's normal
            nx = ci * n0_[k, 0, 0] - si * n0_[k, 0, 1]
            ny = si * n0_[k, 0, 0] + ci * n0_[k, 0, 1]
        tx = -ny
        ty = nx
        kn = kn_[k]
        ks = ks_[k]
        A = Ae_[k]
        e_el = 0.0
        diss = 0.0
        fric = 0.0
        dsum = 0.0
        kmax = 0.0
        ysum = 0.0
        nbroken = 0
        nopen = 0
        slipped = False
        un_sum = 0.0
        us_sum = 0.0
        # the elements' points lie on the edge at equal steps h: their relative displacement and the middle of their
        # two material points are linear in the element's number e (rotated once per bond, not per element)
        r0x = rI_[k, 0, 0]
        r0y = rI_[k, 0, 1]
        q0x = rII_[k, 0, 0]
        q0y = rII_[k, 0, 1]
        hx = rI_[k, 1, 0] - r0x if ne > 1 else 0.0  # the step in I's body frame
        hy = rI_[k, 1, 1] - r0y if ne > 1 else 0.0
        gx = rII_[k, 1, 0] - q0x if ne > 1 else 0.0  # and in II's
        gy = rII_[k, 1, 1] - q0y if ne > 1 else 0.0
        rix = ci * r0x - si * r0y
        riy = si * r0x + ci * r0y
        rjx = cj * q0x - sj * q0y
        rjy = sj * q0x + cj * q0y
        hix = ci * hx - si * hy
        hiy = si * hx + ci * hy
        hjx = cj * gx - sj * gy
        hjy = sj * gx + cj * gy
        d0x = dx + rjx - rix
        d0y = dy + rjy - riy
        un0 = d0x * nx + d0y * ny
        us0 = d0x * tx + d0y * ty
        dun = (hjx - hix) * nx + (hjy - hiy) * ny
        dus = (hjx - hix) * tx + (hjy - hiy) * ty
        ift = 1.0 / ft_[k]
        ico = 1.0 / co_[k]
        rp = 0.0
        if principal and final:  # the particles' stresses of this step's provisional pass (iface_pass)
            sxx = 0.5 * (sg[i, 0] + sg[j, 0])
            syy = 0.5 * (sg[i, 1] + sg[j, 1])
            sxy = 0.5 * (sg[i, 2] + sg[j, 2])
            s1 = 0.5 * (sxx + syy) + math.sqrt(0.25 * (sxx - syy) * (sxx - syy) + sxy * sxy)
            rp = s1 / fp_[k] if s1 > 0.0 else 0.0
        s0n = 0.0
        s0t = 0.0
        s1n = 0.0
        s1t = 0.0
        for e in range(ne):
            un = un0 + e * dun
            us = us0 + e * dus
            # the compressive cap: the normal compression held at it, the rest a permanent compaction (crushing)
            cp = C_[k, e]
            ue = un - cp
            if kn * ue < -cap_[k]:
                cp = un + cap_[k] / kn
                ue = un - cp
            sig, tau, D, kap, sp, sn, ss, sc, tc = element_law(
                ue,
                us,
                D_[k, e],
                K_[k, e],
                S_[k, e],
                kn,
                ks,
                ft_[k],
                co_[k],
                ift,
                ico,
                mu_[k],
                mr_[k],
                GI_[k],
                GII_[k],
                rp,
            )
            s0n += sig
            s0t += tau
            s1n += e * sig
            s1t += e * tau
            dsum += D
            if kap > kmax:
                kmax = kap
            if D >= 1.0:
                nbroken += 1
                if un >= 0.0:  # the faces apart in geometry (a crushed element's compaction still overlaps them)
                    nopen += 1
            if abs(us) > smax_[k]:
                slipped = True
            un_sum += un
            us_sum += abs(us)
            if final:
                snp = sn if sn > 0.0 else 0.0
                Y = 0.5 * snp * snp / kn + 0.5 * (ss * ss - tc * tc) / ks  # released energy density, -dpsi/dD
                e_el += A * ((1.0 - D) * 0.5 * (sn * ue + ss * us) + D * (0.5 * sc * ue + 0.5 * tc * tc / ks))
                wfr = tc * (sp - S_[k, e])
                if cp < C_[k, e]:  # crushing work
                    fric += A * cap_[k] * (C_[k, e] - cp)
                if D > D_[k, e]:
                    diss += A * 0.5 * (Y_[k, e] + Y) * (D - D_[k, e])
                fric += A * D * wfr
                Dn_[k, e] = D
                Kn_[k, e] = kap
                Sn_[k, e] = sp
                Cn_[k, e] = cp
                Yn_[k, e] = Y
                ysum += Y
        # the tractions on I, A (σ n + τ t) at the middle of each element's two material points (angular momentum
        # kept): their sum, and their moments about I's and II's centroids from the sums over e of σ, τ, e σ, e τ
        g0x = A * (s0n * nx + s0t * tx)
        g0y = A * (s0n * ny + s0t * ty)
        g1x = A * (s1n * nx + s1t * tx)
        g1y = A * (s1n * ny + s1t * ty)
        p0x = 0.5 * (rix + dx + rjx)
        p0y = 0.5 * (riy + dy + rjy)
        dpx = 0.5 * (hix + hjx)
        dpy = 0.5 * (hiy + hjy)
        if principal:  # the first moment of the tractions about I's centroid is p0 ⊗ g0 + dp ⊗ g1
            pm_[k, 0] = p0x
            pm_[k, 1] = p0y
            pm_[k, 2] = dpx
            pm_[k, 3] = dpy
            pm_[k, 4] = g1x
            pm_[k, 5] = g1y
        m1 = dpx * g1y - dpy * g1x
        fx = g0x
        fy = g0y
        cI = p0x * g0y - p0y * g0x + m1
        cII = -((p0x - dx) * g0y - (p0y - dy) * g0x + m1)
        fails = nbroken == ne and (nopen == ne or slipped)
        if fails:
            eact_[k] = False
            we[k, 0] = 3.0
            if final:
                # the faces part (or slide off each other): what the interface still stores goes with it
                we[k, 2] = diss + fric + e_el
                we[k, 3] = fric
                knb_[k] = kmax
                dnb_[k] = 1.0
                anb_[k] = False
                Ynb_[k] = 0.0
                fstep_[k] = clock[0]
                fstr_[k, 0] = un_sum / (ne * L_[k])
                fstr_[k, 1] = 0.0
                fstr_[k, 2] = us_sum / (ne * L_[k])
            continue
        eact_[k] = True
        wf[k, 0] = fx
        wf[k, 1] = fy
        wf[k, 2] = cI
        wf[k, 3] = cII
        dm = dsum / ne
        we[k, 0] = 2.0 if dm > 0.0 else 1.0
        if final:
            we[k, 1] = e_el
            we[k, 2] = diss + fric
            we[k, 3] = fric
            knb_[k] = kmax
            dnb_[k] = dm
            anb_[k] = True
            Ynb_[k] = ysum


_iface_kernel_ser, _iface_kernel_par = serial_and_parallel(_iface_kernel_impl)
PARALLEL_MIN_BONDS = 1000


@loop_njit
def iface_pass(final, x, bp, bh, bn, bw, F, bstats):
    """Provisional or final update of the interface bonds (as beam.bond_pass): the per-bond work in parallel, the
    forces added serially in bond order (independent of the number of threads)."""
    if bp.a.shape[0] >= PARALLEL_MIN_BONDS:
        _iface_kernel_par(final, x, bp, bh, bn, bw)
    else:
        _iface_kernel_ser(final, x, bp, bh, bn, bw)
    if bp.iface.principal != 0 and not final:
        particle_stress(x, bp, bh, bw)
    fric = add_bond_forces(final, bp, bw, F, bstats)  # the beams' serial sum (beam.py); column 3 is the friction
    if final:
        bstats[BS_FRIC] = fric
        bstats[BS_AMBIG] = 0.0


@loop_njit
def particle_stress(x, bp, bh, bw):
    """Each particle's mean stress from its interfaces' tractions (Love–Weber: σ = (1/V) Σ sym(r ⊗ f) over the
    elements, r from the particle's centroid to the element's point, f the element's force on it; tension positive),
    for the ``principal`` crack criterion of the final pass at the same step.  Per bond the elements' sum is
    p0 ⊗ g0 + dp ⊗ g1 (the kernel's first point, step, force sum and e-weighted force sum).  Serial, in bond
    order; the bonds this evaluation left active (``eval_active``)."""
    sg = bw.sg
    iv = bw.iv
    wf = bw.f
    pm = bw.pm
    a = bp.a
    b = bp.b
    act = bh.eval_active
    for p in range(sg.shape[0]):
        sg[p, 0] = 0.0
        sg[p, 1] = 0.0
        sg[p, 2] = 0.0
    for k in range(a.shape[0]):
        if not act[k]:
            continue
        fx = wf[k, 0]
        fy = wf[k, 1]
        i = a[k]
        j = b[k]
        px = pm[k, 0]
        py = pm[k, 1]
        hx = pm[k, 2]
        hy = pm[k, 3]
        gx = pm[k, 4]
        gy = pm[k, 5]
        qx = px - (x[j, 0] - x[i, 0])  # the first point from II's centroid
        qy = py - (x[j, 1] - x[i, 1])
        mxy = 0.5 * (hx * gy + hy * gx)
        sg[i, 0] += iv[i] * (px * fx + hx * gx)
        sg[i, 1] += iv[i] * (py * fy + hy * gy)
        sg[i, 2] += iv[i] * (0.5 * (px * fy + py * fx) + mxy)
        sg[j, 0] -= iv[j] * (qx * fx + hx * gx)
        sg[j, 1] -= iv[j] * (qy * fy + hy * gy)
        sg[j, 2] -= iv[j] * (0.5 * (qx * fy + qy * fx) + mxy)


@loop_njit
def accept_iface(bn, bh):
    """The step is accepted: the elements' history of its final pass becomes theirs."""
    s = bn.iface
    d = bh.iface
    for k in range(d.D.shape[0]):
        for e in range(d.D.shape[1]):
            d.D[k, e] = s.D[k, e]
            d.kap[k, e] = s.kap[k, e]
            d.sp[k, e] = s.sp[k, e]
            d.Y[k, e] = s.Y[k, e]
            d.cp[k, e] = s.cp[k, e]


def element_stiffness(ip: IfaceParams, kn=None, ks=None) -> np.ndarray:
    """The intact interfaces' 6 x 6 stiffnesses (nb, 6, 6) in the DOFs (x_I, y_I, φ_I, x_II, y_II, φ_II) at t0:
    Σ_e A_e Bᵀ diag(k_n, k_s) B with δ = B q, δ = u_II + φ_II e3 × r_II − u_I − φ_I e3 × r_I (for the time step's
    bound, and the static solve of analysis/elastic.py); ``kn``, ``ks`` (nb,): other stiffnesses per area than
    the built ones (a calibration's trial E and ν)."""
    kn = ip.kn if kn is None else np.asarray(kn, float)
    ks = ip.ks if ks is None else np.asarray(ks, float)
    n = _turn(ip.n0[:, 0], ip.phi0[:, 0])  # at t0, in the global frame
    rIg = _turn(ip.rI, ip.phi0[:, :1])
    rIIg = _turn(ip.rII, ip.phi0[:, 1:])
    t = np.column_stack([-n[:, 1], n[:, 0]])
    nb = n.shape[0]
    K = np.zeros((nb, 6, 6))
    for e in range(ip.rI.shape[1]):
        rI, rII = rIg[:, e], rIIg[:, e]
        for v, kk in ((n, kn), (t, ks)):
            B = np.column_stack(
                [
                    -v[:, 0],
                    -v[:, 1],
                    rI[:, 1] * v[:, 0] - rI[:, 0] * v[:, 1],
                    v[:, 0],
                    v[:, 1],
                    -rII[:, 1] * v[:, 0] + rII[:, 0] * v[:, 1],
                ]
            )
            K += (ip.Ae * kk)[:, None, None] * B[:, :, None] * B[:, None, :]
    return K
