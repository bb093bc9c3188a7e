"""Numbers the docs quote, written from the results that give them, so that they cannot go stale.

A quoted result in README.md or docs/*.md sits between two markers::

    <!-- generated: NAME — `polydem study index` writes this from RESULT; do not edit by hand -->
    ...
    <!-- end generated: NAME -->

``polydem study index`` (the last step of ``make figures``) rewrites every such block whose result exists
(:func:`update`) and says which it rewrote and which it left because their result is missing.  The blocks:

* ``demo_output`` (README.md): what ``polydem run scenarios/concrete_tension.toml`` printed at its end (the
  main job, ``make demo``; from ``outputs/concrete_tension.summary.json``, else the figure batch's
  ``outputs/ch7/concrete_tension.summary.json`` of the same scenario), with its steps, wall time and threads; the
  summary it came from is kept as ``docs/demo_summary.json``, and ``make test`` fails while the code or the
  scenario that the run executes differs from the one that summary records (tests/test_readme_current.py);
* ``lh_table_1_1``, ``lh_table_1_1_u`` (docs/reproduction.md): Luding & Herrmann's Table 1.1 from
  ``outputs/figures/lh/table1_1[_u].csv`` (``polydem study lh``), the paper's values in brackets, a peak that
  fell on the last point of the loading written "≥" (a lower bound), and the correlation of σ_xx − p_x with
  the side wall's damping stress; ``lh_slopes[_u]``: ε_zz at the peak, the slopes of ε_V and ψ of each run;
  ``lh_rate``: the rate study's peaks (Fig. 1.5).
"""

from __future__ import annotations

import csv
import json
import re
from pathlib import Path

#: the files that hold generated blocks
DOCS = ("README.md", "docs/reproduction.md")

_BLOCK = re.compile(
    r"(?P<head><!-- generated: (?P<name>[\w.]+) [^\n]*-->\n)(?P<body>.*?)(?P<tail><!-- end generated: (?P=name) -->)",
    re.S,
)


def _json(path: Path):
    try:
        return json.loads(path.read_text())
    except (OSError, ValueError):
        return None


#: the main job's summary that the README's demo block was written from, kept beside the docs (committed): the test
#: that the block is current (tests/test_readme_current.py) renders the block from it and compares the code and the
#: scenario it records (``source_digests``, ``scenario_digest``) with today's
DEMO_SUMMARY = Path("docs") / "demo_summary.json"


def demo_summary(outputs: Path) -> dict | None:
    """The finished main job's summary (``outputs/concrete_tension.summary.json``, else the figure batch's
    ``outputs/ch7/concrete_tension.summary.json`` of the same scenario); None until it has run."""
    for p in (outputs / "concrete_tension.summary.json", outputs / "ch7" / "concrete_tension.summary.json"):
        s = _json(p)
        if s and s.get("status") == "finished":
            return s
    return None


def demo_output(outputs: Path) -> str | None:
    """A paragraph on the finished main job (steps, particles, wall time, threads, code version) with the summary it
    printed, for the README; None until it has run."""
    s = demo_summary(outputs)
    return None if s is None else demo_paragraph(s)


def demo_paragraph(s: dict) -> str:
    """The README's demo block from the main job's summary ``s``: what ``polydem run`` printed at its end."""
    from ..solvers.driver import printed_summary

    th = s.get("threads") or {}
    used = "/".join(map(str, th.get("used", []))) or "?"
    ranks = int(s.get("ranks") or 1)
    on = f"{ranks} MPI ranks, " if ranks > 1 else "1 process, "
    lines = printed_summary("outputs/concrete_tension.h5", s)
    return (
        f"It ran {s['steps']:,} steps of {s['dt']:g} s ({s['particles']} particles, {s['bonds']['count']} beams with "
        f"contact after failure) in {s['wall_time_s']:.0f} s of wall ({on}threads: {th.get('mode', '?')}, used "
        f"{used}{' per rank' if ranks > 1 else ''}; code {s.get('code_version', '?')}) and printed:\n\n```\n"
        + "\n".join(lines)
        + "\n```\n"
    )


