"""Runs decomposed over 3, 4 and 8 MPI ranks (engine/distributed.py) against the same run on one process.

On 2 ranks every rank is the other's only neighbour and the boxes meet along one line; from 3 ranks on, recursive
coordinate bisection makes T-junctions (a box's corner on the side of another: 3 ranks always, since the first cut
gives one rank on one side and two on the other), particles cross to ranks that are not the only neighbour, and on 8
ranks some ranks are not neighbours at all.  The ranks run oversubscribed on this machine (mpiexec
``-n`` beyond the cores): these test correctness, not speed (tests/test_ranks.py has the 2-rank cases and the CLI)."""

from __future__ import annotations

import numpy as np
import pytest
from test_ranks import BASE, CONCRETE, DENSE, FAST_PANEL, HEX, MPIEXEC, on_ranks, same_rows, serial

from polydem_cli.engine.decompose import box_gap, plan

pytestmark = pytest.mark.skipif(not MPIEXEC.exists(), reason="the mpich wheel (test extra) is not installed")


def t_junctions(boxes) -> int:
    """How many box corners lie strictly inside another box's side (RCB's T-junctions; a cross of four boxes has
    none).  ``boxes`` (P, 4) = (x_lo, x_hi, y_lo, y_hi), the outer ones reaching to ±inf."""
    n = 0
    for a in boxes:
        for cx in a[:2]:
            for cy in a[2:]:
                if not (np.isfinite(cx) and np.isfinite(cy)):
                    continue
                for b in boxes:
                    on_x_side = cx in (b[0], b[1]) and b[2] < cy < b[3]
                    on_y_side = cy in (b[2], b[3]) and b[0] < cx < b[1]
                    n += bool(on_x_side or on_y_side)
    return n


def test_bonds_failing_across_t_junctions_as_on_one_process(tmp_path):
    """The fast-pulled 12 x 12 concrete panel (Voronoi cells: the bisection's cuts fall at different heights in the two
    halves, so its boxes meet in T-junctions): beams damaged across the boundaries, some failed, their pairs handed
    over to contact.
    Positions, velocities and damage equal the serial run's bit for bit (each particle's force sum is in the serial
    order whatever the rank).  On 3 ranks: 4 pass too, but took 40 s in make test beside the other worker (four
    busy-polling ranks on two shared cores); the four-rank decomposition is the dense packing's test below."""
    ranks = 3
    steps = 6000
    s, sim, rows = serial(CONCRETE, FAST_PANEL, steps)
    got = on_ranks(tmp_path, CONCRETE, FAST_PANEL, steps, ranks=ranks)
    assert t_junctions(got["boxes"]) >= 1
    p = sim.bundle("bonds").p
    own = got["owner"]
    d = sim.bundle("bonds").h.d
    across = own[p.a] != own[p.b]
    assert len({tuple(sorted(q)) for q in zip(own[p.a][across], own[p.b][across])}) >= ranks - 1
    assert (d[across] > 0.0).sum() >= 5, "no beam damaged across a boundary: pull longer"
    assert (d >= 1.0).sum() >= 1 and rows[-1, 13] > 0  # beams failed, their pairs handed over to contact
    np.testing.assert_array_equal(got["x"], sim.nord[:, :, 0])
    np.testing.assert_array_equal(got["v"], sim.nord[:, :, 1] / sim.dt)
    np.testing.assert_array_equal(got["d"], d)
    same_rows(got["rows"], rows)


