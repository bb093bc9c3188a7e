"""Declarative parameter specifications and a strict validator (GUIDE practice 4).

A schema is a tree of :class:`Table` (fixed keys), :class:`MapOf` (user-named
entries such as materials), :class:`ArrayOf` (``[[...]]`` arrays of tables) and
:class:`Param` leaves.  Every leaf declares its type, unit, bounds, default and
a one-line description.  Validation rejects unknown keys (with a suggestion),
wrong types, missing values and out-of-range values, and reports the first
problem as a :class:`ScenarioError` naming file, key path, value and reason.
Defaults are filled in, so the resolved scenario is complete and can be stored
with every result.
"""

from __future__ import annotations

import difflib
import math
from dataclasses import dataclass
from typing import Any, Callable

from .errors import NOVALUE, ScenarioError  # noqa: F401 (ScenarioError re-exported)

REQUIRED = object()

#: the largest integer any scenario value may take unless its Param sets its own max (2^31 - 1)
INT_LIMIT = 2**31 - 1


def _type_name(v: Any) -> str:
    if isinstance(v, bool):
        return "boolean"
    if isinstance(v, int):
        return "integer"
    if isinstance(v, float):
        return "float"
    if isinstance(v, str):
        return "string"
    if isinstance(v, list):
        return "array"
    if isinstance(v, dict):
        return "table"
    return type(v).__name__


@dataclass
class Param:
    """One scenario value.

    kind: ``float``, ``int``, ``str``, ``bool``, ``vec2``, ``vec3``, ``floats``
    (list of numbers), ``pairs`` (list of [int, int]), ``strs`` (list of strings)
    or ``any`` (checked by ``check``).
    """

    kind: str
    unit: str = "-"
    doc: str = ""
    default: Any = REQUIRED
    min: float | None = None
    max: float | None = None
    min_open: bool = False  # True: value must be > min
    max_open: bool = False
    choices: tuple | None = None
    check: Callable[[Any], str | None] | None = None  # returns an error reason or None
    thesis: str = ""  # thesis symbol / equation

    def validate(self, v: Any, file: str, key: str) -> Any:
        if v is None and self.default is None:  # "unset" (a resolved scenario validates again)
            return None
        k = self.kind
        if k == "float":
            v = self._number(v, file, key)
        elif k == "int":
            if isinstance(v, bool) or not isinstance(v, int):
                raise ScenarioError(file, key, v, f"must be an integer, got {_type_name(v)}")
            if self.max is None and abs(v) > INT_LIMIT:
                raise ScenarioError(
                    file,
                    key,
                    v,
                    f"absurdly large: integers are limited to {INT_LIMIT:,} "
                    f"(counts, steps and seeds above it are not sensible)",
                )
            self._bounds(v, file, key)
        elif k == "str":
            if not isinstance(v, str):
                raise ScenarioError(file, key, v, f"must be a string, got {_type_name(v)}")
            if self.choices and v not in self.choices:
                raise ScenarioError(file, key, v, f"must be one of {', '.join(map(repr, self.choices))}")
        elif k == "bool":
            if not isinstance(v, bool):
                raise ScenarioError(file, key, v, f"must be true or false, got {_type_name(v)}")
        elif k in ("vec2", "vec3", "floats"):
            if not isinstance(v, list):
                raise ScenarioError(file, key, v, f"must be an array of numbers, got {_type_name(v)}")
            need = {"vec2": 2, "vec3": 3}.get(k)
            if need is not None and len(v) != need:
                raise ScenarioError(file, key, v, f"must have exactly {need} numbers, got {len(v)}")
            v = [self._number(e, file, f"{key}[{i}]") for i, e in enumerate(v)]
        elif k == "pairs":
            if not isinstance(v, list) or not all(
                isinstance(e, list) and len(e) == 2 and all(isinstance(q, int) and not isinstance(q, bool) for q in e)
                for e in v
            ):
                raise ScenarioError(file, key, v, "must be an array of [integer, integer] pairs")
        elif k == "points":
            if not isinstance(v, list) or not all(
                isinstance(e, list) and len(e) == 2 and all(_is_number(q) for q in e) for e in v
            ):
                raise ScenarioError(file, key, v, "must be an array of [x, y] number pairs")
            v = [[float(q) for q in e] for e in v]
            for i, e in enumerate(v):
                if not all(math.isfinite(q) for q in e):
                    raise ScenarioError(file, f"{key}[{i}]", e, "must be finite")
        elif k == "strs":
            if not isinstance(v, list) or not all(isinstance(e, str) for e in v):
                raise ScenarioError(file, key, v, "must be an array of strings")
        elif k == "any":
            pass
        else:  # pragma: no cover
            raise AssertionError(k)
        if self.check is not None:
            why = self.check(v)
            if why:
                raise ScenarioError(file, key, v, why)
        return v

    def _number(self, v, file, key):
        if not _is_number(v):
            raise ScenarioError(file, key, v, f"must be a number, got {_type_name(v)}")
        v = float(v)
        if not math.isfinite(v):
            raise ScenarioError(file, key, v, "must be finite")
        self._bounds(v, file, key)
        return v

    def _bounds(self, v, file, key):
        if self.min is not None:
            if self.min_open and not v > self.min:
                raise ScenarioError(file, key, v, f"must be > {self.min:g}" + self._what())
            if not self.min_open and not v >= self.min:
                raise ScenarioError(file, key, v, f"must be >= {self.min:g}" + self._what())
        if self.max is not None:
            if self.max_open and not v < self.max:
                raise ScenarioError(file, key, v, f"must be < {self.max:g}" + self._what())
            if not self.max_open and not v <= self.max:
                raise ScenarioError(file, key, v, f"must be <= {self.max:g}" + self._what())

    def _what(self):
        return f" ({self.doc})" if self.doc else ""

    def describe_bounds(self) -> str:
        parts = []
        if self.min is not None:
            parts.append(("> " if self.min_open else ">= ") + f"{self.min:g}")
        if self.max is not None:
            parts.append(("< " if self.max_open else "<= ") + f"{self.max:g}")
        if self.choices:
            parts.append("one of " + ", ".join(self.choices))
        return ", ".join(parts)


