"""The validation suite: a bonded material beside the classic experiments of concrete (``polydem study validate``).

Each experiment is one entry of :data:`EXPERIMENTS` — its runs (scenario templates in ``scenarios/lab/``, full and
smoke size), its numbers from their results, its rows of the table and its figure — and the published numbers it is
judged by live in ``reproductions/sources/*.toml`` with their sources:

* ``biaxial`` — Kupfer, Hilsdorf & Rüsch (1969): a panel under proportional biaxial stress (the lateral faces'
  pressure follows the driven face's stress at α = σ₂/σ₁, ``[[proportional_pressure]]``); the peak (σ₁, σ₂)
  normalised by the model's own f_c (the α = 0 run: its uniaxial compression) or, tension–tension, f_t;
* ``size_effect`` — Bažant: geometrically similar notched beams (Hoover, Bažant et al. 2013 proportions), the
  nominal strength σ_N = 3 F S / (2 T D²) against the depth D, the size-effect law fitted, the largest sizes' slope
  against LEFM's −1/2;
* ``softening`` — Hordijk (1991): the uniaxial tension test's stress against the crack opening w (elongation less
  σ L / E), beside Hordijk's curve with the run's own f_t and G_F;
* ``petersson`` — Petersson's (1981) notched beam: load against the nose's deflection.

The runs are written as scenario files (the template with the study's values: a run can be repeated with
``polydem run`` alone) and run as one batch (workflows/batch.py: finished runs reused, interrupted ones resumed, one
progress line with an ETA; ``--ranks`` for each run).  Every choice the user makes is checked before anything is
written (:func:`plan`).
"""

from __future__ import annotations

import json
import sys
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..analysis import validation as V
from ..analysis.macro import MPA
from ..errors import PolydemError
from .sources import source

#: the experiments in the order the study runs them
EXPERIMENTS_ORDER = ("softening", "biaxial", "size_effect", "petersson")
#: Kupfer's envelope points the study runs by default: "c" σ₁ in compression (α in [−1, 1]: 0 uniaxial, > 0
#: compression–compression, < 0 tension–compression), "t" σ₁ in tension (tension–tension)
BIAXIAL = ("c0", "c0.2", "c0.5", "c1", "c-0.05", "c-0.1", "c-0.2", "t1")
BIAXIAL_SMOKE = ("c0", "c0.5", "c1", "c-0.1", "t1")
#: beam depths D of the size-effect series, cm (a factor 8; cells of 1 cm)
SIZES = (5.0, 10.0, 20.0, 40.0)
SIZES_SMOKE = (5.0, 10.0)
#: the templates, full size and smoke size (relative to the repository's scenarios/)
TEMPLATES = {
    "softening": ("lab/softening.toml", "lab/smoke_softening.toml"),
    "biaxial": ("lab/biaxial.toml", "lab/smoke_biaxial.toml"),
    "size_effect": ("lab/size_effect.toml", "lab/smoke_size_effect.toml"),
    "petersson": ("lab/petersson.toml", "lab/smoke_petersson.toml"),
}


class ValidateError(PolydemError, ValueError):
    """Bad input of the study (``key``: the option or scenario key it names), or a result it cannot use."""

    def __init__(self, key: str, message: str):
        self.key = key
        super().__init__(f"{key}: {message}")


@dataclass
class Run:
    """One run of the study: its name (the file stem), the scenario template, the study's changes to it (a function
    of the resolved scenario dict) and a one-line description."""

    name: str
    template: str
    change: object = None
    what: str = ""
    meta: dict = field(default_factory=dict)


def parse_points(text) -> tuple:
    """Kupfer points from ``--biaxial``: comma-separated ``c<α>`` / ``t<α>`` (σ₁ compression / tension), α = σ₂/σ₁
    in [−1, 1]; ValidateError naming the option otherwise."""
    items = [p.strip() for p in (text.split(",") if isinstance(text, str) else text) if str(p).strip()]
    if not items:
        raise ValidateError("--biaxial", "no point given (e.g. c0,c0.5,c1,c-0.1,t1)")
    out = []
    for p in items:
        kind, num = p[:1], p[1:]
        try:
            a = float(num)
        except ValueError:
            a = None
        if kind not in ("c", "t") or a is None:
            raise ValidateError("--biaxial", f"{p!r}: a point is c<ratio> (sigma_1 compression) or t<ratio> (tension)")
        if not -1.0 <= a <= 1.0:
            raise ValidateError("--biaxial", f"{p!r}: the stress ratio sigma_2/sigma_1 = {a:g} lies outside [-1, 1]")
        if kind == "t" and a < 0.0:
            raise ValidateError(
                "--biaxial", f"{p!r}: with sigma_1 in tension give the tension-compression point as c<ratio> < 0"
            )
        out.append((kind, a))
    if len(set(out)) != len(out):
        raise ValidateError("--biaxial", "a point is given twice")
    return tuple(out)


