"""Scenario files of the quasi-static solver family (``[solver] kind = "quasistatic"``): a plate of the
triangular particle lattice (polydem_cli/coupling/lattice.py), optionally with a rhombus hole and round aggregates, stretched
in e1 by a prescribed displacement of its right edge, solved fully resolved or adaptively (Sorg 2014).

Units as everywhere in polydem: cm, g, s (force dyn, stiffness dyn/cm, energy erg).

Supports (the one loading of the source's examples, stated here): the nodes of the left edge held in e1, the
lowest of them also in e2 (no rigid motion, no lateral restraint), the nodes of the right edge displaced in e1.
Elastic members: one equilibrium at ``loading.displacement`` (with the adaptive solver, one per refinement
stage).  Softening members: sequentially linear analysis, whose load factor is the right edge's displacement
in cm (a saw-tooth event per solve), until the reaction has fallen below ``loading.end_load_drop`` of its peak
or ``loading.max_events`` events.
"""

from __future__ import annotations

import math

from ..params import Param, Table
from .problem import make_problem

SQRT3 = math.sqrt(3.0)


def _pow2(v):
    return None if v >= 1 and (v & (v - 1)) == 0 else "must be a power of two (1, 2, 4, 8, ...)"


LATTICE = Table(
    {
        "spacing": Param(
            "float", unit="cm", min=0.0, min_open=True, doc="distance of neighbouring nodes (particle diameter)"
        ),
        "width": Param(
            "float", unit="cm", min=0.0, min_open=True, doc="plate width along e1, a whole number of spacings"
        ),
        "rows": Param("int", min=2, max=100_000, doc="rows of nodes along e2 (height (rows - 1) sqrt(3)/2 spacing)"),
    },
    doc="The regular triangular lattice of equal round particles (nodes at their centres, bars to the six "
    "nearest neighbours).",
)

HOLE = Table(
    {
        "center": Param("vec2", unit="cm", default=None, doc="centre of the rhombus (default: the plate's centre)"),
        "half_diagonals": Param(
            "vec2",
            unit="cm",
            doc="half diagonals along e1 and e2 (both > 0); the hole must lie inside the plate with at least one "
            "spacing of lattice around it",
            check=lambda v: "both half diagonals must be > 0" if min(v) <= 0 else None,
        ),
    },
    doc="A rhombus-shaped hole (its interior nodes and their members removed).  Omit for a plate without hole.",
    required=False,
)

MEMBERS = Table(
    {
        "k": Param("float", unit="dyn/cm", min=0.0, min_open=True, doc="axial stiffness of a (matrix) member"),
        "law": Param(
            "str",
            default="elastic",
            choices=("elastic", "softening"),
            doc="elastic: linear bars; softening: linear softening in tension (secant unloading), solved by "
            "sequentially linear analysis",
        ),
        "f_t": Param(
            "float",
            unit="dyn",
            default=None,
            min=0.0,
            min_open=True,
            doc="tensile strength of a (matrix) member (softening)",
        ),
        "ductility": Param(
            "float",
            default=5.0,
            min=1.0,
            min_open=True,
            doc="ultimate elongation over the elongation at the strength, delta_u / delta_t (softening; the "
            "fracture energy of a member is f_t delta_u / 2)",
        ),
        "teeth": Param("int", default=10, min=1, max=1000, doc="teeth of the saw-tooth law (softening)"),
        "residual": Param(
            "float",
            default=1e-9,
            min=0.0,
            min_open=True,
            max=1e-3,
            doc="stiffness left to a failed member, as a fraction of k (keeps the lattice connected)",
        ),
    },
    doc="Member law of the lattice's bars.",
    check=lambda t: (
        ("f_t", None, "a softening law needs the strength f_t")
        if t["law"] == "softening" and t["f_t"] is None
        else None
    ),
)

