"""Particle–base friction (thesis §4.4.2) as an interaction family of the compiled loop
(interactions/protocol.py): its bundle, its compiled hooks and its columns, checkpoint fields and summary."""

from __future__ import annotations

from collections import namedtuple

import numpy as np

from ...boundary.prescribed import FREE
from ...jit import loop_njit
from ...params import Param, Table
from ..protocol import Family, register_hooks
from ..ranks import Entries, Groups, Rows
from .friction import (
    BA_DISS,
    BA_E_EL,
    BA_FX,
    BA_FY,
    BA_MAX_UEL,
    BA_NSLIP,
    N_BASTATS,
    BaseParams,
    base_pass,
    build_base,
    empty_base,
)

#: bs: BaseParams; upl / upl_new: u_u^pl per Gauss point (last step / this step); ws: per-particle work;
#: stats: BA_* of the last final pass; acc: [dissipated so far, largest |u_u - u_u^pl| so far]
BaseFriction = namedtuple("BaseFriction", ["bs", "upl", "upl_new", "ws", "stats", "acc"])
ACC_DISS = 0
ACC_MAX_UB = 1
#: what the family builds: the Gauss points and parameters (bs) of the whole scene (gp None) or of a rank's part of a
#: decomposed run (engine/distributed.py: the points of the particles it owns, in local particle numbers, with their
#: numbers among the whole scene's in gp)
BaseData = namedtuple("BaseData", ["bs", "gp"])

COLUMNS = (
    ("elastic_base", "erg", "elastic energy of the particle-base friction (included in 'elastic')"),
    ("dissipated_base", "erg", "energy dissipated by base friction so far (included in 'dissipated')"),
    ("max_ub_elastic", "cm", "largest elastic base displacement |u_u - u_u^pl| at a Gauss point"),
    ("base_slipping_points", "-", "Gauss points that slipped in this step"),
    ("fb1", "dyn", "total base friction force on all particles, e1"),
    ("fb2", "dyn", "total base friction force on all particles, e2"),
)


@loop_njit
def _pass(fam, final, x, v, dt, F):
    base_pass(final, x, fam.bs, fam.upl, fam.upl_new, F, fam.ws, fam.stats)
    return 0


@loop_njit
def _accept(fam):
    for g in range(fam.upl.shape[0]):
        fam.upl[g, 0] = fam.upl_new[g, 0]
        fam.upl[g, 1] = fam.upl_new[g, 1]


@loop_njit
def _accumulate(fam):
    d = fam.stats[BA_DISS]
    fam.acc[ACC_DISS] += d
    fam.acc[ACC_MAX_UB] = max(fam.acc[ACC_MAX_UB], fam.stats[BA_MAX_UEL])
    return d


@loop_njit
def _elastic(fam):
    return fam.stats[BA_E_EL]


@loop_njit
def _row(fam, row, off):
    row[off] = fam.stats[BA_E_EL]
    row[off + 1] = fam.acc[ACC_DISS]
    row[off + 2] = fam.stats[BA_MAX_UEL]
    row[off + 3] = fam.stats[BA_NSLIP]
    row[off + 4] = fam.stats[BA_FX]
    row[off + 5] = fam.stats[BA_FY]
    return off + 6


register_hooks(BaseFriction, pass_=_pass, accept=_accept, accumulate=_accumulate, elastic=_elastic, row=_row)


BASE = Table(
    {
        "gravity": Param(
            "float",
            unit="cm/s^2",
            default=981.0,
            min=0.0,
            min_open=True,
            doc="gravity normal to the base plate: base normal stress sigma_u = -rho T g",
            thesis="g, σ_u",
        ),
        "gauss_points": Param(
            "int",
            default=7,
            choices=None,
            check=lambda v: None if v in (1, 3, 7) else "must be 1, 3 or 7",
            doc="Gauss points per triangle (centroid + two vertices): 7 = degree 5 (thesis), 3, 1",
        ),
    },
    doc="Particle-base friction (thesis 4.4.2) for every particle whose material has k_u > 0 and mu_u > 0. "
    "Omit the table for a scene without a base plate.",
    required=False,
)


def _gauss_points(part):
    """A rank's Gauss points: their numbers in the whole scene, every one counted here (their particles are owned)."""
    gp = part.family_data["base_friction"].gp
    return gp, np.ones(len(gp), bool)


