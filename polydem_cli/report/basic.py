"""The figures of any explicit result: history curves and particle snapshots (the toolbox they use:
:mod:`.common`; which figures a result gets: :mod:`.make`)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ..io.hdf5 import open_result, read_bonds, read_history, read_static
from .common import (
    PLAIN,
    _plt,
    bond_noun,
    bond_segments,
    decade_axis,
    f2_label,
    force_unit,
    headline,
    label_axes_cm,
    panel_height,
    read_frames,
    save,
    world_polygons,
)

#: erg per joule (energies are stored in erg, the cm-g-s unit; drawn in J)
ERG_PER_J = 1.0e7


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


def plot_history(result, png, style=PLAIN):
    """History figure of a result: the energies and the energy balance, the loads and displacements of the
    monitored sets and the contact counts, against time."""
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
        ax.plot(t, tab[:, c[k]] / ERG_PER_J, label=names.get(k, k))
    decade_axis(ax, "x", "t", "s")
    decade_axis(ax, "y", "energy", "J")  # the power of ten in the label, not in a corner
    ax.legend(fontsize=8, loc="upper left")  # the work curves rise to the upper right
    ax.set_title("energies")
    if counts:
        ax = axes.pop(0)
        for k, line in zip(counts, ("k-", "k--", "k:")):
            ax.plot(t, tab[:, c[k]], line, label=k.replace("_", " ").replace("n contacts", "contacts"))
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
        ax.set_title(f"load–displacement of {drv}")
    shown = ["energies"] + (["contacts"] if counts else []) + (["loads"] if sets else [])
    headline(
        fig, "history of the run: " + ", ".join(shown) + " against time" + (" and displacement" if sets else ""), result
    )
    fig.tight_layout()
    save(fig, png, style=style, dpi=120)
    plt.close(fig)


def marked_particles(static, points) -> list:
    """Indices of the particles nearest to each point (x, y) at t = 0 (the particles a close-up follows)."""
    x0 = static["x0"]
    return [int(np.argmin(np.hypot(x0[:, 0] - x, x0[:, 1] - y))) for x, y in points]


def plot_frames(result, png, times=None, max_panels=4, region=None, marks=(), style=PLAIN):
    """Particle outlines coloured by the e2 velocity (thesis Figs. 6.4, 6.8); large bodies (load
    plates) in grey.  One symmetric colour scale for all panels (the largest 99th percentile of |v2|
    over the panels, said on the colour bar; one colour bar), so that colours compare between times; on a bonded
    specimen its failed beams in black (the crack, visible at ``--magnify 1``).  ``region`` (x0, x1, y0,
    y1 in cm): a close-up of that window (Fig. 6.6); ``marks``: points (x, y) whose nearest particles at
    t = 0 are outlined thick and numbered 1, 2, ... in every panel, to follow them."""
    plt = _plt()
    from matplotlib.collections import LineCollection, PolyCollection

    static = read_static(result)
    steps, ftimes, X, V = read_frames(result, style)
    radius = static["radius"]
    free = radius <= 4 * np.median(radius)
    bonds = read_bonds(result)  # a bonded specimen: its failed beams are the crack, drawn on every panel
    if times:
        idx = sorted({int(np.argmin(np.abs(ftimes - t))) for t in times})
    else:
        idx = _telling_frames(len(ftimes), V, free, max_panels)
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
        rest = V is not None and not np.any(V[k, free, :2])
        ax.set_title(
            f"t = {ftimes[k]:.4g} s"
            + (f", {nfailed[-1]} failed {bond_noun([result])} (black)" if bonds is not None else "")
            + (", all particles at rest" if rest else ""),
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
    what = "particles coloured by their velocity in e2" + (
        f", failed {bond_noun([result])} black" if bonds is not None else ""
    )
    if region is not None:
        what = f"close-up of x1 {region[0]:g}…{region[1]:g} cm, x2 {region[2]:g}…{region[3]:g} cm: " + what
    if marked:
        pts = ", ".join(f"({x:g}, {y:g})" for x, y in marks)
        what += f"; outlined green and numbered 1–{len(marked)}: the particles nearest to {pts} cm at t = 0"
    headline(fig, what, result)
    save(fig, png, style=style, dpi=130)
    plt.close(fig)


def _telling_frames(nframes, V, free, max_panels) -> list:
    """Frame indices of the snapshots when none are asked for: evenly spread over the frames that show something —
    a frame in which every particle is at rest (the specimen as built at t = 0: its own figure,
    ``*_specimen.png``) shows a uniform zero colour and no crack, and is left out unless no frame moves —
    with the last frame always among them."""
    pool = list(range(nframes))
    if V is not None:
        pool = [k for k in pool if np.any(V[k][free, :2])] or pool
    pick = np.linspace(0, len(pool) - 1, min(max_panels, len(pool))).round().astype(int)
    return sorted({pool[i] for i in pick})


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
