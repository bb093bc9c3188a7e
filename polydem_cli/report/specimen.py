"""The specimen as built (thesis Figs. 5.6, 6.3, 7.3, 7.9a): particle outlines at t = 0, beams if any, and
what the scenario perturbed — beams with a changed E_h (``[[perturb]]`` on a bond) and particles with a
changed k_n (``[[perturb]] at``) in red — with the particle, beam and perturbation counts in the title."""

from __future__ import annotations

import json
import textwrap

import numpy as np

from ..io.hdf5 import open_result, read_bonds, read_static
from .common import PLAIN, _plt, headline, label_axes_cm, panel_height, save, world_polygons


def perturbed_particles(st) -> np.ndarray:
    """Indices of the particles the result's ``[[perturb]]`` entries changed (resolved as the build does)."""
    from ..scenario.build import perturb_selection
    from ..scenario.spec import ScenarioError

    res = st["attrs"].get("resolved")
    entries = (json.loads(res).get("perturb") or []) if res else []
    group = st["group"]
    ranges = {}
    for gi, name in enumerate(st["group_names"]):
        members = np.flatnonzero(group == gi)
        if len(members):
            ranges[name] = (int(members[0]), int(members[-1]) + 1)
    out = set()
    for pi, pt in enumerate(entries):
        try:
            out.update(int(i) for i in perturb_selection(pt, st["x0"], st["sets"], ranges, "", f"perturb[{pi}]"))
        except (ScenarioError, KeyError):  # a set this result does not store: nothing to mark
            continue
    return np.array(sorted(out), dtype=int)


#: a specimen's beams are drawn over the whole specimen only while its cells are at least this wide on paper [in];
#: a finer network hides the cells under it, and its beams are drawn in a close-up of a few cells instead
BEAMS_MIN_CELL = 0.3
#: how many cells wide the close-up of a fine network is
CLOSEUP_CELLS = 6


def _closeup_window(x0, free, cells=CLOSEUP_CELLS):
    """(x0, x1, y0, y1) [cm]: a square of ``cells`` typical cell widths at the centre of the free particles."""
    p = x0[free, :2]
    lo, hi = p.min(axis=0), p.max(axis=0)
    w = cells * np.sqrt(np.prod(np.maximum(hi - lo, 1e-12)) / max(len(p), 1))
    c = 0.5 * (lo + hi)
    return c[0] - w / 2, c[0] + w / 2, c[1] - w / 2, c[1] + w / 2


def _panel_inches(ax) -> float:
    """The width [in] the panel will have on paper (its box in the figure as laid out so far)."""
    return ax.get_position().width * ax.figure.get_figwidth()


