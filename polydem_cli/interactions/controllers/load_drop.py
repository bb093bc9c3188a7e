"""The load-drop stop (``time.end_load_drop``, open point O-9) as a controller family.

It adds no force.  Registered last (engine/families.py), its final pass sees the generalised forces of every
family at the corrected state and takes the load of the set, ``|f2| = |−Σ F_2|`` over its particles (the
thesis's reaction convention); its ``halt`` hook keeps the running peak from the step the set's motion has
finished ramping up on (``arm``) and ends the run once the load has fallen below ``fraction`` × the peak and stayed
there for ``hold`` steps (``time.end_load_drop_hold``; 0: at the first step below).
"""

from __future__ import annotations

import math
from collections import namedtuple
from dataclasses import dataclass

import numpy as np

from ...boundary.prescribed import RAMP, motion_of
from ...jit import loop_njit
from ..protocol import GO_ON, HALT_END, Family, register_hooks
from ..ranks import Same

#: idx: particles of the set (a rank's own ones in a decomposed run); fraction; arm: first step counted; red/tot (1):
#: this process's part of the set's load and its sum over the ranks (the evaluation's reduction, engine/halo.py
#: ``settle``; one array in a serial run, where the part is the whole); ledger/more: that
#: reduction's totals and those of them added to the x2 force of a particle of the set after the passes (a wall's
#: force from the disks of every rank), which the pass did not see; acc: ACC_*
#: hold: steps the load must stay below the fraction before the run ends (0: none)
LoadDrop = namedtuple("LoadDrop", ["idx", "fraction", "arm", "red", "tot", "ledger", "more", "acc", "hold"])
ACC_PEAK = 0  # running peak of |f2| on the set, dyn
ACC_F2 = 1  # |f2| at the last final pass
ACC_STEP = 2  # the step being computed
ACC_ENDED = 3  # 1 once the criterion was met
ACC_BELOW = 4  # the first step of the present stretch below the fraction, −1 while above it
N_ACC = 5


@loop_njit
def _begin(fam, step, t):
    fam.acc[ACC_STEP] = step


@loop_njit
def _pass(fam, final, x, v, dt, F):
    if final:
        f2 = 0.0
        for q in range(fam.idx.shape[0]):
            f2 -= F[fam.idx[q], 1]
        fam.red[0] = f2  # this process's part (a decomposed run sums it over the ranks with the evaluation)
        fam.acc[ACC_F2] = abs(f2)
    return 0


@loop_njit
def _halt(fam):
    a = fam.acc
    # the set's load over every rank (a serial run: tot is red), summed at the end of the final evaluation (halt
    # runs once, after it), so all ranks take the same decision; with the sums added to its F entries after the
    # passes (none in a serial run)
    f2 = fam.tot[0]
    for k in fam.more:
        f2 -= fam.ledger[k]
    a[ACC_F2] = abs(f2)
    if a[ACC_STEP] < fam.arm:
        return GO_ON
    f2 = a[ACC_F2]
    if f2 > a[ACC_PEAK]:
        a[ACC_PEAK] = f2
    if a[ACC_PEAK] > 0.0 and f2 < fam.fraction * a[ACC_PEAK]:
        if a[ACC_BELOW] < 0.0:
            a[ACC_BELOW] = a[ACC_STEP]
        if a[ACC_STEP] - a[ACC_BELOW] >= fam.hold:
            a[ACC_ENDED] = 1.0
            return HALT_END
    else:
        a[ACC_BELOW] = -1.0
    return GO_ON


register_hooks(LoadDrop, pass_=_pass, begin=_begin, halt=_halt)


def _fresh_acc():
    a = np.zeros(N_ACC)
    a[ACC_BELOW] = -1.0
    return a


@dataclass
class LoadDropSetup:
    """``time.end_load_drop`` resolved: stop once |f2| of ``set`` < ``fraction`` × its peak for ``hold_steps``
    steps, counting from ``arm_step`` (the step the set's motion has finished ramping up on)."""

    fraction: float
    set: str
    arm_step: int
    hold_steps: int = 0


