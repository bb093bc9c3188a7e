"""A complete run: simulation + result file + checkpoints + progress + summary.

Order of work (so that bad input never leaves a file behind): validate →
build → initialise the engine and check the initial state → only then create
the result file.  The loop advances in chunks of about half a second of wall
time, stopping exactly at frame steps; history rows are streamed after every
chunk; a checkpoint is written every ``output.checkpoint_interval`` wall
seconds and at the end.
"""

from __future__ import annotations

import datetime as _dt
import json
import math
import os
import sys
import time
from pathlib import Path

import numpy as np

from .. import __version__
from .._jit_cache import loop_cached
from ..analysis import macro as _macro
from ..interactions.controllers.load_drop import ACC_PEAK as DROP_PEAK
from ..interactions.controllers.load_drop import LOAD_DROP
from ..io.hdf5 import (
    FORMAT,
    FORMAT_VERSION,
    ResultError,
    ResultWriter,
    check_intact,
    open_result,
    read_checkpoint,
    result_lock,
)
from ..scenario.build import build_system
from . import kernels as K
from .families import used_families
from .simulation import EngineError, Simulation
from .stability import check_time_step, describe, estimate
from .threads import ThreadGovernor


def history_columns(system) -> list:
    """(name, unit, description) of every history-table column of a system's runs."""
    cols = list(K.HISTORY_BASE_COLUMNS)
    for f in used_families(system):
        cols += list(f.columns_of(system))
    for name in system.monitored:
        cols.extend((f"{c}:{name}", u, d) for c, u, d in K.SET_COLUMNS)
    if system.macro is not None:
        cols += list(_macro.COLUMNS)
    return cols


class RowMaker:
    """Complete the engine's history rows with the columns derived in Python (macroscopic measures).

    ``file_columns``: the column names of the table a resumed run appends to, if another version of polydem
    wrote it with other columns or in another order: rows are then written in the file's order, a column of
    the file this version does not compute as NaN; columns the file lacks are left out (``dropped``)."""

    def __init__(self, system, columns, file_columns=None):
        self.macro = system.macro
        names = [c[0] for c in columns]
        self.kernel_cols = names[: len(columns) - (len(_macro.COLUMNS) if self.macro else 0)]
        self.take, self.dropped = None, []
        if file_columns is not None and list(file_columns) != names:
            where = {n: i for i, n in enumerate(names)}
            self.take = np.array([where.get(n, -1) for n in file_columns])
            self.dropped = [n for n in names if n not in set(file_columns)]

    def __call__(self, rows):
        if self.macro is not None:
            rows = np.hstack([rows, _macro.derive(self.macro, self.kernel_cols, rows)])
        if self.take is None:
            return rows
        out = rows[:, np.maximum(self.take, 0)]
        out[:, self.take < 0] = np.nan
        return out


def code_version() -> str:
    import subprocess

    v = __version__
    try:
        here = Path(__file__).resolve().parents[2]
        sha = subprocess.run(
            ["git", "-C", str(here), "rev-parse", "--short", "HEAD"], capture_output=True, text=True, timeout=5
        ).stdout.strip()
        dirty = subprocess.run(
            ["git", "-C", str(here), "status", "--porcelain", "--untracked-files=no"],
            capture_output=True,
            text=True,
            timeout=5,
        ).stdout.strip()
        if sha:
            v += f"+g{sha}" + (".dirty" if dirty else "")
    except (OSError, subprocess.SubprocessError):
        pass
    return v