@pytest.mark.parametrize("ranks, rows_", [(3, 12), (8, 24)])
def test_contacts_migrating_over_many_ranks_as_on_one_process(tmp_path, ranks, rows_):
    """Pre-compressed hexagons pushing apart and driven sideways and down onto their held bottom row, with a ghost
    margin of 20 µm: re-cut several times, particles change owner with their contacts' tangential springs — on 3 ranks across the T-junction of the
    bisection (the first cut leaves one rank on one side, two on the other), on 8 ranks (576 hexagons) between
    ranks that are not all neighbours (no ghost between some).  The result equals the serial run to round-off."""
    steps = 200
    over = [f"particles.0.rows={rows_}", f"particles.0.row_counts=[{rows_}, {rows_}]", "output.history_every=10"]
    over += ["particles.0.velocity=[400.0, -400.0, 0.0]", 'boundary=[{set = "hex.bottom", x1 = "fixed", x2 = "fixed"}]']
    s, sim, rows = serial(HEX, over, steps)
    got = on_ranks(tmp_path, HEX, over + ["--skin=0.002"], steps, ranks=ranks)
    dec = plan(s, ranks)
    if ranks == 3:
        assert t_junctions(dec.boxes) >= 1
    else:
        far = sum(int((box_gap(b, dec.boxes) > dec.halo).sum()) for b in dec.boxes)
        assert far >= 2, "every rank is every other's neighbour: the neighbour lists would not be exercised"
    owners = got["owners"]
    assert got["redistributions"] >= 2 and len(owners) == got["redistributions"] + 1
    assert (owners[0] != owners[-1]).sum() >= 3, "no particle changed owner"
    c = sim.bundle("contact")
    m = int(c.hold.meta[0])
    own = got["owner"]
    assert (own[c.hold.a[:m]] != own[c.hold.b[:m]]).sum() >= 5  # contacts with tangential history across cuts
    x = sim.nord[:, :, 0]
    assert np.abs(x - s.x0).max() > 1e-3  # the packing has moved
    np.testing.assert_allclose(got["x"], x, rtol=0, atol=1e-12 * np.abs(x).max())
    np.testing.assert_allclose(got["v"], sim.nord[:, :, 1] / sim.dt, rtol=0, atol=1e-9 * np.abs(got["v"]).max())
    same_rows(got["rows"], rows)


def test_a_refused_re_cut_leaves_every_rank_its_part(tmp_path):
    """Rank 0's first re-cut refused (a DecompositionError, as for a box grown narrower than the interaction range):
    every rank stops with the refusal, none keeps waiting for a part, and the old parts are whole, so the state still
    gathers (what the run's summary and last checkpoint need) and equals the serial run's at that step."""
    over = ["particles.0.rows=12", "particles.0.row_counts=[12, 12]", "output.history_every=10"]
    over += ["particles.0.velocity=[400.0, -400.0, 0.0]", 'boundary=[{set = "hex.bottom", x1 = "fixed", x2 = "fixed"}]']
    got = on_ranks(tmp_path, HEX, over + ["--skin=0.002", "--refuse-recut"], 200, ranks=3)
    k = int(got["step"])
    assert 0 < k < 200, k  # paused to re-cut before the end
    msgs = [str(m) for m in got["messages"]]
    assert msgs[0] == "the re-cut refused for the test" and all("re-cut refused" in m for m in msgs[1:]), msgs
    s, sim, _ = serial(HEX, over, k)
    x = sim.nord[:, :, 0]
    np.testing.assert_allclose(got["x"], x, rtol=0, atol=1e-12 * np.abs(x).max())


def test_dense_packing_on_four_ranks_as_on_one_process(tmp_path):
    """The 144 dense hexagons of tests/test_ranks.py on 4 ranks (a cross of four boxes: four ranks meet in one
    point, so a particle there is a ghost of three ranks)."""
    steps = 300
    s, sim, rows = serial(HEX, DENSE, steps)
    got = on_ranks(tmp_path, HEX, DENSE, steps, ranks=4)
    x = sim.nord[:, :, 0]
    np.testing.assert_allclose(got["x"], x, rtol=0, atol=1e-12 * np.abs(x).max())
    same_rows(got["rows"], rows)


#: two bonded panels flying past each other (no contact: they interact only through their own beams), the lower
#: one spinning its particles so that its beams bend and are damaged on the way
PASSING = """
[scenario]
title = "two bonded panels passing each other"
seed = 1
[time]
integrator = "gear5"
dt = 4.0e-8
end_time = 6.0e-4
[output]
history_every = 100
[stability]
max_energy_error = 1e9
[materials.concrete]
density = 2.40
[[particles]]
name = "a"
material = "concrete"
thickness = 1.0
type = "voronoi"
nx = 10
ny = 6
min_shared_edge = 0.01
velocity = [20000.0, 0.0, 300.0]
[[particles]]
name = "b"
material = "concrete"
thickness = 1.0
type = "voronoi"
nx = 10
ny = 6
origin = [12.0, 7.0]
min_shared_edge = 0.01
velocity = [-20000.0, 0.0, 0.0]
[bonds]
E = 4.14e11
nu = -0.676
kappa_0 = 9.21e-5
G_ax = 1.90e5
"""


