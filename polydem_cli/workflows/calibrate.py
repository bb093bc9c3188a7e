"""``polydem calibrate``: beam parameters from macroscopic targets, instead of fitting by trial (thesis §§7.4–7.5).

Elastic targets (E, ν) need no time integration: the undamaged bond network is a linear frame whose static solve
(:mod:`polydem_cli.analysis.elastic`, the scenario's own supports) gives the macroscopic E and ν of thesis §7.5.1.
The network's stiffness is proportional to the beams' E_h at fixed ν_h, so

    ν(E_h, ν_h) = ν(ν_h),   E(E_h, ν_h) = E_h · E(1, ν_h):

ν_h is found first, by Brent's method on ν(ν_h) − ν_target over ν_h ∈ [−0.99, 0.49] (a target outside the
range ν reaches there is refused, with that range), then E_h = E_target / E(1, ν_h) exactly.

The tensile (or compressive) strength needs dynamic runs of the scenario itself: each run goes just past the
peak (``time.end_load_drop`` = 0.9) and gives the peak stress.  The strength rises monotonically with κ_0 (the
damage threshold; κ_m follows from the fracture energy G_ax as in the scenario), nearly in proportion, so the
root is found by the secant method on log f(log κ_0), starting from the scenario's κ_0 and the proportional
guess; tolerance ``rel_tol`` of the target (default 0.5 %).  Elastic parameters first (they do not depend on
κ_0), then κ_0.

Several seeds (``seeds``): the whole calibration is repeated on each specimen realisation (``scenario.seed``),
and the spread of the fitted parameters and of the achieved values is reported.

Units: targets as ``E=33.5GPa``, ``nu=0.2``, ``f_t=2.9MPa`` (also kPa, Pa, N/mm2, N/cm2, or dyn/cm2, the
scenario's own unit); a stress or force without a unit is refused (``E=33`` would be 33 dyn/cm², 3.3e-9 GPa).

A target the scenario cannot measure is refused before anything runs or is made: every target needs the
scenario's [bonds], E, ν and the strengths its [macro] table, F a set whose x2 motion is prescribed; f_t needs a
specimen pulled apart, f_c one pushed together: the sign of Σ_i (v_i − v̄)(y_i − ȳ) over the particles i whose
x2 is prescribed (velocity v_i, 0 if held; v̄, ȳ their mean velocity and height), or of Σ_i f_i (y_i − ȳ) over
constant x2 loads f_i; a loading that does neither (a rigid motion) is refused for both.

Several tests at once (``tests``, ``--test KEY=SCENARIO``): each target is measured on the scenario given for
it (default: the calibrated one), e.g. f_c on a compression panel and the fracture energy G_F on a notched beam in
three-point bending (RILEM TC-50, :mod:`polydem_cli.analysis.lab`); the fitted beams are the same in every test.
The parameters and their order: E, ν → bonds.E, bonds.nu (static, as above); the first strength of f_t, f_c, F
→ bonds.kappa_0; G_F → bonds.G_ax (secant on log G_F(log G_ax), each run a whole test to its scenario's end,
since the work of fracture is the area under the whole curve); the strength and G_F alternate until both hold
(a larger G_ax makes the beams more ductile and the peak a little higher).  A second strength (f_c with f_t) has no
parameter of its own — κ_0 scales both strengths nearly in proportion, so the beams allow one f_c/f_t — and is
measured and reported, with the ratio the beams give and the κ_0 it alone would need, not fitted.

Edge interfaces (``[bonds] model = "interface"``, interactions/bonds/interface.py): E and ν by the static solve of
the interfaces' stiffness (ν ≤ 0.33); f_t (or F) → bonds.f_t and f_c → bonds.cohesion (its own parameter, so f_c/f_t
is fitted, not measured), in turn until both hold; then G_F → bonds.G_I with bonds.G_II moved in proportion (their
ratio as the scenario gives it: the notched beam's crack runs along the polygons' inclined edges in mixed mode,
so G_F depends on both, and G_I alone left it out of reach once the cohesion had risen to concrete's f_c — at
full size G_I = 38.5 N/m gave 141.7 N/m with c = 6 MPa, G_II = 160 N/m and 480.5 N/m with c = 18 MPa,
G_II = 1000 N/m); rounds of both (:func:`_interface_fits`) until the strengths hold at the fracture energies G_F
was measured with.  Every test of such a calibration must bond by interfaces too.

The calibrated scenario (:func:`write_calibrated`) extends the original and carries every override the
calibration ran with — each ``--set`` (the tables they changed, arrays whole) and the specimen seed — so that it
reproduces the achieved values it states.
"""

from __future__ import annotations

import math
import re
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..errors import PolydemError

UNITS = {
    "dyn/cm2": 1.0,
    "dyn/cm^2": 1.0,
    "pa": 10.0,
    "kpa": 1e4,
    "mpa": 1e7,
    "gpa": 1e10,
    "n/mm2": 1e7,
    "n/mm^2": 1e7,
    "n/cm2": 1e5,
}
NU_RANGE = (-0.99, 0.49)
#: the edge interfaces' nu (k_s/k_n = (1 - 3 nu)/(1 + nu) >= 0: nu <= 1/3)
NU_RANGE_INTERFACE = (-0.99, 0.33)
#: targets that are not stresses: (their units in the cgs unit, what a missing unit is called, the unit of the
#: example, the units listed, why a value <= 0 is refused)
MAGNITUDES = {
    "F": (
        {"dyn": 1.0, "n": 1e5, "kn": 1e8},
        "force's unit",
        "kN",
        "kN, N, dyn",
        "the peak load F is a magnitude, above zero",
    ),
    "G_F": (
        {"n/m": 1e3, "j/m2": 1e3, "j/m^2": 1e3, "erg/cm2": 1.0, "erg/cm^2": 1.0},
        "unit",
        "N/m",
        "N/m, J/m2, erg/cm2",
        "the fracture energy G_F is above zero",
    ),
}


class CalibrationError(PolydemError):
    """A target that cannot be met with the parameters allowed to vary (the message says the reachable range)."""


def parse_target(text: str) -> tuple:
    """``'E=33.5GPa'`` → ('E', 3.35e11) in dyn/cm²; ``nu=0.2`` → ('nu', 0.2).  Refused (ValueError, naming the
    target): a stress or force without its unit, an unknown unit, a value that is not a finite number, E, f_t, F
    not above zero (f_c may be given with either sign: its magnitude is fitted)."""
    d = re.fullmatch(r"\s*dif\s*=\s*([0-9.eE+]+)\s*@\s*([0-9.eE+-]+)\s*", text)
    if d:
        try:
            ratio, rate = float(d.group(1)), float(d.group(2))
        except ValueError:
            ratio = rate = math.nan
        if not (ratio > 1.0 and rate > 0.0 and math.isfinite(ratio) and math.isfinite(rate)):
            raise ValueError(f"--target {text}: dif=<ratio > 1>@<strain rate 1/s>, e.g. dif=1.15@2.5e-2")
        return "dif", (ratio, rate)
    m = re.fullmatch(r"\s*(E|nu|f_t|f_c|F|G_F)\s*=\s*([-+0-9.eE]+)\s*([A-Za-z/^0-9²]*)\s*", text)
    if not m:
        raise ValueError(
            f"--target {text}: expected E=<value>[GPa|MPa|Pa], nu=<value>, f_t=<value>[MPa], f_c=<value>[MPa], "
            f"F=<value>[kN|N] (peak load) or G_F=<value>[N/m] (fracture energy)"
        )
    key, unit = m.group(1), m.group(3).lower().replace("²", "2")
    try:
        val = float(m.group(2))
    except ValueError:
        val = math.nan
    if not math.isfinite(val):
        raise ValueError(f"--target {text}: {m.group(2)!r} is not a finite number")
    if key == "nu":
        if unit:
            raise ValueError(f"--target {text}: nu has no unit")
        return key, val
    if key in MAGNITUDES:  # a force or an energy: its own units, above zero
        units, name, example, listed, positive = MAGNITUDES[key]
        if not unit:
            raise ValueError(f"--target {text}: give the {name}, e.g. {key}={val:g}{example} ({listed})")
        if unit not in units:
            what = name.replace("'s", "")  # "force unit", "unit"
            raise ValueError(f"--target {text}: unknown {what} {m.group(3)!r} ({listed})")
        if val <= 0.0:
            raise ValueError(f"--target {text}: {positive}")
        return key, val * units[unit]
    if not unit:
        raise ValueError(
            f"--target {text}: give the unit, e.g. {key}={val:g}{'GPa' if key == 'E' else 'MPa'} "
            "(GPa, MPa, kPa, Pa, N/mm2, N/cm2, dyn/cm2)"
        )
    if unit not in UNITS:
        raise ValueError(f"--target {text}: unknown unit {m.group(3)!r} (GPa, MPa, kPa, Pa, N/mm2, N/cm2, dyn/cm2)")
    if key == "E" and val <= 0.0:
        raise ValueError(f"--target {text}: Young's modulus E must be above zero")
    if key == "f_t" and val <= 0.0:
        raise ValueError(f"--target {text}: f_t is the tensile strength, above zero (a compressive one is f_c)")
    if key == "f_c" and val == 0.0:
        raise ValueError(f"--target {text}: the compressive strength f_c cannot be zero")
    return key, val * UNITS[unit]


