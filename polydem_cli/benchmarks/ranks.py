"""``make bench-ranks``: particle-steps per second of scenes decomposed over 1 and 2 MPI ranks
(engine/distributed.py), one thread per rank, the two rank counts alternated in fresh processes (this machine's
speed drifts between hours: medians of the rounds and the ratio of each round), and weak scaling (twice the
particles on twice the ranks).  Writes JSON (default outputs/bench_ranks.json).

``--parts SCENE OUT [ROUNDS [FACTOR]]``: the bound of 2 ranks without synchronisation (``parts_bound``).

Scenes: those of ``make bench`` (benchmarks/bench.py) whose families run decomposed today (polygon contact, beam
bonds, base friction, the load-drop stop, disks with walls and servo walls; no plates), and a panel twice as tall
for the weak scaling; any scene of ``make bench`` by its name.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

#: scene -> (scenario, overrides, steps timed)
SCENES = {
    "concrete_40x40": ("scenarios/bench_concrete_40.toml", [], 2000),
    "concrete_40x80": ("scenarios/bench_concrete_40.toml", ["particles.0.ny=80"], 1000),
    "lh_biaxial_1950": ("scenarios/lh/prepare_p100.toml", [], 2000),
    "lh_static": ("scenarios/lh/prepare_p100.toml", ["servo.0.pressure=0.0", "servo.1.pressure=0.0"], 2000),
    "dense_N1e4": (
        "scenarios/bench_dense_hexagons.toml",
        ["particles.0.rows=100", "particles.0.row_counts=[100, 100]"],
        200,
    ),
    "bonded_300x300": ("scenarios/ch5/tension.toml", ["particles.0.nx=300", "particles.0.ny=300"], 100),
    "dense_N1e5": (
        "scenarios/bench_dense_hexagons.toml",
        ["particles.0.rows=316", "particles.0.row_counts=[316, 316]"],
        20,
    ),
}
#: (scene on 1 rank, scene on 2 ranks) of the weak scaling
WEAK = ("concrete_40x40", "concrete_40x80")


def _scene(scene: str) -> tuple:
    """(scenario, overrides, steps) of a scene of this module or of ``make bench`` (benchmarks/bench.py)."""
    from .scenes import SCENES as BENCH

    return SCENES[scene] if scene in SCENES else BENCH[scene]


def supported(scene: str, ranks: int = 2) -> str | None:
    """None if the scene runs on ``ranks`` ranks, else why not (the refusal of engine/distributed.py's check)."""
    import polydem_cli

    polydem_cli.setup_jit_cache()
    from ..engine.distributed import check
    from ..errors import DecompositionError
    from ..scenario.build import build_system
    from ..scenario.load import load_scenario

    path, ov, _ = _scene(scene)
    if not Path(sys.executable).with_name("mpiexec").exists():
        return "no mpiexec next to this Python (pip install -e '.[mpi]')"
    try:
        sc, _ = load_scenario(path, ov)
        check(build_system(sc, path), ranks)
    except DecompositionError as e:
        return str(e)
    return None


def rank_main(scene: str, out: str, steps_factor: float = 1.0) -> None:
    """Under ``mpiexec -n P``: advance the scene, time its steps between barriers; rank 0 writes JSON."""
    import polydem_cli

    polydem_cli.setup_jit_cache()
    from mpi4py import MPI

    from ..engine.distributed import RankSimulation
    from ..scenario.build import build_system
    from ..scenario.load import load_scenario

    path, ov, steps = _scene(scene)
    steps = max(1, int(steps * steps_factor))
    sc, _ = load_scenario(path, ov)
    comm = MPI.COMM_WORLD
    system = build_system(sc, path) if comm.Get_rank() == 0 else None  # rank 0 sends the others their parts
    rs = RankSimulation(system, comm)
    rs.initialize()
    rows = np.zeros((steps + 100, rs.sim.ncols))
    rs.advance(20, rows, 10**9)  # compiled or loaded, caches warm
    rs.redistribute()  # and the code a redistribution loads (its evaluation at the restored state), on any count
    before = rs.redistributions
    comm.Barrier()
    t0 = time.perf_counter()
    rs.advance(20 + steps, rows, 10**9)
    comm.Barrier()
    wall = time.perf_counter() - t0
    held = comm.gather(int(len(rs.part.keep)), root=0)  # each rank's particles (owned and ghosts)
    if comm.Get_rank() == 0:
        Path(out).write_text(
            json.dumps(
                {
                    "scene": scene,
                    "ranks": comm.Get_size(),
                    "particles": int(system.n),
                    "held": held,
                    "steps": steps,
                    "redistributions": int(rs.redistributions - before),
                    "wall_s": wall,
                    "particle_steps_per_s": system.n * steps / wall,
                }
            )
        )


def _one(scene: str, ranks: int, tmp: Path, steps_factor: float = 1.0) -> dict:
    out = tmp / f"{scene}_{ranks}.json"
    mpiexec = Path(sys.executable).with_name("mpiexec")
    cmd = [
        str(mpiexec),
        "-n",
        str(ranks),
        sys.executable,
        "-m",
        "polydem_cli.benchmarks.ranks",
        "--rank-main",
        scene,
        str(out),
        str(steps_factor),
    ]
    subprocess.run(cmd, check=True, env=dict(os.environ, OMP_NUM_THREADS="1", NUMBA_NUM_THREADS="1"))
    return json.loads(out.read_text())


def column(scene: str, rounds: int, tmp: Path, steps_factor: float = 1.0) -> dict:
    """``make bench``'s ranks column of a scene: 1 and 2 ranks alternated ``rounds`` times (after one untimed run
    that compiles or loads the loop), medians and the median of the rounds' ratios; or why it does not run."""
    why = supported(scene)
    if why is not None:
        return {"unsupported": why}
    tmp.mkdir(parents=True, exist_ok=True)
    _one(scene, 2, tmp, steps_factor)
    recs = {1: [], 2: []}
    for _ in range(rounds):
        for ranks in (1, 2):
            recs[ranks].append(_one(scene, ranks, tmp, steps_factor))
    rate = {r: [x["particle_steps_per_s"] for x in recs[r]] for r in recs}
    ratios = [b / a for a, b in zip(rate[1], rate[2])]
    return {
        "particles": recs[1][0]["particles"],
        "held_per_rank_2": recs[2][0]["held"],
        "rate_1_rank": float(np.median(rate[1])),
        "rate_2_ranks": float(np.median(rate[2])),
        "ratio_per_round": ratios,
        "speedup_median": float(np.median(ratios)),
        "redistributions_2_ranks": [x["redistributions"] for x in recs[2]],
    }


def run(out: Path, rounds: int = 3, scenes=None) -> dict:
    """Every scene on 1 and 2 ranks, alternated, ``rounds`` times; medians, per-round ratios, weak scaling."""
    res = {"rounds": rounds, "scenes": {}}
    for scene in scenes or SCENES:
        res["scenes"][scene] = column(scene, rounds, out.parent / "bench_ranks_tmp")
        print(f"{scene}: {res['scenes'][scene]}", flush=True)
    one, two = WEAK
    if all("rate_1_rank" in res["scenes"].get(s, {}) for s in WEAK):
        r1 = res["scenes"][one]["rate_1_rank"]
        r2 = res["scenes"][two]["rate_2_ranks"]
        res["weak_scaling"] = {"one_rank": one, "two_ranks": two, "efficiency_per_rank": r2 / 2 / r1}
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps(res, indent=1))
    return res


