"""polydem from Python: a scenario, a run of it and its result as objects a script or a notebook drives, with the
command line's guarantees (one writer, checkpoints, resume, the same refusals).

>>> from polydem_cli import Scenario, Result
>>> sc = Scenario("scenarios/ch7/smoke_concrete_tension.toml")
>>> sc["bonds.kappa_0"] = 1.2e-4                       # validated at once, as --set would be
>>> res = sc.run("outputs/smoke.h5", overwrite=True)   # in this process; ranks=2 starts MPI ranks
>>> res.macro["E_GPa"], res.history[["eps22", "sigma22"]]

Every refusal is an exception of the :class:`PolydemError` family with the command line's message:
:class:`ScenarioError` (bad file, key or value), :class:`OutputError` (an output place that cannot be written),
:class:`ResultError` (a result a run will not touch, or not a result), :class:`EngineError` (a run that went
unstable), :class:`CallbackError` (a callback that raised).
"""

from __future__ import annotations

import copy
import json
import sys
from pathlib import Path

from . import setup_jit_cache


def _configure_cache():
    """Point Numba at polydem's cache before this module imports any compiled code, as the ``polydem`` command
    does: a compiled function's cache place is fixed when its module is imported, and Numba's own (beside the
    sources, keyed per file) keeps a caller's machine code when a function it calls changes (numba issue #6845;
    seen here: a run of the API segfaulted in the loop's initial state).  Importing ``polydem_cli`` itself changes
    nothing; the first use of its API (this module) sets the cache up."""
    import warnings

    compiled = [
        m for m in sys.modules if m.startswith("polydem_cli.") and m.split(".")[1] in ("engine", "interactions")
    ]
    if compiled and not __import__("os").environ.get("NUMBA_CACHE_DIR"):
        warnings.warn(
            f"polydem's compiled modules ({compiled[0]}, ...) were imported before its API: they cache beside the "
            "sources, where a changed callee is not noticed; call polydem_cli.setup_jit_cache() first",
            stacklevel=3,
        )
    setup_jit_cache()


_configure_cache()

from .errors import (  # noqa: E402 - after the cache's set-up
    NOVALUE,
    CallbackError,
    EngineError,
    OutputError,
    PolydemError,
    ScenarioError,
    toml_value,
)
from .io.hdf5 import ResultError  # noqa: E402
from .solvers.protocol import Every, RunState  # noqa: E402

__all__ = [
    "Scenario",
    "Result",
    "lab",
    "validate",
    "sweep",
    "calibrate",
    "Every",
    "RunState",
    "PolydemError",
    "ScenarioError",
    "OutputError",
    "ResultError",
    "EngineError",
    "CallbackError",
]


