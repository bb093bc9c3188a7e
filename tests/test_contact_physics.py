"""Contact physics through the engine: energy, damping, stick–slip, hard cases."""

import numpy as np
import pytest

from helpers import particle, run, system_from_toml

MAT = """
[materials.m]
density = 1.0
k_n = {kn}
gamma_n = {gn}
k_t = {kt}
mu_t = {mu}
"""


def head(dt, end, integrator="gear5", extra=""):
    return f"""
[scenario]
title = "test"
[time]
integrator = "{integrator}"
dt = {dt}
end_time = {end}
{extra}
"""


def test_two_polygons_collide_energy_conserved():
    """No damping, no friction, small dt: kinetic + elastic energy conserved to 1e-6 (Gear PC)."""
    text = (
        head(2e-6, 0.02)
        + MAT.format(kn=1e7, gn=0.0, kt=0.0, mu=0.0)
        + particle("a", center=[0.0, 0.0], sides=6, circumradius=0.7332, rotation=0.3, velocity=[50.0, 0.0, 3.0])
        + particle("b", center=[1.6, 0.25], sides=5, circumradius=0.7, velocity=[-50.0, 0.0, 0.0])
        + '[contact]\ntangential = "none"\n'
    )
    sim, h = run(system_from_toml(text), every=10)
    E = h["kinetic"] + h["elastic"]
    assert h["n_contacts"].max() == 1 and h["n_contacts"][-1] == 0  # they collided and separated
    assert h["elastic"].max() > 0.05 * E[0]  # a real collision, not a graze
    assert np.max(np.abs(E - E[0])) / E[0] < 1e-6
    # momentum is conserved exactly by the pairwise forces
    m = sim.system.mass
    p = (m[:, None] * sim.velocities()[:, :2]).sum(axis=0)
    assert np.allclose(p, [m[0] * 50 - m[1] * 50, 0.0], atol=1e-9 * m[0] * 50)


@pytest.mark.parametrize("integrator,tol", [("gear5", 1e-6), ("verlet", 1e-3)])
def test_energy_conservation_both_integrators(integrator, tol):
    text = (
        head(2e-6, 0.012, integrator)
        + MAT.format(kn=1e7, gn=0.0, kt=0.0, mu=0.0)
        + particle("a", center=[0.0, 0.0], sides=4, circumradius=0.7, rotation=0.1, velocity=[40.0, 5.0, 0.0])
        + particle("b", center=[1.35, 0.0], sides=7, circumradius=0.6, velocity=[-40.0, 0.0, -2.0])
        + '[contact]\ntangential = "none"\n'
    )
    sim, h = run(system_from_toml(text), every=5)
    E = h["kinetic"] + h["elastic"]
    assert h["elastic"].max() > 0.01 * E[0]
    assert np.max(np.abs(E - E[0])) / E[0] < tol


def test_damping_dissipates_monotonically_and_never_pulls():
    """gamma_n > 0: energy decreases monotonically and the normal force never turns tensile."""
    text = (
        head(1e-6, 0.006)
        + MAT.format(kn=1e7, gn=1e6, kt=0.0, mu=0.0)
        + particle("a", "rectangle", center=[0.0, 0.0], size=[1.0, 1.0], velocity=[30.0, 0.0, 0.0])
        + particle("b", "rectangle", center=[1.0, 0.0], size=[1.0, 1.0])
        + '[contact]\ntangential = "none"\n'
        + '[[boundary]]\nset = "b"\nx1 = "fixed"\nx2 = "fixed"\nphi = "fixed"\n'
    )
    sim, h = run(system_from_toml(text), every=1)
    E = h["kinetic"] + h["elastic"]
    assert h["n_contacts"].max() == 1 and h["n_contacts"][-1] == 0
    assert E[-1] < 0.2 * E[0]  # substantial damping
    assert np.all(np.diff(E) <= 1e-7 * E[0])  # monotone up to the integration error
    f1 = h["f1:b"]  # reaction = -(force of a on b); b is pushed in +e1, so never > 0
    assert f1.min() < 0 and np.all(f1 <= 0.0)
    # the dissipation bookkeeping closes the energy balance
    assert np.max(np.abs(E + h["dissipated"] - E[0])) < 1e-4 * E[0]


