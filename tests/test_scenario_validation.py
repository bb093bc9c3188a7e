"""Malformed scenarios are rejected with one specific message, exit code 2 and no output file."""

import subprocess
import textwrap

import pytest
from click.testing import CliRunner

from polydem_cli.cli import main

from conftest import SCEN, polydem_cmd

VALID = textwrap.dedent("""
    [scenario]
    title = "validation base"

    [time]
    dt = 1.0e-5
    end_time = 0.001

    [materials.steel]
    density = 5.32
    k_n = 1.61e7
    k_t = 4.74e7
    mu_t = 0.294

    [[particles]]
    name = "nuts"
    material = "steel"
    thickness = 0.62
    type = "hexagon_packing"
    width = 1.27
    rows = 2
    row_counts = [3, 2]

    [[particles]]
    name = "spec"
    material = "steel"
    thickness = 1.0
    type = "voronoi"
    nx = 3
    ny = 3
    q_pg = 0.999
    origin = [10.0, 0.0]

    [[particles]]
    name = "plate"
    material = "steel"
    thickness = 0.62
    type = "rectangle"
    center = [1.27, 0.0]
    size = [6.0, 0.5]
    place = "above:nuts"

    [contact]
    tangential = "coulomb"

    [[boundary]]
    set = "plate"
    x1 = "fixed"
    x2 = { velocity = -1.0 }
    phi = "fixed"

    [[boundary]]
    set = "spec.bottom"
    x2 = "fixed"
""")


def sub(old, new, count=1):
    assert old in VALID, old
    return VALID.replace(old, new, count)


