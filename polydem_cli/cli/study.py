"""``polydem study ...``: numerical studies."""
from __future__ import annotations

from pathlib import Path

import click


@click.group()
def study():
    """Numerical studies (integrator convergence, ...)."""


@study.command("integrators")
@click.option("--out", type=click.Path(file_okay=False, path_type=Path), default=Path("outputs/integrators"),
              show_default=True, help="output directory")
def integrators_cmd(out):
    """Error against number of steps for EE, ME, CD, PC (thesis Figs. 3.8, 3.9).

    Writes OUT/integrators.json and OUT/integrators.png.

    \b
    Example:
      polydem study integrators --out outputs/integrators
    """
    from ..studies.integrators import write_study

    res = write_study(out)
    for p in ("oscillator", "collision"):
        orders = ", ".join(f"{m} {res[p][m]['order']:.2f}" for m in ("EE", "ME", "CD", "PC"))
        click.echo(f"{p}: fitted orders {orders}")
    click.echo(f"wrote {out / 'integrators.json'} and {out / 'integrators.png'}")


@study.command("ch5")
@click.option("--runs", type=click.Path(file_okay=False, path_type=Path), default=Path("outputs/ch5"),
              show_default=True, help="directory with the chapter-5 results (<scenario stem>.h5)")
@click.option("--out", type=click.Path(file_okay=False, path_type=Path), default=Path("outputs/figures/ch5"),
              show_default=True)
def ch5_cmd(runs, out):
    """Collate the chapter-5 runs: Figs. 5.7-5.21, Table 5.1 and results.json (thesis values beside ours).

    \b
    Example:
      polydem study ch5 --runs outputs/ch5 --out outputs/figures/ch5
    """
    from ..studies.ch5 import collate

    res = collate(runs, out)
    rep = res["reproduced"]
    for k, v in rep.items():
        if k != "table_5_1":
            click.echo(f"{k}: {v if v is None else round(v, 3)} (thesis {res['thesis'].get(k)})")
    for row, vals in rep["table_5_1"].items():
        click.echo(f"Table 5.1 {row}: " + ", ".join(f"{c} {'-' if v is None else round(v, 3)}" for c, v in vals.items()))
    if res["missing"]:
        click.echo("missing runs: " + ", ".join(res["missing"]))
    click.echo(f"wrote {out / 'results.json'}")