def parts_bound(scene: str, out: Path, rounds: int = 10, steps_factor: float = 1.0, ranks: int = 2) -> dict:
    """The most ``ranks`` ranks could give if they never waited for each other: in one process, one thread, the whole
    scene and each rank's part (engine/distributed.py ``Part``: owned particles and ghosts, the ghosts held still)
    advanced in turn ``rounds`` times; per round the whole scene's step time over the slowest part's.  No MPI: what
    is left of a 2-rank step beyond the slowest part is synchronisation (the exchanges, the reductions, the ranks'
    arrival at them).  Writes JSON to ``out``."""
    import numba

    import polydem_cli

    polydem_cli.setup_jit_cache()
    numba.set_num_threads(1)
    from ..engine.distributed import Cut, PartSimulation
    from ..engine.simulation import Simulation
    from ..scenario.build import build_system
    from ..scenario.load import load_scenario

    path, ov, steps = _scene(scene)
    steps = max(1, int(steps * steps_factor))
    sc, _ = load_scenario(path, ov)
    system = build_system(sc, path)
    sims = {"whole": Simulation(system)}
    held = {}
    cut = Cut(system, ranks)
    for r in range(ranks):
        p = cut.part(r)
        sims[r] = PartSimulation(p.system)
        held[r] = [int(p.system.n), int(p.own.sum())]
    rows = {}
    for k, s in sims.items():
        s.initialize()
        rows[k] = np.zeros((steps * rounds + 200, s.ncols))
        s.advance(20, rows[k], 10**9)  # compiled or loaded, caches warm
    t = {k: [] for k in sims}
    for _ in range(rounds):
        for k, s in sims.items():
            t0 = time.perf_counter()
            s.advance(s.step + steps, rows[k], 10**9)
            t[k].append((time.perf_counter() - t0) / steps)
    whole = np.array(t["whole"])
    slowest = np.max([t[r] for r in range(ranks)], axis=0)
    res = {
        "scene": scene,
        "ranks": ranks,
        "steps_per_round": steps,
        "held_owned": held,
        "step_us": {str(k): float(np.median(v)) * 1e6 for k, v in t.items()},
        "bound_per_round": (whole / slowest).tolist(),
        "bound_median": float(np.median(whole / slowest)),
    }
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps(res, indent=1))
    print(
        f"{scene}: whole {res['step_us']['whole']:.1f} us a step, parts "
        + " / ".join(f"{res['step_us'][str(r)]:.1f}" for r in range(ranks))
        + f" us; at most {res['bound_median']:.2f}x on {ranks} ranks without waiting "
        f"(rounds {' '.join(f'{x:.2f}' for x in res['bound_per_round'])})"
    )
    return res


