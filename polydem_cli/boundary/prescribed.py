"""Prescribed motion of single DOFs (thesis §3.2.3).

A prescribed DOF is removed from the initial value problem: its value, velocity
and acceleration at every evaluation time are given functions of t.

``FREE``      integrated
``FIXED``     x̂ = x0
``VELOCITY``  x̂ = x0 + v t                      (constant velocity from t = 0)
``RAMP``      x̂ = x0 + ½ a t²           t ≤ t_r = v/a
              x̂ = x0 + ½ a t_r² + v (t − t_r)   after (acceleration ramp, then constant velocity)
``COSINE``    x̂ = x0 + D (1 − cos ωt)/2      ωt ≤ π, then x0 + D (Luding & Herrmann (LH 1.1): a smooth
              start and stop; ω = 2π f, the end position is reached at t = 1/(2f)); stored as vel = D, acc = ω
"""

from __future__ import annotations

import math

from numba import njit

FREE = 0
FIXED = 1
VELOCITY = 2
RAMP = 3
COSINE = 4
BC_KINDS = {"free": FREE, "fixed": FIXED, "velocity": VELOCITY, "ramp": RAMP, "cosine": COSINE}
MOVING = (VELOCITY, RAMP, COSINE)


@njit(cache=True, inline="always")
def prescribed(kind, vel, acc, x0, t):
    """Prescribed position, velocity and acceleration of one DOF at time t."""
    if kind == FIXED:
        return x0, 0.0, 0.0
    if kind == VELOCITY:
        return x0 + vel * t, vel, 0.0
    if kind == COSINE:
        if acc * t >= math.pi:
            return x0 + vel, 0.0, 0.0
        c = math.cos(acc * t)
        return x0 + 0.5 * vel * (1.0 - c), 0.5 * vel * acc * math.sin(acc * t), 0.5 * vel * acc * acc * c
    # RAMP
    tr = vel / acc
    if t <= tr:
        return x0 + 0.5 * acc * t * t, acc * t, acc
    return x0 + 0.5 * acc * tr * tr + vel * (t - tr), vel, 0.0


def motion_of(spec) -> tuple[int, float, float]:
    """(kind, velocity, acceleration) of a scenario DOF entry ("free", "fixed" or a table)."""
    if spec == "free":
        return FREE, 0.0, 0.0
    if spec == "fixed":
        return FIXED, 0.0, 0.0
    if "displacement" in spec:
        return COSINE, float(spec["displacement"]), 2.0 * math.pi * float(spec["frequency"])
    v = float(spec["velocity"])
    if "acceleration" in spec:
        return RAMP, v, float(spec["acceleration"])
    return VELOCITY, v, 0.0


def displacement_time(kind: int, vel: float, acc: float, d: float) -> float:
    """Time at which |x̂(t) − x0| of a DOF reaches ``d`` (inf for fixed and free DOFs)."""
    if kind == VELOCITY:
        return d / abs(vel) if vel != 0 else math.inf
    if kind == COSINE:
        if d > abs(vel):
            return math.inf
        return math.acos(max(-1.0, 1.0 - 2.0 * d / abs(vel))) / acc
    if kind == RAMP:
        tr = vel / acc
        dr = 0.5 * abs(acc) * tr * tr
        if d <= dr:
            return math.sqrt(2 * d / abs(acc))
        return tr + (d - dr) / abs(vel)
    return math.inf
