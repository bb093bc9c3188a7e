"""Elasto-damage Timoshenko beam bonds (thesis §5.1.2, §5.2.2) against closed forms."""

import math

import numpy as np
import pytest

from polydem_cli.engine.simulation import Simulation
from polydem_cli.interactions.bonds.beam import (
    N_BSTATS,
    BondParams,
    accept_history,
    beam_constants,
    bond_pass,
    damage_of,
    kappa0_rate,
    new_history,
    new_history_new,
    new_work,
)
from polydem_cli.interactions.bonds.interface import empty_iface

from helpers import run, system_from_toml

E, NU, KAPPA0 = 1.0e4, 0.25, 1e-3


def one_bond(L=1.0, H=0.7, T=1.0, E=E, nu=NU, kappa0=KAPPA0, kappam=5e-3, angle=0.0, rate=0, eps0=1.0, alpha=0.0):
    EA, kb, eta, gfac = beam_constants([L], [H], [T], [E], [nu])
    a = np.array([0]), np.array([1])
    return BondParams(
        *a,
        np.array([L]),
        np.array([H]),
        np.array([T]),
        EA,
        kb,
        eta,
        gfac,
        np.array([kappa0]),
        np.array([kappam]),
        np.array([eps0]),
        np.array([alpha]),
        np.array([math.cos(angle)]),
        np.array([math.sin(angle)]),
        rate,
        np.ones(1),
        empty_iface(),
    )


def forces(bp, x, v=None, bh=None, final=True):
    bh = bh if bh is not None else new_history(1)
    F = np.zeros((2, 3))
    st = np.zeros(N_BSTATS)
    bn = new_history_new(1)
    bond_pass(
        final,
        np.asarray(x, float),
        np.zeros((2, 3)) if v is None else np.asarray(v, float),
        bp,
        bh,
        bn,
        new_work(1),
        F,
        st,
    )
    if final:  # an accepted step: its history becomes the bond's
        accept_history(bn, bh)
    return F, bh, st


def timoshenko_K(L, EA, EI, eta):
    """Element stiffness of a 2-node bar + Timoshenko beam, DOFs [u1, v1, θ1, u2, v2, θ2] (local)."""
    k = EI / (L**3 * (1 + eta))
    a = EA / L
    return np.array(
        [
            [a, 0, 0, -a, 0, 0],
            [0, 12 * k, 6 * L * k, 0, -12 * k, 6 * L * k],
            [0, 6 * L * k, (4 + eta) * L * L * k, 0, -6 * L * k, (2 - eta) * L * L * k],
            [-a, 0, 0, a, 0, 0],
            [0, -12 * k, -6 * L * k, 0, 12 * k, -6 * L * k],
            [0, 6 * L * k, (2 - eta) * L * L * k, 0, -6 * L * k, (4 + eta) * L * L * k],
        ]
    )


def test_small_displacements_match_direct_timoshenko_stiffness():
    rng = np.random.default_rng(0)
    for _ in range(20):
        L, H, ang = rng.uniform(0.5, 1.5), rng.uniform(0.2, 1.2), rng.uniform(-np.pi, np.pi)
        bp = one_bond(L=L, H=H, angle=ang, kappa0=1.0, kappam=2.0)  # stays elastic
        c, s = math.cos(ang), math.sin(ang)
        x0 = np.array([[0.3, -0.2, 0.0], [0.3 + L * c, -0.2 + L * s, 0.0]])
        u = rng.normal(size=6) * 1e-7 * L
        F, _, _ = forces(bp, x0 + u.reshape(2, 3))
        # independent: global stiffness R^T K R with R the rotation into the beam axis
        R1 = np.array([[c, s, 0], [-s, c, 0], [0, 0, 1]])
        R = np.zeros((6, 6))
        R[:3, :3] = R1
        R[3:, 3:] = R1
        I = 1.0 * H**3 / 12.0
        G = E / (2 * (1 + NU))
        eta = 12 * E * I / (G * 5 / 6 * H * 1.0 * L * L)
        K = R.T @ timoshenko_K(L, E * H * 1.0, E * I, eta) @ R
        ref = -(K @ u)
        scale = np.abs(ref).max()
        assert np.allclose(F.ravel(), ref, rtol=0, atol=1e-5 * scale)


