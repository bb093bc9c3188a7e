"""The report's dispatcher, at the top of report/: which figures a result supports (``polydem report``), the
close-up, another solver family's figures, the overlay of several results."""

from __future__ import annotations

from functools import partial
from pathlib import Path

from ..engine.families import FAMILIES
from ..io.hdf5 import check_intact, read_bonds, result_groups
from ..solvers import family_of_result
from . import basic
from . import bonds as rb
from . import macro as rm
from .basic import _title, result_notes
from .common import Style, damage_word, load_curve, save
from .granular import plot_velocity_arrows
from .specimen import plot_specimen


def make_report(result, out_dir=None, times=None, states=None, notes=None, formats=("png",), magnify=1.0) -> list:
    """All figures a result supports; returns the paths of the files written.

    ``formats``: png always, plus any of pdf, svg (each figure in each format); ``magnify``: displacement
    magnification of the particle pictures (bonded specimens deform by 1e-4 of their size).

    ``times``: frame times for particle snapshots; ``states``: prescribed displacements û2 of the
    states marked on the load curve and shown in damage maps (bonded results; default automatic).
    Partial results (interrupted, failed, one frame) get the figures their data allow; what is left
    out and why is appended to ``notes`` (a list) when given.
    """
    style = Style.of(formats, magnify)
    return _with_formats(_make_report(result, out_dir, times, states, notes, style), style)


def make_closeup(result, out_dir=None, times=None, region=None, marks=(), formats=("png",), magnify=1.0) -> list:
    """Only the particle snapshots, in the window ``region`` (x0, x1, y0, y1) with the particles nearest to
    ``marks`` at t = 0 outlined and numbered: ``<stem>_closeup.png`` (thesis Fig. 6.6)."""
    result = Path(result)
    out_dir = Path(out_dir) if out_dir else result.parent
    out_dir.mkdir(parents=True, exist_ok=True)
    png = out_dir / f"{result.stem}_closeup.png"
    style = Style.of(formats, magnify)
    basic.plot_frames(result, png, times, region=region, marks=marks, style=style)
    return _with_formats([png], style)


def family_report(fam, result, out_dir=None, notes=None, formats=("png",)) -> list:
    """The figures of a result of another solver family (``fam.report``), drawn with this report's saver: the
    same extra formats and ``<figure>_plotted.csv`` beside every curve figure."""
    style = Style.of(formats)
    return _with_formats(fam.report(result, out_dir, notes=notes, save=partial(save, style=style)), style)


def _with_formats(files, style) -> list:
    """The files written plus the copies of every PNG figure in the style's extra formats (:func:`save`)."""
    files = [Path(f) for f in files]
    return files + [f.with_suffix("." + ext) for f in files for ext in style.formats if f.suffix == ".png"]


def _make_report(result, out_dir, times, states, notes, style) -> list:

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
    basic.plot_frames(result, files[0], times, style=style)

    files.append(plot_specimen(result, out_dir / f"{stem}_specimen.png", title=_title(result) or stem, style=style))
    if curves:
        files.insert(0, out_dir / f"{stem}_history.png")
        basic.plot_history(result, files[0], style=style)

    if evolution and plot_velocity_arrows(result, out_dir / f"{stem}_velocity.png", times, style=style) is not None:
        files.append(out_dir / f"{stem}_velocity.png")
    if curves and rm.macro_curve(result) is not None:
        f = out_dir / f"{stem}_stress_strain.png"
        rm.plot_stress_strain([(stem, result)], f, title=_title(result), style=style)
        files.append(f)
    held = result_groups(result)
    for fam in FAMILIES:  # each interaction family says which figures its records support
        if fam.figures and fam.result_group in held:
            for name in fam.figures:
                files += FIGURES[name](
                    result, out_dir / stem, states=states, curves=curves, evolution=evolution, style=style
                )
    return files


def _load_damage_strains(result, base, states, curves, evolution, style) -> list:
    """Load–displacement curve with marked states, damage and strain maps at those states (bonded runs with a
    driven set; thesis Figs. 5.8–5.11)."""
    if not (curves and evolution and load_curve(result) is not None):
        return []
    f = [Path(f"{base}_load.png"), Path(f"{base}_damage.png"), Path(f"{base}_strains.png")]
    states = rb.plot_load_displacement(result, f[0], states, style=style)
    rb.plot_damage_maps(result, f[1], states, style=style)
    rb.plot_strain_maps(result, f[2], states[2] if len(states) > 2 else states[-1], style=style)
    return f


def _damage_end(result, base, style, **_) -> list:
    """The beams' damage at the end of the run."""
    f = Path(f"{base}_damage_end.png")
    rm.plot_damage_panels(
        [(base.name, result)],
        f,
        titles=["damage at the end of the run"],
        ncols=1,
        style=style,
        title=(f"{damage_word(read_bonds(result))} d at the end of the run", result),
    )
    return [f]


def _failures(result, base, style, **_) -> list:
    """Failed beams by mode and orientation (when the result records failures)."""
    if rm.failure_records(result) is None:
        return []
    f = Path(f"{base}_failures.png")
    rm.plot_failure_counts([(base.name, result)], f, style=style)
    return [f]


#: how to draw each figure an interaction family names in ``Family.figures``: (result, out_dir / stem, states=,
#: curves=, evolution=, style=) -> the files written (none when the result's data do not allow it)
FIGURES = {"load_damage_strains": _load_damage_strains, "damage_end": _damage_end, "failures": _failures}


def overlay(results, out_dir, formats=("png",), notes=None) -> list:
    """Curves of several explicit results in one figure with a legend: σ22–ε22 when every result has
    macroscopic measures, else the load–displacement curves of their driven sets (bonded or loaded runs);
    results of another solver family (quasi-static) are overlaid among themselves by that family's ``overlay``
    (``overlay_quasistatic_load.png``), never mixed with explicit ones (said in ``notes``)."""

    style = Style.of(formats)
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
        png = out_dir / f"overlay_{fam.__name__.rsplit('.', 1)[-1]}_load.png"
        if fam.overlay(rs, png, save=partial(save, style=style)):
            files += _with_formats([png], style)
        elif notes is not None:
            notes.append(f"overlay: fewer than two of {', '.join(map(str, rs))} have a load curve")
    if len(res) < 2:
        if res and notes is not None and others:
            notes.append(f"{res[0]}: the only explicit result; not overlaid with another family's")
        return files
    out_dir.mkdir(parents=True, exist_ok=True)
    if all(rm.macro_curve(r) is not None for r in res):
        png = out_dir / "overlay_stress_strain.png"
        rm.plot_stress_strain(
            [(r.stem, r) for r in res], png, title="overlay of " + ", ".join(r.stem for r in res), style=style
        )
    elif all(load_curve(r) is not None for r in res):
        png = out_dir / "overlay_load.png"
        rb.plot_load_displacement(res[0], png, others=[(r.stem, r) for r in res[1:]], style=style)
    else:
        if notes is not None:
            notes.append("overlay: the results have no common curve (macroscopic measures or a driven set)")
        return files
    return files + _with_formats([png], style)
