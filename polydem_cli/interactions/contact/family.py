"""Polygon contact (thesis §§4.1–4.3) as an interaction family of the compiled loop (interactions/protocol.py).

The bundle holds what the contact pass (kernel.py) needs — the polygons' geometry, the pair parameters, the
search and pair-list work arrays, the contact history of the last and of this step, which pairs the beam
bonds still join (shared with the bond family, which passes first) — plus the family's statistics and
accumulators.  Everything else about polygon contact outside the loop lives here too: its history-table
columns, checkpoint fields, summary figures, the instability and containment checks and its stiffness for
the critical time step.
"""

from __future__ import annotations

from collections import namedtuple
from dataclasses import dataclass

import numpy as np

from ...errors import NOVALUE, ScenarioError
from ...jit import loop_njit
from ...params import Param, Table
from ..protocol import GO_ON, HALT_ABORT, Family, register_hooks
from ..ranks import Entries, Pairs, PerParticle, Rebuilt
from ..search import large_particle_mask
from .kernel import (
    N_STATS,
    ST_D_FRIC,
    ST_D_RATE,
    ST_E_EL,
    ST_MAX_UT_EL,
    ST_MAXA,
    ST_MAXA_A,
    ST_MAXA_B,
    ST_MAXA_RATIO,
    ST_NC,
    ST_NCONT,
    ST_PAIR_A,
    ST_PAIR_B,
    ContactParams,
    _build_index,
    contact_pass,
    copy_history,
    empty_history,
    make_work,
)
from .normal import harmonic_pair, mean_pair
from .tangential import MODELS as TANGENTIAL_MODELS

#: the polygons as the contact pass sees them (bounding radii; ``is_large``/``large_idx``: particles kept out
#: of the linked-cell mesh, search.py)
Polygons = namedtuple("Polygons", ["vert_start", "body_v", "radius", "area", "thickness", "is_large", "large_idx"])
#: pairs joined by an active bond do not interact by contact: CSR of bonded partners keyed by the smaller
#: index, and the bonds' activity at the present evaluation (arrays of the bond family's bundle)
BondLinks = namedtuple("BondLinks", ["start", "partner", "active"])

#: g: Polygons; cp: ContactParams; cw: ContactWork; hold / hnew: contact history (last step / this step);
#: links: BondLinks; stats: ST_* of the last final pass; acc: ACC_*; need: [capacity asked for, 0 if none];
#: abort: [1 if a contained pair stops the run (contact.on_containment = "abort")]; csum/ctot: the contained pairs
#: this process counted at the last final pass / their count over the ranks (the same array in a serial run; a
#: decomposed run sums them in the evaluation's reduction, so every rank's halt stops alike)
PolygonContact = namedtuple(
    "PolygonContact", ["g", "cp", "cw", "hold", "hnew", "links", "stats", "acc", "need", "abort", "csum", "ctot"]
)
ACC_DRATE_PREV = 0  # dissipation rate of the normal model at the last step (trapezoidal rule)
ACC_MAXA_RATIO = 1  # largest A_n / smaller area so far, and its pair
ACC_MAXA_A = 2
ACC_MAXA_B = 3
ACC_MAXA = 4  # largest A_n so far
ACC_MAX_UT = 5  # largest |u_t - u_t^pl| so far
ACC_NCONT = 6  # contained pair-steps so far, the first such pair and its step
ACC_CONT_A = 7
ACC_CONT_B = 8
ACC_CONT_STEP = 9
ACC_DT = 10  # the time step (for the trapezoidal rule)
ACC_STEP = 11  # the step being computed
ACC_INIT = 12  # 1 once the state at t0 has been accepted
#: accumulators summed over the ranks of a decomposed run (counted on rank 0 after a re-cut)
ACC_SUMS = (ACC_DRATE_PREV, ACC_NCONT)
N_ACC = 13


COLUMNS = (
    ("n_contacts", "-", "number of contacts"),
    ("max_overlap_area", "cm^2", "largest overlap area A_n"),
    ("max_overlap_ratio", "-", "largest A_n / area of the smaller particle"),
    ("max_ut_elastic", "cm", "largest elastic tangential displacement |u_t − u_t^pl|"),
)