@pytest.mark.parametrize("psi", [0.3, 2.0, 3.1, -2.5, 7.0, 100.0])
def test_rigid_rotation_of_the_bonded_pair_gives_no_force(psi):
    L, ang = 1.2, 0.4
    bp = one_bond(L=L, angle=ang)
    x0 = np.array([[0.0, 0.0, 0.0], [L * math.cos(ang), L * math.sin(ang), 0.0]])
    c, s = math.cos(psi), math.sin(psi)
    pivot = np.array([2.0, -1.0])
    x = x0.copy()
    x[:, :2] = (x0[:, :2] - pivot) @ np.array([[c, -s], [s, c]]).T + pivot + [5.0, 3.0]
    x[:, 2] = psi
    F, bh, st = forces(bp, x)
    ref = E * 0.7 * 1.0 * 1e-3  # a force scale: EA at a strain of 1e-3
    assert np.abs(F).max() < 1e-9 * ref
    assert bh.kappa[0] < 1e-12 and st[0] < 1e-20


def _axial_run(G_ax, kappa0, steps_total, extra="", unload=False):
    """Two unit squares bonded along their shared edge; the right one is pulled along e1."""
    L = 1.0
    kappam = 2 * G_ax / (1.0 * kappa0 * L)
    v = 1.2 * kappam * L / (steps_total * 1e-3)  # reach 1.2 kappa_m at the end
    text = f"""
[scenario]
title = "axial"
[time]
dt = 1e-3
end_time = {steps_total * 1e-3}
{extra}
[materials.m]
density = 1.0
[[particles]]
name = "pair"
material = "m"
thickness = 1.0
type = "hexagon_packing"
width = 1.0
rows = 1
row_counts = [2]
[bonds]
E = 1.0
nu = 0.3
kappa_0 = {kappa0}
G_ax = {G_ax}
[[boundary]]
set = "pair[0]"
x1 = "fixed"
x2 = "fixed"
phi = "fixed"
[[boundary]]
set = "pair[1]"
x1 = {{ velocity = {v} }}
x2 = "fixed"
phi = "fixed"
"""
    return system_from_toml(text), kappam


def test_axial_tension_to_failure_follows_linear_softening_and_dissipates_G_A():
    G_ax, kappa0 = 2.5e-6, 1e-3  # kappa_m = 2 G/(E kappa_0 L) = 5e-3
    system, kappam = _axial_run(G_ax, kappa0, 20000)
    assert kappam == pytest.approx(5e-3)
    sim, h = run(system, every=1)
    L, H, T = 1.0, 1.0 / math.sqrt(3.0), 1.0  # hexagons of width 1: L_h = 1, H_h = side
    EA = 1.0 * H * T
    u = h["u1:pair[1]"]
    N = h["f1:pair[1]"]  # reaction on the pulled particle = bar force (tension positive)
    eps = u / L
    pre = eps <= kappa0
    soft = (eps > kappa0) & (eps < kappam)
    after = eps >= kappam
    assert pre.sum() > 100 and soft.sum() > 1000 and after.sum() > 100
    assert np.allclose(N[pre], EA * eps[pre], rtol=1e-10, atol=1e-18)
    assert np.allclose(N[soft], EA * kappa0 * (kappam - eps[soft]) / (kappam - kappa0), rtol=1e-9)
    assert np.all(N[after] == 0.0)
    assert h["bonds_failed"][-1] == 1 and h["bonds_active"][-1] == 0
    # dissipated energy = G_h,ax A_h (5.12)
    assert h["dissipated_damage"][-1] == pytest.approx(G_ax * H * T, rel=1e-6)
    # and it equals the work done by the support (no kinetic energy change: constant velocity)
    assert h["external_work"][-1] == pytest.approx(G_ax * H * T, rel=1e-6)


