"""The linked-cell search finds exactly the pairs of a brute-force all-pairs check (SPEC.md §5.1)."""
import numpy as np
import pytest

from polydem_cli.engine.search import find_candidates, large_particle_mask
from polydem_cli.geometry.polygon import make_shape, rectangle, regular_polygon
from polydem_cli.interactions.contact.geometry import CONTACT, NO_CONTACT, pair_geometry_py

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
    k = find_candidates(x, rad, large, np.flatnonzero(large).astype(np.int64), cell_size,
                        np.zeros(ncell, np.int64), np.zeros(ncell + 1, np.int64), np.zeros(n, np.int64),
                        np.zeros(n, np.int64), cand, *EMPTY, 0.0)
    return k, {tuple(p) for p in cand[:max(k, 0)]}


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
    start[a + 1:] = 1
    large = large_particle_mask(rad)
    cand = np.zeros((10000, 2), np.int64)
    ncell = 4 * n + 64
    for active, expect_in in ((True, False), (False, True)):
        k2 = find_candidates(x, rad, large, np.flatnonzero(large).astype(np.int64), 1.0,
                             np.zeros(ncell, np.int64), np.zeros(ncell + 1, np.int64), np.zeros(n, np.int64),
                             np.zeros(n, np.int64), cand, start, np.array([b]), np.array([active]), 0.0)
        assert ((a, b) in {tuple(p) for p in cand[:k2]}) == expect_in
