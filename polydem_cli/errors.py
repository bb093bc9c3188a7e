"""The input-error type shared by every layer (scenario validation, specimen and network builders, the
engine's initial-state check): one message naming file, key, value and reason.

It lives below all of them so that physics and engine code can report bad input without importing the
scenario layer (``polydem_cli.scenario.spec`` re-exports it).
"""

from __future__ import annotations

from typing import Any


class PolydemError(Exception):
    """What polydem refuses or cannot do, said in one message — the base of every error a user of the Python API
    (polydem_cli/api.py) can catch; the command line prints the same message and exits 2 (bad input, an output place
    that cannot be written, a result it will not touch) or 1 (a run that failed)."""


class ScenarioError(PolydemError):
    """Invalid scenario input: one message naming file, key, value and reason."""

    def __init__(self, file: str, key: str, value: Any, reason: str):
        self.file, self.key, self.value, self.reason = str(file), key, value, reason
        super().__init__(self.message())

    def message(self) -> str:
        key = self.key or "(top level)"
        if self.value is NOVALUE and not self.key:  # the file itself (missing, empty, not TOML)
            return f"{self.file}: {self.reason}"
        if self.value is NOVALUE:
            return f"{self.file}: {key}: {self.reason}"
        if self.value is None:  # a key left out (TOML has no null): never Python's None
            return f"{self.file}: {key} is not set: {self.reason}"
        return f"{self.file}: {key} = {show_value(self.value)}: {self.reason}"


class _NoValue:
    def __repr__(self):
        return "<missing>"


NOVALUE = _NoValue()


def show_value(v: Any) -> str:
    """A value as the scenario file writes it (TOML: true, false, inline tables; a missing value "not set"),
    never Python's spelling of it (None, True, {'a': 1}, np.float64(2.0)); shortened to 80 characters."""
    s = _toml(v)
    return s if len(s) <= 80 else s[:77] + "..."


def toml_value(v: Any) -> str:
    """A value as an inline TOML value (the ``--set key=<value>`` syntax): numbers, booleans, strings, arrays,
    inline tables; NumPy scalars and arrays as their Python values."""
    return _toml(v)


def _toml(v: Any) -> str:
    if getattr(v, "ndim", None) == 0 and hasattr(v, "item"):  # a NumPy scalar
        v = v.item()
    if v is None:
        return "(not set)"
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, (list, tuple)) or (hasattr(v, "tolist") and getattr(v, "ndim", 0) > 0):
        return "[" + ", ".join(_toml(x) for x in (v.tolist() if hasattr(v, "tolist") else v)) + "]"
    if isinstance(v, dict):
        return "{ " + ", ".join(f"{k} = {_toml(x)}" for k, x in v.items()) + " }" if v else "{}"
    return repr(v)  # numbers; strings as TOML literal strings ('fast')


class DecompositionError(PolydemError, ValueError):
    """A decomposition over ranks that cannot work (too many ranks for the scene, an interaction range wider than a
    subdomain, a family that does not run decomposed yet); the message says which and what to do
    (engine/decompose.py)."""


class OutputError(PolydemError):
    """An output place that cannot be written (a folder in the way of a file, a file in the way of a folder, no
    permission, a read-only file system), or a write that failed: the path and the reason (io/places.py)."""


class EngineError(PolydemError, RuntimeError):
    """A run that cannot continue (instability, containment with policy 'abort'): step, time, the particle and the
    critical time step in the message (engine/simulation.py); exit code 1 on the command line."""


class CallbackError(PolydemError):
    """A callback of a run (solvers/protocol.py ``Every``) raised: the run stopped after a checkpoint; the message
    names the callback, the step and the exception's message; ``__cause__`` is the exception."""
