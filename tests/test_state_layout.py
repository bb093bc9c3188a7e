"""The communication layer of a decomposed run's checkpoints (interactions/ranks.py: ``globalize``, ``merge``,
``scatter`` from each family's declared ``state_layout``), without MPI: a serial run's checkpoint fields shared out
to the parts of a 3-rank cut and joined again are the serial fields — every contact with its history once, every
bond's and Gauss point's history, the sums' shares adding up to the scene's, the maxima and their pairs — and the
lists to be rebuilt are marked so.  (The runs on ranks, tests/test_ranks*.py, compare whole runs with one process.)"""

import numpy as np
import pytest
from test_ranks import BASE, CONCRETE, DENSE, FAST_PANEL, HEX, ROOT

from polydem_cli.engine.distributed import Cut, layout
from polydem_cli.engine.families import slot, used_families
from polydem_cli.engine.simulation import Simulation
from polydem_cli.interactions import ranks
from polydem_cli.interactions.ranks import Entries, Pairs, Rebuilt, Rows, Same, Summed
from polydem_cli.scenario.build import build_system
from polydem_cli.scenario.load import load_scenario

#: the interface material of tests/test_interface.py's runs on ranks
INTERFACE = ['bonds.model="interface"', "bonds.nu=0.2", "bonds.f_t=3e7", "bonds.cohesion=6e7", "bonds.G_I=1e5"]
INTERFACE += ["bonds.G_II=4e5", 'bonds.crack_criterion="principal"', "bonds.crack_strength=1.5e7"]
LH = str(ROOT / "scenarios/lh/prepare_p100.toml")

SCENES = {
    # beams failing and handing over to contact (bonds, contact)
    "panel": (CONCRETE, FAST_PANEL, 6000),
    # hexagons in contact with friction history and base friction (contact, base friction)
    "hexagons": (HEX, DENSE + BASE, 200),
    # edge interfaces (their elements' history: 2-D rows) damaged and broken, handing over to contact
    "interfaces": (CONCRETE, FAST_PANEL + INTERFACE, 6000),
    # the cohesive disks under two servo walls (disk contacts and disk-wall pairs: the disks' own counting rules)
    "disks": (LH, [], 300),
}


