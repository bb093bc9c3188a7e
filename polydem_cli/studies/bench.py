"""``make bench``: particle-steps per second of the engine on a contact-dominated scene.

Times the compiled step loop only (after a warm-up that also compiles), as the
median of several repeats from the same initial state; writes JSON with the
machine, the commit and the thread count.  Never used as a test.
"""
from __future__ import annotations

import json
import os
import platform
import time
from pathlib import Path

import numpy as np


def machine() -> dict:
    cpu = platform.processor()
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                cpu = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    import numba

    return {"cpu": cpu, "cores": os.cpu_count(), "python": platform.python_version(),
            "numba": numba.__version__, "numpy": np.__version__, "platform": platform.platform(),
            "numba_threads": numba.get_num_threads()}


def time_scenario(path, steps=None, repeat=3, overrides=()) -> dict:
    from ..engine.simulation import Simulation
    from ..scenario.build import build_system
    from ..scenario.load import load_scenario

    sc, _ = load_scenario(path, overrides)
    system = build_system(sc, str(path))
    steps = steps or system.end_step
    every = max(steps, 1)
    rows = np.zeros((4, 12 + 6 * len(system.monitored)))
    sim = Simulation(system)
    t0 = time.perf_counter()
    sim.initialize()
    sim.advance(min(10, steps), rows, every)  # warm-up (compiles on a cold cache)
    warm = time.perf_counter() - t0
    times = []
    ncont = 0
    for _ in range(repeat):
        sim = Simulation(system)
        sim.initialize()
        t = time.perf_counter()
        sim.advance(steps, rows, every)
        times.append(time.perf_counter() - t)
        ncont = int(sim.stats[3])
    med = float(np.median(times))
    return {"scenario": str(path), "particles": int(system.n), "steps": int(steps), "repeats": repeat,
            "wall_s": times, "median_wall_s": med, "steps_per_s": steps / med,
            "particle_steps_per_s": system.n * steps / med, "contacts_at_end": ncont,
            "warmup_s": warm, "integrator": sc["time"]["integrator"]}


def run_bench(out: Path, scenarios, steps=None, repeat=3) -> dict:
    from ..engine.runner import code_version

    res = {"code_version": code_version(), "machine": machine(),
           "created": time.strftime("%Y-%m-%dT%H:%M:%S%z"), "runs": []}
    for s in scenarios:
        r = time_scenario(s, steps, repeat)
        res["runs"].append(r)
        print(f"{s}: {r['particles']} particles, {r['steps']} steps, median {r['median_wall_s']:.3f} s -> "
              f"{r['particle_steps_per_s']:.3g} particle-steps/s ({r['contacts_at_end']} contacts)")
    out = Path(out)
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps(res, indent=1))
    print(f"wrote {out}")
    return res
