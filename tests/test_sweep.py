"""polydem sweep on a Dask local cluster (started and shut down by the command)."""

import csv
import json

import pytest
from click.testing import CliRunner

from polydem_cli.cli import main
from polydem_cli.studies.sweep import split_values, variant_name, variants

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
    peaks = sorted(float(x["peak_f2:specimen.top"]) for x in rows)
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
    from polydem_cli.studies.sweep import run_variant

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
        with pytest.raises(ResultError, match="still being written by another run"):
            run_variant(str(SCEN / "demo_hex_pile.toml"), ["time.end_displacement=0.001"], str(out))
        assert out.read_bytes() == b"someone else's data"
    finally:
        holder.kill()
        holder.wait()
    time.sleep(0.1)
