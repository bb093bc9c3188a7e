"""Speed against error over time steps and integrators (``polydem study timestep``).

Runs one scenario for every (integrator, Δt) pair, takes the run with the finest
Δt of the first integrator as the reference, and reports for every run

* wall time of the time loop and particle-steps per second;
* the error of the key observables against the reference: relative error of the
  peak load |f2| of the driven set, the load–displacement curve in the
  normalised L2 norm ``‖f − f_ref‖₂ / ‖f_ref‖₂`` (f interpolated onto the
  reference's displacements), and the largest final position difference
  relative to the median particle radius;
* whether it ran stably; the largest stable Δt per integrator;
* the convergence order of each error (slope of log error against log Δt) and the largest Δt
  whose peak-load and curve errors are both within 1 % (``largest_accurate_dt``).

Writes ``timestep.json`` and ``timestep.csv`` and a speed-against-error plot
(error against wall time, one curve per integrator) to the output directory; the
runs themselves go to ``<out>/runs/`` and are reused when the study is repeated.
"""

from __future__ import annotations

import csv
import json
from pathlib import Path

import numpy as np

from ..engine.simulation import EngineError
from ..engine.stability import check_time_step
from ..io.hdf5 import open_result, read_frames, read_history
from ..report.common import save as _save
from ..scenario.build import build_system
from ..scenario.load import load_scenario, scenario_differences
from ..scenario.spec import ScenarioError
from ..solvers import driver
from ..solvers.protocol import RunOptions, Source


def _observables(path):
    cols, tab = read_history(path)
    c = {n: i for i, n in enumerate(cols)}
    sets = [n.split(":", 1)[1] for n in cols if n.startswith("f2:")]
    u = f = None
    if sets:
        drv = max(sets, key=lambda s: np.ptp(tab[:, c["u2:" + s]]))
        u, f = tab[:, c["u2:" + drv]], tab[:, c["f2:" + drv]]
    steps, t, X, V = read_frames(path)
    return u, f, X[-1]


def _errors(run_path, ref_path, radius):
    u, f, x = _observables(run_path)
    ur, fr, xr = _observables(ref_path)
    out = {"final_position": float(np.max(np.hypot(*(x[:, :2] - xr[:, :2]).T)) / radius)}
    if f is not None and fr is not None and np.max(np.abs(fr)) > 0:
        out["peak_load"] = float(abs(np.max(np.abs(f)) - np.max(np.abs(fr))) / np.max(np.abs(fr)))
        order = np.argsort(u)
        fi = np.interp(ur, u[order], f[order])
        out["load_curve_L2"] = float(np.linalg.norm(fi - fr) / np.linalg.norm(fr))
    return out


#: a time step is accurate when the peak load is within 1 % and the load curve within 1 % (normalised L2)
#: of the reference run
PEAK_TOLERANCE = 0.01
CURVE_TOLERANCE = 0.01


def _obtain(sc, path, source, quiet, row):
    """The summary of one run of the study (None when it went unstable: ``row`` says so); a finished run of the
    same scenario is reused, an unfinished one run again whole (driver.STUDY), another scenario's refused."""
    try:
        return driver.obtain(sc, path, source=source, policy=driver.STUDY, opts=RunOptions(quiet=quiet)).summary
    except driver.Refused as e:  # never delete a result of another scenario
        raise ValueError(
            f"{path}: holds a run of a different scenario ({e.existing.why or '?'}); remove it or use another --out"
        ) from None
    except EngineError as e:
        row.update(stable=False, failure=str(e))
        return None


