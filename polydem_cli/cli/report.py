"""``polydem report``."""

from __future__ import annotations

import sys
import tempfile
from pathlib import Path

import click


@click.command("report")
@click.argument("results", nargs=-1, required=True, type=click.Path(dir_okay=False, path_type=Path))
@click.option(
    "--out", type=click.Path(file_okay=False, path_type=Path), help="output directory (default: beside RESULT)"
)
@click.option("--times", default="", help="comma-separated frame times for the snapshots, e.g. 0,0.5,1")
@click.option(
    "--states",
    default="",
    help="bonded results: comma-separated displacements û2 of the marked states "
    "(load curve and damage maps; default: automatic z1-z4 / d1-d4)",
)
@click.option(
    "--movie",
    "movie",
    is_flag=False,
    flag_value="gif",
    default=None,
    type=click.Choice(["gif", "mp4"]),
    help="also an animation of all frames with one colour scale (gif through Pillow; mp4 needs ffmpeg)",
)
@click.option(
    "--format",
    "formats",
    default="png",
    show_default=True,
    metavar="png[,pdf,svg]",
    help="file formats of every figure (pdf and svg are vector graphics for print)",
)
@click.option(
    "--at",
    "at",
    multiple=True,
    metavar="t=SECONDS|u2=CM",
    help="a snapshot at a time (t=0.012) or at a prescribed displacement of a bonded specimen (u2=-0.15); "
    "repeatable; the same as --times / --states",
)
@click.option(
    "--magnify",
    type=click.FloatRange(min=0.0, min_open=True),
    default=1.0,
    show_default=True,
    help="displacement magnification of the particle pictures (bonded specimens: e.g. 200, said in each figure)",
)
@click.option(
    "--region",
    default="",
    metavar="X0,X1,Y0,Y1",
    help="instead of the full report: the particle snapshots (--times) in this window [cm], <result>_closeup.png",
)
@click.option(
    "--mark",
    "marks",
    multiple=True,
    metavar="X,Y",
    help="with --region: outline and number the particle nearest to (X, Y) [cm] at t = 0 in every snapshot "
    "(repeatable), to follow it",
)
def report_cmd(results, out, times, states, movie, formats, at, magnify, region, marks):
    """Plots of a result: energies, contacts, load–displacement, particle snapshots, and for
    bonded specimens the load curve with marked states, damage maps and strain maps (PNG).
    Quasi-static results: the load–displacement curve (or the reaction per refinement stage), the
    final mesh with its levels and damaged members, the refinement stages, the history as CSV.

    Several RESULTs: the figures of each, and overlays of their curves with a legend
    (overlay_stress_strain.png for specimens with macroscopic measures, else overlay_load.png).

    \b
    Example:
      polydem report outputs/demo_hex_pile.h5 --times 0,0.2,0.4
      polydem report outputs/ch7/tension_fast_ru.h5 outputs/ch7/tension_fast_ra.h5 --out outputs/cmp
    """
    try:
        tl = [float(t) for t in times.split(",") if t.strip()] if times else None
        sl = [float(t) for t in states.split(",") if t.strip()] if states else None
    except ValueError:
        click.echo("error: --times/--states: expected comma-separated numbers", err=True)
        sys.exit(2)
    for a in at:
        key, _, val = a.partition("=")
        try:
            v = float(val)
        except ValueError:
            v = None
        if key.strip() not in ("t", "u2") or v is None:
            click.echo(f"error: --at {a}: expected t=<seconds> or u2=<cm>, e.g. --at t=0.012 --at u2=-0.15", err=True)
            sys.exit(2)
        if key.strip() == "t":
            tl = (tl or []) + [v]
        else:
            sl = (sl or []) + [v]
    fmts = [f.strip().lower() for f in formats.split(",") if f.strip()]
    bad = [f for f in fmts if f not in ("png", "pdf", "svg")]
    if bad or not fmts:
        click.echo(f"error: --format {formats}: formats are png, pdf and svg (comma-separated)", err=True)
        sys.exit(2)
    reg = pts = None
    if region or marks:
        try:
            reg = [float(v) for v in region.split(",")] if region else None
            pts = [tuple(float(v) for v in m.split(",")) for m in marks]
        except ValueError:
            reg, pts = None, [()]
        if reg is None or len(reg) != 4 or reg[0] >= reg[1] or reg[2] >= reg[3] or any(len(q) != 2 for q in pts):
            click.echo(
                f"error: --region {region!r} --mark {' '.join(marks)!r}: expected --region X0,X1,Y0,Y1 with X0 < X1, "
                "Y0 < Y1 (cm) and --mark X,Y (repeatable), e.g. --region 3,10,2,8 --mark 6.35,6.6",
                err=True,
            )
            sys.exit(2)
    from .outputs import Stopped, listing, stop_on_signals, writable_dir, writing

    # every folder the figures go to is checked before any work (a result that does not exist is said by the reader)
    dests = [out] if out else list(dict.fromkeys(r.parent for r in results if r.exists()))
    for d in dests:
        writable_dir(d, "the report")
    before = listing(dests)
    done = []  # the results whose figures are all written
    try:
        with stop_on_signals(), writing(dests[0] if dests else Path(".")):
            if reg is not None:
                _closeups(results, out, tl, reg, pts, fmts, magnify, done)
            else:
                _report(results, out, tl, sl, fmts, magnify, movie, done)
    except (Stopped, KeyboardInterrupt) as e:
        signum = getattr(e, "signum", 2)
        _say_stopped(signum, results, done, dests, before)
        sys.exit(128 + signum)  # as polydem run: 130 for SIGINT (Ctrl-C), 143 for SIGTERM