AGGREGATES = Table(
    {
        "radii": Param(
            "floats",
            unit="cm",
            doc="aggregate radii, largest first, placed at random in turn until each class holds its share of the area",
            check=lambda v: "must be a non-empty array of radii > 0" if not v or min(v) <= 0 else None,
        ),
        "fraction": Param("float", min=0.0, max=0.7, min_open=True, doc="area fraction of the aggregates"),
        "seed": Param("int", default=None, min=0, doc="placement seed (default: scenario.seed)"),
        "k_factor": Param("float", default=2.5, min=0.0, min_open=True, doc="stiffness of aggregate members / k"),
        "f_t_factor": Param("float", default=3.0, min=0.0, min_open=True, doc="strength of aggregate members / f_t"),
        "interface_k_factor": Param(
            "float",
            default=0.6,
            min=0.0,
            min_open=True,
            doc="stiffness of interface members (one end in an aggregate) / k",
        ),
        "interface_f_t_factor": Param(
            "float", default=0.5, min=0.0, min_open=True, doc="strength of interface members / f_t"
        ),
    },
    doc="Round aggregates projected onto the lattice: members with both ends in one aggregate are aggregate "
    "members, members with one end in an aggregate interface members, the rest matrix.  Omit for a "
    "homogeneous lattice.",
    required=False,
)

LOADING = Table(
    {
        "displacement": Param(
            "float",
            unit="cm",
            default=None,
            doc="elastic members: the prescribed e1 displacement of the right edge (non-zero)",
            check=lambda v: "must be non-zero" if v == 0 else None,
        ),
        "max_events": Param("int", default=400, min=1, max=10_000_000, doc="softening: at most this many events"),
        "end_load_drop": Param(
            "float",
            default=0.7,
            min=0.0,
            max=1.0,
            min_open=True,
            max_open=True,
            doc="softening: stop when the reaction has fallen below this fraction of its peak",
        ),
    },
    doc="Stretching in e1 (module docstring: the supports).",
    required=False,
    default_if_missing=True,
)

ADAPTIVE = Table(
    {
        "enabled": Param("bool", default=True, doc="false: the fully resolved lattice (the reference)"),
        "coarse_side": Param(
            "int", default=8, min=1, max=1 << 20, check=_pow2, doc="side of the coarsest elements in spacings"
        ),
        "tol": Param(
            "float",
            default=0.1,
            min=0.0,
            min_open=True,
            doc="strain-jump indicator threshold: an element is split when the jump of its strain to a "
            "neighbour's exceeds tol x the largest element strain",
        ),
        "buffer": Param(
            "int",
            default=1,
            min=0,
            max=16,
            doc="rings of neighbours (of the same or a larger side) refined with every element the indicator "
            "marks: the edge of the refined region does not creep one element per stage (docs/performance.md)",
        ),
        "theta": Param(
            "float",
            default=0.8,
            min=0.0,
            max=1.0,
            min_open=True,
            doc="softening: elements holding a member loaded above theta x its present strength are refined to "
            "the lattice before the event is taken",
        ),
        "intact_scale": Param(
            "bool",
            default=True,
            doc="softening: the indicator's largest element strain (tol's scale) taken over the elements holding no "
            "damaged member, whose 'strain' is mostly a crack's opening; false: over every element, so that the "
            "indicator falls silent as the crack opens — fewer refinements after the peak, a coarser (stiffer, more "
            "dissipating) mesh along a long crack (docs/reproduction.md)",
        ),
        "defer": Param(
            "int",
            default=20,
            min=0,
            max=1_000_000,
            doc="softening: after the first event, elements the indicator marks while no member needs resolving "
            "(theta) are refined with the next refinement or after this many events, not at once (each refinement "
            "is a factorisation; 0: at once) — the speed against error of docs/reproduction.md",
        ),
        "max_stages": Param("int", default=20, min=1, max=1000, doc="elastic: at most this many refinement stages"),
        "min_gain": Param(
            "float",
            default=0.0,
            min=0.0,
            max=1.0,
            doc="the indicator's marks (no theta reason) are refined only where the finer mesh has at least "
            "1 + min_gain times the present mesh's master nodes; else an elastic analysis ends (the indicator taken "
            "to hold) and a softening one lets them wait as with defer (0: every mark; the last stages at a notch's "
            "corner add a few DOFs each, a factorisation each — the speed against error of docs/reproduction.md; with "
            "defer = 0 small marks are judged again at every event)",
        ),
        "resolve_softer": Param(
            "bool",
            default=False,
            doc="refine the elements holding a member softer than k (an aggregate's interface) to the lattice "
            "before the first solve: a level-2 element imposes a linear field on its boundary, which stiffens a "
            "soft band between a stiff aggregate and the matrix (docs/reproduction.md, Sorg)",
        ),
    },
    doc="The adaptive FEM-lattice coupling (levels 1-3, refinement by splitting into four, 2:1 balance).",
    required=False,
    default_if_missing=True,
)

