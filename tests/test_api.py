"""The Python API (polydem_cli/api.py): a scenario changed by key paths and validated as --set is, a run in this
process with the command line's guarantees and refusals (the same messages, as exceptions of one family),
callbacks that read, stop and fail a run, a result read back as DataFrames and figures."""

import json

import h5py
import numpy as np
import pytest
from click.testing import CliRunner

import polydem_cli as pd_api
from polydem_cli.cli import main
from polydem_cli.scenario.load import read_toml

from conftest import SCEN

SMOKE = SCEN / "ch7" / "smoke_concrete_tension.toml"
#: a short piece of the smoke panel: 6,000 steps, frames every 1,000
SHORT = [("time.end_time", 2.4e-3), ("output.frame_interval", 4e-4), ("output.history_every", 100)]


def _cli_error(args):
    r = CliRunner().invoke(main, args)
    assert r.exit_code == 2, r.output
    return r.output.strip().splitlines()[-1].removeprefix("error: ")


def test_a_change_is_validated_as_set_would_be_and_a_bad_one_changes_nothing(tmp_path):
    sc = pd_api.Scenario(SMOKE)
    with pytest.raises(pd_api.ScenarioError) as e:
        sc["time.dt"] = -1.0
    assert str(e.value) == _cli_error(["check", str(SMOKE), "--set", "time.dt=-1.0"])
    assert sc["time.dt"] == 4e-7 and sc.overrides == []
    with pytest.raises(pd_api.PolydemError, match="unknown key"):
        sc.set("time.dtx", 1)
    sc["particles.0.nx"] = 6
    assert sc["particles.0.nx"] == 6 and sc.overrides == ["particles.0.nx=6"]
    with pytest.raises(KeyError):
        sc["no.such.key"]


def test_a_scenario_from_a_dict_runs_as_the_same_file_does(tmp_path):
    """The same tables, given as a dict, give the same result: frames bit for bit."""
    data, _ = read_toml(SMOKE)
    a = pd_api.Scenario(SMOKE, SHORT).run(tmp_path / "file.h5", progress=False)
    b = pd_api.Scenario.from_dict(data)
    for k, v in SHORT:
        b[k] = v
    rb = b.run(tmp_path / "dict.h5", progress=False)
    with h5py.File(a.path) as fa, h5py.File(rb.path) as fb:
        assert fa["frames/x"].shape[0] >= 6
        assert np.array_equal(fa["frames/x"][...], fb["frames/x"][...])
        assert np.array_equal(fa["frames/bond_d"][...], fb["frames/bond_d"][...])


def test_every_refusal_of_the_command_is_the_same_exception_from_python(tmp_path):
    out = tmp_path / "r.h5"
    sc = pd_api.Scenario(SMOKE, SHORT)
    sc.run(out, progress=False)
    with pytest.raises(pd_api.ResultError) as e:  # an existing result: refused, not touched
        sc.run(out, progress=False)
    said = _cli_error(["run", str(SMOKE), "-o", str(out)] + [a for k, v in SHORT for a in ("--set", f"{k}={v}")])
    assert str(e.value) == said and isinstance(e.value, pd_api.PolydemError)
    with pytest.raises(pd_api.OutputError) as e:  # an output place that cannot be written
        sc.run(tmp_path / "r.h5" / "x.h5", progress=False)
    assert "is a file, not a folder" in str(e.value) or "Not a directory" in str(e.value)
    with pytest.raises(pd_api.ScenarioError):  # a file that is not there
        pd_api.Scenario(tmp_path / "missing.toml")
    with pytest.raises(pd_api.ResultError, match="not a polydem result"):
        pd_api.Result(SMOKE)
    assert sc.run(out, resume=True, progress=False).status == "finished"  # reused as it is


def test_callbacks_read_stop_and_fail_a_run(tmp_path):
    """Every(steps=N) is called at exactly N, 2N, ...; Every(time=T) at the steps of T, 2T, ...; returning False ends
    the run after a checkpoint (resumed, it ends as an uninterrupted run: frames bit for bit); an exception stops it
    with a checkpoint and comes back as CallbackError with its message."""
    seen, times = [], []
    sc = pd_api.Scenario(SMOKE, SHORT)
    whole = sc.run(
        tmp_path / "whole.h5",
        progress=False,
        callbacks=[
            pd_api.Every(lambda st: seen.append((st.work, st.history["step"], st.positions.shape)), steps=1500),
            pd_api.Every(lambda st: times.append(round(st.time, 9)), time=1e-3),
        ],
    )
    assert [w for w, _, _ in seen] == [1500, 3000, 4500, 6000]
    assert all(w == s for w, s, _ in seen) and seen[0][2] == (64, 3)
    assert times == [1e-3, 2e-3]
    part = sc.run(tmp_path / "part.h5", progress=False, callbacks=[pd_api.Every(lambda st: st.work < 3000, steps=1000)])
    assert part.status == "incomplete" and part.summary["steps"] == 3000
    resumed = sc.run(tmp_path / "part.h5", resume=True, progress=False)
    assert resumed.status == "finished"
    with h5py.File(whole.path) as fa, h5py.File(resumed.path) as fb:
        assert np.array_equal(fa["frames/x"][...], fb["frames/x"][...])

    def bad(state):
        raise ValueError("the yield point was crossed")

    with pytest.raises(pd_api.CallbackError) as e:
        sc.run(tmp_path / "bad.h5", progress=False, callbacks=[pd_api.Every(bad, steps=2000)])
    assert "the yield point was crossed" in str(e.value) and "step 2,000" in str(e.value)
    assert isinstance(e.value.__cause__, ValueError)
    assert pd_api.Result(tmp_path / "bad.h5").status == "incomplete"
    with pytest.raises(pd_api.PolydemError):
        pd_api.Every(bad, steps=0)