class Scenario:
    """A scenario: from a TOML file (``Scenario("scenarios/x.toml")``, its ``extends`` followed) or a dict of the
    same tables (``Scenario({...})``), changed by key paths as ``polydem run --set`` takes them (``sc["time.dt"] =
    2e-7``, ``sc.set("particles.0.nx", 12)``; list entries by their index).  Every change is validated at once
    against the schema; a bad one raises :class:`ScenarioError` (file, key, value and reason, the command line's
    message) and leaves the scenario as it was."""

    def __init__(self, source, overrides=()):
        from .scenario.load import read_toml

        if isinstance(source, dict):
            import tomli_w

            self.file, self._data = "<python>", copy.deepcopy(source)
            try:
                self.text = tomli_w.dumps(self._data)
            except (TypeError, ValueError) as e:
                raise ScenarioError(self.file, "", NOVALUE, f"not a table of TOML values: {e}") from None
        else:
            self.file = str(source)
            self._data, self.text = read_toml(Path(source))
        ovs = [self._override(o) for o in overrides]
        self._resolved = self._validate(ovs)
        self._overrides = ovs

    @staticmethod
    def _override(o) -> str:
        if isinstance(o, str):
            return o
        key, value = o
        return f"{key}={toml_value(value)}"

    def _validate(self, overrides):
        from .scenario.load import validate

        return validate(self._data, self.file, overrides)

    @classmethod
    def from_file(cls, path, overrides=()) -> Scenario:
        """The scenario of a TOML file (with ``--set``-style overrides, ``"key=value"`` strings or (key, value))."""
        return cls(Path(path), overrides)

    @classmethod
    def from_dict(cls, tables: dict) -> Scenario:
        """A scenario from a dict of its tables (as a TOML file has them)."""
        return cls(dict(tables))

    def set(self, key: str, value) -> Scenario:
        """Change the value at ``key`` (a ``--set`` key path: ``time.dt``, ``particles.0.nx``); validated at once
        (:class:`ScenarioError` and no change on bad input); returns the scenario."""
        o = self._override((key, value))
        resolved = self._validate(self._overrides + [o])
        self._overrides.append(o)
        self._resolved = resolved
        return self

    def __setitem__(self, key, value):
        self.set(key, value)

    def __getitem__(self, key):
        """The validated value at ``key`` (defaults filled in)."""
        cur = self._resolved
        for p in key.split("."):
            try:
                cur = cur[int(p)] if isinstance(cur, list) else cur[p]
            except (KeyError, IndexError, ValueError, TypeError):
                raise KeyError(key) from None
        return copy.deepcopy(cur)

    @property
    def resolved(self) -> dict:
        """The validated scenario with every default (what a result stores as ``resolved``)."""
        return copy.deepcopy(self._resolved)

    @property
    def overrides(self) -> list:
        """The changes made, as ``--set`` arguments (``key=value``)."""
        return list(self._overrides)

    def __repr__(self):
        return f"Scenario({self.file!r}, {len(self._overrides)} change(s): {self._resolved['scenario']['title']!r})"

    def check(self) -> list:
        """Build the specimen and check the initial state, as ``polydem check`` does; its lines."""
        from .solvers import family_module

        return family_module(self._resolved["solver"]["kind"]).check(self._resolved, self.file)

    def run(
        self,
        out=None,
        *,
        overwrite=False,
        resume=False,
        threads="auto",
        pin_threads=False,
        ranks=None,
        oversubscribe=False,
        progress=True,
        callbacks=(),
    ) -> Result:
        """Run the scenario into the result file ``out`` (default ``outputs/<file stem>.h5``) and return it as a
        :class:`Result`.  As ``polydem run``: an existing result is refused (:class:`ResultError`) unless
        ``overwrite`` replaces it or ``resume`` continues it (a finished run is then reused as it is); the output
        place is checked first (:class:`OutputError`); a run that goes unstable raises :class:`EngineError`.
        ``threads``, ``pin_threads`` as the command's options; ``ranks``: decompose over that many MPI ranks (a
        separate ``polydem run --ranks`` process; no callbacks); ``progress``: a line that updates in place, in a
        notebook too; ``callbacks``: :class:`Every` triggers."""
        from .io.places import check_file

        out = Path(out) if out is not None else Path("outputs") / (Path(self.file).stem.strip("<>") + ".h5")
        check_file(out, "the result")
        if ranks is not None and (isinstance(ranks, bool) or not isinstance(ranks, int) or ranks < 1):
            raise PolydemError(f"ranks = {ranks!r}: a whole number >= 1")
        if ranks is not None and ranks > 1:
            if callbacks:
                raise PolydemError("callbacks run in this process: not with ranks (run on ranks without them)")
            return self._run_ranks(out, overwrite, resume, threads, ranks, oversubscribe, progress)
        return self._run_here(out, overwrite, resume, threads, pin_threads, progress, tuple(callbacks))

    def _run_here(self, out, overwrite, resume, threads, pin_threads, progress, callbacks) -> Result:
        from .solvers import driver
        from .solvers.protocol import RunOptions, Source

        policy = driver.OVERWRITE if overwrite else driver.CONTINUE if resume else driver.NEW
        stream = _ProgressStream() if progress else None
        opts = RunOptions(
            quiet=not progress, stream=stream, threads=threads, pin_threads=pin_threads, callbacks=callbacks
        )
        source = Source(self.file, self.text, tuple(self._overrides))
        try:
            driver.obtain(self._resolved, out, source=source, policy=policy, opts=opts)
        except OSError as e:
            from .io.places import write_error

            raise write_error(e, out) from None
        finally:
            if stream is not None:
                stream.close()
        return Result(out)

    def _run_ranks(self, out, overwrite, resume, threads, ranks, oversubscribe, progress) -> Result:
        """``polydem run --ranks`` in a process of its own (MPI ranks cannot start inside this one): what this
        process can judge is refused here first with the command's own exceptions (the result's policy); the rest
        comes back by exit code — 2: a refusal of the decomposition (DecompositionError), 1: a run that failed
        (EngineError) — with the command's last error line as the message; its progress lines are shown here."""
        import subprocess
        import tempfile
        import threading

        from .errors import DecompositionError
        from .solvers import driver

        policy = driver.OVERWRITE if overwrite else driver.CONTINUE if resume else driver.NEW
        ex = driver.existing(out, self._resolved)
        if getattr(policy, ex.state, "run") == "refuse":
            raise driver.Refused(out, ex, policy)
        stream = _ProgressStream() if progress else None
        with tempfile.TemporaryDirectory() as d:
            scen = Path(self.file)
            if self.file == "<python>":
                scen = Path(d) / "scenario.toml"
                scen.write_text(self.text)
            cmd = [sys.executable, "-m", "polydem_cli", "run", str(scen), "-o", str(out), "--ranks", str(ranks)]
            cmd += [a for o in self._overrides for a in ("--set", o)] + ["--threads", str(threads)]
            cmd += (["--overwrite"] if overwrite else []) + (["--continue"] if resume else [])
            cmd += (["--oversubscribe"] if oversubscribe else []) + ([] if progress else ["-q"])
            p = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True, bufsize=1)
            errors = []

            def follow():
                for line in p.stderr:
                    if line.startswith("error:"):
                        errors.append(line.strip().removeprefix("error: "))
                    elif stream is not None:
                        stream.write(line)

            reader = threading.Thread(target=follow, daemon=True)
            reader.start()
            rc = p.wait()
            reader.join()
        if stream is not None:
            stream.close()
        if rc != 0:
            text = errors[-1] if errors else f"polydem run --ranks {ranks} ended with exit status {rc}"
            if rc == 2:
                raise DecompositionError(text)
            if rc in (130, 143):
                raise driver.Interrupted(rc - 128)
            raise EngineError(text)
        return Result(out)


