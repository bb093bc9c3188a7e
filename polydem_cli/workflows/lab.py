"""The virtual material laboratory: the standard tests of concrete and rock on one bonded Voronoi material, and
the numbers a model is judged by (``polydem study lab``).

Tests (each a scenario; the material is whatever the scenarios give it — the thesis concrete here):

* ``tension`` / ``compression`` — the thesis's uniaxial panels (driven top row, held bottom row): the peak
  nominal stress f_t, f_c and E, ν of the run summary (:mod:`..analysis.macro`);
* ``brazilian`` — a disc on load strips (``scenarios/lab/``): f_ct,sp = 2 F_max / (π D T);
* ``three_point_bending`` — a notched beam: RILEM TC-50's G_F = W_F / ((h − a₀) T), the net nominal strength
  σ_N = 3 F_max S / (2 T (h − a₀)²), the crack mouth opening at the peak (:mod:`..analysis.lab`);
* ``confined_compression`` — the compression panel under a constant lateral pressure σ₃ (``[[loads]] pressure``
  on its left and right columns), run at each of :data:`PRESSURES`; the Mohr–Coulomb envelope through the peaks
  (and the unconfined compression's, when it ran): cohesion c and friction angle φ;
* ``cyclic_compression`` — the compression panel with partial unloadings (a ``cycle`` motion of its top row):
  the damage d = 1 − E_u/E₀ of every unloading branch.

What the test is follows from the result's specimen (its Voronoi ``shape``: rectangle, disc, notched_beam) and,
for a rectangle, from its loads (a pressure: confined), its driven motion (cyclic) and the sign of its peak
stress.  A pressure on any other test is refused (the tests without confinement have none).  The study reports beside them the ratios users judge a
bonded-particle model by: f_c/f_t (concrete ≈ 10, rock 10–30), f_ct,sp/f_t (fib MC2010 §5.1.5.1 takes
f_ctm = 1.0 f_ct,sp), and G_F against fib MC2010's ``73 f_cm^0.18`` N/m.  A G_F whose load–deflection curve did
not come down below ``COMPLETE`` of its peak is marked incomplete (its tail's work is missing).
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from ..analysis.lab import (
    N_PER_M,
    fib_fracture_energy,
    fracture_energy,
    mohr_coulomb,
    splitting_strength,
    unloading_damage,
)
from ..analysis.macro import MPA
from ..errors import PolydemError
from ..report.common import markdown_table

#: the tests in the order the study runs them
TESTS = ("tension", "compression", "brazilian", "three_point_bending", "confined_compression", "cyclic_compression")
#: the scenarios of the study, full size and smoke size (relative to the repository's scenarios/)
SCENARIOS = {
    "tension": ("concrete_tension.toml", "lab/smoke_tension.toml"),
    "compression": ("concrete_compression.toml", "ch7/smoke_concrete_compression.toml"),
    "brazilian": ("lab/brazilian.toml", "lab/smoke_brazilian.toml"),
    "three_point_bending": ("lab/three_point_bending.toml", "lab/smoke_three_point_bending.toml"),
    "confined_compression": ("lab/confined_compression.toml", "lab/smoke_confined_compression.toml"),
    "cyclic_compression": ("lab/cyclic_compression.toml", "lab/smoke_cyclic_compression.toml"),
}
#: the lateral pressures of the confined compression test, MPa (with the unconfined test: four points of the envelope)
PRESSURES = (1.0, 2.0, 4.0)
#: a fracture test's curve counts as complete when its load ends below this fraction of its peak
COMPLETE = 0.05


class LabError(PolydemError, ValueError):
    """A result that is not one of the laboratory tests (or lacks what its numbers need)."""


def check_pressures(pressures):
    """The confined test's lateral pressures (MPa): each one a value of the scenario's ``[[loads]] pressure``, under
    the schema's rule for that key (scenario/schema.py ``LOADS``), none 0 (the unconfined point is the compression
    test) and no two alike; LabError otherwise.  Both front ends check them (``polydem study lab --pressures``,
    ``polydem_cli.lab(pressures=)``)."""
    from ..scenario.schema import LOADS
    from ..scenario.spec import ScenarioError

    pressures = tuple(pressures)
    for p in pressures:
        try:
            LOADS.fields["pressure"].validate(p * MPA, "--pressures", "loads[].pressure")
        except ScenarioError as e:
            raise LabError(
                f"{p:g} MPa: each pressure is the confined scenario's [[loads]] pressure, and {e.reason}"
            ) from None
    if not pressures or min(pressures) == 0.0 or len({f"{p:g}" for p in pressures}) != len(pressures):
        raise LabError(f"{pressures}: distinct pressures > 0 (the unconfined point is the compression test)")


def _specimen(resolved: dict) -> dict:
    groups = [g for g in resolved.get("particles", []) if g.get("type") == "voronoi"]
    if not groups:
        raise LabError("no Voronoi specimen in this result (the laboratory tests are of [[particles]] type voronoi)")
    return groups[0]


def _driven_set(resolved: dict) -> str:
    s = resolved.get("time", {}).get("end_displacement_set")
    if s:
        return s
    for b in resolved.get("boundary", []):
        if any(isinstance(b.get(k), dict) for k in ("x1", "x2", "phi")):
            return b["set"]
    raise LabError("no boundary entry drives the specimen (a moving DOF)")


def _pressures(resolved: dict) -> list:
    """(key, pressure) of the scenario's ``[[loads]]`` that carry one."""
    return [
        (f"loads[{i}].pressure", float(ld["pressure"]))
        for i, ld in enumerate(resolved.get("loads", []))
        if ld.get("pressure")
    ]