def test_a_result_as_dataframes_and_figures(tmp_path):
    out = tmp_path / "r.h5"
    res = pd_api.Scenario(SMOKE, SHORT).run(out, progress=False)
    df = res.history
    with h5py.File(out) as f:
        table = f["history/table"][...]
        cols = json.loads(f["history/table"].attrs["columns"])
        units = json.loads(f["history/table"].attrs["units"])
    assert list(df.columns) == cols and np.array_equal(df.to_numpy(), table)
    assert df.attrs["units"]["sigma22"] == units[cols.index("sigma22")] == "g/(cm s^2)"
    assert len(res.particles) == 64 and {"mass", "x1", "x2", "group"} <= set(res.particles.columns)
    b = res.bonds
    assert len(b) == res.summary["bonds"]["count"] and (b["damage"] >= 0).all()
    assert res.frames["x"].shape[1:] == (64, 3)
    before = sorted(p.name for p in tmp_path.iterdir())
    figs = res.figures()
    assert {"history", "stress_strain"} <= set(figs) and sorted(p.name for p in tmp_path.iterdir()) == before
    assert all(type(f).__name__ == "Figure" and f.axes for f in figs.values())
    written = res.report(tmp_path / "rep")
    assert written and all(p.exists() for p in written)


def test_the_reference_page_is_generated_from_the_docstrings():
    from polydem_cli.api import reference

    from conftest import ROOT

    assert (ROOT / "docs" / "api.md").read_text() == reference()
    text = reference()
    for name in pd_api.__all__:
        if name != "__version__":
            assert f"## `{name}" in text, name


def test_the_workflows_from_python_give_dataframes(tmp_path):
    """The lab (its smoke tension alone), a calibration of E and nu (static solves only) and a sweep of two values,
    each as a DataFrame; bad choices raise before anything is written."""
    from conftest import ROOT

    df = pd_api.lab(tmp_path / "lab", smoke=True, tests=["tension"], scenarios=ROOT)
    ft = df.loc[df["quantity"] == "f_t [MPa]", "value"].iloc[0]
    assert 2.0 < ft < 5.0 and df.attrs["tests"]["tension"]["strength"] == pytest.approx(ft)
    with pytest.raises(pd_api.PolydemError, match="unknown test"):
        pd_api.lab(tmp_path / "lab2", tests=["shear"])
    assert not (tmp_path / "lab2").exists()
    cal = pd_api.calibrate(SMOKE, {"E": "30GPa", "nu": 0.2}, out=tmp_path / "c.toml", log=lambda *a: None)
    assert cal.loc[0, "E"] == pytest.approx(30e10, rel=0.01) and cal.loc[0, "nu"] == pytest.approx(0.2, abs=0.005)
    assert (tmp_path / "c.toml").exists()
    with pytest.raises(pd_api.PolydemError):
        pd_api.calibrate(SMOKE, {"E": "thirty"}, out=tmp_path / "d.toml")
    sw = pd_api.sweep(SMOKE, {"time.end_time": [2e-3, 3e-3]}, tmp_path / "sweep", workers=1)
    assert len(sw) == 2 and set(sw["time.end_time"].astype(float)) == {2e-3, 3e-3}
    with pytest.raises(pd_api.ScenarioError):
        pd_api.sweep(SMOKE, {"time.dt": [4e-7, -1.0]}, tmp_path / "sweep2")
    assert not (tmp_path / "sweep2").exists()


def test_a_run_on_ranks_from_python(tmp_path):
    """ranks=2 runs polydem run --ranks in a process of its own: the result equals the one-process run's frames; what
    this process can judge is refused here with the command's exceptions, the rest by the command's message."""
    sc = pd_api.Scenario(SMOKE, SHORT)
    one = sc.run(tmp_path / "one.h5", progress=False)
    two = sc.run(tmp_path / "two.h5", ranks=2, progress=False)
    with h5py.File(one.path) as fa, h5py.File(two.path) as fb:
        assert np.array_equal(fa["frames/x"][...], fb["frames/x"][...])
    assert two.summary["ranks"] == 2
    with pytest.raises(pd_api.ResultError, match="exists"):
        sc.run(tmp_path / "two.h5", ranks=2, progress=False)
    with pytest.raises(pd_api.PolydemError, match="ranks = 0"):
        sc.run(tmp_path / "three.h5", ranks=0, progress=False)
    nuts = pd_api.Scenario(SCEN / "ch6" / "nuts_small.toml", [("time.end_time", 1e-3)])
    with pytest.raises(pd_api.PolydemError, match="does not run on several ranks"):
        nuts.run(tmp_path / "nuts.h5", ranks=2, progress=False)


def test_the_lab_refuses_the_pressures_the_command_refuses(tmp_path):
    for bad in ([-1.0, 2.0], [0.0], [1.0, 1.0]):
        with pytest.raises(pd_api.PolydemError) as e:
            pd_api.lab(tmp_path / "lab", smoke=True, pressures=bad)
        said = _cli_error(
            ["study", "lab", "--smoke", "--out", str(tmp_path / "c"), "--pressures", ",".join(map(str, bad))]
        )
        assert str(e.value) in said, (str(e.value), said)
    assert not (tmp_path / "lab").exists() and not (tmp_path / "c").exists()