class _ProgressStream:
    """The run's progress line where it is read: in a Jupyter notebook one line updated in place (IPython's display
    handle), elsewhere the terminal's standard error."""

    def __init__(self):
        self.handle = None
        self.notebook = "ipykernel" in sys.modules
        if self.notebook:
            from IPython.display import display

            self.handle = display({"text/plain": ""}, raw=True, display_id=True)

    def isatty(self):
        return self.notebook or sys.stderr.isatty()

    def write(self, text):
        if not self.notebook:
            return sys.stderr.write(text)
        line = text.replace("\r", "").strip()
        if text.startswith("\r") and line:
            self.handle.update({"text/plain": line}, raw=True)
        elif line:
            sys.stderr.write(text if text.endswith("\n") else text + "\n")
        return len(text)

    def flush(self):
        if not self.notebook:
            sys.stderr.flush()

    def close(self):
        if not self.notebook and sys.stderr.isatty():
            sys.stderr.write("\n")


class Result:
    """A result file (explicit or quasi-static run) read back: its summary, history as a pandas DataFrame with the
    units, frames, particles, bonds and their damage, and the report's figures as matplotlib Figures (written only
    by :meth:`report`).  Opening a file that is not a polydem result raises :class:`ResultError`."""

    def __init__(self, path):
        from .io.hdf5 import open_result
        from .solvers import result_family

        self.path = Path(path)
        if not self.path.exists():
            raise ResultError(f"{self.path}: no such result file")
        cls = result_family(self.path)
        if cls is None:
            raise ResultError(f"{self.path}: not a polydem result file")
        self.kind, self._fmt = cls.KIND, cls.FORMAT
        with open_result(self.path, fmt=self._fmt) as f:
            self.attrs = {k: f.attrs[k] for k in f.attrs}
            table = f["history/table"]
            self._columns = json.loads(table.attrs["columns"])
            self._units = json.loads(table.attrs["units"]) if "units" in table.attrs else None
            self._desc = json.loads(table.attrs["descriptions"]) if "descriptions" in table.attrs else None

    def __repr__(self):
        return f"Result({str(self.path)!r}: {self.status}, {self.attrs.get('title', '')!r})"

    @property
    def status(self) -> str:
        """'finished', 'running', 'failed' or 'incomplete' (interrupted: resume it with Scenario.run(resume=True)
        or ``polydem run --resume``)."""
        s = self.summary.get("status") if self.summary else None
        return s or str(self.attrs.get("status", "?"))

    @property
    def summary(self) -> dict:
        """The run's summary (what ``<result>.summary.json`` holds)."""
        return json.loads(self.attrs["summary"]) if "summary" in self.attrs else {}

    @property
    def scenario(self) -> dict:
        """The validated scenario the run ran (every default filled in)."""
        return json.loads(self.attrs["resolved"])

    @property
    def macro(self) -> dict:
        """The macroscopic measures of an explicit run with ``[macro]`` (E, nu, the strength in MPa, …), else {}."""
        return self.summary.get("macro") or {}

    @property
    def units(self) -> dict:
        """{column: unit} of the history table."""
        cols = [c[0] if isinstance(c, list) else c for c in self._columns]
        if self._units is not None:
            return dict(zip(cols, self._units))
        return {c[0]: c[1] for c in self._columns if isinstance(c, list)}

    @property
    def history(self):
        """The history table as a pandas DataFrame, a column per quantity (``time``, ``step``, energies, each
        family's columns, each set's displacement and reaction, the macroscopic measures); ``df.attrs["units"]``
        and ``df.attrs["descriptions"]`` by column."""
        import pandas as pd

        from .io.hdf5 import open_result

        with open_result(self.path, fmt=self._fmt) as f:
            rows = f["history/table"][...]
        cols = [c[0] if isinstance(c, list) else c for c in self._columns]
        df = pd.DataFrame(rows, columns=cols)
        df.attrs["units"] = self.units
        if self._desc is not None:
            df.attrs["descriptions"] = dict(zip(cols, self._desc))
        elif self._columns and isinstance(self._columns[0], list):
            df.attrs["descriptions"] = {c[0]: c[2] for c in self._columns}
        return df

    @property
    def frames(self) -> dict:
        """The frames of an explicit run: ``step``, ``time`` (F,), ``x`` and ``v`` (F, n, 3: x1, x2, φ and their
        rates), with beams ``bond_d`` (F, nb: the damage), ``bond_kappa``, ``bond_strain``."""
        from .io.hdf5 import open_result

        with open_result(self.path, fmt=self._fmt) as f:
            if "frames" not in f:
                return {}
            return {k: f["frames"][k][...] for k in f["frames"]}

    @property
    def particles(self):
        """The particles as a DataFrame: group, mass, inertia, area, radius, thickness and x1, x2, φ at t0."""
        import pandas as pd

        from .io.hdf5 import read_static

        st = read_static(self.path)
        names = st["group_names"]
        return pd.DataFrame(
            {
                "group": [names[g] for g in st["group"]],
                "mass": st["mass"],
                "inertia": st["inertia"],
                "area": st["area"],
                "radius": st["radius"],
                "thickness": st["thickness"],
                "x1": st["x0"][:, 0],
                "x2": st["x0"][:, 1],
                "phi": st["x0"][:, 2],
            }
        )

    @property
    def bonds(self):
        """The beams as a DataFrame (None without beams): the pair, length L, height H, thickness T, E, nu, kappa_0,
        kappa_m, the step each failed at (−1: not failed) and the damage d in the last frame."""
        import pandas as pd

        from .io.hdf5 import read_bonds

        b = read_bonds(self.path)
        if b is None:
            return None
        cols = {"i": b["pairs"][:, 0], "j": b["pairs"][:, 1]}
        for k in ("L", "H", "T", "E", "nu", "kappa_0", "kappa_m", "fail_step"):
            if k in b:
                cols[k] = b[k]
        if len(b["frame_d"]):
            cols["damage"] = b["frame_d"][-1]
        return pd.DataFrame(cols)

    def figures(self, **kw) -> dict:
        """The figures ``polydem report`` draws for this result, as {name: matplotlib Figure}; nothing is written.
        ``kw``: ``times``, ``states`` as for :meth:`report`."""
        from .report.common import capture_figures

        with capture_figures() as kept:
            self._draw(None, **kw)
        return {stem.removeprefix(self.path.stem + "_"): fig for stem, fig in kept}

    def report(self, out_dir=None, formats=("png",), **kw) -> list:
        """Write the report's figures (``polydem report``) into ``out_dir`` (default beside the result); the
        paths."""
        return self._draw(out_dir, formats=formats, **kw)

    def _draw(self, out_dir, formats=("png",), times=None, states=None):
        from .report.make import family_report, make_report
        from .solvers import family_of_result

        fam = family_of_result(self.path)
        if fam is not None:  # another solver family draws its own figures
            return family_report(fam, self.path, out_dir, formats=formats)
        return make_report(self.path, out_dir, times=times, states=states, formats=formats)