def _cyclic(resolved: dict) -> bool:
    return any(
        isinstance(b.get(k), dict) and "cycle" in b[k]
        for b in resolved.get("boundary", [])
        for k in ("x1", "x2", "phi")
    )


def numbers(path) -> dict:
    """The test and its standard numbers from one finished result (module docstring); stresses in MPa, G_F in
    N/m, lengths in cm, forces in dyn."""
    from ..io.hdf5 import open_result, read_history

    with open_result(path) as f:
        resolved = json.loads(f.attrs["resolved"])
        summary = json.loads(f.attrs["summary"])
    g = _specimen(resolved)
    shape, T, h = g.get("shape", "rectangle"), float(g["thickness"]), float(g["h_pg"])
    cols, H = read_history(path)
    c = {k: i for i, k in enumerate(cols)}
    load = _driven_set(resolved)
    f2, u2 = H[:, c[f"f2:{load}"]], H[:, c[f"u2:{load}"]]
    s = -1.0 if u2[-1] < 0 else 1.0  # pushed down (compression, f2 < 0) or pulled up: the load positive either way
    F, d = s * f2, s * u2  # signed: a swing of the load past zero in the explicit run counts against the work
    k = int(np.argmax(F))
    out = {"result": str(path), "load_set": load, "peak_force": float(F[k]), "displacement_at_peak": float(d[k])}
    out["end_fraction"] = float(F[-1] / F[k]) if F[k] > 0 else 1.0
    out["force"], out["deflection"] = F, d  # the curve (arrays: not in results.json)
    pres = _pressures(resolved)
    if shape == "rectangle":
        m = summary.get("macro") or {}
        if "peak_stress" not in m:
            raise LabError(f"{path}: the run summary has no macroscopic measures ([macro] of the scenario)")
        ps = float(m["peak_stress"])
        test = "tension" if ps > 0 else "compression"
        if pres and (test == "tension" or _cyclic(resolved)):
            raise LabError(
                f"{path}: {pres[0][0]}: a lateral pressure on a {'cyclic' if test != 'tension' else 'tension'} test, "
                "which has no confinement (only the confined compression takes one)"
            )
        if pres:
            if len({p for _, p in pres}) > 1:
                raise LabError(f"{path}: {pres[1][0]}: the confining pressures differ ({[p for _, p in pres]})")
            test = "confined_compression"
            out["pressure"] = pres[0][1] / MPA
        elif _cyclic(resolved):
            test = "cyclic_compression"
            if "sigma22" not in c or "eps22" not in c:
                raise LabError(f"{path}: a cyclic test needs the macroscopic stress and strain (sigma22, eps22)")
            out["strain"], out["stress"] = H[:, c["eps22"]], H[:, c["sigma22"]] / MPA
            try:
                out["damage"] = unloading_damage(out["strain"], out["stress"])
            except ValueError as e:  # e.g. a run that ended before its first unloading
                raise LabError(f"{path}: {e}") from None
        out.update(test=test, strength=abs(ps) / MPA, strain_at_peak=m.get("strain_at_peak"))
        out.update(E=m.get("E"), nu=m.get("nu"))
        if out["E"] is not None:
            out["E"] = float(out["E"]) / 1e10  # GPa
        if test in ("tension", "compression", "confined_compression") and "sigma22" in c and "eps22" in c:
            out["strain"], out["stress"] = H[:, c["eps22"]], H[:, c["sigma22"]] / MPA
        return out
    if pres:
        test = {"disc": "Brazilian", "notched_beam": "three-point bending"}.get(shape, shape)
        raise LabError(
            f"{path}: {pres[0][0]}: a lateral pressure on a {test} test, which has no confinement "
            "(only the confined compression takes one)"
        )
    if shape == "disc":
        D = float(g["nx"]) * h
        out.update(test="brazilian", diameter=D, thickness=T, strength=splitting_strength(F[k], D, T) / MPA)
        return out
    if shape == "notched_beam":
        L2, a0 = float(g["ny"]) * h, float(g["notch_depth"])
        S = float(g["span"]) if g.get("span") is not None else float(g["nx"]) * h - h
        if g.get("cut") == "drop":  # the cells at the notch's tip went with it: the ligament is not h - a0
            raise LabError(f"{path}: a notched beam cut with 'drop' has no defined ligament (use cut = 'clip')")
        lig = L2 - a0
        out.update(test="three_point_bending", ligament=lig, thickness=T, span=S)
        out["G_F"] = fracture_energy(F, d, lig, T) / N_PER_M
        # the run's own load-drop stop saw the load below COMPLETE (its last history row may lie a step before)
        drop = resolved.get("time", {}).get("end_load_drop")
        stopped = drop is not None and drop <= COMPLETE and "load fell below" in (summary.get("end_reason") or "")
        out["complete"] = bool(out["end_fraction"] <= COMPLETE or stopped)
        out["strength"] = 3.0 * F[k] * S / (2.0 * T * lig * lig) / MPA  # net nominal strength σ_N
        ml, mr = f"u1:{g['name']}.mouth_left", f"u1:{g['name']}.mouth_right"
        if ml in c and mr in c:
            cmod = H[:, c[mr]] - H[:, c[ml]]
            out["cmod_at_peak"] = float(cmod[k])
            out["cmod"] = cmod
        return out
    raise LabError(f"{path}: a {shape} specimen is none of the laboratory tests")


