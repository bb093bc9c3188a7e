"""Spatial domain decomposition of a scene over ranks: who owns which particle, and which copies (ghosts) each
rank needs to evaluate the forces on what it owns.  The geometry of the distributed explicit solver (the issue
"One run on every core and across machines"; the solver side is engine/distributed.py); no MPI here, so the rules
can be tested on one process.

**Subdomains: recursive coordinate bisection (RCB).**  The set of particle centroids is cut at the weighted
median along the longer side of its bounding box, the two halves get ``⌊P/2⌋`` and ``⌈P/2⌉`` ranks, and so on
until every box holds one rank (LAMMPS ``balance rcb``, Zoltan's RCB).  Each rank then owns ``n/P`` particles
to within a few (one per level of the bisection), whatever the packing's shape.  Equal coordinates are ordered by
the particle's number, so that the ranks of a running decomposition can find the same cuts together, each from the
particles it owns (:func:`bisect_ranks`, engine/migrate.py's re-cut).  Slabs along the longer axis (``method="slabs"``, LAMMPS's
default bricks in one direction) are the special case that always cuts that one axis: two boundaries per rank
of the specimen's full width, so their ghosts grow with √n while RCB's shrink with √(n/P) —
``polydem_cli/benchmarks/halo.py`` counts both; slabs are kept for the two- and four-rank case, where they are
as good and their boundaries never move sideways.

**Ghosts.**  Two particles interact only when their bounding circles come within ``reach`` of each other
(``Family.reach``: the pair-list buffer of polygon contact and of the disks; a bond joins particles whose circles
touched at t0, and its partners are added explicitly, whatever the distance).  Rank ``r`` therefore holds, beside
what it owns, every particle ``j`` whose centroid lies within ``R_j + R_max + reach`` of its box (``R_max``: the
largest bounding radius among the ordinary particles) and every bond partner of a particle it owns — a sufficient
set, checked against the brute-force pair list in tests/test_decompose.py.

**Large particles** (load plates, walls: ``is_large`` of the contact search, bounding radius above four times the
median) are copied to every rank: one of them would otherwise make every rank's halo as wide as the plate.  Their
generalised forces are summed over the ranks, as the servo walls' global reductions are.

**Who evaluates a pair** (so that no force is counted twice): a pair of two ordinary particles is evaluated on
every rank that holds both, and each rank adds its forces only to the particles it owns; a pair of an ordinary
particle and a large one is evaluated for the large one's sum only on the rank that owns the ordinary one; a
pair of two large particles only on rank 0.  A pair's history (contact history, a bond's damage) therefore
lives, identical, on the rank of each of its owned particles, and travels with a particle when it migrates; the
result file takes it from the rank owning the pair's smaller global index (for a pair with a large particle, from
the rank owning the ordinary one).  Pair scalars (energies, counts) are counted once, on the rank owning the pair's
smaller index, and ghost–ghost pairs skipped (engine/distributed.py, the families' kernels).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..errors import DecompositionError  # noqa: F401 - raised here, imported from here by callers

METHODS = ("rcb", "slabs")


@dataclass
class Decomposition:
    """Owner of every particle and the box of every rank (``boxes[r] = (x_lo, x_hi, y_lo, y_hi)``; the outer boxes
    reach to ±inf so that the boxes tile the plane), the halo width of the ordinary particles and which
    particles are copied to every rank."""

    method: str
    owner: np.ndarray  # (n,) rank owning each particle
    boxes: np.ndarray  # (P, 4)
    halo: float  # R_max + reach [cm]: a particle j is a ghost of a box within R_j + halo of its centroid
    replicated: np.ndarray  # (n,) bool: large particles, on every rank

    @property
    def ranks(self) -> int:
        return int(self.boxes.shape[0])

    def counts(self) -> np.ndarray:
        """Particles owned by each rank."""
        return np.bincount(self.owner, minlength=self.ranks)

    def imbalance(self) -> float:
        """Largest owned count over the mean (1: perfectly balanced)."""
        c = self.counts()
        return float(c.max() / c.mean()) if c.sum() else 1.0


def bisect(points: np.ndarray, nranks: int, method: str = "rcb", weights=None) -> tuple:
    """(owner (n,), boxes (P, 4)): recursive coordinate bisection of ``points`` (n, 2) into ``nranks`` boxes holding
    equal weight (default one per point) to within one point per level of bisection; ``method="slabs"`` cuts along the longer axis of the
    whole set only."""
    if method not in METHODS:
        raise ValueError(f"method {method!r}: one of {', '.join(METHODS)}")
    pts = np.asarray(points, float)
    n = len(pts)
    w = np.ones(n) if weights is None else np.asarray(weights, float)
    owner = np.zeros(n, np.int64)
    boxes = np.zeros((nranks, 4))
    ext = np.ptp(pts, axis=0) if n else np.zeros(2)
    fixed_axis = int(np.argmax(ext)) if method == "slabs" else None
    stack = [(np.arange(n), 0, nranks, np.array([-np.inf, np.inf, -np.inf, np.inf]))]
    while stack:
        idx, r0, p, box = stack.pop()
        if p == 1:
            owner[idx] = r0
            boxes[r0] = box
            continue
        sub = pts[idx]
        axis = fixed_axis if fixed_axis is not None else int(np.argmax(np.ptp(sub, axis=0))) if len(idx) else 0
        left = p // 2
        order = np.lexsort((idx, sub[:, axis]))  # ties by number: the order the ranks' bisection (bisect_ranks) keeps
        cum = np.cumsum(w[idx][order])
        k = int(np.searchsorted(cum, cum[-1] * left / p, side="left")) + 1 if len(idx) else 0
        k = min(max(k, 0), len(idx))
        lo_idx, hi_idx = idx[order[:k]], idx[order[k:]]
        if k == 0:
            cut = box[2 * axis]
        elif k == len(idx):
            cut = box[2 * axis + 1]
        else:  # halfway between the last point of the lower half and the first of the upper one
            cut = 0.5 * (sub[order[k - 1], axis] + sub[order[k], axis])
        lo_box, hi_box = box.copy(), box.copy()
        lo_box[2 * axis + 1] = cut
        hi_box[2 * axis] = cut
        stack.append((lo_idx, r0, left, lo_box))
        stack.append((hi_idx, r0 + left, p - left, hi_box))
    return owner, boxes


_TOP = np.uint64(1 << 63)


def _ordered(c: np.ndarray) -> np.ndarray:
    """Coordinates as unsigned integers of the same order (IEEE bits, the sign flipped for positive numbers and all
    bits for negative ones; −0 as +0, as a sort compares them)."""
    b = (np.asarray(c, float) + 0.0).view(np.uint64)
    return np.where(b & _TOP, ~b, b | _TOP)


def _unordered(u) -> float:
    u = np.uint64(u)
    return float(np.array([u & ~_TOP if u & _TOP else ~u], np.uint64).view(float)[0])


def _split_count(m: int, left: int, p: int) -> int:
    """How many of ``m`` points of unit weight :func:`bisect` puts in the lower ``left`` of ``p`` ranks: one more than
    the cumulated weights below ``m · left / p`` (its searchsorted), at most m."""
    if m == 0:
        return 0
    t = float(m) * left / p
    return min(m, max(0, math.ceil(t) - 1) + 1)


def bisect_ranks(points, gids, nranks: int, reduce, method: str = "rcb") -> tuple:
    """:func:`bisect` of the particles of every rank, computed where they are: each rank passes the centroids
    ``points`` (n_r, 2) of the particles it owns and their global numbers ``gids``, and gets each one's new owner and
    every rank's box — the same owners and boxes as :func:`bisect` of all the points in the order of their numbers
    (unit weights).  The ranks meet only in ``reduce(array, op)`` (op "sum", "min" or "max" over the ranks, an
    allreduce) of arrays of a few numbers per box: per level of the bisection the median of each box is found by
    counting (a bisection over the coordinates' 64 bits, ties among equal coordinates by number), about a hundred
    reductions per level and no array of particles sent anywhere (LAMMPS' ``balance rcb`` and Zoltan's RCB find their
    cuts so)."""
    if method not in METHODS:
        raise ValueError(f"method {method!r}: one of {', '.join(METHODS)}")
    pts = np.asarray(points, float)[:, :2] + 0.0
    gid = np.asarray(gids, np.int64)
    n = len(pts)
    keys = np.column_stack([_ordered(pts[:, 0]), _ordered(pts[:, 1])]) if n else np.zeros((0, 2), np.uint64)
    owner = np.zeros(n, np.int64)
    boxes = np.zeros((nranks, 4))
    fixed_axis = None
    if method == "slabs":
        lo = reduce(pts.min(axis=0) if n else np.full(2, np.inf), "min")
        hi = reduce(pts.max(axis=0) if n else np.full(2, -np.inf), "max")
        fixed_axis = int(np.argmax(np.where(np.isfinite(hi - lo), hi - lo, 0.0)))
    level = [(0, nranks, np.array([-np.inf, np.inf, -np.inf, np.inf]))]
    where = np.zeros(n, np.int64)  # each point's box in ``level`` (−1: its rank found)
    while level:
        nb = len(level)
        act = np.flatnonzero(where >= 0)
        w, p_, g_ = where[act], pts[act], gid[act]
        cnt = reduce(np.bincount(w, minlength=nb).astype(np.int64), "sum")
        lo = np.full((nb, 2), np.inf)
        hi = np.full((nb, 2), -np.inf)
        np.minimum.at(lo, w, p_)
        np.maximum.at(hi, w, p_)
        lo, hi = reduce(lo, "min"), reduce(hi, "max")
        axis = np.zeros(nb, np.int64)
        for b in range(nb):
            if fixed_axis is not None:
                axis[b] = fixed_axis
            elif cnt[b]:
                axis[b] = int(np.argmax(hi[b] - lo[b]))
        split = np.array([lv[1] > 1 for lv in level])
        k = np.array([_split_count(int(cnt[b]), lv[1] // 2, lv[1]) if split[b] else 0 for b, lv in enumerate(level)])
        key = keys[act, axis[w]]
        coord = p_[np.arange(len(act)), axis[w]]

        def count(mask, w=w, nb=nb):
            return reduce(np.bincount(w, weights=mask, minlength=nb).astype(np.int64), "sum")

        # the k-th smallest coordinate of each box: the least v with at least k coordinates <= v
        a = np.zeros(nb, np.uint64)
        z = np.full(nb, np.iinfo(np.uint64).max, np.uint64)
        search = split & (k > 0) & (k < cnt)
        while True:
            open_ = search & (a < z)
            if not open_.any():
                break
            mid = a + (z - a) // np.uint64(2)
            up = open_ & (count(key <= mid[w]) >= k)
            z = np.where(up, mid, z)
            a = np.where(open_ & ~up, mid + np.uint64(1), a)
        v = a
        below = count(key < v[w])
        tie = key == v[w]
        equal = count(tie)
        # among the points at v, the least number g with k − below of them numbered <= g
        ga = np.zeros(nb, np.int64)
        gz = np.zeros(nb, np.int64)
        np.maximum.at(gz, w[tie], g_[tie])
        gz = reduce(gz, "max")
        need = k - below
        while True:
            open_ = search & (ga < gz)
            if not open_.any():
                break
            mid = ga + (gz - ga) // 2
            up = open_ & (count(tie & (g_ <= mid[w])) >= need)
            gz = np.where(up, mid, gz)
            ga = np.where(open_ & ~up, mid + 1, ga)
        # the (k+1)-th coordinate: v again if the tie goes on past k, else the least one above v
        nxt = np.full(nb, np.inf)
        np.minimum.at(nxt, w, np.where(key > v[w], coord, np.inf))
        nxt = reduce(nxt, "min")
        nlevel = []
        where = np.full(n, -1, np.int64)
        for b, (r0, p, box) in enumerate(level):
            mine = act[w == b]
            if p == 1:
                owner[mine] = r0
                boxes[r0] = box
                continue
            ax = int(axis[b])
            kb = key[w == b]
            if k[b] == 0:
                low = np.zeros(len(mine), bool)
                cut = box[2 * ax]
            elif k[b] == cnt[b]:
                low = np.ones(len(mine), bool)
                cut = box[2 * ax + 1]
            else:
                vk = _unordered(v[b])
                low = (kb < v[b]) | ((kb == v[b]) & (gid[mine] <= ga[b]))
                cut = 0.5 * (vk + (vk if below[b] + equal[b] > k[b] else nxt[b]))
            lo_box, hi_box = box.copy(), box.copy()
            lo_box[2 * ax + 1] = cut
            hi_box[2 * ax] = cut
            left = p // 2
            where[mine[low]] = len(nlevel)
            nlevel.append((r0, left, lo_box))
            where[mine[~low]] = len(nlevel)
            nlevel.append((r0 + left, p - left, hi_box))
        level = nlevel
    return owner, boxes


def box_distance(points: np.ndarray, box) -> np.ndarray:
    """Euclidean distance of each point (n, 2) to the box ``(x_lo, x_hi, y_lo, y_hi)`` (0 inside)."""
    p = np.asarray(points, float)
    dx = np.maximum(np.maximum(box[0] - p[:, 0], p[:, 0] - box[1]), 0.0)
    dy = np.maximum(np.maximum(box[2] - p[:, 1], p[:, 1] - box[3]), 0.0)
    return np.hypot(dx, dy)


def box_gap(box, boxes) -> np.ndarray:
    """Distance of the box ``(x_lo, x_hi, y_lo, y_hi)`` to each of ``boxes`` (P, 4) (0 where they touch or overlap)."""
    b = np.asarray(boxes, float)
    dx = np.maximum(np.maximum(box[0] - b[:, 1], b[:, 0] - box[1]), 0.0)
    dy = np.maximum(np.maximum(box[2] - b[:, 3], b[:, 2] - box[3]), 0.0)
    return np.hypot(dx, dy)


def decompose(points, radius, nranks: int, reach: float, is_large=None, method: str = "rcb") -> Decomposition:
    """The decomposition of particles at ``points`` (n, 2) with bounding radii ``radius`` over ``nranks`` ranks
    for interactions reaching ``reach`` beyond touching bounding circles.  DecompositionError when a rank would
    own no particle or a box is narrower, across a direction it was cut in, than the interaction range
    ``2 R_max + reach`` (its ghosts would then come from beyond the adjacent boxes: fewer ranks, or
    ``method="rcb"`` instead of slabs)."""
    if nranks < 1:
        raise DecompositionError(f"ranks = {nranks}: at least 1")
    pts = np.asarray(points, float)[:, :2]
    radius = np.asarray(radius, float)
    large = np.zeros(len(pts), bool) if is_large is None else np.asarray(is_large, bool)
    small = ~large
    if small.sum() < nranks:
        raise DecompositionError(
            f"{nranks} ranks for {int(small.sum())} particles (plates and walls aside): each rank must own at least one"
        )
    owner = np.zeros(len(pts), np.int64)
    own_small, boxes = bisect(pts[small], nranks, method)
    owner[small] = own_small
    if large.any():  # a large particle is owned by the rank whose box holds its centroid (copied to all)
        for i in np.flatnonzero(large):
            owner[i] = int(np.argmin([box_distance(pts[i : i + 1], b)[0] for b in boxes]))
    halo = float(radius[small].max()) + float(reach)
    d = Decomposition(method, owner, boxes, halo, large)
    if nranks > 1:
        w = _thickness(boxes, pts[small])
        r = int(np.argmin(w))
        span = halo + float(radius[small].max())  # the farthest centroid distance of two interacting particles
        if w[r] < span:
            raise DecompositionError(
                f"{nranks} ranks ({method}): the box of rank {r} is {w[r]:.4g} cm across, narrower than the "
                f"interaction range {span:.4g} cm (two bounding radii and the reach {reach:.4g} cm), so its ghosts "
                "would come from beyond its neighbours: use fewer ranks"
                + (" or method 'rcb'" if method == "slabs" else "")
            )
    return d


def plan(system, nranks: int, method: str = "rcb") -> Decomposition:
    """The decomposition of a built scene at its initial positions: the reach is the largest of its interaction
    families' (``Family.reach``), the large particles those of the contact search (interactions/search.py)."""
    from ..interactions.search import large_particle_mask
    from .families import used_families

    reach = max([0.0] + [float(f.reach(system)) for f in used_families(system)])
    return decompose(system.x0, system.radius, nranks, reach, large_particle_mask(system.radius), method)


def _thickness(boxes, pts) -> np.ndarray:
    """Per box, its extent across the directions it was cut in (an outer side cut to the points' bounding box;
    a direction never cut does not count)."""
    lo, hi = pts.min(axis=0), pts.max(axis=0)
    out = np.full(len(boxes), np.inf)
    for ax in (0, 1):
        a, b = boxes[:, 2 * ax], boxes[:, 2 * ax + 1]
        cut = np.isfinite(a) | np.isfinite(b)
        ext = np.minimum(b, hi[ax]) - np.maximum(a, lo[ax])
        out = np.where(cut, np.minimum(out, ext), out)
    return out


def ghosts(d: Decomposition, points, radius, rank: int, bonds=None) -> np.ndarray:
    """The particles rank ``rank`` holds without owning them (sorted global indices): ordinary particles of other
    ranks within ``R_j + halo`` of its box, every large particle, and the bond partners (``bonds``: (nb, 2)
    global pairs) of the particles it owns."""
    pts = np.asarray(points, float)[:, :2]
    radius = np.asarray(radius, float)
    near = box_distance(pts, d.boxes[rank]) <= radius + d.halo
    need = (near | d.replicated) & (d.owner != rank)
    if bonds is not None and len(bonds):
        b = np.asarray(bonds, np.int64)
        mine = d.owner == rank
        for s, t in ((0, 1), (1, 0)):
            sel = mine[b[:, s]] & (d.owner[b[:, t]] != rank)
            need[b[sel, t]] = True
    return np.flatnonzero(need)


def evaluates(d: Decomposition, rank: int, i, j) -> np.ndarray:
    """Whether rank ``rank`` adds the force of pair (i, j) (arrays of global indices) to the sums it reports: the
    rule of the module docstring, for the replicated particles' global sums (a pair of ordinary particles is
    evaluated wherever both are held, each rank keeping the forces on its own particles only)."""
    i, j = np.asarray(i, np.int64), np.asarray(j, np.int64)
    li, lj = d.replicated[i], d.replicated[j]
    both = li & lj
    one = li ^ lj
    ordinary = np.where(li, j, i)  # the ordinary partner of a mixed pair
    return np.where(both, rank == 0, np.where(one, d.owner[ordinary] == rank, True))
