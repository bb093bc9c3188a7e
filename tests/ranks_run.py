"""Run a scenario for a number of steps on the MPI ranks this script was started on (``mpiexec -n N python
tests/ranks_run.py OUT.npz SCENARIO STEPS [--set key=value ...]``, engine/distributed.py) and write, on rank 0, the
positions, velocities, history rows, the damage of every bond, which rank owns each particle (at the end, and
at the start and after each redistribution: ``owners``), the ranks' boxes at the end and how often the particles
were redistributed (``--skin=W``: a ghost margin of W cm instead of the default, to make that often)
(tests/test_ranks.py compares them with a serial run).  ``--until-error``: the run goes through the command every
rank runs (engine/distributed.py ``_advance``), and rank 0 writes the step reached and the error every rank stopped
with; ``--poison=P@K`` (implies it): after step K the external load on particle P (global number) is made infinite
on the rank owning it (a non-finite force at a finite state, as an unstable run first has one).
``--refuse-recut``: the first re-cut is refused (a DecompositionError, as for a box grown narrower than the
interaction range); rank 0 writes the step reached, every rank's error and the positions gathered afterwards.
``--count-collectives``: the run's communicator notes, for each kind of collective call made during a re-cut, the
longest array it carried (written as ``collectives``, named by ``collective_names``).  ``--compare-recut``: each re-cut's
new part and state compared with rank 0's cut of the gathered whole scene (written as ``differ``: where they
differ)."""

from __future__ import annotations

import sys

import numpy as np


