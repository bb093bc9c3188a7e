"""Import layering: lower layers never import higher ones, and no two modules import each other through any
chain (issue 35: no exemptions, no cycles).

    errors, params, jit  <  geometry, boundary  <  interactions, coupling  <  engine  <  io
        <  scenario, analysis  <  solvers  <  report, workflows  <  reproductions, benchmarks  <  cli

io knows files (writer, reader, checkpoints, lock, provenance) and no scenario; solvers (the run driver and the
solver families) compose everything below them."""

import ast
from pathlib import Path

PKG = Path(__file__).resolve().parents[1] / "polydem_cli"
RANK = {
    "errors": 0,
    "params": 0,
    "jit": 0,
    "_jit_cache": 0,
    "mpicall": 0,
    "mpl": 0,
    "geometry": 1,
    "boundary": 1,
    "interactions": 2,
    "coupling": 2,
    "engine": 3,
    "io": 4,
    "scenario": 5,
    "analysis": 5,
    "solvers": 6,
    "report": 7,
    "workflows": 7,
    "reproductions": 8,
    "benchmarks": 8,
    "cli": 9,
    "api": 9,
}


def _module(path) -> str:
    rel = path.relative_to(PKG).with_suffix("")
    parts = list(rel.parts)
    if parts[-1] == "__init__":
        parts = parts[:-1]
    return ".".join(["polydem_cli"] + parts)


def _targets(path):
    """Every polydem_cli module ``path`` imports (lazy imports inside functions too), as dotted names;
    ``from .pkg import name`` gives ``pkg.name`` when that is a module, else ``pkg``."""
    mod = _module(path)
    pkg = mod.split(".") if path.name == "__init__.py" else mod.split(".")[:-1]
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.Import):
            for a in node.names:
                if a.name.startswith("polydem_cli"):
                    yield a.name
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = pkg[: len(pkg) - (node.level - 1)]
                target = ".".join(base + (node.module.split(".") if node.module else []))
            elif node.module and node.module.startswith("polydem_cli"):
                target = node.module
            else:
                continue
            for a in node.names:
                sub = f"{target}.{a.name}"
                yield sub if _exists(sub) else target


def _exists(dotted) -> bool:
    p = PKG.parent.joinpath(*dotted.split("."))
    return p.with_suffix(".py").exists() or (p / "__init__.py").exists()


def _layer(dotted) -> str | None:
    parts = dotted.split(".")
    return parts[1] if len(parts) > 1 else None


def test_no_module_imports_a_higher_layer():
    bad = []
    for path in PKG.rglob("*.py"):
        own = _layer(_module(path))
        if own not in RANK:
            continue
        for t in _targets(path):
            top = _layer(t)
            if top in RANK and RANK[top] > RANK[own]:
                bad.append(f"{path.relative_to(PKG)} imports {t}")
    assert not bad, bad


def test_the_layer_check_sees_lazy_and_absolute_imports(tmp_path):
    """The check above can fail: a lazy relative import and an absolute ``import polydem_cli.x`` of a higher
    layer are both found."""
    f = PKG / "io" / "_probe_for_test_layers.py"
    f.write_text("def f():\n    from ..cli import run\n    import polydem_cli.report.basic\n")
    try:
        got = set(_targets(f))
    finally:
        f.unlink()
    assert {"polydem_cli.cli.run", "polydem_cli.report.basic"} <= got


def _graph() -> dict:
    g = {}
    for path in PKG.rglob("*.py"):
        g.setdefault(_module(path), set()).update(t for t in _targets(path) if _exists(t))
    return g


def _cycles(g) -> list:
    """Strongly connected components of more than one module (Tarjan)."""
    index, low, stack, on, out, n = {}, {}, [], set(), [], [0]

    def visit(v):
        index[v] = low[v] = n[0]
        n[0] += 1
        stack.append(v)
        on.add(v)
        for w in g.get(v, ()):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            comp = []
            while True:
                w = stack.pop()
                on.discard(w)
                comp.append(w)
                if w == v:
                    break
            if len(comp) > 1:
                out.append(sorted(comp))

    for v in list(g):
        if v not in index:
            visit(v)
    return out


def test_no_import_cycles():
    """A package's ``__init__`` importing its own modules is a package's table of contents, not a cycle: edges
    from a package to its own submodules are left out."""
    g = {m: {t for t in ts if not t.startswith(m + ".")} for m, ts in _graph().items()}
    assert not _cycles(g), _cycles(g)


def test_the_cycle_check_finds_a_cycle():
    assert _cycles({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}) == [["a", "b", "c"]]


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