def _is_number(v) -> bool:
    return isinstance(v, (int, float)) and not isinstance(v, bool)


@dataclass
class Table:
    fields: dict
    doc: str = ""
    required: bool = True  # a missing table is an error (else: omitted → None / defaults)
    default_if_missing: bool = False  # missing → filled with defaults
    check: Callable[[dict], tuple[str, Any, str] | None] | None = None  # (key, value, reason)
    variants: dict | None = None  # discriminator value -> extra fields (dict)
    discriminator: str | None = None

    def validate(self, v: Any, file: str, key: str) -> dict:
        if v is None and not self.required and not self.default_if_missing:
            return None  # an omitted optional table in a resolved scenario
        if not isinstance(v, dict):
            raise ScenarioError(file, key, v, f"must be a table, got {_type_name(v)}")
        allowed = dict(self.fields)
        if self.discriminator:
            dv = v.get(self.discriminator, NOVALUE)
            dkey = _join(key, self.discriminator)
            if dv is NOVALUE:
                raise ScenarioError(file, dkey, NOVALUE, f"missing; one of {', '.join(map(repr, self.variants))}")
            if dv not in self.variants:
                raise ScenarioError(file, dkey, dv, f"unknown; valid values: {', '.join(map(repr, self.variants))}")
            allowed.update(self.variants[dv])
        out = {}
        for k in v:
            if k not in allowed:
                close = difflib.get_close_matches(k, list(allowed), n=1)
                hint = f"; did you mean '{close[0]}'?" if close else ""
                raise ScenarioError(file, _join(key, k), v[k], f"unknown key{hint} (valid keys: {', '.join(allowed)})")
        for k, spec in allowed.items():
            sub = _join(key, k)
            if k in v:
                out[k] = spec.validate(v[k], file, sub)
            else:
                out[k] = _missing(spec, file, sub)
        if self.check is not None:
            res = self.check(out)
            if res:
                ck, cv, why = res
                raise ScenarioError(file, _join(key, ck) if ck else key, cv, why)
        return out


@dataclass
class MapOf:
    item: Any
    doc: str = ""
    required: bool = True
    min_items: int = 0

    def validate(self, v, file, key):
        if not isinstance(v, dict):
            raise ScenarioError(file, key, v, f"must be a table of named entries, got {_type_name(v)}")
        if len(v) < self.min_items:
            raise ScenarioError(
                file, key, v, f"needs at least {self.min_items} entr{'y' if self.min_items == 1 else 'ies'}"
            )
        return {k: self.item.validate(e, file, _join(key, k)) for k, e in v.items()}


