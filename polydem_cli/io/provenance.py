"""Provenance of a result: the code version that wrote it and the root attributes every result carries,
whatever its solver family (``format``, ``units`` and the family's own keys come from the family)."""

from __future__ import annotations

import datetime as _dt
import json
import subprocess
from pathlib import Path

from .. import __version__


def code_version() -> str:
    """The package version, plus ``+g<sha>`` (and ``.dirty`` for uncommitted changes) in a git checkout."""
    v = __version__
    try:
        here = Path(__file__).resolve().parents[2]
        sha = subprocess.run(
            ["git", "-C", str(here), "rev-parse", "--short", "HEAD"], capture_output=True, text=True, timeout=5
        ).stdout.strip()
        dirty = subprocess.run(
            ["git", "-C", str(here), "status", "--porcelain", "--untracked-files=no"],
            capture_output=True,
            text=True,
            timeout=5,
        ).stdout.strip()
        if sha:
            v += f"+g{sha}" + (".dirty" if dirty else "")
    except (OSError, subprocess.SubprocessError):
        pass
    return v


def provenance(resolved: dict, scenario_file="", scenario_text="", overrides=()) -> dict:
    """Root attributes that make a result traceable: code version, creation time, the scenario file and its
    text as read, the ``--set`` overrides and the validated scenario with its defaults (JSON)."""
    return {
        "code_version": code_version(),
        "created": _dt.datetime.now(_dt.timezone.utc).isoformat(timespec="seconds"),
        "scenario_file": str(scenario_file),
        "scenario_text": scenario_text,
        "resolved": json.dumps(resolved),
        "overrides": json.dumps(list(overrides)),
        "title": resolved["scenario"]["title"],
    }
