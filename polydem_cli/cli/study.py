"""``polydem study ...``: numerical studies."""

from __future__ import annotations

import tomllib
from pathlib import Path

import click

from .outputs import writable_dir, writable_file, writing


@click.group()
def study():
    """Numerical studies (integrator convergence, ...)."""


@study.command("integrators")
@click.option(
    "--out",
    type=click.Path(file_okay=False, path_type=Path),
    default=Path("outputs/integrators"),
    show_default=True,
    help="output directory",
)
def integrators_cmd(out):
    """Error against number of steps for EE, ME, CD, PC (thesis Figs. 3.8, 3.9).

    Writes OUT/integrators.json and OUT/integrators.png.

    \b
    Example:
      polydem study integrators --out outputs/integrators
    """
    from ..reproductions.integrators import write_study

    writable_dir(out, "the study")
    with writing(out):
        res = write_study(out)
    for p in ("oscillator", "collision"):
        orders = ", ".join(f"{m} {res[p][m]['order']:.2f}" for m in ("EE", "ME", "CD", "PC"))
        click.echo(f"{p}: fitted orders {orders}")
    click.echo(f"wrote {out / 'integrators.json'} and {out / 'integrators.png'}")


@study.command("ch5")
@click.option(
    "--runs",
    type=click.Path(file_okay=False, path_type=Path),
    default=Path("outputs/ch5"),
    show_default=True,
    help="directory with the chapter-5 results (<scenario stem>.h5)",
)
@click.option(
    "--out", type=click.Path(file_okay=False, path_type=Path), default=Path("outputs/figures/ch5"), show_default=True
)
def ch5_cmd(runs, out):
    """Collate the chapter-5 runs: Figs. 5.6-5.21, Table 5.1 (table5_1.csv) and results.json (thesis values beside ours).

    \b
    Example:
      polydem study ch5 --runs outputs/ch5 --out outputs/figures/ch5
    """
    from ..reproductions.ch5 import collate

    writable_dir(out, "the study")
    with writing(out):
        res = collate(runs, out)
    rep = res["reproduced"]
    tables = {"table_5_1": "Table 5.1", "table_5_1_rate_filter": "Table 5.1 (option bonds.rate_filter)"}
    for k, v in rep.items():
        if k not in tables:
            click.echo(f"{k}: {v if v is None else round(v, 3)} (thesis {res['thesis'].get(k)})")
    for key, label in tables.items():
        for row, vals in rep[key].items():
            click.echo(
                f"{label} {row}: " + ", ".join(f"{c} {'-' if v is None else round(v, 3)}" for c, v in vals.items())
            )
    if res["missing"]:
        click.echo("missing runs: " + ", ".join(res["missing"]))
    click.echo(f"wrote {out / 'results.json'}")


