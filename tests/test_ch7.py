"""Chapter 7 (concrete, glued nuts): smoke runs through the CLI, the report, the collation of
Figs. 7.3-7.13 and the DIF study, on small specimens and short horizons."""

import json
import subprocess

import numpy as np
import pytest

from conftest import SCEN, polydem_cmd

CH7 = SCEN / "ch7"


def _cli(args, cwd):
    r = subprocess.run(polydem_cmd() + args, capture_output=True, text=True, cwd=cwd)
    assert r.returncode == 0, r.stdout + r.stderr
    return r


@pytest.fixture(scope="module")
def smoke_runs(tmp_path_factory):
    """The smoke versions of the main job (tension, compression), a rate-dependent run and the glued nuts,
    run through ``polydem run`` under the stems the collation expects."""
    d = tmp_path_factory.mktemp("ch7")
    runs = d / "runs"
    out = {}
    for stem, scen in (
        ("concrete_tension", "smoke_concrete_tension"),
        ("concrete_compression", "smoke_concrete_compression"),
        ("tension_fast_ra", "smoke_tension_ra"),
        ("nuts_glued_small", "smoke_nuts_glued"),
        ("nuts_glued_large", "smoke_nuts_glued"),
    ):
        r = _cli(["run", str(CH7 / f"{scen}.toml"), "-o", str(runs / f"{stem}.h5"), "--threads", "1"], d)
        out[stem] = (runs / f"{stem}.h5", r.stdout)
    return d, out


def test_main_job_smoke_prints_and_stores_macroscopic_measures(smoke_runs):
    d, out = smoke_runs
    path, stdout = out["concrete_tension"]
    assert "E = " in stdout and "GPa" in stdout and "nu = " in stdout and "tensile strength" in stdout
    s = json.loads(path.with_suffix(".summary.json").read_text())
    m = s["macro"]
    assert m["kind"] == "tension" and m["E"] > 0 and 0.0 < m["nu"] < 0.5
    # concrete parameters: E of the order of the thesis's 33.5 GPa, strength of the order of 2.9 N/mm^2
    assert 20 < m["E_GPa"] < 50 and 1.0 < m["peak_stress_MPa"] < 6.0
    assert m["definition"]["L1"] == 8.0 and m["definition"]["L2"] == 8.0
    assert s["bond_failure"]["failed"] >= 0 and set(s["bond_failure"]["by_mode"]) >= {"tension", "bending", "shear"}
    c = json.loads(out["concrete_compression"][0].with_suffix(".summary.json").read_text())["macro"]
    assert c["kind"] == "compression" and c["peak_stress"] < 0
    assert abs(c["peak_stress"]) > 2 * m["peak_stress"]  # concrete-like: compression much stronger


def test_report_draws_the_stress_strain_curve_from_the_history(smoke_runs, tmp_path):
    from matplotlib import pyplot as plt  # noqa: F401 (backend set by the report)

    from polydem_cli.io.hdf5 import read_history
    from polydem_cli.report import macro as rm

    d, out = smoke_runs
    path = out["concrete_tension"][0]
    r = _cli(["report", str(path), "--out", str(tmp_path)], d)
    for suffix in ("stress_strain", "damage_end", "failures", "load"):
        f = tmp_path / f"concrete_tension_{suffix}.png"
        assert f.exists() and f.stat().st_size > 10_000, suffix
    assert "stress_strain" in r.stdout
    # the plotted data are the history's sigma22 in N/mm^2
    e2, s, e1, definition = rm.macro_curve(path)
    cols, tab = read_history(path)
    assert np.array_equal(s, tab[:, cols.index("sigma22")] / 1e7)
    assert np.array_equal(e2, tab[:, cols.index("eps22")])


def test_stress_strain_of_a_running_result_does_not_call_its_maximum_the_peak(smoke_runs, tmp_path, monkeypatch):
    """A snapshot of a running result (attr snapshot_of, io/hdf5.request_snapshot) may not have reached its
    peak yet: the annotation says 'largest so far'; a finished result's says 'peak'."""
    import shutil

    import h5py
    from matplotlib import pyplot as plt

    from polydem_cli.report import macro as rm

    d, out = smoke_runs
    path = out["concrete_tension"][0]
    snap = tmp_path / "concrete_tension.running.h5"
    shutil.copy(path, snap)
    with h5py.File(snap, "a") as f:
        f.attrs["snapshot_of"] = str(path)
    kept = []
    monkeypatch.setattr(plt, "close", lambda fig=None: kept.append(fig))
    texts = []
    for p in (path, snap):
        rm.plot_stress_strain([(p.stem, p)], tmp_path / f"{p.stem}.png")
        texts.append(" ".join(t.get_text() for ax in kept[-1].axes for t in ax.texts))
    assert "peak " in texts[0] and "so far" not in texts[0]
    assert "largest so far " in texts[1] and "peak " not in texts[1]


def test_glued_nuts_smoke_fails_in_compression_with_recorded_modes(smoke_runs):
    d, out = smoke_runs
    s = json.loads(out["nuts_glued_small"][0].with_suffix(".summary.json").read_text())
    assert s["bonds"]["count"] == 48 and s["bonds"]["perturbed"]
    bf = s["bond_failure"]
    # a hexagon packing has horizontal and diagonal beams only
    assert bf["bonds_by_orientation"] == {"horizontal": 18, "diagonal": 30, "vertical": 0}
    assert s["macro"]["kind"] == "compression"