def _resolved(scenario, overrides) -> dict:
    """The validated scenario (values only; no specimen is built)."""
    from ..scenario.load import load_scenario

    return load_scenario(scenario, overrides)[0]


def _system(scenario, overrides):
    from ..scenario.build import build_system
    from ..scenario.load import load_scenario

    sc, _ = load_scenario(scenario, overrides)
    return build_system(sc, str(scenario))


def elastic(scenario, overrides, E_target=None, nu_target=None, log=print) -> dict:
    """(E_h, ν_h) for the targets (either may be None: then that beam value is kept) and the achieved E, ν."""
    from scipy.optimize import brentq

    from ..analysis.elastic import static_response
    from ..interactions.bonds.family import BEAM_BONDS

    solves = [0]
    system = _system(scenario, overrides)  # built once: only the beams' E_h and nu_h change between solves
    base = system.scenario["bonds"]
    net = BEAM_BONDS.network(system)
    E_beams = net.E.copy()  # the scenario's E_h with its per-beam perturbation factors

    def resp(E_h, nu_h):
        solves[0] += 1
        net.E = E_beams * (E_h / float(base["E"]))
        net.nu = np.full(net.n, float(nu_h))
        st = static_response(system)
        return st["E"], st["nu"]

    nu_h = float(base["nu"])
    rng = NU_RANGE_INTERFACE if BEAM_BONDS.interface(system) else NU_RANGE
    if nu_target is not None:
        lo, hi = resp(1.0, rng[0])[1], resp(1.0, rng[1])[1]
        if not min(lo, hi) <= nu_target <= max(lo, hi):
            raise CalibrationError(
                f"nu = {nu_target:g} cannot be reached by varying bonds.nu in [{rng[0]}, {rng[1]}]: this "
                f"specimen's Poisson ratio lies between {min(lo, hi):.4f} and {max(lo, hi):.4f} (the beam lattice's "
                f"geometry bounds it)"
            )
        nu_h = brentq(lambda q: resp(1.0, q)[1] - nu_target, *rng, xtol=1e-6)
    E1, nu_got = resp(1.0, nu_h)
    E_h = float(base["E"]) if E_target is None else E_target / E1
    E_got = E_h * E1
    log(
        f"  elastic: E_h = {E_h:.6g} dyn/cm², nu_h = {nu_h:.5f} -> E = {E_got / 1e10:.4g} GPa, nu = {nu_got:.4f} ({solves[0]} static solves)"
    )
    return {"E_h": E_h, "nu_h": nu_h, "E": E_got, "nu": nu_got, "static_solves": solves[0]}


class _Prefixed:
    """A text stream that puts ``prefix`` before every progress line it passes on (a run's progress inside a
    calibration: which run it is)."""

    def __init__(self, stream, prefix):
        self.stream, self.prefix = stream, prefix

    def isatty(self):
        return hasattr(self.stream, "isatty") and self.stream.isatty()

    def write(self, text):
        if text.startswith("\r"):
            text = "\r" + self.prefix + text[1:]
        elif text.strip():
            text = self.prefix + text
        return self.stream.write(text)

    def flush(self):
        self.stream.flush()


def peak_stress(scenario, overrides, workdir, tag, measure="stress", progress=None) -> tuple:
    """(peak |σ22| in dyn/cm² — or with ``measure="load"`` the peak |f2| of the driven set in dyn —, wall s) of a
    dynamic run of the scenario stopped just past the peak; ``progress``: a stream for the run's progress lines
    (default: none)."""
    from ..scenario.load import load_scenario
    from ..scenario.spec import ScenarioError
    from ..solvers import driver
    from ..solvers.protocol import RunOptions, Source

    ov = list(overrides) + ["time.end_load_drop=0.9"]

    def out_of_reach(e):
        return CalibrationError(
            f"{overrides[-1]} is not a valid value for this scenario ({e.reason}); the target may be out of reach"
        )

    try:
        sc, text = load_scenario(scenario, ov)
    except ScenarioError as e:
        raise out_of_reach(e) from None
    out = Path(workdir) / f"{tag}.h5"
    out.parent.mkdir(parents=True, exist_ok=True)
    quiet = progress is None
    stream = None if quiet else _Prefixed(progress, f"    {out.parent.name}/{tag}: ")
    t0 = time.time()
    try:  # a run of an earlier, interrupted calibration is reused (finished) or resumed when it is the same run
        sm = driver.obtain(
            sc,
            out,
            source=Source(str(scenario), text, tuple(ov)),
            policy=driver.REFRESH,
            opts=RunOptions(quiet=quiet, stream=stream, threads=1),
        ).summary
    except ScenarioError as e:
        raise out_of_reach(e) from None
    if sm.get("status") != "finished":
        raise CalibrationError(f"{scenario}: the run with {overrides[-1]} did not finish ({sm.get('failure')})")
    if "was not met" in (sm.get("end_reason") or ""):  # ended before the drop: is the peak inside the run?
        m = sm.get("macro") or {}
        peaks = [v for k, v in (sm["observables"].get("peaks") or {}).items() if k.startswith("f2:")]
        inside = (
            (m.get("final_stress_over_peak", 1.0) < 0.99 or _peak_early(out, m))
            if measure == "stress" and m
            else bool(peaks) and max(peaks, key=lambda v: abs(v["value"]))["time"] < 0.98 * sm["time"]
        )
        if not inside:
            raise CalibrationError(
                f"{scenario}: the run with {overrides[-1]} ended while the load was still at its maximum "
                f"({sm['end_reason']}); the strength cannot be read: give the scenario a longer end_time / "
                f"end_displacement"
            )
    if measure == "load":
        peaks = [abs(v["value"]) for k, v in (sm["observables"].get("peaks") or {}).items() if k.startswith("f2:")]
        if not peaks:
            raise CalibrationError(f"{scenario}: a load target needs a loaded set (a boundary entry with moving x2)")
        return max(peaks), time.time() - t0
    if not sm.get("macro"):
        raise CalibrationError(
            f"{scenario}: a strength target needs the [macro] table (the stress measure); use F=<peak load> instead"
        )
    return abs(float(sm["macro"]["peak_stress"])), time.time() - t0


def _peak_early(result, macro) -> bool:
    """The peak lies well inside a run that ended on a plateau: its strain is below 0.9 of the final strain."""
    from ..io.hdf5 import read_history

    cols, tab = read_history(result)
    e = np.abs(tab[:, cols.index("eps22")])
    return abs(float(macro.get("strain_at_peak", 0.0))) < 0.9 * float(e.max())


