"""Turn a validated scenario into the arrays the engine runs on (a :class:`System`).

Everything a run needs is resolved here, before any output is written:
geometry from the generators, particle sets, masses, boundary conditions per
DOF, the end step and the frame steps; then each interaction family builds its
own set-up from the scenario and what is resolved here (``Family.build``,
interactions/protocol.py; kept in ``System.family_data``).  Problems that
depend on more than one key (unknown material, unknown set, a DOF prescribed
twice, impossible geometry) raise :class:`ScenarioError` with the key path of
the entry at fault.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass, field

import numpy as np

from ..analysis.macro import MacroSpec
from ..boundary.prescribed import BC_KINDS, FREE, MOVING, displacement_time, motion_of
from ..engine.families import FAMILIES
from ..engine.integrators import INTEGRATORS
from ..geometry import specimens as gen
from ..geometry.polygon import GeometryError, make_shape
from .schema import FAMILY_OF_VARIANT
from .spec import NOVALUE, ScenarioError


@dataclass
class System:
    """Struct-of-arrays description of a scene (static data and initial state)."""

    file: str
    scenario: dict
    n: int
    group: np.ndarray  # (n,) group index
    group_names: list
    vert_start: np.ndarray  # (n+1,)
    body_v: np.ndarray  # (nv, 2) body-frame vertices (centroid at origin, φ0 = 0)
    radius: np.ndarray
    area: np.ndarray
    mass: np.ndarray
    inertia: np.ndarray
    thickness: np.ndarray
    x0: np.ndarray  # (n, 3)
    v0: np.ndarray  # (n, 3)
    bc_kind: np.ndarray  # (n, 3) int
    bc_vel: np.ndarray
    bc_acc: np.ndarray
    sets: dict  # name -> indices
    monitored: list  # set names recorded in the history table
    ext: np.ndarray  # (n, 3) constant external loads
    gravity: np.ndarray  # (2,)
    integrator: int
    dt: float
    end_step: int
    frame_steps: np.ndarray
    history_every: int
    checkpoint_interval: float
    specimens: dict = field(default_factory=dict)  # group name -> Specimen (shared edges etc.)
    unused: list = field(default_factory=list)  # scenario keys the scene does not use (reported)
    macro: MacroSpec | None = None  # macroscopic measures of a specimen ([macro]), None without
    #: family name -> what its ``Family.build`` made of the scenario (``Family.data(system)``): each interaction
    #: model's parameters live there, not here
    family_data: dict = field(default_factory=dict)
    #: a rank's part of a decomposed scene (engine/distributed.py): 1.0 for the particles it owns, 0.0 for its
    #: ghosts (None: a whole scene, every particle owned); and the size over all ranks of each monitored set
    own: np.ndarray | None = None
    set_counts: dict = field(default_factory=dict)
    #: external loads raised linearly from zero over ``ramp_time`` (``[[loads]] ramp_time``; None without):
    #: f_ext(t) = ext + min(1, t_k / ramp_time) ext_ramp, t_k the start of t's block of RAMP_BLOCK steps
    ext_ramp: np.ndarray | None = None
    ramp_time: float = 0.0
    #: a rank's part: each particle's number in the whole scene (None: a whole scene, numbered as it is)
    gid: np.ndarray | None = None

    @property
    def max_vertices(self) -> int:
        return int(np.max(np.diff(self.vert_start))) if self.n else 0

    def number(self, i: int) -> int:
        """Particle ``i``'s number in the whole scene (what a message to the user names)."""
        return int(i) if self.gid is None or i < 0 else int(self.gid[int(i)])


_SET_RE = re.compile(r"^([A-Za-z0-9_\-]+)(?:\.([A-Za-z0-9_\-]+)|\[(\d+)\])?$")


def resolve_set(name: str, sets: dict, group_ranges: dict, file: str, key: str) -> np.ndarray:
    if name == "all":
        return sets["all"]
    if name in sets:
        return sets[name]
    m = _SET_RE.match(name)
    if m and m.group(1) in group_ranges and m.group(3) is not None:
        lo, hi = group_ranges[m.group(1)]
        i = int(m.group(3))
        if i >= hi - lo:
            raise ScenarioError(
                file, key, name, f"group '{m.group(1)}' has {hi - lo} particles (index 0..{hi - lo - 1})"
            )
        return np.array([lo + i])
    known = ", ".join(sorted(sets))
    raise ScenarioError(file, key, name, f"unknown particle set (known sets: {known}; or 'group[i]')")


