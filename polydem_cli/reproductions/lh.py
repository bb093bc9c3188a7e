"""Luding & Herrmann analysis (``polydem study lh``): macroscopic response of the biaxial box, Table 1.1.

From each loading run ``load_p<P>_kc<K>.h5`` (scenarios/lh/) and its history table:

* z(t): height of the box, ``servo_length:right`` (face distance bottom–top); x(t): width, the faces of
  the right and left walls (``wall_face:*``); z0, x0 at t = 0 (the relaxed state);
* ε_zz = 1 − z/z0 (positive in compression), ε_V = (xz − x0z0)/(x0z0) (inferred: the paper does not define it);
* σ_xx = F_right/(h z), σ_zz = F_top/(h x) from the disks' forces on the walls (``wall_force:*``), h the
  depth (the walls' thickness, 1 m); the viscous over-stress correction (LH 1.10) σ_zz^corr = p_x σ_zz/σ_xx;
* the peak of σ_zz^corr (the maximum including fluctuations, as the paper); ν from the initial slope of ε_V:
  1 − ν = −dε_V/dε_zz over ε_zz ≤ 0.3 %; the later slope d' over the last third of the loading and the
  dilatancy angle from d' = 2 sin ψ/(1 − sin ψ) (the paper's extra "tan" is a misprint);
* for each k_c the Mohr circles [p_x, σ^corr_peak] of the two pressures and their common tangent
  τ = c + σ tan φ: sin φ = (r2 − r1)/(m2 − m1), c = (r1 − m1 sin φ)/cos φ (m centres, r radii).
* what σ_xx − p_x is: by the side wall's equation of motion (LH 1.2) the wall's damping stress γ_x ẋ/(h z)
  (plus its inertia, negligible for the light walls): ``sxx_minus_p_vs_wall_damping_correlation`` of each run
  in results.json measures it — the over-stress that the correction (LH 1.10) divides out is the damping of the
  wall, not a property of the material;
* a peak that falls on the last point of the loading (within ``END_TOL`` = 1 % of the largest strain) is where
  the loading stopped, not where the stress turned: ``peak_is_lower_bound`` (results.json) and ``peak_<p>_lower_bound`` (table1_1.csv) say so, and the
  docs' table writes it "≥ …".

Also, when their results are present: the contact networks of Fig. 1.3 (``load_p500_kc2``: overlapping
pairs of the frames nearest ε_zz = 0, 0.013 and the final state, line width ∝ overlap δ, a proxy of the
force), the relaxation study of Fig. 1.4 (``relax_*``: the material's pressure on the right wall
F_x/(h z) against time; τ of an exponential fit p_f − A e^(−t/τ) over the approach to p_f = 400) and the
rate study of Fig. 1.5 (``rate_p500_f*`` with ``load_p500_kc1`` as f = 10: ε_V, σ_zz, σ_xx and σ_zz/σ_xx
against ε_zz, and each rate's peak stress and stress ratio).

Writes table1_1.csv, results.json and figures fig_lh_1_3 … fig_lh_1_8 to the output folder.
"""

from __future__ import annotations

import csv
import json
import math
from pathlib import Path

import numpy as np

from ..report.common import save as _save_figure
from .sources import source

#: the paper's numbers (Table 1.1, ν, dilatancy, slopes) this study compares against, from
#: reproductions/sources/luding_herrmann.toml
PAPER = source("luding_herrmann")
KCS = ("0", "0.5", "1", "2", "4")
#: Fig. 1.5: (loading frequency f [1/s], run) at p_x = 500, k_c = 2 k_1 = k_2; f = 10 is the Table 1.1 loading
RATE_RUNS = [(5, "rate_p500_f5"), (10, "load_p500_kc1"), (20, "rate_p500_f20"), (40, "rate_p500_f40")]
PRESSURES = ("100", "500")
PA = 10.0  # g/(cm s^2) per N/m^2
EZZ = r"$\varepsilon_{zz}$ [−]"  # the abscissa of the loading figures (LH: eps_zz = 1 - z/z0, compression positive)


