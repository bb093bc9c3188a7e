"""The explicit solver family (``[solver] kind = "explicit"``, the default): the thesis's time integration of
rigid polygons, disks and beams (Schneider 2012), run by the one driver (:mod:`.driver`).

A run advances in chunks of about half a second of wall time, stopping exactly at frame steps; history rows
are streamed after every chunk; the state is checked for instability after every chunk.  Order of work (so
that bad input never leaves a file behind): validate → build → initialise the engine and check the initial
state → only then does the driver create the result file.  Result layout: io/hdf5.py.
"""

from __future__ import annotations

import json
import os
import sys
import time

import numpy as np

from .._jit_cache import loop_cached
from ..analysis import macro as _macro
from ..engine.families import FAMILIES, used_families
from ..engine.simulation import EngineError, Simulation
from ..engine.stability import check_time_step, describe, estimate
from ..engine.threads import governor_for
from ..io.hdf5 import FORMAT, FORMAT_VERSION, ResultError
from ..io.provenance import code_version, describe_segments
from ..scenario.build import build_system
from ..scenario.handover import take
from . import driver
from .explicit_history import HistoryStats, RowMaker, history_columns
from .progress import Progress
from .protocol import DEFAULT_OPTIONS, NO_SOURCE, RunOptions, SolverFamily, Source

#: the state is checked for instability at least every this many steps, whatever the output cadence
CHECK_STEPS = 100_000


