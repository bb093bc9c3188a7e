"""``make bench``: particle-steps per second of the engine on the benchmark scenes below.

Every scene runs in its own process (so that its peak memory is its own), times
the compiled step loop only (after a warm-up that also compiles), as the median
of several repeats from the same initial state, with 1, 2 and ``auto`` threads (the default of
``polydem run``, engine/threads.py) timed interleaved repeat by repeat, on an otherwise idle
machine and beside one competing busy process (``competing_load``; the threads-under-load case).
Results go to JSON with the machine, the code version and the thread counts.  With MPI installed (the
``mpi`` extra: ``make bench`` installs it), each scene that runs decomposed is also timed on 1 and 2 MPI ranks, one
thread each, alternated (benchmarks/ranks.py ``column``).
Never used as a test.

Scenes (scenario file + overrides):

* ``bonded_30x30``, ``bonded_300x300`` — chapter-5 specimen, beams only;
* ``hex_base_friction`` — 2,016 pre-compressed hexagons with friction history and
  base friction (7 Gauss points per triangle, the thesis's rule); ``hex_base_friction_3gp`` the
  same with the 3-point rule (exact elastic stiffness, full-slip moment 0.43 % low; see
  docs/performance.md);
* ``concrete_40x40`` — beams and contact (concrete parameters); ``concrete_40x40_interface`` the panel with
  edge-interface bonds (3 elements per edge) instead of beams, ``concrete_40x40_principal`` those with the
  principal-stress crack criterion (docs/interface.md: the law's cost against the beams);
* ``dense_N1e3``, ``dense_N1e4``, ``dense_N1e5`` — pre-compressed hexagon packings for
  the scaling with N;
* ``lh_biaxial_1950`` — the 1,950 cohesive disks of Luding & Herrmann closing in under two servo walls
  (scenarios/lh/prepare_p100.toml, first steps: disk family, wall contacts, servo walls);
* ``lh_loading_1950`` — the same disks relaxed (dense, ~3,800 contacts) under biaxial loading
  (scenarios/lh/load_p100_kc1.toml; needs outputs/lh/prepare_p100.h5, skipped without it).
"""

from __future__ import annotations

import json
import os
import platform
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

from .scenes import BASE, HEX, NEEDS, SCENES  # noqa: F401 - the scenes, by name (also for benchmarks/ranks.py)


def machine() -> dict:
    """The machine a benchmark ran on: CPU model, cores, Python, Numba and NumPy versions, platform, Numba's thread
    limit and threading layer."""
    cpu = platform.processor()
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                cpu = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    import numba

    return {
        "cpu": cpu,
        "cores": os.cpu_count(),
        "python": platform.python_version(),
        "numba": numba.__version__,
        "numpy": np.__version__,
        "platform": platform.platform(),
        "numba_threads_max": numba.config.NUMBA_NUM_THREADS,
        "threading_layer": _layer(),
    }


def _layer():
    try:
        import numba

        return numba.threading_layer()
    except Exception:  # raised before any parallel region ran
        return "not initialised"


def time_system(system, steps, repeat=3):
    """Wall times of ``repeat`` runs of ``steps`` steps of a built system (compiled loop only,
    after a warm-up that compiles on a cold cache): (times, warm-up time, contacts at the end)."""
    times, warm, contacts, _ = time_interleaved(system, steps, repeat, (None,))
    return times[None], warm, contacts


def time_interleaved(system, steps, repeat, configs):
    """Like :func:`time_system` for several thread settings, interleaved: repeat 1 of every setting,
    then repeat 2, ... (this machine's speed drifts between minutes; blocks of one setting after the
    other would compare minutes, not settings).  A setting is None (numba's present count), a count N
    or ``"auto"`` (governed as ``polydem run --threads N|auto`` does, engine/threads.py: the steps run in
    ten chunks with the governor's update between them, after a first second in which it made its first
    choice), or ``"N pinned"`` (exactly N threads, ``--pin-threads``).
    Returns ({setting: times}, warm-up time, contacts at the end, {setting: thread counts used})."""
    import numba

    from ..engine.simulation import Simulation
    from ..engine.threads import governor_for as thread_governor
    from ..interactions.contact.family import POLYGON_CONTACT

    every = max(steps, 1)
    sim = Simulation(system)
    sim.initialize()
    rows = np.zeros((4, sim.ncols))
    t0 = time.perf_counter()
    sim.advance(min(3, steps), rows, every)
    warm = time.perf_counter() - t0
    govs = {c: thread_governor(system, c) for c in configs if c == "auto" or isinstance(c, int)}

    def one_pass(c):
        chunk = steps
        gov = govs.get(c)
        if gov is not None:
            numba.set_num_threads(gov.threads)
            chunk = max(1, steps // 10)
        elif isinstance(c, str):  # "N pinned"
            numba.set_num_threads(int(c.split()[0]))
        sim = Simulation(system)
        sim.initialize()
        t = time.perf_counter()
        while sim.step < steps:
            t_chunk, s0 = time.perf_counter(), sim.step
            sim.advance(min(steps, sim.step + chunk), rows, every)
            if gov is not None:
                gov.update(sim.step - s0, time.perf_counter() - t_chunk)
        return time.perf_counter() - t, sim

    for c, gov in govs.items():  # the governor's first choices (free cores; auto: its probe) before the timing
        t_settle = time.perf_counter()
        while time.perf_counter() - t_settle < 1.0 or (gov.probing and time.perf_counter() - t_settle < 20.0):
            one_pass(c)
    times = {c: [] for c in configs}
    used = {c: [] for c in configs}
    for _ in range(repeat):
        for c in configs:
            t, sim = one_pass(c)
            times[c].append(t)
            used[c].append(govs[c].threads if c in govs else numba.get_num_threads())
    return times, warm, POLYGON_CONTACT.contacts(sim.bundle(POLYGON_CONTACT.name)), used


def write_json(out, res) -> Path:
    """Write a study's result dict to ``out`` (parents created) and say so."""
    out = Path(out)
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps(res, indent=1))
    print(f"wrote {out}")
    return out


