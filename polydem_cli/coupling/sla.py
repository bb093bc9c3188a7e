"""Sequentially linear analysis of a lattice with saw-tooth members (:mod:`.members`), under a prescribed
displacement pattern scaled by one load factor.

Each step: assemble the lattice with every member's present tooth stiffness, solve for the unit pattern
(the prescribed DOFs at their unit values), find the member that reaches its tooth's strength first at the
smallest positive factor (tension only), record the state at that factor and move that member to its next
tooth (removed after the last).  The record of a step is the critical state itself, so the load–displacement
curve is the saw-tooth envelope.  The energy dissipated at an event is the drop of the lattice's stored
energy at the fixed prescribed displacement, ``½ λ² (uᵀ K u − u'ᵀ K' u')`` with the unit solutions before and
after the stiffness drop (the next step's solve gives u'); for a single member ``½ f_i δ_i − ½ k_{i+1} δ_i²``.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .lattice import Lattice
from .problem import Problem
from .stepper import COL, EVENT, Stepper


@dataclass
class SLAResult:
    factor: list = field(default_factory=list)  # load factor (scale of the unit pattern) at each event
    reaction: list = field(default_factory=list)  # sum of the reactions on the DOFs of ``measure`` at it
    member: list = field(default_factory=list)  # the critical member
    force: list = field(default_factory=list)  # its force at the event
    elongation: list = field(default_factory=list)  # its elongation at the event
    dissipated: list = field(default_factory=list)  # energy released by its stiffness drop
    teeth: np.ndarray = None  # the final tooth of every member (n_teeth: removed)


def run_sla(
    lat: Lattice, k, f_t, teeth_f, teeth_k, pattern: dict, measure, steps: int, residual=1e-9, drop=None
) -> SLAResult:
    """``pattern``: {dof: unit value} of the prescribed DOFs; ``measure``: DOFs whose reaction sum is recorded;
    ``teeth_f``/``teeth_k``: (m, N) strengths and stiffnesses per member (:func:`.members.saw_teeth`); a removed
    member keeps ``residual`` × its stiffness so that the lattice stays connected.  The loop is the fully
    resolved :class:`.stepper.Stepper` (the one ``polydem run`` advances); this adds the per-event elongation
    and dissipated energy."""

    def node_comp(dof):
        return (tuple(int(v) for v in lat.ij[dof // 2]), dof % 2)

    kk0 = np.broadcast_to(np.asarray(k, float), (lat.n_members,)).copy()
    p = Problem(
        lat,
        set(),
        kk0,
        None,
        {node_comp(d): v for d, v in pattern.items()},
        [node_comp(d) for d in measure],
        None,
        True,
        [],
    )
    st = Stepper(p, (teeth_f, teeth_k), None, max_events=steps, drop=drop, residual=residual)
    res = SLAResult()
    pending = None  # (factor, stored energy) of the last event, until the next solve gives the energy after it
    while not st.done:
        kk = st.stiffness()
        row = st.advance()
        if pending is not None:
            lam0, e0 = pending
            res.dissipated.append(e0 - lam0 * lam0 * st.unit_energy)
            pending = None
        if row[COL["kind"]] == EVENT:
            lam, c = float(row[COL["u1"]]), int(row[COL["member"]])
            res.factor.append(lam)
            res.reaction.append(float(row[COL["reaction"]]))
            res.member.append(c)
            res.force.append(float(row[COL["member_force"]]))
            res.elongation.append(float(row[COL["member_force"]]) / kk[c])
            pending = (lam, float(row[COL["energy"]]))
    if pending is not None:  # ended on an event (max events, load drop): one more solve for the energy after it
        lam0, e0 = pending
        res.dissipated.append(e0 - lam0 * lam0 * st._solve_unit(st.stiffness())[2])
    res.teeth = st.tooth
    return res


@dataclass
class AdaptiveSLA:
    """Events of an adaptive sequentially linear analysis (see :func:`run_sla_adaptive`)."""

    factor: list = field(default_factory=list)
    reaction: list = field(default_factory=list)
    member: list = field(default_factory=list)
    dofs: list = field(default_factory=list)  # DOFs of the mesh the event was found on
    elements: list = None  # the final mesh
    teeth: np.ndarray = None
    refinements: int = 0  # solves that only refined the mesh


def run_sla_adaptive(
    lat: Lattice,
    domain: set,
    k0: float,
    teeth,
    pattern: dict,
    measure,
    steps: int,
    adaptive=None,
    residual=1e-9,
    drop=None,
) -> AdaptiveSLA:
    """Sequentially linear analysis (:func:`run_sla`) on the adaptive mesh.  Before an event is taken the mesh is
    refined until (a) every element whose members carry more than ``theta`` of their present strength at the
    event's load factor is a lattice triangle (damage only where the lattice is resolved) and (b) the strain-
    jump indicator holds (``tol``; after the first event its marks without a reason of (a) wait up to ``defer``
    events, and marks adding fewer than ``min_gain`` of the nodes wait longer); each refinement costs a solve but records no event.  ``teeth``: (strengths,
    stiffnesses) per member (:func:`.members.saw_teeth`); ``adaptive``: {"coarse_side" (8), "tol" (0.1),
    "theta" (0.8), "intact_scale" (true), "defer" (20), "min_gain" (0), ... — the [adaptive] table's defaults where
    absent}, as :class:`.stepper.Stepper` takes it.  ``pattern``:
    {(node, component): unit value} of the prescribed DOFs (mesh nodes).  (The loop is :class:`.stepper.Stepper`,
    which the run driver advances solve by solve.)"""
    p = Problem(lat, domain, np.full(lat.n_members, float(k0)), None, pattern, list(measure), float(k0), True, [])
    st = Stepper(
        p,
        teeth,
        {"enabled": True} | dict(adaptive or {}),  # the keys it lacks: the [adaptive] table's defaults (Stepper)
        max_events=steps,
        drop=drop,
        residual=residual,
    )
    res = AdaptiveSLA()
    while not st.done and st.events < steps:
        row = st.advance()
        if row[COL["kind"]] == EVENT:
            res.factor.append(float(row[COL["u1"]]))
            res.reaction.append(float(row[COL["reaction"]]))
            res.member.append(int(row[COL["member"]]))
            res.dofs.append(int(row[COL["dofs"]]))
    res.elements, res.teeth, res.refinements = st.elements, st.tooth, st.refinements
    return res
