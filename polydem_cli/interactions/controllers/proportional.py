"""A pressure that follows the stress on another face (``[[proportional_pressure]]``): proportional loading.

The biaxial tests of concrete (Kupfer, Hilsdorf & Rüsch 1969) keep the ratio of the two in-plane principal stresses
fixed while the load rises to failure, through brush platens that do not restrain the faces laterally.  Here one
face is driven (a prescribed motion, as in the uniaxial tests) and the stress on it is measured; the faces across
the other direction carry a pressure that follows it,

    σ_ref = −Σ_i F_i·n_ref / A_ref,        p = −α σ_ref,

F_i the force of every interaction on particle i of the reference set (its reaction, the thesis's f₂ convention:
tension positive), n_ref that face's outward normal and A_ref = T Σ L its exposed edges' area, α = σ₂/σ₁ the stress
ratio.  The pressure (positive inwards; negative: a pull) acts on the exposed edges of the loaded set as a
``[[loads]]`` pressure does (each particle: −p T Σ L n and that resultant's moment about its centroid), and it is a
follower of the measured stress, not of the prescribed motion: it uses the reference stress of the previous step's
final evaluation (one step of lag, 4·10⁻⁷ s in the concrete panels, against loading times of 10⁻²–10⁻¹ s), through a
first-order filter of time constant ``filter_time``.  The filter is needed: the driven face's reaction carries its
wave reflections, and a pressure that follows them closes a loop (pressure, lateral motion, axial reaction) that
rings up — an 8 × 8 cm panel in equal biaxial compression failed at 0.41 f_c unfiltered, at 2.6 f_c with 0.1 ms
(five wave transits; its peak came after 35 ms, so the pressure lagged the stress by 0.3 %).  The
load's work is exact for a force constant over a step: each step adds p Σ_i u_i·(x_i − x_i,prev), u_i the particle's
resultant per unit pressure, which needs one number per entry (Q = Σ u_i·x_i) as history; it is part of
'external_work'.  On several MPI ranks each rank loads and measures its own particles and the reference stress is
the sum over the ranks (the evaluation's reduction).
"""

from __future__ import annotations

from collections import namedtuple

import numpy as np

from ...errors import NOVALUE, ScenarioError
from ...jit import loop_njit
from ...params import ArrayOf, Param, Table
from ..protocol import Family, register_hooks
from ..ranks import Entries, Owned

#: per entry k: idx[start[k]:start[k+1]] its loaded particles with u their resultants per unit pressure (m, 3);
#: ref[rstart[k]:rstart[k+1]] the reference set's particles, nref (K, 2) its outward normal, area (K,) its A_ref;
#: ratio (K,); red / tot (K,): this process's part of Σ −F·n_ref over the reference set and its sum over the ranks
#: (one array in a serial run); st (K, 6): p, σ_ref, f1, f2, work of the last step, Q at the last accepted state;
#: hist (K, 4): work so far, Q, the filtered followed stress, the followed reaction of the last accepted evaluation
#: (checkpointed); acc (1,): marks the family active (an inert bundle's has length 0)
Proportional = namedtuple(
    "Proportional",
    ["idx", "start", "u", "ref", "rstart", "nref", "area", "ratio", "tau", "red", "tot", "st", "hist", "acc"],
)
S_P, S_SIG, S_F1, S_F2, S_DW, S_Q = 0, 1, 2, 3, 4, 5
A_WORK, A_Q, A_SIG, A_REF = 0, 1, 2, 3
#: history columns per entry: (suffix, unit, what)
COLUMN_KINDS = (
    ("p", "dyn/cm^2", "pressure applied (positive inwards)"),
    ("sigma_ref", "dyn/cm^2", "stress on the reference face it follows (tension positive)"),
    ("f1", "dyn", "force e1 it applies"),
    ("f2", "dyn", "force e2 it applies"),
    ("work", "erg", "its work so far (part of 'external_work')"),
)


