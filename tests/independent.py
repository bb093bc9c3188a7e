"""Independent reference geometry for tests (a different algorithm from the engine's clipping).

Overlap polygon = convex hull of (vertices of P inside Q) ∪ (vertices of Q inside P) ∪
(all edge–edge crossing points, found by solving the 2x2 linear system of every edge pair).
"""

import numpy as np
from scipy.spatial import ConvexHull


def inside(p, poly, tol=0.0):
    n = len(poly)
    for k in range(n):
        a, b = poly[k], poly[(k + 1) % n]
        if (b[0] - a[0]) * (p[1] - a[1]) - (b[1] - a[1]) * (p[0] - a[0]) < -tol:
            return False
    return True


def crossings(P, Q):
    out = []
    for i in range(len(P)):
        p0, p1 = P[i], P[(i + 1) % len(P)]
        for j in range(len(Q)):
            q0, q1 = Q[j], Q[(j + 1) % len(Q)]
            M = np.column_stack([p1 - p0, q0 - q1])
            if abs(np.linalg.det(M)) < 1e-14:
                continue
            s, t = np.linalg.solve(M, q0 - p0)
            if 0.0 <= s <= 1.0 and 0.0 <= t <= 1.0:
                out.append(p0 + s * (p1 - p0))
    return np.array(out).reshape(-1, 2)


def overlap_area(P, Q):
    pts = [p for p in P if inside(p, Q)] + [q for q in Q if inside(q, P)]
    c = crossings(P, Q)
    pts = np.array(pts + list(c)).reshape(-1, 2)
    if len(pts) < 3:
        return 0.0
    try:
        return float(ConvexHull(pts).volume)
    except Exception:
        return 0.0


def rotate_about(P, c, phi):
    R = np.array([[np.cos(phi), -np.sin(phi)], [np.sin(phi), np.cos(phi)]])
    return (P - c) @ R.T + c


def random_convex(rng, nmin=3, nmax=10, rmin=0.4, rmax=1.2):
    n = rng.integers(nmin, nmax + 1)
    ang = np.sort(rng.uniform(0, 2 * np.pi, n))
    # avoid nearly coincident vertices
    while np.min(np.diff(np.append(ang, ang[0] + 2 * np.pi))) < 0.15:
        ang = np.sort(rng.uniform(0, 2 * np.pi, n))
    r = rng.uniform(rmin, rmax)
    pts = np.column_stack([np.cos(ang), np.sin(ang)]) * r
    A = np.array([[1.0, rng.uniform(-0.3, 0.3)], [0.0, rng.uniform(0.6, 1.4)]])  # affine keeps convexity
    return pts @ A.T