def perturb_selection(pt: dict, x0, sets: dict, group_ranges: dict, file: str, key: str) -> np.ndarray:
    """The particles one ``[[perturb]]`` entry changes: its ``set``, or the particle whose centroid is nearest
    to its point ``at``."""
    if pt["set"] is not None:
        return resolve_set(pt["set"], sets, group_ranges, file, f"{key}.set")
    return np.array([int(np.argmin(np.hypot(*(np.asarray(x0)[:, :2] - np.asarray(pt["at"])).T)))])


def _generate(p: dict, seed: int, file: str, key: str):
    t = p["type"]
    try:
        if t in FAMILY_OF_VARIANT:
            return FAMILY_OF_VARIANT[t].generate(p, seed)
        if t == "voronoi":
            s = p["seed"] if p["seed"] is not None else seed
            if p["shape"] == "rectangle":
                return gen.voronoi_specimen(p["nx"], p["ny"], p["h_pg"], p["q_pg"], s, p["origin"])
            if p["shape"] == "notched_beam":
                for k in ("notch_depth", "notch_width"):
                    if p[k] is None:
                        raise ScenarioError(
                            file, f"{key}.{k}", NOVALUE, "a notched_beam needs the notch's depth and width"
                        )
                h = p["notch_depth"], p["ny"] * p["h_pg"]
                if h[0] >= h[1]:
                    raise ScenarioError(
                        file,
                        f"{key}.notch_depth",
                        h[0],
                        f"the notch is deeper than the beam (height ny h_pg = {h[1]:g} cm)",
                    )
            elif p["notch_depth"] is not None or p["notch_width"] is not None:
                raise ScenarioError(file, f"{key}.notch_depth", p["notch_depth"], f"a {p['shape']} has no notch")
            if p["shape"] == "disc" and min(p["nx"], p["ny"]) < 2:
                raise ScenarioError(
                    file, f"{key}.nx", p["nx"], "the disc (diameter nx h_pg) would be smaller than a cell (nx >= 2)"
                )
            return gen.voronoi_cut(
                p["nx"],
                p["ny"],
                p["h_pg"],
                p["q_pg"],
                s,
                p["origin"],
                shape=p["shape"],
                cut=p["cut"],
                notch_depth=p["notch_depth"] or 0.0,
                notch_width=p["notch_width"] or 0.0,
                min_piece=p["min_piece"],
                load_width=p["load_width"],
                span=p["span"],
            )
        if t == "hexagon_packing":
            return gen.hexagon_packing(
                p["width"],
                p["row_counts"],
                p["rows"],
                p["origin"],
                p["first_row_shift"],
                p["missing"],
                p["spacing"],
                p["sides"],
            )
        if t == "rectangle":
            return gen.single_rectangle(p["center"], p["size"])
        if t == "polygon":
            return gen.single_polygon(p["vertices"])
        if t == "regular_polygon":
            return gen.single_regular_polygon(p["sides"], p["circumradius"], p["center"], p["rotation"])
    except GeometryError as e:
        raise ScenarioError(file, key, NOVALUE, f"impossible geometry: {e}") from None
    raise AssertionError(t)  # pragma: no cover


#: memory per particle of a built system and its run-time buffers (measured: 4.7 kB for a 80 x 80 Voronoi
#: panel with bonds after build and initialisation; doubled for the generators' temporaries and the writer)
BYTES_PER_PARTICLE = 10_000


def particle_count(p: dict) -> int:
    """Particles a generator will make, from its parameters alone (before anything is allocated)."""
    t = p["type"]
    if t == "voronoi":  # a notch splits a few cells into up to three parts
        return int(p["nx"]) * int(p["ny"]) + (2 * int(p["ny"]) if p.get("shape") == "notched_beam" else 0)
    if t == "hexagon_packing":
        rc, rows = list(p["row_counts"]), int(p["rows"])
        full, rest = divmod(rows, len(rc))
        return full * sum(rc) + sum(rc[:rest]) - len(p["missing"])
    if t == "random_disks":
        return int(p["count"])
    if t == "disks":
        return len(p["centers"])
    return 1


