"""The report's toolbox, shared by every figure module: saving (extra formats, plotted data, whole files
only), frames for pictures (displacement magnification), particle outlines, force units, axis labels, the
damage colour scale, the load curve of a driven set."""

from __future__ import annotations

import contextvars
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..io.hdf5 import read_frames as _read_frames
from ..io.hdf5 import read_history, read_static


@dataclass(frozen=True)
class Style:
    """How a report draws, passed to every figure: the formats written beside each PNG (``polydem report
    --format``: pdf, svg) and the displacement magnification of the particle pictures (``--magnify``)."""

    formats: tuple = ()
    magnify: float = 1.0

    @classmethod
    def of(cls, formats=("png",), magnify=1.0):
        """The style of ``polydem report --format F1,F2 --magnify M`` (PNG is always written)."""
        return cls(tuple(f for f in formats if f != "png"), float(magnify))


#: plain figures: PNG only, displacements as they are
PLAIN = Style()


def read_frames(result, style=PLAIN):
    """The frames of a result for pictures: positions magnified about the initial state by the style's
    factor (x0 + F (x − x0), rotations too), velocities as stored."""
    steps, times, X, V = _read_frames(result)
    if style.magnify != 1.0 and len(X):
        x0 = read_static(result)["x0"]
        X = x0[None, :, :] + style.magnify * (X - x0[None, :, :])
    return steps, times, X, V


def write_curve_data(fig, csv) -> bool:
    """The data of every curve drawn in ``fig`` (lines of two or more points), beside the figure as
    ``<figure>_plotted.csv`` (never a study's own data file): one row per
    point with the panel, its axis labels, the curve's label and x, y as plotted (guides in axes
    coordinates, axhline/axvline, are not data and are left out).  Nothing is written for a
    figure without curves (particle pictures)."""
    import csv as _csv

    rows = []
    for a, ax in enumerate(fig.axes):
        for q, line in enumerate(ax.get_lines()):
            x, y = np.asarray(line.get_xdata(), float), np.asarray(line.get_ydata(), float)
            if x.size < 2 or line.get_transform() != ax.transData:  # a marker, or a guide (axhline, axvline)
                continue
            lab = line.get_label()
            lab = "" if lab.startswith("_") else lab
            for xi, yi in zip(x, y):
                rows.append(
                    (a, ax.get_title(), ax.get_xlabel(), ax.get_ylabel(), q, lab, repr(float(xi)), repr(float(yi)))
                )
    if not rows:
        return False
    with open(csv, "w", newline="") as fh:
        w = _csv.writer(fh)
        w.writerow(["panel", "title", "x_label", "y_label", "curve", "label", "x", "y"])
        w.writerows(rows)
    return True


def figure_title(fig) -> str:
    """What a figure says it shows: its headline (:func:`headline`), else its axes' titles joined."""
    sup = getattr(fig, "_suptitle", None)
    if sup is not None and sup.get_text():
        return sup.get_text()
    return "; ".join(t for t in (ax.get_title() or ax.get_title(loc="left") for ax in fig.axes) if t)


#: figures being collected instead of written (:func:`capture_figures`): a list of (file stem, figure), or None
_CAPTURED = contextvars.ContextVar("polydem_captured_figures", default=None)


@contextmanager
def capture_figures():
    """Inside, :func:`save` keeps each figure (in a list of (the file's stem, the Figure) this yields) instead of
    writing it: the report's figures for the Python API (``Result.figures``), written only when asked."""
    token = _CAPTURED.set([])
    try:
        yield _CAPTURED.get()
    finally:
        _CAPTURED.reset(token)


def save(fig, png, style=PLAIN, **kw):
    """``fig.savefig(png)`` plus the same figure in every extra format of the style (pdf, svg: vector);
    pictures of particles (equal-aspect axes) say their displacement magnification.  Cropped to the drawn
    artists (``bbox_inches="tight"``, text boxes and legends included, :func:`_crop`): equal-aspect panels
    otherwise leave wide empty margins in print.  The figure's title (:func:`figure_title`) is written into the
    file's metadata (PNG ``Title``, PDF and SVG title) too.  Under :func:`capture_figures` nothing is written: the
    figure is kept."""
    kept = _CAPTURED.get()
    if kept is not None:
        kept.append((Path(png).stem, fig))
        return
    kw.setdefault("bbox_inches", "tight")
    kw.setdefault("pad_inches", 0.05)
    if style.magnify != 1.0 and any(ax.get_aspect() == 1.0 for ax in fig.axes):
        fig.text(0.005, 0.005, f"displacements magnified x {style.magnify:g}", fontsize=7, color="0.3")
    if kw["bbox_inches"] == "tight":
        kw["bbox_inches"] = _crop(fig).padded(kw["pad_inches"])
    title = figure_title(fig).replace("\n", " ").replace("$", "")
    png = Path(png)
    _whole(png, lambda tmp: fig.savefig(tmp, format=png.suffix[1:], metadata=_metadata(png.suffix, title), **kw))
    _whole(png.with_name(png.stem + "_plotted.csv"), lambda tmp: write_curve_data(fig, tmp))
    vkw = {k: v for k, v in kw.items() if k != "dpi"}
    for ext in style.formats:
        _whole(
            png.with_suffix("." + ext),
            lambda tmp, ext=ext: fig.savefig(tmp, format=ext, metadata=_metadata("." + ext, title), **vkw),
        )


