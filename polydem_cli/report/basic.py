"""First report: history curves and particle snapshots of any result."""

from __future__ import annotations

from contextlib import contextmanager
from pathlib import Path

import numpy as np

from ..io.hdf5 import open_result, read_bonds, read_history, read_static
from ..io.hdf5 import read_frames as _read_frames

#: extra formats every report figure is also written in (``polydem report --format``; set by make_report)
_EXTRA_FORMATS: list = []
#: displacement magnification of the particle pictures (``polydem report --magnify``; set by make_report)
_MAGNIFY = 1.0


def read_frames(result):
    """The frames of a result for pictures: positions magnified about the initial state by the report's
    factor (x0 + F (x − x0), rotations too), velocities as stored."""
    steps, times, X, V = _read_frames(result)
    if _MAGNIFY != 1.0 and len(X):
        x0 = read_static(result)["x0"]
        X = x0[None, :, :] + _MAGNIFY * (X - x0[None, :, :])
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


def save(fig, png, **kw):
    """``fig.savefig(png)`` plus the same figure in every extra format of this report (pdf, svg: vector);
    pictures of particles (equal-aspect axes) say their displacement magnification.  Cropped to the drawn
    artists (``bbox_inches="tight"``): equal-aspect panels otherwise leave wide empty margins in print."""
    kw.setdefault("bbox_inches", "tight")
    kw.setdefault("pad_inches", 0.05)
    if _MAGNIFY != 1.0 and any(ax.get_aspect() == 1.0 for ax in fig.axes):
        fig.text(0.005, 0.005, f"displacements magnified x {_MAGNIFY:g}", fontsize=7, color="0.3")
    png = Path(png)
    _whole(png, lambda tmp: fig.savefig(tmp, format=png.suffix[1:], **kw))
    _whole(png.with_name(png.stem + "_plotted.csv"), lambda tmp: write_curve_data(fig, tmp))
    vkw = {k: v for k, v in kw.items() if k != "dpi"}
    for ext in _EXTRA_FORMATS:
        _whole(png.with_suffix("." + ext), lambda tmp, ext=ext: fig.savefig(tmp, format=ext, **vkw))


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


def _plt():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

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


def prescribed_axes(result) -> dict:
    """{set: the axes (1, 2) whose DOF the scenario's [[boundary]] prescribes (fixed or driven)} of a result: only
    there is −Σ f on the set a reaction; on a free DOF it is the set's small net force."""
    import json

    with open_result(result) as f:
        resolved = json.loads(f.attrs.get("resolved", "{}"))  # (results of other solvers: none)
    out: dict = {}
    for b in resolved.get("boundary") or []:
        for k, key in ((1, "x1"), (2, "x2")):
            if b.get(key) not in (None, "free"):
                out.setdefault(b["set"], set()).add(k)
    return out


def reaction_curves(c, tab, sets, prescribed) -> list:
    """(component, set, force in dyn) of the load–displacement panel: per monitored set the reaction on its
    prescribed axis that carries load (f2 of a loaded plate, f1 of the fixed side wall of a biaxial box; with two
    prescribed axes the larger); sets with no prescribed axis, or with no force on them, are left out.  If that
    leaves nothing (no [[boundary]] on the monitored sets), the f2 columns as they are."""
    out = []
    for s in sets:
        best = None
        for k in sorted(prescribed.get(s, ())):
            if f"f{k}:{s}" not in c:
                continue
            f = tab[:, c[f"f{k}:{s}"]]
            m = float(np.max(np.abs(f), initial=0.0))
            if m > 0.0 and (best is None or m > best[0]):
                best = (m, k, f)
        if best is not None:
            out.append((best[1], s, best[2]))
    return out or [(2, s, tab[:, c["f2:" + s]]) for s in sets]


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


