"""Cohesive frictionless disks (Luding & Herrmann) through the unchanged time loop: the disk family
(interactions/disks/) against analytic references — contact duration and restitution of (LH 1.8), the
force path of (LH 1.6) from an independent implementation here, disk–wall contacts, the energy balance of a
compressed cohesive packing, a checkpoint round trip, and refused input naming its key."""

import math

import numpy as np
import pytest

from polydem_cli.engine.simulation import Simulation
from polydem_cli.scenario.spec import ScenarioError

from helpers import run, system_from_toml

R = 0.1  # cm
RHO = 2.0  # g/cm^3 (the paper's 2000 kg/m^3)
M = 4.0 / 3.0 * math.pi * RHO * R**3  # sphere mass, g
K2 = 1.0e8  # g/s^2 = 1e5 N/m (the paper)


def _disk(name, center, velocity=(0.0, 0.0, 0.0), r=R):
    return f"""
[[particles]]
name = "{name}"
material = "glass"
thickness = 100.0
type = "disks"
centers = [[{center[0]!r}, {center[1]!r}]]
radii = [{r!r}]
sphere_mass = true
velocity = [{velocity[0]!r}, {velocity[1]!r}, {velocity[2]!r}]
"""


def _scene(body, dt, end, law, extra="", integrator="gear5"):
    return f"""
[scenario]
title = "disk test"
[time]
integrator = "{integrator}"
dt = {dt!r}
end_time = {end!r}
[output]
history_every = 1
{extra}
[materials.glass]
density = {RHO!r}
{body}
[disks]
{law}
"""


def _duration(h, col="disk_contacts"):
    t = h["time"][h[col] > 0]
    dt = h["time"][1] - h["time"][0]
    return t.max() - t.min() + dt


@pytest.mark.parametrize("integrator", ["gear5", "verlet1"])
@pytest.mark.parametrize("gamma0", [0.0, 100.0, 500.0])  # g/s: 0, 0.1, 0.5 kg/s as in the paper
def test_binary_collision_lasts_tc_and_restitutes_as_lh_1_8(gamma0, integrator):
    """k_1 = k_2, k_c = 0: a damped half oscillation of the reduced mass m_12 = m/2, t_c = pi/omega (LH 1.8)
    within 1 %, and the speed after the collision is exp(-eta_0 t_c) of the speed before it; also with the
    one-evaluation Verlet (the viscous force then sees the predicted velocity)."""
    v = 10.0
    body = _disk("a", (0.0, 0.0), (v, 0.0, 0.0)) + _disk("b", (2 * R + 1e-4, 0.0), (-v, 0.0, 0.0))
    law = f"k_1 = {K2!r}\nk_2 = {K2!r}\ngamma_0 = {gamma0!r}"
    sim, h = run(system_from_toml(_scene(body, 2.0e-8, 5.0e-5, law, integrator=integrator)))
    m12 = M / 2
    eta = gamma0 / (2 * m12)
    tc = math.pi / math.sqrt(K2 / m12 - eta * eta)
    assert _duration(h) == pytest.approx(tc, rel=0.01)
    ek0, ek1 = h["kinetic"][0], h["kinetic"][-1]
    assert math.sqrt(ek1 / ek0) == pytest.approx(math.exp(-eta * tc), rel=2e-3)
    assert h["disk_contacts"][-1] == 0  # separated again


def _lh_force(delta, dmax, k1, k2, kc):
    """(LH 1.6) written out here, independently of interactions/disks/law.py."""
    d0 = (1 - k1 / k2) * dmax
    return min(k1 * delta, max(k2 * (delta - d0), -kc * delta))