def test_a_bond_crossing_three_ranks_over_its_life_as_on_one_process(tmp_path):
    """Two bonded panels of 60 Voronoi cells change places, 12 cm each way, on 3 ranks: the cuts follow them (dozens of
    re-cuts), so a bond is counted on each of the three ranks in turn, its damage (the lower panel's particles spin,
    its beams bend) travelling with it — the bond network's rows, their global numbers and which rank counts them
    re-cut each time.  Positions, velocities and every bond's damage equal the serial run bit for bit."""
    path = tmp_path / "passing.toml"
    path.write_text(PASSING)
    steps = 15000
    s, sim, rows = serial(str(path), [], steps)
    got = on_ranks(tmp_path, str(path), [], steps, ranks=3)
    assert got["redistributions"] >= 10
    owners = got["owners"]  # every particle's owner at the start and after each re-cut
    p = sim.bundle("bonds").p
    d = sim.bundle("bonds").h.d
    counted_on = np.array([len(set(owners[:, a])) for a in p.a])  # a bond is counted on the owner of its first
    assert ((counted_on == 3) & (d > 0.0)).sum() >= 10, "no damaged bond was counted on all three ranks"
    assert np.abs(sim.nord[:, 0, 0] - s.x0[:, 0]).max() > 11.0  # the panels have changed places
    np.testing.assert_array_equal(got["x"], sim.nord[:, :, 0])
    np.testing.assert_array_equal(got["v"], sim.nord[:, :, 1] / sim.dt)
    np.testing.assert_array_equal(got["d"], d)
    same_rows(got["rows"], rows)


def test_a_re_cut_sends_no_particle_array_through_a_collective_call(tmp_path):
    """The two passing panels, 240 cells each, on 4 ranks: every re-cut (a dozen or more) moves the particles between
    neighbours only.  During the re-cuts no collective call (gather, broadcast, reduction, …) carries an array as long
    as a fifth of a rank's particles — the medians of the bisection, the message counts and the accumulators (the
    engine's 24 energy sums the longest) are what the ranks share — and the run equals the serial one bit for
    bit."""
    big = PASSING.replace("nx = 10\nny = 6", "nx = 20\nny = 12").replace(
        "origin = [12.0, 7.0]", "origin = [22.0, 13.0]"
    )
    path = tmp_path / "passing.toml"
    path.write_text(big)
    steps = 3000
    s, sim, rows = serial(str(path), [], steps)
    assert s.n == 480
    got = on_ranks(tmp_path, str(path), ["--count-collectives"], steps, ranks=4)
    assert got["redistributions"] >= 10
    longest = dict(zip(got["collective_names"], got["collectives"]))
    assert longest["Allreduce"] >= 1 and longest["allgather"] >= 1  # the counting saw the re-cuts' calls
    assert max(longest.values()) <= 24, longest  # a rank owns 120 particles
    np.testing.assert_array_equal(got["x"], sim.nord[:, :, 0])
    np.testing.assert_array_equal(got["v"], sim.nord[:, :, 1] / sim.dt)


