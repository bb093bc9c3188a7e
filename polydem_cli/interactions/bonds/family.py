"""Elasto-damage Timoshenko beam bonds (thesis §§5.1.2, 5.2.2) as an interaction family of the compiled loop
(interactions/protocol.py).

The bond family passes first: the polygon contact family (which passes next) shares its ``links`` and so
sees which pairs are still bonded at each evaluation (thesis §4.1).  The history a final pass computes is
committed by ``accept``, so that a step the driver repeats (another family asked for more room) starts
from the same bond state.
"""

from __future__ import annotations

from collections import namedtuple

import numpy as np

from ...jit import loop_njit
from ...params import ArrayOf, Param, Table
from ..contact.family import BondLinks
from ..protocol import Family, register_hooks
from ..ranks import PairRows, Rows, Summed
from .beam import (
    BS_ACTIVE,
    BS_DAMAGED,
    BS_DISS,
    BS_E_EL,
    BS_FAILED,
    BS_FRIC,
    N_BSTATS,
    accept_history,
    bond_pass,
    bond_strains,
    empty_params,
    new_history,
    new_history_new,
    new_work,
)
from .failure import failure_counts
from .iface_data import IfaceHist
from .interface import MODEL_INTERFACE, accept_iface, element_stiffness, iface_pass
from .network import BondNetwork, bond_links, build_network, empty_network

#: p: BondParams; h: BondHist (committed); hn: BondHistNew (this step's final pass); w: BondWork;
#: links: BondLinks (shared with polygon contact); stats: BS_* of the last final pass; acc: [dissipated by damage so far]
BeamBonds = namedtuple("BeamBonds", ["p", "h", "hn", "w", "links", "stats", "acc"])
ACC_DISS = 0
ACC_FRIC = 1  # the interface model: friction work of broken elements so far (its acc has 2 entries, the beams' 1)
#: the per-bond checkpoint fields of ``state`` (beside ``bond_acc``)
_STATE_FIELDS = ("bond_kappa", "bond_d", "bond_active", "bond_Y", "bond_fail_step", "bond_fail_strain", "bond_rate_f")

COLUMNS = (
    ("elastic_bonds", "erg", "elastic energy stored in bonds (included in 'elastic')"),
    ("dissipated_damage", "erg", "energy dissipated by bond damage so far (included in 'dissipated')"),
    ("bonds_active", "-", "bonds not yet failed"),
    ("bonds_damaged", "-", "active bonds with 0 < d < 1"),
    ("bonds_failed", "-", "bonds with d = 1 (inactive; the pair interacts by contact)"),
)
#: the interface model's column beyond COLUMNS
IFACE_COLUMNS = (
    (
        "dissipated_interface_plastic",
        "erg",
        "friction work of broken interface elements and crushing work at the compressive cap so far (included in "
        "'dissipated'; not in dissipated_damage)",
    ),
)

# ---------------------------------------------------------------- compiled hooks


@loop_njit
def _begin(fam, step, t):
    fam.h.clock[0] = step


@loop_njit
def _pass(fam, final, x, v, dt, F):
    if fam.p.iface.model == MODEL_INTERFACE:
        iface_pass(final, x, fam.p, fam.h, fam.hn, fam.w, F, fam.stats)
    else:
        bond_pass(final, x, v, fam.p, fam.h, fam.hn, fam.w, F, fam.stats)
    return 0


@loop_njit
def _accept(fam):
    accept_history(fam.hn, fam.h)
    if fam.p.iface.model == MODEL_INTERFACE:
        accept_iface(fam.hn, fam.h)


@loop_njit
def _accumulate(fam):
    d = fam.stats[BS_DISS]
    fam.acc[ACC_DISS] += d - fam.stats[BS_FRIC]  # BS_FRIC is 0 with beams: the same number
    if fam.acc.shape[0] > ACC_FRIC:
        fam.acc[ACC_FRIC] += fam.stats[BS_FRIC]
    return d


