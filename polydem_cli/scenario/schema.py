"""The polydem scenario schema (one TOML file per run).

Units everywhere: centimetre, gram, second (force in dyn = g cm s⁻², energy in
erg).  The thesis quotes N-based values: 1 N = 1e5 dyn, so k_n [N/cm⁴] × 1e5 =
k_n [g cm⁻³ s⁻²], k_t [N/cm²] × 1e5 = k_t [g cm⁻¹ s⁻²], 1 m/s = 100 cm/s.
"""

from __future__ import annotations

from ..coupling import scenario as _qs
from ..engine.families import FAMILIES
from .spec import INT_LIMIT, REQUIRED, ArrayOf, MapOf, Param, Table

INTEGRATOR_CHOICES = ("gear5", "verlet", "verlet1")


def _name_check(v: str):
    if not v or not all(c.isalnum() or c in "_-" for c in v):
        return "must be a non-empty name of letters, digits, '_' or '-'"
    return None


def _ints_check(v):
    if (
        not isinstance(v, list)
        or not v
        or not all(isinstance(e, int) and not isinstance(e, bool) and e >= 1 for e in v)
    ):
        return "must be a non-empty array of integers >= 1"
    if max(v) > INT_LIMIT:
        return f"absurdly large: integers are limited to {INT_LIMIT:,}"
    return None


def _dof_check(v):
    """A DOF is "free", "fixed", {velocity = v, acceleration = a} or {displacement = D, frequency = f}."""
    if isinstance(v, str):
        return (
            None
            if v in ("free", "fixed")
            else 'must be "free", "fixed", a table {velocity = ..., acceleration = ...}, {velocity = ..., cycle = ...} or {displacement = ..., frequency = ...}'
        )
    if isinstance(v, dict) and ("displacement" in v or "frequency" in v):
        extra = set(v) - {"displacement", "frequency"}
        if extra:
            return f"unknown key(s) {sorted(extra)} in a cosine motion (valid: displacement, frequency)"
        for k in ("displacement", "frequency"):
            q = v.get(k)
            if not isinstance(q, (int, float)) or isinstance(q, bool) or q != q or abs(q) == float("inf"):
                return f"a cosine motion (LH 1.1) needs a finite {k}"
        if v["frequency"] <= 0 or v["displacement"] == 0:
            return "frequency must be > 0 and displacement non-zero"
        return None
    if isinstance(v, dict) and "cycle" in v:
        extra = set(v) - {"velocity", "cycle"}
        if extra:
            return f"unknown key(s) {sorted(extra)} in a cyclic motion (valid: velocity, cycle)"
        for k in ("velocity", "cycle"):
            q = v.get(k)
            if not isinstance(q, (int, float)) or isinstance(q, bool) or q != q or abs(q) == float("inf"):
                return f"a cyclic motion needs a finite {k}"
        if v["velocity"] == 0 or v["cycle"] <= 0:
            return "a cyclic motion needs a non-zero velocity and a cycle (displacement between unloadings) > 0"
        return None
    if isinstance(v, dict):
        extra = set(v) - {"velocity", "acceleration"}
        if extra:
            return f"unknown key(s) {sorted(extra)} in prescribed motion (valid: velocity, acceleration; or cycle)"
        if "velocity" not in v:
            return "prescribed motion needs a velocity (the constant velocity, reached after the ramp if acceleration is given)"
        for k, q in v.items():
            if not isinstance(q, (int, float)) or isinstance(q, bool) or q != q or abs(q) == float("inf"):
                return f"{k} must be a finite number"
        if "acceleration" in v:
            a, w = float(v["acceleration"]), float(v["velocity"])
            if a == 0.0:
                return "acceleration must be non-zero (omit it for a constant velocity from t = 0)"
            if w == 0.0 or (a > 0) != (w > 0):
                return "acceleration and velocity must be non-zero and of the same sign (ramp to the target velocity)"
        return None
    return 'must be "free", "fixed", a table {velocity = ..., acceleration = ...}, {velocity = ..., cycle = ...} or {displacement = ..., frequency = ...}'


