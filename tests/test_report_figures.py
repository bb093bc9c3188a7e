"""Figures a reviewer would accept (issue: "figures a reviewer would reject"): the figure objects of a small
bonded run are inspected — integer contact counts, no offset text in a corner (the power of ten in the axis
label instead), the crack drawn on the particle frames, failed beams not drawn bolder than intact ones."""

import numpy as np
import pytest

from polydem_cli.io.hdf5 import read_bonds
from polydem_cli.report import basic

from conftest import SCEN
from helpers import run_scenario


@pytest.fixture(scope="module")
def cracked(tmp_path_factory):
    """The smoke concrete panel pulled until its load has dropped (failed beams, a crack)."""
    out = tmp_path_factory.mktemp("cracked") / "panel.h5"
    run_scenario(SCEN / "ch7" / "smoke_concrete_tension.toml", out, ["time.end_displacement=0.01"])
    return out


@pytest.fixture
def figures(monkeypatch):
    """The figures the report saves, by file name (not written)."""
    got = {}

    def keep(fig, png, **kw):
        got[str(png).rsplit("/", 1)[-1]] = fig

    monkeypatch.setattr(basic, "save", keep)
    for mod in ("macro", "bonds", "granular"):
        monkeypatch.setattr(f"polydem_cli.report.{mod}.save", keep)
    return got


def _offset_texts(fig):
    fig.canvas.draw()
    return [a.get_offset_text().get_text() for ax in fig.axes for a in (ax.xaxis, ax.yaxis)]


def test_history_counts_are_integers_and_no_axis_has_an_offset(cracked, figures, tmp_path):
    basic.plot_history(cracked, tmp_path / "h.png")
    fig = figures["h.png"]
    assert _offset_texts(fig) == [""] * (2 * len(fig.axes))
    (counts,) = [ax for ax in fig.axes if ax.get_ylabel() == "number of contacts"]
    ticks = [t for t in counts.get_yticks() if counts.get_ylim()[0] <= t <= counts.get_ylim()[1]]
    assert ticks and all(float(t).is_integer() for t in ticks)


def test_strain_axis_carries_its_power_of_ten_in_the_label(cracked, figures, tmp_path):
    from polydem_cli.report.macro import plot_stress_strain

    plot_stress_strain([("panel", cracked)], tmp_path / "s.png")
    fig = figures["s.png"]
    assert _offset_texts(fig) == [""] * (2 * len(fig.axes))
    ax = fig.axes[0]
    assert "10^{-4}" in ax.get_xlabel() or "10^{-3}" in ax.get_xlabel(), ax.get_xlabel()
    k = -4 if "10^{-4}" in ax.get_xlabel() else -3
    fmt = ax.xaxis.get_major_formatter()
    assert fmt(2.0 * 10.0**k, 0) == "2" and fmt(1.5 * 10.0**k, 0) == "1.5"  # tick values in units of 10^k


def test_frames_of_a_cracked_specimen_draw_the_failed_beams(cracked, figures, tmp_path):
    from matplotlib.collections import LineCollection

    basic.plot_frames(cracked, tmp_path / "f.png")
    fig = figures["f.png"]
    b = read_bonds(cracked)
    last = fig.axes[len([a for a in fig.axes if a.get_title().startswith("t = ")]) - 1]
    nfailed = int((b["frame_d"][-1] >= 1.0).sum())
    assert nfailed > 0 and f"{nfailed} failed beams" in last.get_title()
    (cracks,) = [c for c in last.collections if isinstance(c, LineCollection)]
    assert len(cracks.get_segments()) == nfailed
    assert "99th percentile" in fig.axes[-1].get_ylabel()  # the colour bar says where its scale ends


def test_failed_beams_are_not_drawn_bolder_than_intact_ones(cracked, figures, tmp_path):
    from polydem_cli.report.macro import plot_damage_panels

    plot_damage_panels([("panel", cracked)], tmp_path / "d.png")
    lc = figures["d.png"].axes[0].collections[0]
    d = np.sort(read_bonds(cracked)["frame_d"][-1])  # drawn in order of damage
    w = np.asarray(lc.get_linewidths())
    assert (d >= 1).any() and w[d >= 1].max() < w[d < 1].min()


def test_velocity_arrows_have_one_scale_and_one_key(tmp_path, figures):
    """Each panel had its own reference arrow of another length; now one scale for the figure, one key."""
    from matplotlib.quiver import Quiver, QuiverKey

    from polydem_cli.report.granular import plot_velocity_arrows

    out = tmp_path / "pile.h5"
    run_scenario(SCEN / "demo_hex_pile.toml", out, ["time.end_displacement=0.3"])
    plot_velocity_arrows(out, tmp_path / "v.png")
    fig = figures["v.png"]
    quivers = [a for ax in fig.axes for a in ax.get_children() if isinstance(a, Quiver)]
    keys = [a for ax in fig.axes for a in ax.get_children() if isinstance(a, QuiverKey)]
    assert len(quivers) == 3 and len({q.scale for q in quivers}) == 1 and len(keys) == 1
    assert "one scale for every panel" in keys[0].text.get_text()
    # the key is in the picture: save() crops to the drawn artists (bbox_inches="tight"), and a QuiverKey has no
    # extent of its own, so the key hung under a panel was cut off the PNG
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    canvas = FigureCanvasAgg(fig)  # the pyplot canvas is gone with plt.close
    canvas.draw()
    r = canvas.get_renderer()
    crop = fig.get_tightbbox(r)  # inches
    inches = fig.dpi_scale_trans.inverted()
    label = keys[0].text.get_window_extent(r).transformed(inches)
    arrow = inches.transform(keys[0].get_transform().transform((keys[0].X, keys[0].Y)))
    assert crop.y0 <= label.y0 and label.y1 <= crop.y1 and crop.x0 <= label.x0 and label.x1 <= crop.x1
    assert crop.contains(*arrow), (crop, arrow)


