"""Figures of bonded specimens (thesis Figs. 5.7–5.13, 5.17–5.21).

* load–displacement curve f2 against û2 of the driven set, with marked states
  (z1–z4 in tension, d1–d4 in compression);
* damage maps: every beam drawn as a straight line between the centroids,
  coloured by its damage d (neutral grey d = 0 to dark red d = 1, ``macro.damage_cmap``); failed
  beams stay drawn at half the width (they carry nothing), particle outlines omitted;
* strain maps at one state: ε_v, ε_ax,M (compression purple, tension orange), |ϰ_M| H_h/2, |γ_M|.

Forces are plotted in the unit system of the run (dyn); 1 N = 1e5 dyn.
"""

from __future__ import annotations

import numpy as np

from ..io.hdf5 import read_bonds
from .common import (
    PLAIN,
    _plt,
    bond_segments,
    damage_cmap,
    damage_widths,
    damage_word,
    f2_label,
    force_unit,
    headline,
    label_axes_cm,
    load_curve,
    read_frames,
    result_name,
    save,
)


def auto_states(u, f):
    """Four states like the thesis's: 90 % of the peak before it (the curve is already clearly
    nonlinear), the peak, 75 % of the peak after it, and the end of the run (displacements)."""
    a = np.abs(f)
    k = int(np.argmax(a))
    pre = np.flatnonzero(a[: k + 1] >= 0.9 * a[k])
    post = np.flatnonzero(a[k:] <= 0.75 * a[k])
    s1 = u[pre[0]] if len(pre) else u[k // 2]
    s3 = u[k + post[0]] if len(post) else u[(k + len(u) - 1) // 2]
    return [float(s1), float(u[k]), float(s3), float(u[-1])]


def _state_labels(u_states):
    prefix = "z" if np.sum(u_states) >= 0 else "d"
    return [f"({prefix}{i + 1})" for i in range(len(u_states))]


def state_notes(u, f, u_states) -> list:
    """What each marked state of the load curve is, for the figures that label panels or points with (z1)… (the
    thesis's names: z tension, d compression): where it lies against the peak and its load as a share of the peak,
    e.g. "before the peak, 90 % of the peak load", "the peak", "end of the run, 12 % of the peak load"."""
    a = np.abs(np.asarray(f, float))
    kp = int(np.argmax(a))
    out = []
    for s in u_states:
        k = int(np.argmin(np.abs(np.asarray(u) - s)))
        share = f"{100 * a[k] / a[kp]:.0f} % of the peak load" if a[kp] > 0 else "no load"
        if k == kp:
            note = "the peak load"
        elif k < kp:
            note = f"before the peak, {share}"
        else:
            note = f"after the peak, {share}"
        if k == len(a) - 1:
            note = "end of the run, " + note.replace("after the peak, ", "")
        out.append(note)
    return out


def _state_legend(ax, u, f, u_states):
    """A key of the marked states on the panel, "(z1) before the peak, 90 % of the peak load", one line each under
    a head saying what the letters mean, placed where it covers the least of the curves."""
    from matplotlib.lines import Line2D

    labels = _state_labels(u_states)
    kind = "tension" if labels and labels[0].startswith("(z") else "compression"
    rows = [f"{lab} {note}" for lab, note in zip(labels, state_notes(u, f, u_states))]
    blank = [Line2D([], [], ls="none", marker="o", color="r", ms=4) for _ in rows]
    return ax.legend(
        blank,
        rows,
        title=f"marked states of the {kind} curve",
        fontsize=8,
        title_fontsize=8,
        loc="best",
        handlelength=0.8,
    )


def plot_load_displacement(result, png, states=None, others=(), style=PLAIN):
    """f2–û2 curve with marked states, each explained in a key on the figure; titled with the driven set and the
    run; ``others``: further (label, result) curves (parameter studies)."""
    plt = _plt()
    u, f, drv, t = load_curve(result)
    states = states or auto_states(u, f)
    labels = _state_labels(states)
    fig, ax = plt.subplots(figsize=(6, 4.9))
    curves = [(lab, load_curve(other)[:2]) for lab, other in others]
    div, unit = force_unit(f, *[fo for _, (_, fo) in curves])
    ax.plot(u, f / div, "k-", lw=1.2, label=str(result.stem) if hasattr(result, "stem") else "run")
    for lab, (uo, fo) in curves:
        ax.plot(uo, fo / div, lw=1.0, label=lab)
    for s, lab in zip(states, labels):
        k = int(np.argmin(np.abs(u - s)))
        ax.plot(u[k], f[k] / div, "ro", ms=5)
        ax.annotate(lab, (u[k], f[k] / div), textcoords="offset points", xytext=(6, 6), fontsize=9)
    if others:
        ax.add_artist(ax.legend(fontsize=8, loc="lower right"))
    _state_legend(ax, u, f, states)
    ax.set_xlabel(rf"$\hat u_2$ of {drv} [cm]")
    ax.set_ylabel(f2_label(unit, f"reaction on {drv}"))
    ax.grid(alpha=0.3)
    if others:
        headline(
            fig,
            f"load–displacement of the driven set {drv}",
            "overlay of " + ", ".join([str(getattr(result, "stem", result))] + [lab for lab, _ in others]),
        )
    else:
        headline(fig, f"load–displacement of the driven set {drv}", result)
    fig.tight_layout()
    save(fig, png, style=style, dpi=130)
    plt.close(fig)
    return states


def _frame_index_for(result, u_states, style=PLAIN):
    u, f, drv, t = load_curve(result)
    steps, ftimes, X, V = read_frames(result, style)
    out = []
    for s in u_states:
        k = int(np.argmin(np.abs(u - s)))
        out.append(int(np.argmin(np.abs(ftimes - t[k]))))
    return out, X, ftimes


def plot_damage_maps(result, png, states=None, style=PLAIN):
    """Damage d of every beam drawn on the specimen at the marked states of the load curve (thesis Fig. 5.9)."""
    plt = _plt()
    from matplotlib.collections import LineCollection

    b = read_bonds(result)
    u, f, drv, t = load_curve(result)
    states = states or auto_states(u, f)
    idx, X, ftimes = _frame_index_for(result, states, style)
    labels = _state_labels(states)
    notes = state_notes(u, f, states)
    ncol = 2 if len(idx) == 4 else len(idx)
    nrow = (len(idx) + ncol - 1) // ncol
    fig, axes = plt.subplots(nrow, ncol, figsize=(4.6 * ncol + 1.0, 4.6 * nrow + 0.5), squeeze=False)
    for ax in axes.ravel()[len(idx) :]:
        ax.set_visible(False)
    for ax, k, lab, note in zip(axes.ravel(), idx, labels, notes):
        d = b["frame_d"][k]
        order = np.argsort(d, kind="stable")  # damaged beams on top
        lc = LineCollection(
            bond_segments(X[k], b["pairs"])[order], cmap=damage_cmap(), linewidths=damage_widths(d[order], 0.8)
        )
        lc.set_array(d[order])
        lc.set_clim(0.0, 1.0)
        ax.add_collection(lc)
        ax.autoscale()
        ax.set_aspect("equal")
        label_axes_cm(ax)
        ax.set_title(
            f"{lab} {note}\n" + rf"$t$ = {ftimes[k]:.4g} s, $\hat u_2$ = {u[np.argmin(np.abs(t - ftimes[k]))]:.3g} cm",
            fontsize=9,
        )
    word = damage_word(b)
    fig.colorbar(lc, ax=axes.ravel().tolist(), label=word + r" $d$ [−]", shrink=0.85)
    headline(
        fig,
        f"{word} at the states {labels[0]}–{labels[-1]} of the load–displacement curve of {drv}"
        if len(labels) > 1
        else f"{word} at the state {labels[0]} of the load curve of {drv}",
        result,
    )
    save(fig, png, style=style, dpi=130)
    plt.close(fig)


def plot_strain_maps(result, png, state=None, style=PLAIN):
    """The mid-span strain parts of every beam (axial, bending, shear; thesis Figs. 5.10–5.11) at one state."""
    plt = _plt()
    from matplotlib.collections import LineCollection

    b = read_bonds(result)
    u, f, drv, t = load_curve(result)
    if state is None:
        state = auto_states(u, f)[2]
    (k,), X, ftimes = _frame_index_for(result, [state], style)
    s = b["frame_strain"][k]
    # white at zero (small strains disappear into the paper, as the thesis's maps); the scale ends at the 99.5th
    # percentile so that the few beams of an open crack do not squash the rest (those draw at the end colour,
    # the colour bar's arrow says so)
    panels = [
        (
            r"equivalent strain $\varepsilon_v = \langle\varepsilon_{ax,M} + |\varkappa_M| H_h/2\rangle + |\gamma_M|$",
            s[:, 3],
            "magma_r",
            (0, None),
        ),
        (r"axial strain $\varepsilon_{ax,M}$ (compression purple, tension orange)", s[:, 0], "PuOr_r", "sym"),
        (r"bending: curvature $\times$ half height, $|\varkappa_M| H_h/2$", s[:, 1], "magma_r", (0, None)),
        (r"shear strain $|\gamma_M|$", s[:, 2], "magma_r", (0, None)),
    ]
    vmax = float(np.percentile(np.abs(s[:, 3]), 99.5)) or float(np.max(np.abs(s[:, 3]))) or 1.0
    # constrained layout: the colour bars' labels must not run into the next panel's axis label
    fig, axes = plt.subplots(2, 2, figsize=(9.5, 8.5), layout="constrained")
    for ax, (title, val, cmap, lim) in zip(axes.ravel(), panels):
        lc = LineCollection(bond_segments(X[k], b["pairs"]), cmap=cmap, linewidths=0.8)
        lc.set_array(val)
        if lim == "sym":
            m = float(np.percentile(np.abs(val), 99.5)) or float(np.max(np.abs(val))) or 1.0
            lc.set_clim(-m, m)
            top = float(np.max(np.abs(val))) > m
        else:
            lc.set_clim(0.0, vmax)
            top = float(np.max(val)) > vmax
        ax.add_collection(lc)
        ax.autoscale()
        ax.set_aspect("equal")
        label_axes_cm(ax, 7)
        ax.set_title(title + " [−]", fontsize=10)
        cb = fig.colorbar(lc, ax=ax, shrink=0.8, extend=("both" if lim == "sym" else "max") if top else "neither")
        cb.formatter.set_powerlimits((-2, 3))  # short tick labels with a power-of-ten factor on top
        cb.update_ticks()
    fig.suptitle(
        rf"beam strains at mid-span, $\hat u_2$ of {drv} = {u[np.argmin(np.abs(u - state))]:.3g} cm "
        rf"($t$ = {ftimes[k]:.4g} s: {state_notes(u, f, [state])[0]})"
        "\n"
        r"$\varepsilon_v$, $|\varkappa_M| H_h/2$, $|\gamma_M|$ on one scale (to the 99.5th percentile of $\varepsilon_v$)"
        "\n" + result_name(result),
        fontsize=10,
    )
    save(fig, png, style=style, dpi=130)
    plt.close(fig)
