"""The contract between the run driver (:mod:`.driver`) and a solver family (:mod:`.explicit`,
:mod:`.quasistatic`, …).

The driver owns everything a run does the same way whatever it solves: the result's write lock, the decision
about an existing result (reuse, resume, replace or refuse), the writer process, SIGINT/SIGTERM, the checkpoint
cadence (two checksummed slots, ``io/hdf5.py``), provenance and the summary file.  A family owns its model, its
result layout and one step of its loop.  A family never touches the file: every write is a writer message
(``io/hdf5.py`` ``_FileWriter.op_*``), so every family's results get the same crash safety.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path


@dataclass(frozen=True)
class Source:
    """Where a run's scenario came from (provenance): the file, its text as read, the ``--set`` overrides."""

    scenario_file: str = ""
    scenario_text: str = ""
    overrides: tuple = ()


@dataclass(frozen=True)
class RunOptions:
    """How to run, not what: the progress stream, quiet, the tests' early stop, threads (explicit only)."""

    quiet: bool = False
    stream: object = None  # default sys.stderr
    stop_after: int | None = None  # tests: end the session after this step / solve, as if killed after a checkpoint
    threads: object = "auto"
    pin_threads: bool = False
    callbacks: tuple = ()  # Every triggers: called between chunks of the loop (the Python API)


@dataclass(frozen=True)
class Every:
    """Call ``fn(state)`` (a :class:`RunState`) every ``steps`` steps (solves) or every ``time`` seconds of simulated
    time (explicit runs): the loop stops exactly there, and only there for it, so that the compiled loop is left no
    more often than the callback asks.  ``fn`` may read the state, record what it likes, and stop the run by
    returning False (the run ends after a checkpoint and can be resumed); an exception it raises stops the run after
    a checkpoint and comes back as :class:`~.driver.CallbackError` with its message."""

    fn: object
    steps: int | None = None
    time: float | None = None

    def __post_init__(self):
        from ..errors import PolydemError

        if (self.steps is None) == (self.time is None):
            raise PolydemError("Every: give exactly one of steps= and time=")
        if self.steps is not None and (
            not isinstance(self.steps, int) or isinstance(self.steps, bool) or self.steps < 1
        ):
            raise PolydemError(f"Every: steps = {self.steps!r}: a whole number >= 1")
        if self.time is not None and not self.time > 0:
            raise PolydemError(f"Every: time = {self.time!r}: must be > 0 s")
        if not callable(self.fn):
            raise PolydemError(f"Every: {self.fn!r} is not callable")


@dataclass(frozen=True)
class RunState:
    """What a callback sees of a run between two chunks of its loop: its work (steps or solves), simulated time
    (None for a quasi-static run), the last history row by column name, and (explicit runs) copies of the
    generalized positions and velocities (n, 3) of every particle."""

    work: int
    time: float | None
    history: dict
    positions: object = None
    velocities: object = None


@dataclass(frozen=True)
class Resume:
    """What the driver read from a result to resume it (handed to :meth:`SolverFamily.restore`)."""

    checkpoint: dict  # the latest intact checkpoint slot
    kept: object  # the history rows the checkpoint counts
    file_columns: list  # the history table's column names as stored
    written_by: str  # code_version of the result
    out: Path | None = None  # the result file


@dataclass(frozen=True)
class SessionInfo:
    """What the driver measured in one session, handed to :meth:`SolverFamily.summary`."""

    out: Path
    wall: float  # over all sessions of the run
    wall_loop: float  # this session's loop
    work_run: int  # steps / solves done this session
    resumed: bool
    failure: str | None
    finished: bool


class SolverFamily:
    """One solver family's part of a run.  Subclasses set the class attributes and implement the methods; the
    driver calls them in this order: ``__init__`` (fresh or resumed), then ``create`` or ``restore``, ``warm_up``,
    while not ``done()``: ``advance``, ``progress``; then ``progress(final=True)``, ``finish``, ``summary``.

    A family module also provides ``FAMILY`` (the class), ``check(resolved, file)`` → lines for ``polydem
    check``, ``summary_lines(summary)`` and ``headline(out, summary)`` for ``polydem run``, and
    ``table_row(summary)`` → the sweep's columns."""

    KIND: str = ""  # [solver] kind
    FORMAT: str = ""  # root attr "format" of its results
    UNIT: str = "step"  # what ``work`` counts, in messages

    resolved: dict  # the validated scenario
    work: int = 0  # steps / solves done so far (absolute)

    def __init__(self, resolved: dict, source: Source, opts: RunOptions, fresh: bool):
        """Build the model from the validated scenario; with ``fresh`` check the initial state too — all before
        any file is written."""
        raise NotImplementedError

    def create(self, writer, attrs: dict) -> None:
        """A new result: the layout messages (``attrs``: provenance, to which the family adds its own) and the
        initial rows."""
        raise NotImplementedError

    def restore(self, back: Resume) -> dict:
        """Resume: restore the state from ``back.checkpoint``; return the arguments of the writer's ``open``
        message that cuts the file back to the checkpoint.  Called before the writer starts: a ResultError here
        (a checkpoint this version cannot continue) leaves the file untouched."""
        raise NotImplementedError

    def resume_note(self, out) -> str:
        raise NotImplementedError

    def warm_up(self) -> None:
        """Before the timed loop (explicit: compile, thread governor)."""

    def done(self) -> bool:
        raise NotImplementedError

    def advance(self, writer, limit: int | None) -> None:
        """One chunk of work (at most up to ``limit``), its rows and frames streamed; raises EngineError when the
        run must stop (instability, a singular solve)."""
        raise NotImplementedError

    def progress(self, final: bool = False) -> None:
        """The progress line (throttled; ``final``: always, the last one)."""

    def checkpoint(self) -> tuple[dict, dict]:
        """(state, counts): the state (must hold ``step``, int64[1], by which damaged-pointer recovery orders
        the slots) and the table rows it belongs to (``history_count``, …)."""
        raise NotImplementedError

    def records(self) -> list:
        """Writer messages (op, fields) that go with every checkpoint (bond failures, damage)."""
        return []

    def finish(self, writer, failure: str | None) -> None:
        """After the loop: the final rows of a finished run, or the failing state for the summary."""

    def finished(self) -> bool:
        raise NotImplementedError

    def run_state(self) -> RunState:
        """The state a callback sees (:class:`RunState`); default: the work only."""
        return RunState(work=int(self.work), time=None, history={})

    def work_of_time(self, t: float) -> int | None:
        """The work (step) at simulated time ``t`` for a time trigger, None where the family has no time."""
        return None

    def summary(self, info: SessionInfo) -> dict:
        raise NotImplementedError


#: the defaults (both are immutable)
NO_SOURCE = Source()
DEFAULT_OPTIONS = RunOptions()
