"""The example notebook docs/api_tour.ipynb runs (nbclient, a Jupyter kernel of this Python) from the repository's
root and its outputs show the smoke panel's E, nu, f_t and figures; it uses only the API's public names."""

import ast
import re

import nbformat
import pytest

import polydem_cli

from conftest import ROOT

NOTEBOOK = ROOT / "docs" / "api_tour.ipynb"


def test_the_notebook_uses_only_public_names():
    nb = nbformat.read(NOTEBOOK, as_version=4)
    used = set()
    for cell in nb.cells:
        if cell.cell_type != "code":
            continue
        tree = ast.parse(cell.source)
        for node in ast.walk(tree):
            if isinstance(node, ast.Attribute) and isinstance(node.value, ast.Name) and node.value.id == "polydem":
                used.add(node.attr)
            if isinstance(node, ast.ImportFrom) and (node.module or "").startswith("polydem_cli."):
                pytest.fail(f"the notebook imports a private module: {node.module}")
    assert used and used <= set(polydem_cli.__all__), used - set(polydem_cli.__all__)


def test_the_notebook_runs_and_shows_the_smoke_panel(tmp_path):
    from nbclient import NotebookClient

    nb = nbformat.read(NOTEBOOK, as_version=4)
    NotebookClient(nb, timeout=600, kernel_name="python3", resources={"metadata": {"path": str(ROOT)}}).execute()
    text, images = [], 0
    for cell in nb.cells:
        for o in cell.get("outputs", []):
            if o.get("output_type") == "stream":
                text.append(o["text"])
            data = o.get("data", {})
            text.append(data.get("text/plain", ""))
            images += "image/png" in data
    out = "\n".join(text)
    m = re.search(r"E = ([\d.]+) GPa, nu = (-?[\d.]+), f_t = ([\d.]+) N/mm\^2", out)
    assert m, out[-2000:]
    E, nu, ft = map(float, m.groups())
    assert 20 < E < 60 and -0.5 < nu < 0.5 and 1.0 < ft < 6.0
    assert "refused:" in out and "must be > 0" in out
    assert images >= 3  # the stress-strain curve, the damage map, the seed study
    assert out.count("seed") >= 1 and "f_t_MPa" in out
