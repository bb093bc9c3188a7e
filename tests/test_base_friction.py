"""Particle-base friction (thesis §4.4.2): creep, sliding, stopping distance, torque (issue 4)."""

import math

import numpy as np
import pytest

from polydem_cli.geometry.polygon import make_shape, regular_polygon
from polydem_cli.interactions.base.friction import RULES, full_slip_moment_regular_polygon, gauss_points

from helpers import particle, run, system_from_toml

W, T, RHO, G = 1.27, 0.62, 5.32, 981.0  # M8 nut and gravity
S = W / math.sqrt(3.0)
MU_U, K_U = 0.258, 8.35e5  # thesis Fig. 6.3c (k_u = 8.35 N/cm^3)
AREA = 1.5 * math.sqrt(3.0) * S * S
MASS = RHO * T * AREA
SIGMA = RHO * T * G  # |sigma_u|
LIMIT = MU_U * SIGMA * AREA  # full-slip friction force


def nut_scene(end, dt=1e-5, velocity=(0.0, 0.0, 0.0), force=(0.0, 0.0), moment=0.0, npts=7, every=10):
    text = f"""
[scenario]
title = "nut on base"
[time]
dt = {dt}
end_time = {end}
[output]
observe = ["nut"]
[materials.steel]
density = {RHO}
k_u = {K_U}
mu_u = {MU_U}
[base]
gravity = {G}
gauss_points = {npts}
[[loads]]
set = "nut"
force = [{force[0]}, {force[1]}]
moment = {moment}
""" + particle(
        "nut",
        material="steel",
        thickness=T,
        center=[0.3, -0.2],
        sides=6,
        circumradius=S,
        rotation=math.pi / 6,
        velocity=list(map(float, velocity)),
    )
    return run(system_from_toml(text), every=every)


def test_below_the_limit_only_elastic_creep():
    sim, h = nut_scene(0.05, force=(0.45 * LIMIT, 0.0))
    u = h["u1:nut"]
    assert np.abs(u).max() <= MU_U * SIGMA / K_U  # never beyond the elastic range
    assert np.abs(u).max() == pytest.approx(2 * 0.45 * LIMIT / (K_U * AREA), rel=0.01)  # suddenly applied load
    assert h["base_slipping_points"].max() == 0
    assert abs(h["u2:nut"]).max() < 1e-12 and abs(h["phi:nut"]).max() < 1e-12


def test_above_the_limit_the_nut_slides():
    sim, h = nut_scene(0.1, force=(1.5 * LIMIT, 0.0), every=100)
    # after the elastic transient (~ 2/omega) the nut slides with (F - mu |sigma_u| A)/m
    u, t = h["u1:nut"], h["time"]
    acc = np.diff(u, 2) / (t[1] - t[0]) ** 2
    late = t[1:-1] > 0.02
    assert np.allclose(acc[late], (1.5 * LIMIT - LIMIT) / MASS, rtol=1e-6)
    assert u[-1] > 100 * MU_U * SIGMA / K_U
    assert h["base_slipping_points"][-1] == 42  # 6 triangles x 7 points


def test_stopping_distance_v2_over_2_mu_g():
    v = 5.0
    sim, h = nut_scene(0.05, velocity=(v, 0.0, 0.0))
    d = h["u1:nut"]
    expect = v * v / (2 * MU_U * G)
    eps = MU_U * SIGMA / K_U  # elastic regularisation
    assert abs(d[-1] - expect) < 2 * eps
    assert d.max() < expect + 2 * eps
    # energy: the kinetic energy went into friction (plus a little elastic base energy)
    assert h["dissipated_base"][-1] == pytest.approx(0.5 * MASS * v * v, rel=0.05)


