"""Specimen generators: Voronoi specimens, hexagon packings, single shapes.

Every generator returns a :class:`Specimen`: world vertices of each particle
(counter-clockwise), named subsets of particle indices (local to the specimen)
and, where particles are generated touching, the shared edge of every touching
pair (needed by the bond network of thesis §5.1.2).

Moukarzel–Herrmann Voronoi specimen (thesis §3.2.1):

(a) a square grid of spacing ``h_pg`` over ``[0, nx h] x [0, ny h]``;
(b) one point per grid cell, uniform in a square of side ``q_pg h_pg`` centred
    on the cell centre (NumPy PCG64 generator seeded with ``seed``; points drawn
    row by row, x before y);
(c) the Voronoi cells of these points, clipped to the specimen rectangle.

Clipping (open point O-1): the cells are those of the points together with
their mirror images across the four sides, which is exactly the tessellation
clipped to the rectangle.  Diagram vertices closer than ``merge_tol`` are merged
so that neighbouring cells share bit-identical vertices and edges of zero
length disappear; vertices within ``merge_tol`` of the rectangle are snapped
onto it.  Subsets (open point O-2): ``top``/``bottom``/``left``/``right`` are
the cells whose generating points lie in the last/first grid row/column.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .polygon import (
    GeometryError,
    _next,
    circle_polygon,
    clip_convex,
    hexagon,
    polygon_area_centroid_inertia,
    rectangle,
    regular_polygon,
    signed_area,
)
from .touching import touching_edges


@dataclass
class Specimen:
    """Particles produced by one generator (indices local to the specimen)."""

    vertices: list  # list of (n_k, 2) arrays, world frame, counter-clockwise
    subsets: dict = field(default_factory=dict)  # name -> int array
    # shared edges between touching particles: (m, 2) int pairs i<j, (m,) lengths,
    # (m, 2, 2) end points
    shared_pairs: np.ndarray = field(default_factory=lambda: np.zeros((0, 2), np.int64))
    shared_lengths: np.ndarray = field(default_factory=lambda: np.zeros(0))
    shared_edges: np.ndarray = field(default_factory=lambda: np.zeros((0, 2, 2)))
    info: dict = field(default_factory=dict)
    #: mesoscale concrete: per particle the aggregate it belongs to, -1 the matrix (None: one phase;
    #: geometry/aggregates.py)
    phase: np.ndarray | None = None

    def __len__(self) -> int:
        return len(self.vertices)


def _merge_close_points(p: np.ndarray, tol: float) -> tuple[np.ndarray, np.ndarray]:
    """Cluster points closer than ``tol`` (union-find on a KD-tree); return (new points, map)."""
    from scipy.spatial import cKDTree

    n = len(p)
    parent = np.arange(n)

    def find(a):
        while parent[a] != a:
            parent[a] = parent[parent[a]]
            a = parent[a]
        return a

    for a, b in cKDTree(p).query_pairs(tol):
        ra, rb = find(a), find(b)
        if ra != rb:
            parent[max(ra, rb)] = min(ra, rb)
    roots = np.array([find(a) for a in range(n)])
    uniq, inv = np.unique(roots, return_inverse=True)
    q = np.zeros((len(uniq), 2))
    np.add.at(q, inv, p)
    q /= np.bincount(inv)[:, None]
    return q, inv


def voronoi_specimen(
    nx: int, ny: int, h_pg: float = 1.0, q_pg: float = 0.999, seed: int = 0, origin=(0.0, 0.0), merge_tol: float = 1e-9
) -> Specimen:
    """Moukarzel–Herrmann specimen of ``nx * ny`` Voronoi cells (see module docstring)."""
    from scipy.spatial import Voronoi

    if nx < 1 or ny < 1:
        raise GeometryError("voronoi: nx and ny must be >= 1")
    rng = np.random.default_rng(seed)
    L1, L2 = nx * h_pg, ny * h_pg
    jj, ii = np.meshgrid(np.arange(ny), np.arange(nx), indexing="ij")
    ii, jj = ii.ravel(), jj.ravel()
    u = rng.random((nx * ny, 2))
    pts = np.column_stack([(ii + 0.5 + q_pg * (u[:, 0] - 0.5)) * h_pg, (jj + 0.5 + q_pg * (u[:, 1] - 0.5)) * h_pg])
    n = len(pts)
    if n == 1:
        cells = [rectangle((L1 / 2, L2 / 2), (L1, L2))]
        spec = Specimen([c + np.asarray(origin) for c in cells])
    else:
        mirrors = [
            pts,
            np.column_stack([-pts[:, 0], pts[:, 1]]),
            np.column_stack([2 * L1 - pts[:, 0], pts[:, 1]]),
            np.column_stack([pts[:, 0], -pts[:, 1]]),
            np.column_stack([pts[:, 0], 2 * L2 - pts[:, 1]]),
        ]
        vor = Voronoi(np.vstack(mirrors))
        tol = merge_tol * h_pg
        V, vmap = _merge_close_points(vor.vertices, tol)
        # snap onto the rectangle
        for col, lim in ((0, 0.0), (0, L1), (1, 0.0), (1, L2)):
            close = np.abs(V[:, col] - lim) <= tol
            V[close, col] = lim
        cells = []
        for k in range(n):
            reg = vor.regions[vor.point_region[k]]
            if -1 in reg or len(reg) < 3:
                raise GeometryError("voronoi: unbounded cell after mirroring (internal error)")
            idx = vmap[np.asarray(reg)]
            # drop repeated consecutive vertices produced by merging
            keep = idx != np.roll(idx, 1)
            idx = idx[keep]
            poly = V[idx]
            # scipy gives regions in arbitrary orientation: order by angle about the point
            ang = np.arctan2(poly[:, 1] - pts[k, 1], poly[:, 0] - pts[k, 0])
            order = np.argsort(ang)
            cells.append((idx[order], poly[order]))
        # shared edges between original cells: ridges whose two points are both original
        rp = np.asarray(vor.ridge_points, np.int64).reshape(-1, 2)
        rv = np.asarray(vor.ridge_vertices, np.int64).reshape(
            -1, 2
        )  # in 2-D a ridge has two vertices (-1: at infinity)
        sel = (rp[:, 0] < n) & (rp[:, 1] < n) & (rv[:, 0] != -1) & (rv[:, 1] != -1)
        va, vb = vmap[rv[sel, 0]], vmap[rv[sel, 1]]
        real = va != vb  # not merged into a point
        ab, va, vb = rp[sel][real], va[real], vb[real]
        P, Q = V[va], V[vb]
        pairs = np.column_stack([ab.min(axis=1), ab.max(axis=1)])
        d = Q - P
        lengths = np.hypot(d[:, 0], d[:, 1])
        order = np.lexsort((pairs[:, 1], pairs[:, 0]))
        o = np.asarray(origin, dtype=float)
        spec = Specimen([c[1] + o for c in cells])
        spec.shared_pairs = pairs[order]
        spec.shared_lengths = lengths[order]
        spec.shared_edges = np.stack([P, Q], axis=1)[order] + o
    spec.subsets = {
        "top": np.flatnonzero(jj == ny - 1),
        "bottom": np.flatnonzero(jj == 0),
        "left": np.flatnonzero(ii == 0),
        "right": np.flatnonzero(ii == nx - 1),
    }
    spec.info = {
        "generator": "voronoi",
        "nx": nx,
        "ny": ny,
        "h_pg": h_pg,
        "q_pg": q_pg,
        "seed": seed,
        "width": L1,
        "height": L2,
        "points": pts + np.asarray(origin),
    }
    return spec


#: shapes a Voronoi specimen can be cut to (:func:`voronoi_cut`)
SHAPES = ("rectangle", "disc", "notched_beam")


@dataclass
class CutOptions:
    """What :func:`voronoi_cut` cuts and how (its docstring)."""

    shape: str = "rectangle"
    cut: str = "clip"
    notch_depth: float = 0.0
    notch_width: float = 0.0
    min_piece: float = 0.1
    chord_tol: float = 0.01
    load_width: float = 0.0
    span: float | None = None


def voronoi_cut(nx: int, ny: int, h_pg: float = 1.0, q_pg: float = 0.999, seed: int = 0, origin=(0.0, 0.0), **options):
    """A Moukarzel–Herrmann specimen (:func:`voronoi_specimen`, the box ``nx h × ny h``) cut to a laboratory
    specimen's domain (``options``: the fields of :class:`CutOptions`):

    * ``rectangle`` — the box itself (the specimen of :func:`voronoi_specimen`, unchanged);
    * ``disc`` — the disc inscribed in the (square) box, diameter D = nx h (Brazilian splitting test), its rim a
      polygon within ``chord_tol`` × h of the circle (:func:`.polygon.circle_polygon`); with ``load_width`` b > 0
      flattened at its top and bottom to flats b wide (the load strips' seats: the flattened Brazilian disc);
    * ``notched_beam`` — the box as a beam with a central notch from its lower side, ``notch_depth`` deep and
      ``notch_width`` wide (three-point bending); ``span`` S between the supports (default: the length less h).

    ``cut`` (stated choice, both offered): ``clip`` — a cell crossing the domain's boundary is clipped to it
    (Sutherland–Hodgman; a convex cell stays convex), and a cell reaching into the notch is split into its convex
    parts above, left of and right of the notch, which become particles of their own, glued like any neighbours;
    parts smaller than ``min_piece`` × h² are dropped (slivers would set the time step); ``drop`` — only the cells
    wholly inside the domain are kept (a ragged boundary: less area, no cut cells).  Shared edges are found
    geometrically (:func:`.touching.touching_edges`).  Subsets: ``top``/``bottom``/``left``/``right`` — the
    particles with a corner on the specimen's highest/lowest/leftmost/rightmost line (the disc's flats, or the
    particle at its top and bottom point); a notched beam also ``nose`` (on the top face within ``load_width``/2 of
    the middle), ``support_left``/``support_right`` (on the bottom face within ``load_width``/2 of x = (L ∓ S)/2)
    and ``mouth_left``/``mouth_right`` (on the bottom face next to the notch: the crack mouth opening is the
    difference of their mean e1-displacements).  ``info`` holds the box (``width``, ``height``), the shape, the
    particles' total ``area`` and the exact ``domain_area``."""
    op = CutOptions(**options)
    if op.shape not in SHAPES:
        raise GeometryError(f"voronoi: unknown shape {op.shape!r} (known: {', '.join(SHAPES)})")
    if op.cut not in ("clip", "drop"):
        raise GeometryError(f"voronoi: cut must be 'clip' or 'drop', not {op.cut!r}")
    if op.shape == "rectangle":
        return voronoi_specimen(nx, ny, h_pg, q_pg, seed, origin)
    L1, L2 = nx * h_pg, ny * h_pg
    outer, notch, regions, domain_area, span = _lab_domain(op, nx, ny, h_pg)
    base = voronoi_specimen(nx, ny, h_pg, q_pg, seed)
    small = op.min_piece * h_pg * h_pg
    cells = []
    for v in base.vertices:
        part = clip_convex(v, outer)
        if op.cut == "drop":
            whole = len(part) and abs(signed_area(part) - signed_area(v)) <= 1e-9 * h_pg * h_pg
            if whole and (notch is None or not len(clip_convex(v, notch))):
                cells.append(v)
            continue
        if not len(part):
            continue
        pieces = [part]
        if notch is not None and len(clip_convex(part, notch)):
            pieces = [q for q in (clip_convex(part, r) for r in regions) if len(q)]
        cells.extend(q for q in pieces if signed_area(q) >= small)
    if not cells:
        raise GeometryError("voronoi: no cell is left inside the specimen's domain")
    o = np.asarray(origin, float)
    cells = [c + o for c in cells]
    spec = Specimen(cells)
    spec.shared_pairs, spec.shared_lengths, spec.shared_edges = touching_edges(cells, tol=1e-7 * h_pg)
    if notch is not None:
        _check_ligament(len(cells), spec.shared_pairs, op, L2, small)
    spec.subsets = _lab_subsets(cells, op, o, L1, L2, h_pg, span)
    spec.info = {k: v for k, v in base.info.items() if k != "points"}  # the box's (its points are not 1:1 now)
    spec.info.update(
        shape=op.shape,
        cut=op.cut,
        area=float(sum(signed_area(c) for c in cells)),
        domain_area=float(domain_area),
        load_width=float(op.load_width),
    )
    if op.shape == "disc":
        spec.info["diameter"] = L1
    else:
        spec.info.update(notch_depth=float(op.notch_depth), notch_width=float(op.notch_width), span=span)
    return spec


