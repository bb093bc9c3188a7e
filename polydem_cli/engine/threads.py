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

On top of that, ``auto`` *measures whether more than one thread pays* for the scene at hand, because
often it does not: the beam and contact kernels of a bonded specimen of 1,600 particles and the disk
family's light kernels run slower on two threads than on one (thread wake-ups and barriers cost more than
the split work saves; ``make bench``: concrete 40 x 40 0.94x, bonded 30 x 30 0.83x, 1,950 disks 0.50x),
while large or contact-heavy scenes gain (dense 10^5 hexagons 1.7x, bonded 300 x 300 1.47x) — and on a virtual
machine the same scene's ratio drifts (the concrete panel 0.9x to 1.7x between quarter hours,
docs/performance.md), so no rule fixed in advance holds.  The results
do not depend on the thread count (tests/test_parallel.py), so the choice is free to be made by timing
the run's own steps: the first chunks alternate between one thread and the free cores, ``PROBE_SLOTS``
slots of at least ``PROBE_SLOT_S`` of wall each, interleaved (this machine's speed drifts between minutes;
slots side by side compare settings, not minutes), and more than one thread is kept only if its median
rate beats one thread's by ``PROBE_MARGIN``.  A loaded specimen's step cost changes as it cracks (contact
after failure), so the probe is repeated every ``REPROBE_S`` of wall (at most about 1 % of a run on the
slower setting).  Scenes without any threaded kernel skip the probe and keep one thread.

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

import numpy as np

from .families import used_families

#: measurement window [s]; the first choice is made after FIRST_WINDOW_S without confirmation, so a
#: run beside a busy process drops to the free cores within its first second
WINDOW_S = 1.0
FIRST_WINDOW_S = 0.25
#: probe of ``auto``: wall per slot [s], slots per setting, margin more threads must win by, repeat [s]
PROBE_SLOT_S = 0.2
PROBE_SLOTS = 3
PROBE_MARGIN = 0.03
REPROBE_S = 300.0


def parse_stat(line: str, count_nice: bool):
    """Busy clock ticks of all cores from the first line of /proc/stat (None if it is not that line)."""
    fields = line.split()
    if not fields or fields[0] != "cpu":
        return None
    v = [int(x) for x in fields[1:]]
    # user nice system idle iowait irq softirq steal [guest guest_nice: already inside user/nice]
    v += [0] * (8 - len(v))
    return v[0] + v[2] + v[5] + v[6] + v[7] + (v[1] if count_nice else 0)


def _cpu_ticks(count_nice: bool, path: str = "/proc/stat", cpus=None):
    """(busy ticks, clock ticks per second) from /proc/stat, or None: of all cores, or, for a process bound to some of
    them (``cpus``, default its affinity, when it is fewer than the machine's: a rank of a batch job), of those only —
    the other ranks' cores are not its to count."""
    try:
        with open(path) as f:
            lines = f.readlines()
    except OSError:
        return None
    if cpus is None:
        try:
            cpus = os.sched_getaffinity(0)
        except AttributeError:  # not Linux
            cpus = None
    per = {}
    for line in lines[1:]:
        name, _, rest = line.partition(" ")
        if name.startswith("cpu") and name[3:].isdigit():
            per[int(name[3:])] = rest
    if cpus is not None and per and set(cpus) < set(per):
        busy = sum(parse_stat("cpu " + per[c], count_nice) for c in cpus if c in per)
    else:
        busy = parse_stat(lines[0], count_nice) if lines else None
    return None if busy is None else (busy, os.sysconf("SC_CLK_TCK"))


def available_cores() -> int:
    """The cores this process may run on (its CPU affinity; the CPU count where the platform has no affinity)."""
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # not Linux
        return os.cpu_count() or 1


#: ``polydem run --ranks auto``: the particles each rank needs at least for a second rank to pay on this machine's
#: cores (measured: docs/performance.md, "Ranks by default"); below, one process
AUTO_PARTICLES_PER_RANK = 200


