"""Mesoscale concrete in a Voronoi specimen: round aggregates by a grading curve, and the phase of every cell.

* Grading: Fuller's curve ``P(d) = (d / d_max)^n`` (n = 0.5: Fuller & Thompson, Trans. ASCE 59 (1907) 67–143),
  the volume (here: area) fraction of the aggregate passing a sieve of size d.  Between ``d_min`` and ``d_max``
  the aggregate is split into ``classes`` sieve classes of geometric widths (d_min q^i, q = (d_max/d_min)^(1/k),
  like the doubling sieve series 2–4–8–16 mm), class i taking the share ``P(s_{i+1}) − P(s_i)`` of the aggregate
  area, normalised over [d_min, d_max] (the fines below d_min belong to the matrix).
* Placement: random sequential addition, largest class first (the take-and-place method of Wang, Kwan & Chan,
  Comput. Struct. 70 (1999) 533–544; the same placement as the heterogeneous coupling plates,
  :func:`polydem_cli.coupling.problem.aggregates`), each diameter uniform in its class, each disc wholly inside
  the specimen (points on a circle ``gap`` outside it all inside some particle) and ``gap`` clear of the
  others; a class is given up after ``tries`` rejected draws (the area reached is stated).
* Phases: a cell (particle) belongs to aggregate q when its centroid lies in disc q, to the matrix otherwise —
  aggregates several cells across, glued by their own beams (``[bonds.aggregate]``), to the matrix by interface
  beams (``[bonds.interface]``; :mod:`polydem_cli.interactions.bonds.network`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .polygon import GeometryError, polygon_area_centroid_inertia


@dataclass
class Grading:
    fraction: float  # aggregate area over the specimen's area
    d_min: float  # cm
    d_max: float  # cm
    exponent: float = 0.5  # Fuller
    classes: int = 3
    gap: float | None = None  # clearance between discs and from the rim (default: the cells' spacing h)
    tries: int = 4000


def grading_classes(d_min: float, d_max: float, classes: int, exponent: float = 0.5) -> list:
    """Sieve classes (d_lo, d_hi, share of the aggregate area) of Fuller's curve, largest first (module
    docstring)."""
    if not 0.0 < d_min < d_max:
        raise GeometryError(f"grading: need 0 < d_min < d_max (got {d_min:g}, {d_max:g})")
    if classes < 1 or not exponent > 0.0:
        raise GeometryError("grading: at least one class and an exponent > 0")
    s = d_min * (d_max / d_min) ** (np.arange(classes + 1) / classes)
    P = (s / d_max) ** exponent
    share = np.diff(P) / (P[-1] - P[0])
    return [(float(s[i]), float(s[i + 1]), float(share[i])) for i in reversed(range(classes))]


def place_aggregates(polys, g: Grading, seed: int, h: float) -> tuple[list, float]:
    """Aggregates (x, y, r) placed in the specimen made of the particles ``polys`` (module docstring) and the
    specimen's area; GeometryError when not even one aggregate of the smallest class fits."""
    from scipy.spatial import cKDTree

    if not 0.0 < g.fraction < 1.0:
        raise GeometryError(f"aggregates: the area fraction must lie in (0, 1), got {g.fraction:g}")
    gap = h if g.gap is None else g.gap
    cen, area, rad = [], 0.0, []
    for v in polys:
        A, c, _ = polygon_area_centroid_inertia(v)
        cen.append(c)
        area += A
        rad.append(float(np.hypot(*(np.asarray(v) - c).T).max()))
    cen, rad = np.array(cen), np.array(rad)
    tree, rmax = cKDTree(cen), float(rad.max())
    lo, hi = np.min([v.min(axis=0) for v in polys], axis=0), np.max([v.max(axis=0) for v in polys], axis=0)
    if g.d_min + 2.0 * gap > min(hi - lo):
        raise GeometryError(
            f"aggregates: the smallest aggregate (d_min {g.d_min:g} cm and a gap of {gap:g} cm round it) does not fit "
            f"the specimen ({hi[0] - lo[0]:g} x {hi[1] - lo[1]:g} cm)"
        )
    ring = np.exp(2j * np.pi * np.arange(24) / 24)

    def inside(p):
        for m in tree.query_ball_point(p, rmax):
            if math.hypot(p[0] - cen[m, 0], p[1] - cen[m, 1]) > rad[m]:
                continue
            w = np.asarray(polys[m])
            e = np.roll(w, -1, axis=0) - w
            if np.all(e[:, 0] * (p[1] - w[:, 1]) - e[:, 1] * (p[0] - w[:, 0]) >= 0.0):
                return True
        return False

    def fits(x, y, r):
        R = r + gap
        return all(inside((x + R * z.real, y + R * z.imag)) for z in ring)

    rng = np.random.default_rng(seed)
    target = g.fraction * area
    placed, got, done = [], 0.0, 0.0
    for d_lo, d_hi, share in grading_classes(g.d_min, g.d_max, g.classes, g.exponent):
        done += share
        tries = 0
        while got < target * done and tries < g.tries:
            tries += 1
            r = 0.5 * rng.uniform(d_lo, d_hi)
            if 2.0 * (r + gap) > min(hi - lo):  # larger than the specimen: a rejected draw
                continue
            x, y = rng.uniform(lo[0] + r, hi[0] - r), rng.uniform(lo[1] + r, hi[1] - r)
            if any(math.hypot(x - px, y - py) < r + pr + gap for px, py, pr in placed):
                continue
            if not fits(x, y, r):
                continue
            placed.append((x, y, r))
            got += math.pi * r * r
    if not placed:
        raise GeometryError(
            f"aggregates: none of d {g.d_min:g}-{g.d_max:g} cm fits in the specimen with a gap of {gap:g} cm"
        )
    return placed, area


def cell_phases(polys, aggs) -> np.ndarray:
    """Per particle, the aggregate its centroid lies in (index into ``aggs``), −1 for the matrix."""
    out = np.full(len(polys), -1, np.int64)
    if not aggs:
        return out
    a = np.asarray(aggs, float)
    for i, v in enumerate(polys):
        c = polygon_area_centroid_inertia(v)[1]
        d = np.hypot(a[:, 0] - c[0], a[:, 1] - c[1]) - a[:, 2]
        k = int(np.argmin(d))
        if d[k] <= 0.0:
            out[i] = k
    return out