def plot_history(result, png):
    plt = _plt()
    cols, tab = read_history(result)
    c = {n: i for i, n in enumerate(cols)}
    sets = sorted({n.split(":", 1)[1] for n in cols if n.startswith("f2:")})
    # the contact counts of the families the scene used (polygon contact, cohesive disks)
    counts = [k for k in ("n_contacts", "disk_contacts", "wall_contacts") if k in c]
    # the load panel is drawn against the displacement of the set that moves most: none moves (a pile on a
    # fixed floor) and it would be a vertical line, so it is left out
    if sets and max(np.ptp(tab[:, c["u2:" + s]]) for s in sets) == 0.0:
        sets = []
    nplot = 1 + (1 if counts else 0) + (1 if sets else 0)
    fig, axes = plt.subplots(1, nplot, figsize=(5 * nplot, 4), squeeze=False)
    axes = list(axes[0])
    t = tab[:, c["time"]]
    ax = axes.pop(0)
    pot = np.any(tab[:, c["potential"]])
    names = {  # the balance column says what it sums: read as "total energy", its zero line puzzled readers
        "external_work": "external work",
        "energy_total": "balance: Σ above − external work",
    }
    for k in ("kinetic", "elastic", "potential", "dissipated", "external_work", "energy_total"):
        if k == "potential" and not pot:
            continue  # no in-plane body force
        ax.plot(t, tab[:, c[k]], label=names.get(k, k))
    decade_axis(ax, "x", "t", "s")
    decade_axis(ax, "y", "energy", "erg")  # the power of ten in the label, not in a corner
    ax.legend(fontsize=8, loc="upper left")  # the work curves rise to the upper right
    ax.set_title("energies")
    if counts:
        ax = axes.pop(0)
        for k, style in zip(counts, ("k-", "k--", "k:")):
            ax.plot(t, tab[:, c[k]], style, label=k.replace("_", " ").replace("n contacts", "contacts"))
        decade_axis(ax, "x", "t", "s")
        ax.set_ylabel("number of contacts")
        from matplotlib.ticker import MaxNLocator

        top = max(float(tab[:, c[k]].max(initial=0.0)) for k in counts)
        ax.set_ylim(0.0, max(1.0, 1.05 * top))  # no contact yet: 0 and 1, not ±0.05
        ax.yaxis.set_major_locator(MaxNLocator(integer=True, min_n_ticks=1))  # counts: no fractional ticks
        if len(counts) > 1:
            ax.legend(fontsize=8)
        if "max_overlap_ratio" in c:
            ax2 = ax.twinx()
            ratio = tab[:, c["max_overlap_ratio"]]
            # in % where that reads (from 0.01 %); a smaller ratio as itself with its power of ten ([10⁻⁷], not a
            # "[10⁻⁵ %]" mixing a power of ten with a percent); never below 0 (an overlap has no sign)
            pct = float(np.max(ratio, initial=0.0)) >= 1e-4
            ax2.plot(t, 100 * ratio if pct else ratio, "r-")
            ax2.set_ylim(bottom=0.0)
            decade_axis(ax2, "y", "max $A_n$ / area of smaller particle", "%" if pct else "")
            ax2.yaxis.label.set_color("r")
        ax.set_title("contacts" if top > 0 else "contacts (none during the run)")
    if sets:
        ax = axes.pop(0)
        # abscissa: the displacement of the driven set (the monitored set that moves most in e2)
        drv = max(sets, key=lambda s: np.ptp(tab[:, c["u2:" + s]]))
        curves = reaction_curves(c, tab, sets, prescribed_axes(result))
        div, unit = force_unit(*[f for _, _, f in curves])
        for comp, s, f in curves:
            ax.plot(tab[:, c["u2:" + drv]], f / div, label=f"$f_{comp}$ on {s}")
        decade_axis(ax, "x", rf"$\hat u_2$ of {drv}", "cm")
        ax.set_ylabel(f2_label(unit) if all(comp == 2 for comp, _, _ in curves) else f"reaction on the set [{unit}]")
        ax.yaxis.get_major_formatter().set_useOffset(False)  # forces already in a readable unit
        ax.legend(fontsize=8)
        ax.set_title("load–displacement")
    fig.tight_layout()
    save(fig, png, dpi=120)
    plt.close(fig)


def bond_segments(X, pairs):
    """(m, 2, 2) straight lines between the centroids of bonded pairs at positions ``X`` (damage maps)."""
    return np.stack([X[pairs[:, 0], :2], X[pairs[:, 1], :2]], axis=1)


def marked_particles(static, points) -> list:
    """Indices of the particles nearest to each point (x, y) at t = 0 (the particles a close-up follows)."""
    x0 = static["x0"]
    return [int(np.argmin(np.hypot(x0[:, 0] - x, x0[:, 1] - y))) for x, y in points]


