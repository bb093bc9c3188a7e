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
