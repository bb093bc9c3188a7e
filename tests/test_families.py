"""The interaction-family protocol (interactions/protocol.py): a family plugs into the compiled loop without
changing it, a scene pays only for the families it uses, and a family's history survives a checkpoint."""

from collections import namedtuple

import numpy as np
import pytest
from numba import njit

from polydem_cli.engine.families import FAMILIES, compose
from polydem_cli.engine.simulation import Simulation
from polydem_cli.interactions.protocol import NO_FAMILY, register_hooks

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

#: a test family: particle i tied to the origin by a linear spring of stiffness k (in e1 and e2)
Tether = namedtuple("Tether", ["k", "i", "energy"])


@njit(cache=True)
def _tether_pass(fam, final, x, v, dt, F):
    i = fam.i
    F[i, 0] -= fam.k * x[i, 0]
    F[i, 1] -= fam.k * x[i, 1]
    if final:
        fam.energy[0] = 0.5 * fam.k * (x[i, 0] ** 2 + x[i, 1] ** 2)
    return 0


@njit(cache=True)
def _tether_elastic(fam):
    return fam.energy[0]


register_hooks(Tether, pass_=_tether_pass, elastic=_tether_elastic)


def test_a_new_family_plugs_into_the_loop_unchanged():
    """The tethered particle oscillates at omega = sqrt(k/m) (analytic) and its spring energy enters the
    energy balance; nothing in engine/kernels.py knows about Tether."""
    s = system_from_toml(ONE.format(dt=1e-4, end=1.0))
    m = s.mass[0]
    k = 4.0 * np.pi**2 * m  # period 1 s
    sim = Simulation(s)
    sim.fams = sim.fams + (Tether(k, 0, np.zeros(1)),)
    sim.initialize()
    rows = np.zeros((20001, sim.ncols))
    n = sim.advance(10000, rows, 1)
    x0, v0 = np.array([0.3, -0.2]), np.array([1.0, 0.5])
    w = 2 * np.pi
    t = 1.0
    exact = x0 * np.cos(w * t) + v0 / w * np.sin(w * t)
    assert sim.positions()[0, :2] == pytest.approx(exact, abs=1e-9)
    e = rows[:n, 3] + rows[:n, 2]  # elastic (the tether's) + kinetic
    assert np.ptp(e) < 1e-7 * e[0]  # without the hook in "elastic" it would swing by its whole size
    assert rows[n - 1, 3] > 0.0


def test_a_scene_composes_only_the_families_it_uses():
    s = system_from_toml(ONE.format(dt=1e-4, end=0.01))
    used, fams = compose(s)
    assert used == () and fams == (NO_FAMILY,)
    names = {f.name for f in FAMILIES}
    assert "base_friction" in names


def test_base_friction_state_goes_through_a_checkpoint_and_legacy_accumulators(tmp_path):
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
    (fam,) = other.fams[1:]
    assert np.array_equal(fam.upl, st["base_upl"]) and np.array_equal(fam.acc, st["base_acc"])
    # a checkpoint written before the family kept its own accumulators: taken from the shared array
    old = {k: v for k, v in st.items() if k != "base_acc"}
    old["acc"] = st["acc"].copy()
    old["acc"][13], old["acc"][14] = 7.0, 0.5
    third = Simulation(s)
    third.initialize()
    third.restore(old)
    assert list(third.fams[1].acc) == [7.0, 0.5]


def test_an_uncached_hook_is_refused_with_a_message():
    Other = namedtuple("Other", ["a"])

    @njit
    def hook(fam, final, x, v, dt, F):
        return 0

    with pytest.raises(TypeError, match="cache=True"):
        register_hooks(Other, pass_=hook)
