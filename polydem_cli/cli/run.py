"""``polydem run``, ``polydem check``, ``polydem schema``."""

from __future__ import annotations

import sys
from pathlib import Path

import click

from ..errors import DecompositionError
from ..scenario.spec import ScenarioError
from .outputs import cannot_write, writable_file, writing
from .outputs import fail as fail_input


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
@click.option(
    "--ranks",
    type=int,
    default=None,
    metavar="N",
    help="decompose the scene over N MPI ranks on this machine (started with the mpiexec of the mpi extra; under a "
    "cluster's launcher use mpiexec -n N polydem run ... instead); explicit scenes without loading plates",
)
@click.option("-q", "--quiet", is_flag=True, help="no progress output and no closing summary")
def run_cmd(scenario, out, overrides, overwrite, resume, cont, threads, pin_threads, ranks, quiet):
    """Run SCENARIO (a TOML file) and write an HDF5 result plus <result>.summary.json.

    \b
    Example:
      polydem run scenarios/demo_hex_pile.toml -o outputs/demo.h5
      polydem run --resume outputs/demo.h5
    """
    from ..engine.simulation import EngineError
    from ..io.hdf5 import ResultError
    from ..solvers import driver
    from ..solvers.protocol import RunOptions, Source

    size = _ranks(scenario, overrides, resume, ranks)
    if size is None:  # a rank > 0 of a decomposed run: it has served rank 0
        return
    if size > 1:  # rank 0: the other ranks leave serve() however this ends (from here on)
        import atexit

        from mpi4py import MPI

        atexit.register(lambda: MPI.COMM_WORLD.bcast(("stop", ()), root=0))

    if pin_threads and threads == "auto":
        fail_input("--pin-threads needs a count: --threads N --pin-threads")
    if threads != "auto":
        import numba

        nmax = numba.config.NUMBA_NUM_THREADS
        if not threads.isdigit() or not 1 <= int(threads) <= nmax:
            fail_input(f"--threads {threads}: must be 'auto' or a whole number between 1 and {nmax}")
        threads = int(threads)
    opts = RunOptions(quiet=quiet, threads=threads, pin_threads=pin_threads)
    try:
        if resume is not None:
            if scenario is not None or overrides or out is not None:
                fail_input("--resume RESULT takes no scenario, -o or --set (the result file holds them)")
            out = resume
            if not resume.exists():
                fail_input(f"{resume}: no such result file")
            writable_file(resume, "the result")  # its lock, checkpoints and summary are written beside it
            outcome = driver.Outcome("resumed", driver.run(out=resume, resume=True, opts=opts))
        else:
            if scenario is None:
                fail_input("missing SCENARIO (or --resume RESULT.h5)")
            out = out or Path("outputs") / (scenario.stem + ".h5")
            writable_file(out, "the result")  # before the specimen is built
            from ..scenario.load import load_scenario

            sc, text = load_scenario(scenario, overrides)
            policy = driver.OVERWRITE if overwrite else driver.CONTINUE if cont else driver.NEW
            source = Source(str(scenario), text, tuple(overrides))
            outcome = driver.obtain(sc, out, source=source, policy=policy, opts=opts)
    except (ScenarioError, DecompositionError) as e:
        fail_input(str(e))
    except ResultError as e:
        fail_input(str(e))
    except driver.AlreadyFinished as e:
        if not quiet:
            sm = e.args[0]
            unit = "steps" if "steps" in sm else "solves"
            click.echo(f"{out}: this run has already finished ({sm.get(unit, 0):,} {unit}); nothing to do")
        return
    except driver.Interrupted as e:
        sys.exit(128 + int(e.args[0]))  # 130 for SIGINT, 143 for SIGTERM (the shell's convention)
    except EngineError as e:
        click.echo(f"error: run stopped: {e}", err=True)
        sys.exit(1)
    except OSError as e:  # the result, its lock or summary could not be written (e.g. the disk is full)
        cannot_write(e, out)
    if quiet:
        return
    if outcome.action == "reused":
        click.echo(f"{out}: this scenario has already finished; nothing to do")
        return
    if outcome.action == "resumed" and resume is None:
        click.echo(f"resumed and finished {out}")
    for line in driver.printed_summary(out, outcome.summary):
        click.echo(line)