def _lab_domain(op: CutOptions, nx: int, ny: int, h_pg: float):
    """(outer convex polygon, notch rectangle or None, the convex regions outside the notch, the exact area, the
    span) of :func:`voronoi_cut`'s shape in the box [0, nx h] × [0, ny h]."""
    L1, L2 = nx * h_pg, ny * h_pg
    if op.shape == "disc":
        if nx != ny:
            raise GeometryError(f"voronoi: a disc needs a square box (nx = ny), not {nx} x {ny}")
        if nx < 2:
            raise GeometryError("voronoi: a disc of one cell's diameter is smaller than its cells (nx >= 2)")
        R = L1 / 2
        outer = circle_polygon((R, R), R, op.chord_tol * h_pg)
        area = np.pi * R**2
        if op.load_width > 0.0:
            if op.load_width >= L1:
                raise GeometryError(f"voronoi: the load strips' width {op.load_width:g} must be less than the diameter")
            yf = np.sqrt(R * R - (op.load_width / 2) ** 2)  # the flats at R ± yf
            outer = clip_convex(outer, rectangle((R, R), (L1 + 2 * h_pg, 2 * yf)))
            area -= 2.0 * (R * R * np.arccos(yf / R) - yf * np.sqrt(R * R - yf * yf))
        return outer, None, [], area, None
    a0, w = op.notch_depth, op.notch_width
    if not 0.0 < a0 < L2:
        raise GeometryError(f"voronoi: the notch depth {a0:g} must lie in (0, the beam's height {L2:g})")
    if not 0.0 < w < L1:
        raise GeometryError(f"voronoi: the notch width {w:g} must lie in (0, the beam's length {L1:g})")
    span = L1 - h_pg if op.span is None else float(op.span)
    if not 0.0 < span <= L1:
        raise GeometryError(f"voronoi: the span {span:g} must lie in (0, the beam's length {L1:g}]")
    x1, x2 = (L1 - w) / 2, (L1 + w) / 2
    regions = [  # outside the notch, as convex regions: above its tip, and left and right of it below the tip
        rectangle((L1 / 2, (a0 + L2) / 2), (L1, L2 - a0)),
        rectangle((x1 / 2, a0 / 2), (x1, a0)),
        rectangle(((x2 + L1) / 2, a0 / 2), (L1 - x2, a0)),
    ]
    outer = rectangle((L1 / 2, L2 / 2), (L1, L2))
    return outer, rectangle((L1 / 2, a0 / 2), (w, a0)), regions, L1 * L2 - w * a0, span


