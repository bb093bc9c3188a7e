"""polydem sweep on a Dask local cluster (started and shut down by the command)."""

import csv
import json

import pytest
from click.testing import CliRunner

from polydem_cli.cli import main
from polydem_cli.workflows.sweep import split_values, variant_name, variants

from conftest import SCEN


def test_variant_expansion():
    assert split_values("1,2,[3, 4],'a,b'") == ["1", "2", "[3, 4]", "'a,b'"]
    vs = variants(["bonds.kappa_0=1e-5,2e-5", "time.dt=0.01,0.02"])
    assert len(vs) == 4 and vs[1] == ["bonds.kappa_0=1e-5", "time.dt=0.02"]
    assert variant_name("t", vs[1]) == "t__kappa-0-1e-5__dt-0.02"


def test_sweep_runs_variants_on_dask_and_reuses_finished_ones(tmp_path):
    args = [
        "sweep",
        str(SCEN / "ch5" / "small_tension.toml"),
        "--set",
        "bonds.kappa_0=1e-5,2e-5",
        "--base",
        "time.end_displacement=6e-5",
        "--base",
        "time.dt=0.04",
        "--out",
        str(tmp_path),
        "--workers",
        "2",
    ]
    r = CliRunner().invoke(main, args)
    assert r.exit_code == 0, r.output
    rows = list(csv.DictReader(open(tmp_path / "sweep.csv")))
    assert len(rows) == 2 and all(x["status"] == "finished" for x in rows)
    assert sorted(x["bonds.kappa_0"] for x in rows) == ["1e-5", "2e-5"]  # the swept key has its own column
    peaks = sorted(float(x["peak |f2:specimen.top| [N]"]) for x in rows)
    assert peaks[1] > 1.3 * peaks[0]  # doubling kappa_0 raises the load carried at this displacement
    assert all((tmp_path / (x["variant"] + ".h5")).exists() for x in rows)
    r = CliRunner().invoke(main, args)
    assert r.exit_code == 0 and r.output.count("(reused)") == 2
    data = json.loads((tmp_path / "sweep.json").read_text())
    assert all(v["reused"] for v in data["variants"])


def test_sweep_rejects_a_bad_variant_before_running(tmp_path):
    r = CliRunner().invoke(
        main,
        ["sweep", str(SCEN / "ch5" / "small_tension.toml"), "--set", "bonds.kappa_0=1e-5,-1", "--out", str(tmp_path)],
    )
    assert r.exit_code == 2 and "bonds.kappa_0 = -1.0" in r.output
    assert not (tmp_path / "sweep.csv").exists()


def test_sweep_never_deletes_a_result_another_run_is_writing(tmp_path):
    """A variant's result held by another process (its write lock) is neither deleted nor resumed."""
    import subprocess
    import sys
    import time

    from polydem_cli.io.hdf5 import ResultError
    from polydem_cli.workflows.sweep import run_variant

    out = tmp_path / "v.h5"
    out.write_bytes(b"someone else's data")
    holder = subprocess.Popen(
        [
            sys.executable,
            "-c",
            "import sys, time; from polydem_cli.io.hdf5 import result_lock\n"
            f"with result_lock({str(out)!r}):\n    print('held', flush=True); time.sleep(60)",
        ],
        stdout=subprocess.PIPE,
        text=True,
    )
    try:
        assert holder.stdout.readline().strip() == "held"
        with pytest.raises(ResultError, match="another polydem run is writing this result"):
            run_variant(str(SCEN / "demo_hex_pile.toml"), ["time.end_displacement=0.001"], str(out))
        assert out.read_bytes() == b"someone else's data"
    finally:
        holder.kill()
        holder.wait()
    time.sleep(0.1)


def test_the_sweep_table_of_a_specimen_has_its_macroscopic_measures_in_report_units(tmp_path):
    """A concrete specimen with [macro]: E in GPa, nu, the peak stress in N/mm2 and the peak load in N, one
    column per swept key, numbers to 6 significant digits (not dyn to 17)."""
    import math

    from polydem_cli.io.hdf5 import open_result

    r = CliRunner().invoke(
        main,
        ["sweep", str(SCEN / "ch7" / "smoke_concrete_tension.toml"), "--set", "bonds.kappa_0=9.21e-5,1.2e-4",
         "--base", "time.end_displacement=0.01", "--out", str(tmp_path), "--workers", "2"],
    )  # fmt: skip
    assert r.exit_code == 0, r.output
    rows = list(csv.DictReader(open(tmp_path / "sweep.csv")))
    header = list(rows[0])
    assert header[:2] == ["variant", "bonds.kappa_0"]
    for col in ("E [GPa]", "nu [-]", "peak stress [N/mm2]", "peak |f2:specimen.bottom| [N]", "failed bonds"):
        assert col in header, header
    for x in rows:
        # whether the peak is the strength or a lower bound (the run ended at the largest stress), as TOML says it
        assert x["peak reached"] in ("true", "false") and x["reused"] == "false", x
        # the line printed per variant says its wall time (it said 0.0 s for every variant)
        assert f"  {x['variant']}: finished ({float(x['wall time [s]']):.1f} s)" in r.output, r.output
        with open_result(tmp_path / (x["variant"] + ".h5")) as f:
            m = json.loads(f.attrs["summary"])["macro"]
        assert float(x["E [GPa]"]) == pytest.approx(m["E"] / 1e10, rel=1e-5)
        assert float(x["peak stress [N/mm2]"]) == pytest.approx(m["peak_stress"] / 1e7, rel=1e-5)
        assert 20 < float(x["E [GPa]"]) < 50 and 1 < float(x["peak stress [N/mm2]"]) < 10
        for v in x.values():
            try:
                float(v)
            except ValueError:
                continue
            digits = v.lower().split("e")[0].replace("-", "").replace(".", "").lstrip("0")
            assert len(digits) <= 6 or not math.isfinite(float(v)), (v, x)
