"""Engine state and the Python side of the fixed driver loop.

:class:`Simulation` owns the struct-of-arrays state of a :class:`System` —
the Nordsieck arrays (n, 3, 6), the contact history, energy accumulators —
and advances it with the compiled :func:`~polydem_cli.engine.kernels.run_steps`.
It knows nothing about files: the explicit solver family (:mod:`polydem_cli.solvers.explicit`), run by the
driver, adds output, checkpoints and progress on top.
"""

from __future__ import annotations

import numpy as np

from ..boundary.prescribed import RAMP_BLOCK, ramp_fraction
from ..errors import EngineError  # noqa: F401 (re-exported: the engine raises it)
from . import kernels as K
from .families import compose, family, slot
from .integrators import ORDER_WIDTH

#: most steps per call of the compiled loop (see Simulation.advance)
STEPS_PER_CALL = 1024


#: what a rank of a decomposed run says when it stopped because another rank saw why (engine/distributed.py picks the
#: message of the rank that saw it)
OTHER_RANK = "on another rank or in a sum over the ranks"
STOPPED = "the run was stopped"


class Simulation:
    def __init__(self, system):
        s = system
        self.system = s
        n = s.n
        self.n = n
        self.dt = s.dt
        self.kind = s.integrator
        self.nord = np.zeros((n, 3, 6))
        self.nord_pd = np.zeros((n, 3, 6))
        self.nord_new = np.zeros((n, 3, 6))
        self.x = np.zeros((n, 3))
        self.v = np.zeros((n, 3))
        self.F = np.zeros((n, 3))
        self.acc = np.zeros(K.N_ACC)
        self.info = np.zeros(4, np.int64)
        #: a rank's part: the whole scene's critical time step estimate (engine/stability.py ``estimate``: what an
        #: instability message quotes)
        self.critical = None
        self.step = 0
        self.P = K.Particles(s.mass, s.inertia, np.ones(n) if s.own is None else np.asarray(s.own, float))
        self.bc = K.Boundary(s.bc_kind, s.bc_vel, s.bc_acc, s.x0)
        self.gravity = np.asarray(s.gravity, float)
        # f_ext: the full loads, plus the ramped ones at their present fraction (set_external_loads)
        self.ext_full = np.asarray(s.ext, float)
        self.ext_ramp = None if s.ext_ramp is None else np.asarray(s.ext_ramp, float)
        self.ext = self.ext_full.copy()
        # the interaction families composed for this scene (interactions/protocol.py)
        self.families, self.fams = compose(s)
        starts, idx = [0], []
        for name in s.monitored:
            ii = s.sets[name]
            idx.extend(int(i) for i in ii)
            starts.append(len(idx))
        cnt = [s.set_counts.get(name, len(s.sets[name])) for name in s.monitored]
        self.mon = K.Monitor(np.asarray(starts, np.int64), np.asarray(idx, np.int64), np.asarray(cnt, np.int64))
        self.ended = False
        self.paused = False  # the loop paused after a committed step (never in a serial run)
        self.ncols = K.N_BASE + sum(len(f.columns_of(s)) for f in self.families) + K.N_SET * len(s.monitored)

    def set_external_loads(self) -> int:
        """f_ext at the present step (``System.ext_ramp``): the ramped loads at min(1, t_k / ramp_time), t_k the
        start of the step's block of :data:`RAMP_BLOCK` steps; returns the step up to which this value holds."""
        if self.ext_ramp is None:
            return 1 << 62
        k0 = (self.step // RAMP_BLOCK) * RAMP_BLOCK
        f = ramp_fraction(self.step, self.dt, self.system.ramp_time)
        np.add(self.ext_full, f * self.ext_ramp, out=self.ext)
        return (1 << 62) if f >= 1.0 else k0 + RAMP_BLOCK

    def family_bundles(self) -> list:
        """(family, its bundle) of the families the scene uses."""
        return [(f, self.fams[slot(f)]) for f in self.families]

    def family_reports(self, limits: dict) -> dict:
        """What the families say of the present state, for the checks between chunks of the loop: ``check``, the
        first reason the run has gone unstable (``Family.check`` with the scenario's [stability] ``limits``) or
        None; ``warnings``, {family name: its warning} (``Family.warning``); ``end``, the first end criterion's
        progress (``Family.end_progress``) or None.  Of this engine's own part of the scene (on a rank of a
        decomposed run, its part: engine/distributed.py combines the ranks' reports)."""
        out = {"check": None, "warnings": {}, "end": None}
        for f, b in self.family_bundles():
            if out["check"] is None:
                out["check"] = f.check(self.system, b, limits)
            w = f.warning(self.system, b)
            if w:
                out["warnings"][f.name] = w
            if out["end"] is None:
                out["end"] = f.end_progress(self.system, b)
        return out

    def bundle(self, name):
        """The bundle of the family called ``name`` (an inert one if the scene does not use it)."""
        return self.fams[slot(family(name))]

    def _grow_families(self):
        """Let the family that ran out of room enlarge its bundle."""
        fams, grown = list(self.fams), False
        for f in self.families:
            k = slot(f)
            nb = f.grow(self.system, fams[k])
            if nb is not None:
                fams[k], grown = nb, True
        if not grown:  # pragma: no cover - a pass asked for room no family gives
            raise RuntimeError("the compiled loop asked for more room, but no interaction family grew")
        self.fams = tuple(fams)

    # ------------------------------------------------------------------ set-up
    def initialize(self):
        """Initial Nordsieck vectors (3.13) with ẍ0 = f(x0, ẋ0)/m, and diagnostics at t0."""
        s = self.system
        self.nord[:] = 0.0
        self.nord[:, :, 0] = s.x0
        self.nord[:, :, 1] = s.v0 * self.dt
        self.step = 0
        self.acc[:] = 0.0
        self.set_external_loads()
        rows = np.empty((1, self.ncols))  # none written (rec_every 0): the writer records t0 (current_row)
        while True:  # "step 0" of the loop: the initial state (kernels.one_step)
            st = K.run_steps(
                self.kind,
                -1,
                0,
                self.dt,
                self.nord,
                self.nord_pd,
                self.nord_new,
                self.x,
                self.v,
                self.F,
                self.P,
                self.bc,
                self.gravity,
                self.acc,
                self.mon,
                0,
                rows,
                self.info,
                self.ext,
                self.fams,
            )
            if st == K.NONFINITE:  # a decomposed run: a non-finite force at t0 (kernels.py evaluate)
                i = int(self.info[2])
                who = f"of particle {s.number(i)}" if i >= 0 else OTHER_RANK
                raise EngineError(f"non-finite force {who} at t = 0")
            if st == K.OK:
                break
            if st != K.GROW:  # pragma: no cover - step 0 returns nothing else
                raise RuntimeError(f"the initial state returned status {st}")
            self._grow_families()
        self.step = 0
        if ORDER_WIDTH[self.kind] < 6:
            self.nord[:, :, ORDER_WIDTH[self.kind] :] = 0.0
        self.x[:] = self.nord[:, :, 0]
        self.v[:] = self.nord[:, :, 1] / self.dt

    def check_initial_overlap(self):
        """Refuse an impossible initial state (e.g. particles overlapping at t0 unless the scenario allows it)."""
        for f, b in self.family_bundles():
            f.check_initial(self.system, b)

    def current_row(self) -> np.ndarray:
        """A history row of the present state (whatever the cadence): the first row at t0, the
        stability checks and the final state of the summary."""
        row = np.zeros(self.ncols)
        K.record_row(
            row,
            self.step * self.dt,
            self.step,
            self.x,
            self.v,
            self.F,
            self.P,
            self.bc,
            self.gravity,
            self.acc,
            self.mon,
            self.fams,
        )
        return row

    # ------------------------------------------------------------------ stepping
    def advance(self, step_stop: int, rows: np.ndarray, rec_every: int) -> int:
        """Advance to ``step_stop`` or until ``rows`` is full; return the number of rows written.

        The compiled loop is entered for at most :data:`STEPS_PER_CALL` steps at a time: with interaction
        families composed into it, each step of one call leaves about a kilobyte per family on the
        thread's stack (the unrolled family tuple; measured with the disk family: a 2-disk scene ran
        out of an 8 MiB stack after about 5,500 steps in one call), so a long call would crash."""
        total = 0
        while True:
            stop = min(step_stop, self.step + STEPS_PER_CALL)
            total += self._advance(stop, rows[total:], rec_every)
            if self.step >= step_stop or self.ended or self.paused or total >= rows.shape[0]:
                return total

    def _advance(self, step_stop: int, rows: np.ndarray, rec_every: int) -> int:
        s = self.system
        while True:
            step_stop = min(step_stop, self.set_external_loads())
            st = K.run_steps(
                self.kind,
                self.step,
                step_stop,
                self.dt,
                self.nord,
                self.nord_pd,
                self.nord_new,
                self.x,
                self.v,
                self.F,
                self.P,
                self.bc,
                self.gravity,
                self.acc,
                self.mon,
                rec_every,
                rows,
                self.info,
                self.ext,
                self.fams,
            )
            done_step, nrows = int(self.info[0]), int(self.info[1])
            self.step = done_step
            if st == K.ENDED:
                self.ended = True
                return nrows
            if st == K.PAUSED:  # a decomposed run's halo: particles to redistribute (engine/distributed.py)
                self.paused = True
                return nrows
            if st == K.GROW:
                if nrows:
                    return nrows  # hand the rows over first; the step is repeated next call
                self._grow_families()
                continue
            if st == K.NONFINITE:
                from .stability import describe, estimate

                i = int(self.info[2])
                what = "force" if self.info[3] else "position or velocity"  # ranks agree on the forces (kernels.py)
                who = f"of particle {s.number(i)} ({s.group_names[s.group[i]]})" if i >= 0 else OTHER_RANK
                crit = self.critical if self.critical is not None else estimate(s)  # of the whole scene
                raise EngineError(
                    f"non-finite {what} {who} at step {done_step + 1}, "
                    f"t = {(done_step + 1) * self.dt:.6g} s: the run is unstable; {describe(crit, self.dt)}"
                )
            if st == K.DIVERGED:
                raise RuntimeError(
                    f"the corrected state of particle {s.number(int(self.info[2]))} is not finite at step "
                    f"{done_step + 1} though every rank's forces were: an overflow the other ranks cannot know of"
                )
            if st == K.ABORTED:
                for f, b in self.family_bundles():
                    msg = f.halt_message(s, b, done_step + 1)
                    if msg:
                        raise EngineError(msg)
                raise EngineError(f"{STOPPED} at step {done_step + 1}")  # another rank's family says why
            return nrows

    @property
    def time(self) -> float:
        return self.step * self.dt

    def positions(self) -> np.ndarray:
        return self.nord[:, :, 0].copy()

    def velocities(self) -> np.ndarray:
        return self.nord[:, :, 1] / self.dt

    def frame_fields(self):
        """(positions, velocities, the families' frame fields ``Family.frame``) for an output frame."""
        x = self.positions()
        fields = {}
        for f, b in self.family_bundles():
            fields.update(f.frame(self.system, b, x))
        return x, self.velocities(), fields

    # ------------------------------------------------------------------ checkpoint
    def state(self) -> dict:
        return {
            "step": np.array([self.step], np.int64),
            "ended": np.array([int(self.ended)], np.int64),
            "nord": self.nord.copy(),
            "acc": self.acc.copy(),
            **{k: v for f, b in self.family_bundles() for k, v in f.state(b).items()},
        }

    def restore(self, st: dict):
        s = self.system
        self.step = int(st["step"][0])
        self.ended = bool(st.get("ended", np.array([0]))[0])
        self.nord[:] = st["nord"]
        self.acc[:] = st["acc"]
        fams = list(self.fams)
        for f in self.families:
            k = slot(f)
            nb = f.restore(fams[k], st, system=s)
            if nb is not None:
                fams[k] = nb
        self.fams = tuple(fams)
        self.x[:] = self.nord[:, :, 0]
        self.v[:] = self.nord[:, :, 1] / self.dt
        self.set_external_loads()