def run_study(scenario: Path, dts, integrators, out: Path, overrides=(), quiet=True, reference=None) -> dict:
    """``reference``: an existing result (e.g. a run at a finer dt) to measure the errors against instead
    of the study's finest run; keys in which its scenario differs beyond dt and integrator are noted."""
    out = Path(out)
    (out / "runs").mkdir(parents=True, exist_ok=True)
    rows = []
    for integ in integrators:
        for dt in sorted(dts):
            name = f"{integ}_dt{dt:.6g}"
            path = out / "runs" / f"{name}.h5"
            ov = list(overrides) + [f"time.dt={dt}", f'time.integrator="{integ}"']
            sc, text = load_scenario(scenario, ov)
            if sc["solver"]["kind"] != "explicit":
                raise ValueError(f"{scenario}: the timestep study varies dt and the integrator of an explicit run")
            system = build_system(sc, str(scenario))
            row = {"integrator": integ, "dt": dt, "result": str(path), "stable": True, "failure": None}
            try:
                check_time_step(system)
            except ScenarioError as e:  # far above the stability limit: not run
                row.update(stable=False, failure=f"refused: {e.reason}")
                rows.append(row)
                continue
            summary = _obtain(sc, path, Source(str(scenario), text, tuple(ov)), quiet, row)
            if summary is not None:
                row.update(
                    wall_s=summary["stepping_wall_time_s"],
                    steps=summary["steps"],
                    particle_steps_per_s=summary["particle_steps_per_s"],
                    particles=summary["particles"],
                )
            rows.append(row)
    ok = [r for r in rows if r["stable"]]
    if not ok:
        raise EngineError("no run of the study was stable")
    ref_note = None
    if reference is not None:
        with open_result(reference) as f:
            stored = json.loads(f.attrs["resolved"])
            rs = json.loads(f.attrs["summary"])
        base, _ = load_scenario(scenario, overrides)
        differs = [k for k in scenario_differences(stored, base) if k not in ("time.dt", "time.integrator")]
        ref = {"integrator": rs["integrator"], "dt": rs["dt"], "result": str(reference)}
        ref_note = (
            (
                f"reference {reference} differs from the study's scenario beyond dt and integrator in: "
                f"{', '.join(differs)}"
            )
            if differs
            else None
        )
    else:
        ref = min((r for r in ok if r["integrator"] == integrators[0]), key=lambda r: r["dt"], default=None) or min(
            ok, key=lambda r: r["dt"]
        )
    sc, _ = load_scenario(scenario, overrides)
    radius = float(np.median(build_system(sc, str(scenario)).radius))
    for r in ok:
        r["errors"] = _errors(r["result"], ref["result"], radius)
    largest = {}
    for integ in integrators:
        st = [r["dt"] for r in rows if r["integrator"] == integ and r["stable"]]
        largest[integ] = max(st) if st else None
    orders, accurate, unfit = {}, {}, {}
    for integ in integrators:
        rs = [r for r in ok if r["integrator"] == integ and r.get("result") != ref["result"]]
        orders[integ] = {}
        for metric in ("peak_load", "load_curve_L2", "final_position"):
            pts = sorted((r["dt"], r["errors"][metric]) for r in rs if r["errors"].get(metric, 0) > 0)
            if len(pts) >= 2:
                x, y = np.log([p[0] for p in pts]), np.log([p[1] for p in pts])
                orders[integ][metric] = float(np.polyfit(x, y, 1)[0])
                why = order_meaningless([p[1] for p in pts], orders[integ][metric])
                if why:
                    unfit.setdefault(integ, {})[metric] = why
        good = [
            r["dt"]
            for r in rs
            if r["errors"].get("peak_load", 1) <= PEAK_TOLERANCE
            and r["errors"].get("load_curve_L2", 1) <= CURVE_TOLERANCE
        ]
        accurate[integ] = max(good) if good else None
    res = {
        "scenario": str(scenario),
        "overrides": list(overrides),
        "reference": {"integrator": ref["integrator"], "dt": ref["dt"], "result": ref["result"], "note": ref_note},
        "largest_stable_dt": largest,
        "convergence_order": orders,
        # the fits that do not measure an order, and why (printed beside the number, drawn in the figure)
        "convergence_order_meaningless": unfit,
        "tolerances": {"peak_load": PEAK_TOLERANCE, "load_curve_L2": CURVE_TOLERANCE},
        "largest_accurate_dt": accurate,
        "runs": rows,
    }
    (out / "timestep.json").write_text(json.dumps(res, indent=1))
    keys = [
        "integrator",
        "dt",
        "stable",
        "wall_s",
        "steps",
        "particle_steps_per_s",
        "peak_load",
        "load_curve_L2",
        "final_position",
        "failure",
    ]
    with open(out / "timestep.csv", "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(keys)
        for r in rows:
            e = r.get("errors", {})
            w.writerow([r.get(k, e.get(k)) if k not in e else e[k] for k in keys])
    _plot(res, out / "timestep.png")
    return res


def order_meaningless(errors_by_dt, order) -> str | None:
    """Why a fitted convergence order is no order (None if it is one): ``errors_by_dt`` in the order of rising
    Δt.  An error that does not fall as Δt falls (a negative or flat slope, or errors out of order) is set by
    something else than the truncation error — round-off, the chaos of a granular pile, a reference too close."""
    e = np.asarray(errors_by_dt, float)
    if order <= 0.1:
        return f"the error does not fall as dt falls (slope {order:.2f}): no convergence order"
    if np.any(np.diff(e) < 0):
        return f"the error is not monotone in dt (slope {order:.2f} over scattered points): no convergence order"
    return None


def _plot(res, png):
    from ..mpl import pyplot

    plt = pyplot()
    from matplotlib.ticker import FuncFormatter, LogLocator, NullFormatter

    fig, axes = plt.subplots(1, 2, figsize=(11, 4.6))
    integs = sorted({r["integrator"] for r in res["runs"]})
    ref = res["reference"]
    ref_run = [r for r in res["runs"] if r.get("result") == ref["result"] and r.get("wall_s")]
    plain = FuncFormatter(lambda v, _: f"{v:g}")  # 0.001, 3, 10: no "3×10⁰" tick labels
    for metric, ax in zip(("load_curve_L2", "final_position"), axes):
        for integ in integs:
            rs = [
                r
                for r in res["runs"]
                if r["integrator"] == integ
                and r["stable"]
                and metric in r.get("errors", {})
                and r["errors"][metric] > 0
            ]
            if not rs:
                continue
            why = (res.get("convergence_order_meaningless", {}).get(integ) or {}).get(metric)
            order = res["convergence_order"].get(integ, {}).get(metric)
            said = "" if order is None else (" (no convergence order)" if why else f" (order {order:.2f})")
            ax.loglog([r["wall_s"] for r in rs], [r["errors"][metric] for r in rs], "o-", label=integ + said)
            for r in rs:
                ax.annotate(
                    f"{r['dt']:.2g}",
                    (r["wall_s"], r["errors"][metric]),
                    fontsize=7,
                    textcoords="offset points",
                    xytext=(3, 3),
                )
        if ref_run:  # its error is zero by definition: no point on a log axis, a line at its wall time
            ax.axvline(
                ref_run[0]["wall_s"], color="0.5", ls="--", lw=0.8, label=f"reference (error 0), dt = {ref['dt']:g} s"
            )
        for a, lim in ((ax.xaxis, ax.get_xlim()), (ax.yaxis, ax.get_ylim())):
            # labelled ticks at 1, 2, 5 per decade over a short span (less than a decade had no label at all once
            # the minor "3×10⁰" labels were gone), at the powers of ten over a long one
            if a.get_scale() == "log":  # (a panel without a single error has linear axes)
                decades = np.log10(max(lim) / min(lim))
                a.set_major_locator(LogLocator(base=10.0, subs=(1.0, 2.0, 5.0) if decades < 3 else (1.0,)))
            a.set_major_formatter(plain)
            a.set_minor_formatter(NullFormatter())
        ax.set_xlabel("wall time of the time loop [s]")
        ax.set_ylabel(
            {
                "load_curve_L2": "load curve error (normalised L2)",
                "final_position": "final position error / median radius",
            }[metric]
        )
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=8)
    fig.suptitle(
        f"speed against error: {Path(res['scenario']).name} (reference {res['reference']['integrator']}, "
        f"dt = {res['reference']['dt']:g} s; labels: dt)",
        fontsize=9,
    )
    fig.tight_layout()
    _save(fig, png, dpi=130)
    plt.close(fig)