def _log_secant(f, x0, target, rel_tol, max_runs, not_met, flat, stuck=None):
    """x with f(x) within ``rel_tol`` of ``target`` for a response that rises with x about in proportion: the
    secant method on log f(log x), from x0 and the proportional guess, each step at most a factor 4; ``not_met(pts)``
    and ``flat(x0, x1, p1)`` make the errors of too many runs and of a response that does not change;
    ``stuck(pts, s)``, if given, that of a secant slope d log f / d log x below :data:`FLAT_SLOPE` while the target
    lies beyond the values reached (out of reach of this parameter).  Returns (x, f(x), the (x, f) pairs run)."""
    pts = []

    def g(x):
        p = f(x, len(pts))
        pts.append((x, p))
        return p

    p0 = g(x0)
    if abs(p0 / target - 1.0) <= rel_tol:
        return x0, p0, pts
    x1 = x0 * min(max(target / p0, 0.25), 4.0)  # proportional guess, at most a factor 4
    p1 = g(x1)
    while abs(p1 / target - 1.0) > rel_tol:
        if len(pts) >= max_runs:
            raise CalibrationError(not_met(pts, x1, p1))
        if abs(p1 - p0) <= 1e-6 * abs(p0):
            raise CalibrationError(flat(x0, x1, p1))
        if x1 == x0:
            x2 = x1 * min(max(target / p1, 0.25), 4.0)
        else:
            s = (math.log(p1) - math.log(p0)) / (math.log(x1) - math.log(x0))  # d log f / d log x
            got = [p for _, p in pts]
            if stuck is not None and s < FLAT_SLOPE and not min(got) <= target <= max(got):
                raise CalibrationError(stuck(pts, s))
            s = s if s > 0.05 else 1.0  # a flat or falling secant: the proportional step
            x2 = x1 * min(max(math.exp((math.log(target) - math.log(p1)) / s), 0.25), 4.0)
        x0, p0, x1 = x1, p1, x2
        p1 = g(x1)
    return x1, p1, pts


#: a secant slope d log f / d log x below this declares a target beyond the values reached out of reach (G_F)
FLAT_SLOPE = 0.1


def strength(
    scenario,
    overrides,
    target,
    workdir,
    rel_tol=0.005,
    max_runs=8,
    log=print,
    measure="stress",
    progress=None,
    tag="",
    key="kappa_0",
) -> dict:
    """The bonds' ``key`` (κ_0 of the beams; f_t or cohesion of edge interfaces) that gives the peak stress (or
    peak load, ``measure="load"``) ``target`` (secant on log–log, from the scenario's value with the overrides); its
    runs are called ``<tag><key>_<n>`` in ``workdir`` (``kappa0_<n>`` for κ_0)."""
    base = _resolved(scenario, overrides)["bonds"]
    walls = 0.0
    stem = "kappa0" if key == "kappa_0" else key

    def f(k, n):
        nonlocal walls
        p, w = peak_stress(
            scenario, list(overrides) + [f"bonds.{key}={k!r}"], workdir, f"{tag}{stem}_{n}", measure, progress
        )
        walls += w
        shown = f"{p / 1e8:.4g} kN" if measure == "load" else f"{p / 1e7:.4g} N/mm²"
        log(f"  run {n + 1}: {key} = {k:.6g} -> peak {shown} ({w:.0f} s)")
        return p

    def not_met(pts, k1, p1):
        return (
            f"strength {target / 1e7:g} N/mm² not met within {max_runs} runs (last {p1 / 1e7:.4g} N/mm² at "
            f"{key} = {k1:.6g}); the peaks found: " + ", ".join(f"{p / 1e7:.4g} at {k:.4g}" for k, p in pts)
        )

    def flat(k0, k1, p1):
        return (
            f"the peak does not change with {key} ({p1:.6g} at {key} = {k0:.4g} and {k1:.4g}): bond "
            f"damage does not limit the load in this run (does it reach its real peak?)"
        )

    k, p, pts = _log_secant(f, float(base[key]), target, rel_tol, max_runs, not_met, flat)
    return {key: k, "peak": p, "runs": len(pts), "run_wall_s": walls, "trace": pts}


def fracture_run(scenario, overrides, workdir, tag, progress=None) -> dict:
    """A whole three-point bending test of a notched beam (to its scenario's own end): its fracture energy G_F
    (RILEM TC-50, erg/cm²), whether its load came down below 5 % of the peak (``complete``), its peak load and its
    wall time (:func:`polydem_cli.workflows.lab.numbers`)."""
    from ..scenario.load import load_scenario
    from ..scenario.spec import ScenarioError
    from ..solvers import driver
    from ..solvers.protocol import RunOptions, Source
    from .lab import LabError, numbers

    try:
        sc, text = load_scenario(scenario, overrides)
    except ScenarioError as e:
        raise CalibrationError(f"{overrides[-1]} is not a valid value for {scenario} ({e.reason})") from None
    out = Path(workdir) / f"{tag}.h5"
    out.parent.mkdir(parents=True, exist_ok=True)
    stream = None if progress is None else _Prefixed(progress, f"    {out.parent.name}/{tag}: ")
    t0 = time.time()
    sm = driver.obtain(
        sc,
        out,
        source=Source(str(scenario), text, tuple(overrides)),
        policy=driver.REFRESH,
        opts=RunOptions(quiet=progress is None, stream=stream, threads=1),
    ).summary
    if sm.get("status") != "finished":
        raise CalibrationError(f"{scenario}: the run with {overrides[-1]} did not finish ({sm.get('failure')})")
    try:
        n = numbers(out)
    except LabError as e:
        raise CalibrationError(str(e)) from None
    from ..analysis.lab import N_PER_M

    return {
        "G_F": n["G_F"] * N_PER_M,
        "complete": n["complete"],
        "end_fraction": n["end_fraction"],
        "peak": n["peak_force"],
        "wall": time.time() - t0,
    }


def fracture_energy_fit(
    scenario,
    overrides,
    target,
    workdir,
    rel_tol=0.01,
    max_runs=8,
    log=print,
    progress=None,
    tag="",
    key="G_ax",
    follow=None,
):
    """bonds.G_ax (edge interfaces: ``key`` = G_I) that gives the fracture energy ``target`` (erg/cm²) in the notched
    beam's three-point bending (secant on log–log from the scenario's value with the overrides; runs
    ``<tag><key>_<n>`` in ``workdir``).  ``follow``: other bonds keys set in proportion, ``{"G_II": ρ}`` sets
    G_II = ρ · G_I in every run (returned beside ``key``)."""
    base = _resolved(scenario, overrides)["bonds"]
    if key == "G_ax" and base.get("G_ax") is None:
        raise CalibrationError(
            f"--target G_F: {scenario} gives its beams kappa_m, not G_ax: G_F is fitted with bonds.G_ax (5.12)"
        )
    walls, last = 0.0, {}

    follow = dict(follow or {})

    def with_(g):
        return [f"bonds.{k}={rho * g!r}" for k, rho in follow.items()] + [f"bonds.{key}={g!r}"]

    def f(g, n):
        nonlocal walls
        r = fracture_run(scenario, list(overrides) + with_(g), workdir, f"{tag}{key}_{n}", progress)
        walls += r["wall"]
        last.update(r)
        log(f"  run {n + 1}: {key} = {g:.6g} -> G_F {r['G_F'] / 1e3:.4g} N/m ({r['wall']:.0f} s)")
        if not r["complete"]:
            raise CalibrationError(
                f"{scenario}: the run with bonds.{key} = {g:.6g} ended with the load at {r['end_fraction']:.0%} of its "
                "peak, not below 5 %: its G_F misses the curve's tail (a lower bound), so G_F cannot be fitted on it; "
                "give the test a longer time.end_displacement (and time.end_load_drop = 0.05)"
            )
        return r["G_F"]

    def not_met(pts, g1, p1):
        return f"G_F {target / 1e3:g} N/m not met within {max_runs} runs: " + ", ".join(
            f"{p / 1e3:.4g} N/m at {key} {g:.4g}" for g, p in pts
        )

    def flat(g0, g1, p1):
        return f"G_F does not change with {key} ({p1 / 1e3:.4g} N/m at {key} = {g0:.4g} and {g1:.4g})"

    def stuck(pts, s):
        got = sorted(p for _, p in pts)
        return (
            f"G_F {target / 1e3:g} N/m is out of reach by varying bonds.{key}: G_F moved only from {got[0] / 1e3:.4g} to "
            f"{got[-1] / 1e3:.4g} N/m over {key} " + ", ".join(f"{g:.4g}" for g, _ in pts) + f" (d ln G_F / d ln {key} "
            f"= {s:.3g}); the bonds' fracture energy no longer sets the specimen's (its cracking runs through contact "
            "friction and the specimen's geometry)"
        )

    g, p, pts = _log_secant(f, float(base[key]), target, rel_tol, max_runs, not_met, flat, stuck)
    out = {key: g, "G_F": p, "G_F_complete": last.get("complete"), "G_F_runs": len(pts), "G_F_wall_s": walls}
    out.update({k: rho * g for k, rho in follow.items()})
    return out


