"""``polydem study coupling``: the four examples of Sorg (2014), adaptive against fully resolved
(polydem_cli/coupling/examples.py states the choices), with results.json and figures in ``out``:

* ``results.json`` — per example: reaction (linear) or peak and curve (softening) of both, their difference,
  DOFs, peak memory growth, wall times and the time ratio beside the source's (≈ 3× faster, slower, −59 %,
  −89 %), and the damaged members of both runs;
* ``coupling_curves.png`` — load–displacement factor curves of the softening examples, adaptive and reference;
* ``coupling_mesh_<example>.png`` — the final adaptive mesh coloured by level, damaged members drawn.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from ..report.common import force_unit, label_axes_cm
from ..report.common import save as _save
from .sources import source

#: the source's time of the adaptive simulation relative to the fully resolved one (reproductions/sources/sorg2014.toml)
SOURCE_TIME_RATIO = source("sorg2014")["time_ratio"]


def _ratio(v) -> str:
    """A time ratio of the source for printing: a number to two places, or its words ("> 1")."""
    return f"{v:.2f}" if isinstance(v, (int, float)) else str(v)


def collate(out: Path, width=None, rows=None, examples=None, settings=None) -> dict:
    """Run Sorg's four examples adaptive and fully resolved (``width``, ``rows``: the plate size), time them and write
    the curves, meshes and comparison table to ``out``; returns the collated numbers.  ``settings``: changes to every
    example's adaptive settings (coupling/examples.py ``adaptive_settings``: e.g. ``{"tol": 0.3}``), recorded in the
    results with each example's settings as run."""
    from ..coupling import examples as ex

    for name in examples or ex.EXAMPLES:  # refused before anything is made or run
        ex.adaptive_settings(name, settings)
    out.mkdir(parents=True, exist_ok=True)
    if settings:
        print("adaptive settings changed in every example: " + ", ".join(f"{k} = {v}" for k, v in settings.items()))
    kw = {}
    if width:
        kw["width"] = width
    if rows:
        kw["rows"] = rows
    res = {"choices": ex.__doc__.split("\n\n", 1)[1].strip(), "examples": {}, "changed_settings": dict(settings or {})}
    meshes = {}
    # warm-up outside the timings: imports, and the compiled mesh code loaded from its cache (once per process)
    for name in examples or ex.EXAMPLES:
        for adaptive in (False, True):
            ex.run(name, adaptive=adaptive, width=24.0, rows=14)
    for name in examples or ex.EXAMPLES:
        ref = ex.run(name, adaptive=False, **kw)
        ad = ex.run(name, adaptive=True, settings=settings, **kw)
        ad["settings"] = ex.adaptive_settings(name, settings)
        meshes[name] = (ad.pop("elements"), ad.get("damaged", []))
        row = {"reference": ref, "adaptive": ad, "time_ratio": ad["wall_s"] / ref["wall_s"]}
        row["source_time_ratio"] = SOURCE_TIME_RATIO[name]
        if "peak" in ref:
            row["peak_error"] = ad["peak"] / ref["peak"] - 1.0
            row["curve_error"] = _curve_error(ref, ad)
            row["post_peak_distance"] = _path_distance(ref, ad, post_peak=True)
            row["dissipated"] = {"reference": dissipated(ref), "adaptive": dissipated(ad)}
            row["dissipated_error"] = row["dissipated"]["adaptive"] / row["dissipated"]["reference"] - 1.0
            row["same_damaged_members"] = len(set(ref["damaged"]) & set(ad["damaged"]))
        else:
            row["reaction_error"] = ad["reaction"] / ref["reaction"] - 1.0
        res["examples"][name] = row
        print(
            f"{name:26s} reference {ref['dofs']:>6d} DOFs {ref['wall_s']:7.2f} s, adaptive {ad['dofs']:>6d} DOFs "
            f"{ad['wall_s']:7.2f} s (ratio {row['time_ratio']:.2f}; source {_ratio(SOURCE_TIME_RATIO[name])}); "
            + (
                f"peak {row['peak_error']:+.2%}, dissipated {row['dissipated_error']:+.2%}, post-peak path "
                f"{row['post_peak_distance']:.2%}"
                if "peak_error" in row
                else f"reaction {row['reaction_error']:+.2%}"
            )
        )
    (out / "results.json").write_text(json.dumps(res, indent=1, default=_jsonable))
    _figures(res, meshes, out, **kw)
    return res


def _jsonable(o):
    if isinstance(o, np.integer | np.floating):
        return o.item()
    if isinstance(o, np.ndarray):
        return o.tolist()
    raise TypeError(type(o))


