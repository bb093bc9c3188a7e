"""The numbers the docs quote are written from the results (polydem_cli/reproductions/docs.py): the README's demo
output is what `polydem run` printed, and each of its numbers is the one recomputed here with numpy from a real run's
history, particles and bonds; Table 1.1 of Luding & Herrmann is the study's CSV, and every quoted block in the docs
is one the generator knows."""

import csv
import re
import subprocess

import numpy as np
import pytest

from polydem_cli.reproductions.docs import BLOCKS, blocks, rewrite, update

from conftest import ROOT, SCEN, polydem_cmd


def test_the_docs_quote_results_only_through_generated_blocks():
    readme = (ROOT / "README.md").read_text()
    repro = (ROOT / "docs" / "reproduction.md").read_text()
    assert blocks(readme) == ["demo_output"]
    assert blocks(repro) == ["lh_table_1_1", "lh_slopes", "lh_rate", "lh_table_1_1_u", "lh_slopes_u"]
    assert set(blocks(readme) + blocks(repro)) <= set(BLOCKS)
    # the numbers of the stale README (2026-12-03) are gone from the prose around the block
    outside = re.sub(r"<!-- generated: demo_output.*?<!-- end generated: demo_output -->", "", readme, flags=re.S)
    assert "65,215" not in outside and "200.7 N/m" not in outside


#: the demo block's lines (polydem_cli/reproductions/docs.py:demo_output, the printed end of `polydem run`): each
#: number the README quotes, by name
DEMO_LINES = {
    "paragraph": r"It ran (?P<steps>[\d,]+) steps of (?P<dt>\S+) s \((?P<particles>\d+) particles, (?P<beams>\d+) beams "
    r"with contact after failure\)",
    "headline": r"wrote \S+ \((?P<head_steps>[\d,]+) steps, (?P<head_particles>\d+) particles, ",
    "end": r"  end: (?P<end>.+)",
    "peak": r"  peak load \|(?P<peak_col>\S+)\| = (?P<peak>\S+) dyn at t = (?P<peak_t>\S+) s",
    "balance": r"  energy-balance error (?P<balance>\S+) \(largest \|E_total - E_0\| over the largest energy term\)",
    "macro": r"  E = (?P<E>\S+) GPa, nu = (?P<nu>\S+) \(fitted where \|sigma22\| is (?P<lo>\S+)-(?P<hi>\S+) % of the "
    r"peak, (?P<points>\d+) points\); tensile strength (?:f_t = )?(?P<ft>\S+) N/mm\^2 at eps22 = (?P<eps_peak>\S+); work "
    r"after the peak (?P<work>\S+) N/m \((?P<work_erg>\S+) erg\), stress at the end (?P<end_pct>\S+) % of the peak",
    "bonds": r"  failed bonds: (?P<failed>\d+) of (?P<of>\d+) \(by mode: tension (?P<tension>\d+), bending "
    r"(?P<bending>\d+), shear (?P<shear>\d+), under_compression (?P<under_compression>\d+); by orientation: "
    r"horizontal (?P<horizontal>\d+), diagonal (?P<diagonal>\d+), vertical (?P<vertical>\d+)\)",
}


def _demo_numbers(block: str) -> dict:
    """The numbers (as printed, strings) of a demo block, by name; every line of DEMO_LINES must be there."""
    out = {}
    for name, pattern in DEMO_LINES.items():
        m = re.search("^" + pattern, block, flags=re.M)
        assert m, f"the demo block has no {name} line ({pattern})"
        out.update(m.groupdict())
    return out


def _printed(text: str, value: float, digits: int) -> bool:
    """``text`` is ``value`` printed to ``digits`` significant digits (half a unit of the last digit, a little
    more for the rounding of ``value`` itself)."""
    v = float(text)
    if value == 0.0:
        return v == 0.0
    ulp = 10.0 ** (np.floor(np.log10(abs(value))) - digits + 1)
    return abs(v - value) <= 0.5 * ulp * (1 + 1e-6) + 1e-12 * abs(value)