def table(res: dict) -> list:
    """The judged ratios (module docstring) from the numbers of the tests run: rows (quantity, value, reference)."""
    rows = []
    t, cmp_, br, bend, conf, cyc = (res.get(k) for k in TESTS)
    if t:
        rows.append(("f_t [MPa]", t["strength"], "thesis concrete 2.9 (§7.5.1)"))
    if cmp_:
        rows.append(("f_c [MPa]", cmp_["strength"], "thesis concrete 14.9 (§7.5.2)"))
    if t and cmp_:
        rows.append(("f_c / f_t", cmp_["strength"] / t["strength"], "concrete ≈ 10, rock 10–30"))
    if br:
        rows.append(("f_ct,sp [MPa]", br["strength"], "2 F / (π D T)"))
        if t:
            rows.append(("f_ct,sp / f_t", br["strength"] / t["strength"], "fib MC2010: 1.0 (f_ctm = 1.0 f_ct,sp)"))
    if bend:
        note = "" if bend["complete"] else f" (incomplete: the load ended at {bend['end_fraction']:.0%} of its peak)"
        rows.append(("G_F [N/m]" + note, bend["G_F"], "RILEM TC-50"))
        if cmp_:
            fib = fib_fracture_energy(cmp_["strength"] * MPA) / N_PER_M
            rows.append(("G_F / fib MC2010 73 f_cm^0.18", bend["G_F"] / fib, f"1 (fib: {fib:.0f} N/m at f_cm = |f_c|)"))
    if conf:
        for n in conf["runs"]:
            rows.append((f"sigma_1 at sigma_3 = {n['pressure']:g} MPa [MPa]", n["strength"], "peak axial stress"))
        mc = conf["mohr_coulomb"]
        pts = "with the unconfined f_c" if conf["with_unconfined"] else "confined runs only"
        rows.append(("friction angle phi [deg]", mc["phi"], f"Mohr-Coulomb fit, {pts}; concrete about 30-40"))
        rows.append(("cohesion c [MPa]", mc["c"], "Mohr-Coulomb fit"))
        if cmp_:
            rows.append(("c / f_c", mc["c"] / cmp_["strength"], "0.23-0.29 for phi 30-40 (tan(45 - phi/2) / 2)"))
    if cyc:
        dmg = cyc["damage"]
        if dmg["d"]:
            k = int(np.argmax(np.asarray(dmg["stress"])))  # the unloading nearest the peak
            rows.append(
                ("damage 1 - E_u/E_0 at the peak's cycle", dmg["d"][k], "unloading stiffness (E_0 first loading)")
            )
            rows.append(("damage at the last unloading", dmg["d"][-1], f"at eps = {dmg['strain'][-1]:.3g}"))
    return rows


