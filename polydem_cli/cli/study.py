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