class LoadDropFamily(Family):
    name = "load_drop"

    def build(self, sc, ctx):
        """The stop of ``time.end_load_drop`` on the set of the boundary entry that drives the run, or None."""
        frac = sc["time"]["end_load_drop"]
        if frac is None:
            return None
        b = sc["boundary"][ctx["drive"]]  # a driving entry exists: scenario/build.py refuses end_load_drop without
        ramps = [motion_of(b[dof]) for dof in ("x1", "x2", "phi")]
        arm = max([int(math.ceil(v / a / ctx["dt"])) for k, v, a in ramps if k == RAMP] or [0])
        hold = int(math.ceil(sc["time"].get("end_load_drop_hold", 0.0) / ctx["dt"]))
        return LoadDropSetup(float(frac), b["set"], arm, hold)

    def uses(self, system):
        d = self.data(system)
        return d is not None and d.fraction > 0

    def bundle(self, system, built=None):
        d = self.data(system)
        return LoadDrop(
            np.asarray(system.sets[d.set], np.int64),
            d.fraction,
            d.arm_step,
            *(np.zeros(1),) * 2,  # red and tot: one array (serial; attach gives a rank its own)
            np.zeros(1),
            np.zeros(0, np.int64),
            _fresh_acc(),
            np.int64(d.hold_steps),
        )

    def inert_bundle(self, system, built=None):
        z1, zi = np.zeros(1), np.zeros(0, np.int64)
        return LoadDrop(zi, 0.0, 0, z1, z1, z1, zi, np.zeros(0), np.int64(0))

    def data_layout(self, data):
        """Nothing to cut: the set is a rank's own members (engine/distributed.py cuts the sets), the load summed over
        the ranks in the loop (:meth:`attach`)."""
        return ()

    def rank_sums(self, system):
        """The set's load, read by the halt hook."""
        return np.array([[-1, -1]], np.int64)

    def attach(self, bundle, mpi, sums):
        """The bundle of a rank of a decomposed run: the set's load summed over the ranks at every evaluation, with
        the sums the evaluation adds to the x2 forces of the set's particles after the passes (the walls' forces of the
        disks: the same entries on every rank, since every rank holds the walls)."""
        more = sums.slots(sums.held_sets[self.data(sums.system).set], 1)
        return bundle._replace(red=sums.local, tot=sums.total, ledger=sums.ledger, more=more)

    def state_layout(self, system):
        """The peak and the load are the scene's on every rank."""
        return ((("drop_acc",), Same()),)

    def state(self, b):
        return {"drop_acc": b.acc.copy()}

    def restore(self, b, st, system=None):
        """A checkpoint from before the hold (4 entries) restores with the load above the fraction."""
        old = st["drop_acc"]
        b.acc[: old.shape[0]] = old
        if old.shape[0] < N_ACC:
            b.acc[ACC_BELOW] = -1.0

    def end_reason(self, system, b):
        if b.acc[ACC_ENDED]:
            return f"the load fell below {b.fraction:g} of its peak (time.end_load_drop)"
        return None

    def end_note(self, system, b):
        """The criterion was not met before the end time: say so, with the peak."""
        return (
            f"reached before the load fell below {b.fraction:g} of its peak (time.end_load_drop was not met; "
            f"peak |f2| {b.acc[ACC_PEAK]:.4g} dyn)"
        )

    def end_progress(self, system, b):
        peak = b.acc[ACC_PEAK]
        if b.acc.shape[0] < N_ACC or peak <= 0.0:
            return None  # not armed yet
        return float(b.acc[ACC_F2] / peak), float(b.fraction), "load / its peak"

    def observables(self, b):
        return {"load_drop_peak": float(b.acc[ACC_PEAK])}


LOAD_DROP = LoadDropFamily()