@dataclass
class ArrayOf:
    item: Any
    doc: str = ""
    required: bool = True
    min_items: int = 0

    def validate(self, v, file, key):
        if not isinstance(v, list):
            raise ScenarioError(file, key, v, f"must be an array of tables ([[{key}]]), got {_type_name(v)}")
        if len(v) < self.min_items:
            raise ScenarioError(
                file, key, v, f"needs at least {self.min_items} entr{'y' if self.min_items == 1 else 'ies'}"
            )
        return [self.item.validate(e, file, f"{key}[{i}]") for i, e in enumerate(v)]


def _missing(spec, file, key):
    if isinstance(spec, Param):
        if spec.default is REQUIRED:
            raise ScenarioError(file, key, NOVALUE, "missing value" + (f" ({spec.doc})" if spec.doc else ""))
        return spec.default() if callable(spec.default) else spec.default
    if isinstance(spec, Table):
        if spec.default_if_missing:
            return spec.validate({}, file, key)
        if spec.required:
            raise ScenarioError(file, key, NOVALUE, "missing table" + (f" ({spec.doc})" if spec.doc else ""))
        return None
    if isinstance(spec, (ArrayOf, MapOf)):
        if spec.required and spec.min_items > 0:
            raise ScenarioError(file, key, NOVALUE, "missing" + (f" ({spec.doc})" if spec.doc else ""))
        return [] if isinstance(spec, ArrayOf) else {}
    raise AssertionError(spec)  # pragma: no cover


def _join(a: str, b: str) -> str:
    return f"{a}.{b}" if a else b


def markdown(schema: Table, title: str = "Scenario file reference") -> str:
    """Render the schema as Markdown (docs/scenario.md is generated from it)."""
    lines = [f"# {title}", "", schema.doc, ""]

    def param_row(name, p: Param):
        dv = p.default() if callable(p.default) else p.default
        d = "required" if p.default is REQUIRED else ("—" if dv is None else f"`{dv!r}`")
        b = p.describe_bounds()
        doc = (p.doc + (f" [{p.thesis}]" if p.thesis else "")).replace("|", "\\|")
        return f"| `{name}` | {p.kind} | {p.unit} | {d} | {b} | {doc} |"

    def walk(t, path, level):
        if isinstance(t, (ArrayOf, MapOf)):
            inner = t.item
            suffix = "[[" + path + "]]" if isinstance(t, ArrayOf) else f"[{path}.<name>]"
            lines.extend([f"{'#' * level} `{suffix}`", "", t.doc, ""])
            walk_table(inner, path, level)
            return
        lines.extend([f"{'#' * level} `[{path}]`", "", t.doc, ""])
        walk_table(t, path, level)

    def walk_table(t, path, level):
        rows = [(k, s) for k, s in t.fields.items() if isinstance(s, Param)]
        if rows:
            lines.extend(["| key | type | unit | default | bounds | meaning |", "|---|---|---|---|---|---|"])
            lines.extend(param_row(k, s) for k, s in rows)
            lines.append("")
        if t.variants:
            for dv, extra in t.variants.items():
                lines.extend([f"*{t.discriminator} = \"{dv}\"*:", ""])
                prow = [(k, s) for k, s in extra.items() if isinstance(s, Param)]
                lines.extend(["| key | type | unit | default | bounds | meaning |", "|---|---|---|---|---|---|"])
                lines.extend(param_row(k, s) for k, s in prow)
                lines.append("")
        for k, s in t.fields.items():
            if not isinstance(s, Param):
                walk(s, _join(path, k), min(level + 1, 4))

    for k, s in schema.fields.items():
        if isinstance(s, Param):
            continue
        walk(s, k, 2)
    top = [(k, s) for k, s in schema.fields.items() if isinstance(s, Param)]
    if top:
        lines.extend(
            ["## top level", "", "| key | type | unit | default | bounds | meaning |", "|---|---|---|---|---|---|"]
        )
        lines.extend(param_row(k, s) for k, s in top)
    return "\n".join(lines) + "\n"
