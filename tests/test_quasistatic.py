"""The quasi-static solver family through the product's interfaces: scenario files (``[solver] kind =
"quasistatic"``), ``polydem check / run / report``, checkpoints and resume, bad input refused with its key,
the level-2 sub-problems in parallel (polydem_cli/solvers/quasistatic.py, coupling/stepper.py)."""

from __future__ import annotations

import json
import subprocess
from pathlib import Path

import h5py
import numpy as np
import pytest

from conftest import DYN_PER_UNIT, SCEN, polydem_cmd

BASE = """
[scenario]
title = "test plate"
[solver]
kind = "quasistatic"
[lattice]
spacing = 1.0
width = 32.0
rows = 21
[hole]
half_diagonals = [4.0, 3.0]
[members]
k = 1.0e4
law = "softening"
f_t = 10.0
[loading]
max_events = 40
"""


def _cli(*args, cwd=None):
    return subprocess.run(polydem_cmd() + list(args), capture_output=True, text=True, cwd=cwd)


def _write(tmp_path, text, name="plate.toml"):
    p = tmp_path / name
    p.write_text(text)
    return p


@pytest.mark.parametrize(
    "change, key",
    [
        ("[hole]\nhalf_diagonals = [17.0, 3.0]", "hole.half_diagonals"),
        ("[lattice]\nspacing = 0.7\nwidth = 32.0\nrows = 21", "lattice.spacing"),
        ("[members]\nk = -1.0e4\nlaw = 'elastic'", "members.k"),
        ("[members]\nk = 1.0e4\nlaw = 'softening'\nf_t = -10.0", "members.f_t"),
        ("[solver]\nkind = 'quasi'", "solver.kind"),
        ("[adaptive]\ncoarse_side = 6", "adaptive.coarse_side"),
    ],
)
def test_bad_input_is_refused_with_its_key_and_nothing_written(tmp_path, change, key):
    table = change.split("\n", 1)[0]
    lines, skip = [], False
    for line in BASE.strip().splitlines():  # replace the table of the change
        if line.startswith("["):
            skip = line == table
        if not skip:
            lines.append(line)
    p = _write(tmp_path, "\n".join(lines) + "\n" + change + "\n")
    out = tmp_path / "r.h5"
    r = _cli("run", str(p), "-o", str(out))
    assert r.returncode == 2, r.stderr
    assert key in r.stderr and str(p) in r.stderr
    assert not out.exists() and not list(tmp_path.glob("r.*"))


def test_run_report_and_the_csv_equal_the_history(tmp_path):
    p = _write(tmp_path, BASE)
    out = tmp_path / "plate.h5"
    r = _cli("run", str(p), "-o", str(out))
    assert r.returncode == 0, r.stderr
    assert "peak reaction" in r.stdout
    sm = json.loads(out.with_suffix(".summary.json").read_text())
    assert sm["status"] == "finished" and sm["solver"] == "quasistatic" and sm["events"] >= 1
    with h5py.File(out, "r") as f:
        h = f["history/table"][...]
        assert f.attrs["format"] == "polydem-quasistatic"
        assert len(f["stages"]) == sm["refinement_solves"] + 1
        tooth = f["damage/tooth"][...]
    # every event takes one tooth of its critical member: the damage equals the events' members
    ev = h[h[:, 1] == 1]
    assert np.array_equal(np.bincount(ev[:, 4].astype(int), minlength=len(tooth)), tooth)
    r = _cli("report", str(out), "--out", str(tmp_path / "rep"))
    assert r.returncode == 0, r.stderr
    made = sorted(q.name for q in (tmp_path / "rep").iterdir())
    assert {"plate_load.png", "plate_mesh.png", "plate_history.csv"} <= set(made)
    csv = np.loadtxt(tmp_path / "rep" / "plate_history.csv", delimiter=",", skiprows=1, ndmin=2)
    assert np.allclose(csv, h, rtol=1e-9, atol=0)
    # the load figure draws the events (u1, reaction) after the origin, in the unit its axis states
    import csv as _csv

    with open(tmp_path / "rep" / "plate_load_plotted.csv") as fh:
        rows = [q for q in _csv.DictReader(fh) if q["curve"] == "0"]
    div = 1e3 if "10³ dyn" in rows[0]["y_label"] else 1.0
    drawn = np.array([[float(q["x"]), float(q["y"])] for q in rows])
    assert np.allclose(drawn[1:, 0], ev[:, 2]) and np.allclose(drawn[1:, 1] * div, ev[:, 3])
    assert np.allclose(drawn[0], 0.0)
    # a finished run is not touched again
    r = _cli("run", str(p), "-o", str(out), "--continue")
    assert r.returncode == 0 and "already finished" in r.stdout


