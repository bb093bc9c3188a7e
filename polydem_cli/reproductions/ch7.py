"""Collate the chapter-7 runs into the thesis's figures and numbers (Figs. 7.3–7.13).

Expects the results of ``scenarios/concrete_tension.toml``, ``scenarios/concrete_compression.toml``
and ``scenarios/ch7/*.toml`` as ``<runs>/<scenario stem>.h5`` (what ``make figures-ch7`` writes)
and writes to ``out``:

* ``results.json`` — concrete: beams, E, ν, tensile and compressive strength and the strain at
  the peak, the peak ratios of the fast and rate-dependent runs against the slow rate-independent
  one (thesis 1.03, 1.15, 1.44 in tension; 1.01, ≈1.0, 1.07 in compression), the fictitious
  single-beam ratio κ_0,ra/κ_0 at the macroscopic rate; glued nuts: peaks, the large/small peak
  ratio (thesis simulation 1.5, experiments 1.8), failed beams by orientation and mode at
  û2 = −0.15 cm (thesis 8/12 diagonal, 7/11 horizontal); wall times and particle-steps/s of
  every run; each next to the thesis value;
* ``fig7_3.png`` (the two glued specimens, beams, the weakened beam marked), ``fig7_4.png``
  (small specimen f2–û2 with states a–c), ``fig7_5.png`` (damage at a–c), ``fig7_6.png`` and
  ``fig7_8.png`` (damage at û2 = −0.15 cm), ``fig7_7.png`` (large and small curves),
  ``fig7_9a.png`` (the concrete specimen), ``fig7_10.png``/``fig7_12.png`` (σ22–ε22, ru grey and
  ra black, slow solid and fast dashed as the thesis's footnotes imply), ``fig7_11.png``/
  ``fig7_13.png`` (damage at the end of each curve), ``failures_nuts.png``.

States of Fig. 7.4 (not defined numerically in the thesis): (a) 50 % of the peak before it
(elastic), (b) 90 % of the peak before it (first damage at the lateral edges), (c) the peak.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from ..interactions.bonds.failure import MODES, ORIENTATIONS
from ..io.hdf5 import open_result, read_bonds, read_frames, read_static, writer_pid
from ..report import bonds as rb
from ..report import macro as rm
from ..report.common import label_axes_cm, load_curve, panel_height
from ..report.common import save as _save
from .sources import source

#: the thesis's numbers (chapter 7) this study compares against, from reproductions/sources/schneider2012_ch7.toml
THESIS = source("schneider2012_ch7")

CONCRETE = {  # stem: (load, rate, model)
    "concrete_tension": ("tension", "slow", "ru"),
    "tension_fast_ru": ("tension", "fast", "ru"),
    "tension_slow_ra": ("tension", "slow", "ra"),
    "tension_fast_ra": ("tension", "fast", "ra"),
    "concrete_compression": ("compression", "slow", "ru"),
    "compression_fast_ru": ("compression", "fast", "ru"),
    "compression_slow_ra": ("compression", "slow", "ra"),
    "compression_fast_ra": ("compression", "fast", "ra"),
}
RATES = {"slow": 2.5e-2, "fast": 2.5e-1}  # |eps22 rate| of §7.5, 1/s


def _summary(path):
    with open_result(path) as f:
        return json.loads(f.attrs["summary"]) if "summary" in f.attrs else {}, str(f.attrs.get("status"))


def _cost(s):
    return {
        k: s.get(k)
        for k in ("status", "end_reason", "steps", "dt", "integrator", "wall_time_s", "particle_steps_per_s")
    }


def collate(runs: Path, out: Path, suffix: str = "") -> dict:
    """``suffix``: collate variant runs ``<stem><suffix>.h5`` of the rate-dependent scenarios instead
    (e.g. ``_filtered``); the rate-independent references are always the plain stems."""
    runs, out = Path(runs), Path(out)
    out.mkdir(parents=True, exist_ok=True)
    res = {
        "thesis": THESIS,
        "runs_dir": str(runs),
        "variant_suffix": suffix,
        "missing": [],
        "unfinished": [],
        "runs": {},
    }
    have = _finished_runs(runs, suffix, res)
    conc = _concrete_runs(have, res)
    rep = _concrete_reproduced(conc, have, res)
    variants = _ra_by_dt(runs, have, conc, suffix, rep)
    rep["fictitious_beam_ratio"] = {rate: (r / 1.0e-2) ** 0.13 if r > 1e-2 else 1.0 for rate, r in RATES.items()}
    _nuts(have, res, rep)
    res["reproduced"] = rep
    res["dif"] = _dif_figure(out, rep, suffix)
    (out / "results.json").write_text(json.dumps(res, indent=1, default=float))
    _figures(have, out, variants)
    return res


def _finished_runs(runs, suffix, res) -> dict:
    """{stem: path} of the finished results in ``runs`` (with ``suffix``: the variant runs stand for the
    rate-dependent stems); runs in progress and unfinished ones are left out (said in ``res``)."""
    have = {}
    for p in sorted(runs.glob("*.h5")):
        if writer_pid(p):
            print(f"skipping {p}: run in progress")
            continue
        have[p.stem] = p
    if suffix:
        for stem in list(CONCRETE):
            if CONCRETE[stem][2] == "ra":
                have.pop(stem, None)
                if stem + suffix in have:
                    have[stem] = have[stem + suffix]
    for stem, p in list(have.items()):  # an interrupted run (resume it with run --continue) is not a result yet
        if _summary(p)[1] != "finished":
            print(f"skipping {p}: not finished (resume it with polydem run ... --continue)")
            res["unfinished"].append(stem)
            del have[stem]
    return have


def _concrete_runs(have, res) -> dict:
    """{stem: macroscopic measures} of the concrete runs; their rows of ``res["runs"]``.  A strength is a
    lower bound when the run ended before its peak (``peak_reached`` false)."""
    conc = {}
    for stem in CONCRETE:
        if stem not in have:
            res["missing"].append(stem)
            continue
        s, _ = _summary(have[stem])
        m = s.get("macro") or {}
        conc[stem] = m
        res["runs"][stem] = dict(
            _cost(s),
            peak_stress_MPa=m.get("peak_stress_MPa"),
            peak_reached=m.get("peak_reached"),
            strain_at_peak=m.get("strain_at_peak"),
            E_GPa=m.get("E_GPa"),
            nu=m.get("nu"),
            bonds=(s.get("bonds") or {}).get("count"),
            failed_bonds=(s.get("bond_failure") or {}).get("failed"),
            bond_failure=s.get("bond_failure"),
        )
    return conc


def _concrete_reproduced(conc, have, res) -> dict:
    """The thesis's concrete numbers as reproduced: beams, E, ν (dynamic and static), strengths and strains at
    the peaks, and the peak ratio of every rate variant against its rate-independent reference."""
    rep = {}
    t = conc.get("concrete_tension")
    if t:
        rep.update(
            beams=res["runs"]["concrete_tension"]["bonds"],
            E_GPa=t.get("E_GPa"),
            nu=t.get("nu"),
            tensile_strength_MPa=_magnitude(t.get("peak_stress_MPa")),
            tensile_strain_at_peak=t.get("strain_at_peak"),
        )
        try:
            from ..analysis.elastic import static_response
            from ..scenario.build import build_system

            with open_result(have["concrete_tension"]) as f:
                sc = json.loads(f.attrs["resolved"])
            st = static_response(build_system(sc, str(have["concrete_tension"])))
            rep.update(E_GPa_static=st["E"] / 1e10, nu_static=st["nu"])
        except Exception as e:  # pragma: no cover - diagnostic only
            rep["static_error"] = str(e)
    c = conc.get("concrete_compression")
    if c:
        rep.update(
            compressive_strength_MPa=_magnitude(c.get("peak_stress_MPa")),
            compressive_strain_at_peak=c.get("strain_at_peak"),
        )
    for stem, (load, rate, model) in CONCRETE.items():
        ref = conc.get("concrete_tension" if load == "tension" else "concrete_compression")
        if stem.startswith("concrete_") or not ref or stem not in conc:
            continue
        rep[f"ratio_{load}_{rate}_{model}"] = conc[stem]["peak_stress"] / ref["peak_stress"]
    return rep


def _ra_by_dt(runs, have, conc, suffix, rep) -> dict:
    """The thesis-form ra runs at other time steps (``<stem>_dt<dt>.h5``; their form does not converge with
    dt): {stem: rows by dt}, and their ratios in ``rep``."""
    variants = {}
    for stem, (load, rate, model) in CONCRETE.items():
        if model != "ra" or suffix or stem not in have:
            continue
        ref = conc.get("concrete_tension" if load == "tension" else "concrete_compression")
        rows = []
        for p in [have[stem]] + sorted(runs.glob(f"{stem}_dt*.h5")):
            if writer_pid(p):
                continue
            sm, _ = _summary(p)
            m = sm.get("macro") or {}
            if not m or not ref:
                continue
            rows.append(
                {
                    "result": str(p),
                    "dt": sm.get("dt"),
                    "status": sm.get("status"),
                    "peak_stress_MPa": m["peak_stress_MPa"],
                    "ratio": m["peak_stress"] / ref["peak_stress"],
                    "wall_time_s": sm.get("wall_time_s"),
                }
            )
        rows.sort(key=lambda r: r["dt"])
        if len(rows) > 1:
            variants[stem] = rows
            rep[f"ratio_{load}_{rate}_ra_by_dt"] = {f"{r['dt']:g}": r["ratio"] for r in rows}
    return variants


def _nuts(have, res, rep) -> None:
    """The glued nuts (§7.1): peak load, failed and cracked beams by orientation; the large/small ratios."""
    nuts = {}
    for stem in ("nuts_glued_small", "nuts_glued_large"):
        if stem not in have:
            res["missing"].append(stem)
            continue
        s, _ = _summary(have[stem])
        u, f, drv, tt = load_curve(have[stem])
        k = int(np.argmax(np.abs(f)))
        fails = rm.failure_records(have[stem])
        cnt = {o: int(np.sum(fails["orientation"] == i)) for i, o in enumerate(ORIENTATIONS)} if fails else {}
        by = (
            {
                o: {m: int(np.sum((fails["orientation"] == i) & (fails["mode"] == j))) for j, m in enumerate(MODES)}
                for i, o in enumerate(ORIENTATIONS)
            }
            if fails
            else {}
        )
        nuts[stem] = {
            "peak_f2_kN": abs(float(f[k])) / 1e8,
            "u2_at_peak": float(u[k]),
            "final_u2": float(u[-1]),
            "failed_by_orientation": cnt,
            "failed_by_orientation_and_mode": by,
            "cracked_by_orientation": _cracked(have[stem], -0.15),
        }
        res["runs"][stem] = dict(_cost(s), **nuts[stem])
    if len(nuts) == 2:
        rep["nuts_peak_ratio_large_small"] = (
            nuts["nuts_glued_large"]["peak_f2_kN"] / nuts["nuts_glued_small"]["peak_f2_kN"]
        )
        for size in ("small", "large"):
            n = nuts[f"nuts_glued_{size}"]["cracked_by_orientation"]
            rep[f"nuts_failed_diagonal_{size}"] = n.get("diagonal")
            rep[f"nuts_failed_horizontal_{size}"] = n.get("horizontal")
            n1 = nuts[f"nuts_glued_{size}"]["failed_by_orientation"]
            rep[f"nuts_d1_diagonal_{size}"] = n1.get("diagonal")
            rep[f"nuts_d1_horizontal_{size}"] = n1.get("horizontal")


def _dif_figure(out, rep, suffix):
    """fig_dif.png: the DIF studies found beside the figures (dif_<load>[_filtered]/dif.json) and the
    ratios of the thesis's runs (ra slow/fast over ru slow), with the fib MC2010 curves."""
    from ..workflows.dif import plot

    studies = []
    root = out if (out / "dif_tension_filtered").exists() or (out / "dif_tension").exists() else out.parent
    for load in ("tension", "compression"):
        for tag, label in (
            ("", "thesis form (5.16)"),
            ("_filtered", "filtered rate (option)"),
            ("_ru", "rate-independent beams (inertia only)"),
        ):
            p = root / f"dif_{load}{tag}" / "dif.json"
            if p.exists():
                d = json.loads(p.read_text())
                d["label"] = f"{load}, {label}"
                studies.append(d)
    extra = []
    for load in ("tension", "compression"):
        for rate in ("slow", "fast"):
            v = rep.get(f"ratio_{load}_{rate}_ra")
            if v is not None:
                extra.append(
                    (f"{load} {rate} ra run{' (' + suffix.strip('_') + ')' if suffix else ''}", load, RATES[rate], v)
                )
        th = THESIS["concrete"]
        for rate in ("slow", "fast"):
            extra.append((f"thesis {load} {rate} ra", load, RATES[rate], th[f"ratio_{load}_{rate}_ra"]))
    if not studies and not extra:
        return None
    plot(
        studies,
        out / "fig_dif.png",
        extra=[e for e in extra if e[0].startswith("thesis")] + [e for e in extra if not e[0].startswith("thesis")],
    )
    return {
        "studies": [s.get("label") for s in studies],
        "points": [{"label": lab, "kind": k, "rate": r, "dif": d} for lab, k, r, d in extra],
    }


