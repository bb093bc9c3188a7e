"""Touching is a geometric fact for every generator: particles with a gap, meeting at a corner or
overlapping share no edge and get no bond; neighbours that meet along an edge do, with that edge's length
(the beam height of thesis §5.1.2)."""

import subprocess

import numpy as np
import pytest

from polydem_cli.geometry.polygon import rectangle
from polydem_cli.geometry.specimens import hexagon_packing, voronoi_specimen
from polydem_cli.geometry.touching import touching_edges

from conftest import SCEN, polydem_cmd


def test_two_squares_touch_along_the_common_part_of_their_edges_only():
    a = rectangle((0.0, 0.0), (1.0, 1.0))
    for dy, length in ((0.0, 1.0), (0.5, 0.5), (0.9, 0.1)):  # B shifted along the common line
        pairs, lengths, edges = touching_edges([a, rectangle((1.0, dy), (1.0, 1.0))])
        assert pairs.tolist() == [[0, 1]]
        assert lengths[0] == pytest.approx(length, rel=1e-12)
        assert np.allclose(edges[0][:, 0], 0.5)  # on the line x = 0.5
        assert sorted(edges[0][:, 1]) == pytest.approx([dy - 0.5, 0.5] if dy > 0 else [-0.5, 0.5])
    for b in (
        rectangle((1.0 + 1e-6, 0.0), (1.0, 1.0)),  # gap of 1e-6
        rectangle((1.0, 1.0), (1.0, 1.0)),  # corner on corner
        rectangle((0.9, 0.0), (1.0, 1.0)),  # overlap of 0.1
        rectangle((0.0, 0.0), (1.0, 1.0)),  # on top of each other
    ):
        assert len(touching_edges([a, b])[0]) == 0


@pytest.mark.parametrize("sides", [6, 24])
def test_hexagon_packing_touches_only_when_neighbours_meet_along_a_flat(sides):
    w = 1.27
    touching = hexagon_packing(w, [5, 4], 4, sides=sides)
    # 4 rows of 5/4: 4+3+4+3 pairs along rows, 2 * 4 between each of the 3 row pairs
    assert len(touching.shared_pairs) == 14 + 3 * 8
    # the flat of a regular polygon of width w across flats: w tan(pi / sides)
    assert np.allclose(touching.shared_lengths, w * np.tan(np.pi / sides), rtol=1e-9)
    cen = np.array([v.mean(axis=0) for v in touching.vertices])
    mid = 0.5 * (cen[touching.shared_pairs[:, 0]] + cen[touching.shared_pairs[:, 1]])
    assert np.allclose(touching.shared_edges.mean(axis=1), mid, atol=1e-12)  # centred between the centroids
    for spacing in (1.5, 1.2701, 1.2699, 1.0):  # gaps (the reported 1.5 cm case, a hair apart) and overlaps
        assert len(hexagon_packing(w, [5, 4], 4, spacing=spacing, sides=sides).shared_pairs) == 0


def test_hexagon_packing_with_defects_does_not_bond_across_the_hole():
    full = hexagon_packing(1.27, [5, 4], 4)
    holed = hexagon_packing(1.27, [5, 4], 4, missing=[[1, 1]])
    assert len(holed.shared_pairs) == len(full.shared_pairs) - 6  # an interior nut has six neighbours


def test_voronoi_shared_edges_are_the_geometric_ones():
    """The tessellation's ridges (the generator) against the polygons' geometry (independent)."""
    for seed, q in ((1, 0.999), (7, 0.5), (3, 0.0)):
        v = voronoi_specimen(9, 7, h_pg=2.0, q_pg=q, seed=seed)
        pairs, lengths, _ = touching_edges(v.vertices)
        if q == 0.0:  # a square grid: the cells' corners meet four at a time, diagonal neighbours only there
            assert len(pairs) == 8 * 7 + 9 * 6
        keep = v.shared_lengths > 1e-6  # edges shorter than the tolerance of a 2 cm cell's geometry
        assert np.array_equal(pairs, v.shared_pairs[keep])
        assert np.allclose(lengths, v.shared_lengths[keep], rtol=1e-6)


def test_bonds_refuse_a_packing_with_gaps_and_check_reports_none(tmp_path):
    """The reported case: spacing 1.5 cm > width 1.27 cm bonded 0.23 cm gaps with beams of 1.5 cm."""
    glued = str(SCEN / "ch7" / "nuts_glued_small.toml")
    r = subprocess.run(
        polydem_cmd() + ["check", glued, "--set", "particles.0.spacing=1.5"], capture_output=True, text=True
    )
    assert r.returncode == 2, r.stdout + r.stderr
    assert "no initially touching particle pairs" in r.stderr and "Traceback" not in r.stderr
    pile = str(SCEN / "demo_hex_pile.toml")
    r = subprocess.run(
        polydem_cmd() + ["check", pile, "--set", "particles.0.spacing=1.5"], capture_output=True, text=True
    )
    assert r.returncode == 0, r.stdout + r.stderr
    assert "touching pairs" not in r.stdout
    r = subprocess.run(polydem_cmd() + ["check", pile], capture_output=True, text=True)
    assert "38 particles, 89 touching pairs" in r.stdout
