"""What a decomposed run would exchange, measured, and what that costs at scale, projected: ``make bench-halo``.

1. **Ghosts per rank** (engine/decompose.py) for recursive bisection and for slabs, on the benchmark scenes as
   built (the concrete panel, dense hexagon packings) and on hexagon lattices of the same particle size up to
   10⁷ particles (built as centroids only: the decomposition needs nothing else), for 2 … 256 ranks.
2. **One exchange** between two MPI ranks on this machine, from 8 B to 8 MiB both ways: from Python (mpi4py
   ``Sendrecv``) and from compiled code (numba-mpi ``sendrecv``, as the time loop would exchange without leaving
   its compiled code); latency (the smallest message) and bandwidth (the largest) of each.  Beside it, what leaving the
   compiled loop once per step costs (the concrete panel advanced one step per call against 1,000 per call):
   the price of exchanging from Python.
3. **Projection**: the parallel efficiency ``E = t_step / (t_step + t_exchange)`` of a step of ``n/P`` particles at
   the measured one-core rate, with two ghost refreshes per step (one before each force evaluation of the
   predictor–corrector step; positions and velocities, 48 B per ghost) to each neighbour of a box, for a 10⁶- and
   a 10⁷-particle specimen and the thesis-form rate-dependent panel made 10× larger (16,000 particles, 10⁷
   steps) on 16, 64 and 256 ranks; within one machine at the latency and bandwidth measured here, across
   machines at an interconnect's stated figures (an assumption, not a measurement: none here).  Left out, and
   said so: load imbalance, migration, and the cost of leaving the compiled loop for each exchange.

Run as ``python -m polydem_cli.benchmarks.halo OUT.json [--rate PARTICLE_STEPS_PER_S]``; the exchange part runs
itself under ``mpiexec -n 2`` (the MPI of the ``mpich`` wheel, installed with the ``mpi`` extra).
"""

from __future__ import annotations

import json
import math
import os
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

from ..engine.decompose import decompose, ghosts

#: one ghost refresh sends, per ghost, its position and velocity (x1, x2, φ and their rates: 6 doubles)
BYTES_PER_GHOST = 48
#: ghost refreshes per step: before each of the two force evaluations of the staggered scheme (thesis Fig. A.2)
REFRESHES_PER_STEP = 2
#: an interconnect between machines, for the projection only (typical HDR InfiniBand figures, not measured here)
NETWORK = {"latency_s": 1.5e-6, "bandwidth_B_per_s": 12e9, "what": "assumed: HDR InfiniBand, 1.5 us, 12 GB/s"}
RANKS = (2, 4, 16, 64, 256)


def hex_lattice(n: int, spacing: float = 1.0) -> np.ndarray:
    """Centroids of about ``n`` hexagons in a square patch (rows ``spacing`` √3/2 apart, alternate rows shifted)."""
    cols = int(math.ceil(math.sqrt(n * math.sqrt(3) / 2)))
    rows = int(math.ceil(n / cols))
    j, i = np.divmod(np.arange(rows * cols), cols)
    x = (i + 0.5 * (j % 2)) * spacing
    y = j * spacing * math.sqrt(3) / 2
    return np.column_stack([x, y])[:n]


def ghost_table(points, radius, reach, ranks=RANKS, methods=("rcb", "slabs"), sample=8) -> list:
    """Per method and rank count: owned particles per rank and the ghosts of the ranks with the most (checked on
    ``sample`` ranks spread over the boxes, all of them when there are fewer), or why it was refused."""
    out = []
    for method in methods:
        for p in ranks:
            try:
                d = decompose(points, radius, p, reach, method=method)
            except ValueError as e:
                out.append({"method": method, "ranks": p, "refused": str(e)})
                continue
            which = range(p) if p <= sample else np.linspace(0, p - 1, sample).astype(int)
            g = [len(ghosts(d, points, radius, int(r))) for r in which]
            out.append(
                {
                    "method": method,
                    "ranks": p,
                    "owned_per_rank": float(len(points) / p),
                    "max_ghosts": int(max(g)),
                    "ghosts_over_owned": float(max(g) / (len(points) / p)),
                    "bytes_per_refresh": int(max(g) * BYTES_PER_GHOST),
                }
            )
    return out


def scene_points(name: str):
    """(centroids, bounding radii, reach) of a ``make bench`` scene as built."""
    from ..engine.decompose import plan
    from ..scenario.build import build_system
    from ..scenario.load import load_scenario
    from .bench import SCENES

    path, ov, _ = SCENES[name]
    sc, _ = load_scenario(path, ov)
    s = build_system(sc, path)
    d = plan(s, 1)
    return s.x0[:, :2], s.radius, d.halo - float(s.radius[~d.replicated].max())


