"""The quasi-static solver family (``[solver] kind = "quasistatic"``): the run driver of the lattice analyses of
:mod:`polydem_cli.coupling.stepper` — one solve per step, history rows streamed, checkpoints, progress, clean
stop on SIGINT/SIGTERM, resume, summary.

Result file (HDF5, written with h5py; ``format = "polydem-quasistatic"``, ``format_version = 1``)::

    attrs     format, format_version, code_version, created, solver = "quasistatic", scenario_file,
              scenario_text, resolved (JSON), overrides (JSON), title, units, status (running / finished /
              failed), summary (JSON, at the end)
    /lattice  x (n, 2) node positions [cm]; ij (n, 2) lattice indices; members (m, 2) node pairs;
              k (m,) stiffness [dyn/cm]; f_t (m,) strength [dyn]; aggregates (q, 3) x, y, r [cm]
    /history/table   (rows, columns) one row per solve; attrs "columns": JSON [[name, unit, description]]
              (coupling/stepper.py COLUMNS)
    /stages/NNNN     the adaptive meshes: elements (e, 4) super-triangles (i, j, orientation, side) in
              lattice indices (coupling/mesh.py), level (e,) 1-3; attr "solve": the first solve on it
    /damage/tooth    (m,) teeth taken per member at the last checkpoint (0: intact; teeth: removed)
    /checkpoint/slot0, slot1, current   the stepper state (tooth, counters, peak, elements) with
              history_count, stage_count, wall_elapsed; two slots, the current one named by "current"

A result is a time series of solves, not of time: ``polydem report`` draws the load–displacement curve, the
mesh and level map of every stage and the damaged members.
"""

from __future__ import annotations

import datetime as _dt
import json
import resource
import sys
import time
from pathlib import Path

import numpy as np

FORMAT = "polydem-quasistatic"
FORMAT_VERSION = 1


def _problem(resolved):
    from ..coupling.examples import _teeth
    from ..coupling.scenario import build_problem
    from ..coupling.stepper import Stepper

    p = build_problem(resolved)
    mem = resolved["members"]
    teeth = _teeth(p, mem["ductility"], mem["teeth"]) if p.softening else None
    ld = resolved["loading"]
    st = Stepper(
        p,
        teeth,
        resolved["adaptive"],
        displacement=ld["displacement"] if ld["displacement"] is not None else 1.0,
        max_events=ld["max_events"],
        drop=ld["end_load_drop"],
        residual=mem["residual"],
        workers=resolved["solver"]["workers"],
    )
    return p, st


def check(resolved, file) -> list:
    """``polydem check``: build the lattice and the first mesh, say what will run."""
    p, st = _problem(resolved)
    ad = resolved["adaptive"]["enabled"]
    lines = [
        f"{file}: OK — quasi-static, {p.lat.n_nodes:,} lattice nodes, {p.lat.n_members:,} members "
        f"({resolved['members']['law']}), " + ("adaptive" if ad else "fully resolved")
    ]
    if ad:
        lv = st.levels()
        lines.append(
            f"  first mesh: {len(st.elements):,} elements (levels 1/2/3: "
            f"{' / '.join(str(int(np.sum(lv == q))) for q in (1, 2, 3))}), {st.model.dofs:,} DOFs"
        )
    if p.aggregates:
        lines.append(f"  {len(p.aggregates)} aggregates")
    return lines


def _attrs(resolved, scenario_file, scenario_text, overrides):
    from ..engine.runner import code_version

    return {
        "format": FORMAT,
        "format_version": FORMAT_VERSION,
        "solver": "quasistatic",
        "code_version": code_version(),
        "created": _dt.datetime.now(_dt.timezone.utc).isoformat(timespec="seconds"),
        "scenario_file": str(scenario_file),
        "scenario_text": scenario_text,
        "resolved": json.dumps(resolved),
        "overrides": json.dumps(list(overrides)),
        "title": resolved["scenario"]["title"],
        "units": "cm, g, s (force dyn, stiffness dyn/cm, energy erg)",
        "status": "running",
    }


def _open(path):
    from ..io.hdf5 import open_result

    return open_result(path, fmt=FORMAT, what="a quasi-static polydem result")