def parse_sizes(text) -> tuple:
    """Beam depths from ``--sizes`` (cm, comma-separated): at least two different ones, each > 0."""
    try:
        sizes = tuple(float(s) for s in (text.split(",") if isinstance(text, str) else text) if str(s).strip())
    except ValueError:
        raise ValidateError("--sizes", f"{text!r}: comma-separated depths in cm") from None
    if any(not np.isfinite(s) or s <= 0.0 for s in sizes):
        raise ValidateError("--sizes", f"{text!r}: every depth must be > 0 cm")
    if len(set(sizes)) < 2:
        raise ValidateError("--sizes", f"{text!r}: a size series needs at least two different depths")
    return tuple(sorted(set(sizes)))


def _point_name(kind, a) -> str:
    return f"biaxial_{kind}{a:g}"


def _set_ratio(a):
    def change(sc):
        for e in sc.get("proportional_pressure") or []:
            e["ratio"] = a
        return sc

    return change


def _pulled(a):
    """σ₁ in tension: the driven row pulled (its motion's velocity and acceleration reversed), the ratio set."""

    def change(sc):
        ref = {e["reference"] for e in sc.get("proportional_pressure") or []}
        for b in sc["boundary"]:
            if b["set"] in ref:
                for k in ("x1", "x2", "phi"):
                    m = b.get(k)
                    if isinstance(m, dict):
                        b[k] = {kk: (-v if kk in ("velocity", "acceleration") else v) for kk, v in m.items()}
        return _set_ratio(a)(sc)

    return change


def _sized(D: float, D_t: float):
    """The size-effect beam at depth D from the template's (depth D_t): the proportions of the source file, the
    template's cells, notch width and support width, its safety limit scaled with D."""
    p = source("size_effect")

    def change(sc):
        g = next(q for q in sc["particles"] if q.get("shape") == "notched_beam")
        h = float(g["h_pg"])
        ny = D / h
        if abs(ny - round(ny)) > 1e-9:
            raise ValidateError("--sizes", f"{D:g} cm: a depth must be a whole number of cells (h_pg = {h:g} cm)")
        g["ny"] = int(round(ny))
        g["nx"] = int(round(p["length_over_depth"] * D / h))
        g["notch_depth"] = p["notch_over_depth"] * D
        g["span"] = p["span_over_depth"] * D
        sc["time"]["end_displacement"] = sc["time"]["end_displacement"] * D / D_t
        return sc

    return change


def plan(smoke=False, tests=EXPERIMENTS_ORDER, biaxial=None, sizes=None) -> list:
    """The study's runs (:class:`Run`), every option checked first (ValidateError naming it): the tests known, the
    biaxial points (the uniaxial compression c0 added when missing: it normalises the envelope), the size series."""
    bad = [t for t in tests if t not in EXPERIMENTS_ORDER]
    if bad:
        raise ValidateError("--test", f"unknown test {bad[0]!r}; the tests are {', '.join(EXPERIMENTS_ORDER)}")
    tests = tuple(t for t in EXPERIMENTS_ORDER if t in tests)
    pts = parse_points(biaxial if biaxial is not None else (BIAXIAL_SMOKE if smoke else BIAXIAL))
    if ("c", 0.0) not in pts:
        pts = (("c", 0.0),) + pts
    Ds = parse_sizes(sizes if sizes is not None else (SIZES_SMOKE if smoke else SIZES))
    pick = 1 if smoke else 0
    runs = []
    if any(t in tests for t in ("softening", "biaxial", "size_effect")):  # f_t normalises all three
        runs.append(Run("tension", TEMPLATES["softening"][pick], None, "uniaxial tension to 2 % of the peak"))
    if "biaxial" in tests:
        for kind, a in pts:
            ch = _pulled(a) if kind == "t" else _set_ratio(a)
            what = f"biaxial, sigma_1 in {'tension' if kind == 't' else 'compression'}, sigma_2/sigma_1 = {a:g}"
            runs.append(Run(_point_name(kind, a), TEMPLATES["biaxial"][pick], ch, what, {"kind": kind, "alpha": a}))
    if "size_effect" in tests:
        for D in Ds:
            runs.append(
                Run(f"size_D{D:g}", TEMPLATES["size_effect"][pick], ("size", D), f"notched beam D = {D:g} cm", {"D": D})
            )
    if "petersson" in tests:
        runs.append(Run("petersson", TEMPLATES["petersson"][pick], None, "Petersson's notched beam"))
    return runs


