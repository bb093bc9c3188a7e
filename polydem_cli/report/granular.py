"""Figures of granular results (thesis Figs. 6.4–6.9).

* particle outlines coloured by the e2 velocity at chosen times (``basic.plot_frames``);
* translational velocity arrows of the free particles at chosen times (Figs. 6.5, 6.9);
* load-plate force against plate displacement (``basic.plot_history``, third panel).
"""

from __future__ import annotations

import numpy as np

from ..io.hdf5 import read_static
from .basic import _plt, label_axes_cm, read_frames, save, world_polygons


def plot_velocity_arrows(result, png, times=None, max_panels=3):
    plt = _plt()
    from matplotlib.collections import PolyCollection

    st = read_static(result)
    steps, ft, X, V = read_frames(result)
    if V is None:
        return None
    if times:
        idx = sorted({int(np.argmin(np.abs(ft - t))) for t in times})
    else:
        idx = sorted(set(np.linspace(1, len(ft) - 1, min(max_panels, len(ft) - 1)).round().astype(int)))
    radius = st["radius"]
    free = radius <= 4 * np.median(radius)  # leave out load plates and other large bodies
    fig, axes = plt.subplots(1, len(idx), figsize=(5.2 * len(idx), 4.8), squeeze=False)
    for ax, k in zip(axes[0], idx):
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
        vtrue = float(np.max(np.hypot(v[:, 0], v[:, 1])))
        vmax = vtrue or 1.0  # all at rest: no arrows to scale
        q = ax.quiver(
            x[:, 0],
            x[:, 1],
            v[:, 0],
            v[:, 1],
            angles="xy",
            scale_units="xy",
            scale=vmax / (1.2 * np.median(radius[free])),
            width=0.004,
            color="C3",
        )
        p = np.vstack([q for q, f in zip(polys, free) if f])
        pad = 2.0 * np.median(radius)
        ax.set_xlim(p[:, 0].min() - pad, p[:, 0].max() + pad)
        ax.set_ylim(p[:, 1].min() - pad, p[:, 1].max() + pad)
        ax.set_aspect("equal")
        label_axes_cm(ax)
        # the arrow scale differs between panels (each is scaled to its fastest particle): a key in each
        if vtrue > 0:
            e = 10.0 ** np.floor(np.log10(vmax))  # the key: a round speed near the fastest, an arrow as long
            key = max(m * e for m in (1.0, 2.0, 5.0) if m * e <= vmax)
            ax.quiverkey(
                q,
                0.80,
                1.02,
                key,
                f"{key:g} cm/s",
                labelpos="E",
                coordinates="axes",
                fontproperties={"size": 8},
            )
            ax.set_title(f"t = {ft[k]:.4g} s, |v| max = {vmax:.3g} cm/s", fontsize=9, loc="left")
        else:
            ax.set_title(f"t = {ft[k]:.4g} s, all particles at rest", fontsize=9, loc="left")
    fig.tight_layout()
    save(fig, png, dpi=130)
    plt.close(fig)
    return png