def _read_checkpoint(f):
    ck = f.get("checkpoint")
    if ck is None or int(ck["current"][0]) < 0:
        return None
    g = ck[f"slot{int(ck['current'][0])}"]
    return {k: g[k][...] for k in g}


def _write_checkpoint(f, state, history_count, stage_count, wall):
    ck = f.require_group("checkpoint")
    if "current" not in ck:
        ck.create_dataset("current", data=np.array([-1], np.int64))
    slot = 1 - int(ck["current"][0]) if int(ck["current"][0]) >= 0 else 0
    name = f"slot{slot}"
    if name in ck:
        del ck[name]
    g = ck.create_group(name)
    for k, v in state.items():
        g.create_dataset(k, data=v)
    g.create_dataset("history_count", data=np.array([history_count], np.int64))
    g.create_dataset("stage_count", data=np.array([stage_count], np.int64))
    g.create_dataset("wall_elapsed", data=np.array([wall]))
    f.flush()  # the slot is complete before the pointer names it
    ck["current"][0] = slot
    dmg = f.require_group("damage")
    if "tooth" in dmg:
        del dmg["tooth"]
    dmg.create_dataset("tooth", data=state["tooth"])
    f.flush()


def existing_state(out, resolved) -> str:
    from ..io.hdf5 import result_state

    return result_state(out, resolved, fmt=FORMAT, checkpoint=_read_checkpoint)


class _Progress:
    def __init__(self, st, quiet, stream):
        self.st, self.quiet, self.stream = st, quiet, stream
        self.tty = hasattr(stream, "isatty") and stream.isatty()
        self.every = 0.5 if self.tty else 10.0
        self.last = 0.0
        self.t0 = time.time()
        self.s0 = st.solves

    def update(self, row, force=False):
        from ..coupling.stepper import COL

        if self.quiet or row is None:
            return
        now = time.time()
        if not force and now - self.last < self.every:
            return
        self.last = now
        st = self.st
        rate = (st.solves - self.s0) / max(now - self.t0, 1e-9)
        if st.softening:
            done = f"event {st.events:,} of at most {st.max_events:,}"
            frac = st.events / st.max_events
        else:
            done = f"stage {st.solves}"
            frac = st.solves / (int(st.ad["max_stages"]) if st.ad else 1)
        msg = (
            f"[{100.0 * min(frac, 1.0):5.1f}%] solve {st.solves:,} | {done} | u1 = {row[COL['u1']]:.5g} cm, "
            f"reaction {row[COL['reaction']]:.4g} dyn (peak {st.peak:.4g}) | {int(row[COL['dofs']]):,} DOFs | "
            f"{rate:.3g} solves/s"
        )
        from ..engine.runner import write_progress

        write_progress(self.stream, self.tty, msg, force, width=120)


def run(
    resolved=None,
    *,
    out,
    scenario_file="",
    scenario_text="",
    overrides=(),
    resume=False,
    quiet=False,
    stream=None,
    stop_after_solves=None,
):
    """Run (or resume) a quasi-static scenario and write its result; returns the summary dict
    (``stop_after_solves``: tests only, ends the session as if killed after a final checkpoint)."""
    from ..io.hdf5 import result_lock

    with result_lock(out):
        return _run(
            resolved,
            Path(out),
            scenario_file,
            scenario_text,
            overrides,
            resume,
            quiet,
            stream or sys.stderr,
            stop_after_solves,
        )