# ---------------------------------------------------------------- compiled hooks


@loop_njit
def _begin(fam, step, t):
    fam.acc[ACC_STEP] = step


@loop_njit
def _pass(fam, final, x, v, dt, F):
    s = fam.stats
    if final:
        for k in range(s.shape[0]):
            s[k] = 0.0
        s[ST_PAIR_A] = -1.0
        s[ST_PAIR_B] = -1.0
        s[ST_MAXA_A] = -1.0
        s[ST_MAXA_B] = -1.0
        fam.acc[ACC_DT] = dt
    r = contact_pass(final, x, v, dt, fam.g, fam.cp, fam.cw, fam.hold, fam.hnew, fam.links, F, s)
    if final:
        fam.csum[0] = s[ST_NCONT]
    if r < 0:
        fam.need[0] = -r
    return r


@loop_njit
def _accept(fam):
    copy_history(fam.hnew, fam.hold, fam.hold.start.shape[0] - 1)
    a = fam.acc
    s = fam.stats
    if a[ACC_INIT] == 0.0:  # the state at t0: start the trapezoidal rule and the running maxima
        a[ACC_DRATE_PREV] = s[ST_D_RATE]
        a[ACC_MAXA_RATIO] = max(a[ACC_MAXA_RATIO], s[ST_MAXA_RATIO])
        a[ACC_MAXA] = max(a[ACC_MAXA], s[ST_MAXA])
        a[ACC_INIT] = 1.0


@loop_njit
def _accumulate(fam):
    """Energy dissipated in the step: viscous damping and tension cut-off (trapezoidal rule of the rate)
    plus friction; running maxima and the containment count."""
    a = fam.acc
    s = fam.stats
    d = 0.5 * a[ACC_DT] * (a[ACC_DRATE_PREV] + s[ST_D_RATE]) + s[ST_D_FRIC]
    a[ACC_DRATE_PREV] = s[ST_D_RATE]
    if s[ST_MAXA_RATIO] > a[ACC_MAXA_RATIO]:
        a[ACC_MAXA_RATIO] = s[ST_MAXA_RATIO]
        a[ACC_MAXA_A] = s[ST_MAXA_A]
        a[ACC_MAXA_B] = s[ST_MAXA_B]
    a[ACC_MAXA] = max(a[ACC_MAXA], s[ST_MAXA])
    a[ACC_MAX_UT] = max(a[ACC_MAX_UT], s[ST_MAX_UT_EL])
    if s[ST_NCONT] > 0:
        a[ACC_NCONT] += s[ST_NCONT]
        if a[ACC_CONT_STEP] <= 0:
            a[ACC_CONT_A] = s[ST_PAIR_A]
            a[ACC_CONT_B] = s[ST_PAIR_B]
            a[ACC_CONT_STEP] = a[ACC_STEP]
    return d


@loop_njit
def _elastic(fam):
    return fam.stats[ST_E_EL]


@loop_njit
def _halt(fam):
    """A pair with one polygon inside the other stops the run if contact.on_containment = "abort" (counted over the
    ranks of a decomposed run: the pair is counted on one rank only)."""
    s = fam.stats
    if fam.ctot[0] > 0 and fam.abort[0]:
        fam.acc[ACC_CONT_A] = s[ST_PAIR_A]
        fam.acc[ACC_CONT_B] = s[ST_PAIR_B]
        fam.acc[ACC_CONT_STEP] = fam.acc[ACC_STEP]
        return HALT_ABORT
    return GO_ON


@loop_njit
def _row(fam, row, off):
    s = fam.stats
    row[off] = s[ST_NC]
    row[off + 1] = s[ST_MAXA]
    row[off + 2] = s[ST_MAXA_RATIO]
    row[off + 3] = s[ST_MAX_UT_EL]
    return off + 4


