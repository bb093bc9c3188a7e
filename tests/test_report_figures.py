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
    said = fig._suptitle.get_text().replace("\n", " ")  # titled with what it shows and the run (issue 51)
    assert "velocity" in said and "damage" in said and _scenario_title(cracked) in said, said
    (beams,) = [c for c in fig.axes[0].collections if isinstance(c, LineCollection)]
    d, w = np.asarray(beams.get_array()), np.asarray(beams.get_linewidths())
    assert (d >= 1).any() and w[d >= 1].max() < w[d < 1].min()


# ------------------------------------------------------------------ issue 51, item 5: figures a reviewer would send back


@pytest.fixture(scope="module")
def fine_panel(tmp_path_factory):
    """The thesis's 40 x 40 concrete panel (1600 cells, 4632 beams) for a few frames: a fine beam network and many
    small particles on one panel."""
    out = tmp_path_factory.mktemp("fine") / "fine.h5"
    over = ["particles.0.nx=40", "particles.0.ny=40", "time.end_displacement=6e-5", "output.frame_interval=1e-4"]
    run_scenario(SCEN / "ch7" / "smoke_concrete_tension.toml", out, over)
    return out


@pytest.fixture
def saved(monkeypatch):
    """Every figure saved (savefig intercepted, the file still written): (figure, file name, savefig arguments)."""
    from matplotlib.figure import Figure

    got = []
    real = Figure.savefig

    def record(self, fname, *a, **kw):
        out = real(self, fname, *a, **kw)
        name = str(fname).rsplit("/", 1)[-1].removeprefix(".").removesuffix(".part")
        got.append((self, name, kw))
        return out

    monkeypatch.setattr(Figure, "savefig", record)
    return got


def _texts(fig):
    from matplotlib.text import Text

    return [t for t in fig.findobj(Text) if t.get_visible() and t.get_text().strip()]


def _scenario_title(result):
    from polydem_cli.io.hdf5 import open_result

    with open_result(result) as f:
        return str(f.attrs["title"])


@pytest.fixture
def other_result(cracked):
    import shutil

    other = cracked.with_name("other.h5")
    shutil.copy(cracked, other)
    yield other
    other.unlink(missing_ok=True)


def test_every_report_figure_is_titled_with_what_it_shows_and_the_run(cracked, other_result, tmp_path):
    """load.png had no title and did not name its set; now every figure of a report says what it shows and names
    the run (its scenario's title), in the figure and in the file's metadata (PNG Title)."""
    from PIL import Image

    from polydem_cli.report import make_report

    files = [f for f in make_report(cracked, tmp_path) if f.suffix == ".png"]
    assert len(files) >= 10, files
    title = _scenario_title(cracked)
    for f in files:
        meta = Image.open(f).text.get("Title", "")
        assert title in meta, (f.name, meta)
    load = Image.open(tmp_path / f"{cracked.stem}_load.png").text["Title"]
    assert "specimen.top" in load and "load" in load, load  # the set it draws
    # and a figure of several results says which
    from polydem_cli.report.make import overlay

    (png,) = [f for f in overlay([cracked, other_result], tmp_path) if f.suffix == ".png"]
    meta = Image.open(png).text.get("Title", "")
    assert "panel" in meta and "other" in meta and "overlay" in meta, meta


def test_marked_states_are_explained_in_every_figure_that_names_them(cracked, saved, tmp_path):
    """damage.png labelled its panels (z1)-(z4), explained only in load.png: every figure that names a state says
    in itself what it is (where against the peak, which share of the peak load)."""
    import re

    from polydem_cli.report import bonds as rb

    u, f, _, _ = rb.load_curve(cracked)
    states = rb.auto_states(u, f)
    rb.plot_load_displacement(cracked, tmp_path / "l.png", states)
    rb.plot_damage_maps(cracked, tmp_path / "d.png", states)
    rb.plot_strain_maps(cracked, tmp_path / "s.png", states[2])
    rb.plot_damage_maps(cracked, tmp_path / "d2.png", [states[0], u[-1]])  # states given by the user
    for fig, name, _ in saved:
        if name.endswith(".csv"):
            continue
        texts = [t.get_text() for t in _texts(fig)]
        named = {m for t in texts for m in re.findall(r"\([zd]\d\)", t)}
        if name != "s.png":
            assert named, name
        for lab in named:
            said = [t for t in texts if lab in t and re.search(r"peak|end of the run", t)]
            assert said, (name, lab, texts)
    titles = [ax.get_title() for fig, name, _ in saved if name == "d.png" for ax in fig.axes if ax.get_title()]
    assert any(t.startswith("(z1) before the peak, 90") for t in titles), titles
    assert any(t.startswith("(z4) end of the run") for t in titles), titles