def _magnitude(v):
    """A strength from a signed peak stress: its magnitude (strengths are positive; stresses tension-positive)."""
    return None if v is None else abs(v)


#: a beam counts as failing (in a crack) at d >= this; with the ductile glue (kappa_m = 0.23) few beams reach
#: d = 1 by u2 = -0.15 cm, and the thesis's counts of "failing" beams (7/8 small, 11/12 large) fit d >= 0.9
CRACK_DAMAGE = 0.9


def _cracked(path, u2):
    """Beams with d >= CRACK_DAMAGE in the frame nearest to the prescribed displacement u2, by orientation."""
    from ..interactions.bonds.failure import beam_angle_deg, orientation_class

    b = read_bonds(path)
    u, f, drv, th = load_curve(path)
    steps, ft, X, _ = read_frames(path)
    kk = int(np.argmin(np.abs(u - u2)))
    k = int(np.argmin(np.abs(ft - th[kk])))
    x0 = read_static(path)["x0"]
    d = x0[b["pairs"][:, 1], :2] - x0[b["pairs"][:, 0], :2]
    o = orientation_class(beam_angle_deg(d[:, 0], d[:, 1]))
    dam = b["frame_d"][k] >= CRACK_DAMAGE
    return {name: int(np.sum(dam & (o == i))) for i, name in enumerate(ORIENTATIONS)} | {
        "u2": float(u[kk]),
        "d_min": CRACK_DAMAGE,
    }


