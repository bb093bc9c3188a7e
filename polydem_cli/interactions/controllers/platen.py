"""Friction between a loading platen and the specimen's particles it drives (``[[platen]]``), as a family.

A laboratory test drives a specimen through steel platens; how much the platens hold the specimen's faces back
laterally (end restraint) changes the compressive strength and the failure pattern (e.g. van Vliet & van Mier,
Mag. Concr. Res. 48 (1996) 109–120).  The laboratory tests here drive the face particles themselves (docs/lab.md):
their x1 free is a frictionless platen, x1 held a fully restraining one.  A ``[[platen]]`` entry puts a Coulomb
friction between the two on a set whose x2 is prescribed and x1 free: on each particle i of the set

    f_1 = −k_t (u_1 − s),   |f_1| ≤ μ N,   N = max(0, n F_2),

with u_1 its x1 displacement from t0 (the platen does not move along e1), s its slip (history), k_t the
tangential stiffness per particle, n = +1 for a platen on top of the set (it pushes down on particles the
specimen pushes up), −1 below, and F_2 the e2 force of every other interaction on the particle at this pass
(registered after them, engine/families.py: it sees their forces; the x2 reaction the platen provides is −F_2).
Sliding (|trial| > μN) sets f_1 = ±μN and moves s; the slip dissipates the mean of the applied force before and
after it times |Δs| (μN|Δs| at a constant grip; the spring's whole release when N falls under a standing particle).  μ = 0 is the free x1,
μ → ∞ the held one (an elastic spring k_t).
"""

from __future__ import annotations

from collections import namedtuple

import numpy as np

from ...boundary.prescribed import FREE
from ...errors import NOVALUE, ScenarioError
from ...jit import loop_njit
from ...params import ArrayOf, Param, Table
from ..protocol import Family, register_hooks

#: idx: the particles; x0: their x1 at t0; sign: n per particle; mu, kt per particle; s / s_new: slip (last step /
#: this step); f / f_new: the force applied (last step / this step); stats: [dissipated in the step, elastic energy,
#: total f_1, particles sliding]; acc: [dissipated so far]
Platen = namedtuple("Platen", ["idx", "x0", "sign", "mu", "kt", "s", "s_new", "f", "f_new", "stats", "acc"])
ST_DISS, ST_EL, ST_F1, ST_SLIDING = 0, 1, 2, 3

COLUMNS = (
    ("dissipated_platen", "erg", "energy dissipated by platen friction so far (included in 'dissipated')"),
    ("f1_platen", "dyn", "total platen friction force on the specimen, e1"),
    ("platen_sliding", "-", "particles sliding on their platen in this step"),
    (
        "work_platen",
        "erg",
        "work of the platen friction on the specimen so far, −(dissipated_platen + the grips' elastic energy)",
    ),
)


@loop_njit
def _pass(fam, final, x, v, dt, F):
    diss, el, f1, sl = 0.0, 0.0, 0.0, 0.0
    for q in range(fam.idx.shape[0]):
        i = fam.idx[q]
        N = fam.sign[q] * F[i, 1]
        if N < 0.0:
            N = 0.0
        lim = fam.mu[q] * N
        u = x[i, 0] - fam.x0[q]
        f = -fam.kt[q] * (u - fam.s[q])
        s = fam.s[q]
        if abs(f) > lim:
            f = lim if f > 0.0 else -lim
            s = u + f / fam.kt[q]
            sl += 1.0
            # the slip's work at the mean of the grip before and after it: μN |Δs| at a constant grip, and the
            # spring's whole release when N falls at a standing u (½ k (e_old² − e_new²) = ½ (|f_old| + |f|) |Δs|)
            diss -= 0.5 * (fam.f[q] + f) * (s - fam.s[q])  # signed: exact also when the grip reverses
        F[i, 0] += f
        f1 += f
        el += 0.5 * f * f / fam.kt[q]
        if final:
            fam.s_new[q] = s
            fam.f_new[q] = f
    if final:
        fam.stats[ST_DISS] = diss
        fam.stats[ST_EL] = el
        fam.stats[ST_F1] = f1
        fam.stats[ST_SLIDING] = sl
    return 0


@loop_njit
def _accept(fam):
    for q in range(fam.s.shape[0]):
        fam.s[q] = fam.s_new[q]
        fam.f[q] = fam.f_new[q]


@loop_njit
def _accumulate(fam):
    d = fam.stats[ST_DISS]
    fam.acc[0] += d
    return d


@loop_njit
def _elastic(fam):
    return fam.stats[ST_EL]


@loop_njit
def _row(fam, row, off):
    row[off] = fam.acc[0]
    row[off + 1] = fam.stats[ST_F1]
    row[off + 2] = fam.stats[ST_SLIDING]
    row[off + 3] = -(fam.acc[0] + fam.stats[ST_EL])  # the friction does work −(stored + dissipated) on the specimen
    return off + 4


