"""Solver families and the one run driver.

* :mod:`.driver` — the outer loop of every run (lock, reuse/resume/refuse, writer, signals, checkpoints,
  summary) and :func:`.driver.obtain`, the one place a run meets an existing result;
* :mod:`.protocol` — what a family supplies to the driver (:class:`.protocol.SolverFamily`);
* :mod:`.explicit` — the thesis's time integration of rigid polygons, disks and beams (Schneider 2012);
* :mod:`.quasistatic` — the lattice and its adaptive FEM coupling (Sorg 2014), one solve per step.

A family module provides ``FAMILY`` (its :class:`.protocol.SolverFamily` subclass, with ``KIND`` and ``FORMAT``:
the ``format`` attribute by which ``report`` and ``--resume`` recognise its results), ``check(resolved, file)``,
``summary_lines(summary)``, ``headline(out, summary)`` and ``table_row(summary)``; a family with its own
figures also ``report(result, out_dir, notes, save)``.  A new family adds its module to :data:`FAMILIES`, its
scenario tables to scenario/schema.py (``SCHEMAS``) and its kind to ``[solver] kind``'s choices.
"""

from __future__ import annotations

import importlib

#: solver kind → module
FAMILIES = {"explicit": "polydem_cli.solvers.explicit", "quasistatic": "polydem_cli.solvers.quasistatic"}
#: the ``format`` attribute of each family's results → its kind (the family's ``FORMAT``; kept here so that
#: recognising a result does not import every family; tests/test_quasistatic.py checks the two agree)
FORMATS = {"polydem-result": "explicit", "polydem-quasistatic": "quasistatic"}


def family_module(kind: str):
    """The module of the solver family ``kind``."""
    return importlib.import_module(FAMILIES[kind])


def family(kind: str):
    """The :class:`.protocol.SolverFamily` class of ``kind``."""
    return family_module(kind).FAMILY


def _format_of(path):
    import h5py

    try:
        with h5py.File(path, "r") as f:
            return f.attrs.get("format")
    except OSError:
        return None


def result_family(path):
    """The family class whose results have the ``format`` of the file at ``path`` (None: not a result)."""
    kind = FORMATS.get(_format_of(path))
    return None if kind is None else family(kind)


def family_of_result(path):
    """The module of the family that wrote a result file if it is not the explicit one, which the report and
    the export read themselves (None: explicit, or not a result of another family — the explicit reader then
    says what is wrong)."""
    cls = result_family(path)
    return None if cls is None or cls.KIND == "explicit" else family_module(cls.KIND)