CASES = [
    # (id, scenario text, expected key path, expected fragment of the reason)
    ("unknown-section", VALID + "\n[tiem]\ndt = 1\n", "tiem", "did you mean 'time'"),
    ("unknown-key", sub("dt = 1.0e-5", "dtt = 1.0e-5\ndt = 1.0e-5"), "time.dtt", "did you mean 'dt'"),
    ("wrong-type", sub("dt = 1.0e-5", 'dt = "fast"'), "time.dt = 'fast'", "must be a number, got string"),
    ("bool-as-number", sub("k_n = 1.61e7", "k_n = true"), "materials.steel.k_n = true", "got boolean"),
    ("missing-dt", sub("dt = 1.0e-5\n", ""), "time.dt", "missing value"),
    (
        "load-drop-without-motion",
        sub("dt = 1.0e-5", "dt = 1.0e-5\nend_load_drop = 0.5").replace("x2 = { velocity = -1.0 }", 'x2 = "fixed"'),
        "time.end_load_drop = 0.5",
        "no boundary entry prescribes a moving DOF",
    ),
    ("missing-material-table", sub('material = "steel"\n', "", 1), "particles[0].material", "missing value"),
    ("negative-density", sub("density = 5.32", "density = -5.32"), "materials.steel.density = -5.32", "must be > 0"),
    ("negative-stiffness", sub("k_n = 1.61e7", "k_n = -1.0"), "materials.steel.k_n = -1.0", "must be >= 0"),
    ("negative-friction", sub("mu_t = 0.294", "mu_t = -0.1"), "materials.steel.mu_t = -0.1", "must be >= 0"),
    (
        "negative-thickness",
        sub("thickness = 0.62", "thickness = -0.62"),
        "particles[0].thickness = -0.62",
        "must be > 0",
    ),
    ("zero-dt", sub("dt = 1.0e-5", "dt = 0.0"), "time.dt = 0.0", "must be > 0"),
    ("q_pg-above-1", sub("q_pg = 0.999", "q_pg = 1.5"), "particles[1].q_pg = 1.5", "must be <= 1"),
    ("q_pg-below-0", sub("q_pg = 0.999", "q_pg = -0.5"), "particles[1].q_pg = -0.5", "must be >= 0"),
    (
        "unknown-integrator",
        sub("dt = 1.0e-5", 'dt = 1.0e-5\nintegrator = "rk4"'),
        "time.integrator = 'rk4'",
        "must be one of 'gear5', 'verlet'",
    ),
    (
        "unknown-generator",
        sub('type = "rectangle"', 'type = "circle"'),
        "particles[2].type = 'circle'",
        "unknown; valid values",
    ),
    (
        "unknown-material",
        sub('material = "steel"\nthickness = 1.0', 'material = "stone"\nthickness = 1.0'),
        "particles[1].material = 'stone'",
        "unknown material",
    ),
    (
        "unknown-set",
        sub('set = "spec.bottom"', 'set = "spec.middle"'),
        "boundary[1].set = 'spec.middle'",
        "unknown particle set",
    ),
    (
        "set-index-out-of-range",
        sub('set = "spec.bottom"', 'set = "spec[9]"'),
        "boundary[1].set = 'spec[9]'",
        "has 9 particles",
    ),
    ("bad-dof", sub('x2 = "fixed"', 'x2 = "moving"'), "boundary[1].x2 = 'moving'", 'must be "free", "fixed"'),
    (
        "ramp-sign",
        sub("x2 = { velocity = -1.0 }", "x2 = { velocity = -1.0, acceleration = 2.0 }"),
        "boundary[0].x2",
        "same sign",
    ),
    (
        "dof-twice",
        VALID + '\n[[boundary]]\nset = "plate"\nx2 = "fixed"\n',
        "boundary[2].x2 = 'fixed'",
        "already has x2 prescribed by boundary[0]",
    ),
    ("no-end", sub("end_time = 0.001\n", ""), "time.end_time is not set", "no end criterion"),
    (
        "vec2-length",
        sub("origin = [10.0, 0.0]", "origin = [10.0, 0.0, 1.0]"),
        "particles[1].origin",
        "exactly 2 numbers",
    ),
    (
        "nonconvex-polygon",
        VALID + '\n[[particles]]\nname = "p"\nmaterial = "steel"\nthickness = 1.0\ntype = "polygon"\n'
        'vertices = [[20, 0], [22, 0], [21, 0.5], [22, 2], [20, 2]]\n',
        "particles[3]",
        "impossible geometry: particle",
    ),
    (
        "defect-outside",
        sub("row_counts = [3, 2]", "row_counts = [3, 2]\nmissing = [[1, 5]]"),
        "particles[0]",
        "outside the packing",
    ),
    ("initial-overlap", sub("origin = [10.0, 0.0]", "origin = [1.0, 0.0]"), "particles", "overlap at t0"),
    ("duplicate-group", sub('name = "spec"', 'name = "nuts"'), "particles[1].name = 'nuts'", "used twice"),
    (
        "place-unknown-group",
        sub('place = "above:nuts"', 'place = "above:bolts"'),
        "particles[2].place = 'above:bolts'",
        "not an earlier particle group",
    ),
    (
        "end-displacement-without-drive",
        sub('x2 = { velocity = -1.0 }', 'x2 = "fixed"').replace("end_time = 0.001", "end_displacement = 0.1"),
        "time.end_displacement = 0.1",
        "no boundary entry prescribes a moving DOF",
    ),
    ("bad-toml", VALID + "\n[time\n", "", "invalid TOML"),
    ("empty-file", "", "", "file is empty"),
    ("blank-file", "\n  \n", "", "file is empty"),
    ("only-comments", "# a scenario, some day\n", "", "no settings (only comments)"),
]


@pytest.fixture
def runner():
    return CliRunner()


@pytest.mark.parametrize("cid,text,key,reason", CASES, ids=[c[0] for c in CASES])
def test_malformed_scenario_rejected(tmp_path, runner, cid, text, key, reason):
    scen = tmp_path / "bad.toml"
    scen.write_text(text)
    out = tmp_path / "out" / "result.h5"
    for args in (["run", str(scen), "-o", str(out), "-q"], ["check", str(scen)]):
        r = runner.invoke(main, args)
        assert r.exit_code == 2, (r.output, r.exception)
        msg = r.output.strip().splitlines()
        assert len(msg) == 1, r.output  # one message
        assert msg[0].startswith(f"error: {scen}: {key}"), msg[0]
        assert reason in msg[0], msg[0]
        assert not any(w in msg[0] for w in ("None", "True", "False")), msg[0]  # TOML's words, not Python's
    assert not out.exists() and not out.parent.exists()
    assert not out.with_suffix(".summary.json").exists()


def test_valid_base_scenario_passes(tmp_path, runner):
    scen = tmp_path / "ok.toml"
    scen.write_text(VALID)
    r = runner.invoke(main, ["check", str(scen)])
    assert r.exit_code == 0, r.output
    assert "OK" in r.output and "15 particles" in r.output


