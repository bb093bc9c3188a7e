"""Critical time step estimate, instability detection, and a smoke run of every shipped scenario."""

import subprocess
from pathlib import Path

import numpy as np
import pytest
from numba import njit

from polydem_cli.engine.integrators import GEAR5, VERLET, correct_dof, predict_dof
from polydem_cli.engine.stability import OMEGA_DT_LIMIT, estimate, gear_spectral_radius
from polydem_cli.scenario.build import build_system
from polydem_cli.scenario.load import load_scenario
from polydem_cli.solvers.explicit import run

from conftest import SCEN, polydem_cmd


def _explicit(path) -> bool:
    from polydem_cli.scenario.load import read_toml
    from polydem_cli.scenario.schema import kind_of

    return kind_of(read_toml(path)[0]) == "explicit"


#: the scenarios of the explicit solver (the quasi-static ones: tests/test_quasistatic.py)
ALL = sorted(p for p in SCEN.rglob("*.toml") if _explicit(p))


@njit(cache=True)
def _oscillate(kind, h, nsteps):
    """Run the engine's own predictor/corrector kernels on x'' = -x (omega = 1, dt = h) from x = 0,
    v = 1 and return the largest |x| over the last tenth of the run (the exact amplitude is 1)."""
    z = np.zeros(6)
    zp = np.zeros(6)
    d = (0.0, 1.0, 0.0, -1.0, 0.0, 1.0)
    fact = (1.0, 1.0, 2.0, 6.0, 24.0, 120.0)
    for k in range(6 if kind == GEAR5 else 3):
        z[k] = d[k] * h**k / fact[k]
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


@pytest.mark.parametrize(
    "name,end",
    [("ch5/small_tension.toml", "time.end_displacement=6e-4"), ("bench_dense_hexagons.toml", "time.end_time=0.1")],
)
def test_detector_trips_at_ten_times_the_critical_step(tmp_path, name, end):
    """A bonded specimen and a dense contact packing at 10x the estimate stop with a clear message.
    (A loose pile whose contacts slide is softer than the estimate assumes and may survive.)"""
    sc, _ = load_scenario(SCEN / name)
    dt = 10 * estimate(build_system(sc, "x"))["dt_crit"]
    r = subprocess.run(
        polydem_cmd()
        + [
            "run",
            str(SCEN / name),
            "-o",
            str(tmp_path / "u.h5"),
            "--set",
            f"time.dt={dt}",
            "--set",
            end,
            "--set",
            "time.allow_large_dt=true",
        ],
        capture_output=True,
        text=True,
    )
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


#: steps of every smoke run, and of the short preparation a scenario with [initial_state] starts from
SMOKE_STEPS = 300


def _preparation_scenario(result) -> Path:
    """The scenario that writes the result ``outputs/<dir>/<name>.h5``: ``scenarios/<dir>/<name>.toml`` (the
    Makefile's rule for every run another run starts from)."""
    result = Path(result)
    path = SCEN / result.parent.name / (result.stem + ".toml")
    assert path.exists(), f"no scenario {path} writes the preparation {result}"
    return path


@pytest.fixture(scope="module")
def prepared(tmp_path_factory):
    """``prepared(sc)``: the ``[initial_state] initial_state.file`` override that points scenario ``sc`` at a short,
    finished run of its own preparation scenario (``SMOKE_STEPS`` steps, made here on first use, itself started from
    its preparation's short run where it has one), and that run's final positions."""
    import h5py

    from helpers import run_scenario

    where = tmp_path_factory.mktemp("preparations")
    done = {}

    def make(sc):
        path = _preparation_scenario(sc["initial_state"]["file"])
        if path not in done:
            prep, _ = load_scenario(path)
            sets = [f"time.end_time={SMOKE_STEPS * prep['time']['dt']!r}"]
            if prep["initial_state"] is not None:
                sets.append(make(prep)[0])
            out = where / (path.stem + ".h5")
            summary = run_scenario(path, out, sets)
            assert summary["status"] == "finished" and summary["steps"] == SMOKE_STEPS, summary["status"]
            with h5py.File(out, "r") as f:
                x = f["frames/x"][-1]
            done[path] = (f'initial_state.file="{out}"', x)
        return done[path]

    return make