#: the beam parameter each target is fitted with
NEEDS = {
    "E": "bonds.E",
    "nu": "bonds.nu",
    "f_t": "bonds.kappa_0",
    "f_c": "bonds.kappa_0",
    "F": "bonds.kappa_0",
    "dif": "bonds.alpha",
    "G_F": "bonds.G_ax",
}


#: a dif target is declared out of reach when the specimen's peak ratio responds to alpha with less than this
#: fraction of a single beam's response ln(rate / eps0_dot): the chapter-5 specimen responds with 0.7 (tension)
#: and 1.15 (compression) of it in the thesis's Table 5.1 (ours: 0.49 and 1.07), the concrete at 2.5e-2 1/s
#: with 0.05 (docs/reproduction.md)
FLAT_RESPONSE = 0.25


def rate_exponent(
    scenario, overrides, ratio, rate, p_ref, workdir, rel_tol=0.005, max_runs=8, log=print, progress=None
) -> dict:
    """α of the rate-dependent beams (5.13) that gives the peak ratio ``ratio`` at the macroscopic strain rate
    ``rate`` over the reference peak ``p_ref`` (the thesis's normalisation: the slow rate-independent run).
    Secant on log(peak ratio) against α (about proportional), from the scenario's α (0.13 if unset)."""
    from .dif import rate_overrides

    unset = _resolved(scenario, overrides)["bonds"]["alpha"] is None
    system = _system(
        scenario, list(overrides) + ["bonds.rate_dependent=true"] + (["bonds.alpha=0.13"] if unset else [])
    )
    a0 = float(system.scenario["bonds"]["alpha"])
    rov = rate_overrides(system, rate)
    pts = []

    ends = [o for o in overrides if o.startswith("time.end_")]  # the user's end criteria win over the rate's

    def g(a):
        p, w = peak_stress(
            scenario,
            list(overrides) + ["bonds.rate_dependent=true"] + rov + ends + [f"bonds.alpha={a!r}"],
            workdir,
            f"alpha_{len(pts)}",
            progress=progress,
        )
        pts.append((a, p / p_ref))
        log(f"  run {len(pts)}: alpha = {a:.5g} at {rate:g} 1/s -> peak ratio {p / p_ref:.4f} ({w:.0f} s)")
        return p / p_ref

    eps0 = float(system.scenario["bonds"]["eps0_dot"])
    s_beam = math.log(rate / eps0) if rate > eps0 else 0.0  # d ln(kappa_0,ra / kappa_0) / d alpha of one beam (5.13)

    r0 = g(a0)
    a1 = a0 * math.log(ratio) / math.log(r0) if r0 > 1.0 + 1e-6 else 2.0 * a0
    a1 = min(max(a1, 0.25 * a0), 4.0 * a0)
    r1 = g(a1)
    while abs(r1 / ratio - 1.0) > rel_tol:
        if abs(r1 - r0) < 1e-9:
            raise CalibrationError(
                f"the peak ratio does not change with alpha ({r1:.4f} at alpha = {a0:.4g} and {a1:.4g}): at "
                f"{rate:g} 1/s the beams' strain rates stay below eps0_dot, where (5.13) has no rate effect"
            )
        s_ = (math.log(r1) - math.log(r0)) / (a1 - a0)
        if s_ < FLAT_RESPONSE * s_beam:
            reached = sorted(r for _, r in pts)
            need = a1 + (math.log(ratio) - math.log(r1)) / s_ if s_ > 0 else math.inf
            raise CalibrationError(
                f"dif {ratio:g} at {rate:g} 1/s is out of reach by varying bonds.alpha: from alpha = {a0:.4g} to "
                f"{a1:.4g} the peak ratio moved only from {r0:.4f} to {r1:.4f} (d ln ratio / d alpha = {s_:.3g}, "
                f"under {FLAT_RESPONSE:g} x the single beam's ln({rate:g} / {eps0:g}) = {s_beam:.3g}); reached: "
                f"{reached[0]:.4f} to {reached[-1]:.4f}. At this slope the target needs alpha = {need:.3g}. The "
                f"specimen's strength does not follow the beams' mean strain rate: where the instantaneous rates "
                f"(5.16) oscillate below eps0_dot, (5.13) gives kappa_0 and the damage (5.15), a maximum over time, "
                f"keeps those instants (a damage equal to the rate-independent one at each beam's largest strain)"
            )
        if len(pts) >= max_runs:
            raise CalibrationError(
                f"dif {ratio:g} at {rate:g} 1/s not met within {max_runs} runs: "
                + ", ".join(f"{r:.4f} at alpha {a:.4g}" for a, r in pts)
            )
        a2 = a1 + (math.log(ratio) - math.log(r1)) / s_ if s_ > 0 else 2.0 * a1
        a2 = min(max(a2, 0.25 * a1), 4.0 * a1)
        a0, r0, a1 = a1, r1, a2
        r1 = g(a1)
    return {"alpha": a1, "dif": r1, "dif_runs": len(pts), "dif_trace": pts}


#: how often the strength (κ_0) and the fracture energy (G_ax) fits alternate at most
#: the edge interfaces' parameter of each target ([bonds] model = "interface"): f_c has its own, the cohesion
NEEDS_INTERFACE = {
    "E": "bonds.E",
    "nu": "bonds.nu",
    "f_t": "bonds.f_t",
    "f_c": "bonds.cohesion",
    "F": "bonds.f_t",
    "dif": "bonds.alpha",
    "G_F": "bonds.G_I",  # and bonds.G_II in proportion
}

ROUNDS = 4


@dataclass(frozen=True)
class Plan:
    """What one calibration does on every specimen seed (checked by :func:`calibrate`): the ``targets`` on the
    ``scenario`` with its ``overrides``, each on its test's scenario (``tests``: target → scenario, default the
    ``scenario``); runs kept in ``workdir``; strengths fitted to ``rel_tol``; ``p_ref`` the reference peak of a dif
    target given by a finished result (else the strength run's); ``strength_key`` the strength target fitted with
    κ_0 (f_t, f_c or F; None without one).  Picklable: seeds calibrated in parallel processes get it whole."""

    scenario: Path
    targets: dict
    overrides: tuple = ()
    workdir: Path = Path(".")
    rel_tol: float = 0.005
    p_ref: float | None = None
    strength_key: str | None = None
    tests: dict = field(default_factory=dict)

    def at(self, key: str) -> Path:
        """The scenario that measures target ``key``."""
        return self.tests.get(key, self.scenario)


