"""The applied loads of ``[[loads]]`` in the history table, as an observing family (it adds no force).

The loads themselves act through f_ext of the time loop (thesis (3.4); scenario/build.py turns forces, moments and
pressures into each particle's dead load, fixed at t0, raised over ``ramp_time`` in blocks of
:data:`~polydem_cli.boundary.prescribed.RAMP_BLOCK` steps).  The reactions of a set (``f1:<set>``) are the
interaction forces on it, ≈ 0 for a set a load holds in equilibrium, so the load itself could not be read from a
result (issue 51).  This family records, per ``[[loads]]`` entry k on set s, the load it applies and the work it has
done:

    f(t) = r(t) Σ_i f_i,        W(t) = ∫₀ᵗ r f·v dt' = Σ_i r(t) f_i·(x_i(t) − x_i(0)) − S(t),

f_i = (f_1, f_2, c) the entry's full load on particle i (a pressure's resultant on its loaded edges and that
resultant's moment about the centroid), r(t) its ramp fraction (1 without a ramp), x_i = (x_1, x_2, φ).  Between two
changes of r the load is constant, so its work is exact along the path: each change Δr at a state x_b adds
Δr Σ f_i·(x_i(t_b) − x_i(0)) to S, the only history (one number per entry).  The columns sum to the loads' part of
``external_work`` (which integrates the power f_ext·v by the trapezoidal rule: the same to the integrator's error).
On several MPI ranks each rank sums the particles it owns; the columns add up over the ranks.
"""

from __future__ import annotations

from collections import namedtuple

import numpy as np

from ...boundary.prescribed import ramp_fraction
from ...jit import loop_njit
from ..protocol import Family, register_hooks
from ..ranks import Owned, Summed

#: idx: the loaded particles of every entry, entry k's at idx[start[k]:start[k+1]]; f: their full loads (m, 3);
#: x0: their positions at t0 (m, 3); ramped: 1.0 for an entry raised over the ramp time; par: [dt, ramp_time];
#: r: [ramp fraction of the step being computed, of the next step]; s: S per entry; ds: the step's change of S;
#: vals: (K, 4) per entry its f1, f2, c and W at the last final pass (the history row's); acc: (1,) marks the
#: family active (an inert bundle has none)
AppliedLoads = namedtuple("AppliedLoads", ["idx", "start", "f", "x0", "ramped", "par", "r", "s", "ds", "vals", "acc"])
#: columns per entry: e1 and e2 force, moment, work
COLUMN_KINDS = (
    ("f1", "dyn", "applied force e1"),
    ("f2", "dyn", "applied force e2"),
    ("c", "dyn cm", "applied moment (about each particle's centroid; a pressure's resultant's moment included)"),
    ("work", "erg", "work done so far (part of 'external_work')"),
)


@loop_njit
def _begin(fam, step, t):
    """Step ``step`` (the initial state: 0) begins: the ramp fractions of its load (that of the block the step
    before it lies in, as engine/simulation.py sets f_ext) and of the next step's."""
    fam.r[0] = ramp_fraction(max(step - 1, 0), fam.par[0], fam.par[1])
    fam.r[1] = ramp_fraction(step, fam.par[0], fam.par[1])


@loop_njit
def _pass(fam, final, x, v, dt, F):
    """At the final pass: each entry's load and work at this state, and the change of S if the ramp fraction changes
    after this step (the module's equations)."""
    if not final:
        return 0
    for k in range(fam.start.shape[0] - 1):
        f1 = f2 = c = path = 0.0
        for q in range(fam.start[k], fam.start[k + 1]):
            i = fam.idx[q]
            f1 += fam.f[q, 0]
            f2 += fam.f[q, 1]
            c += fam.f[q, 2]
            for d in range(3):
                path += fam.f[q, d] * (x[i, d] - fam.x0[q, d])
        r = fam.r[0] if fam.ramped[k] != 0.0 else 1.0
        fam.vals[k, 0] = r * f1
        fam.vals[k, 1] = r * f2
        fam.vals[k, 2] = r * c
        fam.vals[k, 3] = r * path - fam.s[k]
        fam.ds[k] = (fam.r[1] - fam.r[0]) * path if fam.ramped[k] != 0.0 else 0.0
    return 0