# ---------------------------------------------------------------- the workflows, with tables as DataFrames


def lab(out, *, smoke=False, tests=None, pressures=None, material=None, overrides=(), scenarios="."):
    """The virtual material laboratory (``polydem study lab``) into the folder ``out``: a DataFrame of its table
    (quantity, value, reference); ``df.attrs["tests"]`` holds each test's numbers.  ``material``: a scenario file
    whose [bonds] every test takes; finished runs in ``out`` are reused."""
    import pandas as pd

    from .io.places import check_dir
    from .workflows.lab import PRESSURES, TESTS, LabError, check_pressures, material_overrides, run_study

    tests = tuple(TESTS if tests is None else tests)
    bad = [t for t in tests if t not in TESTS]
    if bad:
        raise LabError(f"unknown test {bad[0]!r}; the tests are {', '.join(TESTS)}")
    if pressures is not None:
        check_pressures(pressures)
    ov = (material_overrides(material) if material is not None else []) + list(overrides)
    check_dir(out, "the study")
    res = run_study(Path(out), Path(scenarios), tests, smoke=smoke, pressures=pressures or PRESSURES, overrides=ov)
    df = pd.DataFrame(res["table"], columns=["quantity", "value", "reference"])
    df.attrs["tests"] = {t: {k: v for k, v in n.items() if not hasattr(v, "shape")} for t, n in res["tests"].items()}
    return df