ROOT = __import__("pathlib").Path(__file__).resolve().parents[1]
#: a bonded panel flying into unbonded hexagons: on 3 ranks two ranks hold no bond at all (the bond family's arrays
#: empty there, its fixed-size interface arrays as long as its rows) and the panel's beams come to them
MIXED = """
[scenario]
title = "a bonded panel beside unbonded hexagons"
seed = 1
[time]
integrator = "gear5"
dt = 4.0e-8
end_time = 1.0
[output]
history_every = 50
[stability]
max_energy_error = 1e9
[materials.concrete]
density = 2.40
k_n = 2.07e9
k_t = 2.07e9
mu_t = 0.5
[materials.steel]
density = 5.32
k_n = 1.61e7
k_t = 4.74e7
mu_t = 0.294
[[particles]]
name = "a"
material = "concrete"
thickness = 1.0
type = "voronoi"
nx = 8
ny = 6
min_shared_edge = 0.01
velocity = [20000.0, 0.0, 0.0]
[[particles]]
name = "hex"
material = "steel"
thickness = 0.62
type = "hexagon_packing"
width = 1.27
rows = 12
row_counts = [12, 12]
spacing = 1.2573
origin = [9.5, 0.0]
[bonds]
E = 4.14e11
nu = -0.676
kappa_0 = 9.21e-5
G_ax = 1.90e5
[contact]
tangential = "coulomb"
initial_overlap = "allow"
"""
DRIFT = ["particles.0.velocity=[400.0, -400.0, 0.0]", 'boundary=[{set = "hex.bottom", x1 = "fixed", x2 = "fixed"}]']
LOADED = ["output.history_every=50", 'loads=[{set = "specimen.left", force = [2.0e5, 0.0], ramp_time = 6.0e-4}]']


@pytest.mark.parametrize(
    "path,over,steps,ranks",
    [
        (CONCRETE, FAST_PANEL + ["particles.0.velocity=[3000.0, 0.0, 0.0]", "--skin=0.001"], 2500, 3),  # beams, contact
        (HEX, DENSE + DRIFT + ["--skin=0.002"], 400, 4),  # polygon contact with its histories
        (HEX, DENSE + BASE + ["particles.0.velocity=[200.0, 0.0, 0.0]", "--skin=0.002"], 400, 3),  # base friction
        (str(ROOT / "scenarios/lh/prepare_p100.toml"), ["output.history_every=100", "--skin=0.005"], 3000, 3),  # disks
        (  # proportional pressure, ramped loads
            str(ROOT / "scenarios/lab/smoke_biaxial.toml"),
            LOADED + ["particles.0.velocity=[500.0, 0.0, 0.0]", "--skin=0.0001"],
            1500,
            3,
        ),
    ],
    ids=["bonded-panel", "hexagons", "base-friction", "disks-servo-walls", "proportional-loads"],
)
def test_a_re_cut_between_neighbours_makes_the_parts_a_cut_of_the_whole_scene_makes(tmp_path, path, over, steps, ranks):
    """Every family's data and state through re-cuts between neighbours, against rank 0's cut (``_compare_recuts``)."""
    _compare_recuts(tmp_path, path, over, steps, ranks)


def test_a_re_cut_where_ranks_hold_no_bond_makes_the_parts_a_cut_of_the_whole_scene_makes(tmp_path):
    """The bonded panel flying into the hexagons on 3 ranks: two ranks begin without a bond and receive beams at the
    re-cuts; the parts and states as rank 0's cut gives them, and the positions the serial run's to round-off."""
    path = tmp_path / "mixed.toml"
    path.write_text(MIXED)
    steps = 1500
    s, sim, _ = serial(str(path), [], steps)
    got = _compare_recuts(tmp_path, str(path), ["--skin=0.002"], steps, 3)
    p = sim.bundle("bonds").p
    owners = got["owners"]
    assert any(len(set(o[p.a]) | set(o[p.b])) < 3 for o in owners)  # some rank held no bond
    x = sim.nord[:, :, 0]  # (the hexagons' contacts summed in another order: to round-off, as on the other scenes)
    np.testing.assert_allclose(got["x"], x, rtol=0, atol=1e-12 * np.abs(x).max())


def _compare_recuts(tmp_path, path, over, steps, ranks):
    """Each re-cut made by neighbour exchange (engine/migrate.py) against the cut of the whole scene, gathered to rank
    0, that re-cuts were made by before (engine/distributed.py ``Cut``, ``share``): every rank's new part — its
    particles, its scene with every family's data, its exchange lists and watch lists, its set members — and its
    share of the state equal the reference array for array, bit for bit."""
    got = on_ranks(tmp_path, path, over + ["--compare-recut"], steps, ranks=ranks)
    assert got["redistributions"] >= 2
    differ = [d for d in got["differ"] if d]
    assert not differ, differ[:20]
    return got