def _recomputed(result) -> dict:
    """What the demo block states, computed here with numpy from the result's raw records (history table, particles,
    bonds), not from its summary: the definitions of scenarios/concrete_tension.toml (O-2: σ22 = f2/(L1 T) of the top
    row, ε22 = u2/L2, ε11 = (u1 of the right edge − u1 of the left edge)/L1, L1 × L2 the specimen's extent, T its
    thickness; E and ν the least-squares slopes of σ22 and −ε11 against ε22 over the rows up to the peak where |σ22|
    is 10–40 % of the peak; the energy-balance error the largest |E_total − E_0| over the largest sum of |energy
    terms|; a bond's failure mode the largest of ⟨ε_ax⟩, |ϰ|H/2 and |γ| at failure, its orientation that of the
    line of centroids at t0 within 22.5° of e1 or e2)."""
    import json

    import h5py

    with h5py.File(result, "r") as f:
        cols = json.loads(f["history/table"].attrs["columns"])
        tab = f["history/table"][...]
        x0 = f["particles/x0"][...]
        verts = f["particles/body_vertices"][...]
        vstart = f["particles/vertex_start"][...]
        T = float(f["particles/thickness"][0])
        pairs = f["bonds/pairs"][...]
        fail_step = f["bonds/fail_step"][...]
        fail_strain = f["bonds/fail_strain"][...]
    h = {c: tab[:, i] for i, c in enumerate(cols)}
    owner = np.repeat(np.arange(len(x0)), np.diff(vstart))
    corners = verts + x0[owner, :2]  # body frame at φ0 = 0 (particles/body_vertices)
    L1, L2 = np.ptp(corners[:, 0]), np.ptp(corners[:, 1])
    sigma = h["f2:specimen.top"] / (L1 * T)
    eps22 = h["u2:specimen.top"] / L2
    eps11 = (h["u1:specimen.right"] - h["u1:specimen.left"]) / L1
    k = int(np.argmax(np.abs(sigma)))
    a = np.abs(sigma[: k + 1])
    fit = np.flatnonzero((a >= 0.1 * abs(sigma[k])) & (a <= 0.4 * abs(sigma[k])))
    work = np.trapezoid(h["f2:specimen.top"][k:], h["u2:specimen.top"][k:])  # ∫ f2 du2 after the peak, erg
    loads = [c for c in cols if c.startswith(("f1:", "f2:"))]
    peak_col = max(loads, key=lambda c: np.abs(h[c]).max())
    r = int(np.argmax(np.abs(h[peak_col])))
    e_total = h["kinetic"] + h["elastic"] + h["potential"] + h["dissipated"] - h["external_work"]
    scale = sum(np.abs(h[c]) for c in ("kinetic", "elastic", "dissipated", "external_work"))
    scale = scale + np.abs(h["potential"] - h["potential"][0])
    failed = np.flatnonzero(fail_step >= 0)
    parts = np.column_stack([np.maximum(fail_strain[:, 0], 0.0), fail_strain[:, 1], fail_strain[:, 2]])
    mode = np.argmax(parts, axis=1)[failed]
    axis = x0[pairs[:, 1], :2] - x0[pairs[:, 0], :2]
    angle = np.mod(np.degrees(np.arctan2(axis[:, 1], axis[:, 0])), 180.0)[failed]
    horizontal = np.minimum(angle, 180.0 - angle) <= 22.5
    vertical = np.abs(angle - 90.0) <= 22.5
    return {
        "steps": int(h["step"][-1]),
        "dt": float(np.median(np.diff(h["time"]) / np.diff(h["step"]))),
        "particles": len(x0),
        "beams": len(pairs),
        "top_u2": float(h["u2:specimen.top"][-1]),
        "peak_col": peak_col,
        "peak": float(abs(h[peak_col][r])),
        "peak_t": float(h["time"][r]),
        "balance": float(np.abs(e_total - e_total[0]).max() / scale.max()),
        "E": float(np.polyfit(eps22[fit], sigma[fit], 1)[0]) / 1e10,  # GPa (1 GPa = 1e10 g/(cm s^2))
        "nu": -float(np.polyfit(eps22[fit], eps11[fit], 1)[0]),
        "points": len(fit),
        "ft": float(sigma[k]) / 1e7,  # N/mm^2 = 1e7 g/(cm s^2)
        "eps_peak": float(eps22[k]),
        "work": float(work / (L1 * T)) / 1e3,  # N/m = 1e3 erg/cm^2
        "work_erg": float(work),
        "end_pct": float(100 * sigma[-1] / sigma[k]),
        "failed": len(failed),
        "tension": int(np.sum(mode == 0)),
        "bending": int(np.sum(mode == 1)),
        "shear": int(np.sum(mode == 2)),
        "under_compression": int(np.sum((mode > 0) & (fail_strain[failed, 0] < 0))),
        "horizontal": int(np.sum(horizontal)),
        "vertical": int(np.sum(vertical)),
        "diagonal": int(np.sum(~horizontal & ~vertical)),
    }