def _plain(x):
    """The resolved scenario as TOML can hold it: no None (an unset optional key), no 'extends' (the file is whole)."""
    if isinstance(x, dict):
        return {k: _plain(v) for k, v in x.items() if v is not None and k != "extends"}
    if isinstance(x, list):
        return [_plain(v) for v in x]
    return x


def scenarios(runs, root: Path, overrides=()) -> dict:
    """{run name: (scenario text, resolved)}: each run's template with ``overrides`` (e.g. a calibrated material's
    beams) and the study's change, validated, as a whole scenario file; nothing is written.  ValidateError naming
    the template and key on a refusal."""
    import tomllib

    import tomli_w

    from ..scenario.load import load_scenario, validate
    from ..scenario.spec import ScenarioError

    out = {}
    for r in runs:
        path = root / "scenarios" / r.template
        try:
            sc, _ = load_scenario(path, list(overrides))
        except ScenarioError as e:
            raise ValidateError(str(path), str(e)) from None
        if isinstance(r.change, tuple) and r.change[0] == "size":
            g = next(q for q in sc["particles"] if q.get("shape") == "notched_beam")
            sc = _sized(r.change[1], float(g["ny"]) * float(g["h_pg"]))(sc)
        elif r.change is not None:
            sc = r.change(sc)
        sc["scenario"]["title"] = f"{sc['scenario']['title']} [validate: {r.what}]"
        head = (
            f"# polydem study validate: {r.what}\n# from scenarios/{r.template}"
            + (f" with {', '.join(overrides)}" if overrides else "")
            + " (the study's values written in; run it alone with polydem run)\n"
        )
        text = head + tomli_w.dumps(_plain(sc))
        try:
            resolved = validate(tomllib.loads(text), f"{r.name}.toml")
        except ScenarioError as e:
            raise ValidateError(str(path), f"the study's {r.what}: {e}") from None
        out[r.name] = (text, resolved)
    return out


# ---------------------------------------------------------------- running


def run_all(runs, texts: dict, out: Path, threads="1", jobs=1, ranks=None, quiet=False) -> dict:
    """Write each run's scenario file to ``out/scenarios/`` (unless the same text is there) and run them as one batch
    into ``out/runs/`` (workflows/batch.py: finished runs reused, interrupted ones resumed); {name: result path} of
    the runs that finished."""
    import contextlib
    import io

    from ..workflows.batch import Batch, read_list

    (out / "scenarios").mkdir(parents=True, exist_ok=True)
    (out / "runs").mkdir(parents=True, exist_ok=True)
    items, kept, batched = [], {}, []
    for r in runs:
        scen, res = out / "scenarios" / f"{r.name}.toml", out / "runs" / f"{r.name}.h5"
        text, resolved = texts[r.name]
        if not scen.exists() or scen.read_text() != text:
            scen.write_text(text)
        state = _replace_or_keep(res, resolved, quiet)
        if state == "past peak":  # a run stopped as unstable after its peak: its peak is all the study takes
            kept[r.name] = res
            continue
        items.append(f"{scen}={res}")
        batched.append(r)
    run_args = () if not ranks or ranks == 1 else ("--ranks", str(ranks))
    b = Batch(read_list(items, threads), str(threads), jobs, run_args)
    sink = io.StringIO()
    with contextlib.redirect_stderr(sink) if quiet else contextlib.nullcontext():
        while b.step():
            pass
        if b.tty and not quiet:
            sys.stderr.write("\n")
        with contextlib.redirect_stdout(sink) if quiet else contextlib.nullcontext():
            b.summary()
    done = dict(kept)
    for r, j in zip(batched, b.jobs):
        res = out / "runs" / f"{r.name}.h5"
        if j.status in ("ran", "resumed", "reused") or (j.status == "failed" and past_peak(res)):
            done[r.name] = res  # a run that stopped as unstable after its peak still gives its peak
    return done