@pytest.mark.parametrize("path,reason", [("does/not/exist.toml", "file not found"), (".", "is a directory")])
def test_unreadable_file(tmp_path, runner, path, reason):
    r = runner.invoke(main, ["run", path, "-o", str(tmp_path / "r.h5")])
    assert r.exit_code == 2 and reason in r.output
    assert not (tmp_path / "r.h5").exists()


def test_set_override_is_validated_and_named(tmp_path, runner):
    scen = tmp_path / "ok.toml"
    scen.write_text(VALID)
    r = runner.invoke(main, ["check", str(scen), "--set", "time.dt=-1"])
    assert r.exit_code == 2
    assert f"{scen} (--set time.dt): time.dt = -1.0: must be > 0" in r.output
    r = runner.invoke(main, ["check", str(scen), "--set", "particles.1.q_pg=2"])
    assert r.exit_code == 2 and "particles[1].q_pg = 2.0: must be <= 1" in r.output
    r = runner.invoke(main, ["check", str(scen), "--set", "time.dtx=1"])
    assert r.exit_code == 2 and "time.dtx" in r.output and "unknown key" in r.output
    r = runner.invoke(main, ["check", str(SCEN / "bench_dense_hexagons.toml"), "--set", "particles.0.sides=7"])
    assert r.exit_code == 2 and "particles[0].sides = 7: must be even" in r.output
    r = runner.invoke(main, ["check", str(scen), "--set", "particles.1.nx=4", "--set", 'contact.tangential="none"'])
    assert r.exit_code == 0 and "18 particles" in r.output


def test_existing_result_is_not_overwritten(tmp_path):
    scen = tmp_path / "ok.toml"
    scen.write_text(VALID)
    out = tmp_path / "r.h5"
    out.write_bytes(b"precious")
    r = subprocess.run(polydem_cmd() + ["run", str(scen), "-o", str(out), "-q"], capture_output=True, text=True)
    assert r.returncode == 2 and "exists" in r.stderr and "--overwrite" in r.stderr
    assert out.read_bytes() == b"precious"
    r = subprocess.run(
        polydem_cmd() + ["run", str(scen), "-o", str(out), "-q", "--overwrite"], capture_output=True, text=True
    )
    assert r.returncode == 0, r.stderr
    assert out.read_bytes()[:8] == b"\x89HDF\r\n\x1a\n"


def test_shipped_scenarios_are_valid(runner):
    for f in sorted(SCEN.glob("*.toml")):
        r = runner.invoke(main, ["check", str(f)])
        assert r.exit_code == 0, (f, r.output)


@pytest.mark.parametrize(
    "out,reason",
    [("/proc/polydem-no/r.h5", "cannot write the result there"), ("afile/r.h5", "is a file, not a folder")],
)
def test_unwritable_output_is_refused_before_the_build(tmp_path, out, reason):
    """Exit 2 with a message naming the path, before any work, and nothing left behind."""
    scen = tmp_path / "ok.toml"
    scen.write_text(VALID.replace("nx = 3", "nx = 30").replace("ny = 3", "ny = 30"))
    (tmp_path / "afile").write_text("x")
    before = sorted(p.name for p in tmp_path.iterdir())
    r = subprocess.run(polydem_cmd() + ["run", str(scen), "-o", out], capture_output=True, text=True, cwd=tmp_path)
    assert r.returncode == 2, r.stderr
    assert r.stderr.startswith(f"error: {out}: ") and reason in r.stderr and "Traceback" not in r.stderr
    assert "critical time step" not in r.stderr  # refused before the specimen was built
    assert sorted(p.name for p in tmp_path.iterdir()) == before