def _place_check(v):
    if v is None:
        return None
    side, _, grp = v.partition(":")
    if side not in ("above", "below") or not grp:
        return "must be 'above:<group>' or 'below:<group>'"
    return None


def _time_check(t):
    if t["end_time"] is None and t["end_displacement"] is None:
        return ("end_time", None, "give end_time and/or end_displacement (no end criterion)")
    if t["end_time"] is not None and t["end_time"] < t["dt"]:
        return ("end_time", t["end_time"], f"is shorter than one time step dt = {t['dt']:g}")
    return None


SCENARIO = Table(
    {
        "title": Param("str", doc="short title of the run"),
        "description": Param("str", default="", doc="what the run shows"),
        "reproduces": Param("str", default="", doc="thesis figure/table reproduced, e.g. 'Schneider (2012) Fig. 5.7'"),
        "inferred": Param("str", default="", doc="values chosen because the source is silent (open points O-n)"),
        "seed": Param("int", default=0, min=0, doc="master random seed (specimen generators without their own seed)"),
        "extends": Param(
            "str",
            default="",
            doc="base scenario file (relative path): its tables are merged under this file's "
            "(tables key by key, arrays replaced)",
        ),
    },
    doc="Provenance of the run.",
)

TIME = Table(
    {
        "integrator": Param(
            "str",
            default="gear5",
            choices=INTEGRATOR_CHOICES,
            doc="gear5: Gear 5th-order predictor-corrector (3.12)-(3.16); verlet: central differences in velocity form; "
            "verlet1: verlet with one force evaluation per step, at the predicted state, which also updates the "
            "history (half the cost; the same trajectory where forces and history depend on positions only, e.g. "
            "disks; velocity-dependent history and reported forces at the predicted velocity)",
        ),
        "dt": Param("float", unit="s", min=0.0, min_open=True, doc="time step", thesis="Δt"),
        "end_time": Param("float", unit="s", default=None, min=0.0, min_open=True, doc="simulated end time"),
        "end_displacement": Param(
            "float",
            unit="cm",
            default=None,
            min=0.0,
            min_open=True,
            doc="stop when |prescribed displacement| of end_displacement_set reaches this",
        ),
        "end_displacement_set": Param(
            "str",
            default=None,
            doc="driven set for end_displacement and end_load_drop (default: the first boundary entry "
            "with a moving DOF)",
        ),
        "allow_large_dt": Param(
            "bool",
            default=False,
            doc="run even if dt exceeds twice the critical time step estimate (refused otherwise)",
        ),
        "end_load_drop": Param(
            "float",
            default=None,
            min=0.0,
            max=1.0,
            min_open=True,
            max_open=True,
            doc="stop when the load f2 on the driven set has fallen below this fraction of its peak "
            "(tracked after the acceleration ramp; O-9)",
        ),
        "end_load_drop_hold": Param(
            "float",
            unit="s",
            default=0.0,
            min=0.0,
            doc="end_load_drop ends the run only once the load has stayed below the fraction for this long (0: at "
            "the first step below it); a hold keeps a dynamic spike of the load from ending a softening test early",
        ),
    },
    doc="Time integration and end criteria (end_time and/or end_displacement; end_load_drop may end a run earlier).",
    check=_time_check,
)

OUTPUT = Table(
    {
        "frame_interval": Param(
            "float",
            unit="s",
            default=None,
            min=0.0,
            min_open=True,
            doc="simulated time between frames (default: 50 frames over the run)",
        ),
        "frame_times": Param(
            "floats",
            unit="s",
            default=list,
            doc="additional frame times (snapshots)",
            check=lambda v: "must be >= 0" if any(x < 0 for x in v) else None,
        ),
        "history_every": Param("int", default=10, min=1, doc="steps between rows of the history table"),
        "checkpoint_interval": Param(
            "float",
            unit="s (wall clock)",
            default=60.0,
            min=0.0,
            min_open=True,
            doc="wall-clock time between checkpoints",
        ),
        "observe": Param(
            "strs", default=list, doc="extra particle sets whose mean displacement and reaction are recorded"
        ),
        "velocities": Param("bool", default=True, doc="store particle velocities in frames"),
    },
    doc="What is written to the HDF5 result and how often.",
    required=False,
    default_if_missing=True,
)

