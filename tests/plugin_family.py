"""A family defined outside the package (used by tests/test_families.py in a subprocess with its own Numba
cache: the package's cache index must never hold a type it cannot import).

Particle ``i`` tied to the origin by a linear spring of stiffness ``k`` (in e1 and e2)."""

from collections import namedtuple

from numba import njit

from polydem_cli.interactions.protocol import register_hooks

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


def main():
    """Run the tethered hexagon for 1 s (period 1 s); print final position, energy swing, last elastic."""
    import json

    import numpy as np
    from test_families import ONE

    from polydem_cli.engine.simulation import Simulation

    from helpers import system_from_toml

    s = system_from_toml(ONE.format(dt=1e-4, end=1.0))
    k = 4.0 * np.pi**2 * s.mass[0]
    sim = Simulation(s)
    # the tuple the loop runs over: the halo (first, always) and the new family; the registered families, all inert
    # in this scene, are left out, so that the loop compiled for this type takes seconds, not the minutes of the
    # whole tuple (the loop is the same code whatever the tuple holds)
    sim.fams = (sim.fams[0], Tether(k, 0, np.zeros(1)))
    sim.initialize()
    rows = np.zeros((20001, sim.ncols))
    n = sim.advance(10000, rows, 1)
    e = rows[:n, 3] + rows[:n, 2]  # elastic (the tether's) + kinetic
    print(json.dumps({"x": sim.positions()[0, :2].tolist(), "swing": float(np.ptp(e) / e[0]), "el": rows[n - 1, 3]}))


if __name__ == "__main__":
    main()