def _replace_or_keep(res: Path, resolved: dict, quiet: bool) -> str:
    """What the study does with an existing result in its folder: "past peak" (a run of this scenario that stopped
    as unstable after its peak: kept as it is), "replaced" (a readable result of other values: removed, under its
    lock, so the batch runs this one), or "batch" (nothing there, this run's own, or a file the batch must judge: one
    another process is writing is refused by ``polydem run --continue`` with its reason, never removed)."""
    from ..io.hdf5 import ResultError, open_result, result_lock
    from ..scenario.load import same_run

    if not res.exists():
        return "batch"
    try:
        with open_result(res) as f:
            stored = json.loads(f.attrs["resolved"])
            status = f.attrs.get("status")
    except (ResultError, KeyError, OSError):
        return "batch"
    if same_run(stored, resolved):
        return "past peak" if status == "failed" and past_peak(res) else "batch"
    try:
        with result_lock(res):
            res.unlink()
            res.with_suffix(".summary.json").unlink(missing_ok=True)
    except ResultError:
        return "batch"
    if not quiet:
        print(f"validate: {res} held a run of other values: replaced", file=sys.stderr)
    return "replaced"


#: a run the engine stopped as unstable counts when its load had fallen at least this far below its peak: the peak
#: was passed (a biaxial panel collapses after its peak and crushes particles into each other)
PAST_PEAK = 0.9


def past_peak(path) -> bool:
    """A failed run's result whose driven load had already fallen below :data:`PAST_PEAK` of its peak (its history
    holds the peak, which is all an experiment here takes from a run that stopped early)."""
    try:
        from ..io.hdf5 import open_result, read_history

        with open_result(path) as f:
            resolved = json.loads(f.attrs["resolved"])
        cols, H = read_history(path)
    except Exception:  # noqa: BLE001 - no result, or an unreadable one: not usable
        return False
    c = {k: i for i, k in enumerate(cols)}
    drive = resolved["time"].get("end_displacement_set") or next(
        (b["set"] for b in resolved.get("boundary", []) if isinstance(b.get("x2"), dict)), None
    )
    key = f"f2:{drive}"
    if key not in c or not len(H):
        return False
    f = np.abs(H[:, c[key]])
    return bool(f.max() > 0 and f[-1] < PAST_PEAK * f.max() and int(np.argmax(f)) < len(f) - 1)


# ---------------------------------------------------------------- numbers


def _history(path):
    from ..io.hdf5 import open_result, read_history

    cols, H = read_history(path)
    with open_result(path) as f:
        resolved = json.loads(f.attrs["resolved"])
        summary = json.loads(f.attrs["summary"])
    return {k: H[:, i] for i, k in enumerate(cols)}, resolved, summary


def _specimen(resolved):
    return next(g for g in resolved["particles"] if g.get("type") == "voronoi")


def tension_numbers(path) -> dict:
    """f_t, E, the softening curve (w, σ in MPa, mm) and G_F of the uniaxial tension run."""
    h, resolved, summary = _history(path)
    g = _specimen(resolved)
    m = summary.get("macro") or {}
    E = m.get("E")
    if not E:
        raise ValidateError(str(path), "the tension run has no fitted E (its [macro] curve)")
    L2 = float(g["ny"]) * float(g["h_pg"])
    u = h["u2:specimen.top"] - h["u2:specimen.bottom"]
    s = h["sigma22"]
    sc = V.softening_curve(u, s, E, L2)
    hor = source("hordijk1991")
    rms, wc = V.hordijk_rms(sc["w"], sc["stress"], sc["f_t"], sc["G_F"], c1=hor["c1"], c2=hor["c2"])
    return {
        "f_t_MPa": sc["f_t"] / MPA,
        "E_GPa": E / 1e10,
        "G_F_N_per_m": sc["G_F"] / 1e3,
        "w_c_mm": wc * 10.0,
        "hordijk_rms": rms,
        "end_fraction": sc["end_fraction"],
        "w_mm": (sc["w"] * 10.0).tolist(),
        "stress_MPa": (sc["stress"] / MPA).tolist(),
    }