@study.command("timestep")
@click.argument("scenario", type=click.Path(dir_okay=False, exists=True, path_type=Path))
@click.option("--dt", "dts", required=True, help="comma-separated time steps, e.g. 1e-5,2e-5,5e-5")
@click.option(
    "--integrator",
    "integrators",
    default="gear5,verlet",
    show_default=True,
    help="comma-separated integrators; the finest dt of the first is the reference",
)
@click.option("--set", "overrides", multiple=True, metavar="KEY.PATH=VALUE", help="override a scenario value")
@click.option(
    "--out",
    type=click.Path(file_okay=False, path_type=Path),
    default=None,
    help="output directory (default outputs/timestep/<scenario stem>)",
)
@click.option(
    "--reference",
    type=click.Path(dir_okay=False, exists=True, path_type=Path),
    default=None,
    help="an existing result (a finer time step) to measure the errors against",
)
def timestep_cmd(scenario, dts, integrators, overrides, out, reference):
    """Speed against error of SCENARIO over time steps and integrators.

    Writes timestep.json, timestep.csv and timestep.png (error against wall time).

    \b
    Example:
      polydem study timestep scenarios/ch6/nuts_small.toml --dt 2.5e-6,5e-6,1e-5,2e-5 --integrator gear5,verlet
    """
    import sys

    from ..engine.integrators import INTEGRATORS
    from ..engine.simulation import EngineError
    from ..scenario.spec import ScenarioError
    from ..workflows.timestep import run_study

    try:
        dl = [float(x) for x in dts.split(",") if x.strip()]
        il = [x.strip() for x in integrators.split(",") if x.strip()]
    except ValueError:
        click.echo(f"error: --dt {dts!r}: expected comma-separated numbers", err=True)
        sys.exit(2)
    bad = [i for i in il if i not in INTEGRATORS]
    if bad or not dl or min(dl) <= 0:
        click.echo(f"error: --integrator must be from {', '.join(INTEGRATORS)} and --dt positive", err=True)
        sys.exit(2)
    out = out or Path("outputs/timestep") / scenario.stem
    writable_dir(out, "the study")
    try:
        with writing(out):
            res = run_study(scenario, dl, il, out, overrides, reference=reference)
    except (ScenarioError, ValueError) as e:
        click.echo(f"error: {e}", err=True)
        sys.exit(2)
    except EngineError as e:
        click.echo(f"error: {e}", err=True)
        sys.exit(1)
    for r in res["runs"]:
        e = r.get("errors", {})
        err = ", ".join(f"{k} {v:.3g}" for k, v in e.items())
        click.echo(
            f"{r['integrator']:7s} dt={r['dt']:<10.4g} "
            + (
                f"{r['wall_s']:.2f} s, {r['particle_steps_per_s']:.3g} particle-steps/s, errors: {err}"
                if r["stable"]
                else (
                    "REFUSED (dt above the refusal limit)"
                    if str(r.get("failure", "")).startswith("refused")
                    else "UNSTABLE"
                )
            )
        )
    for integ, o in res["convergence_order"].items():
        bad = res.get("convergence_order_meaningless", {}).get(integ, {})
        click.echo(
            f"{integ}: convergence order "
            + ", ".join(f"{k} {v:.2f}" + (f" ({bad[k]})" if k in bad else "") for k, v in o.items())
        )
    if res["reference"].get("note"):
        click.echo("note: " + res["reference"]["note"])
    click.echo(
        f"largest stable dt: {res['largest_stable_dt']}; largest dt within 1 % (peak and curve): "
        f"{res['largest_accurate_dt']}; wrote {out / 'timestep.json'}"
    )


@study.command("ch7")
@click.option(
    "--runs",
    type=click.Path(file_okay=False, path_type=Path),
    default=Path("outputs/ch7"),
    show_default=True,
    help="directory with the chapter-7 results (<scenario stem>.h5)",
)
@click.option(
    "--out", type=click.Path(file_okay=False, path_type=Path), default=Path("outputs/figures/ch7"), show_default=True
)
@click.option("--variant", default="", help="collate <stem><VARIANT>.h5 for the rate-dependent runs (e.g. _filtered)")
def ch7_cmd(runs, out, variant):
    """Collate the chapter-7 runs: Figs. 7.3-7.13 and results.json (thesis values beside ours).

    \b
    Example:
      polydem study ch7 --runs outputs/ch7 --out outputs/figures/ch7
    """
    from ..reproductions.ch7 import collate

    writable_dir(out, "the study")
    with writing(out):
        res = collate(runs, out, variant)
    for k, v in res["reproduced"].items():
        th = res["thesis"]["concrete"].get(k, res["thesis"]["nuts"].get(k.replace("nuts_", "")))
        click.echo(
            f"{k}: {v if not isinstance(v, float) else format(v, '.4g')}"
            + (f" (thesis {th})" if th is not None else "")
        )
    if res["missing"]:
        click.echo("missing runs: " + ", ".join(res["missing"]))
    click.echo(f"wrote {out / 'results.json'}")


