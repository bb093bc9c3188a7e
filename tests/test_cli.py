"""Command-line interface: run, report, study, schema, progress."""

import json
import shutil
import subprocess

import pytest
from click.testing import CliRunner

from polydem_cli.cli import main
from polydem_cli.scenario.schema import SCHEMA
from polydem_cli.scenario.spec import markdown

from conftest import ROOT, SCEN, polydem_cmd
from helpers import run_unstable_pile


def test_version_and_help():
    r = CliRunner().invoke(main, ["--version"])
    assert r.exit_code == 0 and "polydem" in r.output
    r = CliRunner().invoke(main, ["-h"])
    for cmd in ("run", "check", "report", "study", "bench", "schema"):
        assert cmd in r.output


def test_run_default_output_path_progress_and_report(tmp_path):
    scen = tmp_path / "pile.toml"
    shutil.copy(SCEN / "demo_hex_pile.toml", scen)
    r = subprocess.run(
        polydem_cmd() + ["run", "pile.toml", "--set", "time.end_displacement=0.02"],
        capture_output=True,
        text=True,
        cwd=tmp_path,
    )
    assert r.returncode == 0, r.stderr
    out = tmp_path / "outputs" / "pile.h5"
    assert out.exists() and (tmp_path / "outputs" / "pile.summary.json").exists()
    assert "steps/s" in r.stderr and "ETA" in r.stderr and "100.0%" in r.stderr  # progress
    assert "wrote outputs/pile.h5" in r.stdout
    r = subprocess.run(
        polydem_cmd() + ["run", "pile.toml", "-q", "--set", "time.end_displacement=0.02", "-o", "q.h5"],
        capture_output=True,
        text=True,
        cwd=tmp_path,
    )
    assert r.returncode == 0 and r.stderr == "" and r.stdout == ""
    r = CliRunner().invoke(main, ["report", str(out), "--out", str(tmp_path / "rep"), "--times", "0,0.01"])
    assert r.exit_code == 0, r.output
    pngs = sorted(p.name for p in (tmp_path / "rep").glob("*.png"))
    assert pngs == ["pile_frames.png", "pile_history.png", "pile_specimen.png", "pile_velocity.png"]
    assert all((tmp_path / "rep" / p).stat().st_size > 5000 for p in pngs)


def test_study_integrators_cli(tmp_path):
    r = CliRunner().invoke(main, ["study", "integrators", "--out", str(tmp_path)])
    assert r.exit_code == 0, r.output
    data = json.loads((tmp_path / "integrators.json").read_text())
    assert abs(data["oscillator"]["PC"]["order"] - 6) < 0.3
    assert abs(data["collision"]["PC"]["order"] - 2) < 0.3
    assert (tmp_path / "integrators.png").exists()


def test_scenario_reference_is_up_to_date():
    """docs/scenario.md is generated from the schema (make docs)."""
    assert (ROOT / "docs" / "scenario.md").read_text() == markdown(SCHEMA)
    from polydem_cli.scenario.schema import QS_SCHEMA

    assert (ROOT / "docs" / "scenario_quasistatic.md").read_text() == markdown(
        QS_SCHEMA, "Scenario file reference — quasi-static solver"
    )


@pytest.mark.parametrize(
    "scen,stop",
    [("demo_hex_pile.toml", 3), ("ch7/smoke_concrete_tension.toml", 3), ("ch7/smoke_concrete_tension.toml", 12000)],
)
def test_report_of_an_interrupted_result(tmp_path, scen, stop):
    """An interrupted long run (one frame, one history row; or part of the run): the report writes what the
    data allow, says what is missing and how to continue, exit 0 — no traceback."""
    from polydem_cli.scenario.build import build_system
    from polydem_cli.scenario.load import load_scenario
    from polydem_cli.solvers.explicit import run

    sc, text = load_scenario(SCEN / scen, [])
    out = tmp_path / "part.h5"
    run(build_system(sc, scen), out=out, scenario_text=text, quiet=True, stop_after_steps=stop)
    r = subprocess.run(
        polydem_cmd() + ["report", str(out), "--out", str(tmp_path / "rep")], capture_output=True, text=True
    )
    assert r.returncode == 0 and "Traceback" not in r.stderr, r.stderr
    assert f"note: {out}: an interrupted run (status 'running' at step {stop:,} of " in r.stderr
    assert f"polydem run --resume {out}" in r.stderr
    pngs = {p.name for p in (tmp_path / "rep").glob("*.png")}
    assert "part_frames.png" in pngs
    if stop == 3:
        assert "1 frame(s)" in r.stderr and "1 history row(s)" in r.stderr
        assert "part_history.png" not in pngs and "part_velocity.png" not in pngs
    else:
        assert {"part_history.png", "part_load.png", "part_stress_strain.png"} <= pngs


def test_report_of_a_failed_result(tmp_path):
    out = tmp_path / "u.h5"
    r = run_unstable_pile(out)
    assert r.returncode == 1, r.stderr
    r = subprocess.run(
        polydem_cmd() + ["report", str(out), "--out", str(tmp_path / "rep")], capture_output=True, text=True
    )
    assert r.returncode == 0 and "Traceback" not in r.stderr, r.stderr
    assert "the run failed (unstable at step" in r.stderr
    assert (tmp_path / "rep" / "u_frames.png").exists()