def test_tension_cutoff_releases_separating_overlap():
    """Overlapping blocks separating faster than k_n/gamma_n: f_el + f_vi > 0, so the force is cut
    to zero (4.9); the block keeps its speed and the stored elastic energy is dissipated."""
    kn, gn, v = 1e7, 1e6, -50.0  # cut-off while v_n > k_n/gamma_n = 10 cm/s
    text = (
        head(1e-6, 0.0002)
        + MAT.format(kn=kn, gn=gn, kt=0.0, mu=0.0)
        + particle("a", "rectangle", center=[0.005, 0.0], size=[1.0, 1.0], velocity=[v, 0.0, 0.0])
        + particle("b", "rectangle", center=[1.0, 0.0], size=[1.0, 1.0])
        + '[contact]\ntangential = "none"\ninitial_overlap = "allow"\n'
        + '[[boundary]]\nset = "b"\nx1 = "fixed"\nx2 = "fixed"\nphi = "fixed"\n'
    )
    sim, h = run(system_from_toml(text), every=1)
    assert h["elastic"][0] == pytest.approx(0.5 * kn * 0.005**2, rel=1e-9)
    assert np.all(h["f1:b"] == 0.0)
    assert np.allclose(h["kinetic"], h["kinetic"][0], rtol=1e-14)
    assert h["n_contacts"][-1] == 0
    assert h["dissipated"][-1] == pytest.approx(h["elastic"][0], rel=1e-3)


def _stick_slip_text(kn, kt, mu, delta, blocks):
    t = head(1e-4, 0.0, extra="end_displacement = 0.2").replace("end_time = 0.0\n", "") + MAT.format(
        kn=kn, gn=0.0, kt=kt, mu=mu
    )
    for name, cx, w in blocks:
        t += particle(name, "rectangle", center=[cx, 0.0], size=[w, 1.0])
        t += f'[[boundary]]\nset = "{name}"\nx1 = "fixed"\nx2 = "fixed"\nphi = "fixed"\n'
    t += particle("top", "rectangle", center=[0.0, 1.0 - delta], size=[1.0, 1.0])
    t += (
        '[contact]\ntangential = "coulomb"\ninitial_overlap = "allow"\n'
        '[[boundary]]\nset = "top"\nx1 = { velocity = 1.0, acceleration = 10.0 }\nx2 = "fixed"\nphi = "fixed"\n'
    )
    return t


def test_stick_then_slip_at_coulomb_limit():
    kn, kt, mu, delta = 1e7, 1e6, 0.5, 0.01
    sim, h = run(system_from_toml(_stick_slip_text(kn, kt, mu, delta, [("base", 0.0, 20.0)])), every=1)
    u = h["u1:top"]
    f_t = h["f1:top"]  # reaction in e1 = friction force of the base on the block, sign reversed
    f_n_el = kn * (delta * 1.0) * 1.0 * 1.0  # k_n A_n B_n T
    assert h["f2:top"] == pytest.approx(np.full_like(u, -f_n_el), rel=1e-9)
    limit = mu * f_n_el
    u_slip = limit / kt
    stick = u < 0.98 * u_slip
    slip = u > 1.02 * u_slip
    assert stick.sum() > 50 and slip.sum() > 500
    assert np.allclose(f_t[stick], kt * u[stick], rtol=1e-9, atol=1e-9 * limit)
    assert np.allclose(f_t[slip], limit, rtol=1e-12)
    assert np.all(np.abs(f_t) <= limit * (1 + 1e-12))
    # plastic work = friction force x slip distance
    assert h["dissipated"][-1] == pytest.approx(limit * (u[-1] - u_slip), rel=1e-3)