def validate(out, *, smoke=False, tests=None, material=None, overrides=(), biaxial=None, sizes=None, scenarios=".",
             jobs=1, threads="1", ranks=None, progress=False):  # fmt: skip
    """The validation suite (``polydem study validate``) into the folder ``out``: a DataFrame of its table
    (experiment, quantity, polydem, experiment, difference in %, source); ``df.attrs["results"]`` holds each
    experiment's numbers.  Bad choices raise before anything is written."""
    import pandas as pd

    from .io.places import check_dir
    from .reproductions.validate import EXPERIMENTS_ORDER, plan, run_study
    from .reproductions.validate import scenarios as build
    from .workflows.lab import material_overrides

    ov = (material_overrides(material) if material is not None else []) + list(overrides)
    chosen = tuple(tests or EXPERIMENTS_ORDER)
    build(plan(smoke, chosen, biaxial, sizes), Path(scenarios), ov)
    check_dir(out, "the study")
    res = run_study(Path(out), Path(scenarios), chosen, smoke, ov, biaxial, sizes, threads, jobs, ranks, not progress)
    cols = ["experiment", "quantity", "polydem", "reference", "difference_pct", "source"]
    df = pd.DataFrame(res["table"], columns=cols)
    df.attrs["results"] = res["results"]
    return df


def sweep(scenario, sets: dict, out, *, workers=None):
    """Every combination of the values of ``sets`` ({key path: [values]}) of a scenario file, run in parallel on
    Dask into the folder ``out`` (``polydem sweep``): a DataFrame with a row per variant (its values, E, nu, the
    peak, the wall time, the failure if any)."""
    import pandas as pd

    from .io.places import check_dir
    from .workflows.sweep import sweep as run_sweep

    for key, values in sets.items():  # every value validated before anything runs
        for v in values:
            Scenario(Path(scenario), [(key, v)])
    specs = [f"{k}=" + ",".join(toml_value(v) for v in vals) for k, vals in sets.items()]
    check_dir(out, "the sweep")
    res = run_sweep(Path(scenario), specs, Path(out), workers=workers)
    rows = []
    for r in res["variants"]:
        vals = dict(o.split("=", 1) for o in r["overrides"])
        rows.append(
            {"variant": r["variant"], **vals, **{k: v for k, v in r.items() if k not in ("variant", "overrides")}}
        )
    return pd.DataFrame(rows)