def available_memory() -> int | None:
    """MemAvailable of /proc/meminfo in bytes (None where the platform has no such file)."""
    try:
        with open("/proc/meminfo") as f:
            for line in f:
                if line.startswith("MemAvailable:"):
                    return int(line.split()[1]) * 1024
    except OSError:
        return None
    return None


def check_size(sc: dict, file: str) -> None:
    """Refuse a specimen whose estimated memory exceeds the machine's available memory, before any
    particle is generated (a 1e10-particle grid would otherwise hang or end in a NumPy traceback)."""
    counts = [(f"particles[{gi}]", particle_count(p), p) for gi, p in enumerate(sc["particles"])]
    total = sum(c for _, c, _ in counts)
    need = 0
    for _, c, p in counts:
        need += c * BYTES_PER_PARTICLE * max(1.0, (p.get("sides") or (24 if "disk" in p["type"] else 6)) / 6.0)
    avail = available_memory()
    if avail is not None and need > avail:
        key, c, p = max(counts, key=lambda kc: kc[1])
        what = {
            "voronoi": f"nx x ny = {p.get('nx')} x {p.get('ny')}",
            "hexagon_packing": f"rows = {p.get('rows')}, row_counts = {p.get('row_counts')}",
        }.get(p["type"], "")
        raise ScenarioError(
            file,
            key,
            NOVALUE,
            f"specimen too large for this machine: {total:,} particles ({what}) need about "
            f"{need / 2**30:,.3g} GiB ({BYTES_PER_PARTICLE / 1000:g} kB per particle, estimated), "
            f"{avail / 2**30:,.3g} GiB available",
        )


def _initial_state(sc: dict, file: str, n: int, gnames: list):
    """(x, v, checkpoint fields) of the final state of the result named by [initial_state], or None."""
    ist = sc.get("initial_state")
    if ist is None:
        return None
    import json
    from pathlib import Path

    import h5py

    key, val = "initial_state.file", ist["file"]
    path = Path(val) if Path(val).is_absolute() else Path(file).resolve().parent / val
    if not path.exists():
        raise ScenarioError(file, key, val, f"no such file ({path}); run the preparation scenario first")
    try:
        with h5py.File(path, "r") as f:
            names = json.loads(f["particles/group"].attrs["names"])
            fr = f["frames"]
            if "v" not in fr:
                raise ScenarioError(file, key, val, "the result stores no velocities (output.velocities = false)")
            x, v, step = fr["x"][-1], fr["v"][-1], int(fr["step"][-1])
            radius = f["particles/radius"][...] if "radius" in f["particles"] else None
            st = {}
            ck = f.get("checkpoint")
            if ck is not None and int(ck["current"][0]) >= 0:
                g = ck[f"slot{int(ck['current'][0])}"]
                if int(g["step"][0]) == step:
                    st = {k: g[k][...] for k in g}
    except (OSError, KeyError) as e:
        if "lock" in str(e):
            raise ScenarioError(
                file, key, val, "is being written by another process (locked): wait for that run to finish"
            ) from None
        raise ScenarioError(file, key, val, f"not a readable polydem result ({e})") from None
    if x.shape[0] != n or names != gnames:
        raise ScenarioError(
            file, key, val, f"holds {x.shape[0]} particles in groups {names}; this scenario has {n} in {gnames}"
        )
    if not st:
        raise ScenarioError(file, key, val, "its final frame has no checkpoint of the same step (an unfinished run?)")
    return x, v, st, radius


def _check_same_shapes(init, radius, file, val):
    """The stored run's particles must be this scenario's (a changed generator or seed gives other shapes)."""
    if init[3] is not None and not np.allclose(init[3], radius, rtol=1e-12, atol=0):
        k = int(np.argmax(~np.isclose(init[3], radius, rtol=1e-12, atol=0)))
        raise ScenarioError(
            file,
            "initial_state.file",
            val,
            f"its particle {k} has bounding radius {init[3][k]:.6g} cm, this scenario's {radius[k]:.6g} cm: "
            "not the same specimen (another generator, seed or size); rerun the preparation",
        )


