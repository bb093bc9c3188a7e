"""Cohesive frictionless disks and plane walls (Luding & Herrmann, LH 1.5–1.9) as an interaction family.

Everything the family needs is here: its scenario table ``[disks]`` and particle generators (``disks``,
``random_disks``, ``wall``), the arrays it builds from the validated scenario, its bundle and compiled
hooks (kernel.py), its history-table columns, checkpoint fields, summary figures and its stiffness for
the critical time step.  The time loop does not know it exists (interactions/protocol.py).

Shapes: a disk is drawn (frames, reports) as a regular 24-gon of circumradius r, but it interacts only
through this family, as a circle of radius r; with no tangential force it never feels a moment, so its
rotation stays at rest (its φ DOF is integrated but remains 0).  Masses are those of disks of the group's
thickness (m = ρ π r² T, I = m r²/2) or, with ``sphere_mass = true`` as in the paper, of spheres
(m = 4/3 ρ π r³, I = 2/5 m r²).  A wall is a rectangle particle whose face towards the packing is the
plane ``side``/``position``; it moves only as its boundary conditions say (or freely, with its own mass).

Units: the scenario's (cm, g, s): 1 N/m = 1e3 g/s², 1 kg/s = 1e3 g/s, 1 kg/m³ = 1e-3 g/cm³.
"""

from __future__ import annotations

import math
from collections import namedtuple

import numpy as np

from ...geometry.polygon import GeometryError
from ...geometry.specimens import Specimen, random_disk_packing, rectangle
from ...jit import loop_njit
from ...params import Param, Table
from ..protocol import Family, register_hooks
from ..ranks import Entries, Held, HeldMembers, PairList, Pairs, PerParticle, Rebuilt
from .kernel import (
    N_DSTATS,
    ST_D_HYS,
    ST_D_RATE,
    ST_DT,
    ST_E_EL,
    ST_MAX_REL,
    ST_NATT,
    ST_NC,
    ST_NW,
    DiskParams,
    accept_history,
    disk_pass,
    empty_history,
    make_work,
)

#: p: DiskParams; hold / hnew: contact history (last step / this step); w: work; stats: ST_* of the last
#: final pass; acc: [dissipated so far, dissipation rate at the last step, rate initialised, largest δ/r];
#: wsum (2 nw): scratch of the walls' forces before the pass; rsum (2 nw in a decomposed run with walls, else empty): this rank's part of the walls' forces, summed
#: over the ranks in the evaluation's reduction (engine/halo.py ``settle``), which adds them to F
DiskContact = namedtuple("DiskContact", ["p", "hold", "hnew", "w", "stats", "acc", "wsum", "rsum"])
ACC_DISS = 0
ACC_RATE_PREV = 1
ACC_INIT = 2
ACC_MAX_REL = 3
#: accumulators summed over the ranks (the others: the largest overlap a maximum, the flag rank 0's)
ACC_SUMS = (ACC_DISS, ACC_RATE_PREV)

COLUMNS = (
    ("elastic_disks", "erg", "energy stored in disk contacts, sum of E(delta, delta_max) (included in 'elastic')"),
    ("dissipated_disks", "erg", "energy dissipated by the disk law so far: hysteresis, viscous and background damping"),
    ("disk_contacts", "-", "disk-disk contacts"),
    ("wall_contacts", "-", "disk-wall contacts"),
    ("attractive_contacts", "-", "contacts on an attractive (cohesive) branch, f_hys < 0"),
    ("max_disk_overlap", "-", "largest overlap delta / radius of the smaller disk"),
)

DRAW_SIDES = 24

# ---------------------------------------------------------------- compiled hooks


