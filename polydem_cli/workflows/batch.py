"""Run a list of scenarios to their results, each only as far as needed (a finished result is
reused, an interrupted one resumed), up to ``--jobs`` at a time in the order given, a run that starts from
another run's result (``[initial_state] file``) after it; one progress line over the whole list with an ETA for
the list, and a summary at the end."""

from __future__ import annotations

import datetime as _dt
import re
import subprocess
import sys
import threading
import time
from pathlib import Path

_PCT = re.compile(r"\[\s*([0-9.]+)%\]")
_ETA = re.compile(r"ETA ([0-9][0-9:]*|\d+ days?, [0-9:]+)")
_RATE = re.compile(r"([0-9.]+(?:e[+-]?\d+)?) particle-steps/s")


def jobs_of(items) -> list:
    """'scenario.toml[=result.h5]' → (scenario, result); the default result is outputs/<stem>.h5."""
    out = []
    for it in items:
        scen, _, res = it.partition("=")
        out.append((Path(scen), Path(res) if res else Path("outputs") / (Path(scen).stem + ".h5")))
    return out


def result_state(scen, res) -> str:
    """'finished', 'resumable' or 'new' for a scenario and its result path (as ``run --continue`` decides)."""
    if not res.exists():
        return "new"
    try:
        from ..scenario.load import load_scenario
        from ..solvers.driver import existing

        st = existing(res, load_scenario(scen)[0]).state
    except Exception:  # noqa: BLE001 - the run itself will say what is wrong
        return "new"
    return {"finished": "finished", "resumable": "resumable"}.get(st, "new")


def _kind(sc) -> tuple:
    """What sets a run's cost per particle-step, from its resolved scenario: integrator, particle shape (the
    first particle set's type: disks, Voronoi cells, hexagons), beams and whether they are rate-dependent.  Runs
    of one batch differ by more than 10× in particle-steps per second (LH disks against bonded Voronoi panels),
    so a pending run is planned at the rate of runs of its own kind (:func:`batch_eta`)."""
    b = sc.get("bonds") or {}
    parts = sc.get("particles") or [{}]
    return (sc.get("time", {}).get("integrator"), parts[0].get("type"), bool(b), bool(b.get("rate_dependent")))


def _inspect(scen) -> tuple:
    """(the result it starts from or None, planned particle-steps or None, cost kind (:func:`_kind`) or None) of
    a scenario, without running it.  The plan is the end step × particles (an upper bound when an
    end_load_drop may end the run earlier); None for a quasi-static run, or when the system cannot be built yet
    (its initial state is still to be run)."""
    try:
        from ..scenario.load import load_scenario

        sc, _ = load_scenario(scen)
    except Exception:  # noqa: BLE001 - the run will say what is wrong
        return None, None, None
    ist = sc.get("initial_state")
    start = None
    if ist is not None:
        p = Path(ist["file"])
        start = (p if p.is_absolute() else Path(scen).resolve().parent / p).resolve()
    kind = _kind(sc)
    if sc["solver"]["kind"] != "explicit":  # another solver family (quasi-static): no step plan
        return start, None, kind
    try:
        from ..scenario.build import build_system

        s = build_system(sc, str(scen))
        return start, float(s.end_step) * float(s.n), kind
    except Exception:  # noqa: BLE001
        return start, None, kind


def _recorded_rate(res, threads) -> float | None:
    """The particle-steps rate a finished result records (its summary's ``particle_steps_per_s``), when it ran
    on as many threads as this batch gives each run (``threads`` as given to ``--threads``; a non-numeric value
    accepts any); else None.  The results a batch finds from before (finished, or interrupted with a summary of
    their last session) so plan its pending runs of their kind before any run of this batch has reported a
    rate."""
    import json

    try:
        from ..io.hdf5 import open_result

        with open_result(res) as f:
            summ = json.loads(f.attrs["summary"])
        rate = float(summ["particle_steps_per_s"])
    except Exception:  # noqa: BLE001 - an older or foreign result: no rate, no plan from it
        return None
    want = str(threads).strip()
    th = summ.get("threads") or {}
    if want.isdigit() and th.get("used") != [int(want)]:
        return None
    return rate if rate > 0 else None


