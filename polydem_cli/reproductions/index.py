"""``polydem study index``: ``outputs/figures/INDEX.md`` — one row per result figure of the three sources: the
file(s), whether they exist, the make target and command that make them, the wall time of the runs behind them
(from their summaries), and the key numbers beside the source's, with whether they agree within the stated
tolerance.  Figures and numbers not yet produced are listed as missing, never left out.
"""

from __future__ import annotations

import glob
import json
from pathlib import Path

from ..report.common import markdown_cell

S12, LH, SO = "Schneider 2012", "Luding & Herrmann", "Sorg 2014"


def _json(path):
    p = Path(path)
    return json.loads(p.read_text()) if p.exists() else None


def _get(d, *keys):
    for k in keys:
        if not isinstance(d, dict) or k not in d:
            return None
        d = d[k]
    return d


def _ch5_rep(fig):
    return _get(_json(fig / "ch5" / "results.json"), "reproduced") or {}


def _bond_failure(summary_path):
    return (_json(summary_path) or {}).get("bond_failure") or {}


def _summary_bonds(summary_path):
    return (_json(summary_path) or {}).get("bonds") or {}


def _check(value, test):
    """A qualitative verdict: None while the value is not computed, else ``test(value)``."""
    return None if value is None else bool(test(value))


def _failed_by_orientation(stem, label, order, description):
    """Failed beams of a chapter-5 run by orientation, listed in ``order`` (the orientations the thesis says
    dominate first): they agree when the first two outnumber the third more than three times."""
    bo = _bond_failure(Path("outputs") / "ch5" / f"{stem}.summary.json").get("by_orientation") or None
    shown = None if bo is None else " / ".join(str(bo[o]) for o in order)
    ok = _check(bo, lambda b: b[order[0]] + b[order[1]] > 3 * b[order[2]])
    return (f"{label}failed beams at the end, {' / '.join(order)}", shown, description, None, ok)


def _ratio_check(r, key, label, description, test):
    return (label, r.get(key), description, None, _check(r.get(key), test))