@loop_njit
def _pass(fam, final, x, v, dt, F):
    wall, s = fam.p.wall, fam.wsum
    nw = wall.shape[0]
    ranks = fam.rsum.shape[0] > 0  # a decomposed run with walls (attach)
    if ranks:  # the forces on the walls before this family's: the rest is what this rank's disks add
        for q in range(nw):
            s[2 * q] = F[wall[q], 0]
            s[2 * q + 1] = F[wall[q], 1]
    res = disk_pass(final, x, v, dt, fam.p, fam.hold, fam.hnew, fam.w, F, fam.stats)
    if ranks:  # a decomposed run: each wall feels the disks of every rank (each rank evaluates its own disks');
        # this rank's part leaves F for the evaluation's sum over the ranks (rank_sums), added to F after it
        for q in range(nw):
            for d in range(2):
                fam.rsum[2 * q + d] = F[wall[q], d] - s[2 * q + d]
                F[wall[q], d] = s[2 * q + d]
    return res


@loop_njit
def _accept(fam):
    accept_history(fam.hnew, fam.hold, fam.w.perm)
    if fam.acc[ACC_INIT] == 0.0:  # the state at t0: start the trapezoidal rule of the dissipation rate
        fam.acc[ACC_RATE_PREV] = fam.stats[ST_D_RATE]
        fam.acc[ACC_INIT] = 1.0


@loop_njit
def _accumulate(fam):
    s = fam.stats
    d = 0.5 * s[ST_DT] * (fam.acc[ACC_RATE_PREV] + s[ST_D_RATE]) + s[ST_D_HYS]
    fam.acc[ACC_RATE_PREV] = s[ST_D_RATE]
    fam.acc[ACC_DISS] += d
    fam.acc[ACC_MAX_REL] = max(fam.acc[ACC_MAX_REL], s[ST_MAX_REL])
    return d


@loop_njit
def _elastic(fam):
    return fam.stats[ST_E_EL]


@loop_njit
def _row(fam, row, off):
    row[off] = fam.stats[ST_E_EL]
    row[off + 1] = fam.acc[ACC_DISS]
    row[off + 2] = fam.stats[ST_NC]
    row[off + 3] = fam.stats[ST_NW]
    row[off + 4] = fam.stats[ST_NATT]
    row[off + 5] = fam.stats[ST_MAX_REL]
    off += 6
    for q in range(fam.w.wf.shape[0]):
        row[off] = fam.w.wf[q]
        row[off + 1] = fam.w.wface[q]
        off += 2
    return off


register_hooks(DiskContact, pass_=_pass, accept=_accept, accumulate=_accumulate, elastic=_elastic, row=_row)

# ---------------------------------------------------------------- scenario: the [disks] table and generators


def _law_check(t):
    if t["k_1"] > t["k_2"]:
        return ("k_1", t["k_1"], f"must not exceed k_2 = {t['k_2']:g} (LH 1.6: loading slope k_1 <= k_2)")
    return None


DISKS = Table(
    {
        "k_1": Param(
            "float", unit="g/s^2", min=0.0, min_open=True, doc="loading stiffness; 1 N/m = 1e3", thesis="k_1, (LH 1.6)"
        ),
        "k_2": Param(
            "float",
            unit="g/s^2",
            min=0.0,
            min_open=True,
            doc="un/reloading stiffness (k_2 >= k_1); 1 N/m = 1e3",
            thesis="k_2, (LH 1.6)",
        ),
        "k_c": Param(
            "float", unit="g/s^2", default=0.0, min=0.0, doc="cohesive (attraction) stiffness", thesis="k_c, (LH 1.6)"
        ),
        "gamma_0": Param(
            "float",
            unit="g/s",
            default=0.0,
            min=0.0,
            doc="viscous contact damping; 1 kg/s = 1e3",
            thesis="γ_0, (LH 1.7)",
        ),
        "gamma_b": Param(
            "float",
            unit="g/s",
            default=0.0,
            min=0.0,
            doc="background damping -γ_b v on every disk",
            thesis="γ_b, (LH 1.9)",
        ),
        "delta_max_memory": Param(
            "str",
            default="contact",
            choices=("contact", "pair"),
            doc="how long a pair keeps its δ_max, which the paper leaves open: 'contact' (the decision of "
            "polydem) resets it when the contact opens; 'pair' keeps it while the pair stays within the "
            "buffer of the pair list (an option, to test the open point)",
        ),
        "cell_size": Param(
            "float",
            unit="cm",
            default=None,
            min=0.0,
            min_open=True,
            doc="linked-cell mesh size (default: largest disk diameter plus the buffer)",
        ),
        "buffer": Param(
            "float",
            unit="cm",
            default=None,
            min=0.0,
            doc="buffer distance of the pair list (disk-disk and disk-wall), rebuilt when a disk or a wall has "
            "moved half of it; 0 = search at every evaluation; default 0.2 x median disk radius",
        ),
    },
    doc="Cohesive frictionless disks (Luding & Herrmann): the hysteretic law (LH 1.6) with δ_max per contact, "
    "viscous (LH 1.7) and background (LH 1.9) damping, between the disks of groups of type 'disks' or "
    "'random_disks' and against groups of type 'wall' (the same law, normal = wall normal).  δ_max is reset "
    "when a contact opens (open point of the paper).  Omit the table for a scene without disks.",
    required=False,
    check=_law_check,
)

