"""Normal contact sub-models (thesis §4.2.2).

``area`` — elastic potential of Feng & Owen (2004) (4.2)
``Φ = ½ k_n A_n² T`` giving the generalised force on I (4.3)::

    f_n^el = −k_n A_n B_n T  (≤ 0, along n, acting at K)

plus the viscous force (4.5) ``f_n^vi = γ_n A_n B_n v_n T`` and the tension
cut-off (4.9): the sum is applied only while ``f_n^el + f_n^vi ≤ 0``.
Pair parameters from particle values: (4.4) ``k_n = 2 k_I k_II/(k_I + k_II)``,
(4.8) ``γ_n = (γ_I + γ_II)/2``.

Units (cm–g–s): k_n in g cm⁻³ s⁻² (= dyn/cm⁴; 1 N/cm⁴ = 1e5), γ_n in
g cm⁻³ s⁻¹ (= dyn s/cm⁵), A_n in cm², B_n and T in cm, forces in dyn.
"""

from __future__ import annotations

from numba import njit


@njit(cache=True, inline="always")
def area_normal_force(A, B, vn, kn, gn, T):
    """Return ``(f_n, f_n^el)``: the applied normal force on I along n and its elastic part.

    ``vn = v_rel · n`` (negative while the particles approach, (4.6)).
    """
    fel = -kn * A * B * T
    f = fel + gn * A * B * vn * T
    if f > 0.0:  # tension cut-off (4.9)
        f = 0.0
    return f, fel


@njit(cache=True, inline="always")
def harmonic_pair(a, b):
    """Mixing rule (4.4)/(4.15)/(4.17): 2ab/(a+b) (0 if both are 0)."""
    return 0.0 if a + b == 0.0 else 2.0 * a * b / (a + b)


@njit(cache=True, inline="always")
def mean_pair(a, b):
    """Mixing rule (4.8): arithmetic mean."""
    return 0.5 * (a + b)
