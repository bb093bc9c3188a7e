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
    default="auto",
    show_default=True,
    envvar="POLYDEM_RANKS",
    metavar="N|auto",
    help="decompose the scene over N MPI ranks on this machine (started with the mpiexec of the mpi extra; under a "
    "cluster's launcher use mpiexec -n N polydem run ... instead); explicit scenes without loading plates; at most "
    "the cores this machine lets polydem use (see --oversubscribe).  auto (the default, or $POLYDEM_RANKS): as many "
    "ranks as cores other processes leave free when the scene has enough particles per rank to gain and --threads "
    "is auto, else one process (a line says which and why, except for an asked --threads N); never under a "
    "launcher or batch system (mpiexec, srun, a job script)",
)
@click.option(
    "--oversubscribe",
    is_flag=True,
    help="run more ranks (x pinned threads) than this machine's cores, refused without it (tests, studies of the "
    "decomposition): the ranks take turns on the cores, slower than ranks = cores, and each rank is a process with "
    "the whole scene (a line says what it costs)",
)
@click.option("-q", "--quiet", is_flag=True, help="no progress output and no closing summary")
def run_cmd(scenario, out, overrides, overwrite, resume, cont, threads, pin_threads, ranks, oversubscribe, quiet):
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

    size = _ranks(scenario, overrides, resume, ranks, threads, pin_threads, oversubscribe, out, cont, quiet)
    if size is None:  # a rank > 0 of a decomposed run: it has served rank 0
        return

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
    except ScenarioError as e:
        fail_input(str(e))
    except DecompositionError as e:  # under a launcher: the scene cut for the ranks it started (engine/distributed.py)
        fail_input(f"{resume or scenario}: {size} ranks: {e}")
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


def _ranks(  # noqa: PLR0913 - the options of run that decide the ranks
    scenario,
    overrides,
    resume,
    ranks,
    threads="auto",
    pin_threads=False,
    oversubscribe=False,
    out=None,
    cont=False,
    quiet=False,
):
    """The number of ranks this run has (1: serial); None if this process was a rank > 0 and has served rank 0
    (engine/distributed.py ``serve``).  ``--ranks N`` without a launcher: refuse what cannot run on N ranks — a
    solver or interaction family that does not run decomposed, a scene too small to cut into N parts, more ranks
    (× pinned threads) than cores without ``--oversubscribe`` — each refusal naming the file, the key or family and
    the reason, then start this command again on N ranks (:func:`_launch`).  Under a launcher rank 0 refuses the same
    (its scene is cut when the run begins: a refusal then comes from the driver, cf. ``run_cmd``).  ``auto`` (the
    default) without a launcher: the count :func:`auto_ranks` chooses, then as ``--ranks N``; it never refuses."""
    import os

    from ..engine.distributed import launched_local_ranks, launched_ranks

    size = launched_ranks()
    if size > 1 and not _given_on_command_line("ranks"):
        ranks = "auto"  # $POLYDEM_RANKS (or the default) does not contradict a launcher: its ranks are the run's
    ranks = _parse_ranks(ranks)
    if ranks == "auto":
        if size > 1:  # under a launcher: the ranks it started
            ranks = None
        else:
            scene = []  # the scene auto_ranks built, handed to rank 0 (scenario/handover.py)
            ranks = (
                1
                if under_launcher()
                else auto_ranks(scenario, overrides, resume, threads, pin_threads, out, cont, quiet, scene)
            )
            if ranks > 1:
                _launch(ranks, scene)
            return 1
    each = int(threads) if pin_threads and str(threads).isdigit() else 1
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

            serve()
            return None
        import atexit

        # rank 0: the other ranks leave serve() however this ends (from here on, refusals included)
        from ..engine.distributed import command

        atexit.register(lambda: command(MPI.COMM_WORLD, "stop"))
        where, sc, _ = _scene_of(scenario, overrides, resume)
        _refuse_kind(where, sc, f"{size} ranks (mpiexec -n {size})")
        local = launched_local_ranks()
        if local and not os.environ.get("POLYDEM_RANK_PIDS"):  # polydem run --ranks has checked the cores already
            _cores(
                where,
                f"{local} ranks on this machine (mpiexec -n {size})",
                local,
                each,
                os.cpu_count() or 1,
                oversubscribe,
                "mpiexec -n",
            )
    elif ranks is not None and ranks > 1:
        from ..engine.distributed import check
        from ..scenario.build import build_system

        where, sc, file = _scene_of(scenario, overrides, resume)  # refuse what cannot run on N ranks before starting
        _refuse_kind(where, sc, f"--ranks {ranks}")
        mb = _private_mb()  # a rank's own memory at least (the scene built next is rank 0's, and handed to it)
        try:
            system = build_system(sc, file)
            check(system, ranks)
        except ScenarioError as e:
            fail_input(str(e))
        except DecompositionError as e:
            fail_input(f"{where}: --ranks {ranks}: {e}")
        what = f"--ranks {ranks}" + (f" × --threads {each} --pin-threads" if each > 1 else "")
        _cores(where, what, ranks, each, _available_cores(), oversubscribe, mb=mb)
        scene = [(system, sc, file)]
        del system
        _launch(ranks, scene)
    return size