register_hooks(
    PolygonContact,
    pass_=_pass,
    accept=_accept,
    accumulate=_accumulate,
    elastic=_elastic,
    row=_row,
    begin=_begin,
    halt=_halt,
)

# ---------------------------------------------------------------- the Python side


@dataclass
class ContactSetup:
    """Polygon contact of a scene, from ``[contact]`` and the materials (``PolygonContactFamily.build``).

    kn, gn, kt, mu: (n,) per-particle k_n, γ_n, k_t, μ_t (k_n scaled where ``[[perturb]]`` says), mixed per pair
    of parameter classes once, before the run, by (4.4), (4.8), (4.15), (4.17) (:func:`mixed_table`); tangential: the model's code (tangential.py); area_tol: the
    overlap area, as a fraction of the smaller particle's, below which a pair is not in contact; is_large: the
    particles searched apart (load plates, search.py); cell_size: the linked-cell mesh size (twice the largest
    small radius unless ``contact.cell_size``); buffer: the pair-list buffer (a fifth of the median small radius
    unless ``contact.buffer``); what to do on containment and on overlaps at t0."""

    kn: np.ndarray
    gn: np.ndarray
    kt: np.ndarray
    mu: np.ndarray
    tangential: int
    area_tol: float
    is_large: np.ndarray
    cell_size: float
    buffer: float
    abort_on_containment: bool
    initial_overlap_allowed: bool


def build_setup(sc: dict, ctx: dict) -> ContactSetup | None:
    """The ContactSetup of a scene with ``[contact]`` (None without)."""
    c = sc["contact"]
    picked = [ctx["select"](pt, f"perturb[{pi}]") for pi, pt in enumerate(sc["perturb"])]  # checked in any scene
    if c is None:
        return None
    mat = ctx["materials"]
    kn = np.array([m["k_n"] for m in mat], float)
    gn = np.array([m["gamma_n"] for m in mat], float)
    kt = np.array([m["k_t"] for m in mat], float)
    mu = np.array([m["mu_t"] for m in mat], float)
    for sel, pt in zip(picked, sc["perturb"]):
        kn[sel] *= pt["k_n_factor"]
    classes = len(np.unique(np.column_stack([kn, gn, kt, mu]), axis=0)) if len(kn) else 0
    if classes > MAX_CLASSES:
        raise ScenarioError(
            ctx["file"],
            "perturb",
            NOVALUE,
            f"gives {classes} distinct sets of contact parameters (k_n, gamma_n, k_t, mu_t); the pre-mixed pair table "
            f"takes at most {MAX_CLASSES} (perturb fewer particles, or use materials)",
        )
    radius = ctx["shapes"]["radius"]
    is_large = large_particle_mask(radius)
    small_r = radius[~is_large] if np.any(~is_large) else radius
    cell_size = 2.0 * float(small_r.max()) if ctx["n"] else 1.0
    if c["cell_size"] is not None:
        cell_size = c["cell_size"]
    buffer = c["buffer"] if c["buffer"] is not None else 0.2 * float(np.median(small_r))
    return ContactSetup(
        kn,
        gn,
        kt,
        mu,
        TANGENTIAL_MODELS[c["tangential"]],
        c["area_tolerance"],
        is_large,
        cell_size,
        buffer,
        c["on_containment"] == "abort",
        c["initial_overlap"] == "allow",
    )


def _polygons(system, cs: ContactSetup) -> Polygons:
    s = system
    return Polygons(
        s.vert_start,
        s.body_v,
        s.radius,
        s.area,
        s.thickness,
        cs.is_large,
        np.flatnonzero(cs.is_large).astype(np.int64),
    )


#: most distinct contact parameter sets of a scene (the pair table has MAX_CLASSES² entries, filled in Python)
MAX_CLASSES = 512