def biaxial_numbers(path) -> dict:
    """The peak of the axial stress σ₁ (the driven face, ``sigma22``) and the lateral σ₂ = −p at that moment (MPa,
    tension positive), and the stress ratio reached."""
    h, _, summary = _history(path)
    s1 = h["sigma22"]
    p = [k for k in h if k.startswith("pp0_p:")]
    s2 = -h[p[0]] if p else np.zeros_like(s1)
    k = int(np.argmax(np.abs(s1)))
    return {
        "sigma_1_MPa": float(s1[k] / MPA),
        "sigma_2_MPa": float(s2[k] / MPA),
        "alpha_reached": float(s2[k] / s1[k]) if s1[k] else 0.0,
        "end_fraction": float(abs(s1[-1]) / abs(s1[k])) if s1[k] else 1.0,
        "stopped_unstable": summary.get("status") == "failed",  # after its peak (run_all: past_peak)
    }


def beam_numbers(path) -> dict:
    """Peak load (N) and the nose's load–deflection curve (N, mm) of a notched beam; its depth, span, thickness."""
    h, resolved, _ = _history(path)
    g = _specimen(resolved)
    F = -h["f2:specimen.nose"]
    d = -h["u2:specimen.nose"]
    k = int(np.argmax(F))
    D, S, T = float(g["ny"]) * float(g["h_pg"]), float(g["span"]), float(g["thickness"])
    return {
        "D_cm": D,
        "span_cm": S,
        "T_cm": T,
        "peak_N": float(F[k] / 1e5),
        "deflection_at_peak_mm": float(d[k] * 10.0),
        "sigma_N_MPa": float(3.0 * F[k] * S / (2.0 * T * D * D) / MPA),
        "end_fraction": float(F[-1] / F[k]),
        "load_N": (F / 1e5).tolist(),
        "deflection_mm": (d * 10.0).tolist(),
    }


# ---------------------------------------------------------------- the experiments


def _pct(model, ref):
    return None if model is None or ref in (None, 0) else 100.0 * (model / ref - 1.0)


def analyse(runs, results: dict) -> dict:
    """Each experiment's numbers from the finished runs (those missing are left out and named in ``missing``)."""
    res = {"missing": [r.name for r in runs if r.name not in results]}
    if "tension" in results:
        res["tension"] = tension_numbers(results["tension"])
    pts = [r for r in runs if r.name.startswith("biaxial_") and r.name in results]
    if pts:
        b = {r.name: {**r.meta, **biaxial_numbers(results[r.name])} for r in pts}
        c0 = b.get(_point_name("c", 0.0))
        f_c = abs(c0["sigma_1_MPa"]) if c0 else None
        f_t = res.get("tension", {}).get("f_t_MPa")
        for n in b.values():
            ref = f_c if n["kind"] == "c" else f_t
            n["norm"] = ref
            n["s1"] = n["sigma_1_MPa"] / ref if ref else None
            n["s2"] = n["sigma_2_MPa"] / ref if ref else None
        res["biaxial"] = {"f_c_MPa": f_c, "f_t_MPa": f_t, "points": b}
    beams = [r for r in runs if r.name.startswith("size_D") and r.name in results]
    if beams:
        se = {r.name: beam_numbers(results[r.name]) for r in beams}
        D = [n["D_cm"] for n in se.values()]
        sN = [n["sigma_N_MPa"] for n in se.values()]
        fit = V.size_effect_fit(D, sN) if len(set(D)) >= 2 else None
        f_t = res.get("tension", {}).get("f_t_MPa")
        res["size_effect"] = {"beams": se, "fit": fit, "f_t_MPa": f_t, "B": fit["Bft"] / f_t if fit and f_t else None}
    if "petersson" in results:
        res["petersson"] = beam_numbers(results["petersson"])
    return res


