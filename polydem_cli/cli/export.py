"""``polydem export``."""

from __future__ import annotations

import tempfile
from pathlib import Path

import click


@click.command("export")
@click.argument("result", type=click.Path(dir_okay=False, path_type=Path))
@click.option(
    "--vtk",
    "out",
    type=click.Path(dir_okay=False, path_type=Path),
    default=None,
    help="VTKHDF file to write (default: RESULT with the suffix .vtkhdf)",
)
def export_cmd(result, out):
    """Write every frame of RESULT as one VTKHDF time series for ParaView (File > Open, the .vtkhdf
    file): particles as polygons with velocity, rotation, displacement and group, beams as lines with their
    damage (io/vtkhdf.py documents the fields).

    \b
    Example:
      polydem export outputs/concrete_tension.h5
    """
    import sys

    from ..io.hdf5 import ResultError, readable
    from ..io.vtkhdf import export
    from ..solvers import family_of_result

    if result.exists() and family_of_result(result) is not None:
        click.echo(
            f"error: {result}: a quasi-static result; export writes particle results (its lattice, meshes and "
            f"damage are in the result itself and in polydem report)",
            err=True,
        )
        sys.exit(2)
    from .outputs import writable_file, writing

    if result.exists():  # checked before any work (a missing result is said by the reader)
        writable_file(out or result.with_suffix(".vtkhdf"), "the export", example=f"{result.stem}.vtkhdf")
    try:
        with (
            tempfile.TemporaryDirectory(prefix="polydem-export-") as tmp,
            writing(out or result.with_suffix(".vtkhdf")),
        ):
            src = readable(result, tmp)
            if src != result:
                out = out or result.with_name(f"{result.stem}.running.vtkhdf")
                click.echo(f"note: {result}: still running: the export holds its frames so far", err=True)
            r = export(src, out)
    except ResultError as e:
        click.echo(f"error: {e}", err=True)
        sys.exit(2)
    click.echo(
        f"wrote {r['file']} ({r['frames']} time steps, {r['particles']} particles"
        + (f", {r['beams']} beams" if r["beams"] else "")
        + ")"
    )
