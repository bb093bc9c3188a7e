"""The linked-cell search finds exactly the pairs of a brute-force all-pairs check."""

import numpy as np
import pytest

from polydem_cli.geometry.polygon import make_shape, rectangle, regular_polygon
from polydem_cli.interactions.contact.geometry import NO_CONTACT, pair_geometry_py
from polydem_cli.interactions.search import find_candidates, large_particle_mask

EMPTY = (np.zeros(0, np.int64), np.zeros(0, np.int64), np.zeros(0, np.bool_))


def _scene(seed, n=300, mixed=True, plates=True):
    rng = np.random.default_rng(seed)
    polys = []
    L = np.sqrt(n) * 0.9
    for _ in range(n):
        r = rng.uniform(0.2, 0.6) if mixed else 0.5
        if mixed and rng.random() < 0.05:
            r *= 4  # a few much larger particles, bigger than a cell
        polys.append(regular_polygon(int(rng.integers(3, 9)), r, rng.uniform(0, 6.3), rng.uniform(0, L, 2)))
    if plates:
        polys.append(rectangle((L / 2, -0.5), (L + 4, 1.0)))
        polys.append(rectangle((-0.5, L / 2), (1.0, L + 4)))
    x = np.zeros((len(polys), 3))
    rad = np.zeros(len(polys))
    for i, p in enumerate(polys):
        s, c = make_shape(p)
        x[i, :2] = c
        rad[i] = s.radius
    return polys, x, rad


def _search(x, rad, cell_size, cap=100000):
    n = len(x)
    large = large_particle_mask(rad)
    cand = np.zeros((cap, 2), np.int64)
    ncell = 4 * n + 64
    k = find_candidates(
        x,
        rad,
        large,
        np.flatnonzero(large).astype(np.int64),
        cell_size,
        np.zeros(ncell, np.int64),
        np.zeros(ncell + 1, np.int64),
        np.zeros(n, np.int64),
        np.zeros(n, np.int64),
        cand,
        *EMPTY,
        0.0,
        False,
    )
    return k, {tuple(p) for p in cand[: max(k, 0)]}


def _brute(x, rad):
    out = set()
    for i in range(len(x)):
        for j in range(i + 1, len(x)):
            if np.sum((x[i, :2] - x[j, :2]) ** 2) <= (rad[i] + rad[j]) ** 2:
                out.add((i, j))
    return out


@pytest.mark.parametrize("seed,mixed", [(0, True), (1, True), (2, False)])
@pytest.mark.parametrize("cell_size", [0.3, 1.2, 5.0])
def test_candidates_equal_brute_force(seed, mixed, cell_size):
    polys, x, rad = _scene(seed, mixed=mixed)
    k, found = _search(x, rad, cell_size)
    ref = _brute(x, rad)
    assert k == len(found)  # no duplicates
    assert found == ref


@pytest.mark.parametrize(
    "bad",
    [
        {5: (np.nan, 1.0), 17: (2.0, np.inf)},  # non-finite positions (the engine stops such a state)
        {5: (-np.inf, np.nan), 9: (np.inf, -np.inf)},
        {5: (1e300, 0.0), 9: (-1e300, 1e300)},  # finite, but a mesh of more cells than the integers hold
        {5: (1.7e308, 0.0), 9: (-1.7e308, 0.0)},  # finite, spread beyond the floating-point range
    ],
)
def test_positions_far_out_or_not_finite_stay_within_the_arrays(bad):
    """Whatever it is given, the search writes within its cell arrays (a position that is not finite takes part in
    no pair) and finds among the others exactly the brute-force pairs."""
    polys, x, rad = _scene(6, n=150)
    for i, xy in bad.items():
        x[i, :2] = xy
    k, found = _search(x, rad, 0.5)
    ok = np.isfinite(x[:, :2]).all(axis=1)
    with np.errstate(over="ignore", invalid="ignore"):
        ref = {p for p in _brute(x, rad) if ok[p[0]] and ok[p[1]]}
    assert k == len(found) and found == ref
    assert len(ref) > 20