def test_full_slip_moment_of_a_hexagon_quadrature():
    shape, _ = make_shape(regular_polygon(6, S, math.pi / 6))
    exact = full_slip_moment_regular_polygon(6, S)
    # independent check of the closed form by a fine polar quadrature
    th = np.linspace(-math.pi / 6, math.pi / 6, 200001)
    a = S * math.cos(math.pi / 6)
    fine = 6 * np.trapezoid((a / np.cos(th)) ** 3 / 3, th)
    assert exact == pytest.approx(fine, rel=1e-9)
    errs = {}
    for npts in (1, 3, 7):
        X, wA = gauss_points(shape.body_vertices, npts)
        assert wA.sum() == pytest.approx(shape.area, rel=1e-12)
        errs[npts] = abs(np.sum(wA * np.hypot(X[:, 0], X[:, 1])) - exact) / exact
    assert errs[7] < 0.01 and errs[7] < errs[3] < errs[1]
    # the figures quoted in docs/performance.md: 0.054 %, 0.43 %, 5.0 %
    assert errs[7] == pytest.approx(5.4e-4, rel=0.01) and errs[3] == pytest.approx(4.25e-3, rel=0.01)
    assert errs[1] == pytest.approx(0.0504, rel=0.01)


def test_gauss_rules_integrate_polynomials_exactly():
    """Degrees 1, 2, 5 exactness (Cowper 1973) against Green's theorem on the edges (Gauss-Legendre)."""
    tri = np.array([[0.0, 0.0], [1.3, 0.2], [0.4, 0.9]])
    e1, e2 = tri[1] - tri[0], tri[2] - tri[0]
    area = 0.5 * abs(e1[0] * e2[1] - e1[1] * e2[0])
    gl_x, gl_w = np.polynomial.legendre.leggauss(10)
    for npts, degree in ((1, 1), (3, 2), (7, 5)):
        P, W_ = RULES[npts]
        pts = P @ tri
        for p in range(degree + 1):
            for q in range(degree + 1 - p):
                num = area * np.sum(W_ * pts[:, 0] ** p * pts[:, 1] ** q)
                # ∫_T x^p y^q dA = ∮ x^(p+1) y^q / (p+1) dy (counter-clockwise boundary)
                ref = 0.0
                for k in range(3):
                    a, b = tri[k], tri[(k + 1) % 3]
                    s = 0.5 * (gl_x + 1.0)
                    xs, ys = a[0] + s * (b[0] - a[0]), a[1] + s * (b[1] - a[1])
                    ref += 0.5 * np.sum(gl_w * xs ** (p + 1) * ys**q) / (p + 1) * (b[1] - a[1])
                assert num == pytest.approx(ref, rel=1e-12, abs=1e-15), (npts, p, q)
        # and not exact one degree higher (the rules are what they claim, no more)
        p = degree + 1
        num = area * np.sum(W_ * pts[:, 0] ** p)
        ref = sum(
            0.5
            * np.sum(gl_w * (tri[k][0] + 0.5 * (gl_x + 1) * (tri[(k + 1) % 3][0] - tri[k][0])) ** (p + 1))
            / (p + 1)
            * (tri[(k + 1) % 3][1] - tri[k][1])
            for k in range(3)
        )
        assert abs(num - ref) > 1e-9 * abs(ref)


@pytest.mark.parametrize("factor,spins", [(1.15, True), (0.85, False)])
def test_torque_above_full_slip_moment_spins_below_does_not(factor, spins):
    shape, _ = make_shape(regular_polygon(6, S, math.pi / 6))
    X, wA = gauss_points(shape.body_vertices, 7)
    m_full = MU_U * SIGMA * np.sum(wA * np.hypot(X[:, 0], X[:, 1]))  # the model's full-slip moment
    assert m_full == pytest.approx(MU_U * SIGMA * full_slip_moment_regular_polygon(6, S), rel=0.01)
    sim, h = nut_scene(0.1, moment=factor * m_full, every=100)
    phi = h["phi:nut"]
    if spins:
        theta = sim.system.inertia[0]
        # once every Gauss point slips: angular acceleration (M - M_full)/Theta
        acc = np.diff(phi, 2) / (h["time"][1] - h["time"][0]) ** 2
        assert np.allclose(acc[-20:], (factor - 1) * m_full / theta, rtol=1e-4)  # slip direction lags ~ u_el/r
        assert h["base_slipping_points"][-1] == 42
    else:
        assert np.abs(phi).max() < 1e-2 and np.abs(phi[-500:]).max() < 1e-2
        assert abs(phi[-1]) < 5 * MU_U * SIGMA / K_U / 0.2  # bounded near the elastic range
    assert np.abs(h["u1:nut"]).max() < 1e-9 and np.abs(h["u2:nut"]).max() < 1e-9  # symmetric: no drift