def test_cohesive_contact_follows_the_hysteretic_path_and_dissipates_its_area():
    """A disk thrown at a fixed one with k_1 = k_2/2, k_c = k_2: loading along k_1, unloading along k_2,
    into attraction (largest -k_c delta_min at delta_min = (k2-k1)/(k2+kc) delta_max) and out along
    -k_c delta.  The recorded force (reaction of the fixed disk) equals (LH 1.6) at every step, and the
    kinetic energy left after separation is what the closed path returns (energy conserved, gamma_0 = 0)."""
    k1, k2, kc = 0.5 * K2, K2, K2
    v = 5.0
    body = _disk("a", (0.0, 0.0), (v, 0.0, 0.0)) + _disk("b", (2 * R + 1e-5, 0.0))
    body += '\n[[boundary]]\nset = "b"\nx1 = "fixed"\nx2 = "fixed"\nphi = "fixed"\n'
    law = f"k_1 = {k1!r}\nk_2 = {k2!r}\nk_c = {kc!r}"
    sim, h = run(system_from_toml(_scene(body, 1.0e-8, 6.0e-5, law, 'observe = ["a"]')))
    delta = 2 * R - ((2 * R + 1e-5) - h["u1:a"])  # disk a starts at x1 = 0
    f = -h["f1:b"]
    on = (delta > 0) & (h["disk_contacts"] > 0)
    dmax = np.maximum.accumulate(np.where(on, delta, 0.0))
    expect = np.array([_lh_force(d, m, k1, k2, kc) for d, m in zip(delta[on], dmax[on])])
    scale = k1 * dmax.max()
    assert np.max(np.abs(f[on] - expect)) < 1e-6 * scale
    # every branch was visited, and the attraction reached its analytic extreme
    dm = dmax.max()
    assert dm == pytest.approx(v * math.sqrt(M / k1), rel=1e-3)  # all kinetic energy into k_1 loading
    dmin = (k2 - k1) / (k2 + kc) * dm
    assert f[on].min() == pytest.approx(-kc * dmin, rel=2e-3)
    assert h["attractive_contacts"].max() == 1
    # after separation: kinetic = initial - area enclosed by the path (E(dmax, dmax) returned)
    d0 = (1 - k1 / k2) * dm
    returned = -0.5 * kc * dmin**2 + 0.5 * k2 * ((dm - d0) ** 2 - (dmin - d0) ** 2)
    assert h["disk_contacts"][-1] == 0
    assert h["kinetic"][-1] == pytest.approx(returned, rel=2e-3)
    assert h["dissipated_disks"][-1] == pytest.approx(h["kinetic"][0] - returned, rel=2e-3)
    e = h["energy_total"]
    assert np.max(np.abs(e - e[0])) < 1e-4 * e[0]


@pytest.mark.parametrize("memory", ["contact", "pair"])
def test_delta_max_across_an_opening_is_reset_or_kept_as_the_option_says(memory):
    """A pair loaded to delta_max along k_1, opened, and closed again to 0.3 and 0.75 delta_max (k_c = 0,
    k_1 = k_2/2, so delta_0 = delta_max/2): with the default 'contact' memory the second closing is a fresh
    loading along k_1; with 'pair' (the option) the pair remembers delta_max, exerts no force below delta_0
    and reloads along k_2 above it (LH 1.6, written out in _lh_force)."""
    from polydem_cli.engine.simulation import Simulation
    from polydem_cli.interactions.disks.kernel import accept_history, disk_pass

    k1, k2, gap = 0.5 * K2, K2, 1e-5
    body = _disk("a", (0.0, 0.0)) + _disk("b", (2 * R + gap, 0.0))
    law = f'k_1 = {k1!r}\nk_2 = {k2!r}\nbuffer = 0.05\ndelta_max_memory = "{memory}"'
    sim = Simulation(system_from_toml(_scene(body, 1e-8, 1e-6, law)))
    sim.initialize()
    fam = sim.bundle("disks")
    x, v = sim.x.copy(), np.zeros_like(sim.v)

    def repulsion(delta):  # disk a moved towards b until the overlap is delta; the force pushing a back
        x[0, 0] = gap + delta
        F = np.zeros_like(x)
        disk_pass(True, x, v, 1e-8, fam.p, fam.hold, fam.hnew, fam.w, F, fam.stats)
        accept_history(fam.hnew, fam.hold, fam.w.perm)
        return -F[0, 0]

    dm = 2e-4
    for d in np.linspace(0.0, dm, 5)[1:]:
        assert repulsion(d) == pytest.approx(k1 * d, rel=1e-12)  # first loading along k_1
    assert repulsion(-1e-4) == 0.0  # open (within the pair list's buffer)
    for d in (0.3 * dm, 0.75 * dm):
        expect = k1 * d if memory == "contact" else _lh_force(d, dm, k1, k2, 0.0)
        assert repulsion(d) == pytest.approx(expect, rel=1e-12, abs=1e-12 * k1 * dm)
    if memory == "pair":
        assert _lh_force(0.3 * dm, dm, k1, k2, 0.0) == 0.0 and _lh_force(0.75 * dm, dm, k1, k2, 0.0) > 0.0