def _run(resolved, out, scenario_file, scenario_text, overrides, resume, quiet, stream, stop_after_solves):
    from ..coupling.stepper import COLUMNS
    from ..engine.runner import AlreadyFinished, Interrupted, _catch_signals, _restore_signals, code_version
    from ..engine.simulation import EngineError
    from ..io.hdf5 import ResultError

    t_start = time.time()
    rss0 = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    prior_wall = 0.0
    if resume:
        with _open(out) as f:
            if f.attrs.get("status") == "finished":
                raise AlreadyFinished(json.loads(f.attrs["summary"]) if "summary" in f.attrs else {})
            ck = _read_checkpoint(f)
            if ck is None:
                raise ResultError(f"{out}: no checkpoint to resume from; start the run again with --overwrite")
            resolved = json.loads(f.attrs["resolved"])
            written_by = f.attrs["code_version"]
        if written_by != code_version() and not quiet:
            stream.write(f"warning: {out} was written by polydem {written_by}, resuming with {code_version()}\n")
    p, st = _problem(resolved)
    import h5py

    if resume:
        st.restore(ck)
        prior_wall = float(ck["wall_elapsed"][0])
        f = h5py.File(out, "a")
        nh = int(ck["history_count"][0])
        ns = int(ck["stage_count"][0])
        f["history/table"].resize(nh, axis=0)
        for name in list(f["stages"]):
            if int(name) >= ns:
                del f["stages"][name]
        f.attrs["status"] = "running"
        if not quiet:
            stream.write(f"resuming {out} from solve {st.solves:,} ({st.events:,} events)\n")
    else:
        out.parent.mkdir(parents=True, exist_ok=True)
        f = h5py.File(out, "w")
        f.attrs.update(_attrs(resolved, scenario_file, scenario_text, overrides))
        g = f.create_group("lattice")
        g["x"], g["ij"], g["members"] = p.lat.x, p.lat.ij, p.lat.members
        g["k"], g["f_t"] = p.k, p.f
        g["aggregates"] = np.array(p.aggregates, float).reshape(-1, 3)
        h = f.create_group("history")
        t = h.create_dataset(
            "table", shape=(0, len(COLUMNS)), maxshape=(None, len(COLUMNS)), chunks=(256, len(COLUMNS)), dtype="f8"
        )
        t.attrs["columns"] = json.dumps([list(c) for c in COLUMNS])
        f.create_group("stages")
        nh = ns = 0
        _write_checkpoint(f, st.state(), 0, 0, 0.0)
        if not quiet:
            stream.write(
                f"{p.lat.n_nodes:,} lattice nodes, {p.lat.n_members:,} members ({resolved['members']['law']}), "
                + ("adaptive" if st.ad else "fully resolved")
                + "\n"
            )
    interrupted = []
    old = _catch_signals(interrupted)
    failure = None
    prog = _Progress(st, quiet, stream)
    row = None
    solves_run = 0
    t_loop = time.time()
    try:
        last_ck = time.time()
        interval = float(resolved["output"]["checkpoint_interval"])
        while not st.done:
            if st.ad is not None and st.mesh_changed:
                g = f["stages"].create_group(f"{ns:04d}")
                g["elements"] = np.array(st.elements, np.int64).reshape(-1, 4)
                g["level"] = st.levels()
                g.attrs["solve"] = st.solves + 1
                st.mesh_changed = False
                ns += 1
            row = st.advance()
            solves_run += 1
            if not np.all(np.isfinite(row)):
                raise EngineError(
                    f"solve {st.solves}: non-finite result (a singular system: a part of the lattice "
                    f"has lost every member)"
                )
            tab = f["history/table"]
            tab.resize(nh + 1, axis=0)
            tab[nh] = row
            nh += 1
            prog.update(row)
            if time.time() - last_ck >= interval:
                _write_checkpoint(f, st.state(), nh, ns, prior_wall + time.time() - t_start)
                last_ck = time.time()
            if interrupted:
                stream.write(
                    f"\ninterrupted by signal {interrupted[0]} at solve {st.solves:,}; "
                    f"continue with: polydem run --resume {out}\n"
                )
                break
            if stop_after_solves is not None and st.solves >= stop_after_solves:
                break
        prog.update(row, force=True)
    except EngineError as e:
        failure = str(e)
    finally:
        _restore_signals(old)
        wall = prior_wall + time.time() - t_start
        _write_checkpoint(f, st.state(), nh, ns, wall)
        summary = _summary(resolved, p, st, f, out, wall, time.time() - t_loop, solves_run, resume, failure, rss0)
        f.attrs["status"] = summary["status"]
        f.attrs["summary"] = json.dumps(summary)
        f.close()
        from ..engine.runner import summary_path

        summary_path(out).write_text(json.dumps(summary, indent=1))
    if failure:
        raise EngineError(failure)
    if interrupted:
        raise Interrupted(interrupted[0])
    return summary