def _ranks(scenario, overrides, resume, ranks):
    """The number of ranks this run has (1: serial); None if this process was a rank > 0 and has served rank 0
    (engine/distributed.py ``serve``).  ``--ranks N`` without a launcher: refuse what cannot run on N ranks, then
    start this command again on N ranks (:func:`_launch`)."""
    from ..engine.distributed import launched_ranks

    size = launched_ranks()
    if ranks is not None and ranks < 1:
        fail_input(f"--ranks {ranks}: at least 1")
    if size > 1:
        if ranks is not None and ranks != size:
            fail_input(f"--ranks {ranks}, but the launcher started {size} ranks: leave --ranks out under mpiexec")
        from mpi4py import MPI

        if MPI.COMM_WORLD.Get_size() != size:
            fail_input(
                f"the launcher says {size} ranks but MPI sees {MPI.COMM_WORLD.Get_size()}: mpi4py is built for another "
                "MPI than the mpiexec used (use the mpiexec next to this Python, or mpi4py built for the cluster's MPI)"
            )
        _note_pid(MPI.COMM_WORLD.Get_rank())
        if MPI.COMM_WORLD.Get_rank() > 0:
            from ..engine.distributed import serve
            from ..scenario.build import build_system

            serve(build_system)
            return None
    elif ranks is not None and ranks > 1:
        if resume is None and scenario is not None:  # refuse what cannot run on N ranks before starting them
            from ..engine.distributed import check
            from ..scenario.build import build_system
            from ..scenario.load import load_scenario

            try:
                sc, _ = load_scenario(scenario, overrides)
                check(build_system(sc, str(scenario)), ranks)
            except (ScenarioError, DecompositionError) as e:
                fail_input(str(e))
        _launch(ranks)
    return size


def _launch(ranks: int):
    """Start this very command again on ``ranks`` MPI ranks (the mpiexec of the mpi extra, next to this Python), pass
    SIGINT/SIGTERM on to them (rank 0 then stops every rank after a checkpoint) and leave with their exit status;
    when a rank died or failed (the launcher names it above), say that the result keeps its last checkpoint."""
    import os
    import shutil
    import signal
    import subprocess

    mpiexec = Path(sys.executable).with_name("mpiexec")
    if not mpiexec.exists():
        mpiexec = shutil.which("mpiexec")
    if mpiexec is None:
        fail_input(f"--ranks {ranks} needs MPI: pip install 'polydem[mpi]' (mpi4py and the MPICH wheel)")
    argv, skip = [], False
    for a in sys.argv[1:]:
        if skip:
            skip = False
            continue
        if a == "--ranks":
            skip = True
            continue
        if a.startswith("--ranks="):
            continue
        argv.append(a)
    import tempfile

    fd, pids = tempfile.mkstemp(prefix="polydem-ranks-", suffix=".txt")
    os.close(fd)
    env = dict(os.environ, OMP_NUM_THREADS="1", POLYDEM_RANK_PIDS=pids)
    cmd = [str(mpiexec), "-n", str(ranks), sys.executable, "-m", "polydem_cli", *argv]
    started, pending = [], []

    def forward(sig, _frame):  # SIGHUP (the terminal closed) too: the ranks are in a session of their own
        if not started:
            pending.append(sig)
            return
        try:
            os.killpg(started[0].pid, signal.SIGINT if sig == signal.SIGHUP else sig)
        except ProcessLookupError:
            pass

    for sig in (signal.SIGINT, signal.SIGTERM, signal.SIGHUP):
        signal.signal(sig, forward)
    started.append(subprocess.Popen(cmd, env=env, start_new_session=True))  # signals reach the ranks from here, once
    for sig in pending:
        forward(sig, None)
    rc = started[0].wait()
    if rc < 0:  # mpiexec itself ended by a signal: the shell's convention
        rc = 128 - rc
    try:
        with open(pids) as f:
            who = sorted(tuple(map(int, line.split())) for line in f if line.strip())
        os.unlink(pids)
    except (OSError, ValueError):
        who = []
    if rc not in (0, 1, 2, 128 + signal.SIGINT, 128 + signal.SIGTERM):
        out = _result_named(argv)
        names = ", ".join(f"rank {r} = {p}" for r, p in who)
        click.echo(
            f"error: the run on {ranks} ranks ended abnormally (mpiexec exit status {rc}): a rank died or failed; "
            f"mpiexec's message above gives its process id ({names or 'the ranks did not start'}). "
            + (
                f"{out} keeps its last checkpoint: continue with: polydem run --resume {out}"
                if out and Path(out).exists()
                else "no result was written"
            ),
            err=True,
        )
    sys.exit(rc)


def _note_pid(rank: int):
    """Under ``polydem run --ranks``: note this rank's process id for the launching process (which names the rank of
    a process that died)."""
    import os

    path = os.environ.get("POLYDEM_RANK_PIDS")
    if path:
        try:
            with open(path, "a") as f:
                f.write(f"{rank} {os.getpid()}\n")
        except OSError:
            pass


def _result_named(argv) -> str | None:
    """The result file a ``polydem run`` command line writes (``-o``/``--out``/``--resume``, else the default)."""
    for i, a in enumerate(argv):
        for opt in ("-o", "--out", "--resume"):
            if a == opt and i + 1 < len(argv):
                return argv[i + 1]
            if a.startswith(opt + "=") and opt != "-o":
                return a.split("=", 1)[1]
    scen = next((a for a in argv[1:] if a.endswith(".toml")), None)
    return str(Path("outputs") / (Path(scen).stem + ".h5")) if scen else None


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
    try:
        from ..scenario.load import load_scenario
        from ..solvers import family_module

        sc, _ = load_scenario(scenario, overrides)
        lines = family_module(sc["solver"]["kind"]).check(sc, str(scenario))
    except ScenarioError as e:
        fail_input(str(e))
    for line in lines:
        click.echo(line)


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
