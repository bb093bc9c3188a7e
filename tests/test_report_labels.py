"""Report labels match the data they draw (colours, signs, units, one colour scale per figure).

The figures are captured as matplotlib objects (``pyplot.close`` is intercepted) and their titles,
colour limits and drawn colours are compared with the result's data."""

import matplotlib
import numpy as np
import pytest

matplotlib.use("Agg")

from polydem_cli.io.hdf5 import read_bonds, read_frames, read_static  # noqa: E402
from polydem_cli.report import basic, bonds  # noqa: E402
from polydem_cli.scenario.build import build_system  # noqa: E402
from polydem_cli.scenario.load import load_scenario  # noqa: E402
from polydem_cli.solvers.explicit import run  # noqa: E402

from conftest import DYN_PER_UNIT, SCEN  # noqa: E402


@pytest.fixture(scope="module")
def tension(tmp_path_factory):
    path = SCEN / "ch5" / "small_tension.toml"
    sc, text = load_scenario(path, ["time.end_displacement=2.5e-4"])
    out = tmp_path_factory.mktemp("labels") / "small_tension.h5"
    run(build_system(sc, str(path)), out=out, scenario_file=str(path), scenario_text=text, quiet=True)
    return out


@pytest.fixture
def figures(monkeypatch):
    import matplotlib.pyplot as plt

    kept = []
    real_close = plt.close

    def keep(fig=None):
        kept.append(fig)
        real_close(fig)

    monkeypatch.setattr(plt, "close", keep)
    return kept


def _collections(fig, kind):
    from matplotlib import collections as mc

    cls = getattr(mc, kind)
    return [(ax, c) for ax in fig.axes for c in ax.collections if isinstance(c, cls) and c.get_array() is not None]


def _blue_minus_red(rgba):
    return rgba[:, 2] - rgba[:, 0]


def test_axial_strain_map_draws_tension_orange_and_stretched_beams_are_tension(tension, tmp_path, figures):
    bonds.plot_strain_maps(tension, tmp_path / "s.png")
    (fig,) = figures
    axial = [(ax, c) for ax, c in _collections(fig, "LineCollection") if ax.get_title().startswith("axial strain")]
    assert len(axial) == 1
    ax, lc = axial[0]
    title = ax.get_title()
    assert "tension orange" in title and "compression purple" in title
    a = np.asarray(lc.get_array())
    rgba = lc.to_rgba(a)
    lo, hi = lc.get_clim()
    assert lo == -hi  # symmetric: white is zero strain
    pos, neg = a > 0.3 * hi, a < 0.3 * lo
    assert pos.any()
    assert np.all(rgba[pos, 0] > rgba[pos, 2])  # orange/brown: more red than blue
    if neg.any():
        assert np.all(rgba[neg, 2] > rgba[neg, 0])  # purple: more blue than red
    # the data: in a tension test the beams along the load (e2) are stretched, so mostly positive
    st = read_static(tension)
    b = read_bonds(tension)
    d = st["x0"][b["pairs"][:, 1], :2] - st["x0"][b["pairs"][:, 0], :2]
    along = np.abs(d[:, 1]) > 2 * np.abs(d[:, 0])
    (k,), _, _ = bonds._frame_index_for(tension, [bonds.auto_states(*bonds.load_curve(tension)[:2])[2]])
    assert np.median(b["frame_strain"][k][along, 0]) > 0


def test_damage_map_shows_intact_beams_on_white_and_failed_ones_dark(tension, tmp_path, figures):
    bonds.plot_damage_maps(tension, tmp_path / "d.png")
    (fig,) = figures
    lcs = _collections(fig, "LineCollection")
    assert lcs
    for _, lc in lcs:
        assert lc.get_clim() == (0.0, 1.0)  # one scale, d from 0 to 1, in every panel
        r0, g0, b0, _ = lc.to_rgba(np.array([0.0]))[0]
        r1, g1, b1, _ = lc.to_rgba(np.array([1.0]))[0]
        lum0 = 0.2126 * r0 + 0.7152 * g0 + 0.0722 * b0
        lum1 = 0.2126 * r1 + 0.7152 * g1 + 0.0722 * b1
        assert 0.5 < lum0 < 0.8  # d = 0 visible on the white page, but light
        assert max(r0, g0, b0) - min(r0, g0, b0) < 0.05  # and neutral: no hue of the damage scale
        assert lum1 < 0.25  # failed beams dark
    # the colour bar says what is drawn
    labels = [ax.get_ylabel() for ax in fig.axes]
    assert any("damage $d$" in lab for lab in labels)


def test_snapshot_panels_share_one_velocity_scale_and_label_positions(tension, tmp_path, figures):
    basic.plot_frames(tension, tmp_path / "f.png")
    (fig,) = figures
    polys = _collections(fig, "PolyCollection")
    assert len(polys) >= 2
    clims = {c.get_clim() for _, c in polys}
    assert len(clims) == 1  # one colour scale for the figure
    (vmax,) = {hi for _, hi in clims}
    _, _, _, V = read_frames(tension)
    assert vmax == pytest.approx(max(np.percentile(np.abs(V[k, :, 1]), 99) for k in range(len(V))), rel=0.5)
    for ax, _ in polys:
        assert "[cm]" in ax.get_xlabel() and "[cm]" in ax.get_ylabel()
    assert any("[cm/s]" in ax.get_ylabel() for ax in fig.axes)  # the colour bar


