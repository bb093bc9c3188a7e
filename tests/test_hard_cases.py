"""Numerical stability on hard contact cases (issue 2, open points O-6, O-17)."""

import subprocess

import numpy as np
import pytest
from test_contact_physics import MAT, head

from polydem_cli.interactions.contact.family import ACC_NCONT

from conftest import polydem_cmd
from helpers import particle, run, system_from_toml

FIXED = '[[boundary]]\nset = "{0}"\nx1 = "fixed"\nx2 = "fixed"\nphi = "fixed"\n'


def test_edge_sliding_along_parallel_edge_force_jumps_but_energy_does_not_grow():
    """Fig. 4.5: a square slides over an equal fixed square under gravity; when the vertical edges
    align the overlap line flips diagonal, n and the e1-force jump.  Bounded, no energy growth."""
    kn, g = 1e6, 1000.0
    delta = g / kn  # equilibrium overlap depth: m g = k_n (delta L) L T with m = L = T = 1
    text = (
        head(1e-5, 0.12, extra='[output]\nobserve = ["B"]')
        + MAT.format(kn=kn, gn=0.0, kt=0.0, mu=0.0)
        + particle("A", "rectangle", center=[0.0, 0.0], size=[1.0, 1.0])
        + particle("B", "rectangle", center=[-0.3, 1.0 - delta], size=[1.0, 1.0], velocity=[5.0, 0.0, 0.0])
        + '[contact]\ntangential = "none"\ninitial_overlap = "allow"\n[body_force]\ngravity = [0.0, -1000.0]\n'
        + FIXED.format("A")
        + '[[boundary]]\nset = "B"\nphi = "fixed"\n'
    )
    sim, h = run(system_from_toml(text), every=1)
    E = h["kinetic"] + h["elastic"] + h["potential"]
    assert np.all(np.isfinite(E))
    assert h["n_contacts"].min() == 1  # stays in contact throughout
    i = int(np.argmin(np.abs(h["u1:B"] - 0.3)))  # edges aligned here
    f1 = h["f1:A"]
    jump = f1[i + 1] - f1[i] if h["u1:B"][i] < 0.3 else f1[i] - f1[i - 1]
    assert abs(jump) > 1.5  # the tangential component of the normal force flips sign ...
    assert np.abs(f1).max() < 0.01 * np.abs(h["f2:A"]).max()  # ... but stays bounded (~ delta / L of f_n)
    assert (E.max() - E[0]) / abs(E[0]) < 1e-6


def test_vertex_on_vertex_impact():
    v = 20.0
    text = (
        head(1e-6, 0.01)
        + MAT.format(kn=1e7, gn=0.0, kt=1e6, mu=0.3)
        + particle("a", center=[0.0, 0.0], sides=4, circumradius=0.5, velocity=[v, 0.0, 0.0])
        + particle("b", center=[1.0001, 0.0], sides=4, circumradius=0.5, velocity=[-v, 0.0, 0.0])
        + '[contact]\ntangential = "coulomb"\n'
    )
    sim, h = run(system_from_toml(text), every=10)
    E = h["kinetic"] + h["elastic"]
    assert h["n_contacts"].max() == 1 and h["n_contacts"][-1] == 0
    assert np.all(np.isfinite(sim.positions()))
    assert np.max(np.abs(E - E[0])) / E[0] < 1e-6
    vel = sim.velocities()
    assert vel[0, 0] == pytest.approx(-v, rel=1e-4) and vel[1, 0] == pytest.approx(v, rel=1e-4)
    assert np.abs(vel[:, 1:]).max() < 1e-9 * v  # symmetric impact: no sideways motion, no spin


@pytest.mark.parametrize(
    "gen",
    [
        'type = "voronoi"\nnx = 6\nny = 5\nq_pg = 0.999\nseed = 11\n',
        'type = "hexagon_packing"\nwidth = 1.27\nrows = 4\nrow_counts = [5, 4]\n',
    ],
)
def test_exactly_touching_specimen_has_no_contacts_and_does_not_move(gen):
    text = (
        head(1e-4, 0.02)
        + MAT.format(kn=1.61e7, gn=0.0, kt=4.74e7, mu=0.294)
        + f'[[particles]]\nname = "s"\nmaterial = "m"\nthickness = 1.0\n{gen}'
        + '[contact]\ntangential = "coulomb"\n'
    )
    system = system_from_toml(text)
    sim, h = run(system, every=10)
    assert system.n >= 18
    assert np.all(h["n_contacts"] == 0)
    assert np.all(h["elastic"] == 0)
    assert np.array_equal(sim.positions(), system.x0)  # zero force: not a single bit moved


