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
``CYCLIC``    loading with partial unloadings at speed |v|: along the path s = |v| t the DOF moves by +Δ (in the
              direction of v), then back by Δ/2 and on by 3Δ/2 — every cycle a new extreme one Δ further, after an
              unloading of Δ/2 (the unloading stiffness of a cyclic compression test); stored as vel = v, acc = Δ
"""

from __future__ import annotations

import math

from numba import njit

FREE = 0
FIXED = 1
VELOCITY = 2
RAMP = 3
COSINE = 4
CYCLIC = 5
BC_KINDS = {"free": FREE, "fixed": FIXED, "velocity": VELOCITY, "ramp": RAMP, "cosine": COSINE, "cyclic": CYCLIC}
MOVING = (VELOCITY, RAMP, COSINE, CYCLIC)

#: a ramped external load ([[loads]] ramp_time) rises in steps of this many time steps, counted from step 0 so that
#: the load history does not depend on how a run was cut into calls (resume, output cadence, ranks)
RAMP_BLOCK = 64


@njit(cache=True)
def ramp_fraction(step, dt, ramp_time):
    """The fraction of a ramped external load during the steps after ``step`` up to the end of its block of
    :data:`RAMP_BLOCK` steps: min(1, t_k / ramp_time), t_k the block's start (1 without a ramp, ``ramp_time`` 0).
    The loop's f_ext (engine/simulation.py) and the applied-load columns (interactions/controllers/applied_loads.py)
    both take it from here."""
    if ramp_time <= 0.0:
        return 1.0
    k0 = (step // RAMP_BLOCK) * RAMP_BLOCK
    return min(1.0, k0 * dt / ramp_time)


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
    if kind == CYCLIC:
        u, w = cyclic_path(abs(vel) * t, acc)
        sg = 1.0 if vel > 0.0 else -1.0
        return x0 + sg * u, w * vel, 0.0
    # RAMP
    tr = vel / acc
    if t <= tr:
        return x0 + 0.5 * acc * t * t, acc * t, acc
    return x0 + 0.5 * acc * tr * tr + vel * (t - tr), vel, 0.0


@njit(cache=True, inline="always")
def cyclic_path(s, cycle):
    """The ``CYCLIC`` motion (module docstring) after a path length s: the distance moved (in the direction of the
    velocity) and the direction of travel (+1 loading, -1 unloading)."""
    if s <= cycle:
        return s, 1.0
    r = s - cycle
    k = math.floor(r / (2.0 * cycle))
    r -= 2.0 * cycle * k
    top = (k + 1.0) * cycle
    if r <= 0.5 * cycle:
        return top - r, -1.0
    return top - cycle + r, 1.0


def motion_of(spec) -> tuple[int, float, float]:
    """(kind, velocity, acceleration) of a scenario DOF entry ("free", "fixed" or a table)."""
    if spec == "free":
        return FREE, 0.0, 0.0
    if spec == "fixed":
        return FIXED, 0.0, 0.0
    if "displacement" in spec:
        return COSINE, float(spec["displacement"]), 2.0 * math.pi * float(spec["frequency"])
    if "cycle" in spec:
        return CYCLIC, float(spec["velocity"]), float(spec["cycle"])
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
    if kind == CYCLIC:  # first reached on the loading part of the cycle whose new extreme it lies below
        if d <= acc:
            return d / abs(vel)
        k = math.ceil(d / acc) - 2  # d in ((k+1) Δ, (k+2) Δ]
        return (acc + 2.0 * acc * k + 0.5 * acc + (d - (k + 0.5) * acc)) / abs(vel)
    if kind == RAMP:
        tr = vel / acc
        dr = 0.5 * abs(acc) * tr * tr
        if d <= dr:
            return math.sqrt(2 * d / abs(acc))
        return tr + (d - dr) / abs(vel)
    return math.inf
