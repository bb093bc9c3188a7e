"""The standard numbers of the laboratory tests of concrete and rock, from a test's load record.

* Brazilian splitting (ASTM C496 / EN 12390-6): a disc of diameter D and thickness T loaded along a diameter by
  a force F fails at the splitting tensile strength ``f_ct,sp = 2 F_max / (π D T)`` — the tensile stress across
  the loaded diameter of an elastic disc under two opposite point loads (Hertz's solution; Timoshenko & Goodier,
  *Theory of Elasticity*, §41).
* Three-point bending of a notched beam (RILEM TC-50 FMC, Mater. Struct. 18 (1985) 285–290): the fracture energy
  ``G_F = W_F / A_lig``, W_F the work of the load along its whole load–deflection curve (to the end of the test,
  where the load has fallen to zero), A_lig = (h − a₀) T the ligament's area.  RILEM adds the work of the beam's
  weight, m g δ₀; the 2D specimens here carry no weight (stated: the term is 0).
* Confined (biaxial) compression at lateral pressures σ₃ = p: the Mohr–Coulomb envelope through the peaks,
  ``σ₁ = f_c + N_φ σ₃`` with ``N_φ = (1 + sin φ)/(1 − sin φ)`` and cohesion ``c = f_c (1 − sin φ)/(2 cos φ)``
  (the principal-stress form of τ = c + σ tan φ; e.g. Jaeger, Cook & Zimmerman, *Fundamentals of Rock
  Mechanics*, 4th ed., §4.5), fitted by least squares; compressive stresses positive here.
* Cyclic compression with unloading: the damage of each cycle from its unloading stiffness,
  ``d = 1 − E_u / E₀`` (the scalar damage of continuum damage mechanics, Lemaitre & Chaboche, *Mechanics of
  Solid Materials*, §7.2), E_u the slope of the unloading branch, E₀ that of the first loading (least-squares
  lines through their records: an explicit run's turn at once rings by ρ c Δv, a secant between two points
  would carry that ringing).
* fib Model Code 2010, eq. (5.1-9): ``G_F = 73 f_cm^0.18`` N/m with f_cm in MPa, the estimate a measured G_F is
  judged against.

Units: the cm-g-s system of the rest of polydem (force in dyn, length in cm, stress in g cm⁻¹ s⁻², energy per
area in erg/cm² = 1e-3 N/m); :data:`.macro.MPA` converts stresses.
"""

from __future__ import annotations

import numpy as np

from .macro import MPA

#: erg/cm² per N/m (J/m²)
N_PER_M = 1.0e3


def splitting_strength(peak_force: float, diameter: float, thickness: float) -> float:
    """``f_ct,sp = 2 F / (π D T)`` (module docstring): force in dyn, lengths in cm; g cm⁻¹ s⁻²."""
    if not (diameter > 0.0 and thickness > 0.0):
        raise ValueError("splitting_strength: the diameter and the thickness must be > 0")
    return 2.0 * float(peak_force) / (np.pi * float(diameter) * float(thickness))


def work_of_fracture(force, deflection) -> float:
    """``W_F = ∫ F dδ`` along the record (trapezoids from its first point; the curve from zero load if the record
    starts there), erg."""
    F = np.asarray(force, float)
    d = np.asarray(deflection, float)
    if F.shape != d.shape or F.ndim != 1:
        raise ValueError("work_of_fracture: force and deflection must be 1-D records of one length")
    return float(np.sum(0.5 * (F[1:] + F[:-1]) * np.diff(d))) if len(F) > 1 else 0.0


def fracture_energy(force, deflection, ligament_height: float, thickness: float) -> float:
    """RILEM TC-50 ``G_F = W_F / ((h − a₀) T)`` (no self-weight term, module docstring), erg/cm²;
    ``ligament_height`` = h − a₀."""
    if not (ligament_height > 0.0 and thickness > 0.0):
        raise ValueError("fracture_energy: the ligament height and the thickness must be > 0")
    return work_of_fracture(force, deflection) / (float(ligament_height) * float(thickness))


