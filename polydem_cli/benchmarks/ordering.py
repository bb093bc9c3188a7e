"""How much particle ordering costs: the dense hexagon packing in generator (row) order and
in a random order, same physics, one thread.

    python -m polydem_cli.benchmarks.ordering ROWS STEPS [--out FILE]

Generators emit particles row by row (hexagon packings, Voronoi grids, plates), which is
already cell-coherent; this measures what a scene in random order (e.g. a particle list read
from elsewhere) would lose, i.e. what a re-sort by cell would win.  Contact-only scenes:
the permutation here maps per-particle arrays and vertex lists, not bonds or Gauss points.
"""

from __future__ import annotations

import dataclasses
import json
import sys

import numpy as np

from ..interactions.base.family import BASE_FRICTION
from ..interactions.bonds.family import BEAM_BONDS
from ..interactions.contact.family import POLYGON_CONTACT

HEX = "scenarios/bench_dense_hexagons.toml"


def permuted(s, p):
    """The system ``s`` with its particles in the order ``p`` (contact-only scenes)."""
    if BEAM_BONDS.uses(s) or BASE_FRICTION.uses(s):
        raise ValueError("ordering study: only contact-only scenes (no bonds, no base friction)")
    nv = np.diff(s.vert_start)
    vs = np.zeros(s.n + 1, dtype=s.vert_start.dtype)
    vs[1:] = np.cumsum(nv[p])
    bv = np.concatenate([s.body_v[s.vert_start[i] : s.vert_start[i + 1]] for i in p])
    inv = np.empty_like(p)
    inv[p] = np.arange(len(p))
    sets = {k: np.sort(inv[np.asarray(v, np.int64)]) for k, v in s.sets.items()}
    cs = POLYGON_CONTACT.data(s)
    data = dict(s.family_data, **{POLYGON_CONTACT.name: _per_particle(cs, p, s.n)} if cs is not None else {})
    return dataclasses.replace(s, vert_start=vs, body_v=bv, sets=sets, family_data=data, **_per_particle(s, p, s.n, 0))


def _per_particle(obj, p, n, whole=1):
    """The (n, …) array fields of dataclass ``obj`` in the order ``p``: a copy of ``obj`` (``whole``) or the
    fields alone."""
    d = {
        f.name: getattr(obj, f.name)[p]
        for f in dataclasses.fields(obj)
        if isinstance(getattr(obj, f.name), np.ndarray) and getattr(obj, f.name).shape[:1] == (n,)
    }
    return dataclasses.replace(obj, **d) if whole else d


def rate(s, steps, repeat=3):
    """(particle-steps/s, contacts at the end) of ``steps`` steps of system ``s``."""
    from .bench import time_system

    times, _, contacts = time_system(s, steps, repeat)
    return s.n * steps / float(np.median(times)), contacts


def main(rows: int, steps: int, out=None):
    """The ordering study: particle-steps/s of a dense hexagon packing of ``rows`` x ``rows`` in its generated (row)
    order against the same packing re-sorted by cell and shuffled, ``steps`` steps on one thread; JSON to ``out``."""
    import numba

    from ..scenario.build import build_system
    from ..scenario.load import load_scenario
    from .bench import write_json

    numba.set_num_threads(1)
    sc, _ = load_scenario(HEX, [f"particles.0.rows={rows}", f"particles.0.row_counts=[{rows}, {rows}]"])
    s = build_system(sc, HEX)
    r_row, c_row = rate(s, steps)
    r_shuf, c_shuf = rate(permuted(s, np.random.default_rng(1).permutation(s.n)), steps)
    res = {
        "particles": int(s.n),
        "steps": steps,
        "threads": 1,
        "row_order_particle_steps_per_s": r_row,
        "random_order_particle_steps_per_s": r_shuf,
        "slowdown": r_row / r_shuf,
        "contacts": [c_row, c_shuf],
    }
    print(json.dumps(res, indent=1))
    if out:
        write_json(out, res)
    return res


if __name__ == "__main__":
    from polydem_cli import setup_jit_cache

    setup_jit_cache()
    a = sys.argv[1:]
    out = a[a.index("--out") + 1] if "--out" in a else None
    main(int(a[0]), int(a[1]), out)
