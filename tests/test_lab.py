"""Laboratory specimens and the standard numbers of their tests (issue 38, first part): Voronoi specimens cut to
a disc and to a notched beam, the Brazilian splitting formula, RILEM's fracture energy and fib MC2010's estimate."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from polydem_cli.geometry.polygon import (
    GeometryError,
    check_convex_polygon,
    circle_polygon,
    clip_convex,
    rectangle,
    signed_area,
)
from polydem_cli.geometry.specimens import voronoi_cut


def test_clip_convex_cuts_a_square_by_a_triangle_and_a_disc_polygon():
    sq = rectangle((0.0, 0.0), (2.0, 2.0))
    tri = np.array([[-2.0, -2.0], [2.0, -2.0], [-2.0, 2.0]])  # below the line x + y = 0
    part = clip_convex(sq, tri)
    assert signed_area(part) == pytest.approx(2.0, rel=1e-12)  # half the square
    check_convex_polygon(part)
    assert len(clip_convex(sq, rectangle((5.0, 5.0), (1.0, 1.0)))) == 0  # disjoint
    assert signed_area(clip_convex(sq, rectangle((0.0, 0.0), (10.0, 10.0)))) == pytest.approx(4.0, rel=1e-12)
    c = circle_polygon((0.0, 0.0), 1.0, 1e-4)
    r = np.hypot(*c.T)
    mid = np.hypot(*(0.5 * (c + np.roll(c, -1, axis=0))).T)
    assert np.allclose(r, 1.0) and 1.0 - mid.min() <= 1e-4  # sagitta within the tolerance
    assert signed_area(c) == pytest.approx(math.pi, rel=2e-4)


def _inside(v, clip, tol=1e-9):
    """Every vertex of v inside the convex polygon clip (to tol)."""
    for k in range(len(clip)):
        a, b = clip[k], clip[(k + 1) % len(clip)]
        e = b - a
        if np.any(e[0] * (v[:, 1] - a[1]) - e[1] * (v[:, 0] - a[0]) < -tol * np.hypot(*e)):
            return False
    return True


@pytest.mark.parametrize("cut", ["clip", "drop"])
def test_a_disc_specimen_covers_the_disc_with_convex_particles_inside_it(cut):
    """Clip: the particles' area is the disc's to 1 % (the issue's acceptance), every one convex and inside the
    circle; drop: inside too, less area (the cells crossing the rim are gone); touching neighbours share edges."""
    D, h = 20.0, 1.0
    s = voronoi_cut(20, 20, h, 0.999, seed=3, shape="disc", cut=cut)
    area = sum(signed_area(v) for v in s.vertices)
    exact = math.pi * (D / 2) ** 2
    assert s.info["domain_area"] == pytest.approx(exact)
    if cut == "clip":
        assert abs(area / exact - 1.0) < 0.01
    else:
        assert 0.8 * exact < area < exact
    for v in s.vertices:
        check_convex_polygon(v)
        assert np.all(np.hypot(v[:, 0] - D / 2, v[:, 1] - D / 2) <= D / 2 * (1 + 1e-9))
    # the glue: about three shared edges per particle, as in a rectangle; none longer than a cell could be
    assert 1.2 * len(s) < len(s.shared_pairs) < 3.1 * len(s)
    assert np.all(s.shared_lengths > 0) and s.shared_lengths.max() < 3 * h
    # top/bottom: a cap of particles at the highest/lowest points (where the platens of the test touch)
    ymax = max(v[:, 1].max() for v in s.vertices)
    assert all(s.vertices[i][:, 1].max() >= ymax - h / 2 for i in s.subsets["top"]) and len(s.subsets["top"]) >= 1


def test_a_notched_beam_specimen_has_its_notch_and_convex_particles_outside_it():
    """Clip: the particles' area is the beam's less the notch's to 1 %, none reaches into the notch; the cells the
    notch cut are split into convex parts glued to each other and their neighbours; drop keeps whole cells only."""
    L, H, a0, w = 40.0, 10.0, 3.0, 0.6
    s = voronoi_cut(40, 10, 1.0, 0.999, seed=5, shape="notched_beam", notch_depth=a0, notch_width=w)
    exact = L * H - a0 * w
    area = sum(signed_area(v) for v in s.vertices)
    assert abs(area / exact - 1.0) < 0.01 and s.info["domain_area"] == pytest.approx(exact)
    notch = rectangle((L / 2, a0 / 2), (w, a0))
    beam = rectangle((L / 2, H / 2), (L, H))
    for v in s.vertices:
        check_convex_polygon(v)
        assert _inside(v, beam)
        part = clip_convex(v, notch)
        assert len(part) == 0 or signed_area(part) < 1e-9  # at most touching the notch's faces
    base = voronoi_cut(40, 10, 1.0, 0.999, seed=5)  # the same tessellation uncut
    assert len(s) > len(base) - 4  # only the few cells in the notch's way changed
    d = voronoi_cut(40, 10, 1.0, 0.999, seed=5, shape="notched_beam", notch_depth=a0, notch_width=w, cut="drop")
    assert len(d) < len(base) and all(
        any(np.array_equal(v, b) for b in base.vertices) for v in d.vertices
    )  # whole cells


def test_impossible_lab_specimens_are_refused_with_the_reason():
    with pytest.raises(GeometryError, match="notch depth"):
        voronoi_cut(20, 5, shape="notched_beam", notch_depth=6.0, notch_width=0.5)  # deeper than the beam
    with pytest.raises(GeometryError, match="notch width"):
        voronoi_cut(20, 5, shape="notched_beam", notch_depth=2.0, notch_width=0.0)
    with pytest.raises(GeometryError, match="smaller than its cells"):
        voronoi_cut(1, 1, shape="disc")
    with pytest.raises(GeometryError, match="square box"):
        voronoi_cut(10, 8, shape="disc")
    with pytest.raises(GeometryError, match="unknown shape"):
        voronoi_cut(10, 10, shape="cylinder")


def test_splitting_strength_fracture_energy_and_the_fib_estimate():
    from polydem_cli.analysis.lab import (
        N_PER_M,
        fib_fracture_energy,
        fracture_energy,
        splitting_strength,
        work_of_fracture,
    )
    from polydem_cli.analysis.macro import MPA

    # a 150 mm cylinder of 300 mm length splitting at 200 kN: 2 F / (pi D T) = 2.83 MPa (EN 12390-6's example size)
    F = 200e3 * 1e5  # dyn
    assert splitting_strength(F, 15.0, 30.0) / MPA == pytest.approx(2 * 200e3 / (math.pi * 150 * 300), rel=1e-12)
    # a triangle-and-tail curve: rise to 1 at 0.1, linear fall to 0 at 1.1 -> work 0.05 + 0.5 = 0.55
    d = np.array([0.0, 0.1, 0.6, 1.1])
    f = np.array([0.0, 1.0, 0.5, 0.0])
    assert work_of_fracture(f, d) == pytest.approx(0.55, rel=1e-12)
    assert fracture_energy(f, d, 2.0, 0.5) == pytest.approx(0.55, rel=1e-12)
    # fib MC2010: f_cm = 38 MPa (C30) -> 73 * 38^0.18 = 140.5 N/m
    assert fib_fracture_energy(38 * MPA) / N_PER_M == pytest.approx(73 * 38**0.18, rel=1e-12)
    assert 140.0 < fib_fracture_energy(38 * MPA) / N_PER_M < 141.0
    with pytest.raises(ValueError):
        splitting_strength(1.0, 0.0, 1.0)
    with pytest.raises(ValueError):
        fib_fracture_energy(-30 * MPA)


@pytest.mark.parametrize(
    "scenario,old,new,key,reason",
    [
        (
            "smoke_three_point_bending",
            "notch_depth = 1.2 ",
            "notch_depth = 4.5 ",
            "particles[0].notch_depth = 4.5",
            "deeper than the beam",
        ),
        ("smoke_three_point_bending", "notch_depth = 1.2 ", "# no notch_depth ", "particles[0].notch_depth", "needs"),
        ("smoke_brazilian", "nx = 8\nny = 8", "nx = 1\nny = 1", "particles[0].nx = 1", "smaller than a cell"),
        ("smoke_brazilian", 'cut = "clip"', 'cut = "clip"\nnotch_depth = 1.0', "particles[0].notch_depth", "no notch"),
        (
            "smoke_brazilian",
            'shape = "disc"',
            'shape = "cylinder"',
            "particles[0].shape = 'cylinder'",
            "must be one of",
        ),
    ],
)
def test_bad_lab_specimens_are_refused_with_the_key_named(tmp_path, scenario, old, new, key, reason):
    from click.testing import CliRunner

    from polydem_cli.cli import main

    from conftest import SCEN

    text = (SCEN / "lab" / f"{scenario}.toml").read_text()
    assert old in text
    bad = tmp_path / "bad.toml"
    bad.write_text(text.replace(old, new, 1))
    r = CliRunner().invoke(main, ["check", str(bad)])
    assert r.exit_code == 2, r.output
    assert r.output.startswith(f"error: {bad}: {key}") and reason in r.output, r.output


def test_the_lab_smoke_scenarios_build_the_specimen_and_its_fixtures():
    """scenarios/lab: the disc's load strips sit at its top and bottom; the beam's nose at its top middle, its
    supports at x = (L -+ S)/2 on its lower face, its crack-mouth sets either side of the notch (the runs
    themselves: test_stability runs every shipped scenario, with report and export)."""
    from polydem_cli.scenario.build import build_system
    from polydem_cli.scenario.load import load_scenario

    from conftest import SCEN

    s = build_system(load_scenario(SCEN / "lab" / "smoke_brazilian.toml")[0])
    x = s.x0[:, :2]
    top, bottom = x[s.sets["specimen.top"]], x[s.sets["specimen.bottom"]]
    assert len(top) >= 1 and np.all(top[:, 1] > 6.5) and np.all(np.abs(top[:, 0] - 4.0) < 1.5)
    assert len(bottom) >= 1 and np.all(bottom[:, 1] < 1.5) and np.all(np.abs(bottom[:, 0] - 4.0) < 1.5)
    b = build_system(load_scenario(SCEN / "lab" / "smoke_three_point_bending.toml")[0])
    x = b.x0[:, :2]
    nose, sl, sr = (x[b.sets[f"specimen.{k}"]] for k in ("nose", "support_left", "support_right"))
    assert np.all(np.abs(nose[:, 0] - 8.0) < 1.2) and np.all(nose[:, 1] > 3.0)
    assert np.all(np.abs(sl[:, 0] - 0.5) < 1.2) and np.all(np.abs(sr[:, 0] - 15.5) < 1.2)
    assert np.all(sl[:, 1] < 1.0) and np.all(sr[:, 1] < 1.0)
    ml, mr = x[b.sets["specimen.mouth_left"]], x[b.sets["specimen.mouth_right"]]
    assert np.all((ml[:, 0] < 7.8) & (ml[:, 0] > 6.0)) and np.all((mr[:, 0] > 8.2) & (mr[:, 0] < 10.0))


def test_the_lab_study_runs_the_four_smoke_tests_and_reports_the_judged_ratios(tmp_path):
    """``polydem study lab --smoke``: tension, compression, Brazilian and three-point bending of the thesis
    concrete, each recognised from its result, with strengths of the right order (f_c/f_t between 1 and 20,
    f_ct,sp/f_t between 0.5 and 3, the smoke specimens being 8 cm), a positive G_F, the table and the curves written; a finished run is
    reused the second time; a test the study does not know is refused."""
    from click.testing import CliRunner

    from polydem_cli.cli import main

    from conftest import ROOT

    out = tmp_path / "lab"
    r = CliRunner().invoke(main, ["study", "lab", "--smoke", "--scenarios", str(ROOT), "--out", str(out)])
    assert r.exit_code == 0, r.output
    res = json.loads((out / "results.json").read_text())
    t = res["tests"]
    assert set(t) == {"tension", "compression", "brazilian", "three_point_bending"}
    assert all(n["test"] == k and n["strength"] > 0 for k, n in t.items())
    rows = {q.split(" (")[0]: v for q, v, _ in res["table"]}
    assert 1.0 < rows["f_c / f_t"] < 20.0 and 0.5 < rows["f_ct,sp / f_t"] < 3.0
    assert t["three_point_bending"]["G_F"] > 0 and "cmod_at_peak" in t["three_point_bending"]
    assert (out / "lab_curves.png").stat().st_size > 20_000 and (out / "lab_table.md").read_text().count("|") > 20
    mtime = (out / "brazilian.h5").stat().st_mtime
    r = CliRunner().invoke(
        main, ["study", "lab", "--smoke", "--scenarios", str(ROOT), "--out", str(out), "--test", "brazilian"]
    )
    assert r.exit_code == 0, r.output
    assert (out / "brazilian.h5").stat().st_mtime == mtime  # reused
    r = CliRunner().invoke(main, ["study", "lab", "--test", "torsion", "--out", str(out)])
    assert r.exit_code == 2 and "unknown test 'torsion'" in r.output
