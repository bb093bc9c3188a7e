"""A run of the explicit solver on several MPI ranks: spatial domain decomposition (issue "One run on every core
and across machines").

**Each rank's part.**  The decomposition (engine/decompose.py: recursive coordinate bisection at the initial
positions) gives every rank the particles it owns and the ghosts it needs; :func:`localize` cuts the whole scene
to those particles, renumbered in the order of their global indices, with each interaction family's data cut as it
declares (``Family.data_layout``, cut by interactions/ranks.py ``localize``).  Only rank 0 builds the whole scene:
it cuts it (:class:`Cut`) and sends every other rank its :class:`Part`, one after the other, so the other ranks
never hold an array of the whole scene (a part is its particles, ghosts and their interactions;
tests/test_decompose.py measures it).  The compiled time loop then
runs unchanged on that part (engine/kernels.py): predictor, the families' passes, corrector, the same code as a
serial run.

**Ghosts.**  A ghost's degrees of freedom are marked fixed in the rank's part, so the predictor and the corrector
leave it alone; the halo exchange (:data:`Halo`, the first element of the loop's family tuple, whose ``pass_``
runs before every other family's) overwrites its position and velocity with its owner's before *every* force
evaluation — at the predicted state and at the corrected one (Gear: both evaluations of the staggered scheme;
Verlet: its one).  Each rank sends, to each neighbour, the position and velocity of the particles it owns that
the neighbour holds as ghosts (6 doubles each), with MPI non-blocking calls made from the compiled loop
(engine/mpicall.py), so the loop is never left.

**Pairs across a boundary** are evaluated on both ranks from identical inputs, each rank keeping the forces on its
own particles (the forces on ghosts are discarded); so each pair's history (a bond's damage, a contact's tangential
spring) is the same on both sides and a bond across a boundary fails on both at the same step.  The statistics of
the history table count a pair once, on the rank owning its smaller global index (``System.own``, read by the
kernels), and the energies of the particles on their owner; the table's row is the sum of the ranks' rows.

**Migration and balance.**  The halo pauses the loop after a step once a particle has moved half the ghost layer's
margin (``SKIN`` times the largest bounding radius beyond the interaction range) since its part was cut: the
ghosts may then miss a partner.  The ranks then cut the scene again at the present positions together, by
neighbour exchange (engine/migrate.py): the bisection's medians by reductions of a few numbers per box (so the
counts are balanced again), and each particle sent by its owner to the ranks that hold it after the cut, with its
Nordsieck history and the beams and contacts of its interactions with their histories — nothing gathered to rank 0,
and the same parts as a cut of the whole scene would give.

**Rank 0 drives.**  :class:`Leader` gives the explicit solver family (solvers/explicit.py) the interface of a
:class:`~.simulation.Simulation`; each call is a command that every rank runs (:func:`execute`; the other ranks
wait in :func:`serve`).  Checkpoints hold the whole scene in the serial layout (interactions/ranks.py ``globalize``,
``merge``, ``scatter``, from each family's declared ``state_layout``), so a run resumes on any number of ranks.

**Walls on every rank.**  Large particles (engine/decompose.py) and those a family needs everywhere
(``Family.replicated``: the disks' walls) are held by every rank, owned by one (a ghost elsewhere, refreshed like
any other); the disks family evaluates a disk–wall pair on the rank owning the disk, and the walls' forces are summed
over the ranks at the end of the evaluation, so the wall's owner integrates the whole force;
the servo walls compute their pressure force from the walls' distance on every rank alike (their power counted on
rank 0).  Their moves do not pause the loop: they are on every rank wherever they go.

**The ranks meet twice per force evaluation**, and at no other time within a step: the halo exchange before the
evaluation; after it, one allreduce (the halo's ``settle``) that takes every decision of the step — whether some
rank's family ran out of room (then every rank repeats the step), whether some rank's forces are not finite (then
no rank corrects or commits positions from them: the run stops with the particle named by its rank), whether some rank's ghosts may
be outrun (then every rank pauses after the step to redistribute) — and carries every sum a family asks for
(``Family.rank_sums``: the walls' forces, the load-drop stop's load, the polygon contact's contained pairs with
``on_containment = "abort"``, from which their halts follow on every rank alike).  So verlet1 (the disk box) meets twice a step, Gear and Verlet four times.  A finite force gives a finite
corrected state; should a rank's correction overflow all the same, the loop says so (``DIVERGED``) and the run
stops every rank (:func:`abort`) rather than let the others wait.  Collective calls inside the families' passes
would add a meeting each; a per-particle field a family needs on its ghosts in the final pass (``Family.ghost_field``:
the interfaces' particle stresses) travels with the final evaluation's halo exchange instead.

**Per-particle families** (base friction) keep only the owned particles' data on a rank: a ghost's forces are
its owner's business.

Not yet: polygon contact with plates (refused with its name); a set-up in parts (rank 0 builds the whole scene and
holds it while the run lasts: it writes the frames and checkpoints from it, and resumes cut it).
"""

from __future__ import annotations

import functools

import numpy as np

from .. import mpicall
from ..errors import DecompositionError
from ..interactions import ranks
from ..interactions.protocol import LEDGER_HEAD, RankSums
from .decompose import box_gap, decompose, ghosts
from .families import compose, slot, used_families
from .parts import _PER_PARTICLE, Part, _bond_pairs, data_layout, large_particles, layout, localize  # noqa: F401
from .simulation import OTHER_RANK, STOPPED, EngineError, Simulation

