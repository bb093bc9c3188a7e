"""Member laws of the lattice (Sorg 2014): linear elastic bars, and bars with a uniaxial linear-softening
damage law followed by sequentially linear analysis (a saw-tooth law).

Linear softening (tension only; compression stays elastic), with stiffness k, tensile strength f_t and
ultimate elongation δ_u::

    f(δ) = k δ                                  δ ≤ δ_t = f_t / k
         = f_t (δ_u − δ) / (δ_u − δ_t)          δ_t < δ < δ_u
         = 0                                    δ ≥ δ_u

unloading along the secant to the origin; the energy dissipated to complete failure is the area under the
curve, ``G = ½ f_t δ_u``.

Sequentially linear analysis (Rots et al. 2008) replaces the softening branch by N teeth: tooth i
(0 ≤ i < N) is a linear member of strength ``f_i = f_t (1 − i/N)`` and secant stiffness ``k_i = f_i/δ_i``,
where ``δ_i`` is the elongation at which the softening curve has the force f_i (δ_0 = δ_t, k_0 = k); after
the last tooth the member is removed.  Each step of the analysis is a linear solve; the load is scaled until
the first member reaches its tooth's strength, whose stiffness then drops to the next tooth's.  No iteration,
no convergence failure through snap-back: the path-following method of the softening examples.
"""

from __future__ import annotations

import numpy as np


def softening_force(delta, k: float, f_t: float, delta_u: float):
    """f(δ) of the linear-softening law on its envelope (first loading)."""
    delta = np.asarray(delta, float)
    dt = f_t / k
    soft = f_t * (delta_u - delta) / (delta_u - dt)
    return np.where(delta <= dt, k * delta, np.where(delta < delta_u, soft, 0.0))


def fracture_energy(f_t: float, delta_u: float) -> float:
    """G = ½ f_t δ_u, the area under the linear-softening curve."""
    return 0.5 * f_t * delta_u


def saw_teeth(k: float, f_t: float, delta_u: float, n: int) -> tuple:
    """(strengths f_i, stiffnesses k_i) of the n teeth of the saw-tooth law (module docstring)."""
    if not (k > 0 and f_t > 0 and delta_u > f_t / k and n >= 1):
        raise ValueError("need k > 0, f_t > 0, delta_u > f_t / k and at least one tooth")
    f = f_t * (1.0 - np.arange(n) / n)
    dt = f_t / k
    d = delta_u - f * (delta_u - dt) / f_t  # the softening curve's elongation at force f
    return f, f / d
