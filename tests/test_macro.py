"""Macroscopic measures (thesis §7.5.1), the static network reference, and bond failure modes."""

import math

import numpy as np
import pytest

from polydem_cli.analysis.elastic import element_stiffness, static_response
from polydem_cli.analysis.macro import summarize
from polydem_cli.interactions.bonds.failure import failure_counts, orientation_class

from helpers import run, system_from_toml


def test_summary_recovers_known_E_nu_peak_and_work_from_a_synthetic_curve():
    E, nu, eps_p = 3.3e11, 0.21, 1.5e-4
    e_up = np.linspace(0, eps_p, 301)
    e_dn = np.linspace(eps_p, 3 * eps_p, 201)[1:]
    eps22 = np.r_[e_up, e_dn]
    peak = E * eps_p
    sigma = np.r_[E * e_up, peak * (1 - (e_dn - eps_p) / (2 * eps_p))]  # linear softening to 0 at 3 eps_p
    eps11 = -nu * eps22 + 3e-7  # a start-up offset must not matter
    L1, L2, T = 40.0, 40.0, 1.0
    m = summarize(sigma, eps22, eps11, (0.1, 0.4), L1, T, L2)
    assert m["E"] == pytest.approx(E, rel=1e-9)
    assert m["nu"] == pytest.approx(nu, rel=1e-9)
    assert m["peak_stress"] == pytest.approx(peak)
    assert m["strain_at_peak"] == pytest.approx(eps_p)
    assert m["kind"] == "tension"
    vol = L1 * L2 * T
    assert m["work_to_peak"] == pytest.approx(0.5 * peak * eps_p * vol, rel=1e-9)
    assert m["work_after_peak"] == pytest.approx(0.5 * peak * 2 * eps_p * vol, rel=1e-9)
    assert m["work_after_peak_per_area"] == pytest.approx(m["work_after_peak"] / (L1 * T))
    # compression: negative stress and strain, the same moduli
    mc = summarize(-sigma, -eps22, -eps11, (0.1, 0.4))
    assert mc["kind"] == "compression" and mc["E"] == pytest.approx(E) and mc["nu"] == pytest.approx(nu)


def test_fit_needs_points_in_the_range():
    m = summarize(np.array([0.0, 1.0]), np.array([0.0, 1e-5]), np.zeros(2))
    assert m["E"] is None and m["peak_stress"] == 1.0


PANEL = """
[scenario]
title = "small elastic panel"
seed = 3
[time]
dt = 4.0e-8
end_displacement = {u_end}
[output]
history_every = 20
[materials.c]
density = 2.4
[[particles]]
name = "specimen"
material = "c"
thickness = 1.0
type = "voronoi"
nx = {nx}
ny = {ny}
min_shared_edge = 0.005
[bonds]
E = 4.14e11
nu = {nu}
kappa_0 = 1.0                  # stays elastic
kappa_m = 2.0
[[boundary]]
set = "specimen.top"
x2 = {{ velocity = {v}, acceleration = {a} }}
[[boundary]]
set = "specimen.bottom"
x2 = "fixed"
[macro]
specimen = "specimen"
"""


@pytest.mark.parametrize("nu_h", [-0.676, 0.0])
def test_dynamic_E_and_nu_equal_the_static_solve_of_the_bond_network(nu_h):
    """Slow tension of an 8 x 6 bonded specimen: E and nu fitted from the dynamic run (time integration,
    beam kernel) equal those of the independent sparse linear solve of the same network within 2 %."""
    nx, ny = 8, 6
    # to eps22 = 2e-5 in 1.2e-3 s, about 60 transit times of an elastic wave through the panel
    u_end = 2e-5 * ny
    v = u_end / 1.2e-3
    text = PANEL.format(nx=nx, ny=ny, nu=nu_h, u_end=u_end, v=v, a=v / 2e-5)
    s = system_from_toml(text)
    ref = static_response(s)
    sim, h = run(s, every=20)
    m = summarize(h["sigma22"], h["eps22"], h["eps11"], (0.1, 0.4))
    assert m["E"] == pytest.approx(ref["E"], rel=0.02)
    assert m["nu"] == pytest.approx(ref["nu"], rel=0.02, abs=0.004)
    # the columns follow their definitions
    assert h["sigma22"][-1] == pytest.approx(h["f2:specimen.top"][-1] / (nx * 1.0))
    assert h["eps22"][-1] == pytest.approx(h["u2:specimen.top"][-1] / ny, rel=1e-12)
    assert h["eps11"][-1] == pytest.approx((h["u1:specimen.right"][-1] - h["u1:specimen.left"][-1]) / nx, rel=1e-12)
    assert h["eps22"][-1] == pytest.approx(u_end / ny, rel=1e-2)


def test_static_element_matrix_of_a_rotated_beam_has_rigid_modes():
    K = element_stiffness(1.3, 0.7, 1.0, 2.0, 0.25, angle=0.7)
    c, s = math.cos(0.7), math.sin(0.7)
    L = 1.3
    for mode in ([1, 0, 0, 1, 0, 0], [0, 1, 0, 0, 1, 0], [0, 0, 1, -L * s, L * c, 1]):  # rotation about I
        assert np.abs(K @ np.array(mode, float)).max() < 1e-12 * np.abs(K).max()
    assert np.allclose(K, K.T)


