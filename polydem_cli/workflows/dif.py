"""Dynamic increase factor of strength against strain rate (``polydem study dif``; issue: thesis §7.5
against the fib Model Code 2010).

For every macroscopic strain rate ε̇ the scenario (a specimen with ``[macro]``) is run with its
loaded set driven at ``v = ε̇ L2`` (the sign of the scenario's loading kept), ramped as the thesis
does (2e-4 s up to ε̇ = 0.25 1/s; faster rates ramp over 5e-5/ε̇ s so that the ramp ends at
ε22 = 2.5e-5, as the thesis's fast runs), and stopped once the stress has fallen to 70 % of its
peak (or at |ε22| = 3e-3).  The dynamic increase factor is the peak stress over that of a
reference result (the slow rate-independent run the thesis calibrated on).

fib Model Code 2010 (§5.1.11.1), ε̇ in 1/s:

* tension:     DIF = (ε̇ / 1e-6)^0.018   for ε̇ ≤ 10
* compression: DIF = (ε̇ / 30e-6)^0.014  for ε̇ ≤ 30

The simulated DIF is relative to the reference run, itself at a finite rate (the thesis's slow runs,
2.5e-2 1/s; ``reference_rate`` in dif.json, fitted from its history), while fib's is relative to a
quasi-static rate: the figure also draws fib rescaled to the reference rate.  At rates whose time to the
peak is shorter than a wave transit of the specimen (40 cm panel: c = (E/ρ)^½ ≈ 3.8e5 cm/s, 1e-4 s;
ε̇ ≳ 1 1/s) the boundary stress includes structural inertia: a sweep of the rate-independent scenario
at the same rates measures that part.

The runs are independent and go to Dask like ``polydem sweep`` (finished ones are reused).
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from ..report.common import save as _save

RAMP_TIME = 2.0e-4  # s, thesis §7.4
RAMP_STRAIN_FAST = 2.5e-5  # ε22 at the end of the ramp for rates above 0.25 1/s
STOP_FRACTION = 0.7
SAFETY_STRAIN = 3.0e-3


def fib_dif(rate, kind: str):
    """The dynamic increase factor of fib Model Code 2010 at strain rate ``rate`` (1/s): (ε̇/ε̇₀)^0.018 with
    ε̇₀ = 1e-6 1/s in tension, (ε̇/ε̇₀)^0.014 with ε̇₀ = 30e-6 1/s in compression (their low-rate branches)."""
    rate = np.asarray(rate, float)
    if kind == "tension":
        return (rate / 1.0e-6) ** 0.018
    return (rate / 30.0e-6) ** 0.014


def rate_overrides(system, rate: float) -> list:
    """--set overrides that drive the macro load set at strain rate ``rate`` (see module doc)."""
    sc = system.scenario
    m = system.macro
    bi = next(i for i, b in enumerate(sc["boundary"]) if b["set"] == m.load_set)
    x2 = sc["boundary"][bi]["x2"]
    sign = 1.0 if float(x2["velocity"]) > 0 else -1.0
    v = sign * rate * m.L2
    tr = RAMP_TIME if rate <= 0.25 else 2.0 * RAMP_STRAIN_FAST / rate
    a = v / tr
    t_end = tr / 2 + SAFETY_STRAIN / rate
    steps = t_end / system.dt
    return [
        f"boundary.{bi}.x2={{velocity = {v:.8g}, acceleration = {a:.8g}}}",
        f"time.end_displacement={SAFETY_STRAIN * m.L2:.8g}",
        f"time.end_load_drop={STOP_FRACTION}",
        f"output.frame_interval={t_end:.8g}",
        f"output.history_every={max(1, int(steps / 3000))}",
    ]


def run_study(
    scenario: Path, rates, reference: Path, out: Path, base_overrides=(), workers=None, scheduler=None
) -> dict:
    """The rate study: the scenario at each strain rate in ``rates`` (a sweep), the strength of each against the
    ``reference`` run's, the dynamic increase factors against fib Model Code 2010; table and figure in ``out``."""
    from ..io.hdf5 import open_result
    from ..scenario.build import build_system
    from ..scenario.load import load_scenario
    from .sweep import run_variants

    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    sc, _ = load_scenario(scenario, base_overrides)
    system = build_system(sc, str(scenario))
    if system.macro is None:
        raise ValueError(f"{scenario}: the scenario has no [macro] table (needed for strain rates and stresses)")
    with open_result(reference) as f:
        ref = json.loads(f.attrs["summary"])["macro"]
        cols = json.loads(f["history/table"].attrs["columns"])
        tab = f["history/table"][:]
    kind = ref["kind"]
    half = tab[len(tab) // 2 :]  # the reference's own strain rate (after its ramp)
    ref_rate = abs(float(np.polyfit(half[:, cols.index("time")], half[:, cols.index("eps22")], 1)[0]))
    variants = [(f"{Path(scenario).stem}__rate{r:.4g}", rate_overrides(system, r)) for r in rates]
    rows = run_variants(scenario, variants, out, base_overrides, workers=workers, scheduler=scheduler)
    pts = []
    for r, row in zip(rates, rows):
        p = {
            "rate": r,
            "result": row["result"],
            "status": row.get("status"),
            "wall_time_s": row.get("wall_time_s"),
            "steps": row.get("steps"),
            "failure": row.get("failure"),
        }
        if row.get("status") == "finished":
            with open_result(row["result"]) as f:
                m = json.loads(f.attrs["summary"])["macro"]
            p.update(
                peak_stress_MPa=m["peak_stress_MPa"],
                dif=m["peak_stress"] / ref["peak_stress"],
                fib=float(fib_dif(r, kind)),
            )
        pts.append(p)
    res = {
        "scenario": str(scenario),
        "base_overrides": list(base_overrides),
        "reference": str(reference),
        "reference_peak_MPa": ref["peak_stress_MPa"],
        "reference_rate": ref_rate,
        "kind": kind,
        "points": pts,
        "fib": "tension (rate/1e-6)^0.018, compression (rate/30e-6)^0.014 (fib MC2010)",
    }
    (out / "dif.json").write_text(json.dumps(res, indent=1))
    plot([res], out / "dif.png")
    return res


def plot(studies, png, extra=()):
    """Simulated DIF points of one or several studies with the fib MC2010 curves.
    ``extra``: further (label, kind, rate, dif) points (e.g. the thesis's runs)."""
    from ..mpl import pyplot

    plt = pyplot()

    fig, ax = plt.subplots(figsize=(6.4, 4.6))
    r = np.logspace(-6, 1.5, 200)
    ax.semilogx(r[r <= 10], fib_dif(r[r <= 10], "tension"), "-", color="tab:red", lw=1, label="fib MC2010, tension")
    ax.semilogx(
        r[r <= 30], fib_dif(r[r <= 30], "compression"), "-", color="tab:blue", lw=1, label="fib MC2010, compression"
    )
    # the simulated DIF is relative to the reference run, which is itself at a finite rate (the thesis's
    # slow runs: 2.5e-2 1/s); fib's DIF is relative to 1e-6 (tension) / 30e-6 1/s (compression): the
    # dashed curves are fib rescaled to the reference rate, the like-for-like comparison
    drawn = set()
    for s in studies:
        rr, kind = s.get("reference_rate"), s["kind"]
        if rr and (kind, round(rr, 12)) not in drawn:
            drawn.add((kind, round(rr, 12)))
            q = r[(r >= rr) & (r <= (10 if kind == "tension" else 30))]
            ax.semilogx(
                q,
                fib_dif(q, kind) / fib_dif(rr, kind),
                "--",
                lw=1,
                color="tab:red" if kind == "tension" else "tab:blue",
                label=f"fib MC2010, {kind}, relative to the reference rate {rr:.2g} 1/s",
            )
    for s in studies:
        pts = [p for p in s["points"] if p.get("dif") is not None]
        col = "tab:red" if s["kind"] == "tension" else "tab:blue"
        ax.semilogx(
            [p["rate"] for p in pts],
            [p["dif"] for p in pts],
            "^" if "rate-independent" in s.get("label", "") else "o",
            color=col,
            mfc="none" if "filtered" in s.get("label", "") else col,
            ms=6,
            label=s.get("label") or f"polydem, {s['kind']}",
        )
    for lab, kind, rate, dif in extra:
        ax.semilogx(
            [rate],
            [dif],
            "x" if lab.startswith("thesis") else "s",
            color="tab:red" if kind == "tension" else "tab:blue",
            ms=7,
            mfc="none",
            mew=1.5,
            label=lab,
        )
    ax.axhline(1.0, color="0.6", lw=0.6)
    ax.set_xlabel(r"macroscopic strain rate $|\dot\varepsilon_{22}|$ [1/s]")
    ax.set_ylabel("dynamic increase factor of strength (DIF)")
    ax.grid(alpha=0.3, which="both")
    ax.legend(fontsize=7)
    ax.set_title("strength increase with strain rate: simulation against fib MC2010", fontsize=9)
    fig.tight_layout()
    _save(fig, png, dpi=150)
    plt.close(fig)