register_hooks(Platen, pass_=_pass, accept=_accept, accumulate=_accumulate, elastic=_elastic, row=_row)

PLATEN = Table(
    {
        "set": Param("str", doc="the particles the platen drives (their x2 prescribed, their x1 free)"),
        "mu": Param("float", min=0.0, doc="Coulomb friction coefficient between platen and specimen (0: none)"),
        "k_t": Param(
            "float",
            unit="dyn/cm",
            min=0.0,
            min_open=True,
            doc="tangential stiffness of the grip on each particle of the set before it slides: a spring in dyn/cm per "
            "particle (a stiff value: the platen's grip), not the modulus k_t of [materials] (g/(cm s^2))",
        ),
        "side": Param(
            "str",
            default=None,
            choices=("top", "bottom"),
            doc="the platen lies above ('top') or below ('bottom') the set; default from a set named "
            "'<group>.top' / '<group>.bottom'",
        ),
    },
    doc="Friction between a loading platen and the particles it drives (interactions/controllers/platen.py): "
    "Coulomb, mu times each particle's push on the platen, elastic below it.",
)


class PlatenFriction(Family):
    name = "platen_friction"
    tables = {"platen": ArrayOf(PLATEN, doc=PLATEN.doc, required=False)}
    columns = COLUMNS

    def build(self, sc, ctx):
        """Per particle of every ``[[platen]]`` set: its x1 at t0, side sign, μ, k_t; ScenarioError for a set whose
        x2 is not prescribed or whose x1 is (the platen would have nothing to restrain), a particle on two
        platens, a side that cannot be told."""
        entries = sc.get("platen") or []
        if not entries:
            return None
        idx, sign, mu, kt = [], [], [], []
        seen = set()
        for k, e in enumerate(entries):
            key = f"platen[{k}]"
            sel = np.asarray(ctx["select"]({"set": e["set"], "at": None}, key), np.int64)
            side = e["side"] or {"top": "top", "bottom": "bottom"}.get(e["set"].rsplit(".", 1)[-1])
            if side is None:
                raise ScenarioError(ctx["file"], f"{key}.side", NOVALUE, "give side = 'top' or 'bottom' for this set")
            bc = ctx["bc_kind"][sel]
            if np.any(bc[:, 1] == FREE):
                raise ScenarioError(
                    ctx["file"], f"{key}.set", e["set"], "a platen drives or holds its particles' x2: prescribe it"
                )
            if np.any(bc[:, 0] != FREE):
                raise ScenarioError(
                    ctx["file"],
                    f"{key}.set",
                    e["set"],
                    "its particles' x1 is prescribed: the platen has nothing to restrain (leave x1 free)",
                )
            twice = seen.intersection(sel.tolist())
            if twice:
                raise ScenarioError(
                    ctx["file"], f"{key}.set", e["set"], f"particle {min(twice)} is on two platens already"
                )
            seen.update(sel.tolist())
            idx.append(sel)
            sign += [1.0 if side == "top" else -1.0] * len(sel)
            mu += [e["mu"]] * len(sel)
            kt += [e["k_t"]] * len(sel)
        idx = np.concatenate(idx)
        return dict(
            idx=idx,
            x0=np.asarray(ctx["x0"])[idx, 0].copy(),
            sign=np.array(sign),
            mu=np.array(mu, float),
            kt=np.array(kt, float),
        )

    def uses(self, system):
        return self.data(system) is not None

    def bundle(self, system, built=None):
        d = self.data(system)
        m = len(d["idx"])
        z = [np.zeros(m) for _ in range(4)]
        return Platen(d["idx"], d["x0"], d["sign"], d["mu"], d["kt"], *z, np.zeros(4), np.zeros(1))

    def inert_bundle(self, system, built=None):
        z = [np.zeros(0) for _ in range(8)]
        return Platen(np.zeros(0, np.int64), *z, np.zeros(4), np.zeros(0))

    def state(self, b):
        return {"platen_s": b.s.copy(), "platen_f": b.f.copy(), "platen_acc": b.acc.copy()}

    def restore(self, b, st, system=None):
        b.s[:] = st["platen_s"]
        b.s_new[:] = st["platen_s"]
        b.f[:] = st["platen_f"]
        b.f_new[:] = st["platen_f"]
        b.acc[:] = st["platen_acc"]

    def observables(self, b):
        return {"platen_dissipated": float(b.acc[0])}

    def omegas(self, system):
        """ω = √(k_t / m) of the stiffest grip on the lightest particle."""
        d = self.data(system)
        if d is None or not len(d["idx"]):
            return []
        grip = d["mu"] > 0.0  # a platen without friction exerts no force
        if not grip.any():
            return []
        w = np.where(grip, np.sqrt(d["kt"] / system.mass[d["idx"]]), 0.0)
        q = int(np.argmax(w))
        return [(float(w[q]), f"platen friction of particle {int(d['idx'][q])}")]


PLATEN_FRICTION = PlatenFriction()