def mixed_table(kn, gn, kt, mu) -> tuple:
    """(class of each particle (n,), the (C, C, 4) table of pair parameters k_n, γ_n, k_t, μ_t of two classes): the
    particles with equal (k_n, γ_n, k_t, μ_t) form a class (in practice one per material and one per distinct
    value ``[[perturb]]`` gives), and each pair of classes is mixed once by (4.4), (4.8), (4.15), (4.17) with the
    very functions the kernel used to call per pair, so the table holds the same numbers bit for bit."""
    rows = np.column_stack([kn, gn, kt, mu]).astype(float)
    if not len(rows):
        return np.zeros(0, np.int64), np.zeros((0, 0, 4))
    uniq, cls = np.unique(rows, axis=0, return_inverse=True)
    C = len(uniq)
    mix = np.zeros((C, C, 4))
    for i in range(C):
        for j in range(C):
            a, b = uniq[i], uniq[j]
            mix[i, j] = (
                harmonic_pair(a[0], b[0]),
                mean_pair(a[1], b[1]),
                harmonic_pair(a[2], b[2]),
                harmonic_pair(a[3], b[3]),
            )
    return cls.reshape(-1).astype(np.int64), mix


def _params(cs: ContactSetup) -> ContactParams:
    cls, mix = mixed_table(cs.kn, cs.gn, cs.kt, cs.mu)
    return ContactParams(cls, mix, int(cs.tangential), float(cs.area_tol), float(cs.cell_size), float(cs.buffer))


def _links(built) -> BondLinks:
    bonds = (built or {}).get("bonds")
    if bonds is None:
        return BondLinks(np.zeros(0, np.int64), np.zeros(0, np.int64), np.zeros(0, np.bool_))
    return bonds.links


#: the per-material keys of polygon contact: k_n, γ_n (normal), k_t, μ_t (tangential)
KEYS = ("k_n", "gamma_n", "k_t", "mu_t")

TANGENTIAL_CHOICES = ("none", "coulomb")
NORMAL_CHOICES = ("area",)

CONTACT = Table(
    {
        "normal": Param("str", default="area", choices=NORMAL_CHOICES, doc="normal model: area = (4.3)+(4.5)+(4.9)"),
        "tangential": Param(
            "str",
            default="coulomb",
            choices=TANGENTIAL_CHOICES,
            doc="tangential model: coulomb = elasto-plastic (4.10)-(4.24)",
        ),
        "cell_size": Param(
            "float",
            unit="cm",
            default=None,
            min=0.0,
            min_open=True,
            doc="linked-cell mesh size h_ks (default: largest bounding diameter)",
        ),
        "buffer": Param(
            "float",
            unit="cm",
            default=None,
            min=0.0,
            doc="buffer distance of the pair list, rebuilt when a particle has moved half of it (thesis §4.1 "
            "suggestion); 0 = search at every evaluation as the thesis; default 0.2 x median bounding radius",
        ),
        "area_tolerance": Param(
            "float",
            default=1e-12,
            min=0.0,
            max=1e-3,
            doc="pairs with A_n below this fraction of the smaller area are not in contact (O-17)",
        ),
        "on_containment": Param(
            "str",
            default="warn",
            choices=("warn", "abort"),
            doc="a polygon entirely inside another: warn (zero force) or abort the run (O-6)",
        ),
        "initial_overlap": Param(
            "str",
            default="error",
            choices=("error", "allow"),
            doc="particles overlapping at t0 (beyond area_tolerance): reject the scenario or allow",
        ),
    },
    doc="Contact between particles (thesis ch. 4).  Omit the table for a scene without contact.",
    required=False,
)


def _no_pair_list(name, system):
    """A buffered pair list's fields for a scene or a part, empty: rebuilt at the first pass."""
    return {
        "pairlist_cand": np.zeros((0, 2), np.int64),
        "pairlist_xbuild": np.zeros((system.n, 3)),
        "pairlist_gap": np.zeros(0),
    }[name]


