"""Figures of macroscopic measures (thesis Figs. 7.10, 7.12; §7.5.1) and bond damage at the end of
a run (Figs. 7.11, 7.13).

* stress–strain curves σ22 [N/mm²] against ε22 of one or several results, each with its peak
  marked; for a single result the fitted E and ν and the peak are annotated;
* the damage map of the last frame: every beam a line between the centroids coloured by d
  (grey = undamaged, dark red = failed; failed beams stay drawn);
* failed bonds by mode and orientation (bar chart from the run summary's records).

Stresses are converted from g cm⁻¹ s⁻² to N/mm² (1 N/mm² = 1e7).
"""

from __future__ import annotations

import json

import numpy as np

from ..analysis.macro import MPA, summarize
from ..interactions.bonds.failure import MODES, ORIENTATION_TOLERANCE_DEG, ORIENTATIONS, failure_table
from ..io.hdf5 import open_result, read_bonds, read_history
from .common import (
    PLAIN,
    _plt,
    bond_noun,
    bond_segments,
    damage_cmap,
    damage_widths,
    damage_word,
    decade_axis,
    headline,
    label_axes_cm,
    load_curve,
    panel_height,
    read_frames,
    save,
)


def macro_curve(result):
    """(eps22, sigma22 [N/mm^2], eps11, definition) of a result with [macro], else None."""
    cols, tab = read_history(result)
    if "sigma22" not in cols:
        return None
    c = {n: i for i, n in enumerate(cols)}
    with open_result(result) as f:
        sc = json.loads(f.attrs["resolved"])
    return tab[:, c["eps22"]], tab[:, c["sigma22"]] / MPA, tab[:, c["eps11"]], sc.get("macro") or {}


def plot_stress_strain(
    results, png, title=None, styles=None, annotate=True, reference=None, extra_lines=(), style=PLAIN
):
    """σ22–ε22 curves; ``results``: list of (label, path); ``styles``: matplotlib kwargs per curve;
    ``reference``: optional (label, eps, sigma [N/mm^2]) point of the source (e.g. the thesis's peak)."""
    plt = _plt()
    fig, ax = plt.subplots(figsize=(6.4, 4.6))
    summaries = []
    for i, (label, path) in enumerate(results):
        e2, s, e1, definition = macro_curve(path)
        fr = tuple(definition.get("fit_range", (0.1, 0.4)))
        summaries.append(summarize(s * MPA, e2, e1, fr))
        # a run that ended (at its safety limit) with the stress still at its largest has no peak: its last point
        # is a lower bound of the strength, drawn as an open marker and said in the legend
        reached = summaries[-1] is None or summaries[-1].get("peak_reached", True)
        kw = dict(lw=1.3)
        kw.update((styles or [{}] * len(results))[i] if styles else {})
        (line,) = ax.plot(e2, s, label=label if reached else f"{label} (peak not reached)", **kw)
        k = int(np.argmax(np.abs(s)))
        ax.plot(e2[k], s[k], "o", ms=5, color=line.get_color(), mfc=None if reached else "white")
    if annotate and len(results) == 1 and summaries[0] is not None:
        m = summaries[0]
        with open_result(results[0][1]) as f:  # a snapshot of a running result: its peak may be ahead
            running = "snapshot_of" in f.attrs
        if running or m.get("peak_reached", True):
            word = "largest so far" if running else "peak"
            txt = [f"{word} {m['peak_stress_MPa']:.3g} N/mm² at ε22 = {m['strain_at_peak']:.3g}"]
        else:  # the run ended before the stress turned: no strength, a lower bound of it
            txt = [
                f"peak not reached: strength |σ22| ≥ {abs(m['peak_stress_MPa']):.3g} N/mm²",
                f"(the run ended at ε22 = {m['strain_at_peak']:.3g} with the stress at its largest)",
            ]
        if m["E"] is not None:
            txt.insert(0, f"E = {m['E_GPa']:.3g} GPa, ν = {m['nu']:.3g}")
            e2, s, _, _ = macro_curve(results[0][1])
            x = np.linspace(0, m["strain_at_peak"] * 0.8, 2)
            ax.plot(
                x,
                x * m["E"] / MPA,
                "k:",
                lw=0.9,
                label=f"E fitted ({100 * m['fit_range'][0]:g}–{100 * m['fit_range'][1]:g} % of the peak)",
            )
        # beside the peak, away from the softening branch
        ax.text(
            0.98 if m["kind"] == "tension" else 0.98,
            0.80 if m["kind"] == "tension" else 0.20,
            "\n".join(txt),
            transform=ax.transAxes,
            ha="right",
            va="top" if m["kind"] == "tension" else "bottom",
            fontsize=9,
            bbox=dict(boxstyle="round", fc="white", ec="0.7"),
        )
    for lab, e, sg, kw in extra_lines:
        ax.plot(e, sg, label=lab, **kw)
    if reference is not None:
        lab, e, s = reference
        ax.plot([e], [s], "kx", ms=8, mew=1.5, label=lab)
    ax.axhline(0, color="0.6", lw=0.6)
    ax.set_ylabel(r"macroscopic stress $\sigma_{22} = f_2 / (L_1 T)$ [N/mm²]")
    decade_axis(ax, "x", r"macroscopic strain $\varepsilon_{22} = \hat u_2 / L_2$")  # [10⁻⁴], no corner offset
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8, loc="best")
    what = "macroscopic stress σ22 against strain ε22"
    ax.set_title(f"{what}\n{title}" if title else what, fontsize=9)
    fig.tight_layout()
    save(fig, png, style=style, dpi=150)
    plt.close(fig)
    return summaries


