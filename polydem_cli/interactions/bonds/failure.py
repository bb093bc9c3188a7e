"""Bond failure by mode and orientation (thesis §7.3: tension-dominated failure of the joints
with normal in e1, shear failure of the diagonal joints under normal compression).

For every bond the kernel records the step at which it failed (d reached 1 in the final
update) and the three parts of the equivalent strain (5.8) at that state,
``ε_v = ⟨ε_ax,M + |ϰ_M| H_h/2⟩ + |γ_M|``:

* **mode** — the largest of the tensile axial part ``⟨ε_ax,M⟩``, the bending part
  ``|ϰ_M| H_h/2`` and the shear part ``|γ_M|``: ``tension``, ``bending`` or ``shear``; a shear
  or bending failure with ``ε_ax,M < 0`` also counts as ``under_compression``;
* **orientation** — of the beam axis (the line of centroids at t0), angle θ ∈ [0°, 180°)
  from e1: ``horizontal`` within 22.5° of e1, ``vertical`` within 22.5° of e2, else
  ``diagonal``.  A beam along e1 joins particles side by side: its joint (the shared edge)
  has its normal in e1.  For hexagon packings with flat sides vertical the beams lie at 0°
  (horizontal) and ±60° (diagonal).
"""

from __future__ import annotations

import numpy as np

MODES = ("tension", "bending", "shear")
ORIENTATIONS = ("horizontal", "diagonal", "vertical")
#: half-width of the horizontal and vertical orientation classes, degrees
ORIENTATION_TOLERANCE_DEG = 22.5
#: fail_step of a bond that failed before failure records existed (older checkpoints)
UNKNOWN_STEP = -2


def beam_angle_deg(ux0, uy0) -> np.ndarray:
    """Angle of the beam axis from e1 in [0°, 180°)."""
    return np.mod(np.degrees(np.arctan2(uy0, ux0)), 180.0)


def orientation_class(angle_deg) -> np.ndarray:
    """``horizontal`` / ``diagonal`` / ``vertical`` index (0, 1, 2) of beam angles in degrees."""
    a = np.asarray(angle_deg, float)
    tol = ORIENTATION_TOLERANCE_DEG
    off_h = np.minimum(a, 180.0 - a)  # angle to e1
    off_v = np.abs(a - 90.0)
    return np.where(off_h <= tol, 0, np.where(off_v <= tol, 2, 1))


def failure_modes(fail_strain) -> np.ndarray:
    """Index into MODES of the dominating part of (5.8) for every row (ε_ax, |ϰ|H/2, |γ|)."""
    s = np.asarray(fail_strain, float).reshape(-1, 3)
    parts = np.column_stack([np.maximum(s[:, 0], 0.0), s[:, 1], s[:, 2]])
    return np.argmax(parts, axis=1)


def failure_table(fail_step, fail_strain, ux0, uy0, dt: float) -> dict:
    """Per failed bond: index, step, time, mode, orientation, angle and strain parts."""
    fail_step = np.asarray(fail_step)
    k = np.flatnonzero(fail_step != -1)
    known = fail_step[k] >= 0
    mode = failure_modes(np.asarray(fail_strain)[k])
    ang = beam_angle_deg(np.asarray(ux0)[k], np.asarray(uy0)[k])
    return {
        "bond": k,
        "step": fail_step[k],
        "time": np.where(known, fail_step[k] * dt, np.nan),
        "mode": np.where(known, mode, -1),
        "orientation": orientation_class(ang),
        "angle_deg": ang,
        "strain": np.asarray(fail_strain)[k],
    }


def failure_counts(fail_step, fail_strain, ux0, uy0, dt: float = 1.0, n_bonds_by_orientation=True) -> dict:
    """Counts per mode, per orientation, and mode × orientation (for the run summary)."""
    t = failure_table(fail_step, fail_strain, ux0, uy0, dt)
    out = {
        "failed": int(len(t["bond"])),
        "modes_definition": "dominating part of (5.8) at failure: "
        "<eps_ax,M> tension, |kappa_M| H_h/2 bending, |gamma_M| shear",
        "orientation_definition": f"beam axis within {ORIENTATION_TOLERANCE_DEG:g} deg of e1 horizontal, "
        f"of e2 vertical, else diagonal",
    }
    known = t["mode"] >= 0
    out["by_mode"] = {m: int(np.sum(t["mode"] == i)) for i, m in enumerate(MODES)}
    if not np.all(known):
        out["by_mode"]["unknown"] = int(np.sum(~known))
    comp = known & (t["strain"][:, 0] < 0.0) & (t["mode"] != 0)
    out["by_mode"]["under_compression"] = int(np.sum(comp))
    out["by_orientation"] = {o: int(np.sum(t["orientation"] == i)) for i, o in enumerate(ORIENTATIONS)}
    out["by_orientation_and_mode"] = {
        o: {m: int(np.sum((t["orientation"] == i) & (t["mode"] == j))) for j, m in enumerate(MODES)}
        for i, o in enumerate(ORIENTATIONS)
    }
    if n_bonds_by_orientation:
        allc = orientation_class(beam_angle_deg(np.asarray(ux0), np.asarray(uy0)))
        out["bonds_by_orientation"] = {o: int(np.sum(allc == i)) for i, o in enumerate(ORIENTATIONS)}
    return out
