"""Critical time step estimate, instability detection, and a smoke run of every shipped scenario."""
import subprocess

import numpy as np
import pytest

from conftest import SCEN, polydem_cmd
from polydem_cli.engine.runner import run
from polydem_cli.engine.stability import OMEGA_DT_LIMIT, estimate, gear_spectral_radius
from numba import njit

from polydem_cli.engine.integrators import GEAR5, VERLET, correct_dof, predict_dof
from polydem_cli.scenario.build import build_system
from polydem_cli.scenario.load import load_scenario

ALL = sorted(SCEN.rglob("*.toml"))


@njit(cache=True)
def _oscillate(kind, h, nsteps):
    """Run the engine's own predictor/corrector kernels on x'' = -x (omega = 1, dt = h) from x = 0,
    v = 1 and return the largest |x| over the last tenth of the run (the exact amplitude is 1)."""
    z = np.zeros(6)
    zp = np.zeros(6)
    d = (0.0, 1.0, 0.0, -1.0, 0.0, 1.0)
    fact = (1.0, 1.0, 2.0, 6.0, 24.0, 120.0)
    for k in range(6 if kind == GEAR5 else 3):
        z[k] = d[k] * h ** k / fact[k]
    amp = 0.0
    for step in range(nsteps):
        predict_dof(kind, z, zp)
        correct_dof(kind, zp, -zp[0], h, z)
        if step >= nsteps - nsteps // 10:
            amp = max(amp, abs(z[0]))
        if not abs(z[0]) < 1e6:
            return np.inf
    return amp