def _ch5_fig(k):
    """Key numbers of Fig. 5.k: the thesis's numbers where it gives them, else the measured quantity the
    figure shows beside the thesis's description (a qualitative check)."""
    tension_order, compression_order = ("vertical", "diagonal", "horizontal"), ("horizontal", "diagonal", "vertical")

    def key(fig):
        r = _ch5_rep(fig)
        t = r.get("table_5_1") or {}
        if k == 6:
            sb = _summary_bonds(Path("outputs") / "ch5" / "tension.summary.json")
            return [("beams of the 30 x 30 cell specimen", sb.get("count"), 2568, 0.01)]
        if k == 18:
            desc = "mostly vertical, a wavy horizontal crack (figure only)"
            return [_failed_by_orientation("rate_tension_ra", "ra tension: ", tension_order, desc)]
        if k == 19:
            desc = "horizontal to diagonal, V-shaped cracks (figure only)"
            return [_failed_by_orientation("rate_compression_ra", "ra compression: ", compression_order, desc)]
        if k == 7:
            return [
                ("cells / beams", r.get("beams_30x30"), 2568, 0.01),
                ("peak ratio compression / tension", r.get("peak_ratio_compression_tension"), 3.34, 0.05),
                (
                    "elastic energy at peak, compression / tension",
                    r.get("energy_ratio_at_peak_compression_tension"),
                    9.91,
                    0.10,
                ),
            ]
        if k == 8:  # tension: mostly vertical beams fail, a horizontal main crack
            return [_failed_by_orientation("tension", "", tension_order, "mostly vertical (figure only)")]
        if k == 10:  # compression: horizontal-to-diagonal beams, almost all damaged at d4
            sb = _summary_bonds(Path("outputs") / "ch5" / "compression.summary.json")
            # the map shows every beam with d > 0: the damaged ones still acting and the failed ones (d = 1)
            frac = (sb["damaged"] + sb["failed"]) / sb["count"] if sb.get("count") else None
            return [
                _failed_by_orientation("compression", "", compression_order, "horizontal to diagonal (figure only)"),
                (
                    "damaged fraction of the beams at the end",
                    frac,
                    "almost all (taken as > 0.8)",
                    None,
                    _check(frac, lambda v: v > 0.8),
                ),
            ]
        if k in (9, 11):
            # strain maps (5.9, 5.11): the failure modes the maps show (5.8); tension: the axial strain dominates,
            # compression: tension, mixed and shear failure of compressed beams, so shear failures must occur
            stem = "tension" if k == 9 else "compression"
            bm = _bond_failure(Path("outputs") / "ch5" / f"{stem}.summary.json").get("by_mode") or None
            modes = ("tension", "shear", "bending", "under_compression")
            return [
                (
                    "failed beams by dominating part of (5.8): tension / shear / bending / under compression",
                    None if bm is None else " / ".join(str(bm[m]) for m in modes),
                    "axial strain dominates" if k == 9 else "tension, mixed and shear of compressed beams",
                    None,
                    _check(
                        bm,
                        (lambda b: b["tension"] > b["shear"])
                        if k == 9
                        else (lambda b: b["shear"] + b["under_compression"] > 0),
                    ),
                )
            ]
        if k == 12:
            return [
                ("peak ratio 2κ_0 / reference, tension", r.get("peak_ratio_2kappa0_tension"), 1.93, 0.05),
                _ratio_check(
                    r,
                    "peak_ratio_2kappam_tension",
                    "peak ratio 2κ_m / reference, tension",
                    "slightly higher",
                    lambda v: 1.0 < v < 1.2,
                ),
            ]
        if k == 13:
            return [
                ("peak ratio 2κ_0 / reference, compression", r.get("peak_ratio_2kappa0_compression"), 1.79, 0.05),
                _ratio_check(
                    r,
                    "peak_ratio_2kappam_compression",
                    "peak ratio 2κ_m / reference, compression",
                    "slightly larger",
                    lambda v: 1.0 < v < 1.2,
                ),
                _ratio_check(
                    r,
                    "peak_ratio_10kappam_compression",
                    "peak ratio 10κ_m / reference, compression",
                    "higher",
                    lambda v: v > 1.0,
                ),
            ]
        if k == 17:
            return [
                ("ra/ru tension", _get(t, "reference", "tension"), 1.15, 0.03),
                ("ra/ru compression", _get(t, "reference", "compression"), 1.15, 0.03),
            ]
        if k == 20:
            return [
                ("ra/ru tension, 2α", _get(t, "2alpha", "tension"), 1.25, 0.03),
                ("ra/ru tension, 2ε̇_0", _get(t, "2eps0_dot", "tension"), 1.10, 0.03),
            ]
        if k == 21:
            return [
                ("ra/ru compression, 2α", _get(t, "2alpha", "compression"), 1.32, 0.03),
                ("ra/ru compression, 2ε̇_0", _get(t, "2eps0_dot", "compression"), 1.12, 0.03),
            ]
        return []

    return key


def _ch5(fig):
    r = _ch5_rep(fig)
    out = []
    for tab, what in (("table_5_1", "Table 5.1"), ("table_5_1_rate_filter", "option rate_filter")):
        t = r.get(tab) or {}
        src = {"reference": (1.13, 1.15, 1.15), "2alpha": (1.27, 1.25, 1.32), "2eps0_dot": (1.05, 1.10, 1.12)}
        for row, (beam, ten, com) in src.items():
            if tab == "table_5_1":
                out.append((f"{what} {row}: κ_0,ra/κ_0 single beam", _get(t, row, "beam"), beam, 0.01))
            out.append((f"{what} {row}: ra/ru tension", _get(t, row, "tension"), ten, 0.03))
            out.append((f"{what} {row}: ra/ru compression", _get(t, row, "compression"), com, 0.03))
    return out


