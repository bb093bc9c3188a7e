"""Parameter sweeps on Dask (``polydem sweep``).

The Cartesian product of ``--set key=v1,v2,...`` lists gives the variants; each
variant is an ordinary run (same validation, one HDF5 result and summary per
variant) executed as a Dask task — on a local cluster sized to the machine by
default (one single-threaded worker process per core), or on a running cluster
given by its scheduler address.  Finished variants of the same scenario are not
run again; interrupted ones are resumed from their last checkpoint.  A collated
table ``sweep.csv`` / ``sweep.json`` lists every variant: one column per swept key (its value), status, end,
wall time, the macroscopic measures of a specimen with ``[macro]`` (E, ν, peak stress …), the peak load of each
loaded set, failed bonds and diagnostics, in the units the report uses (named in the header) and to 6
significant digits.

Dask is used rather than our own process pool because it already schedules,
retries and distributes tasks over machines (``--scheduler``), which a study of
many long runs needs.
"""

from __future__ import annotations

import csv
import itertools
import json
import re
from pathlib import Path


def split_values(text: str) -> list[str]:
    """'a=1,2,[3, 4]' values: split on commas outside brackets and quotes."""
    out, depth, cur, quote = [], 0, "", None
    for ch in text:
        if quote:
            cur += ch
            if ch == quote:
                quote = None
            continue
        if ch in "\"'":
            quote = ch
        elif ch in "[{":
            depth += 1
        elif ch in "]}":
            depth -= 1
        if ch == "," and depth == 0:
            out.append(cur.strip())
            cur = ""
        else:
            cur += ch
    if cur.strip():
        out.append(cur.strip())
    return out


def variants(sets) -> list[list[str]]:
    """['a=1,2', 'b=x,y'] -> [['a=1','b=x'], ['a=1','b=y'], ...]."""
    axes = []
    for s in sets:
        if "=" not in s:
            raise ValueError(f"--set {s!r}: expected key.path=value[,value...]")
        key, vals = s.split("=", 1)
        vs = split_values(vals)
        if not vs:
            raise ValueError(f"--set {s!r}: no values")
        axes.append([f"{key.strip()}={v}" for v in vs])
    return [list(c) for c in itertools.product(*axes)] if axes else [[]]


def variant_name(stem: str, overrides) -> str:
    """A file-name-safe name of one variant: the scenario's stem and each override's last key and value."""
    parts = [stem]
    for o in overrides:
        k, v = o.split("=", 1)
        parts.append(re.sub(r"[^A-Za-z0-9.+-]+", "-", f"{k.split('.')[-1]}-{v}").strip("-"))
    return "__".join(parts)


def run_variant(scenario: str, overrides, out: str, base_overrides=()) -> dict:
    """Run (or resume, or reuse) one variant, of any solver family; returns a row of the collated table (the
    family's ``table_row``).  Runs in a worker.  An existing result of the same run is reused when finished and
    resumed when it has a checkpoint; any other file at ``out`` is replaced (the sweep's own folder)."""
    import numba

    from ..engine.simulation import EngineError
    from ..scenario.load import load_scenario
    from ..solvers import driver, family_module
    from ..solvers.protocol import RunOptions, Source

    numba.set_num_threads(1)  # one thread per worker (the run below keeps it: threads=1)
    ov = list(base_overrides) + list(overrides)
    sc, text = load_scenario(scenario, ov)
    out = Path(out)
    row = {"variant": out.stem, "overrides": list(overrides), "result": str(out), "reused": False}
    try:
        o = driver.obtain(
            sc,
            out,
            source=Source(str(scenario), text, tuple(ov)),
            policy=driver.REFRESH,
            opts=RunOptions(quiet=True, threads=1),
        )
    except EngineError as e:
        row.update(status="failed", failure=str(e))
        return row
    row["reused"] = o.action == "reused"
    row.update(family_module(sc["solver"]["kind"]).table_row(o.summary))
    return row


def _cell(v):
    """A table cell: floats to 6 significant digits, booleans as TOML writes them (true, false), None empty."""
    if v is None:
        return ""
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, float):
        return f"{v:.6g}"
    return v


def run_variants(scenario: Path, named, out: Path, base_overrides=(), scheduler=None, workers=None) -> list:
    """Run (name, overrides) variants of ``scenario`` on Dask as ``<out>/<name>.h5``; the rows of
    :func:`run_variant` in order."""
    from dask.distributed import Client, LocalCluster

    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    cluster = None
    if scheduler:
        client = Client(scheduler)
    else:
        import logging
        import os

        cluster = LocalCluster(
            n_workers=workers or os.cpu_count() or 1,
            threads_per_worker=1,
            processes=True,
            dashboard_address=None,
            silence_logs=logging.ERROR,
        )
        client = Client(cluster)
    try:
        futures = [
            client.submit(run_variant, str(scenario), v, str(out / (name + ".h5")), list(base_overrides), pure=False)
            for name, v in named
        ]
        return client.gather(futures)
    finally:
        client.close()
        if cluster is not None:
            cluster.close()


def sweep(scenario: Path, sets, out: Path, scheduler=None, workers=None, base_overrides=()) -> dict:
    """Run every combination of the ``sets`` overrides of a scenario (in parallel, through :func:`run_variants`) and
    write the collated table as ``sweep.json`` in ``out``; returns it."""
    out = Path(out)
    vs = variants(sets)
    rows = run_variants(
        scenario,
        [(variant_name(Path(scenario).stem, v), v) for v in vs],
        out,
        base_overrides,
        scheduler=scheduler,
        workers=workers,
    )
    res = {"scenario": str(scenario), "sets": list(sets), "base_overrides": list(base_overrides), "variants": rows}
    (out / "sweep.json").write_text(json.dumps(res, indent=1))
    swept = [s.split("=", 1)[0].strip() for s in sets]
    first = ("variant", "result", "reused", "failure")
    keys = []
    for r in rows:  # the order of the summary columns, as the first variant that has each gives them
        keys += [k for k in r if k not in keys and k not in first and k != "overrides"]
    with open(out / "sweep.csv", "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(["variant"] + swept + keys + ["reused", "failure", "result"])
        for r in rows:
            vals = dict(o.split("=", 1) for o in r["overrides"])
            w.writerow(
                [r["variant"]] + [vals.get(k) for k in swept] + [_cell(r.get(k)) for k in keys]
                + [_cell(r.get("reused")), r.get("failure", ""), r.get("result")]
            )  # fmt: skip
    return res
