"""The applied loads in the history table (interactions/controllers/applied_loads.py): per [[loads]] entry its force,
moment and work, against closed forms (a free polygon pushed by a constant and by a ramped force: the work equals the
kinetic energy it gains, W = F u for a constant force), a confining pressure's resultant p T L on its side, the
columns summing to the loads' part of 'external_work', and the work kept across a resume."""

import numpy as np
import pytest

from conftest import SCEN
from helpers import run, system_from_toml

ONE = """
[scenario]
title = "one hexagon pushed"
[time]
integrator = "{integrator}"
dt = 1e-4
end_time = 0.2
[output]
history_every = 50
[materials.m]
density = 2.0
[[particles]]
name = "p"
material = "m"
thickness = 0.5
type = "regular_polygon"
center = [0.3, -0.1]
sides = 6
circumradius = 1.0
rotation = 0.2
"""


@pytest.mark.parametrize("integrator", ["verlet", "gear5"])
def test_a_constant_force_and_moment_do_the_work_the_polygon_gains(integrator):
    """F = (2000, -500) dyn and C = 300 dyn cm on a free hexagon from rest: the columns give F and C at every row, and
    the work F·u + C φ, which is the kinetic energy it gained (both integrators are exact for a constant force)."""
    F, C = (2.0e3, -5.0e2), 3.0e2
    s = system_from_toml(
        ONE.format(integrator=integrator) + f'[[loads]]\nset = "p"\nforce = [{F[0]}, {F[1]}]\nmoment = {C}\n'
    )
    sim, h = run(s, every=50)
    assert np.all(h["load0_f1:p"] == F[0]) and np.all(h["load0_f2:p"] == F[1]) and np.all(h["load0_c:p"] == C)
    x = sim.positions()[0] - s.x0[0]
    w = h["load0_work:p"]
    assert w[0] == 0.0
    assert w[-1] == pytest.approx(F[0] * x[0] + F[1] * x[1] + C * x[2], rel=1e-12)
    assert np.allclose(w, h["kinetic"], rtol=1e-9, atol=1e-9 * h["kinetic"].max())
    assert np.allclose(w, h["external_work"], rtol=1e-6, atol=1e-9 * w.max())