def plot_frames(result, png, times=None, max_panels=4, region=None, marks=()):
    """Particle outlines coloured by the e2 velocity (thesis Figs. 6.4, 6.8); large bodies (load
    plates) in grey.  One symmetric colour scale for all panels (the largest 99th percentile of |v2|
    over the panels, said on the colour bar; one colour bar), so that colours compare between times; on a bonded
    specimen its failed beams in black (the crack, visible at ``--magnify 1``).  ``region`` (x0, x1, y0,
    y1 in cm): a close-up of that window (Fig. 6.6); ``marks``: points (x, y) whose nearest particles at
    t = 0 are outlined thick and numbered 1, 2, ... in every panel, to follow them."""
    plt = _plt()
    from matplotlib.collections import LineCollection, PolyCollection

    static = read_static(result)
    steps, ftimes, X, V = read_frames(result)
    if times:
        idx = sorted({int(np.argmin(np.abs(ftimes - t))) for t in times})
    else:
        idx = sorted(set(np.linspace(0, len(ftimes) - 1, min(max_panels, len(ftimes))).round().astype(int)))
    radius = static["radius"]
    free = radius <= 4 * np.median(radius)
    marked = marked_particles(static, marks)
    # panels as high as the scene is (a wide pile between long plates is a flat strip) and a constrained layout:
    # the shared colour bar sits beside the last panel instead of at the far edge of an empty square figure
    if region is not None:
        shown = np.array([[region[0], region[2]], [region[1], region[3]]], float)
    else:
        shown = np.vstack(world_polygons(static, X[idx[0]]))
    height = panel_height(shown, 4.6, 1.2)
    fig, axes = plt.subplots(1, len(idx), figsize=(4.6 * len(idx) + 1.2, height), squeeze=False, layout="constrained")
    vmax = 0.0
    if V is not None:
        vmax = max(float(np.percentile(np.abs(V[k, free, 1]), 99)) for k in idx)
    bonds = read_bonds(result)  # a bonded specimen: its failed beams are the crack, drawn on every panel
    nfailed = []
    col = None
    for ax, k in zip(axes[0], idx):
        polys = world_polygons(static, X[k])
        ax.add_collection(
            PolyCollection(
                [p for p, f in zip(polys, free) if not f], facecolors="0.85", edgecolors="0.4", linewidths=0.4
            )
        )
        col = PolyCollection([p for p, f in zip(polys, free) if f], edgecolors="k", linewidths=0.3, cmap="coolwarm")
        if V is not None:
            col.set_array(V[k, free, 1])
            col.set_clim(-(vmax or 1.0), vmax or 1.0)
        ax.add_collection(col)
        if bonds is not None:
            broken = bonds["frame_d"][k] >= 1.0
            nfailed.append(int(broken.sum()))
            if broken.any():
                ax.add_collection(
                    LineCollection(bond_segments(X[k], bonds["pairs"][broken]), colors="k", linewidths=1.3, zorder=3)
                )
        for q, i in enumerate(marked):
            ax.add_collection(PolyCollection([polys[i]], facecolors="none", edgecolors="lime", linewidths=2.2))
            c = polys[i].mean(axis=0)
            ax.text(c[0], c[1], str(q + 1), ha="center", va="center", fontsize=9, fontweight="bold")
        if region is not None:
            ax.set_xlim(region[0], region[1])
            ax.set_ylim(region[2], region[3])
        else:
            p = np.vstack(polys)  # load plates included: never cropped
            pad = 0.04 * np.ptp(p, axis=0).max()
            ax.set_xlim(p[:, 0].min() - pad, p[:, 0].max() + pad)
            ax.set_ylim(p[:, 1].min() - pad, p[:, 1].max() + pad)
        ax.set_aspect("equal")
        label_axes_cm(ax)
        ax.set_title(
            f"t = {ftimes[k]:.4g} s" + (f", {nfailed[-1]} failed beams (black)" if bonds is not None else ""),
            fontsize=10,
        )
    if V is not None:
        # the scale ends at the 99th percentile of |v2| (a few escaping particles would wash out the rest): faster
        # particles draw at the end colours, the colour bar's arrows say so
        over = any(float(np.abs(V[k, free, 1]).max(initial=0.0)) > vmax for k in idx)
        lab = r"$\dot x_2$ [cm/s]" + (
            r" (scale to the 99th percentile of $|\dot x_2|$)" if vmax else " (all particles at rest)"
        )
        fig.colorbar(
            col, ax=axes[0].tolist(), shrink=0.9, pad=0.01, label=lab, extend="both" if over and vmax else "neither"
        )
    save(fig, png, dpi=130)
    plt.close(fig)


def _title(result):
    with open_result(result) as f:
        return str(f.attrs.get("title", ""))