def _wall(name, side, position, extent, extra=""):
    return f"""
[[particles]]
name = "{name}"
material = "glass"
thickness = 100.0
type = "wall"
side = "{side}"
position = {position!r}
extent = [{extent[0]!r}, {extent[1]!r}]
{extra}
[[boundary]]
set = "{name}"
x1 = "fixed"
x2 = "fixed"
phi = "fixed"
"""


def test_disk_bounces_off_a_fixed_wall_in_the_contact_time_of_its_own_mass():
    """Disk–wall contact uses the same law with the wall normal (open point O-18): a disk dropped on the
    bottom wall stays in contact pi/sqrt(k_2/m) (the wall does not move) and leaves with its speed."""
    body = _disk("a", (0.0, R + 1e-5), (0.0, -3.0, 0.0)) + _wall("floor", "bottom", 0.0, (-1.0, 1.0))
    sim, h = run(system_from_toml(_scene(body, 2.0e-8, 6.0e-5, f"k_1 = {K2!r}\nk_2 = {K2!r}")))
    assert _duration(h, "wall_contacts") == pytest.approx(math.pi / math.sqrt(K2 / M), rel=0.01)
    assert h["kinetic"][-1] == pytest.approx(h["kinetic"][0], rel=1e-4)
    assert sim.velocities()[0, 1] == pytest.approx(3.0, rel=1e-4)


BOX = """
[[particles]]
name = "grains"
material = "glass"
thickness = 100.0
type = "random_disks"
count = 28
radius_min = 0.05
radius_max = 0.15
box = [0.0, 0.0, 1.2, 1.2]
seed = 3
sphere_mass = true
velocity = [0.0, 0.0, 0.0]
"""


def _box_scene(dt=5e-7, end=4e-3, integrator="gear5"):
    walls = _wall("left", "left", 0.0, (0.0, 1.2)) + _wall("bottom", "bottom", 0.0, (0.0, 1.2))
    walls += _wall("right", "right", 1.2, (0.0, 1.2))
    walls += """
[[particles]]
name = "top"
material = "glass"
thickness = 100.0
type = "wall"
side = "top"
position = 1.2
extent = [0.0, 1.2]
[[boundary]]
set = "top"
x1 = "fixed"
x2 = {velocity = -60.0}
phi = "fixed"
"""
    law = f"k_1 = {0.5 * K2!r}\nk_2 = {K2!r}\nk_c = {K2!r}\ngamma_0 = 100.0\ngamma_b = 10.0"
    return _scene(BOX + walls, dt, end, law, integrator=integrator)