MATERIAL = Table(
    {
        "density": Param("float", unit="g/cm^3", min=0.0, min_open=True, doc="density", thesis="ρ"),
        "k_n": Param(
            "float",
            unit="g/(cm^3 s^2)",
            default=0.0,
            min=0.0,
            doc="normal penalty parameter; 1 N/cm^4 = 1e5",
            thesis="k_n, (4.2)-(4.4)",
        ),
        "gamma_n": Param(
            "float",
            unit="g/(cm^3 s)",
            default=0.0,
            min=0.0,
            doc="normal viscosity; 1 N s/cm^5 = 1e5",
            thesis="γ_n, (4.5), (4.8)",
        ),
        "k_t": Param(
            "float",
            unit="g/(cm s^2)",
            default=0.0,
            min=0.0,
            doc="tangential stiffness of the contact between particles per unit thickness (f_t = k_t u_t T, so dyn/cm^2 "
            "= g/(cm s^2); not the [[platen]] k_t, a spring per particle in dyn/cm); 1 N/cm^2 = 1e5",
            thesis="k_t, (4.14)-(4.15)",
        ),
        "mu_t": Param("float", default=0.0, min=0.0, doc="friction coefficient", thesis="μ_t, (4.16)-(4.17)"),
        "k_u": Param(
            "float",
            unit="g/(cm^2 s^2)",
            default=0.0,
            min=0.0,
            doc="base stiffness; 1 N/cm^3 = 1e5 (needs [base])",
            thesis="k_u, (4.26)",
        ),
        "mu_u": Param(
            "float", default=0.0, min=0.0, doc="base friction coefficient (needs [base])", thesis="μ_u, (4.28)"
        ),
    },
    doc="Per-group material and interaction parameters; pair values by the thesis mixing rules "
    "(4.4) harmonic k_n, (4.8) mean γ_n, (4.15) harmonic k_t, (4.17) harmonic μ_t.",
)

