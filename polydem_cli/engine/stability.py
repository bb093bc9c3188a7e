"""Critical time step estimate (open point O-21) and the integrators' stability limits.

The thesis picks Δt "from simplified estimates at a single contact or bond" without a
formula.  polydem estimates the highest angular frequency ω_max of every interaction
that the scene uses and divides the integrator's stability limit by it:

every interaction family gives its own candidates (``Family.omegas``):

* bonds: the largest eigenvalue of M⁻¹K of each two-particle beam element (undamaged
  stiffness of (5.11), masses and moments of inertia of its two particles);
* normal contact: the linearised stiffness of (4.3) for a face contact,
  k = k_n B² T with B ≤ 2 r (the bounding diameter of the smaller particle), acting
  at a lever arm ≤ r on two particles like the lightest one:
  ω² = 2 k (1/m + r²/Θ);  tangential contact the same with k = k_t T;
* base friction: ω² = k_u / (ρ T); cohesive disks: k_2 over half the lightest disk's mass.

Integrator limits for ẍ = −ω²x (spectral radius of the step matrix ≤ 1):
``verlet`` ωΔt < 2; ``gear5`` (one corrector, s1 = 3/20) is only weakly stable — its
spectral radius exceeds 1 by 3e-9 at ωΔt = 0.12 (doubling takes 2e8 steps) but grows
fast beyond ωΔt ≈ 0.3 (doubling within ~1.5e5 steps) — so polydem uses ωΔt = 0.12,
safe for runs of up to ~1e8 steps (the thesis's concrete runs sit at ωΔt ≈ 0.10).
"""

from __future__ import annotations

import numpy as np

from .families import used_families
from .integrators import GEAR5, GEAR5_S, VERLET, VERLET1

#: ω Δt limits, see module docstring
OMEGA_DT_LIMIT = {GEAR5: 0.12, VERLET: 2.0, VERLET1: 2.0}


def gear_spectral_radius(h: float) -> float:
    """Spectral radius of one Gear PC step for ẍ = −ω²x with h = ωΔt (used by tests and docs)."""
    S = np.array(
        [
            [1, 1, 1, 1, 1, 1],
            [0, 1, 2, 3, 4, 5],
            [0, 0, 1, 3, 6, 10],
            [0, 0, 0, 1, 4, 10],
            [0, 0, 0, 0, 1, 5],
            [0, 0, 0, 0, 0, 1],
        ],
        float,
    )
    M = (np.eye(6) + np.outer(GEAR5_S, [-h * h / 2, 0, -1, 0, 0, 0])) @ S
    return float(np.max(np.abs(np.linalg.eigvals(M))))


def estimate(system) -> dict:
    """ω_max of the scene and the critical Δt of its integrator, with what limits it."""
    cand = []  # (omega, description)
    for fam in used_families(system):  # each interaction family gives its own (Family.omegas)
        cand += fam.omegas(system)
    if not cand:
        return {"omega_max": 0.0, "dt_crit": float("inf"), "limited_by": "no interaction", "omega_dt": 0.0}
    w, what = max(cand)
    lim = OMEGA_DT_LIMIT[system.integrator]
    return {
        "omega_max": w,
        "dt_crit": lim / w if w > 0 else float("inf"),
        "limited_by": what,
        "omega_dt": w * system.dt,
        "omega_dt_limit": lim,
    }


def describe(est: dict, dt: float) -> str:
    """One line on the critical time step estimate ``est`` (:func:`estimate`) and where ``dt`` stands against it."""
    if not np.isfinite(est["dt_crit"]):
        return "critical time step: unbounded (no stiff interaction)"
    return (
        f"critical time step estimate {est['dt_crit']:.3g} s (omega_max = {est['omega_max']:.4g} rad/s from "
        f"{est['limited_by']}); dt = {dt:g} s = {dt / est['dt_crit']:.3g} x the estimate"
    )


#: a run whose Δt exceeds the critical estimate by more than this factor is refused before it starts
#: (unless ``time.allow_large_dt``): for gear5 that is ωΔt > 0.24, where the error of the stiffest mode
#: doubles within ~1e6 steps; for verlet ωΔt > 4, beyond the central-difference limit of 2
DT_REFUSE_FACTOR = 2.0


def check_time_step(system, est=None):
    """Raise ScenarioError (key ``time.dt``) if Δt is above DT_REFUSE_FACTOR x the critical estimate."""
    from ..errors import ScenarioError

    est = est or estimate(system)
    t = system.scenario["time"]
    if t.get("allow_large_dt") or not np.isfinite(est["dt_crit"]):
        return est
    if system.dt > DT_REFUSE_FACTOR * est["dt_crit"]:
        raise ScenarioError(
            system.file,
            "time.dt",
            system.dt,
            f"is {system.dt / est['dt_crit']:.3g} x the critical time step estimate {est['dt_crit']:.3g} s "
            f"of the {t['integrator']} integrator (omega_max = {est['omega_max']:.4g} rad/s from "
            f"{est['limited_by']}); runs above {DT_REFUSE_FACTOR:g} x the estimate go unstable. Use "
            f"dt <= {est['dt_crit']:.3g} s, or set time.allow_large_dt = true to run anyway",
        )
    return est