def result_notes(result) -> tuple[list, int, int]:
    """What a partial result lacks: (notes, frames, history rows)."""
    import json

    from ..io.hdf5 import read_checkpoint

    notes = []
    with open_result(result) as f:
        status = str(f.attrs.get("status", ""))
        nframes = int(f["frames/x"].shape[0]) if "frames/x" in f else 0
        nrows = int(f["history/table"].shape[0]) if "history/table" in f else 0
        sm = json.loads(f.attrs["summary"]) if "summary" in f.attrs else {}
        ck = read_checkpoint(f)
        step = int(ck["step"][0]) if ck is not None else None
        of = str(f.attrs.get("snapshot_of", ""))
        last = f["history/table"][-1, :2] if nrows else None  # columns time, step
    end = sm.get("end_step")
    if of:
        at = f" at step {int(last[1]):,}, t = {last[0]:.6g} s" if last is not None else ""
        notes.append(
            f"{of}: still running: the figures show its state so far{at} (a snapshot, {Path(result).name}); "
            "report it again when the run has ended"
        )
    elif status == "running":
        at = f" at step {step:,}" + (f" of {end:,}" if end else "") if step is not None else ""
        notes.append(
            f"{result}: an interrupted run (status 'running'{at}): the figures show the part written "
            f"so far; continue it with: polydem run --resume {result}"
        )
    elif status == "failed":
        notes.append(
            f"{result}: the run failed ({sm.get('failure') or 'no reason recorded'}): the figures show "
            f"the run up to the failure"
        )
    if nframes < 2:
        notes.append(
            f"{result}: {nframes} frame(s): figures that compare frames (velocity arrows, states, damage "
            f"evolution) are left out"
        )
    if nrows < 3:
        notes.append(f"{result}: {nrows} history row(s): curves are left out")
    return notes, nframes, nrows


def make_report(result, out_dir=None, times=None, states=None, notes=None, formats=("png",), magnify=1.0) -> list:
    """All figures a result supports; returns the paths of the files written.

    ``formats``: png always, plus any of pdf, svg (each figure in each format); ``magnify``: displacement
    magnification of the particle pictures (bonded specimens deform by 1e-4 of their size).

    ``times``: frame times for particle snapshots; ``states``: prescribed displacements û2 of the
    states marked on the load curve and shown in damage maps (bonded results; default automatic).
    Partial results (interrupted, failed, one frame) get the figures their data allow; what is left
    out and why is appended to ``notes`` (a list) when given.
    """
    with _settings(formats, magnify) as extra:
        files = _make_report(result, out_dir, times, states, notes)
    return _with_formats(files, extra)


def make_closeup(result, out_dir=None, times=None, region=None, marks=(), formats=("png",), magnify=1.0) -> list:
    """Only the particle snapshots, in the window ``region`` (x0, x1, y0, y1) with the particles nearest to
    ``marks`` at t = 0 outlined and numbered: ``<stem>_closeup.png`` (thesis Fig. 6.6)."""
    result = Path(result)
    out_dir = Path(out_dir) if out_dir else result.parent
    out_dir.mkdir(parents=True, exist_ok=True)
    png = out_dir / f"{result.stem}_closeup.png"
    with _settings(formats, magnify) as extra:
        plot_frames(result, png, times, region=region, marks=marks)
    return _with_formats([png], extra)


def family_report(fam, result, out_dir=None, notes=None, formats=("png",)) -> list:
    """The figures of a result of another solver family (``fam.report``), drawn with this report's saver: the
    same extra formats and ``<figure>_plotted.csv`` beside every curve figure."""
    with _settings(formats) as extra:
        files = fam.report(result, out_dir, notes=notes, save=save)
    return _with_formats(files, extra)


def _with_formats(files, extra) -> list:
    """The files written plus the copies of every PNG figure in the ``extra`` formats (:func:`save`)."""
    files = [Path(f) for f in files]
    return files + [f.with_suffix("." + ext) for f in files for ext in extra if f.suffix == ".png"]


@contextmanager
def _settings(formats, magnify=1.0):
    """The report's extra formats and magnification for the figures drawn inside (reset afterwards); yields the
    extra formats."""
    global _EXTRA_FORMATS, _MAGNIFY
    extra = [f for f in formats if f != "png"]
    _EXTRA_FORMATS, _MAGNIFY = extra, float(magnify)
    try:
        yield extra
    finally:
        _EXTRA_FORMATS, _MAGNIFY = [], 1.0