def _check_ligament(n: int, pairs, op: CutOptions, L2: float, small: float):
    """Refuse a notched beam that the notch cuts in two: its cells, joined where they share an edge, must be one piece
    (a notch as deep as the beam, or one whose ligament is thinner than the smallest part kept, leaves two)."""
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    p = np.asarray(pairs, np.int64).reshape(-1, 2)
    k, _ = connected_components(coo_matrix((np.ones(len(p)), (p[:, 0], p[:, 1])), shape=(n, n)), directed=False)
    if k == 1:
        return
    raise GeometryError(
        f"voronoi: the notch leaves no ligament: notch_depth {op.notch_depth:g} cm in a beam {L2:g} cm high leaves "
        f"{L2 - op.notch_depth:.3g} cm above its tip, and the beam's cells fall into {k} pieces there"
        + (f" (cell parts under min_piece x h_pg^2 = {small:g} cm^2 are dropped)" if op.cut == "clip" else "")
        + "; make the notch shallower (a0/h = 0.3 in the RILEM and Hoover-Bazant beams)"
    )


def _on_line(cells, axis, value, eps, xlo=-np.inf, xhi=np.inf):
    """Particles touching the line (axis) = value within e1 in [xlo, xhi]: an edge on the line overlapping the
    interval, or a corner on it inside the interval."""
    out = []
    for k, c in enumerate(cells):
        at = np.abs(c[:, axis] - value) <= eps
        if not at.any():
            continue
        a, b = c[:, 0], np.roll(c[:, 0], -1)
        edge = at & np.roll(at, -1) & (np.minimum(a, b) <= xhi + eps) & (np.maximum(a, b) >= xlo - eps)
        corner = at & (a >= xlo - eps) & (a <= xhi + eps)
        if edge.any() or corner.any():
            out.append(k)
    return np.array(out, np.int64)


