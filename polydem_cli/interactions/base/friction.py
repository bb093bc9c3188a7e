"""Elasto-plastic particle–base friction on Gauss points (thesis §4.4.2).

Permanent full-area contact of a flat particle with a fixed flat base.  At a
material point with body-frame offset X̃ (from the centroid, φ(t0) = 0) the
relative displacement since t0 is (open point O-7)::

    u_u = (x_M(t) − x_M(t0)) + (R(φ) − I) X̃

additive split (4.25), free energy (4.26), stress on the particle (4.27)::

    τ_u = −k_u (u_u − u_u^pl),   F_u = |τ_u| − μ_u |σ_u| ≤ 0   (4.28)

associative flow (4.29) and, per step, the closed-form return mapping
(4.33)–(4.34) in its consistent form (Δλ = F_tr / k_u)::

    τ_tr = −k_u (u_u,l − u^pl_l−1);  Δλ = max(F_tr, 0)/k_u
    u^pl_l = u^pl_l−1 − Δλ τ_tr/|τ_tr|;  τ = τ_tr − Δλ k_u τ_tr/|τ_tr|

σ_u = −ρ T g (self-weight, g = 9.81 m/s²).  Force and moment (4.32) are
integrated over the particle (Fig. 4.11): the polygon is split into triangles
(centroid + two consecutive vertices), each integrated with a Gauss rule; the
Gauss points are material points, fixed in the body, each with its own plastic
slip history.  Rules: 7 points (degree 5, Cowper 1973, the thesis's), 3 points
(degree 2) or 1 point (centroid) — fewer points trade accuracy for speed.

Units: k_u in g cm⁻² s⁻² (= dyn/cm³; 1 N/cm³ = 1e5), σ_u in g cm⁻¹ s⁻².
"""

from __future__ import annotations

import math
from collections import namedtuple

import numpy as np
from numba import njit, prange

from ...jit import loop_njit, named_copy

#: Gauss rules on a triangle in barycentric coordinates: (points (m, 3), weights (m,)), weights sum to 1
_a1 = (6.0 - math.sqrt(15.0)) / 21.0
_b1 = (9.0 + 2.0 * math.sqrt(15.0)) / 21.0
_a2 = (6.0 + math.sqrt(15.0)) / 21.0
_b2 = (9.0 - 2.0 * math.sqrt(15.0)) / 21.0
_w1 = (155.0 - math.sqrt(15.0)) / 1200.0
_w2 = (155.0 + math.sqrt(15.0)) / 1200.0
RULES = {
    1: (np.array([[1 / 3, 1 / 3, 1 / 3]]), np.array([1.0])),
    3: (np.array([[2 / 3, 1 / 6, 1 / 6], [1 / 6, 2 / 3, 1 / 6], [1 / 6, 1 / 6, 2 / 3]]), np.full(3, 1 / 3)),
    7: (
        np.array(
            [
                [1 / 3, 1 / 3, 1 / 3],
                [_a1, _a1, _b1],
                [_a1, _b1, _a1],
                [_b1, _a1, _a1],
                [_a2, _a2, _b2],
                [_a2, _b2, _a2],
                [_b2, _a2, _a2],
            ]
        ),
        np.array([9 / 40, _w1, _w1, _w1, _w2, _w2, _w2]),
    ),
}

BaseParams = namedtuple("BaseParams", ["start", "X", "wA", "ku", "mu_sigma", "x0", "idx"])
# start (np+1) CSR into Gauss points of the particles with base friction, idx (np) their particle
# indices; X (ngp, 2) body-frame offsets; wA (ngp) weight x triangle area; ku, mu_sigma (np): k_u
# and μ_u |σ_u| per particle; x0 (np, 2) centroid at t0

# statistics of a final pass
BA_E_EL = 0
BA_DISS = 1
BA_MAX_UEL = 2
BA_NSLIP = 3  # Gauss points that slipped in this step
BA_FX = 4  # total base friction force on all particles, e1 / e2 (dyn)
BA_FY = 5
N_BASTATS = 6


def gauss_points(body_vertices: np.ndarray, npts: int):
    """Body-frame Gauss points and weights×areas of a convex polygon (centroid at the origin)."""
    P, W = RULES[npts]
    X, wA = [], []
    n = len(body_vertices)
    for k in range(n):
        p1 = body_vertices[k]
        p2 = body_vertices[(k + 1) % n]
        area = 0.5 * abs(p1[0] * p2[1] - p1[1] * p2[0])  # triangle (centroid, p1, p2)
        for b, w in zip(P, W):
            X.append(b[1] * p1 + b[2] * p2)  # b[0] multiplies the centroid (origin)
            wA.append(w * area)
    return np.array(X), np.array(wA)