def _metadata(suffix, title) -> dict:
    """The title entry of a saved file's metadata (the key each backend knows)."""
    return {"Title": title} if suffix.lower() in (".png", ".pdf", ".svg") and title else {}


def _crop(fig):
    """The box (inches) that ``bbox_inches="tight"`` would crop to, widened to the frames of text boxes
    (``bbox=`` of a text: matplotlib's tight box takes the text without its frame, which was cut off at the edge)."""
    from matplotlib.text import Text
    from matplotlib.transforms import Bbox

    fig.draw_without_rendering()
    r = fig.canvas.get_renderer()
    boxes = [fig.get_tightbbox(r)]
    inches = fig.dpi_scale_trans.inverted()
    for t in fig.findobj(Text):
        patch = t.get_bbox_patch()
        if patch is not None and t.get_visible() and t.get_text():
            boxes.append(patch.get_window_extent(r).transformed(inches))
    return Bbox.union(boxes)


def _whole(path, write):
    """``write(tmp)`` into a hidden file beside ``path``, renamed to it when written: a report stopped
    (Ctrl-C, a full disk) leaves no half-written file.  ``write`` returning False: nothing written."""
    import os

    tmp = path.with_name(f".{path.name}.part")
    try:
        if write(tmp) is not False:
            os.replace(tmp, path)
    finally:
        tmp.unlink(missing_ok=True)


def result_name(result) -> str:
    """The name a figure gives a result: its scenario's title, else the file's stem."""
    from ..io.hdf5 import open_result

    with open_result(result) as f:
        title = str(f.attrs.get("title", "") or "")
    return title or Path(result).stem


def headline(fig, what, result=None, fontsize=10):
    """The figure's title: what it shows (first line) and, given ``result``, which run (the scenario's title,
    :func:`result_name`, of a result file's path; any other text is taken as it is), each line wrapped to the figure's
    width."""
    import textwrap

    lines = [what]
    if result is not None:
        named = isinstance(result, str) and not (result.endswith(".h5") and Path(result).is_file())
        lines.append(result if named else result_name(result))
    width = max(40, int(fig.get_figwidth() * 72 / (0.6 * fontsize)))
    wrap = textwrap.TextWrapper(width, break_on_hyphens=False, break_long_words=False)
    text = "\n".join("\n".join(wrap.wrap(line)) if "$" not in line else line for line in lines)
    return fig.suptitle(text, fontsize=fontsize)


def markdown_cell(value) -> str:
    """A value as the text of one Markdown table cell: ``|`` escaped (it would end the cell), line breaks as
    ``<br>`` (they would end the row)."""
    text = str(value).replace("\\|", "|").replace("|", "\\|")
    return "<br>".join(line.strip() for line in text.splitlines()) if "\n" in text or "\r" in text else text


def markdown_table(header, rows) -> str:
    """A Markdown table (``header``: the column names; ``rows``: sequences of cell texts, each cell through
    :func:`markdown_cell`), one line per row, ending in a newline."""

    def line(cells):
        return "| " + " | ".join(markdown_cell(c) for c in cells) + " |"

    out = [line(header), "|" + "---|" * len(header)]
    for r in rows:
        if len(r) != len(header):
            raise ValueError(f"markdown_table: a row of {len(r)} cells under {len(header)} columns: {r!r}")
        out.append(line(r))
    return "\n".join(out) + "\n"


def _plt():
    from ..mpl import pyplot

    plt = pyplot()

    return plt


def world_polygons(static: dict, x: np.ndarray) -> list:
    """Current outlines x + R(φ) X̃ of every particle for one frame ``x`` (n, 3)."""
    vs, bv = static["vertex_start"], static["body_vertices"]
    out = []
    for i in range(len(vs) - 1):
        b = bv[vs[i] : vs[i + 1]]
        c, s = np.cos(x[i, 2]), np.sin(x[i, 2])
        out.append(np.column_stack([x[i, 0] + c * b[:, 0] - s * b[:, 1], x[i, 1] + s * b[:, 0] + c * b[:, 1]]))
    return out


