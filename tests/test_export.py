"""``polydem export``: a result as a VTKHDF time series, read back with VTK's own reader (vtkHDFReader): the
cell and step counts, every particle polygon's area and centroid against the result's particle table and frames
(rigid bodies keep their area; the body vertices are relative to the centroid), beam damage against the frames."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from conftest import DYN_PER_UNIT, SCEN

vtk = pytest.importorskip("vtk")  # the test extra installs it


@pytest.fixture(scope="module")
def result(tmp_path_factory):
    from polydem_cli.cli import main

    d = tmp_path_factory.mktemp("export")
    out = d / "tension.h5"
    r = CliRunner().invoke(
        main,
        [
            "run",
            str(SCEN / "ch7" / "smoke_concrete_tension.toml"),
            "-o",
            str(out),
            "-q",
            "--set",
            "output.frame_times=[]",
        ],
    )
    assert r.exit_code == 0, r.output
    return out


def _polygon_area_centroid(p):
    x, y = p[:, 0], p[:, 1]
    xn, yn = np.roll(x, -1), np.roll(y, -1)
    cr = x * yn - xn * y
    a = cr.sum() / 2
    return a, np.array([((x + xn) * cr).sum(), ((y + yn) * cr).sum()]) / (6 * a)


def test_export_reads_back_in_vtk_with_the_result_geometry_and_fields(result, tmp_path):
    from vtk.util.numpy_support import vtk_to_numpy

    from polydem_cli.cli import main
    from polydem_cli.io.hdf5 import read_bonds, read_frames, read_static

    out = tmp_path / "t.vtkhdf"
    r = CliRunner().invoke(main, ["export", str(result), "--vtk", str(out)])
    assert r.exit_code == 0, r.output
    st = read_static(result)
    steps, times, X, V = read_frames(result)
    bonds = read_bonds(result)
    n, nb = len(st["mass"]), len(bonds["pairs"])
    rd = vtk.vtkHDFReader()
    rd.SetFileName(str(out))
    rd.UpdateInformation()
    assert rd.GetNumberOfSteps() == len(steps) >= 2
    for k in (0, len(steps) - 1):
        rd.SetStep(k)
        rd.Update()
        g = rd.GetOutput()
        assert g.GetNumberOfCells() == n + nb
        assert [g.GetCellType(i) for i in (0, n - 1, n, n + nb - 1)] == [7, 7, 3, 3]
        pts = vtk_to_numpy(g.GetPoints().GetData())
        for i in range(0, n, max(1, n // 25)):
            ids = g.GetCell(i).GetPointIds()
            poly = pts[[ids.GetId(q) for q in range(ids.GetNumberOfIds())], :2]
            a, c = _polygon_area_centroid(poly)
            assert a == pytest.approx(st["area"][i], rel=1e-9)
            assert np.allclose(c, X[k][i, :2], rtol=0, atol=1e-9)
        cd = g.GetCellData()
        vel = vtk_to_numpy(cd.GetArray("velocity"))
        assert np.allclose(vel[:n, :2], V[k][:, :2])
        assert np.allclose(vtk_to_numpy(cd.GetArray("damage"))[n:], bonds["frame_d"][k])
        assert np.all(np.isnan(vtk_to_numpy(cd.GetArray("damage"))[:n]))
        assert np.array_equal(vtk_to_numpy(cd.GetArray("group"))[:n], st["group"])
    assert (tmp_path / "t.vtkhdf").exists() and not list(tmp_path.glob("*.part"))


def test_export_without_bonds_has_no_beam_fields(tmp_path):
    """A scene without bonds: no beam cells and no damage or kappa arrays (all NaN otherwise); VTK reads it."""
    import shutil

    from vtk.util.numpy_support import vtk_to_numpy

    from polydem_cli.cli import main

    scen = tmp_path / "pile.toml"
    shutil.copy(SCEN / "demo_hex_pile.toml", scen)
    res = tmp_path / "pile.h5"
    r = CliRunner().invoke(main, ["run", str(scen), "-o", str(res), "-q", "--set", "time.end_displacement=0.02"])
    assert r.exit_code == 0, r.output
    r = CliRunner().invoke(main, ["export", str(res)])
    assert r.exit_code == 0, r.output
    rd = vtk.vtkHDFReader()
    rd.SetFileName(str(tmp_path / "pile.vtkhdf"))
    rd.Update()
    cd = rd.GetOutput().GetCellData()
    names = {cd.GetArrayName(i) for i in range(cd.GetNumberOfArrays())}
    assert {"velocity", "displacement", "kind", "group"} <= names
    assert not names & {"damage", "kappa"}
    assert set(vtk_to_numpy(cd.GetArray("kind"))) == {0}


def test_export_of_a_missing_result_is_refused(tmp_path):
    from polydem_cli.cli import main

    r = CliRunner().invoke(main, ["export", str(tmp_path / "nope.h5")])
    assert r.exit_code == 2 and "no such result file" in r.output
    assert not list(tmp_path.iterdir())


def test_movie_has_every_frame_and_one_colour_scale(result, tmp_path):
    import h5py
    from PIL import Image

    from polydem_cli.report.movie import make_movie

    info = make_movie(result, tmp_path / "m.gif")
    with h5py.File(result, "r") as f:
        nframes = len(f["frames/step"])
        v2 = f["frames/v"][:, :, 1]
        radius = f["particles/radius"][...]
    assert Image.open(tmp_path / "m.gif").n_frames == nframes == info["frames"]
    free = radius <= 4 * np.median(radius)
    assert info["v_limit"] == pytest.approx(max(np.percentile(np.abs(v2[k, free]), 99) for k in range(nframes)))
    assert not list(tmp_path.glob("*.part.*"))


def test_report_formats_write_every_figure_as_vector_graphics_too(result, tmp_path, monkeypatch):
    """Every figure also as PDF and SVG; ``--movie`` asks the movie of the result beside them (its frames and colour
    scale are the movie test's, above: here it is only asked for, with its file name, not drawn a second time)."""
    from polydem_cli.cli import main
    from polydem_cli.report import movie

    asked = []

    def made(src, dest, **kw):
        asked.append((Path(src), Path(dest)))
        Path(dest).write_bytes(b"GIF89a")
        return {"file": Path(dest), "frames": 0}

    monkeypatch.setattr(movie, "make_movie", made)
    r = CliRunner().invoke(main, ["report", str(result), "--out", str(tmp_path), "--format", "png,pdf,svg", "--movie"])
    assert r.exit_code == 0, r.output
    assert asked == [(Path(result), tmp_path / "tension_movie.gif")]
    pngs = sorted(p.stem for p in tmp_path.glob("*.png"))  # the movie is a gif
    assert len(pngs) >= 5
    for ext, magic in (("pdf", b"%PDF"), ("svg", b"<?xml")):
        assert sorted(p.stem for p in tmp_path.glob(f"*.{ext}")) == pngs
        assert all((tmp_path / f"{s}.{ext}").read_bytes()[:5].startswith(magic) for s in pngs)
    r = CliRunner().invoke(main, ["report", str(result), "--out", str(tmp_path / "x"), "--format", "png,jpg"])
    assert r.exit_code == 2 and "formats are png, pdf and svg" in r.output


def test_report_at_a_time_and_at_a_displacement(result, tmp_path, monkeypatch):
    from polydem_cli.cli import main
    from polydem_cli.report import basic

    seen = {}
    real = basic.plot_frames

    def spy(res, png, times=None, max_panels=4, **kw):
        seen["times"] = times
        return real(res, png, times, max_panels, **kw)

    monkeypatch.setattr(basic, "plot_frames", spy)
    r = CliRunner().invoke(main, ["report", str(result), "--out", str(tmp_path), "--at", "t=0.005", "--at", "u2=0.004"])
    assert r.exit_code == 0, r.output
    assert seen["times"] == [0.005]
    r = CliRunner().invoke(main, ["report", str(result), "--out", str(tmp_path), "--at", "x=1"])
    assert r.exit_code == 2 and "expected t=<seconds> or u2=<cm>" in r.output


def test_report_of_several_results_overlays_their_curves(result, tmp_path):
    import shutil

    from polydem_cli.cli import main

    other = tmp_path / "tension_copy.h5"
    shutil.copy(result, other)
    r = CliRunner().invoke(main, ["report", str(result), str(other), "--out", str(tmp_path / "rep")])
    assert r.exit_code == 0, r.output
    png = tmp_path / "rep" / "overlay_stress_strain.png"
    assert png.stat().st_size > 20_000
    assert (tmp_path / "rep" / "tension_frames.png").exists() and (
        tmp_path / "rep" / "tension_copy_frames.png"
    ).exists()


def test_magnified_pictures_draw_x0_plus_factor_times_the_displacement(result, tmp_path, monkeypatch):
    import h5py

    from polydem_cli.report import basic, make

    drawn = []
    real = basic.world_polygons

    def spy(static, x):
        drawn.append(np.array(x))
        return real(static, x)

    monkeypatch.setattr(basic, "world_polygons", spy)
    make.make_report(result, tmp_path, magnify=50.0)
    with h5py.File(result, "r") as f:
        X = f["frames/x"][...]
        x0 = f["particles/x0"][...]
    last = x0 + 50.0 * (X[-1] - x0)
    assert any(np.allclose(d, last, rtol=0, atol=1e-9) for d in drawn)
    assert not any(np.allclose(d, X[-1], rtol=0, atol=1e-9) for d in drawn)
    drawn.clear()  # the magnification is the report's argument, not a setting left behind
    make.make_report(result, tmp_path / "plain")
    assert any(np.allclose(d, X[-1], rtol=0, atol=1e-9) for d in drawn)


def test_the_curves_of_the_figures_are_the_result_data(result, tmp_path):
    """Every curve figure has its plotted data beside it (CSV from the artists); the stress-strain and load
    curves equal the history columns of the result (stress in N/mm² = 1e7 dyn/cm²)."""
    import csv
    import json

    import h5py

    from polydem_cli.report import make

    make.make_report(result, tmp_path)
    with h5py.File(result, "r") as f:
        t = f["history/table"]
        cols = [c if isinstance(c, str) else c[0] for c in json.loads(t.attrs["columns"])]
        h = t[...]

    def curve(name, label=None):
        with open(tmp_path / name) as fh:
            rows = [r for r in csv.DictReader(fh) if r["panel"] == "0" and r["curve"] == "0"]
        curve.y_label = rows[0]["y_label"]
        return np.array([[float(r["x"]), float(r["y"])] for r in rows])

    ss = curve("tension_stress_strain_plotted.csv")
    assert np.allclose(ss[:, 0], h[:, cols.index("eps22")]) and np.allclose(ss[:, 1], h[:, cols.index("sigma22")] / 1e7)
    ld = curve("tension_load_plotted.csv")
    top = [c for c in cols if c.startswith("f2:") and "top" in c][0].split(":", 1)[1]
    dyn = DYN_PER_UNIT[curve.y_label.split()[-1].strip("[]")]  # forces in dyn, drawn in kN, N, ... nN
    assert np.allclose(ld[:, 0], h[:, cols.index("u2:" + top)])
    assert np.allclose(ld[:, 1] * dyn, h[:, cols.index("f2:" + top)])
    assert not (tmp_path / "tension_frames_plotted.csv").exists()  # a particle picture has no curves


def test_batch_runs_resumes_reuses_and_reports_failures(tmp_path):
    import subprocess

    from conftest import polydem_cmd

    bad = tmp_path / "bad.toml"
    bad.write_text('[scenario]\ntitle = "x"\n[time]\ndt = -1.0\n')
    a = tmp_path / "a.h5"
    jobs = [
        f"{SCEN / 'ch7' / 'smoke_concrete_tension.toml'}={a}",
        f"{bad}={tmp_path / 'b.h5'}",
        f"{SCEN / 'ch7' / 'smoke_concrete_tension.toml'}={a}",
    ]
    r = subprocess.run(polydem_cmd() + ["batch", *jobs], capture_output=True, text=True)
    assert r.returncode == 1, r.stdout + r.stderr
    assert "batch: 3 runs — 1 ran, 0 resumed, 1 reused, 1 failed" in r.stdout
    assert "time.dt" in r.stdout and "[run 2 of 3]" in r.stderr
    assert a.exists() and not (tmp_path / "b.h5").exists()


def test_batch_runs_in_parallel_after_the_runs_they_start_from(tmp_path):
    """``batch -j 2``: a run whose [initial_state] is another item's result starts only after that item has
    finished; one whose starting run failed is skipped with the reason; the others share the two slots."""
    import re
    import subprocess

    from conftest import polydem_cmd

    base = SCEN / "lh" / "smoke_disk_compression.toml"
    first = tmp_path / "first.toml"
    first.write_text(f'[scenario]\nextends = "{base}"\n[time]\nend_time = 0.002\n')
    other = tmp_path / "other.toml"
    other.write_text(f'[scenario]\nextends = "{base}"\nseed = 2\n[time]\nend_time = 0.002\n')
    second = tmp_path / "second.toml"
    second.write_text(first.read_text() + '[initial_state]\nfile = "first.h5"\n')
    bad = tmp_path / "bad.toml"
    bad.write_text(f'[scenario]\nextends = "{base}"\n[time]\nend_time = -1.0\n')
    orphan = tmp_path / "orphan.toml"
    orphan.write_text(first.read_text() + '[initial_state]\nfile = "bad.h5"\n')
    items = [f"{first}={tmp_path / 'first.h5'}", f"{other}={tmp_path / 'other.h5'}", f"{bad}={tmp_path / 'bad.h5'}"]
    items += [f"{second}={tmp_path / 'second.h5'}", f"{orphan}={tmp_path / 'orphan.h5'}"]
    r = subprocess.run(polydem_cmd() + ["batch", "-j", "2", *items], capture_output=True, text=True)
    assert r.returncode == 1, r.stdout + r.stderr
    assert "batch: 5 runs — 3 ran, 0 resumed, 0 reused, 1 failed, 1 skipped" in r.stdout, r.stdout + r.stderr
    assert re.search(r"skipped: \S*orphan.h5: it needs \S*bad.h5", r.stdout)
    log = r.stderr.splitlines()
    done_first = next(i for i, s in enumerate(log) if "first.h5: done" in s)
    start_second = next(i for i, s in enumerate(log) if "second.h5: started" in s)
    start_other = next(i for i, s in enumerate(log) if "other.h5: started" in s)
    assert start_second > done_first and start_other < done_first  # the independent run did not wait
    import h5py

    with h5py.File(tmp_path / "first.h5") as a, h5py.File(tmp_path / "second.h5") as b:
        assert np.array_equal(a["frames/x"][-1], b["frames/x"][0])  # second started where first ended


def test_batch_stopped_by_sigterm_leaves_its_runs_resumable(tmp_path):
    """SIGTERM to ``polydem batch`` (a job scheduler's stop, a killed make) reaches the running runs: each
    checkpoints and stops, the batch exits 130, and the same command would resume them."""
    import signal
    import subprocess
    import time

    import h5py

    from polydem_cli.workflows.batch import result_state as _state

    from conftest import polydem_cmd

    base = SCEN / "lh" / "smoke_disk_compression.toml"
    scen = tmp_path / "long.toml"
    scen.write_text(f'[scenario]\nextends = "{base}"\n[time]\nend_time = 2.0\n')
    res = tmp_path / "long.h5"
    p = subprocess.Popen(
        polydem_cmd() + ["batch", f"{scen}={res}"], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True
    )
    t0 = time.time()
    while time.time() - t0 < 120:  # until the run has written its first frames
        time.sleep(0.5)
        if res.exists() and (tmp_path / "long.h5.writer").exists():
            try:
                with h5py.File(res, "r", locking=False) as f:
                    if f["frames/step"].shape[0] >= 2:
                        break
            except (OSError, KeyError):
                pass
    p.send_signal(signal.SIGTERM)
    out, err = p.communicate(timeout=120)
    assert p.returncode == 130, out + err
    assert "resume with the same command" in err
    assert _state(scen, res) == "resumable"


def test_batch_plans_its_eta_from_the_scenarios(tmp_path):
    """The list's ETA: a dynamic scenario is planned as end step x particles (from the built system), a
    quasi-static one and one whose initial state is still to be run are not; pending runs at the measured
    particle-steps rate, running ones by their own ETA, over the slots."""
    from polydem_cli.scenario.build import build_system
    from polydem_cli.scenario.load import load_scenario
    from polydem_cli.workflows.batch import Job as _Job
    from polydem_cli.workflows.batch import _inspect, batch_eta

    path = SCEN / "ch7" / "smoke_concrete_tension.toml"
    sc, _ = load_scenario(path)
    s = build_system(sc, str(path))
    start, plan, kind_panel = _inspect(path)
    assert start is None and plan == float(s.end_step) * s.n
    assert kind_panel == ("verlet", "voronoi", True, False)  # concrete_tension.toml: verlet, Voronoi cells, ru beams
    assert _inspect(SCEN / "coupling" / "smoke_homogeneous_elastic.toml")[1] is None
    orphan = tmp_path / "o.toml"
    orphan.write_text(
        f'[scenario]\nextends = "{SCEN / "lh" / "smoke_disk_compression.toml"}"\n[initial_state]\nfile = "x.h5"\n'
    )
    start, plan, kind = _inspect(orphan)
    assert start == (tmp_path / "x.h5").resolve() and plan is None
    assert kind != kind_panel  # disks, no beams: another cost per particle-step
    a, b, c = _Job(1, path, tmp_path / "a.h5"), _Job(2, path, tmp_path / "b.h5"), _Job(3, orphan, tmp_path / "c.h5")
    a.status, a.eta, a.rate = "running", 100.0, 1.0e6
    b.plan, c.plan = 4.0e8, None
    left, unknown = batch_eta([a, b, c], 1)
    assert left == pytest.approx(100.0 + 400.0) and unknown == 1
    left, _ = batch_eta([a, b, c], 2)
    assert left == pytest.approx(max(500.0 / 2, 100.0))


def test_batch_eta_plans_a_pending_run_at_the_rate_of_its_own_kind():
    """A batch mixes runs whose particle-steps rates differ by more than 10x (LH disks ~1e7/s, the thesis-form
    concrete runs ~1e6/s): a pending bonded panel is planned at the rate of bonded panels, not at the batch's
    mean, and a kind not yet measured at the slowest rate measured (the ETA of the whole figure target was
    2:11 h while its slow concrete runs alone needed more than 4 h)."""
    from polydem_cli.workflows.batch import Job as _Job
    from polydem_cli.workflows.batch import batch_eta

    disks, panel = ("verlet1", "random_disks", False, False), ("gear5", "voronoi", True, True)
    done_disks = _Job(1, "d.toml", "d.h5")
    done_disks.status, done_disks.rate, done_disks.kind = "ran", 1.0e7, disks
    done_panel = _Job(2, "p.toml", "p.h5")
    done_panel.status, done_panel.rate, done_panel.kind = "ran", 1.0e6, panel
    pend = _Job(3, "q.toml", "q.h5")
    pend.plan, pend.kind = 3.6e9, panel
    left, unknown = batch_eta([done_disks, done_panel, pend], 1)
    assert left == pytest.approx(3600.0) and unknown == 0  # 3.6e9 at 1e6/s, not at the mean 5.5e6/s
    new_kind = _Job(4, "n.toml", "n.h5")
    new_kind.plan, new_kind.kind = 1.0e9, ("gear5", "hexagon_packing", False, False)
    left, _ = batch_eta([done_disks, done_panel, new_kind], 1)
    assert left == pytest.approx(1000.0)  # no hexagon run measured yet: the slowest rate, 1e6/s


def test_batch_plans_pending_runs_at_the_rate_a_reused_result_recorded(tmp_path):
    """A batch resumed after most of its runs have finished (``make figures`` again) plans its pending runs at
    the particle-steps rate the reused results of their kind recorded, not at the slowest rate of whatever has
    run since; a result measured on another thread count, or without a summary, gives none."""
    import json
    import subprocess

    import h5py

    from polydem_cli.workflows.batch import _recorded_rate, batch_eta
    from polydem_cli.workflows.batch import read_list as _read_list

    from conftest import polydem_cmd

    base = SCEN / "lh" / "smoke_disk_compression.toml"
    scen = tmp_path / "short.toml"
    scen.write_text(f'[scenario]\nextends = "{base}"\n[time]\nend_time = 0.002\n')
    res = tmp_path / "short.h5"
    r = subprocess.run(
        polydem_cmd() + ["run", str(scen), "-o", str(res), "--threads", "1", "-q"], capture_output=True, text=True
    )
    assert r.returncode == 0, r.stdout + r.stderr
    with h5py.File(res) as f:
        summ = json.loads(f.attrs["summary"])
    assert summ["threads"]["used"] == [1] and summ["particle_steps_per_s"] > 0
    assert _recorded_rate(res, "1") == pytest.approx(summ["particle_steps_per_s"])
    assert _recorded_rate(res, "2") is None  # measured on one thread: not the rate of a two-thread run
    assert _recorded_rate(tmp_path / "absent.h5", "1") is None
    # the batch reading its list: the finished result's rate plans a pending run of the same scenario (kind)
    done, pending = _read_list([f"{scen}={res}", f"{scen}={tmp_path / 'next.h5'}"], "1")
    assert done.rate == pytest.approx(summ["particle_steps_per_s"]) and pending.rate is None
    done.status = "reused"
    left, unknown = batch_eta([done, pending], 1)
    assert unknown == 0 and left == pytest.approx(pending.plan / summ["particle_steps_per_s"])
    assert _read_list([f"{scen}={res}"], "2")[0].rate is None