# ---------------------------------------------------------------- a rank's part of the scene

#: the tag of the message that carries a rank its part
_PART_TAG = 37


def _poll(ready):
    """Wait until ``ready()`` is true, sleeping between calls (10 µs doubling up to 1 ms) instead of spinning."""
    import time

    pause = 1e-5
    while not ready():
        time.sleep(pause)
        pause = min(2 * pause, 1e-3)


def _meet(comm):
    """Every rank at this point before the collective call that follows.  Rank 0 waits in a non-blocking barrier; the
    others poll it and sleep between polls, so that ranks waiting for rank 0 (building and cutting the
    scene, writing a frame) leave the cores to it: MPICH's blocking calls spin, and with more ranks than cores
    (tests and studies oversubscribed) the spinning ranks take rank 0's core.  At most a millisecond late."""
    req = comm.Ibarrier()  # (a non-blocking collective matches only non-blocking ones)
    if comm.Get_rank() == 0:
        req.Wait()
    else:
        _poll(req.Test)


def _receive(comm, source: int, tag: int):
    """A pickled message from ``source``, waited for as :func:`_meet` waits (probe, sleep, probe)."""
    msg = [None]

    def arrived():
        msg[0] = comm.improbe(source=source, tag=tag)
        return msg[0] is not None

    _poll(arrived)
    return msg[0].recv()


def trim_heap() -> None:
    """Give the freed heap back to the operating system (glibc ``malloc_trim``; nothing elsewhere).  Building a scene
    leaves millions of small freed objects (scipy's Voronoi regions) that the allocator keeps: a 10⁶-particle build
    left 3.2 GB resident after its arrays were freed, 0.1 GB after the trim."""
    trim = _malloc_trim()
    if trim is not None:
        trim(0)


@functools.cache
def _malloc_trim():
    """glibc's ``malloc_trim``, looked up once (``find_library`` runs ``ldconfig``), or None."""
    import ctypes
    import ctypes.util

    try:
        return ctypes.CDLL(ctypes.util.find_library("c") or "libc.so.6").malloc_trim
    except (OSError, AttributeError):
        return None


#: the cores this process could run on before :func:`bind_to_share` bound it to its share (None: not bound): what the
#: run's provenance records as the cores of its ranks (io/provenance.py)
BOUND_FROM: int | None = None


def bind_to_share(local_rank: int, local_ranks: int) -> tuple | None:
    """Bind this rank to its equal share of the machine's cores (rank k of P on a machine of C cores: cores k·C/P
    to (k+1)·C/P − 1), when nothing has bound it yet (its affinity is every core) and there are at least as many cores
    as ranks; returns the cores, or None where it leaves the affinity alone (a batch system's binding, more ranks
    than cores, a platform without affinity).  Unbound, the kernel moves ranks between cores and now and then runs
    two on one: the disk packing's 2-rank timings (300 steps of 100 µs) were 29.5 ms or 45 ms at random, bound
    29–34 ms (docs/performance.md).  The thread governor then counts this rank's cores only (engine/threads.py)."""
    import os

    try:
        cpus = sorted(os.sched_getaffinity(0))
    except AttributeError:  # not Linux
        return None
    k = len(cpus) // max(1, local_ranks)
    if local_ranks < 2 or k < 1 or len(cpus) < (os.cpu_count() or 1):
        return None
    global BOUND_FROM
    mine = tuple(cpus[local_rank * k : (local_rank + 1) * k])
    os.sched_setaffinity(0, mine)
    BOUND_FROM = len(cpus)
    return mine


def _agree(comm, err):
    """Every rank learns whether rank 0 met ``err`` (None: it did not); if it did, rank 0 raises it and the others an
    error of the same kind (DecompositionError: the scene cannot be cut, reported as a refusal; else EngineError)."""
    _meet(comm)
    got = comm.bcast(None if err is None else (isinstance(err, DecompositionError), str(err)), root=0)
    if got is None:
        return
    if comm.Get_rank() == 0:
        raise err
    raise (DecompositionError if got[0] else EngineError)(f"on rank 0: {got[1]}")


def command(comm, name: str, args=()):
    """Rank 0: send every other rank (waiting in :func:`serve`) the command ``name``."""
    _meet(comm)
    comm.bcast((name, args), root=0)


#: the ghost layer's margin beyond the interaction range, as a fraction of the largest bounding radius: the
#: decomposition stays valid while no particle has moved farther than half of it
SKIN = 0.5