def time_scenario(path, steps=None, repeat=3, overrides=(), threads=None, configs=None) -> dict | list:
    """Median wall time of ``steps`` steps of a scenario (compiled loop only).  With ``configs`` (thread
    settings, see :func:`time_interleaved`) a list of such records, one per setting, timed interleaved."""
    import numba

    from ..interactions.base.family import BASE_FRICTION
    from ..interactions.bonds.family import BEAM_BONDS
    from ..scenario.build import build_system
    from ..scenario.load import load_scenario

    if threads:
        numba.set_num_threads(threads)
    sc, _ = load_scenario(path, overrides)
    t0 = time.perf_counter()
    system = build_system(sc, str(path))
    build_s = time.perf_counter() - t0
    steps = min(steps or system.end_step, system.end_step)
    times, warm, contacts, used = time_interleaved(system, steps, repeat, configs or (None,))
    recs = []
    for c, ts in times.items():
        med = float(np.median(ts))
        recs.append(
            {
                "scenario": str(path),
                "overrides": list(overrides),
                "particles": int(system.n),
                "bonds": int(BEAM_BONDS.network(system).n),
                "gauss_points": int(BASE_FRICTION.params(system).X.shape[0]),
                "steps": int(steps),
                "repeats": repeat,
                "threads": c if c is not None else numba.get_num_threads(),
                "threads_used": used[c],
                "wall_s": ts,
                "median_wall_s": med,
                "steps_per_s": steps / med,
                "particle_steps_per_s": system.n * steps / med,
                "contacts_at_end": contacts,
                "build_s": build_s,
                "warmup_s": warm,
            }
        )
    return recs if configs else recs[0]


def _scene_main(name, repeat, steps_factor):
    """Child process: time one scene with 1, 2 and ``auto`` threads as ``polydem run --threads`` governs them, and
    with 2 pinned threads (``--pin-threads``), idle and beside a busy process; print JSON."""
    import resource

    path, ov, steps = SCENES[name]
    out = {
        "scene": name,
        "runs": [],
        "omp_wait_policy": os.environ.get("OMP_WAIT_POLICY"),
        "gomp_spincount": os.environ.get("GOMP_SPINCOUNT"),
    }
    for load in ("none", "one busy process"):
        busy = None
        if load != "none":  # a competing process on one of the cores (a shared machine, a cluster node)
            busy = subprocess.Popen([sys.executable, "-c", "while True: pass"])
        try:
            recs = time_scenario(path, max(1, int(steps * steps_factor)), repeat, ov, configs=SETTINGS)
            for r in recs:
                r["competing_load"] = load
                out["runs"].append(r)
        finally:
            if busy is not None:
                busy.kill()
                busy.wait()
    out["peak_memory_MiB"] = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0
    out["threading_layer"] = _layer()
    print(json.dumps(out))


#: thread settings of every scene (time_interleaved)
SETTINGS = (1, 2, "auto", "2 pinned")


def _default(d, idle, load) -> dict:
    """What ``polydem run`` without options gets on the scene, against one thread: ``--ranks auto``
    (engine/threads.py :func:`auto_rank_count`, with the machine's cores free when idle and one fewer beside the
    busy process) on the ranks it would start — the ranks column's 2 / 1 ranks, one thread per rank, interleaved —
    or, on one process, ``--threads auto`` against 1 thread of the same interleaved timing."""
    from ..engine.threads import auto_rank_count, available_cores

    cores = available_cores()
    rk = d.get("ranks") or {}
    n = idle[0]["particles"]
    out = {}
    for key, free, rs in (("idle", cores, idle), ("busy", cores - 1, load)):
        ranks = 1 if "unsupported" in rk else auto_rank_count(n, free)
        if ranks == 2 and "speedup_median" in rk:
            out[f"{key}_setting"] = "2 ranks x 1 thread"
            out[f"{key}_over_1_thread"] = rk["speedup_median"]
        elif ranks > 1:  # the ranks column times 1 and 2 ranks only (or was left out: --no-ranks)
            out[f"{key}_setting"] = f"{ranks} ranks x 1 thread (not measured here)"
            out[f"{key}_over_1_thread"] = float("nan")
        else:
            auto = rs[SETTINGS.index("auto")]
            out[f"{key}_setting"] = f"1 process, --threads auto (used {auto['threads_used']})"
            out[f"{key}_over_1_thread"] = auto["particle_steps_per_s"] / rs[0]["particle_steps_per_s"]
    return out