def test_stability_limits_of_the_real_integrators():
    """The limits omega*dt of the stability estimate, checked by running the integrators themselves (not
    the estimate's own matrices): Gear stays bounded at its limit 0.12 over 2e5 steps and grows
    beyond it (0.5); central differences are bounded up to 2 and blow up just above."""
    g = OMEGA_DT_LIMIT[GEAR5]
    assert abs(_oscillate(GEAR5, g, 200_000) - 1.0) < 1e-3
    assert abs(_oscillate(GEAR5, 0.05, 200_000) - 1.0) < 1e-3
    assert _oscillate(GEAR5, 0.5, 200_000) > 10.0  # weakly unstable beyond: the reason for the limit
    assert OMEGA_DT_LIMIT[VERLET] == 2.0
    assert _oscillate(VERLET, 1.95, 200_000) < 10.0  # bounded (elliptic orbit, amplitude 1/sqrt(1 - h^2/4))
    assert _oscillate(VERLET, 2.02, 2_000) == np.inf
    # the spectral radius the estimate uses agrees with the runs: growth per step at 0.5 from the run
    n = 20_000
    growth = (_oscillate(GEAR5, 0.5, n) / _oscillate(GEAR5, 0.5, n // 2)) ** (1.0 / (n - n // 2))
    assert growth == pytest.approx(gear_spectral_radius(0.5), rel=2e-5)


def test_estimate_matches_a_single_contact_oscillation(tmp_path):
    """A square pressed face-to-face on a fixed one oscillates at sqrt(k_n B^2 T / m): the estimate
    (which adds rotation and a second free body) is an upper bound on that frequency."""
    sc, _ = load_scenario(SCEN / "demo_hex_pile.toml")
    s = build_system(sc, "x")
    e = estimate(s)
    i = 0
    w_face = np.sqrt(s.kn[i] * (2 * s.radius[i]) ** 2 * s.thickness[i] / s.mass[i])
    assert e["omega_max"] >= w_face
    assert e["omega_max"] < 10 * w_face


@pytest.mark.parametrize("name,end", [("ch5/small_tension.toml", "time.end_displacement=6e-4"),
                                      ("bench_dense_hexagons.toml", "time.end_time=0.1")])
def test_detector_trips_at_ten_times_the_critical_step(tmp_path, name, end):
    """A bonded specimen and a dense contact packing at 10x the estimate stop with a clear message.
    (A loose pile whose contacts slide is softer than the estimate assumes and may survive.)"""
    sc, _ = load_scenario(SCEN / name)
    dt = 10 * estimate(build_system(sc, "x"))["dt_crit"]
    r = subprocess.run(polydem_cmd() + ["run", str(SCEN / name), "-o", str(tmp_path / "u.h5"),
                                        "--set", f"time.dt={dt}", "--set", end, "--set", "time.allow_large_dt=true"],
                       capture_output=True, text=True)
    assert r.returncode == 1
    assert "warning: dt =" in r.stderr and "exceeds the critical time step estimate" in r.stderr
    msg = r.stderr.strip().splitlines()[-1]
    assert msg.startswith("error: run stopped:") and "unstable" in msg
    assert "at step" in msg and "t = " in msg and "critical time step estimate" in msg
    assert "particle" in msg  # names the offender
    assert "Traceback" not in r.stderr
    from polydem_cli.io.hdf5 import open_result
    with open_result(tmp_path / "u.h5") as f:
        assert f.attrs["status"] == "failed"


@pytest.mark.slow
@pytest.mark.parametrize("path", ALL, ids=[str(p.relative_to(SCEN)) for p in ALL])
def test_every_shipped_scenario_starts_stably(tmp_path, path):
    """Smoke run of every scenario (300 steps): valid, below the critical step, no instability stop."""
    sc, text = load_scenario(path)
    system = build_system(sc, str(path))
    assert system.dt <= estimate(system)["dt_crit"]
    summary = run(system, out=tmp_path / "s.h5", scenario_file=str(path), scenario_text=text, quiet=True,
                  stop_after_steps=min(300, system.end_step))
    assert summary["failure"] is None
    assert summary["steps"] == min(300, system.end_step)


def test_a_time_step_far_above_the_estimate_is_refused_before_any_output(tmp_path):
    """Bad input of the concrete job: dt 3x the critical estimate is refused (exit 2, the key and the
    estimate named, nothing written); time.allow_large_dt = true lets it run."""
    name = SCEN / "ch7" / "small_tension_ra.toml"
    sc, _ = load_scenario(name)
    dt = 3 * estimate(build_system(sc, "x"))["dt_crit"]
    out = tmp_path / "c.h5"
    r = subprocess.run(polydem_cmd() + ["run", str(name), "-o", str(out), "--set", f"time.dt={dt}"],
                       capture_output=True, text=True)
    assert r.returncode == 2, r.stderr
    assert "time.dt" in r.stderr and "critical time step estimate" in r.stderr and "allow_large_dt" in r.stderr
    assert not out.exists() and not out.with_suffix(".summary.json").exists()
    r = subprocess.run(polydem_cmd() + ["check", str(name), "--set", f"time.dt={dt}"], capture_output=True, text=True)
    assert r.returncode == 2 and "time.dt" in r.stderr


def test_unstable_run_is_caught_whatever_the_history_cadence(tmp_path):
    """dt 27x the estimate (allowed explicitly) with one history row per 1e5 steps: the run must not end
    'finished' with a small energy error; it stops as unstable from the present state (exit 1)."""
    import json
    import subprocess

    from conftest import SCEN, polydem_cmd
    from polydem_cli.io.hdf5 import open_result

    out = tmp_path / "u.h5"
    r = subprocess.run(polydem_cmd() + ["run", str(SCEN / "demo_hex_pile.toml"), "-o", str(out), "-q",
                                        "--set", "time.dt=5e-4", "--set", "time.allow_large_dt=true",
                                        "--set", "output.history_every=100000", "--set", "time.end_displacement=0.3"],
                       capture_output=True, text=True)
    assert r.returncode == 1, (r.stdout, r.stderr)
    assert "unstable at step" in r.stderr
    with open_result(out) as f:
        assert f.attrs["status"] == "failed"
        s = json.loads(f.attrs["summary"])
    assert s["status"] == "failed" and "unstable" in s["failure"]
    assert s["observables"]["energy_balance_error"] > 0.25  # of the state it failed in, not of row 0


def test_finished_run_summary_is_of_the_final_state(tmp_path):
    """With a history cadence that does not divide the run, the table still ends at the final step and
    the summary's final energies are those of that state."""
    import json

    from polydem_cli.engine.runner import run
    from polydem_cli.io.hdf5 import read_history
    from polydem_cli.scenario.build import build_system
    from polydem_cli.scenario.load import load_scenario
    from conftest import SCEN

    sc, text = load_scenario(SCEN / "demo_hex_pile.toml", ["time.end_displacement=0.0123", "output.history_every=500"])
    system = build_system(sc, "demo")
    out = tmp_path / "f.h5"
    s = run(system, out=out, scenario_text=text, quiet=True)
    assert system.end_step % 500 != 0
    cols, tab = read_history(out)
    assert tab[-1, cols.index("step")] == system.end_step == s["steps"]
    assert tab[-2, cols.index("step")] == system.end_step // 500 * 500
    assert s["observables"]["final_kinetic"] == tab[-1, cols.index("kinetic")]
    assert json.loads((tmp_path / "f.summary.json").read_text())["observables"]["final_kinetic"] == tab[-1, cols.index("kinetic")]
