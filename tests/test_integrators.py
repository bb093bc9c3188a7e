"""Integrator orders of thesis §3.3.2 (Figs. 3.8, 3.9) and the engine's integrator kernels."""

import json
import math

import numpy as np
import pytest

from polydem_cli.engine.integrators import GEAR5, VERLET, correct_dof, initial_vector, predict_dof
from polydem_cli.reproductions.integrators import run_study, write_study


@pytest.fixture(scope="module")
def study():
    return run_study()


def test_oscillator_orders(study):
    o = study["oscillator"]
    assert o["EE"]["order"] == pytest.approx(1.0, abs=0.3)
    assert o["ME"]["order"] == pytest.approx(2.0, abs=0.3)
    assert o["CD"]["order"] == pytest.approx(2.0, abs=0.3)
    assert o["PC"]["order"] == pytest.approx(6.0, abs=0.3)


def test_collision_orders_and_ranking(study):
    c = study["collision"]
    assert c["PC"]["order"] == pytest.approx(2.0, abs=0.3)
    pc, me, cd = (np.array(c[m]["error"]) for m in ("PC", "ME", "CD"))
    steps = np.array(c["PC"]["steps"])
    asym = (steps >= 40) & (steps <= 40960)
    assert np.all(pc[asym] < me[asym]) and np.all(pc[asym] < cd[asym])


def test_study_writes_json_in_documented_form(tmp_path):
    res = write_study(tmp_path, steps=[20, 40, 80, 160])
    data = json.loads((tmp_path / "integrators.json").read_text())
    for prob in ("oscillator", "collision"):
        for m in ("EE", "ME", "CD", "PC"):
            d = data[prob][m]
            assert set(d) >= {"order", "steps", "error"}
            assert d["steps"] == [20, 40, 80, 160] and len(d["error"]) == 4
    assert (tmp_path / "integrators.png").stat().st_size > 1000
    assert res["oscillator"]["PC"]["error"][0] > res["oscillator"]["PC"]["error"][-1]


def _integrate(kind, f, x0, v0, dt, n):
    z = initial_vector(kind, [x0, v0, f(x0)], dt)
    zp = np.zeros(6)
    xs = []
    for _ in range(n):
        predict_dof(kind, z, zp)
        correct_dof(kind, zp, f(zp[0]), dt, z)
        xs.append(z[0])
    return np.array(xs), z


def test_verlet_kernel_equals_central_differences():
    """The engine's 'verlet' positions equal x_{l+1} = 2 x_l - x_{l-1} + dt^2 f(x_l) started consistently."""
    f = lambda x: -x - 0.3 * x**3  # noqa: E731
    dt, n = 0.05, 400
    xs, z = _integrate(VERLET, f, 0.2, 1.0, dt, n)
    x_prev, x = 0.2, 0.2 + dt * 1.0 + 0.5 * dt * dt * f(0.2)
    ref = [x]
    for _ in range(n - 1):
        x_prev, x = x, 2 * x - x_prev + dt * dt * f(x)
        ref.append(x)
    assert np.allclose(xs, ref, rtol=0, atol=1e-13)
    # velocity is the central-difference velocity (x_{l+1} - x_{l-1}) / (2 dt)
    assert z[1] / dt == pytest.approx((ref[-1] - ref[-2]) / dt + 0.5 * dt * f(ref[-1]), rel=1e-10)


def test_gear_is_exact_for_quintic_motion():
    """Predictor-corrector reproduces x = t^5 (f = 20 t^3 given as a function of x)."""
    dt = 0.01
    z = initial_vector(GEAR5, [1.0, 5.0, 20.0, 60.0, 120.0, 120.0], dt)  # x = (1 + t)^5 at t = 0
    zp = np.zeros(6)
    for l in range(1, 101):
        predict_dof(GEAR5, z, zp)
        t = l * dt
        correct_dof(GEAR5, zp, 20.0 * (1 + t) ** 3, dt, z)
    assert z[0] == pytest.approx(2.0**5, rel=1e-12)
    assert z[1] / dt == pytest.approx(5 * 2.0**4, rel=1e-12)


def test_gear_oscillator_one_period():
    dt = 2 * math.pi / 2000
    z = initial_vector(GEAR5, [0.0, 1.0, 0.0, -1.0, 0.0, 1.0], dt)
    zp = np.zeros(6)
    for _ in range(2000):
        predict_dof(GEAR5, z, zp)
        correct_dof(GEAR5, zp, -zp[0], dt, z)
    assert z[0] == pytest.approx(0.0, abs=1e-12)
    assert z[1] / dt == pytest.approx(1.0, abs=1e-10)