@loop_njit
def _pass(fam, final, x, v, dt, F):
    """The pressure from the reference stress of the last final evaluation, on the loaded particles; at the final
    pass also this evaluation's reaction of the reference set (after every family before it has added its forces)."""
    for k in range(fam.ratio.shape[0]):
        # the followed stress through a first-order filter of time constant tau (none: tau = 0)
        w = 1.0 if fam.tau[k] <= 0.0 else min(1.0, dt / fam.tau[k])
        sig = fam.hist[k, A_SIG] + (fam.hist[k, A_REF] / fam.area[k] - fam.hist[k, A_SIG]) * w
        p = -fam.ratio[k] * sig
        f1 = f2 = q = 0.0
        for j in range(fam.start[k], fam.start[k + 1]):
            i = fam.idx[j]
            F[i, 0] += p * fam.u[j, 0]
            F[i, 1] += p * fam.u[j, 1]
            F[i, 2] += p * fam.u[j, 2]
            f1 += p * fam.u[j, 0]
            f2 += p * fam.u[j, 1]
            q += fam.u[j, 0] * x[i, 0] + fam.u[j, 1] * x[i, 1] + fam.u[j, 2] * x[i, 2]
        if final:
            r = 0.0
            for j in range(fam.rstart[k], fam.rstart[k + 1]):
                i = fam.ref[j]
                r -= F[i, 0] * fam.nref[k, 0] + F[i, 1] * fam.nref[k, 1]
            fam.red[k] = r
            fam.st[k, S_P] = p
            fam.st[k, S_SIG] = sig
            fam.st[k, S_F1] = f1
            fam.st[k, S_F2] = f2
            fam.st[k, S_DW] = p * (q - fam.hist[k, A_Q])
            fam.st[k, S_Q] = q
    return 0


@loop_njit
def _accept(fam):
    """The initial state (and every accepted step): its Q is where the next step's work counts from."""
    for k in range(fam.ratio.shape[0]):
        fam.hist[k, A_Q] = fam.st[k, S_Q]
        fam.hist[k, A_SIG] = fam.st[k, S_SIG]
        # the followed reaction: this accepted evaluation's (summed over the ranks); a step repeated for room (GROW)
        # is not accepted, so it starts again from the same one
        fam.hist[k, A_REF] = fam.tot[k]


@loop_njit
def _work(fam):
    w = 0.0
    for k in range(fam.ratio.shape[0]):
        w += fam.st[k, S_DW]
        fam.hist[k, A_WORK] += fam.st[k, S_DW]
        fam.st[k, S_DW] = 0.0
    return w


@loop_njit
def _row(fam, row, off):
    for k in range(fam.ratio.shape[0]):
        row[off] = fam.st[k, S_P]
        row[off + 1] = fam.st[k, S_SIG]
        row[off + 2] = fam.st[k, S_F1]
        row[off + 3] = fam.st[k, S_F2]
        row[off + 4] = fam.hist[k, A_WORK]
        off += 5
    return off


register_hooks(Proportional, pass_=_pass, accept=_accept, work=_work, row=_row)

PROPORTIONAL = Table(
    {
        "set": Param("str", doc="the particles whose exposed edges carry the pressure (e.g. 'specimen.left')"),
        "ratio": Param(
            "float",
            min=-1.0,
            max=1.0,
            doc="alpha = sigma_2 / sigma_1: the pressure is -alpha times the reference face's stress (tension "
            "positive), so 0.5 with the reference in compression pushes in with half its stress, -0.1 pulls with a "
            "tenth of it (tension-compression), 1 with the reference in tension pulls as hard (tension-tension)",
        ),
        "reference": Param(
            "str",
            doc="the driven set whose stress the pressure follows (e.g. 'specimen.top'): its reaction over the area "
            "of its exposed edges facing 'reference_normal'",
        ),
        "reference_normal": Param(
            "vec2",
            default=None,
            doc="outward normal of the reference face; default: the side its name says ('<group>.top' -> [0, 1], ...)",
        ),
        "filter_time": Param(
            "float",
            unit="s",
            default=0.0,
            min=0.0,
            doc="the followed stress passes a first-order filter of this time constant (0: none); a pressure that "
            "follows the unfiltered reaction of a driven face takes up its wave reflections",
        ),
        "normal": Param(
            "vec2",
            default=None,
            doc="load only the exposed edges of the set whose outward normal lies within 60 degrees of this; default: "
            "the side the set's name says, every exposed edge otherwise",
        ),
    },
    doc="A pressure that follows the stress on another (driven) face at a fixed ratio: proportional biaxial loading "
    "(Kupfer's tests; interactions/controllers/proportional.py).  It uses the reference stress of the previous step.",
)