def main_job(out: Path) -> dict:
    """The main job (scenarios/concrete_tension.toml) run whole on one process with 1 and with 2 threads and on 2
    ranks: its macroscopic measures (E, ν, tensile strength) and failure-mode counts side by side, the ranks' relative
    differences from the 1-thread run beside the threads' (their scatter).  Writes JSON to ``out``."""
    runs = {
        "1_thread": ["--threads", "1", "--pin-threads"],
        "2_threads": ["--threads", "2", "--pin-threads"],
        "2_ranks": ["--ranks", "2", "--oversubscribe"],  # as measured, also where fewer cores (a line says so)
    }
    res = {"scenario": "scenarios/concrete_tension.toml", "runs": {}}
    for name, args in runs.items():
        h5 = out.parent / f"main_job_{name}.h5"
        cmd = [sys.executable, "-m", "polydem_cli", "run", res["scenario"], "-o", str(h5), "--overwrite", "-q", *args]
        t0 = time.perf_counter()
        subprocess.run(cmd, check=True)
        sm = json.loads(h5.with_suffix(".summary.json").read_text())
        res["runs"][name] = {
            "wall_s": time.perf_counter() - t0,
            "steps": sm["steps"],
            "E": sm["macro"]["E"],
            "nu": sm["macro"]["nu"],
            "f_t": sm["macro"]["peak_stress"],
            "failed": sm["bond_failure"]["failed"],
            "by_mode": sm["bond_failure"]["by_mode"],
        }
        print(f"{name}: {res['runs'][name]}", flush=True)
    one = res["runs"]["1_thread"]
    for name in ("2_threads", "2_ranks"):
        r = res["runs"][name]
        res[f"{name}_vs_1_thread"] = {k: r[k] / one[k] - 1 for k in ("E", "nu", "f_t")} | {
            "same_modes": r["by_mode"] == one["by_mode"],
            "same_steps": r["steps"] == one["steps"],
        }
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps(res, indent=1))
    return res


if __name__ == "__main__":
    if len(sys.argv) > 1 and sys.argv[1] == "--main-job":  # [OUT.json]
        main_job(Path(sys.argv[2] if len(sys.argv) > 2 else "outputs/ranks_main_job.json"))
    elif len(sys.argv) > 1 and sys.argv[1] == "--parts":  # SCENE OUT.json [ROUNDS [STEPS_FACTOR]]
        a = sys.argv[2:]
        parts_bound(a[0], Path(a[1]), int(a[2]) if len(a) > 2 else 10, float(a[3]) if len(a) > 3 else 1.0)
    elif len(sys.argv) > 1 and sys.argv[1] == "--rank-main":
        rank_main(sys.argv[2], sys.argv[3], float(sys.argv[4]) if len(sys.argv) > 4 else 1.0)
    else:  # [OUT.json [SCENE ...]]
        run(Path(sys.argv[1] if len(sys.argv) > 1 else "outputs/bench_ranks.json"), scenes=sys.argv[2:] or None)