class Progress:
    """Simulated time, steps/s and ETA on stderr (a line every ~10 s when not a terminal).

    The rate and the ETA are measured from the first report on (the first chunk carries one-time
    costs: cache loading, the first neighbour list), over a sliding window of the last ~60 s of wall
    time, so that a change of machine load shows within a minute; before two reports no ETA is printed.

    A run with an end criterion (a family's ``end_progress``: the load-drop stop) usually ends before its
    safety limit (``time.end_time`` / ``end_displacement``), so the limit only bounds the ETA: before the
    measure falls the line says "ETA ≤ …" and how far the measure is from its end; once it falls (the load
    after its peak) the end is estimated from the fall so far — the mean rate since the measure last stood
    at its top, extrapolated linearly to the end value — and the percentage counts towards that end.
    """

    WINDOW = 60.0  # s of wall time
    #: the measure counts as at its top (the load at its peak) above this
    TOP = 0.999

    def __init__(self, total_steps, dt, n, quiet=False, stream=None):
        self.total, self.dt, self.n = total_steps, dt, n
        self.quiet = quiet
        self.stream = stream or sys.stderr
        self.tty = hasattr(self.stream, "isatty") and self.stream.isatty()
        self.last = 0.0
        self.every = 0.5 if self.tty else 10.0
        self.samples = []  # (wall, steps_done) at each report
        self.top_step = None  # last step at which the end measure stood at its top

    def rate_eta(self, step, steps_done, wall):
        """(steps/s, ETA in s or None) from the samples so far plus this one."""
        self.samples.append((wall, steps_done))
        while len(self.samples) > 2 and wall - self.samples[1][0] >= self.WINDOW:
            self.samples.pop(0)
        w0, s0 = self.samples[0]
        if len(self.samples) < 2 or wall <= w0 or steps_done <= s0:
            return (steps_done / wall if wall > 0 else 0.0), None
        rate = (steps_done - s0) / (wall - w0)
        return rate, (self.total - step) / rate

    def steps_to_end(self, step, end):
        """Steps until the end criterion ``end = (now, end value, what)`` fires, from its fall since it last
        stood at its top; None while it has not fallen."""
        now, stop, _ = end
        if now >= self.TOP or self.top_step is None or step <= self.top_step:
            return None
        fall = (1.0 - now) / (step - self.top_step)  # per step, mean since the top
        return max(0.0, (now - stop) / fall)

    def track(self, step, end):
        if end is not None and end[0] >= self.TOP:
            self.top_step = step

    def update(self, step, steps_done, wall, force=False, end=None):
        """Report at ``step`` (``steps_done`` in this session, ``wall`` s); ``end``: the end criterion's
        ``(now, end value, what)`` or None.  Call after every chunk: the end measure is tracked each time."""
        self.track(step, end)
        if self.quiet:
            return
        now = time.time()
        if not force and now - self.last < self.every:
            return
        self.last = now
        rate, eta = self.rate_eta(step, steps_done, wall)
        head = f"{100.0 * step / self.total:5.1f}%"
        bound = ""
        tail = ""
        if end is not None:
            left = self.steps_to_end(step, end)
            what, _, of = end[2].partition(" / ")
            tail = f" | {what} {100 * end[0]:.0f} % of {of}, ends below {100 * end[1]:.0f} %"
            if end[0] < end[1]:  # the criterion has fired: this is the last line
                head, tail = "100.0%", f" | {what} {100 * end[0]:.4g} % of {of}: ended below {100 * end[1]:.0f} %"
                eta = 0.0
            elif left is not None and left < self.total - step:
                head = f"~{100.0 * step / (step + left):4.1f}%"
                eta = left / rate if eta is not None and rate > 0 else None
                tail += " (ETA from the fall so far)"
            elif eta is not None:
                bound = "≤ "
                tail += " (ETA: the safety limit)"
        eta_s = "--:--:--" if eta is None or not math.isfinite(eta) else bound + str(_dt.timedelta(seconds=int(eta)))
        msg = (
            f"[{head}] t = {step * self.dt:.6g} of {'at most ' if end is not None else ''}{self.total * self.dt:.6g} s"
            f" | step {step:,} | {rate:.3g} steps/s, {rate * self.n:.3g} particle-steps/s | ETA {eta_s}{tail}"
        )
        write_progress(self.stream, self.tty, msg, force)


def end_progress(system, sim):
    """The first end criterion of the run's families that can tell how near it is (``Family.end_progress``)."""
    for f, b in sim.family_bundles():
        e = f.end_progress(system, b)
        if e is not None:
            return e
    return None


def write_progress(stream, tty, msg, force=False, width=110):
    """A progress line: rewritten in place on a terminal (a newline after the final one), else one per line."""
    if tty:
        stream.write("\r" + msg.ljust(width))
        if force:
            stream.write("\n")
    else:
        stream.write(msg + "\n")
    stream.flush()


