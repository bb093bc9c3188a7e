"""``polydem bench``."""

from __future__ import annotations

from pathlib import Path

import click


@click.command("bench")
@click.argument("scenes", nargs=-1)
@click.option(
    "--out", type=click.Path(dir_okay=False, path_type=Path), default=Path("outputs/bench.json"), show_default=True
)
@click.option("--repeat", type=int, default=3, show_default=True, help="timings per scene and thread count (median)")
@click.option("--quick", is_flag=True, help="a tenth of the steps (a smoke check of the benchmark itself)")
@click.option(
    "--ranks/--no-ranks",
    default=True,
    show_default=True,
    help="also time each scene that runs decomposed on 1 and 2 MPI ranks (needs the mpi extra)",
)
def bench_cmd(scenes, out, repeat, quick, ranks):
    """Particle-steps per second, 1, 2 and auto threads (idle and beside a busy process), 1 and 2 MPI ranks, peak memory (the benchmark scenes of polydem_cli/benchmarks/bench.py; default: all).

    Scenes: bonded_30x30, bonded_300x300, hex_base_friction, hex_base_friction_3gp, concrete_40x40,
    concrete_40x40_interface (the panel with edge-interface bonds), concrete_40x40_principal (those with the
    principal crack criterion), dense_N1e3, dense_N1e4, dense_N1e5, lh_biaxial_1950, lh_loading_1950 (needs
    outputs/lh/prepare_p100.h5: skipped without it).

    \b
    Example:
      polydem bench --out outputs/bench.json
      polydem bench dense_N1e3 hex_base_friction --repeat 5
    """
    from ..benchmarks.bench import SCENES, run_bench

    bad = [s for s in scenes if s not in SCENES]
    if bad:
        raise click.BadParameter(f"unknown scene(s) {bad}; valid: {', '.join(SCENES)}")
    from .outputs import writable_file, writing

    writable_file(out, "the benchmark", example="bench.json")  # before the scenes run
    with writing(out):
        run_bench(out, list(scenes) or None, repeat, 0.1 if quick else 1.0, ranks)