def _lab_subsets(cells, op: CutOptions, o, L1, L2, h_pg, span) -> dict:
    """The named subsets of :func:`voronoi_cut` (its docstring)."""
    allv = np.vstack(cells)
    eps = 1e-7 * h_pg
    sub = {
        "top": _on_line(cells, 1, allv[:, 1].max(), eps),
        "bottom": _on_line(cells, 1, allv[:, 1].min(), eps),
        "left": _on_line(cells, 0, allv[:, 0].min(), eps),
        "right": _on_line(cells, 0, allv[:, 0].max(), eps),
    }
    if op.shape == "notched_beam":
        hw = max(op.load_width, eps) / 2
        y0, y1, mid = o[1], o[1] + L2, o[0] + L1 / 2
        w = op.notch_width
        sub.update(
            nose=_on_line(cells, 1, y1, eps, mid - hw, mid + hw),
            support_left=_on_line(cells, 1, y0, eps, mid - span / 2 - hw, mid - span / 2 + hw),
            support_right=_on_line(cells, 1, y0, eps, mid + span / 2 - hw, mid + span / 2 + hw),
            mouth_left=_on_line(cells, 1, y0, eps, mid - w / 2 - h_pg, mid - w / 2),
            mouth_right=_on_line(cells, 1, y0, eps, mid + w / 2, mid + w / 2 + h_pg),
        )
        for name, ks in sub.items():
            if not len(ks):
                why = "widen load_width" if name in ("nose", "support_left", "support_right") else "cut = 'clip'"
                raise GeometryError(f"voronoi: no particle on the beam's face for '{name}' ({why})")
    return sub