def _kn_curve(path):
    u, f, drv, t = load_curve(path)
    return u, f / 1e8  # dyn -> kN


def _nut_states(u, f):
    a = np.abs(f)
    k = int(np.argmax(a))
    pre = lambda fr: int(np.flatnonzero(a[: k + 1] >= fr * a[k])[0])  # noqa: E731
    return [pre(0.5), pre(0.9), k]


def _specimen_panel(ax, path, title):
    from ..report.specimen import specimen_panel

    specimen_panel(ax, path, title)


def _figures(have, out, variants=None):
    plt = rb._plt()
    small, large = have.get("nuts_glued_small"), have.get("nuts_glued_large")
    if small and large:
        fig, axes = plt.subplots(1, 2, figsize=(10, 4.2))
        _specimen_panel(axes[0], small, "Fig. 7.3a small")
        _specimen_panel(axes[1], large, "Fig. 7.3b large")
        fig.tight_layout()
        _save(fig, out / "fig7_3.png", dpi=150)
        plt.close(fig)
    if small:
        u, f = _kn_curve(small)
        ks = _nut_states(u, f)
        fig, ax = plt.subplots(figsize=(6, 4.3))
        ax.plot(-u, -f, "k-", lw=1.2, label="simulation (22 nuts)")
        for kk, lab in zip(ks, ("(a)", "(b)", "(c)")):
            ax.plot(-u[kk], -f[kk], "ro", ms=5)
            ax.annotate(lab, (-u[kk], -f[kk]), textcoords="offset points", xytext=(6, -10), fontsize=9)
        ax.set_xlabel(r"$-\hat u_2$ [cm]")
        ax.set_ylabel(r"$-f_2$ [kN]")
        ax.set_title("Fig. 7.4: small glued specimen (experiments not available)", fontsize=9)
        ax.grid(alpha=0.3)
        ax.legend(fontsize=8)
        fig.tight_layout()
        _save(fig, out / "fig7_4.png", dpi=150)
        plt.close(fig)
        _damage_at_states(small, [u[k] for k in ks], ["(a)", "(b)", "(c)"], out / "fig7_5.png", "Fig. 7.5")
        rm.plot_damage_panels(
            [("small", small)],
            out / "fig7_6.png",
            u2=-0.15,
            ncols=1,
            titles=[r"Fig. 7.6: small specimen, $\hat u_2$ = −0.15 cm"],
        )
    if large:
        rm.plot_damage_panels(
            [("large", large)],
            out / "fig7_8.png",
            u2=-0.15,
            ncols=1,
            titles=[r"Fig. 7.8: large specimen, $\hat u_2$ = −0.15 cm"],
        )
    if small and large:
        fig, ax = plt.subplots(figsize=(6, 4.3))
        for path, lab, kw in (
            (large, "simulation, large (45 nuts)", dict(color="k")),
            (small, "simulation, small (22 nuts)", dict(color="0.6")),
        ):
            u, f = _kn_curve(path)
            ax.plot(-u, -f, lw=1.2, label=lab, **kw)
        ax.set_xlabel(r"$-\hat u_2$ [cm]")
        ax.set_ylabel(r"$-f_2$ [kN]")
        ax.set_title("Fig. 7.7: large (gr) and small (kl) glued specimens", fontsize=9)
        ax.grid(alpha=0.3)
        ax.legend(fontsize=8)
        fig.tight_layout()
        _save(fig, out / "fig7_7.png", dpi=150)
        plt.close(fig)
        rm.plot_failure_counts([("small", small), ("large", large)], out / "failures_nuts.png")
    if "concrete_tension" in have:
        fig, ax = plt.subplots(figsize=(5.2, 5))
        _specimen_panel(ax, have["concrete_tension"], "Fig. 7.9a concrete")
        fig.tight_layout()
        _save(fig, out / "fig7_9a.png", dpi=150)
        plt.close(fig)
    for load, fig_curve, fig_dmg in (
        ("tension", "fig7_10.png", "fig7_11.png"),
        ("compression", "fig7_12.png", "fig7_13.png"),
    ):
        order = [(s, v) for s, v in CONCRETE.items() if v[0] == load and s in have]
        if not order:
            continue
        curves, styles = [], []
        for stem, (_, rate, model) in order:
            curves.append((f"{model} {rate} ({RATES[rate] * (1 if load == 'tension' else -1):.3g} 1/s)", have[stem]))
            styles.append(dict(color="0.55" if model == "ru" else "k", ls="-" if rate == "slow" else "--"))
        num = fig_curve[3:-4].replace("_", ".")
        rm.plot_stress_strain(
            curves, out / fig_curve, title=f"Fig. {num}: concrete, {load}", styles=styles, annotate=False
        )
        var = [(stem, rows) for stem, rows in (variants or {}).items() if CONCRETE[stem][0] == load]
        if var:
            cv, sv = [], []
            for stem, rows in var:
                for k, r in enumerate(rows):
                    cv.append((f"ra {CONCRETE[stem][1]}, dt = {r['dt']:g} s", Path(r["result"])))
                    sv.append(
                        dict(
                            color=str(0.65 * (1 - k / max(len(rows) - 1, 1))),
                            ls="-" if CONCRETE[stem][1] == "slow" else "--",
                            lw=1.0,
                        )
                    )
            rm.plot_stress_strain(
                cv,
                out / fig_curve.replace(".png", "_dt.png"),
                title=f"Fig. {num}: concrete, {load}; rate-dependent runs at several time steps (thesis: 1e-9 s)",
                styles=sv,
                annotate=False,
            )
        numd = fig_dmg[3:-4].replace("_", ".")
        rm.plot_damage_panels(
            [(lab, p) for lab, p in curves], out / fig_dmg, titles=[f"Fig. {numd} {lab}" for lab, _ in curves]
        )


