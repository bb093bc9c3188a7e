"""The virtual material laboratory: the standard tests of concrete and rock on one bonded Voronoi material, and
the numbers a model is judged by (``polydem study lab``).

Tests (each a scenario; the material is whatever the scenarios give it — the thesis concrete here):

* ``tension`` / ``compression`` — the thesis's uniaxial panels (driven top row, held bottom row): the peak
  nominal stress f_t, f_c and E, ν of the run summary (:mod:`..analysis.macro`);
* ``brazilian`` — a disc on load strips (``scenarios/lab/``): f_ct,sp = 2 F_max / (π D T);
* ``three_point_bending`` — a notched beam: RILEM TC-50's G_F = W_F / ((h − a₀) T), the net nominal strength
  σ_N = 3 F_max S / (2 T (h − a₀)²), the crack mouth opening at the peak (:mod:`..analysis.lab`).

What the test is follows from the result's specimen (its Voronoi ``shape``: rectangle, disc, notched_beam) and,
for a rectangle, from the sign of its peak stress.  The study reports beside them the ratios users judge a
bonded-particle model by: f_c/f_t (concrete ≈ 10, rock 10–30), f_ct,sp/f_t (fib MC2010 §5.1.5.1 takes
f_ctm = 1.0 f_ct,sp), and G_F against fib MC2010's ``73 f_cm^0.18`` N/m.  A G_F whose load–deflection curve did
not come down below ``COMPLETE`` of its peak is marked incomplete (its tail's work is missing).
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from ..analysis.lab import N_PER_M, fib_fracture_energy, fracture_energy, splitting_strength
from ..analysis.macro import MPA

#: the tests in the order the study runs them
TESTS = ("tension", "compression", "brazilian", "three_point_bending")
#: the scenarios of the study, full size and smoke size (relative to the repository's scenarios/)
SCENARIOS = {
    "tension": ("concrete_tension.toml", "ch7/smoke_concrete_tension.toml"),
    "compression": ("concrete_compression.toml", "ch7/smoke_concrete_compression.toml"),
    "brazilian": ("lab/brazilian.toml", "lab/smoke_brazilian.toml"),
    "three_point_bending": ("lab/three_point_bending.toml", "lab/smoke_three_point_bending.toml"),
}
#: a fracture test's curve counts as complete when its load ends below this fraction of its peak
COMPLETE = 0.05


class LabError(ValueError):
    """A result that is not one of the laboratory tests (or lacks what its numbers need)."""


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
    if shape == "rectangle":
        m = summary.get("macro") or {}
        if "peak_stress" not in m:
            raise LabError(f"{path}: the run summary has no macroscopic measures ([macro] of the scenario)")
        ps = float(m["peak_stress"])
        out.update(test="tension" if ps > 0 else "compression", strength=abs(ps) / MPA)
        out.update(E=m.get("E"), nu=m.get("nu"))
        if out["E"] is not None:
            out["E"] = float(out["E"]) / 1e10  # GPa
        return out
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
        out["complete"] = out["end_fraction"] <= COMPLETE
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
    t, cmp_, br, bend = (res.get(k) for k in TESTS)
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
    return rows


def run_study(out: Path, root: Path, tests=TESTS, smoke=False, quiet=True) -> dict:
    """Run (or reuse finished runs of) the tests' scenarios into ``out``, take their numbers, write
    ``out/results.json``, ``out/lab_table.md`` and the fracture tests' curves (``lab_curves.png``)."""
    from ..scenario.load import load_scenario
    from ..solvers import driver
    from ..solvers.protocol import RunOptions, Source

    out.mkdir(parents=True, exist_ok=True)
    res = {}
    for t in tests:
        scen = root / "scenarios" / SCENARIOS[t][1 if smoke else 0]
        sc, text = load_scenario(scen)
        h5 = out / f"{t}.h5"
        sm = driver.obtain(
            sc, h5, source=Source(str(scen), text, ()), policy=driver.REFRESH, opts=RunOptions(quiet=quiet, threads=1)
        ).summary
        if sm.get("status") != "finished":
            raise LabError(f"{scen}: the run did not finish ({sm.get('failure')})")
        n = numbers(h5)
        if n["test"] != t:
            raise LabError(f"{scen}: its result is a {n['test']} test, not {t}")
        n["scenario"], n["wall_s"] = str(scen), sm.get("wall_time_s")
        res[t] = n
    rows = table(res)
    _curves(res, out / "lab_curves.png")
    keep = {t: {k: v for k, v in n.items() if not isinstance(v, np.ndarray)} for t, n in res.items()}
    (out / "results.json").write_text(json.dumps({"tests": keep, "table": rows}, indent=1))
    lines = ["| quantity | value | reference |", "|---|---|---|"]
    lines += [f"| {q} | {v:.4g} | {r} |" for q, v, r in rows]
    (out / "lab_table.md").write_text("\n".join(lines) + "\n")
    return {"tests": res, "table": rows}


def _curves(res: dict, png: Path):
    """Load–displacement of the Brazilian disc and load–deflection / load–CMOD of the notched beam."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 3, figsize=(13, 3.8))
    br = res.get("brazilian")
    if br:
        axes[0].plot(br["deflection"] * 10, br["force"] * 1e-5)
        axes[0].set(title=f"Brazilian: f_ct,sp = {br['strength']:.2f} MPa", xlabel="strip displacement [mm]")
    bend = res.get("three_point_bending")
    if bend:
        axes[1].plot(bend["deflection"] * 10, bend["force"] * 1e-5)
        axes[1].set(title=f"3-point bending: G_F = {bend['G_F']:.0f} N/m", xlabel="nose deflection [mm]")
        if "cmod" in bend:
            axes[2].plot(bend["cmod"] * 10, bend["force"] * 1e-5)
            axes[2].set(title="load against crack mouth opening", xlabel="CMOD [mm]")
    for ax in axes:
        ax.set_ylabel("load [N]")
        ax.grid(alpha=0.3)
    fig.tight_layout()
    fig.savefig(png, dpi=130)
    plt.close(fig)