def _ch7(fig):
    from .ch7 import THESIS  # the thesis's numbers, kept once (the ch7 study writes them beside ours)

    r = _get(_json(fig / "ch7" / "results.json"), "reproduced") or {}
    src = THESIS["concrete"]
    rows = [
        ("tension fast ru", "ratio_tension_fast_ru"),
        ("tension slow ra", "ratio_tension_slow_ra"),
        ("tension fast ra", "ratio_tension_fast_ra"),
        ("compression fast ru", "ratio_compression_fast_ru"),
        ("compression fast ra", "ratio_compression_fast_ra"),
        # §7.5, Fig. 7.12: "about the same" strength as the slow ru run (no number): taken as 1.00
        ("compression slow ra (thesis: about the same, 1.00)", "ratio_compression_slow_ra"),
    ]
    return [(f"peak ratio {what}", r.get(key), src[key], 0.03) for what, key in rows]


def _ch7_rep(fig):
    return _get(_json(fig / "ch7" / "results.json"), "reproduced") or {}


def _ch7_nuts(k):
    """Glued nuts (Figs. 7.3-7.8): the thesis's 1.5 peak ratio and its 8/12 diagonal, 7/11 horizontal failing
    beams (small/large); the peak load and displacement where the thesis shows the curve only."""

    def key(fig):
        r = _ch7_rep(fig)
        runs = _get(_json(fig / "ch7" / "results.json"), "runs") or {}
        if k == 3:
            out = []
            for size in ("small", "large"):
                sb = _summary_bonds(Path("outputs") / "ch7" / f"nuts_glued_{size}.summary.json")
                out.append((f"{size}: beams (one with E_h −10 %)", sb.get("count"), None, None))
            return out
        if k in (4, 5):
            s_ = runs.get("nuts_glued_small") or {}
            return [
                ("small: peak f_2 [kN]", s_.get("peak_f2_kN"), "the mean experimental curve (figure only)", None, None),
                ("small: û_2 at the peak [cm]", s_.get("u2_at_peak"), None, None),
            ]
        if k in (6, 8):
            size = "small" if k == 6 else "large"
            d, h = (8, 7) if k == 6 else (12, 11)
            return [
                (f"{size}: failed diagonal beams at û_2 = −0.15 cm", r.get(f"nuts_failed_diagonal_{size}"), d, 0.2),
                (f"{size}: failed horizontal beams at û_2 = −0.15 cm", r.get(f"nuts_failed_horizontal_{size}"), h, 0.2),
            ]
        if k == 7:
            s_ = runs.get("nuts_glued_large") or {}
            return [
                ("peak ratio large / small", r.get("nuts_peak_ratio_large_small"), 1.5, 0.1),
                ("large: peak f_2 [kN]", s_.get("peak_f2_kN"), None, None),
            ]
        return []

    return key


def _nuts_history(stem):
    """(max overlap area / particle area, max elastic tangential displacement [cm], relative energy error) of
    a chapter-6 run, or Nones."""
    p = Path("outputs") / "ch6" / f"{stem}.h5"
    s = _json(Path("outputs") / "ch6" / f"{stem}.summary.json") or {}
    if not p.exists() or s.get("status") != "finished":
        return None, None, None
    from ..io.hdf5 import read_history

    cols, tab = read_history(p)
    ov = float(tab[:, cols.index("max_overlap_ratio")].max()) if "max_overlap_ratio" in cols else None
    ut = float(tab[:, cols.index("max_ut_elastic")].max()) if "max_ut_elastic" in cols else None
    return ov, ut, _get(s, "observables", "energy_balance_error")


def _ch6(stem):
    def key(fig):
        ov, ut, err = _nuts_history(stem)
        return [
            ("max overlap area / hexagon area", ov, "< 3 %", None, _check(ov, lambda v: v < 0.03)),
            ("max elastic tangential displacement [cm]", ut, "< 0.004", None, _check(ut, lambda v: v < 0.004)),
            ("relative energy balance error", err, None, None),
        ]

    return key


def _ch6_specimens(fig):
    out = []
    for stem, n in (("nuts_defect", 114), ("nuts_perfect", 217)):
        s = _json(Path("outputs") / "ch6" / f"{stem}.summary.json") or {}
        p = s.get("particles")
        out.append((f"{stem}: nuts (particles without the two plates)", None if p is None else p - 2, n, 0.0))
    return out


