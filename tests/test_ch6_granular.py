"""Hex nuts between load plates on a base (thesis ch. 6): plate contact, plate friction, momentum balance."""

import math

import numpy as np
import pytest

from polydem_cli.io.hdf5 import read_frames, read_history
from polydem_cli.scenario.build import build_system
from polydem_cli.scenario.load import load_scenario

from conftest import SCEN
from helpers import run, system_from_toml

S = 1.27 / math.sqrt(3)
MU_SL = 2 * 0.294 * 0.236 / (0.294 + 0.236)  # (4.17): nut-plate pair = measured 0.262

ONE_NUT = """
[scenario]
title = "one nut between plates"
[time]
dt = 1e-5
end_time = {end}
[materials.nut]
density = 5.32
k_n = 1.61e7
k_t = 4.74e7
mu_t = 0.294
k_u = 8.35e5
mu_u = 0.258
[materials.plate]
density = 7.85
k_n = 1.61e7
k_t = 3.81e7
mu_t = 0.236
[[particles]]
name = "nut"
material = "nut"
thickness = 0.62
type = "regular_polygon"
center = [0.0, 0.0]
sides = 6
circumradius = 0.7332050808
rotation = {rot}
[[particles]]
name = "bottom"
material = "plate"
thickness = 0.62
type = "rectangle"
center = [0.0, 0.0]
size = [6.0, 0.5]
place = "below:nut"
[[particles]]
name = "top"
material = "plate"
thickness = 0.62
type = "rectangle"
center = [0.0, 0.0]
size = [6.0, 0.5]
place = "above:nut"
[contact]
tangential = "coulomb"
initial_overlap = "allow"
[base]
gravity = 981.0
[[boundary]]
set = "bottom"
x1 = "fixed"
x2 = "fixed"
phi = "fixed"
[[boundary]]
set = "top"
x1 = {x1}
x2 = {x2}
phi = "fixed"
[output]
observe = ["nut"]
"""


def test_nut_squeezed_between_plates_carries_the_plate_force():
    """Corner contacts, as in the pile (flats vertical): the plate force goes through the nut."""
    text = ONE_NUT.format(end=0.1, x1='"fixed"', x2="{ velocity = -0.5 }", rot=math.pi / 6)
    sim, h = run(system_from_toml(text), every=10)
    ft, fb = h["f2:top"], h["f2:bottom"]
    assert ft.min() < -300.0  # squeezed: compression on the top plate ...
    assert fb.max() > 300.0  # ... and on the bottom plate
    # Newton for the nut along e2: plate reactions (= forces of the plates on the nut) + base friction
    # (it acts in the plane, so also along e2) = m u2''
    m = sim.system.mass[0]
    u2, t = h["u2:nut"], h["time"]
    acc = np.gradient(np.gradient(u2, t), t)
    total = ft + fb + h["fb2"]
    inner = slice(5, -5)
    assert np.allclose(total[inner], m * acc[inner], atol=0.02 * np.abs(ft).max())
    assert np.abs(h["fb2"]).max() > 0.5 * 0.258 * 5.32 * 0.62 * 981 * 1.3968  # the base resists


def test_friction_against_a_moving_plate_sticks_then_slips_at_mu_SL():
    """A nut pressed by the top plate, which is dragged sideways: stick, then slip at mu_S-L = 0.262
    (pair value (4.17) of mu_t,s = 0.294 and mu_t,L = 0.236)."""
    # flats against the plates; the nut is held, the top plate starts 0.004 cm lower than touching
    # (pre-squeezed) and is then dragged sideways
    text = ONE_NUT.format(end=0.06, x1="{ velocity = 0.5, acceleration = 20.0 }", x2='"fixed"', rot=0.0)
    text += '[[boundary]]\nset = "nut"\nx1 = "fixed"\nx2 = "fixed"\nphi = "fixed"\n'
    system = system_from_toml(text)
    system.x0[2, 1] -= 0.004
    sim, h = run(system, every=10)
    f1, f2 = h["f1:top"], h["f2:top"]
    ratio = np.abs(f1) / np.abs(f2)
    u = h["u1:top"]
    assert np.all(ratio <= MU_SL * (1 + 1e-9))
    slip = u > 0.01
    assert slip.sum() > 50
    assert np.allclose(ratio[slip], MU_SL, rtol=1e-6)
    stick = (u > 1e-5) & (u < 1e-4)
    assert stick.sum() > 3 and np.all(ratio[stick] < 0.99 * MU_SL)
    # stick: elastic tangential spring k_t T u_t with the pair stiffness (4.15)
    kt = 2 * 4.74e7 * 3.81e7 / (4.74e7 + 3.81e7)
    assert np.allclose(np.abs(f1[stick]), kt * 0.62 * u[stick], rtol=1e-6)


@pytest.mark.slow
def test_small_pile_momentum_balance_and_diagnostics(tmp_path):
    from polydem_cli.solvers.explicit import run as run_result

    path = SCEN / "ch6" / "nuts_small.toml"
    sc, text = load_scenario(path)
    system = build_system(sc, str(path))
    out = tmp_path / "pile.h5"
    summary = run_result(system, out=out, scenario_file=str(path), scenario_text=text, quiet=True)
    cols, tab = read_history(out)
    c = {n: i for i, n in enumerate(cols)}
    t = tab[:, c["time"]]
    # momentum of the nuts: d/dt sum(m v) = plate reactions on the nuts + base friction
    steps, ft, X, V = read_frames(out)
    nuts = np.arange(28)
    m = system.mass[nuts]
    P = (m[None, :, None] * V[:, nuts, :2]).sum(axis=1)  # (F, 2)
    force = np.column_stack(
        [
            tab[:, c["f1:top_plate"]] + tab[:, c["f1:bottom_plate"]] + tab[:, c["fb1"]],
            tab[:, c["f2:top_plate"]] + tab[:, c["f2:bottom_plate"]] + tab[:, c["fb2"]],
        ]
    )
    impulse = np.array([np.trapezoid(force[:, d], t) for d in range(2)])
    scale = np.trapezoid(np.abs(tab[:, c["f2:top_plate"]]), t)
    assert np.allclose(P[-1] - P[0], impulse, atol=2e-3 * scale)
    obs = summary["observables"]
    assert obs["max_overlap_ratio"] < 0.05  # thesis: < 3 % in the full runs (slower plate)
    assert obs["max_ub_elastic"] <= 0.258 * 5.32 * 0.62 * 981 / 8.35e5 * (1 + 1e-9)  # <= 0.001 cm
    assert obs["max_ut_elastic"] < 0.004  # thesis bound
    assert summary["status"] == "finished"