def _summary(resolved, p, st, f, out, wall, wall_loop, solves_run, resume, failure, rss0):
    from ..coupling.stepper import COL, ELASTIC, EVENT
    from ..engine.runner import code_version

    h = f["history/table"][...]
    kind = EVENT if st.softening else ELASTIC
    ev = h[h[:, COL["kind"]] == kind] if len(h) else h
    finished = st.done and failure is None
    out_ = {
        "result": str(out),
        "title": resolved["scenario"]["title"],
        "solver": "quasistatic",
        "code_version": code_version(),
        "status": "finished" if finished else ("failed" if failure else "incomplete"),
        "failure": failure,
        "resumed": bool(resume),
        "end_reason": st.end_reason,
        "adaptive": st.ad is not None,
        "law": resolved["members"]["law"],
        "nodes": p.lat.n_nodes,
        "members": p.lat.n_members,
        "lattice_dofs": 2 * p.lat.n_nodes,
        "solves": st.solves,
        "events": st.events,
        "refinement_solves": st.refinements,
        "max_dofs": int(h[:, COL["dofs"]].max()) if len(h) else 0,
        "final_dofs": int(h[-1, COL["dofs"]]) if len(h) else 0,
        "final_elements": int(h[-1, COL["elements"]]) if len(h) else 0,
        "final_levels": [int(h[-1, COL[c]]) for c in ("level1", "level2", "level3")] if len(h) else [0, 0, 0],
        "damaged_members": int(np.count_nonzero(st.tooth)),
        "wall_time_s": wall,
        "solve_wall_time_s": float(h[:, COL["wall"]].sum()) if len(h) else 0.0,
        "solves_per_s": solves_run / wall_loop if wall_loop > 0 else 0.0,
        "peak_rss_growth_MiB": (resource.getrusage(resource.RUSAGE_SELF).ru_maxrss - rss0) / 1024.0,
    }
    if len(ev):
        k = int(np.argmax(np.abs(ev[:, COL["reaction"]])))
        out_["peak_reaction"] = float(ev[k, COL["reaction"]])
        out_["u1_at_peak"] = float(ev[k, COL["u1"]])
        if not st.softening:
            out_["reaction"] = float(ev[-1, COL["reaction"]])
            out_["stiffness"] = float(ev[-1, COL["reaction"]] / ev[-1, COL["u1"]])
    return out_


def summary_lines(sm: dict) -> list:
    out = []
    if sm.get("end_reason"):
        out.append(f"end: {sm['end_reason']}")
    if "stiffness" in sm:
        out.append(
            f"reaction {sm['reaction']:.6g} dyn at u1 = {sm['u1_at_peak']:.4g} cm (stiffness {sm['stiffness']:.6g} dyn/cm)"
        )
    elif "peak_reaction" in sm:
        out.append(
            f"peak reaction {sm['peak_reaction']:.6g} dyn at u1 = {sm['u1_at_peak']:.5g} cm; {sm['events']:,} events, "
            f"{sm['damaged_members']:,} members damaged"
        )
    out.append(
        f"DOFs: {sm['final_dofs']:,} at the end, at most {sm['max_dofs']:,} (the lattice has {sm['lattice_dofs']:,})"
        + (
            f"; {sm['final_elements']:,} elements, levels 1/2/3 {' / '.join(map(str, sm['final_levels']))}, "
            f"{sm['refinement_solves']} refinement solves"
            if sm["adaptive"]
            else ""
        )
    )
    return out


def load_curve(result):
    """(û1 [cm], reaction [dyn]) of a saw-tooth run from the unloaded state through its events, or None for a run
    without events (an elastic run has one load, refined in stages: no curve to overlay)."""
    from ..coupling.stepper import COL, EVENT

    with _open(result) as f:
        h = f["history/table"][...]
    ev = h[h[:, COL["kind"]] == EVENT] if len(h) else h
    if not len(ev):
        return None
    return np.concatenate([[0.0], ev[:, COL["u1"]]]), np.concatenate([[0.0], ev[:, COL["reaction"]]])


