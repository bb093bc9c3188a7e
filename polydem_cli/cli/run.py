"""``polydem run``, ``polydem check``, ``polydem schema``."""

from __future__ import annotations

import sys
from pathlib import Path

import click

from ..scenario.spec import ScenarioError
from .outputs import cannot_write, remove_existing, writable_file, writing
from .outputs import fail as fail_input


def _load_and_build(scenario, overrides):
    from ..scenario.build import build_system
    from ..scenario.load import load_scenario

    sc, text = load_scenario(scenario, overrides)
    return build_system(sc, str(scenario)), text


@click.command("run")
@click.argument("scenario", required=False, type=click.Path(dir_okay=False, path_type=Path))
@click.option(
    "-o",
    "--out",
    type=click.Path(dir_okay=False, path_type=Path),
    help="result file (default outputs/<scenario stem>.h5)",
)
@click.option(
    "--set",
    "overrides",
    multiple=True,
    metavar="KEY.PATH=VALUE",
    help="override a scenario value (validated like the file), e.g. --set time.dt=1e-6",
)
@click.option("--overwrite", is_flag=True, help="replace an existing result file")
@click.option(
    "--resume",
    type=click.Path(dir_okay=False, path_type=Path),
    metavar="RESULT.h5",
    help="continue an interrupted run from its last checkpoint",
)
@click.option(
    "--continue",
    "cont",
    is_flag=True,
    help="if the result file exists: resume it when it holds the same scenario, do nothing when that run "
    "has finished (for make and batch scripts)",
)
@click.option(
    "--threads",
    default="auto",
    show_default=True,
    metavar="N|auto",
    help="threads for the parallel kernels; auto: the cores other processes leave free, re-measured during "
    "the run (engine/threads.py); N: at most N, fewer while other processes keep cores busy",
)
@click.option(
    "--pin-threads",
    is_flag=True,
    help="keep exactly --threads N even beside busy processes (2 threads sharing a core with another process "
    "run no faster than 1; for measuring that)",
)
@click.option("-q", "--quiet", is_flag=True, help="no progress output and no closing summary")
def run_cmd(scenario, out, overrides, overwrite, resume, cont, threads, pin_threads, quiet):
    """Run SCENARIO (a TOML file) and write an HDF5 result plus <result>.summary.json.

    \b
    Example:
      polydem run scenarios/demo_hex_pile.toml -o outputs/demo.h5
      polydem run --resume outputs/demo.h5
    """
    from ..engine.runner import AlreadyFinished, Interrupted, existing_state, run
    from ..engine.simulation import EngineError
    from ..io.hdf5 import ResultError, result_lock

    fam = None
    if pin_threads and threads == "auto":
        fail_input("--pin-threads needs a count: --threads N --pin-threads")
    if threads != "auto":
        import numba

        nmax = numba.config.NUMBA_NUM_THREADS
        if not threads.isdigit() or not 1 <= int(threads) <= nmax:
            fail_input(f"--threads {threads}: must be 'auto' or a whole number between 1 and {nmax}")
        threads = int(threads)
    try:
        if resume is not None:
            if scenario is not None or overrides or out is not None:
                fail_input("--resume RESULT takes no scenario, -o or --set (the result file holds them)")
            out = resume
            if not resume.exists():
                fail_input(f"{resume}: no such result file")
            writable_file(resume, "the result")  # its lock, checkpoints and summary are written beside it
            from ..solvers import family_of_result

            fam = family_of_result(resume)
            if fam is not None:
                summary = fam.run(out=resume, resume=True, quiet=quiet)
            else:
                summary = run(out=resume, resume=True, quiet=quiet, threads=threads, pin_threads=pin_threads)
        else:
            if scenario is None:
                fail_input("missing SCENARIO (or --resume RESULT.h5)")
            out = out or Path("outputs") / (scenario.stem + ".h5")
            writable_file(out, "the result")  # before the specimen is built
            from ..scenario.load import load_scenario
            from ..solvers import family

            sc, text = load_scenario(scenario, overrides)
            fam = family(sc["solver"]["kind"])
            if fam is not None:
                summary = _run_family(fam, sc, text, scenario, out, overrides, cont, overwrite, quiet)
                if summary is None:
                    return
                _print_summary(out, summary, quiet, fam)
                return
            from ..scenario.build import build_system

            system = build_system(sc, str(scenario))
            with result_lock(out):  # refused at once if another run writes this result
                if out.exists() and cont and not overwrite:
                    state = existing_state(out, system)
                    if state == "finished":
                        if not quiet:
                            click.echo(f"{out}: this scenario has already finished; nothing to do")
                        return
                    if state == "resumable":
                        summary = run(out=out, resume=True, quiet=quiet, threads=threads, pin_threads=pin_threads)
                        if not quiet:
                            click.echo(f"resumed and finished {out}")
                        return
                    fail_input(f"{out}: result of a different scenario or without checkpoint (use --overwrite)")
                if out.exists() and not overwrite:
                    fail_input(f"{out}: result file exists (use --overwrite to replace it, or --resume {out})")
                remove_existing(out)
                summary = run(
                    system,
                    out=out,
                    scenario_file=str(scenario),
                    scenario_text=text,
                    overrides=overrides,
                    quiet=quiet,
                    threads=threads,
                    pin_threads=pin_threads,
                )
    except ScenarioError as e:
        fail_input(str(e))
    except ResultError as e:
        fail_input(str(e))
    except AlreadyFinished as e:
        if not quiet:
            sm = e.args[0]
            unit = "steps" if "steps" in sm else "solves"
            click.echo(f"{out}: this run has already finished ({sm.get(unit, 0):,} {unit}); nothing to do")
        return
    except Interrupted as e:
        sys.exit(128 + int(e.args[0]))  # 130 for SIGINT, 143 for SIGTERM (the shell's convention)
    except EngineError as e:
        click.echo(f"error: run stopped: {e}", err=True)
        sys.exit(1)
    except OSError as e:  # the result, its lock or summary could not be written (e.g. the disk is full)
        cannot_write(e, out)
    _print_summary(out, summary, quiet, fam)


