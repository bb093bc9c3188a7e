"""Figures of granular results (thesis Figs. 6.4–6.9).

* particle outlines coloured by the e2 velocity at chosen times (``basic.plot_frames``);
* translational velocity arrows of the free particles at chosen times (Figs. 6.5, 6.9);
* load-plate force against plate displacement (``basic.plot_history``, third panel).
"""

from __future__ import annotations

import numpy as np

from ..io.hdf5 import read_static
from .common import PLAIN, _plt, label_axes_cm, read_frames, save, world_polygons


def plot_velocity_arrows(result, png, times=None, max_panels=3, style=PLAIN):
    """Translational velocity arrows of the free particles (Figs. 6.5, 6.9), one length scale for the whole figure
    so that panels compare: the 99th percentile of |v| over the panels is drawn 1.5 median radii long (a few
    escaping particles do not shrink every other arrow to a dot), and one key under the panels says it."""
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
    speeds = [np.hypot(V[k][free, 0], V[k][free, 1]) for k in idx]
    vref = max(float(np.percentile(sp, 99)) for sp in speeds) if len(idx) else 0.0
    length = 1.5 * float(np.median(radius[free]))  # cm of arrow for vref
    fig, axes = plt.subplots(1, len(idx), figsize=(5.2 * len(idx), 5.2), squeeze=False)
    q = None
    for ax, k, sp in zip(axes[0], idx, speeds):
        polys = world_polygons(st, X[k])
        ax.add_collection(
            PolyCollection([p for p, f in zip(polys, free) if f], facecolors="none", edgecolors="0.6", linewidths=0.4)
        )
        ax.add_collection(
            PolyCollection(
                [p for p, f in zip(polys, free) if not f], facecolors="0.85", edgecolors="0.4", linewidths=0.4
            )
        )
        v = V[k][free]
        x = X[k][free]
        if vref > 0:
            q = ax.quiver(
                x[:, 0],
                x[:, 1],
                v[:, 0],
                v[:, 1],
                angles="xy",
                scale_units="xy",
                scale=vref / length,
                width=0.006,
                headwidth=3.5,
                headlength=4.0,
                color="C3",
            )
        p = np.vstack([q_ for q_, f in zip(polys, free) if f])
        pad = 2.0 * np.median(radius)
        ax.set_xlim(p[:, 0].min() - pad, p[:, 0].max() + pad)
        ax.set_ylim(p[:, 1].min() - pad, p[:, 1].max() + pad)
        ax.set_aspect("equal")
        label_axes_cm(ax)
        said = f"|v| max {float(sp.max(initial=0.0)):.3g} cm/s" if sp.size and sp.max() > 0 else "all particles at rest"
        ax.set_title(f"t = {ft[k]:.4g} s, {said}", fontsize=9, loc="left")
    if q is not None:
        e = 10.0 ** np.floor(np.log10(vref))  # the key: a round speed near the reference, an arrow as long
        key = max(m * e for m in (1.0, 2.0, 5.0) if m * e <= vref)
        fig.tight_layout(rect=(0, 0.08, 1, 1))
        # the key lives in an axis-less strip under the panels: a QuiverKey has no extent of its own, so the
        # tight crop of save() cut it off when it hung below a panel (the arrow's length is its quiver's scale)
        fig.draw_without_rendering()  # equal-aspect panels sit inside their slots: the strip goes just under them
        low = min(ax.get_tightbbox().y0 for ax in axes[0]) / fig.bbox.height
        strip = fig.add_axes((0.0, max(low - 0.08, 0.0), 1.0, 0.07))
        strip.set_axis_off()
        strip.quiverkey(
            q,
            0.7,
            max(low - 0.045, 0.035),  # figure coordinates, in the strip (the key's "axes" would be its quiver's)
            key,
            f"one scale for every panel (99th percentile of |v|: {vref:.3g} cm/s):  {key:g} cm/s",
            labelpos="W",
            coordinates="figure",
            fontproperties={"size": 9},
        )
    else:
        fig.tight_layout()
    save(fig, png, style=style, dpi=130)
    plt.close(fig)
    return png