@study.command("dif")
@click.argument("scenario", type=click.Path(dir_okay=False, exists=True, path_type=Path))
@click.option("--rates", required=True, help="comma-separated macroscopic strain rates |eps22 rate| in 1/s")
@click.option(
    "--reference",
    required=True,
    type=click.Path(dir_okay=False, exists=True, path_type=Path),
    help="result whose peak stress is the static strength (the slow rate-independent run)",
)
@click.option("--set", "overrides", multiple=True, metavar="KEY.PATH=VALUE", help="override a scenario value")
@click.option(
    "--out",
    type=click.Path(file_okay=False, path_type=Path),
    default=None,
    help="output directory (default outputs/dif/<scenario stem>)",
)
@click.option("--workers", type=int, default=None, help="local Dask workers (default: one per core)")
def dif_cmd(scenario, rates, reference, overrides, out, workers):
    """Dynamic increase factor of strength over strain rates against fib MC2010.

    Writes dif.json and dif.png (simulated points and the fib tension and compression curves).

    \b
    Example:
      polydem study dif scenarios/ch7/tension_slow_ra.toml --rates 1e-3,0.1,1,10 \\
          --reference outputs/ch7/concrete_tension.h5
    """
    import sys

    from ..scenario.spec import ScenarioError
    from ..workflows.dif import run_study

    try:
        rl = [float(x) for x in rates.split(",") if x.strip()]
    except ValueError:
        click.echo(f"error: --rates {rates!r}: expected comma-separated numbers", err=True)
        sys.exit(2)
    if not rl or min(rl) <= 0:
        click.echo("error: --rates must be positive", err=True)
        sys.exit(2)
    out = out or Path("outputs/dif") / scenario.stem
    writable_dir(out, "the study")
    try:
        with writing(out):
            res = run_study(scenario, rl, reference, out, overrides, workers=workers)
    except (ScenarioError, ValueError) as e:
        click.echo(f"error: {e}", err=True)
        sys.exit(2)
    for p in res["points"]:
        click.echo(
            f"rate {p['rate']:<8.3g} "
            + (
                f"peak {p['peak_stress_MPa']:.4g} N/mm^2, DIF {p['dif']:.4f} "
                f"(fib {p['fib']:.4f}), {p['wall_time_s']:.0f} s"
                if p.get("dif")
                else f"{p['status']}: {p.get('failure')}"
            )
        )
    click.echo(f"wrote {out / 'dif.json'} and {out / 'dif.png'}")


@study.command("lh")
@click.option(
    "--runs",
    type=click.Path(file_okay=False, path_type=Path),
    default=Path("outputs/lh"),
    show_default=True,
    help="directory with the loading runs load_p<P>_kc<K>.h5 (scenarios/lh/)",
)
@click.option(
    "--out", type=click.Path(file_okay=False, path_type=Path), default=Path("outputs/figures/lh"), show_default=True
)
@click.option(
    "--variant",
    type=click.Choice(["", "u"]),
    default="",
    help="p = 100 runs: '' as shipped (load_p100_kc*), 'u' from the p = 500 packing unloaded to 100 (load_p100u_kc*)",
)
def lh_cmd(runs, out, variant):
    """Luding & Herrmann biaxial box: corrected peak stresses, nu, dilatancy, Mohr-Coulomb phi and c
    (Table 1.1 as table1_1.csv), figures and results.json.

    \b
    Example:
      polydem study lh --runs outputs/lh --out outputs/figures/lh
      polydem study lh --variant u        # p = 100 runs from the unloaded p = 500 packing
    """
    from ..reproductions.lh import collate

    writable_dir(out, "the study")
    with writing(out):
        res = collate(runs, out, variant)

    def fmt(v):
        return "-" if v is None else f"{v:.4g}"

    def peak(row, p):
        return ("≥ " if row[f"peak_{p}_lower_bound"] else "") + fmt(row[f"peak_{p}"])

    for row in res["table1_1"]:
        click.echo(
            f"k_c/k_2 = {row['kc_over_k2']:g}: peak p=100 {peak(row, '100')} (paper {row['paper_peak_100']}), "
            f"p=500 {peak(row, '500')} (paper {row['paper_peak_500']}), c {fmt(row['c'])} (paper {row['paper_c']}), "
            f"phi {fmt(row['phi_deg'])} deg"
        )
    if any(row[f"peak_{p}_lower_bound"] for row in res["table1_1"] for p in ("100", "500")):
        click.echo("≥: the peak fell on the last point of the loading (the stress still rising): a lower bound")
    cs = [
        r["sxx_minus_p_vs_wall_damping_correlation"]
        for r in res["runs"].values()
        if "sxx_minus_p_vs_wall_damping_correlation" in r
    ]
    if cs:
        click.echo(
            f"sigma_xx - p_x is the side wall's damping gamma_x xdot/(h z) (LH 1.2): correlation {min(cs):.3f}-{max(cs):.3f} "
            "over the loading runs (the correction LH 1.10 divides out the wall's damping)"
        )
    if res["missing"]:
        click.echo("missing runs: " + ", ".join(res["missing"]))
    click.echo(f"wrote {out / ('table1_1' + ('_' + variant if variant else '') + '.csv')}")