def test_no_parameter_is_shown_in_raw_cgs_units(cracked, saved, tmp_path):
    """specimen.png printed 'E 4.14e+11 g/(cm s^2)'; the history's energies read [erg]: the figures show E in GPa,
    G_ax in N/m, energies in J, forces in N (never g/(cm s²), g/s², dyn, erg)."""
    import json
    import re

    from polydem_cli.io.hdf5 import open_result
    from polydem_cli.report import make_report

    make_report(cracked, tmp_path)
    raw = re.compile(r"g/\(cm|g/s\^?2|g/s²|\bdyn\b|\berg\b|g cm")
    texts = [t.get_text() for fig, _, _ in saved for t in _texts(fig)]
    texts += [ax.get_xlabel() + ax.get_ylabel() for fig, _, _ in saved for ax in fig.axes]
    assert texts and not [t for t in texts if raw.search(t)], [t for t in texts if raw.search(t)]
    with open_result(cracked) as f:
        bonds = json.loads(f.attrs["resolved"])["bonds"]
    (spec,) = [fig for fig, name, _ in saved if name.endswith("_specimen.png")]
    box = "\n".join(t.get_text() for t in _texts(spec))
    assert f"{bonds['E'] / 1e10:.4g} GPa" in box and f"{bonds['G_ax'] / 1e3:.4g} N/m" in box, box
    (hist,) = [fig for fig, name, _ in saved if name.endswith("_history.png")]
    assert any("J]" in ax.get_ylabel() and "energy" in ax.get_ylabel() for ax in hist.axes)


def _crop(fig, kw):
    """The part of the figure the file holds [in]: savefig's bbox_inches as matplotlib applies it."""
    from matplotlib.transforms import Bbox

    b = kw.get("bbox_inches")
    r = fig.canvas.get_renderer()
    if b == "tight":
        return fig.get_tightbbox(r).padded(kw.get("pad_inches", 0.1) or 0.0)
    return b if isinstance(b, Bbox) else fig.bbox_inches


def _outside(fig, kw):
    """Texts (with their frames) drawn beyond the saved part of the figure: cut off in the file."""
    from unittest import mock

    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.text import Text

    drawn = []
    real = Text.draw

    def draw(self, renderer):  # the texts a draw of the figure renders (not the tick labels off the view, ...)
        real(self, renderer)
        if self.get_visible() and self.get_text().strip():
            drawn.append(self)

    FigureCanvasAgg(fig)  # a fresh canvas (the figure may be closed)
    with mock.patch.object(Text, "draw", draw):
        fig.canvas.draw()
    r = fig.canvas.get_renderer()
    crop = _crop(fig, kw)
    inches = fig.dpi_scale_trans.inverted()
    cut = []
    for t in drawn:
        boxes = [t.get_window_extent(r)]
        if t.get_bbox_patch() is not None:
            boxes.append(t.get_bbox_patch().get_window_extent(r))
        for b in boxes:
            b = b.transformed(inches)
            if b.x0 < crop.x0 - 1e-3 or b.x1 > crop.x1 + 1e-3 or b.y0 < crop.y0 - 1e-3 or b.y1 > crop.y1 + 1e-3:
                cut.append(t.get_text()[:40])
    return cut


def test_nothing_is_clipped_in_any_report_figure(cracked, fine_panel, saved, tmp_path):
    """The beam parameters' box of specimen.png was cut off on the right (the tight crop takes a text without its
    frame): no text or text frame of any figure reaches beyond the part of the figure the file holds."""
    from polydem_cli.report import make_report

    make_report(cracked, tmp_path / "a")
    make_report(fine_panel, tmp_path / "b")
    assert len(saved) >= 20
    for fig, name, kw in saved:
        assert not _outside(fig, kw), (name, _outside(fig, kw))


