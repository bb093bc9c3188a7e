"""The one outer driver of every run, whatever its solver family (the shape of pyro2's ``run_sim``).

:func:`run` runs or resumes one result: it holds the result's write lock, starts the writer process, catches
SIGINT/SIGTERM, writes a checksummed checkpoint every ``output.checkpoint_interval`` wall seconds and at the
end, and writes the summary (root attribute and ``<result>.summary.json``).  The family
(:class:`.protocol.SolverFamily`) does the work between: prepare, advance, progress, state, summary.

:func:`obtain` is the one place a run meets an existing result: :func:`existing` says what the file is to the
run (new, finished, resumable, stale, different) and a :class:`Policy` says what to do with each (reuse,
resume, replace, refuse).  ``polydem run``, ``batch``, ``sweep``, ``calibrate`` and the ``timestep`` study all go
through it, so each works for every solver family.
"""

from __future__ import annotations

import json
import signal
import sys
import threading
import time
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path

from ..engine.simulation import EngineError
from ..errors import CallbackError, PolydemError
from ..io.hdf5 import ResultError, ResultWriter, check_intact, open_result, read_checkpoint, result_lock
from ..io.provenance import code_version, provenance, session
from ..scenario.load import same_run, scenario_differences
from . import family, result_family
from .protocol import DEFAULT_OPTIONS, NO_SOURCE, Resume, SessionInfo, Source


class Interrupted(PolydemError):
    """The run stopped on SIGINT/SIGTERM after writing a checkpoint; ``args[0]`` is the signal number."""