def mohr_coulomb(sigma3, sigma1) -> dict:
    """The Mohr–Coulomb envelope ``σ₁ = f_c + N_φ σ₃`` (module docstring) fitted by least squares to peak axial
    stresses ``sigma1`` at lateral pressures ``sigma3`` (compression positive, any one stress unit; at least two
    distinct pressures): ``f_c`` (the envelope's unconfined strength), ``N_phi``, ``phi`` (degrees), ``c`` (the
    stress unit) and ``rms`` (the residual of σ₁)."""
    s3 = np.asarray(sigma3, float)
    s1 = np.asarray(sigma1, float)
    if s3.shape != s1.shape or s3.ndim != 1 or len(np.unique(s3)) < 2:
        raise ValueError("mohr_coulomb: needs peaks at two or more distinct lateral pressures")
    A = np.column_stack([np.ones_like(s3), s3])
    (fc, N), *_ = np.linalg.lstsq(A, s1, rcond=None)
    if not N > 1.0:
        raise ValueError(
            f"mohr_coulomb: the peaks do not rise with the pressure fast enough for a friction angle (N_phi = {N:.3g})"
        )
    sphi = (N - 1.0) / (N + 1.0)
    phi = np.arcsin(sphi)
    c = fc * (1.0 - sphi) / (2.0 * np.cos(phi))
    rms = float(np.sqrt(np.mean((A @ np.array([fc, N]) - s1) ** 2)))
    return {"f_c": float(fc), "N_phi": float(N), "phi": float(np.degrees(phi)), "c": float(c), "rms": rms}


def unloading_damage(strain, stress) -> dict:
    """Per unloading branch of a cyclic record (compression or tension, one sign), its stiffness and the damage
    ``d = 1 − E_u / E₀`` (module docstring).  A branch runs from a local maximum of |strain| to the next local
    minimum, E_u the slope of the least-squares line through its points; E₀ that of the first loading's points
    from 10 % of its top stress to its top (the initial, undamaged stiffness).  Returns ``E0`` and lists ``strain``
    (at each branch's start), ``stress`` (there), ``E_u`` and ``d``."""
    e = np.abs(np.asarray(strain, float))
    s = np.abs(np.asarray(stress, float))
    if e.shape != s.shape or e.ndim != 1 or len(e) < 3:
        raise ValueError("unloading_damage: strain and stress must be 1-D records of one length (3 points or more)")
    de = np.diff(e)
    sign = np.sign(de)
    # the record's turning points: the last point of each run of rising / falling strain
    for k in range(1, len(sign)):
        if sign[k] == 0:
            sign[k] = sign[k - 1]
    turns = np.flatnonzero(sign[1:] != sign[:-1]) + 1
    tops = [int(t) for t in turns if sign[t - 1] > 0]
    bottoms = [int(t) for t in turns if sign[t - 1] < 0] + [len(e) - 1]
    if not tops:
        raise ValueError("unloading_damage: the record has no unloading branch")

    def slope(i, j):
        x, y = e[i : j + 1], s[i : j + 1]
        dx = x - x.mean()
        return float(np.sum(dx * (y - y.mean())) / np.sum(dx * dx))

    first = int(np.flatnonzero(s[: tops[0] + 1] >= 0.1 * s[tops[0]])[0])
    if tops[0] - first < 1 or e[tops[0]] <= e[first]:
        raise ValueError("unloading_damage: no loading from the origin before the first unloading")
    E0 = slope(first, tops[0])
    out = {"E0": float(E0), "strain": [], "stress": [], "E_u": [], "d": []}
    for a in tops:
        b = next((t for t in bottoms if t > a), None)
        if b is None or e[a] - e[b] <= 0.0:
            continue
        Eu = slope(a, b)
        out["strain"].append(float(e[a]))
        out["stress"].append(float(s[a]))
        out["E_u"].append(float(Eu))
        out["d"].append(float(1.0 - Eu / E0))
    return out


def fib_fracture_energy(f_cm: float) -> float:
    """fib Model Code 2010 (5.1-9): ``G_F = 73 f_cm^0.18`` N/m, ``f_cm`` the mean compressive strength in
    g cm⁻¹ s⁻² (converted to MPa); returns erg/cm²."""
    if not f_cm > 0.0:
        raise ValueError("fib_fracture_energy: f_cm must be > 0 (the compressive strength's magnitude)")
    return 73.0 * (float(f_cm) / MPA) ** 0.18 * N_PER_M