@study.command("coupling")
@click.option(
    "--out",
    type=click.Path(file_okay=False, path_type=Path),
    default=Path("outputs/figures/coupling"),
    show_default=True,
)
@click.option("--width", type=float, default=None, help="plate width in spacings (default 120; smaller: a quick look)")
@click.option("--rows", type=int, default=None, help="lattice rows (default 72)")
@click.option("--example", "examples", multiple=True, help="run only these examples (repeatable)")
@click.option(
    "--scale",
    default="",
    metavar="W1,W2,...",
    help="instead: the largest plate each solver holds — the (first) example at these widths (rows 0.6 x width), "
    "fully resolved and adaptive, each in its own process (scale.json)",
)
@click.option(
    "--adaptive",
    "changes",
    multiple=True,
    metavar="KEY=VALUE",
    help="change an adaptive setting of every example compared (tol, theta, buffer, coarse_side, max_stages, "
    "resolve_softer, intact_scale, defer, min_gain; repeatable; not with --scale): the speed-error trade, e.g. --adaptive tol=0.3",
)
def coupling_cmd(out, width, rows, examples, scale, changes):
    """Sorg (2014): the four plates with a rhombus hole, adaptive FEM-lattice against fully resolved
    (errors, DOFs, memory, wall time and the time ratio beside the source's), results.json and figures.

    \b
    Example:
      polydem study coupling --out outputs/figures/coupling
      polydem study coupling --width 40 --rows 24 --example homogeneous_softening
      polydem study coupling --width 80 --rows 48 --example homogeneous_elastic --adaptive tol=0.3
    """
    from ..coupling.examples import EXAMPLES, adaptive_settings
    from ..reproductions.coupling import collate
    from ..reproductions.coupling import scale as scale_study

    unknown = [e for e in examples if e not in EXAMPLES]
    if unknown:
        raise click.BadParameter(
            f"{', '.join(unknown)}: the examples are {', '.join(EXAMPLES)}", param_hint="--example"
        )
    settings = {}
    for c in changes:
        key, sep, val = c.partition("=")
        try:
            if not sep:
                raise ValueError("expected KEY=VALUE")
            try:
                settings[key.strip()] = tomllib.loads(f"v = {val.strip()}")["v"]
            except tomllib.TOMLDecodeError:
                raise ValueError(f"{val.strip()!r} is not a number, true or false") from None
            for name in list(examples) or EXAMPLES:
                adaptive_settings(name, settings)
        except ValueError as e:
            raise click.BadParameter(f"{c}: {e}", param_hint="--adaptive") from None
    writable_dir(out, "the study")
    if scale and settings:
        raise click.BadParameter("the scale study runs the examples' own settings", param_hint="--adaptive")
    if scale:
        try:
            widths = [float(w) for w in scale.split(",") if w.strip()]
        except ValueError:
            raise click.BadParameter(
                "expected comma-separated widths, e.g. 120,240,480", param_hint="--scale"
            ) from None
        with writing(out):
            scale_study(out, widths, examples[0] if examples else "homogeneous_elastic")
        click.echo(f"wrote {out / 'scale.json'}")
        return
    with writing(out):
        collate(out, width, rows, list(examples) or None, settings or None)
    click.echo(f"wrote {out / 'results.json'}")


