"""Critical time step estimate (open point O-21) and the integrators' stability limits.

The thesis picks Δt "from simplified estimates at a single contact or bond" without a
formula.  polydem estimates the highest angular frequency ω_max of every interaction
that the scene uses and divides the integrator's stability limit by it:

* bonds: the largest eigenvalue of M⁻¹K of each two-particle beam element (undamaged
  stiffness of (5.11), masses and moments of inertia of its two particles);
* normal contact: the linearised stiffness of (4.3) for a face contact,
  k = k_n B² T with B ≤ 2 r (the bounding diameter of the smaller particle), acting
  at a lever arm ≤ r on two particles like the lightest one:
  ω² = 2 k (1/m + r²/Θ);  tangential contact the same with k = k_t T;
* the plugged-in families (base friction: ω² = k_u / (ρ T)) give their own, ``Family.omegas``.

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


def _bond_omegas(system) -> np.ndarray:
    net = system.bonds
    if not net.n:
        return np.zeros(0)
    p = net.params
    L, EA, kb, eta = p.L, p.EA, p.kb, p.eta
    nb = len(L)
    K = np.zeros((nb, 6, 6))
    a = EA / L
    k = kb
    K[:, 0, 0] = K[:, 3, 3] = a
    K[:, 0, 3] = K[:, 3, 0] = -a
    K[:, 1, 1] = K[:, 4, 4] = 12 * k
    K[:, 1, 4] = K[:, 4, 1] = -12 * k
    for (i, j), f in (((1, 2), 6), ((1, 5), 6), ((2, 4), -6), ((4, 5), -6)):
        K[:, i, j] = K[:, j, i] = f * L * k
    K[:, 2, 2] = K[:, 5, 5] = (4 + eta) * L * L * k
    K[:, 2, 5] = K[:, 5, 2] = (2 - eta) * L * L * k
    m = np.stack(
        [
            system.mass[p.a],
            system.mass[p.a],
            system.inertia[p.a],
            system.mass[p.b],
            system.mass[p.b],
            system.inertia[p.b],
        ],
        axis=1,
    )
    s = 1.0 / np.sqrt(m)
    A = K * s[:, :, None] * s[:, None, :]
    return np.sqrt(np.maximum(np.linalg.eigvalsh(A)[:, -1], 0.0))


def estimate(system) -> dict:
    """ω_max of the scene and the critical Δt of its integrator, with what limits it."""
    cand = []  # (omega, description)
    free = np.any(system.bc_kind == 0, axis=1)
    if system.bonds.n:
        w = _bond_omegas(system)
        k = int(np.argmax(w))
        p = system.bonds.params
        cand.append(
            (float(w[k]), f"bond {k} (particles {p.a[k]}-{p.b[k]}, L_h = {p.L[k]:.3g} cm, H_h = {p.H[k]:.3g} cm)")
        )
    if system.has_contact and system.n:
        r, m, th, T = system.radius, system.mass, system.inertia, system.thickness
        rot = 1.0 / m + r * r / th
        sel = free if np.any(free) else np.ones(system.n, bool)
        wn = np.sqrt(2.0 * system.kn * (2 * r) ** 2 * T * rot)
        wn = np.where(sel, wn, 0.0)
        i = int(np.argmax(wn))
        cand.append((float(wn[i]), f"normal contact of particle {i} (k_n = {system.kn[i]:.3g})"))
        if system.tangential:
            wt = np.where(sel, np.sqrt(2.0 * system.kt * T * rot), 0.0)
            i = int(np.argmax(wt))
            cand.append((float(wt[i]), f"tangential contact of particle {i} (k_t = {system.kt[i]:.3g})"))
    for fam in used_families(system):  # the plugged-in families (interactions/protocol.py) give their own
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
