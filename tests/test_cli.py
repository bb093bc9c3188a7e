"""Command-line interface: run, report, study, schema, progress."""
import json
import shutil
import subprocess

from click.testing import CliRunner

from conftest import ROOT, SCEN, polydem_cmd
from polydem_cli.cli import main
from polydem_cli.scenario.schema import SCHEMA
from polydem_cli.scenario.spec import markdown


def test_version_and_help():
    r = CliRunner().invoke(main, ["--version"])
    assert r.exit_code == 0 and "polydem" in r.output
    r = CliRunner().invoke(main, ["-h"])
    for cmd in ("run", "check", "report", "study", "bench", "schema"):
        assert cmd in r.output


def test_run_default_output_path_progress_and_report(tmp_path):
    scen = tmp_path / "pile.toml"
    shutil.copy(SCEN / "demo_hex_pile.toml", scen)
    r = subprocess.run(polydem_cmd() + ["run", "pile.toml", "--set", "time.end_displacement=0.02"],
                       capture_output=True, text=True, cwd=tmp_path)
    assert r.returncode == 0, r.stderr
    out = tmp_path / "outputs" / "pile.h5"
    assert out.exists() and (tmp_path / "outputs" / "pile.summary.json").exists()
    assert "steps/s" in r.stderr and "ETA" in r.stderr and "100.0%" in r.stderr  # progress
    assert "wrote outputs/pile.h5" in r.stdout
    r = subprocess.run(polydem_cmd() + ["run", "pile.toml", "-q", "--set", "time.end_displacement=0.02",
                                        "-o", "q.h5"], capture_output=True, text=True, cwd=tmp_path)
    assert r.returncode == 0 and r.stderr == "" and r.stdout == ""
    r = CliRunner().invoke(main, ["report", str(out), "--out", str(tmp_path / "rep"), "--times", "0,0.01"])
    assert r.exit_code == 0, r.output
    pngs = sorted(p.name for p in (tmp_path / "rep").glob("*.png"))
    assert pngs == ["pile_frames.png", "pile_history.png", "pile_velocity.png"]
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