def _given_on_command_line(name: str) -> bool:
    """Whether the option ``name`` of the running click command was given on its command line (not taken from its
    environment variable or default); True outside a click command."""
    ctx = click.get_current_context(silent=True)
    if ctx is None:
        return True
    src = ctx.get_parameter_source(name)
    return src is None or src == click.core.ParameterSource.COMMANDLINE


def _parse_ranks(ranks):
    """``--ranks``: "auto", None or a whole number at least 1 (exit 2 otherwise)."""
    if ranks is None or ranks == "auto" or isinstance(ranks, int) and ranks >= 1:
        return ranks
    text = str(ranks).strip()
    if text == "auto":
        return "auto"
    try:
        n = int(text)
    except ValueError:
        n = 0
    if n < 1:
        fail_input(f"--ranks {ranks}: at least 1, or auto")
    return n


#: environment variables that say this process runs under a launcher or batch system (or is a rank polydem started):
#: ``--ranks auto`` then never starts an mpiexec of its own (a single-rank ``mpiexec -n 1``, ``srun -n 1`` or a job
#: script's plain command report one rank; the cluster's launcher decides the ranks there)
LAUNCHER_VARS = ("POLYDEM_RANK_PIDS", "PMI_RANK", "PMIX_RANK", "OMPI_COMM_WORLD_RANK", "SLURM_JOB_ID", "PBS_JOBID")


def under_launcher() -> bool:
    """Whether any of :data:`LAUNCHER_VARS` is set."""
    import os

    return any(os.environ.get(k) for k in LAUNCHER_VARS)


def auto_ranks(  # noqa: PLR0913 - the options of run that decide the ranks
    scenario, overrides, resume, threads, pin_threads, out=None, cont=False, quiet=False, scene=None
) -> int:
    """``--ranks auto``: the ranks a run on this machine starts with, and a line on stderr that says why.

    More than one only where the decomposition is measured to pay (docs/performance.md, "Ranks by default"):
    ``--threads`` is auto (a thread count asked for keeps one process with it), the solver is explicit and every
    family of the scene runs decomposed, MPI is installed, and then as many ranks as cores other processes leave
    free (``/proc/stat`` over ``AUTO_WINDOW_S``, as ``--threads auto`` counts them, engine/threads.py), at most
    one per ``AUTO_PARTICLES_PER_RANK`` particles (engine/threads.py :func:`auto_rank_count`).  A run that ``--continue`` finds finished is not started
    on ranks.  ``scene``: a list that gets the scene built to choose, (system, scenario, file), when the count is
    more than one (:func:`_launch` hands it to rank 0).  The result does not depend on the count (bit-identical, tests/test_ranks.py)."""
    if threads != "auto" or pin_threads:
        return 1  # a thread count asked for: one process with it, nothing to say
    say = (lambda m: None) if quiet else (lambda m: click.echo(f"ranks auto: {m}", err=True))
    from ..engine import threads as governor

    if governor.available_cores() < 2:
        return 1
    if _mpiexec() is None or not _has_mpi4py():
        say("one process: MPI is not installed here (pip install 'polydem[mpi]', which make demo does)")
        return 1
    try:
        where, sc, file = _scene_quiet(scenario, overrides, resume)
    except Exception:  # noqa: BLE001 - the run itself says what is wrong with its input
        return 1
    if sc["solver"]["kind"] != "explicit":
        say(f"one process: [solver] kind = '{sc['solver']['kind']}' does not run on ranks")
        return 1
    if cont and resume is None and _finished(sc, out or Path("outputs") / (Path(scenario).stem + ".h5")):
        return 1
    free = governor.free_cores()
    if free < 2:
        say(f"one process: {free} core{'' if free == 1 else 's'} free of {governor.available_cores()}")
        return 1
    from ..engine.distributed import check, trim_heap
    from ..scenario.build import build_system

    try:
        system = build_system(sc, file)
    except Exception:  # noqa: BLE001 - the run itself says what is wrong with its input
        return 1
    n = governor.auto_rank_count(system.n, free)
    if n < 2:
        say(f"one process: {system.n:,} particles, fewer than 2 x {governor.AUTO_PARTICLES_PER_RANK} for 2 ranks")
        return 1
    try:
        check(system, n)
    except DecompositionError as e:
        say(f"one process: {e}")
        return 1
    count = system.n
    if scene is not None:
        scene.append((system, sc, file))
    del system
    trim_heap()  # the scene built to choose: its memory back to the machine while the ranks run (unless kept)
    say(f"{n} ranks ({free} free cores, {count:,} particles; --ranks 1 for one process)")
    return n