#: the outward normal a set's name implies
SIDE_NORMALS = {"left": (-1.0, 0.0), "right": (1.0, 0.0), "top": (0.0, 1.0), "bottom": (0.0, -1.0)}


def _side(name, given, file, key):
    if given is not None:
        n = np.asarray(given, float)
        if not np.any(n):
            raise ScenarioError(file, key, given, "must not be the zero vector")
        return n / np.hypot(*n)
    side = name.rsplit(".", 1)[-1] if "." in name else None
    return None if side not in SIDE_NORMALS else np.asarray(SIDE_NORMALS[side], float)


def _faces(ctx, sel, normal, thickness):
    """Per particle of ``sel``: its resultant per unit pressure on its exposed edges within 60° of ``normal`` (all
    with None), (f1, f2, moment about its centroid), and the loaded length."""
    from ...geometry.polygon import exposed_edges, polygon_area_centroid_inertia

    verts, groups = ctx["verts"], np.asarray(ctx["group"], np.int64)
    per = exposed_edges(verts, sel, np.flatnonzero(np.isin(groups, np.unique(groups[sel]))))
    u, length = np.zeros((len(sel), 3)), 0.0
    for j, (i, edges) in enumerate(zip(sel, per)):
        c = polygon_area_centroid_inertia(np.asarray(verts[i], float))[1]
        for L, nv, m in edges:
            if normal is not None and nv @ normal < 0.5:
                continue
            f = -thickness[i] * L * nv
            u[j, :2] += f
            u[j, 2] += (m[0] - c[0]) * f[1] - (m[1] - c[1]) * f[0]
            length += L * thickness[i]
    return u, length