def _calibrate_seed(plan: Plan, seed, log=print, progress=None):
    """The calibration on one specimen seed: elastic (static), strength (κ_0) alternating with the fracture energy
    (G_ax), a second strength measured, rate (α), in that order (module docstring); each target on its test's
    scenario (:meth:`Plan.at`)."""
    scenario, targets, workdir, rel_tol = plan.scenario, plan.targets, plan.workdir, plan.rel_tol
    strength_key, at = plan.strength_key, plan.at
    ov = list(plan.overrides) + [f"scenario.seed={int(seed)}"]
    if "dif" in targets:  # the strength and its reference: rate-independent beams (the thesis's slow ru run)
        ov.append("bonds.rate_dependent=false")
    log(f"seed {seed}:")
    row = {"seed": int(seed)}
    wd = workdir / f"seed{seed}"
    # the parameters each target is fitted with: NEEDS (beams), NEEDS_INTERFACE (edge interfaces)
    iface = _resolved(scenario, ov)["bonds"]["model"] == "interface"
    if "E" in targets or "nu" in targets:
        row.update(elastic(at("E" if "E" in targets else "nu"), ov, targets.get("E"), targets.get("nu"), log=log))
        ov += [f"bonds.E={row['E_h']!r}", f"bonds.nu={row['nu_h']!r}"]
    if iface:  # f_t and the cohesion, then G_F with G_I and G_II in proportion, in rounds
        ov = _interface_fits(plan, ov, row, wd, log, progress)
    else:  # kappa_0 and G_ax in turn; f_c measured
        ov = _beam_fits(plan, ov, row, wd, log, progress)
    if "dif" in targets:
        ratio, rate = targets["dif"]
        ov = [o for o in ov if o != "bonds.rate_dependent=false"]
        ref = plan.p_ref if plan.p_ref is not None else row["peak"]
        row.update(  # on the strength's test: its peak is the reference
            rate_exponent(
                at(strength_key) if strength_key else scenario,
                ov,
                ratio,
                rate,
                ref,
                workdir / f"seed{seed}",
                rel_tol,
                log=log,
                progress=progress,
            )
        )
    return row


def _set_bond(ov, key, value) -> list:
    """The overrides ``ov`` with ``bonds.<key>`` set to ``value`` (an earlier setting of it dropped)."""
    return [o for o in ov if not o.startswith(f"bonds.{key}=")] + [f"bonds.{key}={value!r}"]


def _fit_strength(plan: Plan, ov, tkey, bkey, wd, log, progress, tag) -> dict:
    """:func:`strength` of target ``tkey`` on its test, fitted with ``bonds.<bkey>`` (a peak load for F)."""
    return strength(
        plan.at(tkey),
        ov,
        abs(plan.targets[tkey]),
        wd,
        plan.rel_tol,
        log=log,
        measure="load" if tkey == "F" else "stress",
        progress=progress,
        tag=tag,
        key=bkey,
    )


def _beam_fits(plan: Plan, ov, row, wd, log, progress) -> list:
    """The beams' strength (κ_0) alternating with G_F (G_ax) until both hold, then a second strength (f_c beside
    f_t) measured, not fitted (module docstring); fills ``row``, returns the overrides with the fitted values."""
    targets, rel_tol, strength_key, at = plan.targets, plan.rel_tol, plan.strength_key, plan.at
    skey, gkey = "kappa_0", "G_ax"
    for r in range(ROUNDS if "G_F" in targets else 1):
        if strength_key:
            if r:
                log(f"  {strength_key} again with {gkey} = {row[gkey]:.6g}:")
            st = _fit_strength(plan, ov, strength_key, skey, wd, log, progress, f"r{r}_" if r else "")
            row.update({skey: st[skey], "peak": st["peak"]})
            row["runs"] = row.get("runs", 0) + st["runs"]
            row["run_wall_s"] = row.get("run_wall_s", 0.0) + st["run_wall_s"]
            ov = _set_bond(ov, skey, st[skey])
            if r and st["runs"] == 1:  # the strength held at the new G_ax: both hold
                break
        if "G_F" not in targets:
            break
        log(f"  G_F on {at('G_F')}:")
        gf = fracture_energy_fit(
            at("G_F"), ov, targets["G_F"], wd, max(rel_tol, 0.01), log=log, progress=progress, tag=f"r{r}_", key=gkey
        )
        runs = gf.pop("G_F_runs")
        row["G_F_runs"] = row.get("G_F_runs", 0) + runs
        row["G_F_wall_s"] = row.get("G_F_wall_s", 0.0) + gf.pop("G_F_wall_s")
        row.update(gf)
        ov = _set_bond(ov, gkey, gf[gkey])
        if not strength_key or runs == 1:  # G_F held at the kappa_0 the strength just got: both hold
            break
    else:
        if "G_F" in targets and strength_key:
            raise CalibrationError(
                f"{strength_key} and G_F did not hold together after {ROUNDS} rounds of fitting {skey} and {gkey} in "
                f"turn (last: {skey} = {row[skey]:.6g}, {gkey} = {row[gkey]:.6g})"
            )
    if strength_key == "f_t" and "f_c" in targets:  # measured, not fitted (module docstring)
        log(f"  f_c on {at('f_c')} (not fitted: kappa_0 is set by f_t):")
        p, w = peak_stress(at("f_c"), ov, wd, "f_c_check", progress=progress)
        want = abs(targets["f_c"])
        row.update(f_c=p, f_c_wall_s=w, f_c_over_f_t=p / row["peak"])
        log(f"  f_c = {p / 1e7:.4g} N/mm² ({w:.0f} s): f_c/f_t = {p / row['peak']:.3g} with these beams")
        if abs(p / want - 1.0) > rel_tol:
            k_alone = row["kappa_0"] * want / p  # the strengths scale about in proportion with kappa_0
            row["unreached"] = {
                "f_c": (
                    f"f_c {want / 1e7:g} N/mm² not reached with f_t {row['peak'] / 1e7:.4g} N/mm²: these beams give "
                    f"f_c/f_t = {p / row['peak']:.3g}, the targets ask {want / abs(targets['f_t']):.3g}; f_c alone "
                    f"would need kappa_0 ≈ {k_alone:.4g} (f_t then ≈ {row['peak'] * want / p / 1e7:.3g} N/mm², "
                    "both about proportional to kappa_0)"
                )
            }
            log("  " + row["unreached"]["f_c"])
    return ov


