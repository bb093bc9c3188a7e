"""One solve at a time: the quasi-static analyses of a lattice problem (:class:`.problem.Problem`) as a stepper
that the run driver (polydem_cli/solvers/driver.py, through the quasi-static solver family) advances,
checkpoints and resumes.

Four analyses, by member law and solver:

* elastic, fully resolved — one equilibrium of the lattice at the prescribed displacement;
* elastic, adaptive — one equilibrium per refinement stage, from the coarse mesh until the strain-jump
  indicator holds (:func:`.adaptive.mark`), its marks would add fewer than ``min_gain`` of the mesh's nodes, or
  ``max_stages``;
* softening, fully resolved — sequentially linear analysis: a saw-tooth event per solve.  Each solve assembles
  the lattice with every member's present tooth stiffness and solves for the unit displacement pattern; the member
  that reaches its tooth's strength first at the smallest positive load factor (tension only) takes its next tooth
  (removed after the last), and the row records that critical state, so that the load–displacement curve is the
  saw-tooth envelope.  The energy an event dissipates is the drop of the stored energy at the fixed displacement,
  ½ λ² (uᵀ K u − u'ᵀ K' u') with the unit solutions before and after the drop (for one member
  ½ f_i δ_i − ½ k_{i+1} δ_i²);
* softening, adaptive — the same on the adaptive mesh, refined before an event until every element holding a
  member loaded above ``theta`` of its present strength is resolved and (until the first event, and at every
  refinement) the indicator holds; after the first event the indicator's marks without a theta reason wait up to
  ``defer`` events, and marks that would add fewer than ``min_gain`` of the nodes wait (another ``defer`` events
  each time) for a refinement with a theta reason or marks that add more (a refinement solve records no event).

Every solve gives one row of :data:`COLUMNS`.  The state between solves is the members' present teeth and the
mesh (``state``/``restore``): an element's matrices follow from them; with them the stiffnesses at the last
factorisation of the system and the changes since (:mod:`.factor`), so a resumed run continues exactly.
"""

from __future__ import annotations

import resource
import time

import numpy as np

from .adaptive import Model, mark, refine, resolve_members
from .factor import HeldSolver, add_dense
from .lattice import DIRECTIONS, assemble
from .meshkern import index_of, initial_mesh_of, masters, node_of, sla_ratios
from .scenario import ADAPTIVE

#: history columns of a quasi-static run: (name, unit, description)
COLUMNS = (
    ("solve", "-", "solves so far (this one included)"),
    ("kind", "-", "0: refinement solve (no event), 1: saw-tooth event, 2: elastic equilibrium"),
    ("u1", "cm", "prescribed e1 displacement of the right edge (the load factor of a saw-tooth analysis)"),
    ("reaction", "dyn", "sum of the e1 reactions on the right edge"),
    ("member", "-", "member that reaches its strength at this state (-1: none)"),
    ("member_force", "dyn", "its force"),
    ("energy", "erg", "elastic energy stored in the lattice (mesh) at this state"),
    ("dofs", "-", "free degrees of freedom of the solve"),
    ("elements", "-", "elements of the mesh (fully resolved: 0)"),
    ("level1", "-", "level-1 elements (homogenised continuum)"),
    ("level2", "-", "level-2 elements (Cauchy-Born / eigenmode from the members inside)"),
    ("level3", "-", "level-3 elements (lattice triangles)"),
    ("teeth_taken", "-", "saw-tooth events so far (members' stiffness drops)"),
    ("damaged", "-", "members with at least one tooth taken"),
    ("wall", "s", "wall time of this solve"),
    ("peak_memory", "MiB", "peak resident memory of the process so far"),
)
COL = {c[0]: i for i, c in enumerate(COLUMNS)}
REFINE, EVENT, ELASTIC = 0, 1, 2