def _lh_rows(outputs: Path, variant: str):
    p = outputs / "figures" / "lh" / f"table1_1{'_' + variant if variant else ''}.csv"
    try:
        with open(p, newline="") as fh:
            return list(csv.DictReader(fh))
    except OSError:
        return None


def _num(v, fmt):
    return "–" if v in (None, "", "None") else format(float(v), fmt)


def _peak(row, p):
    v = _num(row[f"peak_{p}"], ".0f")
    return ("≥ " + v) if row.get(f"peak_{p}_lower_bound") == "True" else v


def _lh_damping(outputs: Path, sfx: str) -> str:
    r = _json(outputs / "figures" / "lh" / f"results{sfx}.json") or {}
    cs = [
        v["sxx_minus_p_vs_wall_damping_correlation"]
        for v in r.get("runs", {}).values()
        if v and "sxx_minus_p_vs_wall_damping_correlation" in v
    ]
    if not cs:
        return ""
    return (
        f"σ_xx − p_x is the side wall's damping stress γ_x ẋ/(h z) (its equation of motion, LH 1.2): correlation "
        f"{min(cs):.3f}–{max(cs):.3f} over the {len(cs)} loading runs, so the correction (LH 1.10) divides out the "
        "wall's damping.  "
    )


def lh_table(outputs: Path, variant: str = "") -> str | None:
    """The Markdown table of the Luding–Herrmann runs against the paper's values (``variant``: one variant's rows),
    with a note on peaks that are lower bounds; None without results."""
    from .lh import PAPER

    rows = _lh_rows(outputs, variant)
    if not rows:
        return None
    bounds = sum(r.get(f"peak_{p}_lower_bound") == "True" for r in rows for p in ("100", "500"))
    note = (
        f"{bounds} peak(s) fell on the last point of the loading: written ≥, a lower bound (the stress was still rising).  "
        if bounds
        else "No peak fell on the last point of the loading.  "
    )
    if variant:
        shipped = {r["kc_over_k2"]: r for r in (_lh_rows(outputs, "") or [])}
        out = [
            "| k_c/k_2 | peak p = 100 (shipped; paper) | peak p = 500 (paper) | c (shipped; paper) | φ |",
            "|---|---|---|---|---|",
        ]
        for i, r in enumerate(rows):
            s = shipped.get(r["kc_over_k2"], {})
            out.append(
                f"| {float(r['kc_over_k2']):g} | {_peak(r, '100')} ({_peak(s, '100') if s else '–'}; "
                f"{PAPER['peak_100'][i]}) | {_peak(r, '500')} ({PAPER['peak_500'][i]}) | {_num(r['c'], '.1f')} "
                f"({_num(s.get('c'), '.1f')}; {PAPER['c'][i]}) | {_num(r['phi_deg'], '.1f')}° |"
            )
    else:
        out = [
            "| k_c/k_2 | peak p=100 (paper) | peak p=500 (paper) | c (paper) | φ (paper ≈ 13°) |",
            "|---|---|---|---|---|",
        ]
        for i, r in enumerate(rows):
            out.append(
                f"| {float(r['kc_over_k2']):g} | {_peak(r, '100')} ({PAPER['peak_100'][i]}) | {_peak(r, '500')} "
                f"({PAPER['peak_500'][i]}) | {_num(r['c'], '.1f')} ({PAPER['c'][i]}) | {_num(r['phi_deg'], '.1f')}° |"
            )
    return "\n".join(out) + "\n\n" + note + _lh_damping(outputs, f"_{variant}" if variant else "") + "\n"