@pytest.mark.parametrize("adaptive", [True, False])
def test_an_interrupted_run_resumes_to_the_uninterrupted_result(tmp_path, adaptive):
    """Stopped after 1 to 25 solves (the first solves refine the mesh: a new mesh is pending at some of these
    stops; the factor of the system was updated by saw-tooth events at others; the indicator's marks wait at
    later ones) and resumed, the run writes the
    same rows, damage and stages as an uninterrupted one, bit for bit; adaptive and fully resolved."""
    from polydem_cli.scenario.load import load_scenario
    from polydem_cli.solvers import driver
    from polydem_cli.solvers import quasistatic as qs

    p = _write(tmp_path, BASE if adaptive else BASE + "[adaptive]\nenabled = false\n")
    sc, text = load_scenario(p)
    whole = qs.run(sc, out=tmp_path / "whole.h5", quiet=True)
    for stop in (1, 2, 3, 5, 12, 25) if adaptive else (2, 7, 12):
        part = tmp_path / f"part{stop}.h5"
        qs.run(sc, out=part, quiet=True, stop_after_solves=stop)
        with h5py.File(part, "r") as f:
            assert f.attrs["status"] == "running" and len(f["history/table"]) == stop
        assert driver.existing(part, sc).state == "resumable"
        rest = qs.run(out=part, resume=True, quiet=True)
        assert rest["status"] == "finished" and rest["solves"] == whole["solves"]
        with h5py.File(tmp_path / "whole.h5", "r") as a, h5py.File(part, "r") as b:
            cols = [c[0] for c in json.loads(a["history/table"].attrs["columns"])]
            keep = [i for i, c in enumerate(cols) if c not in ("wall", "peak_memory")]
            assert np.array_equal(a["history/table"][:, keep], b["history/table"][:, keep]), stop
            assert np.array_equal(a["damage/tooth"][...], b["damage/tooth"][...])
            assert sorted(a["stages"]) == sorted(b["stages"]), stop
            for g in a["stages"]:
                assert np.array_equal(a["stages"][g]["elements"][...], b["stages"][g]["elements"][...])


def test_elastic_adaptive_stages_converge_to_the_fully_resolved_reaction(tmp_path):
    from polydem_cli.scenario.load import load_scenario
    from polydem_cli.solvers import quasistatic as qs

    text = BASE.replace('law = "softening"\nf_t = 10.0', 'law = "elastic"').replace(
        "[loading]\nmax_events = 40", "[loading]\ndisplacement = 0.02"
    )
    p = _write(tmp_path, text)
    ref = _write(tmp_path, text + "[adaptive]\nenabled = false\n", "ref.toml")
    a = qs.run(load_scenario(p)[0], out=tmp_path / "a.h5", quiet=True)
    b = qs.run(load_scenario(ref)[0], out=tmp_path / "b.h5", quiet=True)
    assert b["solves"] == 1 and b["final_dofs"] > a["final_dofs"]
    # the adaptive reaction is stiffer (a coarser kinematic space) and within 2 % of the lattice's
    assert 0.0 <= a["reaction"] / b["reaction"] - 1.0 < 0.02
    with h5py.File(tmp_path / "a.h5", "r") as f:
        h = f["history/table"][...]
    assert np.all(np.diff(h[:, 3]) <= 1e-9 * abs(h[0, 3]))  # refinement only relaxes the stiffness


def test_level2_subproblems_in_parallel_give_the_serial_matrices():
    from polydem_cli.coupling import examples as ex
    from polydem_cli.coupling.adaptive import Model
    from polydem_cli.coupling.meshkern import initial_mesh_of

    p = ex.problem("heterogeneous_elastic", width=48.0, rows=28)
    els = initial_mesh_of(p.lat, 8)
    one = Model(p.lat, p.domain, els, p.k, k_ref=p.k_ref, workers=1)
    two = Model(p.lat, p.domain, els, p.k, k_ref=p.k_ref, workers=2)
    heavy = [k for k in range(len(els)) if one.levels[k] == 2 and one._heterogeneous(k)]
    assert len(heavy) >= 16  # enough for both threads to have work (meshkern.element_matrices)
    assert np.array_equal(one.Ke, two.Ke)


