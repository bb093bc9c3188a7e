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
        if self.value is NOVALUE:
            return f"{self.file}: {key}: {self.reason}"
        return f"{self.file}: {key} = {show_value(self.value)}: {self.reason}"


class _NoValue:
    def __repr__(self):
        return "<missing>"


NOVALUE = _NoValue()


def show_value(v: Any) -> str:
    s = repr(v)
    return s if len(s) <= 80 else s[:77] + "..."