def _print_summary(out, summary, quiet, fam=None):
    if quiet:
        return
    if fam is not None:
        click.echo(
            f"wrote {out} ({summary['solves']:,} solves, {summary['nodes']:,} lattice nodes, "
            f"{summary['wall_time_s']:.1f} s wall)"
        )
        for line in fam.summary_lines(summary):
            click.echo("  " + line)
    else:
        from ..engine.runner import printed_summary

        for line in printed_summary(out, summary):
            click.echo(line)


def _run_family(fam, sc, text, scenario, out, overrides, cont, overwrite, quiet):
    """``run`` of a scenario of another solver family (solvers/): the same rules for existing results."""
    from ..io.hdf5 import result_lock

    with result_lock(out):
        if out.exists() and cont and not overwrite:
            state = fam.existing_state(out, sc)
            if state == "finished":
                if not quiet:
                    click.echo(f"{out}: this scenario has already finished; nothing to do")
                return None
            if state == "resumable":
                return fam.run(out=out, resume=True, quiet=quiet)
            fail_input(f"{out}: result of a different scenario or without checkpoint (use --overwrite)")
        if out.exists() and not overwrite:
            fail_input(f"{out}: result file exists (use --overwrite to replace it, or --resume {out})")
        remove_existing(out)
        return fam.run(sc, out=out, scenario_file=str(scenario), scenario_text=text, overrides=overrides, quiet=quiet)


@click.command("check")
@click.argument("scenario", type=click.Path(dir_okay=False, path_type=Path))
@click.option("--set", "overrides", multiple=True, metavar="KEY.PATH=VALUE", help="override a scenario value")
def check_cmd(scenario, overrides):
    """Validate SCENARIO without running it (exit code 2 on bad input).

    Builds the specimen and checks the initial state too.

    \b
    Example:
      polydem check scenarios/demo_hex_pile.toml --set time.dt=1e-5
    """
    from ..engine.simulation import Simulation

    try:
        from ..scenario.load import load_scenario
        from ..solvers import family

        sc, _ = load_scenario(scenario, overrides)
        fam = family(sc["solver"]["kind"])
        if fam is not None:
            for line in fam.check(sc, str(scenario)):
                click.echo(line)
            return
        system, _ = _load_and_build(scenario, overrides)
        sim = Simulation(system)
        sim.initialize()
        sim.check_initial_overlap()
        from ..engine.stability import check_time_step

        check_time_step(system)
    except ScenarioError as e:
        fail_input(str(e))
    s = system
    click.echo(
        f"{scenario}: OK — {s.n} particles in {len(s.group_names)} group(s) "
        f"({', '.join(s.group_names)}), {s.end_step:,} steps of dt = {s.dt:g} s "
        f"({s.scenario['time']['integrator']}), {len(s.frame_steps)} frames, "
        f"contact: {'on' if s.has_contact else 'off'}, monitored sets: {', '.join(s.monitored) or '-'}"
    )
    from ..engine.stability import describe, estimate

    click.echo("  " + describe(estimate(s), s.dt))
    for name, sp in s.specimens.items():
        if len(sp.shared_pairs):
            click.echo(f"  {name}: {len(sp)} particles, {len(sp.shared_pairs)} touching pairs (shared edges)")
    if s.unused:
        click.echo("note: unused parameters: " + "; ".join(s.unused))


@click.command("schema")
@click.option("--out", type=click.Path(dir_okay=False, path_type=Path), help="write Markdown to this file")
@click.option(
    "--kind",
    type=click.Choice(["explicit", "quasistatic"]),
    default="explicit",
    show_default=True,
    help="the solver family whose scenario tables to print ([solver] kind)",
)
def schema_cmd(out, kind):
    """Print the scenario file reference (Markdown), generated from the schema."""
    from ..scenario.schema import SCHEMAS
    from ..scenario.spec import markdown

    title = "Scenario file reference" + (" — quasi-static solver" if kind == "quasistatic" else "")
    text = markdown(SCHEMAS[kind], title)
    if out:
        writable_file(out, "the reference")
        with writing(out):
            out.write_text(text)
    else:
        click.echo(text)