class Cut:
    """The decomposition of the whole scene into every rank's part, made where the whole scene is: on rank 0 of a
    run (which sends each rank its :class:`Part`), or without MPI (:func:`check`, the tests).  It holds the arrays of
    the whole scene; a rank's part holds none."""

    def __init__(self, system, nranks: int, method: str = "rcb", x=None, skin=None):
        """``x``: the positions (n, ≥2) to cut at (default the initial ones); ``skin``: the ghost layer's margin
        beyond the interaction range (default :data:`SKIN` times the largest bounding radius)."""
        for f in used_families(system):  # refuse before anything else (a family that does not run decomposed)
            try:
                if f.data(system) is not None:
                    data_layout(f, f.data(system))
            except DecompositionError as e:
                raise DecompositionError(refusal_of(f, system, e)) from None
        reach = max([0.0] + [float(f.reach(system)) for f in used_families(system)])
        self.large = large_particles(system)
        small = system.radius[~self.large]
        rmax = float(np.max(small)) if len(small) else 0.0
        self.reach, self.rmax = reach, rmax
        self.skin = SKIN * rmax if skin is None else float(skin)
        self.method = method
        self.x = np.asarray(system.x0 if x is None else x, float)[:, :2].copy()
        self.dec = decompose(self.x, system.radius, nranks, reach + self.skin, self.large, method)
        bonds = _bond_pairs(system)
        self.keeps = []
        for r in range(nranks):
            g = ghosts(self.dec, self.x, system.radius, r, bonds)
            self.keeps.append(np.union1d(np.flatnonzero(self.dec.owner == r), g).astype(np.int64))
        self.system, self.nranks = system, nranks
        # the ranks holding each particle (CSR by particle, ranks ascending) and each set's members as a mask, so
        # that a part's lists come from its own particles: O(part), not O(N) or O(P) per part
        held = np.concatenate(self.keeps)
        order = np.argsort(held, kind="stable")
        self._holders = np.repeat(np.arange(nranks), [len(k) for k in self.keeps])[order]
        self._hstart = np.searchsorted(held[order], np.arange(system.n + 1))
        self._members = {}
        for name, idx in system.sets.items():
            m = np.zeros(system.n, bool)
            m[np.asarray(idx, np.int64)] = True
            self._members[name] = m

    def part(self, r: int) -> Part:
        """Rank ``r``'s part: its scene (:func:`localize`), its halo's exchange lists, the members of each set it
        holds (global numbers)."""
        keep = self.keeps[r]
        own = self.dec.owner[keep] == r
        held = {name: keep[m[keep]] for name, m in self._members.items()}
        lists = self._halo_lists(r, keep, own)
        geom = {"reach": self.reach, "rmax": self.rmax, "skin": self.skin, "method": self.method}
        part = Part(r, self.nranks, keep, own, localize(self.system, keep, own), lists, held, self.system.n, geom)
        part.large, part.cut = self.large[keep], self
        return part

    def _halo_lists(self, r, keep, own) -> dict:
        """The exchange lists of rank ``r``: to each neighbour the owned particles it holds (in global order), from
        each the ghosts it owns; the owned particles it watches and the near ranks that do not hold them."""
        mine = own & ~self.large[keep]  # large particles are on every rank: their moves never outrun the ghosts
        # (owned particle, another rank holding it), from the holders' CSR
        mg = keep[own]
        cnt = self._hstart[mg + 1] - self._hstart[mg]
        first = np.repeat(self._hstart[mg] - np.concatenate([[0], np.cumsum(cnt)[:-1]]), cnt)
        q_of = self._holders[first + np.arange(cnt.sum())]
        p_of = np.repeat(mg, cnt)
        other = q_of != r
        q_of, p_of = q_of[other], p_of[other]
        owner = self.dec.owner[keep]
        nbr, s_idx, s_start, r_idx, r_start = [], [], [0], [], [0]
        for q in np.union1d(q_of, owner[~own]):  # the ranks holding one of mine or owning one I hold
            send = p_of[q_of == q]  # mine, held by q (in global order: mg is)
            recv = keep[owner == q]  # q's, held by me
            nbr.append(int(q))
            s_idx.extend(np.searchsorted(keep, send))
            s_start.append(len(s_idx))
            r_idx.extend(np.searchsorted(keep, recv))
            r_start.append(len(r_idx))
        e = 0.5 * self.skin
        near = self.rmax + self.reach + e
        rad = np.asarray(self.system.radius, float)[keep[mine]]
        boxes = self.dec.boxes
        gap = box_gap(boxes[r], boxes)
        gm = keep[mine]
        cand = [q for q in range(len(boxes)) if q != r and gap[q] <= rad.max(initial=0.0) + near + e]
        col = np.full(self.nranks, -1)
        col[cand] = np.arange(len(cand))
        holds = np.zeros((len(gm), len(cand)), bool)  # whether the near rank holds the particle
        row = np.searchsorted(gm, p_of)
        hit = (row < len(gm)) & (gm[np.minimum(row, len(gm) - 1)] == p_of) & (col[q_of] >= 0) if len(gm) else row < 0
        holds[row[hit], col[q_of[hit]]] = True
        watch = (gap[cand][None, :] <= (rad + near + e)[:, None]) & ~holds  # the near ranks that do not hold it
        i64 = np.int64
        return {
            "nbr": np.array(nbr, i64),
            "send_start": np.array(s_start, i64),
            "send_idx": np.array(s_idx, i64),
            "recv_start": np.array(r_start, i64),
            "recv_idx": np.array(r_idx, i64),
            "mine": np.flatnonzero(mine).astype(i64),
            "xref": self.x[keep[mine]].copy(),
            "rad": rad,
            "lim": np.array([0.25 * e * e, 0.5 * e, near + 0.5 * e]),
            "boxes": np.ascontiguousarray(boxes, float),
            "wstart": np.concatenate([[0], np.cumsum(watch.sum(axis=1))]).astype(i64),
            "wrank": np.array(cand, i64)[np.nonzero(watch)[1]],
        }


class PartSimulation(Simulation):
    """The engine on one rank's part: a step that some rank had to repeat for room is repeated on every rank
    (the halo's ``settle``), so a rank whose families need no room just repeats it."""

    def _grow_families(self):
        fams = list(self.fams)
        for f in self.families:
            k = slot(f)
            nb = f.grow(self.system, fams[k])
            if nb is not None:
                fams[k] = nb
        self.fams = tuple(fams)