def specimen_panel(ax, path, title, params=None):
    """One specimen on ``ax``; ``params``: lines of text (parameters) drawn in a box beside the panel.

    The cells are drawn light with their outlines above the beams (thin lines between the centroids).  When the
    cells are narrower on paper than :data:`BEAMS_MIN_CELL`, the network would hide them: the panel draws the cells
    (and any perturbed beam) only and a close-up beside it shows a few cells with their beams (the window marked
    on the panel)."""
    from matplotlib.collections import LineCollection, PolyCollection
    from matplotlib.patches import Rectangle

    st = read_static(path)
    b = read_bonds(path)
    x0 = st["x0"]
    polys = world_polygons(st, x0)
    radius = st["radius"]
    big = radius > 4 * np.median(radius)  # load plates
    weak_p = perturbed_particles(st)
    face = np.where(big, "0.75", "0.93").astype(object)
    face[weak_p] = "#e74c3c"

    def cells(a):
        a.add_collection(PolyCollection(polys, facecolors=list(face), edgecolors="none", zorder=1))
        a.add_collection(PolyCollection(polys, facecolors="none", edgecolors="0.3", linewidths=0.5, zorder=3))

    cells(ax)
    what = [f"{int(np.sum(~big))} particles"]
    if big.any():
        what.append(f"{int(np.sum(big))} plates")
    handles = []
    closeup = None
    bond = "interface" if b is not None and "interface" in b else "beam"  # the bond model (io/hdf5.py /bonds)
    if b is not None:
        seg = np.stack([x0[b["pairs"][:, 0], :2], x0[b["pairs"][:, 1], :2]], axis=1)
        what.append(f"{len(b['pairs'])} {bond}s")
        free = ~big
        p = x0[free, :2]
        cell = float(np.sqrt(np.prod(np.maximum(np.ptp(p, axis=0), 1e-12)) / max(len(p), 1)))  # cm
        span = float(np.ptp(np.vstack(polys), axis=0).max())
        fine = cell / span * _panel_inches(ax) < BEAMS_MIN_CELL
        beams = LineCollection(
            seg, colors="tab:blue", linewidths=0.6, zorder=2, label=f"{bond} (drawn centroid to centroid)"
        )
        if fine:
            closeup = _closeup_window(x0, free)
        else:
            ax.add_collection(beams)
            handles.append(beams)
        E = b.get("E")
        weak = np.flatnonzero(E != np.median(E)) if E is not None else []
        if 0 < len(weak) <= max(3, 0.01 * len(E)):  # a few perturbed beams, not a random field
            f = float(np.median(E[weak] / np.median(E)))
            lc = LineCollection(
                seg[weak], colors="red", linewidths=2.0, zorder=4, label=rf"beam with $E_h \times$ {f:.3g}"
            )
            ax.add_collection(lc)
            handles.append(lc)
    if len(weak_p):
        from matplotlib.patches import Patch

        handles.append(Patch(facecolor="#e74c3c", edgecolor="0.45", label="perturbed particle (k_n)"))
    if handles:
        # below the panel: inside, it covered the end of the top plate (Fig. 6.3)
        ax.legend(handles=handles, fontsize=7, loc="upper center", bbox_to_anchor=(0.5, -0.13), ncol=len(handles))
    ax.autoscale()
    ax.set_aspect("equal")
    label_axes_cm(ax, 8)
    # a long scenario title is wrapped and the counts get a line of their own, so the title stays over its panel
    head = f"{title}: {', '.join(what)}" if title else ", ".join(what)
    if len(head) > 50 and title:
        head = "\n".join(textwrap.wrap(title, 50, break_on_hyphens=False)) + "\n" + ", ".join(what)
    ax.set_title(head, fontsize=9)
    if params:
        ax.text(
            1.03,
            1.0,
            "\n".join(params),
            transform=ax.transAxes,
            va="top",
            ha="left",
            fontsize=7,
            family="monospace",
            bbox={"facecolor": "white", "edgecolor": "0.7"},
        )
    if closeup is not None:
        x_0, x_1, y_0, y_1 = closeup
        ax.add_patch(Rectangle((x_0, y_0), x_1 - x_0, y_1 - y_0, fill=False, ec="k", lw=1.2, zorder=5))
        # beside the panel, right of the parameters' box (its width on paper: the longest line in 7 pt monospace)
        box = 0.0 if not params else (max(len(t) for t in params) + 2) * 0.6 * 7 / 72 / _panel_inches(ax)
        ins = ax.inset_axes((1.06 + box, 0.0, 0.5, 0.5))
        cells(ins)
        mid = seg.mean(axis=1)
        inside = (mid[:, 0] >= x_0) & (mid[:, 0] <= x_1) & (mid[:, 1] >= y_0) & (mid[:, 1] <= y_1)
        near = LineCollection(seg[inside], colors="tab:blue", linewidths=1.0, zorder=2)
        ins.add_collection(near)
        ins.set_xlim(x_0, x_1)
        ins.set_ylim(y_0, y_1)
        ins.set_aspect("equal")
        ins.tick_params(labelsize=6)
        ins.set_title(
            f"close-up (black square):\ncells and their {bond}s\n(blue, centroid to centroid;\n{int(inside.sum())} here)",
            fontsize=7,
            loc="left",
        )