def confined(runs: list, unconfined: dict | None = None) -> dict:
    """The confined compression test from its runs at several pressures (and the unconfined compression's numbers,
    a point σ₃ = 0 of the envelope, when given): the runs, their pressures and peaks (MPa) and the Mohr–Coulomb fit
    (:func:`..analysis.lab.mohr_coulomb`)."""
    s3 = [n["pressure"] for n in runs]
    s1 = [n["strength"] for n in runs]
    if unconfined is not None:
        s3, s1 = [0.0] + s3, [unconfined["strength"]] + s1
    try:
        mc = mohr_coulomb(s3, s1)
    except ValueError as e:
        raise LabError(f"confined compression: {e}") from None
    return {
        "test": "confined_compression",
        "runs": runs,
        "pressures": s3,
        "peaks": s1,
        "with_unconfined": unconfined is not None,
        "mohr_coulomb": mc,
        "strength": mc["f_c"],
        "peak_force": max(n["peak_force"] for n in runs),
        "wall_s": sum(n.get("wall_s") or 0.0 for n in runs),
    }


def _plain(n):
    """A test's numbers without its curves (arrays), for results.json."""
    if isinstance(n, dict):
        return {k: _plain(v) for k, v in n.items() if not isinstance(v, np.ndarray)}
    if isinstance(n, list):
        return [_plain(v) for v in n]
    return n


def material_overrides(path) -> list:
    """The ``[bonds]`` values of a scenario file (a calibrated one, ``polydem calibrate -o``) as ``--set`` overrides
    for every test: ``bonds.<key>=<value>``; LabError if the file gives none."""
    from ..scenario.load import read_toml
    from ..scenario.spec import ScenarioError

    try:
        bonds = read_toml(Path(path))[0].get("bonds") or {}
    except ScenarioError as e:
        raise LabError(str(e)) from None

    def value(v):
        if isinstance(v, str):  # a model's name (bonds.model = "interface")
            return json.dumps(v)
        return ("true" if v else "false") if isinstance(v, bool) else repr(v) if isinstance(v, (int, float)) else None

    sets = []
    for k, v in bonds.items():  # values and the phases' tables ([bonds.aggregate], [bonds.interface])
        for kk, vv in v.items() if isinstance(v, dict) else [(None, v)]:
            s = value(vv)
            if s is not None:
                sets.append(f"bonds.{k}{'' if kk is None else '.' + kk}={s}")
    if not sets:
        raise LabError(f"{path}: no [bonds] values to give the tests' beams")
    return sets