def overlay(results, png, save=None) -> bool:
    """The load–displacement curves of several quasi-static results in one figure, with a legend and each
    peak marked (``polydem report A.h5 B.h5``); False if fewer than two have a curve."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    curves = [(Path(r).stem, load_curve(r)) for r in results]
    curves = [(n, c) for n, c in curves if c is not None]
    if len(curves) < 2:
        return False
    top = max(float(np.abs(c[1]).max()) for _, c in curves)
    sc, unit = (1e3, "10³ dyn") if top >= 1e3 else (1.0, "dyn")
    fig, ax = plt.subplots(figsize=(6.5, 4.2))
    for name, (u, r) in curves:
        (ln,) = ax.plot(u, r / sc, ".-", ms=2, lw=0.7, label=name)
        k = int(np.argmax(r))
        ax.plot([u[k]], [r[k] / sc], "v", color=ln.get_color(), ms=6)
    ax.set(
        xlabel="displacement of the right edge û1 [cm]",
        ylabel=f"reaction on the right edge [{unit}]",
        title="overlay (saw-tooth events from the unloaded state; ▼ peaks)",
    )
    ax.legend(fontsize=8, loc="best")
    fig.tight_layout()
    (save or (lambda fig, path, **kw: fig.savefig(path, **kw)))(fig, png, dpi=200)
    plt.close(fig)
    return True


def report(result, out_dir=None, notes=None, save=None) -> list:
    """Figures of a quasi-static result: the load–displacement curve (events, or the reaction per refinement
    stage of an elastic run against its DOFs), and per stored mesh the level map with the damaged members.
    ``save(fig, path, dpi=...)``: the report layer's saver (extra formats, plotted-data CSV); default
    ``fig.savefig``."""
    import textwrap

    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.collections import LineCollection, PolyCollection

    from ..coupling.mesh import corners
    from ..coupling.stepper import COL, COLUMNS, ELASTIC, EVENT

    if save is None:

        def save(fig, path, **kw):
            fig.savefig(path, **kw)

    result = Path(result)
    out_dir = Path(out_dir) if out_dir else result.parent
    out_dir.mkdir(parents=True, exist_ok=True)
    files = []
    with _open(result) as f:
        h = f["history/table"][...]
        x = f["lattice/x"][...]
        ij = f["lattice/ij"][...]
        members = f["lattice/members"][...]
        aggs = f["lattice/aggregates"][...]
        tooth = f["damage/tooth"][...]
        stages = [
            (int(f["stages"][s].attrs["solve"]), f["stages"][s]["elements"][...], f["stages"][s]["level"][...])
            for s in sorted(f["stages"])
        ]
        title = f.attrs["title"]
    if len(h) == 0:
        if notes is not None:
            notes.append(f"{result}: no solve recorded; nothing to draw")
        return files
    stem = result.stem
    fig, ax = plt.subplots(figsize=(6.5, 4.2))
    ev = h[h[:, COL["kind"]] == EVENT]
    el = h[h[:, COL["kind"]] == ELASTIC]
    if len(ev):
        # the path from the unloaded state: the origin, then the event states (the saw-tooth envelope)
        uu = np.concatenate([[0.0], ev[:, COL["u1"]]])
        rr = np.concatenate([[0.0], ev[:, COL["reaction"]]])
        sc, unit = (1e3, "10³ dyn") if np.abs(rr).max() >= 1e3 else (1.0, "dyn")
        ax.plot(uu, rr / sc, "k.-", ms=3, lw=0.6, label=f"saw-tooth events ({len(ev):,})")
        ax.set(xlabel="displacement of the right edge û1 [cm]", ylabel=f"reaction on the right edge [{unit}]")
        k = int(np.argmax(rr))
        ax.plot([uu[k]], [rr[k] / sc], "rv", ms=6, label=f"peak {rr[k]:.4g} dyn at û1 = {uu[k]:.4g} cm")
        ax.legend(fontsize=8, loc="lower right")
        name = out_dir / f"{stem}_load.png"
    else:
        ax.plot(el[:, COL["dofs"]], el[:, COL["reaction"]] / 1e3, "ko-", ms=4)
        for r in el:
            ax.annotate(
                f"{int(r[COL['elements']])} el.",
                (r[COL["dofs"]], r[COL["reaction"]] / 1e3),
                textcoords="offset points",
                xytext=(4, 4),
                fontsize=7,
            )
        ax.set(xlabel="degrees of freedom of the stage", ylabel=f"reaction at û1 = {el[0, COL['u1']]:g} cm [10³ dyn]")
        name = out_dir / f"{stem}_stages.png"
    ax.set_title("\n".join(textwrap.wrap(title, 90)), fontsize=9)
    fig.tight_layout()
    save(fig, name, dpi=200)
    plt.close(fig)
    files.append(name)
    node = {(int(i), int(j)): q for q, (i, j) in enumerate(ij)}
    colours = {1: "#d9d9d9", 2: "#fdae61", 3: "#2b83ba"}
    aspect = (np.ptp(x[:, 1]) + 1) / (np.ptp(x[:, 0]) + 1)

    def draw(ax, els, lev, damaged, title):
        if els is not None:
            polys = [x[[node[c] for c in corners(tuple(int(v) for v in e))]] for e in els]
            ax.add_collection(
                PolyCollection(polys, facecolors=[colours[int(v)] for v in lev], edgecolors="k", linewidths=0.15)
            )
        else:
            ax.add_collection(LineCollection(x[members], colors="0.75", linewidths=0.2))
        for cx, cy, r in aggs:
            ax.add_patch(plt.Circle((cx, cy), r, fill=False, lw=0.6, color="g"))
        if damaged.size:
            ax.add_collection(LineCollection(x[members[damaged]], colors="r", linewidths=1.2))
        ax.set_aspect("equal")
        ax.autoscale()
        ax.set(xlabel=r"$x_1$ [cm]", ylabel=r"$x_2$ [cm]")
        ax.set_title(title, fontsize=8)

    key = "levels: grey 1 (continuum), orange 2 (from the members), blue 3 (lattice);\ndamaged members red"
    damaged = np.flatnonzero(tooth)
    fig, ax = plt.subplots(figsize=(8, 8 * aspect + 0.8))
    if stages:
        s_, els, lev = stages[-1]
        draw(ax, els, lev, damaged, f"final mesh, stage {len(stages)} ({len(els):,} elements) — {key}")
    else:
        draw(ax, None, None, damaged, f"fully resolved lattice; damaged members ({damaged.size:,}) red")
    fig.tight_layout()
    name = out_dir / f"{stem}_mesh.png"
    save(fig, name, dpi=200)
    plt.close(fig)
    files.append(name)
    if len(stages) > 1:  # the refinement stages (at most six, evenly spread), damage as it was at each
        pick = sorted({int(round(q)) for q in np.linspace(0, len(stages) - 1, min(6, len(stages)))})
        nc = 2 if len(pick) > 1 else 1
        nr = (len(pick) + nc - 1) // nc
        fig, axes = plt.subplots(nr, nc, figsize=(6 * nc, (6 * aspect + 0.7) * nr), squeeze=False)
        for ax, q in zip(axes.ravel(), pick):
            s_, els, lev = stages[q]
            # the damage at the end of the stage (the last stage's is the run's, as in the summary)
            end = stages[q + 1][0] if q + 1 < len(stages) else np.inf
            during = h[(h[:, COL["solve"]] < end) & (h[:, COL["kind"]] == EVENT)]
            dmg = np.unique(during[:, COL["member"]].astype(np.int64))
            dofs = h[h[:, COL["solve"]] == s_, COL["dofs"]]
            draw(
                ax,
                els,
                lev,
                dmg,
                f"stage {q + 1}: from solve {s_}, {len(els):,} elements, "
                f"{int(dofs[0]) if dofs.size else 0:,} DOFs, {dmg.size} damaged at its end",
            )
        for ax in axes.ravel()[len(pick) :]:
            ax.set_visible(False)
        fig.suptitle(key, fontsize=8)
        fig.tight_layout()
        name = out_dir / f"{stem}_stages_mesh.png"
        save(fig, name, dpi=150)
        plt.close(fig)
        files.append(name)
    csv = out_dir / f"{stem}_history.csv"  # the plotted data, beside the figures
    with open(csv, "w") as fh:
        fh.write(",".join(n if u == "-" else f"{n} [{u}]" for n, u, _ in COLUMNS) + "\n")
        np.savetxt(fh, h, delimiter=",", fmt="%.10g")
    files.append(csv)
    return files
