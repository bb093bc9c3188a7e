"""``polydem batch``: run a list of scenarios to their results, each only as far as needed (a finished result is
reused, an interrupted one resumed), with one progress line over the whole list and a summary at the end."""

from __future__ import annotations

import re
import subprocess
import sys
import time
from pathlib import Path

import click

_PCT = re.compile(r"\[\s*([0-9.]+)%\].*?ETA ([0-9:\-]+)")


def _jobs(items) -> list:
    """'scenario.toml[=result.h5]' → (scenario, result); the default result is outputs/<stem>.h5."""
    out = []
    for it in items:
        scen, _, res = it.partition("=")
        out.append((Path(scen), Path(res) if res else Path("outputs") / (Path(scen).stem + ".h5")))
    return out


def _state(scen, res) -> str:
    """'finished', 'resumable' or 'new' for a scenario and its result path (as ``run --continue`` decides)."""
    if not res.exists():
        return "new"
    try:
        from ..scenario.load import load_scenario
        from ..solvers import family

        sc, _ = load_scenario(scen)
        fam = family(sc["solver"]["kind"])
        if fam is not None:
            st = fam.existing_state(res, sc)
        else:
            from ..engine.runner import existing_state as _existing_state
            from ..scenario.build import build_system

            st = _existing_state(res, build_system(sc, str(scen)))
    except Exception:  # noqa: BLE001 - the run itself will say what is wrong
        return "new"
    return {"finished": "finished", "resumable": "resumable"}.get(st, "new")


@click.command("batch")
@click.argument("items", nargs=-1, required=True, metavar="SCENARIO[=RESULT] ...")
@click.option("--threads", default="1", show_default=True, help="threads of each run (see polydem run)")
def batch_cmd(items, threads):
    """Run SCENARIOs in order (each to RESULT, default outputs/<stem>.h5): finished results are reused,
    interrupted ones resumed, the others run; one progress line over the list (which run, how far, its ETA)
    and a summary at the end (reused, resumed, ran, failed and why).  Exit code 1 if any run failed.

    \b
    Example:
      polydem batch scenarios/lh/prepare_p100.toml=outputs/lh/prepare_p100.h5 \\
                    scenarios/lh/load_p100_kc1.toml=outputs/lh/load_p100_kc1.h5
    """
    from ..engine.runner import write_progress

    jobs = _jobs(items)
    tty = sys.stderr.isatty()
    rows = []
    for i, (scen, res) in enumerate(jobs, 1):
        head = f"[run {i} of {len(jobs)}] {res}"
        state = _state(scen, res)
        if state == "finished":
            rows.append((res, "reused", 0.0, ""))
            click.echo(f"{head}: finished earlier, reused", err=True)
            continue
        res.parent.mkdir(parents=True, exist_ok=True)
        cmd = [
            sys.executable,
            "-m",
            "polydem_cli",
            "run",
            str(scen),
            "-o",
            str(res),
            "--continue",
            "--threads",
            threads,
        ]
        t0 = time.time()
        p = subprocess.Popen(cmd, stderr=subprocess.PIPE, stdout=subprocess.PIPE, text=True, bufsize=1)
        last_err = ""
        for line in p.stderr:
            m = _PCT.search(line)
            if m:
                msg = f"{head} ({'resumed' if state == 'resumable' else 'running'}): {m.group(1)} %, ETA {m.group(2)}"
                write_progress(sys.stderr, tty, msg, width=100)
            elif line.strip().startswith("error"):
                last_err = line.strip()
        out = p.stdout.read()
        p.wait()
        if tty:
            sys.stderr.write("\n")
        wall = time.time() - t0
        if p.returncode == 0:
            rows.append((res, "resumed" if state == "resumable" else "ran", wall, ""))
            click.echo(f"{head}: done in {wall:.0f} s", err=True)
        else:
            why = last_err or (out.strip().splitlines() or [f"exit code {p.returncode}"])[-1]
            rows.append((res, "failed", wall, why))
            click.echo(f"{head}: FAILED ({why})", err=True)
    counts = {k: sum(1 for r in rows if r[1] == k) for k in ("reused", "resumed", "ran", "failed")}
    click.echo(
        f"batch: {len(rows)} runs — {counts['ran']} ran, {counts['resumed']} resumed, {counts['reused']} reused, "
        f"{counts['failed']} failed; {sum(r[2] for r in rows) / 60:.1f} min"
    )
    for res, what, _wall, why in rows:
        if what == "failed":
            click.echo(f"  failed: {res}: {why}")
    if counts["failed"]:
        sys.exit(1)