def test_explicit_scenarios_name_their_solver_and_old_results_still_match():
    from polydem_cli.scenario.load import load_scenario, same_run

    sc, _ = load_scenario(SCEN / "ch7" / "smoke_concrete_tension.toml")
    assert sc["solver"] == {"kind": "explicit"}
    old = {k: v for k, v in sc.items() if k != "solver"}  # a result written before [solver] existed
    assert same_run(old, sc)


def test_the_example_scenarios_build_the_examples_of_the_study():
    """scenarios/coupling/<example>.toml is the plate that ``polydem study coupling`` solves (coupling/examples.py):
    the same nodes, members, stiffnesses, strengths and supports, and the same adaptive settings."""
    from polydem_cli.coupling import examples as ex
    from polydem_cli.coupling.scenario import build_problem
    from polydem_cli.scenario.load import load_scenario

    for name in ex.EXAMPLES:
        resolved = load_scenario(SCEN / "coupling" / f"{name}.toml")[0]
        a = build_problem(resolved)
        b = ex.problem(name)
        table = resolved["adaptive"]
        assert table["enabled"] and {k: table[k] for k in ex.adaptive_table(name)} == ex.adaptive_table(name), name
        assert np.array_equal(a.lat.x, b.lat.x) and np.array_equal(a.lat.members, b.lat.members)
        assert np.array_equal(a.k, b.k) and np.array_equal(a.f, b.f), name
        assert a.pattern == b.pattern and a.softening == b.softening and a.aggregates == b.aggregates
    for f in SCEN.glob("coupling/*.toml"):  # every coupling scenario validates
        load_scenario(f)


@pytest.mark.parametrize(
    "name", ["homogeneous_elastic", "heterogeneous_elastic", "homogeneous_softening", "heterogeneous_softening"]
)
def test_smoke_chain_of_the_coupling_scenarios(tmp_path, name):
    from click.testing import CliRunner

    from polydem_cli.cli import main

    scen = SCEN / "coupling" / f"smoke_{name}.toml"
    out = tmp_path / f"{name}.h5"
    r = CliRunner().invoke(main, ["run", str(scen), "-o", str(out), "-q"])
    assert r.exit_code == 0, r.output
    r = CliRunner().invoke(main, ["report", str(out), "--out", str(tmp_path)])
    assert r.exit_code == 0, r.output
    assert (tmp_path / f"{name}_mesh.png").stat().st_size > 20_000
    sm = json.loads(out.with_suffix(".summary.json").read_text())
    assert sm["status"] == "finished" and sm["final_dofs"] < sm["lattice_dofs"]


def test_coupling_study_figures_draw_the_solutions_it_reports(tmp_path):
    """``polydem study coupling`` on a small plate (a quick look; aggregate classes too large for it are left
    out): results.json for the four examples, the curves figure draws each softening run's path of events from
    zero load as stored, one mesh figure per example."""
    import csv
    import json

    from polydem_cli.reproductions.coupling import collate

    res = collate(tmp_path, width=24, rows=14)
    assert set(res["examples"]) == {
        "homogeneous_elastic",
        "heterogeneous_elastic",
        "homogeneous_softening",
        "heterogeneous_softening",
    }
    stored = json.loads((tmp_path / "results.json").read_text())["examples"]
    for name, row in stored.items():
        assert (tmp_path / f"coupling_mesh_{name}.png").stat().st_size > 20_000
        assert row["adaptive"]["dofs"] <= row["reference"]["dofs"]
    with open(tmp_path / "coupling_curves_plotted.csv") as fh:
        rows = list(csv.DictReader(fh))
    drawn = {}
    for r in rows:
        drawn.setdefault((r["title"].replace(" ", "_"), r["label"].split(" ")[0]), []).append(
            (float(r["x"]), float(r["y"]))
        )
    unit = rows[0]["y_label"].split()[-1].strip("[]")  # reactions in dyn, drawn in kN, N, ... nN
    assert len(drawn) == 4  # two softening examples, reference and adaptive each
    for (name, key), pts in drawn.items():
        run = stored[name][key]
        xy = np.array(pts)
        assert np.allclose(xy[:, 0], [0.0, *run["factor"]]) and np.allclose(
            xy[:, 1] * DYN_PER_UNIT[unit], [0.0, *run["reaction_curve"]]
        )


