"""The validation suite (polydem study validate, reproductions/validate.py): its formulas against closed forms and
the published constants, its refusals of bad input before anything is written, and the smoke study end to end
(every experiment's table rows, figures and sources)."""

import json

import numpy as np
import pytest
from click.testing import CliRunner

from polydem_cli.analysis import validation as V
from polydem_cli.cli import main
from polydem_cli.reproductions.sources import source

from conftest import ROOT


def test_hordijk_curve_and_its_area():
    """sigma/f_t = 1 at w = 0 and 0 at w_c; the area under it is 1/5.136 (the constant of w_c = 5.136 G_F/f_t,
    integrated here by the trapezoidal rule on a fine grid, independently of the 0.1947 the source quotes)."""
    hor = source("hordijk1991")
    x = np.linspace(0.0, 1.0, 200001)
    y = V.hordijk(x, hor["c1"], hor["c2"])
    assert y[0] == 1.0 and abs(y[-1]) < 1e-12 and np.all(np.diff(y) <= 1e-12)
    area = np.trapezoid(y, x)
    assert 1.0 / area == pytest.approx(hor["wc_times_ft_over_GF"], abs=5e-4)
    assert V.hordijk_area(hor["c1"], hor["c2"]) == pytest.approx(area, rel=1e-6)


def test_kupfer_envelope_against_the_published_points():
    """The Kupfer-Gerstle form gives 1.1625 f_c in equal biaxial compression (the paper's abstract: 16 % above the
    uniaxial), 1.256 at alpha = 0.5 (the digitized curve: 1.237 at 0.52), f_c at alpha = 0; every point lies on its
    ray sigma_2 = alpha sigma_1, the tension-governed branch (alpha < -0.17) at sigma_2 = f_t."""
    kup = source("kupfer1969")
    s1, s2 = V.kupfer_envelope([1.0, 0.52, 0.0, -0.1, -0.5], 0.1)
    assert -s1[0] == pytest.approx(kup["equal_biaxial_over_fc"], abs=0.005) and s2[0] == s1[0]
    d = kup["digitized"]
    assert -s1[1] == pytest.approx(d["peaks_MPa"][0] / d["uniaxial_fc_MPa"], rel=0.02)
    assert s1[2] == -1.0 and s2[2] == 0.0
    assert 0.65 < -s1[3] < 1.0 and s2[3] > 0.0
    assert s2[4] == pytest.approx(0.1) and s1[4] == pytest.approx(-0.2)  # f_t / alpha
    a = np.linspace(-1.0, 1.0, 41)
    s1, s2 = V.kupfer_envelope(a, 0.1)
    assert np.allclose(s2, a * s1) and np.all(s1 < 0)
    with pytest.raises(ValueError):
        V.kupfer_envelope([1.2])


def test_size_effect_fit_recovers_the_law():
    """Nominal strengths made by the law itself (B f_t = 6 MPa, D0 = 12 cm) give back its parameters, the fit's
    residual 0 and, between sizes far beyond D0, the LEFM slope -1/2."""
    D = np.array([5.0, 10.0, 20.0, 40.0])
    f = V.size_effect_fit(D, V.size_effect_law(D, 6.0, 12.0))
    assert f["Bft"] == pytest.approx(6.0, rel=1e-6) and f["D0"] == pytest.approx(12.0, rel=1e-5)
    assert f["residual"] < 1e-8
    big = np.array([1e4, 2e4])
    assert V.size_effect_fit(big, V.size_effect_law(big, 6.0, 12.0))["slope_largest"] == pytest.approx(-0.5, abs=1e-3)
    with pytest.raises(ValueError):
        V.size_effect_fit([10.0, 10.0], [3.0, 3.0])


def test_softening_curve_of_a_linear_law():
    """A bar of length L, modulus E, loaded to f_t and softening linearly to zero at w1: the crack opening is the
    elongation less sigma L / E, its area f_t w1 / 2."""
    E, L, ft, w1 = 3e11, 10.0, 3e7, 2e-3
    up = np.linspace(0.0, ft * L / E, 50)
    w = np.linspace(0.0, w1, 200)
    s = np.concatenate([up * E / L, ft * (1 - w / w1)])
    u = np.concatenate([up, ft * (1 - w / w1) * L / E + w])  # after the peak: the elastic part and the crack
    sc = V.softening_curve(u, s, E, L)
    assert sc["f_t"] == ft and sc["G_F"] == pytest.approx(ft * w1 / 2, rel=1e-3)
    assert sc["w"][-1] == pytest.approx(w1, rel=1e-9)


@pytest.mark.parametrize(
    "args, key",
    [
        (["--test", "kupfer"], "--test"),
        (["--biaxial", "c0,c1.5"], "--biaxial"),
        (["--biaxial", "c0.5,q0.2"], "--biaxial"),
        (["--sizes", "10"], "--sizes"),
        (["--sizes", "10,10"], "--sizes"),
        (["--sizes", "5,7.5"], "--sizes"),
        (["--ranks", "0"], "--ranks"),
    ],
)
def test_bad_input_is_refused_before_anything_is_written(tmp_path, args, key):
    out = tmp_path / "study"
    r = CliRunner().invoke(main, ["study", "validate", "--smoke", "--scenarios", str(ROOT), "--out", str(out), *args])
    assert r.exit_code == 2, r.output
    assert key in r.output and "Traceback" not in r.output
    assert not out.exists()


def test_the_smoke_study_writes_its_table_and_figures_with_their_sources(tmp_path):
    """All four experiments at smoke size (about half a minute): a row per number with its source, one figure per
    experiment, results.json; a finished study run again reuses every run."""
    out = tmp_path / "study"
    args = ["study", "validate", "--smoke", "--scenarios", str(ROOT), "--out", str(out), "-q"]
    r = CliRunner().invoke(main, args)
    assert r.exit_code == 0, r.output
    for name in ("biaxial", "size_effect", "softening", "petersson"):
        assert (out / f"validate_{name}.png").exists(), name
    table = (out / "validation_table.md").read_text().splitlines()
    assert all(line.count("|") - line.count("\\|") == 7 for line in table), table
    res = json.loads((out / "results.json").read_text())
    rows = res["table"]
    assert {r[0] for r in rows} == {"softening", "biaxial", "size_effect", "petersson"}
    assert all(r[5] for r in rows)  # every row names where its number comes from
    b = res["results"]["biaxial"]
    assert b["points"]["biaxial_c0"]["s1"] == pytest.approx(-1.0)  # f_c is the uniaxial run's own peak
    kinds = {(p["kind"], p["alpha"]) for p in b["points"].values()}
    assert ("t", 1.0) in kinds and ("c", -0.1) in kinds
    for p in b["points"].values():  # the stress ratio the pressure held at the peak
        assert p["alpha_reached"] == pytest.approx(p["alpha"], abs=0.12)
    s = res["results"]["size_effect"]
    assert sorted(n["D_cm"] for n in s["beams"].values()) == [5.0, 10.0]
    t = res["results"]["tension"]
    assert 0.0 <= t["hordijk_rms"] < 0.5 and t["G_F_N_per_m"] > 0
    # run again: every run reused, the same table
    r = CliRunner().invoke(main, args)
    assert r.exit_code == 0, r.output
    assert json.loads((out / "results.json").read_text())["table"] == rows
