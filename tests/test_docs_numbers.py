"""The numbers the docs quote are written from the results (polydem_cli/reproductions/docs.py): the README's demo
output is what `polydem run` printed, Table 1.1 of Luding & Herrmann is the study's CSV, and every quoted
block in the docs is one the generator knows."""

import csv
import re
import subprocess

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


def test_the_demo_block_is_what_polydem_run_printed(tmp_path):
    """A small run of the main job's scenario (same chain: concrete_tension.toml extended), its printed end
    lines against the block written from its summary."""
    (tmp_path / "outputs").mkdir()
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
    assert body == printed
    assert "the load fell below 0.1 of its peak" in body and "old numbers" not in text
    assert update(tmp_path, tmp_path / "outputs", files=("README.md",)) == {"README.md": {"demo_output": "unchanged"}}


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