def test_the_last_stage_picture_counts_the_damaged_members_of_the_summary(tmp_path):
    """The stage figure drew the damage at the start of each stage, so its last panel said 24 damaged where
    the summary said 25; each panel now shows the damage at the end of its stage."""
    import re

    from polydem_cli.solvers.quasistatic import report

    out = tmp_path / "soft.h5"
    r = _cli("run", str(SCEN / "coupling" / "smoke_homogeneous_softening.toml"), "-o", str(out), "-q")
    assert r.returncode == 0, r.stderr
    sm = json.loads(out.with_suffix(".summary.json").read_text())
    titles = {}

    def save(fig, path, **kw):
        titles[path.name] = [ax.get_title() for ax in fig.axes if ax.get_visible()]

    report(out, tmp_path, save=save)
    stages = titles.get("soft_stages_mesh.png")
    assert stages, sorted(titles)
    counts = [int(re.search(r"(\d+) damaged at its end", t).group(1)) for t in stages]
    assert counts == sorted(counts) and counts[-1] == sm["damaged_members"] > 0


def test_report_of_two_quasistatic_results_overlays_their_load_curves(tmp_path):
    """`polydem report A.h5 B.h5` dropped quasi-static results from the overlay; it now draws their
    load–displacement curves (from the unloaded state through the events) in one figure."""
    import csv

    from polydem_cli.solvers.quasistatic import load_curve

    outs = []
    for ft in (10.0, 14.0):
        p = _write(tmp_path, BASE.replace("f_t = 10.0", f"f_t = {ft}"), f"plate_{ft:g}.toml")
        out = tmp_path / f"plate_{ft:g}.h5"
        r = _cli("run", str(p), "-o", str(out), "-q")
        assert r.returncode == 0, r.stderr
        outs.append(out)
    r = _cli("report", *map(str, outs), "--out", str(tmp_path / "rep"))
    assert r.returncode == 0, r.stderr
    png = tmp_path / "rep" / "overlay_quasistatic_load.png"
    assert png.exists() and "left out" not in r.stderr
    with open(png.with_name(png.stem + "_plotted.csv")) as fh:
        rows = list(csv.DictReader(fh))
    for k, out in enumerate(outs):
        u, reaction = load_curve(out)
        ys = np.array([float(x["y"]) for x in rows if x["curve"] == str(2 * k)])  # the curve, then its peak marker
        scale = 1e3 if max(load_curve(o)[1].max() for o in outs) >= 1e3 else 1.0  # the axis in 10³ dyn or dyn
        assert len(ys) == len(reaction) and np.allclose(ys * scale, reaction)
    peaks = [load_curve(o)[1].max() for o in outs]
    assert peaks[1] > peaks[0]  # the stronger members carry more


def _same_quasistatic_result(a_path, b_path):
    """Two quasi-static results hold the same rows (wall time and memory aside), damage and stage meshes."""
    with h5py.File(a_path, "r") as a, h5py.File(b_path, "r") as b:
        cols = [c[0] for c in json.loads(a["history/table"].attrs["columns"])]
        keep = [i for i, c in enumerate(cols) if c not in ("wall", "peak_memory")]
        assert np.array_equal(a["history/table"][:, keep], b["history/table"][:, keep])
        assert np.array_equal(a["damage/tooth"][...], b["damage/tooth"][...])
        assert sorted(a["stages"]) == sorted(b["stages"])
        for g in a["stages"]:
            assert np.array_equal(a["stages"][g]["elements"][...], b["stages"][g]["elements"][...])


#: a softening plate whose run takes a few seconds, with a checkpoint every 0.1 s
LONG = (
    BASE.replace("max_events = 40", "max_events = 400\nend_load_drop = 0.02")
    .replace("width = 32.0\nrows = 21", "width = 64.0\nrows = 41")
    .replace("[loading]", "[output]\ncheckpoint_interval = 0.1\n[loading]")
)


