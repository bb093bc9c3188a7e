"""The quasi-static solver family (``[solver] kind = "quasistatic"``): the lattice analyses of
:mod:`polydem_cli.coupling.stepper`, one solve per step, run by the one driver (:mod:`.driver`: lock, writer
process, checksummed checkpoints, progress, clean stop on SIGINT/SIGTERM, resume, summary).

Result file (HDF5, written by the writer process of io/hdf5.py with a Fletcher-32 checksum on every dataset;
``format = "polydem-quasistatic"``, ``format_version = 2``; version 1 files, written in-process without
checksums, are still read by the report)::

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
    /checkpoint/slot0, slot1, current   the stepper state (tooth, counters, peak, elements; factor_k (m,) the
              member stiffnesses at the last factorisation of the system and factor_log (r, 3) the changes since —
              fully resolved: member, stiffness before, after; adaptive: change, member, stiffness after — from
              which a resumed run rebuilds the factor bit for bit, coupling/factor.py), step (= solves),
              history_count, stage_count, wall_elapsed; two slots, the current one named by "current"

A result is a time series of solves, not of time: ``polydem report`` draws the load–displacement curve, the
mesh and level map of every stage and the damaged members.
"""

from __future__ import annotations

import json
import os
import resource
import sys
import time
from pathlib import Path

import numpy as np

from .._jit_cache import cached
from ..coupling.stepper import COL, COLUMNS, ELASTIC, EVENT, REFINE
from ..engine.simulation import EngineError
from ..io.provenance import code_version
from . import driver
from .progress import Ticker
from .protocol import DEFAULT_OPTIONS, NO_SOURCE, RunOptions, SolverFamily, Source

FORMAT = "polydem-quasistatic"
#: 2: written by the writer process with checksums, "step" in the checkpoint (1: written in-process)
FORMAT_VERSION = 2


def _problem(resolved):
    from ..coupling.problem import member_teeth
    from ..coupling.scenario import build_problem
    from ..coupling.stepper import Stepper

    p = build_problem(resolved)
    mem = resolved["members"]
    teeth = member_teeth(p, mem["ductility"], mem["teeth"]) if p.softening else None
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


def _open(path):
    from ..io.hdf5 import open_result

    return open_result(path, fmt=FORMAT, what="a quasi-static polydem result")


class QSProgress(Ticker):
    """Solves, events (or stages), the load and the reaction, the DOFs and solves/s."""

    def __init__(self, st, quiet, stream):
        super().__init__(quiet, stream)
        self.st = st
        self.t0 = time.time()
        self.s0 = st.solves

    def update(self, row, force=False):
        if row is None or not self.due(force):
            return
        st = self.st
        rate = (st.solves - self.s0) / max(time.time() - self.t0, 1e-9)
        if st.softening:
            done = f"event {st.events:,} of at most {st.max_events:,}"
            frac = st.events / st.max_events
            # a refinement solve's reaction is where the next member would break on the coarser mesh, not an event
            what = "next event at" if int(row[COL["kind"]]) == REFINE else "event at"
            peak = f", peak so far {st.peak:.4g} dyn" if st.events else ", no event yet"
        else:
            done = f"stage {st.solves}"
            frac = st.solves / (int(st.ad["max_stages"]) if st.ad else 1)
            what, peak = "at", ""
        msg = (
            f"[{100.0 * min(frac, 1.0):5.1f}%] solve {st.solves:,} | {done} | {what} u1 = {row[COL['u1']]:.5g} cm "
            f"reaction {row[COL['reaction']]:.4g} dyn{peak} | {int(row[COL['dofs']]):,} DOFs | {rate:.3g} solves/s"
        )
        self.emit(msg, force, width=120)