def test_unloading_is_secant_to_the_origin_and_compression_is_not_softened():
    bp = one_bond(L=1.0, H=0.5, kappa0=1e-3, kappam=5e-3)
    EA = E * 0.5
    bh = new_history(1)
    x = lambda u: np.array([[0, 0, 0], [1.0 + u, 0, 0]], float)  # noqa: E731
    F, bh, _ = forces(bp, x(3e-3), bh=bh)  # load into softening
    d = bh.d[0]
    assert d == pytest.approx(damage_of(3e-3, 1e-3, 5e-3)) and 0 < d < 1
    for u in (2e-3, 1e-3, 2e-4, 0.0):
        F, bh, _ = forces(bp, x(u), bh=bh)
        assert F[0, 0] == pytest.approx((1 - d) * EA * u, rel=1e-12, abs=1e-15)  # damaged secant stiffness
        assert bh.d[0] == d  # no further damage on unloading
    for u in (-1e-4, -3e-3, -2e-2):  # compression: full stiffness, no new damage
        F, bh, _ = forces(bp, x(u), bh=bh)
        assert F[0, 0] == pytest.approx(EA * u, rel=1e-12)
        assert bh.d[0] == d
    # reloading in tension continues on the damaged secant until kappa is exceeded
    F, bh, _ = forces(bp, x(2.5e-3), bh=bh)
    assert F[0, 0] == pytest.approx((1 - d) * EA * 2.5e-3, rel=1e-12)


def test_shear_and_bending_damage_the_beam():
    bp = one_bond(L=1.0, H=0.5, kappa0=1e-3, kappam=5e-3)
    F, bh, _ = forces(bp, np.array([[0, 0, 0.0], [1.0, 0, 0.01]]))  # end rotation: bending + shear
    assert bh.d[0] > 0 and bh.kappa[0] > 1e-3


def test_rate_dependent_threshold_and_alpha_zero():
    assert kappa0_rate(1e-9, 1e-5, 1e-8, 0.1) == 1e-5
    assert kappa0_rate(1e-6 / 30, 1e-5, 1e-8, 0.1) == pytest.approx(1e-5 * (1 / 0.3) ** 0.1)
    # Table 5.1 single-beam ratios at the macroscopic rate 3.33e-8 1/s
    r = 1e-6 / 30
    assert kappa0_rate(r, 1.0, 1e-8, 0.1) == pytest.approx(1.13, abs=0.005)
    assert kappa0_rate(r, 1.0, 1e-8, 0.2) == pytest.approx(1.27, abs=0.005)
    assert kappa0_rate(r, 1.0, 2e-8, 0.1) == pytest.approx(1.05, abs=0.005)


def test_rate_dependent_beam_starts_to_damage_at_kappa0_ra():
    """Constant axial strain rate: damage begins at κ_0,ra of (5.13) within one time step."""
    G_ax, kappa0 = 2.5e-6, 1e-3
    system, kappam = _axial_run(G_ax, kappa0, 4000)
    from polydem_cli.scenario.build import build_system
    from polydem_cli.scenario.load import validate

    sc = dict(system.scenario)
    sc["bonds"] = dict(sc["bonds"], rate_dependent=True, eps0_dot=1e-5, alpha=0.2)
    sys_r = build_system(validate(sc, "<test>"), "<test>")
    sim, h = run(sys_r, every=1)
    v = sys_r.bc_vel[1, 0]
    rate = v / 1.0
    k0ra = kappa0 * (rate / 1e-5) ** 0.2
    assert k0ra > 1.5 * kappa0
    eps = h["u1:pair[1]"]
    first = np.flatnonzero(h["bonds_damaged"] > 0)[0]
    assert eps[first - 1] <= k0ra < eps[first] + 1e-12
    assert eps[first] - k0ra <= rate * 1e-3 * 1.0001
    # alpha = 0 reproduces the rate-independent model exactly
    sc0 = dict(system.scenario)
    sc0["bonds"] = dict(sc0["bonds"], rate_dependent=True, eps0_dot=1e-3, alpha=0.0)
    sim0, h0 = run(build_system(validate(sc0, "<test>"), "<test>"), every=1)
    simr, hr = run(system, every=1)
    assert np.allclose(h0["f1:pair[1]"], hr["f1:pair[1]"], rtol=1e-12, atol=0)
    assert np.allclose(h0["dissipated_damage"], hr["dissipated_damage"], rtol=1e-12, atol=0)
    assert hr["bonds_damaged"].max() == 1