def split_cells(spec: Specimen, h_pg: float, min_edge: float = 0.3, max_wedge: float = 150.0) -> Specimen:
    """Each cell of a Voronoi specimen cut into convex pieces at its centroid: the pieces are the cell's parts
    between the rays from its centroid to the midpoints of its edges at least ``min_edge`` × h long (a
    barycentric-dual split; the midpoint of an edge shared by two cells is the same point for both, so the pieces
    of neighbouring cells meet edge to edge).  Where two consecutive midpoints are more than ``max_wedge`` degrees
    apart about the centroid, the midpoint of the skipped edge nearest the middle of the gap is added (a piece
    stays convex; the neighbour's whole edge then meets two pieces, which :func:`.touching.touching_edges`
    finds).  A cell with fewer than two edges that long stays whole.

    Why: a crack between Voronoi cells has to follow their edges; inside a cell it can now run along the rays,
    which point roughly at the neighbouring cells' centroids (the Delaunay directions), so it finds straighter
    paths through the network.  Subsets map to all pieces of their cells (the loaded region is unchanged);
    ``info['parent']`` holds each piece's cell.  Shared edges are found geometrically."""
    if not 0.0 < min_edge:
        raise GeometryError(f"voronoi split: min_edge must be > 0, not {min_edge:g}")
    if not 90.0 <= max_wedge < 180.0:
        raise GeometryError(f"voronoi split: max_wedge must lie in [90, 180) degrees, not {max_wedge:g}")
    lim = np.radians(max_wedge)
    pieces, parent = [], []
    for k, v in enumerate(spec.vertices):
        v = np.asarray(v, float)
        n = len(v)
        w = _next(v)
        m = 0.5 * (v + w)
        _, c, _ = polygon_area_centroid_inertia(v)
        ang = np.arctan2(m[:, 1] - c[1], m[:, 0] - c[0])
        split = np.hypot(*(w - v).T) >= min_edge * h_pg
        while split.sum() >= 2:
            idx = np.flatnonzero(split)
            gaps = np.mod(ang[np.roll(idx, -1)] - ang[idx], 2.0 * np.pi)
            g = int(np.argmax(gaps))
            if gaps[g] <= lim:
                break
            i, j = idx[g], idx[(g + 1) % len(idx)]
            between = [(i + d) % n for d in range(1, (j - i) % n)]
            if not between:
                break
            mid = ang[i] + 0.5 * gaps[g]
            split[min(between, key=lambda e: abs(np.angle(np.exp(1j * (ang[e] - mid)))))] = True
        idx = np.flatnonzero(split)
        if len(idx) < 2:
            pieces.append(v)
            parent.append(k)
            continue
        for a, b in zip(idx, np.roll(idx, -1)):
            ring = [(a + d) % n for d in range(1, (b - a) % n + 1)] if b != a else []
            pieces.append(np.vstack([c, m[a], v[ring], m[b]]))
            parent.append(k)
    parent = np.asarray(parent, np.int64)
    out = Specimen(pieces)
    out.shared_pairs, out.shared_lengths, out.shared_edges = touching_edges(pieces, tol=1e-7 * h_pg)
    out.subsets = {name: np.flatnonzero(np.isin(parent, idx)) for name, idx in spec.subsets.items()}
    out.info = {key: val for key, val in spec.info.items() if key != "points"}
    out.info.update(split="centroid", split_min_edge=float(min_edge), cells=len(spec), parent=parent)
    return out


