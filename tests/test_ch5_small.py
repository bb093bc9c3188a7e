"""Small (6 x 6) versions of the chapter-5 specimens: peak load and softening, output, report, resume."""

import json

import h5py
import numpy as np
import pytest

from polydem_cli.io.hdf5 import read_bonds, read_history
from polydem_cli.report import make_report
from polydem_cli.scenario.build import build_system
from polydem_cli.scenario.load import load_scenario
from polydem_cli.solvers.explicit import run

from conftest import SCEN

CH5 = SCEN / "ch5"


def _run(name, tmp_path, overrides=(), **kw):
    sc, text = load_scenario(CH5 / f"{name}.toml", overrides)
    system = build_system(sc, str(CH5 / f"{name}.toml"))
    out = tmp_path / f"{name}.h5"
    summary = run(system, out=out, scenario_file=str(CH5 / f"{name}.toml"), scenario_text=text, quiet=True, **kw)
    cols, tab = read_history(out)
    c = {n: i for i, n in enumerate(cols)}
    return system, summary, out, tab[:, c["u2:specimen.top"]], tab[:, c["f2:specimen.top"]], tab, c


@pytest.mark.slow
def test_small_tension_and_compression_show_peak_and_softening(tmp_path):
    _, st, _, ut, ft, tt, ct = _run("small_tension", tmp_path, ["time.end_displacement=2.5e-4"])
    _, sc, out_c, uc, fc, tc, cc = _run("small_compression", tmp_path, ["time.end_displacement=8e-4"])
    # tension: f2 > 0, a peak inside the run, softening after it
    kt = int(np.argmax(ft))
    assert 0 < kt < len(ft) - 10 and ft[kt] > 0
    assert ft[-1] < 0.95 * ft[kt]
    assert tt[-1, ct["bonds_damaged"]] > 10
    # linear start: secant stiffness at 20 % of the peak is the initial one
    k20 = int(np.argmax(ft > 0.2 * ft[kt]))
    k5 = int(np.argmax(ft > 0.05 * ft[kt]))
    assert ft[k20] / ut[k20] == pytest.approx(ft[k5] / ut[k5], rel=0.02)
    # compression: f2 < 0, brittle failure with failed beams, larger peak than in tension
    kc = int(np.argmin(fc))
    assert 0 < kc < len(fc) - 10 and fc[kc] < 0
    assert abs(fc[-1]) < 0.6 * abs(fc[kc])
    assert tc[-1, cc["bonds_failed"]] > 5
    assert abs(fc[kc]) > 2.0 * ft[kt]  # thesis (30 x 30): 3.34
    # energy bookkeeping closes (quasi-static: tiny kinetic energy)
    assert sc["observables"]["energy_balance_error"] < 1e-3
    # the bonded output and the report
    b = read_bonds(out_c)
    nb = len(b["L"])
    assert b["frame_d"].shape[1] == nb and b["frame_strain"].shape[1:] == (nb, 4)
    assert np.all(np.diff(b["frame_d"], axis=0) >= 0)  # damage never heals
    assert np.array_equal(np.isclose(b["frame_d"][-1], 1.0), b["frame_d"][-1] >= 1.0)
    assert sc["bonds"]["count"] == nb and sc["bonds"]["failed"] == int((b["frame_d"][-1] >= 1).sum())
    files = make_report(out_c, tmp_path / "rep")
    names = sorted(f.name for f in files)
    assert "small_compression_damage.png" in names and "small_compression_strains.png" in names
    assert all(f.stat().st_size > 5000 for f in files)


def test_bonded_run_resumes_bit_identically(tmp_path):
    ov = ["time.end_displacement=1.2e-4", "output.frame_interval=200"]
    _, _, a, *_ = _run("small_tension", tmp_path, ov)
    sc, text = load_scenario(CH5 / "small_tension.toml", ov)
    system = build_system(sc, "x")
    b = tmp_path / "b.h5"
    run(system, out=b, scenario_file="x", scenario_text=text, quiet=True, stop_after_steps=140_001)
    run(out=b, resume=True, quiet=True)
    with h5py.File(a, "r") as fa, h5py.File(b, "r") as fb:
        for k in ("frames/x", "frames/bond_d", "frames/bond_strain", "history/table"):
            assert np.array_equal(fa[k][...], fb[k][...]), k
        assert json.loads(fb.attrs["summary"])["resumed"]


def test_rate_dependent_small_runs(tmp_path):
    """Faster loading: the rate-dependent beams (alpha > 0) carry more than the rate-independent ones."""
    ov = ["time.end_displacement=1.2e-4", "output.frame_interval=50", "time.dt=1e-3"]
    *_, f_ra, _, _ = _run("small_rate_tension_ra", tmp_path, ov)
    *_, f_ru, _, _ = _run("small_rate_tension_ra", tmp_path, ov + ["bonds.rate_dependent=false"])
    assert f_ra.max() > 1.02 * f_ru.max()