def main(argv):
    import polydem_cli

    polydem_cli.setup_jit_cache()
    from mpi4py import MPI

    from polydem_cli.engine.distributed import RankSimulation
    from polydem_cli.scenario.build import build_system
    from polydem_cli.scenario.load import load_scenario

    out, path, steps = argv[0], argv[1], int(argv[2])
    skin = [float(a.split("=", 1)[1]) for a in argv[3:] if a.startswith("--skin=")]
    poison = [a.split("=", 1)[1].split("@") for a in argv[3:] if a.startswith("--poison=")]
    until_error = bool(poison) or "--until-error" in argv[3:]
    refuse = "--refuse-recut" in argv[3:]
    count = "--count-collectives" in argv[3:]
    compare = "--compare-recut" in argv[3:]
    flags = ("--skin=", "--poison=", "--until-error", "--refuse-recut", "--count-collectives", "--compare-recut")
    sc, _ = load_scenario(path, [a for a in argv[3:] if not a.startswith(flags)])
    Counting = _counting()
    comm = Counting(MPI.COMM_WORLD) if count else MPI.COMM_WORLD
    lead = comm.Get_rank() == 0
    try:
        system = build_system(sc, path) if lead else None  # the other ranks get their parts from rank 0
    except Exception:  # the other ranks would wait for their parts forever
        import traceback

        traceback.print_exc()
        comm.Abort(3)
    rs = RankSimulation(system, comm, skin=skin[0] if skin else None)
    every = rs.part.system.history_every
    owners = [rs.owners()]  # every particle's owner at the start and after each re-cut (None but on rank 0)
    cut = rs.redistribute

    differ = []  # with --compare-recut: where a re-cut's part or state differs from rank 0's cut of the whole scene

    def redistribute():
        if compare:
            differ.extend(_compare_recut(rs))
        else:
            Counting.on = count  # what the re-cut itself sends over the ranks (not the test's gathers around it)
            try:
                cut()
            finally:
                Counting.on = False
        owners.append(rs.owners())

    rs.redistribute = redistribute
    rs.initialize()
    if refuse:
        return _refused_recut(rs, out, steps, every)
    if until_error:
        return _until_error(rs, out, steps, every, *(int(v) for v in (poison[0] if poison else ())))
    rows = np.zeros((steps // every + 2, rs.sim.ncols))
    n = rs.advance(steps, rows, every)
    x, v = rs.positions(), rs.velocities()
    b = rs.sim.bundle("bonds")
    net = rs.part.system.family_data.get("bonds")
    net = net if net is not None and net.gid is not None else None
    mine = np.zeros(0, np.int64) if net is None else net.gid[net.counted == 1]
    dmg = np.zeros(0) if net is None else b.h.d[net.counted == 1]
    got = comm.gather((mine, dmg), root=0)
    owner = rs.owners()
    seen = comm.gather(Counting.seen, root=0)
    differ = comm.gather(differ, root=0)
    if comm.Get_rank() == 0:
        nb = sum(len(g) for g, _ in got)
        d = np.full(nb, np.nan)
        for g, val in got:
            d[g] = val
        np.savez(
            out,
            x=x,
            v=v,
            rows=rows[:n],
            d=d,
            owner=owner,
            owners=np.array(owners),
            boxes=rs.part.lists["boxes"],
            ranks=comm.Get_size(),
            redistributions=rs.redistributions,
            collectives=np.array([max(g.get(k, 0) for g in seen) for k in Counting.NAMES]),
            collective_names=np.array(Counting.NAMES),
            differ=np.array([f"rank {r}: {d}" for r, ds in enumerate(differ) for d in ds] + [""]),
        )


def _compare_recut(rs):
    """A re-cut by neighbour exchange (engine/migrate.py), checked against the cut of the whole scene gathered to
    rank 0 (engine/distributed.py ``Cut`` and ``share``, the way re-cuts were made before): the new part (its particles,
    scene, family data, exchange lists, set members) and the rank's share of the checkpoint fields, array by array.
    Returns where they differ."""
    import polydem_cli.engine.distributed as D
    import polydem_cli.engine.migrate as M

    comm = rs.comm
    st = D._state(rs)  # the whole scene's state on rank 0
    if comm.Get_rank() == 0:
        cut = D.Cut(rs.global_system, comm.Get_size(), rs.method, st["nord"][:, :, 0], rs.skin)
        refs = [(cut.part(r), D.share(st, cut.part(r))) for r in range(comm.Get_size())]
        for r in range(1, comm.Get_size()):
            comm.send(refs[r], dest=r, tag=77)
        ref = refs[0]
    else:
        ref = comm.recv(source=0, tag=77)
    local = M.recut(rs)
    D._settle(rs, local)
    rs.redistributions += 1
    p, q = rs.part, ref[0]
    out = []
    for name in ("keep", "own", "large", "held_sets", "lists", "n_whole"):
        out += _differ(getattr(p, name), getattr(q, name), name)
    out += _differ(p.system, q.system, "system")
    out += _differ(local, ref[1], "state")
    return out


def _differ(a, b, path) -> list:
    """Where two nested values (arrays, dicts, tuples, dataclasses) differ, as paths; arrays bit for bit."""
    from dataclasses import fields, is_dataclass

    if isinstance(a, np.ndarray) or isinstance(b, np.ndarray):
        a, b = np.asarray(a), np.asarray(b)
        # the dtype too, empty or not: another dtype is another compiled specialisation of the loop
        same = a.shape == b.shape and a.dtype == b.dtype and np.array_equal(a, b, equal_nan=a.dtype.kind == "f")
        return [] if same else [f"{path}: {a.dtype}{a.shape} {b.dtype}{b.shape}"]
    if isinstance(a, dict) and isinstance(b, dict):
        if set(a) != set(b):
            return [f"{path}: keys {sorted(map(str, set(a) ^ set(b)))}"]
        return [d for k in a for d in _differ(a[k], b[k], f"{path}.{k}")]
    if is_dataclass(a) and type(a) is type(b):
        return [d for f in fields(a) for d in _differ(getattr(a, f.name), getattr(b, f.name), f"{path}.{f.name}")]
    if isinstance(a, (tuple, list)) and isinstance(b, (tuple, list)):
        if len(a) != len(b) or type(a) is not type(b):
            return [f"{path}: {type(a).__name__} of {len(a)} vs {type(b).__name__} of {len(b)}"]
        names = getattr(a, "_fields", range(len(a)))
        return [d for k, x, y in zip(names, a, b) for d in _differ(x, y, f"{path}.{k}")]
    try:
        same = a == b
        return [] if bool(same) else [f"{path}: {a!r} vs {b!r}"[:200]]
    except (ValueError, TypeError):
        return [f"{path}: not comparable ({type(a).__name__})"]


def _longest(obj) -> int:
    """The longest array or list in a message (an array by its first axis): what a per-particle array would make as
    long as a rank's particles."""
    if isinstance(obj, np.ndarray):
        return int(obj.shape[0]) if obj.ndim else 1
    if isinstance(obj, dict):
        obj = list(obj.values())
    if isinstance(obj, (list, tuple)):
        return max([len(obj)] + [_longest(o) for o in obj])
    return 1


def _counting():
    from mpi4py import MPI

    class Counting(MPI.Intracomm):
        """The world communicator, noting for each collective call the longest array it carried while ``on``."""

        on = False
        seen: dict = {}
        NAMES = ("gather", "allgather", "bcast", "scatter", "alltoall", "Allreduce", "Reduce", "Reduce_scatter_block")

        def _note(self, name, payload):
            if Counting.on:
                Counting.seen[name] = max(Counting.seen.get(name, 0), _longest(payload))

        def gather(self, obj, root=0):
            self._note("gather", obj)
            return super().gather(obj, root=root)

        def allgather(self, obj):
            self._note("allgather", obj)
            return super().allgather(obj)

        def bcast(self, obj, root=0):
            self._note("bcast", obj)
            return super().bcast(obj, root=root)

        def scatter(self, obj, root=0):
            self._note("scatter", obj)
            return super().scatter(obj, root=root)

        def alltoall(self, obj):
            self._note("alltoall", obj)
            return super().alltoall(obj)

        def Allreduce(self, a, b, op=MPI.SUM):
            self._note("Allreduce", a)
            return super().Allreduce(a, b, op=op)

        def Reduce(self, a, b, op=MPI.SUM, root=0):
            self._note("Reduce", a)
            return super().Reduce(a, b, op=op, root=root)

        def Reduce_scatter_block(self, a, b, op=MPI.SUM):
            self._note("Reduce_scatter_block", a)
            return super().Reduce_scatter_block(a, b, op=op)

    return Counting


def _refused_recut(rs, out, steps, every):
    import polydem_cli.engine.migrate as M
    from polydem_cli.errors import DecompositionError

    def refusing(*args, **kw):
        raise DecompositionError("the re-cut refused for the test")

    M.new_boxes = refusing  # the first cut is made: the next one (at the first redistribution) is refused
    msg = ""
    try:
        rs.advance(steps, np.zeros((steps // every + 2, rs.sim.ncols)), every)
    except DecompositionError as e:
        msg = str(e)
    msgs = rs.comm.gather(msg, root=0)
    x = rs.positions()  # the old parts are whole: the state gathers as for the summary
    if rs.comm.Get_rank() == 0:
        np.savez(out, step=rs.sim.step, messages=np.array(msgs), x=x)


def _until_error(rs, out, steps, every, p=-1, k=0):
    from polydem_cli.engine.distributed import _advance
    from polydem_cli.engine.simulation import EngineError

    if p >= 0:
        rs.advance(k, np.zeros((k // every + 2, rs.sim.ncols)), every)
        if p in rs.part.keep[rs.part.own]:
            i = int(np.flatnonzero(rs.part.keep == p)[0])
            rs.sim.ext[i, 0] = np.inf
    msg = ""
    try:
        _advance(rs, steps, steps // every + 2, every)
    except EngineError as e:
        msg = str(e)
    if rs.comm.Get_rank() == 0:
        np.savez(out, step=rs.sim.step, message=msg)


if __name__ == "__main__":
    main(sys.argv[1:])
