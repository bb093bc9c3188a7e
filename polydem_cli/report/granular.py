"""Figures of granular results (thesis Figs. 6.4–6.9).

* particle outlines coloured by the e2 velocity at chosen times (``basic.plot_frames``);
* translational velocity arrows of the free particles at chosen times (Figs. 6.5, 6.9);
* load-plate force against plate displacement (``basic.plot_history``, third panel).
"""

from __future__ import annotations

import numpy as np

from ..geometry.polygon import signed_area
from ..io.hdf5 import read_static
from .common import PLAIN, _plt, headline, label_axes_cm, panel_height, read_frames, save, world_polygons

#: the closest two arrows' tails may come on paper [in]: particles closer than this share one arrow (their mean
#: velocity), or the arrows of a specimen of many small cells merge into one mass of colour
ARROW_SPACING = 0.2


def arrow_field(x, v, cell):
    """(positions, velocities) of the arrows of one panel: one per particle when ``cell`` is None, else one per
    square of side ``cell`` [cm] of a grid from the particles' lower left corner that holds particles, at the
    square's centre (arrows a cell apart) with the mean velocity of its particles."""
    if cell is None or len(x) == 0:
        return x[:, :2], v[:, :2]
    lo = x[:, :2].min(axis=0)
    key = np.floor((x[:, :2] - lo) / cell).astype(np.int64)
    keys, inv, cnt = np.unique(key, axis=0, return_inverse=True, return_counts=True)
    inv = inv.ravel()
    vel = np.zeros((len(cnt), 2))
    np.add.at(vel, inv, v[:, :2])
    return lo + (keys + 0.5) * cell, vel / cnt[:, None]


def plot_velocity_arrows(result, png, times=None, max_panels=3, style=PLAIN):
    """Translational velocity arrows of the free particles (Figs. 6.5, 6.9), one length scale for the whole figure
    so that panels compare: the 99th percentile of the arrows' speeds over the panels is drawn 0.75 of the arrows'
    spacing long (a few escaping particles do not shrink every other arrow to a dot), and one key under the panels
    says it.  Arrows closer on paper than :data:`ARROW_SPACING` would merge into one mass: then each arrow is the
    mean velocity of the particles in a square of a grid whose cells are that far apart, and the title says so."""
    plt = _plt()
    from matplotlib.collections import PolyCollection

    st = read_static(result)
    steps, ft, X, V = read_frames(result, style)
    if V is None:
        return None
    if times:
        idx = sorted({int(np.argmin(np.abs(ft - t))) for t in times})
    else:
        idx = sorted(set(np.linspace(1, len(ft) - 1, min(max_panels, len(ft) - 1)).round().astype(int)))
    radius = st["radius"]
    free = radius <= 4 * np.median(radius)  # leave out load plates and other large bodies
    # the particles' spacing: the side of a square of a particle's area (a Voronoi cell's width; for round
    # particles the bounding radius would say a third more)
    spacing = float(np.sqrt(np.median([abs(signed_area(p)) for p, f in zip(world_polygons(st, X[0]), free) if f])))
    pad = 2.0 * np.median(radius)
    polys = {k: world_polygons(st, X[k]) for k in idx}
    boxes = {}
    for k in idx:
        p = np.vstack([q_ for q_, f in zip(polys[k], free) if f])
        boxes[k] = (p.min(axis=0) - pad, p.max(axis=0) + pad)
    corners = np.vstack([c for b in boxes.values() for c in b])
    # panels as high as the scene (a flat pile between plates is a strip), room for the titles and the key
    fig, axes = plt.subplots(1, len(idx), figsize=(5.2 * len(idx), panel_height(corners, 5.2, 1.6)), squeeze=False)
    for ax, k in zip(axes[0], idx):
        ax.set_xlim(boxes[k][0][0], boxes[k][1][0])
        ax.set_ylim(boxes[k][0][1], boxes[k][1][1])
        ax.set_aspect("equal")
        label_axes_cm(ax)
        vp = np.hypot(V[k][free, 0], V[k][free, 1])
        said = f"|v| max {float(vp.max(initial=0.0)):.3g} cm/s" if vp.size and vp.max() > 0 else "all particles at rest"
        ax.set_title(f"t = {ft[k]:.4g} s, {said}", fontsize=9, loc="left")
    # the panels' scale on paper (equal aspect: the drawn box after the layout): where the particles lie closer
    # than ARROW_SPACING, one arrow per square of a grid that far apart
    head = headline(fig, "velocity of the particles (arrows)", result)
    fig.tight_layout(rect=(0, 0.08, 1, 1))
    fig.draw_without_rendering()
    inch = min(ax.get_window_extent().width / fig.dpi / np.ptp(ax.get_xlim()) for ax in axes[0])  # in per cm
    cell = ARROW_SPACING / inch if spacing * inch < ARROW_SPACING else None
    if cell is not None:
        head.set_text(
            head.get_text().replace(
                "(arrows)", f"(arrows: each the mean velocity of the particles in a square of {cell:.3g} cm)", 1
            )
        )
    fields = [arrow_field(X[k][free], V[k][free], cell) for k in idx]
    speeds = [np.hypot(v[:, 0], v[:, 1]) for _, v in fields]
    vref = max(float(np.percentile(sp, 99)) for sp in speeds) if len(idx) else 0.0
    spacing = cell if cell is not None else spacing
    length = 0.75 * spacing  # cm of arrow for vref
    q = None
    for ax, k, (x, v) in zip(axes[0], idx, fields):
        ax.add_collection(
            PolyCollection(
                [p for p, f in zip(polys[k], free) if f], facecolors="none", edgecolors="0.6", linewidths=0.4
            )
        )
        ax.add_collection(
            PolyCollection(
                [p for p, f in zip(polys[k], free) if not f], facecolors="0.85", edgecolors="0.4", linewidths=0.4
            )
        )
        if vref > 0:
            q = ax.quiver(
                x[:, 0],
                x[:, 1],
                v[:, 0],
                v[:, 1],
                angles="xy",
                scale_units="xy",
                scale=vref / length,
                units="xy",
                width=0.08 * spacing,  # shaft and head in the arrows' own spacing: neighbours do not touch
                headwidth=3.5,
                headlength=4.0,
                headaxislength=3.5,
                color="C3",
            )
    if q is not None:
        e = 10.0 ** np.floor(np.log10(vref))  # the key: a round speed near the reference, an arrow as long
        key = max(m * e for m in (1.0, 2.0, 5.0) if m * e <= vref)
        # the key lives in an axis-less strip under the panels: a QuiverKey has no extent of its own, so the
        # tight crop of save() cut it off when it hung below a panel (the arrow's length is its quiver's scale)
        fig.draw_without_rendering()  # equal-aspect panels sit inside their slots: the strip goes just under them
        low = min(ax.get_tightbbox().y0 for ax in axes[0]) / fig.bbox.height
        # (below the figure's edge if the labels reach down there: save() crops to what is drawn)
        strip = fig.add_axes((0.0, low - 0.08, 1.0, 0.07))
        strip.set_axis_off()
        of = "of the arrows' speeds" if cell is not None else "of |v|"
        strip.quiverkey(
            q,
            0.7,
            low - 0.045,  # figure coordinates, in the strip (the key's "axes" would be its quiver's)
            key,
            f"one scale for every panel (99th percentile {of}: {vref:.3g} cm/s):  {key:g} cm/s",
            labelpos="W",
            coordinates="figure",
            fontproperties={"size": 9},
        )
    save(fig, png, style=style, dpi=130)
    plt.close(fig)
    return png