class RankSimulation:
    """The engine's :class:`~.simulation.Simulation` on one rank's part, with the halo exchange leading the
    family tuple; history rows and positions gathered over the ranks with mpi4py (outside the compiled loop).
    Only rank 0 holds the whole scene (``system``; None elsewhere): it cuts it and sends every other rank its part.
    ``est``: the whole scene's critical time step estimate (engine/stability.py), if rank 0 has made it already."""

    def __init__(self, system, comm=None, method: str = "rcb", threads: int = 1, skin=None, est=None):
        import numba
        from mpi4py import MPI

        from .stability import estimate

        self.comm = comm or MPI.COMM_WORLD
        _meet(self.comm)  # the other ranks wait here while rank 0 builds the scene
        node = self.comm.Split_type(MPI.COMM_TYPE_SHARED)
        #: ranks of this run on this machine (they share its cores)
        self.local_ranks = node.Get_size()
        bind_to_share(node.Get_rank(), self.local_ranks)
        node.Free()
        # one thread per rank until rank 0's thread governor (engine/threads.py) sends a count with each advance;
        # setting it also starts Numba's threading layer (its threads on this rank's cores), which the cached loop's
        # threaded kernels need before they load
        numba.set_num_threads(max(1, min(int(threads), numba.config.NUMBA_NUM_THREADS)))
        self.mpi = mpicall.api(self.comm)
        lead = self.comm.Get_rank() == 0
        #: the whole scene, on rank 0 only; the decomposition of it (:class:`Cut`) rank 0 made last
        self.global_system, self.cut = (system if lead else None), None
        self.method, self.skin = method, skin
        #: the whole scene's critical time step estimate (what an instability message quotes on any rank)
        crit = err = None
        if lead:
            try:
                crit = est or estimate(system)
            except BaseException as e:  # noqa: BLE001 - told to every rank, then raised
                err = e
        _agree(self.comm, err)
        self.critical = self.comm.bcast(crit, root=0)
        self.redistributions = 0
        self._make(None)

    def _make(self, x, st=None):
        """This rank's part and a fresh engine on it: rank 0 cuts the whole scene at positions ``x`` (default the
        initial ones) and sends every other rank its part, one at a time, with that part's share of the whole
        scene's checkpoint fields ``st`` (rank 0's; :func:`share`) when given.  Returns the rank's share (or None)."""
        comm, rank, size = self.comm, self.comm.Get_rank(), self.comm.Get_size()
        # first the cut, agreed by every rank: a refused one (a box narrower than the range) leaves every rank its
        # old part, so that the run can still end with its summary
        cut = part0 = local = err = None
        if rank == 0:
            try:
                cut = Cut(self.global_system, size, self.method, x, self.skin)
                part0 = cut.part(0)
                local = None if st is None else share(st, part0)
            except BaseException as e:  # noqa: BLE001 - told to every rank, then raised (Ctrl-C included)
                err = e
        _agree(comm, err)
        # then the parts: the old one freed before the new one comes
        self.sim = self.part = self.halo = None
        if rank == 0:
            self.cut, sent = cut, 1
            try:
                for sent in range(1, size):
                    p = cut.part(sent)
                    comm.send((p, None if st is None else share(st, p)), dest=sent, tag=_PART_TAG)
                    del p
                sent = size
            except BaseException as e:  # noqa: BLE001 - the ranks still waiting for their part are told
                err = e
            for r in range(sent, size):
                comm.send(None, dest=r, tag=_PART_TAG)
            self.part = part0
        else:
            got = _receive(comm, 0, _PART_TAG)
            if got is not None:
                self.part, local = got
        _agree(comm, err)
        self._engine()
        return local

    def _engine(self):
        """A fresh engine on this rank's part (``self.part``): its simulation, the families attached to the sums
        over the ranks, the halo exchange leading the family tuple."""
        trim_heap()  # the memory freed since the last cut (rank 0: the build's), back to the machine
        self.sim = PartSimulation(self.part.system)
        self.sim.info[3] = 1  # decomposed: the loop tells a non-finite state the ranks did not agree on (DIVERGED)
        self.sim.critical = self.critical
        # the sums over the ranks the families ask for at every evaluation: one reduction with its agreement
        sums = [np.asarray(f.rank_sums(self.part.system), np.int64).reshape(-1, 2) for f in self.sim.families]
        tgt = np.concatenate([np.zeros((0, 2), np.int64)] + sums)
        lsum, tsum = np.zeros(LEDGER_HEAD + len(tgt)), np.zeros(LEDGER_HEAD + len(tgt))
        tglob = np.where(tgt[:, :1] >= 0, np.column_stack([self.part.keep[np.maximum(tgt[:, 0], 0)], tgt[:, 1]]), -1)
        fams = list(self.sim.fams)
        off = LEDGER_HEAD
        for f, s in zip(self.sim.families, sums):  # families that reduce over the ranks inside the loop
            k = len(s)
            rs = RankSums(lsum[off : off + k], tsum[off : off + k], tsum, tglob, self.part.system, self.part.held_sets)
            fams[slot(f)] = f.attach(fams[slot(f)], self.mpi, rs)
            off += k
        # the halo last, on the bundles the loop will run (the field a family needs on its ghosts is one of theirs)
        self.halo = self.part.halo(self.mpi, _ghost_field(self.sim.families, fams))._replace(
            lsum=lsum, tsum=tsum, tpart=np.ascontiguousarray(tgt[:, 0]), tdof=np.ascontiguousarray(tgt[:, 1])
        )
        fams[0] = self.halo
        self.sim.fams = tuple(fams)
        self.reduce = row_reductions(self.part.system)

    @property
    def step(self) -> int:
        return self.sim.step

    def initialize(self):
        self.sim.initialize()

    def advance(self, step_stop: int, rows: np.ndarray, rec_every: int) -> int:
        """Advance every rank to ``step_stop`` (or until ``rows`` is full); the rows, combined over the ranks, on
        rank 0.  Whenever the loop pauses because a particle has moved half the ghost margin since its part was cut,
        the particles are redistributed (:meth:`redistribute`) and the run goes on."""
        from mpi4py import MPI

        total = 0
        while True:
            self.sim.paused = False
            total += self.sim.advance(step_stop, rows[total:], rec_every)
            if not self.sim.paused:
                break
            self.redistribute()
            if self.sim.step >= step_stop or self.sim.ended or total >= rows.shape[0]:
                break
        if total:
            mine = np.ascontiguousarray(rows[:total])
            tot, big = np.zeros_like(mine), np.zeros_like(mine)
            self.comm.Reduce(mine, tot, op=MPI.SUM, root=0)
            self.comm.Reduce(mine, big, op=MPI.MAX, root=0)
            if self.comm.Get_rank() == 0:
                rows[:total] = np.where(self.reduce == 0, mine, np.where(self.reduce == 1, tot, big))
        return total

    def redistribute(self):
        """Migration and load balance in one, between neighbours (engine/migrate.py): the scene cut again at the
        present positions by every rank together (recursive coordinate bisection: equal counts), each particle sent
        by its owner, with its state — integrator history, the beams and contact histories of its interactions — to
        the ranks that hold it after the cut; nothing gathered to rank 0."""
        from . import migrate

        _settle(self, migrate.recut(self))
        self.redistributions += 1

    def owners(self):
        """(n,) the rank owning each particle, in global order, on rank 0 (None elsewhere): gathered (tests, reports)."""
        got = self.comm.gather(self.part.keep[self.part.own], root=0)
        if self.comm.Get_rank() != 0:
            return None
        out = np.full(self.part.n_whole, -1, np.int64)
        for r, idx in enumerate(got):
            out[idx] = r
        return out

    def positions(self):
        """(n, 3) positions of every particle in global order on rank 0 (None elsewhere)."""
        return self._gather(self.sim.nord[:, :, 0])

    def velocities(self):
        return self._gather(self.sim.nord[:, :, 1] / self.sim.dt)

    def _gather(self, a):
        own = self.part.own
        parts = self.comm.gather((self.part.keep[own], np.ascontiguousarray(a[own])), root=0)
        if self.comm.Get_rank() != 0:
            return None
        out = np.zeros((self.part.n_whole,) + a.shape[1:])
        for idx, val in parts:
            out[idx] = val
        return out


