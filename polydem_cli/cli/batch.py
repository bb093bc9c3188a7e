"""``polydem batch``: run a list of scenarios to their results, each only as far as needed (a finished result is
reused, an interrupted one resumed), up to ``--jobs`` at a time in the order given, a run that starts from
another run's result (``[initial_state] file``) after it; one progress line over the whole list with an ETA for
the list, and a summary at the end (polydem_cli/workflows/batch.py)."""

from __future__ import annotations

import sys

import click

from ..workflows.batch import Batch, jobs_of, read_list


@click.command("batch")
@click.argument("items", nargs=-1, required=True, metavar="SCENARIO[=RESULT] ...")
@click.option("--threads", default="1", show_default=True, help="threads of each run (see polydem run)")
@click.option(
    "-j",
    "--jobs",
    "slots",
    default=1,
    show_default=True,
    type=click.IntRange(1, 64),
    help="runs at a time (each with --threads threads); runs start in the order given",
)
def batch_cmd(items, threads, slots):
    """Run SCENARIOs (each to RESULT, default outputs/<stem>.h5): finished results are reused, interrupted
    ones resumed, the others run, up to --jobs at a time in the order given.  A scenario whose
    [initial_state] file is another item's result (or an item repeated) waits for that item; if it failed, the
    dependent run is skipped.  One progress line over the list (the running runs, how far, the ETA of the
    list: the pending runs' planned particle-steps at the rate measured so far (or recorded by an earlier
    result run on as many threads) for runs of the same kind — integrator, particle shape, beams —, or at the
    slowest rate measured; an estimate, long when a run ends at a load drop) and a summary at the end (reused,
    resumed, ran, failed or skipped and why).  Exit code 1 if any run failed or was skipped.

    \b
    Example:
      polydem batch -j 2 scenarios/lh/prepare_p100.toml=outputs/lh/prepare_p100.h5 \\
                    scenarios/lh/load_p100_kc1.toml=outputs/lh/load_p100_kc1.h5
    """
    from .outputs import writable_file

    for _, res in jobs_of(items):  # every result's place, before anything runs
        writable_file(res, "the result")
    if len(items) > 1:
        click.echo(f"batch: {len(items)} runs; reading their scenarios (the plan of the ETA)", err=True)
    b = Batch(read_list(items, threads), threads, slots)
    import signal

    def _term(signum, frame):
        raise KeyboardInterrupt

    old_term = signal.signal(signal.SIGTERM, _term)
    try:
        while b.step():
            pass
    except KeyboardInterrupt:  # SIGINT or SIGTERM: the runs checkpoint and stop on SIGTERM (again, if the
        b.stop()  # terminal's SIGINT reached them too: harmless); wait for them
        click.echo("batch interrupted: the interrupted runs resume with the same command", err=True)
        sys.exit(130)
    finally:
        signal.signal(signal.SIGTERM, old_term)
    if b.tty:
        sys.stderr.write("\n")
    if not b.summary():
        sys.exit(1)
