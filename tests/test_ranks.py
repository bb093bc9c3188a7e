"""A run decomposed over 2 MPI ranks (engine/distributed.py) against the same run on one process: contacts and
bonds across the subdomain boundary, bonds failing across it.  The ranks are started with the ``mpiexec`` of the
MPICH wheel the test extra installs (no system MPI)."""

from __future__ import annotations

import json
import os
import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from polydem_cli.engine.simulation import EngineError, Simulation
from polydem_cli.errors import DecompositionError
from polydem_cli.scenario.build import build_system
from polydem_cli.scenario.load import load_scenario
from polydem_cli.solvers.explicit_history import history_columns

ROOT = Path(__file__).resolve().parents[1]
MPIEXEC = Path(sys.executable).with_name("mpiexec")
CONCRETE = str(ROOT / "scenarios/bench_concrete_40.toml")
HEX = str(ROOT / "scenarios/bench_dense_hexagons.toml")
#: a 12 x 12 concrete panel pulled fast (1 m/s at once): beams fail within a few hundred steps, contact after
FAST_PANEL = [
    "particles.0.nx=12",
    "particles.0.ny=12",
    "boundary.0.x2.velocity=100.0",
    "boundary.0.x2.acceleration=1e12",
    "output.history_every=10",
]
#: a dense, pre-compressed packing of 144 hexagons: every neighbour in contact, all pushing apart
DENSE = ["particles.0.rows=12", "particles.0.row_counts=[12, 12]", "output.history_every=10"]
#: particle-base friction on the dense packing
BASE = ["base.gravity=981.0", "materials.steel.k_u=8.35e5", "materials.steel.mu_u=0.258"]
#: nuts between two loading plates (polygon contact with plates does not run decomposed yet)
NUTS = str(ROOT / "scenarios/ch6/nuts_small.toml")