def _dif(fig):
    """DIF studies: ours against fib Model Code 2010 at 1 and 10 1/s (the thesis's CEB comparison)."""
    out = []
    for d in sorted(glob.glob(str(fig / "ch7" / "dif_*" / "dif.json"))):
        r = _json(d) or {}
        name = Path(d).parent.name[4:]
        for pt in r.get("points") or []:
            if pt.get("rate") in (1.0, 10.0) and pt.get("dif") is not None:
                out.append((f"{name}: DIF at {pt['rate']:g} 1/s (fib)", pt["dif"], pt.get("fib"), 0.1))
    return out or [("DIF at 1 and 10 1/s", None, None, None)]


def _lh_res(fig):
    return _json(fig / "lh" / "results.json") or {}


def _lh_fig(k):
    def key(fig):
        r = _lh_res(fig)
        paper = r.get("paper") or {}
        rows = r.get("table1_1") or []
        if k == 3:
            nets = r.get("networks") or []
            return [
                (f"contacts at ε_zz = {n['eps_zz']:.3g}", n["contacts"], "figure only", None, None) for n in nets
            ] or [("contacts", None, None, None)]
        if k == 4:
            rel = r.get("relaxation") or {}
            return [
                (f"{name}: wall stress at the end [N/m²]", v.get("p_end"), 400.0, 0.05) for name, v in rel.items()
            ] or [("relaxation", None, None, None)]
        if k == 5:
            rate = r.get("rate") or {}
            vals = [(float(f), v.get("peak_corrected")) for f, v in rate.items()]
            vals.sort()
            rising = all(b[1] > a[1] for a, b in zip(vals, vals[1:])) if len(vals) > 1 else None
            return [
                (f"f = {f:g} 1/s: peak σ_zz (inertia corrected) [N/m²]", v, "rises with f (figure only)", None, rising)
                for f, v in vals
            ] or [("rate", None, None, None)]
        if k in (6, 7):
            p = "500" if k == 6 else "100"
            return [
                (f"peak p={p}, kc/k2={row['kc_over_k2']:g} [N/m²]", row[f"peak_{p}"], row[f"paper_peak_{p}"], 0.1)
                for row in rows
            ] or [(f"peak p={p}", None, None, None)]
        if k == 8:
            return [
                (f"friction angle φ, kc/k2={row['kc_over_k2']:g} [°]", row.get("phi_deg"), paper.get("phi_deg"), 0.2)
                for row in rows
            ] or [("friction angle", None, None, None)]
        return []

    return key


def _abs(v):
    return None if v is None else abs(v)


def _concrete(fig):
    s = _json(Path("outputs") / "ch7" / "concrete_tension.summary.json") or _json(
        Path("outputs") / "concrete_tension.summary.json"
    )
    m = (s or {}).get("macro") or {}
    c = (_json(Path("outputs") / "ch7" / "concrete_compression.summary.json") or {}).get("macro") or {}
    return [
        ("E [GPa]", m.get("E_GPa"), 33.5, 0.05),
        ("nu", m.get("nu"), 0.2, 0.1),
        ("tensile strength f_t [N/mm²]", _abs(m.get("peak_stress_MPa")), 2.9, 0.05),
        # strengths are magnitudes (the thesis writes the compressive one signed, -14.9)
        ("compressive strength f_c [N/mm²]", _abs(c.get("peak_stress_MPa")), 14.9, 0.1),
    ]


def _lh(fig):
    rows = _lh_res(fig).get("table1_1") or []
    if not rows:
        return [("Table 1.1", None, None, None)]
    out = []
    for row in rows:
        kc = f"{row['kc_over_k2']:g}"
        out.append((f"peak p=500, kc/k2={kc} [N/m²]", row["peak_500"], row["paper_peak_500"], 0.1))
        out.append((f"cohesion c, kc/k2={kc} [N/m²]", row["c"], row["paper_c"], 0.2))
    return out