def _make_report(result, out_dir, times, states, notes) -> list:
    from ..io.hdf5 import check_intact, read_bonds
    from . import bonds as rb

    result = Path(result)
    check_intact(result)  # a damaged block is reported, not plotted
    why, nframes, nrows = result_notes(result)
    if notes is not None:
        notes.extend(why)
    curves = nrows >= 3
    evolution = nframes >= 2
    out_dir = Path(out_dir) if out_dir else result.parent
    out_dir.mkdir(parents=True, exist_ok=True)
    stem = result.stem
    files = [out_dir / f"{stem}_frames.png"]
    plot_frames(result, files[0], times)
    from .specimen import plot_specimen

    files.append(plot_specimen(result, out_dir / f"{stem}_specimen.png", title=_title(result) or stem))
    if curves:
        files.insert(0, out_dir / f"{stem}_history.png")
        plot_history(result, files[0])
    from .granular import plot_velocity_arrows

    if evolution and plot_velocity_arrows(result, out_dir / f"{stem}_velocity.png", times) is not None:
        files.append(out_dir / f"{stem}_velocity.png")
    if curves and evolution and read_bonds(result) is not None and rb.load_curve(result) is not None:
        f = [out_dir / f"{stem}_load.png", out_dir / f"{stem}_damage.png", out_dir / f"{stem}_strains.png"]
        states = rb.plot_load_displacement(result, f[0], states)
        rb.plot_damage_maps(result, f[1], states)
        rb.plot_strain_maps(result, f[2], states[2] if len(states) > 2 else states[-1])
        files += f
    from . import macro as rm

    if curves and rm.macro_curve(result) is not None:
        f = out_dir / f"{stem}_stress_strain.png"
        rm.plot_stress_strain([(stem, result)], f, title=_title(result))
        files.append(f)
    if read_bonds(result) is not None:
        f = out_dir / f"{stem}_damage_end.png"
        rm.plot_damage_panels([(stem, result)], f, titles=["damage at the end of the run"], ncols=1)
        files.append(f)
        if rm.failure_records(result) is not None:
            f = out_dir / f"{stem}_failures.png"
            rm.plot_failure_counts([(stem, result)], f)
            files.append(f)
    return files


def overlay(results, out_dir, formats=("png",), notes=None) -> list:
    """Curves of several explicit results in one figure with a legend: σ22–ε22 when every result has
    macroscopic measures, else the load–displacement curves of their driven sets (bonded or loaded runs);
    results of another solver family (quasi-static) are overlaid among themselves by that family's ``overlay``
    (``overlay_quasistatic_load.png``), never mixed with explicit ones (said in ``notes``)."""
    from ..solvers import family_of_result
    from . import bonds as rb
    from . import macro as rm

    res, others = [], {}
    for r in results:
        r = Path(r)
        fam = family_of_result(r)
        if fam is not None:
            others.setdefault(fam, []).append(r)
            continue
        res.append(r)
    out_dir = Path(out_dir)
    files = []
    for fam, rs in others.items():  # results of another solver family: overlaid among themselves
        if len(rs) < 2 or not hasattr(fam, "overlay"):
            if notes is not None:
                notes.extend(f"{r}: no other result of its solver family to overlay it with" for r in rs)
            continue
        out_dir.mkdir(parents=True, exist_ok=True)
        with _settings(formats) as extra:
            png = out_dir / f"overlay_{fam.__name__.rsplit('.', 1)[-1]}_load.png"
            if fam.overlay(rs, png, save=save):
                files += _with_formats([png], extra)
            elif notes is not None:
                notes.append(f"overlay: fewer than two of {', '.join(map(str, rs))} have a load curve")
    if len(res) < 2:
        if res and notes is not None and others:
            notes.append(f"{res[0]}: the only explicit result; not overlaid with another family's")
        return files
    out_dir.mkdir(parents=True, exist_ok=True)
    with _settings(formats) as extra:
        if all(rm.macro_curve(r) is not None for r in res):
            png = out_dir / "overlay_stress_strain.png"
            rm.plot_stress_strain([(r.stem, r) for r in res], png, title="overlay")
        elif all(rb.load_curve(r) is not None for r in res):
            png = out_dir / "overlay_load.png"
            rb.plot_load_displacement(res[0], png, others=[(r.stem, r) for r in res[1:]])
        else:
            if notes is not None:
                notes.append("overlay: the results have no common curve (macroscopic measures or a driven set)")
            return files
    return files + _with_formats([png], extra)
