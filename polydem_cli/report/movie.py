"""``polydem report RESULT --movie``: the frames of a result as an animation (GIF through Pillow, which needs no
system tool; MP4 through ffmpeg when it is installed), with one colour scale for the whole movie.

Particles are coloured by their e2 velocity on a symmetric scale ±v, v the largest 99th percentile of |v2| of
the free particles (not the load plates) over all frames — a colour means the same velocity in every frame;
large bodies (load plates) grey.  With bonds, the beams are drawn between the particle centroids, coloured by
their damage on the fixed scale 0…1 (intact grey, failed dark red), failed beams included.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ..io.hdf5 import ResultError, read_bonds, read_frames, read_static
from .common import (
    _plt,
    bond_segments,
    damage_cmap,
    damage_widths,
    damage_word,
    headline,
    label_axes_cm,
    world_polygons,
)


def velocity_scale(V, free) -> float:
    """The movie's colour limit: the largest over the frames of the 99th percentile of |v2| (free particles)."""
    if V is None:
        return 0.0
    return max(float(np.percentile(np.abs(V[k, free, 1]), 99)) for k in range(len(V)))


def make_movie(result, out, fps=10, max_frames=400) -> dict:
    """Write the animation ``out`` (.gif or .mp4); returns {"file", "frames", "v_limit"}."""
    plt = _plt()
    from matplotlib import animation
    from matplotlib.collections import LineCollection, PolyCollection

    result, out = Path(result), Path(out)
    kind = out.suffix.lower()
    if kind not in (".gif", ".mp4"):
        raise ResultError(f"{out}: a movie is written as .gif or .mp4")
    if kind == ".mp4" and not animation.writers.is_available("ffmpeg"):
        raise ResultError(f"{out}: MP4 needs ffmpeg, which is not installed here; write a .gif (Pillow) instead")
    st = read_static(result)
    steps, times, X, V = read_frames(result)
    if len(steps) < 2:
        raise ResultError(f"{result}: {len(steps)} frame(s); a movie needs at least two")
    idx = np.unique(np.linspace(0, len(steps) - 1, min(max_frames, len(steps))).round().astype(int))
    bonds = read_bonds(result)
    radius = st["radius"]
    free = radius <= 4 * np.median(radius)
    vmax = velocity_scale(V[idx] if V is not None else None, free) or 1.0
    allp = np.vstack([np.vstack(world_polygons(st, X[k])) for k in (idx[0], idx[-1])])
    pad = 0.04 * np.ptp(allp, axis=0).max()
    lo, hi = allp.min(axis=0) - pad, allp.max(axis=0) + pad
    aspect = (hi[1] - lo[1]) / (hi[0] - lo[0])
    fig, ax = plt.subplots(figsize=(6.4, max(2.5, 5.2 * aspect) + 1.0), layout="constrained")
    what = "particles coloured by their velocity in e2" + (", beams by their damage" if bonds is not None else "")
    headline(fig, what, result)
    fixed = PolyCollection([], facecolors="0.85", edgecolors="0.4", linewidths=0.4)
    moving = PolyCollection([], edgecolors="k", linewidths=0.3, cmap="coolwarm")
    moving.set_clim(-vmax, vmax)
    ax.add_collection(fixed)
    ax.add_collection(moving)
    beams = None
    if bonds is not None:
        beams = LineCollection([], cmap=damage_cmap(), linewidths=0.8)
        beams.set_clim(0.0, 1.0)
        ax.add_collection(beams)
        fig.colorbar(beams, ax=ax, shrink=0.7, label=damage_word(bonds) + r" $d$ [−]", pad=0.01)
    fig.colorbar(
        moving,
        ax=ax,
        orientation="horizontal",
        shrink=0.6,
        label=r"particle velocity $\dot x_2$ [cm/s]"
        + (r" (scale to the 99th percentile of $|\dot x_2|$)" if V is not None else " (no velocities stored)"),
        pad=0.12,
        extend="both" if V is not None else "neither",  # faster particles draw at the end colours
    )
    ax.set_xlim(lo[0], hi[0])
    ax.set_ylim(lo[1], hi[1])
    ax.set_aspect("equal")
    label_axes_cm(ax)
    title = ax.set_title("", fontsize=9)

    def draw(j):
        k = idx[j]
        polys = world_polygons(st, X[k])
        fixed.set_verts([p for p, f in zip(polys, free) if not f])
        moving.set_verts([p for p, f in zip(polys, free) if f])
        moving.set_array(V[k, free, 1] if V is not None else np.zeros(int(free.sum())))
        if beams is not None:
            beams.set_segments(bond_segments(X[k], bonds["pairs"]))
            beams.set_array(bonds["frame_d"][k])
            beams.set_linewidths(damage_widths(bonds["frame_d"][k], 0.8))  # failed beams thinner, as in the maps
        title.set_text(f"t = {times[k]:.5g} s (frame {k + 1} of {len(steps)})")
        return fixed, moving, title

    anim = animation.FuncAnimation(fig, draw, frames=len(idx), blit=False)
    writer = animation.PillowWriter(fps=fps) if kind == ".gif" else animation.FFMpegWriter(fps=fps)
    out.parent.mkdir(parents=True, exist_ok=True)
    part = out.with_name(out.stem + ".part" + out.suffix)  # complete or absent
    try:
        anim.save(part, writer=writer, dpi=100)
        part.replace(out)
    finally:  # stopped (Ctrl-C) or failed: no partial file
        plt.close(fig)
        part.unlink(missing_ok=True)
    return {"file": str(out), "frames": len(idx), "v_limit": vmax}
