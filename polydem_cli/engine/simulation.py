"""Engine state and the Python side of the fixed driver loop.

:class:`Simulation` owns the struct-of-arrays state of a :class:`System` —
the Nordsieck arrays (n, 3, 6), the contact history, energy accumulators —
and advances it with the compiled :func:`~polydem_cli.engine.kernels.run_steps`.
It knows nothing about files: :mod:`polydem_cli.engine.runner` adds output,
checkpoints and progress on top.
"""

from __future__ import annotations

import numpy as np

from ..errors import NOVALUE, ScenarioError
from ..interactions.bonds.beam import N_BSTATS, bond_strains, new_history, new_work
from ..interactions.bonds.network import bond_links
from ..interactions.contact.kernel import N_STATS, ST_NC, ST_PAIR_A, ST_PAIR_B, ContactParams, empty_history, make_work
from . import kernels as K
from .families import compose, slot
from .integrators import ORDER_WIDTH

#: most steps per call of the compiled loop (see Simulation.advance)
STEPS_PER_CALL = 1024


class EngineError(RuntimeError):
    """A run that cannot continue (instability, containment with policy 'abort')."""


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
        self.stats = np.zeros(N_STATS)
        self.acc = np.zeros(K.N_ACC)
        self.info = np.zeros(4, np.int64)
        self.step = 0
        self.P = K.Particles(
            s.vert_start,
            s.body_v,
            s.radius,
            s.area,
            s.mass,
            s.inertia,
            s.thickness,
            s.group,
            s.is_large,
            np.flatnonzero(s.is_large).astype(np.int64),
        )
        self.bc = K.Boundary(s.bc_kind, s.bc_vel, s.bc_acc, s.x0)
        self.cp = ContactParams(
            s.kn, s.gn, s.kt, s.mu, int(s.tangential), float(s.area_tol), float(s.cell_size), float(s.contact_buffer)
        )
        self.gravity = np.asarray(s.gravity, float)
        self.bp = s.bonds.params
        self.nb = s.bonds.n
        self.has_bonds = self.nb > 0
        self.bh = new_history(self.nb)
        self.bh_save = new_history(self.nb)
        self.bw = new_work(self.nb)
        self.bstats = np.zeros(N_BSTATS)
        self.bonds = K.BondLinks(bond_links(self.bp, n), self.bp.b, self.bh.eval_active)
        self.ext = np.asarray(s.ext, float)
        # the interaction families composed for this scene (interactions/protocol.py); bonds and
        # polygon contact still have fixed places in the loop
        self.families, self.fams = compose(s)
        starts, idx = [0], []
        for name in s.monitored:
            ii = s.sets[name]
            idx.extend(int(i) for i in ii)
            starts.append(len(idx))
        self.mon = K.Monitor(np.asarray(starts, np.int64), np.asarray(idx, np.int64))
        self.drop_idx = np.asarray(s.sets[s.load_drop_set] if s.load_drop > 0 else [], np.int64)
        self.ended = False
        self.ncols = (
            K.N_BASE
            + (K.N_BOND if self.has_bonds else 0)
            + sum(len(f.columns_of(s)) for f in self.families)
            + K.N_SET * len(s.monitored)
        )
        self._alloc(max(64, 8 * n))

    # ------------------------------------------------------------------ buffers
    def _alloc(self, cap):
        s = self.system
        self.cap = int(cap)
        ncell = max(64, 4 * self.n + 64)
        self.cw = make_work(self.n, len(s.body_v), max(s.max_vertices, 3), self.cap, ncell)
        old = getattr(self, "hold", None)
        self.hold = empty_history(self.n, self.cap)
        self.hnew = empty_history(self.n, self.cap)
        if old is not None:
            m = int(old.meta[0])
            for a, b in zip(self.hold, old):
                if a.shape == b.shape:
                    a[:] = b
                else:
                    a[:m] = b[:m]

    def family_bundles(self) -> list:
        """(family, its bundle) of the families the scene uses."""
        return [(f, self.fams[slot(f)]) for f in self.families]

    def _grow_families(self) -> bool:
        """Let the family that ran out of room enlarge its bundle; False if none did."""
        fams, grown = list(self.fams), False
        for f in self.families:
            k = slot(f)
            nb = f.grow(self.system, fams[k])
            if nb is not None:
                fams[k], grown = nb, True
        self.fams = tuple(fams)
        return grown

    def _grow(self, needed):
        self._alloc(max(2 * int(needed), 2 * self.cap))

    # ------------------------------------------------------------------ set-up
    def initialize(self):
        """Initial Nordsieck vectors (3.13) with ẍ0 = f(x0, ẋ0)/m, and diagnostics at t0."""
        s = self.system
        self.nord[:] = 0.0
        self.nord[:, :, 0] = s.x0
        self.nord[:, :, 1] = s.v0 * self.dt
        self.step = 0
        self.acc[:] = 0.0
        while True:
            r = K.initial_state(
                self.kind,
                self.nord,
                self.x,
                self.v,
                self.dt,
                self.P,
                self.bc,
                self.gravity,
                s.has_contact,
                self.cp,
                self.cw,
                self.hold,
                self.hnew,
                self.bonds,
                self.F,
                self.stats,
                self.acc,
                self.has_bonds,
                self.bp,
                self.bh,
                self.bw,
                self.bstats,
                self.ext,
                self.fams,
            )
            if r >= 0:
                break
            if not self._grow_families():
                self._grow(-r)
        if ORDER_WIDTH[self.kind] < 6:
            self.nord[:, :, ORDER_WIDTH[self.kind] :] = 0.0
        self.x[:] = self.nord[:, :, 0]
        self.v[:] = self.nord[:, :, 1] / self.dt

    def check_initial_overlap(self):
        """Reject particles overlapping at t0 unless the scenario allows it."""
        s = self.system
        if not s.has_contact or s.initial_overlap_allowed or self.stats[ST_NC] == 0:
            return
        a = self.hold.a[0]
        b = self.hold.b[0]
        if self.hold.meta[0] == 0:  # tangential model 'none' keeps no list: find one pair
            a, b = int(self.stats[ST_PAIR_A]), int(self.stats[ST_PAIR_B])
        msg = (
            f"{int(self.stats[ST_NC])} particle pair(s) overlap at t0 by more than the area tolerance"
            + (
                f", e.g. particles {a} ({s.group_names[s.group[a]]}) and {b} ({s.group_names[s.group[b]]})"
                if a >= 0
                else ""
            )
            + "; move them apart or set contact.initial_overlap = \"allow\""
        )
        raise ScenarioError(s.file, "particles", NOVALUE, f"impossible geometry: {msg}")

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
            self.stats,
            self.acc,
            self.mon,
            self.has_bonds,
            self.bstats,
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
            if self.step >= step_stop or self.ended or total >= rows.shape[0]:
                return total

    def _advance(self, step_stop: int, rows: np.ndarray, rec_every: int) -> int:
        s = self.system
        while True:
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
                s.has_contact,
                self.cp,
                self.cw,
                self.hold,
                self.hnew,
                self.bonds,
                self.stats,
                self.acc,
                self.mon,
                rec_every,
                rows,
                self.info,
                s.abort_on_containment,
                self.has_bonds,
                self.bp,
                self.bh,
                self.bw,
                self.bstats,
                self.bh_save,
                self.drop_idx,
                float(s.load_drop),
                int(s.load_drop_arm_step),
                self.ext,
                self.fams,
            )
            done_step, nrows = int(self.info[0]), int(self.info[1])
            self.step = done_step
            if st == K.ENDED:
                self.ended = True
                return nrows
            if st == K.GROW:
                if nrows:
                    return nrows  # hand the rows over first; the step is repeated next call
                if not self._grow_families():
                    self._grow(int(self.info[2]))
                continue
            if st == K.NONFINITE:
                from .stability import describe, estimate

                i = int(self.info[2])
                raise EngineError(
                    f"non-finite position of particle {i} ({s.group_names[s.group[i]]}) at step {done_step + 1}, "
                    f"t = {(done_step + 1) * self.dt:.6g} s: the run is unstable; {describe(estimate(s), self.dt)}"
                )
            if st == K.CONTAINED_ABORT:
                a, b = int(self.acc[K.AC_CONT_A]), int(self.acc[K.AC_CONT_B])
                raise EngineError(
                    f"particle {min(a, b)} and {max(a, b)}: one polygon lies entirely inside the other at step "
                    f"{done_step + 1}, t = {(done_step + 1) * self.dt:.6g} s (contact.on_containment = 'abort'); "
                    f"k_n too small or dt too large"
                )
            return nrows

    @property
    def time(self) -> float:
        return self.step * self.dt

    def positions(self) -> np.ndarray:
        return self.nord[:, :, 0].copy()

    def velocities(self) -> np.ndarray:
        return self.nord[:, :, 1] / self.dt

    def bond_state(self) -> dict:
        """Per bond at the current state: damage d, κ and the mid-span strain parts (Figs. 5.8–5.11)."""
        out = np.zeros((self.nb, 4))
        if self.nb:
            bond_strains(self.nord[:, :, 0].copy(), self.bp, out)
        return {"d": self.bh.d.copy(), "kappa": self.bh.kappa.copy(), "strain": out}

    # ------------------------------------------------------------------ checkpoint
    def state(self) -> dict:
        m = int(self.hold.meta[0])
        nl = max(int(self.cw.list_meta[0]), 0)
        return {
            "pairlist_n": self.cw.list_meta.copy(),
            "pairlist_cand": self.cw.cand[:nl].copy(),
            "pairlist_xbuild": self.cw.x_build.copy(),
            "pairlist_gap": self.cw.cand_gap[:nl].copy(),
            "step": np.array([self.step], np.int64),
            "ended": np.array([int(self.ended)], np.int64),
            "nord": self.nord.copy(),
            "acc": self.acc.copy(),
            "contact_a": self.hold.a[:m].copy(),
            "contact_b": self.hold.b[:m].copy(),
            "contact_ut": self.hold.ut[:m].copy(),
            "contact_upl": self.hold.upl[:m].copy(),
            "contact_vt": self.hold.vt[:m].copy(),
            "bond_kappa": self.bh.kappa.copy(),
            "bond_d": self.bh.d.copy(),
            "bond_active": self.bh.active.copy(),
            "bond_Y": self.bh.Y.copy(),
            "bond_fail_step": self.bh.fail_step.copy(),
            "bond_fail_strain": self.bh.fail_strain.copy(),
            "bond_rate_f": self.bh.rate_f.copy(),
            **{k: v for f, b in self.family_bundles() for k, v in f.state(b).items()},
        }

    def restore(self, st: dict):
        from ..interactions.contact.kernel import _build_index

        s = self.system
        self.step = int(st["step"][0])
        self.ended = bool(st.get("ended", np.array([0]))[0])
        self.nord[:] = st["nord"]
        self.acc[:] = st["acc"]
        m = len(st["contact_a"])
        if m > self.cap:
            self._alloc(2 * m)
        h = self.hold
        h.meta[0] = m
        h.a[:m] = st["contact_a"]
        h.b[:m] = st["contact_b"]
        h.ut[:m] = st["contact_ut"]
        h.upl[:m] = st["contact_upl"]
        h.vt[:m] = st["contact_vt"]
        _build_index(h, self.n)
        if "pairlist_n" in st:  # the buffered pair list: resume with the very same list
            nl = max(int(st["pairlist_n"][0]), 0)
            if nl > self.cap:
                self._alloc(2 * nl)
            self.cw.list_meta[:] = st["pairlist_n"]
            self.cw.cand[:nl] = st["pairlist_cand"]
            xb = st["pairlist_xbuild"]
            self.cw.x_build[:, : xb.shape[1]] = xb
            if "pairlist_gap" in st:
                self.cw.cand_gap[:nl] = st["pairlist_gap"]
            else:  # a checkpoint written before pair gaps existed: check every listed pair
                self.cw.cand_gap[:nl] = 0.0
        if self.nb:
            self.bh.kappa[:] = st["bond_kappa"]
            self.bh.d[:] = st["bond_d"]
            self.bh.active[:] = st["bond_active"]
            self.bh.eval_active[:] = st["bond_active"]
            self.bh.Y[:] = st["bond_Y"]
            if "bond_rate_f" in st:
                self.bh.rate_f[:] = st["bond_rate_f"]
            if "bond_fail_step" in st:
                self.bh.fail_step[:] = st["bond_fail_step"]
                self.bh.fail_strain[:] = st["bond_fail_strain"]
            else:  # checkpoint written before failures were recorded: failed, step and mode unknown
                self.bh.fail_step[:] = np.where(self.bh.active, -1, -2)
        fams = list(self.fams)
        for f in self.families:
            k = slot(f)
            nb = f.restore(fams[k], st, acc_legacy=st["acc"], system=s)
            if nb is not None:
                fams[k] = nb
        self.fams = tuple(fams)
        self.x[:] = self.nord[:, :, 0]
        self.v[:] = self.nord[:, :, 1] / self.dt