class ProportionalPressure(Family):
    name = "proportional_pressure"
    tables = {"proportional_pressure": ArrayOf(PROPORTIONAL, doc=PROPORTIONAL.doc, required=False)}

    def build(self, sc, ctx):
        """Per entry: the loaded particles and their unit-pressure resultants, the reference set, its normal and
        area; ScenarioError for a set with no exposed edge that way, a reference without a normal."""
        entries = sc.get("proportional_pressure") or []
        if not entries:
            return None
        file, T = ctx["file"], np.asarray(ctx["thickness"], float)
        out = {"sets": [], "idx": [], "u": [], "ref": [], "nref": [], "area": [], "ratio": [], "tau": []}
        for k, e in enumerate(entries):
            key = f"proportional_pressure[{k}]"
            sel = np.asarray(ctx["select"]({"set": e["set"], "at": None}, f"{key}.set"), np.int64)
            ref = np.asarray(ctx["select"]({"set": e["reference"], "at": None}, f"{key}.reference"), np.int64)
            n_load = _side(e["set"], e["normal"], file, f"{key}.normal")
            n_ref = _side(e["reference"], e["reference_normal"], file, f"{key}.reference_normal")
            if n_ref is None:
                raise ScenarioError(
                    file, f"{key}.reference_normal", NOVALUE, "give the reference face's outward normal for this set"
                )
            u, length = _faces(ctx, sel, n_load, T)
            if length <= 0.0:
                raise ScenarioError(file, f"{key}.set", e["set"], "no exposed edge of this set to carry the pressure")
            _, area = _faces(ctx, ref, n_ref, T)
            if area <= 0.0:
                raise ScenarioError(
                    file, f"{key}.reference", e["reference"], f"no exposed edge of this set faces {list(n_ref)}"
                )
            for name, val in (("sets", (e["set"], e["reference"])), ("idx", sel), ("u", u), ("ref", ref)):
                out[name].append(val)
            out["nref"].append(n_ref)
            out["area"].append(area)
            out["ratio"].append(float(e["ratio"]))
            out["tau"].append(float(e["filter_time"]))
        return out

    def uses(self, system):
        return self.data(system) is not None

    def columns_of(self, system):
        d = self.data(system)
        if d is None:
            return ()
        return tuple(
            (f"pp{k}_{c}:{s}", unit, f"{what} ([[proportional_pressure]] entry {k} on set '{s}', following '{r}')")
            for k, (s, r) in enumerate(d["sets"])
            for c, unit, what in COLUMN_KINDS
        )

    def bundle(self, system, built=None):
        d = self.data(system)
        K = len(d["ratio"])
        start = np.concatenate([[0], np.cumsum([len(i) for i in d["idx"]])]).astype(np.int64)
        rstart = np.concatenate([[0], np.cumsum([len(i) for i in d["ref"]])]).astype(np.int64)
        red = np.zeros(K)
        return Proportional(
            np.concatenate(d["idx"]).astype(np.int64),
            start,
            np.concatenate(d["u"]).reshape(-1, 3),
            np.concatenate(d["ref"]).astype(np.int64),
            rstart,
            np.asarray(d["nref"], float).reshape(K, 2),
            np.asarray(d["area"], float),
            np.asarray(d["ratio"], float),
            np.asarray(d["tau"], float),
            red,
            red,  # serial: the sum over the ranks is this process's part (attach gives a rank its own)
            np.zeros((K, 6)),
            np.zeros((K, 4)),
            np.ones(1),
        )

    def inert_bundle(self, system, built=None):
        zi, z = np.zeros(0, np.int64), np.zeros(0)
        return Proportional(
            zi, np.zeros(1, np.int64), np.zeros((0, 3)), zi, np.zeros(1, np.int64), np.zeros((0, 2)), z, z, z, z, z,
            np.zeros((0, 6)), np.zeros((0, 4)), z,
        )  # fmt: skip

    def state_layout(self, system):
        """Work and Q summed over the ranks (each its own particles), rank 0 keeping them; the reference reaction and
        the filtered stress the same on every rank.  (Q then counts on rank 0 the particles every rank has: its next
        step's work is p (Q_now − Q) summed over the ranks, the same as one process's.)"""
        return ((("proportional_hist",), Entries(sums=(A_WORK, A_Q))),)

    def state(self, b):
        return {"proportional_hist": b.hist.copy()}

    def restore(self, b, st, system=None):
        b.hist[:] = st["proportional_hist"]

    def observables(self, b):
        return {"proportional_work": float(b.hist[:, A_WORK].sum())}

    # ---- a decomposed run: each rank loads and measures its own particles; the reference reaction is summed
    def data_layout(self, data):
        """Each entry's loaded particles (with their loads' directions) and reference particles that the rank owns,
        renumbered."""
        return ((("idx", "u"), Owned()), (("ref",), Owned()))

    def rank_sums(self, system):
        """The reference sets' reactions, one sum per entry, read by the family itself."""
        return np.full((len(self.data(system)["ratio"]), 2), -1, np.int64)

    def attach(self, bundle, mpi, sums):
        return bundle._replace(red=sums.local, tot=sums.total)

    def column_reductions(self, system):
        return ("same", "same", "sum", "sum", "sum") * len(self.data(system)["ratio"])


PROPORTIONAL_PRESSURE = ProportionalPressure()