def _curve_error(ref: dict, ad: dict) -> float:
    """L2 difference of the two reaction curves over the reference's load factor range (envelopes of the
    saw-tooth paths: the running maximum of the reaction against the largest factor reached so far), over the
    reference's peak."""
    fr, rr = np.asarray(ref["factor"]), np.asarray(ref["reaction_curve"])
    fa, ra = np.asarray(ad["factor"]), np.asarray(ad["reaction_curve"])
    if len(fr) < 2 or len(fa) < 2:
        return float("nan")
    grid = np.linspace(fr.min(), min(fr.max(), fa.max()), 200)
    a, b = _interp_max(grid, fa, ra), _interp_max(grid, fr, rr)
    return float(np.sqrt(np.mean((a - b) ** 2)) / np.max(np.abs(rr)))


def dissipated(r: dict) -> float:
    """Energy dissipated along a saw-tooth analysis, erg: the work along its path of events from zero load (the
    load–displacement polyline, snap-backs included) less the elastic energy left at its last event, ½ F u (a
    member unloads along its secant to the origin)."""
    u = np.concatenate([[0.0], np.asarray(r["factor"], float)])
    F = np.concatenate([[0.0], np.asarray(r["reaction_curve"], float)])
    return float(np.sum(0.5 * (F[1:] + F[:-1]) * np.diff(u)) - 0.5 * F[-1] * u[-1])


def _path_distance(ref: dict, ad: dict, post_peak=True) -> float:
    """How far apart the two event paths lie in the load–displacement plane: the mean over the points of each path
    (after its peak, with ``post_peak``) of the distance to the other polyline, both directions averaged, with the
    displacement in units of the reference's displacement at its peak and the reaction in its peak."""

    def pts(r):
        u, F = np.asarray(r["factor"], float), np.asarray(r["reaction_curve"], float)
        return u, F

    ur, Fr = pts(ref)
    if len(ur) < 2:
        return float("nan")
    k = int(np.argmax(Fr))
    su, sF = ur[k], Fr[k]

    def norm(r):
        u, F = pts(r)
        p = np.stack([np.concatenate([[0.0], u]) / su, np.concatenate([[0.0], F]) / sF], 1)
        start = int(np.argmax(F)) + 1 if post_peak else 0
        return p, p[start:]

    def dist(points, poly):
        a, b = poly[:-1], poly[1:]
        d = b - a
        t = np.clip(
            np.einsum("pij,ij->pi", points[:, None, :] - a[None], d) / np.maximum((d * d).sum(1), 1e-300), 0.0, 1.0
        )
        near = a[None] + t[..., None] * d[None]
        return np.sqrt(((points[:, None, :] - near) ** 2).sum(-1)).min(axis=1)

    pr, qr = norm(ref)
    pa, qa = norm(ad)
    if not len(qr) or not len(qa):
        return float("nan")
    return float(0.5 * (dist(qa, pr).mean() + dist(qr, pa).mean()))


def _interp_max(grid, f, r):
    """The largest reaction recorded at a load factor up to each grid point (saw-tooth envelope)."""
    order = np.argsort(f, kind="stable")
    f, r = f[order], np.maximum.accumulate(np.asarray(r)[order])
    return np.interp(grid, f, r)


def _figures(res, meshes, out, **kw):
    from ..mpl import pyplot

    plt = pyplot()
    from matplotlib.collections import LineCollection, PolyCollection

    from ..coupling import examples as ex
    from ..coupling.adaptive import Model
    from ..coupling.mesh import corners

    soft = [n for n, r in res["examples"].items() if "peak_error" in r]
    if soft:
        fig, axes = plt.subplots(1, len(soft), figsize=(6 * len(soft), 5), squeeze=False)
        div, unit = force_unit(
            *(res["examples"][n][k]["reaction_curve"] for n in soft for k in ("reference", "adaptive"))
        )
        for ax, name in zip(axes[0], soft):
            for key, style in (("reference", "k-"), ("adaptive", "r-")):
                r = res["examples"][name][key]
                ax.plot(
                    np.concatenate([[0.0], r["factor"]]),
                    np.concatenate([[0.0], r["reaction_curve"]]) / div,
                    style,
                    lw=0.8 if key == "reference" else 0.6,
                    label=f"{key} ({r['dofs']} DOFs): path of the saw-tooth events from zero load, "
                    f"dissipated {dissipated(r):.3g} erg",
                )
            ax.set(
                xlabel=r"displacement of the right edge $\hat u_1$ [cm]",
                ylabel=f"reaction on the right edge [{unit}]",
                title=name.replace("_", " "),
            )
            ax.legend(fontsize=7, loc="upper center", bbox_to_anchor=(0.5, -0.14))
        fig.tight_layout()
        _save(fig, out / "coupling_curves.png", dpi=200)
        plt.close(fig)
    colours = {1: "#d9d9d9", 2: "#fdae61", 3: "#2b83ba"}
    for name, (els, damaged) in meshes.items():
        p = ex.problem(name, **kw)
        node = p.lat.node_at()
        fig, ax = plt.subplots(figsize=(9, 5))
        m = Model(p.lat, p.domain, els, p.k, k_ref=p.k_ref)
        polys = [p.lat.x[[node[c] for c in corners(e)]] for e in els]
        ax.add_collection(
            PolyCollection(polys, facecolors=[colours[lv] for lv in m.levels], edgecolors="k", linewidths=0.15)
        )
        for x, y, r in p.aggregates:
            ax.add_patch(plt.Circle((x, y), r, fill=False, lw=0.6, color="g"))
        if damaged:
            seg = p.lat.x[p.lat.members[damaged]]
            ax.add_collection(LineCollection(seg, colors="r", linewidths=1.2))
        ax.set_aspect("equal")
        ax.autoscale()
        label_axes_cm(ax)
        ax.set(
            title=f"{name.replace('_', ' ')}: adaptive mesh (grey level 1, orange level 2, blue level 3), damaged members red, aggregates green",
        )
        ax.title.set_fontsize(9)
        fig.tight_layout()
        _save(fig, out / f"coupling_mesh_{name}.png", dpi=200)
        plt.close(fig)


