"""Coarse-scale triangular elements of the adaptive coupling (Sorg 2014), whose nodes are lattice nodes.

Level 1 — the homogenised continuum of the central-force triangular lattice.  A bar of stiffness k along the
unit vector n, at spacing a, stores ½ k a² (n·ε·n)² under an affine strain ε; there are three bars per node
(one per direction) and (√3/2) a² of area per node, so the energy density is
``W(ε) = (k/√3) Σ_{n ∈ 0°, 60°, 120°} (n·ε·n)²``, which is isotropic with

    λ = μ = √3 k / 4,    E_2D = 2 k / √3,    ν = 1/3

(per unit depth; k in force per length, λ and μ in force per length too).  The element is the linear
(constant-strain) triangle of that continuum: ``K_e = A Bᵀ D B``.

Level 2 — the element's stiffness from the lattice members it covers, with the particle displacements
interpolated linearly from its three nodes (Cauchy–Born): a member of direction n and length a inside the
element elongates by ``δ = a n·(∇u)·n`` with ``∇u = Σ_b U_b ⊗ ∇N_b``, so it adds ``w k g gᵀ`` with
``g_b = a (∇N_b·n) n``.  A member on an edge the element shares with another counts half (``w = ½``), one
on the domain's boundary fully.  For a homogeneous lattice and an element whose edges run along lattice
directions the level-1 and level-2 elements and the lattice itself store the same energy under any
affine displacement (the patch test, tests/test_coupling.py).

Level 3 — fully resolved: the lattice's own members between nodes that are all element nodes
(:mod:`.lattice`).
"""

from __future__ import annotations

import math

import numpy as np

SQRT3 = math.sqrt(3.0)


def lattice_constants(k: float) -> dict:
    """λ, μ, E_2D and ν of the homogenised triangular lattice of bars of stiffness k (module docstring)."""
    lam = mu = SQRT3 * k / 4.0
    return {"lambda": lam, "mu": mu, "E": 4.0 * mu * (lam + mu) / (lam + 2.0 * mu), "nu": lam / (lam + 2.0 * mu)}


def constitutive(lam: float, mu: float) -> np.ndarray:
    """D of the 2D isotropic continuum for [ε11, ε22, γ12 = 2ε12]."""
    return np.array([[lam + 2 * mu, lam, 0.0], [lam, lam + 2 * mu, 0.0], [0.0, 0.0, mu]])


def shape_gradients(X) -> tuple:
    """(∇N (3, 2), area) of the linear triangle with corners ``X`` (3, 2), counter-clockwise or not."""
    X = np.asarray(X, float)
    (x1, y1), (x2, y2), (x3, y3) = X
    det = (x2 - x1) * (y3 - y1) - (x3 - x1) * (y2 - y1)
    if abs(det) <= 1e-300:
        raise ValueError("degenerate triangle")
    g = np.array([[y2 - y3, x3 - x2], [y3 - y1, x1 - x3], [y1 - y2, x2 - x1]]) / det
    return g, 0.5 * abs(det)


def level1_stiffness(X, k: float) -> np.ndarray:
    """6×6 stiffness (DOFs u1, u2 of the three nodes) of the constant-strain triangle of the homogenised
    lattice (level 1)."""
    g, A = shape_gradients(X)
    B = np.zeros((3, 6))
    for b in range(3):
        B[0, 2 * b] = g[b, 0]
        B[1, 2 * b + 1] = g[b, 1]
        B[2, 2 * b] = g[b, 1]
        B[2, 2 * b + 1] = g[b, 0]
    c = lattice_constants(k)
    return A * B.T @ constitutive(c["lambda"], c["mu"]) @ B


def level2_stiffness(X, n, L, k, w) -> np.ndarray:
    """6×6 Cauchy–Born stiffness (level 2) of the triangle ``X`` from the lattice members it covers: unit
    vectors ``n`` (m, 2), lengths ``L`` (m,), stiffnesses ``k`` (m,), weights ``w`` (m,)."""
    g, _ = shape_gradients(X)
    n = np.atleast_2d(np.asarray(n, float))
    gn = n @ g.T  # (m, 3): ∇N_b·n
    G = (np.asarray(L, float)[:, None, None] * gn[:, :, None] * n[:, None, :]).reshape(len(n), 6)
    return (G * (np.asarray(k, float) * np.asarray(w, float))[:, None]).T @ G


def members_in_triangle(x, members, X, boundary_edge=None, tol=1e-9) -> tuple:
    """(member indices, weights) of the lattice members a triangle with corners ``X`` covers: members whose
    midpoint lies inside, with weight ½ for a member on an edge (shared with the neighbouring element) or 1
    if that edge is on the domain's boundary (``boundary_edge(p, q)`` → bool for the edge between corners
    p and q).  ``x``: node positions, ``members``: (m, 2) node pairs."""
    g, A = shape_gradients(X)
    X = np.asarray(X, float)
    mid = 0.5 * (x[members[:, 0]] + x[members[:, 1]])
    lam = np.einsum("bk,mk->mb", g, mid - X[0]) + np.array([1.0, 0.0, 0.0])  # barycentric coordinates
    lam[:, 0] = 1.0 - lam[:, 1] - lam[:, 2]
    inside = np.all(lam >= -tol, axis=1)
    idx = np.flatnonzero(inside)
    w = np.ones(len(idx))
    on_edge = np.abs(lam[idx]) <= tol  # the member lies on the edge opposite the corner with λ = 0
    for r, row in enumerate(on_edge):
        if row.any():
            c = int(np.argmax(row))  # corner opposite the edge
            p, q = [b for b in range(3) if b != c]
            w[r] = 1.0 if boundary_edge is not None and boundary_edge(p, q) else 0.5
    return idx, w
