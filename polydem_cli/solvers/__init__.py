"""Solver families: what ``polydem run``, ``check``, ``report`` and ``--continue`` do with a scenario of each
``[solver] kind``.

A solver family is a module with

* ``FORMAT`` — the ``format`` attribute of its HDF5 results (how ``report`` and ``--resume`` recognise them);
* ``run(resolved, *, out, scenario_file, scenario_text, overrides, resume, quiet, stream, ...)`` → summary
  dict; holds the result's write lock, writes checkpoints, stops cleanly on SIGINT/SIGTERM
  (``engine.runner.Interrupted``), refuses to resume a finished run (``engine.runner.AlreadyFinished``);
* ``check(resolved, file)`` → lines describing the run (``polydem check``);
* ``existing_state(out, resolved)`` → "finished", "resumable" or "other" (``run --continue``);
* ``summary_lines(summary)`` → the lines printed after a run;
* ``report(result, out_dir, notes, save)`` → the figure files of a result (``save(fig, path, **kw)``: the report
  layer's saver, extra formats and plotted-data CSV included).

``explicit`` (the thesis's time integration) has its driver in engine/runner.py and is called directly by the
CLI; ``quasistatic`` (the lattice and its adaptive FEM coupling, Sorg 2014) lives in :mod:`.quasistatic`.
A new family adds its module here, its scenario tables to scenario/schema.py (``SCHEMAS``) and its kind to
``[solver] kind``'s choices.
"""

from __future__ import annotations

import importlib

#: solver kind → module (None: the explicit driver, engine/runner.py)
FAMILIES = {"explicit": None, "quasistatic": "polydem_cli.solvers.quasistatic"}


def family(kind: str):
    """The module of a solver family (None for explicit)."""
    mod = FAMILIES[kind]
    return importlib.import_module(mod) if mod else None


def family_of_result(path):
    """The module of the family that wrote a result file (None: explicit, or not a result of another
    family — the explicit reader then says what is wrong)."""
    import h5py

    try:
        with h5py.File(path, "r") as f:
            fmt = f.attrs.get("format")
    except OSError:
        return None
    for mod in FAMILIES.values():
        if mod:
            m = importlib.import_module(mod)
            if fmt == m.FORMAT:
                return m
    return None