def read_list(items, threads) -> list:
    """The batch's jobs from its 'scenario[=result]' items, before anything runs: each one's plan and cost kind
    (:func:`_inspect`), the rate a result from before recorded (:func:`_recorded_rate`) and the items it waits
    for (the one whose result is its initial state, an earlier item with the same result)."""
    jobs = [Job(i, s, r) for i, (s, r) in enumerate(jobs_of(items), 1)]
    by_result = {}
    for j in jobs:
        start, j.plan, j.kind = _inspect(j.scen)
        if j.res.exists():  # a result from before: its recorded rate plans the pending runs of its kind
            j.rate = _recorded_rate(j.res, threads)
        key = j.res.resolve()
        if key in by_result:  # the same result twice: the second reuses the first
            j.deps.add(by_result[key])
        for k in jobs[: j.i - 1]:
            if start is not None and k.res.resolve() == start:
                j.deps.add(k.i)
        by_result.setdefault(key, j.i)
    return jobs


class Job:
    def __init__(self, i, scen, res):
        self.i, self.scen, self.res = i, scen, res
        self.deps = set()
        self.plan = None  # particle-steps (upper bound) or None
        self.kind = None  # what sets its cost per particle-step (_kind)
        self.status = "pending"  # pending, running, reused, ran, resumed, failed, skipped
        self.state = None
        self.pct, self.eta, self.rate = 0.0, None, None  # from the run's progress lines
        self.t0, self.wall, self.why, self.last_err = None, 0.0, "", ""
        self.proc = self.reader = None
        self.out = ""

    def read(self):
        """Follow the run's progress lines (a thread per running job)."""
        for line in self.proc.stderr:
            m = _PCT.search(line)
            if m:
                self.pct = float(m.group(1))
                e = _ETA.search(line)
                self.eta = _seconds(e.group(1)) if e else None
                r = _RATE.search(line)
                if r:
                    self.rate = float(r.group(1))
            elif line.strip().startswith("error"):
                self.last_err = line.strip()


def _seconds(text):
    """'1 day, 2:03:04' or '2:03:04' → s."""
    days = 0
    if "day" in text:
        d, _, text = text.partition(",")
        days = int(d.split()[0])
    parts = [int(p) for p in text.strip().split(":")]
    s = 0
    for p in parts:
        s = 60 * s + p
    return 86400 * days + s


def _fmt(s):
    return str(_dt.timedelta(seconds=int(max(s, 0))))


def batch_eta(jobs, slots) -> tuple:
    """(seconds, runs without an estimate) left for the whole list: the running runs' own ETAs, the pending
    runs' planned particle-steps at the particle-steps rate measured in this batch for runs of the same kind
    (a reused result's recorded rate counts, :func:`_recorded_rate`; :func:`_kind`; the slowest rate measured
    so far when no run of its kind has reported one), shared over
    ``slots`` parallel runs.  An estimate: runs may end early (end_load_drop), and a kind not yet measured
    may be slower still."""
    by_kind = {}
    for j in jobs:
        if j.rate:
            by_kind.setdefault(j.kind, []).append(j.rate)
    slowest = min((r for rs in by_kind.values() for r in rs), default=None)

    def rate_of(j):
        rs = by_kind.get(j.kind)
        return sum(rs) / len(rs) if rs else slowest

    work, unknown = 0.0, 0
    for j in jobs:
        rate = rate_of(j)
        if j.status == "running":
            if j.eta is not None:
                work += j.eta
            elif j.plan and rate:
                work += j.plan * (1.0 - j.pct / 100.0) / rate
            else:
                unknown += 1
        elif j.status == "pending":
            if j.plan and rate:
                work += j.plan / rate
            else:
                unknown += 1
    running = [j.eta or 0.0 for j in jobs if j.status == "running"]
    # never less than the longest running run
    return max(work / max(slots, 1), max(running, default=0.0)), unknown