def table(res: dict) -> list:
    """Rows (experiment, quantity, polydem, experiment, difference %, source) of the validation table."""
    rows = []
    kup, hor, pet, sef = source("kupfer1969"), source("hordijk1991"), source("petersson1981"), source("size_effect")
    t = res.get("tension")
    if t:
        rows += [
            ("softening", "f_t [MPa]", t["f_t_MPa"], None, None, "the tension run's peak"),
            ("softening", "G_F [N/m] (area under sigma-w to the run's end)", t["G_F_N_per_m"], None, None, "the run"),
            ("softening", "w_c = 5.136 G_F / f_t [mm]", t["w_c_mm"], None, None, "Hordijk (1991)"),
            ("softening", "RMS of sigma/f_t - Hordijk over w/w_c <= 1", t["hordijk_rms"], 0.0, None, f"Hordijk (1991): c1 = {hor['c1']:g}, c2 = {hor['c2']:g} (OOFEM concrete3.C, Serendip.jl)"),
        ]  # fmt: skip
    b = res.get("biaxial")
    if b:
        dig = dict(zip(kup["digitized"]["ratios"], kup["digitized"]["peaks_MPa"]))
        ft_fc = kup["tension_over_compression"]  # Kupfer's concrete's envelope (its f_t/f_c)
        fc_exp = abs(kup["digitized"]["uniaxial_fc_MPa"])
        for n in sorted(b["points"].values(), key=lambda n: (n["kind"], -n["alpha"])):
            if n["s1"] is None:
                continue
            a = n["alpha_reached"]
            if n["kind"] == "t":
                rows.append(("biaxial", f"sigma_1/f_t, tension-tension, sigma_2/sigma_1 = {a:.3g}", n["s1"],
                             kup["tension_tension_over_ft"], _pct(n["s1"], kup["tension_tension_over_ft"]),
                             "Kupfer et al. (1969) abstract: biaxial tensile strength approximately f_t"))  # fmt: skip
                continue
            ref = float(-V.kupfer_envelope(max(-1.0, min(1.0, a)), ft_fc)[0])
            note = ", the run stopped unstable after its peak" if n.get("stopped_unstable") else ""
            rows.append(("biaxial", f"|sigma_1|/f_c at sigma_2/sigma_1 = {a:.3g} (asked {n['alpha']:g}{note})", abs(n["s1"]),
                         ref, _pct(abs(n["s1"]), ref), kup["formula"]["source"]))  # fmt: skip
            near = [r for r in dig if abs(r - n["alpha"]) < 0.05]
            if near:
                rows.append(("biaxial", f"|sigma_1|/f_c at sigma_2/sigma_1 = {near[0]:g}, Kupfer's curve", abs(n["s1"]),
                             abs(dig[near[0]]) / fc_exp, _pct(abs(n["s1"]), abs(dig[near[0]]) / fc_exp),
                             kup["digitized"]["source"]))  # fmt: skip
            if n["alpha"] == 1.0:
                rows.append(("biaxial", "|sigma_1|/f_c, equal biaxial compression", abs(n["s1"]), kup["equal_biaxial_over_fc"],
                             _pct(abs(n["s1"]), kup["equal_biaxial_over_fc"]), f"Kupfer et al. (1969), {kup['abstract']}"))  # fmt: skip
    s = res.get("size_effect")
    if s:
        for n in sorted(s["beams"].values(), key=lambda n: n["D_cm"]):
            rows.append(("size_effect", f"sigma_N [MPa] at D = {n['D_cm']:g} cm", n["sigma_N_MPa"], None, None,
                         "3 F S / (2 T D^2), the run's peak"))  # fmt: skip
        f = s["fit"]
        if f:
            rows += [
                ("size_effect", "B = sigma_N(D -> 0) / f_t", s["B"], None, None, "size-effect law fitted (Bazant 1984)"),
                ("size_effect", "D0 [cm]", f["D0"], None, None, "size-effect law fitted"),
                ("size_effect", "fit residual (RMS of ln sigma_N)", f["residual"], None, None, "least squares on ln sigma_N"),
                ("size_effect", "log-log slope of the two largest sizes", f["slope_largest"], sef["lefm_slope"],
                 None, "LEFM limit of the size-effect law"),
                ("size_effect", "measured series of Hoover, Bazant et al. (2013)", None, None, None, sef["measured"]),
            ]  # fmt: skip
    p = res.get("petersson")
    if p:
        rows.append(("petersson", "peak load [N]", p["peak_N"], None, None, "the run (Petersson's peak not in reach)"))
        rows.append(("petersson", "deflection at the peak [mm]", p["deflection_at_peak_mm"], None, None, "the run"))
        for dd, ff in zip(pet["curve"]["deflection_mm"], pet["curve"]["load_N"]):
            m = float(np.interp(dd, p["deflection_mm"], p["load_N"], right=np.nan))
            rows.append(("petersson", f"load [N] at {dd:g} mm", None if np.isnan(m) else m, ff,
                         None if np.isnan(m) else _pct(m, ff), pet["curve"]["source"]))  # fmt: skip
    return rows