PARTICLE_VARIANTS = {
    "voronoi": {
        "nx": Param("int", min=1, doc="grid cells in e1"),
        "ny": Param("int", min=1, doc="grid cells in e2"),
        "h_pg": Param("float", unit="cm", default=1.0, min=0.0, min_open=True, doc="grid spacing", thesis="h_pg"),
        "q_pg": Param("float", default=0.999, min=0.0, max=1.0, doc="disorder factor", thesis="q_pg"),
        "origin": Param("vec2", unit="cm", default=lambda: [0.0, 0.0], doc="lower-left corner"),
        "seed": Param("int", default=None, min=0, doc="random seed (default: scenario.seed)"),
        "min_shared_edge": Param(
            "float",
            unit="cm",
            default=0.0,
            min=0.0,
            doc="shared edges shorter than this count as not touching (bond network; O-1)",
        ),
        "shape": Param(
            "str",
            default="rectangle",
            choices=("rectangle", "disc", "notched_beam"),
            doc="the specimen cut from the nx h x ny h box: the box; the disc inscribed in it (nx = ny; "
            "Brazilian test); the box as a beam with a central notch from below (three-point bending)",
        ),
        "cut": Param(
            "str",
            default="clip",
            choices=("clip", "drop"),
            doc="cells crossing the shape's boundary: clipped to it (convex parts; parts below min_piece h^2 "
            "dropped) or dropped whole (a ragged boundary)",
        ),
        "notch_depth": Param(
            "float", unit="cm", default=None, min=0.0, min_open=True, doc="notched_beam: the notch's depth a0"
        ),
        "notch_width": Param(
            "float", unit="cm", default=None, min=0.0, min_open=True, doc="notched_beam: the notch's width"
        ),
        "load_width": Param(
            "float",
            unit="cm",
            default=0.0,
            min=0.0,
            doc="disc: the flats cut at its top and bottom (load strips; 0: none); notched_beam: the width of the "
            "sets nose, support_left and support_right on its faces",
        ),
        "span": Param(
            "float",
            unit="cm",
            default=None,
            min=0.0,
            min_open=True,
            doc="notched_beam: the supports' distance (default: nx h_pg - h_pg)",
        ),
        "min_piece": Param(
            "float",
            default=0.1,
            min=0.0,
            max=1.0,
            doc="clip: parts of cut cells smaller than this x h_pg^2 are dropped (slivers would set the time step)",
        ),
        "split": Param(
            "str",
            default="none",
            choices=("none", "centroid"),
            doc="cut each cell into convex pieces at its centroid, between the rays to the midpoints of its edges "
            "at least split_min_edge h_pg long (geometry/specimens.py split_cells): cracks can then cross the "
            "cells; sets map to all pieces of their cells",
        ),
        "split_min_edge": Param(
            "float",
            default=0.3,
            min=0.0,
            min_open=True,
            doc="split = 'centroid': edges shorter than this x h_pg get no ray (no sliver pieces)",
        ),
        "aggregate_fraction": Param(
            "float",
            default=0.0,
            min=0.0,
            max=1.0,
            max_open=True,
            doc="mesoscale concrete: the area fraction of round aggregates placed by a grading curve "
            "(geometry/aggregates.py); a cell whose centroid lies in an aggregate belongs to it (subsets 'aggregate' "
            "and 'matrix'; beams by [bonds.aggregate] and [bonds.interface]); 0: none",
        ),
        "aggregate_d_min": Param(
            "float", unit="cm", default=None, min=0.0, min_open=True, doc="the smallest aggregate's diameter"
        ),
        "aggregate_d_max": Param(
            "float", unit="cm", default=None, min=0.0, min_open=True, doc="the largest aggregate's diameter"
        ),
        "grading_exponent": Param(
            "float",
            default=0.5,
            min=0.0,
            min_open=True,
            doc="n of the grading curve P(d) = (d/d_max)^n (0.5: Fuller)",
        ),
        "grading_classes": Param(
            "int", default=3, min=1, doc="sieve classes of geometric widths between d_min and d_max"
        ),
        "aggregate_gap": Param(
            "float",
            unit="cm",
            default=None,
            min=0.0,
            doc="clearance between aggregates and from the specimen's rim (default h_pg)",
        ),
    },
    "hexagon_packing": {
        "width": Param("float", unit="cm", min=0.0, min_open=True, doc="width across flats"),
        "rows": Param("int", min=1, doc="number of rows"),
        "row_counts": Param("any", check=_ints_check, doc="hexagons per row, pattern repeated (e.g. [16, 15])"),
        "origin": Param(
            "vec2", unit="cm", default=lambda: [0.0, 0.0], doc="centroid of position (0, 0) before the row shift"
        ),
        "first_row_shift": Param(
            "float",
            default=0.0,
            min=0.0,
            max=1.0,
            max_open=True,
            doc="shift of row 0 in units of the width; rows alternate by 1/2",
        ),
        "missing": Param("pairs", default=list, doc="[row, index] positions left empty (defects)"),
        "spacing": Param(
            "float",
            unit="cm",
            default=None,
            min=0.0,
            min_open=True,
            doc="centroid distance of neighbours (default: width; smaller = pre-compressed, overlapping)",
        ),
        "sides": Param(
            "int",
            default=6,
            min=4,
            check=lambda v: "must be even" if v % 2 else None,
            doc="corners of each particle: 6 = hexagon; any even number gives a regular polygon with "
            "the same width across flats (e.g. 24 for disk-like particles, peer benchmark)",
        ),
    },
    "rectangle": {
        "center": Param("vec2", unit="cm", doc="centre"),
        "size": Param(
            "vec2",
            unit="cm",
            doc="[width, height]",
            check=lambda v: "width and height must be > 0" if min(v) <= 0 else None,
        ),
        "place": Param(
            "str",
            default=None,
            check=_place_check,
            doc="'above:<group>' or 'below:<group>': replace center[1] so that the rectangle touches "
            "the extreme vertices of an earlier group without overlap (load plates)",
        ),
    },
    "polygon": {
        "vertices": Param("points", unit="cm", doc="convex outline, world coordinates at t0"),
    },
    "regular_polygon": {
        "center": Param("vec2", unit="cm", doc="centre"),
        "sides": Param("int", min=3, doc="number of sides"),
        "circumradius": Param("float", unit="cm", min=0.0, min_open=True, doc="centre-vertex distance"),
        "rotation": Param("float", unit="rad", default=0.0, doc="angle of the first vertex"),
    },
}