SIZES = [8 * 4**k for k in range(11)]  # 8 B … 8 MiB


def _fit(rows) -> dict:
    """Latency (the time of the smallest message) and bandwidth (the largest message's bytes over its time beyond
    that latency): the two ends of the measured range, so that neither is set by the other's messages."""
    b = np.array([r["bytes"] for r in rows], float)
    t = np.array([r["median_s"] for r in rows])
    return {"rows": rows, "latency_s": float(t[0]), "bandwidth_B_per_s": float(b[-1] / (t[-1] - t[0]))}


def _python_rows(comm, other) -> list:
    """Sendrecv from Python (mpi4py), each one timed alone between barriers."""
    from mpi4py import MPI

    rows = []
    for nbytes in SIZES:
        send = np.ones(max(1, nbytes // 8))
        recv = np.empty_like(send)
        reps = max(20, min(2000, int(2e7 // max(nbytes, 1))))
        for _ in range(5):
            comm.Sendrecv(send, dest=other, recvbuf=recv, source=other)
        times = []
        for _ in range(reps):
            comm.Barrier()
            t0 = MPI.Wtime()
            comm.Sendrecv(send, dest=other, recvbuf=recv, source=other)
            times.append(MPI.Wtime() - t0)
        rows.append({"bytes": int(send.nbytes), "median_s": float(np.median(times)), "repeats": reps})
    return rows


def _compiled_rows(comm, other) -> list:
    """Sendrecv from compiled code (numba-mpi: the exchange a compiled time loop would make without leaving
    it), the mean over a run of back-to-back exchanges, median of five runs."""
    import numba
    import numba_mpi

    @numba.njit
    def burst(send, recv, reps, other):
        for _ in range(reps):
            numba_mpi.sendrecv(send, other, recv, other)

    rows = []
    for nbytes in SIZES:
        send = np.ones(max(1, nbytes // 8))
        recv = np.empty_like(send)
        reps = max(20, min(20000, int(2e8 // max(nbytes, 1))))
        burst(send, recv, 5, other)
        runs = []
        for _ in range(5):
            comm.Barrier()
            t0 = time.perf_counter()
            burst(send, recv, reps, other)
            runs.append((time.perf_counter() - t0) / reps)
        rows.append({"bytes": int(send.nbytes), "median_s": float(np.median(runs)), "repeats": reps})
    return rows


def loop_exit_cost(name: str = "concrete_40x40", steps: int = 1000, trials: int = 3) -> dict:
    """Wall per step of a bench scene on one thread advanced ``steps`` steps in one call and one step per call
    (medians of ``trials`` interleaved), and their difference: the cost of leaving the compiled loop each step."""
    import numba

    from ..engine.simulation import Simulation
    from ..scenario.build import build_system
    from ..scenario.load import load_scenario
    from .bench import SCENES

    numba.set_num_threads(1)
    path, ov, _ = SCENES[name]
    sc, _ = load_scenario(path, ov)
    s = build_system(sc, path)
    res = {"batched": [], "one_step_per_call": []}
    for _ in range(trials):
        for mode in res:
            sim = Simulation(s)
            sim.initialize()
            rows = np.zeros((10, sim.ncols))
            sim.advance(50, rows, 10**9)  # compiled or loaded; caches warm
            end = sim.step + steps
            t0 = time.perf_counter()
            if mode == "batched":
                sim.advance(end, rows, 10**9)
            while sim.step < end:
                sim.advance(sim.step + 1, rows, 10**9)
            res[mode].append((time.perf_counter() - t0) / steps)
    b, o = float(np.median(res["batched"])), float(np.median(res["one_step_per_call"]))
    return {
        "scene": name,
        "particles": int(s.n),
        "batched_s_per_step": b,
        "one_step_per_call_s": o,
        "per_call_s": o - b,
    }


def exchange_main(out: str) -> None:
    """Under ``mpiexec -n 2``: time a Sendrecv of each message size between the two ranks, from Python and (with
    numba-mpi) from compiled code; rank 0 writes JSON."""
    from mpi4py import MPI

    comm = MPI.COMM_WORLD
    other = 1 - comm.Get_rank()
    res = {"mpi": MPI.Get_library_version().splitlines()[0], "python": _fit(_python_rows(comm, other))}
    try:
        res["compiled"] = _fit(_compiled_rows(comm, other))
    except ImportError:
        res["compiled"] = None
    if comm.Get_rank() == 0:
        Path(out).write_text(json.dumps(res, indent=1))


def measure_exchange(tmp: Path) -> dict:
    """Start this module's exchange timing on two ranks (``mpiexec -n 2``) and read what rank 0 wrote."""
    mpiexec = Path(sys.executable).with_name("mpiexec")
    out = tmp / "exchange.json"
    cmd = [str(mpiexec), "-n", "2", sys.executable, "-m", "polydem_cli.benchmarks.halo", "--exchange", str(out)]
    subprocess.run(cmd, check=True, env=dict(os.environ, OMP_NUM_THREADS="1", NUMBA_NUM_THREADS="1"))
    return json.loads(out.read_text())


def efficiency(n: int, ranks: int, ghosts_max: int, neighbours: int, rate: float, net: dict) -> dict:
    """Projected step time and parallel efficiency of ``n`` particles on ``ranks`` ranks (one core each, ``rate``
    particle-steps/s each) exchanging ``ghosts_max`` ghosts with ``neighbours`` boxes per refresh over ``net``."""
    t_step = n / ranks / rate
    t_x = REFRESHES_PER_STEP * (neighbours * net["latency_s"] + ghosts_max * BYTES_PER_GHOST / net["bandwidth_B_per_s"])
    return {"t_step_s": t_step, "t_exchange_s": t_x, "efficiency": t_step / (t_step + t_x)}


#: the thesis-form rate-dependent panel is 1,600 particles over 10^7 steps; the projection takes it 10x larger
THESIS_PANEL_10X = 16_000
THESIS_STEPS = 10**7


def run(out: Path, rate: float, sizes=(THESIS_PANEL_10X, 10**6, 10**7)) -> dict:
    """The three parts of the module docstring; JSON to ``out``, a summary printed."""
    import tempfile

    res = {"rate_particle_steps_per_s": rate, "scenes": {}, "lattices": {}, "projection": []}
    for name in ("concrete_40x40", "dense_N1e4"):
        pts, r, reach = scene_points(name)
        res["scenes"][name] = {"particles": len(pts), "reach": reach, "ghosts": ghost_table(pts, r, reach, (2, 4))}
    spacing = 1.0
    radius_hex = spacing / math.sqrt(3)  # circumradius of a hexagon of width ``spacing``
    for n in sizes:
        pts = hex_lattice(n, spacing)
        r = np.full(len(pts), radius_hex)
        res["lattices"][str(n)] = ghost_table(pts, r, 0.2 * radius_hex, RANKS, ("rcb",))
    res["loop_exit"] = loop_exit_cost()
    with tempfile.TemporaryDirectory() as tmp:
        try:
            res["exchange"] = measure_exchange(Path(tmp))
        except (OSError, subprocess.CalledProcessError) as e:
            res["exchange"] = {"error": f"no exchange measured ({e}); install the mpi extra: pip install '.[mpi]'"}
    ex = res["exchange"]
    here = ex.get("compiled") or ex.get("python")  # the compiled loop's own exchange where numba-mpi is there
    for n in sizes:
        for row in res["lattices"][str(n)]:
            if "refused" in row or row["ranks"] < 16:
                continue
            for where, net in (("one machine", here), ("across machines", NETWORK)):
                if net is None:
                    continue
                e = efficiency(n, row["ranks"], row["max_ghosts"], 4, rate, net)
                res["projection"].append({"particles": n, "ranks": row["ranks"], "network": where, **e})
    for p in res["projection"]:
        if p["particles"] == THESIS_PANEL_10X:
            p["thesis_form_run_h"] = THESIS_STEPS * (p["t_step_s"] + p["t_exchange_s"]) / 3600.0
    res["thesis_form_run_one_core_h"] = THESIS_STEPS * THESIS_PANEL_10X / rate / 3600.0
    Path(out).parent.mkdir(parents=True, exist_ok=True)
    Path(out).write_text(json.dumps(res, indent=1))
    for p in res["projection"]:
        print(
            f"{p['particles']:>9,d} particles on {p['ranks']:>3d} ranks ({p['network']}): step {p['t_step_s'] * 1e3:.3g} ms, "
            f"exchange {p['t_exchange_s'] * 1e6:.3g} us, efficiency {p['efficiency']:.3f}"
        )
    return res


if __name__ == "__main__":  # pragma: no cover - a benchmark entry point
    if sys.argv[1:2] == ["--exchange"]:
        exchange_main(sys.argv[2])
    else:
        from polydem_cli import setup_jit_cache

        setup_jit_cache()
        rate = float(sys.argv[sys.argv.index("--rate") + 1]) if "--rate" in sys.argv else 1.9e6
        run(
            Path(sys.argv[1] if len(sys.argv) > 1 and not sys.argv[1].startswith("--") else "outputs/bench_halo.json"),
            rate,
        )
