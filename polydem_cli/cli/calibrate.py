"""``polydem calibrate``."""

from __future__ import annotations

from pathlib import Path

import click


@click.command("calibrate")
@click.argument("scenario", type=click.Path(dir_okay=False, path_type=Path))
@click.option(
    "--target",
    "targets",
    multiple=True,
    required=True,
    metavar="KEY=VALUE",
    help="E=33.5GPa, nu=0.2, f_t=2.9MPa (tension) or f_c=-14.9MPa (compression, either sign; the scenario's "
    "loading must pull, or push, the specimen), "
    "F=12kN (peak load of the driven set, for specimens without [macro], e.g. glued nuts), G_F=120N/m (fracture "
    "energy of a notched beam in three-point bending); stresses, forces and energies need their unit (GPa, MPa, "
    "kPa, Pa, N/mm2, N/cm2, dyn/cm2; kN, N, dyn; N/m, J/m2, erg/cm2); repeatable",
)
@click.option(
    "--test",
    "tests",
    multiple=True,
    metavar="KEY=SCENARIO",
    help="measure target KEY on another test's scenario (same beams), e.g. --test f_c=scenarios/concrete_compression.toml "
    "--test G_F=scenarios/lab/three_point_bending.toml; default: every target on SCENARIO; repeatable",
)
@click.option(
    "--vary",
    default="",
    metavar="bonds.E,bonds.nu,bonds.kappa_0",
    help="the beam parameters allowed to change (default: those the targets need)",
)
@click.option("--set", "overrides", multiple=True, metavar="KEY.PATH=VALUE", help="override a scenario value first")
@click.option(
    "--seeds",
    default="",
    metavar="S1,S2,...",
    help="repeat on these specimen seeds (scenario.seed) and report the spread",
)
@click.option(
    "-o",
    "--out",
    type=click.Path(dir_okay=False, path_type=Path),
    default=None,
    help="calibrated scenario to write (default: outputs/<scenario stem>_calibrated.toml; its runs in <out>.runs/)",
)
@click.option(
    "--reference",
    type=click.Path(dir_okay=False, path_type=Path),
    default=None,
    help="finished result whose peak stress is the reference of a dif target (default: the strength target's run)",
)
@click.option(
    "--tol",
    type=click.FloatRange(min=1e-4, max=0.1),
    default=0.005,
    show_default=True,
    help="relative tolerance of a strength target",
)
@click.option("-q", "--quiet", is_flag=True, help="no progress lines of the dynamic runs (only one line per run)")
@click.option(
    "-j",
    "--jobs",
    default=1,
    show_default=True,
    type=click.IntRange(1, 64),
    help="specimen seeds calibrated in parallel processes (with --seeds)",
)
def calibrate_cmd(scenario, targets, tests, overrides, vary, seeds, out, reference, tol, quiet, jobs):
    """Fit the beams of a bonded SCENARIO to macroscopic targets: bonds.E and bonds.nu from E and nu by static
    solves of the bond network (no time integration), bonds.kappa_0 from the strength by a few dynamic runs
    stopped past the peak (secant method).  Writes a calibrated copy of the scenario (extends the original)
    and <out>.json with every iteration.

    \b
    Example:
      polydem calibrate scenarios/concrete_tension.toml --target E=33.5GPa --target nu=0.2 --target f_t=2.9MPa
      polydem calibrate scenarios/concrete_tension.toml --target E=33.5GPa --target nu=0.2 --target f_t=2.9MPa \\
        --target f_c=38MPa --test f_c=scenarios/concrete_compression.toml \\
        --target G_F=141N/m --test G_F=scenarios/lab/three_point_bending.toml

    With several tests, G_F is fitted with bonds.G_ax, alternating with kappa_0 (the strength) until both hold; a
    second strength (f_c beside f_t) is measured and reported with the f_c/f_t the beams give, not fitted.
    Edge interfaces (bonds.model = "interface", docs/interface.md): f_t with bonds.f_t and f_c with
    bonds.cohesion (bonds.crack_strength with crack_criterion = "principal") in turn, then G_F with bonds.G_I
    and bonds.G_II at the scenario's ratio, in rounds until all hold at the final values.
    """
    import json
    import sys

    from ..scenario.spec import ScenarioError
    from ..solvers.driver import Interrupted
    from ..workflows.calibrate import CalibrationError, calibrate, parse_target, write_calibrated
    from .outputs import writable_file, writing

    try:
        tg = {}
        for t in targets:
            k, v = parse_target(t)
            if k in tg:
                raise ValueError(f"--target {t}: {k} is given twice (one target per key)")
            tg[k] = v
        tmap = {}
        for t in tests:
            k, sep, path = t.partition("=")
            if not sep or not path.strip() or k.strip() not in ("E", "nu", "f_t", "f_c", "F", "G_F"):
                raise ValueError(f"--test {t}: expected KEY=SCENARIO with KEY one of E, nu, f_t, f_c, F, G_F")
            if not Path(path.strip()).is_file():
                raise ValueError(f"--test {t}: no scenario file {path.strip()}")
            tmap[k.strip()] = Path(path.strip())
        try:
            sl = [int(s) for s in seeds.split(",") if s.strip()] if seeds else None
        except ValueError:
            raise ValueError(f"--seeds {seeds}: expected whole numbers S1,S2,... (scenario.seed)") from None
    except ValueError as e:
        click.echo(f"error: {e}", err=True)
        sys.exit(2)
    out = out or Path("outputs") / (scenario.stem + "_calibrated.toml")
    writable_file(out, "the calibrated scenario", example=scenario.stem + "_calibrated.toml")
    click.echo("targets: " + ", ".join(_said(k, v) for k, v in tg.items()))
    try:
        vl = [v.strip() for v in vary.split(",") if v.strip()] or None
        res = calibrate(
            scenario,
            tg,
            overrides,
            sl,
            workdir=out.with_suffix(".runs"),
            rel_tol=tol,
            log=click.echo,
            vary=vl,
            reference=reference,
            progress=None if quiet else sys.stderr,
            jobs=jobs,
            tests=tmap,
        )
    except (ScenarioError, CalibrationError, ValueError) as e:
        click.echo(f"error: {e}", err=True)
        sys.exit(2)
    except Interrupted as e:  # SIGINT/SIGTERM: the running run has checkpointed
        click.echo(
            f"calibration interrupted by signal {e.args[0]}; the same command resumes it (finished runs are reused)",
            err=True,
        )
        sys.exit(130)
    with writing(out):
        write_calibrated(scenario, res, out)
        out.with_suffix(".json").write_text(json.dumps(res, indent=1, default=float))
    click.echo(f"wrote {out} and {out.with_suffix('.json')} ({res['wall_s']:.0f} s)")


def _said(key, value) -> str:
    """A parsed target as the calibration reads it, in the units the report uses (echoed before any run)."""
    if key == "nu":
        return f"nu = {value:g}"
    if key == "F":
        return f"F = {value / 1e8:g} kN"
    if key == "dif":
        return f"dif = {value[0]:g} at {value[1]:g} 1/s"
    if key == "G_F":
        return f"G_F = {value / 1e3:g} N/m"
    return f"{key} = {value / 1e10:g} GPa" if key == "E" else f"{key} = {value / 1e7:g} N/mm2"