def serial(path, overrides, steps):
    sc, _ = load_scenario(path, overrides)
    s = build_system(sc, path)
    sim = Simulation(s)
    sim.initialize()
    rows = np.zeros((steps // s.history_every + 2, sim.ncols))
    n = sim.advance(steps, rows, s.history_every)
    return s, sim, rows[:n]


def on_ranks(tmp_path, path, overrides, steps, ranks=2):
    out = tmp_path / "ranks.npz"
    cmd = [str(MPIEXEC), "-n", str(ranks), sys.executable, str(ROOT / "tests/ranks_run.py"), str(out), path, str(steps)]
    cmd += overrides
    env = dict(os.environ, NUMBA_NUM_THREADS="1", OMP_NUM_THREADS="1")
    res = subprocess.run(cmd, capture_output=True, text=True, env=env, timeout=900)
    assert res.returncode == 0, res.stderr[-3000:]
    return dict(np.load(out))


def same_rows(a, b, tol=1e-10, columns=None, length=None):
    """Equal to round-off: the ranks sum their rows in another order; energy_total (column 7) is a small difference
    of large energies and is compared with the size of the energies.

    With ``columns`` (the history's column names) and ``length`` (the specimen's size), each measure is compared with
    the size of its kind in the scene rather than with its own largest value: the sets' forces (f1, f2) with the
    largest force on any set, their moments c with that force times ``length``, their displacements (u1, u2) with the
    largest displacement and their rotations phi with that over ``length``, the energies and works with the largest
    energy.  A face held by a prescribed pressure carries a reaction some 10⁻⁴ of the forces between its
    particles, a sum of forces of either sign: the summation order moves it in the last bits of those forces, not
    of itself."""
    assert a.shape == b.shape
    scale = np.maximum(np.abs(b).max(axis=0), 1e-300)
    energy = [2, 3, 4, 5, 6, 7]
    if columns is not None:
        kind = {j: c.partition(":")[0] for j, c in enumerate(columns) if ":" in c}
        energy += [j for j, c in enumerate(columns) if "work" in c or c.startswith(("elastic", "dissipated"))]

        def big(*kinds):
            js = [j for j, k in kind.items() if k in kinds]
            return float(np.abs(b[:, js]).max()) if js else 0.0

        force, disp = big("f1", "f2"), big("u1", "u2")
        for j, k in kind.items():
            ref = {"f1": force, "f2": force, "u1": disp, "u2": disp}.get(k)
            if length is not None:
                ref = {"c": force * length, "phi": disp / length}.get(k, ref)
            if ref is not None:
                scale[j] = max(scale[j], ref)
    scale[energy] = np.maximum(scale[energy], max(scale[energy].max(), 1e-300) if columns is not None else 0.0)
    scale[7] = max(scale[2], scale[3], scale[6], 1e-300)
    rel = np.abs(a - b).max(axis=0) / scale
    assert rel.max() < tol, (np.flatnonzero(rel >= tol), rel.max())


@pytest.mark.skipif(not MPIEXEC.exists(), reason="the mpich wheel (test extra) is not installed")
def test_bonds_failing_across_the_boundary_as_on_one_process(tmp_path):
    steps = 6000
    s, sim, rows = serial(CONCRETE, FAST_PANEL, steps)
    got = on_ranks(tmp_path, CONCRETE, FAST_PANEL, steps)
    d = sim.bundle("bonds").h.d
    p = sim.bundle("bonds").p
    across = got["owner"][p.a] != got["owner"][p.b]
    # the test means something: beams across the boundary, some of them failed, contacts made
    assert across.sum() >= 5
    assert (d[across] >= 1.0).sum() >= 1, "no bond failed across the boundary: pull longer"
    assert rows[-1, 13] > 0  # n_contacts (failed beams hand their pairs over to contact)
    # each particle's force sum is in the serial order: positions, velocities and damage equal bit for bit
    np.testing.assert_array_equal(got["x"], sim.nord[:, :, 0])
    np.testing.assert_array_equal(got["v"], sim.nord[:, :, 1] / sim.dt)
    np.testing.assert_array_equal(got["d"], d)
    same_rows(got["rows"], rows)


@pytest.mark.skipif(not MPIEXEC.exists(), reason="the mpich wheel (test extra) is not installed")
def test_a_ramped_lateral_pressure_on_two_ranks_as_on_one_process(tmp_path):
    """The fast panel under a lateral pressure raised over 1,250 steps ([[loads]] pressure, ramp_time): the ramp's
    blocks counted from step 0 on every rank, each particle's load on its owner only — bit for bit the serial
    run."""
    steps = 2000
    over = FAST_PANEL + [
        'loads=[{set = "specimen.left", pressure = 2e7, ramp_time = 5e-4}, '
        '{set = "specimen.right", pressure = 2e7, ramp_time = 5e-4}]'
    ]
    s, sim, rows = serial(CONCRETE, over, steps)
    assert s.ext_ramp is not None and np.abs(s.ext_ramp).max() > 0
    got = on_ranks(tmp_path, CONCRETE, over, steps)
    np.testing.assert_array_equal(got["x"], sim.nord[:, :, 0])
    np.testing.assert_array_equal(got["v"], sim.nord[:, :, 1] / sim.dt)
    same_rows(got["rows"], rows)


@pytest.mark.skipif(not MPIEXEC.exists(), reason="the mpich wheel (test extra) is not installed")
def test_contacts_across_the_boundary_as_on_one_process(tmp_path):
    steps = 300
    s, sim, rows = serial(HEX, DENSE, steps)
    got = on_ranks(tmp_path, HEX, DENSE, steps)
    c = sim.bundle("contact")
    m = int(c.hold.meta[0])
    a, b = c.hold.a[:m], c.hold.b[:m]
    assert (got["owner"][a] != got["owner"][b]).sum() >= 5  # contacts with tangential history across the cut
    x = sim.nord[:, :, 0]
    assert np.abs(x - s.x0).max() > 1e-4  # the packing has moved
    np.testing.assert_allclose(got["x"], x, rtol=0, atol=1e-12 * np.abs(x).max())
    same_rows(got["rows"], rows)


@pytest.mark.skipif(not MPIEXEC.exists(), reason="the mpich wheel (test extra) is not installed")
def test_base_friction_on_two_ranks_as_on_one_process(tmp_path):
    """The dense packing sliding apart on a base plate: each particle's base friction (its Gauss points' plastic
    slips) evaluated on its owner only; with a 50 µm margin the packing is re-cut and the slips travel with their
    particles."""
    steps = 300
    over = DENSE + BASE + ["particles.0.velocity=[200.0, 0.0, 0.0]"]
    s, sim, rows = serial(HEX, over, steps)
    got = on_ranks(tmp_path, HEX, over + ["--skin=0.005"], steps)
    b = sim.bundle("base_friction")
    assert rows[-1, 2] > 0 and b.acc[0] > 0  # the plate dissipates (points slipped)
    assert got["redistributions"] >= 1
    x = sim.nord[:, :, 0]
    np.testing.assert_allclose(got["x"], x, rtol=0, atol=1e-12 * np.abs(x).max())
    same_rows(got["rows"], rows)


@pytest.mark.skipif(not MPIEXEC.exists(), reason="the mpich wheel (test extra) is not installed")
def test_particles_migrating_with_their_contact_history(tmp_path):
    """A ghost margin of 20 µm and the expanding packing drifting across the subdomain boundary: it is redistributed
    over the ranks many times (particles change owner, with their Nordsieck history and their contacts' tangential
    springs) and still equals the serial run."""
    steps = 300
    drift = DENSE + ["particles.0.velocity=[400.0, 400.0, 0.0]"]
    s, sim, rows = serial(HEX, drift, steps)
    got = on_ranks(tmp_path, HEX, drift + ["--skin=0.002"], steps)
    assert got["redistributions"] >= 2  # the part re-cut where the packing has gone (RCB: a drift keeps the owners)
    x = sim.nord[:, :, 0]
    np.testing.assert_allclose(got["x"], x, rtol=0, atol=1e-12 * np.abs(x).max())
    np.testing.assert_allclose(got["v"], sim.nord[:, :, 1] / sim.dt, rtol=0, atol=1e-9 * np.abs(got["v"]).max())
    same_rows(got["rows"], rows)


@pytest.mark.skipif(not MPIEXEC.exists(), reason="the mpich wheel (test extra) is not installed")
def test_disks_and_servo_walls_on_two_ranks_as_on_one_process(tmp_path):
    """The Luding–Herrmann box closing under its servo walls: the walls are on both ranks, the disks' forces on
    them summed over the ranks inside the loop, the servos' pressure from the walls' distance; with a ghost margin
    of 50 µm the disks pushed by the walls migrate between the ranks (with their contacts' δ_max).  Equal to the
    serial run to round-off (the walls' force sums are added in another order)."""
    path = str(ROOT / "scenarios/lh/prepare_p100.toml")
    over = ["output.history_every=100"]
    steps = 6000
    s, sim, rows = serial(path, over, steps)
    got = on_ranks(tmp_path, path, over + ["--skin=0.005"], steps)
    walls = s.family_data["disks"].params.wall
    disks = s.family_data["disks"].params.disk
    x = sim.nord[:, :, 0]
    # the test means something: walls moved by the servos onto the packing, wall contacts on both ranks' disks
    assert abs(x[walls[2], 0] - s.x0[walls[2], 0]) > 0.5 and abs(x[walls[3], 1] - s.x0[walls[3], 1]) > 0.5
    b = sim.bundle("disks")
    m = int(b.hold.meta[0])
    on_wall = b.hold.a[:m][np.isin(b.hold.b[:m], walls)]
    assert len(set(got["owner"][on_wall])) == 2, "wall contacts on one rank only: run longer"
    from polydem_cli.engine.distributed import Cut

    assert got["redistributions"] >= 1
    moved = got["owner"][disks] != Cut(s, 2, skin=0.005).dec.owner[disks]
    assert moved.sum() >= 1, moved.sum()  # disks changed owner, with their contacts' δ_max
    np.testing.assert_allclose(got["x"][walls], x[walls], rtol=0, atol=1e-9)
    np.testing.assert_allclose(got["x"][disks], x[disks], rtol=0, atol=1e-9)
    same_rows(got["rows"], rows, tol=1e-8)


def test_a_family_that_does_not_run_decomposed_is_refused():
    from polydem_cli.engine.distributed import Cut

    sc, _ = load_scenario(NUTS, [])
    s = build_system(sc, NUTS)
    with pytest.raises(DecompositionError, match="polygon contact with 2 large particle.*plates.*several ranks"):
        Cut(s, 2)


@pytest.mark.skipif(not MPIEXEC.exists(), reason="the mpich wheel (test extra) is not installed")
def test_the_load_drop_stop_on_two_ranks_as_on_one_process(tmp_path):
    """A bonded specimen pulled until its load has fallen below a fraction of its peak: the set's load is summed
    over the ranks inside the loop, so both ranks stop at the step the serial run stops."""
    path = str(ROOT / "scenarios/ch5/tension.toml")
    # pulled 10x faster than the thesis (ramp 100 s instead of 1000 s): 93,000 steps to the drop instead of 923,000,
    # the same 5 bonds failed
    over = ["particles.0.nx=6", "particles.0.ny=6", "output.history_every=10"]
    over += ["boundary.0.x2={velocity = 1e-6, acceleration = 1e-8}"]
    sc, _ = load_scenario(path, over)
    steps = int(build_system(sc, path).end_step)
    _, sim, rows = serial(path, over, steps)
    assert sim.ended and sim.step < steps  # the load drop ended it
    got = on_ranks(tmp_path, path, over, steps)
    assert got["rows"][-1, 1] == sim.step
    np.testing.assert_array_equal(got["x"], sim.nord[:, :, 0])
    same_rows(got["rows"], rows)


@pytest.mark.skipif(not MPIEXEC.exists(), reason="the mpich wheel (test extra) is not installed")
def test_the_load_drop_stop_on_a_wall_pushed_by_the_disks_of_both_ranks(tmp_path):
    """The load-drop stop on the driven top wall of the disk box, which a disk touches from the start: on ranks the
    wall's force from the disks is summed after the families' passes (engine/halo.py ``settle``), which the stop
    must count (without it the stop sees no load and never ends the run); it ends at the serial run's step."""
    path = str(ROOT / "scenarios/lh/smoke_disk_compression.toml")
    over = ["output.history_every=10", "time.end_load_drop=0.5"]
    steps = 2000
    s, sim, rows = serial(path, over, steps)
    assert sim.ended and sim.step < steps  # the load drop ended it
    ds, h = s.family_data["disks"], sim.bundle("disks").hold
    top = ds.params.wall[ds.wall_names.index("top")]
    assert top in h.b[: int(h.meta[0])]  # a disk pushes the wall
    got = on_ranks(tmp_path, path, over, steps)
    assert got["rows"][-1, 1] == sim.step
    np.testing.assert_allclose(got["x"], sim.nord[:, :, 0], rtol=0, atol=1e-9)


@pytest.mark.skipif(not MPIEXEC.exists(), reason="the mpich wheel (test extra) is not installed")
@pytest.mark.parametrize(
    "path, over, p",
    [
        (CONCRETE, FAST_PANEL, 33),  # gear5, bonds and contact; particle 33 lies on rank 1, a ghost of no other
        (str(ROOT / "scenarios/lh/smoke_disk_compression.toml"), ["output.history_every=10"], 13),  # verlet1, disks
    ],
    ids=["gear5-panel", "verlet1-disks"],
)
def test_a_non_finite_state_on_one_rank_stops_every_rank_at_the_serial_step(tmp_path, path, over, p):
    """An infinite external load on one particle, on the rank owning it: its force is not finite at the next
    evaluation, which every rank learns in the evaluation's one reduction (engine/halo.py ``settle``; no meeting
    after the step), so no rank corrects or commits the step and all stop together, with the message of the rank
    that saw it: the serial run's step and particle (by its global number).
    Without the agreement the other rank waits in the next exchange (the run's timeout) or the poisoned one stops
    alone (DIVERGED: mpiexec fails)."""
    k, steps = 40, 200
    s, sim, _ = serial(path, over, k)
    sim.ext[p, 0] = np.inf
    with pytest.raises(EngineError, match=f"non-finite position or velocity of particle {p} .* at step {k + 1},"):
        sim.advance(steps, np.zeros((steps, sim.ncols)), s.history_every)
    assert sim.step == k
    got = on_ranks(tmp_path, path, over + [f"--poison={p}@{k}"], steps)
    assert int(got["step"]) == k
    msg = str(got["message"])
    assert f"non-finite force of particle {p} " in msg and f"at step {k + 1}," in msg, msg
    from polydem_cli.engine.stability import describe, estimate

    assert describe(estimate(s), s.dt) in msg, msg  # the whole scene's critical step, not the rank's part's


#: squares in a row, not touching, and a small triangle inside the thirteenth from the start: a contained pair that
#: contact.on_containment = "abort" stops at step 1; on 2 ranks it is counted on the rank owning square 12 only
ROW_WITH_CONTAINED = (
    '[scenario]\ntitle = "contained pair on ranks"\n[time]\nintegrator = "gear5"\ndt = 1e-5\nend_time = 0.001\n'
    "[materials.m]\ndensity = 1.0\nk_n = 1e6\ngamma_n = 0.0\nk_t = 1e6\nmu_t = 0.3\n"
    + "".join(
        f'[[particles]]\nname = "s{i}"\nmaterial = "m"\nthickness = 1.0\ntype = "rectangle"\n'
        f"center = [{1.5 * i}, 0.0]\nsize = [1.0, 1.0]\n"
        for i in range(16)
    )
    + '[[particles]]\nname = "t"\nmaterial = "m"\nthickness = 1.0\ntype = "regular_polygon"\n'
    "center = [18.05, 0.0]\nsides = 3\ncircumradius = 0.2\nvelocity = [1.0, 0.0, 0.0]\n"
    '[contact]\ntangential = "coulomb"\ninitial_overlap = "allow"\non_containment = "abort"\n'
    "[stability]\nmax_overlap_ratio = 2.0\n"
)


@pytest.mark.skipif(not MPIEXEC.exists(), reason="the mpich wheel (test extra) is not installed")
def test_a_contained_pair_on_one_rank_stops_every_rank(tmp_path):
    """contact.on_containment = "abort" with the contained pair counted on one rank: the count travels in the
    evaluation's reduction (the contact family's rank sum), so every rank's halt stops the run at the serial step,
    with the message of the rank that found the pair (before, the ranks met after the step on the halt)."""
    path = tmp_path / "row.toml"
    path.write_text(ROW_WITH_CONTAINED)
    s, sim, _ = serial(str(path), [], 0)
    with pytest.raises(EngineError, match="particle 12 and 16: one polygon lies entirely inside the other") as err:
        sim.advance(50, np.zeros((50, sim.ncols)), s.history_every)
    got = on_ranks(tmp_path, str(path), ["--until-error"], 50)
    assert int(got["step"]) == sim.step == 0
    assert str(got["message"]) == str(err.value)


@pytest.mark.skipif(not MPIEXEC.exists(), reason="the mpich wheel (test extra) is not installed")
def test_checks_and_warnings_on_two_ranks_name_the_serial_particles(tmp_path):
    """The checks between chunks of the loop (an overlap beyond stability.max_overlap_ratio, a contained pair with
    contact.on_containment = "warn") are made by each rank on its own part (engine/distributed.py ``_reports``), not
    on the whole state gathered to rank 0: the rank that holds the pair finds it and names its particles by their
    numbers in the whole scene, so the console says what a serial run says."""
    text = ROW_WITH_CONTAINED.replace('on_containment = "abort"', 'on_containment = "warn"')
    for name, toml in (("warn", text), ("check", text.replace("max_overlap_ratio = 2.0", "max_overlap_ratio = 0.01"))):
        path = tmp_path / f"{name}.toml"
        path.write_text(toml)
        one = polydem("run", str(path), "-o", str(tmp_path / f"{name}1.h5"), "--threads", "1")
        two = polydem("run", str(path), "-o", str(tmp_path / f"{name}2.h5"), *RANKS2)
        if name == "warn":
            assert one.returncode == two.returncode == 0, two.stderr[-2000:]
            msg = "warning: particles 12 and 16: one polygon lies entirely inside the other"
        else:
            assert one.returncode == two.returncode == 1, two.stderr[-2000:]
            msg = "the overlap of particle 12 (s12) and particle 16 (t) reached"
        line = [ln for ln in one.stderr.splitlines() if msg in ln]
        assert line and line[0] in two.stderr.splitlines(), (one.stderr[-1500:], two.stderr[-1500:])


#: the run of test_no_whole_state_gathered_between_frames: its first and last frame only, no wall-clock checkpoint (a
#: slow machine's) between them
GATHER_RUN = ["particles.0.nx=12", "particles.0.ny=12", "time.end_time=1.6e-3", "output.frame_interval=1.0"]
GATHER_RUN += ["output.checkpoint_interval=1e6"]


@pytest.fixture(scope="module")
def gather_serial(tmp_path_factory):
    """That run in one process with an integrator: the frames the ranks' must equal."""
    where, done = tmp_path_factory.mktemp("gather"), {}

    def run(integrator):
        if integrator not in done:
            out = where / f"serial_{integrator}.h5"
            sets = [a for o in GATHER_RUN + [f'time.integrator="{integrator}"'] for a in ("--set", o)]
            r = polydem("run", CONCRETE, "-o", str(out), *sets, "--threads", "1")
            assert r.returncode == 0, r.stderr[-2000:]
            done[integrator] = out
        return done[integrator]

    return run


@pytest.mark.skipif(not MPIEXEC.exists(), reason="the mpich wheel (test extra) is not installed")
@pytest.mark.parametrize("nranks, integrator", [(2, "verlet1"), (4, "gear5")])
def test_no_whole_state_gathered_between_frames(tmp_path, nranks, integrator, gather_serial):
    """Between two frames the run checks its state every chunk of the loop (about 0.5 s of wall: stability,
    warnings, the progress of the end criterion): on ranks from small reports of each rank's part, not by gathering
    the whole state to rank 0.  A run of several seconds with its first and last frame only: the summary counts the
    chunks checked and the gathers — one per frame (of each rank's own rows, not the whole state), the whole state for
    its final checkpoint and its summary, none per chunk — on 2 ranks and on 4 (a cross of four boxes: four ranks meet
    at one corner); the frames equal the serial run's (verlet1 on 2 ranks, gear5 on 4)."""
    out = tmp_path / "g.h5"
    ranks = ("--ranks", str(nranks), "--oversubscribe")
    sets = [a for o in GATHER_RUN + [f'time.integrator="{integrator}"'] for a in ("--set", o)]
    r = polydem("run", CONCRETE, "-o", str(out), *sets, *ranks, "--threads", "1")
    assert r.returncode == 0, r.stderr[-2000:]
    summary = json.loads(out.with_suffix(".summary.json").read_text())
    assert summary["ranks"] == nranks, summary["ranks"]
    dec = summary["decomposition"]
    g = dec["whole_state_gathers"]
    assert dec["checks"] >= 6, dec  # chunks of the loop checked
    assert dec["redistributions"] == 0
    assert g["frame"] == 2, g  # the frames at t = 0 and at the end: each rank's own rows, gathered once
    assert g["positions"] == g["velocities"] == 0, g  # (a frame gathered them apart before)
    assert g["state"] <= 2, g  # the final checkpoint (and its records), the summary: not for the frames
    # the frames assembled from the ranks' rows: the serial run's, bit for bit (verlet1: the loop's last exchange is
    # before its corrector, so the frame's ghosts come from an exchange of their own)
    frames_equal(gather_serial(integrator), out)


# ---------------------------------------------------------------- polydem run --ranks


def polydem(*args, timeout=900, extra_env=None, **kw):
    env = dict(os.environ, NUMBA_NUM_THREADS="1") | (extra_env or {})
    return subprocess.run(
        [sys.executable, "-m", "polydem_cli", *args], capture_output=True, text=True, env=env, timeout=timeout, **kw
    )


#: 2 ranks whatever the machine's cores (a 1-core machine refuses them without --oversubscribe)
RANKS2 = ("--ranks", "2", "--oversubscribe")
#: the fast-pulled 12 x 12 panel through the CLI (the shock start is far from energy-conserving: not checked)
CLI_PANEL = [
    a
    for o in FAST_PANEL[:-1]
    + ["time.end_displacement=0.03", "output.frame_interval=2e-5", "stability.max_energy_error=1e9"]
    for a in ("--set", o)
]


def frames_equal(a, b):
    import h5py

    with h5py.File(a) as fa, h5py.File(b) as fb:
        for name in ("x", "v", "bond_d", "bond_kappa", "bond_strain", "step"):
            np.testing.assert_array_equal(fa["frames"][name][()], fb["frames"][name][()], err_msg=name)
        np.testing.assert_array_equal(fa["bonds/fail_step"][()], fb["bonds/fail_step"][()])
        same_rows(fa["history/table"][()], fb["history/table"][()])


@pytest.mark.skipif(not MPIEXEC.exists(), reason="the mpich wheel (test extra) is not installed")
def test_polydem_run_on_two_ranks_writes_the_serial_result(tmp_path):
    ser, ran = tmp_path / "serial.h5", tmp_path / "ranks.h5"
    r = polydem("run", CONCRETE, "-o", str(ser), *CLI_PANEL, "--threads", "1", "-q")
    assert r.returncode == 0, r.stderr[-2000:]
    tmp = tmp_path / "tmp"
    tmp.mkdir()
    r = polydem("run", CONCRETE, "-o", str(ran), *CLI_PANEL, *RANKS2, extra_env={"TMPDIR": str(tmp)})
    assert r.returncode == 0, r.stderr[-2000:]
    assert "failed bonds" in r.stdout
    frames_equal(ser, ran)
    s1 = json.loads(ser.with_suffix(".summary.json").read_text())
    s2 = json.loads(ran.with_suffix(".summary.json").read_text())
    # rank 0 ran the scene the launcher built for its check (scenario/handover.py); no temporary file is left
    assert (s1["scene"], s2["scene"]) == ("built", "launcher")
    assert not list(tmp.iterdir()), list(tmp.iterdir())
    assert len(s1["peak_memory_MiB"]) == 1 and len(s2["peak_memory_MiB"]) == 2
    assert all(50 < m < 5000 for m in s1["peak_memory_MiB"] + s2["peak_memory_MiB"]), s2["peak_memory_MiB"]
    assert s1["bond_failure"] == s2["bond_failure"] and s1["bond_failure"]["failed"] > 0
    # provenance: the ranks and threads each run used, in the console, the summary and the HDF5 attributes
    assert "ran on 2 MPI ranks × 1 thread each (auto)" in r.stdout, r.stdout
    assert s1["ranks"] == 1 and s2["ranks"] == 2
    for sm, path, ranks in ((s1, ser, 1), (s2, ran, 2)):
        (seg,) = sm["segments"]
        assert (seg["ranks"], seg["start"], seg["end"], seg["status"]) == (ranks, 0, sm["steps"], "finished")
        assert seg["threads_used"] == [1] and seg["cores"] >= 1 and seg["oversubscribed"] is False
        assert segments_of(path) == sm["segments"]


@pytest.mark.skipif(not MPIEXEC.exists(), reason="the mpich wheel (test extra) is not installed")
def test_interrupted_on_two_ranks_resumes_on_one_and_back(tmp_path):
    """SIGINT to the launcher: every rank stops after a checkpoint (exit 130); the checkpoint resumes on 1 rank;
    a serial checkpoint resumes on 2; both equal the uninterrupted run frame for frame.  A rank killed (SIGKILL):
    every rank stops, the message names the process of each rank, the last checkpoint resumes to the same frames."""
    import signal
    import time

    over = FAST_PANEL[2:-1] + ["particles.0.nx=16", "particles.0.ny=16", "time.end_displacement=0.18"]
    over += ["output.frame_interval=2e-5", "stability.max_energy_error=1e9", "output.checkpoint_interval=0.5"]
    longer = [a for o in over for a in ("--set", o)]
    ref = tmp_path / "ref.h5"
    assert polydem("run", CONCRETE, "-o", str(ref), *longer, "--threads", "1", "-q").returncode == 0
    for first, then in (([*RANKS2], ["--threads", "1"]), (["--threads", "1"], [*RANKS2])):
        out = tmp_path / f"int_{first[0][2:]}.h5"
        log = (tmp_path / "log").open("w+")
        env = dict(os.environ, NUMBA_NUM_THREADS="1")
        p = subprocess.Popen(
            [sys.executable, "-m", "polydem_cli", "run", CONCRETE, "-o", str(out), *longer, *first],
            stderr=log,
            stdout=log,
            env=env,
            start_new_session=True,
        )
        t0 = time.time()
        while time.time() - t0 < 600:  # until the loop runs (a cold cache compiles first), then a while longer
            time.sleep(0.2)
            log.seek(0)
            if "step 64 |" in log.read():
                time.sleep(1.5)
                break
        os.killpg(p.pid, signal.SIGINT)
        assert p.wait(timeout=120) == 130
        log.seek(0)
        text = log.read()
        assert "continue with: polydem run --resume" in text and "ended abnormally" not in text, text[-2000:]
        r = polydem("run", "--resume", str(out), *then, "-q")
        assert r.returncode == 0, r.stderr[-2000:]
        frames_equal(ref, out)
        sm = json.loads(out.with_suffix(".summary.json").read_text())
        segs = sm["segments"]
        # resumed on 2 ranks: rank 0 took the scene the launcher built from the result's scenario
        assert sm["scene"] == ("launcher" if then[0] == "--ranks" else "built")
        assert [(g["ranks"], g["status"]) for g in segs] == [
            (2 if first[0] == "--ranks" else 1, "interrupted"),
            (2 if then[0] == "--ranks" else 1, "finished"),
        ]
        assert segs[0]["end"] == segs[1]["start"] > 0 and segments_of(out) == segs
    # a rank killed outright: the run stops, says which process was which rank, and resumes from its checkpoint
    out = tmp_path / "killed.h5"
    log = (tmp_path / "klog").open("w+")
    p = subprocess.Popen(
        [sys.executable, "-m", "polydem_cli", "run", CONCRETE, "-o", str(out), *longer, *RANKS2],
        stderr=log,
        stdout=log,
        env=dict(os.environ, NUMBA_NUM_THREADS="1"),
        start_new_session=True,
    )
    victim, t0 = None, time.time()
    while victim is None and time.time() - t0 < 600:
        time.sleep(0.2)
        log.seek(0)
        if "step 64 |" in log.read():
            time.sleep(1.5)
            victim = _rank_process(1, str(out))
    os.kill(victim, signal.SIGKILL)
    assert p.wait(timeout=120) not in (0, 130)
    log.seek(0)
    text = log.read()
    assert f"rank 1 = {victim}" in text and f"continue with: polydem run --resume {out}" in text, text[-2000:]
    assert f"rank 1 (process {victim}) died first" in text, text[-2000:]
    r = polydem("run", "--resume", str(out), "--threads", "1", "-q")
    assert r.returncode == 0, r.stderr[-2000:]
    frames_equal(ref, out)
    segs = segments_of(out)
    assert [(g["ranks"], g["status"]) for g in segs] == [(2, "killed"), (1, "finished")] and "end" not in segs[0]


def _rank_process(rank, arg):
    """The process id of rank ``rank`` of a run whose command line holds ``arg`` (from /proc; not rank 0's result
    writer, which has its environment and the result in its command line too)."""
    for d in Path("/proc").iterdir():
        try:
            cmd = (d / "cmdline").read_bytes().split(b"\0")
            env = (d / "environ").read_bytes().split(b"\0")
        except (OSError, ValueError):
            continue
        if arg.encode() in cmd and f"PMI_RANK={rank}".encode() in env and b"polydem_cli.io.writer_proc" not in cmd:
            return int(d.name)
    return None


def segments_of(path):
    """The ``segments`` root attribute of a result (JSON): the provenance of each session."""
    import h5py

    with h5py.File(path) as f:
        return json.loads(f.attrs["segments"])


def test_bad_ranks_are_refused_before_any_output(tmp_path):
    """Every refusal of --ranks: exit 2, nothing written, and the message names the file, the key or family and the
    reason — a scene too small to cut, an interaction family that does not run decomposed (and, for the plates of
    polygon contact, their groups), a solver family that does not, the same for a result --resume continues."""
    out = tmp_path / "r.h5"
    r = polydem("run", CONCRETE, "-o", str(out), *CLI_PANEL, "--ranks", "0")
    assert r.returncode == 2 and "--ranks 0: at least 1" in r.stderr
    scene = f"{CONCRETE}: --ranks 200: "
    r = polydem("run", CONCRETE, "-o", str(out), *CLI_PANEL, "--ranks", "200")
    assert r.returncode == 2 and scene + "200 ranks for 144 particles" in r.stderr, r.stderr[-2000:]
    r = polydem("run", NUTS, "-o", str(out), "--ranks", "2")
    assert r.returncode == 2, r.stderr[-2000:]
    family = "interaction family 'contact' ([contact]): polygon contact with 2 large particle(s) (plates) does not run"
    assert f"{NUTS}: --ranks 2: {family}" in r.stderr
    assert "the large particles are those of bottom_plate, top_plate" in r.stderr
    platen = ["--set", 'platen=[{set = "specimen.top", mu = 0.3, k_t = 1e9}]']
    r = polydem("run", CONCRETE, "-o", str(out), *CLI_PANEL, *platen, "--ranks", "2")
    assert r.returncode == 2, r.stderr[-2000:]
    assert (
        f"{CONCRETE}: --ranks 2: interaction family 'platen_friction' ([[platen]]) does not run on several ranks"
        in r.stderr
    )
    lattice = str(ROOT / "scenarios/coupling/smoke_homogeneous_elastic.toml")
    r = polydem("run", lattice, "-o", str(out), "--ranks", "2")
    assert (
        r.returncode == 2
        and f"{lattice}: --ranks 2: [solver] kind = 'quasistatic' does not run on several ranks" in r.stderr
    )
    assert not out.exists() and not list(tmp_path.glob("r.h5*"))
    # a result to resume: the refusal names it and the scenario it holds, and leaves it as it was
    done = tmp_path / "done.h5"
    short = [*CLI_PANEL, "--set", "time.end_displacement=0.0003"]
    assert polydem("run", CONCRETE, "-o", str(done), *short, "--threads", "1", "-q").returncode == 0
    before = done.read_bytes()
    r = polydem("run", "--resume", str(done), "--ranks", "200")
    assert r.returncode == 2, r.stderr[-2000:]
    assert f"{done} (scenario {CONCRETE}): --ranks 200: 200 ranks for 144 particles" in r.stderr
    assert done.read_bytes() == before


def _one_core():
    os.sched_setaffinity(0, {min(os.sched_getaffinity(0))})


@pytest.mark.skipif(not hasattr(os, "sched_setaffinity"), reason="CPU affinity is Linux's")
def test_more_ranks_than_cores_are_refused_unless_asked_for(tmp_path):
    """On one core (the CPU affinity the ranks inherit): --ranks 2 refused (exit 2, nothing written) with what it
    would cost; --ranks 2 × pinned threads beyond the cores likewise; with --oversubscribe it runs, after a line
    that says what it costs, and its provenance says it was oversubscribed."""
    out = tmp_path / "o.h5"
    short = [*CLI_PANEL, "--set", "time.end_displacement=0.003"]
    r = polydem("run", CONCRETE, "-o", str(out), *short, "--ranks", "2", preexec_fn=_one_core)
    assert r.returncode == 2, r.stderr[-2000:]
    assert f"{CONCRETE}: --ranks 2: 2 ranks for the 1 core this machine lets polydem use: refused" in r.stderr
    assert "--oversubscribe" in r.stderr and "slower than on 1 rank" in r.stderr and "MB each" in r.stderr
    assert not list(tmp_path.iterdir())
    if len(os.sched_getaffinity(0)) >= 2:  # 2 ranks on 2 cores, but 2 pinned threads each
        two = sorted(os.sched_getaffinity(0))[:2]
        r = polydem(
            "run",
            CONCRETE,
            "-o",
            str(out),
            *short,
            "--ranks",
            "2",
            "--threads",
            "2",
            "--pin-threads",
            preexec_fn=lambda: os.sched_setaffinity(0, two),
        )
        assert r.returncode == 2, r.stderr[-2000:]
        assert "--ranks 2 × --threads 2 --pin-threads: 4 threads for the 2 cores" in r.stderr
        assert not list(tmp_path.iterdir())
    if not MPIEXEC.exists():
        return
    r = polydem("run", CONCRETE, "-o", str(out), *short, *RANKS2, preexec_fn=_one_core)
    assert r.returncode == 0, r.stderr[-2000:]
    assert "note: --oversubscribe: --ranks 2 on 1 core: 2 per core take turns" in r.stderr
    assert "oversubscribed: 2 ranks on 1 core" in r.stdout, r.stdout
    (seg,) = segments_of(out)
    assert (seg["ranks"], seg["ranks_on_host"], seg["cores"], seg["oversubscribed"]) == (2, 2, 1, True)


@pytest.mark.skipif(not MPIEXEC.exists(), reason="the mpich wheel (test extra) is not installed")
def test_ranks_and_threads_of_each_segment_of_a_resumed_run(tmp_path):
    """A run begun on one process (1 thread) and resumed on 2 ranks: the summary, the HDF5 attributes and the
    console give each segment's ranks and threads and the steps it kept."""
    from polydem_cli.solvers import explicit

    out = tmp_path / "seg.h5"
    over = FAST_PANEL[:-1] + ["time.end_displacement=0.003", "stability.max_energy_error=1e9"]
    sc, text = load_scenario(CONCRETE, over)
    explicit.run(
        build_system(sc, CONCRETE), out=out, scenario_file=CONCRETE, stop_after_steps=200, threads=1, quiet=True
    )
    (seg,) = segments_of(out)
    assert (seg["ranks"], seg["threads"], seg["start"], seg["status"]) == (1, 1, 0, "interrupted")
    r = polydem("run", "--resume", str(out), *RANKS2)
    assert r.returncode == 0, r.stderr[-2000:]
    sm = json.loads(out.with_suffix(".summary.json").read_text())
    first, second = sm["segments"]
    assert first["end"] == second["start"] >= 200 and second["end"] == sm["steps"] > second["start"]
    assert (first["ranks"], first["threads_used"], second["ranks"], second["threads_used"]) == (1, [1], 2, [1])
    assert sm["ranks"] == 2 and segments_of(out) == sm["segments"]
    assert (
        f"ran in 2 segments: steps 0–{first['end']:,} on 1 process, 1 thread (--threads 1) (interrupted); "
        f"steps {second['start']:,}–{sm['steps']:,} on 2 MPI ranks × 1 thread each (auto)"
    ) in r.stdout, r.stdout


@pytest.mark.skipif(not MPIEXEC.exists(), reason="the mpich wheel (test extra) is not installed")
@pytest.mark.parametrize("victim, interval", [(1, 60.0), (0, 0.3)], ids=["rank1-only-the-first-checkpoint", "rank0"])
def test_a_killed_rank_is_named_with_the_checkpoint_its_result_keeps(tmp_path, victim, interval):
    """kill -9 of one rank: polydem names that rank and its process (mpiexec's banner may name another rank's), and
    what the result keeps — its current checkpoint's step and time as the file has them, that the steps after it
    are lost and the checkpoint interval; with a 60 s interval that is the checkpoint the run began with."""
    import signal
    import time

    import h5py

    from polydem_cli.io.hdf5 import read_checkpoint

    over = FAST_PANEL[2:-1] + ["particles.0.nx=16", "particles.0.ny=16", "time.end_displacement=0.3"]
    over += ["stability.max_energy_error=1e9", f"output.checkpoint_interval={interval}"]
    out = tmp_path / "killed.h5"
    log = (tmp_path / "log").open("w+")
    p = subprocess.Popen(
        [sys.executable, "-m", "polydem_cli", "run", CONCRETE, "-o", str(out), *[a for o in over for a in ("--set", o)]]
        + [*RANKS2],
        stderr=log,
        stdout=log,
        env=dict(os.environ, NUMBA_NUM_THREADS="1"),
        start_new_session=True,
    )
    pid, t0 = None, time.time()
    while pid is None and time.time() - t0 < 600:
        time.sleep(0.2)
        log.seek(0)
        if "step 64 |" in log.read():
            time.sleep(2.0)  # some checkpoints at 0.3 s
            pid = _rank_process(victim, str(out))
    assert pid is not None
    os.kill(pid, signal.SIGKILL)
    assert p.wait(timeout=120) == signal.SIGKILL  # mpiexec's status: the rank's signal
    log.seek(0)
    text = log.read()
    with h5py.File(out) as f:
        step = int(read_checkpoint(f)["step"][0])
    assert f"rank {victim} (process {pid}) died first (mpiexec exit status 9: signal 9, SIGKILL" in text, text[-3000:]
    kept = (
        f"{out} keeps only the checkpoint this session began with"
        if interval > 1
        else f"{out} keeps its last checkpoint"
    )
    assert f"{kept}: step {step:,} (t = {step * 4e-8:.6g} s)" in text, text[-3000:]
    assert (step == 0) == (interval > 1)
    assert "the work after it is lost" in text
    assert f"a checkpoint being written every {interval:g} s of wall (output.checkpoint_interval)" in text
    if interval > 1:  # 2 s of steps, of which the history rows say how many
        assert re.search(r"\(the run had reached step [\d,]+, t = \S+ s: [\d,]+ steps\)", text), text[-3000:]
    assert f"continue with: polydem run --resume {out} --ranks 2 --oversubscribe" in text


@pytest.mark.skipif(not MPIEXEC.exists(), reason="the mpich wheel (test extra) is not installed")
def test_a_proportional_pressure_on_two_ranks_as_on_one_process(tmp_path):
    """The biaxial smoke panel ([[proportional_pressure]] at alpha = 0.5) in its elastic range: each rank loads and
    measures its own particles, the followed reaction summed over the ranks.  The sum runs in another order than one
    process's, so the run agrees to round-off, not bit for bit (it drifts to 4e-6 relative through the failure)."""
    steps = 3000
    path = str(ROOT / "scenarios/lab/smoke_biaxial.toml")
    over = ["output.history_every=50"]
    s, sim, rows = serial(path, over, steps)
    got = on_ranks(tmp_path, path, over, steps)
    cols = [c[0] for c in history_columns(s)]
    k = cols.index("pp0_p:specimen.left")
    assert np.abs(rows[:, k]).max() > 1e6  # the pressure follows a loaded face
    # each measure against its kind's size (same_rows); 4e-10 here on 2026-12-07 (numba 0.68.1): the sets' reactions
    # follow the trajectory, which the followed reaction's summation order moves in its last bits
    length = float(np.ptp(sim.nord[:, :2, 0], axis=0).max())  # the panel's size
    same_rows(got["rows"], rows, tol=1e-8, columns=cols, length=length)
    np.testing.assert_allclose(got["x"], sim.nord[:, :, 0], rtol=0, atol=1e-12 * np.abs(sim.nord[:, :, 0]).max())


@pytest.mark.skipif(not MPIEXEC.exists(), reason="the mpich wheel (test extra) is not installed")
def test_proportional_pressure_and_ramped_loads_through_a_redistribution(tmp_path):
    """Drifting sideways with a ghost margin of 1 µm, the loaded panel is re-cut while the ramp of a [[loads]] force is under way: the
    families' state travels through globalize / merge / scatter (the proportional pressure's work, Q, filtered stress
    and followed reaction; the loads' S) and the begin hooks run before the re-cut state is evaluated (the ramp's
    fraction), so the rows stay the serial run's to round-off."""
    steps = 3000
    path = str(ROOT / "scenarios/lab/smoke_biaxial.toml")
    over = ["output.history_every=50", 'loads=[{set = "specimen.left", force = [2.0e5, 0.0], ramp_time = 6.0e-4}]']
    over += ["particles.0.velocity=[500.0, 0.0, 0.0]"]  # a drift across the cut (x1 is free on every face)
    s, sim, rows = serial(path, over, steps)
    got = on_ranks(tmp_path, path, over + ["--skin=0.0001"], steps)
    assert got["redistributions"] >= 1
    cols = [c[0] for c in history_columns(s)]
    k = cols.index("load0_f1:specimen.left")
    assert rows[-1, k] == 2.0e5 * len(s.sets["specimen.left"]) and 0.0 < rows[5, k] < rows[-1, k]
    # the families' columns to round-off; the sets' reaction sums (small sums of cancelling forces) follow the
    # trajectory, which the followed reaction's other summation order moves in the last bits: to 1e-5 of their size
    fam = [j for j, c in enumerate(cols) if c.startswith(("load0_", "pp0_", "pp1_"))]
    a, b = got["rows"][:, fam], rows[:, fam]
    assert (np.abs(a - b).max(axis=0) <= 1e-8 * np.maximum(np.abs(b).max(axis=0), 1e-300)).all()
    same_rows(got["rows"], rows, tol=1e-5)


@pytest.mark.skipif(not MPIEXEC.exists(), reason="the mpich wheel (test extra) is not installed")
def test_the_rank_benchmark_runs_its_two_rank_child(tmp_path):
    """`make bench`'s 2-rank timing (benchmarks/ranks.py, under mpiexec) at a hundredth of its steps: it re-cuts once
    before it times and reports each rank's particles from its part (there is no cut of the whole scene after a re-cut
    between neighbours)."""
    from polydem_cli.benchmarks import ranks

    got = ranks._one("bonded_30x30", 2, tmp_path, 0.01)
    assert got["ranks"] == 2 and got["particles"] == 900
    assert len(got["held"]) == 2 and 900 < sum(got["held"]) < 1100  # the ghosts of one boundary twice
    assert got["particle_steps_per_s"] > 0