def test_ch7_collation_writes_every_figure_family(smoke_runs, tmp_path):
    from polydem_cli.reproductions.ch7 import collate

    d, out = smoke_runs
    res = collate(d / "runs", tmp_path)
    rep = res["reproduced"]
    assert rep["E_GPa"] == pytest.approx(rep["E_GPa_static"], rel=0.05)
    assert "ratio_tension_fast_ra" in rep and rep["nuts_peak_ratio_large_small"] == pytest.approx(1.0)
    for png in (
        "fig7_3",
        "fig7_4",
        "fig7_5",
        "fig7_6",
        "fig7_7",
        "fig7_8",
        "fig7_9a",
        "fig7_10",
        "fig7_11",
        "fig7_12",
        "fig7_13",
        "failures_nuts",
    ):
        f = tmp_path / f"{png}.png"
        assert f.exists() and f.stat().st_size > 10_000, png
    # every curve drawn in the chapter-7 figures is one run's history: (eps22, sigma22 in N/mm^2) or the load
    # curve (u2, f2 in kN) of the driven set
    import csv

    from polydem_cli.io.hdf5 import read_history
    from polydem_cli.report.bonds import load_curve

    pairs = []
    for p in sorted((d / "runs").glob("*.h5")):
        cols, tab = read_history(p)
        if "eps22" in cols:
            pairs.append((tab[:, cols.index("eps22")], tab[:, cols.index("sigma22")] / 1e7))
        u, f, _, _ = load_curve(p)
        pairs += [(u, f / 1e8), (-u, -f / 1e8)]  # the nut curves compression-positive (labels -u2, -f2)
    checked = 0
    for csv_path in sorted(tmp_path.glob("fig7_*_plotted.csv")):
        curves = {}
        with open(csv_path) as fh:
            for r in csv.DictReader(fh):
                curves.setdefault((r["panel"], r["curve"]), []).append((float(r["x"]), float(r["y"])))
        for key, pts in curves.items():
            xy = np.array(pts)
            hit = any(
                len(x) == len(xy) and np.allclose(xy[:, 0], x) and np.allclose(xy[:, 1], y, rtol=1e-9, atol=1e-12)
                for x, y in pairs
            )
            assert hit, f"{csv_path.name} curve {key} is no run's history"
            checked += 1
    assert checked >= 4
    assert set(res["missing"]) == {
        "tension_fast_ru",
        "tension_slow_ra",
        "compression_fast_ru",
        "compression_slow_ra",
        "compression_fast_ra",
    }


@pytest.mark.slow
def test_dif_study_against_fib(smoke_runs, tmp_path):
    from polydem_cli.workflows.dif import fib_dif, run_study

    d, out = smoke_runs
    res = run_study(CH7 / "smoke_tension_ra.toml", [1.0, 10.0], out["concrete_tension"][0], tmp_path, workers=1)
    assert [p["status"] for p in res["points"]] == ["finished", "finished"]
    for p in res["points"]:
        assert p["dif"] > 0.9 and p["fib"] == pytest.approx(float(fib_dif(p["rate"], "tension")))
    assert fib_dif(1.0, "tension") == pytest.approx(1e6**0.018)
    assert fib_dif(1.0, "compression") == pytest.approx((1 / 30e-6) ** 0.014)
    assert (tmp_path / "dif.png").stat().st_size > 10_000
    # the reference run's own strain rate (fitted from its history) is its prescribed top speed over L2
    from polydem_cli.io.hdf5 import open_result

    with open_result(out["concrete_tension"][0]) as f:
        sc = json.loads(f.attrs["resolved"])
        L2 = json.loads(f.attrs["summary"])["macro"]["definition"]["L2"]
    v = next(b["x2"]["velocity"] for b in sc["boundary"] if isinstance(b.get("x2"), dict))
    assert res["reference_rate"] == pytest.approx(abs(v) / L2, rel=1e-3)


def test_glued_nuts_report(smoke_runs, tmp_path):
    d, out = smoke_runs
    _cli(["report", str(out["nuts_glued_small"][0]), "--out", str(tmp_path)], d)
    for suffix in ("load", "damage", "damage_end", "stress_strain"):
        assert (tmp_path / f"nuts_glued_small_{suffix}.png").stat().st_size > 10_000, suffix


def test_an_end_criterion_that_is_not_met_is_reported(tmp_path):
    """The load-drop end criterion cannot be met before the safety limit: the run says so at the end and
    in its summary (end_reason), instead of claiming the load dropped."""
    r = _cli(
        [
            "run",
            str(CH7 / "smoke_concrete_tension.toml"),
            "-o",
            str(tmp_path / "s.h5"),
            "--threads",
            "1",
            "--set",
            "time.end_displacement=4e-4",
        ],
        tmp_path,
    )
    assert "end_load_drop was not met" in r.stdout
    s = json.loads((tmp_path / "s.summary.json").read_text())
    assert s["status"] == "finished" and "not met" in s["end_reason"]


def test_ch7_collation_leaves_out_an_interrupted_run(smoke_runs, tmp_path):
    """A run that stopped before its end (resumable, status not "finished") is not a result: its partial peak
    would make a false ratio (a compression run interrupted before its peak gave 0.31 for 1.0)."""
    import shutil

    import h5py

    from polydem_cli.reproductions.ch7 import collate

    d, out = smoke_runs
    runs = tmp_path / "runs"
    shutil.copytree(d / "runs", runs, ignore=shutil.ignore_patterns("*.lock", "*.writer"))
    (ra,) = [p for p in runs.glob("tension_fast_ra*.h5")]
    with h5py.File(ra, "r+") as f:
        f.attrs["status"] = "interrupted"
    res = collate(runs, tmp_path / "fig")
    assert ra.stem in res["unfinished"] and "tension_fast_ra" in res["missing"]
    assert "ratio_tension_fast_ra" not in res["reproduced"]
