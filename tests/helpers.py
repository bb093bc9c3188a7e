"""Build and run small scenes in-process (no files)."""

import tomllib

import numpy as np

from polydem_cli.engine.simulation import Simulation
from polydem_cli.scenario.build import build_system
from polydem_cli.scenario.load import validate
from polydem_cli.solvers.explicit_history import RowMaker, history_columns


def system_from_toml(text, overrides=()):
    sc = validate(tomllib.loads(text), "<test>", overrides)
    return build_system(sc, "<test>")


def run(system, steps=None, every=1):
    """Run to ``steps`` (default: the end); return (sim, dict column -> array incl. the t0 row)."""
    sim = Simulation(system)
    sim.initialize()
    steps = system.end_step if steps is None else steps
    rows = np.zeros((steps // every + 2, sim.ncols))
    rows[0] = sim.current_row()
    k = 1
    while sim.step < steps:
        k += sim.advance(steps, rows[k:], every)
    columns = history_columns(system)
    table = RowMaker(system, columns)(rows[:k])
    return sim, {c[0]: table[:, j] for j, c in enumerate(columns)}


def particle(name, poly_type="regular_polygon", material="m", thickness=1.0, **kw):
    lines = [f'[[particles]]\nname = "{name}"\nmaterial = "{material}"\nthickness = {thickness}\ntype = "{poly_type}"']
    for k, v in kw.items():
        lines.append(f"{k} = {toml_value(v)}")
    return "\n".join(lines) + "\n"


def toml_value(v):
    if isinstance(v, str):
        return f'"{v}"'
    if isinstance(v, (list, tuple)):
        return "[" + ", ".join(toml_value(e) for e in v) + "]"
    if isinstance(v, bool):
        return "true" if v else "false"
    return repr(float(v)) if isinstance(v, float) else str(v)


def run_unstable_pile(out, *sets):
    """``polydem run`` of the demo pile at dt 27x its critical estimate (explicitly allowed): a run that
    must end as unstable (exit 1).  Returns the CompletedProcess."""
    import subprocess

    from conftest import SCEN, polydem_cmd

    args = ["run", str(SCEN / "demo_hex_pile.toml"), "-o", str(out), "-q", "--set", "time.dt=5e-4"]
    args += ["--set", "time.allow_large_dt=true", "--set", "time.end_displacement=0.3"]
    for a in sets:
        args += ["--set", a]
    return subprocess.run(polydem_cmd() + args, capture_output=True, text=True)


def run_scenario(path, out, overrides=(), **kw):
    """Run the scenario file ``path`` (with ``overrides``) into the result ``out`` in-process; its summary.
    ``kw``: further arguments of solvers.explicit.run (stream, quiet, ...; quiet by default)."""
    from polydem_cli.scenario.load import load_scenario
    from polydem_cli.solvers.explicit import run as run_result

    sc, text = load_scenario(path, list(overrides))
    kw.setdefault("quiet", True)
    return run_result(build_system(sc, str(path)), out=out, scenario_file=str(path), scenario_text=text, **kw)