def _say_stopped(signum, results, done, dests, before):
    """What an interrupted report wrote (the files new or replaced in its folders; every figure is written whole
    or not at all) and what it did not."""
    from .outputs import listing

    new = sorted(p for p, st in listing(dests).items() if before.get(p) != st)
    figs = [p for p in new if p.suffix in (".png", ".pdf", ".svg", ".gif", ".mp4")]
    data = len(new) - len(figs)
    where = ", ".join(str(d) for d in dests)
    wrote = (
        f"wrote {len(figs)} figure file(s) in {where} ({', '.join(p.name for p in figs)})"
        + (f" and {data} data file(s)" if data else "")
        if figs or data
        else "wrote nothing"
    )
    rest = [str(r) for r in results if r not in done]
    todo = ("the remaining figures of " if figs or data else "the figures of ") + ", ".join(rest) if rest else ""
    if len(results) > 1:
        todo += (" and " if todo else "") + "the overlay"
    click.echo(
        f"report interrupted by signal {signum}: {wrote}; not written: {todo}; the same command writes the whole "
        "report",
        err=True,
    )


def _closeups(results, out, tl, reg, pts, fmts, magnify, done):
    from ..io.hdf5 import ResultError, readable
    from ..report.make import make_closeup

    try:
        with tempfile.TemporaryDirectory(prefix="polydem-report-") as tmp:
            for result in results:
                src = readable(result, Path(tmp))
                if src != result:
                    click.echo(f"note: {result}: still running: the close-up shows its state so far", err=True)
                for f in make_closeup(src, out or result.parent, tl, reg, pts, formats=fmts, magnify=magnify):
                    click.echo(f"wrote {f}")
                done.append(result)
    except ResultError as e:
        click.echo(f"error: {e}", err=True)
        sys.exit(2)


def _report(results, out, tl, sl, fmts, magnify, movie, done):
    from ..io.hdf5 import ResultError, readable
    from ..report import make_report
    from ..solvers import family_of_result

    notes, files = [], []
    with tempfile.TemporaryDirectory(prefix="polydem-report-") as tmp:
        try:
            srcs = [readable(r, Path(tmp)) for r in results]
        except ResultError as e:
            click.echo(f"error: {e}", err=True)
            sys.exit(2)
        for result, src in zip(results, srcs):
            dest = out or result.parent  # a snapshot's figures go beside the running result, named <stem>.running_*
            fam = family_of_result(src) if src.exists() else None
            try:
                if fam is not None:
                    from ..report.make import family_report

                    files += family_report(fam, src, dest, notes=notes, formats=fmts)
                else:
                    files += make_report(src, dest, tl, sl, notes=notes, formats=fmts, magnify=magnify)
            except ResultError as e:
                click.echo(f"error: {e}", err=True)
                sys.exit(2)
            if movie and fam is None:
                from ..report.movie import make_movie

                try:
                    files.append(make_movie(src, Path(dest) / f"{src.stem}_movie.{movie}")["file"])
                except ResultError as e:
                    click.echo(f"error: {e}", err=True)
                    sys.exit(2)
            done.append(result)
        if len(results) > 1:
            from ..report import overlay

            try:
                files += overlay(srcs, Path(out or results[0].parent), formats=fmts, notes=notes)
            except ResultError as e:
                click.echo(f"error: {e}", err=True)
                sys.exit(2)
    for n in notes:
        click.echo(f"note: {n}", err=True)
    for f in files:
        click.echo(f"wrote {f}")