@pytest.mark.parametrize("integrator", ["gear5", "verlet1"])
def test_compressed_cohesive_packing_keeps_its_energy_balance(integrator):
    """28 cohesive disks in a box compressed by the top wall (prescribed velocity): the work of the wall's
    support = kinetic + stored + dissipated energy (hysteresis exactly, viscous and background damping by the
    trapezoidal rule), and the top wall carries a compressive reaction at the end."""
    sim, h = run(system_from_toml(_box_scene(integrator=integrator)), every=10)
    w = h["external_work"][-1]
    assert w > 0 and h["wall_contacts"][-1] > 0 and h["disk_contacts"][-1] > 10
    e = h["energy_total"]
    assert np.max(np.abs(e - e[0])) < 2e-3 * w
    assert h["f2:top"][-1] < 0  # the packing pushes the top wall up: the support pulls down (reaction)


def test_one_evaluation_verlet_follows_the_two_evaluation_trajectory_of_disks():
    """verlet1 evaluates once per step, at the predicted state, where verlet evaluates there and again at the
    corrected state (engine/integrators.py).  Disk forces and δ_max depend on the positions and the predicted
    velocity only, so the compressed cohesive box follows the same trajectory bit for bit (at half the cost:
    docs/performance.md)."""
    a, ha = run(system_from_toml(_box_scene(end=2e-3, integrator="verlet")), every=10)
    b, hb = run(system_from_toml(_box_scene(end=2e-3, integrator="verlet1")), every=10)
    assert ha["disk_contacts"][-1] > 10
    np.testing.assert_array_equal(b.positions(), a.positions())
    np.testing.assert_array_equal(hb["disk_contacts"], ha["disk_contacts"])


@pytest.mark.parametrize("buffer", [None, 0.5])
def test_buffered_pair_list_misses_no_contact(buffer):
    """The compressed box with the buffered pair list (default buffer 0.2 x median radius, rebuilt when a disk
    or the moving wall has gone half of it; and a buffer of 0.5 cm that lists every pair, beyond the initial
    capacity, so the buffers must grow) against a search at every evaluation (buffer = 0): the same contacts,
    the same trajectory to round-off (only the order of the force sums differs)."""

    def scene(b):
        text = _box_scene(end=2e-3)
        return text if b is None else text.replace("gamma_b = 10.0", f"gamma_b = 10.0\nbuffer = {b!r}")

    ref, href = run(system_from_toml(scene(0.0)), every=10)
    sim, h = run(system_from_toml(scene(buffer)), every=10)
    np.testing.assert_array_equal(h["disk_contacts"], href["disk_contacts"])
    np.testing.assert_array_equal(h["wall_contacts"], href["wall_contacts"])
    assert href["disk_contacts"][-1] > 10
    np.testing.assert_allclose(sim.positions(), ref.positions(), rtol=0, atol=1e-11)
    builds = {f.name: f.observables(b) for f, b in sim.family_bundles()}["disks"]["disk_list_builds"]
    builds_ref = {f.name: f.observables(b) for f, b in ref.family_bundles()}["disks"]["disk_list_builds"]
    assert builds_ref >= 2 * 4000  # two evaluations per step
    assert builds < builds_ref / 20


def test_disk_history_survives_a_checkpoint_bit_for_bit():
    s = system_from_toml(_box_scene(end=2e-3))
    a = Simulation(s)
    a.initialize()
    rows = np.zeros((100, a.ncols))
    while a.step < 2000:
        a.advance(2000, rows, 1000)
    st = a.state()
    b = Simulation(system_from_toml(_box_scene(end=2e-3)))
    b.initialize()
    b.restore(st)
    for sim in (a, b):
        while sim.step < 4000:
            sim.advance(4000, rows, 1000)
    assert np.array_equal(a.nord, b.nord)
    assert a.state()["disk_dmax"].tolist() == b.state()["disk_dmax"].tolist()