_SIDES = {"left": (1.0, 0.0), "right": (-1.0, 0.0), "bottom": (0.0, 1.0), "top": (0.0, -1.0)}

VARIANTS = {
    "disks": {
        "centers": Param("points", unit="cm", doc="disk centres at t0"),
        "radii": Param(
            "floats",
            unit="cm",
            doc="disk radii, one per centre",
            check=lambda v: "every radius must be > 0" if any(r <= 0 for r in v) else None,
        ),
        "sphere_mass": Param("bool", default=False, doc="masses and inertias of spheres (the paper) instead of disks"),
    },
    "random_disks": {
        "count": Param("int", min=1, doc="number of disks"),
        "radius_min": Param("float", unit="cm", min=0.0, min_open=True, doc="smallest radius (uniform distribution)"),
        "radius_max": Param("float", unit="cm", min=0.0, min_open=True, doc="largest radius"),
        "box": Param(
            "floats",
            unit="cm",
            doc="[x1_min, x2_min, x1_max, x2_max] of the region the disks are placed in (random sequential "
            "addition, no overlap)",
            check=lambda v: (
                None
                if len(v) == 4 and v[2] > v[0] and v[3] > v[1]
                else "must be [x1_min, x2_min, x1_max, x2_max] with max > min"
            ),
        ),
        "seed": Param("int", default=None, min=0, doc="random seed (default: scenario.seed)"),
        "sphere_mass": Param("bool", default=False, doc="masses and inertias of spheres (the paper) instead of disks"),
    },
    "wall": {
        "side": Param(
            "str", choices=tuple(_SIDES), doc="which side of the packing the wall bounds (its normal points in)"
        ),
        "position": Param("float", unit="cm", doc="coordinate of the face towards the packing (x1 or x2)"),
        "extent": Param(
            "vec2",
            unit="cm",
            doc="[from, to] along the wall",
            check=lambda v: "must be [from, to] with to > from" if v[1] <= v[0] else None,
        ),
        "width": Param(
            "float",
            unit="cm",
            default=None,
            min=0.0,
            min_open=True,
            doc="thickness of the drawn wall (default: extent/50)",
        ),
        "mass": Param("float", unit="g", default=None, min=0.0, min_open=True, doc="wall mass (default: ρ × area × T)"),
    },
}


def _outline(c, r):
    a = 2.0 * math.pi * np.arange(DRAW_SIDES) / DRAW_SIDES
    return np.column_stack([c[0] + r * np.cos(a), c[1] + r * np.sin(a)])


