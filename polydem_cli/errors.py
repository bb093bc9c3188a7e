"""The input-error type shared by every layer (scenario validation, specimen and network builders, the
engine's initial-state check): one message naming file, key, value and reason.

It lives below all of them so that physics and engine code can report bad input without importing the
scenario layer (``polydem_cli.scenario.spec`` re-exports it).
"""

from __future__ import annotations

from typing import Any


class ScenarioError(Exception):
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


class DecompositionError(ValueError):
    """A decomposition over ranks that cannot work (too many ranks for the scene, an interaction range wider than a
    subdomain, a family that does not run decomposed yet); the message says which and what to do
    (engine/decompose.py)."""
