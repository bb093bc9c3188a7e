"""The Luding–Herrmann normal contact law of cohesive frictionless disks (LH 1.5)–(1.9).

Overlap (LH 1.5) ``δ = (d_i + d_j)/2 − (r_i − r_j)·n``, ``n = (r_i − r_j)/|r_i − r_j|`` from j to i; the
force on i is ``f n``, positive repulsive, and acts only while δ > 0.

Hysteretic spring (LH 1.6), ``k_1 ≤ k_2``, ``k_c ≥ 0``, history ``δ_max`` per contact::

    δ_0 = (1 − k_1/k_2) δ_max
    f_hys = k_1 δ            if k_2 (δ − δ_0) ≥ k_1 δ           (loading; then δ_max = δ)
          = k_2 (δ − δ_0)    if k_1 δ > k_2 (δ − δ_0) > −k_c δ  (un/reloading)
          = −k_c δ           if −k_c δ ≥ k_2 (δ − δ_0)          (attraction limit)

so the largest attraction is ``−k_c δ_min`` at ``δ_min = (k_2 − k_1)/(k_2 + k_c) δ_max``.  Viscous
dissipation (LH 1.7) ``f_diss = γ_0 dδ/dt`` is added to f; background damping (LH 1.9) ``−γ_b v_i``
acts on every particle and is not part of the pair law.

Decision on an open point of the paper (its reset of ``δ_max`` is not stated): a contact's history
lives while δ > 0; when the disks separate (δ ≤ 0, where every branch gives f = 0) the contact is
removed, and a new contact starts with δ_max = 0.

Stored energy (for the energy balance; the paper gives none): the work the contact would return if
it were opened along its reversible branches at fixed δ_max,

    E(δ, δ_max) = −½ k_c δ²                                          for δ ≤ δ_min
                = −½ k_c δ_min² + ½ k_2 [(δ − δ_0)² − (δ_min − δ_0)²]  for δ_min < δ ≤ δ_max

(with k_c = 0 and δ ≤ δ_0 the force is zero and so is E); the rest of the work done on a contact
is dissipated (loading along k_1 and the viscous term).  dE/dδ = f_hys on every reversible branch.
"""

from __future__ import annotations

from numba import njit


@njit(cache=True, inline="always")
def lh_constants(k1, k2, kc):
    """(1 − k_1/k_2, (k_2 − k_1)/(k_2 + k_c)): δ_0 and δ_min per unit δ_max, for the ``*_c`` forms below (a
    pass over many contacts computes them once; the arithmetic per contact is the same)."""
    return 1.0 - k1 / k2, (k2 - k1) / (k2 + kc)


@njit(cache=True, inline="always")
def lh_hysteretic_c(delta, delta_max, k1, k2, kc, c0):
    """:func:`lh_hysteretic` with ``c0 = 1 − k_1/k_2`` given."""
    d0 = c0 * delta_max
    f2 = k2 * (delta - d0)
    if f2 >= k1 * delta:
        return k1 * delta, max(delta_max, delta)
    if f2 > -kc * delta:
        return f2, delta_max
    return -kc * delta, delta_max


@njit(cache=True, inline="always")
def lh_hysteretic(delta, delta_max, k1, k2, kc):
    """(f_hys, δ_max after this state) of (LH 1.6) at overlap ``delta`` > 0 with history ``delta_max``."""
    return lh_hysteretic_c(delta, delta_max, k1, k2, kc, 1.0 - k1 / k2)


@njit(cache=True, inline="always")
def lh_energy_c(delta, delta_max, k2, kc, c0, cmin):
    """:func:`lh_energy` with ``(c0, cmin) = lh_constants(k1, k2, kc)`` given."""
    if delta <= 0.0:
        return 0.0
    dm = max(delta_max, delta)
    d0 = c0 * dm
    dmin = cmin * dm
    if delta <= dmin:
        return -0.5 * kc * delta * delta
    return -0.5 * kc * dmin * dmin + 0.5 * k2 * ((delta - d0) ** 2 - (dmin - d0) ** 2)


@njit(cache=True, inline="always")
def lh_energy(delta, delta_max, k1, k2, kc):
    """Stored (recoverable) energy E(δ, δ_max) of a contact, see the module docstring."""
    return lh_energy_c(delta, delta_max, k2, kc, 1.0 - k1 / k2, (k2 - k1) / (k2 + kc))


def contact_duration(k2, m12, gamma0):
    """Half-period t_c = π/ω of (LH 1.8), ω = sqrt(k_2/m_12 − η_0²), η_0 = γ_0/(2 m_12)."""
    import math

    eta = gamma0 / (2.0 * m12)
    return math.pi / math.sqrt(k2 / m12 - eta * eta)