#: generators of the interaction families (e.g. disks and walls, interactions/disks/family.py)
for _fam in FAMILIES:
    PARTICLE_VARIANTS.update(_fam.particle_variants)
#: the family that generates each family-owned particle type
FAMILY_OF_VARIANT = {t: f for f in FAMILIES for t in f.particle_variants}

PARTICLES = Table(
    {
        "name": Param("str", check=_name_check, doc="group name, used in set names ('name', 'name.top', 'name[3]')"),
        "material": Param("str", doc="key of [materials]"),
        "thickness": Param("float", unit="cm", min=0.0, min_open=True, doc="out-of-plane thickness", thesis="T"),
        "type": Param("str", choices=tuple(PARTICLE_VARIANTS), doc="generator"),
        "velocity": Param(
            "vec3",
            unit="cm/s, cm/s, rad/s",
            default=lambda: [0.0, 0.0, 0.0],
            doc="initial velocity of every particle of the group",
        ),
    },
    doc="Particle groups, one generator each.\n\n"
    "**Particle sets** — what a `set` key names (`[[boundary]]`, `[[loads]]`, `[[platen]]`, `[[perturb]]`, "
    "`[output] observe`, `end_displacement_set`, …): `all` (every particle), `<name>` (a group), `<name>[i]` (its "
    "i-th particle, from 0) and `<name>.<subset>`, a subset its generator names:\n\n"
    "* `voronoi`, `shape = \"rectangle\"`: `top` / `bottom` — the cells whose generating point lies in the last / "
    "first row of the nx × ny grid (the thesis's loaded rows; a choice where the thesis is silent, O-2), `left` / "
    "`right` — the first / last column;\n"
    "* `voronoi`, `shape = \"disc\"` or `\"notched_beam\"`: `top` / `bottom` / `left` / `right` — the particles "
    "with a corner on the specimen's highest / lowest / leftmost / rightmost line (a flattened disc: its flats; a "
    "round one: the particles at its top and bottom point); a notched beam also `nose` (on the top face within "
    "`load_width`/2 of the middle), `support_left` / `support_right` (on the bottom face within `load_width`/2 of "
    "x = (L ∓ S)/2, S the `span`) and `mouth_left` / `mouth_right` (on the bottom face within h_pg beside the "
    "notch);\n"
    "* `voronoi` with `aggregate_fraction` > 0: `aggregate` and `matrix` (the cells of each phase);\n"
    "* `hexagon_packing`: `bottom` / `top` — the lowest / highest row, `left` / `right` — the first / last particle "
    "of each row;\n"
    "* the other generators name no subsets (use the group or `<name>[i]`).\n\n"
    "A set name that the scene does not have is refused with the list of those it has.",
    variants=PARTICLE_VARIANTS,
    discriminator="type",
)

LOADS = Table(
    {
        "set": Param("str", doc="particle set"),
        "force": Param(
            "vec2", unit="dyn", default=lambda: [0.0, 0.0], doc="constant force on every particle of the set"
        ),
        "moment": Param("float", unit="dyn cm", default=0.0, doc="constant moment about each particle's centroid"),
        "pressure": Param(
            "float",
            unit="dyn/cm^2",
            default=0.0,
            min=0.0,
            doc="a pressure (pushing inwards; a pull on the edges is not a pressure: give it as a force) on the exposed edges of the set's particles — those no other "
            "particle of their group shares — as a dead load: each particle gets -p T L n summed over its loaded edges "
            "(length L, outward normal n); a membrane of constant pressure, e.g. the lateral confinement of a "
            "biaxial test (1 MPa = 1e7 dyn/cm^2)",
        ),
        "normal": Param(
            "vec2",
            default=None,
            doc="load only the exposed edges whose outward normal lies within 60 degrees of this direction; default: "
            "the side a set called '<group>.left' / '.right' / '.top' / '.bottom' names, every exposed edge otherwise",
        ),
        "ramp_time": Param(
            "float",
            unit="s",
            default=0.0,
            min=0.0,
            doc="raise this load linearly from zero to its full value over this time (0: full from t = 0), in "
            "steps of 64 time steps; every ramped load of a scenario shares one ramp_time",
        ),
    },
    doc="Constant external loads f_ext (thesis (3.4); none in the thesis's tests).",
    check=lambda t: (
        ("normal", t["normal"], "must not be the zero vector")
        if t["normal"] is not None and not any(t["normal"])
        else None
    ),
)

