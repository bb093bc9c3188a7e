"""The README's demo block is what this code prints (issue 51: the block quoted 65,578 steps, 201.2 N/m and 9.98 %
where the commit printed 65,215, 200.7 and 10 %).

The block is written by ``polydem study index --docs`` from the main job's summary, which it keeps as
``docs/demo_summary.json`` (polydem_cli/reproductions/docs.py).  Here: the block is that summary rendered by today's
code (nobody edited it by hand, and the printed format is today's), and the summary was written by a run of today's
run code on today's scenario (``source_digests`` of the package folders a run executes, ``scenario_digest`` of the
validated scenario).  When this fails after a change to the run's code or scenario: ``make demo`` and then
``.venv/bin/polydem study index --docs`` (rewrites the block and the summary), and commit both."""

import json
import re

from polydem_cli.io.provenance import RUN_PACKAGES, scenario_digest, source_digests
from polydem_cli.reproductions.docs import DEMO_SUMMARY, demo_paragraph
from polydem_cli.scenario.load import load_scenario

from conftest import ROOT, SCEN

FIX = "run `make demo`, then `.venv/bin/polydem study index --docs`, and commit README.md and docs/demo_summary.json"


def _block() -> str:
    m = re.search(
        r"<!-- generated: demo_output [^\n]*-->\n(.*?)<!-- end generated: demo_output -->",
        (ROOT / "README.md").read_text(),
        re.S,
    )
    assert m, "README.md has no demo_output block"
    return m.group(1)


def _summary() -> dict:
    return json.loads((ROOT / DEMO_SUMMARY).read_text())


def test_the_readme_demo_block_is_its_summary_as_this_code_prints_it():
    s = _summary()
    assert s["status"] == "finished" and s["scenario_file"].endswith("concrete_tension.toml")
    assert _block() == demo_paragraph(s), f"README's demo block is not docs/demo_summary.json as printed today: {FIX}"


def test_the_demo_summary_was_written_by_this_code_on_this_scenario():
    s = _summary()
    now = source_digests()
    stale = [k for k in RUN_PACKAGES if (s.get("source_digests") or {}).get(k) != now[k]]
    assert not stale, f"the demo ran on other code in polydem_cli/{{{', '.join(stale)}}} than this tree's: {FIX}"
    sc, _ = load_scenario(SCEN / "concrete_tension.toml", [])
    assert s.get("scenario_digest") == scenario_digest(sc), f"the demo ran another concrete_tension.toml: {FIX}"


def test_a_changed_package_or_scenario_is_noticed(tmp_path, monkeypatch):
    """The digests change with one byte of a run folder's code and with a scenario value (so the checks above fail
    when the README is stale), and not with a folder a run does not execute."""
    import polydem_cli.io.provenance as prov

    before = source_digests()
    fake = tmp_path / "polydem_cli"
    for folder in ("engine", "report"):
        (fake / folder).mkdir(parents=True)
    (fake / "io").mkdir()
    (fake / "io" / "provenance.py").write_text("")
    (fake / "engine" / "kernels.py").write_text("x = 1\n")
    (fake / "report" / "basic.py").write_text("y = 1\n")
    monkeypatch.setattr(prov, "__file__", str(fake / "io" / "provenance.py"))
    a = prov.source_digests()
    (fake / "engine" / "kernels.py").write_text("x = 2\n")
    b = prov.source_digests()
    (fake / "report" / "basic.py").write_text("y = 2\n")
    c = prov.source_digests()
    assert a["engine"] != b["engine"] and b["engine"] == c["engine"] and b["report"] != c["report"]
    assert "report" not in RUN_PACKAGES and before["engine"] != a["engine"]
    sc, _ = load_scenario(SCEN / "concrete_tension.toml", [])
    sc2, _ = load_scenario(SCEN / "concrete_tension.toml", ["time.dt=3e-7"])
    assert scenario_digest(sc) != scenario_digest(sc2)