@pytest.mark.parametrize(
    "change, key",
    [
        (("radii = [0.1]", "radii = [0.0]"), "particles[0].radii"),
        (("k_1 = 100000000.0", "k_1 = 200000000.0"), "disks.k_1"),
        (("k_c = 0.0", "k_c = -1.0"), "disks.k_c"),
        (("sphere_mass = true\n", 'sphere_mass = true\nsides = 6\n'), "particles[0].sides"),
        (("[disks]", "[contact]\n[disks]"), "contact"),
        (("[disks]\nk_1 = 100000000.0\nk_2 = 100000000.0\nk_c = 0.0", ""), "particles[0].type"),
    ],
)
def test_bad_disk_input_is_refused_with_its_key(change, key):
    text = _scene(_disk("a", (0.0, 0.0)), 1e-8, 1e-6, f"k_1 = {K2!r}\nk_2 = {K2!r}\nk_c = 0.0")
    assert change[0] in text
    with pytest.raises(ScenarioError) as e:
        system_from_toml(text.replace(change[0], change[1]))
    assert e.value.key == key, str(e.value)


def test_disk_parameter_on_a_polygon_group_is_refused():
    text = """
[scenario]
title = "t"
[time]
dt = 1e-6
end_time = 1e-5
[materials.m]
density = 1.0
[[particles]]
name = "p"
material = "m"
thickness = 1.0
type = "regular_polygon"
center = [0.0, 0.0]
sides = 6
circumradius = 1.0
sphere_mass = true
"""
    with pytest.raises(ScenarioError) as e:
        system_from_toml(text)
    assert e.value.key == "particles[0].sphere_mass"


def test_a_long_advance_runs_on_a_small_stack(tmp_path):
    """One call of Simulation.advance over 20,000 steps on a thread with a 4 MiB stack (a subprocess, so that
    a crash fails only this test): the compiled loop is entered in bounded chunks; entered once for all
    steps, the composed family tuple used about 1.4 kB of stack per step and the run segfaulted."""
    import subprocess
    import sys
    import textwrap

    body = _disk("a", (0.0, 0.0), (5.0, 0.0, 0.0)) + _disk("b", (2 * R + 1e-5, 0.0))
    toml = tmp_path / "pair.toml"
    toml.write_text(_scene(body, 1e-8, 2.0e-4, f"k_1 = {K2!r}\nk_2 = {K2!r}"))
    code = textwrap.dedent(
        f"""
        import threading, tomllib, numpy as np
        from polydem_cli.scenario.load import validate
        from polydem_cli.scenario.build import build_system
        from polydem_cli.engine.simulation import Simulation
        s = build_system(validate(tomllib.loads(open({str(toml)!r}).read()), "t", ()), "t")
        sim = Simulation(s)
        sim.initialize()
        rows = np.zeros((4, sim.ncols))
        sim.advance(sim.step, rows, 10**9)  # compile on the main thread
        threading.stack_size(4 << 20)
        t = threading.Thread(target=lambda: sim.advance(20000, rows, 10**9))
        t.start()
        t.join()
        print(sim.step)
        """
    )
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert r.returncode == 0, r.stderr[-2000:]
    assert r.stdout.split()[-1] == "20000"


def test_disk_box_smoke_runs_and_reports(tmp_path):
    """scenarios/lh/smoke_disk_compression.toml through `polydem run` (shortened) and `polydem report`:
    the top wall meets the packing, contacts form, the energy balance holds and the report draws."""
    import subprocess

    from conftest import SCEN, polydem_cmd

    out = tmp_path / "box.h5"
    r = subprocess.run(
        polydem_cmd()
        + ["run", str(SCEN / "lh" / "smoke_disk_compression.toml"), "-o", str(out), "-q"]
        + ["--set", "time.end_time=0.016", "--set", "output.frame_interval=0.008"],
        capture_output=True,
        text=True,
    )
    assert r.returncode == 0, r.stderr[-2000:]
    from polydem_cli.io.hdf5 import read_history

    cols, d = read_history(out)
    h = {c: d[:, j] for j, c in enumerate(cols)}
    assert h["disk_contacts"][-1] > 100 and h["wall_contacts"][-1] > 10
    assert h["f2:top"][-1] < 0  # compressed: the support holds the top wall against the packing
    assert np.allclose(h["wall_force:top"], -h["f2:top"], rtol=1e-12, atol=0)  # the disks are all it feels
    assert h["wall_face:top"][-1] == pytest.approx(6.0 - 100.0 * 0.016, rel=1e-12)
    e = h["energy_total"]
    assert np.max(np.abs(e - e[0])) < 1e-2 * h["external_work"][-1]
    rep = subprocess.run(
        polydem_cmd() + ["report", str(out), "--out", str(tmp_path / "rep")], capture_output=True, text=True
    )
    assert rep.returncode == 0, rep.stderr[-2000:]
    assert list((tmp_path / "rep").glob("*.png"))


