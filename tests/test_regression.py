"""Stored-result regression: one small scenario per model family, run for a fixed number of steps and
compared with numbers stored in tests/regression/<name>.json, so that any unintended change of a result
shows up (an intended one: regenerate with ``POLYDEM_REGENERATE=1 pytest tests/test_regression.py`` and
say why in the commit).

Compared: the last history row (every column: energies, loads, bond counts, macro measures) and the
final generalised positions of all particles.  The granular runs are short (a few thousand steps) so that
the round-off differences of another CPU or compiler stay far below the tolerance in the contact piles;
the bonded ones run into damage (and failure, contact after failure), the part of the model they test.

Numba compiles for the host CPU, so another vector width or use of fused multiply-add changes the last
bits, and 150,000-400,000 steps through damage thresholds amplify them: measured between the stored
results and an AMD EPYC host (2026-12-02; the same numbers from the commit before and after the disk
family): a residual moment of the top row 3.8e-4 of its value, a kinetic energy 1e-8 of the case's energy
scale 1.3 % of its own value, rotations 1.7e-7.  A stored result therefore records the CPU it was computed
on (``cpu``, LLVM's host CPU name and a digest of its features): on that CPU every column must agree to RTOL = 1e-7 of its unit's scale,
on another only to RTOL_CROSS = 1e-2 of it (the largest difference measured: the top-row load of the
filtered-rate case after 250,000 steps into softening, 3.0e-3), and the residual columns (kinetic energy, a
set's mean rotation and moment sum: small sums of cancelling terms in these quasi-static runs; the
filtered-rate case's bottom-row moment differs by 1.25e-2) to RTOL_RESIDUAL_CROSS = 5e-2: across CPUs the test
catches changes of about a per cent and more.  Regenerating on the CI's CPU restores the strict check.
"""

import json
import os

import numpy as np
import pytest

from polydem_cli.io.hdf5 import open_result, read_checkpoint, read_history
from polydem_cli.scenario.build import build_system
from polydem_cli.scenario.load import load_scenario
from polydem_cli.solvers.explicit import run

from conftest import SCEN

STORE = os.path.join(os.path.dirname(__file__), "regression")
REGENERATE = os.environ.get("POLYDEM_REGENERATE") == "1"
RTOL = 1e-7
RTOL_CROSS = 1e-2
RESIDUAL = ("kinetic", "phi:", "c:")  # column prefixes of the residual quantities
RTOL_RESIDUAL_CROSS = 5e-2


def host_cpu() -> str:
    """LLVM's name of the host CPU and a digest of the features it compiles for: two hosts called znver4 differed in
    the last bits of the glued nuts' residual moment after 150,000 steps (1.2e-7 of it; f69bdc5 and later trees
    alike), so the name alone does not say that Numba made the same machine code."""
    import hashlib

    import llvmlite.binding as ll

    feats = ",".join(sorted(k for k, v in ll.get_host_cpu_features().items() if v))
    return f"{ll.get_host_cpu_name()}+{hashlib.sha1(feats.encode()).hexdigest()[:8]}"


#: name: (scenario, overrides, steps) -- one per model family
CASES = {
    "contact_pile_gear5": ("demo_hex_pile.toml", [], 3000),  # area contact, Coulomb friction, load plates
    "contact_pile_verlet": ("demo_hex_pile.toml", ['time.integrator="verlet"'], 3000),
    "base_friction_nuts": ("ch6/nuts_small.toml", [], 2000),  # particle-base friction
    "beams_rate_independent": ("ch5/small_tension.toml", [], 400_000),  # elasto-damage beams (5.8)-(5.12)
    "beams_rate_dependent": ("ch5/small_rate_tension_ra.toml", [], 250_000),  # (5.13)-(5.16)
    "beams_rate_filtered": ("ch5/small_rate_tension_ra.toml", ["bonds.rate_filter=6.0"], 250_000),
    "concrete_contact_after_failure": ("ch7/smoke_concrete_tension.toml", [], 25_000),  # beams + contact, [macro]
    "glued_nuts": ("ch7/smoke_nuts_glued.toml", [], 150_000),
    "cohesive_disks": ("lh/smoke_disk_compression.toml", [], 20_000),  # Luding-Herrmann law (LH 1.5)-(1.9), walls
    "servo_walls": ("lh/prepare_p100.toml", ["particles.0.count=300"], 10_000),  # stress-controlled walls (LH 1.2)
}


@pytest.mark.parametrize("name", sorted(CASES))
def test_stored_result(tmp_path, name):
    scen, sets, steps = CASES[name]
    sc, text = load_scenario(SCEN / scen, sets)
    out = tmp_path / "r.h5"
    run(build_system(sc, scen), out=out, scenario_text=text, quiet=True, stop_after_steps=steps)
    cols, tab = read_history(out)
    with open_result(out) as f:
        units = json.loads(f["history/table"].attrs["units"])
        ck = read_checkpoint(f)
    assert int(ck["step"][0]) == steps
    if "bonds_damaged" in cols:  # the bonded cases reach the nonlinear part of the model
        assert tab[-1, cols.index("bonds_damaged")] + tab[-1, cols.index("bonds_failed")] > 0
    x = ck["nord"][..., 0] if ck["nord"].ndim == 3 else ck["nord"]
    got = {
        "scenario": scen,
        "overrides": sets,
        "steps": steps,
        "columns": cols,
        "units": units,
        "last_row": tab[-1].tolist(),
        "positions": np.asarray(x).tolist(),
        "cpu": host_cpu(),
    }
    path = os.path.join(STORE, f"{name}.json")
    if REGENERATE:
        with open(path, "w") as f:
            json.dump(got, f)
        pytest.skip(f"regenerated {path}")
    assert os.path.exists(path), f"no stored result {path}: run with POLYDEM_REGENERATE=1 once"
    with open(path) as f:
        ref = json.load(f)
    assert ref["columns"] == cols
    same_cpu = ref.get("cpu") == host_cpu()  # stored before 'cpu' was recorded: unknown, another CPU
    rtol = RTOL if same_cpu else RTOL_CROSS
    row, rrow = np.array(got["last_row"]), np.array(ref["last_row"])
    for c, u, a, b in zip(cols, units, row, rrow):
        scale = max(abs(v) for v, uu in zip(rrow, units) if uu == u)  # the magnitude of quantities of that unit
        r = RTOL_RESIDUAL_CROSS if not same_cpu and c.startswith(RESIDUAL) else rtol
        assert a == pytest.approx(b, rel=r, abs=r * scale), f"{name}: history column {c} changed" + (
            "" if same_cpu else f" (stored on CPU {ref.get('cpu', 'unrecorded')}, this is {host_cpu()})"
        )
    x, xr = np.asarray(got["positions"]), np.array(ref["positions"])
    assert x.shape == xr.shape
    assert np.max(np.abs(x - xr)) <= rtol * np.max(np.abs(xr)), f"{name}: final positions changed"