class ExplicitFamily(SolverFamily):
    KIND = "explicit"
    FORMAT = FORMAT
    UNIT = "step"

    def __init__(self, resolved, source=NO_SOURCE, opts=DEFAULT_OPTIONS, fresh=True, system=None):
        """``system``: a System built by the caller (tests, studies) instead of from ``resolved``."""
        self.t_created = time.time()  # the session's time before its first step counts from here (headline)
        self.opts = opts
        self.quiet = opts.quiet
        self.stream = opts.stream or sys.stderr
        # the scene polydem run --ranks built before it started the ranks (scenario/handover.py), else built here
        handed = None if system is not None else take(resolved, source.scenario_file)
        self.scene_source = "given" if system is not None else "launcher" if handed is not None else "built"
        self.system = system = system or handed or build_system(resolved, source.scenario_file)
        del handed
        self.resolved = system.scenario
        self.est = estimate(system)
        if fresh:
            check_time_step(system, self.est)  # before any work: a dt far above the stability limit is refused
        self.t_compile = self.compile_s = self.startup_s = None
        if not loop_cached():  # a cold cache: minutes without output otherwise
            self.t_compile = time.time()
            if not self.quiet:
                self.stream.write(
                    "compiling the time loop and the interaction kernels (first run after installation or a code "
                    f"change; a few minutes, then cached in {os.environ.get('NUMBA_CACHE_DIR', '.jit_cache/')})\n"
                )
                self.stream.flush()
        self.sim = _engine(system, self.est)
        self.sim.initialize()
        if fresh:
            self._initial_checks()
        self.cols = history_columns(system)
        self.make_rows = RowMaker(system, self.cols)
        self.stats = HistoryStats(self.cols)
        self.nframes = self.nhist = 0
        self.steps_run = 0
        self.gov = None
        self.warned = set()  # families whose warning was printed

    def _initial_checks(self):
        system, stream = self.system, self.stream
        self.sim.check_initial_overlap()
        if system.unused and not self.quiet:
            stream.write("note: unused parameters: " + "; ".join(system.unused) + "\n")
        if not self.quiet:
            stream.write(describe(self.est, system.dt) + "\n")
        if system.dt > self.est["dt_crit"]:
            stream.write(
                f"warning: dt = {system.dt:g} s exceeds the critical time step estimate "
                f"{self.est['dt_crit']:.3g} s of the {system.scenario['time']['integrator']} integrator\n"
            )

    @property
    def work(self):
        return self.sim.step

    def now_row(self):
        """A history row of the present state, off the cadence."""
        return self.make_rows(self.sim.current_row()[None, :])

    def run_state(self):
        from .protocol import RunState

        sim = self.sim
        row = self.now_row()[0]
        return RunState(
            work=int(sim.step),
            time=float(sim.step * self.system.dt),
            history={c[0]: float(v) for c, v in zip(self.cols, row)},
            positions=sim.positions().copy(),
            velocities=sim.velocities().copy(),
        )

    def work_of_time(self, t):
        return int(np.ceil(t / self.system.dt - 1e-9))

    def frame(self):
        sim = self.sim
        x, v, fields = sim.frame_fields()  # on ranks: each rank's own rows (engine/distributed.py), no state gathered
        return {"step": sim.step, "time": sim.time, "x": x, "v": v} | fields

    # ------------------------------------------------------------------ a new result / a resumed one
    def create(self, writer, attrs):
        s = self.system
        attrs = {"format": FORMAT, "format_version": FORMAT_VERSION} | attrs
        attrs |= {"seed": int(s.scenario["scenario"]["seed"]), "units": "cm, g, s (force dyn, energy erg)"}
        attrs["unused"] = json.dumps(s.unused)
        writer.send(
            "create",
            attrs=attrs,
            particles=_static(s),
            sets={k: v for k, v in s.sets.items()},
            columns=self.cols,
            n=s.n,
            velocities=s.scenario["output"]["velocities"],
            statics=dict(r for r in (f.static(s) for f in FAMILIES) if r is not None),
            frame_fields={k: v for f in used_families(s) for k, v in f.frame_layout(s).items()},
        )
        row0 = self.now_row()
        writer.send("history", rows=row0)
        self.stats.update(row0)
        writer.send("frame", **self.frame())
        self.nframes, self.nhist = 1, 1

    def restore(self, back):
        file_cols = back.file_columns
        self.make_rows = RowMaker(self.system, self.cols, file_cols)
        mk = self.make_rows
        if mk.take is not None:  # a result written by another version: its table keeps its own columns
            if not self.quiet and (mk.dropped or np.any(mk.take < 0)):
                lost = [c for c, k in zip(file_cols, mk.take) if k < 0]
                self.stream.write(
                    f"note: the result has the history columns of polydem {back.written_by}; the rows of this "
                    f"session are written in its order"
                    + (f", without {', '.join(mk.dropped)}" if mk.dropped else "")
                    + (f"; {', '.join(lost)} are no longer computed (NaN)" if lost else "")
                    + "\n"
                )
            units = {c[0]: c for c in self.cols}
            self.cols = [units.get(n, (n, "", "")) for n in file_cols]
        self.stats = HistoryStats(self.cols)
        ck = back.checkpoint
        missing = sorted(set(self.sim.state()) - set(ck) - {"ended"})
        if missing:
            raise ResultError(
                f"{back.out}: its checkpoint was written by polydem {back.written_by}, which kept the state in another form "
                f"(no {', '.join(missing)}); this version cannot continue it: run the scenario again with --overwrite"
            )
        self.sim.restore(ck)
        self.nframes = int(ck["frames_count"][0])
        self.nhist = len(back.kept)
        self.stats.update(back.kept)
        return {"frames_keep": self.nframes, "history_keep": self.nhist}

    def resume_note(self, out):
        s, step0 = self.system, self.sim.step
        return (
            f"resuming {out} from step {step0:,} (t = {step0 * s.dt:.6g} s) of {s.end_step:,} "
            f"(t = {s.end_step * s.dt:.6g} s)"
        )

    # ------------------------------------------------------------------ the loop
    def warm_up(self):
        s, sim = self.system, self.sim
        self.prog = Progress(s.end_step, s.dt, s.n, quiet=self.quiet, stream=self.stream)
        self.every = s.history_every
        self.chunk = 64
        self.rows = np.zeros((max(1024, 4 * self.chunk // self.every + 4), sim.ncols))
        sim.advance(sim.step, self.rows, self.every)  # zero steps: compiles the step loop outside the timing
        if self.t_compile is not None:
            self.compile_s = time.time() - self.t_compile
            if not self.quiet:
                self.stream.write(f"compiled in {self.compile_s:.0f} s\n")
        self.startup_s = time.time() - self.t_created  # build, compile or load, initial checks
        # a decomposed run: the same governor on rank 0, its count sent to every rank with each advance, the cores of
        # the machine shared out among the ranks on it (engine/threads.py ``per_rank``)
        self.gov = governor_for(s, self.opts.threads, self.opts.pin_threads, ranks=getattr(sim, "local_ranks", 1))
        self.t_loop = time.time()
        self.fi = int(np.searchsorted(s.frame_steps, sim.step, side="right"))
        self.reports = (None, None)  # (step, sim.family_reports there): made once per chunk (advance)

    def done(self):
        return self.sim.step >= self.system.end_step or self.sim.ended

    finished = done

    def advance(self, writer, limit):
        s, sim, frames = self.system, self.sim, self.system.frame_steps
        target = min(s.end_step, sim.step + self.chunk)
        if self.fi < len(frames):
            target = min(target, int(frames[self.fi]))
        if limit is not None:
            target = min(target, limit)
        need_rows = (target - sim.step) // self.every + 2
        if self.rows.shape[0] < need_rows:
            self.rows = np.zeros((need_rows, sim.ncols))
        t0, s0 = time.time(), sim.step
        nr = sim.advance(target, self.rows, self.every)
        dtw = time.time() - t0
        self.steps_run += sim.step - s0
        if nr:
            chunk_rows = self.make_rows(self.rows[:nr].copy())
            writer.send("history", rows=chunk_rows)
            self.stats.update(chunk_rows)
            self.nhist += nr
        if dtw > 0 and sim.step > s0:  # ~0.5 s of wall, and the state is checked at least every CHECK_STEPS
            self.chunk = int(min(max((sim.step - s0) / dtw * 0.5, 1), CHECK_STEPS))
        self._frames(writer)
        # the families' checks, warnings and end progress of this state, once per chunk (on ranks: each rank on its
        # own part, engine/distributed.py; the state is not gathered for them)
        self.reports = (sim.step, sim.family_reports(s.scenario["stability"]))
        check_stability(s, sim, self.stats, self.est, self.now_row(), self.reports[1])
        self.gov.update(sim.step - s0, dtw)
        self._warnings(self.reports[1])

    def _frames(self, writer):
        frames, sim = self.system.frame_steps, self.sim
        while self.fi < len(frames) and frames[self.fi] <= sim.step:
            if frames[self.fi] == sim.step:
                writer.send("frame", **self.frame())
                self.nframes += 1
            self.fi += 1
        if sim.ended and not (self.fi > 0 and frames[self.fi - 1] == sim.step):
            writer.send("frame", **self.frame())  # the final state of a run ended by the load drop
            self.nframes += 1

    def _warnings(self, reports):
        if self.quiet:
            return
        for name, msg in reports["warnings"].items():
            if name not in self.warned:
                self.stream.write(f"\nwarning: {msg}\n")
                self.warned.add(name)

    def progress(self, final=False):
        sim = self.sim
        step, rep = self.reports
        end = rep["end"] if step == sim.step else end_progress(self.system, sim)
        self.prog.update(sim.step, self.steps_run, time.time() - self.t_loop, force=final, end=end)

    def checkpoint(self):
        return self.sim.state(), {"frames_count": self.nframes, "history_count": self.nhist}

    def records(self):
        """The families' records that go with every checkpoint (bond failures)."""
        return [(kind, fields) for f, b in self.sim.family_bundles() for kind, fields in f.records(b).items()]

    def finish(self, writer, failure):
        stats, sim = self.stats, self.sim
        if failure is None:
            if self.done() and stats.last is not None and stats.last_step != sim.step:
                # a finished run's table ends with its final state even off the history cadence (after the
                # last checkpoint: a finished run is never resumed), so the summary's figures are of that state
                final = self.now_row()
                writer.send("history", rows=final)
                stats.update(final)
                self.nhist += 1
        elif stats.last is not None and stats.last_step != sim.step:
            try:  # the summary of a failed run describes the state it failed in, not the last table row
                stats.update(self.now_row())
            except Exception:  # noqa: BLE001 - a broken state must not hide the failure message
                pass

    def summary(self, info):
        sm = _summary(
            self.system, self.sim, self.stats, info, self.steps_run, self.gov, self.startup_s, self.compile_s, self.est
        )
        # where the scene came from (built by this process, or by the launcher of polydem run --ranks:
        # scenario/handover.py) and the peak memory of each process of the run so far, in rank order
        from ..engine.distributed import peak_rss_mib

        sm["scene"] = self.scene_source
        sm["peak_memory_MiB"] = [
            round(m, 1) for m in (self.sim.peak_rss_mib() if hasattr(self.sim, "peak_rss_mib") else [peak_rss_mib()])
        ]
        return sm


def _engine(system, est=None):
    """The engine of the run: a Simulation, or, under an MPI launcher with several ranks, rank 0's
    :class:`~..engine.distributed.Leader` of the decomposed run (the other ranks serve it, cli/run.py)."""
    from ..engine.distributed import Leader, launched_ranks

    return Leader(system, est=est) if launched_ranks() > 1 else Simulation(system)


def end_progress(system, sim):
    """The first end criterion of the run's families that can tell how near it is (``Family.end_progress``)."""
    return sim.family_reports(system.scenario["stability"])["end"]


FAMILY = ExplicitFamily


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
    """Run (or resume) the explicit simulation of a built ``system`` through the driver and return the summary
    (for tests and studies that build or change a System themselves; ``polydem run`` goes through
    :func:`.driver.obtain`).  ``stop_after_steps`` (tests only) ends the session early as if killed after a
    final checkpoint."""
    opts = RunOptions(quiet=quiet, stream=stream, stop_after=stop_after_steps, threads=threads, pin_threads=pin_threads)
    src = Source(str(scenario_file), scenario_text, tuple(overrides))
    if resume:
        return driver.run(out=out, resume=True, opts=opts)
    fam = ExplicitFamily(system.scenario, src, opts, fresh=True, system=system)
    return driver.run(system.scenario, out=out, source=src, opts=opts, prepared=fam)


def headline(out, summary: dict) -> str:
    """The one-line account printed when an explicit run has written its result: its steps and wall time, and of
    this session's wall the part before the first step (building the scene, compiling or loading the compiled code)
    apart from the stepping, whose time alone the rate divides the steps by."""
    start, comp = summary.get("startup_wall_time_s"), summary.get("compile_time_s")
    rate = f"{summary['particle_steps_per_s']:.3g} particle-steps/s"
    if start is None:  # a result written before these keys existed
        return f"wrote {out} ({summary['steps']:,} steps, {summary['particles']} particles, {summary['wall_time_s']:.1f} s wall, {rate})"
    before = f"{start:.1f} s before the first step" + (f", {comp:.0f} s of it compiling" if comp else "")
    stepping = f"{summary['stepping_wall_time_s']:.1f} s stepping at {rate}"
    if summary.get("resumed"):
        return (
            f"wrote {out} ({summary['steps']:,} steps, {summary['particles']} particles, "
            f"{summary['wall_time_s']:.1f} s wall over all sessions; this session {summary['steps_this_session']:,} "
            f"steps: {before}, {stepping})"
        )
    return (
        f"wrote {out} ({summary['steps']:,} steps, {summary['particles']} particles, "
        f"{summary['wall_time_s']:.1f} s wall: {before}, {stepping})"
    )


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


def check_stability(system, sim, stats, est, now_row=None, reports=None):
    """Stop a run that has gone unstable: energy growth beyond ``stability.max_energy_error`` (from the
    history rows and the present state ``now_row``, so that a long ``history_every`` does not hide it),
    overlaps beyond a sane fraction (the families' ``check``: ``reports``, ``sim.family_reports`` of the present
    state, made here if not given).  (Non-finite positions and velocities — forces, on ranks — are stopped by
    the step kernel: NONFINITE.)"""
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

    msg = (reports or sim.family_reports(lim))["check"]
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
    if summary.get("segments"):  # ranks x threads of each session (provenance; io/provenance.py)
        out.append(describe_segments(summary["segments"]))
    m = summary.get("macro")
    if m:
        out.append(_macro.describe(m))
    for f in FAMILIES:
        out += f.summary_lines(summary)
    return out


def _end_reason(s, sim, finished):
    for f, b in sim.family_bundles():
        why = f.end_reason(s, b)
        if why:
            return why
    if not finished:
        return None
    notes = [n for n in (f.end_note(s, b) for f, b in sim.family_bundles()) if n]
    return " ".join(["end time / end displacement"] + notes)


def _summary(system, sim, stats, info, steps_run, threads=None, startup=None, compile_s=None, est=None):
    """The summary dict of an explicit run (``info``: the driver's :class:`.protocol.SessionInfo`; ``startup``,
    ``compile_s``: this session's wall before its first step and the compile's part of it; ``est``: the scene's
    critical time step estimate, if made already)."""
    from ..io.provenance import scenario_digest, source_digests

    wall_loop, finished, failure = info.wall_loop, info.finished, info.failure
    s = system
    rate = steps_run / wall_loop if wall_loop > 0 else 0.0
    obs = {}
    sections = {k: None for f in FAMILIES for k in f.summary_keys}
    for f, b in sim.family_bundles():
        obs.update(f.observables(b))
        sections.update(f.summary(s, b))
    obs.update(stats.summary())
    return {
        "result": str(info.out),
        "title": s.scenario["scenario"]["title"],
        "scenario_file": s.file,
        "code_version": code_version(),
        # which code and scenario wrote it, also from an uncommitted tree (io/provenance.py)
        "source_digests": source_digests(),
        "scenario_digest": scenario_digest(s.scenario),
        "status": "finished" if finished else ("failed" if failure else "incomplete"),
        "failure": failure,
        "resumed": bool(info.resumed),
        "particles": int(s.n),
        "integrator": s.scenario["time"]["integrator"],
        "dt": s.dt,
        "steps": int(sim.step),
        "end_step": int(s.end_step),
        "time": sim.step * s.dt,
        "end_reason": _end_reason(s, sim, finished),
        "steps_this_session": int(steps_run),
        "wall_time_s": info.wall,
        # this session: the wall before its first step (build, compile or load, checks), of it the compile
        # (None: the compiled code came from the cache), and the stepping that the rates divide by
        "startup_wall_time_s": startup,
        "compile_time_s": compile_s,
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
        "critical_time_step": est or estimate(s),
        "specimens": {
            k: {"particles": len(v), "touching_pairs": int(len(v.shared_pairs))} for k, v in s.specimens.items()
        },
        "unused_parameters": list(s.unused),
        "observables": obs,
        "macro": stats.macro_summary(s.macro),
        # a decomposed run (engine/distributed.py): how often this session gathered the whole scene's per-particle
        # arrays to rank 0 (frames, checkpoints, this summary), checked its state (each rank its part: once per
        # chunk of the loop) and redistributed the particles
        "decomposition": (
            {
                "whole_state_gathers": dict(sim.gathers),
                "checks": sim.checks,
                "redistributions": int(sim.rs.redistributions),
            }
            if hasattr(sim, "gathers")
            else None
        ),
        **sections,
    }


#: columns of the macroscopic measures (``[macro]``, analysis/macro.py): (column with its unit, summary key, scale)
MACRO_COLUMNS = (
    ("E [GPa]", "E", 1e-10),
    ("nu [-]", "nu", 1.0),
    ("peak stress [N/mm2]", "peak_stress", 1e-7),
    ("strain at peak [-]", "strain_at_peak", 1.0),
    ("work after peak [N/m]", "work_after_peak_per_area_N_per_m", 1.0),
    ("stress at end / peak [-]", "final_stress_over_peak", 1.0),
    ("peak reached", "peak_reached", None),  # false: the run ended at the largest stress (a lower bound)
)


def table_row(summary: dict) -> dict:
    """A variant's table columns from its run summary, in the units the report uses (GPa, N/mm², N; column names
    carry them): status, end, wall time, the macroscopic measures of a specimen with [macro], the peak load of
    each loaded set, failed bonds, and the diagnostics."""
    obs = summary.get("observables", {})
    cols = {
        "status": summary["status"],
        "end": summary.get("end_reason"),
        "wall time [s]": summary["wall_time_s"],
        "steps": summary["steps"],
        "particle-steps/s": summary["particle_steps_per_s"],
    }
    m = summary.get("macro") or {}
    for name, key, scale in MACRO_COLUMNS:
        if m.get(key) is not None:
            cols[name] = m[key] if scale is None else float(m[key]) * scale
    for k, v in (obs.get("peaks") or {}).items():
        if k.startswith("f2:"):
            cols[f"peak |{k}| [N]"] = abs(float(v["value"])) / 1e5  # dyn -> N
    for f in FAMILIES:
        cols.update(f.table_columns(summary))
    cols["max overlap ratio [-]"] = obs.get("max_overlap_ratio")
    cols["energy balance error [-]"] = obs.get("energy_balance_error")
    return cols


def check(resolved, file) -> list:
    """``polydem check``: build the specimen, check the initial state and the time step; the lines to print.
    ScenarioError for bad input."""
    system = build_system(resolved, str(file))
    sim = Simulation(system)
    sim.initialize()
    sim.check_initial_overlap()
    check_time_step(system)
    s = system
    lines = [
        f"{file}: OK — {s.n} particles in {len(s.group_names)} group(s) "
        f"({', '.join(s.group_names)}), {s.end_step:,} steps of dt = {s.dt:g} s "
        f"({s.scenario['time']['integrator']}), {len(s.frame_steps)} frames, "
        f"interactions: {', '.join(f.name for f in used_families(s)) or 'none'}, "
        f"monitored sets: {', '.join(s.monitored) or '-'}",
        "  " + describe(estimate(s), s.dt),
    ]
    for name, sp in s.specimens.items():
        if len(sp.shared_pairs):
            lines.append(f"  {name}: {len(sp)} particles, {len(sp.shared_pairs)} touching pairs (shared edges)")
    if s.unused:
        lines.append("note: unused parameters: " + "; ".join(s.unused))
    return lines