class _Triggers:
    """The run's callbacks with the work (step, solve) each is due at next."""

    def __init__(self, callbacks, fam):
        self.items = []
        for cb in callbacks:
            if cb.time is not None and fam.work_of_time(cb.time) is None:
                raise PolydemError(f"Every(time={cb.time:g}): a {fam.KIND} run has no simulated time; use steps=")
            self.items.append([cb, self._next(cb, fam, int(fam.work))])

    @staticmethod
    def _next(cb, fam, work):
        if cb.steps is not None:
            return (work // cb.steps + 1) * cb.steps
        k = max(1, work // max(fam.work_of_time(cb.time), 1))  # the k-th time k T, the first after ``work``
        while fam.work_of_time(k * cb.time) <= work:
            k += 1
        return fam.work_of_time(k * cb.time)

    def limit(self, other):
        due = [n for _, n in self.items]
        if other is not None:
            due.append(other)
        return min(due) if due else None

    def fire(self, fam, out) -> bool:
        """Call the callbacks that are due; False if one asked to stop; CallbackError if one raised."""
        go_on = True
        for item in self.items:
            cb, due = item
            if fam.work < due:
                continue
            try:
                said = cb.fn(fam.run_state())
            except Exception as e:  # noqa: BLE001 - the user's code: its message goes into ours
                name = getattr(cb.fn, "__name__", repr(cb.fn))
                raise CallbackError(
                    f"the callback {name} raised {type(e).__name__}: {e} (at {fam.UNIT} {fam.work:,}; {out} keeps a "
                    "checkpoint there)"
                ) from e
            item[1] = self._next(cb, fam, int(fam.work))
            if said is False:
                go_on = False
        return go_on


class Refused(ResultError):
    """:func:`obtain` will not touch an existing result; ``existing``: what it is (:class:`Existing`)."""

    def __init__(self, out, existing, policy=None):
        super().__init__(_refusal(out, existing, policy))
        self.out, self.existing = out, existing


class AlreadyFinished(Exception):
    """``resume`` of a finished run: nothing to do, the file is not touched; ``args[0]`` is its summary."""


def summary_path(out) -> Path:
    """The summary file beside a result (``<result>.summary.json``)."""
    return Path(out).with_suffix(".summary.json")


def run(resolved=None, *, out, source=NO_SOURCE, resume=False, opts=DEFAULT_OPTIONS, prepared=None) -> dict:
    """Run (or, with ``resume``, continue) one result and return its summary.

    ``resolved``: the validated scenario (the family comes from its ``[solver] kind``); on resume the scenario,
    its source and the family come from the file.  ``prepared``: a family instance the caller has set up
    already (tests and studies that build a system themselves).  The write lock is held for the whole session:
    a second run on the same path is refused with a ResultError before anything is written."""
    with result_lock(out):
        return _session(Path(out), resolved, source, resume, opts, prepared)


def _session(out, resolved, source, resume, opts, prepared):
    t_start = time.time()
    stream = opts.stream or sys.stderr
    back, prior_wall, segments = None, 0.0, []
    if resume:
        cls, resolved, source, back, segments = _read_resume(out, opts, stream)
        prior_wall = float(back.checkpoint["wall_elapsed"][0])
        fam = cls(resolved, source, opts, fresh=False)
    else:
        fam = prepared or family(resolved["solver"]["kind"])(resolved, source, opts, fresh=True)
    interval = float(fam.resolved["output"]["checkpoint_interval"])
    writer = failure = t_loop = None

    def wall():
        return prior_wall + time.time() - t_start

    reopen = fam.restore(back) if resume else None  # before the writer: a refused checkpoint touches nothing
    work0 = fam.work  # this session's work counts from here (a resumed run: from its checkpoint)
    if segments and "end" not in segments[-1]:  # the session before ended without closing (killed)
        segments[-1]["status"] = "killed"
    # this session's provenance (a segment of the run): written when it begins, so a killed session is recorded too
    segments.append(
        session(opts.threads, opts.pin_threads) | {"unit": fam.UNIT, "start": int(work0), "wall_before": prior_wall}
    )
    triggers = _Triggers(opts.callbacks, fam)  # a callback that cannot run is refused before the writer starts
    with catch_signals() as interrupted:
        try:
            writer = ResultWriter(out)
            if resume:
                writer.send("open", **reopen)
                writer.send("attrs", attrs={"segments": json.dumps(segments)})
                if not opts.quiet:
                    stream.write(fam.resume_note(out) + "\n")
            else:
                fam.create(
                    writer, provenance(fam.resolved, *_source_fields(source)) | {"segments": json.dumps(segments)}
                )
                _checkpoint(writer, fam, wall(), records=False)
            fam.warm_up()
            t_loop = last_ck = time.time()
            while not fam.done():
                fam.advance(writer, triggers.limit(opts.stop_after))
                fam.progress()
                if time.time() - last_ck >= interval:
                    _checkpoint(writer, fam, wall())
                    last_ck = time.time()
                if opts.stop_after is not None and fam.work >= opts.stop_after:
                    break
                try:
                    go_on = triggers.fire(fam, out)
                except CallbackError:
                    _checkpoint(writer, fam, wall())
                    raise
                if not go_on:
                    if not opts.quiet:
                        stream.write(
                            f"\nstopped by a callback at {fam.UNIT} {fam.work:,}; continue with: polydem run --resume "
                            f"{out}\n"
                        )
                    break
                if interrupted:
                    stream.write(
                        f"\ninterrupted by signal {interrupted[0]} at {fam.UNIT} {fam.work:,}; "
                        f"continue with: polydem run --resume {out}\n"
                    )
                    break
            fam.progress(final=True)
            _checkpoint(writer, fam, wall(), records=False)
            fam.finish(writer, None)
        except EngineError as e:
            failure = str(e)
            fam.finish(writer, failure)  # no checkpoint of a failed state: a resume continues before it
        finally:
            info = SessionInfo(
                out=out,
                wall=wall(),
                wall_loop=time.time() - t_loop if t_loop else 0.0,
                work_run=fam.work - work0,
                resumed=bool(resume),
                failure=failure,
                finished=failure is None and fam.finished(),
            )
            summary = _close(writer, fam, info, segments)
    if failure:
        raise EngineError(failure)
    if interrupted:
        raise Interrupted(interrupted[0])
    return summary


def _source_fields(source):
    return source.scenario_file, source.scenario_text, source.overrides


def _read_resume(out, opts, stream):
    """(family class, resolved scenario, Source, Resume, the run's segments so far) of a result to resume;
    refuses a finished run (AlreadyFinished), damaged data and a result without checkpoint (ResultError)."""
    cls = result_family(out)
    if cls is None:
        with open_result(out):  # says what the file is instead (missing, foreign, truncated, locked)
            pass
        raise ResultError(f"{out}: not a polydem result")
    check_intact(out, skip=("/checkpoint",), fmt=cls.FORMAT)  # never continue on damaged data
    notes = []
    with open_result(out, fmt=cls.FORMAT) as f:
        if f.attrs.get("status") == "finished":
            raise AlreadyFinished(json.loads(f.attrs["summary"]) if "summary" in f.attrs else {})
        ck = read_checkpoint(f, notes)
        if ck is None:
            raise ResultError(f"{out}: no checkpoint to resume from; start the run again with --overwrite")
        resolved = json.loads(f.attrs["resolved"])
        source = Source(f.attrs["scenario_file"], f.attrs["scenario_text"], tuple(json.loads(f.attrs["overrides"])))
        table = f["history/table"]
        kept = table[: int(ck["history_count"][0])]
        cols = json.loads(table.attrs["columns"])
        written_by = f.attrs["code_version"]
        segments = json.loads(f.attrs.get("segments", "[]"))  # none in a result written before they were recorded
    if written_by != code_version() and not opts.quiet:
        stream.write(f"warning: {out} was written by polydem {written_by}, resuming with {code_version()}\n")
    for n in notes:
        stream.write(f"warning: {n}\n")
    names = [c[0] if isinstance(c, list) else c for c in cols]
    return cls, resolved, source, Resume(ck, kept, names, written_by, out), segments


def _checkpoint(writer, fam, wall, records=True):
    state, counts = fam.checkpoint()
    writer.send("checkpoint", state=state, wall_elapsed=wall, **counts)
    if records:
        for op, fields in fam.records():
            writer.send(op, **fields)


def _close(writer, fam, info, segments):
    """The summary into the result (root attrs) and beside it (``.summary.json``), with the run's segments (this
    session's closed: where it ended, its wall time, the threads it ran on, how it ended) and this session's ranks;
    None if no file was begun."""
    if writer is None:
        return None
    summary = fam.summary(info)
    status = "finished" if info.finished else ("failed" if info.failure else "running")
    seg = segments[-1]
    threads = summary.get("threads") or {}
    seg.update(
        end=int(fam.work),
        wall=info.wall - seg["wall_before"],
        threads_used=threads.get("used"),
        status="interrupted" if status == "running" else status,
    )
    summary.update(ranks=seg["ranks"], segments=segments)
    try:
        for op, fields in fam.records():
            writer.send(op, **fields)
        writer.send("attrs", attrs={"status": status, "summary": json.dumps(summary), "segments": json.dumps(segments)})
    finally:
        writer.close()
    summary_path(info.out).write_text(json.dumps(summary, indent=1))
    return summary


@contextmanager
def catch_signals():
    """SIGINT and SIGTERM set a flag instead of killing the run (the loop stops after a checkpoint); yields
    the list the signal numbers are appended to.  Outside the main thread nothing is caught."""
    flag = []
    old = {}
    if threading.current_thread() is threading.main_thread():
        for sig in (signal.SIGINT, signal.SIGTERM):
            old[sig] = signal.getsignal(sig)
            signal.signal(sig, lambda signum, frame: flag.append(signum))
    try:
        yield flag
    finally:
        for sig, h in old.items():
            signal.signal(sig, h)


# ====================================================================== an existing result
@dataclass(frozen=True)
class Existing:
    """What an existing result is to a run of a scenario."""

    state: str  # "new" | "finished" | "resumable" | "stale" | "different"
    summary: dict | None = None  # finished: its stored summary
    why: str = ""  # different: what differs, or what the file is


def existing(out, resolved) -> Existing:
    """new (no file); finished (this scenario's run, finished); resumable (this scenario's run with a readable
    checkpoint — a failed run with one counts); stale (this scenario's run without a usable checkpoint);
    different (another scenario, another family's result, a foreign, unreadable or damaged file)."""
    out = Path(out)
    if not out.exists():
        return Existing("new")
    cls = result_family(out)
    if cls is None or cls.KIND != resolved["solver"]["kind"]:
        return Existing("different", why="not a result of this solver family")
    try:
        with open_result(out, fmt=cls.FORMAT) as f:
            stored = json.loads(f.attrs["resolved"])
            if not same_run(stored, resolved):
                return Existing("different", why="; ".join(scenario_differences(stored, resolved)))
            if f.attrs.get("status") == "finished":
                return Existing("finished", json.loads(f.attrs["summary"]) if "summary" in f.attrs else {})
            return Existing("resumable" if read_checkpoint(f) is not None else "stale")
    except (ResultError, KeyError, OSError) as e:
        return Existing("different", why=str(e))


@dataclass(frozen=True)
class Policy:
    """What to do with an existing result in each state: "reuse", "resume", "replace" or "refuse"."""

    finished: str
    resumable: str
    stale: str
    different: str


#: ``polydem run`` without a flag: an existing file is never touched
NEW = Policy("refuse", "refuse", "refuse", "refuse")
#: ``polydem run --overwrite``
OVERWRITE = Policy("replace", "replace", "replace", "replace")
#: ``polydem run --continue`` and ``polydem batch``: finish what is there, never replace another run's result
CONTINUE = Policy("reuse", "resume", "refuse", "refuse")
#: sweep, calibrate, dif: their own work folders, whose files only they write
REFRESH = Policy("reuse", "resume", "replace", "replace")
#: the timestep study: it compares wall times, so an unfinished run is run again whole (a resumed run's stepping
#: time covers its last session only); its folder may hold another study's runs, which it must not replace
STUDY = Policy("reuse", "replace", "replace", "refuse")


@dataclass(frozen=True)
class Outcome:
    action: str  # "ran" | "resumed" | "reused"
    summary: dict


def obtain(resolved, out, *, source=NO_SOURCE, policy=CONTINUE, opts=DEFAULT_OPTIONS) -> Outcome:
    """The result of ``resolved`` at ``out``, by ``policy``: decision and run both under the result's lock (a
    second polydem on the same path is refused, never raced).  Refusals are ResultError saying why."""
    out = Path(out)
    with result_lock(out):
        acts = {policy.finished, policy.resumable, policy.stale, policy.different}
        if len(acts) == 1 and out.exists():  # one action whatever the file is (--overwrite): no need to read it
            ex, act = Existing("different"), acts.pop()
        else:
            ex = existing(out, resolved)
            act = "run" if ex.state == "new" else getattr(policy, ex.state)
        if act == "refuse":
            raise Refused(out, ex, policy)
        if act == "reuse":
            return Outcome("reused", ex.summary)
        if act == "resume":
            return Outcome("resumed", _session(out, None, Source(), True, opts, None))
        if act == "replace":
            _remove(out)
        return Outcome("ran", _session(out, resolved, source, False, opts, None))


def _refusal(out, ex, policy=None) -> str:
    if policy == NEW or ex.state == "finished" or ex.state == "resumable":
        return f"{out}: result file exists (use --overwrite to replace it, or --resume {out})"
    why = f" ({ex.why})" if ex.why else ""
    if ex.state == "different":
        return f"{out}: holds a result of a different scenario or no polydem result{why}; use --overwrite"
    return f"{out}: holds a result of this scenario without a checkpoint to resume from; use --overwrite"


def _remove(out):
    for p in (out, summary_path(out)):
        try:
            p.unlink(missing_ok=True)
        except OSError as e:
            raise ResultError(f"{out}: cannot remove the existing result ({e.strerror}); nothing was run") from None


def printed_summary(out, summary: dict) -> list:
    """What ``polydem run`` prints at the end: the family's 'wrote …' line and its summary lines (indented);
    also the source of the demo output quoted in README.md (reproductions/docs.py)."""
    mod = family_module(summary.get("solver", "explicit"))
    return [mod.headline(out, summary)] + ["  " + line for line in mod.summary_lines(summary)]


def family_module(kind):
    """The module of the solver family ``kind`` (``[solver] kind``, registered in ``solvers/__init__.py``)."""
    import importlib

    from . import FAMILIES

    return importlib.import_module(FAMILIES[kind])
