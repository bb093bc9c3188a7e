"""Command-line interface: ``polydem <command>`` (thin click layer; one module per command group)."""

from __future__ import annotations

import click

from .. import __version__
from .batch import batch_cmd
from .bench import bench_cmd
from .calibrate import calibrate_cmd
from .export import export_cmd
from .report import report_cmd
from .run import check_cmd, run_cmd, schema_cmd
from .study import study
from .sweep import sweep_cmd


@click.group(context_settings={"help_option_names": ["-h", "--help"]})
@click.version_option(__version__, prog_name="polydem")
def main():
    """polydem — 2D discrete elements of rigid convex polygons (Schneider 2012).

    \b
    Examples:
      polydem check scenarios/demo_hex_pile.toml
      polydem run scenarios/demo_hex_pile.toml -o outputs/demo.h5
      polydem report outputs/demo.h5
      polydem study integrators --out outputs/integrators
    """
    from .. import setup_jit_cache

    setup_jit_cache()  # before any command imports compiled code (the commands import it lazily)


main.add_command(run_cmd)
main.add_command(check_cmd)
main.add_command(schema_cmd)
main.add_command(study)
main.add_command(report_cmd)
main.add_command(bench_cmd)
main.add_command(sweep_cmd)
main.add_command(export_cmd)
main.add_command(calibrate_cmd)
main.add_command(batch_cmd)