def build_system(sc: dict, file: str = "<scenario>") -> System:
    """The System of a validated scenario: particle groups and sets, shapes and masses, the initial state,
    per-particle interaction parameters, boundary conditions, time and output, and each interaction family's
    set-up (``Family.build``); ScenarioError with the key path for what only the whole scenario can tell."""
    check_size(sc, file)
    g = _particles(sc, file)
    n = g["n"]
    thick = np.asarray(g["thick"], float)
    shapes = _shapes(sc, file, g)
    x0, vel0 = shapes.pop("x0"), g["vel0"]
    init = _initial_state(sc, file, n, g["gnames"])
    if init is not None:
        _check_same_shapes(init, shapes["radius"], file, sc["initial_state"]["file"])
        x0[:] = init[0]
        vel0 = [list(r) for r in init[1]]
    sets, ranges, specimens = g["sets"], g["group_ranges"], g["specimens"]
    bc = _boundaries(sc, file, n, sets, ranges)
    monitored = bc.pop("monitored")
    macro = _macro_spec(sc, file, sets, ranges, specimens, g["verts"], g["thick"])
    for name in (macro.load_set, macro.left, macro.right) if macro is not None else ():
        if name not in monitored:
            monitored.append(name)
    for name in monitored:
        if name not in sets:
            sets[name] = resolve_set(name, sets, ranges, file, "boundary")
    timing = _time_and_frames(sc, file, bc.pop("driven"))
    loads = _external_loads(sc, file, g)
    ctx = _family_context(sc, file, g, shapes, x0, bc["bc_kind"], timing, init, loads)
    return System(
        file=file,
        scenario=sc,
        n=n,
        group=np.asarray(g["groups"], dtype=np.int64),
        group_names=g["gnames"],
        thickness=thick,
        x0=x0,
        v0=np.asarray(vel0, float).reshape(n, 3),
        sets=sets,
        monitored=monitored,
        **shapes,
        **bc,
        ext=loads["ext"],
        ext_ramp=loads["ext_ramp"],
        ramp_time=loads["ramp_time"],
        gravity=np.array(sc["body_force"]["gravity"], float) if sc["body_force"] is not None else np.zeros(2),
        integrator=INTEGRATORS[sc["time"]["integrator"]],
        dt=timing["dt"],
        end_step=timing["end_step"],
        frame_steps=timing["frame_steps"],
        history_every=sc["output"]["history_every"],
        checkpoint_interval=sc["output"]["checkpoint_interval"],
        specimens=specimens,
        unused=unused_parameters(sc),
        macro=macro,
        family_data={f.name: f.build(sc, ctx) for f in FAMILIES},
    )


def _family_context(sc, file, g, shapes, x0, bc_kind, timing, init, loads=None) -> dict:
    """What the interaction families' ``build`` (interactions/protocol.py) may read besides the scenario: the
    file, particle count, the validated [[particles]], group index ranges, specimens, each particle's material
    table, the shapes (body_v, vert_start, radius, area, mass, inertia), x0, thickness, the boundary kinds, the
    named sets, ``select(entry, key)`` (the particles a [[perturb]]-like entry with ``set`` or ``at`` picks),
    dt, the index of the boundary entry whose motion drives the run (None), the [contact] table (None), the
    checkpoint fields of [initial_state] (None), the [[loads]] per entry (:func:`_external_loads`), every particle's
    outline at t0 (``verts``) and group index (``group``)."""
    sets, ranges = g["sets"], g["group_ranges"]
    return dict(
        file=file,
        n=g["n"],
        particles=sc["particles"],
        groups=ranges,
        specimens=g["specimens"],
        materials=[sc["materials"][sc["particles"][q]["material"]] for q in g["groups"]],
        shapes=shapes,
        x0=x0,
        thickness=np.asarray(g["thick"], float),
        bc_kind=bc_kind,
        sets=sets,
        select=lambda entry, key: perturb_selection(entry, x0, sets, ranges, file, key),
        dt=timing["dt"],
        drive=timing["drive"],
        contact=sc["contact"],
        initial_state=init[2] if init is not None else None,
        loads=loads,
        verts=g["verts"],
        group=g["groups"],
    )