def scale_point(name: str, width: float, adaptive: bool) -> dict:
    """One solve of example ``name`` on a plate ``width`` spacings wide (rows 0.6 × width), in this process
    (after a solve of a 16-spacing plate, so that loading the compiled code is not timed): nodes, DOFs, wall time
    (problem set-up and solve separately) and peak resident memory."""
    import resource
    import time

    from ..coupling import examples as ex

    ex.run(name, adaptive=adaptive, width=16.0, rows=10)  # the compiled code loaded before the timing
    t0 = time.perf_counter()
    rows = int(round(0.6 * width))
    ex.problem(name, width, rows)  # set-up alone (lattice, domain, supports), timed apart from the solve
    t_setup = time.perf_counter() - t0
    r = ex.run(name, adaptive=adaptive, width=width, rows=rows)
    return {
        "example": name,
        "width": width,
        "rows": rows,
        "adaptive": adaptive,
        "nodes": r["nodes"],
        "dofs": r["dofs"],
        "reaction": r.get("reaction", r.get("peak")),
        "setup_s": t_setup,
        "wall_s": r["wall_s"],
        "peak_rss_MiB": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0,
    }


def scale(out: Path, widths, name="homogeneous_elastic", limit_s=1800.0, limit_gib=20.0) -> list:
    """The largest plate each solver holds: ``name`` at growing widths, fully resolved and adaptive, each point
    in its own process (its peak memory is its own), a solver dropped once a point exceeds ``limit_s`` of wall
    time or ``limit_gib`` of memory (or fails, e.g. out of memory).  Writes ``scale.json``."""
    import subprocess
    import sys

    out.mkdir(parents=True, exist_ok=True)
    rows, alive = [], {False: True, True: True}
    for w in widths:
        for adaptive in (False, True):
            if not alive[adaptive]:
                continue
            code = (
                "import json; from polydem_cli.reproductions.coupling import scale_point; "
                f"print(json.dumps(scale_point({name!r}, {float(w)!r}, {adaptive!r})))"
            )
            try:
                p = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=limit_s * 1.5)
                res = json.loads(p.stdout.strip().splitlines()[-1]) if p.returncode == 0 else None
                why = None if res else (p.stderr.strip().splitlines() or ["failed"])[-1]
            except subprocess.TimeoutExpired:
                res, why = None, f"over {limit_s * 1.5:.0f} s"
            if res is None:
                res = {"example": name, "width": w, "adaptive": adaptive, "failed": why}
                alive[adaptive] = False
            elif res["wall_s"] + res["setup_s"] > limit_s or res["peak_rss_MiB"] > limit_gib * 1024:
                alive[adaptive] = False
            rows.append(res)
            print(
                f"width {w:>6g}: {'adaptive' if adaptive else 'fully resolved':15s} "
                + (
                    f"{res['nodes']:>9,} nodes {res['dofs']:>9,} DOFs, set-up {res['setup_s']:7.1f} s, "
                    f"solve {res['wall_s']:7.1f} s, peak memory {res['peak_rss_MiB']:8.0f} MiB"
                    if "failed" not in res
                    else f"failed: {res['failed']}"
                ),
                flush=True,
            )
            (out / "scale.json").write_text(json.dumps(rows, indent=1))
    return rows