class HistoryStats:
    """Running aggregates of the history table for the summary."""

    def __init__(self, columns):
        self.cols = [c[0] for c in columns]
        self.peak = {}
        self.last = None
        self.first = None
        self.e_dev = 0.0
        self.e_scale = 0.0
        self.macro_rows = []  # (sigma22, eps22, eps11) chunks, when the history has them
        self.has_macro = "sigma22" in self.cols

    def update(self, rows):
        if len(rows) == 0:
            return
        if self.first is None:
            self.first = rows[0].copy()
        self.last = rows[-1].copy()
        c = self.cols
        d, sc = self.energy_terms(rows)
        self.e_dev, self.e_scale = max(self.e_dev, d), max(self.e_scale, sc)
        if self.has_macro:
            self.macro_rows.append(rows[:, [c.index("sigma22"), c.index("eps22"), c.index("eps11")]].copy())
        for j, name in enumerate(c):
            if name.startswith(("f1:", "f2:", "c:")):
                k = int(np.argmax(np.abs(rows[:, j])))
                v = float(rows[k, j])
                if abs(v) >= abs(self.peak.get(name, (0.0, 0.0, 0.0))[0]):
                    u = name.split(":", 1)
                    ucol = "u2:" + u[1] if "u2:" + u[1] in c else None
                    self.peak[name] = (
                        v,
                        float(rows[k, c.index("time")]),
                        float(rows[k, c.index(ucol)]) if ucol else 0.0,
                    )

    @property
    def last_step(self):
        """The step of the last row seen (None before any)."""
        return None if self.last is None else int(self.last[self.cols.index("step")])

    def energy_terms(self, rows):
        """(largest |E_total - E_0|, largest energy scale) over ``rows`` (relative to the first row seen)."""
        c = self.cols
        rows = np.atleast_2d(rows)
        et = rows[:, c.index("energy_total")]
        dev = float(np.max(np.abs(et - self.first[c.index("energy_total")])))
        scale = (
            np.abs(rows[:, c.index("kinetic")])
            + np.abs(rows[:, c.index("elastic")])
            + np.abs(rows[:, c.index("dissipated")])
            + np.abs(rows[:, c.index("external_work")])
            + np.abs(rows[:, c.index("potential")] - self.first[c.index("potential")])
        )
        return dev, float(scale.max())

    def summary(self):
        out = {}
        if self.last is not None:
            for key in ("kinetic", "elastic", "potential", "dissipated", "external_work"):
                out[f"final_{key}"] = float(self.last[self.cols.index(key)])
            out["energy_balance_error"] = self.e_dev / self.e_scale if self.e_scale > 0 else 0.0
        out["peaks"] = {k: {"value": v[0], "time": v[1], "u2": v[2]} for k, v in self.peak.items()}
        return out

    def macro_summary(self, spec):
        if not self.has_macro or spec is None or not self.macro_rows:
            return None
        m = np.vstack(self.macro_rows)
        res = _macro.summarize(m[:, 0], m[:, 1], m[:, 2], spec.fit_range, spec.L1, spec.T, spec.L2)
        res["definition"] = spec.as_dict()
        return res


def _attrs(system, scenario_file, scenario_text, overrides):
    sc = system.scenario
    return {
        "format": FORMAT,
        "format_version": FORMAT_VERSION,
        "code_version": code_version(),
        "created": _dt.datetime.now(_dt.timezone.utc).isoformat(timespec="seconds"),
        "scenario_file": str(scenario_file),
        "scenario_text": scenario_text,
        "resolved": json.dumps(sc),
        "overrides": json.dumps(list(overrides)),
        "seed": int(sc["scenario"]["seed"]),
        "units": "cm, g, s (force dyn, energy erg)",
        "title": sc["scenario"]["title"],
        "unused": json.dumps(system.unused),
    }


def _static(system):
    s = system
    return {
        "group": s.group,
        "vertex_start": s.vert_start,
        "body_vertices": s.body_v,
        "mass": s.mass,
        "inertia": s.inertia,
        "area": s.area,
        "radius": s.radius,
        "thickness": s.thickness,
        "x0": s.x0,
        "group_names": s.group_names,
    }