def test_the_demo_block_states_what_a_real_run_of_the_main_job_holds(tmp_path):
    """A small run of the main job's scenario (same chain: concrete_tension.toml extended): the README block the
    generator writes from it (reproductions/docs.py) is what `polydem run` printed, and every number in it is the
    one recomputed here from the result's history, particles and bonds (:func:`_recomputed`), to the digits
    printed."""
    (tmp_path / "outputs").mkdir()
    (tmp_path / "docs").mkdir()  # where the generator may keep the summary the block came from
    r = subprocess.run(
        polydem_cmd()
        + [
            "run",
            str(SCEN / "ch7" / "smoke_concrete_tension.toml"),
            "-o",
            "outputs/concrete_tension.h5",
            "--set",
            "time.end_displacement=0.01",
        ],
        capture_output=True,
        text=True,
        cwd=tmp_path,
    )
    assert r.returncode == 0, r.stderr
    printed = r.stdout[r.stdout.index("wrote outputs/concrete_tension.h5") :].rstrip("\n")
    readme = tmp_path / "README.md"
    readme.write_text(
        "before\n<!-- generated: demo_output — test -->\nold numbers\n<!-- end generated: demo_output -->\nafter\n"
    )
    report = update(tmp_path, tmp_path / "outputs", files=("README.md",))
    assert report == {"README.md": {"demo_output": "rewritten"}}
    text = readme.read_text()
    assert text.startswith("before\n") and text.endswith("<!-- end generated: demo_output -->\nafter\n")
    body = text[text.index("```\n") + 4 : text.rindex("\n```")]
    assert body == printed and "old numbers" not in text
    assert update(tmp_path, tmp_path / "outputs", files=("README.md",)) == {"README.md": {"demo_output": "unchanged"}}

    got = _demo_numbers(text)
    want = _recomputed(tmp_path / "outputs" / "concrete_tension.h5")
    for key in ("steps", "head_steps"):
        assert int(got[key].replace(",", "")) == want["steps"]
    assert float(got["dt"]) == pytest.approx(want["dt"], rel=1e-9)
    assert int(got["particles"]) == int(got["head_particles"]) == want["particles"] == 64  # 8 x 8 cells
    assert int(got["beams"]) == int(got["of"]) == want["beams"]
    # ended by the load drop, before the end displacement of 0.01 cm, with the stress at 10 % of its peak
    assert got["end"] == "the load fell below 0.1 of its peak (time.end_load_drop)"
    assert want["top_u2"] < 0.01 and 9.5 < want["end_pct"] <= 10.1
    assert got["peak_col"] == want["peak_col"]
    assert _printed(got["peak"], want["peak"], 4) and _printed(got["peak_t"], want["peak_t"], 6)
    assert _printed(got["balance"], want["balance"], 2)
    assert (got["lo"], got["hi"]) == ("10", "40") and int(got["points"]) == want["points"] >= 3
    for key, digits in (("E", 4), ("nu", 3), ("ft", 4), ("eps_peak", 3), ("work", 4), ("work_erg", 4), ("end_pct", 3)):
        assert _printed(got[key], want[key], digits), (key, got[key], want[key])
    for key in ("failed", "tension", "bending", "shear", "under_compression", "horizontal", "diagonal", "vertical"):
        assert int(got[key]) == want[key], (key, got[key], want[key])
    assert want["failed"] >= 1  # the panel cracked: the line is there and counts something


def test_the_readme_quotes_the_demo_block_whose_numbers_are_checked():
    """README.md's demo block has every line whose numbers the test above checks against a real result, and its
    numbers agree with each other (the paragraph and the printed lines come from one summary)."""
    readme = (ROOT / "README.md").read_text()
    block = re.search(r"<!-- generated: demo_output.*?<!-- end generated: demo_output -->", readme, flags=re.S)
    got = _demo_numbers(block.group(0))
    assert got["steps"] == got["head_steps"] and got["particles"] == got["head_particles"]
    assert got["beams"] == got["of"] and int(got["failed"]) <= int(got["of"])
    assert int(got["failed"]) == sum(int(got[k]) for k in ("tension", "bending", "shear"))
    assert int(got["failed"]) == sum(int(got[k]) for k in ("horizontal", "diagonal", "vertical"))
    assert float(got["work_erg"]) == pytest.approx(float(got["work"]) * 1e3 * 40.0 * 1.0, rel=1e-3)  # L1 T = 40 cm²


def test_lh_table_from_the_study_csv_with_lower_bounds_marked(tmp_path):
    from polydem_cli.reproductions.lh import PAPER

    d = tmp_path / "figures" / "lh"
    d.mkdir(parents=True)
    fields = ["kc_over_k2", "peak_100", "peak_500", "c", "phi_deg", "peak_100_lower_bound", "peak_500_lower_bound"]
    rows = [[kc, 139.3 + i, 651.0 + i, 7.5, 6.8, i == 2, False] for i, kc in enumerate(PAPER["kc"])]
    with open(d / "table1_1.csv", "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(fields + ["paper_peak_100"])
        w.writerows([r + [0] for r in rows])
    text = "x\n<!-- generated: lh_table_1_1 — t -->\n<!-- end generated: lh_table_1_1 -->\n"
    new, status = rewrite(text, tmp_path)
    assert status == {"lh_table_1_1": "rewritten"}
    lines = [ln for ln in new.splitlines() if ln.startswith("| ")]
    assert lines[1] == "| 0 | 139 (183) | 651 (798) | 7.5 (11) | 6.8° |"
    assert lines[3].startswith("| 1 | ≥ 141 (264) | 653 (915) |")
    assert "1 peak(s) fell on the last point of the loading" in new
    # without its result a block is left as it is
    assert rewrite(text.replace("lh_table_1_1", "lh_table_1_1_u"), tmp_path / "none")[1] == {
        "lh_table_1_1_u": "no result"
    }
