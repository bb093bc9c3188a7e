"""``polydem sweep``."""

from __future__ import annotations

import sys
from pathlib import Path

import click


@click.command("sweep")
@click.argument("scenario", type=click.Path(dir_okay=False, exists=True, path_type=Path))
@click.option(
    "--set",
    "sets",
    multiple=True,
    required=True,
    metavar="KEY.PATH=V1,V2,...",
    help="values of one parameter; several --set give the Cartesian product",
)
@click.option("--base", "base", multiple=True, metavar="KEY.PATH=VALUE", help="override applied to every variant")
@click.option(
    "--out",
    type=click.Path(file_okay=False, path_type=Path),
    default=None,
    help="directory for the results and the table (default outputs/sweep/<scenario stem>)",
)
@click.option(
    "--scheduler", default=None, metavar="ADDRESS", help="a running Dask scheduler (default: a local cluster)"
)
@click.option("--workers", type=int, default=None, help="local cluster size (default: one worker per core)")
def sweep_cmd(scenario, sets, base, out, scheduler, workers):
    """Run the variants of SCENARIO on Dask; one result per variant and a collated table.

    Finished variants are not run again, interrupted ones are resumed.

    \b
    Example (thesis Figs. 5.12/5.13 style):
      polydem sweep scenarios/ch5/tension.toml --set bonds.G_ax=5e-9,1e-8 --set bonds.kappa_0=1e-5,2e-5
    """
    from ..scenario.spec import ScenarioError
    from ..workflows.sweep import sweep, variants
    from .outputs import writable_dir, writing

    try:
        vs = variants(sets)
    except ValueError as e:
        click.echo(f"error: {e}", err=True)
        sys.exit(2)
    # validate every variant before anything runs (as polydem check does, for the scenario's solver family)
    from ..scenario.load import load_scenario
    from ..solvers import family_module

    try:
        for v in vs:
            sc, _ = load_scenario(scenario, list(base) + v)
            family_module(sc["solver"]["kind"]).check(sc, str(scenario))
    except ScenarioError as e:
        click.echo(f"error: {e}", err=True)
        sys.exit(2)
    out = out or Path("outputs/sweep") / scenario.stem
    writable_dir(out, "the sweep")
    click.echo(f"{len(vs)} variant(s) of {scenario} -> {out}")
    with writing(out):
        res = sweep(scenario, sets, out, scheduler, workers, base)
    for r in res["variants"]:
        if r.get("reused"):
            extra = "reused"
        elif r.get("wall time [s]") is not None:
            extra = f"{r['wall time [s]']:.1f} s"
        else:
            extra = r.get("failure") or "no summary"
        click.echo(f"  {r['variant']}: {r['status']} ({extra})")
    click.echo(f"wrote {out / 'sweep.csv'}")
