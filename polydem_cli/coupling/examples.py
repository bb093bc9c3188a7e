"""The four examples of Sorg (2014): a rectangular plate with a central rhombus-shaped hole, stretched
horizontally — homogeneous / heterogeneous lattice, linear elastic / softening members — each solved
adaptively and fully resolved (the reference).

Choices the abstract leaves open (stated here, used by ``polydem study coupling``):

* plate ``W × H`` = 120 a × 72 rows (62.4 a), spacing a = 1 cm; the rhombus hole centred, half diagonals
  W/8 along e1 and H/6 along e2;
* supports: the left edge held in e1 (its lowest node also in e2), the right edge displaced in e1 (the unit
  pattern of the analysis, scaled by the load factor);
* members: k = 1e4 dyn/cm (matrix); heterogeneous: round aggregates of radii 6 a, 4 a and 2.5 a placed at
  random (seed 1) outside the hole up to 35 % of the area, members with both ends in one aggregate stiffer
  (k × 2.5) and stronger (f_t × 3), members with one end in an aggregate the weak interface (k × 0.6,
  f_t × 0.5) — the proportions of a normal-strength concrete;
* softening: f_t = 1e-3 k a (a tensile elongation of 1e-3 a), δ_u = 5 f_t/k (of each member's own f_t and
  k), 10 teeth, as many events as it takes the reaction to fall below 70 % of its peak (at most ``max_events``);
* adaptivity: coarsest elements of side 8 a, strain-jump tolerance 0.1, members refined to the lattice
  before they carry 80 % of their strength (softening).
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass

import numpy as np

from .lattice import triangular_lattice
from .members import saw_teeth
from .mesh import domain_triangles, triangulated

A = 1.0
K_MAT = 1.0e4
WIDTH, ROWS = 120.0, 72
FT = 1.0e-3 * K_MAT * A
DU = 5.0 * FT / K_MAT
TEETH = 10
AGG = {"k": 2.5, "f": 3.0}
ITZ = {"k": 0.6, "f": 0.5}
RADII = (6.0, 4.0, 2.5)
FRACTION = 0.35
EXAMPLES = ("homogeneous_elastic", "heterogeneous_elastic", "homogeneous_softening", "heterogeneous_softening")


@dataclass
class Problem:
    lat: object
    domain: set
    k: np.ndarray  # member stiffnesses
    f: np.ndarray  # member strengths
    pattern: dict  # {(node, comp): unit value}
    measure: list
    k_ref: float
    softening: bool
    aggregates: list


def plate(width=WIDTH, rows=ROWS, a=A):
    H = rows * math.sqrt(3) / 2 * a
    hole = ((width / 2, H / 2), (width / 8, H / 6))
    return triangulated(triangular_lattice(a, width, H, hole=hole)), hole, H


def aggregates(width, height, hole, a=A, seed=1):
    """Random sequential placement of round aggregates (radii RADII × a, largest first) up to FRACTION of the
    plate's area, clear of the edges, the hole and each other by one spacing."""
    rng = np.random.default_rng(seed)
    target = FRACTION * width * height
    placed, area = [], 0.0
    (cx, cy), (hx, hy) = hole
    for r0 in RADII:
        r = r0 * a
        tries = 0
        while area < target * (RADII.index(r0) + 1) / len(RADII) and tries < 4000:
            tries += 1
            x, y = rng.uniform(r + a, width - r - a), rng.uniform(r + a, height - r - a)
            if abs(x - cx) / (hx + r + a) + abs(y - cy) / (hy + r + a) < 1.0:
                continue
            if any(math.hypot(x - px, y - py) < r + pr + a for px, py, pr in placed):
                continue
            placed.append((x, y, r))
            area += math.pi * r * r
    return placed