def _interface_fits(plan: Plan, ov, row, wd, log, progress) -> list:
    """The edge interfaces' strengths and fracture energy, in rounds (at most :data:`ROUNDS`): the first strength
    (f_t or F with bonds.f_t; f_c alone with the cohesion) and, with f_c beside it, f_c with bonds.cohesion (with
    ``crack_criterion = "principal"``: bonds.crack_strength), in turn until both hold; then G_F with G_I and G_II moved in proportion (:func:`fracture_energy_fit`, ``follow``);
    a round after a G_F that moved measures the strengths again, and the calibration ends when a round's strengths
    held at their values (so every achieved value was measured with the final parameters).  Fills ``row``, returns
    the overrides with the fitted values."""
    targets, rel_tol, sk, at = plan.targets, plan.rel_tol, plan.strength_key, plan.at
    b0 = _resolved(at(sk) if sk else at("G_F"), ov)["bonds"]
    c_key = "cohesion"
    if b0["crack_criterion"] == "principal":
        # the crack strength sets f_c (the panel splits along the load), the edges' f_t sets f_t (docs/interface.md)
        c_key = "crack_strength"
        if b0["crack_strength"] is None:
            ov = _set_bond(ov, c_key, float(b0["f_t"]))
    fits = []  # (target, its bonds key)
    if sk:
        fits.append((sk, c_key if sk == "f_c" else "f_t"))
    if sk in ("f_t", "F") and "f_c" in targets:
        fits.append(("f_c", c_key))

    for r in range(ROUNDS):
        moved_any = False
        for k in range(ROUNDS):
            moved = False
            for tkey, bkey in fits:
                if r or k:
                    log(f"  {tkey} again ({bkey} = {row.get(bkey, 0.0):.6g}):")
                elif tkey == "f_c" and len(fits) > 1:
                    log(f"  f_c on {at('f_c')} with bonds.{c_key}:")
                st = _fit_strength(plan, ov, tkey, bkey, wd, log, progress, f"r{r}p{k}_" if (r or k) else "")
                ov = _set_bond(ov, bkey, st[bkey])
                row[bkey] = st[bkey]
                if tkey == sk:
                    row.update(peak=st["peak"], runs=row.get("runs", 0) + st["runs"])
                    row["run_wall_s"] = row.get("run_wall_s", 0.0) + st["run_wall_s"]
                else:
                    row.update(f_c=st["peak"])
                    row["f_c_wall_s"] = row.get("f_c_wall_s", 0.0) + st["run_wall_s"]
                moved |= st["runs"] > 1
            moved_any |= moved
            if not moved or len(fits) < 2:
                break
        else:
            raise CalibrationError(
                f"the strengths {', '.join(t for t, _ in fits)} did not hold together after {ROUNDS} passes of "
                "fitting " + ", ".join(f"{b} (last {row[b]:.6g})" for _, b in fits) + " in turn"
            )
        if "G_F" not in targets or (r and not moved_any):  # the strengths held at the G's G_F was measured with
            break
        base = _resolved(at("G_F"), ov)["bonds"]
        ratio = float(base["G_II"]) / float(base["G_I"])
        log(f"  G_F on {at('G_F')} (G_I, with G_II = {ratio:.4g} G_I):")
        gf = fracture_energy_fit(
            at("G_F"),
            ov,
            targets["G_F"],
            wd,
            max(rel_tol, 0.01),
            log=log,
            progress=progress,
            tag=f"r{r}_",
            key="G_I",
            follow={"G_II": ratio},
        )
        runs = gf.pop("G_F_runs")
        row["G_F_runs"] = row.get("G_F_runs", 0) + runs
        row["G_F_wall_s"] = row.get("G_F_wall_s", 0.0) + gf.pop("G_F_wall_s")
        row.update(gf)
        ov = _set_bond(_set_bond(ov, "G_I", gf["G_I"]), "G_II", gf["G_II"])
        if runs == 1:  # G_F held at the strengths just fitted: all hold
            break
    else:
        raise CalibrationError(
            f"the strengths and G_F did not hold together after {ROUNDS} rounds (last: "
            + ", ".join(f"{k} = {row[k]:.6g}" for k in ("f_t", "cohesion", "crack_strength", "G_I", "G_II") if k in row)
            + ")"
        )
    if "f_c" in row and sk == "f_t":  # (beside a peak load F the ratio would mix a stress and a force)
        row["f_c_over_f_t"] = row["f_c"] / row["peak"]
        log(f"  f_c = {row['f_c'] / 1e7:.4g} N/mm²: f_c/f_t = {row['f_c_over_f_t']:.3g}")
    return ov


def _seed_quiet(plan: Plan, seed):
    """:func:`_calibrate_seed` in a worker process: (row, its log lines)."""
    lines = []
    return _calibrate_seed(plan, seed, log=lines.append), lines


def calibrate(
    scenario,
    targets: dict,
    overrides=(),
    seeds=None,
    workdir=None,
    rel_tol=0.005,
    log=print,
    vary=None,
    reference=None,
    progress=None,
    jobs=1,
    tests=None,
) -> dict:
    """Calibrate on the scenario's specimen (and on each of ``seeds``); returns fitted and achieved values.
    ``vary``: the parameters allowed to change (default: those the targets need, :data:`NEEDS`);
    ``reference``: a finished result whose peak stress is the reference of a ``dif`` target (instead of the
    strength run; e.g. the slow rate-independent run, when the scenario's own time step is the fine one of the
    rate-dependent beams).  Runs are kept in ``workdir``: an interrupted calibration started again with the same
    arguments reuses its finished runs and resumes the interrupted one; a calibration that fails (a target out of
    reach, a run that does not finish) removes the runs it made.  Targets the scenario cannot measure are refused
    before anything is made (:func:`check_measurable`).  ``progress``: a stream for the dynamic
    runs' progress lines, each prefixed with its run (default: none); ``jobs``: seeds calibrated in parallel
    processes (their lines printed per seed as it finishes; no progress lines); ``tests``: target → the scenario
    that measures it (default: ``scenario``; module docstring)."""
    import tempfile

    iface = (_resolved(scenario, overrides).get("bonds") or {}).get("model") == "interface"
    needs = NEEDS_INTERFACE if iface else NEEDS
    if vary is not None:
        unknown = sorted(set(vary) - set(needs.values()))
        if unknown:
            raise CalibrationError(f"--vary {','.join(unknown)}: can vary {', '.join(sorted(set(needs.values())))}")
        for k in targets:
            if needs[k] not in vary:
                raise CalibrationError(
                    f"target {k} is fitted with {needs[k]}, which --vary does not allow to change "
                    f"(allowed: {', '.join(vary)})"
                )
    strengths = {"f_t", "f_c", "F"} & set(targets)
    if len(strengths) > 1 and strengths != {"f_t", "f_c"}:
        raise CalibrationError(
            "give one strength target (f_t, f_c or F; or f_t and f_c, of which f_c is measured with beams and fitted "
            "with the cohesion of edge interfaces): each is fitted with bonds.kappa_0 (beams) or bonds.f_t"
        )
    scenario = Path(scenario)
    tests = {k: Path(v) for k, v in (tests or {}).items()}
    for k in tests:
        if k not in targets:
            raise CalibrationError(f"--test {k}=...: there is no target {k} to measure on it")

    def same(a, b):
        return Path(tests.get(a, scenario)).resolve() == Path(tests.get(b, scenario)).resolve()

    if "E" in targets and "nu" in targets and not same("E", "nu"):
        raise CalibrationError("--test: E and nu come from one static solve, so from one scenario")
    if {"f_t", "f_c"} <= set(targets) and same("f_t", "f_c"):
        raise CalibrationError(
            "--target f_t and f_c: one scenario measures one of them (pulled apart or pushed together); give the "
            "other's with --test, e.g. --test f_c=scenarios/concrete_compression.toml"
        )
    if "dif" in targets and not ({"f_t", "f_c"} & set(targets)) and reference is None:
        raise CalibrationError(
            "a dif target needs a reference peak: a strength target (f_t or f_c, whose run is it) or --reference RESULT"
        )
    if iface and "dif" in targets:
        raise CalibrationError("--target dif: edge interfaces ([bonds] model = \"interface\") are rate-independent")
    for sc_, tg in _by_scenario(scenario, targets, tests).items():
        check_measurable(sc_, overrides, tg)
        model = (_resolved(sc_, overrides).get("bonds") or {}).get("model")
        if model != ("interface" if iface else "beam"):
            raise CalibrationError(
                f"--test: {sc_} bonds its particles by bonds.model = {model!r}, {scenario} by "
                f"{'interface' if iface else 'beam'!r}: every test of a calibration takes the same bonds (give "
                "the model and its values with --set, or a test scenario of the same material)"
            )
        if "G_F" in targets and not iface and (_resolved(sc_, overrides).get("bonds") or {}).get("G_ax") is None:
            raise CalibrationError(  # G_ax, fitted on the bending test, is set in every test's beams
                f"--target G_F: {sc_} gives its beams kappa_m, not G_ax: G_F is fitted with bonds.G_ax (5.12), "
                "which every test of the calibration takes"
            )
    p_ref = None
    if reference is not None:
        import json

        from ..io.hdf5 import ResultError, open_result

        try:
            with open_result(reference) as f:
                m = (json.loads(f.attrs["summary"]) if "summary" in f.attrs else {}).get("macro") or {}
        except ResultError as e:
            raise CalibrationError(str(e)) from None
        if "peak_stress" not in m:
            raise CalibrationError(f"{reference}: no macroscopic peak stress in its summary (a [macro] run, finished)")
        p_ref = abs(float(m["peak_stress"]))
    workdir = Path(workdir or tempfile.mkdtemp(prefix="polydem-calibrate-"))
    made = _missing_parents(workdir)
    workdir.mkdir(parents=True, exist_ok=True)
    before = _files(workdir)
    try:
        strength_key = next((k for k in ("f_t", "f_c", "F") if k in targets), None)
        plan = Plan(scenario, dict(targets), tuple(overrides), workdir, rel_tol, p_ref, strength_key, tests)
        return _calibrate(plan, seeds, log, progress, jobs)
    except Exception as e:
        from ..solvers.driver import Interrupted

        if not isinstance(e, Interrupted):  # a failed calibration: the runs it made go (an interrupted one resumes)
            for f in _files(workdir) - before:
                f.unlink(missing_ok=True)
        raise
    finally:  # the runs of a finished or interrupted calibration stay (started again, it reuses them); empty
        _remove_empty(workdir, made)  # folders do not


