"""``make bench-memory``: what a decomposed run costs each rank besides its steps (issue 54 item 6) — peak memory
(resident set), the set-up time, the messages and bytes of the halo exchange per step, and the time of a
redistribution (migration and re-balance) — for bonded specimens of 10⁴ and 10⁵ particles (and 10⁶ with ``--big``)
on 1, 2, 4 and 8 ranks.  Writes JSON (default outputs/bench_memory.json).

Each rank count runs in a fresh ``mpiexec -n P`` (oversubscribed beyond this machine's cores: the memory and the
message counts do not depend on it; the times do, and are for orientation).  Per rank:

* ``rss_start_mb``: the resident set after the imports and before the scene is built — the interpreter, NumPy,
  Numba and h5py; ``rss_loaded_mb`` after the scene's first steps, i.e. with the compiled loop loaded from the cache;
  ``rss_peak_mb``: the peak over the run (``getrusage``).  The constant part of every process is the peak of a
  16-particle specimen on one rank; the summary states each run's peak beyond it against one rank's;
* ``setup_s``: building the scene (rank 0 only) and cutting and sending the parts (``RankSimulation``): until the
  last rank has its part;
* ``held``, ``owned``: the particles the rank holds (owned and ghosts) and owns; ``neighbours``: the ranks it
  exchanges ghosts with; ``sent``, ``received``: ghost records per exchange (6 doubles each);
  ``exchanges_per_step``: force evaluations per step (Gear: 2), each one exchange with every neighbour (a send and a
  receive) and one allreduce;
* ``step_s``: wall per step (oversubscribed: orientation only); ``redistribute_s``: a redistribution (the re-cut
  by neighbour exchange, engine/migrate.py; the median of three) and ``redistribute_via_rank0_s`` the re-cut it
  replaced, alternated with it (the whole state gathered to rank 0, which cuts the scene again and sends every rank
  its part with its state; the peak memory is taken before these).

The summary gives the largest peak and, apart, rank 0's (the whole scene is built and kept there: the writer) and
the largest of the other ranks' (their parts only).
"""

from __future__ import annotations

import json
import os
import resource
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

#: bonded specimens (chapter 5's tension test, square cells): name -> (scenario, overrides)
SCENES = {
    "bonded_16": ("scenarios/ch5/tension.toml", ["particles.0.nx=4", "particles.0.ny=4"]),  # the constant part
    "bonded_1e4": ("scenarios/ch5/tension.toml", ["particles.0.nx=100", "particles.0.ny=100"]),
    "bonded_1e5": ("scenarios/ch5/tension.toml", ["particles.0.nx=316", "particles.0.ny=316"]),
    "bonded_1e6": ("scenarios/ch5/tension.toml", ["particles.0.nx=1000", "particles.0.ny=1000"]),
}
RANKS = (1, 2, 4, 8)
STEPS = 20


def _rss_mb() -> float:
    """The present resident set of this process [MB] (``/proc/self/statm``)."""
    with open("/proc/self/statm") as f:
        return int(f.read().split()[1]) * os.sysconf("SC_PAGE_SIZE") / 1e6


def rank_main(scene: str, out: str) -> None:
    """Under ``mpiexec -n P``: set up, step, redistribute once, and gather each rank's record to rank 0's JSON."""
    import polydem_cli

    polydem_cli.setup_jit_cache()
    import h5py  # noqa: F401 - what a run imports (the result writer), in the constant part
    from mpi4py import MPI

    from ..engine.distributed import RankSimulation
    from ..scenario.build import build_system
    from ..scenario.load import load_scenario

    comm = MPI.COMM_WORLD
    rec = {"rank": comm.Get_rank(), "rss_start_mb": _rss_mb()}
    path, ov = SCENES[scene]
    t0 = time.perf_counter()
    sc, _ = load_scenario(path, ov)
    system = build_system(sc, path) if comm.Get_rank() == 0 else None  # rank 0 sends the others their parts
    rs = RankSimulation(system, comm)
    rs.initialize()
    rec["setup_s"] = time.perf_counter() - t0
    rows = np.zeros((STEPS + 10, rs.sim.ncols))
    rs.advance(2, rows, 10**9)  # the compiled loop loaded
    rec["rss_loaded_mb"] = _rss_mb()
    comm.Barrier()
    t0 = time.perf_counter()
    rs.advance(2 + STEPS, rows, 10**9)
    comm.Barrier()
    rec["step_s"] = (time.perf_counter() - t0) / STEPS
    h, part = rs.halo, rs.part
    rec.update(
        particles=int(part.n_whole),
        held=int(len(part.keep)),
        owned=int(part.own.sum()),
        neighbours=int(len(h.nbr)),
        sent=int(len(h.send_idx)) if len(h.nbr) else 0,
        received=int(len(h.recv_idx)) if len(h.nbr) else 0,
        exchanges_per_step=1 if sc["time"]["integrator"] == "verlet1" else 2,
    )
    if comm.Get_size() > 1:
        comm.Barrier()
        t0 = time.perf_counter()
        rs.redistribute()
        comm.Barrier()
        rec["redistribute_s"] = time.perf_counter() - t0
    rec["rss_peak_mb"] = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1e3  # kB on Linux
    if comm.Get_size() > 1:  # against the re-cut through rank 0 that came before it, alternated, after the peak
        from ..engine import distributed as D

        mine, via0 = [rec["redistribute_s"]], []
        for _ in range(2):
            for way in (via0, mine):
                comm.Barrier()
                t0 = time.perf_counter()
                D._restore(rs, D._state(rs)) if way is via0 else rs.redistribute()
                comm.Barrier()
                way.append(time.perf_counter() - t0)
        rec["redistribute_s"] = float(np.median(mine))
        rec["redistribute_via_rank0_s"] = float(np.median(via0))
    got = comm.gather(rec, root=0)
    if comm.Get_rank() == 0:
        Path(out).write_text(json.dumps({"scene": scene, "ranks": comm.Get_size(), "per_rank": got}))


