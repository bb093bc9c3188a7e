"""Thread count of the parallel kernels: fixed, or chosen from the cores other processes leave free.

On a shared machine (a cluster node, a workstation running a second job) a run that uses every core
competes with the other processes for them; each step's parallel regions then wait at their barriers
for a thread that is not scheduled.  Measured on 2 cores beside one busy process (docs/performance.md,
"Threads under load"): 2 threads ran 0.8-1.07x as fast as 1 thread with the passive OpenMP wait policy
and about 3x slower with the spinning one, which on a quiet machine is the one that makes 2 threads pay
(1.3-1.6x).  ``auto`` (the default of ``polydem run``) therefore uses the cores the *other* processes
leave free, re-measured while the run goes on:

    others = (busy CPU time of the machine - CPU time of this process) / wall time   [cores]
    threads = clamp(round(cores - others), 1, numba's maximum)

from ``/proc/stat`` and ``time.process_time()``: first after ``FIRST_WINDOW_S``, then over windows of
at least ``WINDOW_S`` seconds, where a new count is taken only when two windows in a row ask for it
(a short burst of another process does not make the run flip).  CPU time of processes with a positive nice value is not counted as competing
unless this process is itself niced (the scheduler gives a nice-0 thread most of a core beside a
nice-19 one).  Where ``/proc/stat`` is missing (not Linux), ``auto`` keeps numba's maximum.

A count N (``polydem run --threads N``) is a ceiling governed the same way (at most N threads, fewer while
other processes keep cores busy; OpenMP's ``OMP_DYNAMIC=true`` does the same for an OpenMP program):
beside one busy process on 2 cores, 2 threads kept on regardless ran 0.80-1.04x as fast as 1 thread
with passive waiting and about 3x slower with spinning (every parallel region of a step waits at its barrier for the thread that shares a core with the other
process; neither TBB nor dynamic chunks (numba.set_parallel_chunksize 8, 64) changed that, 0.75-0.90x,
docs/performance.md).  ``pin=True`` (``--pin-threads``) keeps exactly N whatever the load, for
measurements of that effect.
"""

from __future__ import annotations

import os
import time

#: measurement window [s]; the first choice is made after FIRST_WINDOW_S without confirmation, so a
#: run beside a busy process drops to the free cores within its first second
WINDOW_S = 1.0
FIRST_WINDOW_S = 0.25


def parse_stat(line: str, count_nice: bool):
    """Busy clock ticks of all cores from the first line of /proc/stat (None if it is not that line)."""
    fields = line.split()
    if not fields or fields[0] != "cpu":
        return None
    v = [int(x) for x in fields[1:]]
    # user nice system idle iowait irq softirq steal [guest guest_nice: already inside user/nice]
    v += [0] * (8 - len(v))
    return v[0] + v[2] + v[5] + v[6] + v[7] + (v[1] if count_nice else 0)


def _cpu_ticks(count_nice: bool):
    """(busy ticks of all cores, clock ticks per second) from /proc/stat, or None."""
    try:
        with open("/proc/stat") as f:
            busy = parse_stat(f.readline(), count_nice)
    except OSError:
        return None
    return None if busy is None else (busy, os.sysconf("SC_CLK_TCK"))


def available_cores() -> int:
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # not Linux
        return os.cpu_count() or 1


class ThreadGovernor:
    """Sets numba's thread count: ``"auto"`` (at most numba's maximum) or an int N (at most N), re-chosen
    by :meth:`update` from the free cores; with ``pin=True`` exactly N, set once.

    ``update()`` is cheap (one small file read at most once per window); call it between chunks of
    compiled steps, never inside them.  ``history`` records (wall time, threads) of every change.
    """

    def __init__(self, mode="auto", *, pin=False, cores=None, max_threads=None, clock=time.monotonic, reader=None):
        import numba

        self.max_threads = int(max_threads or numba.config.NUMBA_NUM_THREADS)
        self.cores = int(cores or available_cores())
        self.clock = clock
        if mode != "auto":
            n = max(1, min(int(mode), self.max_threads))
            mode = f"pinned {n}" if pin else f"at most {n}"
            self.max_threads = n
        #: "auto", "at most N" (governed ceiling) or "pinned N"; "max" where nothing can be measured
        self.mode = mode
        self._count_nice = os.nice(0) > 0 if hasattr(os, "nice") else False
        self._reader = reader or (lambda: _cpu_ticks(self._count_nice))
        self._last = None
        self._first = True
        self._proposal = None
        self.history = []
        self.threads = self.max_threads
        if not pin:
            self._last = self._sample()
            if self._last is None:
                self.mode = "max"  # nothing to measure with: the ceiling, as before
        self._apply(self.threads)

    @property
    def governed(self) -> bool:
        return self.mode == "auto" or self.mode.startswith("at most")

    def _sample(self):
        t = self._reader()
        if t is None:
            return None
        return self.clock(), time.process_time(), t[0], t[1]

    def _apply(self, n):
        import numba

        numba.set_num_threads(n)
        self.threads = n
        self.history.append((self.clock(), n))

    def others(self, now, before) -> float:
        """Cores kept busy by other processes between two samples."""
        wall = now[0] - before[0]
        own = now[1] - before[1]
        busy = (now[2] - before[2]) / now[3]
        return max(0.0, (busy - own) / wall)

    def update(self) -> int:
        """Re-choose the thread count unless pinned (at most once per window); return it."""
        if not self.governed:
            return self.threads
        if self.clock() - self._last[0] < (FIRST_WINDOW_S if self._first else WINDOW_S):
            return self.threads
        now = self._sample()
        if now is None:  # /proc/stat went away: keep the present count
            self.mode = "max"
            return self.threads
        want = max(1, min(self.max_threads, self.cores, int(round(self.cores - self.others(now, self._last)))))
        self._last = now
        if self._first:
            self._first = False
            if want != self.threads:
                self._apply(want)
        elif want == self.threads:
            self._proposal = None
        elif want == self._proposal:  # asked for twice in a row
            self._apply(want)
            self._proposal = None
        else:
            self._proposal = want
        return self.threads