def force_unit(*forces) -> tuple:
    """(divisor, unit) for plotting forces given in dyn: the largest of kN, N, mN, µN, nN (1 kN = 1e8 dyn,
    1 N = 1e5 dyn) in which the largest force is at least 0.1, so that the axis needs no offset factor (the
    chapter-5 specimen's loads are of order 1e-9 N); one unit for all the curves of a figure."""
    m = max((float(np.max(np.abs(f))) for f in forces if len(f)), default=0.0)
    for div, unit in ((1.0e8, "kN"), (1.0e5, "N"), (1.0e2, "mN"), (1.0e-1, "µN")):
        if m >= 0.1 * div:
            return div, unit
    return 1.0e-4, "nN"


def f2_label(unit, what="reaction on the set") -> str:
    """Axis label of the f2 columns: the reaction −Σ (interaction forces in e2) on a set (engine/kernels.py,
    SET_COLUMNS)."""
    return rf"$f_2$, {what} [{unit}]"


def panel_height(points, width, extra) -> float:
    """Height [in] of an equal-aspect panel ``width`` inches wide showing ``points`` (n, 2) [cm]: as high as the
    scene is (a flat strip stays flat, at least 1.6 in, at most square) plus ``extra`` for titles and labels."""
    aspect = float(np.ptp(points[:, 1]) / max(np.ptp(points[:, 0]), 1e-12))
    return min(max(width * aspect, 1.6), width) + extra


def label_axes_cm(ax, fontsize=8):
    """x1, x2 axis labels of a snapshot panel (positions in cm)."""
    ax.set_xlabel(r"$x_1$ [cm]", fontsize=fontsize)
    ax.set_ylabel(r"$x_2$ [cm]", fontsize=fontsize)
    ax.tick_params(labelsize=fontsize - 1)


def decade_axis(ax, axis, label, unit=""):
    """Label an axis ``label [10^k unit]`` with its ticks divided by 10^k, where the data's magnitude asks for it
    (below 1e-2 or from 1e3 on), instead of matplotlib's offset text in the corner ("1e-4" beside a "[−]" label);
    the plotted data keep their units (the ``_plotted.csv`` beside the figure).  Call after plotting."""
    from matplotlib.ticker import FuncFormatter, ScalarFormatter

    a = ax.xaxis if axis == "x" else ax.yaxis
    lim = max(abs(v) for v in (ax.get_xlim() if axis == "x" else ax.get_ylim()))
    k = 0 if lim == 0 or 1e-2 <= lim < 1e3 else int(np.floor(np.log10(lim)))
    if k:
        a.set_major_formatter(FuncFormatter(lambda v, _: f"{v / 10.0**k:.6g}"))
        unit = rf"$10^{{{k}}}$" + (f" {unit}" if unit else "")
    else:
        fmt = ScalarFormatter(useOffset=False)
        fmt.set_scientific(False)
        a.set_major_formatter(fmt)
    (ax.set_xlabel if axis == "x" else ax.set_ylabel)(f"{label} [{unit or '−'}]")


def bond_segments(X, pairs):
    """(m, 2, 2) straight lines between the centroids of bonded pairs at positions ``X`` (damage maps)."""
    return np.stack([X[pairs[:, 0], :2], X[pairs[:, 1], :2]], axis=1)


def damage_word(bonds) -> str:
    """What a bond's damage d is, for labels: "beam damage", or "interface damage" (the mean of its elements')
    for edge interfaces (``/bonds/interface`` in the result, io/hdf5.py)."""
    return "interface damage" if bonds is not None and "interface" in bonds else "beam damage"


def bond_noun(results) -> str:
    """The bonds of one or several results, for labels: "beams", "interfaces" (edge interfaces), or "bonds" when
    they mix the two models (``results``: result paths)."""
    from ..io.hdf5 import read_bonds

    words = {"interfaces" if (b := read_bonds(p)) is not None and "interface" in b else "beams" for p in results}
    return words.pop() if len(words) == 1 else "bonds"


def damage_cmap():
    """d = 0 neutral grey (visible on white, no hue of the damage scale), through yellow and orange to dark
    red at d = 1."""
    from matplotlib.colors import LinearSegmentedColormap

    return LinearSegmentedColormap.from_list(
        "damage", [(0.0, "#b8b8b8"), (0.25, "#f4c542"), (0.6, "#e0541b"), (1.0, "#5c0000")]
    )


def damage_widths(d, base):
    """Line widths of a damage map: a failed beam (d = 1) carries nothing and is drawn at half the width of the
    others, so that the saturated end colour does not make the cracks look like the strongest members."""
    return np.where(np.asarray(d) >= 1.0, 0.5 * base, base)


def load_curve(result, driven=None):
    """(û2, f2, set name) of the driven set (the monitored set moving most in e2)."""
    cols, tab = read_history(result)
    c = {n: i for i, n in enumerate(cols)}
    sets = [n.split(":", 1)[1] for n in cols if n.startswith("f2:")]
    if not sets:
        return None
    drv = driven or max(sets, key=lambda s: np.ptp(tab[:, c["u2:" + s]]))
    return tab[:, c["u2:" + drv]], tab[:, c["f2:" + drv]], drv, tab[:, c["time"]]