def _base_impl(final, x, start, X, wA, ku, ms, x0, idx, upl, upl_new, F, ws):
    """Loop over particles with base friction (independent: each writes only its own F row)."""
    for q in prange(idx.shape[0]):
        i = idx[q]
        c = math.cos(x[i, 2])
        s = math.sin(x[i, 2])
        dx = x[i, 0] - x0[q, 0]
        dy = x[i, 1] - x0[q, 1]
        k = ku[q]
        lim = ms[q]
        fx = 0.0
        fy = 0.0
        m = 0.0
        e_el = 0.0
        diss = 0.0
        umax = 0.0
        nslip = 0.0
        for g in range(start[q], start[q + 1]):
            X0 = X[g, 0]
            Y0 = X[g, 1]
            ax = c * X0 - s * Y0  # current arm R(φ) X̃
            ay = s * X0 + c * Y0
            ux = dx + ax - X0  # u_u = Δx_M + (R − I) X̃
            uy = dy + ay - Y0
            tx = -k * (ux - upl[g, 0])
            ty = -k * (uy - upl[g, 1])
            px = upl[g, 0]
            py = upl[g, 1]
            dl = 0.0
            tn2 = tx * tx + ty * ty
            if tn2 > lim * lim and k > 0.0:  # (4.28) violated: no square root for sticking points
                tn = math.sqrt(tn2)
                dl = (tn - lim) / k
                nx = tx / tn
                ny = ty / tn
                px -= dl * nx
                py -= dl * ny
                tx -= dl * k * nx
                ty -= dl * k * ny
                nslip += 1.0
            w = wA[g]
            fx += w * tx
            fy += w * ty
            m += w * (ax * ty - ay * tx)
            if final:
                upl_new[g, 0] = px
                upl_new[g, 1] = py
                el2 = (ux - px) ** 2 + (uy - py) ** 2
                e_el += w * 0.5 * k * el2
                diss += w * math.sqrt(tx * tx + ty * ty) * dl
                if el2 > umax:
                    umax = el2
        F[i, 0] += fx
        F[i, 1] += fy
        F[i, 2] += m
        ws[q, 4] = fx
        ws[q, 5] = fy
        ws[q, 0] = e_el
        ws[q, 1] = diss
        ws[q, 2] = math.sqrt(umax)
        ws[q, 3] = nslip


#: only the threaded compilation (faster than the serial one at any size, see contact.kernel._pairs)
_base = njit(cache=True, parallel=True)(named_copy(_base_impl, "_base_threaded"))


@loop_njit
def base_pass(final, x, bs, upl, upl_new, F, ws, bastats):
    """Provisional (final = False) or final base-friction update; adds f_u^g (4.32) to F.

    ``upl`` holds u_u^pl of the last completed step; a final pass writes the new
    values to ``upl_new`` (committed by the driver at the end of the step).
    Deterministic for any thread count: each particle's sum runs in one thread
    in a fixed Gauss-point order.
    """
    _base(final, x, bs.start, bs.X, bs.wA, bs.ku, bs.mu_sigma, bs.x0, bs.idx, upl, upl_new, F, ws)
    if final:
        e = 0.0
        d = 0.0
        um = 0.0
        ns = 0.0
        fx = 0.0
        fy = 0.0
        for q in range(bs.idx.shape[0]):
            e += ws[q, 0]
            d += ws[q, 1]
            um = max(um, ws[q, 2])
            ns += ws[q, 3]
            fx += ws[q, 4]
            fy += ws[q, 5]
        bastats[BA_E_EL] = e
        bastats[BA_DISS] = d
        bastats[BA_MAX_UEL] = um
        bastats[BA_NSLIP] = ns
        bastats[BA_FX] = fx
        bastats[BA_FY] = fy


def empty_base() -> BaseParams:
    """Base-friction parameters with no Gauss point (a scene without ``[base]``)."""
    return BaseParams(
        np.zeros(1, np.int64),
        np.zeros((0, 2)),
        np.zeros(0),
        np.zeros(0),
        np.zeros(0),
        np.zeros((0, 2)),
        np.zeros(0, np.int64),
    )


def build_base(body_v, vert_start, x0, density, thickness, ku, mu_u, g, npts) -> BaseParams:
    """Gauss points of every particle with base friction (k_u > 0 and μ_u > 0)."""
    idx = [i for i in range(len(x0)) if ku[i] > 0 and mu_u[i] > 0]
    if not idx:
        return empty_base()
    start, Xs, ws = [0], [], []
    for i in idx:
        X, wA = gauss_points(body_v[vert_start[i] : vert_start[i + 1]], npts)
        Xs.append(X)
        ws.append(wA)
        start.append(start[-1] + len(X))
    idx = np.asarray(idx, np.int64)
    sigma = density[idx] * thickness[idx] * g  # |σ_u| = ρ T g
    return BaseParams(
        np.asarray(start, np.int64),
        np.vstack(Xs),
        np.concatenate(ws),
        np.asarray(ku, float)[idx],
        np.asarray(mu_u, float)[idx] * sigma,
        np.ascontiguousarray(x0[idx, :2]),
        idx,
    )


def full_slip_moment_regular_polygon(n_sides: int, circumradius: float) -> float:
    """∫_A |r| dA of a regular polygon about its centre (the full-slip moment per unit μ_u|σ_u|).

    Each of the n isosceles triangles centre–edge: ∫_{−π/n}^{π/n} (a³/3) sec³θ dθ with the
    apothem a = R cos(π/n); ∫ sec³ = ½ (sec tan + ln|sec + tan|).
    """
    t = math.pi / n_sides
    a = circumradius * math.cos(t)
    sec, tan = 1.0 / math.cos(t), math.tan(t)
    return n_sides * (a**3 / 3.0) * (sec * tan + math.log(sec + tan))
