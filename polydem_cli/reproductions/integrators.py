"""Integrator study of thesis §3.3.2 (Figs. 3.8 and 3.9).

Problems, both on t ∈ [0, 3π]:

* harmonic oscillator (3.18) ``ẍ = −x, x0 = 0, ẋ0 = 1``, solution ``sin t`` (3.19);
* mass–spring collision (3.20) ``ẍ = 0 (x ≤ 0), −x (x > 0), x0 = −π, ẋ0 = 1``,
  solution (3.21).

Methods: EE explicit Euler, ME modified Euler (explicit midpoint), CD central
differences (start value x_{−1} from the analytic solution), PC Gear's
predictor–corrector (the engine's own kernels of
:mod:`polydem_cli.engine.integrators`; initial Nordsieck entries from the
analytic solution for the oscillator, ``[−π, Δt, 0, 0, 0, 0]`` for the collision).

Error (open point O-11): ``max_l |x(t_l) − x_l|`` over all steps.  Step counts
``n = 10·2^k``; none is divisible by 3, so on the collision problem all runs
belong to one phase family of the impact time π = (n/3)Δt.
The order is the least-squares slope of log(error) against log(n) over the
asymptotic range (see :func:`fit_order`): below ``FIT_HIGH`` and clear of the
round-off floor.
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
from numba import njit

from ..engine.integrators import GEAR5, correct_dof, predict_dof
from ..report.common import save as _save

OSCILLATOR = 0
COLLISION = 1
METHODS = ("EE", "ME", "CD", "PC")
FIT_HIGH = 1e-2
FLOOR_FACTOR = 30.0
T_END = 3.0 * math.pi


@njit(cache=True)
def _rhs(problem, x):
    if problem == OSCILLATOR:
        return -x
    return 0.0 if x <= 0.0 else -x


@njit(cache=True)
def _exact(problem, t):
    if problem == OSCILLATOR:
        return math.sin(t)
    if t <= math.pi:
        return t - math.pi
    if t < 2.0 * math.pi:
        return -math.sin(t)
    return -t + 2.0 * math.pi


@njit(cache=True)
def _run(problem, method, n):
    """Return max_l |x(t_l) − x_l| for ``n`` steps of ``method`` (0 EE, 1 ME, 2 CD, 3 PC)."""
    dt = T_END / n
    if problem == OSCILLATOR:
        x, v = 0.0, 1.0
    else:
        x, v = -math.pi, 1.0
    err = 0.0
    if method == 0:  # explicit Euler on (x, v)
        for l in range(1, n + 1):
            a = _rhs(problem, x)
            x, v = x + dt * v, v + dt * a
            err = max(err, abs(_exact(problem, l * dt) - x))
    elif method == 1:  # modified Euler (explicit midpoint)
        for l in range(1, n + 1):
            xm = x + 0.5 * dt * v
            vm = v + 0.5 * dt * _rhs(problem, x)
            x, v = x + dt * vm, v + dt * _rhs(problem, xm)
            err = max(err, abs(_exact(problem, l * dt) - x))
    elif method == 2:  # central differences, x_{-1} analytic
        xprev = _exact(problem, -dt) if problem == OSCILLATOR else -math.pi - dt
        for l in range(1, n + 1):
            xn = 2.0 * x - xprev + dt * dt * _rhs(problem, x)
            xprev, x = x, xn
            err = max(err, abs(_exact(problem, l * dt) - x))
    else:  # Gear predictor-corrector with the engine kernels
        z = np.zeros(6)
        zp = np.zeros(6)
        if problem == OSCILLATOR:
            d = (0.0, 1.0, 0.0, -1.0, 0.0, 1.0)
        else:
            d = (-math.pi, 1.0, 0.0, 0.0, 0.0, 0.0)
        fact = (1.0, 1.0, 2.0, 6.0, 24.0, 120.0)
        for k in range(6):
            z[k] = d[k] * dt**k / fact[k]
        for l in range(1, n + 1):
            predict_dof(GEAR5, z, zp)
            a = _rhs(problem, zp[0])
            correct_dof(GEAR5, zp, a, dt, z)
            err = max(err, abs(_exact(problem, l * dt) - z[0]))
    return err


def fit_order(steps, errors, high=FIT_HIGH, floor_factor=FLOOR_FACTOR):
    """Least-squares log–log slope (negated) over the asymptotic range.

    The asymptotic range is the set of points with ``error < high`` (past the
    pre-asymptotic regime) that lie before the minimum of the error curve and
    more than ``floor_factor`` above that minimum, when the curve rises again
    after it (round-off dominated tail, thesis Fig. 3.8).  If the error
    decreases up to the last point, every point below ``high`` is used.
    """
    s = np.asarray(steps, float)
    e = np.asarray(errors, float)
    imin = int(np.argmin(e))
    m = e < high
    if imin < len(e) - 1:
        m &= (np.arange(len(e)) < imin) & (e > floor_factor * e[imin])
    if m.sum() < 2:
        return float("nan"), []
    p = np.polyfit(np.log(s[m]), np.log(e[m]), 1)
    return float(-p[0]), [int(v) for v in s[m]]


def run_study(steps=None) -> dict:
    """Errors and fitted orders of all methods on both problems."""
    import time

    if steps is None:
        steps = [10 * 2**k for k in range(18)]
    t0 = time.time()
    res = {}
    for pname, prob in (("oscillator", OSCILLATOR), ("collision", COLLISION)):
        res[pname] = {}
        for mi, m in enumerate(METHODS):
            errs = [float(_run(prob, mi, int(n))) for n in steps]
            order, used = fit_order(steps, errs)
            res[pname][m] = {"order": order, "steps": [int(n) for n in steps], "error": errs, "fit_steps": used}
    res["meta"] = {
        "error_measure": "max over all steps of |x(t_l) - x_l|, t in [0, 3 pi]",
        "fit_range": (
            f"points with error < {FIT_HIGH:g}, before the error minimum and more than "
            f"{FLOOR_FACTOR:g}x above it when round-off makes the error rise again"
        ),
        "reproduces": "Schneider (2012) Figs. 3.8 and 3.9",
        "wall_s": time.time() - t0,
    }
    return res


def plot_study(res: dict, out_png: Path) -> None:
    """Error against the number of steps of each integrator for the oscillator and the collision (thesis
    Figs. 3.8, 3.9), log-log, to ``out_png``."""
    from ..mpl import pyplot

    plt = pyplot()

    fig, axes = plt.subplots(1, 2, figsize=(10, 4.2))
    styles = {"EE": "o-", "ME": "s-", "CD": "^-", "PC": "d-"}
    titles = {"oscillator": "Fig. 3.8: harmonic oscillator", "collision": "Fig. 3.9: mass–spring collision"}
    for ax, pname in zip(axes, ("oscillator", "collision")):
        for m in METHODS:
            d = res[pname][m]
            ax.loglog(d["steps"], d["error"], styles[m], ms=3.5, label=f"{m} (order {d['order']:.2f})")
        ax.set_xlabel("number of time steps $n_a$")
        ax.set_ylabel(r"error $\max_l |x(t_l)-x_l|$")
        ax.set_title(titles[pname])
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=8)
    fig.tight_layout()
    _save(fig, out_png, dpi=130)
    plt.close(fig)


def write_study(out_dir: Path, steps=None) -> dict:
    """Run the integrator study and write ``integrators.json`` and ``integrators.png`` to ``out_dir``; returns it."""
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    res = run_study(steps)
    (out_dir / "integrators.json").write_text(json.dumps(res, indent=1))
    plot_study(res, out_dir / "integrators.png")
    return res