def test_timestep_axes_spanning_less_than_a_decade_have_labelled_ticks(tmp_path, monkeypatch):
    """With the '3×10⁰' minor labels gone, a log axis from 1.5 s to 8 s had no tick label at all."""
    from polydem_cli.workflows import timestep as T

    runs = [
        {"integrator": i, "dt": dt, "stable": True, "wall_s": w, "result": f"{i}{dt}", "errors": {"load_curve_L2": e}}
        for i, dt, w, e in [("gear5", 0.01, 8.0, 0.0), ("gear5", 0.02, 4.0, 2e-4), ("gear5", 0.04, 2.0, 8e-4)]
        + [("verlet", 0.02, 3.0, 3e-3), ("verlet", 0.04, 1.5, 1e-3)]
    ]
    res = {
        "scenario": "s.toml",
        "reference": {"integrator": "gear5", "dt": 0.01, "result": "gear50.01"},
        "runs": runs,
        "convergence_order": {"gear5": {"load_curve_L2": 2.0}, "verlet": {"load_curve_L2": -1.6}},
    }
    figs = []
    monkeypatch.setattr(T, "_save", lambda fig, png, **kw: figs.append(fig))
    T._plot(res, tmp_path / "t.png")
    (fig,) = figs
    fig.canvas.draw()
    ax = fig.axes[0]
    for axis, (lo, hi) in ((ax.xaxis, ax.get_xlim()), (ax.yaxis, ax.get_ylim())):
        ticks = [*zip(axis.get_majorticklocs(), axis.get_majorticklabels())]
        ticks += [*zip(axis.get_minorticklocs(), axis.get_minorticklabels())]
        shown = [t.get_text() for v, t in ticks if lo <= v <= hi and t.get_text()]
        assert len(shown) >= 2 and not any("×" in s or "times" in s for s in shown), shown


def test_a_tiny_overlap_is_a_ratio_with_its_power_of_ten_not_a_power_of_ten_of_percent(cracked, figures, monkeypatch):
    """The overlap axis read '[%]' with '1e-5' in the corner, then '[10⁻⁵ %]'; a ratio of 3e-7 reads [10⁻⁷]."""
    cols, tab = basic.read_history(cracked)
    tab = tab.copy()
    k = list(cols).index("max_overlap_ratio")
    tab[:, k] = 3e-7 * np.linspace(0.0, 1.0, len(tab))
    monkeypatch.setattr(basic, "read_history", lambda result: (cols, tab))
    basic.plot_history(cracked, "h.png")
    fig = figures["h.png"]
    (ax2,) = [ax for ax in fig.axes if "A_n" in ax.get_ylabel()]
    assert "10^{-7}" in ax2.get_ylabel() and "%" not in ax2.get_ylabel(), ax2.get_ylabel()
    assert _offset_texts(fig) == [""] * (2 * len(fig.axes)) and ax2.get_ylim()[0] == 0.0
    assert ax2.yaxis.get_major_formatter()(2e-7, 0) == "2"


def test_a_run_stopped_before_its_peak_is_drawn_as_a_lower_bound(tmp_path, figures):
    """The stress–strain figure wrote 'peak … N/mm²' at the last point of a run stopped while the stress rose."""
    from polydem_cli.report.macro import plot_stress_strain

    out = tmp_path / "rising.h5"
    run_scenario(SCEN / "ch7" / "smoke_concrete_tension.toml", out, ["time.end_displacement=0.0005"])
    (m,) = plot_stress_strain([("rising", out)], tmp_path / "s.png")
    assert not m["peak_reached"]
    ax = figures["s.png"].axes[0]
    said = " ".join(t.get_text() for t in ax.texts)
    assert "peak not reached" in said and "strength |σ22| ≥" in said, said
    assert [t.get_text() for t in ax.get_legend().get_texts()][0] == "rising (peak not reached)"
    (marker,) = [ln for ln in ax.lines if ln.get_marker() == "o"]
    assert marker.get_markerfacecolor() == "white"  # an open marker: the end of the run, not a peak


def test_movie_says_where_its_colour_scale_ends_and_draws_failed_beams_thin(cracked, tmp_path, monkeypatch):
    """The movie's colour bar did not say its scale ends at the 99th percentile, and its failed beams were as
    wide as the intact ones (in the saturated end colour: the cracks looked like the strongest members)."""
    from matplotlib import animation
    from matplotlib.collections import LineCollection

    from polydem_cli.report.movie import make_movie

    seen = {}

    class LastFrame:  # draws the last frame instead of writing the animation
        def __init__(self, fig, func, frames, **kw):
            seen.update(fig=fig, draw=func)

        def save(self, path, **kw):
            seen["draw"](-1)
            open(path, "wb").close()

    monkeypatch.setattr(animation, "FuncAnimation", LastFrame)
    make_movie(cracked, tmp_path / "m.gif")
    fig = seen["fig"]
    assert any("99th percentile" in ax.get_xlabel() for ax in fig.axes)
    (beams,) = [c for c in fig.axes[0].collections if isinstance(c, LineCollection)]
    d, w = np.asarray(beams.get_array()), np.asarray(beams.get_linewidths())
    assert (d >= 1).any() and w[d >= 1].max() < w[d < 1].min()
