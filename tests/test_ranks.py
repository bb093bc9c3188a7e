"""A run decomposed over 2 MPI ranks (engine/distributed.py) against the same run on one process: contacts and
bonds across the subdomain boundary, bonds failing across it.  The ranks are started with the ``mpiexec`` of the
MPICH wheel the test extra installs (no system MPI)."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from polydem_cli.engine.simulation import Simulation
from polydem_cli.errors import DecompositionError
from polydem_cli.scenario.build import build_system
from polydem_cli.scenario.load import load_scenario

ROOT = Path(__file__).resolve().parents[1]
MPIEXEC = Path(sys.executable).with_name("mpiexec")
CONCRETE = str(ROOT / "scenarios/bench_concrete_40.toml")
HEX = str(ROOT / "scenarios/bench_dense_hexagons.toml")
#: a 12 x 12 concrete panel pulled fast (1 m/s at once): beams fail within a few hundred steps, contact after
FAST_PANEL = [
    "particles.0.nx=12",
    "particles.0.ny=12",
    "boundary.0.x2.velocity=100.0",
    "boundary.0.x2.acceleration=1e12",
    "output.history_every=10",
]
#: a dense, pre-compressed packing of 144 hexagons: every neighbour in contact, all pushing apart
DENSE = ["particles.0.rows=12", "particles.0.row_counts=[12, 12]", "output.history_every=10"]


def serial(path, overrides, steps):
    sc, _ = load_scenario(path, overrides)
    s = build_system(sc, path)
    sim = Simulation(s)
    sim.initialize()
    rows = np.zeros((steps // s.history_every + 2, sim.ncols))
    n = sim.advance(steps, rows, s.history_every)
    return s, sim, rows[:n]


def on_ranks(tmp_path, path, overrides, steps, ranks=2):
    out = tmp_path / "ranks.npz"
    cmd = [str(MPIEXEC), "-n", str(ranks), sys.executable, str(ROOT / "tests/ranks_run.py"), str(out), path, str(steps)]
    cmd += overrides
    env = dict(os.environ, NUMBA_NUM_THREADS="1", OMP_NUM_THREADS="1")
    res = subprocess.run(cmd, capture_output=True, text=True, env=env, timeout=900)
    assert res.returncode == 0, res.stderr[-3000:]
    return dict(np.load(out))


def same_rows(a, b):
    """Equal to round-off: the ranks sum their rows in another order; energy_total (column 7) is a small difference
    of large energies and is compared with the size of the energies."""
    assert a.shape == b.shape
    scale = np.maximum(np.abs(a).max(axis=0), 1e-300)
    scale[7] = max(scale[2], scale[3], scale[6], 1e-300)
    rel = np.abs(a - b).max(axis=0) / scale
    assert rel.max() < 1e-10, (np.flatnonzero(rel >= 1e-10), rel.max())


@pytest.mark.skipif(not MPIEXEC.exists(), reason="the mpich wheel (test extra) is not installed")
def test_bonds_failing_across_the_boundary_as_on_one_process(tmp_path):
    steps = 6000
    s, sim, rows = serial(CONCRETE, FAST_PANEL, steps)
    got = on_ranks(tmp_path, CONCRETE, FAST_PANEL, steps)
    d = sim.bundle("bonds").h.d
    p = sim.bundle("bonds").p
    across = got["owner"][p.a] != got["owner"][p.b]
    # the test means something: beams across the boundary, some of them failed, contacts made
    assert across.sum() >= 5
    assert (d[across] >= 1.0).sum() >= 1, "no bond failed across the boundary: pull longer"
    assert rows[-1, 13] > 0  # n_contacts (failed beams hand their pairs over to contact)
    # each particle's force sum is in the serial order: positions, velocities and damage equal bit for bit
    np.testing.assert_array_equal(got["x"], sim.nord[:, :, 0])
    np.testing.assert_array_equal(got["v"], sim.nord[:, :, 1] / sim.dt)
    np.testing.assert_array_equal(got["d"], d)
    same_rows(got["rows"], rows)


@pytest.mark.skipif(not MPIEXEC.exists(), reason="the mpich wheel (test extra) is not installed")
def test_contacts_across_the_boundary_as_on_one_process(tmp_path):
    steps = 300
    s, sim, rows = serial(HEX, DENSE, steps)
    got = on_ranks(tmp_path, HEX, DENSE, steps)
    c = sim.bundle("contact")
    m = int(c.hold.meta[0])
    a, b = c.hold.a[:m], c.hold.b[:m]
    assert (got["owner"][a] != got["owner"][b]).sum() >= 5  # contacts with tangential history across the cut
    x = sim.nord[:, :, 0]
    assert np.abs(x - s.x0).max() > 1e-4  # the packing has moved
    np.testing.assert_allclose(got["x"], x, rtol=0, atol=1e-12 * np.abs(x).max())
    same_rows(got["rows"], rows)


def test_a_family_that_does_not_run_decomposed_is_refused():
    from polydem_cli.engine.distributed import Part

    path = str(ROOT / "scenarios/ch5/tension.toml")
    sc, _ = load_scenario(path, ["particles.0.nx=6", "particles.0.ny=6"])
    s = build_system(sc, path)
    with pytest.raises(DecompositionError, match="'load_drop' does not run on several ranks"):
        Part(s, 0, 2)