def test_load_curve_sign_is_the_reaction_tension_positive(tension, tmp_path, figures):
    bonds.plot_load_displacement(tension, tmp_path / "l.png")
    (fig,) = figures
    (ax,) = fig.axes
    unit = ax.get_ylabel().split()[-1]
    assert unit.strip("[]") in DYN_PER_UNIT and "reaction" in ax.get_ylabel() and "[cm]" in ax.get_xlabel()
    (line,) = [ln for ln in ax.get_lines() if len(ln.get_xdata()) > 10]
    u, f = np.asarray(line.get_xdata()), np.asarray(line.get_ydata())
    assert u.max() > 0 and f.max() > 0 and f.max() > -f.min()  # pulled up, positive tension load
    # drawn in the unit it states: the history's f2 (dyn) over 1e8 (kN) or 1e5 (N); kN from 0.1 kN up
    _, f_dyn, _, _ = bonds.load_curve(tension)
    div = DYN_PER_UNIT[unit.strip("[]")]
    assert np.allclose(f * div, f_dyn)
    assert (unit == "[kN]") == (np.abs(f_dyn).max() >= 1e7)


def test_velocity_arrow_key_states_the_speed_its_arrow_draws(tension, tmp_path, figures):
    """One key for the figure: a round speed (1, 2 or 5 x 10^n) at most the reference speed (the 99th percentile
    of |v| over the panels) and more than 2/5 of it; the reference arrow spans 3/4 of the particles' spacing (the
    side of a square of a particle's median area)."""
    from matplotlib.quiver import QuiverKey

    from polydem_cli.report import granular

    granular.plot_velocity_arrows(tension, tmp_path / "v.png")
    (fig,) = figures
    _, _, _, V = read_frames(tension)
    radius = read_static(tension)["radius"]
    free = radius <= 4 * np.median(radius)
    panels = sorted(set(np.linspace(1, len(V) - 1, min(3, len(V) - 1)).round().astype(int)))
    vref = max(float(np.percentile(np.hypot(V[k][free, 0], V[k][free, 1]), 99)) for k in panels)
    (key,) = [a for ax in fig.axes for a in ax.get_children() if isinstance(a, QuiverKey)]
    m = key.U / 10.0 ** np.floor(np.log10(key.U))
    assert min(abs(m - r) for r in (1.0, 2.0, 5.0)) < 1e-9
    assert 0.4 * vref < key.U <= vref
    assert key.text.get_text().endswith(f"{key.U:g} cm/s")
    from polydem_cli.geometry.polygon import signed_area

    polys = basic.world_polygons(read_static(tension), read_frames(tension)[2][0])
    spacing = np.sqrt(np.median([abs(signed_area(p)) for p, f in zip(polys, free) if f]))
    assert key.Q.scale == pytest.approx(vref / (0.75 * spacing), rel=1e-9)
    assert vref > 0


