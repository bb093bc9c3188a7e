"""Convex polygon geometry: area, centroid, polar moment, mass properties.

Formulas (standard shoelace forms) for vertices :math:`(x_k, y_k)`
in counter-clockwise order, indices cyclic, :math:`a_k = x_k y_{k+1} - x_{k+1} y_k`::

    A   = 1/2  sum a_k
    c   = 1/(6A) sum a_k (x_k + x_{k+1}, y_k + y_{k+1})
    J_O = 1/12 sum a_k (x_k^2 + x_k x_{k+1} + x_{k+1}^2 + y_k^2 + y_k y_{k+1} + y_{k+1}^2)
    J_c = J_O - A |c|^2
    m = rho T A,   Theta = rho T J_c

Units: cm, g, s.  Everything here is plain NumPy: it runs once
while a specimen is built, never inside the time loop.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


class GeometryError(ValueError):
    """A polygon that cannot be a particle (non-convex, degenerate, ...)."""


def _next(a: np.ndarray) -> np.ndarray:
    """``a`` shifted by one along its first axis (``np.roll(a, -1, axis=0)``: each vertex's successor), without
    ``np.roll``'s generality, which cost a third of building a 10⁵-particle specimen."""
    return np.concatenate((a[1:], a[:1]))


def signed_area(v: np.ndarray) -> float:
    """Signed area of a polygon (positive for counter-clockwise order)."""
    x, y = v[:, 0], v[:, 1]
    return 0.5 * float(np.sum(x * _next(y) - _next(x) * y))


def polygon_area_centroid_inertia(v: np.ndarray) -> tuple[float, np.ndarray, float]:
    """Area, centroid and polar second moment about the centroid (per unit density and thickness).

    Parameters
    ----------
    v : (n, 2) array, counter-clockwise vertices.

    Returns
    -------
    A : float, cm^2
    c : (2,) array, cm
    J_c : float, cm^4 (polar moment of area about the centroid)
    """
    v = np.asarray(v, dtype=float)
    # shift to the vertex mean first: the shoelace sums then do not lose digits
    # for polygons far from the origin
    o = v.mean(axis=0)
    w = v - o
    x, y = w[:, 0], w[:, 1]
    xn, yn = _next(x), _next(y)
    a = x * yn - xn * y
    A = 0.5 * a.sum()
    if A == 0.0:
        raise GeometryError("polygon has zero area")
    cx = (a * (x + xn)).sum() / (6.0 * A)
    cy = (a * (y + yn)).sum() / (6.0 * A)
    JO = (a * (x * x + x * xn + xn * xn + y * y + y * yn + yn * yn)).sum() / 12.0
    Jc = JO - A * (cx * cx + cy * cy)
    return float(A), np.array([cx, cy]) + o, float(Jc)


def check_convex_polygon(v: np.ndarray, what: str = "polygon", rel_tol: float = 1e-9) -> np.ndarray:
    """Return the vertices in counter-clockwise order or raise :class:`GeometryError`.

    Accepts clockwise input (reversed), rejects fewer than three vertices,
    repeated vertices, zero area and non-convex or self-intersecting outlines.
    Collinear vertices (interior angle of exactly 180 degrees) are allowed.
    """
    v = np.asarray(v, dtype=float)
    if v.ndim != 2 or v.shape[1] != 2:
        raise GeometryError(f"{what}: vertices must be a list of [x, y] pairs")
    if v.shape[0] < 3:
        raise GeometryError(f"{what}: needs at least 3 vertices, got {v.shape[0]}")
    if not np.all(np.isfinite(v)):
        raise GeometryError(f"{what}: vertex coordinates must be finite")
    A = signed_area(v)
    scale = float(np.max(np.ptp(v, axis=0)))
    if scale == 0.0 or abs(A) <= rel_tol * scale * scale:
        raise GeometryError(f"{what}: zero area")
    if A < 0:
        v = v[::-1].copy()
    e = _next(v) - v
    lengths = np.hypot(e[:, 0], e[:, 1])
    if np.any(lengths <= rel_tol * scale):
        raise GeometryError(f"{what}: repeated vertex (zero-length edge)")
    cross = e[:, 0] * _next(e[:, 1]) - e[:, 1] * _next(e[:, 0])
    if np.any(cross < -rel_tol * scale * scale):
        raise GeometryError(f"{what}: not convex")
    # convex turns everywhere but the outline may wind more than once
    ang = np.arctan2(e[:, 1], e[:, 0])
    turn = np.mod(_next(ang) - ang + np.pi, 2 * np.pi) - np.pi
    if abs(turn.sum() - 2 * np.pi) > 1e-6:
        raise GeometryError(f"{what}: self-intersecting outline")
    return v


@dataclass(frozen=True)
class PolygonShape:
    """A rigid convex polygon in its body frame (vertices relative to the centroid)."""

    body_vertices: np.ndarray  # (n, 2), counter-clockwise, centroid at the origin
    area: float  # cm^2
    polar_moment: float  # cm^4, J_c per unit density and thickness
    radius: float  # bounding-circle radius about the centroid, cm

    def mass(self, density: float, thickness: float) -> float:
        """m = rho T A (g)."""
        return density * thickness * self.area

    def inertia(self, density: float, thickness: float) -> float:
        """Theta = rho T J_c (g cm^2)."""
        return density * thickness * self.polar_moment


def make_shape(world_vertices: np.ndarray, what: str = "polygon") -> tuple[PolygonShape, np.ndarray]:
    """Build a :class:`PolygonShape` from world vertices; also return the centroid."""
    v = check_convex_polygon(world_vertices, what)
    A, c, J = polygon_area_centroid_inertia(v)
    body = v - c
    r = float(np.max(np.hypot(body[:, 0], body[:, 1])))
    return PolygonShape(body, A, J, r), c


def regular_polygon(n: int, circumradius: float, rotation: float = 0.0, center=(0.0, 0.0)) -> np.ndarray:
    """Vertices of a regular n-gon, counter-clockwise, first vertex at angle ``rotation``."""
    k = np.arange(n)
    ang = rotation + 2.0 * np.pi * k / n
    return np.column_stack([center[0] + circumradius * np.cos(ang), center[1] + circumradius * np.sin(ang)])


def hexagon(width_across_flats: float, center=(0.0, 0.0)) -> np.ndarray:
    """Regular hexagon with vertical flat sides ("pointy-top").

    Side s = w / sqrt(3) equals the circumradius; vertices at 30 + 60 k degrees,
    so the flats are at x = +-w/2 and the corners point along e2.
    """
    s = width_across_flats / np.sqrt(3.0)
    return regular_polygon(6, s, rotation=np.pi / 6.0, center=center)


def rectangle(center, size) -> np.ndarray:
    """Axis-aligned rectangle, counter-clockwise from the lower-left corner."""
    cx, cy = center
    w, h = size
    return np.array(
        [[cx - w / 2, cy - h / 2], [cx + w / 2, cy - h / 2], [cx + w / 2, cy + h / 2], [cx - w / 2, cy + h / 2]],
        dtype=float,
    )


def clip_convex(poly: np.ndarray, clip: np.ndarray, eps: float = 1e-12) -> np.ndarray:
    """The part of polygon ``poly`` inside the convex polygon ``clip`` (both counter-clockwise; Sutherland &
    Hodgman, Comm. ACM 17 (1974) 32–42): one pass per edge of ``clip`` keeps what lies to its left.  Convex in,
    convex out; vertices closer than ``eps`` × the clip's size merged; an empty (n < 3) array when nothing is left."""
    out = np.asarray(poly, float)
    clip = np.asarray(clip, float)
    size = float(np.ptp(clip, axis=0).max()) or 1.0
    for k in range(len(clip)):
        if len(out) < 3:
            break
        a, b = clip[k], clip[(k + 1) % len(clip)]
        e = b - a
        side = e[0] * (out[:, 1] - a[1]) - e[1] * (out[:, 0] - a[0])  # > 0: left of a -> b (inside)
        side[np.abs(side) <= eps * size * np.hypot(*e)] = 0.0
        nxt = _next(out)
        s_nxt = _next(side)
        pts = []
        for p, q, sp, sq in zip(out, nxt, side, s_nxt):
            if sp >= 0.0:
                pts.append(p)
            if (sp > 0.0 and sq < 0.0) or (sp < 0.0 and sq > 0.0):
                pts.append(p + (q - p) * (sp / (sp - sq)))
        out = np.array(pts).reshape(-1, 2)
        if len(out):  # merge repeated vertices (a vertex on the clip line)
            d = np.hypot(*(out - _next(out)).T)
            out = out[d > eps * size]
    return out if len(out) >= 3 and signed_area(out) > (eps * size) ** 2 else np.zeros((0, 2))


def circle_polygon(center, radius: float, chord_tol: float) -> np.ndarray:
    """A regular polygon inscribed in the circle, with enough corners that no point of the circle lies farther
    than ``chord_tol`` from it (sagitta r (1 − cos(π/n)) ≤ chord_tol); counter-clockwise, a multiple of four
    corners (at least 8) with one at the top, so that corners lie on both axes."""
    if not radius > 0.0:
        raise GeometryError("circle_polygon: the radius must be > 0")
    if not chord_tol > 1e-12 * radius:
        raise GeometryError("circle_polygon: the chord tolerance must be > 0 (and above round-off)")
    c = max(1.0 - chord_tol / radius, -1.0)
    n = max(8, int(np.ceil(np.pi / np.arccos(c))))
    n = 4 * ((n + 3) // 4)  # a multiple of four, a corner at 90°: corners on the axes (a disc's top and bottom)
    return regular_polygon(n, radius, rotation=np.pi / 2, center=center)


def exposed_edges(polys, loaded, among) -> list:
    """The edges of the polygons ``polys[i]``, i in ``loaded``, that no polygon of ``among`` covers — a particle
    assembly's outline (each polygon counter-clockwise): an edge counts as exposed when a point just outside its
    midpoint (a millionth of its length along the outward normal) lies in no other polygon of ``among``.  One
    list per loaded polygon of (length, outward unit normal (2,), midpoint (2,)) triples."""
    from scipy.spatial import cKDTree

    among = np.asarray(among, np.int64)
    cen = np.array([np.mean(polys[j], axis=0) for j in among]).reshape(-1, 2)
    rad = np.array([np.hypot(*(np.asarray(polys[j]) - c).T).max() for j, c in zip(among, cen)])
    tree = cKDTree(cen) if len(among) else None
    rmax = float(rad.max()) if len(among) else 0.0
    out = []
    for i in loaded:
        v = np.asarray(polys[i], float)
        d = _next(v) - v
        L = np.hypot(d[:, 0], d[:, 1])
        edges = []
        for k in range(len(v)):
            if L[k] <= 0.0:
                continue
            n = np.array([d[k, 1], -d[k, 0]]) / L[k]
            p = v[k] + 0.5 * d[k] + 1e-6 * L[k] * n
            covered = False
            for m in tree.query_ball_point(p, rmax) if tree is not None else ():
                j = int(among[m])
                if j == i or np.hypot(*(p - cen[m])) > rad[m]:
                    continue
                w = np.asarray(polys[j], float)
                e = _next(w) - w
                if np.all(e[:, 0] * (p[1] - w[:, 1]) - e[:, 1] * (p[0] - w[:, 0]) > 0.0):
                    covered = True
                    break
            if not covered:
                edges.append((float(L[k]), n, v[k] + 0.5 * d[k]))
        out.append(edges)
    return out