def measures(path) -> dict:
    """Macroscopic curves of one loading run (stresses in N/m^2)."""
    import json

    from ..io.hdf5 import open_result, read_history, read_static

    cols, d = read_history(path)
    h = {c: d[:, j] for j, c in enumerate(cols)}
    st = read_static(path)
    depth = float(st["thickness"][st["group"] == st["group_names"].index("right")][0])
    z = h["servo_length:right"]
    x = h["wall_face:right"] - h["wall_face:left"]
    z0, x0 = z[0], x[0]
    ezz = 1.0 - z / z0
    ev = (x * z - x0 * z0) / (x0 * z0)
    sxx = h["wall_force:right"] / (depth * z) / PA
    szz = h["wall_force:top"] / (depth * x) / PA
    m = {"t": h["time"], "ezz": ezz, "ev": ev, "sxx": sxx, "szz": szz, "z0": z0, "x0": x0}
    # the side wall's damping force per area, gamma_x xdot / (h z) (x outward): by the wall's equation of motion
    # (LH 1.2) sigma_xx - p_x is this plus the wall's inertia m_x xddot / (h z), negligible for the light walls
    with open_result(path) as f:
        servo = [s for s in json.loads(f.attrs["resolved"]).get("servo", []) if s["set"] == "right"]
    if servo and len(h["time"]) > 2:
        xdot = np.gradient(h["wall_face:right"], h["time"])
        m["damping"] = servo[0]["gamma"] * xdot / (depth * z) / PA
        m["p_x"] = servo[0]["pressure"] / PA
    return m


def analyse(m: dict, p: float) -> dict:
    """Figures of one biaxial test at confining pressure ``p`` from its macroscopic measures ``m`` (LH 2.1–2.3): the
    corrected peak stress ratio and the strain at it (flagged when it is a lower bound), the initial and late
    slopes of ε_v against ε_zz, Poisson's ratio and the dilatancy angle, the initial specimen size."""
    load = m["ezz"] >= 0
    ezz, ev = m["ezz"], m["ev"]
    sxx = np.where(np.abs(m["sxx"]) > 0, m["sxx"], np.nan)
    corr = p * m["szz"] / sxx
    k = int(np.nanargmax(np.where(load, corr, -np.inf)))
    top = float(np.max(ezz))
    ini = (ezz > 0) & (ezz <= min(0.003, 0.3 * top))
    s1 = float(np.polyfit(ezz[ini], ev[ini], 1)[0]) if ini.sum() >= 3 else float("nan")
    rising = np.concatenate([[True], np.diff(ezz) > 0])
    late = rising & (ezz >= 2.0 / 3.0 * top)
    s2 = float(np.polyfit(ezz[late], ev[late], 1)[0]) if late.sum() >= 3 else float("nan")
    sin_psi = s2 / (2.0 + s2) if s2 == s2 else float("nan")
    extra = {}
    if "damping" in m:  # sigma_xx - p_x against the wall damping gamma_x xdot / (h z)
        ok = np.isfinite(sxx) & np.isfinite(m["damping"])
        extra["sxx_minus_p_vs_wall_damping_correlation"] = float(
            np.corrcoef(sxx[ok] - m["p_x"], m["damping"][ok])[0, 1]
        )
    return extra | {
        "peak_corrected": float(corr[k]),
        "peak_is_lower_bound": at_loading_end(ezz, k),
        "eps_at_peak": float(ezz[k]),
        "initial_slope": s1,
        "late_slope": s2,
        "nu": 1.0 + s1,
        "psi_deg": math.degrees(math.asin(sin_psi)) if abs(sin_psi) <= 1 else float("nan"),
        "z0_cm": float(m["z0"]),
        "x0_cm": float(m["x0"]),
    }


#: a peak within this fraction of the largest strain from it fell where the loading (nearly) stopped
END_TOL = 0.01


def at_loading_end(ezz, k) -> bool:
    """Is the peak at index ``k`` on the last point of the loading: at a strain within ``END_TOL`` of the largest
    ε_zz of the run?  There the stress was still rising when the push stopped (the cosine law LH 1.1 comes to
    rest at its end), so the peak is a lower bound of the material's, not a turning point."""
    top = float(np.nanmax(ezz))
    return bool(top > 0 and ezz[k] >= (1.0 - END_TOL) * top)