def _ghost_field(families, fams):
    """The per-particle field one of the ``families`` (their bundles ``fams``, the loop's tuple) needs on its ghosts
    (Family.ghost_field), or None; the halo carries one."""
    fields = [(f.name, f.ghost_field(fams[slot(f)])) for f in families]
    fields = [(n, a) for n, a in fields if a is not None]
    if len(fields) > 1:
        raise DecompositionError(
            "families " + ", ".join(n for n, _ in fields) + " each need a field on the ghosts; the halo carries one"
        )
    return fields[0][1] if fields else None


def row_reductions(system) -> np.ndarray:
    """Per history-row column of the engine: 0 the same on every rank (time, step), 1 summed over the ranks
    (energies, counts, set sums; each counted on one rank), 2 the largest (a family's maxima)."""
    from . import kernels as K

    code = {"same": 0, "sum": 1, "max": 2}
    red = [0, 0] + [1] * (K.N_BASE - 2)
    for f in used_families(system):
        red += [code[r] for r in f.column_reductions(system)]
    red += [1] * (K.N_SET * len(system.monitored))
    return np.array(red)


def refusal_of(family, system, e) -> str:
    """A family's refusal to run decomposed, naming the family, the scenario table it is set by and, when it is
    large particles (plates, walls) that the family cannot share out, the groups they belong to."""
    from ..params import ArrayOf

    tables = ", ".join(f"[[{k}]]" if isinstance(v, ArrayOf) else f"[{k}]" for k, v in family.tables.items())
    msg = str(e)
    if f"'{family.name}'" not in msg:
        msg = f"interaction family '{family.name}'{f' ({tables})' if tables else ''}: {msg}"
    elif tables:
        msg = msg.replace(f"'{family.name}'", f"'{family.name}' ({tables})", 1)
    if "large particle" in msg:
        large = large_particles(system)
        groups = sorted({system.group_names[g] for g in np.unique(np.asarray(system.group)[large])})
        if groups:
            msg += f"; the large particles are those of {', '.join(groups)}"
    return msg


def check(system, nranks: int, method: str = "rcb") -> None:
    """Refuse (DecompositionError) a scene that cannot run on ``nranks`` ranks — a family that does not run
    decomposed, more ranks than particles, a subdomain narrower than the interaction range — without MPI, so that
    ``polydem run --ranks N`` says so before it starts N processes."""
    Cut(system, nranks, method).part(0)  # cuts the scene for every rank