def problem(name: str, width=WIDTH, rows=ROWS) -> Problem:
    if name not in EXAMPLES:
        raise ValueError(f"unknown example {name!r}; the examples are {', '.join(EXAMPLES)}")
    lat, hole, H = plate(width, rows)
    m = lat.n_members
    k = np.full(m, K_MAT)
    f = np.full(m, FT)
    aggs = []
    if name.startswith("heterogeneous"):
        aggs = aggregates(width, H, hole)
        inside = np.full(lat.n_nodes, -1)
        for q, (x, y, r) in enumerate(aggs):
            inside[np.hypot(lat.x[:, 0] - x, lat.x[:, 1] - y) <= r] = q
        ia, ib = inside[lat.members[:, 0]], inside[lat.members[:, 1]]
        agg = (ia >= 0) & (ia == ib)
        itz = (ia >= 0) != (ib >= 0)
        k[agg] *= AGG["k"]
        f[agg] *= AGG["f"]
        k[itz] *= ITZ["k"]
        f[itz] *= ITZ["f"]
    x = lat.x
    ij = [tuple(map(int, v)) for v in lat.ij]
    left = [ij[i] for i in np.flatnonzero(x[:, 0] < 1e-9)]
    right = [ij[i] for i in np.flatnonzero(x[:, 0] > x[:, 0].max() - 1e-9)]
    pattern = {(nd, 0): 0.0 for nd in left}
    pattern.update({(nd, 0): 1.0 for nd in right})
    low = min(left, key=lambda nd: nd[1])
    pattern[(low, 1)] = 0.0
    return Problem(
        lat,
        domain_triangles(set(lat.node_at())),
        k,
        f,
        pattern,
        [(nd, 0) for nd in right],
        K_MAT,
        name.endswith("softening"),
        aggs,
    )


def _teeth(p: Problem):
    # per unit stiffness and strength (δ_u = 5 δ_t), scaled per member: strengths by its f_t, stiffnesses by its k
    tf, tk = saw_teeth(1.0, 1.0, DU * K_MAT / FT, TEETH)
    TF = p.f[:, None] * tf[None, :]
    TK = p.k[:, None] * tk[None, :]
    return TF, TK


def run(name: str, adaptive: bool, max_events=400, drop=0.7, width=WIDTH, rows=ROWS) -> dict:
    """Solve one example; returns its load–displacement record, DOFs, wall time and peak memory (RSS growth)."""
    import resource

    from .adaptive import Model, _member_weights, mark, refine, run_sla_adaptive
    from .lattice import assemble, solve_displacements
    from .mesh import initial_mesh
    from .sla import run_sla

    p = problem(name, width, rows)
    node = p.lat.node_at()
    rss0 = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    t0 = time.perf_counter()
    out = {"example": name, "adaptive": adaptive, "nodes": p.lat.n_nodes, "members": p.lat.n_members}
    if not p.softening:
        if adaptive:
            els, stages = initial_mesh(p.domain, 8), []
            weights = _member_weights(p.lat, p.domain)
            for _ in range(20):
                model = Model(p.lat, p.domain, els, p.k, k_ref=p.k_ref, weights=weights)
                st = model.solve(p.pattern, p.measure, full=False)
                stages.append(
                    {
                        "dofs": st.dofs,
                        "reaction": st.reaction,
                        "elements": len(els),
                        "levels": np.bincount(st.level, minlength=4)[1:].tolist(),
                    }
                )
                marked = mark(p.lat, els, st.u, 0.1, model)
                if not marked:
                    break
                els = refine(els, marked)
            out.update(reaction=st.reaction, dofs=st.dofs, stages=stages, elements=els)
        else:
            Kg = assemble(p.lat, p.k)
            u = solve_displacements(Kg, {2 * node[nd] + c: v for (nd, c), v in p.pattern.items()}, 2 * p.lat.n_nodes)
            r = Kg @ u
            out.update(reaction=float(sum(r[2 * node[nd] + c] for nd, c in p.measure)), dofs=2 * p.lat.n_nodes)
    else:
        TF, TK = _teeth(p)
        if adaptive:
            res = run_sla_adaptive(p.lat, p.domain, p.k_ref, TF, TK, p.pattern, p.measure, max_events, drop=drop)
            out.update(dofs=max(res.dofs), refinement_solves=res.refinements, elements=res.elements)
        else:
            res = run_sla(
                p.lat,
                p.k_ref,
                FT,
                TF,
                TK,
                {2 * node[nd] + c: v for (nd, c), v in p.pattern.items()},
                [2 * node[nd] for nd, _ in p.measure],
                max_events,
                drop=drop,
            )
            out.update(dofs=2 * p.lat.n_nodes)
        out.update(
            factor=list(res.factor), reaction_curve=list(res.reaction), damaged=np.flatnonzero(res.teeth).tolist()
        )
        out["peak"] = max(res.reaction) if res.reaction else 0.0
    out["wall_s"] = time.perf_counter() - t0
    out["peak_rss_growth_MiB"] = (resource.getrusage(resource.RUSAGE_SELF).ru_maxrss - rss0) / 1024.0
    return out