class QuasiStaticFamily(SolverFamily):
    """One solve per step of the lattice analyses (coupling/stepper.py), run by the driver (:mod:`.driver`)."""

    KIND = "quasistatic"
    FORMAT = FORMAT
    UNIT = "solve"

    def __init__(self, resolved, source=NO_SOURCE, opts=DEFAULT_OPTIONS, fresh=True):
        self.resolved = resolved
        self.quiet, self.stream = opts.quiet, opts.stream or sys.stderr
        self.rss0 = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
        self.t_compile = None
        if not cached("coupling*/meshkern.*.nbi") or not cached("coupling*/factor.*.nbi"):
            self.t_compile = time.time()  # a cold cache: half a minute without output otherwise
            if not self.quiet:
                self.stream.write(
                    "compiling the lattice and coupling kernels (first run after installation or a code change; "
                    f"about half a minute, then cached in {os.environ.get('NUMBA_CACHE_DIR', '.jit_cache/')})\n"
                )
                self.stream.flush()
        self.p, self.st = _problem(resolved)
        self.rows = []  # every history row (the summary's), resumed ones included
        self.ns = 0  # stages stored
        self.row = None

    @property
    def work(self):
        return self.st.solves

    def create(self, writer, attrs):
        p, st = self.p, self.st
        attrs = {"format": FORMAT, "format_version": FORMAT_VERSION, "solver": self.KIND} | attrs
        attrs["units"] = "cm, g, s (force dyn, stiffness dyn/cm, energy erg)"
        writer.send("new", attrs=attrs)
        lat = {"x": p.lat.x, "ij": p.lat.ij, "members": p.lat.members, "k": p.k, "f_t": p.f}
        lat["aggregates"] = np.array(p.aggregates, float).reshape(-1, 3)
        writer.send("group", path="lattice", data=lat)
        writer.send(
            "table", ncols=len(COLUMNS), attrs={"columns": json.dumps([list(c) for c in COLUMNS])}, chunk_rows=256
        )
        writer.send("group", path="stages", data={})
        if not self.quiet:
            self.stream.write(
                f"{p.lat.n_nodes:,} lattice nodes, {p.lat.n_members:,} members ({self.resolved['members']['law']}), "
                + ("adaptive" if st.ad else "fully resolved")
                + "\n"
            )

    def restore(self, back):
        ck = back.checkpoint
        self.st.restore(ck)
        self.rows = list(back.kept)
        self.ns = int(ck["stage_count"][0])
        return {"history_keep": len(self.rows), "trim": {"stages": self.ns}}

    def resume_note(self, out):
        return f"resuming {out} from solve {self.st.solves:,} ({self.st.events:,} events)"

    def warm_up(self):
        self.prog = QSProgress(self.st, self.quiet, self.stream)

    def done(self):
        return self.st.done

    def finished(self):
        return self.st.done

    def advance(self, writer, limit):
        st = self.st
        if st.ad is not None and st.mesh_changed:
            data = {"elements": np.array(st.elements, np.int64).reshape(-1, 4), "level": st.levels()}
            writer.send("group", path=f"stages/{self.ns:04d}", data=data, attrs={"solve": st.solves + 1})
            st.mesh_changed = False
            self.ns += 1
        row = st.advance()
        if not np.all(np.isfinite(row)):
            raise EngineError(
                f"solve {st.solves}: non-finite result (a singular system: a part of the lattice has lost every member)"
            )
        writer.send("history", rows=row[None, :])
        self.rows.append(row)
        self.row = row

    def run_state(self):
        from .protocol import RunState

        row = {} if self.row is None else {c[0]: float(v) for c, v in zip(COLUMNS, self.row)}
        return RunState(work=int(self.st.solves), time=None, history=row)

    def progress(self, final=False):
        if self.t_compile is not None:  # the kernels are compiled by the set-up and the first solve
            if not self.quiet:
                self.stream.write(f"compiled in {time.time() - self.t_compile:.0f} s (with the first solve)\n")
            self.t_compile = None
        self.prog.update(self.row, force=final)

    def checkpoint(self):
        state = self.st.state() | {"step": np.array([self.st.solves], np.int64)}
        return state, {"history_count": len(self.rows), "stage_count": self.ns}

    def records(self):
        return [("put", {"path": "damage/tooth", "data": self.st.tooth})]

    def summary(self, info):
        return _summary(self, info)


FAMILY = QuasiStaticFamily


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
    """Run (or resume) a quasi-static scenario through the driver and return the summary
    (``stop_after_solves``: tests only, ends the session as if killed after a final checkpoint)."""
    opts = RunOptions(quiet=quiet, stream=stream, stop_after=stop_after_solves)
    src = Source(str(scenario_file), scenario_text, tuple(overrides))
    return driver.run(resolved, out=out, source=src, resume=resume, opts=opts)