def bond_parameters(path) -> list:
    """Text lines of the bond parameters of a bonded result — edge interfaces' own keys for ``model = "interface"``,
    else the beams' — (the thesis's parameter tables, Figs. 5.6b, 7.9b) in the
    units a reader of concrete data reads (:data:`SHOWN`: E in GPa, G_ax in N/m); the phases of a mesoscale specimen
    (``[bonds.aggregate]``, ``[bonds.interface]``) with the values they change."""
    with open_result(path) as f:
        sc = json.loads(f.attrs["resolved"])
    bd = sc.get("bonds") or {}
    out = []
    if bd.get("model") == "interface":  # edge interfaces (interactions/bonds/interface.py): their own keys
        keys = ("E", "nu", "f_t", "cohesion", "friction", "residual_friction", "G_I", "G_II", "compressive_cap")
        out = ["edge interfaces:"] + [
            _parameter_line(k, bd[k], 18)
            for k in keys
            if isinstance(bd.get(k), (int, float)) and not isinstance(bd.get(k), bool)
        ]
        return out + [f"{'elements':18s}{bd.get('elements') or 3}"]
    for key in ("E", "nu", "kappa_0", "G_ax", "kappa_m", "alpha", "eps0_dot", "rate_filter"):
        v = bd.get(key)
        if isinstance(v, (int, float)) and not isinstance(v, bool) and not (key == "rate_filter" and v == 0):
            out.append(_parameter_line(key, v))
    if bd.get("rate_dependent"):
        out.append("rate-dependent (5.13)")
    for phase in ("aggregate", "interface"):
        ph = bd.get(phase) or {}
        given = [(k, v) for k, v in ph.items() if isinstance(v, (int, float)) and not isinstance(v, bool)]
        if given:
            out.append(f"{phase} beams:")
            out += ["  " + _parameter_line(k, v, 7) for k, v in given]
    return out


#: how each beam parameter is shown: (divisor from the scenario's cm-g-s value, unit); E in GPa (1 GPa = 1e10
#: g/(cm s²)), G_ax in N/m = J/m² (1 N/m = 1e3 g/s²), a time in µs; the dimensionless ones as they are
SHOWN = {
    "E": (1.0e10, "GPa"),
    "G_ax": (1.0e3, "N/m"),
    "G_I": (1.0e3, "N/m"),
    "G_II": (1.0e3, "N/m"),
    "f_t": (1.0e7, "MPa"),
    "cohesion": (1.0e7, "MPa"),
    "compressive_cap": (1.0e7, "MPa"),
    "eps0_dot": (1.0, "1/s"),
    "rate_filter": (1.0e-6, "µs"),
}


def _parameter_line(key, v, width=9) -> str:
    div, unit = SHOWN.get(key, (1.0, ""))
    return f"{key:{width}s}{v / div:.4g} {unit}".rstrip()


def plot_specimen(result, png, title=None, style=PLAIN):
    """The specimen at t = 0 with its beams and what ``[[perturb]]`` changed, beside a table of its bond parameters
    (bonded results); titled with what it shows and ``title`` (default: the result's scenario title)."""
    plt = _plt()
    params = bond_parameters(result) if read_bonds(result) is not None else None
    # as high as the specimen (a pile between long plates is a strip), room for the titles and the parameters
    pts = np.vstack(world_polygons(read_static(result), read_static(result)["x0"]))
    high = max(panel_height(pts, 5.0, 1.4), 0.13 * len(params or ()) + 1.4)
    fig, ax = plt.subplots(figsize=((8.4 + 0.08 * max(len(t) for t in params)) if params else 5.6, high))
    specimen_panel(ax, result, "", params)
    bond = "interface" if params and params[0] == "edge interfaces:" else "beam"
    headline(
        fig,
        "the specimen as built (t = 0)" + (f": cells, {bond}s and {bond} parameters" if params else ""),
        title or result,
    )
    fig.tight_layout()
    save(fig, png, style=style, dpi=150)
    plt.close(fig)
    return png