def _coupling(fig):
    r = _json(fig / "coupling" / "results.json")
    if r is None:
        return [("time ratio adaptive/fully resolved", None, None, None)]
    out = []
    changed = r.get("changed_settings") or {}  # a run with --adaptive KEY=VALUE: not the examples' own settings
    tag = " (adaptive " + ", ".join(f"{k}={v}" for k, v in changed.items()) + ")" if changed else ""
    for name, row in r["examples"].items():
        src = row.get("source_time_ratio")
        out.append(
            (
                f"{name}: time ratio adaptive/resolved{tag}",
                row["time_ratio"],
                src if isinstance(src, float) else None,
                None,
            )
        )
        err = row.get("peak_error", row.get("reaction_error"))
        out.append((f"{name}: peak (reaction) error{tag}", err, 0.0, 0.03))
    return out


def _integrators(fig):
    r = _json(fig / "ch3" / "integrators.json")
    return [
        ("Gear order, oscillator", _get(r, "oscillator", "PC", "order"), 6.0, 0.05),
        ("Gear order, collision", _get(r, "collision", "PC", "order"), 2.0, 0.05),
    ]


#: (source, figure, files under outputs/figures, make target, command, runs behind it (globs), key numbers)
ROWS = [
    (
        S12,
        "Figs. 3.8, 3.9",
        ["ch3/integrators.png"],
        "figures-ch3",
        "polydem study integrators",
        ["integrators"],
        _integrators,
    ),
    *[
        (
            S12,
            f"Fig. 5.{k}",
            [f"ch5/fig5_{k}.png"],
            "figures-ch5",
            "polydem study ch5",
            [f"outputs/ch5/{r}.summary.json" for r in runs],
            _ch5_fig(k),
        )
        for k, runs in (
            (6, ("tension",)),
            (7, ("tension", "compression")),
            (8, ("tension",)),
            (9, ("tension",)),
            (10, ("compression",)),
            (11, ("compression",)),
            (12, ("tension", "tension_2kappa0", "tension_2kappam")),
            (13, ("compression", "compression_2kappa0", "compression_2kappam", "compression_10kappam")),
            (17, ("rate_tension_ru", "rate_tension_ra", "rate_compression_ru", "rate_compression_ra")),
            (18, ("rate_tension_ra",)),
            (19, ("rate_compression_ra",)),
            (20, ("rate_tension_ru", "rate_tension_ra", "rate_tension_ra_2alpha", "rate_tension_ra_2eps0")),
            (
                21,
                (
                    "rate_compression_ru",
                    "rate_compression_ra",
                    "rate_compression_ra_2alpha",
                    "rate_compression_ra_2eps0",
                ),
            ),
        )
    ],
    (
        S12,
        "Table 5.1",
        ["ch5/table5_1.csv"],
        "figures-ch5",
        "polydem study ch5",
        ["outputs/ch5/rate_*.summary.json"],
        _ch5,
    ),
    (
        S12,
        "Fig. 6.3 (the two specimens)",
        ["ch6/nuts_defect_specimen.png", "ch6/nuts_perfect_specimen.png"],
        "figures-ch6",
        "polydem report outputs/ch6/nuts_{defect,perfect}.h5",
        ["outputs/ch6/nuts_*.summary.json"],
        _ch6_specimens,
    ),
    (
        S12,
        "Figs. 6.4-6.6 (114 nuts, defect)",
        ["ch6/nuts_defect_frames.png", "ch6/nuts_defect_velocity.png", "ch6/nuts_defect_closeup.png"],
        "figures-ch6",
        "polydem report outputs/ch6/nuts_defect.h5 --times 0,12.9,19.4",
        ["outputs/ch6/nuts_defect.summary.json"],
        _ch6("nuts_defect"),
    ),
    (
        S12,
        "Figs. 6.7-6.9 (217 nuts)",
        ["ch6/nuts_perfect_frames.png", "ch6/nuts_perfect_velocity.png"],
        "figures-ch6",
        "polydem report outputs/ch6/nuts_perfect.h5 --times 5.9,20.2,22.4,41.2",
        ["outputs/ch6/nuts_perfect.summary.json"],
        _ch6("nuts_perfect"),
    ),
    *[
        (
            S12,
            f"Fig. 7.{k}",
            [f"ch7/fig7_{k}.png"],
            "figures-ch7",
            "polydem study ch7",
            ["outputs/ch7/nuts_*.summary.json"],
            _ch7_nuts(k),
        )
        for k in (3, 4, 5, 6, 7, 8)
    ],
    (
        S12,
        "Fig. 7.9 (concrete slow ru)",
        ["ch7/fig7_9a.png"],
        "figures-ch7",
        "polydem study ch7",
        ["outputs/ch7/concrete_*.summary.json"],
        _concrete,
    ),
    (
        S12,
        "Figs. 7.10-7.13 (rate effects)",
        [f"ch7/fig7_{k}.png" for k in (10, 11, 12, 13)],
        "figures-ch7",
        "polydem study ch7",
        ["outputs/ch7/tension_*.summary.json", "outputs/ch7/compression_*.summary.json"],
        _ch7,
    ),
    (
        S12,
        "DIF against fib MC2010",
        ["ch7/fig_dif.png"],
        "figures-ch7",
        "polydem study dif + polydem study ch7",
        ["outputs/figures/ch7/dif_*/*.summary.json"],
        _dif,
    ),
    *[
        (
            LH,
            f"Fig. 1.{k}",
            [f"lh/{f}"],
            "figures-lh",
            "polydem study lh",
            [f"outputs/lh/{g}.summary.json" for g in globs],
            _lh_fig(k),
        )
        for k, f, globs in (
            (3, "fig_lh_1_3_networks.png", ("prepare_p500", "load_p500_kc2")),
            (4, "fig_lh_1_4_relaxation.png", ("relax_*",)),
            (5, "fig_lh_1_5_rate.png", ("rate_*", "load_p500_kc1")),  # f = 10 1/s: the k_c = k_2 = 2 k_1 loading
            (6, "fig_lh_1_6_p500.png", ("prepare_p500", "load_p500_*")),
            (7, "fig_lh_1_7_p100.png", ("prepare_p100", "load_p100_*")),
            (8, "fig_lh_1_8_mohr.png", ("load_p100_*", "load_p500_*")),
        )
    ],
    (LH, "Table 1.1", ["lh/table1_1.csv"], "figures-lh", "polydem study lh", ["outputs/lh/load_*.summary.json"], _lh),
    (
        SO,
        "the four examples",
        ["coupling/coupling_curves.png"]
        + [
            f"coupling/coupling_mesh_{n}.png"
            for n in (
                "homogeneous_elastic",
                "heterogeneous_elastic",
                "homogeneous_softening",
                "heterogeneous_softening",
            )
        ],
        "figures-coupling",
        "polydem study coupling --width 80 --rows 48",
        ["coupling"],
        _coupling,
    ),
]