def _disk_specimen(centers, radii, sphere):
    centers = np.asarray(centers, float)
    radii = np.asarray(radii, float)
    if len(centers) != len(radii):
        raise GeometryError(f"{len(centers)} centres but {len(radii)} radii")
    spec = Specimen([_outline(c, r) for c, r in zip(centers, radii)])
    spec.info.update(disk_radius=radii, sphere_mass=bool(sphere))
    return spec


def _generate(p: dict, seed: int) -> Specimen:
    """The specimen of one of this family's particle groups (raises GeometryError)."""
    t = p["type"]
    if t == "disks":
        return _disk_specimen(p["centers"], p["radii"], p["sphere_mass"])
    if t == "random_disks":
        if p["radius_min"] > p["radius_max"]:
            raise GeometryError(f"radius_min = {p['radius_min']:g} exceeds radius_max = {p['radius_max']:g}")
        c, r = random_disk_packing(
            p["count"], (p["radius_min"], p["radius_max"]), p["box"], p["seed"] if p["seed"] is not None else seed
        )
        return _disk_specimen(c, r, p["sphere_mass"])
    if t == "wall":
        nx, ny = _SIDES[p["side"]]
        lo, hi = p["extent"]
        wdt = p["width"] if p["width"] is not None else (hi - lo) / 50.0
        along = 0.5 * (lo + hi)
        if nx:  # a vertical wall; its centre lies behind the face
            center, size = (p["position"] - nx * wdt / 2, along), (wdt, hi - lo)
        else:
            center, size = (along, p["position"] - ny * wdt / 2), (hi - lo, wdt)
        spec = Specimen([rectangle(center, size)])
        spec.info.update(wall_normal=(nx, ny), wall_offset=wdt / 2, wall_mass=p["mass"])
        return spec
    raise AssertionError(t)  # pragma: no cover


def _mass_properties(spec: Specimen, rho: float, thickness: float, mass, inertia):
    """(mass, inertia) per particle of a disk or wall specimen, given those of its drawn polygons."""
    if "disk_radius" in spec.info:
        r = spec.info["disk_radius"]
        if spec.info["sphere_mass"]:
            m = 4.0 / 3.0 * math.pi * rho * r**3
            return m, 0.4 * m * r**2
        m = math.pi * rho * thickness * r**2
        return m, 0.5 * m * r**2
    if spec.info.get("wall_mass") is not None:
        f = spec.info["wall_mass"] / mass
        return mass * f, inertia * f
    return mass, inertia


# ---------------------------------------------------------------- the Python side

#: the arrays the family builds from the validated scenario (System.family_data["disks"])
DiskSystem = namedtuple("DiskSystem", ["params", "n_disks", "wall_names", "initial"])