def _finished(sc, res) -> bool:
    """Whether the result ``res`` holds a finished run of the resolved scenario ``sc`` (what ``--continue`` would
    then do nothing for)."""
    try:
        from ..solvers.driver import existing

        return Path(res).exists() and existing(Path(res), sc).state == "finished"
    except Exception:  # noqa: BLE001 - the run itself says what is wrong with the result
        return False


def _scene_quiet(scenario, overrides, resume):
    """:func:`_scene_of` that raises instead of exiting (``--ranks auto`` leaves the refusal to the run)."""
    import contextlib
    import io

    try:
        with contextlib.redirect_stderr(io.StringIO()):
            return _scene_of(scenario, overrides, resume)
    except SystemExit as e:
        raise ValueError("no scene") from e


def _has_mpi4py() -> bool:
    import importlib.util

    return importlib.util.find_spec("mpi4py") is not None


def _mpiexec():
    """The mpiexec of the mpi extra (next to this Python), else the one on PATH, else None."""
    import shutil

    mpiexec = Path(sys.executable).with_name("mpiexec")
    return str(mpiexec) if mpiexec.exists() else shutil.which("mpiexec")


def _scene_of(scenario, overrides, resume):
    """(how to name it, the resolved scenario, its file) of the run this command makes: from the scenario file, or
    from the result a ``--resume`` continues.  Exit 2 with the reason when there is neither or it cannot be read."""
    import json

    from ..io.hdf5 import ResultError, open_result

    if resume is not None:
        from ..solvers import result_family

        try:
            if not Path(resume).exists():
                raise ResultError(f"{resume}: no such result file")
            cls = result_family(resume)
            if cls is None:
                with open_result(resume):  # says what the file is (foreign, truncated, locked)
                    pass
                raise ResultError(f"{resume}: not a polydem result")
            with open_result(resume, fmt=cls.FORMAT) as f:
                sc, file = json.loads(f.attrs["resolved"]), str(f.attrs["scenario_file"])
        except ResultError as e:
            fail_input(str(e))
        return f"{resume} (scenario {file})", sc, file
    if scenario is None:
        fail_input("missing SCENARIO (or --resume RESULT.h5)")
    from ..scenario.load import load_scenario

    try:
        sc, _ = load_scenario(scenario, overrides)
    except ScenarioError as e:
        fail_input(str(e))
    return str(scenario), sc, str(scenario)


def _refuse_kind(where, sc, what):
    """Exit 2 unless the scenario's solver family runs on several ranks (the explicit one)."""
    kind = sc["solver"]["kind"]
    if kind != "explicit":
        fail_input(
            f"{where}: {what}: [solver] kind = '{kind}' does not run on several ranks (only the explicit solver "
            "decomposes a scene); run it on one process, without --ranks"
        )


def _available_cores() -> int:
    """The cores this process may run on (its CPU affinity, which the ranks it starts inherit)."""
    import os

    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # not Linux
        return os.cpu_count() or 1