def _summary(fam, info):
    resolved, p, st = fam.resolved, fam.p, fam.st
    h = np.array(fam.rows).reshape(-1, len(COLUMNS))
    kind = EVENT if st.softening else ELASTIC
    ev = h[h[:, COL["kind"]] == kind] if len(h) else h
    out_ = {
        "result": str(info.out),
        "title": resolved["scenario"]["title"],
        "solver": "quasistatic",
        "code_version": code_version(),
        "status": "finished" if info.finished else ("failed" if info.failure else "incomplete"),
        "failure": info.failure,
        "resumed": bool(info.resumed),
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
        "wall_time_s": info.wall,
        "solve_wall_time_s": float(h[:, COL["wall"]].sum()) if len(h) else 0.0,
        "solves_per_s": info.work_run / info.wall_loop if info.wall_loop > 0 else 0.0,
        "peak_rss_growth_MiB": (resource.getrusage(resource.RUSAGE_SELF).ru_maxrss - fam.rss0) / 1024.0,
    }
    if len(ev):
        k = int(np.argmax(np.abs(ev[:, COL["reaction"]])))
        out_["peak_reaction"] = float(ev[k, COL["reaction"]])
        out_["u1_at_peak"] = float(ev[k, COL["u1"]])
        if not st.softening:
            out_["reaction"] = float(ev[-1, COL["reaction"]])
            out_["stiffness"] = float(ev[-1, COL["reaction"]] / ev[-1, COL["u1"]])
    return out_


def headline(out, summary: dict) -> str:
    """The one-line account printed when a quasi-static run has written its result."""
    return (
        f"wrote {out} ({summary['solves']:,} solves, {summary['nodes']:,} lattice nodes, "
        f"{summary['wall_time_s']:.1f} s wall)"
    )


def table_row(summary: dict) -> dict:
    """A variant's sweep columns: status, end, wall time, solves, the peak (or elastic) reaction, damage, DOFs."""
    cols = {
        "status": summary["status"],
        "end": summary.get("end_reason"),
        "wall time [s]": summary["wall_time_s"],
        "solves": summary["solves"],
        "events": summary["events"],
    }
    for name, key in (
        ("peak reaction [dyn]", "peak_reaction"),
        ("u1 at peak [cm]", "u1_at_peak"),
        ("stiffness [dyn/cm]", "stiffness"),
    ):
        if key in summary:
            cols[name] = summary[key]
    cols["damaged members"] = summary["damaged_members"]
    cols["final DOFs"] = summary["final_dofs"]
    return cols


def summary_lines(sm: dict) -> list:
    """Short human-readable account of a quasi-static run's summary (its end, reaction or peak, events)."""
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
    with _open(result) as f:
        h = f["history/table"][...]
    ev = h[h[:, COL["kind"]] == EVENT] if len(h) else h
    if not len(ev):
        return None
    return np.concatenate([[0.0], ev[:, COL["u1"]]]), np.concatenate([[0.0], ev[:, COL["reaction"]]])


def overlay(results, png, save=None) -> bool:
    """The load–displacement curves of several quasi-static results in one figure, with a legend and each
    peak marked (``polydem report A.h5 B.h5``); False if fewer than two have a curve."""
    from ..mpl import pyplot

    plt = pyplot()

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


def _read_for_report(result) -> dict:
    with _open(result) as f:
        return {
            "h": f["history/table"][...],
            "x": f["lattice/x"][...],
            "ij": f["lattice/ij"][...],
            "members": f["lattice/members"][...],
            "aggs": f["lattice/aggregates"][...],
            "tooth": f["damage/tooth"][...],
            "stages": [
                (int(f["stages"][s].attrs["solve"]), f["stages"][s]["elements"][...], f["stages"][s]["level"][...])
                for s in sorted(f["stages"])
            ],
            "title": f.attrs["title"],
        }


def _load_figure(plt, d, out_dir, stem, save) -> Path:
    """The load–displacement curve of the events from the unloaded state, or an elastic run's reaction per
    refinement stage against its DOFs."""
    import textwrap

    h = d["h"]
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
    ax.set_title("\n".join(textwrap.wrap(d["title"], 90)), fontsize=9)
    fig.tight_layout()
    save(fig, name, dpi=200)
    plt.close(fig)
    return name