class PolygonContactFamily(Family):
    name = "contact"
    tables = {"contact": CONTACT}
    columns = COLUMNS
    threaded = True

    summary_keys = ("contact_model",)

    def build(self, sc, ctx):
        """The scene's ContactSetup (None without ``[contact]``)."""
        return build_setup(sc, ctx)

    def unused(self, sc):
        """Contact parameters of the used materials that the scene's contact model ignores, and ``[[perturb]]``
        (it scales k_n) in a scene without contact."""
        c, used = sc["contact"], {p["material"] for p in sc["particles"]}
        mats = [(name, m) for name, m in sc["materials"].items() if name in used]
        if c is None:
            return [f"materials.{name}.{k} (no [contact])" for name, m in mats for k in KEYS if m[k] != 0] + [
                f"perturb[{pi}] (no [contact])" for pi in range(len(sc["perturb"]))
            ]
        if c["tangential"] == "none":
            return [
                f"materials.{name}.{k} (contact.tangential = 'none')" for name, m in mats for k in KEYS[2:] if m[k] != 0
            ]
        return []

    def uses(self, system):
        return self.data(system) is not None

    def column_reductions(self, system):
        """n_contacts sums over the ranks; the largest overlap and elastic slip are maxima."""
        return ("sum", "max", "max", "max")

    def data_layout(self, data):
        """The per-particle parameters of the kept particles (a pair counts on the rank owning its smaller index:
        ``System.own``, read by the kernel).  Plates and walls (large particles) are not decomposed yet."""
        if data.is_large.any():
            from ...errors import DecompositionError

            raise DecompositionError(
                f"polygon contact with {int(data.is_large.sum())} large particle(s) (plates) does not run on several "
                "ranks yet (use --ranks 1)"
            )
        return ((("kn", "gn", "kt", "mu", "is_large"), PerParticle()),)

    def rank_sums(self, system):
        """With contact.on_containment = "abort": the contained pairs, counted on one rank each, summed over the
        ranks at every evaluation, so that every rank's halt stops the run at the same step."""
        cs = self.data(system)
        return np.full((1 if cs is not None and cs.abort_on_containment else 0, 2), -1, np.int64)

    def attach(self, bundle, mpi, sums):
        return bundle._replace(csum=sums.local, ctot=sums.total) if len(sums.local) else bundle

    def reach(self, system):
        """The pair-list buffer: pairs whose bounding circles come within it are listed."""
        cs = self.data(system)
        return float(cs.buffer) if cs is not None else 0.0

    def _capacity(self, system):
        return max(64, 8 * system.n)

    def bundle(self, system, built=None, cap=None, links=None):
        n = system.n
        cap = int(cap or self._capacity(system))
        ncell = max(64, 4 * n + 64)
        cs = self.data(system)
        return PolygonContact(
            _polygons(system, cs),
            _params(cs),
            make_work(n, len(system.body_v), max(system.max_vertices, 3), cap, ncell, system.own),
            empty_history(n, cap),
            empty_history(n, cap),
            links if links is not None else _links(built),
            np.zeros(N_STATS),
            np.zeros(N_ACC),
            np.zeros(1, np.int64),
            np.array([int(cs.abort_on_containment)], np.int64),
            *(np.zeros(1),) * 2,  # csum and ctot: one array (serial; attach gives a rank its own)
        )

    def inert_bundle(self, system, built=None):
        z, zi = np.zeros(0), np.zeros(0, np.int64)
        g = Polygons(zi, np.zeros((0, 2)), z, z, z, np.zeros(0, np.bool_), zi)
        cp = ContactParams(np.zeros(0, np.int64), np.zeros((0, 0, 4)), 0, 0.0, 1.0, 0.0)
        return PolygonContact(
            g,
            cp,
            make_work(0, 0, 3, 0, 1),
            empty_history(0, 0),
            empty_history(0, 0),
            _links(None),
            np.zeros(N_STATS),
            z,
            np.zeros(1, np.int64),
            np.zeros(1, np.int64),
            *(np.zeros(1),) * 2,  # csum and ctot: one array (serial; attach gives a rank its own)
        )

    def grow(self, system, b):
        """A bundle with larger contact and pair buffers and the same history, if the last pass asked."""
        need = int(b.need[0])
        if need <= 0:
            return None
        nb = self.bundle(system, cap=max(2 * need, 2 * b.hold.a.shape[0]), links=b.links)
        m = int(b.hold.meta[0])
        for new, old in zip(nb.hold, b.hold):
            if new.shape == old.shape:
                new[:] = old
            else:
                new[:m] = old[:m]
        nb.stats[:] = b.stats
        nb.acc[:] = b.acc
        return nb._replace(csum=b.csum, ctot=b.ctot)

    def check_initial(self, system, b):
        """Reject particles overlapping at t0 unless the scenario allows it."""
        s = system
        if self.data(s).initial_overlap_allowed or b.stats[ST_NC] == 0:
            return
        a, c = int(b.hold.a[0]), int(b.hold.b[0])
        if b.hold.meta[0] == 0:  # tangential model 'none' keeps no list: find one pair
            a, c = int(b.stats[ST_PAIR_A]), int(b.stats[ST_PAIR_B])
        msg = (
            f"{int(b.stats[ST_NC])} particle pair(s) overlap at t0 by more than the area tolerance"
            + (
                f", e.g. particles {a} ({s.group_names[s.group[a]]}) and {c} ({s.group_names[s.group[c]]})"
                if a >= 0
                else ""
            )
            + '; move them apart or set contact.initial_overlap = "allow"'
        )
        raise ScenarioError(s.file, "particles", NOVALUE, f"impossible geometry: {msg}")

    def check(self, system, b, limits):
        if b.acc[ACC_MAXA_RATIO] > limits["max_overlap_ratio"]:
            a, c = int(b.acc[ACC_MAXA_A]), int(b.acc[ACC_MAXA_B])  # (on a rank: its own numbering)
            names = system.group_names
            return (
                f"the overlap of particle {system.number(a)} ({names[system.group[a]]}) and particle {system.number(c)} "
                f"({names[system.group[c]]}) reached {b.acc[ACC_MAXA_RATIO]:.3g} of the smaller particle's area "
                f"(stability.max_overlap_ratio = {limits['max_overlap_ratio']:g})"
            )
        return None

    def warning(self, system, b):
        if b.acc[ACC_NCONT] > 0:
            a, c = system.number(b.acc[ACC_CONT_A]), system.number(b.acc[ACC_CONT_B])
            return (
                f"particles {a} and {c}: one polygon lies entirely inside the other at "
                f"t = {b.acc[ACC_CONT_STEP] * system.dt:.6g} s; contact force set to zero "
                f"(contact.on_containment = 'warn'); k_n too small or dt too large?"
            )
        return None

    def halt_message(self, system, b, step):
        if not (b.abort[0] and b.stats[ST_NCONT] > 0):
            return None  # (a decomposed run: another rank counted the pair and says so)
        a, c = system.number(b.acc[ACC_CONT_A]), system.number(b.acc[ACC_CONT_B])
        return (
            f"particle {min(a, c)} and {max(a, c)}: one polygon lies entirely inside the other at step "
            f"{step}, t = {step * system.dt:.6g} s (contact.on_containment = 'abort'); "
            f"k_n too small or dt too large"
        )

    def state(self, b):
        m = int(b.hold.meta[0])
        nl = max(int(b.cw.list_meta[0]), 0)
        return {
            "pairlist_n": b.cw.list_meta.copy(),
            "pairlist_cand": b.cw.cand[:nl].copy(),
            "pairlist_xbuild": b.cw.x_build.copy(),
            "pairlist_gap": b.cw.cand_gap[:nl].copy(),
            "contact_a": b.hold.a[:m].copy(),
            "contact_b": b.hold.b[:m].copy(),
            "contact_ut": b.hold.ut[:m].copy(),
            "contact_upl": b.hold.upl[:m].copy(),
            "contact_vt": b.hold.vt[:m].copy(),
            "contact_acc": b.acc.copy(),
        }

    def restore(self, b, st, system=None):
        m = len(st["contact_a"])
        nl = max(int(st["pairlist_n"][0]), 0) if "pairlist_n" in st else 0
        if max(m, nl) > b.hold.a.shape[0]:  # the run had grown its buffers: start from a bundle that fits
            b = self.bundle(system, cap=2 * max(m, nl), links=b.links)._replace(csum=b.csum, ctot=b.ctot)
        h = b.hold
        h.meta[0] = m
        h.a[:m] = st["contact_a"]
        h.b[:m] = st["contact_b"]
        h.ut[:m] = st["contact_ut"]
        h.upl[:m] = st["contact_upl"]
        h.vt[:m] = st["contact_vt"]
        _build_index(h, system.n)
        if "pairlist_n" in st:  # the buffered pair list: resume with the very same list
            b.cw.list_meta[:] = st["pairlist_n"]
            b.cw.cand[:nl] = st["pairlist_cand"]
            xb = st["pairlist_xbuild"]
            b.cw.x_build[:, : xb.shape[1]] = xb
            b.cw.cand_gap[:nl] = st["pairlist_gap"]
        b.acc[:] = st["contact_acc"]
        return b

    def state_layout(self, system):
        """The contacts, each from the rank counting it (the pair's smaller index owned there) to every rank that
        evaluates it; sums (rank 0 keeps them), maxima with the pair of the largest overlap ratio, the first
        contained pair; the buffered pair list is not carried: rebuilt at the first pass (its builds so far
        summed)."""
        return (
            (("contact_a", "contact_b", "contact_ut", "contact_upl", "contact_vt"), Pairs()),
            (
                ("contact_acc",),
                Entries(
                    sums=ACC_SUMS,
                    maxima=(ACC_MAXA, ACC_MAX_UT),
                    particles=(ACC_MAXA_A, ACC_MAXA_B, ACC_CONT_A, ACC_CONT_B),
                    argmax=((ACC_MAXA_RATIO, ACC_MAXA_A, ACC_MAXA_B),),
                    first=((ACC_CONT_STEP, ACC_CONT_A, ACC_CONT_B),),
                ),
            ),
            (("pairlist_n",), Entries(sums=(1,), fixed=((0, -1),))),
            (("pairlist_cand", "pairlist_xbuild", "pairlist_gap"), Rebuilt(_no_pair_list)),
        )

    def observables(self, b):
        return {
            "max_overlap_area": float(b.acc[ACC_MAXA]),
            "max_overlap_ratio": float(b.acc[ACC_MAXA_RATIO]),
            "max_ut_elastic": float(b.acc[ACC_MAX_UT]),
            "contained_pair_steps": int(b.acc[ACC_NCONT]),
        }

    def summary(self, system, b):
        c = system.scenario["contact"]
        return {"contact_model": {"normal": c["normal"], "tangential": c["tangential"]}}

    def omegas(self, system):
        """Normal contact: the linearised stiffness of (4.3) for a face contact, k = k_n B² T with B ≤ 2 r
        (the bounding diameter of the smaller particle), at a lever arm ≤ r, on two particles like the
        lightest one: ω² = 2 k (1/m + r²/Θ); tangential contact the same with k = k_t T."""
        s, cs = system, self.data(system)
        if not s.n or cs is None:
            return []
        free = np.any(s.bc_kind == 0, axis=1)
        r, m, th, T = s.radius, s.mass, s.inertia, s.thickness
        rot = 1.0 / m + r * r / th
        sel = free if np.any(free) else np.ones(s.n, bool)
        wn = np.where(sel, np.sqrt(2.0 * cs.kn * (2 * r) ** 2 * T * rot), 0.0)
        i = int(np.argmax(wn))
        out = [(float(wn[i]), f"normal contact of particle {i} (k_n = {cs.kn[i]:.3g})")]
        if cs.tangential:
            wt = np.where(sel, np.sqrt(2.0 * cs.kt * T * rot), 0.0)
            i = int(np.argmax(wt))
            out.append((float(wt[i]), f"tangential contact of particle {i} (k_t = {cs.kt[i]:.3g})"))
        return out

    # ---- for tests and studies
    @staticmethod
    def contacts(b) -> int:
        """Contacts at the last final pass."""
        return int(b.stats[ST_NC])


POLYGON_CONTACT = PolygonContactFamily()
