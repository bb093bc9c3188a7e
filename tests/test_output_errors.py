"""Every command that writes, on a place that cannot be written: one line naming the path and the reason, exit
code 2, before any work and nothing left behind (no traceback).  A report stopped by Ctrl-C says what it wrote
and what it did not, and leaves no half-written figure.  A scenario given where a result is expected (and the
other way round) is named as such.

Places that cannot be written even by root: a folder under a regular file (``afile/sub``) and /proc."""

import shutil
import subprocess

import pytest
from click.testing import CliRunner

from polydem_cli.cli import main

from conftest import SCEN, polydem_cmd

PILE = ["--set", "time.end_displacement=0.02"]  # a second or two


@pytest.fixture(scope="module")
def pile(tmp_path_factory):
    """A finished tiny result (40 hexagons, two frames, no bonds) and its scenario."""
    d = tmp_path_factory.mktemp("pile")
    scen = d / "pile.toml"
    shutil.copy(SCEN / "demo_hex_pile.toml", scen)
    out = d / "pile.h5"
    r = CliRunner().invoke(main, ["run", str(scen), "-o", str(out), "-q"] + PILE)
    assert r.exit_code == 0, r.output
    return scen, out


def _files(d):
    return sorted(str(p.relative_to(d)) for p in d.rglob("*"))


def _one_error_line(r, path):
    assert r.exit_code == 2, (r.output, r.exception)
    assert r.exception is None or isinstance(r.exception, SystemExit), r.exception
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1, r.stderr
    assert lines[0].startswith("error: ") and str(path) in lines[0], lines[0]
    return lines[0]


@pytest.mark.parametrize(
    "args,target,reason",
    [
        (["report", "{res}", "--out", "{tmp}/afile/rep"], "{tmp}/afile/rep", "afile is a file, not a folder"),
        (["report", "{res}", "--out", "/proc/polydem-no"], "/proc/polydem-no", "files cannot be created in /proc"),
        (["report", "{res}", "--out", "{tmp}/afile/c", "--region", "0,5,0,5"], "{tmp}/afile/c", "afile is a file"),
        (["export", "{res}", "--vtk", "{tmp}/afile/x.vtkhdf"], "{tmp}/afile/x.vtkhdf", "afile is a file"),
        (["export", "{res}", "--vtk", "/proc/x.vtkhdf"], "/proc/x.vtkhdf", "files cannot be created in /proc"),
        (["batch", "{scen}={tmp}/ok.h5", "{scen}={tmp}/afile/r.h5"], "{tmp}/afile/r.h5", "afile is a file"),
        (["schema", "--out", "{tmp}/afile/s.md"], "{tmp}/afile/s.md", "afile is a file"),
        (["study", "integrators", "--out", "{tmp}/afile/st"], "{tmp}/afile/st", "afile is a file"),
        (
            ["study", "timestep", "{scen}", "--dt", "1e-5", "--out", "{tmp}/afile/st"] + PILE,
            "{tmp}/afile/st",
            "afile is a file",
        ),
        (["study", "index", "--figures", "{tmp}/afile/figs"], "{tmp}/afile/figs/INDEX.md", "afile is a file"),
        (["sweep", "{scen}", "--set", "time.dt=1e-5", "--out", "{tmp}/afile/sw"], "{tmp}/afile/sw", "afile is a file"),
        (
            ["calibrate", "{scen}", "--target", "E=30GPa", "-o", "{tmp}/afile/c.toml"],
            "{tmp}/afile/c.toml",
            "afile is a",
        ),
    ],
    ids=[
        "report-under-file",
        "report-proc",
        "closeup",
        "export-under-file",
        "export-proc",
        "batch",
        "schema",
        "study-integrators",
        "study-timestep",
        "study-index",
        "sweep",
        "calibrate",
    ],
)
def test_an_output_that_cannot_be_written_is_one_line_before_any_work(pile, tmp_path, args, target, reason):
    scen, res = pile
    (tmp_path / "afile").write_text("x")
    before = _files(tmp_path)
    fill = {"res": res, "scen": scen, "tmp": tmp_path}
    r = CliRunner().invoke(main, [a.format(**fill) for a in args])
    line = _one_error_line(r, target.format(**fill))
    assert "cannot write" in line and reason in line, line
    assert _files(tmp_path) == before  # nothing written, not even a temporary file


def test_bench_refuses_an_unwritable_out_before_it_measures(tmp_path, monkeypatch):
    from polydem_cli.benchmarks import bench

    calls = []
    monkeypatch.setattr(bench, "run_bench", lambda *a, **k: calls.append(a))
    (tmp_path / "afile").write_text("x")
    r = CliRunner().invoke(main, ["bench", "dense_N1e3", "--out", str(tmp_path / "afile" / "b.json")])
    line = _one_error_line(r, tmp_path / "afile" / "b.json")
    assert "cannot write the benchmark there" in line
    assert calls == []