def _coupling_wall() -> float | None:
    r = _json(Path("outputs") / "figures" / "coupling" / "results.json")
    if not r:
        return None
    tot = 0.0
    for row in r["examples"].values():
        for side in ("reference", "adaptive"):
            tot += float((row.get(side) or {}).get("wall_s") or 0.0)
    return tot or None


def _wall(globs) -> float | None:
    """Wall seconds of the runs behind a figure (their summaries); "coupling": the study's solves."""
    if globs == ["coupling"]:
        return _coupling_wall()
    if globs == ["integrators"]:
        return _get(_json(Path("outputs") / "figures" / "ch3" / "integrators.json"), "meta", "wall_s")
    tot, seen = 0.0, False
    for g in globs:
        for p in glob.glob(g):
            s = _json(p) or {}
            if "wall_time_s" in s:
                tot += float(s["wall_time_s"])
                seen = True
    return tot if seen else None


def _scenarios(globs) -> str:
    """The scenario files behind a figure, from the globs of its runs' summaries (outputs/D/NAME.summary.json is
    the run of scenarios/D/NAME.toml; the concrete panel's main jobs live at the top of scenarios/)."""
    if globs == ["integrators"]:
        return "— (the test problems of thesis §3.3.2, built in)"
    if globs == ["coupling"]:
        return "`scenarios/coupling/*.toml`"
    out = []
    for g in globs:
        if g.startswith("outputs/figures/ch7/dif_"):  # polydem study dif: the scenarios at several strain rates
            out += ["scenarios/ch7/*_slow_ra_filtered.toml", "scenarios/concrete_*.toml (rates varied)"]
            continue
        d, name = g.removeprefix("outputs/").removesuffix(".summary.json").split("/", 1)
        out.append(f"scenarios/{name}.toml" if name.startswith("concrete_") else f"scenarios/{d}/{name}.toml")
    return ", ".join(f"`{x}`" for x in dict.fromkeys(out))