def test_tangential_history_resets_at_a_new_contact():
    """A sliding block bounces on a base: the same pair separates and meets again.  The second
    contact starts from u_t = u_t^pl = 0 (thesis footnotes 2-3), not from the first contact's slip."""
    from polydem_cli.engine.simulation import Simulation

    text = (
        head(1e-6, 0.03)
        + MAT.format(kn=1e7, gn=0.0, kt=1e6, mu=0.3)
        + particle("base", "rectangle", center=[0.0, 0.0], size=[40.0, 1.0])
        + particle("block", "rectangle", center=[0.0, 1.02], size=[1.0, 1.0], velocity=[20.0, 0.0, 0.0])
        + '[contact]\ntangential = "coulomb"\n[body_force]\ngravity = [0.0, -9810.0]\n'
        + '[[boundary]]\nset = "base"\nx1 = "fixed"\nx2 = "fixed"\nphi = "fixed"\n'
    )
    sim = Simulation(system_from_toml(text))
    sim.initialize()
    rows = np.zeros((2, sim.ncols))
    phases, ut_end_first, checked = [], None, False
    in_contact, ut_prev = False, 0.0
    while sim.step < sim.system.end_step:
        sim.advance(sim.step + 1, rows, 10**9)
        now = sim.bundle("contact").hold.meta[0] == 1
        if now and not in_contact:
            phases.append(sim.step)
        if in_contact and not now:
            ut_end_first = ut_end_first if ut_end_first is not None else abs(ut_prev)
        if now:
            ut_prev = sim.bundle("contact").hold.ut[0]
            if len(phases) == 2 and sim.step == phases[1] + 20:
                # 20 steps into the second contact: |u_t| <= 20 dt |v_t| (|v_t| < 30 cm/s here)
                assert abs(sim.bundle("contact").hold.ut[0]) <= 21 * 1e-6 * 30
                assert abs(sim.bundle("contact").hold.upl[0]) <= abs(sim.bundle("contact").hold.ut[0])
                checked = True
        in_contact = now
    assert len(phases) >= 2, "the block must bounce and land again"
    assert ut_end_first > 10 * 21 * 1e-6 * 30  # the first contact slid much further
    assert checked


def test_free_fall_is_exact_for_gear():
    text = (
        head(1e-3, 0.5)
        + MAT.format(kn=0.0, gn=0.0, kt=0.0, mu=0.0)
        + particle("a", center=[0.0, 10.0], sides=5, circumradius=1.0, velocity=[2.0, 3.0, 0.5])
        + "[body_force]\ngravity = [0.0, -981.0]\n"
    )
    sim, h = run(system_from_toml(text), every=50)
    x = sim.positions()[0]
    t = 0.5
    assert x[0] == pytest.approx(sim.system.x0[0, 0] + 2.0 * t, rel=1e-13)
    assert x[1] == pytest.approx(10.0 + 3.0 * t - 0.5 * 981.0 * t * t, rel=1e-12)
    assert x[2] == pytest.approx(0.5 * t, rel=1e-13)
    E = h["kinetic"] + h["potential"]
    assert np.max(np.abs(E - E[0])) < 1e-9 * abs(E[0])


def test_prescribed_ramp_positions_and_support_work():
    text = (
        head(1e-3, 3.0)
        + MAT.format(kn=0.0, gn=0.0, kt=0.0, mu=0.0)
        + particle("a", center=[0.0, 0.0], sides=4, circumradius=1.0)
        + '[[boundary]]\nset = "a"\nx2 = { velocity = -0.5, acceleration = -0.25 }\nphi = "fixed"\n'
    )
    sim, h = run(system_from_toml(text), every=100)
    # t_r = 2 s, u(t_r) = -0.5; then -0.5 * (t - 2)
    assert h["u2:a"][-1] == pytest.approx(-0.5 - 0.5 * 1.0, rel=1e-12)
    i = np.argmin(np.abs(h["time"] - 1.0))
    assert h["u2:a"][i] == pytest.approx(-0.125, rel=1e-12)
    m = sim.system.mass[0]
    assert h["kinetic"][-1] == pytest.approx(0.5 * m * 0.25, rel=1e-12)
    # support work by the trapezoidal rule: exact except for the step containing t_r, where the
    # support power jumps (error m a v dt / 2)
    assert h["external_work"][-1] == pytest.approx(0.5 * m * 0.25, rel=1e-3)
