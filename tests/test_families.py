"""The interaction-family protocol (interactions/protocol.py): a family plugs into the compiled loop without
changing it, a scene pays only for the families it uses, and a family's history survives a checkpoint."""

from collections import namedtuple

import numpy as np
import pytest
from numba import njit

from polydem_cli.engine.families import FAMILIES, compose, slot
from polydem_cli.engine.simulation import Simulation
from polydem_cli.interactions.protocol import register_hooks

from helpers import particle, run, system_from_toml

ONE = """
[scenario]
title = "one free hexagon"
[time]
integrator = "gear5"
dt = {dt}
end_time = {end}
[materials.m]
density = 1.0
k_n = 1.0e7
""" + particle("p", center=[0.3, -0.2], sides=6, circumradius=0.5, velocity=[1.0, 0.5, 0.0])


def test_a_new_family_plugs_into_the_loop_unchanged(tmp_path):
    """A tether-spring family defined outside the package (tests/plugin_family.py): the tethered particle
    oscillates at omega = sqrt(k/m) (analytic) and the spring energy enters the energy balance; nothing in
    engine/kernels.py knows about it.  Run in a subprocess with its own Numba cache (kept beside the
    package's, keyed the same way), so that the package's cache index never holds the test's type; the tuple
    holds the halo and the tether only (the scene uses no registered family), so the loop compiles in seconds."""
    import json
    import os
    import subprocess
    import sys

    from polydem_cli._jit_cache import source_hash

    here = os.path.dirname(__file__)
    env = dict(os.environ)
    import glob
    import shutil

    cache = os.path.join(here, os.pardir, ".jit_cache", f"plugin-test-{source_hash()}")
    for old in glob.glob(os.path.join(here, os.pardir, ".jit_cache", "plugin-test-*")):
        if os.path.basename(old) != os.path.basename(cache):
            shutil.rmtree(old, ignore_errors=True)
    env["NUMBA_CACHE_DIR"] = cache
    env["PYTHONPATH"] = here + os.pathsep + env.get("PYTHONPATH", "")
    r = subprocess.run(
        [sys.executable, os.path.join(here, "plugin_family.py")], env=env, capture_output=True, text=True
    )
    assert r.returncode == 0, r.stderr[-3000:]
    got = json.loads(r.stdout.strip().splitlines()[-1])
    x0, v0 = np.array([0.3, -0.2]), np.array([1.0, 0.5])
    w = 2 * np.pi
    exact = x0 * np.cos(w * 1.0) + v0 / w * np.sin(w * 1.0)
    assert got["x"] == pytest.approx(exact, abs=1e-9)
    assert got["swing"] < 1e-7  # without the hook in "elastic" it would swing by its whole size
    assert got["el"] > 0.0


def test_a_scene_composes_only_the_families_it_uses():
    s = system_from_toml(ONE.format(dt=1e-4, end=0.01))
    used, fams = compose(s)
    assert used == () and fams[0].acc.shape == (0,) and len(fams) == 1 + len(FAMILIES)  # the inert halo
    assert all(b.acc.shape == (0,) for b in fams[1:])  # inert: every hook returns at once
    names = {f.name for f in FAMILIES}
    assert {"base_friction", "disks", "servo"} <= names
    # one loop signature for every scene: the tuple's type does not depend on the families used
    from numba import typeof

    disks = system_from_toml(
        ONE.format(dt=1e-4, end=0.01).split("[[particles]]")[0]
        + '[[particles]]\nname = "d"\nmaterial = "m"\nthickness = 1.0\ntype = "disks"\n'
        + "centers = [[0.0, 0.0]]\nradii = [0.5]\n[disks]\nk_1 = 1.0\nk_2 = 1.0\n"
    )
    assert typeof(compose(disks)[1]) == typeof(fams)


def test_base_friction_state_goes_through_a_checkpoint(tmp_path):
    text = (
        ONE.format(dt=1e-5, end=0.02).replace("k_n = 1.0e7", "k_n = 1.0e7\nk_u = 8.35e5\nmu_u = 0.258")
        + "[base]\ngravity = 981.0\n"
    )
    s = system_from_toml(text)
    used, _ = compose(s)
    assert [f.name for f in used] == ["base_friction"]
    sim, h = run(s, steps=1000, every=100)
    st = sim.state()
    assert {"base_upl", "base_acc"} <= set(st)
    assert st["base_acc"][0] == pytest.approx(h["dissipated_base"][-1])
    other = Simulation(s)
    other.initialize()
    other.restore(st)
    fam = other.fams[slot(used[0])]
    assert np.array_equal(fam.upl, st["base_upl"]) and np.array_equal(fam.acc, st["base_acc"])


def test_a_checkpoint_of_an_older_form_is_refused_and_the_result_left_as_it_was(tmp_path):
    """A checkpoint without a field this version keeps (here the base friction's own accumulators, which older
    versions kept in a shared array) is not continued with made-up values: --resume says what is missing and
    why, and the file is not touched."""
    import hashlib
    import subprocess

    import h5py

    from polydem_cli.solvers.explicit import run as run_result

    from conftest import polydem_cmd

    text = (
        ONE.format(dt=1e-5, end=0.02).replace("k_n = 1.0e7", "k_n = 1.0e7\nk_u = 8.35e5\nmu_u = 0.258")
        + "[base]\ngravity = 981.0\n"
    )
    s = system_from_toml(text)
    out = tmp_path / "r.h5"
    run_result(s, out=out, quiet=True, stop_after_steps=500)
    with h5py.File(out, "r+") as f:
        for slot_ in ("slot0", "slot1"):
            if f"checkpoint/{slot_}/base_acc" in f:
                del f[f"checkpoint/{slot_}/base_acc"]
    before = hashlib.sha1(out.read_bytes()).hexdigest()
    r = subprocess.run(polydem_cmd() + ["run", "--resume", str(out)], capture_output=True, text=True)
    assert r.returncode == 2, r.stderr
    assert "cannot continue it" in r.stderr and "base_acc" in r.stderr and "--overwrite" in r.stderr
    assert hashlib.sha1(out.read_bytes()).hexdigest() == before


def test_an_uncached_hook_is_refused_with_a_message():
    Other = namedtuple("Other", ["a"])

    @njit
    def hook(fam, final, x, v, dt, F):
        return 0

    with pytest.raises(TypeError, match="cache=True"):
        register_hooks(Other, pass_=hook)