def hexagon_packing(
    width: float,
    row_counts,
    rows: int,
    origin=(0.0, 0.0),
    first_row_shift: float = 0.0,
    missing=(),
    spacing: float | None = None,
    sides: int = 6,
) -> Specimen:
    """Regular packing of "pointy-top" hexagons (flat sides vertical).

    Row ``r`` (0 = bottom) holds ``row_counts[r % len(row_counts)]`` hexagons whose
    centroids are at ``origin + ((k + s_r) w, r w sqrt(3)/2)``, with
    ``s_r = (first_row_shift + r/2) mod 1``: consecutive rows are staggered by w/2,
    neighbours sit at 0, +-60 and 180 degrees and touch along full edges.
    ``missing`` lists ``(row, k)`` positions left empty (defects).  ``spacing``
    (default ``width``) is the centroid distance of neighbours: a smaller value
    gives a pre-compressed packing whose neighbours overlap (benchmarks), a larger one a packing with gaps;
    only neighbours that share an edge (``spacing == width``) are recorded as touching (geometry/touching.py).
    ``sides`` (even, default 6) replaces the hexagons by regular polygons of the
    same width across flats, a flat facing ±e1 (24 sides: disk-like particles).
    """
    if width <= 0:
        raise GeometryError("hexagon_packing: width must be > 0")
    counts = [int(c) for c in row_counts]
    if rows < 1 or not counts or min(counts) < 1:
        raise GeometryError("hexagon_packing: rows and row_counts must be >= 1")
    miss = {(int(r), int(k)) for r, k in missing}
    for r, k in miss:
        if not (0 <= r < rows and 0 <= k < counts[r % len(counts)]):
            raise GeometryError(f"hexagon_packing: missing position [{r}, {k}] is outside the packing")
    sp = width if spacing is None else float(spacing)
    if sp <= 0:
        raise GeometryError("hexagon_packing: spacing must be > 0")
    dy = sp * np.sqrt(3.0) / 2.0
    verts, rc = [], []
    for r in range(rows):
        s = (first_row_shift + 0.5 * r) % 1.0
        for k in range(counts[r % len(counts)]):
            if (r, k) in miss:
                continue
            c = (origin[0] + (k + s) * sp, origin[1] + r * dy)
            verts.append(
                hexagon(width, c)
                if sides == 6
                else regular_polygon(sides, 0.5 * width / np.cos(np.pi / sides), rotation=np.pi / sides, center=c)
            )
            rc.append((r, k))
    if not verts:
        raise GeometryError("hexagon_packing: every position is missing")
    rc = np.array(rc)
    last_k = {r: rc[rc[:, 0] == r, 1].max() for r in np.unique(rc[:, 0])}
    first_k = {r: rc[rc[:, 0] == r, 1].min() for r in np.unique(rc[:, 0])}
    spec = Specimen(verts)
    spec.subsets = {
        "bottom": np.flatnonzero(rc[:, 0] == rc[:, 0].min()),
        "top": np.flatnonzero(rc[:, 0] == rc[:, 0].max()),
        "left": np.array([i for i, (r, k) in enumerate(rc) if k == first_k[r]], dtype=np.int64),
        "right": np.array([i for i, (r, k) in enumerate(rc) if k == last_k[r]], dtype=np.int64),
    }
    # touching pairs from the geometry itself: a spacing above the width leaves gaps, one below it overlaps
    spec.shared_pairs, spec.shared_lengths, spec.shared_edges = touching_edges(verts)
    spec.info = {"generator": "hexagon_packing", "rows_cols": rc}
    return spec


