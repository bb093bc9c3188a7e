"""Collate the chapter-5 runs into the thesis's figures and numbers (Figs. 5.7–5.21, Table 5.1).

Expects the results of ``scenarios/ch5/*.toml`` as ``<runs>/<scenario stem>.h5`` (what ``make
figures`` writes) and produces, in ``out``:

* ``results.json`` — specimen counts, peak loads and ratios (compression/tension 3.34,
  2κ_0 ratios 1.93 / 1.79), stored elastic energy at the peak (ratio 9.91), Table 5.1
  (κ_0,ra/κ_0 of a single beam at the macroscopic rate, peak ratios ra/ru; also for the option
  ``bonds.rate_filter``, ``rate_*_filtered.toml``, where those runs exist), wall times, each next to the
  thesis value;
* ``fig5_6.png`` (the specimen, its beams and their parameters), ``fig5_7.png`` (tension and compression
  curves with states), ``fig5_8.png``/``fig5_10.png``
  (damage maps), ``fig5_9.png``/``fig5_11.png`` (strain maps), ``fig5_12.png``/``fig5_13.png``
  (parameter variations), ``fig5_17.png``, ``fig5_20.png``, ``fig5_21.png`` (rate dependence),
  ``fig5_18.png``/``fig5_19.png`` (damage of the rate-dependent runs).

Runs that are missing are reported as such; nothing is silently tuned.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from ..io.hdf5 import open_result, read_history, writer_pid
from ..report import bonds as rb
from ..report.common import load_curve
from ..report.common import save as _save
from .sources import source

#: the thesis's numbers (chapter 5) this study compares against, from reproductions/sources/schneider2012_ch5.toml
THESIS = source("schneider2012_ch5")


def _peak(path):
    """(|peak f2|, û2 at peak, elastic energy in bonds at peak, summary) of one result."""
    cols, tab = read_history(path)
    c = {n: i for i, n in enumerate(cols)}
    f = tab[:, c["f2:specimen.top"]]
    k = int(np.argmax(np.abs(f)))
    with open_result(path) as h5:
        summary = json.loads(h5.attrs["summary"]) if "summary" in h5.attrs else {}
    return abs(float(f[k])), float(tab[k, c["u2:specimen.top"]]), float(tab[k, c["elastic_bonds"]]), summary


def _ratio(a, b):
    return None if a is None or b is None else a / b


def collate(runs: Path, out: Path) -> dict:
    """The chapter-5 study from the finished results in ``runs``: figures and the comparison table against the
    thesis in ``out``; results still written or unfinished are skipped with a note; returns the collated numbers."""
    runs, out = Path(runs), Path(out)
    out.mkdir(parents=True, exist_ok=True)
    have = {}
    for p in sorted(runs.glob("*.h5")):
        if writer_pid(p):
            print(f"skipping {p}: run in progress")
        else:
            have[p.stem] = p
    for stem, p in list(have.items()):  # an interrupted run (resume it with run --continue) is not a result yet
        try:
            with open_result(p) as h5:
                status = str(h5.attrs.get("status"))
        except Exception:  # noqa: BLE001 - a foreign file: _peak below says so
            continue
        if status != "finished":
            print(f"skipping {p}: not finished (resume it with polydem run ... --continue)")
            del have[stem]
    peaks = {}
    for stem, p in sorted(have.items()):
        try:
            peaks[stem] = _peak(p)
        except Exception as e:  # an unfinished or foreign file
            peaks[stem] = None
            print(f"skipping {p}: {e}")
    pk = {k: (v[0] if v else None) for k, v in peaks.items()}
    res = {"thesis": THESIS, "runs_dir": str(runs), "missing": [], "runs": {}}
    for stem, v in peaks.items():
        if v:
            s = v[3]
            res["runs"][stem] = {
                "peak_f2": v[0],
                "u2_at_peak": v[1],
                "elastic_bonds_at_peak": v[2],
                "status": s.get("status"),
                "end_reason": s.get("end_reason"),
                "steps": s.get("steps"),
                "wall_time_s": s.get("wall_time_s"),
                "particle_steps_per_s": s.get("particle_steps_per_s"),
                "bonds": s.get("bonds"),
                "specimens": s.get("specimens"),
            }
    needed = [
        "tension",
        "compression",
        "tension_2kappa0",
        "tension_2kappam",
        "compression_2kappa0",
        "compression_2kappam",
        "compression_10kappam",
        "rate_tension_ru",
        "rate_tension_ra",
        "rate_tension_ra_2alpha",
        "rate_tension_ra_2eps0",
        "rate_compression_ru",
        "rate_compression_ra",
        "rate_compression_ra_2alpha",
        "rate_compression_ra_2eps0",
    ]
    res["missing"] = [n for n in needed if pk.get(n) is None]
    rep = {}
    if "tension" in res["runs"]:
        rep["beams_30x30"] = res["runs"]["tension"]["bonds"]["count"] if res["runs"]["tension"]["bonds"] else None
    rep["peak_ratio_compression_tension"] = _ratio(pk.get("compression"), pk.get("tension"))
    if peaks.get("compression") and peaks.get("tension"):
        rep["energy_ratio_at_peak_compression_tension"] = peaks["compression"][2] / peaks["tension"][2]
    rep["peak_ratio_2kappa0_tension"] = _ratio(pk.get("tension_2kappa0"), pk.get("tension"))
    rep["peak_ratio_2kappa0_compression"] = _ratio(pk.get("compression_2kappa0"), pk.get("compression"))
    rep["peak_ratio_2kappam_tension"] = _ratio(pk.get("tension_2kappam"), pk.get("tension"))
    rep["peak_ratio_2kappam_compression"] = _ratio(pk.get("compression_2kappam"), pk.get("compression"))
    rep["peak_ratio_10kappam_compression"] = _ratio(pk.get("compression_10kappam"), pk.get("compression"))
    rate = 1.0e-6 / 30.0  # macroscopic strain rate of §5.2.3
    # Table 5.1 of the thesis's form (5.16), and of the option bonds.rate_filter (rate_*_filtered.toml)
    for key, variant in (("table_5_1", ""), ("table_5_1_rate_filter", "_filtered")):
        t51 = {}
        for name, alpha, e0, suffix in (
            ("reference", 0.1, 1e-8, ""),
            ("2alpha", 0.2, 1e-8, "_2alpha"),
            ("2eps0_dot", 0.1, 2e-8, "_2eps0"),
        ):
            t51[name] = {
                "beam": (rate / e0) ** alpha,
                "tension": _ratio(pk.get(f"rate_tension_ra{suffix}{variant}"), pk.get("rate_tension_ru")),
                "compression": _ratio(pk.get(f"rate_compression_ra{suffix}{variant}"), pk.get("rate_compression_ru")),
            }
        rep[key] = t51
    res["reproduced"] = rep
    (out / "results.json").write_text(json.dumps(res, indent=1))
    _table_5_1(rep, out / "table5_1.csv")
    _figures(have, out)
    return res


def _table_5_1(rep, path):
    """Table 5.1 as CSV: per parameter set the peak ratios ra/ru (κ_0,ra/κ_0 of a single beam at the
    specimen's strain rate, the specimen in tension and in compression), ours beside the thesis's; the rows
    of the option bonds.rate_filter after those of the thesis's form (5.16).  Empty cells: run missing."""
    import csv

    with open(path, "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(["form", "parameters", "quantity", "polydem", "thesis"])
        for key, form in (("table_5_1", "thesis (5.16)"), ("table_5_1_rate_filter", "option rate_filter")):
            for row, vals in (rep.get(key) or {}).items():
                for q in ("beam", "tension", "compression"):
                    ours = vals.get(q)
                    w.writerow([form, row, q, "" if ours is None else f"{ours:.4f}", THESIS["table_5_1"][row][q]])


def _unit(paths):
    from ..report.common import force_unit

    return force_unit(*[load_curve(p)[1] for p in paths])


def _mark_states(ax, u, f, div):
    """The states z1-z4 (tension) or d1-d4 (compression) of the damage maps, marked on a curve."""
    st = rb.auto_states(u, f)
    for s, lab in zip(st, rb._state_labels(st)):
        k = int(np.argmin(np.abs(u - s)))
        ax.plot(u[k], f[k] / div, "ro", ms=4)
        ax.annotate(lab, (u[k], f[k] / div), textcoords="offset points", xytext=(5, 5), fontsize=8)


def _figures(have, out):
    plt = rb._plt()
    if "tension" in have and "compression" in have:
        fig, ax = plt.subplots(figsize=(7, 4.5))
        div, unit = _unit([have["tension"], have["compression"]])
        for stem in ("tension", "compression"):
            u, f, drv, t = load_curve(have[stem])
            ax.plot(u, f / div, "k-", lw=1.1)
            _mark_states(ax, u, f, div)
        ax.set_xlabel(r"$\hat u_2$ [cm]")
        ax.set_ylabel(rf"$f_2$ [{unit}]")
        ax.set_title("Fig. 5.7: tension and compression (rate-independent beams)")
        ax.grid(alpha=0.3)
        fig.tight_layout()
        _save(fig, out / "fig5_7.png", dpi=130)
        plt.close(fig)
    if "tension" in have:
        from ..report.specimen import bond_parameters, specimen_panel

        fig, ax = plt.subplots(figsize=(7.6, 5.2))
        specimen_panel(ax, have["tension"], "Fig. 5.6: specimen", bond_parameters(have["tension"]))
        fig.tight_layout()
        _save(fig, out / "fig5_6.png", dpi=150)
        plt.close(fig)
    for stem, png in (("rate_tension_ra", "fig5_18.png"), ("rate_compression_ra", "fig5_19.png")):
        if stem in have:  # damage of the rate-dependent runs at their states z1-z4 / d1-d4
            u, f, drv, t = load_curve(have[stem])
            rb.plot_damage_maps(have[stem], out / png, rb.auto_states(u, f))
    for stem, dmg, strain in (("tension", "fig5_8.png", "fig5_9.png"), ("compression", "fig5_10.png", "fig5_11.png")):
        if stem in have:
            u, f, drv, t = load_curve(have[stem])
            st = rb.auto_states(u, f)
            rb.plot_damage_maps(have[stem], out / dmg, st)
            rb.plot_strain_maps(have[stem], out / strain, st[2])
    groups = {
        "fig5_12.png": (
            "Fig. 5.12: tension, parameter variation",
            [("reference", "tension"), (r"2$\kappa_0$", "tension_2kappa0"), (r"2$\kappa_m$", "tension_2kappam")],
        ),
        "fig5_13.png": (
            "Fig. 5.13: compression, parameter variation",
            [
                ("reference", "compression"),
                (r"2$\kappa_0$", "compression_2kappa0"),
                (r"2$\kappa_m$", "compression_2kappam"),
                (r"10$\kappa_m$", "compression_10kappam"),
            ],
        ),
        "fig5_17.png": (
            "Fig. 5.17: rate-independent (ru) and rate-dependent (ra) beams",
            [
                ("ru tension", "rate_tension_ru"),
                ("ra tension", "rate_tension_ra"),
                ("ru compression", "rate_compression_ru"),
                ("ra compression", "rate_compression_ra"),
            ],
        ),
        "fig5_20.png": (
            "Fig. 5.20: tension, rate-dependent variations",
            [
                ("ru", "rate_tension_ru"),
                ("ra", "rate_tension_ra"),
                (r"ra 2$\alpha$", "rate_tension_ra_2alpha"),
                (r"ra 2$\dot\varepsilon_0$", "rate_tension_ra_2eps0"),
            ],
        ),
        "fig5_21.png": (
            "Fig. 5.21: compression, rate-dependent variations",
            [
                ("ru", "rate_compression_ru"),
                ("ra", "rate_compression_ra"),
                (r"ra 2$\alpha$", "rate_compression_ra_2alpha"),
                (r"ra 2$\dot\varepsilon_0$", "rate_compression_ra_2eps0"),
            ],
        ),
    }
    for png, (title, curves) in groups.items():
        present = [(lab, stem) for lab, stem in curves if stem in have]
        if len(present) < 2:
            continue
        fig, ax = plt.subplots(figsize=(7, 4.5))
        div, unit = _unit([have[stem] for _, stem in present])
        for lab, stem in present:
            u, f, drv, t = load_curve(have[stem])
            ax.plot(u, f / div, label=lab, lw=1.0)
            if png == "fig5_17.png" and stem.endswith("_ra"):  # the states of Figs. 5.18/5.19
                _mark_states(ax, u, f, div)
        ax.set_xlabel(r"$\hat u_2$ [cm]")
        ax.set_ylabel(rf"$f_2$ [{unit}]")
        ax.set_title(title, fontsize=10)
        ax.legend(fontsize=8)
        ax.grid(alpha=0.3)
        fig.tight_layout()
        _save(fig, out / png, dpi=130)
        plt.close(fig)