def _fmt(v):
    if v is None:
        return "—"
    if isinstance(v, float):
        return f"{v:.4g}"
    return str(v)


def build(figdir=Path("outputs/figures"), out=None) -> dict:
    """Write INDEX.md; returns counts (figures present / missing, numbers agreeing / not / unknown)."""
    figdir = Path(figdir)
    out = Path(out) if out else figdir / "INDEX.md"
    lines = [
        "# Result figures (generated by `polydem study index`; `make figures` rebuilds everything)",
        "",
        "| source | figure | files | scenarios | make target / command | wall of its runs "
        "| key numbers: ours / source (tolerance) |",
        "|---|---|---|---|---|---|---|",
    ]
    counts = {"present": 0, "missing": 0, "agree": 0, "differ": 0, "open": 0}
    for src, figure, files, target, cmd, runs, key in ROWS:
        have = [f for f in files if (figdir / f).exists()]
        counts["present" if len(have) == len(files) else "missing"] += 1
        fl = ", ".join(f"[{f}]({f})" if f in have else f"{f} (missing)" for f in files)
        w = _wall(runs)
        nums = []
        for item in key(figdir) if key else []:
            q, ours, theirs, tol = item[:4]
            verdict = item[4] if len(item) > 4 else None  # a qualitative check: True, False or None
            if ours is None:
                nums.append(f"{q}: not yet computed")
                counts["open"] += 1
                continue
            if len(item) > 4:
                said = f"{q}: {_fmt(ours)} / {_fmt(theirs)}"
                if verdict is not None:
                    counts["agree" if verdict else "differ"] += 1
                    said += f" **{'agrees' if verdict else 'differs'}**"
                nums.append(said)
                continue
            if theirs is None or tol is None or isinstance(theirs, str):
                nums.append(f"{q}: {_fmt(ours)}" + (f" / {_fmt(theirs)}" if theirs is not None else " (source: —)"))
                continue
            ok = abs(ours - theirs) <= tol * max(abs(theirs), 1e-12) if theirs != 0 else abs(ours) <= tol
            counts["agree" if ok else "differ"] += 1
            nums.append(f"{q}: {_fmt(ours)} / {_fmt(theirs)} (±{tol:.0%}) **{'agrees' if ok else 'differs'}**")
        cells = (
            src,
            figure,
            fl,
            _scenarios(runs),
            f"`make {target}` / `{cmd}`",
            "—" if w is None else (f"{w:.1f} s" if w < 60 else f"{w / 60:.1f} min"),
            "<br>".join(markdown_cell(n) for n in nums) or "—",
        )  # every cell escaped: a '|' in a number's name (|f2|) would split the row
        lines.append("| " + " | ".join(c if k == 6 else markdown_cell(c) for k, c in enumerate(cells)) + " |")
    lines += [
        "",
        f"{counts['present']} figure rows complete, {counts['missing']} with missing files; key numbers: "
        f"{counts['agree']} agree, {counts['differ']} differ, {counts['open']} not yet computed.  Why the "
        "differences: docs/reproduction.md.",
        "",
    ]
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text("\n".join(lines))
    return counts
