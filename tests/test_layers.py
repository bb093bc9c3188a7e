"""Import layering: lower layers never import higher ones (issue 13: backward imports removed).

    errors, params, jit  <  geometry, boundary  <  interactions, coupling  <  engine  <  scenario  <  io, report, studies, cli

The run driver ``engine/runner.py`` composes the layers (it builds a system from a stored scenario, writes
through io, summarises through analysis) and ranks with io."""

import ast
from pathlib import Path

PKG = Path(__file__).resolve().parents[1] / "polydem_cli"
RANK = {
    "errors": 0,
    "params": 0,
    "jit": 0,
    "_jit_cache": 0,
    "geometry": 1,
    "boundary": 1,
    "interactions": 2,
    "coupling": 2,
    "engine": 3,
}
RANK.update(scenario=4, analysis=4, io=5, solvers=5, report=6, studies=6, cli=7)
DRIVER = {"engine/runner.py": 5}


def _imports(path):
    rel = path.relative_to(PKG)
    depth = len(rel.parts) - 1  # package depth of the module
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.ImportFrom) and node.module is not None and node.level > 0:
            if node.level > depth + 1:
                continue
            base = list(rel.parts[:-1])[: depth - (node.level - 1)]
            yield (base + node.module.split("."))[0] if base + node.module.split(".") else None
        elif isinstance(node, ast.ImportFrom) and node.module and node.module.startswith("polydem_cli."):
            yield node.module.split(".")[1]


def test_no_module_imports_a_higher_layer():
    bad = []
    for path in PKG.rglob("*.py"):
        rel = path.relative_to(PKG)
        own = rel.parts[0] if len(rel.parts) > 1 else rel.stem
        if own not in RANK:
            continue
        rank = DRIVER.get(str(rel), RANK[own])
        for top in _imports(path):
            if top in RANK and RANK[top] > rank:
                bad.append(f"{rel} imports {top}")
    assert not bad, bad


def test_sources_cite_the_papers_not_the_working_specification():
    """Docstrings, scenario files and docs cite the thesis's or the paper's equation and section numbers, never
    the working specification, which is not part of the product (issue 12 item 11)."""
    root = PKG.parent
    word = "SP" + "EC"  # not spelled out, so that this file does not match itself
    found = []
    for sub, pattern in (("polydem_cli", "*.py"), ("tests", "*.py"), ("scenarios", "*.toml"), ("docs", "*.md")):
        for p in (root / sub).rglob(pattern):
            for i, line in enumerate(p.read_text().splitlines(), 1):
                if word in line.split():
                    found.append(f"{p.relative_to(root)}:{i}")
                elif f"{word} §" in line or f"{word}.md" in line or f"({word} " in line or f"; {word}" in line:
                    found.append(f"{p.relative_to(root)}:{i}")
    for name in ("README.md", "Makefile"):
        if word in (root / name).read_text():
            found.append(name)
    assert not found, found