@loop_njit
def _elastic(fam):
    return fam.stats[BS_E_EL]


@loop_njit
def _row(fam, row, off):
    s = fam.stats
    row[off] = s[BS_E_EL]
    row[off + 1] = fam.acc[ACC_DISS]
    row[off + 2] = s[BS_ACTIVE]
    row[off + 3] = s[BS_DAMAGED]
    row[off + 4] = s[BS_FAILED]
    if fam.acc.shape[0] > ACC_FRIC:
        row[off + 5] = fam.acc[ACC_FRIC]
        return off + 6
    return off + 5


register_hooks(BeamBonds, pass_=_pass, accept=_accept, accumulate=_accumulate, elastic=_elastic, row=_row, begin=_begin)

# ---------------------------------------------------------------- the Python side


def _bond_omegas(system) -> np.ndarray:
    """Per bond, the largest eigenvalue of M⁻¹K of its two-particle beam element: the undamaged stiffness of
    (5.11) with the masses and moments of inertia of its two particles."""
    p = BEAM_BONDS.network(system).params
    L, EA, kb, eta = p.L, p.EA, p.kb, p.eta
    nb = len(L)
    K = np.zeros((nb, 6, 6))
    a = EA / L
    k = kb
    K[:, 0, 0] = K[:, 3, 3] = a
    K[:, 0, 3] = K[:, 3, 0] = -a
    K[:, 1, 1] = K[:, 4, 4] = 12 * k
    K[:, 1, 4] = K[:, 4, 1] = -12 * k
    for (i, j), f in (((1, 2), 6), ((1, 5), 6), ((2, 4), -6), ((4, 5), -6)):
        K[:, i, j] = K[:, j, i] = f * L * k
    K[:, 2, 2] = K[:, 5, 5] = (4 + eta) * L * L * k
    K[:, 2, 5] = K[:, 5, 2] = (2 - eta) * L * L * k
    return pair_omegas(system, p, K)


def pair_omegas(system, p, K, chunk: int = 8192) -> np.ndarray:
    """Per bond, the square root of the largest eigenvalue of M⁻¹K of its two-particle element: ``K`` (nb, 6, 6) in
    the DOFs (x, y, φ of I, then of II), with the masses and moments of inertia of the bond's particles.  Taken
    ``chunk`` bonds at a time, so that the scaled matrices and LAPACK's work arrays stay small beside ``K`` (each
    bond's eigenvalues are its own: the same numbers as all at once)."""
    w = np.empty(len(K))
    for lo in range(0, len(K), chunk):
        a, b = p.a[lo : lo + chunk], p.b[lo : lo + chunk]
        m = np.stack(
            [system.mass[a], system.mass[a], system.inertia[a], system.mass[b], system.mass[b], system.inertia[b]],
            axis=1,
        )
        s = 1.0 / np.sqrt(m)
        A = K[lo : lo + chunk] * s[:, :, None] * s[:, None, :]
        w[lo : lo + chunk] = np.sqrt(np.maximum(np.linalg.eigvalsh(A)[:, -1], 0.0))
    return w


#: the keys of the edge-interface model ([bonds] model = "interface", interface.py) and of the beams'
INTERFACE_KEYS = ("f_t", "cohesion", "G_I", "G_II")
INTERFACE_OPTIONAL = ("elements", "compressive_cap", "crack_criterion", "crack_strength")
BEAM_ONLY_KEYS = ("kappa_0", "kappa_m", "G_ax", "G_ax_kappa_0")


def _inverse_volumes(system) -> np.ndarray:
    """1/(A T) of each particle (its mean stress is the sum of its interfaces' first moments over its volume)."""
    return 1.0 / (np.asarray(system.area, float) * np.asarray(system.thickness, float))