@pytest.mark.slow
@pytest.mark.parametrize("path", ALL, ids=[str(p.relative_to(SCEN)) for p in ALL])
def test_every_shipped_scenario_starts_stably(tmp_path, path, request):
    """Smoke run of every scenario (300 steps): valid, below the critical step, no instability stop.  A
    scenario that starts from another run's final state ([initial_state]: the Luding & Herrmann loading,
    rate and relaxation runs and the alternative preparation) starts from a short run of its preparation scenario
    made here (the ``prepared`` fixture), and must start from that run's final positions."""
    sc, text = load_scenario(path)
    start = None
    if sc["initial_state"] is not None:
        override, start = request.getfixturevalue("prepared")(sc)
        sc, text = load_scenario(path, [override])
    system = build_system(sc, str(path))
    if start is not None:
        np.testing.assert_array_equal(system.x0, start)  # the preparation's final state, not the generated one
    assert system.dt <= estimate(system)["dt_crit"]
    summary = run(
        system,
        out=tmp_path / "s.h5",
        scenario_file=str(path),
        scenario_text=text,
        quiet=True,
        stop_after_steps=min(SMOKE_STEPS, system.end_step),
    )
    assert summary["failure"] is None
    assert summary["steps"] == min(SMOKE_STEPS, system.end_step)
    if (
        path.stem.startswith(("smoke_", "small_")) or path.stem == "nuts_small"
    ):  # the reduced counterparts: report, export
        from polydem_cli.io.vtkhdf import export
        from polydem_cli.report import make_report

        files = make_report(tmp_path / "s.h5", tmp_path / "rep")
        assert files and all(f.stat().st_size > 1000 for f in files)
        r = export(tmp_path / "s.h5", tmp_path / "s.vtkhdf")
        assert r["frames"] >= 1 and r["particles"] == system.n


def test_a_time_step_far_above_the_estimate_is_refused_before_any_output(tmp_path):
    """Bad input of the concrete job: dt 3x the critical estimate is refused (exit 2, the key and the
    estimate named, nothing written); time.allow_large_dt = true lets it run."""
    name = SCEN / "ch7" / "small_tension_ra.toml"
    sc, _ = load_scenario(name)
    dt = 3 * estimate(build_system(sc, "x"))["dt_crit"]
    out = tmp_path / "c.h5"
    r = subprocess.run(
        polydem_cmd() + ["run", str(name), "-o", str(out), "--set", f"time.dt={dt}"], capture_output=True, text=True
    )
    assert r.returncode == 2, r.stderr
    assert "time.dt" in r.stderr and "critical time step estimate" in r.stderr and "allow_large_dt" in r.stderr
    assert not out.exists() and not out.with_suffix(".summary.json").exists()
    r = subprocess.run(polydem_cmd() + ["check", str(name), "--set", f"time.dt={dt}"], capture_output=True, text=True)
    assert r.returncode == 2 and "time.dt" in r.stderr


def test_unstable_run_is_caught_whatever_the_history_cadence(tmp_path):
    """dt 27x the estimate (allowed explicitly) with one history row per 1e5 steps: the run must not end
    'finished' with a small energy error; it stops as unstable from the present state (exit 1)."""
    import json

    from polydem_cli.io.hdf5 import open_result

    from helpers import run_unstable_pile

    out = tmp_path / "u.h5"
    r = run_unstable_pile(out, "output.history_every=100000")
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

    from polydem_cli.io.hdf5 import read_history
    from polydem_cli.scenario.build import build_system
    from polydem_cli.scenario.load import load_scenario
    from polydem_cli.solvers.explicit import run

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
    assert (
        json.loads((tmp_path / "f.summary.json").read_text())["observables"]["final_kinetic"]
        == tab[-1, cols.index("kinetic")]
    )


PAIR = """
[scenario]
title = "two bonded cells, free"
seed = 3
[time]
integrator = "{integ}"
dt = {dt}
end_time = 1.0e-3
[materials.cell]
density = 2.4
[[particles]]
name = "pair"
material = "cell"
thickness = 1.0
type = "voronoi"
nx = 2
ny = 1
q_pg = 0.999
[bonds]
E = 4.14e11
nu = -0.676
kappa_0 = 1.0
G_ax = 1.0e12
"""