def _serial(name):
    path, over, steps = SCENES[name]
    s = build_system(load_scenario(path, over)[0], path)
    sim = Simulation(s)
    sim.initialize()
    sim.advance(steps, np.zeros((steps // s.history_every + 2, sim.ncols)), s.history_every)
    return s, sim


@pytest.mark.parametrize("name", list(SCENES))
def test_a_checkpoint_shared_out_and_joined_again_is_the_serial_one(name):
    s, sim = _serial(name)
    cut = Cut(s, 3)
    parts = [cut.part(r) for r in range(3)]
    checked = set()
    for f in used_families(s):
        whole = f.state(sim.fams[slot(f)])
        lay = layout(f, s)
        shares = [ranks.scatter(layout(f, p.system), whole, p.keep, p.own, p.system, p.rank) for p in parts]
        partials = [ranks.globalize(layout(f, p.system), sh, p.keep, p.own, p.system) for p, sh in zip(parts, shares)]
        back = ranks.merge(lay, partials, s)
        for names, kind in lay:
            checked.add(type(kind).__name__)
            for k in names:
                if isinstance(kind, Pairs):
                    a, b = names[0], names[1]
                    order = np.lexsort((whole[b], whole[a]))
                    got = np.lexsort((back[b], back[a]))
                    assert len(back[k]) == len(whole[k]), (f.name, k)  # every pair once
                    np.testing.assert_array_equal(back[k][got], whole[k][order], err_msg=f"{f.name}.{k}")
                elif isinstance(kind, Rebuilt):
                    assert len(back[k]) == 0 or not np.any(back[k]), (f.name, k)  # empty or zero: rebuilt
                elif isinstance(kind, Entries):
                    w = np.asarray(whole[k])
                    keep = [e for e in range(w.shape[-1]) if e not in dict(kind.fixed)]
                    np.testing.assert_array_equal(np.asarray(back[k])[..., keep], w[..., keep], err_msg=f"{f.name}.{k}")
                    for e, v in kind.fixed:
                        assert np.all(np.asarray(back[k])[..., e] == v)
                    for e in kind.sums:  # the shares: on rank 0 only
                        assert all(np.all(np.asarray(sh[k])[..., e] == 0) for sh in shares[1:])
                else:  # Same, Summed, Rows
                    np.testing.assert_array_equal(back[k], whole[k], err_msg=f"{f.name}.{k}")
                    if isinstance(kind, Summed):
                        np.testing.assert_array_equal(sum(sh[k] for sh in shares), whole[k])
    # the scenes exercise the kinds the families declare (Same and the controllers' Summed: tests/test_ranks.py)
    assert {"Pairs", "Entries", "Rebuilt"} | ({"Rows"} if name != "disks" else set()) <= checked
    st = {f.name: f.state(sim.fams[slot(f)]) for f in used_families(s)}
    if name in ("panel", "interfaces"):  # pairs were there to move: contacts with history after the bonds failed
        assert len(st["contact"]["contact_a"]) > 0
    if name == "interfaces":  # elements damaged and broken: their rows carry history
        assert (st["bonds"]["bond_e_D"] > 0).any() and (st["bonds"]["bond_e_D"] == 1).any()
    if name == "disks":  # disk-disk and disk-wall pairs
        wall = s.family_data["disks"].params.wall
        b = st["disks"]["disk_b"]
        assert np.isin(b, wall).any() and (~np.isin(b, wall)).any()


def test_rows_and_pairs_by_hand():
    """Three particles on two ranks (rank 0 owns 0, 1; rank 1 owns 2, holding 1 as a ghost): a row counted on rank 1,
    a pair (1, 2) counted by its smaller index's owner (rank 0) and evaluated on both."""

    class Part:
        def __init__(self, rows):
            self.family_data = {"f": rows}

    keep = [np.array([0, 1, 2]), np.array([1, 2])]
    own = [np.array([True, True, False]), np.array([False, True])]
    row_ids = [(np.array([0, 1]), np.array([True, False])), (np.array([1]), np.array([True]))]
    lay = (
        (("r",), Rows(ids=lambda p: p.family_data["f"], n=lambda s: 2)),
        (("a", "b", "h"), Pairs()),
        (("s",), Summed()),
        (("c",), Same()),
        (("e",), Entries(sums=(0,), maxima=(1,), particles=(2,))),
    )
    whole = {
        "r": np.array([10.0, 11.0]),
        "a": np.array([1]),
        "b": np.array([2]),
        "h": np.array([7.5]),
        "s": np.array([4.0]),
        "c": np.array([3.0]),
        "e": np.array([5.0, 9.0, 2.0]),
    }
    parts = [Part(row_ids[r]) for r in range(2)]
    sh = [ranks.scatter(lay, whole, keep[r], own[r], parts[r], r) for r in range(2)]
    assert list(sh[0]["a"]) == [1] and list(sh[0]["b"]) == [2]  # local numbers on rank 0
    assert list(sh[1]["a"]) == [0] and list(sh[1]["b"]) == [1]  # and on rank 1
    assert sh[1]["s"][0] == 0.0 and sh[1]["e"][0] == 0.0 and sh[1]["e"][1] == 9.0
    assert sh[0]["e"][2] == 2.0 and sh[1]["e"][2] == 1.0  # particle 2 is local 2 on rank 0, 1 on rank 1
    sh[1]["e"][1] = 12.0  # rank 1 saw a larger maximum since
    g = [ranks.globalize(lay, sh[r], keep[r], own[r], parts[r]) for r in range(2)]
    assert len(g[0]["a"]) == 1 and len(g[1]["a"]) == 0  # counted once, on rank 0
    back = ranks.merge(lay, g, None)
    assert list(back["r"]) == [10.0, 11.0] and list(back["s"]) == [4.0] and list(back["c"]) == [3.0]
    assert list(back["e"]) == [5.0, 12.0, 2.0]
    assert list(back["a"]) == [1] and list(back["b"]) == [2] and list(back["h"]) == [7.5]


def test_localize_cuts_each_kind_of_scene_data_as_declared():
    """interactions/ranks.py ``localize`` on hand-made data, against the cut worked out by hand: a rank holding
    particles 1, 3, 4, 6 of 7 (local 0–3) and owning 1 and 4.  Per-particle rows are kept for the held particles,
    the walls (held everywhere) renumbered, each entry's members kept where owned with their parallel arrays;
    paths reach into dicts, namedtuples and tuples, and what the layout does not name is left alone."""
    from collections import namedtuple

    from polydem_cli.interactions.ranks import Held, Owned, PerParticle, localize

    keep, own = np.array([1, 3, 4, 6]), np.array([True, False, True, False])
    W = namedtuple("W", ["wall", "k"])
    data = {
        "kn": np.arange(7) * 10.0,
        "walls": (W(wall=np.array([3, 6]), k=np.array([5.0, 6.0])), "names"),
        "idx": [np.array([0, 1, 3, 4]), np.array([6]), np.array([4, 1])],
        "f": [np.array([[1.0], [2.0], [3.0], [4.0]]), np.array([[5.0]]), np.array([[6.0], [7.0]])],
        "other": np.array([9, 9]),
    }
    lay = ((("kn",), PerParticle()), (("walls.0.wall",), Held()), (("idx", "f"), Owned()))
    out = localize(lay, data, keep, own)
    assert out["kn"].tolist() == [10.0, 30.0, 40.0, 60.0]
    assert out["walls"][0].wall.tolist() == [1, 3] and out["walls"][0].k is data["walls"][0].k
    assert out["walls"][1] == "names"
    assert [i.tolist() for i in out["idx"]] == [[0, 2], [], [2, 0]]  # global 1, 4 | none | 4, 1
    assert [f[:, 0].tolist() for f in out["f"]] == [[2.0, 4.0], [], [6.0, 7.0]]
    assert out["other"] is data["other"]
    assert data["kn"].shape == (7,) and data["walls"][0].wall.tolist() == [3, 6]  # the whole scene's data unchanged
    assert localize(lay, None, keep, own) is None


def test_localize_cuts_pair_rows_groups_and_pair_lists_as_declared():
    """The other kinds of ``localize`` on hand-made data (the rank holds 1, 3, 4, 6 of 7 particles and owns 1 and 4):
    bonds with an owned end, renumbered, each counted on the owner of its first particle, every per-bond array of a
    container cut by ``.*``; Gauss-point groups of the owned particles with their members; the held disks and their
    count; initial pairs kept where the rule says they are evaluated."""
    from collections import namedtuple
    from dataclasses import dataclass

    from polydem_cli.interactions.ranks import Groups, HeldMembers, PairList, PairRows, localize

    keep, own = np.array([1, 3, 4, 6]), np.array([True, False, True, False])

    P = namedtuple("P", ["a", "b", "k", "iface", "scalar"])
    I = namedtuple("I", ["h", "other"])  # noqa: E741

    @dataclass(frozen=True)
    class Net:
        params: P
        E: np.ndarray
        listed: list
        gid: np.ndarray | None = None
        counted: np.ndarray | None = None

    # bonds (a, b): (1,3) owned a, (3,4) owned b, (3,6) no owned end, (4,6) owned a, (0,1) owned b (0 not held: refused)
    a, b = np.array([1, 3, 3, 4]), np.array([3, 4, 6, 6])
    net = Net(P(a, b, np.array([1.0, 2.0, 3.0, 4.0]), I(np.arange(8.0).reshape(4, 2), np.zeros(2)), 7.0), a * 10.0, [5])
    rows = PairRows("params.a", "params.b", ("params.*", "params.iface.*", "E"), "gid", "counted", ("listed",))
    out = localize((((), rows),), net, keep, own)
    assert out.params.a.tolist() == [0, 1, 2] and out.params.b.tolist() == [1, 2, 3]  # rows 0, 1, 3
    assert out.params.k.tolist() == [1.0, 2.0, 4.0] and out.E.tolist() == [10.0, 30.0, 40.0]
    assert out.params.iface.h.tolist() == [[0.0, 1.0], [2.0, 3.0], [6.0, 7.0]] and out.params.iface.other.shape == (2,)
    assert out.gid.tolist() == [0, 1, 3] and out.counted.tolist() == [1, 0, 1] and out.listed == []
    assert out.params.scalar == 7.0
    bad = Net(P(np.array([0]), np.array([1]), np.ones(1), I(np.zeros((1, 2)), None), 0.0), np.ones(1), [])
    with pytest.raises(ValueError, match="not among the kept"):
        localize((((), rows),), bad, keep, own)

    # Gauss points: particle 1 has points 0-1, particle 3 point 2, particle 4 points 3-5
    B = namedtuple("B", ["start", "X", "idx", "ku"])
    D = namedtuple("D", ["bs", "gp"])
    d = D(
        B(np.array([0, 2, 3, 6]), np.arange(12.0).reshape(6, 2), np.array([1, 3, 4]), np.array([1.0, 3.0, 4.0])), None
    )
    g = localize((((), Groups("bs.idx", "bs.start", ("bs.ku",), ("bs.X",), ids="gp")),), d, keep, own)
    assert g.bs.idx.tolist() == [0, 2] and g.bs.start.tolist() == [0, 2, 5] and g.bs.ku.tolist() == [1.0, 4.0]
    assert g.gp.tolist() == [0, 1, 3, 4, 5] and g.bs.X[:, 0].tolist() == [0.0, 2.0, 6.0, 8.0, 10.0]

    # disks 0, 3, 6 (held: 3, 6), count written; initial pairs kept where an end is owned
    S = namedtuple("S", ["disk", "n", "initial"])
    s = S(
        np.array([0, 3, 6]), 3, {"a": np.array([1, 3, 0]), "b": np.array([3, 6, 4]), "dmax": np.array([1.0, 2.0, 3.0])}
    )
    lay = ((("disk",), HeldMembers(count="n")), (("initial.a", "initial.b", "initial.dmax"), PairList()))
    c = localize(lay, s, keep, own)
    assert c.disk.tolist() == [1, 3] and c.n == 2
    assert c.initial["a"].tolist() == [0] and c.initial["b"].tolist() == [1] and c.initial["dmax"].tolist() == [1.0]
    only_first = PairList(lambda a, b, loc, owned, data: (loc[a] >= 0) & (loc[b] >= 0))
    c = localize(((("initial.a", "initial.b", "initial.dmax"), only_first),), s, keep, own)
    assert c.initial["dmax"].tolist() == [1.0, 2.0]  # the rule decides: (3, 6) too
    assert localize(((("initial.x", "initial.y"), PairList()),), s, keep, own) is s  # a list the data lack
