"""``polydem study lh`` on a small real chain (two preparations of 150 disks, a loading run at each pressure):
Table 1.1 and Figs. 1.6-1.8 are drawn, their curves are the runs' wall histories, and the table's cohesion and
friction angle are the common tangent of the two peak circles."""

from __future__ import annotations

import csv
import json
import math

import numpy as np
import pytest

from polydem_cli.io.hdf5 import read_history
from polydem_cli.scenario.build import build_system
from polydem_cli.scenario.load import load_scenario
from polydem_cli.solvers.explicit import run

from conftest import DYN_PER_UNIT, SCEN

LH = SCEN / "lh"


def _small(text: str) -> str:
    """The shipped box reduced: 150 disks in 4 cm x 5 cm, short horizons."""
    for a, b in (
        ("count = 1950", "count = 150"),
        ("box = [0.0, 0.0, 11.0, 15.0]", "box = [0.0, 0.0, 4.0, 5.0]"),
        ("extent = [0.0, 15.0]", "extent = [0.0, 5.0]"),
        ("extent = [0.0, 11.0]", "extent = [0.0, 4.0]"),
        ("position = 11.0", "position = 4.0"),
        ("position = 15.0", "position = 5.0"),
        ("end_time = 0.12", "end_time = 0.03"),
    ):
        assert a in text, a
        text = text.replace(a, b)
    return text


def _run(path):
    sc, text = load_scenario(path)
    run(
        build_system(sc, str(path)),
        out=path.with_suffix(".h5"),
        scenario_file=str(path),
        scenario_text=text,
        quiet=True,
    )


@pytest.fixture(scope="module")
def runs(tmp_path_factory):
    d = tmp_path_factory.mktemp("lh")
    for p in ("100", "500"):
        prep = d / f"prepare_p{p}.toml"
        prep.write_text(_small((LH / f"prepare_p{p}.toml").read_text()))
        _run(prep)
        load = d / f"load_p{p}_kc1.toml"
        text = (LH / f"load_p{p}_kc1.toml").read_text()
        text = text.replace(f'extends = "prepare_p{p}.toml"', f'extends = "{prep.name}"')
        text = text.replace(f'file = "../../outputs/lh/prepare_p{p}.h5"', f'file = "prepare_p{p}.h5"')
        # a faster, smaller push (the cosine law LH 1.1 to D = -0.1 cm at t = 1/(2f) = 0.01 s)
        text = text.replace("end_time = 0.05", "end_time = 0.01").replace(
            "displacement = -0.42, frequency = 10.0", "displacement = -0.1, frequency = 50.0"
        )
        load.write_text(text)
        _run(load)
    return d


def test_lh_study_draws_table_and_figures_from_the_runs(runs, tmp_path):
    import shutil

    from polydem_cli.reproductions.lh import PA, collate

    shutil.copy(runs / "load_p500_kc1.h5", runs / "load_p500_kc2.h5")  # Fig. 1.3 draws the k_c = 2 k_2 run
    res = collate(runs, tmp_path)
    for png in ("fig_lh_1_3_networks", "fig_lh_1_6_p500", "fig_lh_1_7_p100", "fig_lh_1_8_mohr"):
        assert (tmp_path / f"{png}.png").stat().st_size > 20_000, png
    # Figs. 1.6/1.7: the volumetric strain curve is the run's wall history, recomputed here from the columns
    for p, png in (("500", "fig_lh_1_6_p500"), ("100", "fig_lh_1_7_p100")):
        cols, tab = read_history(runs / f"load_p{p}_kc1.h5")
        h = {c: tab[:, j] for j, c in enumerate(cols)}
        z = h["servo_length:right"]
        x = h["wall_face:right"] - h["wall_face:left"]
        with open(tmp_path / f"{png}_plotted.csv") as fh:
            rows = [r for r in csv.DictReader(fh) if r["panel"] == "0" and r["curve"] == "0"]  # k_c = k_2 first
        xy = np.array([[float(r["x"]), float(r["y"])] for r in rows])
        assert np.allclose(xy[:, 0], 1.0 - z / z[0])
        assert np.allclose(xy[:, 1], x * z / (x[0] * z[0]) - 1.0)
        # the vertical stress panel: sigma_zz = F_top / (h x) in N/m^2
        with open(tmp_path / f"{png}_plotted.csv") as fh:
            rows = [r for r in csv.DictReader(fh) if r["panel"] == "1" and r["curve"] == "0"]
        s = np.array([float(r["y"]) for r in rows])
        assert np.allclose(s, h["wall_force:top"] / (100.0 * x) / PA)
    # Table 1.1: cohesion and friction angle of the common tangent to the two circles at the peaks
    (row,) = [r for r in res["table1_1"] if r["kc_over_k2"] == 1.0]
    s1, s2 = row["peak_100"], row["peak_500"]
    r1, r2, c1, c2 = (s1 - 100) / 2, (s2 - 500) / 2, (s1 + 100) / 2, (s2 + 500) / 2
    sin_phi = (r2 - r1) / (c2 - c1)
    phi = math.degrees(math.asin(sin_phi))
    c = r1 / math.cos(math.radians(phi)) - c1 * math.tan(math.radians(phi))
    assert row["phi_deg"] == pytest.approx(phi, rel=1e-9) and row["c"] == pytest.approx(c, rel=1e-9, abs=1e-9)
    assert json.loads((tmp_path / "results.json").read_text())["table1_1"] == res["table1_1"]
    # sigma_xx - p_x is the side wall's damping stress gamma_x xdot / (h z) (LH 1.2), up to the light wall's inertia
    for name, r in res["runs"].items():
        assert r["sxx_minus_p_vs_wall_damping_correlation"] > 0.95, (name, r)
    assert [n["contacts"] for n in res["networks"]] and all(n["contacts"] > 0 for n in res["networks"])


def test_report_of_the_box_draws_the_wall_reactions_it_carries(runs, tmp_path):
    """polydem report on a biaxial box: the load panel draws f2 of the top and bottom walls and f1 of the fixed
    left wall (its confining reaction; f2 there is zero), and leaves out the servo-controlled right wall (its x1
    is free: its columns are its net force, not a reaction) — each curve the history column in the axis's force
    unit."""
    from polydem_cli.report.basic import plot_history

    res = runs / "load_p500_kc1.h5"
    plot_history(res, tmp_path / "h.png")
    cols, tab = read_history(res)
    h = {c: tab[:, j] for j, c in enumerate(cols)}
    with open(tmp_path / "h_plotted.csv") as fh:
        rows = [r for r in csv.DictReader(fh) if r["title"].startswith("load–displacement")]  # "… of <set>"
    curves = {}
    for r in rows:
        curves.setdefault(r["label"], []).append((float(r["x"]), float(r["y"])))
    assert set(curves) == {"$f_2$ on top", "$f_2$ on bottom", "$f_1$ on left"}
    assert rows[0]["y_label"].startswith("reaction on the set [")
    dyn = DYN_PER_UNIT[rows[0]["y_label"].split("[")[-1].rstrip("]")]
    for label, col in (("$f_2$ on top", "f2:top"), ("$f_2$ on bottom", "f2:bottom"), ("$f_1$ on left", "f1:left")):
        xy = np.array(curves[label])
        assert np.allclose(xy[:, 0], h["u2:top"]) and np.allclose(xy[:, 1] * dyn, h[col])
    assert np.max(np.abs(h["f1:left"])) > 10 * np.max(np.abs(h["f1:right"]))  # the servo wall's net force is small
