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
  k), 10 teeth, as many events as it takes the reaction to fall below 5 % of its peak (at most ``max_events``):
  the crack has then crossed both ligaments, above and below the hole (the whole fracture, not its start);
* adaptivity: coarsest elements of side 8 a, strain-jump tolerance 0.1 with one ring of neighbours refined
  along (``buffer``: without it the refined region's edge crept one element per stage); softening: members
  refined to the lattice before they carry ``THETA`` of their strength — 40 % in the homogeneous plate, 50 % in
  the heterogeneous one (the closest to a crack tip the coarse elements may come: with 50 % the homogeneous
  whole fracture at 240 × 144 dissipated 7.7 % more than the lattice, with 40 % 3.5 %, with 80 % 20 % more at
  120 × 72 — with the indicator's old scale, ``intact_scale = false``; the heterogeneous plate is within 3 % at 50 %, docs/reproduction.md); in the heterogeneous plates
  the weak interface members' elements resolved from the start (``resolve_softer``: Sorg's level-2 elements over a soft band between a stiff
  aggregate and the matrix made the adaptive plate 7 % too stiff at 120 × 72; docs/reproduction.md); the
  indicator's scale (``tol`` × the largest element strain) taken over the elements without a damaged member
  (``intact_scale``: measured against a crack's opening, the indicator fell silent as the crack grew, and at
  480 × 288 the homogeneous whole fracture dissipated 5 % and the heterogeneous one 11 % more than the lattice,
  the latter along other interfaces; now 1.5 % and 0.5 %, docs/reproduction.md); after the first event the
  indicator's marks without a θ reason wait for the next refinement or 20 events (``defer``: each refinement is a
  factorisation; about 0.6 of the time at 240 × 144, half at 480 × 288, the same accuracy); marks of the
  indicator alone that would add fewer than 2 % of the mesh's nodes are not refined (``min_gain``: the last stages
  at the hole's corners and the refined region's edge, a factorisation each for a few DOFs; the heterogeneous
  elastic plate takes 2 stages instead of 3–4, half the time, its reaction within 0.2 % of the one with every
  stage; docs/reproduction.md).
"""

from __future__ import annotations

import math
import resource
import time

import numpy as np

from .problem import Problem, make_problem, member_teeth
from .stepper import COL, ELASTIC, EVENT, Stepper

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
#: softening: members refined to the lattice before they carry this fraction of their strength (module docstring)
THETA = {"homogeneous": 0.4, "heterogeneous": 0.5}
EXAMPLES = ("homogeneous_elastic", "heterogeneous_elastic", "homogeneous_softening", "heterogeneous_softening")


def problem(name: str, width=WIDTH, rows=ROWS) -> Problem:
    """One of the four examples (module docstring) on a plate ``width`` × ``rows`` row spacings."""
    if name not in EXAMPLES:
        raise ValueError(f"unknown example {name!r}; the examples are {', '.join(EXAMPLES)}")
    H = rows * math.sqrt(3) / 2 * A
    hole = ((width / 2, H / 2), (width / 8, H / 6))
    agg = None
    if name.startswith("heterogeneous"):
        agg = {
            "radii": [r * A for r in RADII],
            "fraction": FRACTION,
            "seed": 1,
            "k_factor": AGG["k"],
            "f_t_factor": AGG["f"],
            "interface_k_factor": ITZ["k"],
            "interface_f_t_factor": ITZ["f"],
        }
    return make_problem(A, width, H, hole, K_MAT, FT, name.endswith("softening"), agg)


def adaptive_table(name: str) -> dict:
    """The [adaptive] settings of example ``name`` (module docstring; scenarios/coupling/<name>.toml has them)."""
    return {
        "coarse_side": 8,
        "tol": 0.1,
        "buffer": 1,
        "theta": THETA[name.split("_")[0]],
        "max_stages": 20,
        "resolve_softer": name.startswith("heterogeneous"),
        "intact_scale": True,
        "defer": 20,
        "min_gain": 0.02,
    }


def adaptive_settings(name: str, changes=None) -> dict:
    """:func:`adaptive_table` of example ``name`` with ``changes`` (key → value) applied, each checked as the
    scenario's ``[adaptive]`` table checks it (coupling/scenario.py ``ADAPTIVE``: kind and range); an unknown
    example or key, or a value out of its range, is refused (ValueError saying why)."""
    from ..errors import ScenarioError
    from .scenario import ADAPTIVE

    if name not in EXAMPLES:
        raise ValueError(f"unknown example {name!r}; the examples are {', '.join(EXAMPLES)}")
    out = adaptive_table(name)
    for k, v in (changes or {}).items():
        if k not in out:
            raise ValueError(f"adaptive setting {k!r}: the settings are {', '.join(out)}")
        try:
            out[k] = ADAPTIVE.fields[k].validate(v, "--adaptive", k)
        except ScenarioError as e:
            raise ValueError(f"{k} = {v!r}: {e.reason}") from None
    return out


def run(
    name: str, adaptive: bool, max_events=5000, drop=0.05, width=WIDTH, rows=ROWS, workers=1, settings=None
) -> dict:
    """Solve one example (:class:`.stepper.Stepper`, the loop of ``polydem run`` on a quasi-static scenario);
    returns its load–displacement record, DOFs, wall time and peak memory (RSS growth).  ``settings``: changes to
    the example's adaptive settings (:func:`adaptive_settings`; the speed–error trade of the indicator's ``tol``
    and the softening's ``theta``)."""
    p = problem(name, width, rows)
    rss0 = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    t0 = time.perf_counter()
    out = {"example": name, "adaptive": adaptive, "nodes": p.lat.n_nodes, "members": p.lat.n_members}
    st = Stepper(
        p,
        member_teeth(p, DU * K_MAT / FT, TEETH) if p.softening else None,
        adaptive_settings(name, settings) if adaptive else None,
        displacement=1.0,
        max_events=max_events,
        drop=drop,
        workers=workers,
    )
    rows_ = []
    while not st.done:
        rows_.append(st.advance())
    wall = time.perf_counter() - t0  # the solution; the record below is this driver's reporting
    h = np.array(rows_)
    ev = h[h[:, COL["kind"]] == (EVENT if p.softening else ELASTIC)]
    dofs = int(h[:, COL["dofs"]].max())
    if adaptive:
        out["elements"] = [tuple(int(v) for v in e) for e in st.elements]
    if not p.softening:
        out.update(reaction=float(ev[-1, COL["reaction"]]), dofs=int(ev[-1, COL["dofs"]]))
        if adaptive:
            out["stages"] = [
                {
                    "dofs": int(r[COL["dofs"]]),
                    "reaction": float(r[COL["reaction"]]),
                    "elements": int(r[COL["elements"]]),
                    "levels": [int(r[COL["level1"]]), int(r[COL["level2"]]), int(r[COL["level3"]])],
                }
                for r in h
            ]
    else:
        out.update(
            dofs=dofs,
            factor=ev[:, COL["u1"]].tolist(),
            reaction_curve=ev[:, COL["reaction"]].tolist(),
            damaged=np.flatnonzero(st.tooth).tolist(),
        )
        if adaptive:
            out["refinement_solves"] = st.refinements
        out["peak"] = float(np.max(ev[:, COL["reaction"]])) if len(ev) else 0.0
    out["wall_s"] = wall
    out["peak_rss_growth_MiB"] = (resource.getrusage(resource.RUSAGE_SELF).ru_maxrss - rss0) / 1024.0
    return out