def test_overwrite_of_a_result_that_cannot_be_removed(pile, tmp_path, monkeypatch):
    import pathlib

    scen, res = pile
    out = tmp_path / "r.h5"
    shutil.copy(res, out)
    real = pathlib.Path.unlink

    def unlink(self, missing_ok=False):  # as for a file of another user in a sticky folder
        if self == out:
            raise PermissionError(13, "Permission denied", str(self))
        return real(self, missing_ok=missing_ok)

    monkeypatch.setattr(pathlib.Path, "unlink", unlink)
    r = CliRunner().invoke(main, ["run", str(scen), "-o", str(out), "-q", "--overwrite"] + PILE)
    line = _one_error_line(r, out)
    assert "cannot remove the existing result (Permission denied)" in line
    assert out.read_bytes() == res.read_bytes()


def test_report_stopped_by_ctrl_c_says_what_it_wrote_and_what_not(pile, tmp_path, monkeypatch):
    """Ctrl-C during the third figure: exit 130 as polydem run, the figures written named, the rest said to be
    missing (not click's bare "Aborted!")."""
    from polydem_cli.report import basic

    def interrupted(*a, **k):
        raise KeyboardInterrupt

    monkeypatch.setattr(basic, "plot_history", interrupted)
    _, res = pile
    rep = tmp_path / "rep"
    r = CliRunner().invoke(main, ["report", str(res), "--out", str(rep)])
    assert r.exit_code == 130, (r.output, r.exception)
    figs = sorted(p.name for p in rep.glob("*.png"))
    assert figs and "pile_history.png" not in figs
    msg = r.stderr.strip()
    assert "Aborted" not in r.output and len(msg.splitlines()) == 1, msg
    assert msg.startswith("report interrupted by signal 2: "), msg
    assert f"wrote {len(figs)} figure file(s) in {rep} ({', '.join(figs)})" in msg, msg
    assert f"not written: the remaining figures of {res}" in msg, msg
    assert not [p for p in rep.iterdir() if p.name.startswith(".")]


def test_a_figure_interrupted_while_being_written_is_not_left_half_written(pile, tmp_path, monkeypatch):
    from matplotlib.figure import Figure

    real = Figure.savefig
    n = []

    def savefig(self, fname, *a, **k):
        n.append(fname)
        if len(n) == 2:  # the second figure: some bytes, then Ctrl-C
            with open(fname, "wb") as fh:
                fh.write(b"\x89PNG half")
            raise KeyboardInterrupt
        return real(self, fname, *a, **k)

    monkeypatch.setattr(Figure, "savefig", savefig)
    _, res = pile
    rep = tmp_path / "rep"
    r = CliRunner().invoke(main, ["report", str(res), "--out", str(rep)])
    assert r.exit_code == 130, (r.output, r.exception)
    files = list(rep.iterdir())
    assert len(files) >= 1 and all(b"half" not in p.read_bytes() for p in files), files


def test_a_scenario_or_an_empty_file_given_as_a_result_is_named(pile, tmp_path):
    scen, res = pile
    empty = tmp_path / "empty.toml"
    empty.write_text("")
    for cmd in (["report"], ["export"], ["run", "--resume"]):
        r = CliRunner().invoke(main, cmd + [str(scen)])
        line = _one_error_line(r, scen)
        assert "a scenario file, not a result" in line and f"polydem run {scen}" in line, line
        assert "HDF5" not in line, line
    r = CliRunner().invoke(main, ["report", str(empty)])
    assert "file is empty" in _one_error_line(r, empty)
    r = CliRunner().invoke(main, ["check", str(res)])  # and a result given as a scenario
    line = _one_error_line(r, res)
    assert "a result file (HDF5), not a scenario" in line and f"polydem report {res}" in line, line
    assert not list(tmp_path.glob("*.vtkhdf")) and not list(scen.parent.glob("*.vtkhdf"))


def test_export_failing_while_writing_leaves_no_part_file(pile, tmp_path, monkeypatch):
    """An OSError inside the VTKHDF writer (a full disk): one line, the temporary file removed."""
    import h5py

    _, res = pile
    real = h5py.Group.create_dataset

    def full(self, name, *a, **k):
        if name == "Points":
            raise OSError(28, "No space left on device")
        return real(self, name, *a, **k)

    monkeypatch.setattr(h5py.Group, "create_dataset", full)
    out = tmp_path / "x.vtkhdf"
    r = CliRunner().invoke(main, ["export", str(res), "--vtk", str(out)])
    line = _one_error_line(r, out)
    assert "No space left on device" in line, line
    assert list(tmp_path.iterdir()) == []


def test_unwritable_output_of_a_subprocess_run_is_one_line(pile, tmp_path):
    """The same through the console script (no click runner in between)."""
    _, res = pile
    (tmp_path / "afile").write_text("x")
    r = subprocess.run(
        polydem_cmd() + ["export", str(res), "--vtk", str(tmp_path / "afile" / "x.vtkhdf")],
        capture_output=True,
        text=True,
    )
    assert r.returncode == 2 and "Traceback" not in r.stderr, r.stderr
    assert r.stderr.startswith(f"error: {tmp_path / 'afile' / 'x.vtkhdf'}: cannot write the export there"), r.stderr