def write_table(rows, path: Path):
    """The table as Markdown (every cell escaped: report/common.py)."""
    from ..report.common import markdown_table

    def num(v):
        return "—" if v is None else f"{v:.4g}"

    body = [(e, q, num(m), num(x), "—" if d is None else f"{d:+.1f} %", src) for e, q, m, x, d, src in rows]
    path.write_text(markdown_table(("experiment", "quantity", "polydem", "experiment", "difference", "source"), body))


# ---------------------------------------------------------------- figures


def _fig_biaxial(b, path, title):
    from ..report.common import _plt, save

    plt = _plt()
    kup = source("kupfer1969")
    fig, ax = plt.subplots(figsize=(5.6, 5.4))
    ft_fc = kup["tension_over_compression"]  # Kupfer's concrete's (the model's points: normalised by its own)
    a = np.linspace(1.0, -0.17, 300)  # sigma_1 the larger compression: from equal biaxial to tension-compression
    s1, s2 = V.kupfer_envelope(a, ft_fc)
    # beyond alpha = -0.17 the tensile strength governs: up to sigma_2 = f_t, along it, round the tension-tension
    # corner (f_t, f_t), and back down the mirrored branch (sigma_2 the larger compression)
    x = np.concatenate([s1, [s1[-1], ft_fc, ft_fc], s2[::-1]])
    y = np.concatenate([s2, [ft_fc, ft_fc, s1[-1]], s1[::-1]])
    ax.plot(x, y, "k-", lw=1.2, label="Kupfer & Gerstle envelope (f_t/f_c = 0.1)")
    ax.plot([ft_fc], [ft_fc], "ks", mfc="none", label="tension-tension ~ f_t (Kupfer et al. 1969)")
    dig = kup["digitized"]
    fc = abs(dig["uniaxial_fc_MPa"])
    for r, pk in zip(dig["ratios"], dig["peaks_MPa"]):
        ax.plot(
            [pk / fc],
            [r * pk / fc],
            "k^",
            ms=7,
            label="Kupfer et al. (1969), digitized" if r == dig["ratios"][0] else None,
        )
    ax.plot(
        [-kup["equal_biaxial_over_fc"]],
        [-kup["equal_biaxial_over_fc"]],
        "kD",
        mfc="none",
        label="equal biaxial 1.16 f_c (abstract)",
    )
    first = True
    for n in b["points"].values():
        if n["s1"] is None:
            continue
        # tension-tension points normalised by the model's f_t, drawn in units of the envelope's f_t (Kupfer's f_t/f_c)
        scale = ft_fc if n["kind"] == "t" else 1.0
        x, y = n["s1"] * scale, n["s2"] * scale
        ax.plot([x, y], [y, x], "o", color="C3", ms=6, label="polydem (peak of sigma_1)" if first else None)
        first = False
    ax.axhline(0, color="0.7", lw=0.6)
    ax.axvline(0, color="0.7", lw=0.6)
    ax.set(xlabel="sigma_1 / f_c (compression negative)", ylabel="sigma_2 / f_c", aspect="equal")
    ax.set_title(f"Biaxial strength envelope: {title}", fontsize=9)
    ax.legend(fontsize=7, loc="lower right")
    save(fig, path)
    plt.close(fig)


def _fig_size_effect(s, path, title):
    from ..report.common import _plt, save

    plt = _plt()
    fig, ax = plt.subplots(figsize=(5.6, 4.2))
    f = s["fit"]
    D = np.array(f["D"])
    x = np.geomspace(min(D.min(), f["D0"]) / 10, max(D.max(), f["D0"]) * 10, 200)
    ax.loglog(x / f["D0"], V.size_effect_law(x, f["Bft"], f["D0"]) / f["Bft"], "k-", lw=1.2,
              label=f"size-effect law, B = {s['B']:.3g}, D0 = {f['D0']:.3g} cm (residual {f['residual']:.3f})" if s["B"]
              else f"size-effect law, D0 = {f['D0']:.3g} cm")  # fmt: skip
    ax.loglog(x / f["D0"], np.ones_like(x), "k:", lw=0.8, label="strength criterion (no size effect)")
    ax.loglog(x / f["D0"], np.sqrt(f["D0"] / x), "k--", lw=0.8, label="LEFM, slope -1/2")
    ax.loglog(
        D / f["D0"], np.array(f["sigma_N"]) / f["Bft"], "o", color="C3", ms=7, label="polydem, notched beams a0/D = 0.3"
    )
    ax.set(xlabel="D / D0", ylabel="sigma_N / (B f_t)", ylim=(0.05, 2.0))
    ax.set_title(f"Size effect (Bazant): {title}\nmeasured series not in reach (see docs/validation.md)", fontsize=9)
    ax.legend(fontsize=7, loc="lower left")
    save(fig, path)
    plt.close(fig)