def test_a_fine_beam_network_does_not_hide_the_cells(fine_panel, saved, tmp_path):
    """specimen.png of the 1600-cell panel drew its 4632 beams over the cells (a blue mesh hiding them): no panel
    draws more than a few beams per cell area on paper, the cell outlines lie above the beams, and the beams are
    shown (a close-up of a few cells)."""
    from matplotlib.collections import LineCollection, PolyCollection

    from polydem_cli.report.specimen import plot_specimen

    plot_specimen(fine_panel, tmp_path / "s.png")
    (fig, _, _), *_ = saved
    fig.canvas.draw()
    shown = 0
    for ax in fig.axes + [c for a in fig.axes for c in a.child_axes]:
        beams = [c for c in ax.collections if isinstance(c, LineCollection)]
        cells = [c for c in ax.collections if isinstance(c, PolyCollection)]
        n = sum(len(c.get_segments()) for c in beams)
        if not n:
            continue
        box = ax.get_window_extent()
        area = box.width * box.height / fig.dpi**2  # in^2
        assert n / area < 40.0, (n, area)  # 4632 beams on a 5 in panel: 190 per in^2
        outlines = [c for c in cells if len(c.get_edgecolor()) and c.get_linewidths()[0] > 0]
        assert outlines and min(c.get_zorder() for c in outlines) > max(c.get_zorder() for c in beams)
        shown += n
    assert shown >= 50  # the beams are shown, where they can be seen


def test_velocity_arrows_of_many_small_particles_stay_apart(fine_panel, saved, tmp_path):
    """velocity.png of the 1600-cell panel: an arrow per particle, 0.1 in apart with heads wider than that,
    merged into one red mass.  Arrows now lie at least 0.18 in apart on paper, thinner than a tenth of that, the
    99th-percentile speed drawn shorter than their spacing, and the figure says what an arrow then is."""
    from matplotlib.quiver import Quiver

    from polydem_cli.report.granular import plot_velocity_arrows

    plot_velocity_arrows(fine_panel, tmp_path / "v.png")
    (fig, _, _), *_ = [s for s in saved if s[1] == "v.png"]
    fig.canvas.draw()
    quivers = [a for ax in fig.axes for a in ax.get_children() if isinstance(a, Quiver)]
    assert len(quivers) == 3
    for q in quivers:
        ax = q.axes
        per_in = ax.get_window_extent().width / fig.dpi / np.ptp(ax.get_xlim())  # in per cm
        xy = np.asarray(q.XY) * per_in
        d = np.hypot(*(xy[:, None, :] - xy[None, :, :]).transpose(2, 0, 1))
        np.fill_diagonal(d, np.inf)
        gap = d.min()
        assert gap >= 0.18, gap
        width = q.width * (per_in if q.units == "xy" else ax.get_window_extent().width / fig.dpi)
        assert width < 0.1 * gap, (width, gap)
        speed = np.hypot(q.U, q.V)
        longest = np.percentile(speed, 99) / q.scale * per_in  # scale_units xy: cm of arrow per cm/s
        assert longest < gap, (longest, gap)
    assert "mean velocity of the particles in a square of" in fig._suptitle.get_text()


def test_snapshots_leave_out_frames_in_which_nothing_moves(cracked, figures, tmp_path):
    """frames.png drew t = 0, every particle at rest: a uniform panel that shows nothing (the specimen as built is
    specimen.png).  The default snapshots are frames in which particles move; a frame at rest asked for (--times)
    says so in its title."""
    from polydem_cli.io.hdf5 import read_frames as raw_frames

    _, times, _, V = raw_frames(cracked)
    assert not np.any(V[0])  # the run starts at rest
    basic.plot_frames(cracked, tmp_path / "f.png")
    panels = [ax for ax in figures["f.png"].axes if ax.get_title().startswith("t = ")]
    assert len(panels) == 4
    for ax in panels:
        t = float(ax.get_title().split()[2])
        k = int(np.argmin(np.abs(times - t)))
        assert np.any(V[k]), ax.get_title()
    assert float(panels[-1].get_title().split()[2]) == pytest.approx(times[-1], rel=1e-3)  # the end is shown
    basic.plot_frames(cracked, tmp_path / "g.png", times=[0.0, times[-1]])
    first = [ax for ax in figures["g.png"].axes if ax.get_title().startswith("t = ")][0]
    assert "at rest" in first.get_title()


def test_a_markdown_table_escapes_the_bar_in_its_cells():
    """lab_table.md had '|f_c|' in a cell, which split its row: every cell escapes |, and a line break in a value
    does not end the row."""
    import re

    from polydem_cli.report.common import markdown_table

    text = markdown_table(("quantity", "value", "reference"), [("a | b", "1", "at f_cm = |f_c|"), ("x\ny", "2", "z")])
    rows = text.splitlines()
    assert len(rows) == 4
    for row in rows:
        cells = re.split(r"(?<!\\)\|", row.strip())[1:-1]
        assert len(cells) == 3, row
    assert r"\|f_c\|" in rows[2]