def _particles(sc, file) -> dict:
    """The particle groups of ``[[particles]]`` generated in order: outlines, group of each particle, names,
    thickness and initial velocity per particle, the named sets (each group and its generator's subsets),
    the index range and the generated specimen of each group."""
    seed = sc["scenario"]["seed"]
    mats = sc["materials"]
    verts, groups, gnames, thick, vel0 = [], [], [], [], []
    sets: dict = {}
    group_ranges: dict = {}
    specimens: dict = {}
    for gi, p in enumerate(sc["particles"]):
        key = f"particles[{gi}]"
        if p["name"] in group_ranges or p["name"] == "all":
            raise ScenarioError(file, f"{key}.name", p["name"], "group name used twice (or reserved)")
        if p["material"] not in mats:
            raise ScenarioError(
                file, f"{key}.material", p["material"], f"unknown material (defined: {', '.join(mats)})"
            )
        if p["type"] == "rectangle" and p["place"] is not None:
            p = _placed(p, key, file, group_ranges, verts)
        spec = _generate(p, seed, file, key)
        if p["type"] == "voronoi" and p["split"] != "none":
            spec = gen.split_cells(spec, p["h_pg"], p["split_min_edge"])
        if p["type"] == "voronoi" and p["aggregate_fraction"] > 0.0:
            _aggregates(spec, p, p["seed"] if p["seed"] is not None else seed, file, key)
        if p["type"] == "voronoi" and p["min_shared_edge"] > 0 and len(spec.shared_pairs):
            keep = spec.shared_lengths >= p["min_shared_edge"]
            spec.shared_pairs = spec.shared_pairs[keep]
            spec.shared_lengths = spec.shared_lengths[keep]
            spec.shared_edges = spec.shared_edges[keep]
        lo = len(verts)
        verts.extend(spec.vertices)
        hi = len(verts)
        groups.extend([gi] * len(spec))
        gnames.append(p["name"])
        thick.extend([p["thickness"]] * len(spec))
        vel0.extend([p["velocity"]] * len(spec))
        group_ranges[p["name"]] = (lo, hi)
        sets[p["name"]] = np.arange(lo, hi)
        for sname, idx in spec.subsets.items():
            sets[f"{p['name']}.{sname}"] = lo + np.asarray(idx, dtype=np.int64)
        specimens[p["name"]] = spec
    sets["all"] = np.arange(len(verts))
    return dict(
        n=len(verts),
        verts=verts,
        groups=groups,
        gnames=gnames,
        thick=thick,
        vel0=vel0,
        sets=sets,
        group_ranges=group_ranges,
        specimens=specimens,
    )


def _aggregates(spec, p, seed, file, key):
    """Aggregates by the group's grading curve in a Voronoi specimen (geometry/aggregates.py): ``spec.phase`` (per
    cell its aggregate, -1 matrix), subsets ``aggregate`` and ``matrix``, the discs and the area reached in
    ``spec.info``."""
    from ..geometry.aggregates import Grading, cell_phases, place_aggregates

    for k in ("aggregate_d_min", "aggregate_d_max"):
        if p[k] is None:
            raise ScenarioError(file, f"{key}.{k}", NOVALUE, "aggregates need the grading's smallest and largest size")
    if p["aggregate_d_min"] >= p["aggregate_d_max"]:
        raise ScenarioError(file, f"{key}.aggregate_d_min", p["aggregate_d_min"], "must be below aggregate_d_max")
    if p["aggregate_d_min"] < 2.0 * p["h_pg"]:
        raise ScenarioError(
            file,
            f"{key}.aggregate_d_min",
            p["aggregate_d_min"],
            f"an aggregate must span cells: at least 2 h_pg = {2.0 * p['h_pg']:g} cm across",
        )
    g = Grading(
        p["aggregate_fraction"],
        p["aggregate_d_min"],
        p["aggregate_d_max"],
        p["grading_exponent"],
        p["grading_classes"],
        p["aggregate_gap"],
    )
    # a seed of its own for the placement, so that the cells stay those of the specimen's seed
    try:
        aggs, area = place_aggregates(spec.vertices, g, seed + 7919, p["h_pg"])
    except GeometryError as e:
        raise ScenarioError(file, f"{key}.aggregate_d_min", p["aggregate_d_min"], str(e)) from None
    spec.phase = cell_phases(spec.vertices, aggs)
    spec.subsets["aggregate"] = np.flatnonzero(spec.phase >= 0)
    spec.subsets["matrix"] = np.flatnonzero(spec.phase < 0)
    reached = sum(np.pi * r * r for _, _, r in aggs) / area
    spec.info.update(aggregates=[list(map(float, a)) for a in aggs], aggregate_area_fraction=float(reached))