@loop_njit
def _accumulate(fam):
    for k in range(fam.s.shape[0]):
        fam.s[k] += fam.ds[k]
        fam.ds[k] = 0.0
    return 0.0


@loop_njit
def _row(fam, row, off):
    for k in range(fam.vals.shape[0]):
        for c in range(4):
            row[off + 4 * k + c] = fam.vals[k, c]
    return off + 4 * fam.vals.shape[0]


register_hooks(AppliedLoads, pass_=_pass, begin=_begin, accumulate=_accumulate, row=_row)


class AppliedLoadsFamily(Family):
    """The ``[[loads]]`` entries' load and work in the history table (the module's docstring)."""

    name = "applied_loads"

    def build(self, sc, ctx):
        """Per ``[[loads]]`` entry: its set's name, particles, their full loads and x0, and whether it is ramped (from
        scenario/build.py's ``loads``, the same numbers f_ext is made of); None without loads."""
        loads = ctx.get("loads") or {}
        entries = loads.get("entries") or []
        if not entries:
            return None
        x0 = np.asarray(ctx["x0"], float)
        return {
            "sets": [e["set"] for e in entries],
            "idx": [np.asarray(e["idx"], np.int64) for e in entries],
            "f": [np.asarray(e["f"], float).reshape(-1, 3) for e in entries],
            "x0": [x0[np.asarray(e["idx"], np.int64)] for e in entries],
            "ramped": [bool(e["ramped"]) for e in entries],
            "dt": float(ctx["dt"]),
            "ramp_time": float(loads["ramp_time"]),
        }

    def uses(self, system):
        return self.data(system) is not None

    def columns_of(self, system):
        d = self.data(system)
        if d is None:
            return ()
        return tuple(
            (f"load{k}_{c}:{s}", unit, f"{what} of [[loads]] entry {k} on set '{s}', summed over its particles")
            for k, s in enumerate(d["sets"])
            for c, unit, what in COLUMN_KINDS
        )

    def bundle(self, system, built=None):
        d = self.data(system)
        K = len(d["sets"])
        start = np.concatenate([[0], np.cumsum([len(i) for i in d["idx"]])]).astype(np.int64)
        cat = lambda a, w: np.concatenate(a) if a else np.zeros((0, w))  # noqa: E731
        return AppliedLoads(
            np.concatenate(d["idx"]).astype(np.int64) if K else np.zeros(0, np.int64),
            start,
            cat(d["f"], 3).reshape(-1, 3),
            cat(d["x0"], 3).reshape(-1, 3),
            np.array([1.0 if r else 0.0 for r in d["ramped"]]),
            np.array([d["dt"], d["ramp_time"]]),
            np.zeros(2),
            np.zeros(K),
            np.zeros(K),
            np.zeros((K, 4)),
            np.zeros(1),
        )

    def inert_bundle(self, system, built=None):
        z = np.zeros(0)
        return AppliedLoads(
            np.zeros(0, np.int64), np.zeros(1, np.int64), np.zeros((0, 3)), np.zeros((0, 3)), z, np.zeros(2),
            np.zeros(2), z, z, np.zeros((0, 4)), z,
        )  # fmt: skip

    def state_layout(self, system):
        """S: each rank's sum over the particles it owns."""
        return ((("loads_s",), Summed()),)

    def state(self, b):
        return {"loads_s": b.s.copy()}

    def restore(self, b, st, system=None):
        b.s[:] = st["loads_s"]

    # ---- a decomposed run: each rank sums the particles it owns; S summed over the ranks, kept on rank 0
    def data_layout(self, data):
        """Each entry's particles that the rank owns, renumbered, with their forces and initial positions."""
        return ((("idx", "f", "x0"), Owned()),)


APPLIED_LOADS = AppliedLoadsFamily()
