"""Macroscopic nominal stress and strains of a specimen (thesis §7.5.1, Figs. 7.10, 7.12).

* ``σ22 = f2 / (L1 T)``: f2 the sign-reversed sum of the interaction forces in e2 on the
  loaded set (the top row; the thesis's f2 convention, tension positive), L1 the assumed
  original width and T the thickness;
* ``ε22 = û2 / L2``: the prescribed displacement of the loaded set over the assumed
  original height L2;
* ``ε11 = (u_r,1 − u_l,1) / L1``: the arithmetic means of the e1-displacements of the
  particles of the right and left edges.

From the curve the run summary reports ``E = σ22/ε22`` and ``ν = −ε11/ε22`` fitted by least
squares (slopes of straight lines, so a start-up offset does not matter) over the pre-peak
part where |σ22| lies in a stated range of the peak (``macro.fit_range``, default 10–40 %),
the peak stress and the strain at the peak, and the work of the load before and after the
peak, ``∫ f2 dû2`` (the energy the specimen takes up; after the peak, per unit of cross-section
L1 T, an estimate of the fracture energy).

Units: σ in g cm⁻¹ s⁻² (1 N/mm² = 1 MPa = 1e7), work in erg, work per area in erg/cm²
(1 N/m = 1 J/m² = 1e3 erg/cm²).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

#: unit conversions from the cm-g-s system
MPA = 1.0e7  # g cm^-1 s^-2 per N/mm^2
GPA = 1.0e10
J_PER_M2 = 1.0e3  # erg/cm^2 per N/m

#: a peak counts as reached (a strength) once the stress has fallen below this fraction of it
PEAK_REACHED = 0.99

COLUMNS = (
    ("sigma22", "g/(cm s^2)", "macroscopic nominal stress f2/(L1 T) on the loaded set (1 N/mm^2 = 1e7)"),
    ("eps22", "-", "macroscopic nominal strain u2/L2 of the loaded set"),
    ("eps11", "-", "macroscopic lateral strain (u1 right edge - u1 left edge)/L1"),
)


@dataclass
class MacroSpec:
    """Resolved ``[macro]`` table: sets, lengths, thickness and fit range."""

    specimen: str
    load_set: str
    left: str
    right: str
    L1: float
    L2: float
    T: float
    fit_range: tuple

    def as_dict(self) -> dict:
        return {
            "specimen": self.specimen,
            "load_set": self.load_set,
            "left": self.left,
            "right": self.right,
            "L1": self.L1,
            "L2": self.L2,
            "T": self.T,
            "fit_range": list(self.fit_range),
        }


def derive(spec: MacroSpec, cols: list, rows: np.ndarray) -> np.ndarray:
    """The COLUMNS for history rows whose column names are ``cols``: (R, 3)."""
    c = {n: i for i, n in enumerate(cols)}
    rows = np.atleast_2d(rows)
    out = np.empty((rows.shape[0], 3))
    out[:, 0] = rows[:, c["f2:" + spec.load_set]] / (spec.L1 * spec.T)
    out[:, 1] = rows[:, c["u2:" + spec.load_set]] / spec.L2
    out[:, 2] = (rows[:, c["u1:" + spec.right]] - rows[:, c["u1:" + spec.left]]) / spec.L1
    return out


def _slope(x, y):
    x = np.asarray(x, float)
    y = np.asarray(y, float)
    xm = x - x.mean()
    den = float(np.dot(xm, xm))
    return float(np.dot(xm, y - y.mean()) / den) if den > 0 else float("nan")


def summarize(sigma, eps22, eps11, fit_range=(0.1, 0.4), L1=None, T=None, L2=None) -> dict | None:
    """E, ν, peak stress, strain at the peak and work of the load, from the curve (see module doc).

    Returns None for an empty curve.  ``E``/``nu`` are None when fewer than 3 points fall into
    the fit range (too coarse a history, or no load yet).
    """
    s = np.asarray(sigma, float)
    e2 = np.asarray(eps22, float)
    e1 = np.asarray(eps11, float)
    if s.size == 0:
        return None
    k = int(np.argmax(np.abs(s)))
    peak = float(s[k])
    lo, hi = fit_range
    a = np.abs(s[: k + 1])
    sel = np.flatnonzero((a >= lo * abs(peak)) & (a <= hi * abs(peak)))
    out = {
        "peak_stress": peak,
        "peak_stress_MPa": peak / MPA,
        # the strength: the peak's magnitude (f_t, f_c > 0, as fib MC2010 and the lab write them); stresses, the
        # peak stress among them, are signed, tension positive
        "strength_MPa": abs(peak) / MPA,
        "strain_at_peak": float(e2[k]),
        "kind": "tension" if peak > 0 else "compression",
        "fit_range": [lo, hi],
        "fit_points": int(len(sel)),
        "E": None,
        "E_GPa": None,
        "nu": None,
        # the curve turned: the stress at the end is below PEAK_REACHED of the peak (else the run stopped, at its
        # safety limit, while the stress was still at its largest: the peak is a lower bound of the strength)
        "peak_reached": bool(abs(s[-1]) < PEAK_REACHED * abs(peak)),
    }
    if len(sel) >= 3 and abs(peak) > 0:
        E = _slope(e2[sel], s[sel])
        nu = -_slope(e2[sel], e1[sel])
        out.update(E=E, E_GPa=E / GPA, nu=nu)
    if L1 is not None and T is not None and L2 is not None:
        vol = L1 * L2 * T
        # work of the load f2 dû2 = σ (L1 T) · L2 dε22 (trapezoidal rule)
        w = np.concatenate([[0.0], np.cumsum(0.5 * (s[1:] + s[:-1]) * np.diff(e2))]) * vol
        out["work_to_peak"] = float(w[k])
        out["work_after_peak"] = float(w[-1] - w[k])
        out["work_after_peak_per_area"] = float((w[-1] - w[k]) / (L1 * T))
        out["work_after_peak_per_area_N_per_m"] = out["work_after_peak_per_area"] / J_PER_M2
        out["final_stress_over_peak"] = float(s[-1] / peak) if peak else None
    return out


def describe(m: dict) -> str:
    """One line for the end of a run."""
    if not m:
        return "macroscopic measures: no history"
    parts = []
    if m.get("E") is not None:
        parts.append(
            f"E = {m['E_GPa']:.4g} GPa, nu = {m['nu']:.3g} (fitted where |sigma22| is "
            f"{100 * m['fit_range'][0]:g}-{100 * m['fit_range'][1]:g} % of the peak, {m['fit_points']} points)"
        )
    else:
        parts.append("E, nu: too few history points in the fit range")
    what, sym = ("tensile", "f_t") if m["kind"] == "tension" else ("compressive", "f_c")
    strength = abs(m["peak_stress_MPa"])  # strengths are magnitudes; stresses are signed, tension positive
    signed = "" if m["kind"] == "tension" else f" (sigma22 = {m['peak_stress_MPa']:.4g} N/mm^2, tension positive)"
    if m.get("peak_reached", True):
        parts.append(f"{what} strength {sym} = {strength:.4g} N/mm^2{signed} at eps22 = {m['strain_at_peak']:.3g}")
    else:
        parts.append(
            f"no {what} strength: the run ended with the stress still at its largest, |sigma22| = {strength:.4g} "
            f"N/mm^2 at eps22 = {m['strain_at_peak']:.3g} (a lower bound; give a longer end_displacement / end_time)"
        )
    if "work_after_peak_per_area" in m:
        parts.append(
            f"work after the peak {m['work_after_peak_per_area_N_per_m']:.4g} N/m "
            f"({m['work_after_peak']:.4g} erg), stress at the end {100 * (m['final_stress_over_peak'] or 0):.3g} % of the peak"
        )
    return "; ".join(parts)