def run_study(out: Path, root: Path, tests=TESTS, smoke=False, quiet=True, pressures=PRESSURES, overrides=()) -> dict:
    """Run (or reuse finished runs of) the tests' scenarios into ``out`` — the confined compression once per
    lateral pressure of ``pressures`` (MPa), every test with ``overrides`` first (e.g. a calibrated material's
    beams, :func:`material_overrides`) — take their numbers, write ``out/results.json``, ``out/lab_table.md``,
    the curves (``lab_curves.png``) and the failure patterns (``lab_failure.png``, each test's last frame)."""
    from ..scenario.load import load_scenario
    from ..scenario.spec import ScenarioError
    from ..solvers import driver
    from ..solvers.protocol import RunOptions, Source

    out.mkdir(parents=True, exist_ok=True)

    def one(t, h5, own=()):
        scen = root / "scenarios" / SCENARIOS[t][1 if smoke else 0]
        ov = list(overrides) + list(own)
        try:
            sc, text = load_scenario(scen, ov)
        except ScenarioError as e:
            raise LabError(str(e)) from None
        sm = driver.obtain(
            sc,
            h5,
            source=Source(str(scen), text, tuple(ov)),
            policy=driver.REFRESH,
            opts=RunOptions(quiet=quiet, threads=1),
        ).summary
        if sm.get("status") != "finished":
            raise LabError(f"{scen}: the run did not finish ({sm.get('failure')})")
        n = numbers(h5)
        if n["test"] != t:
            raise LabError(f"{scen}: its result is a {n['test']} test, not {t}")
        n["scenario"], n["wall_s"] = str(scen), sm.get("wall_time_s")
        return n

    res, pictures = {}, []
    for t in tests:
        if t != "confined_compression":
            res[t] = one(t, out / f"{t}.h5")
            pictures.append((_ending(t.replace("_", " "), res[t]), out / f"{t}.h5"))
            continue
        scen = root / "scenarios" / SCENARIOS[t][1 if smoke else 0]
        try:
            keys = [k for k, _ in _pressures(load_scenario(scen, list(overrides))[0])]
        except ScenarioError as e:
            raise LabError(str(e)) from None
        if not keys:
            raise LabError(f"{scen}: no [[loads]] entry with a pressure for the study to set")
        runs = []
        for P in pressures:
            sets = [f"{k.replace('[', '.').replace(']', '')}={P * MPA!r}" for k in keys]
            runs.append(one(t, out / f"{t}_{P:g}MPa.h5", sets))
            pictures.append((_ending(f"confined, {P:g} MPa", runs[-1]), out / f"{t}_{P:g}MPa.h5"))
        res[t] = confined(runs, res.get("compression"))
    rows = table(res)
    what = f"{'smoke-size' if smoke else 'full-size'} specimens" + (", " + " ".join(overrides) if overrides else "")
    _curves(res, out / "lab_curves.png", what)
    _failure(pictures, out / "lab_failure.png", what)
    keep = {t: _plain(n) for t, n in res.items()}
    (out / "results.json").write_text(
        json.dumps({"tests": keep, "table": rows, "overrides": list(overrides)}, indent=1)
    )
    write_table(rows, out / "lab_table.md")
    return {"tests": res, "table": rows}


def write_table(rows, path: Path):
    """The judged ratios (:func:`table`'s rows) as a Markdown table: quantity, value (4 digits), reference; a ``|``
    in a text (``|f_c|``) escaped, so that every row keeps its three cells (:func:`..report.common.markdown_table`)."""
    text = markdown_table(("quantity", "value", "reference"), [(q, f"{v:.4g}", r) for q, v, r in rows])
    Path(path).write_text(text)


def _ending(label: str, n: dict) -> str:
    """A failure panel's name: the test and where its load ended against its peak (a pattern drawn before the peak
    would show no crack)."""
    return f"{label} (load at the end: {100 * n['end_fraction']:.0f} % of its peak)"