def run_bench(out: Path, scenes=None, repeat=3, steps_factor=1.0, ranks=True) -> dict:
    """``make bench``: time each scene in its own process (:data:`SCENES`, default all), print one line per scene and
    write the results with the machine and the code version to ``out`` (JSON); returns them.  ``ranks``: also time
    each scene decomposed over 1 and 2 MPI ranks where it runs so (the ``ranks`` entry of a scene)."""
    from ..io.provenance import code_version

    scenes = scenes or list(SCENES)
    res = {
        "code_version": code_version(),
        "machine": machine(),
        "created": time.strftime("%Y-%m-%dT%H:%M:%S%z"),
        "repeat": repeat,
        "scenes": {},
    }
    for name in scenes:
        if name in NEEDS and not Path(NEEDS[name]).exists():
            print(f"{name}: skipped, it starts from {NEEDS[name]} (make {NEEDS[name]})")
            res["scenes"][name] = {"skipped": f"needs {NEEDS[name]}"}
            continue
        r = subprocess.run(
            [sys.executable, "-m", "polydem_cli.benchmarks.bench", name, str(repeat), str(steps_factor)],
            capture_output=True,
            text=True,
        )
        if r.returncode != 0:
            print(f"{name}: failed\n{r.stderr[-2000:]}")
            res["scenes"][name] = {"error": r.stderr[-2000:]}
            continue
        d = json.loads(r.stdout.strip().splitlines()[-1])
        res["scenes"][name] = d
        k = len(SETTINGS)
        idle, load = d["runs"][:k], d["runs"][k:]

        def figs(rs):
            return " / ".join(f"{r['particle_steps_per_s']:.3g}" for r in rs)

        d["under_load"] = {str(c): r["particle_steps_per_s"] for c, r in zip(SETTINGS, load)}
        d["under_load"]["2_over_1"] = load[1]["particle_steps_per_s"] / load[0]["particle_steps_per_s"]
        print(
            f"{name:18s} N={idle[0]['particles']:>6d}  {' / '.join(map(str, SETTINGS))} threads: {figs(idle)} "
            f"particle-steps/s, peak {d['peak_memory_MiB']:.0f} MiB;  beside a busy process: {figs(load)} "
            f"(2 used {load[1]['threads_used']}; 2 / 1 threads under load {d['under_load']['2_over_1']:.3f})"
        )
        if ranks:  # the scene decomposed over 1 and 2 MPI ranks (benchmarks/ranks.py), one thread per rank
            from .ranks import column

            d["ranks"] = rk = column(name, repeat, out.parent / "bench_ranks_tmp", steps_factor)
            print(
                f"{'':18s} ranks: not run ({rk['unsupported']})"
                if "unsupported" in rk
                else f"{'':18s} 1 / 2 ranks: {rk['rate_1_rank']:.3g} / {rk['rate_2_ranks']:.3g} particle-steps/s "
                f"(2 / 1 ranks {rk['speedup_median']:.2f}, rounds {' '.join(f'{x:.2f}' for x in rk['ratio_per_round'])})"
            )
        d["default"] = _default(d, idle, load)
        dd = d["default"]

        def ratio(v):  # NaN: the default's ranks were not timed (--no-ranks, or more than 2)
            return "not measured" if v != v else f"{v:.2f}x one thread"

        print(
            f"{'':18s} default (polydem run: {dd['idle_setting']}): idle {ratio(dd['idle_over_1_thread'])}, "
            f"beside a busy process {ratio(dd['busy_over_1_thread'])} ({dd['busy_setting']})"
        )
    dense = [
        (res["scenes"][k]["runs"][1]["particles"], res["scenes"][k]["runs"][1]["particle_steps_per_s"])
        for k in ("dense_N1e3", "dense_N1e4", "dense_N1e5")
        if k in res["scenes"] and "runs" in res["scenes"][k]
    ]
    if len(dense) >= 2:
        n, p = np.array(dense, float).T
        res["scaling"] = {
            "N": n.tolist(),
            "particle_steps_per_s_2_threads": p.tolist(),
            "exponent": float(np.polyfit(np.log(n), np.log(p), 1)[0]),
            "loss_first_to_last": float(1 - p[-1] / p[0]),
        }
        print(
            f"scaling: particle-steps/s ~ N^{res['scaling']['exponent']:.3f}, "
            f"loss from N={int(n[0])} to N={int(n[-1])}: {100 * res['scaling']['loss_first_to_last']:.0f} %"
        )
    write_json(out, res)
    return res


if __name__ == "__main__":
    from polydem_cli import setup_jit_cache

    setup_jit_cache()
    _scene_main(sys.argv[1], int(sys.argv[2]), float(sys.argv[3]))
