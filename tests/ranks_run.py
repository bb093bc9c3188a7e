"""Run a scenario for a number of steps on the MPI ranks this script was started on (``mpiexec -n N python
tests/ranks_run.py OUT.npz SCENARIO STEPS [--set key=value ...]``, engine/distributed.py) and write, on rank 0, the
positions, velocities, history rows, the damage of every bond, which rank owns each particle (at the end, and
at the start and after each redistribution: ``owners``), the ranks' boxes at the end and how often the particles
were redistributed (``--skin=W``: a ghost margin of W cm instead of the default, to make that often)
(tests/test_ranks.py compares them with a serial run).  ``--until-error``: the run goes through the command every
rank runs (engine/distributed.py ``_advance``), and rank 0 writes the step reached and the error every rank stopped
with; ``--poison=P@K`` (implies it): after step K the external load on particle P (global number) is made infinite
on the rank owning it (a non-finite force at a finite state, as an unstable run first has one).
``--refuse-recut``: rank 0's first re-cut is refused (a DecompositionError, as for a box grown narrower than the
interaction range); rank 0 writes the step reached, every rank's error and the positions gathered afterwards."""

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
    flags = ("--skin=", "--poison=", "--until-error", "--refuse-recut")
    sc, _ = load_scenario(path, [a for a in argv[3:] if not a.startswith(flags)])
    comm = MPI.COMM_WORLD
    lead = comm.Get_rank() == 0
    try:
        system = build_system(sc, path) if lead else None  # the other ranks get their parts from rank 0
    except Exception:  # the other ranks would wait for their parts forever
        import traceback

        traceback.print_exc()
        comm.Abort(3)
    rs = RankSimulation(system, comm, skin=skin[0] if skin else None)
    every = rs.part.system.history_every
    owners = [rs.cut.dec.owner.copy()] if lead else []  # every particle's owner at the start and after each re-cut
    cut = rs.redistribute

    def redistribute():
        cut()
        if lead:
            owners.append(rs.cut.dec.owner.copy())

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
            owner=rs.cut.dec.owner,
            owners=np.array(owners),
            boxes=rs.cut.dec.boxes,
            ranks=comm.Get_size(),
            redistributions=rs.redistributions,
        )


def _refused_recut(rs, out, steps, every):
    import polydem_cli.engine.distributed as D
    from polydem_cli.errors import DecompositionError

    class Refusing(D.Cut):
        def __init__(self, *args, **kw):
            raise DecompositionError("the re-cut refused for the test")

    D.Cut = Refusing  # the first cut is made: the next one (at the first redistribution) is refused
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
