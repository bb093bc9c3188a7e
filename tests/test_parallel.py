"""Thread-count determinism: the parallel kernels give bit-identical results for 1 and 2 threads."""

import os
import subprocess

import h5py
import numpy as np

from conftest import SCEN, polydem_cmd


def test_bonded_run_is_identical_with_one_and_two_threads(tmp_path):
    # 20 x 20 cells: ~1,130 beams, above the parallel threshold of the bond kernel
    args = [
        "run",
        str(SCEN / "ch5" / "small_tension.toml"),
        "-q",
        "--set",
        "particles.0.nx=20",
        "--set",
        "particles.0.ny=20",
        "--set",
        "time.end_displacement=2e-4",
        "--set",
        "time.dt=2e-2",
        "--set",
        "output.frame_interval=20",
        # loaded ten times faster than the scenario (the comparison needs damage, not quasi-statics)
        "--set",
        "boundary.0.x2.velocity=1e-6",
        "--set",
        "boundary.0.x2.acceleration=1e-8",
    ]
    res = []
    for t in (1, 2):
        out = tmp_path / f"t{t}.h5"
        env = dict(os.environ, NUMBA_NUM_THREADS=str(t))
        r = subprocess.run(polydem_cmd() + args + ["-o", str(out)], capture_output=True, text=True, env=env)
        assert r.returncode == 0, r.stderr
        with h5py.File(out, "r") as f:
            res.append((f["history/table"][...], f["frames/x"][...], f["frames/bond_d"][...]))
            assert len(f["bonds/L"]) >= 1000
    (h1, x1, d1), (h2, x2, d2) = res
    assert d1[-1].max() > 0  # damage happened
    assert np.array_equal(h1, h2) and np.array_equal(x1, x2) and np.array_equal(d1, d2)
