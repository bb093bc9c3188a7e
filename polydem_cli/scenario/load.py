"""Read a scenario file, apply ``--set key.path=value`` overrides, validate."""

from __future__ import annotations

import copy
import tomllib
from pathlib import Path

from .schema import schema_of
from .spec import NOVALUE, ScenarioError

#: the first bytes of an HDF5 file (a polydem result)
HDF5_SIGNATURE = b"\x89HDF\r\n\x1a\n"


def parse_override(text: str, file: str):
    """``'time.dt=1e-4'`` -> (['time', 'dt'], 1e-4).  The value is read as a TOML value
    (numbers, booleans, arrays, inline tables, quoted strings); anything else is a bare string."""
    if "=" not in text:
        raise ScenarioError(file, text, NOVALUE, "--set needs the form key.path=value")
    key, raw = text.split("=", 1)
    key = key.strip()
    if not key or any(not p for p in key.split(".")):
        raise ScenarioError(file, key, raw, "--set: empty key path")
    try:
        value = tomllib.loads(f"v = {raw.strip()}")["v"]
    except tomllib.TOMLDecodeError:
        value = raw.strip()
    return key.split("."), value


def apply_override(data: dict, path: list, value, file: str):
    """Set the value at key ``path`` (a ``--set`` key split at dots; list indices as digits) in ``data``;
    ScenarioError naming the key when a part of the path does not exist."""
    cur = data
    for i, p in enumerate(path[:-1]):
        sub = ".".join(path[: i + 1])
        if isinstance(cur, list):
            if not p.isdigit() or int(p) >= len(cur):
                raise ScenarioError(file, sub, NOVALUE, f"--set: no entry {p} in this array of {len(cur)}")
            cur = cur[int(p)]
        elif isinstance(cur, dict):
            if p not in cur:
                cur[p] = {}
            cur = cur[p]
        else:
            raise ScenarioError(file, sub, cur, "--set: not a table or array")
    last = path[-1]
    if isinstance(cur, list):
        if not last.isdigit() or int(last) >= len(cur):
            raise ScenarioError(file, ".".join(path), NOVALUE, "--set: no such array entry")
        cur[int(last)] = value
    elif isinstance(cur, dict):
        cur[last] = value
    else:
        raise ScenarioError(file, ".".join(path[:-1]), cur, "--set: not a table")


def display_key(path: list) -> str:
    """['particles', '0', 'thickness'] -> 'particles[0].thickness' (the validator's notation)."""
    out = ""
    for p in path:
        out += f"[{p}]" if p.isdigit() else (f".{p}" if out else p)
    return out


def deep_merge(base: dict, over: dict) -> dict:
    """Tables merge key by key (recursively); any other value, arrays included, is replaced."""
    out = dict(base)
    for k, v in over.items():
        out[k] = deep_merge(out[k], v) if isinstance(v, dict) and isinstance(out.get(k), dict) else v
    return out


def read_toml(path, _chain=()) -> tuple[dict, str]:
    """Read a scenario file; ``[scenario] extends = "base.toml"`` merges it onto its base first."""
    data, text = _read_one(path)
    base = data.get("scenario", {}).get("extends") if isinstance(data.get("scenario"), dict) else None
    if base:
        if not isinstance(base, str):
            raise ScenarioError(str(path), "scenario.extends", base, "must be a file name (string)")
        bpath = (Path(path).parent / base).resolve()
        chain = _chain + (Path(path).resolve(),)
        if bpath in chain:
            raise ScenarioError(str(path), "scenario.extends", base, "circular extends")
        try:
            bdata, _ = read_toml(bpath, chain)
        except ScenarioError as e:
            raise ScenarioError(str(path), "scenario.extends", base, f"base scenario: {e.message()}") from None
        data = deep_merge(bdata, data)
    return data, text


def _read_one(path) -> tuple[dict, str]:
    p = Path(path)
    try:
        text = p.read_text(encoding="utf-8")
    except FileNotFoundError:
        raise ScenarioError(str(p), "", NOVALUE, "file not found") from None
    except IsADirectoryError:
        raise ScenarioError(str(p), "", NOVALUE, "is a directory, not a scenario file") from None
    except PermissionError:
        raise ScenarioError(str(p), "", NOVALUE, "file is not readable (permission denied)") from None
    except UnicodeDecodeError:
        if p.read_bytes()[:8] == HDF5_SIGNATURE:
            raise ScenarioError(
                str(p),
                "",
                NOVALUE,
                f"a result file (HDF5), not a scenario: see it with polydem report {p}, continue an "
                f"interrupted run with polydem run --resume {p}",
            ) from None
        raise ScenarioError(str(p), "", NOVALUE, "file is not UTF-8 text") from None
    except OSError as e:
        raise ScenarioError(str(p), "", NOVALUE, f"cannot read file ({e.strerror})") from None
    if not text.strip():
        raise ScenarioError(str(p), "", NOVALUE, "file is empty") from None
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as e:
        raise ScenarioError(str(p), "", NOVALUE, f"invalid TOML: {e}") from None
    if not data:
        raise ScenarioError(str(p), "", NOVALUE, "file holds no settings (only comments)") from None
    return data, text


def validate(data: dict, file: str, overrides=()) -> dict:
    """Validate a raw scenario dict (after overrides) against the schema of its solver kind
    (:func:`.schema.schema_of`)."""
    data = copy.deepcopy(data)
    keys = []
    for o in overrides:
        path, value = parse_override(o, file)
        apply_override(data, path, value, file)
        keys.append(display_key(path))
    try:
        return schema_of(data, file).validate(data, file, "")
    except ScenarioError as e:
        for k in keys:
            if e.key == k or e.key.startswith(k + ".") or e.key.startswith(k + "["):
                e.file = f"{file} (--set {k})"
                e.args = (e.message(),)
        raise


def load_scenario(path, overrides=()) -> tuple[dict, str]:
    """Return (resolved scenario, original text)."""
    data, text = read_toml(path)
    return validate(data, str(path), overrides), text


#: keys of [scenario] that document a run without changing it
PROVENANCE_KEYS = ("title", "description", "reproduces", "inferred", "extends")


def _complete_and_strip(d):
    import json

    try:
        d = validate(d, "<stored>")
    except ScenarioError:
        pass
    d = json.loads(json.dumps(d))
    sc = d.get("scenario") or {}
    for k in PROVENANCE_KEYS:
        sc.pop(k, None)
    return d


def scenario_differences(resolved_a: dict, resolved_b: dict) -> list:
    """Key paths in which two resolved scenarios differ (documentation keys of [scenario] ignored)."""
    out = []

    def walk(x, y, path):
        if isinstance(x, dict) and isinstance(y, dict):
            for k in sorted(set(x) | set(y)):
                walk(x.get(k), y.get(k), f"{path}.{k}" if path else k)
        elif x != y:
            out.append(path)

    walk(_complete_and_strip(resolved_a), _complete_and_strip(resolved_b), "")
    return out


def same_run(resolved_a: dict, resolved_b: dict) -> bool:
    """True if two resolved scenarios define the same simulation: equal after dropping the
    documentation keys of [scenario] (so that rewording a scenario file does not invalidate a
    finished or resumable result)."""
    import json

    def strip(d):
        d = json.loads(json.dumps(d))
        sc = d.get("scenario") or {}
        for k in PROVENANCE_KEYS:
            sc.pop(k, None)
        return d

    def complete(d):  # a result written before a parameter existed gets its default
        try:
            return validate(d, "<stored>")
        except ScenarioError:
            return d

    return strip(complete(resolved_a)) == strip(complete(resolved_b))