def plot_damage_panels(results, png, frame="last", titles=None, ncols=2, u2=None, style=PLAIN, title=None):
    """Damage maps of several results (one panel each) with one colour scale; ``frame``: 'last' or an
    index; ``u2``: instead, the frame nearest to this prescribed displacement of the driven set; ``title``: the
    figure's title (default: what the panels show and, for one result, its scenario's title)."""
    plt = _plt()
    from matplotlib.collections import LineCollection

    n = len(results)
    ncols = min(ncols, n)
    nrows = (n + ncols - 1) // ncols
    # panels as high as the specimen (the glued nuts are twice as wide as high) and a constrained layout, so that
    # the colour bar spans the panels instead of a square box
    from ..io.hdf5 import read_static

    height = panel_height(read_static(results[0][1])["x0"], 4.0, 0.8)  # + two title lines and the x label
    fig, axes = plt.subplots(
        nrows, ncols, figsize=(4.4 * ncols + 0.9, height * nrows), squeeze=False, layout="constrained"
    )
    for ax in axes.ravel()[n:]:
        ax.set_visible(False)
    lc = None
    words = set()  # the colour bar's and title's word: one for all panels, "bond damage" when they mix models
    for ax, (label, path), t in zip(axes.ravel(), results, titles or [None] * n):
        b = read_bonds(path)
        words.add(damage_word(b))
        steps, ftimes, X, _ = read_frames(path, style)
        k = len(ftimes) - 1 if frame == "last" else int(frame)
        if u2 is not None:
            u, f, drv, th = load_curve(path)
            kk = int(np.argmin(np.abs(u - u2)))
            k = int(np.argmin(np.abs(ftimes - th[kk])))
        d = b["frame_d"][k]
        order = np.argsort(d)  # damaged beams on top
        lc = LineCollection(
            bond_segments(X[k], b["pairs"])[order], cmap=damage_cmap(), linewidths=damage_widths(d[order], 0.9)
        )
        lc.set_array(d[order])
        lc.set_clim(0.0, 1.0)
        ax.add_collection(lc)
        ax.autoscale()
        ax.set_aspect("equal")
        label_axes_cm(ax, 8)
        nf = int(np.sum(d >= 1.0))
        ax.set_title(
            f"{t or label}\n$t$ = {ftimes[k]:.4g} s, {nf} failed, {int(np.sum((d > 0) & (d < 1)))} damaged", fontsize=9
        )
    word = words.pop() if len(words) == 1 else "bond damage (beams and edge interfaces)"
    fig.colorbar(lc, ax=axes.ravel().tolist(), label=word + r" $d$ [−]", shrink=0.9)
    if title is None:
        when = (
            "in the last frame"
            if u2 is None and frame == "last"
            else (f"at û2 = {u2:g} cm of the driven set" if u2 is not None else f"in frame {frame}")
        )
        title = (f"{word} d {when}", results[0][1] if n == 1 else None)
    headline(fig, *(title if isinstance(title, tuple) else (title,)))
    save(fig, png, style=style, dpi=150)
    plt.close(fig)