class Stepper:
    """``p``: the problem; ``teeth``: (strengths, stiffnesses) per member and tooth (softening) or None
    (elastic); ``adaptive``: the [adaptive] table (``enabled`` false or None: fully resolved);
    ``displacement``: the elastic runs' prescribed displacement of the right edge."""

    def __init__(
        self,
        p,
        teeth=None,
        adaptive=None,
        displacement=1.0,
        max_events=400,
        drop=0.7,
        residual=1e-9,
        workers=1,
    ):
        self.p = p
        self.lat = p.lat
        self.softening = teeth is not None
        if self.softening:
            self.TF, self.TK = teeth
        # a key the table lacks (a caller's partial table, a run saved before the setting existed) takes its schema
        # default, as scenario/load.py:same_run completes a stored scenario when it matches a run
        on = adaptive and adaptive.get("enabled", True)
        self.ad = {k: prm.default for k, prm in ADAPTIVE.fields.items()} | dict(adaptive) if on else None
        self._buffer = int(self.ad["buffer"]) if self.ad else 0  # rings around marked elements (mark)
        # softening: the indicator's marks that come without a theta reason wait for the next refinement or this
        # many events
        self._defer = int(self.ad["defer"]) if self.ad else 0
        self._deferred, self._waited = set(), 0  # those marks (elements of the present mesh); events since
        # marks of the indicator alone that would add fewer than this fraction of the present DOFs are not refined at
        # once: an elastic analysis ends there, a softening one lets them wait as above
        self._min_gain = float(self.ad["min_gain"]) if self.ad else 0.0
        self.u_load = float(displacement)
        self.max_events, self.drop, self.residual = int(max_events), drop, residual
        self.workers = int(workers)
        m = self.lat.n_members
        self.tooth = np.zeros(m, np.int64)
        self.solves = self.events = self.refinements = 0
        self.peak = 0.0
        self.done, self.end_reason = False, None
        self.model = None
        self.elements = initial_mesh_of(self.lat, int(self.ad["coarse_side"])) if self.ad else None
        if self.ad and self.ad["resolve_softer"] and p.k_ref is not None:
            self.elements = resolve_members(self.lat, self.elements, np.asarray(p.k, float) < p.k_ref)
        self.mesh_changed = self.ad is not None  # a new mesh the driver has not stored yet
        self._cache = {}  # element matrices across the meshes (adaptive.Model)
        # the fully resolved solver's factor, updated between saw-tooth events (factor.py), its matrix (updated in
        # place), the stiffnesses at its factorisation and the changes since (m, k before, k after), the
        # stiffnesses of the last solve
        self._held = self._K = self._fac_k = self._k_solved = None
        self._log = []
        self._replay = None  # the adaptive model's factor to rebuild on resuming (restore)
        self._all = None  # every member's index (the fully resolved saw-tooth step)
        self._kk = None  # the present stiffnesses, kept up to date member by member (stiffness)
        ix = index_of(self.lat)

        def dof(nd, c):
            q = node_of(ix, nd)
            if q < 0:
                raise ValueError(f"the supports name node {nd}, which the lattice does not have")
            return 2 * q + c

        self._pattern = {dof(nd, c): v for (nd, c), v in p.pattern.items()}
        self._measure = np.array([dof(nd, c) for nd, c in p.measure], np.int64)

    # -- state -------------------------------------------------------------------------------------------
    def stiffness(self) -> np.ndarray:
        """The members' present (secant) stiffnesses."""
        if not self.softening:
            return np.asarray(self.p.k, float)
        if self._kk is None:
            nt = self.TF.shape[1]
            m = np.arange(self.lat.n_members)
            k = np.where(self.tooth < nt, self.TK[m, np.minimum(self.tooth, nt - 1)], self.residual * self.p.k)
            self._kk = np.asarray(k, float)
        return self._kk.copy()

    def _tooth_taken(self, c):
        """Member c's next tooth: its stiffness with it (as :meth:`stiffness` has it)."""
        self.tooth[c] += 1
        if self._kk is not None:
            nt = self.TF.shape[1]
            t = self.tooth[c]
            self._kk[c] = self.TK[c, t] if t < nt else self.residual * np.broadcast_to(self.p.k, self._kk.shape)[c]

    def state(self) -> dict:
        st = {
            "tooth": self.tooth.copy(),
            "counters": np.array([self.solves, self.events, self.refinements, int(self.done)], np.int64),
            "peak": np.array([self.peak]),
        }
        if self.ad:
            st["elements"] = np.array(self.elements, np.int64).reshape(-1, 4)
            st["mesh_changed"] = np.array([int(self.mesh_changed)], np.int64)  # a new mesh not yet stored
            st["deferred"] = np.array(sorted(self._deferred), np.int64)  # the indicator's waiting marks
            st["deferred_events"] = np.array([self._waited], np.int64)
            fk, log = self.model.factor_state() if self.model is not None else (None, None)
            if fk is None and self._replay is not None:  # resumed and not solved since
                fk, log = self._replay
        else:
            fk, log = self._fac_k, np.array(self._log, float).reshape(-1, 3)
        if fk is not None:  # the factor's state: resuming rebuilds it and continues bit for bit
            st["factor_k"] = np.asarray(fk, float)
            st["factor_log"] = np.asarray(log, float).reshape(-1, 3)
        return st

    def restore(self, st: dict):
        self._held = self._K = self._fac_k = self._k_solved = self._replay = self._kk = None
        self._log = []
        self.tooth = np.asarray(st["tooth"], np.int64).copy()
        self.solves, self.events, self.refinements, done = (int(v) for v in st["counters"])
        self.done = bool(done)
        self.peak = float(st["peak"][0])
        if self.ad:
            self.elements = np.asarray(st["elements"], np.int64).reshape(-1, 4)
            self.model = None
            self.mesh_changed = bool(st["mesh_changed"][0]) if "mesh_changed" in st else False
            self._deferred = set(np.asarray(st.get("deferred", []), np.int64).tolist())
            self._waited = int(st["deferred_events"][0]) if "deferred_events" in st else 0
            if "factor_k" in st:  # the model is built at these stiffnesses and its changes replayed (_ensure_model)
                self._replay = (np.asarray(st["factor_k"], float), np.asarray(st["factor_log"], float).reshape(-1, 3))
        elif "factor_k" in st:  # factorise where the interrupted run did, add the same changes since
            self._fac_k = np.asarray(st["factor_k"], float).copy()
            self._held = HeldSolver(list(self._pattern), list(self._pattern.values()), 2 * self.lat.n_nodes)
            self._K = self._held.factorise(assemble(self.lat, self._fac_k))
            self._k_solved = self._fac_k.copy()
            for m, kb, ka in np.asarray(st["factor_log"], float).reshape(-1, 3):
                self._member_change(int(m), kb, ka)
                self._log.append((int(m), kb, ka))
                self._k_solved[int(m)] = ka

    def levels(self) -> np.ndarray:
        """The level of every element of the present mesh (builds the model if needed)."""
        if not self.ad:
            return np.zeros(0, np.int64)
        self._ensure_model(self.stiffness())
        return np.asarray(self.model.levels, np.int64)

    # -- one solve ----------------------------------------------------------------------------------------
    def _ensure_model(self, kk):
        if self.model is None:
            replay, self._replay = self._replay, None
            self.model = Model(
                self.lat,
                self.p.domain,
                self.elements,
                kk if replay is None else replay[0],
                k_ref=self.p.k_ref,
                workers=self.workers,
                cache=self._cache,
            )
            if replay is not None:  # resuming: the model's factor as the interrupted run had it, then its changes
                self.model.replay_factor(self.p.pattern, replay[1])
        self.model.set_stiffness(kk)

    def _member_change(self, m, k_before, k_after):
        """Member m's stiffness changed: Δk g gᵀ with g = (n, −n) on its two nodes, to the factor and the matrix."""
        a, b = self.lat.members[m]
        nx, ny = self.lat.n[m]
        dofs, g, dk = [2 * a, 2 * a + 1, 2 * b, 2 * b + 1], np.array([nx, ny, -nx, -ny]), k_after - k_before
        self._held.add(dofs, g, dk)
        if self._K is not None and not add_dense(self._K, dofs, dk * np.outer(g, g)):
            self._K = None  # assembled and factorised afresh at the next solve (HeldSolver.solve)

    def _solve_unit(self, kk):
        """(node displacements (n, 2), reaction, energy, dofs, levels) for the unit pattern."""
        if self.ad:
            self._ensure_model(kk)
            # the indicator and the member checks need the mesh nodes only (Model.sla_ratios)
            st = self.model.solve(self.p.pattern, self.p.measure, full=False)
            lv = np.bincount(st.level, minlength=4)[1:]
            return st.u, st.reaction, st.energy, st.dofs, lv
        if self._held is None:
            self._held = HeldSolver(list(self._pattern), list(self._pattern.values()), 2 * self.lat.n_nodes)
            self._K = None
        changes = []
        if self._K is not None:  # the members whose stiffness changed since the last solve
            for m in np.flatnonzero(kk != self._k_solved):
                changes.append((m, self._k_solved[m], kk[m]))
                self._member_change(m, self._k_solved[m], kk[m])
        u, r, self._K = self._held.solve(self._K, lambda: assemble(self.lat, kk))
        if self._held.fresh:  # the factor's state follows from these stiffnesses (state/restore)
            self._fac_k, self._log = kk.copy(), []
        else:
            self._log.extend(changes)
        self._k_solved = kk.copy()
        n2 = 2 * self.lat.n_nodes
        return (
            u.reshape(-1, 2),
            float(r[self._measure].sum()),
            0.5 * float(u @ r),
            n2 - len(self._pattern),
            np.zeros(3, np.int64),
        )

    def advance(self) -> np.ndarray:
        """One solve; returns its history row (:data:`COLUMNS`).  Sets ``done`` (and ``end_reason``) when the
        analysis has ended."""
        if self.done:
            raise RuntimeError("the analysis has ended")
        t0 = time.perf_counter()
        kk = self.stiffness()
        u, reaction, energy, dofs, lv = self._solve_unit(kk)
        self.unit_energy = energy  # of the unit pattern on this solve's stiffness (an event's dissipation: module doc)
        n_el = len(self.model.els) if self.ad else 0  # of the mesh solved (a refinement replaces it)
        self.solves += 1
        row = np.zeros(len(COLUMNS))
        row[COL["member"]] = -1
        if not self.softening:
            s = self.u_load
            row[COL["kind"]] = ELASTIC
            row[[COL["u1"], COL["reaction"], COL["energy"]]] = s, s * reaction, s * s * energy
            self.peak = max(self.peak, abs(s * reaction))
            if self.ad:
                marked = mark(self.lat, self.elements, u, float(self.ad["tol"]), self.model, self._buffer)
                more = self.solves < int(self.ad["max_stages"])
                finer = self._worth(marked) if more else None
                if finer is not None:
                    self._refine(marked, finer)
                else:
                    self.done = True
                    if not marked:
                        self.end_reason = "the refinement indicator holds"
                    elif not more:
                        self.end_reason = f"adaptive.max_stages = {self.solves} reached"
                    else:
                        self.end_reason = (
                            f"the refinement indicator's marks add fewer than adaptive.min_gain = {self._min_gain:g} "
                            "of the DOFs"
                        )
            else:
                self.done, self.end_reason = True, "elastic equilibrium"
        else:
            self._sla(row, kk, u, reaction, energy)
        row[COL["solve"]] = self.solves
        row[COL["dofs"]] = dofs
        if self.ad:
            row[COL["elements"]] = n_el
            row[[COL["level1"], COL["level2"], COL["level3"]]] = lv
        row[COL["teeth_taken"]] = int(self.tooth.sum())
        row[COL["damaged"]] = int(np.count_nonzero(self.tooth))
        row[COL["wall"]] = time.perf_counter() - t0
        row[COL["peak_memory"]] = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0
        return row

    def _worth(self, marked):
        """The mesh ``marked`` refines to, or None where there is none or it adds fewer than ``min_gain`` of the
        present mesh's master nodes (DOFs): on a stage that resolves the last few elements at a notch's corner or
        the edge of the refined region the indicator is then taken to hold (a factorisation saved; stated choice,
        docs/reproduction.md)."""
        if not marked:
            return None
        finer = refine(self.elements, marked)
        if self._min_gain > 0.0:  # the present mesh's master nodes: its model's T has two columns per node
            if masters(finer, self.model.ix, self.lat.n_nodes) < (1.0 + self._min_gain) * (self.model.T.shape[1] // 2):
                return None
        return finer

    def _refine(self, marked, finer=None):
        self._deferred, self._waited = set(), 0  # the waiting marks were refined with these (they are of this mesh)
        self.elements = refine(self.elements, marked) if finer is None else finer
        self.model = None
        self.refinements += 1
        self.mesh_changed = True

    def _sla(self, row, kk, u, reaction, energy):
        """The saw-tooth step: the member that reaches its present strength first under the unit solution ``u``
        takes its next tooth at that load factor (the module's docstring)."""
        if self.ad:
            return self._sla_adaptive(row, kk, u, reaction, energy)
        if self._all is None:  # every member "resolved", no coarser element (meshkern.sla_ratios)
            self._all = np.arange(self.lat.n_members)
        none = np.zeros((0, 3), np.int64)
        _, _, ratio, f_unit = sla_ratios(
            none, np.zeros((0, 3, 2)), np.zeros((0, 4), np.int64), np.zeros((0, 3)), DIRECTIONS, self._all,
            self.lat.members, self.lat.n, u, kk, self.tooth, self.TF,
        )  # fmt: skip
        c = int(np.argmin(ratio)) if len(ratio) else -1
        if c < 0 or not np.isfinite(ratio[c]):
            row[COL["kind"]] = REFINE
            self.done, self.end_reason = True, "no member is in tension any more"
            return
        lam = float(ratio[c])
        row[[COL["u1"], COL["reaction"], COL["energy"]]] = lam, lam * reaction, lam * lam * energy
        row[COL["member"]], row[COL["member_force"]] = c, lam * f_unit[c]
        self._event(row, c, lam, reaction)

    def _sla_adaptive(self, row, kk, u, reaction, energy):
        """:meth:`_sla` on the adaptive mesh: the critical member among the resolved members and the coarser
        elements' (Model.sla_ratios: their members' elongations follow from the element strains), the mesh
        refined first where a member is loaded above theta of its strength; the indicator's marks too, at once
        before the first event, else with the next refinement or after ``defer`` events (marks still waiting
        when the run ends — the load drop, ``max_events`` — are left: at most ``defer`` events were taken on
        the mesh they would have refined); marks that would add fewer than ``min_gain`` of the nodes
        (:meth:`_worth`) are not refined when their time comes but wait another ``defer`` events, or for a
        refinement with a theta reason, which takes them along."""
        ratio_e, dir_e, res, ratio_r, f_r, WM = self.model.sla_ratios(u, kk, self.tooth, self.TF)
        ie = int(np.argmin(ratio_e)) if len(ratio_e) else -1
        ir = int(np.argmin(ratio_r)) if len(ratio_r) else -1
        lam_e = ratio_e[ie] if ie >= 0 else np.inf
        lam_r = ratio_r[ir] if ir >= 0 else np.inf
        if not np.isfinite(min(lam_e, lam_r)):
            row[COL["kind"]] = REFINE
            self.done, self.end_reason = True, "no member is in tension any more"
            return
        if lam_r <= lam_e:
            lam, c, fc = float(lam_r), int(res[ir]), float(lam_r * f_r[ir])
        else:  # a member of a coarser element: refined below before it can take an event
            lam, c = float(lam_e), int(WM[ie, dir_e[ie]])
            fc = float(self.TF[c, 0])
        row[[COL["u1"], COL["reaction"], COL["energy"]]] = lam, lam * reaction, lam * lam * energy
        row[COL["member"]], row[COL["member_force"]] = c, fc
        theta = float(self.ad["theta"])
        ks = self.model.elements_of_members(res[ratio_r * theta < lam])  # above theta of their strength
        coarse = set(ks[self.elements[ks, 3] > 1].tolist())
        coarse |= set(np.flatnonzero(ratio_e * theta < lam).tolist())
        if lam_r > lam_e:  # even at theta = 1: a member is damaged only once resolved
            coarse.add(ie)
        # the damaged members' elements' "strain" is a crack's opening: not the indicator's scale (adaptive.mark)
        cracked = np.flatnonzero(self.tooth) if self.ad["intact_scale"] else None
        marks = mark(self.lat, self.elements, u, float(self.ad["tol"]), self.model, self._buffer, cracked)
        # the indicator's marks without a theta reason wait (defer): a refinement is a factorisation, and after the
        # first event they come every few events along a growing crack; they go with the next refinement, or
        # after `defer` events (0: at once); until the first event every mark is taken at once (unless it adds fewer
        # than min_gain of the nodes: _worth)
        pending = marks | self._deferred
        if coarse:
            row[COL["kind"]] = REFINE
            self._refine(coarse | pending)
            return
        if pending and (self.events == 0 or self._waited >= self._defer):
            finer = self._worth(pending)
            if finer is not None:
                row[COL["kind"]] = REFINE
                self._refine(pending, finer)
                return
            self._waited = 0  # they add fewer than min_gain of the DOFs: another `defer` events (or a refinement)
        if pending:
            self._deferred = pending
            self._waited += 1
        self._event(row, c, lam, reaction)

    def _event(self, row, c, lam, reaction):
        """Member c takes its next tooth at load factor lam."""
        row[COL["kind"]] = EVENT
        self.events += 1
        self._tooth_taken(c)
        r = abs(lam * reaction)
        self.peak = max(self.peak, r)
        if self.drop is not None and r < self.drop * self.peak:
            self.done = True
            self.end_reason = f"the reaction fell below {self.drop:g} of its peak {self.peak:.6g} dyn"
        elif self.events >= self.max_events:
            self.done = True
            self.end_reason = f"loading.max_events = {self.max_events} events reached"
