"""The formulas the validation suite (``polydem study validate``, reproductions/validate.py) compares a material with:
Kupfer's biaxial envelope, Bažant's size-effect law, Hordijk's tension softening, and the measures taken from the
runs (the crack opening of a tension test).  Pure functions of numbers; the published constants and points are in
``reproductions/sources/*.toml`` with their sources.
"""

from __future__ import annotations

import numpy as np


def kupfer_envelope(alpha, f_t_over_f_c: float = 0.1):
    """Kupfer & Gerstle's biaxial strength of concrete (the form of Kupfer, Hilsdorf & Rüsch 1969's envelope used in
    Darwin & Pecknold 1977's model; reproductions/sources/kupfer1969.toml), for the stress ratio α = σ₂/σ₁ with σ₁ the
    larger compression: (σ₁/f_c, σ₂/f_c), compression negative.

    * compression–compression, 0 ≤ α ≤ 1: |σ₁| = (1 + 3.65 α)/(1 + α)² f_c, σ₂ = α σ₁;
    * tension–compression, −0.17 ≤ α < 0: |σ₁| = (1 + 3.28 α)/(1 + α)² f_c, σ₂ = α σ₁ (a tension);
    * α < −0.17: the tensile strength governs, σ₂ = f_t: on the ray σ₂ = α σ₁ that is |σ₁| = f_t / |α|.  (Darwin &
      Pecknold's region (c) gives the two directions' peaks, |σ₁| = 0.65 f_c and σ₂ = f_t, separately: not a point
      of the ray.)

    Every point lies on its ray: σ₂/σ₁ = α.  Tension–tension (both positive) is σ₁ = σ₂ = f_t, outside this
    function's ratio.  ``f_t_over_f_c``: the concrete's f_t/f_c (0.1 in Darwin & Pecknold's use of the envelope,
    reproductions/sources/kupfer1969.toml): the envelope is Kupfer's concrete's, a model's points are drawn on it
    normalised by the model's own f_c."""
    a = np.asarray(alpha, float)
    if np.any(a < -1.0) or np.any(a > 1.0):
        raise ValueError("kupfer_envelope: alpha = sigma_2 / sigma_1 must lie in [-1, 1]")
    with np.errstate(divide="ignore", invalid="ignore"):  # alpha = -1 or 0 on the branch not taken
        s1 = np.where(a >= 0.0, (1.0 + 3.65 * a) / (1.0 + a) ** 2, (1.0 + 3.28 * a) / (1.0 + a) ** 2)
        s1 = np.where(a < -0.17, f_t_over_f_c / np.abs(a), s1)  # σ₂ = f_t on the ray
    s2 = -a * s1  # σ₂ = α σ₁ with σ₁ = −s1 f_c
    return -s1, s2


def hordijk(w_over_wc, c1: float = 3.0, c2: float = 6.93):
    """Hordijk's (1991) tension softening σ/f_t at the crack opening w/w_c (0 beyond w_c):
    σ/f_t = (1 + (c₁ w/w_c)³) e^(−c₂ w/w_c) − (w/w_c)(1 + c₁³) e^(−c₂)."""
    x = np.asarray(w_over_wc, float)
    s = (1.0 + (c1 * x) ** 3) * np.exp(-c2 * x) - x * (1.0 + c1**3) * np.exp(-c2)
    return np.where((x >= 0.0) & (x <= 1.0), s, 0.0)


def hordijk_area(c1: float = 3.0, c2: float = 6.93) -> float:
    """∫₀¹ σ/f_t d(w/w_c) of Hordijk's curve (0.19470 for c₁ = 3, c₂ = 6.93), so w_c = G_F / (f_t × this)
    = 5.136 G_F / f_t."""
    x = np.linspace(0.0, 1.0, 20001)
    y = hordijk(x, c1, c2)
    return float(np.sum(0.5 * (y[1:] + y[:-1]) * np.diff(x)))


def crack_opening(elongation, stress, E: float, length: float):
    """The crack opening of a tension test: its total elongation less the elastic part σ L / E (the elastic
    unloading of the uncracked material with the initial modulus, a stated choice)."""
    return np.asarray(elongation, float) - np.asarray(stress, float) * length / E


