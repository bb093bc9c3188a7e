"""Stress-controlled walls (Luding & Herrmann LH 1.2, interactions/servo/): the wall reaches the prescribed
pressure and oscillates about it as the linear two-mass system it forms with the packing, whose
eigenvalues are computed here independently (numpy); the cosine strain law (LH 1.1) of a driven wall."""

import math

import numpy as np
import pytest

from polydem_cli.scenario.spec import ScenarioError

from helpers import run, system_from_toml

R = 0.1
RHO = 2.0
M_D = 4.0 / 3.0 * math.pi * RHO * R**3
K = 1.0e8
P = 1000.0  # g/(cm s^2) = 100 N/m^2
H = 100.0  # cm, depth (1 m)
Z = 1.0  # cm between the faces of the bottom and top walls
M_X = 0.1  # g = 1e-4 kg (the paper)
F = P * H * Z
D_E = F / K  # overlap of each contact at equilibrium


def _wall(name, side, position, extent, bc=True, mass=None):
    s = f"""
[[particles]]
name = "{name}"
material = "glass"
thickness = {H!r}
type = "wall"
side = "{side}"
position = {position!r}
extent = [{extent[0]!r}, {extent[1]!r}]
"""
    if mass is not None:
        s += f"mass = {mass!r}\n"
    if bc:
        s += f'[[boundary]]\nset = "{name}"\nx1 = "fixed"\nx2 = "fixed"\nphi = "fixed"\n'
    return s


def _scene(gamma_x, kick, end, dt=2e-8, servo_extra="", law_extra=""):
    """A disk between a fixed left wall and a servo right wall, both contacts at their equilibrium overlap,
    the servo wall displaced by ``kick`` into the packing; bottom and top walls set z = Z (not touched)."""
    x_disk = R - D_E
    right = x_disk + R - D_E - kick
    return f"""
[scenario]
title = "servo wall on one disk"
[time]
integrator = "gear5"
dt = {dt!r}
end_time = {float(end)!r}
[output]
history_every = 10
[materials.glass]
density = {RHO!r}
[[particles]]
name = "d"
material = "glass"
thickness = {H!r}
type = "disks"
centers = [[{x_disk!r}, 0.0]]
radii = [{R!r}]
sphere_mass = true
{_wall("left", "left", 0.0, (-0.5, 0.5))}
{_wall("bottom", "bottom", -0.5, (0.0, 1.0))}
{_wall("top", "top", 0.5, (0.0, 1.0))}
{_wall("right", "right", right, (-0.5, 0.5), bc=False, mass=M_X)}
[[boundary]]
set = "right"
x2 = "fixed"
phi = "fixed"
[[boundary]]
set = "d"
x2 = "fixed"
phi = "fixed"
[disks]
k_1 = {K!r}
k_2 = {K!r}
{law_extra}
[[servo]]
set = "right"
pressure = {P!r}
gamma = {gamma_x!r}
length_between = ["bottom", "top"]
{servo_extra}
"""


def _slow_mode(gamma_x):
    """(decay rate, angular frequency) of the slow mode of the disk + wall system, from the eigenvalues of
    its linear state matrix (two springs k in series, wall damping gamma_x)."""
    M = np.diag([M_D, M_X])
    Kmat = K * np.array([[2.0, -1.0], [-1.0, 1.0]])
    C = np.diag([0.0, gamma_x])
    Mi = np.linalg.inv(M)
    A = np.block([[np.zeros((2, 2)), np.eye(2)], [-Mi @ Kmat, -Mi @ C]])
    lam = np.linalg.eigvals(A)
    slow = min((l for l in lam if l.imag > 0), key=lambda l: l.imag)
    return -slow.real, slow.imag