def _fig_softening(t, path, title):
    from ..report.common import _plt, save

    plt = _plt()
    hor = source("hordijk1991")
    fig, ax = plt.subplots(figsize=(5.6, 4.0))
    wc = t["w_c_mm"]
    x = np.linspace(0.0, 1.0, 200)
    ax.plot(x, V.hordijk(x, hor["c1"], hor["c2"]), "k-", lw=1.2, label="Hordijk (1991), the model's f_t and G_F")
    w, s = np.array(t["w_mm"]), np.array(t["stress_MPa"])
    ax.plot(w / wc, s / t["f_t_MPa"], "-", color="C3", lw=1.2, label=f"polydem (RMS difference {t['hordijk_rms']:.3f})")
    ax.set(
        xlabel="crack opening w / w_c (w = elongation - sigma L / E)",
        ylabel="sigma / f_t",
        xlim=(0, 1.05),
        ylim=(0, 1.05),
    )
    ax.set_title(
        f"Tension softening: {title}\nf_t {t['f_t_MPa']:.3g} MPa, G_F {t['G_F_N_per_m']:.3g} N/m, w_c {wc:.3g} mm",
        fontsize=9,
    )
    ax.legend(fontsize=7)
    save(fig, path)
    plt.close(fig)


def _fig_petersson(p, path, title):
    from ..report.common import _plt, save

    plt = _plt()
    pet = source("petersson1981")
    fig, ax = plt.subplots(figsize=(5.6, 4.0))
    ax.plot(p["deflection_mm"], p["load_N"], "-", color="C3", lw=1.2, label="polydem (its own material)")
    ax.plot(
        pet["curve"]["deflection_mm"],
        pet["curve"]["load_N"],
        "ks",
        label="reference points (code_aster SSNP166, 5 % of Petersson's curve)",
    )
    ax.set(xlabel="deflection of the nose [mm]", ylabel="load [N]", xlim=(0, None), ylim=(0, None))
    ax.set_title(
        f"Petersson's notched beam: {title}\nD {p['D_cm'] * 10:g} mm, span {p['span_cm'] * 10:g} mm, T {p['T_cm'] * 10:g} mm",
        fontsize=9,
    )
    ax.legend(fontsize=7)
    save(fig, path)
    plt.close(fig)


def figures(res: dict, out: Path, title: str) -> list:
    """One figure per experiment with numbers (``out/validate_<experiment>.png``); the paths written."""
    made = []
    for key, draw, ok in (
        ("biaxial", _fig_biaxial, lambda r: r.get("f_c_MPa")),
        ("size_effect", _fig_size_effect, lambda r: r.get("fit")),
        ("softening", _fig_softening, lambda r: True),
        ("petersson", _fig_petersson, lambda r: True),
    ):
        r = res.get("tension" if key == "softening" else key)
        if r and ok(r):
            path = out / f"validate_{key}.png"
            draw(r, path, title)
            made.append(path)
    return made


# ---------------------------------------------------------------- the study


def run_study(out: Path, root: Path, tests=EXPERIMENTS_ORDER, smoke=False, overrides=(), biaxial=None, sizes=None,
              threads="1", jobs=1, ranks=None, quiet=False, title="thesis concrete") -> dict:  # fmt: skip
    """Plan, write and run the study's runs, then its numbers, table (``out/validation_table.md``), figures and
    ``out/results.json``; the results.  Bad input raises ValidateError before anything is written."""
    runs = plan(smoke, tests, biaxial, sizes)
    texts = scenarios(runs, root, overrides)
    results = run_all(runs, texts, out, threads, jobs, ranks, quiet)
    res = analyse(runs, results)
    rows = table(res)
    write_table(rows, out / "validation_table.md")
    made = figures(res, out, title)
    keep = {k: v for k, v in res.items()}
    (out / "results.json").write_text(
        json.dumps({"results": keep, "table": rows, "overrides": list(overrides)}, indent=1)
    )
    return {"results": res, "table": rows, "figures": made}