def softening_curve(elongation, stress, E: float, length: float) -> dict:
    """The tension softening of a run from its elongation and stress (tension positive): the post-peak part's crack
    opening w (counted from the peak) and stress, the peak f_t, and the fracture energy G_F = ∫ σ dw over the whole
    curve up to where the run ended, the opening before the peak (pre-peak cracking) included.  The two differ by
    that pre-peak opening times about f_t: the σ–w curve is compared with Hordijk's from the peak on, with w_c from
    this whole G_F (a stated choice: G_F is the material's, whenever its cracks opened)."""
    u, s = np.asarray(elongation, float), np.asarray(stress, float)
    k = int(np.argmax(s))
    w = crack_opening(u, s, E, length)
    w = w - w[0]
    post = slice(k, None)
    wp = np.maximum.accumulate(w[post])  # the opening grows: a dynamic wiggle does not close the crack
    g = float(np.sum(0.5 * (s[1:] + s[:-1]) * np.diff(np.maximum.accumulate(w))))
    return {"f_t": float(s[k]), "w": wp - wp[0], "stress": s[post], "G_F": g, "end_fraction": float(s[-1] / s[k])}


def hordijk_rms(w, stress, f_t: float, G_F: float, samples: int = 201, c1: float = 3.0, c2: float = 6.93) -> tuple:
    """(RMS of σ/f_t − Hordijk's, w_c) over w/w_c in [0, 1] with the model's own f_t and G_F: the model's curve
    interpolated at evenly spaced w/w_c (where the run ended before w_c, its last stress carried on — a stated
    choice that favours neither)."""
    wc = G_F / (f_t * hordijk_area(c1, c2))
    x = np.linspace(0.0, 1.0, samples)
    w, s = np.asarray(w, float), np.asarray(stress, float) / f_t
    model = np.interp(x * wc, w, s, right=s[-1])
    return float(np.sqrt(np.mean((model - hordijk(x, c1, c2)) ** 2))), wc


def size_effect_fit(D, sigma_N) -> dict:
    """Bažant's size-effect law σ_N = B f_t / √(1 + D/D₀) fitted to the nominal strengths of geometrically similar
    specimens by least squares on log σ_N (the relative misfit): ``Bft`` (= B f_t), ``D0``, the residual (RMS of
    ln σ_N − ln fit) and the log–log slope between the two largest sizes (−1/2 in the LEFM limit).  At least two
    sizes.  A series the law cannot follow (a slope steeper than −1/2, or none) ends with D₀ far below or above the
    sizes: the residual says how well it fits."""
    from scipy.optimize import least_squares

    D, s = np.asarray(D, float), np.asarray(sigma_N, float)
    if len(D) < 2 or len(np.unique(D)) < 2:
        raise ValueError("size_effect_fit: at least two different sizes")
    order = np.argsort(D)
    D, s = D[order], s[order]
    # start from the linear regression of 1/σ² = (1 + D/D0) / (B f_t)²
    A, C = np.polyfit(D, 1.0 / s**2, 1)[::-1]
    d0 = A / C if C > 0 and A > 0 else 10.0 * D[-1]
    b0 = 1.0 / np.sqrt(A) if A > 0 else s[0]

    def res(p):
        return np.log(s) - (p[0] - 0.5 * np.log1p(D / np.exp(p[1])))

    r = least_squares(res, [np.log(b0), np.log(d0)])
    bft, d0 = float(np.exp(r.x[0])), float(np.exp(r.x[1]))
    slope = float(np.log(s[-1] / s[-2]) / np.log(D[-1] / D[-2]))
    return {
        "Bft": bft,
        "D0": d0,
        "residual": float(np.sqrt(np.mean(res(r.x) ** 2))),
        "slope_largest": slope,
        "D": D.tolist(),
        "sigma_N": s.tolist(),
    }


def size_effect_law(D, Bft: float, D0: float):
    """σ_N = B f_t / √(1 + D/D₀)."""
    return Bft / np.sqrt(1.0 + np.asarray(D, float) / D0)