def _one(scene: str, ranks: int, tmp: Path) -> dict:
    out = tmp / f"{scene}_{ranks}.json"
    cmd = [
        str(Path(sys.executable).with_name("mpiexec")),
        "-n",
        str(ranks),
        sys.executable,
        "-m",
        "polydem_cli.benchmarks.memory",
    ]
    cmd += ["--rank-main", scene, str(out)]
    subprocess.run(cmd, check=True, env=dict(os.environ, OMP_NUM_THREADS="1", NUMBA_NUM_THREADS="1"))
    return json.loads(out.read_text())


def summarise(res: dict, constant_mb: float) -> dict:
    """Per scene and rank count: the largest rank's peak, the peak beyond the constant part (``constant_mb``: the
    peak of a 16-particle specimen on one rank — the interpreter, the libraries and the compiled loop) against one
    rank's, and the halo's messages and bytes per step of the busiest rank."""
    out = {}
    for scene, by in res.items():
        one = max(r["rss_peak_mb"] for r in by["1"]["per_rank"]) - constant_mb if "1" in by else 0.0
        rows = {}
        for p, d in by.items():
            pr = d["per_rank"]
            scene_mb = max(r["rss_peak_mb"] for r in pr) - constant_mb
            busiest = max(pr, key=lambda r: r["sent"] + r["received"])
            ex = busiest["exchanges_per_step"]
            others = [r["rss_peak_mb"] for r in pr if r["rank"] != 0]
            rows[p] = {
                "peak_mb_largest_rank": max(r["rss_peak_mb"] for r in pr),
                "peak_mb_rank0": next(r["rss_peak_mb"] for r in pr if r["rank"] == 0),
                "peak_mb_other_ranks_max": max(others) if others else None,
                "constant_mb": constant_mb,
                "beyond_constant_mb": scene_mb,
                "beyond_constant_vs_1_rank": scene_mb / one if one > 0 else None,
                "setup_s_max": max(r["setup_s"] for r in pr),
                "messages_per_step": 2 * busiest["neighbours"] * ex,
                "bytes_per_step": 48 * (busiest["sent"] + busiest["received"]) * ex,
                "held_max": max(r["held"] for r in pr),
                "redistribute_s": max((r.get("redistribute_s", 0.0) for r in pr), default=None),
                "redistribute_via_rank0_s": max((r.get("redistribute_via_rank0_s", 0.0) for r in pr), default=None),
            }
        out[scene] = rows
    return out


def run(out: Path, scenes=("bonded_1e4", "bonded_1e5"), ranks=RANKS) -> dict:
    """Every scene on every rank count, one ``mpiexec`` each, after the constant part (a 16-particle specimen on one
    rank); the records, their summary and a line per run on the console."""
    tmp = out.parent / "bench_memory_runs"
    tmp.mkdir(parents=True, exist_ok=True)
    base = _one("bonded_16", 1, tmp)
    constant = base["per_rank"][0]["rss_peak_mb"]
    res = {}
    for scene in scenes:
        res[scene] = {}
        for p in ranks:
            print(f"{scene} on {p} rank(s) ...", flush=True)
            res[scene][str(p)] = _one(scene, p, tmp)
    doc = {
        "constant": base,
        "runs": res,
        "summary": summarise(res, constant),
        "steps": STEPS,
        "machine_cores": os.cpu_count(),
    }
    out.write_text(json.dumps(doc, indent=1))
    for scene, rows in doc["summary"].items():
        for p, r in rows.items():
            print(
                f"{scene} P={p}: peak {r['peak_mb_largest_rank']:.0f} MB (constant {r['constant_mb']:.0f}; "
                f"rank 0 {r['peak_mb_rank0']:.0f}, the others at most {r['peak_mb_other_ranks_max'] or 0:.0f}), "
                f"beyond it {r['beyond_constant_mb']:.0f} MB = {r['beyond_constant_vs_1_rank'] or float('nan'):.2f} x 1 rank; "
                f"set-up {r['setup_s_max']:.1f} s; {r['messages_per_step']} messages, "
                f"{r['bytes_per_step'] / 1e3:.1f} kB per step (busiest rank); "
                f"redistribution {r['redistribute_s'] or 0:.2f} s (through rank 0: {r['redistribute_via_rank0_s'] or 0:.2f} s)"
            )
    return doc


if __name__ == "__main__":
    if len(sys.argv) > 1 and sys.argv[1] == "--rank-main":
        rank_main(sys.argv[2], sys.argv[3])
    else:  # [OUT.json] [--big] [--scene=NAME ...] [--ranks=1,2]
        args = [a for a in sys.argv[1:] if not a.startswith("--")]
        big = "--big" in sys.argv
        scenes = ("bonded_1e4", "bonded_1e5") + (("bonded_1e6",) if big else ())
        scenes = tuple(a.split("=", 1)[1] for a in sys.argv if a.startswith("--scene=")) or scenes
        ranks = next((a.split("=", 1)[1] for a in sys.argv if a.startswith("--ranks=")), None)
        unknown = [s for s in scenes if s not in SCENES]
        if unknown:
            sys.exit(f"bench-memory: unknown scene {unknown[0]!r} (known: {', '.join(SCENES)})")
        rk = tuple(int(p) for p in ranks.split(",")) if ranks else RANKS
        run(Path(args[0] if args else "outputs/bench_memory.json"), scenes, rk)