def _damage_at_states(path, u_states, labels, png, fig_no):
    plt = rb._plt()
    from matplotlib.collections import LineCollection

    b = read_bonds(path)
    u, f, drv, t = load_curve(path)
    steps, ft, X, _ = read_frames(path)
    # panels as high as the specimen (the glued nuts are about twice as wide as high), so the colour bar spans them
    height = panel_height(read_static(path)["x0"], 4.2, 0.7)
    fig, axes = plt.subplots(1, len(u_states), figsize=(4.2 * len(u_states) + 0.8, height), squeeze=False)
    lc = None
    for ax, us, lab in zip(axes[0], u_states, labels):
        kk = int(np.argmin(np.abs(u - us)))
        k = int(np.argmin(np.abs(ft - t[kk])))
        d = b["frame_d"][k]
        seg = np.stack([X[k][b["pairs"][:, 0], :2], X[k][b["pairs"][:, 1], :2]], axis=1)
        lc = LineCollection(seg, cmap=rm.damage_cmap(), linewidths=2.0)
        lc.set_array(d)
        lc.set_clim(0, 1)
        ax.add_collection(lc)
        ax.autoscale()
        ax.set_aspect("equal")
        ax.set_title(rf"{fig_no} {lab}: $\hat u_2$ = {u[kk]:.3g} cm (frame $t$ = {ft[k]:.3g} s)", fontsize=8)
        label_axes_cm(ax)
    fig.colorbar(lc, ax=axes.ravel().tolist(), label=r"beam damage $d$ [−]", shrink=0.75)
    _save(fig, png, dpi=150)
    plt.close(fig)