@pytest.mark.parametrize("integ", ["gear5", "verlet"])
def test_estimate_is_the_highest_frequency_of_a_simulated_bonded_pair(tmp_path, integ):
    """Two free Voronoi cells joined by one beam (the concrete's stiffness), started with a random velocity
    kick and left alone: the highest frequency in the spectrum of the simulated relative motion is the
    estimate's omega_max (the estimate is used for the critical time step of every run)."""
    from polydem_cli.engine.simulation import Simulation

    scen = tmp_path / "pair.toml"
    sc0, _ = load_scenario(_write(scen, PAIR.format(integ=integ, dt=1e-9)))
    e = estimate(build_system(sc0, str(scen)))
    w = e["omega_max"]
    dt = 0.02 / w  # well resolved: the frequency error of both integrators is < 1e-4 here
    sc, _ = load_scenario(_write(scen, PAIR.format(integ=integ, dt=dt)))
    s = build_system(sc, str(scen))
    assert s.n == 2 and s.family_data["bonds"].n == 1
    rng = np.random.default_rng(5)
    s.v0[:] = rng.normal(size=(2, 3)) * np.array([1e-3, 1e-3, 1e-3])  # cm/s, rad/s: tiny, elastic
    sim = Simulation(s)
    sim.initialize()
    n = 16384
    rows = np.zeros((4, sim.ncols))
    rel = np.zeros((n, 3))
    for k in range(n):
        sim.advance(sim.step + 1, rows, 10**9)
        x = sim.positions()
        rel[k] = x[1] - x[0]
    spec = np.abs(np.fft.rfft((rel - rel.mean(axis=0)) * np.hanning(n)[:, None], axis=0)).sum(axis=1)
    freqs = 2 * np.pi * np.fft.rfftfreq(n, dt)
    peaks = [
        i
        for i in range(1, len(spec) - 1)
        if spec[i] > spec[i - 1] and spec[i] >= spec[i + 1] and spec[i] > 1e-3 * spec.max()
    ]
    i = max(peaks)
    a, b, c = np.log(spec[i - 1 : i + 2])
    w_sim = freqs[i] + 0.5 * (a - c) / (a - 2 * b + c) * (freqs[1] - freqs[0])  # parabolic peak position
    assert w_sim == pytest.approx(w, rel=2e-3)  # the frequency bin is 1.9 % of w; measured: 2e-4 apart


def _write(path, text):
    path.write_text(text)
    return path


SQUARES = """
[scenario]
title = "a square resting on a fixed square under in-plane gravity"
[time]
integrator = "gear5"
dt = {dt}
end_time = 1.0
[materials.m]
density = 1.0
k_n = 1.0e7
[[particles]]
name = "base"
material = "m"
thickness = 1.0
type = "regular_polygon"
center = [0.0, 0.0]
sides = 4
circumradius = 0.7071067811865476
rotation = 0.7853981633974483
[[particles]]
name = "top"
material = "m"
thickness = 1.0
type = "regular_polygon"
center = [0.0, 1.0]
sides = 4
circumradius = 0.7071067811865476
rotation = 0.7853981633974483
velocity = [0.0, 0.0, 0.05]
[[boundary]]
set = "base"
x1 = "fixed"
x2 = "fixed"
phi = "fixed"
[contact]
tangential = "none"
[body_force]
gravity = [0.0, -1000.0]
"""


def test_contact_estimate_bounds_the_frequencies_of_a_simulated_face_contact():
    """The stiffest contact there is, a full face contact (B = the side a): a unit square resting on a fixed
    one under gravity, with a small spin to rock it.  Simulated with the real integrator; the spectrum of
    its height and rotation has the bouncing mode at the analytic omega = sqrt(k_n a^2 T / m) (f_n = k_n A_n
    B_n T with A_n = a delta, B_n = a: linear in the overlap) and a rocking mode.  The estimate must bound
    both and not be far above them (its bound B <= 2r, lever arm <= r, two free particles: 4x here)."""
    from polydem_cli.engine.simulation import Simulation

    from helpers import system_from_toml

    w_est = estimate(system_from_toml(SQUARES.format(dt=1e-6)))["omega_max"]
    dt = 0.02 / w_est
    s = system_from_toml(SQUARES.format(dt=dt))
    m, a = s.mass[1], 1.0
    assert m == pytest.approx(1.0) and s.n == 2
    w_bounce = np.sqrt(1.0e7 * a * a * 1.0 / m)
    sim = Simulation(s)
    sim.initialize()
    n = 32768  # frequency bins of 1 % of the bouncing frequency
    rows = np.zeros((4, sim.ncols))
    y = np.zeros((n, 2))
    for k in range(n):
        sim.advance(sim.step + 1, rows, 10**9)
        y[k] = sim.positions()[1, 1:3]
    assert np.all(sim.positions()[1, 1] < 1.0)  # it never lifted off: one contact all along

    def peaks(sig):
        spec = np.abs(np.fft.rfft((sig - sig.mean()) * np.hanning(n)))
        freqs = 2 * np.pi * np.fft.rfftfreq(n, dt)
        out = []
        for i in range(2, len(spec) - 1):
            if spec[i] > spec[i - 1] and spec[i] >= spec[i + 1] and spec[i] > 1e-2 * spec.max():
                a_, b_, c_ = np.log(spec[i - 1 : i + 2])
                out.append(freqs[i] + 0.5 * (a_ - c_) / (a_ - 2 * b_ + c_) * (freqs[1] - freqs[0]))
        return out

    bounce = peaks(y[:, 0])
    rock = peaks(y[:, 1])
    assert bounce and rock
    assert max(bounce, key=lambda w: -abs(w - w_bounce)) == pytest.approx(w_bounce, rel=5e-3)
    w_max = max(bounce + rock)
    assert w_max <= w_est  # the estimate is a bound of what the integrator meets
    assert w_est <= 5.0 * w_max  # and not so loose that it wastes steps