def _cores(where, what, ranks, each, cores, oversubscribe, flag="--ranks", mb=None):  # noqa: PLR0913
    """More ranks × pinned threads than ``cores``: exit 2 naming the cost, or with ``--oversubscribe`` a line saying
    what it costs (``mb``: a rank's own memory at least, default this process's private memory)."""
    need = ranks * each
    if need <= cores:
        return
    cost = _oversubscription_cost(ranks, need, cores, mb)
    on = f"{cores} core{'s' if cores > 1 else ''}"
    if not oversubscribe:
        fewer = f"{flag} {cores // each} or fewer" if cores >= each else "fewer --threads"
        fail_input(
            f"{where}: {what}: {need} {'threads' if each > 1 else 'ranks'} for the {on} this machine lets polydem "
            f"use: refused; use {fewer}, or add --oversubscribe to run it all the same (tests, studies of the "
            f"decomposition) at this cost: {cost}"
        )
    click.echo(f"note: --oversubscribe: {what} on {on}: {cost}", err=True)


def _oversubscription_cost(ranks, need, cores, mb=None) -> str:
    """What ``need`` ranks × threads on ``cores`` cost: time (they take turns, and MPICH's waiting ranks spin) and
    memory (every rank a process with the interpreter, the compiled loop and its part of the scene: at least this
    process's private written memory each)."""
    mb = _private_mb() if mb is None else mb
    total = ranks * mb / 1024
    avail = _available_gb()
    text = (
        f"{need / cores:.3g} per core take turns and MPICH's waiting ranks spin, so the run is slower than on {cores} "
        f"rank{'s' if cores > 1 else ''}, not only no faster (scenarios/concrete_tension.toml: 2.4x slower on 4 ranks "
        f"than on 2, 2 cores); each rank is a process of its own with the interpreter, the compiled loop and its part "
        f"of the scene: at least "
        f"{mb:.0f} MB each, {total:.1f} GB for {ranks}"
    )
    if avail is not None:
        text += f" of the {avail:.1f} GB available" + (
            ": more than there is, the machine will swap or its out-of-memory killer end ranks" if total > avail else ""
        )
    return text


def _private_mb() -> float:
    """This process's private written memory in MB, what a rank (the same interpreter and libraries, and more) has at
    least of its own (the pages of the libraries' files are shared by the ranks)."""
    try:
        with open("/proc/self/smaps_rollup") as f:
            kb = sum(int(line.split()[1]) for line in f if line.startswith("Private_Dirty:"))
        return kb / 1024
    except (OSError, ValueError, IndexError):
        import resource

        return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024


def _available_gb() -> float | None:
    try:
        with open("/proc/meminfo") as f:
            for line in f:
                if line.startswith("MemAvailable:"):
                    return int(line.split()[1]) / 1024**2
    except (OSError, ValueError, IndexError):
        pass
    return None


