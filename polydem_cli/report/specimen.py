"""The specimen as built (thesis Figs. 5.6, 6.3, 7.3, 7.9a): particle outlines at t = 0, beams if any, and
what the scenario perturbed — beams with a changed E_h (``[[perturb]]`` on a bond) and particles with a
changed k_n (``[[perturb]] at``) in red — with the particle, beam and perturbation counts in the title."""

from __future__ import annotations

import json
import textwrap

import numpy as np

from ..io.hdf5 import open_result, read_bonds, read_static
from .common import PLAIN, _plt, label_axes_cm, save, world_polygons


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


def specimen_panel(ax, path, title, params=None):
    """One specimen on ``ax``; ``params``: lines of text (parameters) drawn in a box below the title."""
    from matplotlib.collections import LineCollection, PolyCollection

    st = read_static(path)
    b = read_bonds(path)
    x0 = st["x0"]
    polys = world_polygons(st, x0)
    radius = st["radius"]
    big = radius > 4 * np.median(radius)  # load plates
    weak_p = perturbed_particles(st)
    face = np.where(big, "0.75", "0.93").astype(object)
    face[weak_p] = "#e74c3c"
    ax.add_collection(PolyCollection(polys, facecolors=list(face), edgecolors="0.45", linewidths=0.4))
    what = [f"{int(np.sum(~big))} particles"]
    if big.any():
        what.append(f"{int(np.sum(big))} plates")
    handles = []
    if b is not None:
        seg = np.stack([x0[b["pairs"][:, 0], :2], x0[b["pairs"][:, 1], :2]], axis=1)
        ax.add_collection(LineCollection(seg, colors="tab:blue", linewidths=0.6))
        what.append(f"{len(b['pairs'])} beams")
        E = b.get("E")
        weak = np.flatnonzero(E != np.median(E)) if E is not None else []
        if 0 < len(weak) <= max(3, 0.01 * len(E)):  # a few perturbed beams, not a random field
            f = float(np.median(E[weak] / np.median(E)))
            lc = LineCollection(seg[weak], colors="red", linewidths=2.0, label=rf"beam with $E_h \times$ {f:.3g}")
            ax.add_collection(lc)
            handles.append(lc)
    if len(weak_p):
        from matplotlib.patches import Patch

        handles.append(Patch(facecolor="#e74c3c", edgecolor="0.45", label="perturbed particle (k_n)"))
    if handles:
        # below the panel: inside, it covered the end of the top plate (Fig. 6.3)
        ax.legend(handles=handles, fontsize=7, loc="upper center", bbox_to_anchor=(0.5, -0.2), ncol=len(handles))
    ax.autoscale()
    ax.set_aspect("equal")
    label_axes_cm(ax, 8)
    # a long scenario title is wrapped and the counts get a line of their own, so the title stays over its panel
    head = f"{title}: {', '.join(what)}"
    if len(head) > 50:
        head = "\n".join(textwrap.wrap(title, 50)) + "\n" + ", ".join(what)
    ax.set_title(head, fontsize=9)
    if params:
        ax.text(
            1.02,
            1.0,
            "\n".join(params),
            transform=ax.transAxes,
            va="top",
            ha="left",
            fontsize=7,
            family="monospace",
            bbox={"facecolor": "white", "edgecolor": "0.7"},
        )


def bond_parameters(path) -> list:
    """Text lines of the beam parameters of a bonded result, with the units of the scenario schema (the
    thesis's parameter tables, Figs. 5.6b, 7.9b)."""
    from ..interactions.bonds.family import BONDS

    with open_result(path) as f:
        sc = json.loads(f.attrs["resolved"])
    bd = sc.get("bonds") or {}
    out = []
    for key in ("E", "nu", "kappa_0", "G_ax", "kappa_m", "alpha", "eps0_dot", "rate_filter"):
        v = bd.get(key)
        if isinstance(v, (int, float)) and not isinstance(v, bool) and not (key == "rate_filter" and v == 0):
            unit = (getattr(BONDS.fields.get(key), "unit", None) or "").replace("-", "")
            out.append(f"{key:9s}{v:.4g} {unit}".rstrip())
    if bd.get("rate_dependent"):
        out.append("rate-dependent (5.13)")
    return out


def plot_specimen(result, png, title="specimen", style=PLAIN):
    """The specimen at t = 0 with its beams and what ``[[perturb]]`` changed, beside a table of its bond parameters
    (bonded results)."""
    plt = _plt()
    params = bond_parameters(result) if read_bonds(result) is not None else None
    fig, ax = plt.subplots(figsize=(7.2 if params else 5.6, 5.2))
    specimen_panel(ax, result, title, params)
    fig.tight_layout()
    save(fig, png, style=style, dpi=150)
    plt.close(fig)
    return png