PERTURB = Table(
    {
        "set": Param("str", default=None, doc="particle set, e.g. 'nuts[107]'"),
        "at": Param("vec2", unit="cm", default=None, doc="the particle whose centroid is nearest to this point"),
        "k_n_factor": Param("float", default=1.0, min=0.0, min_open=True, doc="factor on the particle's k_n"),
    },
    doc="Change one particle's k_n to break the symmetry of a perfect packing (thesis §6.2: -10 %).",
    check=lambda t: (
        None if (t["set"] is None) != (t["at"] is None) else ("set", t["set"], "give exactly one of set and at")
    ),
)

STABILITY = Table(
    {
        "max_overlap_ratio": Param(
            "float",
            default=0.5,
            min=0.0,
            min_open=True,
            doc="stop the run when an overlap area exceeds this fraction of the smaller particle's area",
        ),
        "max_energy_error": Param(
            "float",
            default=0.25,
            min=0.0,
            min_open=True,
            doc="stop the run when the energy balance error exceeds this fraction of the energy scale",
        ),
    },
    doc="Instability detection: non-finite positions, velocities or forces always stop the run; these limits too.",
    required=False,
    default_if_missing=True,
)

BODY_FORCE = Table(
    {
        "gravity": Param("vec2", unit="cm/s^2", default=lambda: [0.0, 0.0], doc="in-plane gravity, e.g. [0, -981]"),
    },
    doc="Optional in-plane body force.",
    required=False,
)


def _fit_range_check(v):
    if len(v) != 2 or not 0.0 <= v[0] < v[1] <= 1.0:
        return "must be [low, high] fractions of the peak stress with 0 <= low < high <= 1"
    return None


MACRO = Table(
    {
        "specimen": Param("str", doc="particle group that forms the specimen (its sets and size define the measures)"),
        "load_set": Param(
            "str", default=None, doc="set on which f2 and the prescribed u2 are taken (default '<specimen>.top')"
        ),
        "left": Param("str", default=None, doc="left-edge set for eps11 (default '<specimen>.left'; O-2)"),
        "right": Param("str", default=None, doc="right-edge set for eps11 (default '<specimen>.right'; O-2)"),
        "L1": Param(
            "float",
            unit="cm",
            default=None,
            min=0.0,
            min_open=True,
            doc="assumed original width (default: the generator's width, nx h_pg for voronoi, else the "
            "bounding box of the group at t0)",
            thesis="L_1",
        ),
        "L2": Param(
            "float",
            unit="cm",
            default=None,
            min=0.0,
            min_open=True,
            doc="assumed original height (default as L1)",
            thesis="L_2",
        ),
        "thickness": Param(
            "float",
            unit="cm",
            default=None,
            min=0.0,
            min_open=True,
            doc="thickness in A2 = L1 T (default: the group's thickness)",
            thesis="T",
        ),
        "fit_range": Param(
            "floats",
            default=lambda: [0.1, 0.4],
            check=_fit_range_check,
            doc="E and nu are fitted over the pre-peak part of the curve where |sigma22| lies between "
            "these fractions of the peak",
        ),
    },
    doc="Macroscopic nominal stress and strains of a specimen (thesis §7.5.1): sigma22 = f2/(L1 T), "
    "eps22 = u2/L2, eps11 = (u1 right - u1 left)/L1 as history columns; E, nu, peak stress, strain at "
    "the peak and the work after the peak in the summary.  Omit the table for no macroscopic measures.",
    required=False,
)

