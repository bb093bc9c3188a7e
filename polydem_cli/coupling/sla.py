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

from .lattice import Lattice, assemble, member_elongation, solve_displacements


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
    member keeps ``residual`` × its stiffness so that the lattice stays connected."""
    m = lat.n_members
    nt = teeth_f.shape[1]
    tooth = np.zeros(m, np.int64)
    res = SLAResult()
    n2 = 2 * lat.n_nodes
    measure = np.asarray(list(measure), np.int64)
    pending = None  # (factor, stored energy) of the last event, until the next solve gives the energy after it
    for step in range(steps + 1):
        kk = np.where(tooth < nt, teeth_k[np.arange(m), np.minimum(tooth, nt - 1)], residual * np.asarray(k, float))
        K = assemble(lat, kk)
        u = solve_displacements(K, pattern, n2)
        e_unit = 0.5 * float(u @ (K @ u))
        if pending is not None:
            lam0, e0 = pending
            res.dissipated.append(e0 - lam0 * lam0 * e_unit)
        if step == steps:
            break
        d = member_elongation(lat, u.reshape(-1, 2))
        f_unit = kk * d
        ok = (tooth < nt) & (f_unit > 0)
        if not np.any(ok):
            break
        strength = teeth_f[np.arange(m), np.minimum(tooth, nt - 1)]
        ratio = np.full(m, np.inf)
        ratio[ok] = strength[ok] / f_unit[ok]
        c = int(np.argmin(ratio))
        lam = float(ratio[c])
        r = K @ (lam * u)
        res.factor.append(lam)
        res.reaction.append(float(r[measure].sum()))
        res.member.append(c)
        res.force.append(float(lam * f_unit[c]))
        res.elongation.append(float(lam * d[c]))
        pending = (lam, lam * lam * e_unit)
        tooth[c] += 1
        if drop is not None and abs(res.reaction[-1]) < drop * max(abs(v) for v in res.reaction):
            steps = step + 1  # one more solve gives the energy after this event
    res.teeth = tooth
    return res