@pytest.mark.slow
def test_a_killed_quasistatic_run_resumes_from_its_checksummed_checkpoint(tmp_path):
    """SIGKILL in the middle of a quasi-static run (``polydem run`` in a subprocess): the result is intact, every
    dataset carries its Fletcher-32 checksum (the writer process wrote it, not the killed one), and ``--resume``
    gives the rows, damage and meshes of the uninterrupted run."""
    import signal
    import time

    from polydem_cli.io.hdf5 import check_intact, open_result, read_checkpoint
    from polydem_cli.solvers.quasistatic import FORMAT

    p = _write(tmp_path, LONG)
    ref, cut = tmp_path / "ref.h5", tmp_path / "cut.h5"

    def start(out):  # the run, and the time its writer started (the loop's start, after the set-up)
        proc = subprocess.Popen(polydem_cmd() + ["run", str(p), "-o", str(out), "-q", "--overwrite"],
                                stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)  # fmt: skip
        marker = Path(str(out) + ".writer")
        while not marker.exists() and proc.poll() is None:
            time.sleep(0.01)
        return proc, time.time()

    proc, t0 = start(ref)
    assert proc.wait(timeout=300) == 0, proc.communicate()
    t_loop = time.time() - t0
    for frac in (0.5, 0.3, 0.15, 0.05):  # the machine's speed drifts: kill earlier if the run has already ended
        proc, _ = start(cut)
        time.sleep(frac * t_loop)
        if proc.poll() is None:
            proc.send_signal(signal.SIGKILL)
        proc.communicate(timeout=60)
        with open_result(cut, fmt=FORMAT) as f:  # the run may have finished between the poll and the signal
            if f.attrs["status"] == "running":
                break
    else:
        pytest.fail("every run ended before the signal was due")
    check_intact(cut, fmt=FORMAT)  # every dataset reads back with its checksum
    with open_result(cut, fmt=FORMAT) as f:
        assert f.attrs["status"] == "running" and f.attrs["checksums"] == "fletcher32"
        assert f["history/table"].fletcher32 and f["lattice/k"].fletcher32
        ck = read_checkpoint(f)
        assert ck is not None and int(ck["step"][0]) == int(ck["counters"][0])
    r = _cli("run", "--resume", str(cut))
    assert r.returncode == 0, r.stderr
    assert "resuming" in r.stderr and "from solve" in r.stderr
    _same_quasistatic_result(ref, cut)