@pytest.mark.parametrize(
    "sets,key,reason",
    [
        (["particles.1.nx=100000", "particles.1.ny=100000"], "particles[1]", "specimen too large for this machine"),
        (["particles.0.rows=1000000000"], "particles[0]", "specimen too large for this machine"),
        (["particles.1.nx=1000000000000"], "particles[1].nx = 1000000000000", "absurdly large"),
        (["particles.0.row_counts=[3, 10000000000000]"], "particles[0].row_counts", "absurdly large"),
        (["output.history_every=100000000000000000"], "output.history_every", "absurdly large"),
    ],
)
def test_oversized_specimen_and_absurd_integers_are_refused(tmp_path, runner, sets, key, reason):
    """A 1e10-particle grid would hang or end in a NumPy traceback: the particle count and memory are
    estimated from the parameters and refused with the estimate and the available memory; integers
    beyond 2^31 - 1 are refused by validation."""
    scen = tmp_path / "ok.toml"
    scen.write_text(VALID)
    args = ["check", str(scen)] + [a for s in sets for a in ("--set", s)]
    r = runner.invoke(main, args)
    assert r.exit_code == 2, (r.output, r.exception)
    assert key in r.output and reason in r.output, r.output
    if "too large" in reason:
        assert "GiB available" in r.output and "particles (" in r.output


def test_a_negative_pressure_is_refused_by_one_rule_for_the_scenario_and_the_lab(tmp_path, runner):
    """A pressure pushes on the exposed edges ([[loads]] pressure >= 0 in the schema); a pull on them is a force.
    The scenario (--set) and the lab study's --pressures refuse a negative one by that same rule, before any run."""
    confined = SCEN / "lab" / "smoke_confined_compression.toml"
    r = runner.invoke(main, ["check", str(confined), "--set", "loads.0.pressure=-1e7"])
    assert r.exit_code == 2 and "loads[0].pressure = -10000000.0: must be >= 0" in r.output, r.output
    r = runner.invoke(main, ["run", str(confined), "--set", "loads.0.pressure=-1e7", "-o", str(tmp_path / "r.h5")])
    assert r.exit_code == 2 and not (tmp_path / "r.h5").exists()
    out = tmp_path / "lab"
    r = runner.invoke(main, ["study", "lab", "--smoke", "--pressures=-1,2", "--out", str(out)])
    assert r.exit_code == 2 and "--pressures" in r.output and "-1 MPa" in r.output and "must be >= 0" in r.output
    assert "[[loads]] pressure" in r.output and not out.exists()


@pytest.mark.parametrize("depth", [3.95, 4.0, 3.99])
def test_a_notch_that_leaves_no_ligament_is_refused_naming_it(runner, depth):
    """A notch as deep as the beam (or leaving a ligament thinner than the smallest cell part kept) cuts the beam in
    two: refused as such, not as a loading nose without particles."""
    beam = SCEN / "lab" / "smoke_three_point_bending.toml"
    r = runner.invoke(main, ["check", str(beam), "--set", f"particles.0.notch_depth={depth}"])
    assert r.exit_code == 2, r.output
    assert "particles[0]" in r.output and ("no ligament" in r.output or "deeper than the beam" in r.output), r.output
    assert "load_width" not in r.output


def test_every_subset_a_generator_names_is_documented_where_sets_are():
    """docs/scenario.md's [[particles]] section (the schema's doc) names, per generator, the subsets it yields (they
    were defined only in README's 'Decisions')."""
    import polydem_cli.geometry.specimens as gen
    from polydem_cli.scenario.schema import PARTICLES

    doc = PARTICLES.doc
    made = {
        "rectangle": gen.voronoi_specimen(4, 4),
        "disc": gen.voronoi_cut(6, 6, shape="disc", load_width=1.0),
        "notched_beam": gen.voronoi_cut(8, 4, shape="notched_beam", notch_depth=1.2, notch_width=0.4, load_width=1.0),
        "hexagon_packing": gen.hexagon_packing(1.0, [4, 3], 3),
    }
    for what, spec in made.items():
        line = next(ln for ln in doc.splitlines() if what in ln and ln.startswith("* "))
        for sub in spec.subsets:
            assert f"`{sub}`" in line, (what, sub, line)
    assert "`aggregate` and `matrix`" in doc and "`<name>[i]`" in doc and "`all`" in doc


def test_a_regular_notched_beam_with_cell_edges_on_its_middle_is_accepted(runner):
    """q_pg = 0 (a square grid): no cell straddles the beam's middle, but the cells are joined there: one piece."""
    beam = SCEN / "lab" / "smoke_three_point_bending.toml"
    r = runner.invoke(main, ["check", str(beam), "--set", "particles.0.q_pg=0.0"])
    assert r.exit_code == 0, r.output