def calibrate(scenario, targets: dict, *, tests=None, overrides=(), seeds=None, out=None, vary=None, rel_tol=0.005,
              log=print):  # fmt: skip
    """Fit the beams of a bonded scenario file to macroscopic targets (``polydem calibrate``): ``targets`` as the
    command's --target values ({"E": "33.6GPa", "nu": 0.2, "f_t": "2.9MPa"}), ``tests`` {key: scenario file} where a
    target is measured on its own test.  Writes the calibrated scenario ``out`` (default
    ``outputs/<stem>_calibrated.toml``) and returns a DataFrame with a row per specimen seed (the fitted parameters
    and the values reached)."""
    import pandas as pd

    from .io.places import check_file
    from .workflows.calibrate import calibrate as run_calibration
    from .workflows.calibrate import parse_target, write_calibrated

    scenario = Path(scenario)
    tg = {}
    for k, v in targets.items():
        try:
            key, value = parse_target(f"{k}={v}")
        except ValueError as e:
            raise PolydemError(str(e)) from None
        tg[key] = value
    out = Path(out) if out is not None else Path("outputs") / (scenario.stem + "_calibrated.toml")
    check_file(out, "the calibrated scenario", example=scenario.stem + "_calibrated.toml")
    res = run_calibration(
        scenario, tg, list(overrides), seeds, workdir=out.with_suffix(".runs"), rel_tol=rel_tol, log=log, vary=vary,
        tests={k: Path(v) for k, v in (tests or {}).items()},
    )  # fmt: skip
    write_calibrated(scenario, res, out)
    out.with_suffix(".json").write_text(json.dumps(res, indent=1, default=float))
    df = pd.DataFrame([{k: v for k, v in r.items() if not isinstance(v, (list, dict))} for r in res["seeds"]])
    df.attrs["calibrated"] = str(out)
    return df


# ---------------------------------------------------------------- the reference page


def reference() -> str:
    """docs/api.md: every public name of ``polydem_cli`` with its signature and docstring (``python -m
    polydem_cli.api --out docs/api.md``; a test checks that the page is current)."""
    import inspect

    import polydem_cli

    lines = [
        "# polydem's Python API",
        "",
        "Generated from the docstrings (`python -m polydem_cli.api --out docs/api.md`; `make docs`). A tour: "
        "[api_tour.ipynb](api_tour.ipynb). Everything below is importable from `polydem_cli`; nothing else is "
        "public.",
        "",
        inspect.cleandoc(__doc__ or ""),
        "",
    ]

    def sig(obj):
        try:
            return str(inspect.signature(obj))
        except (TypeError, ValueError):
            return ""

    for name in polydem_cli.__all__:
        obj = getattr(polydem_cli, name)
        if name == "__version__":
            continue
        kind = "class" if inspect.isclass(obj) else "function"
        lines += [f"## `{name}{sig(obj) if kind == 'function' or not issubclass(obj, BaseException) else ''}`", ""]
        if inspect.isclass(obj) and issubclass(obj, BaseException):
            bases = ", ".join(b.__name__ for b in obj.__bases__)
            lines += [f"*exception ({bases})*", ""]
        lines += [inspect.cleandoc(obj.__doc__ or "(no docstring)"), ""]
        if inspect.isclass(obj) and not issubclass(obj, BaseException):
            for m, member in obj.__dict__.items():
                if m.startswith("_") and m != "__init__":
                    continue
                doc = getattr(member, "__doc__", None) or (
                    member.fget.__doc__ if isinstance(member, property) else None
                )
                if not doc or m == "__init__":
                    continue
                call = (
                    ""
                    if isinstance(member, property)
                    else sig(member.__func__ if isinstance(member, classmethod) else member)
                )
                lines += [f"### `{name}.{m}{call}`", "", inspect.cleandoc(doc), ""]
    return "\n".join(lines).rstrip() + "\n"


if __name__ == "__main__":
    import argparse

    ap = argparse.ArgumentParser(description="write polydem's Python API reference (Markdown)")
    ap.add_argument("--out", help="the file (default: standard output)")
    a = ap.parse_args()
    if a.out:
        Path(a.out).write_text(reference())
    else:
        print(reference(), end="")
