"""Results written by an earlier polydem (tests/data/old_results, gzipped: the smoke concrete panel pulled until
two beams failed, explicit format 1, and the smoke heterogeneous-softening plate, quasi-static format 1, both
written by code version 0.1.0+g1f7c2ad, before the solver driver and the interaction families were reorganised)
still read and report with today's code."""

import gzip
import json
import shutil
from pathlib import Path

import matplotlib

matplotlib.use("Agg")

from polydem_cli.io.hdf5 import read_bonds, read_frames, read_history, read_static  # noqa: E402
from polydem_cli.report.make import family_report, make_report  # noqa: E402
from polydem_cli.solvers import family_of_result, result_family  # noqa: E402

DATA = Path(__file__).parent / "data" / "old_results"


def _unpacked(name, tmp_path) -> Path:
    out = tmp_path / name
    with gzip.open(DATA / f"{name}.gz", "rb") as src, open(out, "wb") as dst:
        shutil.copyfileobj(src, dst)
    return out


def test_an_explicit_result_of_the_earlier_code_reads_and_reports(tmp_path):
    path = _unpacked("panel_v1.h5", tmp_path)
    assert result_family(path).KIND == "explicit" and family_of_result(path) is None
    st = read_static(path)
    assert len(st["mass"]) == 64 and "specimen.top" in st["sets"]
    cols, tab = read_history(path)
    assert "elastic_bonds" in cols and tab.shape[1] == len(cols) and tab.shape[0] >= 3
    steps, times, x, v = read_frames(path)
    assert x.shape[1:] == (64, 3) and len(steps) == len(times) >= 2
    b = read_bonds(path)
    assert len(b["L"]) == 162 and b["frame_d"].shape == (len(steps), 162)
    assert (b["fail_step"] >= 0).sum() == 2  # the two beams that failed in that run
    files = {p.name for p in make_report(path, tmp_path / "report")}
    for fig in (
        "history",
        "frames",
        "specimen",
        "load",
        "damage",
        "strains",
        "stress_strain",
        "damage_end",
        "failures",
    ):
        assert f"panel_v1_{fig}.png" in files, fig
    assert all((tmp_path / "report" / f).exists() for f in files)


def test_a_quasistatic_result_of_the_earlier_code_reads_and_reports(tmp_path):
    path = _unpacked("qs_v1.h5", tmp_path)
    fam = family_of_result(path)
    assert fam is not None and result_family(path).KIND == "quasistatic"
    files = family_report(fam, path, tmp_path / "report")
    assert files and all(Path(f).exists() for f in files)
    import h5py

    with h5py.File(path, "r") as f:
        summary = json.loads(f.attrs["summary"])
    assert summary["events"] == 22 and summary["damaged_members"] == 5