BOND2 = """
[scenario]
title = "two bonded squares"
[time]
dt = 1.0e-4
end_time = {t_end}
[output]
history_every = 10
[materials.m]
density = 1.0
k_n = 1.0e6
k_t = 1.0e6
mu_t = 0.3
[[particles]]
name = "a"
material = "m"
thickness = 1.0
type = "hexagon_packing"
width = 1.0
rows = 1
row_counts = [2]
[bonds]
E = 1.0e4
kappa_0 = 1.0e-3
kappa_m = 2.0e-3
[contact]
[[boundary]]
set = "a[0]"
x1 = "fixed"
x2 = "fixed"
phi = "fixed"
[[boundary]]
set = "a[1]"
x1 = {x1}
x2 = {x2}
phi = "fixed"
"""


def test_failure_mode_tension_of_a_horizontal_beam():
    s = system_from_toml(BOND2.format(t_end=0.5, x1="{ velocity = 0.01 }", x2='"fixed"'))
    sim, _ = run(s)
    assert not sim.bundle("bonds").h.active[0]
    p = s.family_data["bonds"].params
    c = failure_counts(sim.bundle("bonds").h.fail_step, sim.bundle("bonds").h.fail_strain, p.ux0, p.uy0, s.dt)
    assert c["failed"] == 1 and c["by_mode"]["tension"] == 1 and c["by_orientation"]["horizontal"] == 1
    # the step of failure: the strain reaches kappa_m = 2e-3 at u = 2e-3 cm (L_h = 1 cm), t = 0.2 s
    assert sim.bundle("bonds").h.fail_step[0] * s.dt == pytest.approx(0.2, abs=2e-3)
    assert sim.bundle("bonds").h.fail_strain[0, 0] == pytest.approx(2e-3, rel=0.01)


def test_failure_mode_shear_under_compression():
    # II pushed against I (axial compression) and moved sideways: the beam fails in shear
    s = system_from_toml(BOND2.format(t_end=0.5, x1="{ velocity = -0.001 }", x2="{ velocity = 0.01 }"))
    sim, _ = run(s)
    p = s.family_data["bonds"].params
    c = failure_counts(sim.bundle("bonds").h.fail_step, sim.bundle("bonds").h.fail_strain, p.ux0, p.uy0, s.dt)
    assert c["failed"] == 1 and c["by_mode"]["shear"] == 1 and c["by_mode"]["under_compression"] == 1


def test_orientation_classes():
    assert list(orientation_class([0.0, 10.0, 60.0, 120.0, 90.0, 100.0, 170.0, 45.0])) == [0, 0, 1, 1, 2, 2, 0, 1]


def test_a_run_ended_at_its_safety_limit_with_the_stress_at_its_largest_states_no_strength():
    """The reported case: the last point was called 'tensile strength ... stress at the end 100 % of the peak'."""
    from polydem_cli.analysis.macro import describe, summarize

    e = np.linspace(0.0, 1e-4, 101)
    rising = summarize(3.4e11 * e, e, -0.2 * e, L1=10.0, T=1.0, L2=10.0)
    assert not rising["peak_reached"]
    line = describe(rising)
    assert "no tensile strength" in line and "lower bound" in line and "f_t = 3.4" not in line
    falling = np.where(e < 5e-5, 3.4e11 * e, 3.4e11 * 5e-5 * (1 - (e - 5e-5) / 6e-5))
    turned = summarize(falling, e, -0.2 * e, L1=10.0, T=1.0, L2=10.0)
    assert turned["peak_reached"] and "tensile strength f_t = 1.7 N/mm^2" in describe(turned)
    compression = summarize(-falling, -e, 0.2 * e)
    assert compression["peak_reached"] and "compressive strength" in describe(compression)


def test_a_strength_is_a_magnitude_and_a_stress_is_signed():
    """One sign convention (the lab's table and fib MC2010): f_c and f_t are positive; the peak stress keeps its sign
    (tension positive).  The reported case: polydem run printed the compressive strength as -18.91 N/mm^2 where the
    lab table printed +18.45."""
    from polydem_cli.analysis.macro import describe, summarize

    e = np.linspace(0.0, 1e-3, 101)
    s = -np.where(e < 5e-4, 3.8e10 * e, 3.8e10 * 5e-4 * (1 - (e - 5e-4) / 6e-4))  # to -1.9 N/mm^2, then softening
    m = summarize(s, -e, 0.2 * e)
    assert m["kind"] == "compression" and np.isclose(m["strength_MPa"], 1.9) and np.isclose(m["peak_stress_MPa"], -1.9)
    line = describe(m)
    assert "compressive strength f_c = 1.9 N/mm^2 (sigma22 = -1.9 N/mm^2, tension positive)" in line, line
    assert "strength -" not in line and "f_c = -" not in line
    t = summarize(-s, e, -0.2 * e)
    assert np.isclose(t["strength_MPa"], 1.9) and "tensile strength f_t = 1.9 N/mm^2 at" in describe(t)