@study.command("index")
@click.option(
    "--figures",
    "figdir",
    type=click.Path(file_okay=False, path_type=Path),
    default=Path("outputs/figures"),
    show_default=True,
)
@click.option("--out", type=click.Path(dir_okay=False, path_type=Path), default=None, help="default: FIGURES/INDEX.md")
@click.option(
    "--docs/--no-docs",
    default=True,
    show_default=True,
    help="also rewrite the results quoted in ./README.md and ./docs/reproduction.md (their generated blocks) "
    "from the results beside FIGURES",
)
def index_cmd(figdir, out, docs):
    """INDEX.md of the result figures: files, make target and command, wall time of the runs behind each, key
    numbers beside the source's and whether they agree (missing ones listed as missing); and the numbers the
    docs quote, rewritten from the results (polydem_cli/reproductions/docs.py).

    \b
    Example:
      polydem study index
    """
    from ..reproductions.index import build

    writable_file(out or figdir / "INDEX.md", "the index", example="INDEX.md")
    with writing(out or figdir / "INDEX.md"):
        c = build(figdir, out)
    click.echo(
        f"wrote {out or figdir / 'INDEX.md'}: {c['present']} figure rows complete, {c['missing']} with missing files; "
        f"key numbers {c['agree']} agree, {c['differ']} differ, {c['open']} not yet computed"
    )
    if docs:
        from ..reproductions.docs import update

        for f, blocks in update(Path("."), figdir.parent).items():
            said = ", ".join(f"{b} {st}" for b, st in blocks.items())
            click.echo(f"{f}: {said}")