def test_specimen_figure_marks_what_the_scenario_perturbed(tmp_path, figures):
    """Figs. 5.6/6.3/7.3: the specimen at t = 0 with the particle of [[perturb]] (k_n) filled red and the beam of
    [[bonds.perturb]] (E_h) drawn red, and the counts in the title."""
    from matplotlib.collections import LineCollection, PolyCollection

    from polydem_cli.report.specimen import plot_specimen

    nuts = tmp_path / "nuts.toml"
    nuts.write_text(
        f'[scenario]\nextends = "{SCEN / "ch6" / "nuts_small.toml"}"\n[time]\nend_time = 1e-4\n'
        "[[perturb]]\nat = [2.6, 2.1]\nk_n_factor = 0.9\n"
    )
    sc, text = load_scenario(nuts)
    s = build_system(sc, str(nuts))
    run(s, out=tmp_path / "nuts.h5", scenario_file=str(nuts), scenario_text=text, quiet=True)
    plot_specimen(tmp_path / "nuts.h5", tmp_path / "n.png")
    (fig,) = figures
    (ax,) = fig.axes
    x0 = read_static(tmp_path / "nuts.h5")["x0"]
    (pc,) = [c for c in ax.collections if isinstance(c, PolyCollection) and len(c.get_facecolors()) == len(x0)]
    k = int(np.argmin(np.hypot(x0[:, 0] - 2.6, x0[:, 1] - 2.1)))
    red = np.flatnonzero((pc.get_facecolors()[:, 0] > 0.8) & (pc.get_facecolors()[:, 1] < 0.4))
    assert list(red) == [k]
    assert "28 particles, 2 plates" in ax.get_title()
    # by a set (group[i]), resolved as the build resolves it
    from polydem_cli.report.specimen import perturbed_particles

    by_set = tmp_path / "nuts_set.toml"
    by_set.write_text(nuts.read_text().replace("at = [2.6, 2.1]", 'set = "nuts[5]"'))
    sc, text = load_scenario(by_set)
    s2 = build_system(sc, str(by_set))
    run(s2, out=tmp_path / "nuts_set.h5", scenario_file=str(by_set), scenario_text=text, quiet=True)
    st2 = read_static(tmp_path / "nuts_set.h5")
    first = int(np.flatnonzero(st2["group"] == st2["group_names"].index("nuts"))[0])
    assert list(perturbed_particles(st2)) == [first + 5]
    kn = s2.family_data["contact"].kn
    assert np.flatnonzero(kn != np.median(kn)).tolist() == [first + 5]  # the build changed that particle

    glued = tmp_path / "glued.toml"
    glued.write_text(
        f'[scenario]\nextends = "{SCEN / "ch7" / "smoke_nuts_glued.toml"}"\n[time]\nend_time = 1e-5\n'
        "[[bonds.perturb]]\nat = [1.9, 1.1]\nE_factor = 0.9\n"
    )
    sc, text = load_scenario(glued)
    run(build_system(sc, str(glued)), out=tmp_path / "g.h5", scenario_file=str(glued), scenario_text=text, quiet=True)
    plot_specimen(tmp_path / "g.h5", tmp_path / "g.png")
    ax = figures[-1].axes[0]
    b = read_bonds(tmp_path / "g.h5")
    weak = np.flatnonzero(b["E"] != np.median(b["E"]))
    assert len(weak) >= 1
    red = [c for c in ax.collections if isinstance(c, LineCollection) and r"$E_h \times$ 0.9" in str(c.get_label())]
    assert len(red) == 1 and len(red[0].get_segments()) == len(weak)
    assert f"{len(b['pairs'])} beams" in ax.get_title()


def test_closeup_shows_the_window_and_follows_the_marked_particles(tension, tmp_path, figures):
    """Fig. 6.6: ``--region`` sets the window of every snapshot, ``--mark`` outlines the particle nearest to
    each point at t = 0 in every panel, at its position in that frame."""
    from matplotlib.collections import PolyCollection

    st = read_static(tension)
    _, _, X, _ = read_frames(tension)
    pts = [(2.0, 2.0), (4.0, 1.0)]
    want = [int(np.argmin(np.hypot(st["x0"][:, 0] - x, st["x0"][:, 1] - y))) for x, y in pts]
    basic.plot_frames(tension, tmp_path / "c.png", region=(1.0, 5.0, 0.5, 3.5), marks=pts)
    (fig,) = figures
    panels = [ax for ax in fig.axes if ax.get_title().startswith("t = ")]
    assert panels
    for ax in panels:
        assert ax.get_xlim() == (1.0, 5.0) and ax.get_ylim() == (0.5, 3.5)
        rings = [c for c in ax.collections if isinstance(c, PolyCollection) and c.get_linewidths()[0] > 2]
        assert len(rings) == len(pts)
        k = int(np.argmin([abs(float(ax.get_title().split()[2]) - t) for t in read_frames(tension)[1]]))
        for ring, i in zip(rings, want):
            poly = ring.get_paths()[0].vertices[:-1]
            assert np.allclose(poly.mean(axis=0), basic.world_polygons(st, X[k])[i].mean(axis=0), atol=1e-9)
        assert [t.get_text() for t in ax.texts] == ["1", "2"]


def test_closeup_options_refuse_a_bad_window_with_the_expected_form(tension, tmp_path):
    from click.testing import CliRunner

    from polydem_cli.cli import main

    for args in (["--region", "5,1,0,3"], ["--region", "1,5,0"], ["--region", "1,5,0,3", "--mark", "2"]):
        r = CliRunner().invoke(main, ["report", str(tension), "--out", str(tmp_path), *args])
        assert r.exit_code == 2 and "expected --region X0,X1,Y0,Y1" in r.output, args
    assert not list(tmp_path.glob("*.png"))  # nothing half-written
    r = CliRunner().invoke(main, ["report", str(tension), "--out", str(tmp_path), "--region", "1,5,0,3"])
    assert r.exit_code == 0 and [p.name for p in tmp_path.glob("*.png")] == ["small_tension_closeup.png"]


@pytest.mark.parametrize(
    "dyn, unit", [(3.0e7, "kN"), (2.0e5, "N"), (2.0e4, "N"), (9.0e3, "mN"), (50.0, "mN"), (0.05, "µN"), (7.7e-4, "nN")]
)
def test_force_axis_takes_the_unit_in_which_the_largest_force_is_at_least_a_tenth(dyn, unit):
    """No offset factor on the axis: the chapter-5 specimen's loads (~8e-9 N = 8e-4 dyn) are drawn in nN."""
    div, got = basic.force_unit(np.array([0.0, -dyn, 0.5 * dyn]))
    assert got == unit and div == DYN_PER_UNIT[unit]
    assert 0.1 <= dyn / div < 1000.0