def lh_slopes(outputs: Path, variant: str = "") -> str | None:
    """The volumetric-strain measures of each loading run (``results[_u].json`` of ``polydem study lh``)."""
    from .lh import KCS, PAPER

    sfx = f"_{variant}" if variant else ""
    r = (_json(outputs / "figures" / "lh" / f"results{sfx}.json") or {}).get("runs")
    if not r:
        return None
    out = [
        "| run | ε_zz at peak | initial slope dε_V/dε_zz (paper) | ν = 1 + slope | late slope (paper) | ψ (paper) |",
        "|---|---|---|---|---|---|",
    ]
    for p in ("100", "500"):
        runs = [r.get(f"p{p}_kc{kc}") for kc in KCS]
        if not all(runs):
            continue

        def col(key, fmt, runs=runs):
            return " / ".join(format(x[key], fmt) for x in runs)

        s1, s2 = PAPER["slopes"][p]
        nu = [x["nu"] for x in runs]
        out.append(
            f"| p{p}{variant} k_c {' / '.join(KCS)} | {col('eps_at_peak', '.3f')} | {col('initial_slope', '+.2f')} ({s1:+.2f}) "
            f"| {max(nu):.2f} … {min(nu):.2f}{' (%.2f)' % PAPER['nu'] if p == '500' else ''} | {col('late_slope', '+.2f')} "
            f"({s2:+.2f}) | {col('psi_deg', '.1f')}° ({PAPER['psi_deg'][p]:g}°) |"
        )
    return "\n".join(out) + "\n"


def lh_rate(outputs: Path) -> str | None:
    """The loading-rate study (Fig. 1.5) of ``polydem study lh``: each rate's peak σ_zz and stress ratio."""
    rate = (_json(outputs / "figures" / "lh" / "results.json") or {}).get("rate")
    if not rate:
        return None
    fs = sorted(rate, key=float)

    def peak(f):
        return ("≥ " if rate[f].get("peak_is_lower_bound") else "") + f"{rate[f]['peak_szz']:.0f}"

    return (
        f"Rate study (Fig. 1.5, p_x = 500, k_c = k_2): peak σ_zz {', '.join(peak(f) for f in fs)} N/m² and peak "
        f"σ_zz/σ_xx {', '.join(format(rate[f]['max_ratio'], '.2f') for f in fs)} for f = {', '.join(fs)} 1/s.\n"
    )


#: block name -> function(outputs folder) giving its Markdown (None when its result is missing)
BLOCKS = {
    "demo_output": demo_output,
    "lh_table_1_1": lambda o: lh_table(o, ""),
    "lh_table_1_1_u": lambda o: lh_table(o, "u"),
    "lh_slopes": lambda o: lh_slopes(o, ""),
    "lh_slopes_u": lambda o: lh_slopes(o, "u"),
    "lh_rate": lh_rate,
}


def blocks(text: str) -> list:
    """The names of the generated blocks in a Markdown text, in order."""
    return [m.group("name") for m in _BLOCK.finditer(text)]


def rewrite(text: str, outputs: Path) -> tuple[str, dict]:
    """``text`` with each generated block whose result exists written anew; {name: "rewritten" | "unchanged" |
    "no result" | "unknown block"}."""
    status = {}

    def sub(m):
        name = m.group("name")
        make = BLOCKS.get(name)
        body = make(outputs) if make else None
        if body is None:
            status[name] = "no result" if make else "unknown block"
            return m.group(0)
        status[name] = "unchanged" if body == m.group("body") else "rewritten"
        return m.group("head") + body + m.group("tail")

    return _BLOCK.sub(sub, text), status


def _replace(p: Path, text: str):
    """Write ``text`` to ``p`` whole (through a temporary file beside it)."""
    tmp = p.with_name(p.name + ".part")
    tmp.write_text(text)
    tmp.replace(p)


def update(root: Path = Path("."), outputs: Path = Path("outputs"), files=DOCS) -> dict:
    """Rewrite the generated blocks of ``files`` (under ``root``) from the results in ``outputs``;
    {file: {block: status}}.  A file is written only when a block changed (whole, through a temporary file)."""
    report = {}
    for rel in files:
        p = Path(root) / rel
        if not p.exists():
            continue
        old = p.read_text()
        new, status = rewrite(old, Path(outputs))
        if new != old:
            _replace(p, new)
        if status.get("demo_output") in ("rewritten", "unchanged"):  # keep the summary the block came from
            _replace(Path(root) / DEMO_SUMMARY, json.dumps(demo_summary(Path(outputs)), indent=1) + "\n")
        if status:
            report[rel] = status
    return report
