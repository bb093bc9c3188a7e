"""``polydem report``."""

from __future__ import annotations

from pathlib import Path

import click


@click.command("report")
@click.argument("result", type=click.Path(dir_okay=False, path_type=Path))
@click.option(
    "--out", type=click.Path(file_okay=False, path_type=Path), help="output directory (default: beside RESULT)"
)
@click.option("--times", default="", help="comma-separated frame times for the snapshots, e.g. 0,0.5,1")
@click.option(
    "--states",
    default="",
    help="bonded results: comma-separated displacements û2 of the marked states "
    "(load curve and damage maps; default: automatic z1-z4 / d1-d4)",
)
def report_cmd(result, out, times, states):
    """Plots of a result: energies, contacts, load–displacement, particle snapshots, and for
    bonded specimens the load curve with marked states, damage maps and strain maps (PNG).

    \b
    Example:
      polydem report outputs/demo_hex_pile.h5 --times 0,0.2,0.4
    """
    import sys

    from ..io.hdf5 import ResultError
    from ..report import make_report

    try:
        tl = [float(t) for t in times.split(",") if t.strip()] if times else None
        sl = [float(t) for t in states.split(",") if t.strip()] if states else None
    except ValueError:
        click.echo("error: --times/--states: expected comma-separated numbers", err=True)
        sys.exit(2)
    notes = []
    try:
        files = make_report(result, out, tl, sl, notes=notes)
    except ResultError as e:
        click.echo(f"error: {e}", err=True)
        sys.exit(2)
    for n in notes:
        click.echo(f"note: {n}", err=True)
    for f in files:
        click.echo(f"wrote {f}")