def _placed(p, key, file, group_ranges, verts) -> dict:
    """A rectangle ``place``d "above:G" or "below:G" an earlier group G: its centre moved to touch it."""
    side, _, other = p["place"].partition(":")
    if other not in group_ranges:
        raise ScenarioError(
            file,
            f"{key}.place",
            p["place"],
            f"'{other}' is not an earlier particle group ({', '.join(group_ranges) or 'none'})",
        )
    lo_, hi_ = group_ranges[other]
    ys = np.concatenate([np.asarray(v)[:, 1] for v in verts[lo_:hi_]])
    h = p["size"][1]
    return dict(p, center=[p["center"][0], ys.max() + h / 2 if side == "above" else ys.min() - h / 2])


def _shapes(sc, file, g) -> dict:
    """Body-frame outlines (CSR by particle), centroids, radii, areas, masses and moments of inertia; disks and
    walls take their family's own mass properties."""
    n, verts, groups, thick = g["n"], g["verts"], g["groups"], g["thick"]
    mats = sc["materials"]
    vert_start = np.zeros(n + 1, np.int64)
    bodies, x0 = [], np.zeros((n, 3))
    radius, area, mass, inertia = (np.zeros(n) for _ in range(4))
    for i, v in enumerate(verts):
        gi = groups[i]
        try:
            shape, c = make_shape(v, f"particle {i}")
        except GeometryError as e:
            raise ScenarioError(file, f"particles[{gi}]", NOVALUE, f"impossible geometry: {e}") from None
        rho = mats[sc["particles"][gi]["material"]]["density"]
        bodies.append(shape.body_vertices)
        vert_start[i + 1] = vert_start[i] + len(shape.body_vertices)
        x0[i, :2] = c
        radius[i] = shape.radius
        area[i] = shape.area
        mass[i] = shape.mass(rho, thick[i])
        inertia[i] = shape.inertia(rho, thick[i])
    for p in sc["particles"]:  # disks (sphere masses) and walls: the family's own masses
        if p["type"] in FAMILY_OF_VARIANT:
            lo, hi = g["group_ranges"][p["name"]]
            rho = mats[p["material"]]["density"]
            mass[lo:hi], inertia[lo:hi] = FAMILY_OF_VARIANT[p["type"]].mass_properties(
                g["specimens"][p["name"]], rho, p["thickness"], mass[lo:hi], inertia[lo:hi]
            )
    body_v = np.vstack(bodies) if bodies else np.zeros((0, 2))
    return dict(vert_start=vert_start, body_v=body_v, x0=x0, radius=radius, area=area, mass=mass, inertia=inertia)


#: the outward normal a pressure's set name implies (``[[loads]] normal``)
_SIDE_NORMALS = {"left": (-1.0, 0.0), "right": (1.0, 0.0), "top": (0.0, 1.0), "bottom": (0.0, -1.0)}