class Batch:
    """The runs of one ``polydem batch``: each a ``polydem run --continue`` subprocess, started in the order
    given as slots and dependencies allow, watched, and summed up."""

    def __init__(self, jobs, threads, slots, run_args=()):
        """``run_args``: more options of every ``polydem run`` (e.g. ``--ranks 2``)."""
        self.jobs, self.threads, self.slots, self.run_args = jobs, threads, slots, tuple(run_args)
        self.n = len(jobs)
        self.tty = sys.stderr.isatty()
        self.t_start = time.time()
        self.last_line = 0.0

    def say(self, j, msg):
        if self.tty:
            sys.stderr.write("\r" + " " * 110 + "\r")
        print(f"[run {j.i} of {self.n}] {j.res}: {msg}", file=sys.stderr, flush=True)

    def start(self, j):
        j.state = result_state(j.scen, j.res)
        if j.state == "finished":
            j.status = "reused"
            self.say(j, "finished earlier, reused")
            return
        j.res.parent.mkdir(parents=True, exist_ok=True)
        cmd = [sys.executable, "-m", "polydem_cli", "run", str(j.scen), "-o", str(j.res), "--continue"]
        cmd += ["--threads", self.threads, *self.run_args]
        if not any(a == "--ranks" or a.startswith("--ranks=") for a in self.run_args):
            cmd += ["--ranks", "1"]  # the batch's slots share the cores, not --ranks auto's count of them
        j.t0 = time.time()
        j.proc = subprocess.Popen(cmd, stderr=subprocess.PIPE, stdout=subprocess.PIPE, text=True, bufsize=1)
        j.reader = threading.Thread(target=j.read, daemon=True)
        j.reader.start()
        j.status = "running"
        self.say(j, "resumed" if j.state == "resumable" else "started")

    def finish(self, j):
        j.reader.join()
        j.out = j.proc.stdout.read()
        j.wall = time.time() - j.t0
        r = _RATE.search(j.out)
        if r:
            j.rate = float(r.group(1))
        if j.proc.returncode == 0:
            j.status = "resumed" if j.state == "resumable" else "ran"
            self.say(j, f"done in {j.wall:.0f} s")
            for k in self.jobs:  # the runs that start from this one can be planned now
                if k.status == "pending" and j.i in k.deps and k.plan is None:
                    _, k.plan, k.kind = _inspect(k.scen)
        else:
            j.status = "failed"
            j.why = j.last_err or (j.out.strip().splitlines() or [f"exit code {j.proc.returncode}"])[-1]
            self.say(j, f"FAILED ({j.why})")

    def _done(self):
        return {j.i: j.status for j in self.jobs if j.status not in ("pending", "running")}

    def step(self) -> bool:
        """One pass: collect ended runs, skip the runs whose dependency failed, start what slots allow, draw the
        progress line; False when every run has ended."""
        jobs = self.jobs
        for j in jobs:
            if j.status == "running" and j.proc.poll() is not None:
                self.finish(j)
        done = self._done()
        for j in jobs:
            if j.status == "pending":
                bad = [d for d in j.deps if done.get(d) in ("failed", "skipped")]
                if bad:
                    j.status, j.why = "skipped", f"it needs {jobs[bad[0] - 1].res}, which did not finish"
                    self.say(j, f"skipped ({j.why})")
        running = [j for j in jobs if j.status == "running"]
        for j in jobs:
            if len(running) >= self.slots:
                break
            if j.status == "pending" and all(d in done for d in j.deps):
                self.start(j)
                if j.status == "running":
                    running.append(j)
                done = self._done()
        if not running and all(j.status != "pending" for j in jobs):
            return False
        if not running:  # nothing to watch (dependencies are on earlier items, so the next pass starts one)
            time.sleep(0.05)
            return True
        self.progress(running)
        time.sleep(0.2)
        return True

    def progress(self, running):
        from ..solvers.progress import write_progress

        now = time.time()
        if now - self.last_line < (0.5 if self.tty else 30.0):
            return
        self.last_line = now
        left, unknown = batch_eta(self.jobs, self.slots)
        ndone = len(self._done())
        runs = ", ".join(
            f"{j.i}: {j.res.stem} {j.pct:.0f} %" + (f" ETA {_fmt(j.eta)}" if j.eta is not None else "") for j in running
        )
        more = f" + {unknown} not estimated" if unknown else ""
        msg = f"[batch {ndone} of {self.n} done, {_fmt(now - self.t_start)}] {runs} | list ETA ~ {_fmt(left)}{more}"
        write_progress(sys.stderr, self.tty, msg, width=110)

    def stop(self):
        import signal

        for j in self.jobs:
            if j.status == "running" and j.proc.poll() is None:
                j.proc.send_signal(signal.SIGTERM)
        for j in self.jobs:
            if j.status == "running":
                j.proc.wait()

    def summary(self) -> bool:
        """The closing lines; False if a run failed or was skipped."""
        jobs = self.jobs
        counts = {k: sum(1 for j in jobs if j.status == k) for k in ("reused", "resumed", "ran", "failed", "skipped")}
        print(
            f"batch: {self.n} runs — {counts['ran']} ran, {counts['resumed']} resumed, {counts['reused']} reused, "
            f"{counts['failed']} failed"
            + (f", {counts['skipped']} skipped" if counts["skipped"] else "")
            + f"; {(time.time() - self.t_start) / 60:.1f} min"
        )
        for j in jobs:
            if j.status in ("failed", "skipped"):
                print(f"  {j.status}: {j.res}: {j.why}")
        return not (counts["failed"] or counts["skipped"])
