"""Time integrators in Nordsieck predictor–corrector form (thesis §3.3.1).

Every degree of freedom carries a scaled Taylor vector (3.12)::

    x̌ = [x, ẋ Δt, ẍ Δt²/2, x''' Δt³/6, x'''' Δt⁴/24, x^(5) Δt⁵/120]

A step is *predict* (3.14) ``x̌_pd = S x̌``, one function evaluation at the
predicted position and velocity (3.15), and *correct* (3.16)::

    Δx̌ = (f_pd − ẍ_pd) Δt²/2,   x̌ = x̌_pd + s Δx̌ .

``gear5``
    Gear (1971) 5th-order predictor–corrector, ``S`` the 6×6 Pascal matrix and
    ``s = [3/20, 251/360, 1, 11/18, 1/6, 1/60]`` (thesis uses s1 = 3/20 for all
    right-hand sides, footnote 4).  One corrector iteration per step.
``verlet``
    Central differences in velocity-Verlet form written in the same layout:
    predictor ``x = x + ẋΔt + ẍΔt²/2``, ``ẋΔt ← ẋΔt + 2·ẍΔt²/2`` (the velocity
    at t_l predicted with the old acceleration, used only by velocity-dependent
    forces), corrector ``s = [0, 1, 1]``.  Positions equal those of the
    two-step central-difference formula ``x_{l+1} = 2x_l − x_{l−1} + Δt² f(x_l)``.

``verlet1``
    The same central differences with **one** function evaluation per step: at the predicted state, which
    also updates the history (the common velocity-Verlet practice, as in LAMMPS), instead of the thesis's
    provisional evaluation at the predicted state plus the final one at the corrected state (Fig. A.2).
    The corrector of ``verlet`` leaves the positions unchanged and takes the accelerations of the
    provisional evaluation, so where a family's forces and new history depend on the positions and the
    predicted velocity alone (cohesive disks (LH 1.5)-(1.9), rate-independent beams) the trajectory is the
    one of ``verlet`` at half the cost; what differs is what the final evaluation alone records: reported
    forces, energies and history that depend on the velocity (tangential contact springs, the strain rate of
    rate-dependent beams) are evaluated at the predicted velocity ẋ + ẍΔt instead of the corrected one.

The same kernels drive the engine and :mod:`polydem_cli.reproductions.integrators`,
so the convergence study tests the code that runs the simulations.
"""

from __future__ import annotations

import numpy as np
from numba import njit

GEAR5 = 0
VERLET = 1
VERLET1 = 2  # verlet with one evaluation per step (engine/kernels.py run_steps); predictor and corrector as VERLET

INTEGRATORS = {
    "gear5": GEAR5,
    "verlet": VERLET,
    "verlet1": VERLET1,
}

#: width of the Nordsieck vector for each integrator
ORDER_WIDTH = {GEAR5: 6, VERLET: 3, VERLET1: 3}

#: Gear corrector coefficients (3.16)
GEAR5_S = np.array([3.0 / 20.0, 251.0 / 360.0, 1.0, 11.0 / 18.0, 1.0 / 6.0, 1.0 / 60.0])


@njit(cache=True, inline="always")
def predict_dof(kind, z, out):
    """Predictor (3.14) for one DOF: ``out = S z`` (``z``, ``out``: length-6 views)."""
    if kind == GEAR5:
        z0, z1, z2, z3, z4, z5 = z[0], z[1], z[2], z[3], z[4], z[5]
        out[0] = z0 + z1 + z2 + z3 + z4 + z5
        out[1] = z1 + 2.0 * z2 + 3.0 * z3 + 4.0 * z4 + 5.0 * z5
        out[2] = z2 + 3.0 * z3 + 6.0 * z4 + 10.0 * z5
        out[3] = z3 + 4.0 * z4 + 10.0 * z5
        out[4] = z4 + 5.0 * z5
        out[5] = z5
    else:  # entries 3-5 of a central-difference vector stay 0 (ORDER_WIDTH): not touched
        out[0] = z[0] + z[1] + z[2]
        out[1] = z[1] + 2.0 * z[2]
        out[2] = z[2]


@njit(cache=True, inline="always")
def correct_dof(kind, zpd, acc, dt, out):
    """Corrector (3.16) for one DOF: ``out = zpd + s (acc Δt²/2 − zpd[2])``."""
    delta = acc * 0.5 * dt * dt - zpd[2]
    if kind == GEAR5:
        out[0] = zpd[0] + (3.0 / 20.0) * delta
        out[1] = zpd[1] + (251.0 / 360.0) * delta
        out[2] = zpd[2] + delta
        out[3] = zpd[3] + (11.0 / 18.0) * delta
        out[4] = zpd[4] + (1.0 / 6.0) * delta
        out[5] = zpd[5] + (1.0 / 60.0) * delta
    else:
        out[0] = zpd[0]
        out[1] = zpd[1] + delta  # (v + aΔt) − aΔt/2 + a_newΔt/2, scaled by Δt
        out[2] = zpd[2] + delta


def initial_vector(kind: int, derivs, dt: float) -> np.ndarray:
    """Scaled Nordsieck vector (3.13) from ``[x, ẋ, ẍ, x''', x'''', x^(5)]`` (missing = 0)."""
    d = np.zeros(6)
    d[: len(derivs)] = derivs
    fact = np.array([1.0, 1.0, 2.0, 6.0, 24.0, 120.0])
    z = d * dt ** np.arange(6) / fact
    if kind != GEAR5:
        z[3:] = 0.0
    return z
