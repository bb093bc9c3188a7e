"""Tangential contact sub-models (thesis §4.3.2).

``coulomb`` — elasto-plastic Coulomb friction with per-contact history.
Tangential relative displacement since contact start (4.10), trapezoidal rule (4.22)::

    u_t,l = u_t,l−1 + Δt (v_t,l−1 + v_t,l)/2        (u_t = v_t = 0 before contact start)

additive split u_t = u_t^el + u_t^pl (4.12), force (4.14) ``f_t = k_t (u_t − u_t^pl) T``,
yield function (4.16) ``|f_t| − μ_t |f_n^el| ≤ 0`` with the *elastic* normal
force, and the closed-form return mapping (4.23)–(4.24)::

    f_tr = k_t (u_t,l − u^pl_t,l−1) T,   F_tr = |f_tr| − μ_t |f_n^el|
    Δλ = max(F_tr, 0)/(k_t T),  u^pl = u^pl + Δλ sgn f_tr,  f_t = f_tr − Δλ k_t T sgn f_tr

Pair parameters: (4.15) ``k_t`` and (4.17) ``μ_t`` by the harmonic rule.
Units: k_t in g cm⁻¹ s⁻² (= dyn/cm²; 1 N/cm² = 1e5), μ_t dimensionless.
"""

from __future__ import annotations

from numba import njit

NONE = 0
COULOMB = 1

MODELS = {"none": NONE, "coulomb": COULOMB}


@njit(cache=True, inline="always")
def coulomb_update(ut_prev, upl_prev, vt_prev, vt, dt, kt, mu, fel, T):
    """One history update; returns ``(u_t, u_t^pl, f_t, Δλ)``."""
    ut = ut_prev + 0.5 * dt * (vt_prev + vt)
    ktT = kt * T
    ftr = ktT * (ut - upl_prev)
    Ftr = abs(ftr) - mu * abs(fel)
    if Ftr > 0.0 and ktT > 0.0:
        dl = Ftr / ktT
        sg = 1.0 if ftr > 0.0 else -1.0
        return ut, upl_prev + dl * sg, ftr - dl * ktT * sg, dl
    return ut, upl_prev, ftr, 0.0