def _bonds_check(b):
    if b["model"] == "interface":
        for k in INTERFACE_KEYS:
            if b[k] is None:
                return (k, None, 'missing value (needed by model = "interface")')
        if b["nu"] > 1.0 / 3.0:
            return ("nu", b["nu"], "above 1/3: the interface's k_s/k_n = (1 - 3 nu)/(1 + nu) would be negative")
        if b["rate_dependent"]:
            return ("rate_dependent", True, "the interface model has no rate dependence (a beam option, (5.13))")
        return None
    if b["kappa_0"] is None:
        return ("kappa_0", None, "missing value (the beams' strain at damage onset, (5.6))")
    if (b["kappa_m"] is None) == (b["G_ax"] is None):
        return (
            "kappa_m",
            b["kappa_m"],
            "give exactly one of kappa_m and G_ax (kappa_m = 2 G_ax/(E kappa_0 L_h), (5.12))",
        )
    if b["rate_dependent"]:
        for k in ("eps0_dot", "alpha"):
            if b[k] is None:
                return (k, None, "missing value (needed by rate_dependent = true, (5.13))")
    return None


BOND_PERTURB = Table(
    {
        "at": Param(
            "vec2",
            unit="cm",
            default=None,
            doc="the bond whose midpoint (between the centroids) is nearest to this point",
        ),
        "pair": Param(
            "pairs",
            default=None,
            doc="[[i, j]]: the bond between particles i and j (global indices)",
            check=lambda v: None if v is None or len(v) == 1 else "give exactly one [i, j] pair",
        ),
        "E_factor": Param("float", min=0.0, min_open=True, doc="factor on E_h of that bond (symmetry breaking)"),
    },
    doc="Scale E_h of one bond (thesis: one beam weakened by 10 %).",
    check=lambda t: (
        None if (t["at"] is None) != (t["pair"] is None) else ("at", t["at"], "give exactly one of at and pair")
    ),
)

BOND_PHASE = Table(
    {
        "E": Param("float", unit="g/(cm s^2)", default=None, min=0.0, min_open=True, doc="E_h (default: [bonds] E)"),
        "nu": Param("float", default=None, min=-1.0, max=0.5, min_open=True, doc="ν_h (default: [bonds] nu)"),
        "kappa_0": Param("float", default=None, min=0.0, min_open=True, doc="κ_0 (default: [bonds] kappa_0)"),
        "G_ax": Param(
            "float",
            unit="g/s^2",
            default=None,
            min=0.0,
            min_open=True,
            doc="G_h,ax, κ_m by (5.12) with this phase's E and κ_0 (default: [bonds] G_ax; only with G_ax)",
        ),
    },
    doc="Beams of one phase of a mesoscale Voronoi specimen (a group with aggregate_fraction > 0): each value "
    "given replaces [bonds]'s for these beams, the others are [bonds]'s.",
    required=False,
)