def _curves(res: dict, png: Path, what: str = ""):
    """One panel per curve of the tests run, each titled with its test: the stress–strain curves of the uniaxial
    tension and of the compression tests (unconfined, confined; cyclic), the load–displacement of the Brazilian
    disc, the load–deflection and load–CMOD of the notched beam and the Mohr–Coulomb envelope; the figure titled
    with the study (``what``: which specimens)."""
    from ..report.common import _plt, force_unit, headline, save

    plt = _plt()
    panels = []  # (title, xlabel, ylabel, draw(ax))
    t = res.get("tension")
    if t and "strain" in t:

        def tension(ax):
            ax.plot(t["strain"] * 1e3, t["stress"])
            k = int(np.argmax(t["stress"]))
            ax.plot(t["strain"][k] * 1e3, t["stress"][k], "o", ms=4, label=f"peak f_t = {t['strength']:.2f} MPa")
            ax.legend(fontsize=8)

        panels.append((f"uniaxial tension: f_t = {t['strength']:.2f} MPa", "eps22 [1e-3]", "sigma22 [MPa]", tension))
    cmp_, conf, cyc = res.get("compression"), res.get("confined_compression"), res.get("cyclic_compression")
    curves = ([("unconfined", cmp_)] if cmp_ and "strain" in cmp_ else []) + [
        (f"sigma_3 = {n['pressure']:g} MPa", n) for n in (conf["runs"] if conf else []) if "strain" in n
    ]
    if curves:

        def compression(ax):
            for label, n in curves:
                ax.plot(-n["strain"] * 1e3, -n["stress"], label=label)
            ax.legend(fontsize=8)

        name = "compression, unconfined and confined" if conf and cmp_ else "confined compression" if conf else None
        name = name or f"uniaxial compression: f_c = {cmp_['strength']:.2f} MPa"
        panels.append((name, "-eps22 [1e-3]", "-sigma22 [MPa]", compression))
    if cyc:

        def cyclic(ax):
            ax.plot(-cyc["strain"] * 1e3, -cyc["stress"], lw=0.8)
            d = cyc["damage"]
            if d["d"]:
                ax.plot(np.asarray(d["strain"]) * 1e3, d["stress"], "o", ms=3, label="unloading starts")
                ax.legend(fontsize=8)

        panels.append(("cyclic compression", "-eps22 [1e-3]", "-sigma22 [MPa]", cyclic))
    loads = [n["force"] for n in (res.get("brazilian"), res.get("three_point_bending")) if n]
    div, unit = force_unit(*loads) if loads else (1e5, "N")
    br = res.get("brazilian")
    if br:
        panels.append(
            (
                f"Brazilian: f_ct,sp = {br['strength']:.2f} MPa",
                "strip displacement [mm]",
                f"load [{unit}]",
                lambda ax: ax.plot(br["deflection"] * 10, br["force"] / div),
            )
        )
    bend = res.get("three_point_bending")
    if bend:
        panels.append(
            (
                f"3-point bending: G_F = {bend['G_F']:.0f} N/m",
                "nose deflection [mm]",
                f"load [{unit}]",
                lambda ax: ax.plot(bend["deflection"] * 10, bend["force"] / div),
            )
        )
        if "cmod" in bend:
            panels.append(
                (
                    "3-point bending: load against crack mouth opening",
                    "CMOD [mm]",
                    f"load [{unit}]",
                    lambda ax: ax.plot(bend["cmod"] * 10, bend["force"] / div),
                )
            )
    if conf:
        mc = conf["mohr_coulomb"]

        def envelope(ax):
            s3 = np.asarray(conf["pressures"])
            ax.plot(s3, conf["peaks"], "o", label="peaks")
            x = np.linspace(0.0, s3.max() * 1.1, 20)
            ax.plot(x, mc["f_c"] + mc["N_phi"] * x, "-", label=f"phi = {mc['phi']:.1f} deg, c = {mc['c']:.2f} MPa")
            ax.legend(fontsize=8)

        panels.append(
            ("confined compression: Mohr-Coulomb envelope", "sigma_3 [MPa]", "sigma_1 at the peak [MPa]", envelope)
        )
    if not panels:
        return
    ncols = min(3, len(panels))
    nrows = (len(panels) + ncols - 1) // ncols
    fig, axes = plt.subplots(nrows, ncols, figsize=(4.4 * ncols, 3.7 * nrows + 0.5), squeeze=False)
    for a, (title, xl, yl, draw) in zip(axes.ravel(), panels):
        draw(a)
        a.set(title=title, xlabel=xl, ylabel=yl)
        a.title.set_fontsize(10)
        a.grid(alpha=0.3)
    for a in axes.ravel()[len(panels) :]:
        a.set_visible(False)
    headline(fig, "virtual laboratory: the curves of the tests" + (f" ({what})" if what else ""))
    fig.tight_layout()
    save(fig, png, dpi=130)
    plt.close(fig)


def _failure(pictures: list, png: Path, what: str = ""):
    """The failure pattern of every test: its beams' damage in its last frame (one panel each, named with where its
    load ended against its peak)."""
    from ..report.macro import plot_damage_panels

    if pictures:
        plot_damage_panels(
            [(label, str(p)) for label, p in pictures],
            png,
            ncols=4,
            title="virtual laboratory: the failure pattern of each test, beam damage d in its last frame"
            + (f" ({what})" if what else ""),
        )