def _external_loads(sc, file, g) -> dict:
    """The external forces and moments of ``[[loads]]``: ``ext`` (n, 3) the loads at full value from t = 0,
    ``ext_ramp`` (n, 3) those raised linearly over ``ramp_time`` (one for all; 0 without), a pressure turned into
    each particle's resultant on its loaded exposed edges (:func:`..geometry.polygon.exposed_edges`) and the
    resultant's moment about the particle's centroid (both fixed at t0: a dead load); ``entries``: per entry its set,
    particles (``idx``), their loads ``f`` (m, 3) and whether it is ramped."""
    from ..geometry.polygon import exposed_edges, polygon_area_centroid_inertia

    n, sets, ranges = g["n"], g["sets"], g["group_ranges"]
    ext, ramped = np.zeros((n, 3)), np.zeros((n, 3))
    ramp = 0.0
    groups = np.asarray(g["groups"], np.int64)
    entries = []  # per entry its particles and their loads (the history's applied-load columns)
    for li, ld in enumerate(sc["loads"]):
        key = f"loads[{li}]"
        sel = resolve_set(ld["set"], sets, ranges, file, f"{key}.set")
        mine = np.zeros((len(sel), 3))
        mine[:, 0], mine[:, 1], mine[:, 2] = ld["force"][0], ld["force"][1], ld["moment"]
        entries.append({"set": ld["set"], "idx": np.asarray(sel, np.int64), "f": mine, "ramped": ld["ramp_time"] > 0})
        tr = float(ld["ramp_time"])
        if tr > 0.0:
            if ramp > 0.0 and tr != ramp:
                raise ScenarioError(
                    file,
                    f"{key}.ramp_time",
                    tr,
                    f"every ramped load shares one ramp_time (an earlier one has {ramp:g} s)",
                )
            ramp = tr
        tgt = ramped if tr > 0.0 else ext
        tgt[sel, 0] += ld["force"][0]
        tgt[sel, 1] += ld["force"][1]
        tgt[sel, 2] += ld["moment"]
        p = float(ld["pressure"])
        if p == 0.0:
            if ld["normal"] is not None:
                raise ScenarioError(file, f"{key}.normal", ld["normal"], "a normal only selects a pressure's edges")
            continue
        side = ld["set"].rsplit(".", 1)[-1] if "." in ld["set"] else None
        normal = ld["normal"] if ld["normal"] is not None else _SIDE_NORMALS.get(side)
        if normal is not None:
            normal = np.asarray(normal, float) / np.hypot(*normal)
        sel = np.asarray(sel, np.int64)
        per = exposed_edges(g["verts"], sel, np.flatnonzero(np.isin(groups, np.unique(groups[sel]))))
        any_edge = False
        for j, (i, edges) in enumerate(zip(sel, per)):
            c = polygon_area_centroid_inertia(np.asarray(g["verts"][i], float))[1]
            for L, nv, m in edges:
                if normal is not None and nv @ normal < 0.5:
                    continue
                any_edge = True
                f = -p * g["thick"][i] * L * nv
                tgt[i, :2] += f
                tgt[i, 2] += (m[0] - c[0]) * f[1] - (m[1] - c[1]) * f[0]
                mine[j, :2] += f
                mine[j, 2] += (m[0] - c[0]) * f[1] - (m[1] - c[1]) * f[0]
        if not any_edge:
            raise ScenarioError(
                file,
                f"{key}.set",
                ld["set"],
                "the pressure finds no exposed edge of this set"
                + (f" facing {list(np.round(normal, 3))}" if normal is not None else "")
                + " (an edge no other particle of its group shares)",
            )
    return dict(ext=ext, ext_ramp=ramped if ramp > 0.0 else None, ramp_time=ramp, entries=entries)


def _boundaries(sc, file, n, sets, group_ranges) -> dict:
    """Kind, velocity and acceleration of every prescribed DOF (``[[boundary]]``; a DOF prescribed twice is
    refused), the monitored sets (prescribed and observed) and the boundary entries that move."""
    bc_kind = np.zeros((n, 3), np.int64)
    bc_vel = np.zeros((n, 3))
    bc_acc = np.zeros((n, 3))
    owner = -np.ones((n, 3), np.int64)
    monitored, driven = [], []
    for bi, b in enumerate(sc["boundary"]):
        key = f"boundary[{bi}]"
        idx = resolve_set(b["set"], sets, group_ranges, file, f"{key}.set")
        any_presc, moving = False, False
        for d, dof in enumerate(("x1", "x2", "phi")):
            kind, vv, aa = motion_of(b[dof])
            if kind == FREE:
                continue
            any_presc = True
            moving |= kind in MOVING
            clash = owner[idx, d] >= 0
            if np.any(clash):
                i = int(idx[np.argmax(clash)])
                raise ScenarioError(
                    file,
                    f"{key}.{dof}",
                    b[dof],
                    f"particle {i} already has {dof} prescribed by boundary[{owner[i, d]}]",
                )
            owner[idx, d] = bi
            bc_kind[idx, d] = kind
            bc_vel[idx, d] = vv
            bc_acc[idx, d] = aa
        if any_presc and b["set"] not in monitored:
            monitored.append(b["set"])
        if moving:
            driven.append(bi)
    for oi, name in enumerate(sc["output"]["observe"]):
        resolve_set(name, sets, group_ranges, file, f"output.observe[{oi}]")
        if name not in monitored:
            monitored.append(name)
    return dict(bc_kind=bc_kind, bc_vel=bc_vel, bc_acc=bc_acc, monitored=monitored, driven=driven)