BONDS = Table(
    {
        "model": Param(
            "str",
            default="beam",
            choices=("beam", "interface"),
            doc="beam: elasto-damage Timoshenko beam (5.2)-(5.12); interface: the shared edge as a "
            "cohesive-frictional interface of elements (interactions/bonds/interface.py: Potyondy 2012's flat "
            "joint, Alfano & Sacco 2006's damage with friction, a Mohr-Coulomb surface with a tension cut-off "
            "as Cusatis et al. 2011's)",
        ),
        "groups": Param(
            "strs",
            default=None,
            doc="particle groups whose initially touching pairs are bonded (default: every group "
            "whose generator records touching pairs)",
        ),
        "E": Param(
            "float", unit="g/(cm s^2)", min=0.0, min_open=True, doc="Young's modulus; 1 N/cm^2 = 1e5", thesis="E_h"
        ),
        "nu": Param(
            "float", default=0.0, min=-1.0, max=0.5, min_open=True, doc="Poisson ratio (may be negative)", thesis="ν_h"
        ),
        "kappa_0": Param(
            "float", default=None, min=0.0, min_open=True, doc="strain at damage onset (beams)", thesis="κ_0, (5.6)"
        ),
        "kappa_m": Param(
            "float", default=None, min=0.0, min_open=True, doc="strain at complete failure", thesis="κ_m, (5.6)"
        ),
        "G_ax": Param(
            "float",
            unit="g/s^2",
            default=None,
            min=0.0,
            min_open=True,
            doc="energy dissipated in axial tension per cross-section (1 N cm/cm^2 = 1e5); kappa_m = 2 G_ax/(E kappa_0 L_h) per beam",
            thesis="G_h,ax, (5.12)",
        ),
        "G_ax_kappa_0": Param(
            "float",
            default=None,
            min=0.0,
            min_open=True,
            doc="kappa_0 used in (5.12) to turn G_ax into kappa_m (default: kappa_0; the thesis's 2 kappa_0 "
            "variation keeps the reference kappa_m, O-20)",
        ),
        "shear_factor": Param(
            "float", default=5.0 / 6.0, min=0.0, max=1.0, min_open=True, doc="A_h,Q / A_h", thesis="α_Q"
        ),
        "kappa_m_below_kappa_0": Param(
            "str",
            default="error",
            choices=("error", "clamp"),
            doc="a beam with kappa_m < kappa_0: reject the scenario, or clamp kappa_m = kappa_0 with a warning",
        ),
        "rate_dependent": Param("bool", default=False, doc="rate-dependent strength (5.13)-(5.16)"),
        "eps0_dot": Param(
            "float", unit="1/s", default=None, min=0.0, min_open=True, doc="threshold strain rate", thesis="ε̇_0"
        ),
        "alpha": Param("float", default=None, min=0.0, doc="rate exponent", thesis="α"),
        "rate_filter": Param(
            "float",
            unit="s",
            default=0.0,
            min=0.0,
            doc="option, not in the thesis: time constant tau of an exponential filter of the axial strain "
            "rate used in (5.13), d(rate_f)/dt = (rate - rate_f)/tau, so that the strength follows the "
            "loading rate of the beam rather than its elastic vibrations; 0 = the thesis's instantaneous "
            "rate (5.16)",
        ),
        "f_t": Param(
            "float",
            unit="g/(cm s^2)",
            default=None,
            min=0.0,
            min_open=True,
            doc="interface: tensile strength of an element (1 N/mm^2 = 1e7)",
        ),
        "cohesion": Param(
            "float",
            unit="g/(cm s^2)",
            default=None,
            min=0.0,
            min_open=True,
            doc="interface: shear strength at zero normal stress, c",
        ),
        "friction": Param(
            "float",
            default=0.7,
            min=0.0,
            doc="interface: mu of the intact interface's Mohr-Coulomb branch |tau| = c - mu sigma (sigma < 0)",
        ),
        "residual_friction": Param(
            "float", default=0.6, min=0.0, doc="interface: Coulomb friction of broken element faces, mu_r"
        ),
        "G_I": Param(
            "float",
            unit="g/s^2",
            default=None,
            min=0.0,
            min_open=True,
            doc="interface: mode I fracture energy per area (1 N/m = 1e3)",
        ),
        "G_II": Param(
            "float",
            unit="g/s^2",
            default=None,
            min=0.0,
            min_open=True,
            doc="interface: mode II (shear, no normal stress) fracture energy per area",
        ),
        "compressive_cap": Param(
            "float",
            unit="g/(cm s^2)",
            default=None,
            min=0.0,
            min_open=True,
            doc="interface: the normal compression an element carries at most; beyond it the element crushes "
            "(perfectly plastic, a permanent compaction; default none)",
        ),
        "elements": Param("int", default=None, min=1, doc="interface: elements along each shared edge (default 3)"),
        "crack_criterion": Param(
            "str",
            default=None,
            choices=("facet", "principal"),
            doc="interface: what breaks an element — 'facet' (default): its own traction against the strength "
            "surface; 'principal': also the largest principal stress of its two particles' mean stress (from their "
            "interfaces' tractions) above crack_strength, so that a crack can form across inclined edges "
            "(docs/interface.md; not with integrator verlet1)",
        ),
        "crack_strength": Param(
            "float",
            unit="g/(cm s^2)",
            default=None,
            min=0.0,
            min_open=True,
            doc="interface, crack_criterion = 'principal': the principal stress of two particles' mean stress at "
            "which the material between them cracks across (default f_t)",
        ),
        "perturb": ArrayOf(BOND_PERTURB, doc=BOND_PERTURB.doc, required=False),
        "aggregate": BOND_PHASE,
        "interface": Table(
            BOND_PHASE.fields,
            doc="Beams between an aggregate's cell and a matrix cell or another aggregate's (the interfacial "
            "transition zone), as [bonds.aggregate].",
            required=False,
        ),
    },
    doc="Bonds between initially touching particles (thesis ch. 5).  Omit the table for a scene without bonds.",
    required=False,
    check=_bonds_check,
)