def test_contacts_equal_brute_force_overlap():
    polys, x, rad = _scene(5, n=200)
    k, found = _search(x, rad, 1.0)
    contacts = {p for p in found if pair_geometry_py(polys[p[0]], polys[p[1]])[0] != NO_CONTACT}
    brute = set()
    for i in range(len(polys)):
        for j in range(i + 1, len(polys)):
            if pair_geometry_py(polys[i], polys[j])[0] != NO_CONTACT:
                brute.add((i, j))
    assert contacts == brute
    assert len(brute) > 50


def test_overflow_reports_needed_capacity():
    polys, x, rad = _scene(3)
    k, _ = _search(x, rad, 1.0, cap=10)
    assert k < -10
    k2, found = _search(x, rad, 1.0, cap=-k)
    assert k2 == -k and len(found) == -k


def test_bonded_pairs_are_excluded():
    polys, x, rad = _scene(4, n=100, plates=False)
    n = len(x)
    k, found = _search(x, rad, 1.0)
    a, b = sorted(found)[0]
    start = np.zeros(n + 1, np.int64)
    start[a + 1 :] = 1
    large = large_particle_mask(rad)
    cand = np.zeros((10000, 2), np.int64)
    ncell = 4 * n + 64
    for active, expect_in in ((True, False), (False, True)):
        k2 = find_candidates(
            x,
            rad,
            large,
            np.flatnonzero(large).astype(np.int64),
            1.0,
            np.zeros(ncell, np.int64),
            np.zeros(ncell + 1, np.int64),
            np.zeros(n, np.int64),
            np.zeros(n, np.int64),
            cand,
            start,
            np.array([b]),
            np.array([active]),
            0.0,
            False,
        )
        assert ((a, b) in {tuple(p) for p in cand[:k2]}) == expect_in


def test_buffered_pair_list_finds_exactly_the_unbuffered_contacts_at_every_step():
    """Dynamic pile: at every step the buffered list (rebuilt only after a particle moved half the
    buffer) and a fresh thesis search give the same set of contacting pairs."""
    from polydem_cli.engine.simulation import Simulation
    from polydem_cli.interactions.contact.kernel import contact_pass, empty_history, make_work
    from polydem_cli.scenario.build import build_system
    from polydem_cli.scenario.load import load_scenario

    from conftest import SCEN

    sc, _ = load_scenario(SCEN / "ch6" / "nuts_small.toml", ["time.end_displacement=0.05"])
    s = build_system(sc, "x")
    sim = Simulation(s)
    sim.initialize()
    n = s.n
    g = sim.bundle("contact").g  # the polygons as the contact family sees them
    links = sim.bundle("bonds").links
    work = {}
    for name, buf in (("fresh", 0.0), ("buffered", 0.3 * float(np.median(s.radius)))):
        c = sim.bundle("contact").cp
        cp = c._replace(tangential=0, buffer=buf)
        work[name] = (
            cp,
            make_work(n, len(s.body_v), 6, 4096, 4 * n + 64),
            empty_history(n, 4096),
            empty_history(n, 4096),
        )
    rows = np.zeros((4, sim.ncols))
    builds = 0
    for step in range(1, s.end_step + 1, 5):
        sim.advance(step, rows, 10**9)
        sets = {}
        for name, (cp, cw, h0, h1) in work.items():
            F = np.zeros((n, 3))
            st = np.zeros(13)
            contact_pass(True, sim.x, sim.v, s.dt, g, cp, cw, h0, h1, links, F, st)
            nl = cw.list_meta[0]
            sets[name] = {tuple(cw.cand[k]) for k in range(nl) if cw.pr_i[k, 0] != 0}
            if name == "buffered":
                builds = cw.list_meta[1]
        assert sets["fresh"] == sets["buffered"], step
    assert builds < s.end_step // 5 / 3  # the list was reused most of the time
    assert len(sets["fresh"]) > 20
