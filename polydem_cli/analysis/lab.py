"""The standard numbers of the laboratory tests of concrete and rock, from a test's load record.

* Brazilian splitting (ASTM C496 / EN 12390-6): a disc of diameter D and thickness T loaded along a diameter by
  a force F fails at the splitting tensile strength ``f_ct,sp = 2 F_max / (π D T)`` — the tensile stress across
  the loaded diameter of an elastic disc under two opposite point loads (Hertz's solution; Timoshenko & Goodier,
  *Theory of Elasticity*, §41).
* Three-point bending of a notched beam (RILEM TC-50 FMC, Mater. Struct. 18 (1985) 285–290): the fracture energy
  ``G_F = W_F / A_lig``, W_F the work of the load along its whole load–deflection curve (to the end of the test,
  where the load has fallen to zero), A_lig = (h − a₀) T the ligament's area.  RILEM adds the work of the beam's
  weight, m g δ₀; the 2D specimens here carry no weight (stated: the term is 0).
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


def fib_fracture_energy(f_cm: float) -> float:
    """fib Model Code 2010 (5.1-9): ``G_F = 73 f_cm^0.18`` N/m, ``f_cm`` the mean compressive strength in
    g cm⁻¹ s⁻² (converted to MPa); returns erg/cm²."""
    if not f_cm > 0.0:
        raise ValueError("fib_fracture_energy: f_cm must be > 0 (the compressive strength's magnitude)")
    return 73.0 * (float(f_cm) / MPA) ** 0.18 * N_PER_M
