"""polydem study timestep end to end on a smoke scenario."""
import csv
import json

from click.testing import CliRunner

from conftest import SCEN
from polydem_cli.cli import main


def test_timestep_study_smoke(tmp_path):
    r = CliRunner().invoke(main, ["study", "timestep", str(SCEN / "ch5" / "small_tension.toml"), "--dt",
                                  "0.01,0.02,0.04", "--integrator", "gear5,verlet", "--set",
                                  "time.end_displacement=1.2e-4", "--out", str(tmp_path)])
    assert r.exit_code == 0, r.output
    res = json.loads((tmp_path / "timestep.json").read_text())
    assert res["reference"] == {"integrator": "gear5", "dt": 0.01}
    runs = {(x["integrator"], x["dt"]): x for x in res["runs"]}
    assert len(runs) == 6 and all(x["stable"] for x in runs.values())
    assert runs[("gear5", 0.01)]["errors"]["peak_load"] == 0.0
    e = [runs[("gear5", dt)]["errors"]["load_curve_L2"] for dt in (0.01, 0.02, 0.04)]
    assert e[0] < e[1] < e[2] < 1e-2  # error grows with dt and stays small
    assert all(x["particle_steps_per_s"] > 0 and x["wall_s"] > 0 for x in runs.values())
    assert res["largest_stable_dt"] == {"gear5": 0.04, "verlet": 0.04}
    rows = list(csv.DictReader(open(tmp_path / "timestep.csv")))
    assert len(rows) == 6 and "load_curve_L2" in rows[0]
    assert (tmp_path / "timestep.png").stat().st_size > 5000