def test_a_ramped_force_shows_its_staircase_and_its_work():
    """Ramped over T_r in blocks of 64 steps: the force column at a row after step l is F r, r = (the block start of
    step l - 1) dt / T_r (the f_ext the loop applied in that step), then F; the work is still the kinetic energy."""
    F, dt = 2.0e3, 1e-4
    Tr = 16 * 64 * dt
    s = system_from_toml(
        ONE.format(integrator="verlet") + f'[[loads]]\nset = "p"\nforce = [{F}, 0.0]\nramp_time = {Tr}\n'
    )
    sim, h = run(s, every=50)
    step = h["step"].astype(int)
    r = np.minimum(1.0, ((np.maximum(step - 1, 0) // 64) * 64) * dt / Tr)
    assert np.allclose(h["load0_f1:p"], F * r, rtol=1e-12, atol=0.0)
    assert h["load0_f1:p"][-1] == F and h["load0_f1:p"][0] == 0.0
    # the staircase's work equals the kinetic energy to the integrator's error at its 16 steps of the force
    assert np.allclose(h["load0_work:p"], h["kinetic"], rtol=2e-3, atol=1e-6 * h["kinetic"].max())
    assert h["load0_work:p"][-1] == pytest.approx(h["kinetic"][-1], rel=1e-4)
    assert np.allclose(h["load0_work:p"], h["external_work"], rtol=2e-3, atol=1e-6 * h["kinetic"].max())


def test_the_confining_pressure_is_read_from_its_columns(tmp_path):
    """The confined compression's lateral pressure on specimen.left / .right: the columns give p T L2 inward on each
    side (the reaction columns f1:<set> stay near 0: the load holds the set in equilibrium, which is why the applied
    load needs its own), and the membranes' work is positive (they push the sides in)."""
    from polydem_cli.scenario.build import build_system
    from polydem_cli.scenario.load import load_scenario

    scen = SCEN / "lab" / "smoke_confined_compression.toml"
    sc, _ = load_scenario(scen, ["time.end_time=2e-3", "output.history_every=100"])
    s = build_system(sc, str(scen))
    loads = sc["loads"]
    assert [ld["set"] for ld in loads] == ["specimen.left", "specimen.right"]
    p, T = loads[0]["pressure"], sc["particles"][0]["thickness"]
    L2 = sc["particles"][0]["ny"] * sc["particles"][0]["h_pg"]
    sim, h = run(s, every=100)
    full = h["step"] * s.dt >= loads[0]["ramp_time"] + 64 * s.dt
    assert full.any()
    assert np.allclose(h["load0_f1:specimen.left"][full], p * T * L2, rtol=1e-9)
    assert np.allclose(h["load1_f1:specimen.right"][full], -p * T * L2, rtol=1e-9)
    assert np.allclose(h["load0_f2:specimen.left"], 0.0, atol=1e-9 * p * T * L2)
    w = h["load0_work:specimen.left"] + h["load1_work:specimen.right"]
    assert w[-1] > 0.0  # the membranes push the sides in
    if "f1:specimen.left" in h:  # the reaction: what the interactions exert, nearly nothing of the applied load
        assert np.abs(h["f1:specimen.left"][full]).max() < 0.1 * p * T * L2


def test_the_work_of_a_ramped_load_resumes_from_its_checkpoint(tmp_path):
    """Stopped in the middle of the ramp and resumed, the run's columns equal an uninterrupted run's bit for bit (S,
    the work's history, is checkpoint state)."""
    import json

    import h5py

    from polydem_cli.scenario.load import load_scenario
    from polydem_cli.solvers import driver
    from polydem_cli.solvers.protocol import RunOptions, Source

    F, dt = 2.0e3, 1e-4
    Tr = 16 * 64 * dt
    scen = tmp_path / "push.toml"
    scen.write_text(ONE.format(integrator="verlet") + f'[[loads]]\nset = "p"\nforce = [{F}, 0.0]\nramp_time = {Tr}\n')
    sc, text = load_scenario(scen, [])
    src = Source(str(scen), text, ())
    whole, part = tmp_path / "whole.h5", tmp_path / "part.h5"
    driver.obtain(sc, whole, source=src, opts=RunOptions(quiet=True))
    driver.obtain(sc, part, source=src, opts=RunOptions(quiet=True, stop_after=700))
    driver.run(out=part, resume=True, opts=RunOptions(quiet=True))

    def table(p):
        with h5py.File(p, "r") as f:
            return json.loads(f["history/table"].attrs["columns"]), f["history/table"][...]

    ca, a = table(whole)
    cb, b = table(part)
    assert ca == cb and "load0_work:p" in ca
    k = ca.index("load0_work:p")
    assert np.array_equal(a[:, k], b[:, k]) and a[-1, k] > 0.0


def test_the_platen_friction_work_closes_the_energy_of_a_sliding_particle():
    """A hexagon held in x2 against a platen on top (mu = 0.4) and pushed sideways by F1 = 1.5 mu P: the platen's
    friction force is -mu P once it slides, and its work column -mu P (u - mu P / k_t) - (mu P)^2 / (2 k_t) (the
    slip at the sliding force, and the grip's spring stored); with the load's work it gives the kinetic energy."""
    P, mu, kt = 1.0e4, 0.4, 1.0e6
    F1 = 1.5 * mu * P
    text = ONE.format(integrator="verlet") + (
        f'[[boundary]]\nset = "p"\nx2 = "fixed"\n[[loads]]\nset = "p"\nforce = [{F1}, {P}]\n'
        f'[[platen]]\nset = "p"\nside = "top"\nmu = {mu}\nk_t = {kt}\n'
    )
    sim, h = run(system_from_toml(text), every=50)
    u = h["u1:p"][-1]
    f = mu * P
    assert h["f1_platen"][-1] == pytest.approx(-f, rel=1e-9)
    assert h["work_platen"][-1] == pytest.approx(-f * (u - f / kt) - f * f / (2 * kt), rel=1e-3)
    assert h["load0_work:p"][-1] == pytest.approx(F1 * u, rel=1e-12)
    assert h["load0_work:p"][-1] + h["work_platen"][-1] == pytest.approx(h["kinetic"][-1], rel=1e-4)