def _files(d: Path) -> set:
    """The files below ``d``."""
    return {p for p in Path(d).rglob("*") if p.is_file()}


def _missing_parents(d: Path) -> list:
    """``d`` and its ancestors that do not exist yet (innermost first)."""
    out = []
    d = d.absolute()
    while not d.exists() and d != d.parent:
        out.append(d)
        d = d.parent
    return out


def _remove_empty(workdir: Path, made: list) -> None:
    """Remove the empty folders below ``workdir``, then ``workdir`` and the parents this call made, if empty."""
    import os

    if workdir.exists():
        for root, _, _ in sorted(os.walk(workdir), key=lambda t: -len(t[0])):
            try:
                Path(root).rmdir()
            except OSError:
                pass  # not empty: finished runs to resume from
    for d in made:
        try:
            if d.exists():
                d.rmdir()
        except OSError:
            break


def check_measurable(scenario, overrides, targets) -> None:
    """Refuse (CalibrationError) targets the scenario cannot measure, before anything runs: no [bonds] to fit;
    E, nu, f_t, f_c without the [macro] table (the stress and strain measures of thesis §7.5.1) or with a load set
    whose x2 is not prescribed; F without a set whose x2 is driven; f_t on a specimen that is pushed together,
    f_c on one pulled apart, either on one the scenario neither pulls nor pushes along x2 (module docstring); G_F
    on anything but a notched beam (a Voronoi specimen of shape notched_beam, cut by clipping) driven along x2."""
    sc = _resolved(scenario, overrides)
    if "G_F" in targets:
        beams = [g for g in sc.get("particles", []) if g.get("type") == "voronoi" and g.get("shape") == "notched_beam"]
        if not beams or beams[0].get("cut") == "drop":
            raise CalibrationError(
                f"--target G_F: {scenario} is not a three-point bending test of a notched beam (a [[particles]] "
                "voronoi group with shape = 'notched_beam' and cut = 'clip'), so it cannot measure the fracture "
                "energy; give the test that does, e.g. --test G_F=scenarios/lab/three_point_bending.toml"
            )
    if "G_F" in targets and sc.get("bonds") and sc["bonds"].get("G_ax") is None:
        raise CalibrationError(
            f"--target G_F: {scenario} gives its beams kappa_m, not G_ax: G_F is fitted with bonds.G_ax (5.12)"
        )
    if not sc.get("bonds"):
        raise CalibrationError(
            f"{scenario}: no [bonds] table: calibrate fits the beams' parameters (bonds.E, bonds.nu, bonds.kappa_0), "
            "and this scenario has no beams"
        )
    system = _system(scenario, overrides)
    stress = [k for k in ("E", "nu", "f_t", "f_c", "dif") if k in targets]
    if stress and system.macro is None:
        raise CalibrationError(
            f"--target {stress[0]}: {scenario} has no [macro] table, so no macroscopic stress and strain to measure "
            "it with (give the table, or fit the peak load with F=<value>kN)"
        )
    if stress and not np.any(system.bc_kind[system.sets[system.macro.load_set], 1] != 0):
        raise CalibrationError(
            f"--target {stress[0]}: the [macro] load set {system.macro.load_set} has no prescribed x2, so the "
            "scenario does not load its specimen along x2"
        )
    loading = _loading(system)
    if "F" in targets and not _driven(system):
        raise CalibrationError(
            f"--target F: {scenario} drives no set along x2 (a boundary entry with an x2 velocity or displacement), "
            "so it has no peak load to fit"
        )
    for key, sign in {"f_t": 1, "f_c": -1}.items():
        if key not in targets:
            continue
        other = "f_t" if key == "f_c" else "f_c"
        if loading == 0:
            raise CalibrationError(
                f"--target {key}: {scenario} neither pulls its specimen apart nor pushes it together along x2 (no "
                f"set with an x2 velocity or displacement away from or towards its middle), so {key} cannot be read"
            )
        if loading != sign:
            said = "pulled apart (tension)" if loading > 0 else "pushed together (compression)"
            raise CalibrationError(
                f"--target {key}: this scenario's specimen is {said}; its peak stress is {other}, which "
                f"{key} cannot be fitted to (use a {'compression' if key == 'f_c' else 'tension'} scenario, or "
                f"measure {key} on one with --test {key}=SCENARIO)"
            )


def _driven(system) -> list:
    """(set, signed x2 velocity or displacement) of the boundary entries that move their set along x2."""
    out = []
    for b in system.scenario.get("boundary") or []:
        x2 = b.get("x2")
        if isinstance(x2, dict):
            v = x2.get("velocity") or x2.get("displacement")
            if v:
                out.append((b["set"], float(v)))
    return out


def _loading(system) -> int:
    """+1 if the prescribed x2 motions pull the specimen apart, −1 if they push it together, 0 if they do neither
    (a rigid motion): the sign of Σ_i (v_i − v̄)(y_i − ȳ) over the particles i whose x2 is prescribed (v_i their
    velocity, 0 if held, the displacement of a cosine motion; any set name, 'group[i]' too; v̄, ȳ their means),
    else of Σ_i f_i (y_i − ȳ) over the constant x2 loads f_i of [[loads]] (ȳ over all particles)."""
    y = system.x0[:, 1]
    ext = system.ext if system.ext_ramp is None else system.ext + system.ext_ramp  # the loads at full value
    held = system.bc_kind[:, 1] != 0  # FREE = 0
    v, yh = system.bc_vel[held, 1], y[held]
    terms = (v - v.mean()) * (yh - yh.mean()) if held.any() else np.zeros(0)
    if abs(terms.sum()) <= 1e-9 * np.abs(terms).sum() or not terms.any():
        terms = ext[:, 1] * (y - y.mean())
    s = float(terms.sum())
    return 0 if abs(s) <= 1e-9 * float(np.abs(terms).sum()) else int(np.sign(s))


def _by_scenario(scenario, targets, tests) -> dict:
    """The targets grouped by the scenario that measures them."""
    out = {}
    for k, v in targets.items():
        out.setdefault(Path(tests.get(k, scenario)), {})[k] = v
    return out