def test_rate_filter_option_follows_the_exponential_filter():
    """Option bonds.rate_filter: from rest, a constant axial strain rate r is seen by (5.13) as
    r_f = r (1 - exp(-t/tau)); damage starts where the strain reaches kappa_0 (r_f/eps0_dot)^alpha,
    earlier than with the thesis's instantaneous rate."""
    G_ax, kappa0 = 2.5e-6, 1e-3
    system, kappam = _axial_run(G_ax, kappa0, 4000)
    from polydem_cli.scenario.build import build_system
    from polydem_cli.scenario.load import validate

    eps0, alpha, tau = 1e-5, 0.2, 1.0
    base = dict(system.scenario["bonds"], rate_dependent=True, eps0_dot=eps0, alpha=alpha)
    v = system.bc_vel[1, 0]
    rate = v / 1.0
    first = {}
    for name, tf in (("thesis", 0.0), ("filtered", tau)):
        sc = dict(system.scenario, bonds=dict(base, rate_filter=tf))
        s = build_system(validate(sc, "<test>"), "<test>")
        sim, h = run(s, every=1)
        first[name] = k = int(np.flatnonzero(h["bonds_damaged"] > 0)[0])
        if name == "filtered":
            t = h["time"]
            rf = rate * (1.0 - np.exp(-t / tau))
            k0ra = kappa0 * np.maximum(rf / eps0, 1.0) ** alpha
            eps = h["u1:pair[1]"]
            assert eps[k - 1] <= k0ra[k - 1] and eps[k] > k0ra[k] * (1 - 1e-9)
            sim1 = Simulation(s)
            sim1.initialize()
            sim1.advance(300, np.zeros((4, sim1.ncols)), 10**9)
            assert sim1.bundle("bonds").h.rate_f[0] == pytest.approx(
                rate * (1.0 - math.exp(-300 * s.dt / tau)), rel=1e-6
            )
        else:
            assert sim.bundle("bonds").h.rate_f[0] == 0.0  # the thesis's form keeps no filter state
    assert first["filtered"] < first["thesis"]


def test_failed_bond_hands_the_pair_to_contact():
    """A bonded pair is pressed together (by a body force) and sheared until the beam fails; the
    bonded pair is excluded from contact while the beam lives, then contact carries the load."""
    text = """
[scenario]
title = "handover"
[time]
dt = 1e-5
end_time = 0.2
[output]
observe = ["pair[1]"]
[materials.m]
density = 1.0
k_n = 1.0e7
k_t = 1.0e6
mu_t = 0.3
[[particles]]
name = "pair"
material = "m"
thickness = 1.0
type = "hexagon_packing"
width = 1.0
rows = 1
row_counts = [2]
[bonds]
E = 1.0e6
nu = 0.0
kappa_0 = 1.0e-3
kappa_m = 2.0e-3
[contact]
tangential = "coulomb"
[body_force]
gravity = [-1000.0, 0.0]
[[boundary]]
set = "pair[0]"
x1 = "fixed"
x2 = "fixed"
phi = "fixed"
[[boundary]]
set = "pair[1]"
x2 = { velocity = 0.05 }
phi = "fixed"
"""
    sim, h = run(system_from_toml(text), every=10)
    failed = h["bonds_failed"] > 0
    assert failed.any() and not failed[0]
    k = int(np.argmax(failed))
    before = slice(1, k)
    # before failure: the beam is compressed, the polygons overlap, yet no contact is detected
    u1 = h["u1:pair[1]"]
    assert (u1[before] < -1e-4).mean() > 0.7 and u1[before].min() < -2e-3  # overlapping most of the time
    assert np.all(h["n_contacts"][before] == 0)
    # after failure the beam is gone; contact, not the dead beam, repels the particles: the stored
    # compression throws the free particle off, gravity brings it back, it bounces on the contact
    aft = h["n_contacts"][k:] == 1
    assert aft[0] and aft[1:].sum() >= 5 and (~aft).sum() > 20  # repeated contact phases
    w = sim.system.mass[1] * 1000.0
    f_contact = w - h["f1:pair[1]"][k:]  # reaction = -(weight + contact force) in e1
    assert np.all(f_contact[aft] > 0)  # the contact pushes the free particle away (+e1): repulsive only
    assert np.allclose(f_contact[~aft], 0.0, atol=1e-9 * w)  # free flight: no force from the broken bond
    assert h["bonds_active"][-1] == 0
    # no interpenetration beyond the penalty overlap: about as deep as at the moment of failure
    # (the energy released by the beam comes back in each bounce), far below 1 % of the area
    assert h["max_overlap_area"][k + 1 :].max() <= 1.2 * h["max_overlap_area"][k]
    assert h["max_overlap_ratio"].max() < 0.01
    assert sim.positions()[1, 0] - sim.positions()[0, 0] > 0.99
