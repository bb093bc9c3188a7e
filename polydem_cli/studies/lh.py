"""Luding & Herrmann analysis (``polydem study lh``): macroscopic response of the biaxial box, Table 1.1.

From each loading run ``load_p<P>_kc<K>.h5`` (scenarios/lh/) and its history table:

* z(t): height of the box, ``servo_length:right`` (face distance bottom–top); x(t): width, the faces of
  the right and left walls (``wall_face:*``); z0, x0 at t = 0 (the relaxed state);
* ε_zz = 1 − z/z0 (positive in compression), ε_V = (xz − x0z0)/(x0z0) (SPEC §12.5, inferred);
* σ_xx = F_right/(h z), σ_zz = F_top/(h x) from the disks' forces on the walls (``wall_force:*``), h the
  depth (the walls' thickness, 1 m); the viscous over-stress correction (LH 1.10) σ_zz^corr = p_x σ_zz/σ_xx;
* the peak of σ_zz^corr (the maximum including fluctuations, as the paper); ν from the initial slope of ε_V:
  1 − ν = −dε_V/dε_zz over ε_zz ≤ 0.3 %; the later slope d' over the last third of the loading and the
  dilatancy angle from d' = 2 sin ψ/(1 − sin ψ) (the paper's extra "tan" is a misprint);
* for each k_c the Mohr circles [p_x, σ^corr_peak] of the two pressures and their common tangent
  τ = c + σ tan φ: sin φ = (r2 − r1)/(m2 − m1), c = (r1 − m1 sin φ)/cos φ (m centres, r radii).

Writes table1_1.csv, results.json and figures (σ–ε and ε_V–ε per run, Mohr circles) to the output folder.
"""

from __future__ import annotations

import csv
import json
import math
from pathlib import Path

import numpy as np

#: Table 1.1 of the paper: corrected peak stresses (N/m^2) and cohesion for k_c/k_2 = 0, 1/2, 1, 2, 4
PAPER = {
    "kc": [0.0, 0.5, 1.0, 2.0, 4.0],
    "peak_100": [183, 234, 264, 310, 336],
    "peak_500": [798, 853, 915, 941, 972],
    "c": [11, 32, 40, 60, 71],
    "phi_deg": 13.0,
    "nu": 0.69,
    "psi_deg": {"100": 11.0, "500": 5.0},
    "slopes": {"100": (-0.30, 0.44), "500": (-0.32, 0.19)},
}
KCS = ("0", "0.5", "1", "2", "4")
PRESSURES = ("100", "500")
PA = 10.0  # g/(cm s^2) per N/m^2


def measures(path) -> dict:
    """Macroscopic curves of one loading run (stresses in N/m^2)."""
    from ..io.hdf5 import read_history, read_static

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
    return {"t": h["time"], "ezz": ezz, "ev": ev, "sxx": sxx, "szz": szz, "z0": z0, "x0": x0}


def analyse(m: dict, p: float) -> dict:
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
    return {
        "peak_corrected": float(corr[k]),
        "eps_at_peak": float(ezz[k]),
        "initial_slope": s1,
        "late_slope": s2,
        "nu": 1.0 + s1,
        "psi_deg": math.degrees(math.asin(sin_psi)) if abs(sin_psi) <= 1 else float("nan"),
        "z0_cm": float(m["z0"]),
        "x0_cm": float(m["x0"]),
    }


def mohr_coulomb(p1, s1, p2, s2):
    """Common tangent of the circles [p1, s1] and [p2, s2]: (φ in degrees, c)."""
    m1, r1, m2, r2 = (p1 + s1) / 2, (s1 - p1) / 2, (p2 + s2) / 2, (s2 - p2) / 2
    sphi = (r2 - r1) / (m2 - m1)
    c = (r1 - m1 * sphi) / math.sqrt(1 - sphi * sphi)
    return math.degrees(math.asin(sphi)), c


def collate(runs: Path, out: Path) -> dict:
    import matplotlib

    from ..io.hdf5 import ResultError

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    out.mkdir(parents=True, exist_ok=True)
    res, curves, missing = {}, {}, []
    for p in PRESSURES:
        for kc in KCS:
            f = runs / f"load_p{p}_kc{kc}.h5"
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
    table = []
    for i, kc in enumerate(KCS):
        a, b = res.get(f"p100_kc{kc}"), res.get(f"p500_kc{kc}")
        row = {"kc_over_k2": float(kc), "peak_100": None, "peak_500": None, "c": None, "phi_deg": None}
        row.update(
            {"paper_peak_100": PAPER["peak_100"][i], "paper_peak_500": PAPER["peak_500"][i], "paper_c": PAPER["c"][i]}
        )
        if a:
            row["peak_100"] = a["peak_corrected"]
        if b:
            row["peak_500"] = b["peak_corrected"]
        if a and b:
            row["phi_deg"], row["c"] = mohr_coulomb(100.0, a["peak_corrected"], 500.0, b["peak_corrected"])
        table.append(row)
    with open(out / "table1_1.csv", "w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=list(table[0]))
        w.writeheader()
        w.writerows(table)
    # figures: corrected stress and volumetric strain against eps_zz; Mohr circles
    if curves:
        fig, ax = plt.subplots(1, 2, figsize=(10, 4))
        for (p, kc), m in sorted(curves.items()):
            corr = float(p) * m["szz"] / np.where(m["sxx"] != 0, m["sxx"], np.nan)
            ax[0].plot(m["ezz"], corr, label=f"p = {p}, kc/k2 = {kc}")
            ax[1].plot(m["ezz"], m["ev"], label=f"p = {p}, kc/k2 = {kc}")
        ax[0].set(
            xlabel="ε_zz (−)", ylabel="σ_zz^corr = p σ_zz/σ_xx (N/m²)", title="corrected vertical stress (LH 1.10)"
        )
        ax[1].set(xlabel="ε_zz (−)", ylabel="ε_V (−)", title="volumetric strain")
        ax[0].legend(fontsize=7)
        fig.tight_layout()
        fig.savefig(out / "fig_lh_stress_strain.png", dpi=150)
        plt.close(fig)
        fig, ax = plt.subplots(figsize=(6, 4))
        th = np.linspace(0, math.pi, 100)
        for row in table:
            for p, s in ((100.0, row["peak_100"]), (500.0, row["peak_500"])):
                if s is not None:
                    ax.plot((p + s) / 2 + (s - p) / 2 * np.cos(th), (s - p) / 2 * np.sin(th), lw=0.8)
            if row["c"] is not None:
                sg = np.linspace(0, 1100, 10)
                ax.plot(sg, row["c"] + sg * math.tan(math.radians(row["phi_deg"])), "k--", lw=0.6)
        ax.set(
            xlabel="normal stress σ (N/m²)",
            ylabel="shear stress τ (N/m²)",
            title="Mohr circles at failure, common tangents",
        )
        ax.set_aspect("equal")
        fig.tight_layout()
        fig.savefig(out / "fig_lh_mohr.png", dpi=150)
        plt.close(fig)
    summary = {"runs": res, "table1_1": table, "paper": PAPER, "missing": missing}
    (out / "results.json").write_text(json.dumps(summary, indent=1))
    return summary