def _calibrate(plan: Plan, seeds, log, progress, jobs) -> dict:
    targets, overrides, tests = plan.targets, list(plan.overrides), plan.tests
    base_seed = _resolved(plan.scenario, overrides)["scenario"]["seed"]
    t0 = time.time()
    seeds = list(seeds or [base_seed])
    if jobs > 1 and len(seeds) > 1:  # one process per specimen seed; each seed's lines printed as it finishes
        import multiprocessing
        from concurrent.futures import ProcessPoolExecutor

        # spawned, not forked: forked workers of a process that had run the Numba kernels died (BrokenProcessPool)
        with ProcessPoolExecutor(min(jobs, len(seeds)), mp_context=multiprocessing.get_context("spawn")) as pool:
            futures = [pool.submit(_seed_quiet, plan, seed) for seed in seeds]
            rows = []
            for f in futures:
                row, lines = f.result()
                for line in lines:
                    log(line)
                rows.append(row)
    else:
        rows = [_calibrate_seed(plan, seed, log=log, progress=progress) for seed in seeds]
    out = {"targets": targets, "overrides": list(overrides), "seeds": rows, "wall_s": time.time() - t0}
    if tests:
        out["tests"] = {k: str(v) for k, v in tests.items()}
    keys = [k for k in tuple(FITTED) + ("E", "nu", "peak", "G_F", "f_c", "dif") if k in rows[0]]
    out["spread"] = {
        k: {
            "mean": float(np.mean([r[k] for r in rows])),
            "std": float(np.std([r[k] for r in rows])),
            "min": float(min(r[k] for r in rows)),
            "max": float(max(r[k] for r in rows)),
        }
        for k in keys
    }
    return out


def _override_tables(scenario, overrides) -> dict:
    """What the ``--set`` overrides change in the scenario, as tables to write into a file that extends it:
    changed keys of tables (tables merge key by key on ``extends``) and changed arrays whole (arrays are
    replaced; ``particles.0.nx=300`` writes the whole ``[[particles]]`` array)."""
    import copy

    from ..scenario.load import apply_override, parse_override, read_toml

    raw, _ = read_toml(scenario)
    new = copy.deepcopy(raw)
    for o in overrides:
        apply_override(new, *parse_override(o, str(scenario)), str(scenario))

    def delta(a, b):
        out = {}
        for k, v in b.items():
            if isinstance(v, dict) and isinstance(a.get(k), dict):
                d = delta(a[k], v)
                if d:
                    out[k] = d
            elif k not in a or a[k] != v:
                out[k] = v
        return out

    return delta(raw, new)


#: every parameter a calibration fits (its row's key) and the [bonds] key it is written to: the beams' (E_h, nu_h,
#: kappa_0, G_ax, alpha) and the edge interfaces' (f_t, cohesion, crack_strength, G_I, G_II).  One list for the
#: result's spread and the calibrated file, so that a new fitted parameter reaches both (a crack strength once
#: reached the spread and not the file)
FITTED = {
    "E_h": "E",
    "nu_h": "nu",
    "kappa_0": "kappa_0",
    "G_ax": "G_ax",
    "f_t": "f_t",
    "cohesion": "cohesion",
    "crack_strength": "crack_strength",
    "G_I": "G_I",
    "G_II": "G_II",
    "alpha": "alpha",
}


def write_calibrated(scenario, result: dict, path) -> Path:
    """A calibrated copy of the scenario: extends the original and carries every override the calibration ran
    with — the ``--set`` overrides and the specimen seed (``scenario.seed``) — and the fitted [bonds] values (the
    seed's, or the mean over the seeds), with targets and achieved values in comments.  What a comment says this
    file gives, it gives: with one seed, the achieved values of its calibration; with several, each seed's
    achieved values are stated with that seed's own fitted values, and the file's (the mean values on the
    first seed's specimen) are its static solve's E and ν (its strength is not run).  A relative
    ``initial_state.file`` is rewritten relative to the new file."""
    import os

    import tomli_w

    scenario, path = Path(scenario), Path(path)
    rows = result["seeds"]
    sp = result["spread"]
    overrides = list(result.get("overrides") or [])
    fitted = {k: sp[k]["mean"] for k in FITTED if k in sp}
    names = FITTED
    seed = int(rows[0]["seed"])
    rel = os.path.relpath(scenario.resolve(), path.resolve().parent)
    data = _override_tables(scenario, overrides)
    data.setdefault("scenario", {}).update(extends=rel, seed=seed)
    data.setdefault("bonds", {}).update({names[k]: float(v) for k, v in fitted.items()})
    ist = _resolved(scenario, overrides).get("initial_state")
    if ist and not Path(ist["file"]).is_absolute():  # read relative to the scenario given to the run
        where = scenario.resolve().parent / ist["file"]
        data.setdefault("initial_state", {})["file"] = os.path.relpath(where, path.resolve().parent)
    t = result["targets"]
    fmt = {
        "E": lambda v: f"{v / 1e10:g} GPa",
        "nu": lambda v: f"{v:g}",
        "f_t": lambda v: f"{v / 1e7:g} N/mm2",
        "f_c": lambda v: f"{v / 1e7:g} N/mm2",
        "F": lambda v: f"{v / 1e8:g} kN",
        "dif": lambda v: f"{v[0]:g} at {v[1]:g} 1/s",
        "G_F": lambda v: f"{v / 1e3:g} N/m",
    }
    unit = ("kN", 1e8) if "F" in t else ("N/mm2", 1e7)
    peak_of = "peak (rate-independent beams, the dif reference)" if "dif" in t else "peak"

    def achieved(r):
        got = []
        if "E" in r:
            got += [f"E = {r['E'] / 1e10:.6g} GPa", f"nu = {r['nu']:.6g}"]
        if "peak" in r:
            got.append(
                f"{peak_of} = {r['peak'] / unit[1]:.6g} {unit[0]} after {r['runs']} dynamic runs "
                f"({r['run_wall_s']:.0f} s)"
            )
        if "G_F" in r:
            got.append(f"G_F = {r['G_F'] / 1e3:.5g} N/m after {r['G_F_runs']} bending runs ({r['G_F_wall_s']:.0f} s)")
        if "f_c" in r:
            how = next(
                (
                    f"fitted with the {w}"
                    for k, w in (("cohesion", "cohesion"), ("crack_strength", "crack strength"))
                    if k in r
                ),
                "measured",
            )
            got.append(f"f_c = {r['f_c'] / 1e7:.5g} N/mm2 ({how}, f_c/f_t = {r['f_c_over_f_t']:.3g})")
        if "dif" in r:
            got.append(f"dif = {r['dif']:.4f} after {r['dif_runs']} rate-dependent runs")
        return ", ".join(got)

    lines = [
        f"# Calibrated by polydem calibrate from {scenario} ({len(rows)} specimen seed(s): "
        + ", ".join(str(r["seed"]) for r in rows)
        + ")",
        "# targets: " + ", ".join(f"{k} = {fmt[k](v)}" for k, v in t.items()),
    ]
    if overrides:
        lines.append("# with the overrides it ran with (written below): " + " ".join(overrides))
    if result.get("tests"):
        lines.append(
            "# measured on: "
            + ", ".join(f"{k} {v}" for k, v in result["tests"].items())
            + " (the same [bonds] values apply to them)"
        )
    for r in rows:
        for msg in (r.get("unreached") or {}).values():
            lines.append(f"# not reached (seed {r['seed']}): {msg}")
    if len(rows) == 1:
        lines.append(f"# this file (specimen seed {seed}) gives: {achieved(rows[0])}")
    else:
        for r in rows:
            own = ", ".join(f"{names[k]} = {r[k]:.6g}" for k in fitted)
            lines.append(f"# seed {r['seed']}, with its own fitted {own}: achieved {achieved(r)}")
        lines.append(
            "# fitted values (mean, std over the seeds): "
            + ", ".join(f"{names[k]} {sp[k]['mean']:.6g} ± {sp[k]['std']:.2g}" for k in fitted)
        )
        mine = f"# this file (the mean values, specimen seed {seed})"
        if "E_h" in fitted or "nu_h" in fitted:
            from ..analysis.elastic import static_response

            ov = overrides + [f"scenario.seed={seed}"] + [f"bonds.{names[k]}={float(v)!r}" for k, v in fitted.items()]
            st = static_response(_system(scenario, ov))
            mine += f" gives: E = {st['E'] / 1e10:.6g} GPa, nu = {st['nu']:.6g} (static solve)"
        if "kappa_0" in fitted or "alpha" in fitted:
            mine += ("; " if " gives: " in mine else ": ") + "its strength was not run"
        lines.append(mine)
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text("\n".join(lines) + "\n" + tomli_w.dumps(data))
    return path