def _bonds_static(system):
    net = system.bonds
    if not net.n:
        return None
    p = net.params
    return {
        "pairs": np.column_stack([p.a, p.b]),
        "L": p.L,
        "H": p.H,
        "T": p.T,
        "E": net.E,
        "nu": net.nu,
        "kappa_0": p.kappa0,
        "kappa_m": p.kappam,
        "eps0_dot": p.eps0dot,
        "alpha": p.alpha,
        "edges": net.edges,
        "rate_dependent": np.array([p.rate_dependent]),
    }


def _frame(sim):
    x = sim.positions()
    fr = {"step": sim.step, "time": sim.time, "x": x, "v": sim.velocities()}
    for f, b in sim.family_bundles():
        fr.update(f.frame(sim.system, b, x))
    return fr


def _send_records(writer, sim):
    """The families' records that go with every checkpoint (bond failures)."""
    for f, b in sim.family_bundles():
        for kind, fields in f.records(b).items():
            writer.send(kind, **fields)


def existing_state(out, system) -> str:
    """'finished', 'resumable' or 'other' for an existing result file and the system to run."""
    from ..io.hdf5 import result_state

    return result_state(out, system.scenario)


def summary_path(out: Path) -> Path:
    return Path(out).with_suffix(".summary.json")


def run(
    system=None,
    *,
    out,
    scenario_file="",
    scenario_text="",
    overrides=(),
    resume=False,
    quiet=False,
    stream=None,
    stop_after_steps=None,
    threads="auto",
    pin_threads=False,
):
    """Run (or resume) a simulation and write the result; returns the summary dict.

    ``threads``: ``"auto"`` (the cores other processes leave free, re-chosen during the run;
    engine/threads.py) or a count N, a ceiling governed the same way unless ``pin_threads``.

    The result's write lock is held for the whole run (``io.hdf5.result_lock``): a second run on the
    same path is refused with a ResultError before anything is written.
    ``stop_after_steps`` (tests only) ends the session early as if killed after
    a final checkpoint.
    """
    with result_lock(out):
        return _run(
            system,
            out=out,
            scenario_file=scenario_file,
            scenario_text=scenario_text,
            overrides=overrides,
            resume=resume,
            quiet=quiet,
            stream=stream,
            stop_after_steps=stop_after_steps,
            threads=threads,
            pin_threads=pin_threads,
        )