# ---------------------------------------------------------------- the run driven from rank 0


def launched_ranks() -> int:
    """The number of ranks this process was started among by an MPI launcher (mpiexec, srun), read from the
    environment the launchers set, so that a serial run never imports MPI; 1 without a launcher."""
    import os

    for key in ("PMI_SIZE", "OMPI_COMM_WORLD_SIZE", "PMIX_SIZE", "SLURM_STEP_NUM_TASKS"):
        v = os.environ.get(key)
        if v and v.isdigit():
            return int(v)
    return 1


def launched_local_ranks() -> int | None:
    """The ranks of this run on this machine, as the launcher tells them in the environment (MPICH's hydra,
    Open MPI; None where it does not), so that rank 0 can compare them with the machine's cores before the run."""
    import os

    for key in ("MPI_LOCALNRANKS", "OMPI_COMM_WORLD_LOCAL_SIZE"):
        v = os.environ.get(key)
        if v and v.isdigit():
            return int(v)
    return None


def _state(rs):
    """Rank 0: the checkpoint fields of the whole scene, gathered (each rank's owned particles, the interactions
    and sums it counts) and merged; the same fields a serial run writes, so it resumes on any number of ranks."""
    part, sim = rs.part, rs.sim
    st = sim.state()
    own = part.own
    mine = {
        "idx": part.keep[own],
        "nord": sim.nord[own],
        "acc": st["acc"],
        "fam": {
            f.name: ranks.globalize(layout(f, part.system), f.state(sim.fams[slot(f)]), part.keep, own, part.system)
            for f in sim.families
        },
    }
    got = rs.comm.gather(mine, root=0)
    if rs.comm.Get_rank() != 0:
        return None
    g = rs.global_system
    nord = np.zeros((g.n, 3, 6))
    for m in got:  # each rank's rows dropped once copied: the gathered parts and the whole arrays not held at once
        nord[m["idx"]] = m.pop("nord")
    out = {"step": st["step"], "ended": st["ended"], "nord": nord, "acc": np.sum([m["acc"] for m in got], axis=0)}
    for f in sim.families:
        out.update(ranks.merge(layout(f, g), [m["fam"][f.name] for m in got], g, consume=True))
    return out


def _frame(rs):
    """Rank 0: an output frame's fields of the whole scene — positions, velocities and every family's frame fields
    (``Family.frame``) — each rank's owned particles and the rows it counts (``Family.frame_rows``) computed on its
    own part and gathered once; the whole state is not gathered for a frame."""
    from .halo import exchange

    part, sim = rs.part, rs.sim
    own = part.own
    # the committed positions with the ghosts' from their owners (a bond's strain needs both of its particles): one
    # exchange of them here, as the loop's last one need not be of the committed state (verlet1 corrects after it);
    # not counted among the loop's exchanges
    x, v = sim.nord[:, :, 0].copy(), sim.nord[:, :, 1] / sim.dt
    if rs.halo is not None and rs.halo.acc.shape[0]:
        count = rs.halo.acc[0]
        exchange(rs.halo, np.bool_(False), x, v)
        rs.halo.acc[0] = count
    mine = {"idx": part.keep[own], "x": x[own], "v": v[own], "fam": {}}
    for f in sim.families:
        rows = f.frame_rows(part.system)
        if rows is None:
            if f.frame_layout(part.system):
                raise TypeError(f"family {f.name!r} writes frame fields but does not number their rows (frame_rows)")
            continue
        fr = f.frame(part.system, sim.fams[slot(f)], x)
        # field by field: a rank without any of the family's rows may leave out a field (its width unknown there)
        mine["fam"][f.name] = {k: ranks.globalize([((k,), rows)], fr, part.keep, own, part.system) for k in fr}
    got = rs.comm.gather(mine, root=0)
    if rs.comm.Get_rank() != 0:
        return None
    n = part.n_whole
    x, v = np.zeros((n, 3)), np.zeros((n, 3))
    for m in got:
        x[m["idx"]] = m["x"]
        v[m["idx"]] = m["v"]
    fields, g = {}, rs.global_system
    for f in sim.families:
        names = dict.fromkeys(k for m in got for k in m["fam"].get(f.name, {}))
        for k in names:
            layout = [((k,), f.frame_rows(g))]
            fields.update(ranks.merge(layout, [m["fam"][f.name][k] for m in got if k in m["fam"].get(f.name, {})], g))
    return x, v, fields


def share(st, part) -> dict:
    """A rank's share of the whole scene's checkpoint fields ``st``: its particles' integrator state, the history
    sums on rank 0 only, each family's state cut to the part (interactions/ranks.py ``scatter`` from ``Family.state_layout``)."""
    local = {
        "step": st["step"],
        "ended": st["ended"],
        "nord": st["nord"][part.keep],
        "acc": st["acc"] if part.rank == 0 else np.zeros_like(st["acc"]),
    }
    for f in used_families(part.system):
        local.update(ranks.scatter(layout(f, part.system), st, part.keep, part.own, part.system, part.rank))
    return local


def _restore(rs, st):
    """Every rank: its part cut by rank 0 at the positions of the whole scene's checkpoint fields ``st`` (rank 0's;
    None elsewhere) and sent with its share of them; then one evaluation of the forces at that state (not a step:
    the diagnostics of the history row, the reactions)."""
    _settle(rs, rs._make(None if st is None else st["nord"][:, :, 0], st))


