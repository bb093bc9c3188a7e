"""``polydem bench``."""
from __future__ import annotations

from pathlib import Path

import click

DEFAULT = ("scenarios/bench_dense_hexagons.toml",)


@click.command("bench")
@click.argument("scenarios", nargs=-1, type=click.Path(dir_okay=False, path_type=Path))
@click.option("--out", type=click.Path(dir_okay=False, path_type=Path), default=Path("outputs/bench.json"),
              show_default=True)
@click.option("--steps", type=int, default=None, help="steps per timing (default: the scenario's end)")
@click.option("--repeat", type=int, default=3, show_default=True, help="timings per scenario (median reported)")
def bench_cmd(scenarios, out, steps, repeat):
    """Particle-steps per second on benchmark scenes (default: dense hexagon packing).

    \b
    Example:
      polydem bench --out outputs/bench.json
    """
    from ..studies.bench import run_bench

    run_bench(out, scenarios or [Path(p) for p in DEFAULT], steps, repeat)