def _run(
    system,
    *,
    out,
    scenario_file,
    scenario_text,
    overrides,
    resume,
    quiet,
    stream,
    stop_after_steps,
    threads,
    pin_threads,
):
    t_start = time.time()
    out = Path(out)
    stream = stream or sys.stderr
    hist_keep = None
    prior_wall = 0.0
    if resume:
        check_intact(out, skip=("/checkpoint",))  # never continue on damaged data (checkpoints: below)
        ck_notes = []
        with open_result(out) as f:
            if f.attrs.get("status") == "finished":
                raise AlreadyFinished(json.loads(f.attrs["summary"]) if "summary" in f.attrs else {})
            ck = read_checkpoint(f, ck_notes)
            if ck is None:
                raise ResultError(f"{out}: no checkpoint to resume from; start the run again with --overwrite")
            resolved = json.loads(f.attrs["resolved"])
            scenario_file = f.attrs["scenario_file"]
            scenario_text = f.attrs["scenario_text"]
            overrides = json.loads(f.attrs["overrides"])
            written_by = f.attrs["code_version"]
            hist_keep = f["history/table"][: int(ck["history_count"][0])]
            file_cols = json.loads(f["history/table"].attrs["columns"])
        if written_by != code_version() and not quiet:
            stream.write(f"warning: {out} was written by polydem {written_by}, resuming with {code_version()}\n")
        system = build_system(resolved, scenario_file)
        prior_wall = float(ck["wall_elapsed"][0])
        for n in ck_notes:
            stream.write(f"warning: {n}\n")
        if not quiet:
            step0 = int(ck["step"][0])
            stream.write(
                f"resuming {out} from step {step0:,} (t = {step0 * system.dt:.6g} s) of {system.end_step:,} "
                f"(t = {system.end_step * system.dt:.6g} s)\n"
            )
    est = estimate(system)
    if not resume:
        check_time_step(system, est)  # before any work: a dt far above the stability limit is refused
    t_compile = None
    if not quiet and not loop_cached():  # a cold cache: minutes without output otherwise
        t_compile = time.time()
        stream.write(
            "compiling the time loop and the interaction kernels (first run after installation or a code "
            f"change; a few minutes, then cached in {os.environ.get('NUMBA_CACHE_DIR', '.jit_cache/')})\n"
        )
        stream.flush()
    sim = Simulation(system)
    sim.initialize()
    if not resume:
        sim.check_initial_overlap()
        if system.unused and not quiet:
            stream.write("note: unused parameters: " + "; ".join(system.unused) + "\n")
        if not quiet:
            stream.write(describe(est, system.dt) + "\n")
        if system.dt > est["dt_crit"]:
            stream.write(
                f"warning: dt = {system.dt:g} s exceeds the critical time step estimate "
                f"{est['dt_crit']:.3g} s of the {system.scenario['time']['integrator']} integrator\n"
            )
    cols = history_columns(system)
    make_rows = RowMaker(system, cols, file_cols if resume else None)
    if make_rows.take is not None:  # a result written by another version: its table keeps its own columns
        if not quiet and (make_rows.dropped or np.any(make_rows.take < 0)):
            lost = [c for c, k in zip(file_cols, make_rows.take) if k < 0]
            stream.write(
                f"note: {out} has the history columns of polydem {written_by}; the rows of this session are "
                f"written in its order"
                + (f", without {', '.join(make_rows.dropped)}" if make_rows.dropped else "")
                + (f"; {', '.join(lost)} are no longer computed (NaN)" if lost else "")
                + "\n"
            )
        units = {c[0]: c for c in cols}
        cols = [units.get(n, (n, "", "")) for n in file_cols]

    def now_row():  # a history row of the present state, off the cadence
        return make_rows(sim.current_row()[None, :])

    stats = HistoryStats(cols)
    frames = system.frame_steps
    writer = None
    failure = None
    t_loop = None
    gov = None
    steps_run = 0
    interrupted = []
    old_handlers = _catch_signals(interrupted)
    try:
        if resume:
            sim.restore(ck)
            writer = ResultWriter(out)
            writer.send("open", frames_keep=int(ck["frames_count"][0]), history_keep=len(hist_keep))
            nframes = int(ck["frames_count"][0])
            nhist = len(hist_keep)
            stats.update(hist_keep)
        else:
            writer = ResultWriter(out)
            writer.send(
                "create",
                attrs=_attrs(system, scenario_file, scenario_text, overrides),
                particles=_static(system),
                sets={k: v for k, v in system.sets.items()},
                columns=cols,
                n=system.n,
                velocities=system.scenario["output"]["velocities"],
                bonds=_bonds_static(system),
            )
            row0 = now_row()
            writer.send("history", rows=row0)
            stats.update(row0)
            writer.send("frame", **_frame(sim))
            nframes, nhist = 1, 1
            writer.send(
                "checkpoint",
                state=sim.state(),
                frames_count=nframes,
                history_count=nhist,
                wall_elapsed=time.time() - t_start,
            )
        prog = Progress(system.end_step, system.dt, system.n, quiet=quiet, stream=stream)
        every = system.history_every
        chunk = 64
        rows = np.zeros((max(1024, 4 * chunk // every + 4), sim.ncols))
        sim.advance(sim.step, rows, every)  # zero steps: compiles the step loop outside the timing
        if t_compile is not None:
            stream.write(f"compiled in {time.time() - t_compile:.0f} s\n")
        gov = thread_governor(system, threads, pin_threads)
        t_loop = time.time()
        last_ck = time.time()
        warned = set()  # families whose warning was printed
        fi = int(np.searchsorted(frames, sim.step, side="right"))
        while sim.step < system.end_step and not sim.ended:
            target = min(system.end_step, sim.step + chunk)
            if fi < len(frames):
                target = min(target, int(frames[fi]))
            if stop_after_steps is not None:
                target = min(target, stop_after_steps)
            need_rows = (target - sim.step) // every + 2
            if rows.shape[0] < need_rows:
                rows = np.zeros((need_rows, sim.ncols))
            t0 = time.time()
            s0 = sim.step
            nr = sim.advance(target, rows, every)
            dtw = time.time() - t0
            steps_run += sim.step - s0
            if nr:
                chunk_rows = make_rows(rows[:nr].copy())
                writer.send("history", rows=chunk_rows)
                stats.update(chunk_rows)
                nhist += nr
            if dtw > 0 and sim.step > s0:  # ~0.5 s of wall, and the state is checked at least every CHECK_STEPS
                chunk = int(min(max((sim.step - s0) / dtw * 0.5, 1), CHECK_STEPS))
            while fi < len(frames) and frames[fi] <= sim.step:
                if frames[fi] == sim.step:
                    writer.send("frame", **_frame(sim))
                    nframes += 1
                fi += 1
            if sim.ended and not (fi > 0 and frames[fi - 1] == sim.step):
                writer.send("frame", **_frame(sim))  # the final state of a run ended by the load drop
                nframes += 1
            _check_stability(system, sim, stats, est, now_row())
            gov.update(sim.step - s0, dtw)
            if not quiet:
                for f, b in sim.family_bundles():
                    msg = None if f.name in warned else f.warning(system, b)
                    if msg:
                        stream.write(f"\nwarning: {msg}\n")
                        warned.add(f.name)
            prog.update(sim.step, steps_run, time.time() - t_loop, end=end_progress(system, sim))
            if time.time() - last_ck >= system.checkpoint_interval:
                writer.send(
                    "checkpoint",
                    state=sim.state(),
                    frames_count=nframes,
                    history_count=nhist,
                    wall_elapsed=prior_wall + time.time() - t_start,
                )
                _send_records(writer, sim)
                last_ck = time.time()
            if stop_after_steps is not None and sim.step >= stop_after_steps:
                break
            if interrupted:
                stream.write(
                    f"\ninterrupted by signal {interrupted[0]} at step {sim.step:,}; "
                    f"continue with: polydem run --resume {out}\n"
                )
                break
        prog.update(sim.step, steps_run, time.time() - t_loop, force=True, end=end_progress(system, sim))
        writer.send(
            "checkpoint",
            state=sim.state(),
            frames_count=nframes,
            history_count=nhist,
            wall_elapsed=prior_wall + time.time() - t_start,
        )
        if (sim.step >= system.end_step or sim.ended) and stats.last is not None and stats.last_step != sim.step:
            # a finished run's table ends with its final state even off the history cadence (after the
            # last checkpoint: a finished run is never resumed), so the summary's figures are of that state
            final = now_row()
            writer.send("history", rows=final)
            stats.update(final)
            nhist += 1
    except EngineError as e:
        failure = str(e)
        if stats.last is not None and stats.last_step != sim.step:
            try:  # the summary of a failed run describes the state it failed in, not the last table row
                stats.update(now_row())
            except Exception:  # noqa: BLE001 - a broken state must not hide the failure message
                pass
    finally:
        _restore_signals(old_handlers)
        wall_loop = time.time() - t_loop if t_loop else 0.0
        summary = None
        if writer is not None:
            finished = failure is None and (sim.step >= system.end_step or sim.ended)
            summary = _summary(
                system,
                sim,
                stats,
                out,
                wall=prior_wall + time.time() - t_start,
                wall_loop=wall_loop,
                steps_run=steps_run,
                resumed=resume,
                failure=failure,
                finished=finished,
                threads=gov,
            )
            try:
                _send_records(writer, sim)
                writer.send(
                    "attrs",
                    attrs={
                        "status": "finished" if finished else ("failed" if failure else "running"),
                        "summary": json.dumps(summary),
                    },
                )
            finally:
                writer.close()
            summary_path(out).write_text(json.dumps(summary, indent=1))
    if failure:
        raise EngineError(failure)
    if interrupted:
        raise Interrupted(interrupted[0])
    return summary


class Interrupted(Exception):
    """The run stopped on SIGINT/SIGTERM after writing a checkpoint; ``args[0]`` is the signal number."""


class AlreadyFinished(Exception):
    """``resume`` of a finished run: nothing to do, the file is not touched; ``args[0]`` is its summary."""


def _catch_signals(flag):
    import signal
    import threading

    if threading.current_thread() is not threading.main_thread():
        return {}
    old = {}
    for sig in (signal.SIGINT, signal.SIGTERM):
        old[sig] = signal.getsignal(sig)
        signal.signal(sig, lambda signum, frame: flag.append(signum))
    return old


def _restore_signals(old):
    import signal

    for sig, h in old.items():
        signal.signal(sig, h)


#: the state is checked for instability at least every this many steps, whatever the output cadence
CHECK_STEPS = 100_000


def _check_stability(system, sim, stats, est, now_row=None):
    """Stop a run that has gone unstable: energy growth beyond ``stability.max_energy_error`` (from the
    history rows and the present state ``now_row``, so that a long ``history_every`` does not hide it),
    overlaps beyond a sane fraction.  (Non-finite positions are stopped by the step kernel: NONFINITE.)"""
    lim = system.scenario["stability"]
    where = f"at step {sim.step:,}, t = {sim.time:.6g} s"
    hint = describe(est, system.dt)
    names = system.group_names

    def who(i):
        return f"particle {i} ({names[system.group[i]]})"

    e_dev, e_scale = stats.e_dev, stats.e_scale
    if now_row is not None and stats.first is not None:
        d, sc = stats.energy_terms(now_row)
        if not (np.isfinite(d) and np.isfinite(sc)):
            raise EngineError(f"unstable {where}: the energies are not finite; {hint}")
        e_dev, e_scale = max(e_dev, d), max(e_scale, sc)

    for f, b in sim.family_bundles():
        msg = f.check(system, b, lim)
        if msg:
            raise EngineError(f"unstable {where}: {msg}; {hint}")
    if e_scale > 0 and e_dev > lim["max_energy_error"] * e_scale:
        v = sim.velocities()
        ek = 0.5 * system.mass * (v[:, 0] ** 2 + v[:, 1] ** 2) + 0.5 * system.inertia * v[:, 2] ** 2
        i = int(np.argmax(ek))
        raise EngineError(
            f"unstable {where}: energy balance error {e_dev:.3g} erg is "
            f"{e_dev / e_scale:.3g} of the energy scale (stability.max_energy_error = "
            f"{lim['max_energy_error']:g}); fastest: {who(i)}, kinetic energy {ek[i]:.3g} erg; {hint}"
        )


def printed_summary(out, summary: dict) -> list:
    """What ``polydem run`` prints at the end of an explicit run: the 'wrote …' line and the summary lines
    (indented); also the source of the demo output quoted in README.md (studies/docs.py)."""
    head = (
        f"wrote {out} ({summary['steps']:,} steps, {summary['particles']} particles, "
        f"{summary['wall_time_s']:.1f} s wall, {summary['particle_steps_per_s']:.3g} particle-steps/s)"
    )
    return [head] + ["  " + line for line in summary_lines(summary)]


def summary_lines(summary: dict) -> list:
    """Short human-readable account of a run's summary (printed at the end of ``polydem run``)."""
    out = []
    if summary.get("end_reason"):
        out.append(f"end: {summary['end_reason']}")
    obs = summary.get("observables") or {}
    peaks = obs.get("peaks") or {}
    loads = {k: v for k, v in peaks.items() if k.startswith(("f1:", "f2:"))}
    if loads:
        k, v = max(loads.items(), key=lambda kv: abs(kv[1]["value"]))
        out.append(f"peak load |{k}| = {abs(v['value']):.4g} dyn at t = {v['time']:.6g} s")
    if "energy_balance_error" in obs:
        out.append(
            f"energy-balance error {obs['energy_balance_error']:.2g} (largest |E_total - E_0| over the "
            f"largest energy term)"
        )
    th = summary.get("threads")
    if th and th.get("probes"):
        p = th["probes"][0]
        rates = ", ".join(f"{k} thread{'s' if k != '1' else ''} {v:.3g}" for k, v in p["particle_steps_per_s"].items())
        again = f"; {len(th['probes'])} probes in all" if len(th["probes"]) > 1 else ""
        out.append(
            f"threads: {th['mode']}, measured {rates} particle-steps/s over the first steps: ran on {p['chosen']}"
            f"{again}, {th['final']} at the end (--threads N --pin-threads fixes the count)"
        )
    elif th and not th["mode"].startswith("pinned") and len(th["used"]) > 1:
        out.append(
            f"threads: {th['mode']}, used {' and '.join(map(str, th['used']))} (other processes kept cores busy; "
            f"--pin-threads keeps the count), {th['final']} at the end"
        )
    m = summary.get("macro")
    if m:
        out.append(_macro.describe(m))
    bf = summary.get("bond_failure")
    if bf and bf["failed"]:
        modes = ", ".join(f"{k} {v}" for k, v in bf["by_mode"].items())
        ori = ", ".join(f"{k} {v}" for k, v in bf["by_orientation"].items())
        out.append(
            f"failed bonds: {bf['failed']} of {summary['bonds']['count']} (by mode: {modes}; by orientation: {ori})"
        )
    return out


def _end_reason(s, sim, finished):
    for f, b in sim.family_bundles():
        why = f.end_reason(s, b)
        if why:
            return why
    if not finished:
        return None
    what = "end time / end displacement"
    if s.load_drop > 0:
        what += (
            f" reached before the load fell below {s.load_drop:g} of its peak (time.end_load_drop was not met; "
            f"peak |f2| {sim.bundle(LOAD_DROP.name).acc[DROP_PEAK]:.4g} dyn)"
        )
    return what


def thread_governor(system, threads="auto", pin_threads=False) -> ThreadGovernor:
    """The thread governor of a run of ``system`` (engine/threads.py): ``auto`` keeps one thread for a scene
    without threaded kernels and otherwise measures whether more than one pays; ``make bench`` times the
    same governor."""
    return ThreadGovernor(
        threads, pin=pin_threads, max_threads=1 if threads == "auto" and not _threaded(system) else None
    )


def _threaded(system) -> bool:
    """Does the scene have a threaded interaction kernel (polygon contact, beams, base friction)?  Without
    one, ``auto`` keeps one thread: the only parallel regions left are the predictor and corrector, whose
    thread wake-ups (passive OpenMP wait) cost more than they save — the 1,950-disk box of Luding &
    Herrmann ran at 4.3 M particle-steps/s on two threads and 8.1 M on one (2026-12-02)."""
    return any(f.threaded for f in used_families(system))


def _summary(system, sim, stats, out, wall, wall_loop, steps_run, resumed, failure, finished, threads=None):
    s = system
    rate = steps_run / wall_loop if wall_loop > 0 else 0.0
    obs = {}
    sections = {"contact_model": None, "bonds": None, "bond_failure": None}
    for f, b in sim.family_bundles():
        obs.update(f.observables(b))
        sections.update(f.summary(s, b))
    obs.update(stats.summary())
    return {
        "result": str(out),
        "title": s.scenario["scenario"]["title"],
        "scenario_file": s.file,
        "code_version": code_version(),
        "status": "finished" if finished else ("failed" if failure else "incomplete"),
        "failure": failure,
        "resumed": bool(resumed),
        "particles": int(s.n),
        "integrator": s.scenario["time"]["integrator"],
        "dt": s.dt,
        "steps": int(sim.step),
        "end_step": int(s.end_step),
        "time": sim.step * s.dt,
        "end_reason": _end_reason(s, sim, finished),
        "steps_this_session": int(steps_run),
        "wall_time_s": wall,
        "stepping_wall_time_s": wall_loop,
        "steps_per_s": rate,
        "particle_steps_per_s": rate * s.n,
        "threads": (
            {
                "mode": str(threads.mode),
                "used": sorted({n for _, n in threads.history}),
                "final": threads.threads,
                # each probe of auto: particle-steps/s per thread count (medians) and the count chosen
                "probes": [
                    {"particle_steps_per_s": {str(k): v * system.n for k, v in r.items()}, "chosen": c}
                    for _, r, c in threads.probes
                ],
            }
            if threads is not None
            else None
        ),
        "critical_time_step": estimate(s),
        "contact_model": sections.pop("contact_model"),
        "specimens": {
            k: {"particles": len(v), "touching_pairs": int(len(v.shared_pairs))} for k, v in s.specimens.items()
        },
        "bonds": sections.pop("bonds"),
        "unused_parameters": list(s.unused),
        "observables": obs,
        "macro": stats.macro_summary(s.macro),
        "bond_failure": sections.pop("bond_failure"),
        **sections,
    }
