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


def session(threads="auto", pin_threads=False) -> dict:
    """Provenance of one session of a run — a segment: the run as started, then each resume — as it begins: when,
    on which machine and code, on how many MPI ranks (in all, and on this machine as the launcher tells: None where
    it does not), the cores this process may use and the machine has, the threads asked for per rank (``auto`` or
    N, pinned or not) and whether this machine's ranks × pinned threads exceed its cores (None: not known).  The
    run driver (solvers/driver.py) adds where the segment began and, at its end, where it ended, the threads it
    ran on and how it ended; the list of segments is the result's root attribute ``segments`` (JSON) and the
    summary's ``segments``."""
    import os
    import socket

    from ..engine import distributed
    from ..engine.distributed import launched_local_ranks, launched_ranks

    ranks = launched_ranks()
    local = 1 if ranks == 1 else launched_local_ranks()
    machine = os.cpu_count() or 1
    try:
        cores = len(os.sched_getaffinity(0))
    except AttributeError:  # not Linux
        cores = machine
    cores = distributed.BOUND_FROM or cores  # a rank bound to its share: the cores its ranks share
    each = int(threads) if pin_threads and str(threads).isdigit() else 1
    # ranks that polydem run --ranks started share this process's cores; a cluster's launcher may bind each rank to
    # cores of its own, so there only the machine's count is a bound
    limit = cores if ranks == 1 or os.environ.get("POLYDEM_RANK_PIDS") else machine
    return {
        "started": _dt.datetime.now(_dt.timezone.utc).isoformat(timespec="seconds"),
        "code_version": code_version(),
        "host": socket.gethostname(),
        "ranks": ranks,
        "ranks_on_host": local,
        "cores": cores,
        "machine_cores": machine,
        "threads": threads if threads == "auto" else int(threads),
        "pin_threads": bool(pin_threads),
        "oversubscribed": None if local is None else local * each > limit,
    }


def describe_segments(segments: list) -> str:
    """One line for the console: what the run ran on — ranks × threads per rank, per segment after a resume (with
    the work each segment kept and how it ended)."""

    def on(s):
        used, asked = s.get("threads_used") or [], s["threads"]
        th = f"{min(used)}–{max(used)}" if len(set(used)) > 1 else str(used[0]) if used else str(asked)
        th = f"{th} thread{'' if th == '1' else 's'}{' each' if s['ranks'] > 1 else ''}"
        if used:  # how the count was chosen (a killed session's is not known: what was asked for)
            th += " (auto)" if asked == "auto" else f" (--threads {asked}{' pinned' if s.get('pin_threads') else ''})"
        txt = (f"{s['ranks']} MPI ranks × " if s["ranks"] > 1 else "1 process, ") + th
        if s.get("oversubscribed"):
            txt += f", oversubscribed: {s['ranks_on_host']} ranks on {s['cores']} core{'s' if s['cores'] > 1 else ''}"
        return txt

    if len(segments) == 1:
        s = segments[0]
        if s["start"] > 0:  # resumed from a result written before segments were recorded
            return f"ran on {on(s)} ({s['unit']}s {s['start']:,}–{s.get('end', 0):,}; earlier sessions not recorded)"
        return f"ran on {on(s)}"
    items = []
    for k, s in enumerate(segments):
        nxt = segments[k + 1]["start"] if k + 1 < len(segments) else None
        end = s.get("end") if s.get("end") is not None else nxt
        kept = f"{s['start']:,}–{end:,}" if end is not None else f"{s['start']:,}–"
        how = s.get("status")
        note = {"killed": " (killed: its work after the last checkpoint redone)", "failed": " (failed)"}.get(how, "")
        if how == "interrupted":
            note = " (interrupted)"
        items.append(f"{s['unit']}s {kept} on {on(s)}{note}")
    return f"ran in {len(segments)} segments: " + "; ".join(items)


#: the folders of the package whose code a run executes (the rest: the CLI, figures, workflows, reproductions,
#: benchmarks and the quasi-static coupling, which an explicit run does not touch); "." holds the top-level modules
RUN_PACKAGES = ("engine", "interactions", "geometry", "boundary", "scenario", "solvers", "analysis", "io", ".")


def source_digests() -> dict:
    """{folder of the package: SHA-1 (12 hex digits) of its Python sources}, "." for the top-level modules: which
    code wrote a result even from an uncommitted tree (``code_version`` then only says ``.dirty``), so that a number
    quoted from a result can be checked against the code that would print it today (tests/test_readme_current.py)."""
    import hashlib

    pkg = Path(__file__).resolve().parents[1]
    out = {}
    for p in sorted(pkg.rglob("*.py")):
        rel = p.relative_to(pkg)
        key = rel.parts[0] if len(rel.parts) > 1 else "."
        h = out.setdefault(key, hashlib.sha1())
        h.update(str(rel).encode() + b"\0" + p.read_bytes())
    return {k: h.hexdigest()[:12] for k, h in out.items()}


def scenario_digest(resolved: dict) -> str:
    """SHA-1 (12 hex digits) of a validated scenario with its defaults (its canonical JSON)."""
    import hashlib

    return hashlib.sha1(json.dumps(resolved, sort_keys=True).encode()).hexdigest()[:12]