def _launch(ranks: int, scene=()):
    """Start this very command again on ``ranks`` MPI ranks (the mpiexec of the mpi extra, next to this Python), pass
    SIGINT/SIGTERM on to them (rank 0 then stops every rank after a checkpoint) and leave with their exit status.
    ``scene``: a list with the scene built here, (system, scenario, file), written for rank 0 to read instead of
    building it again (scenario/handover.py) and taken out of the list, so that its memory goes back to the machine
    while the ranks run.
    When a rank died or failed: which rank ended first and how (:class:`_Watch`, mpiexec's exit status), and what the
    result keeps — its last checkpoint's step and time, how much work after it is lost — read from the file."""
    import os
    import signal
    import subprocess
    import time

    mpiexec = _mpiexec()
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

    from ..engine.distributed import trim_heap
    from ..scenario import handover

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
    handed = pids = None
    try:  # the temporary files go however this ends
        if scene:
            system, sc, file = scene.pop()
            try:
                handed = handover.hand_over(system, sc, file)
            except Exception:  # noqa: BLE001 - no room in the temporary folder, say: rank 0 builds it, as under any launcher
                pass
            del system
        trim_heap()  # the scene built here: its memory back to the machine while the ranks run
        if pending:  # stopped while the scene was written: no rank started, nothing to stop
            sys.exit(128 + int(pending[0]))
        fd, pids = tempfile.mkstemp(prefix="polydem-ranks-", suffix=".txt")
        os.close(fd)
        env = dict(os.environ, OMP_NUM_THREADS="1", POLYDEM_RANK_PIDS=pids)
        env.pop(handover.ENV, None)
        if handed:
            env[handover.ENV] = handed
        cmd = [str(mpiexec), "-n", str(ranks), sys.executable, "-m", "polydem_cli", *argv]
        started.append(
            subprocess.Popen(cmd, env=env, start_new_session=True)
        )  # signals reach the ranks from here, once
        watch = _Watch(pids)
        watch.start()
        for sig in pending:
            forward(sig, None)
        rc = started[0].wait()
        t_end = time.time()
        watch.finish()
    finally:
        for path in (pids, handed):  # rank 0 deletes the scene's once read; not if it failed before
            if path:
                handover.discard(path)
    if rc < 0:  # mpiexec itself ended by a signal: the shell's convention
        rc = 128 - rc
    who = sorted(watch.seen)
    if rc not in (0, 1, 2, 128 + signal.SIGINT, 128 + signal.SIGTERM):
        out = _result_named(argv)
        first, t_first = watch.first()
        lines = [_death(ranks, rc, who, first)]
        if out and Path(out).exists():
            again = f"polydem run --resume {out} --ranks {ranks}" + (
                " --oversubscribe" if "--oversubscribe" in argv else ""
            )
            lines.append(_kept(out, t_first or t_end, first) + f"; continue with: {again}")
        else:
            lines.append("no result was written")
        click.echo("error: " + "\n  ".join(lines), err=True)
    sys.exit(rc)


class _Watch:
    """Follows the ranks' processes as each notes its process id (:func:`_note_pid`) and records when each ends (a
    pidfd per process, polled; where there is none, a probe every 0.1 s): the rank that ended first is the one that
    died or failed — mpiexec then stops the others — whatever process mpiexec's message names."""

    def __init__(self, path):
        import threading

        self.path = path
        self.seen = set()  # (rank, pid)
        self.ended = []  # (wake, time, rank, pid): ends seen at the same wake are not told apart
        self._done = threading.Event()
        self._thread = threading.Thread(target=self._run, daemon=True)

    def start(self):
        self._thread.start()

    def finish(self):
        self._done.set()
        self._thread.join(5.0)

    def first(self):
        """([(rank, pid), …] that ended first, the time they did); ([], None) if none was seen ending."""
        if not self.ended:
            return [], None
        w = min(e[0] for e in self.ended)
        firsts = [e for e in self.ended if e[0] == w]
        return sorted((r, p) for _, _, r, p in firsts), min(t for _, t, _, _ in firsts)

    def _run(self):
        import os
        import select
        import time

        poller, fds, probed, wake = select.poll(), {}, {}, 0
        while True:
            last = self._done.is_set()  # mpiexec has ended: one more look, then stop
            try:
                with open(self.path) as f:
                    text = f.read()
            except OSError:
                text = ""
            gone = []
            for line in text.split("\n")[:-1]:  # whole lines only (a rank may be writing its own)
                try:
                    rank, pid = map(int, line.split())
                except ValueError:
                    continue
                if (rank, pid) in self.seen:
                    continue
                self.seen.add((rank, pid))
                try:
                    fd = os.pidfd_open(pid)
                except ProcessLookupError:  # ended before it could be watched
                    gone.append((rank, pid))
                    continue
                except (AttributeError, OSError):  # no pidfd here: probe
                    probed[pid] = rank
                    continue
                fds[fd] = (rank, pid)
                poller.register(fd, select.POLLIN)
            events = poller.poll(100) if fds else []
            if not fds:
                time.sleep(0.1)
            now = time.time()
            gone += [fds.pop(fd) for fd, _ in events]
            for fd, _ in events:
                poller.unregister(fd)
                os.close(fd)
            for pid, rank in list(probed.items()):
                try:
                    os.kill(pid, 0)
                except ProcessLookupError:
                    gone.append((rank, pid))
                    del probed[pid]
                except OSError:
                    pass
            if gone:
                wake += 1
                self.ended += [(wake, now, r, p) for r, p in gone]
            if last:
                break
        for fd in fds:
            os.close(fd)