class BeamBondFamily(Family):
    name = "bonds"
    tables = {"bonds": BONDS}
    columns = COLUMNS
    threaded = True

    summary_keys = ("bonds", "bond_failure")
    figures = ("load_damage_strains", "damage_end", "failures")
    result_group = "bonds"

    def build(self, sc, ctx):
        """The scene's BondNetwork (network.py; an empty one without ``[bonds]``)."""
        return build_network(sc, ctx["file"], ctx["specimens"], ctx["groups"], ctx["x0"], ctx["thickness"], ctx["dt"])

    def unused(self, sc):
        """Rate-dependence parameters set while ``bonds.rate_dependent`` is false; the other model's parameters (a
        beam material's kappa_0 under an interface material given with --set or extends)."""
        b = sc["bonds"]
        if b is not None and b["model"] == "interface":
            out = [f"bonds.{k} (bonds.model = interface)" for k in BEAM_ONLY_KEYS if b[k] is not None]
            if b["crack_strength"] is not None and b["crack_criterion"] != "principal":
                out.append('bonds.crack_strength (bonds.crack_criterion is not "principal")')
            return out
        if b is None:
            return []
        out = [f"bonds.{k} (bonds.model = beam)" for k in INTERFACE_KEYS + INTERFACE_OPTIONAL if b[k] is not None]
        if b["rate_dependent"]:
            return out
        out += [f"bonds.{k} (bonds.rate_dependent = false)" for k in ("eps0_dot", "alpha") if b[k] is not None]
        if b["rate_filter"]:
            out.append("bonds.rate_filter (bonds.rate_dependent = false)")
        return out

    def interface(self, system) -> bool:
        """Whether the scene's bonds are edge interfaces (``[bonds] model = "interface"``)."""
        return self.network(system).params.iface.model == MODEL_INTERFACE

    def columns_of(self, system) -> tuple:
        """COLUMNS, and the interface's friction work with the interface model."""
        return COLUMNS + IFACE_COLUMNS if self.interface(system) else COLUMNS

    def network(self, system) -> BondNetwork:
        """The scene's bond network (empty without bonds)."""
        net = self.data(system)
        return net if net is not None else empty_network()

    def uses(self, system):
        # a rank's part of a bonded scene uses the family even without a bond of its own (the same families, and
        # so the same history columns and collective calls, on every rank)
        net = self.network(system)
        return net.n > 0 or net.gid is not None

    def data_layout(self, data):
        """The bonds of the rank's own particles, renumbered (the order by (a, b) stays: the renumbering is monotone),
        each counted on the rank owning its particle I; every per-bond array of the parameters, the edge interfaces,
        the moduli and the edges cut alike; a part carries no clamped or perturbed list (the whole scene's, for the
        summary)."""
        rows = PairRows(
            a="params.a",
            b="params.b",
            along=("params.*", "params.iface.*", "E", "nu", "edges"),
            ids="gid",
            counted="counted",
            emptied=("clamped", "perturbed"),
        )
        return (((), rows),)

    def ghost_field(self, bundle):
        """The particles' mean stress of the ``principal`` crack criterion: a rank holds every interface of its own
        particles (``data_layout``) but not of its ghosts, so a ghost's stress is its owner's (interface.py
        ``particle_stress``)."""
        return bundle.w.sg if bundle.p.iface.principal else None

    def bundle(self, system, built=None):
        net = self.network(system)
        p = net.params
        nb = int(p.a.shape[0])
        ne = p.iface.rI.shape[1] if p.iface.model == MODEL_INTERFACE else 0
        h = new_history(nb, ne)
        return BeamBonds(
            p,
            h,
            new_history_new(nb, ne),
            new_work(nb, net.counted, system.n if ne else 0, _inverse_volumes(system) if p.iface.principal else None),
            BondLinks(bond_links(p, system.n), p.b, h.eval_active),
            np.zeros(N_BSTATS),
            np.zeros(2 if ne else 1),
        )

    def inert_bundle(self, system, built=None):
        h = new_history(0)
        z = np.zeros(0, np.int64)
        return BeamBonds(
            empty_params(),
            h,
            new_history_new(0),
            new_work(0),
            BondLinks(z, z, h.eval_active),
            np.zeros(N_BSTATS),
            np.zeros(0),
        )

    def state(self, b):  # the per-bond fields are _STATE_FIELDS (and bond_e_* of the interface's elements)
        h = b.h
        return {
            "bond_kappa": h.kappa.copy(),
            "bond_d": h.d.copy(),
            "bond_active": h.active.copy(),
            "bond_Y": h.Y.copy(),
            "bond_fail_step": h.fail_step.copy(),
            "bond_fail_strain": h.fail_strain.copy(),
            "bond_rate_f": h.rate_f.copy(),
            "bond_acc": b.acc.copy(),
        } | ({f"bond_e_{k}": v.copy() for k, v in h.iface._asdict().items()} if h.iface.D.shape[1] else {})

    def restore(self, b, st, system=None):
        h = b.h
        h.kappa[:] = st["bond_kappa"]
        h.d[:] = st["bond_d"]
        h.active[:] = st["bond_active"]
        h.eval_active[:] = st["bond_active"]
        h.Y[:] = st["bond_Y"]
        h.rate_f[:] = st["bond_rate_f"]
        h.fail_step[:] = st["bond_fail_step"]
        h.fail_strain[:] = st["bond_fail_strain"]
        b.acc[:] = st["bond_acc"]
        for k, v in h.iface._asdict().items():
            if v.shape[1]:  # (a checkpoint from before the cap has no compaction: zero)
                v[:] = st[f"bond_e_{k}"] if f"bond_e_{k}" in st else 0.0

    def state_layout(self, system):
        """Every bond's history by its number in the whole scene, from the rank counting it; the dissipated energy
        summed (rank 0 keeps it)."""
        rows = _STATE_FIELDS + (tuple(f"bond_e_{k}" for k in IfaceHist._fields) if self.interface(system) else ())
        return (
            (
                rows,
                Rows(
                    ids=lambda part: (self.data(part).gid, self.data(part).counted == 1), n=lambda s: self.network(s).n
                ),
            ),
            (("bond_acc",), Summed()),
        )

    def omegas(self, system):
        if self.interface(system):
            return self._iface_omegas(system)
        w = _bond_omegas(system)
        k = int(np.argmax(w))
        p = self.network(system).params
        return [(float(w[k]), f"bond {k} (particles {p.a[k]}-{p.b[k]}, L_h = {p.L[k]:.3g} cm, H_h = {p.H[k]:.3g} cm)")]

    def _iface_omegas(self, system):
        """The largest eigenvalue of M⁻¹K of each intact interface's two-particle element (interface.py
        ``element_stiffness``)."""
        p = self.network(system).params
        w = pair_omegas(system, p, element_stiffness(p.iface))
        k = int(np.argmax(w))
        return [
            (float(w[k]), f"interface {k} (particles {p.a[k]}-{p.b[k]}, L_h = {p.L[k]:.3g} cm, edge {p.H[k]:.3g} cm)")
        ]

    def frame(self, system, b, x):
        """Per bond: damage d, κ and the mid-span strain parts (Figs. 5.8–5.11) at positions ``x``."""
        out = np.zeros((self.network(system).n, 4))
        bond_strains(np.ascontiguousarray(x), b.p, out)
        fr = {"bond_d": b.h.d.copy(), "bond_kappa": b.h.kappa.copy(), "bond_strain": out}
        if b.h.iface.D.shape[1]:
            fr["bond_element_d"] = b.h.iface.D.copy()
        return fr

    def frame_layout(self, system):
        """Damage, κ and the strain parts of every bond per frame."""
        nb = self.network(system).n
        return {
            "bond_d": ((nb,), None),
            "bond_kappa": ((nb,), None),
            "bond_strain": ((nb, 4), ["eps_ax_M", "abs_kappa_M_H_half", "abs_gamma_M", "eps_v"]),
        } | (
            {"bond_element_d": ((nb, self.network(system).params.iface.rI.shape[1]), None)}
            if self.interface(system)
            else {}
        )

    def frame_rows(self, system):
        """Every bond by its number in the whole scene, from the rank counting it (as its history, :meth:`state_layout`)."""
        return self.state_layout(system)[0][1]

    def static(self, system):
        """``/bonds``: the pairs, the beam geometry and parameters, the shared edges (io/hdf5.py)."""
        net = self.network(system)
        if not net.n:
            return None
        p = net.params
        return "bonds", {
            "pairs": np.column_stack([p.a, p.b]),
            "L": p.L,
            "H": p.H,
            "T": p.T,
            "E": net.E,
            "nu": net.nu,
            "kappa_0": p.kappa0,
            "kappa_m": p.kappam,
            "eps0_dot": p.eps0dot,
            "alpha": p.alpha,
            "edges": net.edges,
            "rate_dependent": np.array([p.rate_dependent]),
        } | (self._iface_static(p.iface) if p.iface.model == MODEL_INTERFACE else {})

    @staticmethod
    def _iface_static(ip):
        """The interface model's data in ``/bonds`` (io/hdf5.py): its flag, elements and law per bond."""
        return {
            "interface": np.array([ip.rI.shape[1]]),
            "k_n": ip.kn,
            "k_s": ip.ks,
            "f_t": ip.ft,
            "cohesion": ip.coh,
            "friction": ip.mu,
            "residual_friction": ip.mur,
            "G_I": ip.GI,
            "G_II": ip.GII,
            "compressive_cap": ip.cap,
        } | ({"crack_strength": ip.fp} if ip.principal else {})

    def records(self, b):
        return {"bond_failure": {"step": b.h.fail_step.copy(), "strain": b.h.fail_strain.copy()}}

    def summary(self, system, b):
        net, h = self.network(system), b.h
        return {
            "bonds": {
                "count": net.n,
                "failed": int((~h.active).sum()),
                "damaged": int(((h.d > 0) & h.active).sum()),
                "kappa_m_clamped": len(net.clamped),
                "perturbed": net.perturbed,
            },
            "bond_failure": failure_counts(h.fail_step, h.fail_strain, net.params.ux0, net.params.uy0, system.dt),
        }

    def summary_lines(self, summary):
        """How many bonds failed, by mode and by orientation."""
        bf = summary.get("bond_failure")
        if not (bf and bf["failed"]):
            return []
        modes = ", ".join(f"{k} {v}" for k, v in bf["by_mode"].items())
        ori = ", ".join(f"{k} {v}" for k, v in bf["by_orientation"].items())
        return [
            f"failed bonds: {bf['failed']} of {summary['bonds']['count']} (by mode: {modes}; by orientation: {ori})"
        ]

    def table_columns(self, summary):
        """The failed bonds (with bonds)."""
        bf = summary.get("bond_failure")
        return {"failed bonds": bf.get("failed")} if bf else {}


BEAM_BONDS = BeamBondFamily()