@study.command("lab")
@click.option(
    "--out", type=click.Path(file_okay=False, path_type=Path), default=Path("outputs/figures/lab"), show_default=True
)
@click.option(
    "--scenarios",
    "root",
    type=click.Path(file_okay=False, exists=True, path_type=Path),
    default=Path("."),
    show_default=True,
    help="the repository whose scenarios/ the tests run",
)
@click.option("--test", "tests", multiple=True, help="run only these tests (repeatable; default: all six)")
@click.option(
    "--pressures",
    default=None,
    help="the confined compression's lateral pressures, MPa, comma-separated (default 1,2,4)",
)
@click.option(
    "--material",
    type=click.Path(dir_okay=False, exists=True, path_type=Path),
    default=None,
    help="a scenario file whose [bonds] values every test's beams take (e.g. the calibrated one of polydem calibrate)",
)
@click.option("--set", "overrides", multiple=True, metavar="KEY.PATH=VALUE", help="override a value in every test")
@click.option("--smoke", is_flag=True, help="the smoke-size specimens (seconds; what the tests check)")
def lab_cmd(out, root, tests, pressures, material, overrides, smoke):
    """The virtual material laboratory: uniaxial tension and compression, Brazilian splitting, three-point
    bending of a notched beam, confined compression at several lateral pressures and cyclic compression with
    unloadings, on the thesis concrete; their standard numbers (f_t, f_c, f_ct,sp = 2F/(pi D T), RILEM G_F,
    Mohr-Coulomb c and phi, damage from the unloading stiffness) and the ratios a bonded-particle model is judged
    by (f_c/f_t, f_ct,sp/f_t, G_F against fib MC2010). Finished runs in OUT are reused. Writes OUT/results.json,
    OUT/lab_table.md, OUT/lab_curves.png and OUT/lab_failure.png.

    \b
    Example:
      polydem study lab --smoke --out outputs/figures/lab_smoke
      polydem study lab --test brazilian --test three_point_bending
      polydem study lab --test compression --test confined_compression --pressures 1,2,4,8
      polydem study lab --material outputs/calibration/c30_37.toml --out outputs/figures/lab_c30_37
    """
    from ..workflows.lab import PRESSURES, TESTS, LabError, check_pressures, material_overrides, run_study

    bad = [t for t in tests if t not in TESTS]
    if bad:
        raise click.BadParameter(f"unknown test {bad[0]!r}; the tests are {', '.join(TESTS)}", param_hint="--test")
    chosen = tuple(t for t in TESTS if not tests or t in tests)
    if pressures is not None:
        if "confined_compression" not in chosen:
            raise click.BadParameter(
                "a lateral pressure is for the confined compression test only (none of the chosen tests has confinement)",
                param_hint="--pressures",
            )
        try:
            pressures = tuple(float(p) for p in pressures.split(","))
        except ValueError:
            raise click.BadParameter(
                f"{pressures!r}: not comma-separated numbers (MPa)", param_hint="--pressures"
            ) from None
        try:
            check_pressures(pressures)
        except LabError as e:
            raise click.BadParameter(str(e), param_hint="--pressures") from None
    ov = list(overrides)
    if material is not None:
        try:
            ov = material_overrides(material) + ov
        except LabError as e:
            raise click.BadParameter(str(e), param_hint="--material") from None
    writable_dir(out, "the study")
    try:
        with writing(out):
            res = run_study(out, root, chosen, smoke=smoke, pressures=pressures or PRESSURES, overrides=ov)
    except LabError as e:
        raise click.ClickException(str(e)) from None
    for t, n in res["tests"].items():
        if t == "confined_compression":
            mc, peaks = n["mohr_coulomb"], ", ".join(f"{s:.2f}" for s in n["peaks"])
            click.echo(f"{t:20s} phi {mc['phi']:.1f} deg, c {mc['c']:.3f} MPa (peaks {peaks} MPa)")
            continue
        click.echo(f"{t:20s} strength {n['strength']:8.3f} MPa, peak load {n['peak_force'] * 1e-5:10.1f} N")
    for q, v, r in res["table"]:
        click.echo(f"  {q:45s} {v:10.4g}   ({r})")
    click.echo(
        f"wrote {out / 'results.json'}, {out / 'lab_table.md'}, {out / 'lab_curves.png'} and {out / 'lab_failure.png'}"
    )