def _settle(rs, local):
    """Every rank: its new engine put in the state ``local`` (its share of the scene's checkpoint fields), then one
    evaluation of the forces at that state (not a step: the diagnostics of the history row, the reactions)."""
    from . import kernels as K

    sim = rs.sim
    sim.restore(local)
    # the forces and statistics at the restored state (its step's begin hooks first: a ramped load's fraction); the
    # final pass also writes history (a beam's failure record), so the restored state is put back after it
    K.begin_families(sim.fams, sim.step, sim.step * sim.dt)
    while K.evaluate(True, sim.x, sim.v, sim.dt, sim.P, sim.gravity, sim.ext, sim.fams, sim.F) < 0:
        sim._grow_families()
    sim.restore(local)


def _advance(rs, step_stop, nrows, rec_every, threads=1):
    """Every rank: advance with ``threads`` threads (rank 0's governor chose them for every rank); (rows, step, ended)
    on rank 0, or an EngineError on every rank with the message of the rank that saw the failure (a non-finite
    position names its particle by its global index)."""
    import numba

    numba.set_num_threads(max(1, min(int(threads), numba.config.NUMBA_NUM_THREADS)))
    rows = np.zeros((nrows, rs.sim.ncols))
    err = None
    try:
        n = rs.advance(step_stop, rows, rec_every)
    except EngineError as e:
        n, err = 0, str(e)
    # every rank stopped alike; the message of a rank that saw why (a named particle, a family's halt message)
    # before one that only followed the others (Simulation.advance: OTHER_RANK, the run "was stopped"); of several
    # ranks naming a particle with a non-finite force, the smallest number (the one a serial run names)
    key = (2, 0) if err is None else (1, 0) if OTHER_RANK in err or err.startswith(STOPPED) else (0, 0)
    if key[0] == 0 and "non-finite" in err and 0 <= int(rs.sim.info[2]) < rs.sim.system.n:
        key = (0, rs.sim.system.number(int(rs.sim.info[2])))
    got = [g for g in rs.comm.allgather((key, err)) if g[1]]
    if got:
        raise EngineError(min(got, key=lambda g: g[0])[1])
    return rows[:n], rs.sim.step, rs.sim.ended


def _current_row(rs):
    from mpi4py import MPI

    row = rs.sim.current_row()
    tot, big = np.zeros_like(row), np.zeros_like(row)
    rs.comm.Reduce(row, tot, op=MPI.SUM, root=0)
    rs.comm.Reduce(row, big, op=MPI.MAX, root=0)
    if rs.comm.Get_rank() != 0:
        return None
    return np.where(rs.reduce == 0, row, np.where(rs.reduce == 1, tot, big))


def _reports(rs, limits):
    """Rank 0: the families' reports (``Simulation.family_reports``) of the whole scene, combined from each rank's
    report of its own part — small messages, no per-particle array: a check or warning found on any rank (the first
    in rank order; a rank names particles by their global numbers), the end criterion's progress of rank 0 (an end
    criterion decides from sums agreed over the ranks, protocol.py ``halt``, so every rank reports the same)."""
    got = rs.comm.gather(rs.sim.family_reports(limits), root=0)
    if rs.comm.Get_rank() != 0:
        return None
    out = {"check": next((g["check"] for g in got if g["check"]), None), "warnings": {}, "end": got[0]["end"]}
    for g in reversed(got):
        out["warnings"].update(g["warnings"])
    return out


def execute(rs, name, args):
    """One collective command, run by every rank (rank 0's :class:`Leader` sends it, the others :func:`serve`)."""
    if name == "initialize":
        rs.initialize()
        return None
    if name == "advance":
        return _advance(rs, *args)
    if name == "state":
        return _state(rs)
    if name == "frame":
        return _frame(rs)
    if name == "positions":
        return rs.positions()
    if name == "velocities":
        return rs.velocities()
    if name == "current_row":
        return _current_row(rs)
    if name == "reports":
        return _reports(rs, *args)
    if name == "peaks":
        return rs.comm.gather(peak_rss_mib(), root=0)
    raise ValueError(f"unknown command {name!r}")  # pragma: no cover


def peak_rss_mib() -> float:
    """This process's peak resident memory so far [MiB] (``getrusage``'s ru_maxrss: KiB on Linux, bytes on macOS)."""
    import resource
    import sys

    got = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    return got / 1024.0**2 if sys.platform == "darwin" else got / 1024.0


def serve(comm=None):
    """Ranks 1…P−1 of a decomposed run: receive the part of the scene rank 0 sends (they never build or hold the
    whole scene), then run the commands it broadcasts until it says stop.
    SIGINT and SIGTERM are left to rank 0, which stops every rank after a checkpoint."""
    import signal

    from mpi4py import MPI

    comm = comm or MPI.COMM_WORLD
    for sig in (signal.SIGINT, signal.SIGTERM):
        signal.signal(sig, signal.SIG_IGN)
    rs = None
    while True:
        _meet(comm)
        name, args = comm.bcast(None, root=0)
        if name == "stop":
            return
        try:
            if name == "setup":
                rs = None
                rs = RankSimulation(None, comm)
            elif name == "restore":
                _restore(rs, None)
            elif rs is not None:
                execute(rs, name, args)
        except (EngineError, DecompositionError):
            pass  # met by every rank alike (an agreed engine failure, a refused decomposition): rank 0 reports it
        except Exception:  # noqa: BLE001 - anything else leaves the ranks out of step
            abort(comm, f"command {name!r}")


