"""polydem study timestep end to end on a smoke scenario."""

import csv
import json

from click.testing import CliRunner

from polydem_cli.cli import main

from conftest import SCEN

SMALL = SCEN / "ch5" / "small_tension.toml"


def _cli(*args):
    return CliRunner().invoke(main, [str(a) for a in args])


def _timestep(out, dts, integrators, *extra, end="1.2e-4"):
    """polydem study timestep on the small ch.5 specimen to u2 = ``end`` (cm)."""
    return _cli(
        "study",
        "timestep",
        SMALL,
        "--dt",
        dts,
        "--integrator",
        integrators,
        "--set",
        f"time.end_displacement={end}",
        "--out",
        out,
        *extra,
    )


def test_timestep_study_smoke(tmp_path):
    r = _timestep(tmp_path, "0.01,0.02,0.04", "gear5,verlet")
    assert r.exit_code == 0, r.output
    res = json.loads((tmp_path / "timestep.json").read_text())
    assert (res["reference"]["integrator"], res["reference"]["dt"]) == ("gear5", 0.01)
    runs = {(x["integrator"], x["dt"]): x for x in res["runs"]}
    assert len(runs) == 6 and all(x["stable"] for x in runs.values())
    # physics, not bookkeeping: central differences are second order, so the final-position error of the
    # verlet runs against the Gear reference falls as dt^2 (measured slope 1.93)
    assert 1.6 < res["convergence_order"]["verlet"]["final_position"] < 2.4
    assert runs[("verlet", 0.01)]["errors"]["final_position"] > 0  # a different integrator: a true difference
    e = [runs[("gear5", dt)]["errors"]["load_curve_L2"] for dt in (0.01, 0.02, 0.04)]
    assert e[0] < e[1] < e[2] < 1e-2  # error grows with dt and stays small
    assert all(x["particle_steps_per_s"] > 0 and x["wall_s"] > 0 for x in runs.values())
    assert res["largest_stable_dt"] == {"gear5": 0.04, "verlet": 0.04}
    rows = list(csv.DictReader(open(tmp_path / "timestep.csv")))
    assert len(rows) == 6 and "load_curve_L2" in rows[0]
    assert (tmp_path / "timestep.png").stat().st_size > 5000

    # a second study over the same runs reuses them, with an explicit reference of a finer step; a result of
    # another scenario at a run's path is never deleted
    finer = tmp_path / "finer.h5"
    r = _cli("run", SMALL, "--set", "time.end_displacement=1.2e-4", "--set", "time.dt=0.005", "-o", finer, "-q")
    assert r.exit_code == 0, r.output
    r = _timestep(tmp_path, "0.02,0.04", "gear5", "--reference", finer)
    assert r.exit_code == 0, r.output
    res2 = json.loads((tmp_path / "timestep.json").read_text())
    assert res2["reference"]["dt"] == 0.005 and res2["reference"]["note"] is None
    runs2 = {x["dt"]: x for x in res2["runs"]}
    assert runs2[0.02]["wall_s"] == runs[("gear5", 0.02)]["wall_s"]  # reused, not run again
    assert 0 < runs2[0.02]["errors"]["load_curve_L2"] < runs2[0.04]["errors"]["load_curve_L2"]
    foreign = tmp_path / "runs" / "gear5_dt0.02.h5"
    before = foreign.stat().st_mtime_ns
    r = _timestep(tmp_path, "0.02", "gear5", end="1.5e-4")
    assert r.exit_code == 2 and "different scenario" in r.output and "time.end_displacement" in r.output
    assert foreign.stat().st_mtime_ns == before


def test_a_fit_that_is_no_convergence_order_is_said_and_the_figure_reads_plainly(tmp_path, monkeypatch):
    """Negative Verlet 'orders' were printed without a word; the reference point (error 0) was silently missing
    from the log axes; minor ticks read '3×10⁰'."""
    from polydem_cli.workflows import timestep as T

    assert T.order_meaningless([1e-4, 4e-4, 1.6e-3], 2.0) is None  # second order, monotone
    assert "does not fall" in T.order_meaningless([3e-3, 2e-3, 1e-3], -0.5)
    assert "not monotone" in T.order_meaningless([1e-4, 5e-5, 2e-3], 1.2)
    runs = [
        {"integrator": i, "dt": dt, "stable": True, "wall_s": w, "result": f"{i}{dt}", "errors": e}
        for i, dt, w, e in [
            ("gear5", 0.01, 8.0, {"load_curve_L2": 0.0, "final_position": 0.0}),
            ("gear5", 0.02, 4.0, {"load_curve_L2": 2e-4, "final_position": 3e-3}),
            ("gear5", 0.04, 2.0, {"load_curve_L2": 8e-4, "final_position": 1.2e-2}),
            ("verlet", 0.02, 3.0, {"load_curve_L2": 3e-3, "final_position": 2e-2}),
            ("verlet", 0.04, 1.5, {"load_curve_L2": 1e-3, "final_position": 1e-2}),
        ]
    ]
    res = {
        "scenario": "s.toml",
        "reference": {"integrator": "gear5", "dt": 0.01, "result": "gear50.01"},
        "runs": runs,
        "convergence_order": {
            "gear5": {"load_curve_L2": 2.0, "final_position": 2.0},
            "verlet": {"load_curve_L2": -1.6},
        },
        "convergence_order_meaningless": {"verlet": {"load_curve_L2": "the error does not fall as dt falls"}},
    }
    figs = []
    monkeypatch.setattr(T, "_save", lambda fig, png, **kw: figs.append(fig))
    T._plot(res, tmp_path / "t.png")
    (fig,) = figs
    fig.canvas.draw()
    for ax in fig.axes:
        labels = [t.get_text() for t in ax.get_xticklabels() + ax.get_yticklabels() + ax.get_xminorticklabels()]
        assert not any("times" in t or "×" in t or "^" in t for t in labels), labels
        legend = [t.get_text() for t in ax.get_legend().get_texts()]
        assert any(t.startswith("reference (error 0)") for t in legend)
    legend = [t.get_text() for t in fig.axes[0].get_legend().get_texts()]
    assert "verlet (no convergence order)" in legend and "gear5 (order 2.00)" in legend