class DiskFamily(Family):
    name = "disks"
    columns = COLUMNS
    tables = {"disks": DISKS}
    particle_variants = VARIANTS

    def generate(self, p, seed):
        return _generate(p, seed)

    def mass_properties(self, spec, rho, thickness, mass, inertia):
        return _mass_properties(spec, rho, thickness, mass, inertia)

    def build(self, sc, ctx):
        """DiskSystem from the scenario, or None for a scene without disks.  ``ctx``: file, groups (group
        name → (lo, hi)), specimens (group name → Specimen), particles (the validated [[particles]]), n,
        radius (bounding radii), contact (the [contact] table or None)."""
        from ...errors import NOVALUE, ScenarioError

        file, sc_d = ctx["file"], sc.get("disks")
        mine = [(gi, p) for gi, p in enumerate(ctx["particles"]) if p["type"] in VARIANTS]
        disks = [(gi, p) for gi, p in mine if p["type"] != "wall"]
        if sc_d is None:
            if mine:
                gi, p = mine[0]
                raise ScenarioError(
                    file,
                    f"particles[{gi}].type",
                    p["type"],
                    "a disk or wall group needs the [disks] table (its contact law)",
                )
            return None
        if not disks:
            raise ScenarioError(file, "disks", NOVALUE, "no particle group of type 'disks' or 'random_disks'")
        if ctx["contact"] is not None:
            raise ScenarioError(
                file,
                "contact",
                NOVALUE,
                "polygon contact and disks in one scene are not supported: the disks interact through [disks]",
            )
        n = ctx["n"]
        r = np.zeros(n)
        excl = np.ones(n, np.bool_)
        didx, widx, wn, woff, wnames = [], [], [], [], []
        for _gi, p in mine:
            lo, hi = ctx["groups"][p["name"]]
            spec = ctx["specimens"][p["name"]]
            if p["type"] == "wall":
                widx.append(lo)
                wnames.append(p["name"])
                wn.append(spec.info["wall_normal"])
                woff.append(spec.info["wall_offset"])
            else:
                r[lo:hi] = spec.info["disk_radius"]
                excl[lo:hi] = False
                didx.extend(range(lo, hi))
        buffer = sc_d["buffer"] if sc_d["buffer"] is not None else 0.2 * float(np.median(r[didx]))
        cell = sc_d["cell_size"] if sc_d["cell_size"] is not None else 2.0 * float(r.max()) + buffer
        params = DiskParams(
            np.asarray(didx, np.int64),
            r,
            excl,
            np.asarray(widx, np.int64),
            np.asarray(wn, float).reshape(-1, 2),
            np.asarray(woff, float),
            float(sc_d["k_1"]),
            float(sc_d["k_2"]),
            float(sc_d["k_c"]),
            float(sc_d["gamma_0"]),
            float(sc_d["gamma_b"]),
            float(cell),
            float(buffer),
            int(sc_d["delta_max_memory"] == "pair"),
        )
        return DiskSystem(params, len(didx), wnames, ctx.get("initial_state") or {})

    def uses(self, system):
        return system.family_data.get(self.name) is not None

    # ------------------------------------------------------------ a decomposed run (engine/distributed.py)

    def replicated(self, system):
        """The walls: every rank holds them (a disk finds a wall by its plane, wherever the wall's centre lies)."""
        return np.asarray(system.family_data[self.name].params.wall, np.int64)

    def data_layout(self, data):
        """The held disks (and their count), every particle's radius and exclusion, the walls renumbered (every wall
        is held: :meth:`replicated`); a pair of the initial contact history stays where it is evaluated (see
        kernel.py's ``own``: a disk–wall pair on the disk's owner, a disk–disk pair where either is owned)."""
        return (
            (("params.disk",), HeldMembers(count="n_disks")),
            (("params.r", "params.excl"), PerParticle()),
            (("params.wall",), Held()),
            (("initial.disk_a", "initial.disk_b", "initial.disk_dmax"), PairList(_evaluated_initial)),
        )

    def rank_sums(self, system):
        """The walls' forces along x1 and x2 (each rank evaluates its own disks against every wall)."""
        wall = np.asarray(system.family_data[self.name].params.wall, np.int64)
        return np.stack([np.repeat(wall, 2), np.tile([0, 1], len(wall))], axis=1).astype(np.int64)

    def attach(self, bundle, mpi, sums):
        """A rank of a decomposed run: the walls' forces summed over the ranks at every evaluation."""
        return bundle._replace(rsum=sums.local)

    def column_reductions(self, system):
        """Energies and counts summed (each pair counted on one rank), the largest overlap a maximum; per wall its
        force summed, its face the same on every rank."""
        nw = len(system.family_data[self.name].wall_names)
        return ("sum", "sum", "sum", "sum", "sum", "max") + ("sum", "same") * nw

    def state_layout(self, system):
        """The contacts, each from the rank counting it (kernel.py's rule: the disk's owner against a wall, the
        smaller index's between disks) to every rank that evaluates it; dissipation sums (rank 0 keeps them), the
        largest overlap; the buffered list is not carried: rebuilt at the first pass (its builds so far summed)."""
        return (
            (("disk_a", "disk_b", "disk_dmax"), Pairs(counted=self._counted, evaluated=self._evaluated_here)),
            (("disk_acc",), Entries(sums=ACC_SUMS, maxima=(ACC_MAX_REL,))),
            (("disk_list_meta",), Entries(sums=(1,), fixed=((0, -1), (2, 0)))),
            (("disk_list_cand", "disk_list_wcand", "disk_list_xbuild"), Rebuilt(lambda k, s: _no_list(s.n, 0)[k])),
        )

    def _counted(self, a, b, own, part):
        """The pairs (local numbers) this rank counts."""
        wall = np.asarray(part.family_data[self.name].params.wall, np.int64)
        return np.where(np.isin(b, wall), own[a], own[np.minimum(a, b)]) if len(a) else np.zeros(0, bool)

    def _evaluated_here(self, a, b, loc, owned, part):
        """The pairs (global numbers) the rank of ``part`` evaluates."""
        keep = np.flatnonzero(loc >= 0)  # the held particles' global numbers, in local order
        wall_global = keep[np.asarray(part.family_data[self.name].params.wall, np.int64)]
        return _evaluated(a, b, loc, owned, wall_global)[2]

    def reach(self, system):
        """The pair-list buffer (disk-disk and disk-wall pairs within it are listed)."""
        d = self.data(system)
        return float(d.params.buffer) if d is not None else 0.0

    def columns_of(self, system):
        cols = list(self.columns)
        for s in system.family_data[self.name].wall_names:
            cols += [
                (
                    f"wall_force:{s}",
                    "dyn",
                    f"force of the disks on wall {s}, along its outward normal (pushing it away)",
                ),
                (f"wall_face:{s}", "cm", f"coordinate of the face of wall {s} (x1 for a left/right wall, x2 else)"),
            ]
        return tuple(cols)

    def _capacity(self, system):
        """Contacts of a packing of non-overlapping disks: fewer than 3 per disk, plus the walls'."""
        return 4 * system.family_data[self.name].n_disks + 64

    def bundle(self, system, built=None, cap=None):
        ds = system.family_data[self.name]
        n = system.n
        init = ds.initial
        cap = max(cap or self._capacity(system), 2 * len(init.get("disk_a", ())))
        nw = len(ds.wall_names)
        b = DiskContact(
            ds.params,
            empty_history(n, cap),
            empty_history(n, cap),
            make_work(n, cap, nw, system.own),
            np.zeros(N_DSTATS),
            np.zeros(4),
            np.zeros(2 * nw),
            np.zeros(0),
        )
        if "disk_a" in init:  # initial_state: the contact history of the earlier run (its δ_max)
            m = len(init["disk_a"])
            b.hnew.meta[0] = m
            b.hnew.a[:m], b.hnew.b[:m], b.hnew.dmax[:m] = init["disk_a"], init["disk_b"], init["disk_dmax"]
            accept_history(b.hnew, b.hold, b.w.perm)
        return b

    def inert_bundle(self, system, built=None):
        z, zi = np.zeros(0), np.zeros(0, np.int64)
        p = DiskParams(zi, z, np.zeros(0, np.bool_), zi, np.zeros((0, 2)), z, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0)
        return DiskContact(
            p,
            empty_history(0, 0),
            empty_history(0, 0),
            make_work(0, 0),
            np.zeros(N_DSTATS),
            z,
            z,
            z,
        )

    def grow(self, system, b):
        """A larger bundle with the same history, if the last pass asked for more room (else None)."""
        need = int(b.w.need[0])
        if need <= 0:
            return None
        nb = self.bundle(system, cap=max(2 * need, 2 * b.w.cand.shape[0]))
        m = int(b.hold.meta[0])
        nb.hold.meta[0] = m
        nb.hold.a[:m], nb.hold.b[:m], nb.hold.dmax[:m] = b.hold.a[:m], b.hold.b[:m], b.hold.dmax[:m]
        nb.hold.start[:] = b.hold.start
        nb.stats[:] = b.stats
        nb.acc[:] = b.acc
        return nb._replace(rsum=b.rsum)

    def state(self, b):
        m = int(b.hold.meta[0])
        nl, nwl = max(int(b.w.list_meta[0]), 0), int(b.w.list_meta[2])
        return {
            "disk_a": b.hold.a[:m].copy(),
            "disk_b": b.hold.b[:m].copy(),
            "disk_dmax": b.hold.dmax[:m].copy(),
            "disk_acc": b.acc.copy(),
            # the buffered pair list, so that a resumed run rebuilds it when the uninterrupted one would
            "disk_list_meta": b.w.list_meta.copy(),
            "disk_list_cand": b.w.cand[:nl].copy(),
            "disk_list_wcand": b.w.wcand[:nwl].copy(),
            "disk_list_xbuild": b.w.x_build.copy(),
        }

    def restore(self, b, st, system=None):
        m = len(st["disk_a"])
        nl = len(st.get("disk_list_cand", ()))
        if max(m, nl) > b.hnew.a.shape[0]:  # the run had grown its buffers: start from a bundle that fits
            b = self.bundle(system, cap=2 * max(m, nl))._replace(rsum=b.rsum)
        h = b.hnew  # restored through accept_history, which also rebuilds the index of hold
        h.meta[0] = m
        h.a[:m], h.b[:m], h.dmax[:m] = st["disk_a"], st["disk_b"], st["disk_dmax"]
        accept_history(b.hnew, b.hold, b.w.perm)
        b.acc[:] = st["disk_acc"]
        if "disk_list_meta" in st:  # else (older checkpoints) the list is rebuilt at the first pass
            b.w.list_meta[:] = st["disk_list_meta"]
            b.w.cand[:nl] = st["disk_list_cand"]
            nwl = len(st["disk_list_wcand"])
            b.w.wcand[:nwl] = st["disk_list_wcand"]
            b.w.x_build[:] = st["disk_list_xbuild"]
        return b

    def observables(self, b):
        return {"max_disk_overlap": float(b.acc[ACC_MAX_REL]), "disk_list_builds": int(b.w.list_meta[1])}

    def omegas(self, system):
        """ω = sqrt(k_2 / m_12) of the stiffest contact: two of the lightest disks (m_12 = m/2)."""
        p = system.family_data[self.name].params
        m = system.mass[p.disk]
        q = int(np.argmin(m))
        k = max(p.k1, p.k2)
        return [(math.sqrt(2.0 * k / m[q]), f"disk contact of the lightest disk {int(p.disk[q])} (k_2, m/2)")]


