"""Particle numbering is not physics: the same scene in a random particle order gives the
same trajectories (up to the round-off of a different summation order)."""

import numpy as np

from polydem_cli.benchmarks.ordering import HEX, permuted
from polydem_cli.engine.simulation import Simulation
from polydem_cli.interactions.contact.family import POLYGON_CONTACT
from polydem_cli.scenario.build import build_system
from polydem_cli.scenario.load import load_scenario


def _run(s, steps):
    sim = Simulation(s)
    sim.initialize()
    rows = np.zeros((4, sim.ncols))
    while sim.step < steps:
        sim.advance(steps, rows, steps)
    return sim.positions(), POLYGON_CONTACT.contacts(sim.bundle("contact"))


def test_random_particle_order_gives_same_motion():
    sc, _ = load_scenario(HEX, ["particles.0.rows=8", "particles.0.row_counts=[7, 8]", "time.dt=1e-5"])
    s = build_system(sc, HEX)
    p = np.random.default_rng(3).permutation(s.n)
    x0, c0 = _run(s, 300)
    x1, c1 = _run(permuted(s, p), 300)
    assert c0 == c1 > 0
    moved = np.abs(x0 - s.x0).max()
    assert moved > 1e-6  # the pre-compressed packing does move
    np.testing.assert_allclose(x1, x0[p], rtol=0, atol=1e-9 * max(moved, 1.0))