def _drive(sc, file, driven):
    """The boundary entry whose motion the end displacement and the load drop follow (None: none moves)."""
    t = sc["time"]
    if t["end_displacement_set"] is None:
        return driven[0] if driven else None
    cand = [bi for bi, b in enumerate(sc["boundary"]) if b["set"] == t["end_displacement_set"]]
    if not cand or cand[0] not in driven:
        raise ScenarioError(
            file,
            "time.end_displacement_set",
            t["end_displacement_set"],
            "is not the set of a boundary entry with a moving DOF",
        )
    return cand[0]


def _time_and_frames(sc, file, driven) -> dict:
    """dt, the end step (the earliest of the end time and the end displacement), the frame steps and the index of
    the boundary entry whose motion drives the run (None if none moves)."""
    t = sc["time"]
    dt = t["dt"]
    ends = []
    drive_bi = _drive(sc, file, driven)
    if t["end_time"] is not None:
        ends.append(t["end_time"])
    if t["end_displacement"] is not None:
        if drive_bi is None:
            raise ScenarioError(
                file, "time.end_displacement", t["end_displacement"], "no boundary entry prescribes a moving DOF"
            )
        b = sc["boundary"][drive_bi]
        times = [displacement_time(*motion_of(b[dof]), t["end_displacement"]) for dof in ("x1", "x2", "phi")]
        ends.append(min(times))
    end_time = min(ends)
    if t["end_load_drop"] is not None and drive_bi is None:  # refused here, in the order of the [time] keys
        raise ScenarioError(
            file,
            "time.end_load_drop",
            t["end_load_drop"],
            "no boundary entry prescribes a moving DOF (no load to follow)",
        )
    end_step = max(1, int(math.ceil(end_time / dt - 1e-9)))
    if end_step > 10**12:
        raise ScenarioError(file, "time.dt", dt, f"gives {end_step:.3g} steps to the end time {end_time:g} s")
    o = sc["output"]
    fi = o["frame_interval"] if o["frame_interval"] is not None else end_step * dt / 50.0
    nfr = int(math.floor(end_step * dt / fi + 1e-9))
    steps = {0, end_step}
    steps.update(min(end_step, int(round(k * fi / dt))) for k in range(nfr + 1))
    for ft in o["frame_times"]:
        steps.add(min(end_step, int(round(ft / dt))))
    return dict(
        dt=dt,
        end_step=end_step,
        frame_steps=np.array(sorted(steps), dtype=np.int64),
        drive=drive_bi,
    )


def _macro_spec(sc, file, sets, group_ranges, specimens, verts, thick):
    """Resolve ``[macro]``: sets (named), L1, L2 (generator size or bounding box) and T."""
    m = sc.get("macro")
    if m is None:
        return None
    g = m["specimen"]
    if g not in group_ranges:
        raise ScenarioError(file, "macro.specimen", g, f"unknown particle group ({', '.join(group_ranges)})")
    names = {}
    for key, default in (("load_set", "top"), ("left", "left"), ("right", "right")):
        name = m[key] if m[key] is not None else f"{g}.{default}"
        resolve_set(name, sets, group_ranges, file, f"macro.{key}")
        names[key] = name
    lo, hi = group_ranges[g]
    info = specimens[g].info or {}
    if "width" in info and "height" in info:
        w, h = float(info["width"]), float(info["height"])
    else:
        pts = np.vstack([np.asarray(v) for v in verts[lo:hi]])
        w, h = (float(q) for q in np.ptp(pts, axis=0))
    L1 = m["L1"] if m["L1"] is not None else w
    L2 = m["L2"] if m["L2"] is not None else h
    T = m["thickness"] if m["thickness"] is not None else float(thick[lo])
    return MacroSpec(g, names["load_set"], names["left"], names["right"], L1, L2, T, tuple(m["fit_range"]))


def unused_parameters(sc: dict) -> list:
    """Keys set in the scenario that the scene does not use (GUIDE practice 9): materials no group uses, and
    what each interaction family says it will not use (``Family.unused``)."""
    used_mats = {p["material"] for p in sc["particles"]}
    out = [f"materials.{name} (no particle group uses it)" for name in sc["materials"] if name not in used_mats]
    for f in FAMILIES:
        out += f.unused(sc)
    return out


__all__ = ["System", "build_system", "BC_KINDS"]