QS_OUTPUT = Table(
    {
        "checkpoint_interval": Param(
            "float",
            unit="s (wall clock)",
            default=60.0,
            min=0.0,
            min_open=True,
            doc="wall-clock time between checkpoints",
        ),
    },
    doc="What is written and how often.",
    required=False,
    default_if_missing=True,
)


def _check(sc):
    lat, hole, mem = sc["lattice"], sc["hole"], sc["members"]
    a, w = lat["spacing"], lat["width"]
    n = w / a
    if abs(n - round(n)) > 1e-9 * max(1.0, n) or round(n) < 1:
        return (
            "lattice.spacing",
            a,
            f"does not fit the plate: width {w:g} cm is {n:.6g} spacings, not a whole number",
        )
    if round(n) > 100_000:
        return ("lattice.width", w, f"{round(n):,} spacings: absurdly large")
    h = (lat["rows"] - 1) * SQRT3 / 2.0 * a
    if hole is not None:
        cx, cy = hole["center"] if hole["center"] is not None else (w / 2.0, h / 2.0)
        hx, hy = hole["half_diagonals"]
        if cx - hx < a or cx + hx > w - a or cy - hy < a or cy + hy > h - a:
            return (
                "hole.half_diagonals",
                [hx, hy],
                f"the hole (centre [{cx:g}, {cy:g}] cm) does not lie inside the {w:g} x {h:.4g} cm plate with one "
                f"spacing ({a:g} cm) of lattice around it",
            )
    if mem["law"] == "elastic" and sc["loading"]["displacement"] is None:
        return ("loading.displacement", None, "elastic members need the prescribed displacement of the right edge")
    if mem["law"] == "softening" and sc["loading"]["displacement"] is not None:
        return (
            "loading.displacement",
            sc["loading"]["displacement"],
            "is for elastic members; a softening run finds its own load factor (the right edge's displacement) "
            "event by event: remove it",
        )
    ag = sc["aggregates"]
    if ag is not None and min(ag["radii"]) < a:
        return ("aggregates.radii", ag["radii"], f"an aggregate smaller than one spacing ({a:g} cm) holds no member")
    return None


def schema(common: dict) -> Table:
    """The quasi-static scenario schema; ``common``: tables shared with the explicit schema ([scenario],
    [solver])."""
    return Table(
        {
            **common,
            "lattice": LATTICE,
            "hole": HOLE,
            "members": MEMBERS,
            "aggregates": AGGREGATES,
            "loading": LOADING,
            "adaptive": ADAPTIVE,
            "output": QS_OUTPUT,
        },
        doc=__doc__.strip(),
        check=_check,
    )


def build_problem(sc: dict):
    """The :class:`.problem.Problem` (lattice, member stiffnesses and strengths, supports) of a resolved
    quasi-static scenario."""

    lat, hole, mem, ag = sc["lattice"], sc["hole"], sc["members"], sc["aggregates"]
    a, w = lat["spacing"], lat["width"]
    h = (lat["rows"] - 1) * SQRT3 / 2.0 * a
    hl = None
    if hole is not None:
        c = hole["center"] if hole["center"] is not None else (w / 2.0, h / 2.0)
        hl = (tuple(c), tuple(hole["half_diagonals"]))
    agg = None
    if ag is not None:
        agg = dict(ag)
        if agg["seed"] is None:
            agg["seed"] = sc["scenario"]["seed"]
    return make_problem(
        a,
        w,
        h,
        hl,
        mem["k"],
        mem["f_t"] if mem["f_t"] is not None else 1e-3 * mem["k"] * a,
        mem["law"] == "softening",
        agg,
    )