def failure_records(result):
    """Failure table of a bonded result (see :func:`failure_table`), or None."""
    b = read_bonds(result)
    if b is None or "fail_step" not in b:
        return None
    from ..io.hdf5 import read_static

    st = read_static(result)
    x0 = st["x0"]
    d = x0[b["pairs"][:, 1], :2] - x0[b["pairs"][:, 0], :2]
    L = np.hypot(d[:, 0], d[:, 1])
    with open_result(result) as f:
        dt = json.loads(f.attrs["resolved"])["time"]["dt"]
    return failure_table(b["fail_step"], b["fail_strain"], d[:, 0] / L, d[:, 1] / L, dt)


def plot_failure_counts(results, png, style=PLAIN, title=None):
    """Failed bonds by orientation, split by mode, for one or several results; ``title``: the figure's title
    (default: what it shows and, for one result, its scenario's title)."""
    from matplotlib.ticker import MaxNLocator

    plt = _plt()
    fig, ax = plt.subplots(figsize=(2.9 + 1.6 * len(results), 4.0))
    colors = {"tension": "#c0392b", "bending": "#8e44ad", "shear": "#2471a3"}
    width = 0.8 / len(ORIENTATIONS)
    xt, xl = [], []
    for r, (label, path) in enumerate(results):
        t = failure_records(path)
        for o, oname in enumerate(ORIENTATIONS):
            x = r + (o - 1) * width
            bottom = 0
            for m, mname in enumerate(MODES):
                c = int(np.sum((t["orientation"] == o) & (t["mode"] == m))) if t is not None else 0
                ax.bar(
                    x, c, width * 0.9, bottom=bottom, color=colors[mname], label=mname if (r == 0 and o == 0) else None
                )
                bottom += c
            ax.text(x, bottom, str(bottom), ha="center", va="bottom", fontsize=7)
            xt.append(x)
            xl.append(f"{oname[0].upper()}")
        ax.text(r, -0.12, label, transform=ax.get_xaxis_transform(), ha="center", va="top", fontsize=8)
    ax.set_xticks(xt)
    ax.set_xticklabels(xl, fontsize=7)
    noun = bond_noun([path for _, path in results])
    ax.set_ylabel(f"failed {noun}")
    ax.yaxis.set_major_locator(MaxNLocator(integer=True))  # counts
    ax.set_ylim(0, 1.12 * max(ax.get_ylim()[1], 1.0))  # room for the counts above the bars
    tol = ORIENTATION_TOLERANCE_DEG
    ax.set_title(
        f"{noun[:-1]} at t = 0 within {tol:g}° of H horizontal, V vertical,\nelse D diagonal; colour: mode of failure",
        fontsize=8,
    )
    ax.legend(fontsize=8, loc="upper left", bbox_to_anchor=(1.01, 1.0))  # beside the bars, never over a count
    headline(
        fig,
        title or f"failed {noun} by orientation and mode",
        results[0][1] if len(results) == 1 and title is None else None,
    )
    fig.tight_layout()
    save(fig, png, style=style, dpi=150)
    plt.close(fig)