def auto_rank_count(particles: int, free: int) -> int:
    """The ranks ``--ranks auto`` starts for a decomposable scene of ``particles`` with ``free`` cores free: one per
    free core, at most one per :data:`AUTO_PARTICLES_PER_RANK` particles, and 1 when that is fewer than 2."""
    n = min(int(free), int(particles) // AUTO_PARTICLES_PER_RANK)
    return n if n >= 2 else 1


#: ``polydem run --ranks auto``: the wall over which the free cores are counted before the run starts [s]
AUTO_WINDOW_S = 0.3


def busy_elsewhere(now, before) -> float:
    """Cores kept busy by other processes between two samples (wall, own CPU time, busy ticks, ticks per second):
    the machine's busy time less this process's, over the wall."""
    wall = now[0] - before[0]
    own = now[1] - before[1]
    busy = (now[2] - before[2]) / now[3]
    return max(0.0, (busy - own) / wall)


def free_cores(window: float = AUTO_WINDOW_S, reader=None, clock=time.monotonic, sleep=time.sleep) -> int:
    """The cores other processes leave free, counted once over ``window`` seconds of wall by the rule of ``auto``
    (module docstring: round(cores − others)); the available cores where nothing can be measured.  ``polydem run
    --ranks auto`` starts as many ranks (cli/run.py)."""
    cores = available_cores()
    count_nice = os.nice(0) > 0 if hasattr(os, "nice") else False
    read = reader or (lambda: _cpu_ticks(count_nice))

    def sample():
        t = read()
        return None if t is None else (clock(), time.process_time(), t[0], t[1])

    before = sample()
    if before is None:
        return cores
    sleep(window)
    now = sample()
    if now is None or now[0] <= before[0]:
        return cores
    return max(0, min(cores, round(cores - busy_elsewhere(now, before))))


class ThreadGovernor:
    """Sets numba's thread count: ``"auto"`` (at most numba's maximum) or an int N (at most N), re-chosen
    by :meth:`update` from the free cores; with ``pin=True`` exactly N, set once.  ``auto`` also probes
    whether more than one thread is faster than one for this scene (module docstring); ``probe=False``
    leaves that out (load-governed only).

    ``update(steps, wall)`` is cheap (one small file read at most once per window); call it between chunks
    of compiled steps, never inside them, with the steps and wall time of the chunk just run (the probe's
    measurements).  ``history`` records (wall time, threads) of every change, ``probes`` each probe's
    outcome as (wall time, {threads: median steps/s}, chosen count).
    """

    def __init__(
        self, mode="auto", *, pin=False, cores=None, max_threads=None, clock=time.monotonic, reader=None, probe=None
    ):
        import numba

        self.max_threads = int(max_threads or numba.config.NUMBA_NUM_THREADS)
        self.cores = int(cores or available_cores())
        self.clock = clock
        auto = mode == "auto"
        if not auto:
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
        self.probes = []
        #: the count the free cores allow (load-governed); the count run is this or 1 (probe)
        self.cap = self.max_threads
        #: does more than one thread pay?  None: not known yet (probing), True / False: measured
        self.multi = None
        self._probe_on = (auto if probe is None else bool(probe)) and not pin and self.max_threads > 1
        self._slots: dict = {}
        self._slot = [0, 0.0]  # steps and wall of the slot being filled
        self._decided_at = None
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

    def _set(self, n):
        if n != self.threads:
            self._apply(n)

    @property
    def probing(self) -> bool:
        """Is the probe of auto running (whether more than one thread pays is not known yet)?"""
        return self._probe_on and self.multi is None and self.cap > 1

    def _target(self) -> int:
        """The count to run now: the free cores, or one thread where one was measured faster; while probing,
        the setting whose slot is being filled."""
        if self.probing:
            return self._probe_setting()
        return 1 if self.multi is False else self.cap

    def _probe_setting(self) -> int:
        n1, nc = len(self._slots.get(1, ())), len(self._slots.get(self.cap, ()))
        return self.cap if nc <= n1 else 1  # alternate, the free cores first

    def _restart_probe(self):
        self._slots, self._slot, self.multi = {}, [0, 0.0], None

    def _observe(self, steps, wall):
        """Add a chunk of ``steps`` run in ``wall`` seconds on the present count to the probe."""
        if not self.probing or steps <= 0 or wall <= 0 or self.threads != self._probe_setting():
            return
        self._slot[0] += steps
        self._slot[1] += wall
        if self._slot[1] < PROBE_SLOT_S:
            return
        self._slots.setdefault(self.threads, []).append(self._slot[0] / self._slot[1])
        self._slot = [0, 0.0]
        r1, rc = self._slots.get(1, []), self._slots.get(self.cap, [])
        if len(r1) >= PROBE_SLOTS and len(rc) >= PROBE_SLOTS:
            m1, mc = float(np.median(r1)), float(np.median(rc))
            self.multi = mc > (1.0 + PROBE_MARGIN) * m1
            self._decided_at = self.clock()
            self.probes.append((self._decided_at, {1: m1, self.cap: mc}, self.cap if self.multi else 1))

    def update(self, steps: int = 0, wall: float = 0.0) -> int:
        """Record the chunk just run (``steps`` in ``wall`` seconds) for the probe, re-choose the count
        unless pinned (the free cores at most once per window); return it."""
        if not self.governed:
            return self.threads
        self._observe(steps, wall)
        if self._probe_on and self.multi is not None and self.clock() - self._decided_at >= REPROBE_S:
            self._restart_probe()  # the step cost of a loaded specimen changes as it cracks
        if self.clock() - self._last[0] >= (FIRST_WINDOW_S if self._first else WINDOW_S):
            self._update_cap()
        self._set(self._target())
        return self.threads

    def _update_cap(self):
        now = self._sample()
        if now is None:  # /proc/stat went away: keep the present count
            self.mode = "max"
            return
        want = max(1, min(self.max_threads, self.cores, int(round(self.cores - busy_elsewhere(now, self._last)))))
        self._last = now
        new = None
        if self._first:
            self._first = False
            new = want if want != self.cap else None
        elif want == self.cap:
            self._proposal = None
        elif want == self._proposal:  # asked for twice in a row
            new = want
            self._proposal = None
        else:
            self._proposal = want
        if new is not None:
            self.cap = new
            if self._probe_on and (self.multi is None or new > 1):
                self._restart_probe()  # other free cores: whether they pay is measured anew


def governor_for(system, threads="auto", pin_threads=False, ranks: int = 1) -> ThreadGovernor:
    """The thread governor of a run of ``system``: ``auto`` keeps one thread for a scene without threaded
    kernels and otherwise measures whether more than one pays; ``make bench`` times the same governor.

    ``ranks``: the ranks of a decomposed run on this machine (engine/distributed.py): rank 0's governor chooses for
    every rank by the same rule, from the whole run's speed, among at most :func:`per_rank` threads under ``auto``
    (an explicit ``--threads N`` is N per rank: ranks per node x N should not exceed its cores)."""
    if threads == "auto" and not threaded(system):
        cap = 1
    elif threads == "auto" and ranks > 1:
        cap = per_rank(ranks)
    else:
        cap = None
    return ThreadGovernor(threads, pin=pin_threads, max_threads=cap)


def per_rank(ranks: int) -> int:
    """Threads per rank when ``ranks`` ranks share this machine: the cores the launcher bound this rank to (a batch
    system's ``--cpus-per-task``), or, unbound, an equal share of the machine's cores; at least one."""
    import numba

    mine, machine = available_cores(), os.cpu_count() or 1
    share = mine if mine < machine else machine // max(1, ranks)
    return max(1, min(numba.config.NUMBA_NUM_THREADS, share))


def threaded(system) -> bool:
    """Does the scene have a threaded interaction kernel (polygon contact, beams, base friction)?  Without
    one, ``auto`` keeps one thread: the only parallel regions left are the predictor and corrector, whose
    thread wake-ups (passive OpenMP wait) cost more than they save — the 1,950-disk box of Luding &
    Herrmann ran at 4.3 M particle-steps/s on two threads and 8.1 M on one (2026-12-02)."""
    return any(f.threaded for f in used_families(system))