class BaseFrictionFamily(Family):
    name = "base_friction"
    tables = {"base": BASE}
    columns = COLUMNS

    def build(self, sc, ctx):
        """The Gauss points and parameters of ``[base]`` (friction.py; empty without the table): particles with
        every DOF prescribed get none (base friction would have no effect on them)."""
        if sc["base"] is None:
            return BaseData(empty_base(), None)
        mat, sh = ctx["materials"], ctx["shapes"]
        fully = np.all(ctx["bc_kind"] != FREE, axis=1)
        bs = build_base(
            sh["body_v"],
            sh["vert_start"],
            ctx["x0"],
            np.array([m["density"] for m in mat], float),
            ctx["thickness"],
            np.where(fully, 0.0, [m["k_u"] for m in mat]),
            [m["mu_u"] for m in mat],
            sc["base"]["gravity"],
            sc["base"]["gauss_points"],
        )
        return BaseData(bs, None)

    def unused(self, sc):
        """k_u and μ_u of the used materials in a scene without ``[base]``."""
        if sc["base"] is not None:
            return []
        used = {p["material"] for p in sc["particles"]}
        return [
            f"materials.{name}.{k} (no [base])"
            for name, m in sc["materials"].items()
            if name in used
            for k in ("k_u", "mu_u")
            if m[k] != 0
        ]

    def params(self, system) -> BaseParams:
        """The scene's base-friction parameters (empty without ``[base]``)."""
        d = self.data(system)
        return d.bs if d is not None else empty_base()

    def uses(self, system):
        """A scene with Gauss points; and every rank's part of one (a rank owning none keeps the family's columns)."""
        d = self.data(system)
        return d is not None and (d.gp is not None or d.bs.X.shape[0] > 0)

    # ------------------------------------------------------------ a decomposed run (engine/distributed.py)

    def data_layout(self, data):
        """The Gauss points of the owned particles only: the friction acts on a particle alone, and a ghost's forces
        are its owner's business; so each point is counted once, on its particle's owner."""
        return (((), Groups("bs.idx", "bs.start", ("bs.ku", "bs.mu_sigma", "bs.x0"), ("bs.X", "bs.wA"), ids="gp")),)

    def column_reductions(self, system):
        return ("sum", "sum", "max", "sum", "sum", "sum")

    def state_layout(self, system):
        """The Gauss points' plastic slips by their numbers in the whole scene (a rank holds its owned particles'
        points only: ``data_layout``); the dissipation summed, the largest elastic slip the largest."""
        return (
            (("base_upl",), Rows(ids=_gauss_points, n=lambda s: self.params(s).X.shape[0])),
            (("base_acc",), Entries(sums=(ACC_DISS,), maxima=(ACC_MAX_UB,))),
        )

    def bundle(self, system, built=None):
        bs = self.params(system)
        ngp = int(bs.X.shape[0])
        return BaseFriction(
            bs, np.zeros((ngp, 2)), np.zeros((ngp, 2)), np.zeros((bs.idx.shape[0], 6)), np.zeros(N_BASTATS), np.zeros(2)
        )

    def inert_bundle(self, system, built=None):
        return self.bundle(system)._replace(acc=np.zeros(0))

    def state(self, b):
        return {"base_upl": b.upl.copy(), "base_acc": b.acc.copy()}

    def restore(self, b, st, system=None):
        b.upl[:] = st["base_upl"]
        b.acc[:] = st["base_acc"]

    def observables(self, b):
        return {"max_ub_elastic": float(b.acc[ACC_MAX_UB])}

    def omegas(self, system):
        """ω² = k_u / (ρ T), translation and rotation alike (a particle on its own elastic base)."""
        bs = self.params(system)
        if not bs.idx.shape[0]:  # a rank's part without base friction
            return []
        rho = system.mass[bs.idx] / (system.area[bs.idx] * system.thickness[bs.idx])
        wb = np.sqrt(bs.ku / (rho * system.thickness[bs.idx]))
        q = int(np.argmax(wb))
        return [(float(wb[q]), f"base friction of particle {int(bs.idx[q])}")]


BASE_FRICTION = BaseFrictionFamily()