def test_a_damaged_quasistatic_checkpoint_falls_back_to_the_other_slot(tmp_path):
    """The current checkpoint slot of a quasi-static result fails its checksum (a bad disk block, written
    bypassing HDF5): resume uses the older slot, says so, and still ends with the uninterrupted result."""
    from polydem_cli.scenario.load import load_scenario
    from polydem_cli.solvers import quasistatic as qs

    p = _write(tmp_path, BASE)
    sc, _ = load_scenario(p)
    qs.run(sc, out=tmp_path / "whole.h5", quiet=True)
    part = tmp_path / "part.h5"
    qs.run(sc, out=part, quiet=True, stop_after_solves=3)
    qs.run(out=part, resume=True, quiet=True, stop_after_solves=6)  # two checkpoints after the first: 3 and 6
    with h5py.File(part, "r") as f:
        cur = int(f["checkpoint/current"][0])
        big = max(f[f"checkpoint/slot{cur}"], key=lambda n: f[f"checkpoint/slot{cur}/{n}"].nbytes)
        d = f[f"checkpoint/slot{cur}/{big}"]
        info = d.id.get_chunk_info(0)
        assert d.fletcher32 and info.size >= 32
    with open(part, "r+b") as fh:  # overwrite 16 bytes inside the chunk, as a bad disk block would
        fh.seek(info.byte_offset + info.size // 2 - 8)
        fh.write(b"\xa5" * 16)
    r = _cli("run", "--resume", str(part))
    assert r.returncode == 0, r.stderr
    assert f"/checkpoint/slot{cur} failed its checksums; using the older checkpoint at step 3" in r.stderr
    assert "from solve 3 " in r.stderr
    _same_quasistatic_result(tmp_path / "whole.h5", part)


def test_quasistatic_scenarios_run_through_sweep_and_batch(tmp_path):
    """``polydem sweep`` (two variants of the member strength) and ``polydem batch`` run quasi-static scenarios
    through the same driver as ``polydem run``: the sweep's table has the family's columns, a second sweep
    reuses the finished runs, and a batch of a finished result and a new one runs only the new one."""
    import csv

    p = _write(tmp_path, BASE)
    out = tmp_path / "sw"
    r = _cli("sweep", str(p), "--set", "members.f_t=8,12", "--out", str(out), "--workers", "1")
    assert r.returncode == 0, r.stderr
    rows = list(csv.DictReader((out / "sweep.csv").open()))
    assert [r_["members.f_t"] for r_ in rows] == ["8", "12"]
    assert all(r_["status"] == "finished" for r_ in rows)
    peaks = [float(r_["peak reaction [dyn]"]) for r_ in rows]
    assert peaks[1] > peaks[0] > 0  # stronger members: a higher peak
    r = _cli("sweep", str(p), "--set", "members.f_t=8,12", "--out", str(out), "--workers", "1")
    assert r.returncode == 0 and r.stdout.count("reused") == 2, r.stdout
    first = tmp_path / "a.h5"
    assert _cli("run", str(p), "-o", str(first), "-q").returncode == 0
    p2 = _write(tmp_path, BASE.replace("f_t = 10.0", "f_t = 11.0"), "plate2.toml")
    r = _cli("batch", f"{p}={first}", f"{p2}={tmp_path / 'b.h5'}")
    assert r.returncode == 0, r.stderr + r.stdout
    with h5py.File(tmp_path / "b.h5", "r") as f:
        assert f.attrs["status"] == "finished" and f.attrs["format"] == "polydem-quasistatic"
    assert "reused" in r.stdout + r.stderr


def test_the_registry_knows_each_family_by_the_format_of_its_results():
    from polydem_cli.solvers import FAMILIES, FORMATS, family

    assert {family(k).FORMAT: k for k in FAMILIES} == FORMATS
    assert all(family(k).KIND == k for k in FAMILIES)


def test_the_coupling_study_changes_an_adaptive_setting_and_refuses_an_unknown_one(tmp_path):
    """``polydem study coupling --adaptive KEY=VALUE`` (the speed-error trade): with an indicator tolerance no strain
    jump reaches, the adaptive run stops after its first solve (one stage, the coarse mesh), where the example's own
    tolerance refines; the settings run are in results.json; an unknown key or a value of the wrong kind is refused
    before anything is written."""
    import json

    from click.testing import CliRunner

    from polydem_cli.cli import main

    base = ["study", "coupling", "--width", "24", "--rows", "14", "--example", "homogeneous_elastic"]
    stages = {}
    for tag, extra in (("own", []), ("loose", ["--adaptive", "tol=1e9"])):
        out = tmp_path / tag
        r = CliRunner().invoke(main, [*base, "--out", str(out), *extra])
        assert r.exit_code == 0, r.output
        res = json.loads((out / "results.json").read_text())
        ad = res["examples"]["homogeneous_elastic"]["adaptive"]
        stages[tag] = (len(ad["stages"]), ad["dofs"], ad["settings"]["tol"])
    assert stages["own"][0] > 1 and stages["own"][2] == 0.1
    assert stages["loose"][0] == 1 and stages["loose"][1] < stages["own"][1] and stages["loose"][2] == 1e9
    for bad, why in (
        ("tolerance=0.3", "the settings are"),
        ("buffer=1.5", "must be an integer"),
        ("tol=x", "not a number"),
        ("coarse_side=3", "power of two"),
        ("tol=0", "must be > 0"),
    ):
        r = CliRunner().invoke(main, [*base, "--out", str(tmp_path / "bad"), "--adaptive", bad])
        assert r.exit_code == 2 and why in r.output, r.output
        assert not (tmp_path / "bad").exists()


def test_a_cold_start_is_announced_and_the_first_progress_line_names_no_peak_before_an_event(tmp_path, monkeypatch):
    """The quasi-static solver compiles its kernels silently for half a minute on a fresh install (issue 51): it says
    so, and when it is done; its first progress line read "reaction 74.14 dyn (peak 0)" — a refinement solve's load
    with a peak of no event yet."""
    import io

    import polydem_cli.solvers.quasistatic as qs
    from polydem_cli.scenario.load import load_scenario
    from polydem_cli.solvers import driver
    from polydem_cli.solvers.protocol import RunOptions, Source

    monkeypatch.setattr(qs, "cached", lambda pattern: False)  # as on a fresh install (the kernels load as usual)
    scen = SCEN / "coupling" / "smoke_homogeneous_softening.toml"
    sc, text = load_scenario(scen, [])
    err = io.StringIO()
    driver.obtain(sc, tmp_path / "r.h5", source=Source(str(scen), text, ()), opts=RunOptions(stream=err))
    lines = err.getvalue().replace("\r", "\n").splitlines()
    assert lines[0].startswith("compiling the lattice and coupling kernels"), lines[:3]
    assert any(ln.startswith("compiled in ") for ln in lines)
    first = next(ln for ln in lines if "solve 1 |" in ln)
    assert "no event yet" in first and "peak 0" not in first and "next event at" in first, first
    last = [ln for ln in lines if "| event " in ln][-1]
    assert "peak so far" in last, last
