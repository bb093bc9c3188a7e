"""The lattice plate problem of the adaptive coupling (Sorg 2014): a plate with a rhombus-shaped hole,
members (stiffness, strength; aggregates and their interface), supports and the displacement pattern that
stretches it.  The four examples (:mod:`.examples`) and scenario files (:mod:`.scenario`) both build one."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .lattice import triangular_lattice
from .members import saw_teeth
from .mesh import domain_set, triangulated


@dataclass
class Problem:
    """A lattice plate problem: the lattice, its domain, member stiffnesses and strengths, the prescribed
    displacement pattern, the measured DOFs, the reference stiffness, the member law, the aggregates."""

    lat: object
    domain: object  # the domain triangles (i, j, o, 1): a set, or the set-like meshkern.DomainView
    k: np.ndarray  # member stiffnesses
    f: np.ndarray  # member strengths
    pattern: dict  # {(node, comp): unit value}
    measure: list
    k_ref: float
    softening: bool
    aggregates: list


def aggregates(width, height, hole, a, seed, radii, fraction):
    """Random sequential placement of round aggregates (``radii``, largest first) up to ``fraction`` of the
    plate's area (each class in turn up to its share), clear of the edges, the hole and each other by one
    spacing; gives up on a class after 4,000 rejected tries; leaves out a class too large for the plate."""
    rng = np.random.default_rng(seed)
    target = fraction * width * height
    placed, area = [], 0.0
    for q, r in enumerate(radii):
        if 2.0 * (r + a) > min(width, height):  # a class that does not fit a small plate (a quick look)
            continue
        tries = 0
        while area < target * (q + 1) / len(radii) and tries < 4000:
            tries += 1
            x, y = rng.uniform(r + a, width - r - a), rng.uniform(r + a, height - r - a)
            if hole is not None:
                (cx, cy), (hx, hy) = hole
                if abs(x - cx) / (hx + r + a) + abs(y - cy) / (hy + r + a) < 1.0:
                    continue
            if any(math.hypot(x - px, y - py) < r + pr + a for px, py, pr in placed):
                continue
            placed.append((x, y, r))
            area += math.pi * r * r
    return placed


def make_problem(a, width, height, hole, k0, f_t, softening, agg=None) -> Problem:
    """The plate of spacing ``a`` over [0, width] × [0, height] less the rhombus ``hole`` ((centre, half
    diagonals) or None), members of stiffness ``k0`` and strength ``f_t``, aggregates ``agg`` (the keys of a
    scenario's [aggregates] table, or None), stretched in e1 (left edge held in e1, its lowest node in e2)."""
    lat = triangulated(triangular_lattice(a, width, height, hole=hole))
    m = lat.n_members
    k = np.full(m, float(k0))
    f = np.full(m, float(f_t))
    aggs = []
    if agg is not None:
        aggs = aggregates(width, height, hole, a, agg["seed"], tuple(agg["radii"]), agg["fraction"])
        inside = np.full(lat.n_nodes, -1)
        for q, (x, y, r) in enumerate(aggs):
            inside[np.hypot(lat.x[:, 0] - x, lat.x[:, 1] - y) <= r] = q
        ia, ib = inside[lat.members[:, 0]], inside[lat.members[:, 1]]
        ag = (ia >= 0) & (ia == ib)
        itz = (ia >= 0) != (ib >= 0)
        k[ag] *= agg["k_factor"]
        f[ag] *= agg["f_t_factor"]
        k[itz] *= agg["interface_k_factor"]
        f[itz] *= agg["interface_f_t_factor"]
    x = lat.x
    ij = lat.ij
    left = [(int(ij[i, 0]), int(ij[i, 1])) for i in np.flatnonzero(x[:, 0] < x[:, 0].min() + 1e-9 * a)]
    right = [(int(ij[i, 0]), int(ij[i, 1])) for i in np.flatnonzero(x[:, 0] > x[:, 0].max() - 1e-9 * a)]
    pattern = {(nd, 0): 0.0 for nd in left}
    pattern.update({(nd, 0): 1.0 for nd in right})
    low = min(left, key=lambda nd: nd[1])
    pattern[(low, 1)] = 0.0
    return Problem(
        lat,
        domain_set(lat),
        k,
        f,
        pattern,
        [(nd, 0) for nd in right],
        float(k0),
        bool(softening),
        aggs,
    )


def member_teeth(p: Problem, ductility, n):
    """(strengths, stiffnesses) of every member's teeth: the law per unit stiffness and strength with
    δ_u = ``ductility`` δ_t, scaled per member (strengths by its f_t, stiffnesses by its k)."""
    tf, tk = saw_teeth(1.0, 1.0, ductility, n)
    TF = p.f[:, None] * tf[None, :]
    TK = p.k[:, None] * tk[None, :]
    return TF, TK