def test_a_run_continues_from_the_final_state_of_another(tmp_path):
    """[initial_state]: a loading run starts from the final positions, velocities and delta_max history of an
    earlier run (the relaxed packing): its first state equals that run's last, and a contact loaded on k_1 in
    the first run is unloaded along k_2 in the second (its delta_max came with it)."""
    import subprocess

    from conftest import polydem_cmd

    k1, k2 = 0.5 * K2, K2
    body = _disk("a", (0.0, 0.0), (2.0, 0.0, 0.0)) + _disk("b", (2 * R + 1e-5, 0.0))
    body += '\n[[boundary]]\nset = "b"\nx1 = "fixed"\nx2 = "fixed"\nphi = "fixed"\n'
    law = f"k_1 = {k1!r}\nk_2 = {k2!r}"
    first = tmp_path / "first.toml"
    first.write_text(_scene(body, 1e-8, 3.0e-5, law, 'observe = ["a"]'))  # ends after the peak, unloading
    r = subprocess.run(
        polydem_cmd() + ["run", str(first), "-o", str(tmp_path / "first.h5"), "-q"], capture_output=True, text=True
    )
    assert r.returncode == 0, r.stderr[-2000:]
    second = tmp_path / "second.toml"
    second.write_text(
        first.read_text()
        .replace("[disks]", '[initial_state]\nfile = "first.h5"\n[disks]')
        .replace("end_time = 3e-05", "end_time = 4e-05")
    )
    s1 = system_from_toml(first.read_text())
    s2 = build_system_at(second)
    from polydem_cli.io.hdf5 import read_frames

    _, _, xs, vs = read_frames(tmp_path / "first.h5")
    assert np.array_equal(s2.x0, xs[-1]) and np.array_equal(s2.v0, vs[-1])
    assert not np.array_equal(s1.x0, s2.x0)
    sim, h = run(s2)
    delta = 2 * R - (s2.x0[1, 0] - s2.x0[0, 0] - h["u1:a"])
    f = -h["f1:b"]
    on = delta > 0
    assert on.sum() > 50 and h["disk_contacts"][-1] == 0  # unloaded to separation
    # unloading along k_2 (not k_1): f = k_2 (delta - delta_0), delta_0 = (1 - k1/k2) delta_max
    push = on & (f > 1e-3 * f.max())  # below delta_0 the contact carries no force (k_c = 0)
    assert push.sum() > 50
    slope = np.polyfit(delta[push], f[push], 1)[0]
    assert slope == pytest.approx(k2, rel=1e-3)
    # a bad initial-state file is refused with its key
    bad = tmp_path / "bad.toml"
    bad.write_text(second.read_text().replace('file = "first.h5"', 'file = "nothere.h5"'))
    with pytest.raises(ScenarioError) as e:
        build_system_at(bad)
    assert e.value.key == "initial_state.file"


def build_system_at(path):
    from polydem_cli.scenario.build import build_system
    from polydem_cli.scenario.load import load_scenario

    sc, _ = load_scenario(path)
    return build_system(sc, str(path))