def abort(comm, what: str):
    """Stop every rank of the run now (MPI_Abort), after saying on stderr which rank failed in what, with its
    traceback: an unexpected failure on one rank leaves the others waiting in a collective call.  The result keeps
    its last checkpoint (written whole or not at all, io/hdf5.py)."""
    import sys
    import traceback

    r, size = comm.Get_rank(), comm.Get_size()
    sys.stderr.write(f"polydem: rank {r} of {size} failed in {what}; stopping every rank\n")
    traceback.print_exc(file=sys.stderr)
    sys.stderr.flush()
    comm.Abort(70 + min(r, 50))


#: the commands that gather per-particle arrays of the whole scene to rank 0 (frames, checkpoints, the summary; a
#: redistribution does not: engine/migrate.py)
WHOLE_STATE = ("state", "frame", "positions", "velocities")


class Leader:
    """Rank 0's engine of a decomposed run: the interface of :class:`~.simulation.Simulation` that the explicit
    solver family uses (advance, state, restore, positions, family bundles, …), each call a command that every
    rank runs together.  The family bundles it shows are of the whole scene, refreshed from the ranks' state when
    the step has changed (frames, checks, the summary)."""

    def __init__(self, system, comm=None, est=None):
        """``est``: the scene's critical time step estimate (engine/stability.py), if made already."""
        from mpi4py import MPI

        self.comm = comm or MPI.COMM_WORLD
        self.system = system
        self.n, self.dt, self.kind = system.n, system.dt, system.integrator
        command(self.comm, "setup")
        self.rs = RankSimulation(system, self.comm, est=est)
        self.ncols = self.rs.sim.ncols
        self.families, self._fams = compose(system)
        self._fresh = -1
        self.step, self.ended = 0, False
        self.info = np.zeros(4, np.int64)
        #: how often each command that gathers per-particle arrays to rank 0 ran (frames, checkpoints, the summary)
        self.gathers = {name: 0 for name in WHOLE_STATE}
        self.checks = 0  # the families' reports made (once per chunk of the loop)

    @property
    def ranks(self) -> int:
        return self.comm.Get_size()

    def _cmd(self, name, *args):
        if name in WHOLE_STATE:
            self.gathers[name] += 1
        command(self.comm, name, args)
        try:
            return execute(self.rs, name, args)
        except (EngineError, DecompositionError):
            raise
        except Exception:  # noqa: BLE001 - the other ranks would wait for this one forever
            abort(self.comm, f"command {name!r}")

    def stop(self):
        """Let the other ranks leave :func:`serve`."""
        command(self.comm, "stop")

    # ---- the Simulation interface
    def initialize(self):
        self._cmd("initialize")
        self.step, self.ended, self._fresh = 0, False, -1

    def check_initial_overlap(self):
        """The initial state checked on the whole scene (one evaluation at t0 on rank 0), so that a refusal names
        particles by their global numbers."""
        sim = Simulation(self.system)
        sim.initialize()
        sim.check_initial_overlap()

    @property
    def local_ranks(self) -> int:
        return self.rs.local_ranks

    def advance(self, step_stop, rows, rec_every) -> int:
        """Advance every rank, each with the thread count rank 0's governor has set here (solvers/explicit.py)."""
        import numba

        total = 0
        while True:
            got, self.step, self.ended = self._cmd(
                "advance", step_stop, rows.shape[0] - total, rec_every, numba.get_num_threads()
            )
            rows[total : total + len(got)] = got
            total += len(got)
            if self.step >= step_stop or self.ended or total >= rows.shape[0]:
                return total

    def current_row(self):
        return self._cmd("current_row")

    def family_reports(self, limits):
        """The families' checks, warnings and end progress, each rank reporting on its own part (:func:`_reports`):
        between frames the state is not gathered to rank 0 for them."""
        self.checks += 1
        return self._cmd("reports", limits)

    @property
    def time(self):
        return self.step * self.dt

    def positions(self):
        return self._cmd("positions")

    def velocities(self):
        return self._cmd("velocities")

    def frame_fields(self):
        """(positions, velocities, the families' frame fields) of the whole scene for an output frame, on rank 0: each
        rank's own rows gathered (:func:`_frame`), not the whole state."""
        return self._cmd("frame")

    def peak_rss_mib(self) -> list:
        """Each rank's peak resident memory so far [MiB], in rank order (one number per rank)."""
        return self._cmd("peaks")

    def state(self):
        st = self._cmd("state")
        self._show(st)
        return st

    def restore(self, st):
        command(self.comm, "restore")
        _restore(self.rs, st)
        self.step, self.ended = int(st["step"][0]), bool(st.get("ended", np.array([0]))[0])
        self._fresh = -1

    def _show(self, st):
        fams = list(self._fams)
        for f in self.families:
            k = slot(f)
            nb = f.restore(fams[k], st, system=self.system)
            if nb is not None:
                fams[k] = nb
        self._fams = tuple(fams)
        self._fresh = self.step

    def family_bundles(self):
        """(family, its bundle of the whole scene), the state as of the present step."""
        if self._fresh != self.step:
            self.state()
        return [(f, self._fams[slot(f)]) for f in self.families]

    def bundle(self, name):
        from .families import family

        self.family_bundles()
        return self._fams[slot(family(name))]