class _MeshDrawing:
    """Draws a mesh (level colours), the aggregates and the damaged members of a quasi-static result."""

    COLOURS = {1: "#d9d9d9", 2: "#fdae61", 3: "#2b83ba"}
    KEY = "levels: grey 1 (continuum), orange 2 (from the members), blue 3 (lattice);\ndamaged members red"

    def __init__(self, plt, d):
        self.plt, self.d = plt, d
        x = d["x"]
        self.node = {(int(i), int(j)): q for q, (i, j) in enumerate(d["ij"])}
        self.aspect = (np.ptp(x[:, 1]) + 1) / (np.ptp(x[:, 0]) + 1)

    def draw(self, ax, els, lev, damaged, title):
        from matplotlib.collections import LineCollection, PolyCollection

        from ..coupling.mesh import corners

        x, members = self.d["x"], self.d["members"]
        if els is not None:
            polys = [x[[self.node[c] for c in corners(tuple(int(v) for v in e))]] for e in els]
            faces = [self.COLOURS[int(v)] for v in lev]
            ax.add_collection(PolyCollection(polys, facecolors=faces, edgecolors="k", linewidths=0.15))
        else:
            ax.add_collection(LineCollection(x[members], colors="0.75", linewidths=0.2))
        for cx, cy, r in self.d["aggs"]:
            ax.add_patch(self.plt.Circle((cx, cy), r, fill=False, lw=0.6, color="g"))
        if damaged.size:
            ax.add_collection(LineCollection(x[members[damaged]], colors="r", linewidths=1.2))
        ax.set_aspect("equal")
        ax.autoscale()
        ax.set(xlabel=r"$x_1$ [cm]", ylabel=r"$x_2$ [cm]")
        ax.set_title(title, fontsize=8)

    def final(self, name, save):
        plt, stages = self.plt, self.d["stages"]
        damaged = np.flatnonzero(self.d["tooth"])
        fig, ax = plt.subplots(figsize=(8, 8 * self.aspect + 0.8))
        if stages:
            _, els, lev = stages[-1]
            self.draw(ax, els, lev, damaged, f"final mesh, stage {len(stages)} ({len(els):,} elements) — {self.KEY}")
        else:
            self.draw(ax, None, None, damaged, f"fully resolved lattice; damaged members ({damaged.size:,}) red")
        fig.tight_layout()
        save(fig, name, dpi=200)
        plt.close(fig)

    def stages(self, name, save):
        """The refinement stages (at most six, evenly spread), each with the damage at its end (the last
        stage's is the run's, as in the summary)."""
        plt, stages, h = self.plt, self.d["stages"], self.d["h"]
        pick = sorted({int(round(q)) for q in np.linspace(0, len(stages) - 1, min(6, len(stages)))})
        nc = 2 if len(pick) > 1 else 1
        nr = (len(pick) + nc - 1) // nc
        fig, axes = plt.subplots(nr, nc, figsize=(6 * nc, (6 * self.aspect + 0.7) * nr), squeeze=False)
        for ax, q in zip(axes.ravel(), pick):
            s_, els, lev = stages[q]
            end = stages[q + 1][0] if q + 1 < len(stages) else np.inf
            during = h[(h[:, COL["solve"]] < end) & (h[:, COL["kind"]] == EVENT)]
            dmg = np.unique(during[:, COL["member"]].astype(np.int64))
            dofs = h[h[:, COL["solve"]] == s_, COL["dofs"]]
            self.draw(
                ax,
                els,
                lev,
                dmg,
                f"stage {q + 1}: from solve {s_}, {len(els):,} elements, "
                f"{int(dofs[0]) if dofs.size else 0:,} DOFs, {dmg.size} damaged at its end",
            )
        for ax in axes.ravel()[len(pick) :]:
            ax.set_visible(False)
        fig.suptitle(self.KEY, fontsize=8)
        fig.tight_layout()
        save(fig, name, dpi=150)
        plt.close(fig)


def report(result, out_dir=None, notes=None, save=None) -> list:
    """Figures of a quasi-static result: the load–displacement curve (events, or the reaction per refinement
    stage of an elastic run against its DOFs), and per stored mesh the level map with the damaged members.
    ``save(fig, path, dpi=...)``: the report layer's saver (extra formats, plotted-data CSV); default
    ``fig.savefig``."""
    from ..mpl import pyplot

    plt = pyplot()

    if save is None:

        def save(fig, path, **kw):
            fig.savefig(path, **kw)

    result = Path(result)
    out_dir = Path(out_dir) if out_dir else result.parent
    out_dir.mkdir(parents=True, exist_ok=True)
    d = _read_for_report(result)
    if len(d["h"]) == 0:
        if notes is not None:
            notes.append(f"{result}: no solve recorded; nothing to draw")
        return []
    stem = result.stem
    files = [_load_figure(plt, d, out_dir, stem, save)]
    drawing = _MeshDrawing(plt, d)
    files.append(out_dir / f"{stem}_mesh.png")
    drawing.final(files[-1], save)
    if len(d["stages"]) > 1:
        files.append(out_dir / f"{stem}_stages_mesh.png")
        drawing.stages(files[-1], save)
    csv = out_dir / f"{stem}_history.csv"  # the plotted data, beside the figures
    with open(csv, "w") as fh:
        fh.write(",".join(n if u == "-" else f"{n} [{u}]" for n, u, _ in COLUMNS) + "\n")
        np.savetxt(fh, d["h"], delimiter=",", fmt="%.10g")
    files.append(csv)
    return files