@study.command("validate")
@click.option(
    "--out",
    type=click.Path(file_okay=False, path_type=Path),
    default=Path("outputs/figures/validate"),
    show_default=True,
    help="the study's folder: scenarios/ (the runs' scenario files), runs/ (their results), the table and figures",
)
@click.option(
    "--scenarios",
    "root",
    type=click.Path(file_okay=False, exists=True, path_type=Path),
    default=Path("."),
    show_default=True,
    help="the repository whose scenarios/lab/ templates the study runs",
)
@click.option(
    "--test",
    "tests",
    multiple=True,
    help="run only these experiments (repeatable): softening, biaxial, size_effect, petersson (default: all)",
)
@click.option(
    "--material",
    type=click.Path(dir_okay=False, exists=True, path_type=Path),
    default=None,
    help="a scenario file whose [bonds] values every run's beams take (e.g. a calibrated one)",
)
@click.option("--set", "overrides", multiple=True, metavar="KEY.PATH=VALUE", help="override a value in every run")
@click.option(
    "--biaxial",
    default=None,
    metavar="POINTS",
    help="Kupfer's envelope points: c<ratio> (sigma_1 compression) or t<ratio> (tension), ratio = sigma_2/sigma_1 in "
    "[-1, 1], comma-separated (default c0,c0.2,c0.5,c1,c-0.05,c-0.1,c-0.2,t1; smoke c0,c0.5,c1,c-0.1,t1)",
)
@click.option(
    "--sizes",
    default=None,
    metavar="D,D,...",
    help="depths of the size-effect beams, cm, whole cells (default 5,10,20,40; smoke 5,10)",
)
@click.option("--smoke", is_flag=True, help="the smoke-size specimens (seconds each; what the tests run)")
@click.option("-j", "--jobs", default=1, show_default=True, type=click.IntRange(1, 64), help="runs at a time")
@click.option("--threads", default="1", show_default=True, help="threads of each run (see polydem run)")
@click.option("--ranks", type=int, default=None, metavar="N", help="each run decomposed over N MPI ranks (polydem run)")
@click.option("-q", "--quiet", is_flag=True, help="no progress line")
def validate_cmd(out, root, tests, material, overrides, biaxial, sizes, smoke, jobs, threads, ranks, quiet):
    """A material beside the classic experiments of concrete: Kupfer's biaxial envelope (a panel under proportional
    biaxial stress), Bazant's size effect (notched beams D = 5-40 cm, the size-effect law fitted), Hordijk's
    tension softening (stress against crack opening) and Petersson's notched beam (load against deflection), with
    the published numbers and their sources (polydem_cli/reproductions/sources/). Writes OUT/validation_table.md,
    OUT/validate_<experiment>.png and OUT/results.json; the runs' scenario files in OUT/scenarios/ (each runs
    alone with polydem run), their results in OUT/runs/ (finished runs reused, interrupted ones resumed).

    \b
    Example:
      polydem study validate --smoke --out outputs/figures/validate_smoke
      polydem study validate --test biaxial --biaxial c0,c0.5,c1
      polydem study validate --material outputs/calibration/c30_37.toml --ranks 2 --out outputs/figures/validate_c30
    """
    from ..reproductions.validate import EXPERIMENTS_ORDER, ValidateError, plan, run_study, scenarios
    from ..workflows.lab import LabError, material_overrides

    if ranks is not None and ranks < 1:
        raise click.BadParameter(f"{ranks}: at least 1", param_hint="--ranks")
    ov = list(overrides)
    title = "thesis concrete"
    if material is not None:
        try:
            ov = material_overrides(material) + ov
        except LabError as e:
            raise click.BadParameter(str(e), param_hint="--material") from None
        title = f"beams of {material.name}"
    try:  # every choice checked, every scenario built in memory, before anything is written
        scenarios(plan(smoke, tests or EXPERIMENTS_ORDER, biaxial, sizes), root, ov)
    except ValidateError as e:
        raise click.BadParameter(str(e).split(": ", 1)[1], param_hint=e.key) from None
    writable_dir(out, "the study")
    try:
        with writing(out):
            res = run_study(
                out, root, tests or EXPERIMENTS_ORDER, smoke, ov, biaxial, sizes, threads, jobs, ranks, quiet, title
            )
    except ValidateError as e:
        raise click.ClickException(str(e)) from None
    for e, q, m, x, d, _ in res["table"]:
        mm = "—" if m is None else f"{m:.4g}"
        xx = "" if x is None else f"  (experiment {x:.4g}" + (f", {d:+.1f} %)" if d is not None else ")")
        click.echo(f"  {e:12s} {q:60s} {mm:>10s}{xx}")
    if res["results"]["missing"]:
        click.echo(f"not finished (left out): {', '.join(res['results']['missing'])}", err=True)
    click.echo(
        f"wrote {out / 'validation_table.md'}, {', '.join(str(p) for p in res['figures'])}, {out / 'results.json'}"
    )
    if res["results"]["missing"]:
        raise SystemExit(1)