@pytest.mark.parametrize("gamma_x", [0.0, 1000.0])
def test_servo_wall_oscillates_as_the_linear_two_mass_system(gamma_x):
    """(LH 1.3): a small deviation of the wall decays as a damped oscillation; frequency and decay rate of the
    simulated wall motion (least-squares fit) equal the slow eigenvalue of the linearised disk + wall system
    within 1 % (frequency) and 3 % (decay).  Its frequency is sqrt(K/m - (gamma/2m)^2) of an effective spring:
    the paper's plus sign under the root is a misprint."""
    from scipy.optimize import curve_fit

    sigma, omega = _slow_mode(gamma_x)
    period = 2 * math.pi / omega
    kick = 0.2 * D_E
    sim, h = run(system_from_toml(_scene(gamma_x, kick, 3.0 * period)), every=10)
    t, u = h["time"], h["u1:right"]

    def model(t, a, s, w, ph, c):
        return a * np.exp(-s * t) * np.cos(w * t + ph) + c

    p0 = (-kick, sigma, omega, 0.0, 0.0)
    (a, s, w, ph, c), _ = curve_fit(model, t, u, p0=p0)
    assert w == pytest.approx(omega, rel=0.01)
    assert s == pytest.approx(sigma, rel=0.03, abs=0.01 * omega)
    # the energy balance holds with the servo's work in 'external_work'
    e = h["energy_total"]
    assert np.max(np.abs(e - e[0])) < 1e-4 * max(abs(h["servo_work"]).max(), h["kinetic"].max())


def test_servo_wall_reaches_the_prescribed_pressure():
    """Released from 40 % off its equilibrium, the damped servo wall settles where the material's force on it
    (the reaction of the fixed opposite wall) equals p h z within 1e-4 (background damping on the disk
    removes the disk's own, faster oscillation between the walls)."""
    sigma, omega = _slow_mode(1000.0)
    text = _scene(1000.0, 0.4 * D_E, 20.0 / sigma, law_extra="gamma_b = 50.0")
    sim, h = run(system_from_toml(text), every=10)
    assert h["servo_length:right"][-1] == pytest.approx(Z, rel=1e-12)
    assert h["servo_force:right"][-1] == pytest.approx(-F, rel=1e-12)  # along x1: the right wall is pushed left
    assert h["f1:left"][-1] == pytest.approx(F, rel=1e-4)


def test_cosine_strain_law_of_a_driven_wall():
    """(LH 1.1): x = x0 + D (1 - cos 2 pi f t)/2 up to t = 1/(2f), then held."""
    text = _scene(0.0, 0.0, 6e-4).replace(
        '[[boundary]]\nset = "top"\nx1 = "fixed"\nx2 = "fixed"',
        '[[boundary]]\nset = "top"\nx1 = "fixed"\nx2 = {displacement = -0.05, frequency = 1000.0}',
    )
    sim, h = run(system_from_toml(text), every=10)
    t = h["time"]
    w = 2 * math.pi * 1000.0
    expect = np.where(w * t < math.pi, -0.025 * (1 - np.cos(w * t)), -0.05)
    assert np.max(np.abs(h["u2:top"] - expect)) < 1e-12
    # z(t) of the servo follows the top wall
    assert h["servo_length:right"][-1] == pytest.approx(Z - 0.05, rel=1e-9)


@pytest.mark.parametrize(
    "change, key",
    [
        ("pressure = 1000.0\n", "servo[0].pressure"),
        ('length_between = ["bottom", "top"]', "servo[0].length_between"),
    ],
)
def test_bad_servo_input_is_refused_with_its_key(change, key):
    text = _scene(0.0, 0.0, 1e-6)
    assert change in text
    with pytest.raises(ScenarioError) as e:
        system_from_toml(text.replace(change, ""))
    assert e.value.key == key, str(e.value)


def test_servo_on_a_prescribed_dof_or_a_non_wall_is_refused():
    text = _scene(0.0, 0.0, 1e-6)
    with pytest.raises(ScenarioError) as e:
        system_from_toml(text.replace('set = "right"\npressure', 'set = "d"\npressure'))
    assert e.value.key == "servo[0].set"
    with pytest.raises(ScenarioError) as e:
        system_from_toml(
            text.replace(
                '[[boundary]]\nset = "right"\nx2 = "fixed"', '[[boundary]]\nset = "right"\nx1 = "fixed"\nx2 = "fixed"'
            )
        )
    assert e.value.key == "servo[0].set"
