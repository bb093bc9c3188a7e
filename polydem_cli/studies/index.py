"""``polydem study index``: ``outputs/figures/INDEX.md`` — one row per result figure of the three sources: the
file(s), whether they exist, the make target and command that make them, the wall time of the runs behind them
(from their summaries), and the key numbers beside the source's, with whether they agree within the stated
tolerance.  Figures and numbers not yet produced are listed as missing, never left out.
"""

from __future__ import annotations

import csv
import glob
import json
from pathlib import Path

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


def _ch5(fig):
    r = _get(_json(fig / "ch5" / "results.json"), "reproduced") or {}
    t = r.get("table_5_1") or {}
    return [
        ("Table 5.1 ra/ru tension (reference)", _get(t, "reference", "tension"), 1.15, 0.03),
        ("Table 5.1 ra/ru compression (reference)", _get(t, "reference", "compression"), 1.15, 0.03),
        ("Table 5.1 ra/ru tension (2 alpha)", _get(t, "2alpha", "tension"), None, None),
    ]


def _ch7(fig):
    r = _get(_json(fig / "ch7" / "results.json"), "reproduced") or {}
    return [
        ("peak ratio tension fast ru", r.get("ratio_tension_fast_ru"), 1.03, 0.03),
        ("peak ratio tension slow ra", r.get("ratio_tension_slow_ra"), 1.15, 0.03),
        ("peak ratio tension fast ra", r.get("ratio_tension_fast_ra"), 1.44, 0.03),
        ("peak ratio compression fast ru", r.get("ratio_compression_fast_ru"), 1.01, 0.03),
        ("peak ratio compression fast ra", r.get("ratio_compression_fast_ra"), 1.07, 0.03),
    ]


def _ch7_nuts(fig):
    r = _get(_json(fig / "ch7" / "results.json"), "reproduced") or {}
    return [("peak ratio large/small glued nuts", r.get("nuts_peak_ratio_large_small"), 1.5, 0.1)]


def _concrete(fig):
    s = _json(Path("outputs") / "ch7" / "concrete_tension.summary.json") or _json(
        Path("outputs") / "concrete_tension.summary.json"
    )
    m = (s or {}).get("macro") or {}
    c = (_json(Path("outputs") / "ch7" / "concrete_compression.summary.json") or {}).get("macro") or {}
    return [
        ("E [GPa]", m.get("E_GPa"), 33.5, 0.05),
        ("nu", m.get("nu"), 0.2, 0.1),
        ("tensile strength [N/mm²]", m.get("peak_stress_MPa"), 2.9, 0.05),
        ("compressive strength [N/mm²]", c.get("peak_stress_MPa"), -14.9, 0.1),
    ]


def _lh(fig):
    p = fig / "lh" / "table1_1.csv"
    if not p.exists():
        return [("Table 1.1", None, None, None)]
    out = []
    with open(p) as fh:
        for row in csv.DictReader(fh):
            kc = row["kc_over_k2"]
            out.append((f"peak p=500, kc/k2={kc} [N/m²]", float(row["peak_500"]), float(row["paper_peak_500"]), 0.1))
            out.append((f"cohesion c, kc/k2={kc} [N/m²]", float(row["c"]), float(row["paper_c"]), 0.2))
    return out


def _coupling(fig):
    r = _json(fig / "coupling" / "results.json")
    if r is None:
        return [("time ratio adaptive/fully resolved", None, None, None)]
    out = []
    for name, row in r["examples"].items():
        src = row.get("source_time_ratio")
        out.append(
            (f"{name}: time ratio adaptive/resolved", row["time_ratio"], src if isinstance(src, float) else None, None)
        )
        err = row.get("peak_error", row.get("reaction_error"))
        out.append((f"{name}: peak (reaction) error", err, 0.0, 0.03))
    return out


def _integrators(fig):
    r = _json(fig / "ch3" / "integrators.json")
    return [
        ("Gear order, oscillator", _get(r, "oscillator", "PC", "order"), 6.0, 0.05),
        ("Gear order, collision", _get(r, "collision", "PC", "order"), 2.0, 0.05),
    ]