def _evaluated_initial(a, b, loc, owned, data):
    """The initial pairs (global numbers) a rank evaluates, of the whole scene's ``data``."""
    return _evaluated(a, b, loc, owned, np.asarray(data.params.wall, np.int64))[2]


def _evaluated(a, b, loc, owned, wall):
    """Local numbers (``loc``: global → local or −1) of the pairs (a, b) (global; b may be a wall of ``wall``) a rank
    evaluates — both held, and the disk owned against a wall, one of the two owned between disks — and the mask of
    those (the local numbers of the others are −1)."""
    a, b = np.asarray(a, np.int64), np.asarray(b, np.int64)
    isw = np.isin(b, wall)
    sel = (loc[a] >= 0) & (loc[b] >= 0) & np.where(isw, owned[a], owned[a] | owned[b])
    return np.where(sel, loc[a], -1), np.where(sel, loc[b], -1), sel


def _no_list(n: int, builds: int) -> dict:
    """Checkpoint fields of a buffered list to be rebuilt at the first pass (``builds`` so far)."""
    return {
        "disk_list_meta": np.array([-1, builds, 0], np.int64),
        "disk_list_cand": np.zeros((0, 2), np.int64),
        "disk_list_wcand": np.zeros((0, 2), np.int64),
        "disk_list_xbuild": np.zeros((n, 2)),
    }


DISK_CONTACT = DiskFamily()