def mohr_coulomb(p1, s1, p2, s2):
    """Common tangent of the circles [p1, s1] and [p2, s2]: (φ in degrees, c)."""
    m1, r1, m2, r2 = (p1 + s1) / 2, (s1 - p1) / 2, (p2 + s2) / 2, (s2 - p2) / 2
    sphi = (r2 - r1) / (m2 - m1)
    c = (r1 - m1 * sphi) / math.sqrt(1 - sphi * sphi)
    return math.degrees(math.asin(sphi)), c


#: variants of the p = 100 loading runs (``polydem study lh --variant``): "" the shipped protocol (each pressure
#: prepared at its own p), "u" the p = 500 packing unloaded to p = 100 (prepare_p100_from_p500.toml)
VARIANTS = {"": "each pressure prepared at its own p", "u": "p = 100 runs from the p = 500 packing unloaded to 100"}


def collate(runs: Path, out: Path, variant: str = "") -> dict:
    """Table 1.1, Figs. 1.3-1.8 and results.json from the loading runs in ``runs``; ``variant`` (VARIANTS) takes
    the p = 100 runs ``load_p100<variant>_kc<K>.h5`` and writes ``table1_1<_variant>.csv`` etc."""
    from ..mpl import pyplot

    plt = pyplot()

    out.mkdir(parents=True, exist_ok=True)
    res, curves, missing = _loading_runs(runs, variant)
    table = _table_1_1(res)
    sfx = f"_{variant}" if variant else ""
    with open(out / f"table1_1{sfx}.csv", "w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=list(table[0]))
        w.writeheader()
        w.writerows(table)
    _figs_1_6_1_7(res, curves, out, variant, sfx, plt)
    if any(r["c"] is not None for r in table):
        _fig_1_8(table, out, sfx, plt)
    extra = {}
    if not variant:
        extra["networks"] = _fig_networks(runs / "load_p500_kc2.h5", out, plt)
        extra["relaxation"] = _fig_relaxation(runs, out, plt)
        extra["rate"] = _fig_rate(runs, out, plt)
    summary = {
        "variant": VARIANTS[variant],
        "runs": res,
        "table1_1": table,
        "paper": PAPER,
        "missing": missing,
        **extra,
    }
    (out / f"results{sfx}.json").write_text(json.dumps(summary, indent=1))
    return summary


def _loading_runs(runs, variant):
    """(measures and analysis per run, curves per (p, k_c), runs missing or unreadable) of the loading runs."""
    from ..io.hdf5 import ResultError

    res, curves, missing = {}, {}, []
    for p in PRESSURES:
        for kc in KCS:
            f = runs / f"load_p{p}{variant if p == '100' else ''}_kc{kc}.h5"
            if not f.exists():
                missing.append(f.name)
                continue
            try:
                m = measures(f)
            except ResultError as e:  # still running, or damaged: said, not collated
                missing.append(f"{f.name} ({e})")
                continue
            curves[(p, kc)] = m
            res[f"p{p}_kc{kc}"] = analyse(m, float(p))
    return res, curves, missing


def _table_1_1(res) -> list:
    """Table 1.1: corrected peak stresses at p = 100 and 500 (lower bounds marked), friction angle and
    cohesion of their Mohr-Coulomb envelope, beside the paper's."""
    table = []
    for i, kc in enumerate(KCS):
        a, b = res.get(f"p100_kc{kc}"), res.get(f"p500_kc{kc}")
        row = {
            "kc_over_k2": float(kc),
            "peak_100": None,
            "peak_500": None,
            "c": None,
            "phi_deg": None,
            "peak_100_lower_bound": None,
            "peak_500_lower_bound": None,
        }
        row.update(
            {"paper_peak_100": PAPER["peak_100"][i], "paper_peak_500": PAPER["peak_500"][i], "paper_c": PAPER["c"][i]}
        )
        if a:
            row["peak_100"], row["peak_100_lower_bound"] = a["peak_corrected"], a["peak_is_lower_bound"]
        if b:
            row["peak_500"], row["peak_500_lower_bound"] = b["peak_corrected"], b["peak_is_lower_bound"]
        if a and b:
            row["phi_deg"], row["c"] = mohr_coulomb(100.0, a["peak_corrected"], 500.0, b["peak_corrected"])
        table.append(row)
    return table


def _figs_1_6_1_7(res, curves, out, variant, sfx, plt):
    """Figs. 1.6 (p = 500) and 1.7 (p = 100): volumetric strain and vertical stress against eps_zz."""
    for p, fname in (("500", "fig_lh_1_6_p500.png"), ("100", f"fig_lh_1_7_p100{sfx}.png")):
        if variant and p == "500":
            continue  # the same runs as the shipped protocol's
        mine = {kc: curves[(p, kc)] for kc in KCS if (p, kc) in curves}
        if not mine:
            continue
        fig, ax = plt.subplots(1, 2, figsize=(10, 4))
        for kc, m in mine.items():
            (ln,) = ax[0].plot(m["ezz"], m["ev"], lw=0.9, label=rf"$k_c/k_2$ = {kc}")
            ax[1].plot(m["ezz"], m["szz"], lw=0.7, color=ln.get_color(), label=rf"$k_c/k_2$ = {kc}: $\sigma_{{zz}}$")
            corr = float(p) * m["szz"] / np.where(m["sxx"] != 0, m["sxx"], np.nan)
            ax[1].plot(m["ezz"], corr, lw=0.6, ls="--", color=ln.get_color())
            a = res[f"p{p}_kc{kc}"]
            ax[1].annotate(
                "",
                xy=(a["eps_at_peak"], a["peak_corrected"]),
                xytext=(a["eps_at_peak"], a["peak_corrected"] + 0.16 * float(p)),  # arrows 0.16 p long
                arrowprops={"arrowstyle": "->", "color": ln.get_color()},
            )
        top = max(res[f"p{p}_kc{kc}"]["peak_corrected"] for kc in mine)
        ax[1].set_ylim(top=top + 0.2 * float(p))
        packing = " (packing unloaded from $p$ = 500)" if variant and p == "100" else ""
        ax[0].set(
            xlabel=EZZ,
            ylabel=r"$\varepsilon_V = (V - V_0)/V_0$ [−]",
            title=f"volumetric strain, $p_x$ = {p} N/m²{packing}",
        )
        ax[1].set(
            xlabel=EZZ,
            ylabel=r"$\sigma_{zz}$ [N/m²]",
            title=r"$\sigma_{zz}$ (solid), $p_x\,\sigma_{zz}/\sigma_{xx}$ (dashed, LH 1.10); arrows: peaks",
        )
        ax[0].title.set_fontsize(10)
        ax[1].title.set_fontsize(10)
        ax[0].legend(fontsize=7)
        _save(fig, out / fname, plt)


def _fig_1_8(table, out, sfx, plt):
    """Fig. 1.8: Mohr circles at failure and their common tangents."""
    fig, ax = plt.subplots(figsize=(9, 3.6))  # equal aspect over sigma 0..1100, tau 0..~300
    th = np.linspace(0, math.pi, 100)
    for row in table:
        col = None
        for p, s in ((100.0, row["peak_100"]), (500.0, row["peak_500"])):
            if s is not None:
                (ln,) = ax.plot((p + s) / 2 + (s - p) / 2 * np.cos(th), (s - p) / 2 * np.sin(th), lw=0.8, color=col)
                col = ln.get_color()
        if row["c"] is not None:
            sg = np.linspace(0, 1100, 10)
            ax.plot(
                sg,
                row["c"] + sg * math.tan(math.radians(row["phi_deg"])),
                "--",
                lw=0.6,
                color=col,
                label=rf"$k_c/k_2$ = {row['kc_over_k2']:g}: $\varphi$ = {row['phi_deg']:.1f}°, $c$ = {row['c']:.0f} N/m²",
            )
    ax.set(
        xlabel=r"normal stress $\sigma$ [N/m²]",
        ylabel=r"shear stress $\tau$ [N/m²]",
        title=r"Mohr circles at failure ($p_x$ = 100, 500 N/m²) and their common tangents",
    )
    ax.set_aspect("equal")
    ax.legend(fontsize=7, loc="upper left")
    _save(fig, out / f"fig_lh_1_8_mohr{sfx}.png", plt)


def _save(fig, path, plt):
    fig.tight_layout()
    _save_figure(fig, path, dpi=200)
    plt.close(fig)


def _readable(path) -> bool:
    from ..io.hdf5 import ResultError, read_history

    if not path.exists():
        return False
    try:
        read_history(path)
    except ResultError:
        return False
    return True


def _fig_networks(path, out, plt):
    """Fig. 1.3: overlapping pairs at ε_zz ≈ 0, 0.013 (failure in the paper) and the last frame."""
    from scipy.spatial import cKDTree

    from ..io.hdf5 import read_frames, read_static

    if not _readable(path):
        return None
    m = measures(path)
    _, times, xs, _ = read_frames(path)
    st = read_static(path)
    grains = st["sets"]["grains"]
    r = st["radius"][grains]
    targets = (0.0, 0.013, float(m["ezz"][-1]))
    eps_f = np.interp(times, m["t"], m["ezz"])
    picks = sorted({int(np.argmin(np.abs(eps_f - e))) for e in targets})
    fig, ax = plt.subplots(1, len(picks), figsize=(3.2 * len(picks), 5))
    ax = np.atleast_1d(ax)
    shown = []
    for a, k in zip(ax, picks, strict=True):
        x = xs[k][grains, :2]
        pairs = cKDTree(x).query_pairs(2.0 * float(r.max()), output_type="ndarray")
        d = np.linalg.norm(x[pairs[:, 0]] - x[pairs[:, 1]], axis=1)
        delta = r[pairs[:, 0]] + r[pairs[:, 1]] - d
        on = delta > 0
        pairs, delta = pairs[on], delta[on]
        from matplotlib.collections import LineCollection

        segs = np.stack([x[pairs[:, 0]], x[pairs[:, 1]]], axis=1)
        w = np.clip(delta / np.percentile(delta, 98), 0, 1) if len(delta) else delta
        order = np.argsort(w)  # strong contacts drawn last, on top
        a.add_collection(
            LineCollection(
                segs[order], linewidths=0.1 + 1.4 * w[order] ** 2, colors=plt.cm.gray_r(0.15 + 0.85 * w[order])
            )
        )
        a.set_xlim(x[:, 0].min() - 0.2, x[:, 0].max() + 0.2)
        a.set_ylim(x[:, 1].min() - 0.2, x[:, 1].max() + 0.2)
        a.set_aspect("equal")
        a.set(title=rf"$\varepsilon_{{zz}}$ = {eps_f[k]:.3f} ($t$ = {times[k]:.3f} s)", xlabel=r"$x$ [cm]")
        a.title.set_fontsize(9)
        shown.append({"t": float(times[k]), "eps_zz": float(eps_f[k]), "contacts": int(len(delta))})
    ax[0].set_ylabel(r"$z$ [cm]")
    fig.suptitle(
        r"contact network, $p_x$ = 500 N/m², $k_c/k_2$ = 2 (darker and wider: larger overlap $\delta$)", fontsize=10
    )
    _save(fig, out / "fig_lh_1_3_networks.png", plt)
    return shown


def _pressure_history(path):
    from ..io.hdf5 import read_history

    cols, d = read_history(path)
    h = {c: d[:, j] for j, c in enumerate(cols)}
    return h["time"], h["wall_force:right"] / (100.0 * h["servo_length:right"]) / PA


def _tau(t, p, pf=400.0):
    """Relaxation time of an exponential approach p_f − A e^(−t/τ) (least squares on log|p_f − p| where
    |p_f − p| falls from 30 % to 1 % of p_f)."""
    gap = np.abs(pf - p)
    sel = (gap < 0.3 * pf) & (gap > 0.01 * pf) & (t > 0)
    if sel.sum() < 5:
        return None
    k = np.polyfit(t[sel], np.log(gap[sel]), 1)[0]
    return float(-1.0 / k) if k < 0 else None


def _fig_relaxation(runs, out, plt):
    """Fig. 1.4: (a) γ_b = γ_x = 0, m_x varied; (b) m_x = 1e-4 kg, γ_x = 193.5 γ_0, γ_b varied."""
    panels = {
        "a": [
            ("a_mx1e-2", r"$m_x = 10^{-2}$ kg"),
            ("a_mx1e-3", r"$m_x = 10^{-3}$ kg"),
            ("a_mx1e-4", r"$m_x = 10^{-4}$ kg"),
        ],
        "b": [
            ("b_gb0", r"$\gamma_b = 0$"),
            ("b_gb0.01", r"$\gamma_b = \gamma_0/100$"),
            ("b_gb0.1", r"$\gamma_b = \gamma_0/10$"),
            ("b_gb1", r"$\gamma_b = \gamma_0$"),
        ],
    }
    found = {k: [(n, lab) for n, lab in v if _readable(runs / f"relax_{n}.h5")] for k, v in panels.items()}
    if not any(found.values()):
        return None
    fig, ax = plt.subplots(1, 2, figsize=(10, 4), sharey=True)
    res = {}
    for a, (key, items) in zip(ax, found.items(), strict=True):
        for n, lab in items:
            t, p = _pressure_history(runs / f"relax_{n}.h5")
            tau = _tau(t, p)
            res[n] = {"tau_s": tau, "p_end": float(p[-1])}
            # τ only where the approach is monotone enough for an exponential (panel b)
            a.plot(t, p, lw=0.8, label=lab + (rf", $\tau$ = {tau:.4f} s" if tau and key == "b" else ""))
        a.axhline(400.0, color="k", lw=0.5, ls=":")
        a.set(xlabel=r"$t$ [s]", title=f"({key})")
        a.legend(fontsize=7)
    ax[0].set_ylabel(r"pressure on the right wall $F_x/(h\,z)$ [N/m²]")
    fig.suptitle(r"approach to $p_f$ = 400 N/m² from the relaxed state at 100 N/m² ($k_c$ = 0)", fontsize=10)
    _save(fig, out / "fig_lh_1_4_relaxation.png", plt)
    return res


def _fig_rate(runs, out, plt):
    """Fig. 1.5: k_c = 2 k_1, p_x = 500, f = 5, 10, 20, 40 1/s."""
    files = [(f, n) for f, n in RATE_RUNS if _readable(runs / f"{n}.h5")]
    if not files:
        return None
    fig, ax = plt.subplots(2, 2, figsize=(10, 7), sharex=True)
    res = {}
    for f, n in files:
        m = measures(runs / f"{n}.h5")
        sxx = np.where(m["sxx"] != 0, m["sxx"], np.nan)
        ratio = m["szz"] / sxx
        lab = f"$f$ = {f} 1/s"
        ax[0, 0].plot(m["ezz"], m["ev"], lw=0.8, label=lab)
        ax[0, 1].plot(m["ezz"], m["szz"], lw=0.8, label=lab)
        ax[1, 0].plot(m["ezz"], m["sxx"], lw=0.8, label=lab)
        ax[1, 1].plot(m["ezz"], ratio, lw=0.8, label=lab)
        k = int(np.nanargmax(m["szz"]))
        res[str(f)] = {
            "peak_szz": float(m["szz"][k]),
            "eps_at_peak": float(m["ezz"][k]),
            "peak_is_lower_bound": at_loading_end(m["ezz"], k),
            "max_ratio": float(np.nanmax(ratio)),
            "peak_corrected": float(np.nanmax(500.0 * ratio)),
        }
    ax[0, 0].set(ylabel=r"$\varepsilon_V$ [−]")
    ax[0, 1].set(ylabel=r"$\sigma_{zz}$ [N/m²]")
    ax[1, 0].set(ylabel=r"$\sigma_{xx} = p_x + \gamma_x \dot{x}/(hz)$ [N/m²]", xlabel=EZZ)  # LH 1.2: the wall damping
    ax[1, 1].set(ylabel=r"$\sigma_{zz}/\sigma_{xx}$ [−]", xlabel=EZZ)
    ax[0, 0].legend(fontsize=7)
    fig.suptitle(r"loading rate, $p_x$ = 500 N/m², $k_c = 2\,k_1$", fontsize=10)
    _save(fig, out / "fig_lh_1_5_rate.png", plt)
    return res