BOUNDARY = Table(
    {
        "set": Param("str", doc="particle set: 'all', 'group', 'group.subset' or 'group[i]'"),
        "x1": Param(
            "any",
            default="free",
            check=_dof_check,
            doc='"free", "fixed", {velocity, acceleration} (acceleration ramps to the velocity), '
            "{displacement, frequency}: x0 + D (1 - cos 2 pi f t)/2 until t = 1/(2f), then held (LH 1.1), or "
            "{velocity, cycle}: at |velocity|, on by cycle, back by cycle/2, on by 3 cycle/2, ... (every cycle a new "
            "extreme after a partial unloading: cyclic compression)",
        ),
        "x2": Param("any", default="free", check=_dof_check, doc="as x1"),
        "phi": Param("any", default="free", check=_dof_check, doc="as x1 (rad, rad/s, rad/s^2)"),
    },
    doc="Boundary conditions per particle set.  A prescribed DOF is removed from the "
    "integration; its reaction is recorded in the history table.",
)

INITIAL_STATE = Table(
    {
        "file": Param(
            "str",
            doc="a finished polydem result (path relative to this file) whose final state starts this run: "
            "positions, velocities and the contact history of its interaction families (e.g. the disks' "
            "delta_max); energies and the other accumulators start from zero, displacements are measured "
            "from that state.  Its particles (count and groups) must be this scenario's",
        ),
    },
    doc="Start from the final state of an earlier run (a prepared, relaxed packing reused by every loading "
    "run).  Omit the table to start from the generated geometry at rest.",
    required=False,
)

SOLVER = Table(
    {
        "kind": Param(
            "str",
            default="explicit",
            choices=("explicit", "quasistatic"),
            doc="explicit: dynamic particle simulation (time integration, the thesis's method); quasistatic: "
            "equilibrium of a particle lattice under prescribed displacements, fully resolved or adaptive "
            "FEM-lattice coupling (Sorg 2014)",
        ),
    },
    doc="The solver family that runs this scenario (default explicit; each kind has its own tables).",
    required=False,
    default_if_missing=True,
)

QS_SOLVER = Table(
    {
        **SOLVER.fields,
        "workers": Param(
            "int",
            default=1,
            min=1,
            max=64,
            doc="threads for the independent level-2 sub-problems of an adaptive mesh",
        ),
    },
    doc=SOLVER.doc,
    required=False,
    default_if_missing=True,
)

SCHEMA = Table(
    {
        "scenario": SCENARIO,
        "solver": SOLVER,
        "time": TIME,
        "output": OUTPUT,
        "materials": MapOf(MATERIAL, doc=MATERIAL.doc, min_items=1),
        "particles": ArrayOf(PARTICLES, doc=PARTICLES.doc, min_items=1),
        # the interaction families' own tables ([bonds], [contact], [base], [disks], [[servo]]), in registry order
        **{name: t for f in FAMILIES for name, t in f.tables.items()},
        "body_force": BODY_FORCE,
        "loads": ArrayOf(LOADS, doc=LOADS.doc, required=False),
        "stability": STABILITY,
        "perturb": ArrayOf(PERTURB, doc=PERTURB.doc, required=False),
        "boundary": ArrayOf(BOUNDARY, doc=BOUNDARY.doc, required=False),
        "macro": MACRO,
        "initial_state": INITIAL_STATE,
    },
    doc=__doc__.strip(),
)

#: the schema of ``[solver] kind = "quasistatic"`` scenarios (polydem_cli/coupling/scenario.py)
QS_SCHEMA = _qs.schema({"scenario": SCENARIO, "solver": QS_SOLVER})

#: schema by solver kind
SCHEMAS = {"explicit": SCHEMA, "quasistatic": QS_SCHEMA}


def kind_of(data, file: str = "") -> str:
    """The solver kind of a raw scenario (a bad ``[solver] kind`` is refused here, with its key)."""
    sv = data.get("solver") if isinstance(data, dict) else None
    if not isinstance(sv, dict) or "kind" not in sv:
        return "explicit"
    return QS_SOLVER.fields["kind"].validate(sv["kind"], file, "solver.kind")


def schema_of(data, file: str = "") -> Table:
    """The schema of a raw scenario, by its ``[solver] kind``."""
    return SCHEMAS[kind_of(data, file)]


__all__ = ["SCHEMA", "QS_SCHEMA", "SCHEMAS", "schema_of", "kind_of", "REQUIRED"]