def _death(ranks, rc, who, first) -> str:
    """What ended a run on ``ranks`` ranks abnormally: which rank and process, and how, as far as can be told."""
    import signal

    names = ", ".join(f"rank {r} = {p}" for r, p in who)
    missing = sorted(set(range(ranks)) - {r for r, _ in who})
    how = f"mpiexec exit status {rc}"
    failed = 70 <= rc <= 120  # engine/distributed.py abort: 70 + the failing rank (120: rank 50 or above)
    if failed:
        how += f": rank {rc - 70}{' or above' if rc == 120 else ''} failed (its message above)"
    elif 1 <= rc < 64:
        try:
            name = signal.Signals(rc).name
        except ValueError:
            name = None
        if name:
            hint = {"SIGKILL": ": kill -9 or the kernel's out-of-memory killer", "SIGSEGV": ": a crash"}.get(name, "")
            how += f": signal {rc}, {name}{hint}"
    elif rc > 128:
        how += f": mpiexec itself killed by signal {rc - 128}"
    if failed and rc < 120:
        pid = dict(who).get(rc - 70)
        head = f"rank {rc - 70}" + (f" (process {pid})" if pid else "") + " failed"
    elif len(first) == 1:
        head = f"rank {first[0][0]} (process {first[0][1]}) died first"
    elif first:
        head = " and ".join(f"rank {r} (process {p})" for r, p in first) + " ended at the same moment"
    else:
        head = "a rank died or failed"
    tail = f"every rank stopped ({names or 'no rank noted its process'}"
    tail += f"; rank {', '.join(map(str, missing))} had not started)" if missing and who else ")"
    return f"the run on {ranks} ranks ended abnormally: {head} ({how}); {tail}"


def _kept(out, t_death, first) -> str:
    """What the result ``out`` of a run that died at ``t_death`` keeps: its last checkpoint's step and time and the
    work after it that is lost (how far the run had got: its history table; how long ago: the session's segment)."""
    import datetime as dt
    import json
    import time

    from ..io.hdf5 import ResultError, open_result, read_checkpoint, wait_for_writer

    wait_for_writer(out, timeout=60.0)  # the writer (a session of its own) applies the messages it has, then ends
    err = None
    for _ in range(50):  # its lock goes with it
        try:
            with open_result(out) as f:
                ck = read_checkpoint(f)
                sc = json.loads(f.attrs["resolved"])
                segs = json.loads(f.attrs.get("segments", "[]"))
                t = f["history/table"]
                cols = json.loads(t.attrs["columns"])
                reached = int(t[-1, cols.index("step")]) if t.shape[0] and "step" in cols else None
            break
        except ResultError as e:
            err = e
            time.sleep(0.2)
        except (OSError, KeyError, ValueError) as e:
            return f"{out}: its checkpoint could not be read ({e})"
    else:
        return f"{out}: its checkpoint could not be read ({err})"
    if ck is None:
        return f"{out} holds no checkpoint: nothing to resume (start again with --overwrite)"
    dt_s, interval = float(sc["time"]["dt"]), float(sc["output"]["checkpoint_interval"])
    step, written = int(ck["step"][0]), float(ck["wall_elapsed"][0])
    seg = segs[-1] if segs and "end" not in segs[-1] else None  # this session's segment (written when it began)
    only = seg is not None and step <= seg["start"]
    which = "its last checkpoint"
    if only:  # none written since this session began: all its work is lost
        which = "only the checkpoint this session " + ("resumed from" if seg["start"] else "began with")
    text = f"{out} keeps {which}: step {step:,} (t = {step * dt_s:.6g} s)"
    lost = None
    if seg is not None:
        began = dt.datetime.fromisoformat(seg["started"]).timestamp()
        lost = seg["wall_before"] + (t_death - began) - written
    who = f"rank {first[0][0]} died" if len(first) == 1 else "the ranks stopped"
    if lost is not None and lost > 0:
        text += f", written {lost:.2g} s of wall before {who}"
    text += "; the work after it is lost"
    if reached is not None and reached > step:  # how far the run had got: the history rows it had sent
        text += f" (the run had reached step {reached:,}, t = {reached * dt_s:.6g} s: {reached - step:,} steps)"
    text += f", a checkpoint being written every {interval:g} s of wall (output.checkpoint_interval)"
    return text


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