def test_specimen_pressed_together_makes_contacts():
    """Counter-check for the test above: the same packing pushed into a plate does make contacts."""
    text = (
        head(1e-5, 0.05)
        + MAT.format(kn=1.61e7, gn=0.0, kt=4.74e7, mu=0.294)
        + '[[particles]]\nname = "s"\nmaterial = "m"\nthickness = 1.0\ntype = "hexagon_packing"\n'
        'width = 1.27\nrows = 3\nrow_counts = [4, 3]\nvelocity = [0.0, -5.0, 0.0]\n'
        + particle("plate", "rectangle", center=[1.9, 0.0], size=[8.0, 0.5], place="below:s")
        + '[contact]\ntangential = "coulomb"\n'
        + FIXED.format("plate")
    )
    sim, h = run(system_from_toml(text), every=10)
    assert h["n_contacts"].max() >= 4


def test_deep_penetration_vertex_exits_far_side():
    """A fast needle goes right through a soft block: more than two boundary crossings, overlap
    line = farthest crossing points (thesis §4.2.2); no crash, no NaN, bounded energy."""
    text = (
        head(1e-6, 0.004)
        + MAT.format(kn=1e5, gn=0.0, kt=0.0, mu=0.0)
        + particle("block", "rectangle", center=[0.0, 0.0], size=[1.0, 1.0])
        + particle(
            "needle", "polygon", vertices=[[-3.0, 0.05], [-3.0, -0.05], [-0.6, 0.0]], velocity=[1000.0, 0.0, 0.0]
        )
        + '[contact]\ntangential = "none"\n'
        + FIXED.format("block")
    )
    sim, h = run(system_from_toml(text), every=10)  # (in-process: no stability stop)
    x = sim.positions()
    assert np.all(np.isfinite(x)) and np.all(np.isfinite(h["kinetic"]))
    assert x[1, 0] > 1.0  # the needle's centroid passed the block
    assert h["max_overlap_ratio"].max() > 0.5  # deep penetration happened
    E = h["kinetic"] + h["elastic"]
    assert E.max() < 1.01 * E[0] and E[-1] > 0.98 * E[0]


CONTAINED = (
    head(1e-5, 0.001)
    + MAT.format(kn=1e6, gn=0.0, kt=1e6, mu=0.3)
    + particle("big", "rectangle", center=[0.0, 0.0], size=[4.0, 4.0])
    + particle("small", center=[0.3, -0.2], sides=3, circumradius=0.4, velocity=[1.0, 0.0, 0.0])
    + '[contact]\ntangential = "coulomb"\ninitial_overlap = "allow"\non_containment = "{policy}"\n'
    + '[stability]\nmax_overlap_ratio = 2.0\n'
    + FIXED.format("big")
)


def test_polygon_inside_another_zero_force_warning_no_nan():
    sim, h = run(system_from_toml(CONTAINED.format(policy="warn")), every=10)
    x = sim.positions()
    assert np.all(np.isfinite(x))
    # policy: the gradient of A_n vanishes, so no force: the small one moves on unaffected
    assert x[1, 0] == pytest.approx(sim.system.x0[1, 0] + 0.001, rel=1e-12)
    assert sim.bundle("contact").acc[ACC_NCONT] > 0  # the contained pair-steps are counted


def test_containment_warning_and_abort_through_the_cli(tmp_path):
    for policy, code, text in (
        ("warn", 0, "warning: particles 0 and 1: one polygon lies entirely inside"),
        ("abort", 1, "one polygon lies entirely inside the other"),
    ):
        f = tmp_path / f"c_{policy}.toml"
        f.write_text(CONTAINED.format(policy=policy))
        r = subprocess.run(
            polydem_cmd() + ["run", str(f), "-o", str(tmp_path / f"{policy}.h5")], capture_output=True, text=True
        )
        assert r.returncode == code, r.stderr
        assert text in r.stderr
        assert "Traceback" not in r.stderr