#: (source, figure, files under outputs/figures, make target, command, runs behind it (globs), key numbers)
ROWS = [
    (S12, "Figs. 3.8, 3.9", ["ch3/integrators.png"], "figures-ch3", "polydem study integrators", [], _integrators),
    *[
        (
            S12,
            f"Fig. 5.{k}",
            [f"ch5/fig5_{k}.png"],
            "figures-ch5",
            "polydem study ch5",
            ["outputs/ch5/*.summary.json"],
            None,
        )
        for k in (7, 8, 9, 10, 11, 12, 13, 17, 20, 21)
    ],
    (
        S12,
        "Table 5.1",
        ["ch5/results.json"],
        "figures-ch5",
        "polydem study ch5",
        ["outputs/ch5/rate_*.summary.json"],
        _ch5,
    ),
    (
        S12,
        "Figs. 6.4-6.7 (114 nuts, defect)",
        ["ch6/nuts_defect_frames.png", "ch6/nuts_defect_velocity.png"],
        "figures-ch6",
        "polydem report outputs/ch6/nuts_defect.h5 --times 0,12.9,19.4",
        ["outputs/ch6/nuts_defect.summary.json"],
        None,
    ),
    (
        S12,
        "Figs. 6.8, 6.9 (217 nuts)",
        ["ch6/nuts_perfect_frames.png", "ch6/nuts_perfect_velocity.png"],
        "figures-ch6",
        "polydem report outputs/ch6/nuts_perfect.h5 --times 5.9,20.2,22.4,41.2",
        ["outputs/ch6/nuts_perfect.summary.json"],
        None,
    ),
    (
        S12,
        "Fig. 7.3",
        ["ch7/fig7_3.png"],
        "figures-ch7",
        "polydem study ch7",
        ["outputs/ch7/nuts_*.summary.json"],
        _ch7_nuts,
    ),
    *[
        (
            S12,
            f"Fig. 7.{k}",
            [f"ch7/fig7_{k}.png"],
            "figures-ch7",
            "polydem study ch7",
            ["outputs/ch7/nuts_*.summary.json"],
            None,
        )
        for k in (4, 5, 6, 7, 8)
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
        None,
    ),
    *[
        (LH, f"Fig. 1.{k}", [f"lh/{f}"], "figures-lh", "polydem study lh", ["outputs/lh/*.summary.json"], None)
        for k, f in (
            (3, "fig_lh_1_3_networks.png"),
            (4, "fig_lh_1_4_relaxation.png"),
            (5, "fig_lh_1_5_rate.png"),
            (6, "fig_lh_1_6_p500.png"),
            (7, "fig_lh_1_7_p100.png"),
            (8, "fig_lh_1_8_mohr.png"),
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
        "polydem study coupling",
        [],
        _coupling,
    ),
]


def _wall(globs) -> float | None:
    tot, seen = 0.0, False
    for g in globs:
        for p in glob.glob(g):
            s = _json(p) or {}
            if "wall_time_s" in s:
                tot += float(s["wall_time_s"])
                seen = True
    return tot if seen else None


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
        "| source | figure | files | make target / command | wall of its runs | key numbers: ours / source (tolerance) |",
        "|---|---|---|---|---|---|",
    ]
    counts = {"present": 0, "missing": 0, "agree": 0, "differ": 0, "open": 0}
    for src, figure, files, target, cmd, runs, key in ROWS:
        have = [f for f in files if (figdir / f).exists()]
        counts["present" if len(have) == len(files) else "missing"] += 1
        fl = ", ".join(f"[{f}]({f})" if f in have else f"{f} (missing)" for f in files)
        w = _wall(runs)
        nums = []
        for q, ours, theirs, tol in key(figdir) if key else []:
            if ours is None:
                nums.append(f"{q}: not yet computed")
                counts["open"] += 1
                continue
            if theirs is None or tol is None:
                nums.append(f"{q}: {_fmt(ours)}" + (f" / {_fmt(theirs)}" if theirs is not None else ""))
                continue
            ok = abs(ours - theirs) <= tol * max(abs(theirs), 1e-12) if theirs != 0 else abs(ours) <= tol
            counts["agree" if ok else "differ"] += 1
            nums.append(f"{q}: {_fmt(ours)} / {_fmt(theirs)} (±{tol:.0%}) **{'agrees' if ok else 'differs'}**")
        lines.append(
            f"| {src} | {figure} | {fl} | `make {target}` / `{cmd}` | "
            f"{'—' if w is None else f'{w / 60:.1f} min'} | {'<br>'.join(nums) or '—'} |"
        )
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