def single_polygon(vertices) -> Specimen:
    """A specimen of one polygon with the given vertices (counter-clockwise, convex)."""
    return Specimen([np.asarray(vertices, dtype=float)])


def single_regular_polygon(n_sides: int, circumradius: float, center, rotation: float = 0.0) -> Specimen:
    """A specimen of one regular polygon of ``n_sides`` sides and circumradius ``circumradius`` about ``center``,
    turned by ``rotation`` (rad)."""
    return Specimen([regular_polygon(n_sides, circumradius, rotation, center)])


def single_rectangle(center, size) -> Specimen:
    """A specimen of one axis-parallel rectangle of ``size`` (width, height) about ``center``."""
    return Specimen([rectangle(center, size)])


def random_disk_packing(n: int, radius_range, box, seed: int = 0, max_tries: int = 200000):
    """Non-overlapping random disks in ``box = (x0, y0, x1, y1)``.

    The n radii are drawn first, uniform in ``radius_range``, and placed largest first by random sequential
    addition (each at a uniformly random position that overlaps no disk placed before).  Drawing a new radius
    at every try instead biases the packing towards small disks at higher densities (seen: 1,950 disks at a
    packing fraction of 0.43 had a mean radius 11 % below the distribution's).  Returns centres (n, 2) and
    radii (n,), in placement order.
    """
    rng = np.random.default_rng(seed)
    x0, y0, x1, y1 = box
    rmin, rmax = radius_range
    radii = np.sort(rng.uniform(rmin, rmax, n))[::-1]
    c = np.zeros((n, 2))
    r = np.zeros(n)
    tries = 0
    for k, rr in enumerate(radii):
        if 2 * rr > min(x1 - x0, y1 - y0):
            raise GeometryError(f"disk packing: a disk of radius {rr:g} does not fit into the box")
        while True:
            tries += 1
            if tries > max_tries:
                raise GeometryError(f"disk packing: could only place {k} of {n} disks in {max_tries} tries")
            p = rng.uniform([x0 + rr, y0 + rr], [x1 - rr, y1 - rr])
            if k and np.any(np.hypot(*(c[:k] - p).T) < r[:k] + rr):
                continue
            c[k], r[k] = p, rr
            break
    return c, r
