"""The fine scale and element levels of the adaptive discrete–continuum coupling (Sorg 2014; issue 14).

References independent of the code under test, written out in this file (the references use nothing of the
package's elements, assembly, solvers or mesh code): the energy of every bar summed directly from its end displacements; the
lattice's stiffness assembled bar by bar and solved with its held DOFs by scipy's direct solver (:func:`_bars`,
:func:`_held`); closed-form affine fields and the homogenised constants; the softening law, and the sequentially
linear analysis as a few lines of numpy (:func:`_sla_reference`); a chain of bars in series, whose events follow in
closed form; the geometry of the mesh from lattice coordinates (which lattice triangles a super-triangle covers, its
edges, neighbours, hanging nodes, the share of every member, :func:`_triangles` …); the constant-strain triangle of
the homogenised continuum and the Cauchy–Born element from barycentric coordinates (:func:`_cst`,
:func:`_cauchy_born`); Sorg's eigenmode element as the energy statement it is (:func:`_inner_energy`)."""

import math

import numpy as np
import pytest

from polydem_cli.coupling.elements import (
    lattice_constants,
    level1_stiffness,
    level2_stiffness,
    members_in_triangle,
)
from polydem_cli.coupling.lattice import assemble, solve_displacements, triangular_lattice
from polydem_cli.coupling.members import fracture_energy, saw_teeth, softening_force

A, K = 1.0, 2.5e4  # spacing (cm) and bar stiffness (dyn/cm)
RNG = np.random.default_rng(7)
SQRT3 = math.sqrt(3.0)


def _bar_energies(x, members, u, k):
    """½ k δ² of every bar from its end displacements, δ = (u_j − u_i)·(x_j − x_i)/|x_j − x_i| (written out)."""
    out = np.empty(len(members))
    for q, (i, j) in enumerate(members):
        e = x[j] - x[i]
        e = e / math.hypot(*e)
        d = float((u[j] - u[i]) @ e)
        out[q] = 0.5 * k * d * d
    return out


def _affine(x, grad):
    return x @ np.asarray(grad).T


# ---- the lattice and its solve, written out ------------------------------------------------------------------


def _unit(x, members):
    """Unit vectors from the first to the second node of every bar."""
    e = x[members[:, 1]] - x[members[:, 0]]
    return e / np.hypot(e[:, 0], e[:, 1])[:, None]


def _bars(x, members, k):
    """The stiffness (sparse, 2n square) of central-force bars: a bar of stiffness k along the unit vector e from
    node i to node j adds k e⊗e to the blocks (i, i) and (j, j) and −k e⊗e to (i, j) and (j, i)."""
    from scipy.sparse import coo_matrix

    e = _unit(x, members)
    ee = np.broadcast_to(np.asarray(k, float), (len(members),))[:, None, None] * e[:, :, None] * e[:, None, :]
    rows, cols, vals = [], [], []
    for p, q, sign in ((0, 0, 1.0), (1, 1, 1.0), (0, 1, -1.0), (1, 0, -1.0)):
        for r in range(2):
            for c in range(2):
                rows.append(2 * members[:, p] + r)
                cols.append(2 * members[:, q] + c)
                vals.append(sign * ee[:, r, c])
    n = 2 * len(x)
    return coo_matrix((np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))), shape=(n, n)).tocsr()


def _held(Kg, held: dict):
    """(u, reactions K u) with the DOFs of ``held`` ({dof: value}) at their values and the others in equilibrium: a
    direct sparse solve of the free block (scipy's spsolve)."""
    from scipy.sparse.linalg import spsolve

    fixed = np.fromiter(held.keys(), np.int64, len(held))
    val = np.fromiter(held.values(), float, len(held))
    free = np.setdiff1d(np.arange(Kg.shape[0]), fixed)
    u = np.zeros(Kg.shape[0])
    u[fixed] = val
    Kf = Kg[free]
    u[free] = spsolve(Kf[:, free].tocsc(), -(Kf[:, fixed] @ val))
    return u, Kg @ u


def _sla_reference(x, members, k0, TF, TK, held: dict, measure, events, residual=1e-9):
    """Sequentially linear analysis (Rots et al. 2008) written out: at every step the lattice with each member's
    present tooth stiffness (a removed member: ``residual`` × its stiffness ``k0``) is solved for the unit pattern
    ``held``; of the members in tension with a tooth left, the one with the smallest strength / force takes its next
    tooth at that load factor.  [(member, load factor, reaction summed over the DOFs ``measure``)] of ``events``
    events."""
    m, nt = len(members), TF.shape[1]
    rows = np.arange(m)
    e = _unit(x, members)
    tooth = np.zeros(m, np.int64)
    out = []
    for _ in range(events):
        t = np.minimum(tooth, nt - 1)
        k = np.where(tooth < nt, TK[rows, t], residual * np.asarray(k0, float))
        u, r = _held(_bars(x, members, k), held)
        u = u.reshape(-1, 2)
        f = k * np.einsum("mi,mi->m", u[members[:, 1]] - u[members[:, 0]], e)
        live = (tooth < nt) & (f > 0)
        if not live.any():
            break
        ratio = np.where(live, TF[rows, t] / np.where(live, f, 1.0), np.inf)
        c = int(np.argmin(ratio))
        out.append((c, float(ratio[c]), float(ratio[c] * r[list(measure)].sum())))
        tooth[c] += 1
    return out


# ---- the mesh's geometry, from lattice coordinates (coupling/mesh.py states the definitions) --------------------


def _corners(e) -> tuple:
    """The corners of super-triangle e = (i, j, o, s): up (o = 0) (i, j), (i+s, j), (i, j+s); down (i+s, j),
    (i+s, j+s), (i, j+s).  Node (i, j) sits at ((i + j/2) a, j √3/2 a)."""
    i, j, o, s = e
    return ((i, j), (i + s, j), (i, j + s)) if o == 0 else ((i + s, j), (i + s, j + s), (i, j + s))


def _covers(e, t) -> bool:
    """Whether super-triangle e covers lattice triangle t (side 1): t's centroid, (i + 1/3, j + 1/3) up or
    (i + 2/3, j + 2/3) down in lattice coordinates, lies inside e (below the diagonal of e's rhombus cell if e is up,
    above it if down)."""
    i, j, o, s = e
    c = (1 + t[2]) / 3.0
    p, q = t[0] + c - i, t[1] + c - j
    return 0 < p < s and 0 < q < s and ((p + q < s) if o == 0 else (p + q > s))


def _triangles(e) -> list:
    """The lattice triangles super-triangle e covers."""
    i, j, _, s = e
    return [
        (i + p, j + q, o, 1) for p in range(s) for q in range(s) for o in (0, 1) if _covers(e, (i + p, j + q, o, 1))
    ]


def _super(t, s) -> tuple:
    """The super-triangle of side s on the tiling of that side that covers lattice triangle t."""
    i0, j0 = t[0] - t[0] % s, t[1] - t[1] % s
    c = (1 + t[2]) / 3.0
    return (i0, j0, 0 if (t[0] - i0 + c) + (t[1] - j0 + c) < s else 1, s)


def _edges(e) -> tuple:
    a, b, c = _corners(e)
    return ((a, b), (b, c), (c, a))


def _along(p, q) -> list:
    """The lattice nodes from p to q (along a lattice direction), both included, with their fraction from p."""
    n = max(abs(q[0] - p[0]), abs(q[1] - p[1]))
    return [((p[0] + (q[0] - p[0]) * k // n, p[1] + (q[1] - p[1]) * k // n), k / n) for k in range(n + 1)]


def _segments(e) -> set:
    """The unit segments (node pairs, sorted) along e's three edges."""
    out = set()
    for p, q in _edges(e):
        nodes = [nd for nd, _ in _along(p, q)]
        out.update(tuple(sorted(pq)) for pq in zip(nodes, nodes[1:]))
    return out


def _neighbours(els):
    """(per element the set of elements it shares a unit edge segment with, {segment: the elements having it}): a
    segment of one element only lies on the domain's boundary."""
    owner = {}
    for k, e in enumerate(els):
        for sg in _segments(e):
            owner.setdefault(sg, []).append(k)
    nb = [set() for _ in els]
    for ks in owner.values():
        for a in ks:
            nb[a].update(b for b in ks if b != a)
    return nb, owner


def _domain(lat) -> set:
    """The mesh's domain (coupling/mesh.py:domain_set): the lattice triangles whose three corners are nodes (a down
    triangle's anchor (i, j) too)."""
    nodes = set(map(tuple, lat.ij.tolist()))
    return {(i, j, o, 1) for i, j in nodes for o in (0, 1) if all(c in nodes for c in _corners((i, j, o, 1)))}


def _member_shares(lat, dom):
    """(shares, count, index): ``shares(e)`` {member: weight} of element e — how many of its lattice triangles have
    the member as an edge over ``count[member]``, how many domain triangles do; ``index`` {frozenset of the two end
    nodes: member}."""
    ij = [tuple(v) for v in lat.ij.tolist()]
    index = {frozenset((ij[a], ij[b])): m for m, (a, b) in enumerate(lat.members.tolist())}
    count = np.zeros(lat.n_members)
    for t in dom:
        for pq in _edges(t):
            count[index[frozenset(pq)]] += 1

    def shares(e):
        own = {}
        for t in _triangles(e):
            for pq in _edges(t):
                m = index[frozenset(pq)]
                own[m] = own.get(m, 0) + 1
        return {m: c / count[m] for m, c in own.items()}

    return shares, count, index


def _position(lat):
    """{lattice node (i, j): its position}."""
    return {tuple(v): x for v, x in zip(lat.ij.tolist(), lat.x)}


# ---- element matrices, written out -----------------------------------------------------------------------------


def _bary(X, x):
    """Barycentric coordinates (one row per point) of the points ``x`` (m, 2) in the triangle ``X`` (3, 2)."""
    M = np.vstack([np.ones(3), np.asarray(X, float).T])
    return np.linalg.solve(M, np.vstack([np.ones(len(x)), np.asarray(x, float).T])).T


def _cst(X, k):
    """The constant-strain triangle of the homogenised lattice (λ = μ = √3 k/4, the closed forms checked below):
    area × Bᵀ D B with ε = [ε11, ε22, γ12] = B U, B from the gradients of the barycentric coordinates."""
    M = np.vstack([np.ones(3), np.asarray(X, float).T])
    G = np.linalg.inv(M)[:, 1:]  # λ_b = Minv[b] · (1, x, y): ∇λ_b = Minv[b, 1:]
    B = np.zeros((3, 6))
    B[0, 0::2], B[1, 1::2], B[2, 0::2], B[2, 1::2] = G[:, 0], G[:, 1], G[:, 1], G[:, 0]
    lam = mu = SQRT3 * k / 4.0
    D = np.array([[lam + 2 * mu, lam, 0.0], [lam, lam + 2 * mu, 0.0], [0.0, 0.0, mu]])
    return 0.5 * abs(np.linalg.det(M)) * B.T @ D @ B


def _cauchy_born(lat, X, shares: dict, k):
    """Σ w k g gᵀ over the members of ``shares`` ({member: w}), g_b = (λ_b(x_j) − λ_b(x_i)) e: the member's
    elongation under the linear field of the triangle ``X``'s corner displacements."""
    ms = np.fromiter(shares.keys(), np.int64, len(shares))
    w = np.fromiter(shares.values(), float, len(shares))
    lam = _bary(X, lat.x[lat.members[ms].ravel()]).reshape(-1, 2, 3)
    g = ((lam[:, 1] - lam[:, 0])[:, :, None] * _unit(lat.x, lat.members[ms])[:, None, :]).reshape(-1, 6)
    return (g * (w * np.asarray(k, float)[ms])[:, None]).T @ g


def _inner_energy(lat, X, shares: dict, k, v):
    """Twice the least energy (uᵀ K u) of the members of ``shares`` (stiffness k × weight) with the lattice nodes on
    the triangle ``X``'s edges moved by the linear field of the corner displacements ``v`` (6,) and the nodes inside
    free (a dense solve)."""
    ms = np.fromiter(shares.keys(), np.int64, len(shares))
    w = np.fromiter(shares.values(), float, len(shares))
    nodes, local = np.unique(lat.members[ms], return_inverse=True)
    Kl = _bars(lat.x[nodes], local.reshape(-1, 2), w * np.asarray(k, float)[ms]).toarray()
    lam = _bary(X, lat.x[nodes])
    held = np.repeat(np.any(np.abs(lam) < 1e-9, axis=1), 2)
    u = (lam @ np.asarray(v, float).reshape(3, 2)).ravel()
    if not held.all():
        free = ~held
        u[free] = np.linalg.solve(Kl[np.ix_(free, free)], -Kl[np.ix_(free, held)] @ u[held])
    return float(u @ Kl @ u)


def test_homogenised_constants_are_those_of_the_triangular_lattice():
    """λ = μ = √3 k/4, E_2D = 2k/√3, ν = 1/3 (the closed forms of the issue), and the energy density of a
    lattice under affine strains equals ½ λ (tr ε)² + μ ε:ε: a bar energy sum over a periodic cell."""
    c = lattice_constants(K)
    assert c["lambda"] == pytest.approx(math.sqrt(3) * K / 4, rel=1e-15)
    assert c["mu"] == pytest.approx(math.sqrt(3) * K / 4, rel=1e-15)
    assert c["E"] == pytest.approx(2 * K / math.sqrt(3), rel=1e-14)
    assert c["nu"] == pytest.approx(1.0 / 3.0, rel=1e-14)
    for _ in range(5):
        g = RNG.normal(size=(2, 2)) * 1e-3
        eps = 0.5 * (g + g.T)
        w = 0.5 * c["lambda"] * np.trace(eps) ** 2 + c["mu"] * np.sum(eps * eps)
        # one node's three bars (0°, 60°, 120°) carry the energy of an area √3/2 a² (periodic lattice)
        bars = A * np.array([[1.0, 0.0], [0.5, math.sqrt(3) / 2], [-0.5, math.sqrt(3) / 2]])
        e = sum(0.5 * K * float(b @ g @ b / A) ** 2 for b in bars)  # δ = n·∇u·n a = b·∇u·b / a
        assert e / (math.sqrt(3) / 2 * A * A) == pytest.approx(w, rel=1e-12)


def test_lattice_geometry_rhombus_hole_and_member_count():
    lat = triangular_lattice(A, 10.0, 8.0)
    d = np.hypot(*(lat.x[lat.members[:, 1]] - lat.x[lat.members[:, 0]]).T)
    assert np.allclose(d, A, rtol=1e-14) and np.allclose(lat.L, A, rtol=1e-14)
    assert lat.x[:, 0].min() >= -1e-9 and lat.x[:, 0].max() <= 10.0 + 1e-9 and lat.x[:, 1].max() <= 8.0 + 1e-9
    # every interior node has six neighbours
    deg = np.bincount(lat.members.ravel(), minlength=lat.n_nodes)
    inner = (lat.x[:, 0] > 1.1) & (lat.x[:, 0] < 8.9) & (lat.x[:, 1] > 1.1) & (lat.x[:, 1] < 6.9)
    assert np.all(deg[inner] == 6)
    holed = triangular_lattice(A, 10.0, 8.0, hole=((5.0, 4.0), (2.0, 1.5)))
    gone = lat.n_nodes - holed.n_nodes
    assert gone > 0
    assert not np.any(np.abs(holed.x[:, 0] - 5.0) / 2.0 + np.abs(holed.x[:, 1] - 4.0) / 1.5 < 1 - 1e-9)


def test_an_affine_boundary_displacement_gives_the_affine_field_inside():
    """Patch test of the lattice solver: every boundary node of a rectangle moved by an affine field, the
    interior nodes (free) take the same affine field to round-off (each interior node is balanced by its six
    symmetric neighbours), and the stored energy is the sum of the bar energies of that field."""
    lat = triangular_lattice(A, 12.0, 9.0)
    x = lat.x
    g = np.array([[2e-3, -7e-4], [5e-4, -1e-3]])
    deg = np.bincount(lat.members.ravel(), minlength=lat.n_nodes)
    boundary = np.flatnonzero(deg < 6)
    u_aff = _affine(x, g)
    pres = {2 * i + c: u_aff[i, c] for i in boundary for c in range(2)}
    Kg = assemble(lat, K)
    u = solve_displacements(Kg, pres, 2 * lat.n_nodes).reshape(-1, 2)
    assert np.max(np.abs(u - u_aff)) < 1e-12 * np.max(np.abs(u_aff))
    e = 0.5 * u.ravel() @ (Kg @ u.ravel())
    assert e == pytest.approx(_bar_energies(x, lat.members, u_aff, K).sum(), rel=1e-12)


def test_lattice_in_uniaxial_tension_has_the_homogenised_modulus():
    """A strip pulled along e1 (left edge held in e1, one node pinned, right edge displaced; the long
    edges free): E_2D = σ/ε and ν = −ε22/ε11 of the middle part within 3 % of 2k/√3 and 1/3 (edge effects)."""
    W, H = 60.0, 12.0 * math.sqrt(3) / 2 * A * 2
    lat = triangular_lattice(A, W, H)
    x = lat.x
    left = np.flatnonzero(x[:, 0] < 1e-9)
    right = np.flatnonzero(x[:, 0] > x[:, 0].max() - 1e-9)
    du = 0.06
    pres = {2 * i: 0.0 for i in left}
    pres.update({2 * i: du for i in right})
    pres[2 * left[0] + 1] = 0.0
    Kg = assemble(lat, K)
    u = solve_displacements(Kg, pres, 2 * lat.n_nodes)
    f = Kg @ u
    force = f[2 * right].sum()
    height = x[:, 1].max() - x[:, 1].min()
    eps = du / (x[right[0], 0] - x[left[0], 0])
    c = lattice_constants(K)
    assert force / height / eps == pytest.approx(c["E"], rel=0.03)
    u2 = u.reshape(-1, 2)
    mid = np.abs(x[:, 0] - W / 2) < 2 * A
    top, bot = mid & (x[:, 1] > x[:, 1].max() - 1e-9), mid & (x[:, 1] < 1e-9)
    eps22 = (u2[top, 1].mean() - u2[bot, 1].mean()) / height
    assert -eps22 / eps == pytest.approx(c["nu"], rel=0.03)


@pytest.mark.parametrize("side", [1, 2, 4])
def test_patch_test_level_1_level_2_and_the_lattice_store_the_same_energy(side):
    """A triangle with corners at lattice nodes and edges along lattice directions (side 1, 2, 4 spacings),
    an arbitrary affine displacement: the level-1 element (homogenised continuum), the level-2 element
    (Cauchy–Born over the members it covers, edge members counted half) and the lattice itself (the bars
    inside, edge bars half) store the same energy to round-off."""
    lat = triangular_lattice(A, 12.0, 10.0)
    where = lat.node_at()
    i0, j0 = 3, 2
    corners = [where[(i0, j0)], where[(i0 + side, j0)], where[(i0, j0 + side)]]
    X = lat.x[corners]
    idx, w = members_in_triangle(lat.x, lat.members, X)
    assert np.isclose(w.sum(), 1.5 * side * side)  # 3/2 bars per small triangle, side² small triangles
    for _ in range(4):
        g = RNG.normal(size=(2, 2)) * 1e-3
        U = _affine(X, g).ravel()
        e1 = 0.5 * U @ level1_stiffness(X, K) @ U
        e2 = 0.5 * U @ level2_stiffness(X, lat.n[idx], lat.L[idx], np.full(len(idx), K), w) @ U
        el = float((w * _bar_energies(lat.x, lat.members[idx], _affine(lat.x, g), K)).sum())
        assert e1 == pytest.approx(el, rel=1e-12)
        assert e2 == pytest.approx(el, rel=1e-12)


def test_level2_edge_members_on_the_domain_boundary_count_fully():
    lat = triangular_lattice(A, 4.0, 4.0)
    where = lat.node_at()
    X = lat.x[[where[(0, 0)], where[(2, 0)], where[(0, 2)]]]
    _, w_in = members_in_triangle(lat.x, lat.members, X)
    _, w_b = members_in_triangle(lat.x, lat.members, X, boundary_edge=lambda p, q: {p, q} == {0, 1})
    assert w_b.sum() - w_in.sum() == pytest.approx(0.5 * 2)  # the two bars of the bottom edge: ½ → 1


def _law(d, k, ft, du):
    """Linear softening written out: k d up to ft/k, then the straight line to 0 at du."""
    dt = ft / k
    return k * d if d <= dt else (ft * (du - d) / (du - dt) if d < du else 0.0)


def _problem(lat, k, pattern, measure, domain=frozenset(), k_ref=None):
    """The lattice problem the quasi-static stepper takes (coupling/problem.py): member stiffnesses ``k``, the unit
    pattern {(node (i, j), component): value}, the measured (node, component)s."""
    from polydem_cli.coupling.problem import Problem

    k = np.broadcast_to(np.asarray(k, float), (lat.n_members,)).copy()
    return Problem(lat, domain, k, None, pattern, list(measure), k_ref, True, [])


def _events(st):
    """Advance a softening stepper to its end: one dict per saw-tooth event with its load factor, reaction, member,
    the member's force and elongation, the stored energy and the energy released by the member's stiffness drop (the
    stored energy at the event less that of the same prescribed displacement on the next solve's stiffnesses)."""
    from polydem_cli.coupling.stepper import COL, EVENT

    out = []
    while not st.done:
        kk = st.stiffness()
        row = st.advance()
        if out and "released" not in out[-1]:
            out[-1]["released"] = out[-1]["energy"] - out[-1]["factor"] ** 2 * st.unit_energy
        if row[COL["kind"]] == EVENT:
            c = int(row[COL["member"]])
            out.append(
                {
                    "factor": float(row[COL["u1"]]),
                    "reaction": float(row[COL["reaction"]]),
                    "member": c,
                    "force": float(row[COL["member_force"]]),
                    "elongation": float(row[COL["member_force"]]) / kk[c],
                    "energy": float(row[COL["energy"]]),
                }
            )
    return out


def test_single_softening_member_follows_its_law_and_dissipates_its_fracture_energy():
    """One bar between a fixed and a pulled node, sequentially linear analysis with N teeth (the stepper that
    ``polydem run`` advances): every event lies on the softening curve (force and elongation; the reaction is the
    bar's force, the stored energy ½ f δ), the elastic part has slope k, and the dissipated energy (stored energy
    drops at fixed displacement) approaches G = ½ f_t δ_u as N grows (error ~ 1/N)."""
    from polydem_cli.coupling.stepper import Stepper

    ft, du = 50.0, 0.05
    lat = triangular_lattice(A, 1.0, 0.1)  # two nodes, one bar along e1
    assert lat.n_members == 1
    assert softening_force(0.5 * ft / K, K, ft, du) == pytest.approx(0.5 * ft)
    G = fracture_energy(ft, du)
    pattern = {((0, 0), 0): 0.0, ((0, 0), 1): 0.0, ((1, 0), 1): 0.0, ((1, 0), 0): 1.0}  # node 1 pulled along e1
    errs = []
    for n in (40, 160, 640):
        tf, tk = saw_teeth(K, ft, du, n)
        assert all(f == pytest.approx(_law(f / k, K, ft, du), rel=1e-12) for f, k in zip(tf, tk))  # on the curve
        st = Stepper(_problem(lat, K, pattern, [((1, 0), 0)]), (tf[None, :], tk[None, :]), max_events=n + 2, drop=None)
        ev = _events(st)
        assert len(ev) == n  # one event per tooth, then the bar is gone
        for e in ev:
            assert e["force"] == pytest.approx(_law(e["elongation"], K, ft, du), rel=1e-10)
            assert e["elongation"] == pytest.approx(e["factor"], rel=1e-10)  # the bar's elongation is the pull
            assert e["reaction"] == pytest.approx(e["force"], rel=1e-10)  # the pulled node's reaction is its force
            assert e["energy"] == pytest.approx(0.5 * e["force"] * e["elongation"], rel=1e-10)
        assert ev[0]["force"] == pytest.approx(ft) and ev[0]["elongation"] == pytest.approx(ft / K)
        errs.append(abs(sum(e["released"] for e in ev) - G) / G)
    assert errs[2] < 0.01 and errs[0] > errs[1] > errs[2]
    assert errs[0] / errs[2] == pytest.approx(16.0, rel=0.1)  # first order in 1/N (0.074, 0.020, 0.0050)


def test_a_chain_of_bars_in_series_softens_its_weakest_bar_first_at_the_load_factors_of_the_series_law():
    """Three bars in a row along e1 (strengths 1, 0.8 and 1.1 f_t from the left), the left end held, the right end
    pulled, e2 held everywhere: every bar carries the same force, so the saw-tooth events take the weakest bar tooth by
    tooth until it is removed, then the next weakest; at an event of tooth strength f the load factor (the pull) is
    f Σ_b 1/k_b over the bars' present stiffnesses (a removed bar keeps 1e-9 of its own) and the reaction is f."""
    from polydem_cli.coupling.stepper import Stepper

    ft, du, n = 50.0, 0.01, 5
    lat = triangular_lattice(A, 3.0, 0.1)
    assert lat.n_members == 3 and np.allclose(np.abs(lat.n[:, 0]), 1.0)
    left_x = lat.x[lat.members, 0].min(axis=1)
    strength = ft * np.array([1.0, 0.8, 1.1])[np.round(left_x / A).astype(int)]  # by position from the left
    tf, tk = saw_teeth(K, ft, du, n)
    TF, TK = strength[:, None] * tf[None, :] / ft, np.tile(tk, (3, 1))
    # the teeth of a bar of strength c f_t: c f_t (1 - i/n) with the secant stiffness of the law scaled alike
    pattern = {((i, 0), 1): 0.0 for i in range(4)} | {((0, 0), 0): 0.0, ((3, 0), 0): 1.0}
    st = Stepper(_problem(lat, K, pattern, [((3, 0), 0)]), (TF, TK), max_events=2 * n + 1, drop=None)
    ev = _events(st)
    order = np.argsort(strength, kind="stable")
    assert [e["member"] for e in ev] == [order[0]] * n + [order[1]] * n + [order[2]]
    k = np.full(3, K)
    for q, e in enumerate(ev):
        c, i = e["member"], q % n
        k[c] = TK[c, i]
        f = TF[c, i]
        rel = 1e-10 if k.min() > 1e-3 * K else 1e-6  # round-off of a solve with a removed bar (1e-9 k) in series
        assert e["factor"] == pytest.approx(f * np.sum(1.0 / k), rel=rel)
        assert e["reaction"] == pytest.approx(f, rel=rel) and e["force"] == pytest.approx(f, rel=rel)
        if i == n - 1:
            k[c] = 1e-9 * K  # its last tooth taken: removed


def test_bad_lattice_input_is_refused():
    with pytest.raises(ValueError):
        triangular_lattice(0.0, 1.0, 1.0)
    with pytest.raises(ValueError):
        saw_teeth(K, 50.0, 1e-4, 10)  # delta_u below the elastic limit f_t/k: the law would snap back
    lat = triangular_lattice(A, 3.0, 2.0)
    with pytest.raises(ValueError):
        solve_displacements(assemble(lat, K), {0: 0.0}, 2 * lat.n_nodes)  # one DOF held: a mechanism


def _plate(W=40.0, rows=24, hole=True):
    """A plate with a central rhombus hole, the left edge held in e1 (one node also in e2), the right edge
    pulled by 1 % of the width; the lattice trimmed to what triangles cover (mesh.triangulated)."""
    from polydem_cli.coupling.mesh import triangulated

    H = rows * math.sqrt(3) / 2 * A
    lat = triangulated(triangular_lattice(A, W, H, hole=((W / 2, H / 2), (W / 8, H / 6)) if hole else None))
    node = lat.node_at()
    x = lat.x
    left = [tuple(map(int, lat.ij[i])) for i in np.flatnonzero(x[:, 0] < 1e-9)]
    right = [tuple(map(int, lat.ij[i])) for i in np.flatnonzero(x[:, 0] > x[:, 0].max() - 1e-9)]
    pres = {(nd, 0): 0.0 for nd in left}
    pres.update({(nd, 0): 0.01 * W for nd in right})
    pres[(left[0], 1)] = 0.0
    return lat, node, _domain(lat), pres, [(nd, 0) for nd in right]


def _fine(lat, node, pres, measure):
    """The lattice fully resolved, assembled and solved here (:func:`_bars`, :func:`_held`): displacements (n, 2),
    the reaction summed over ``measure``, the stored energy."""
    u, r = _held(_bars(lat.x, lat.members, K), {2 * node[nd] + c: v for (nd, c), v in pres.items()})
    return u.reshape(-1, 2), float(sum(r[2 * node[nd] + c] for nd, c in measure)), 0.5 * float(u @ r)


def test_refined_everywhere_the_adaptive_solution_is_the_fine_scale_one():
    """Every element a lattice triangle (level 3): the same displacements, reaction and energy as the lattice
    solve to solver tolerance (the member weights share every bar exactly once)."""
    from polydem_cli.coupling.adaptive import solve

    lat, node, dom, pres, measure = _plate()
    u, R, E = _fine(lat, node, pres, measure)
    st = solve(lat, dom, sorted(dom), K, pres, measure)
    assert set(st.level) == {3}
    assert np.max(np.abs(st.u - u)) < 1e-10 * np.max(np.abs(u))
    assert st.reaction == pytest.approx(R, rel=1e-10)
    assert st.energy == pytest.approx(E, rel=1e-10)


def test_coarse_mesh_with_hanging_nodes_passes_the_patch_test():
    """A mesh of a plate with coarse elements (sides up to 8) inside, the lattice triangles along the boundary,
    and hanging nodes between the levels, under an affine displacement of every boundary node: every lattice
    node takes the affine field (level 1, 2 and 3 elements and the hanging-node interpolation all reproduce
    it).  (The boundary is resolved because an affine field asks a surface force of every boundary node of a
    lattice, which a node inside a coarse edge could not receive.)"""
    from polydem_cli.coupling.adaptive import Model, refine, solve
    from polydem_cli.coupling.meshkern import initial_mesh_of

    lat, node, dom, _, _ = _plate(hole=False)
    _, count, index = _member_shares(lat, dom)
    els = [tuple(map(int, e)) for e in initial_mesh_of(lat, 8)]
    while True:  # split every coarse element with a bar on the boundary (in one domain triangle only)
        edge = {
            k
            for k, e in enumerate(els)
            if e[3] > 1 and any(count[index[frozenset(pq)]] == 1 for t in _triangles(e) for pq in _edges(t))
        }
        if not edge:
            break
        els = [tuple(map(int, e)) for e in refine(els, edge)]
    hanging = Model(lat, dom, els, K, K).hang
    assert hanging and max(e[3] for e in els) >= 4  # coarse elements and hanging nodes remain
    masters = {c for e in els for c in _corners(e)} - set(hanging)
    g = np.array([[1e-3, 4e-4], [-2e-4, 6e-4]])
    deg = np.bincount(lat.members.ravel(), minlength=lat.n_nodes)
    ij = [tuple(map(int, v)) for v in lat.ij]
    assert all(ij[i] in masters for i in np.flatnonzero(deg < 6))
    pres = {(ij[i], c): float((lat.x[i] @ g.T)[c]) for i in np.flatnonzero(deg < 6) for c in range(2)}
    st = solve(lat, dom, els, K, pres)
    assert {1, 3} <= set(st.level)
    aff = lat.x @ g.T
    assert np.max(np.abs(st.u - aff)) < 1e-10 * np.max(np.abs(aff))


def test_adaptive_refinement_converges_towards_the_fine_scale_with_fewer_dofs():
    """Start coarse, refine where the element strain jumps (tol 0.1): the reaction approaches the lattice's
    from above (a stiffer, constrained model) and ends within 1 % of it with well under half its DOFs."""
    from polydem_cli.coupling.adaptive import Model, mark, refine, solve
    from polydem_cli.coupling.meshkern import initial_mesh_of

    lat, node, dom, pres, measure = _plate(W=64.0, rows=40)
    _, R, _ = _fine(lat, node, pres, measure)
    els = initial_mesh_of(lat, 8)
    errs, dofs = [], []
    for _ in range(10):
        st = solve(lat, dom, els, K, pres, measure)
        errs.append(st.reaction / R - 1.0)
        dofs.append(st.dofs)
        m = mark(lat, els, st.u, 0.1)
        model = Model(lat, dom, els, K, K)
        assert mark(lat, els, st.u, 0.1, model) == m  # compiled (meshkern) = numpy
        assert mark(lat, els, st.u, 0.1, model, buffer=1) == mark(lat, els, st.u, 0.1, buffer=1)
        if not m:
            break
        els = refine(els, m)
    assert all(e > -1e-12 for e in errs)  # never softer than the lattice
    assert errs[0] > 0.02 and errs[-1] < 0.01 and errs[-1] < errs[0] / 5
    assert dofs[-1] < 0.5 * 2 * lat.n_nodes


def test_the_indicator_scale_leaves_out_the_elements_of_cracked_members():
    """``mark(..., cracked=members)``: the largest element strain is taken over the elements holding none of those
    members, so marking with them equals marking without them at a tolerance scaled by (largest strain without the
    cracked elements) / (largest strain of all) — compiled and numpy alike; with the member of the most strained
    lattice triangle cracked, more elements are marked, never fewer."""
    from polydem_cli.coupling.adaptive import Model, element_strains, mark, refine, solve
    from polydem_cli.coupling.meshkern import initial_mesh_of

    lat, node, dom, pres, measure = _plate(W=48.0, rows=28)
    els = initial_mesh_of(lat, 8)
    for _ in range(3):  # lattice triangles at the hole's corners, where the strain is largest
        st = solve(lat, dom, els, K, pres, measure)
        els = refine(els, mark(lat, els, st.u, 0.1))
    st = solve(lat, dom, els, K, pres, measure)
    model = Model(lat, dom, els, K, K)
    eps = element_strains(lat, els, st.u, model)
    norm = np.sqrt(eps[:, 0] ** 2 + eps[:, 1] ** 2 + 2 * eps[:, 2] ** 2)
    top = int(np.argmax(norm))
    assert model.els[top, 3] == 1  # the most strained element is a lattice triangle
    members = model.members_of(top)[0]
    cracked = np.array(members[:1], np.int64)
    held = model.elements_of_members(cracked)  # the lattice triangles of that member (one or two)
    assert top in held
    rest = np.ones(len(norm), bool)
    rest[held] = False
    scaled = 0.1 * norm[rest].max() / norm.max()
    assert scaled < 0.1
    with_crack = mark(lat, els, st.u, 0.1, model, buffer=1, cracked=cracked)
    assert with_crack == mark(lat, els, st.u, scaled, model, buffer=1)
    assert with_crack == mark(lat, els, st.u, 0.1, buffer=1, cracked=cracked)  # numpy
    assert with_crack > mark(lat, els, st.u, 0.1, model, buffer=1)


def test_deferred_marks_wait_at_most_defer_events_and_resume_exactly():
    """``[adaptive] defer``: after the first event the indicator's marks without a theta reason wait for the next
    refinement or ``defer`` events — so a run takes fewer refinements than with ``defer = 0`` (at once), and
    between two refinements at most ``defer`` events pass with marks waiting; the waiting marks are state: a
    stepper restored from ``state()`` while marks wait gives the rows of the uninterrupted one, bit for bit."""
    from polydem_cli.coupling import examples as ex
    from polydem_cli.coupling.problem import member_teeth
    from polydem_cli.coupling.stepper import COL, REFINE, Stepper

    p = ex.problem("homogeneous_softening", 40.0, 24)
    teeth = member_teeth(p, ex.DU * ex.K_MAT / ex.FT, ex.TEETH)
    keep = [i for i, c in enumerate(COL) if c not in ("wall", "peak_memory")]

    def stepper(defer):
        table = ex.adaptive_table("homogeneous_softening") | {
            "defer": defer,
            "min_gain": 0.0,
        }  # every mark: defer's rule
        return Stepper(p, teeth, table, max_events=150)

    now = stepper(0)
    while not now.done:
        now.advance()
    st, rows, saved, waited, forced = stepper(5), [], None, 0, 0
    while not st.done:
        before = waited
        rows.append(st.advance()[keep])
        waited = waited + 1 if st._deferred else 0
        assert waited <= 5  # solves with marks waiting in a row: events
        forced += before == 5 and rows[-1][COL["kind"]] == REFINE  # the limit's refinement
        if saved is None and st._deferred and st.events > 3:
            saved = (len(rows), {k: np.copy(v) for k, v in st.state().items()})
    assert forced >= 1
    assert st.refinements < now.refinements
    assert saved is not None and len(saved[1]["deferred"])
    again = stepper(5)
    again.restore(saved[1])
    back = again.state()  # the waiting marks and their count survive the round trip
    assert all(np.array_equal(back[k], saved[1][k]) for k in ("deferred", "deferred_events", "tooth", "elements"))
    rest = []
    while not again.done:
        rest.append(again.advance()[keep])
    assert np.array_equal(np.array(rows[saved[0] :]), np.array(rest))


def test_the_fully_resolved_saw_tooth_analysis_takes_the_events_of_one_written_out():
    """The plate with its hole, members of random strengths (0.8–1.2 f_t: no ties), 10 teeth: until the reaction
    has fallen below 5 % of its peak (the crack across both ligaments, some 70 events), the fully resolved stepper
    (its factor updated between events, the compiled scan of the members) takes the same members in the same order
    at the same load factors and reactions as the sequentially linear analysis written out here
    (:func:`_sla_reference`: the lattice assembled and solved afresh for every event)."""
    from polydem_cli.coupling.stepper import Stepper

    lat, node, dom, pres, measure = _plate(W=24.0, rows=14)
    pattern = {key: (1.0 if v else 0.0) for key, v in pres.items()}
    f0 = 1e-3 * K * np.random.default_rng(5).uniform(0.8, 1.2, lat.n_members)
    tf, tk = saw_teeth(1.0, 1.0, 5.0, 10)  # the law per unit strength and stiffness, delta_u = 5 delta_t
    TF, TK = f0[:, None] * tf[None, :], np.full((lat.n_members, 1), K) * tk[None, :]
    ev = _events(Stepper(_problem(lat, K, pattern, measure), (TF, TK), max_events=200, drop=0.05))
    held = {2 * node[nd] + c: v for (nd, c), v in pattern.items()}
    ref = _sla_reference(lat.x, lat.members, K, TF, TK, held, [2 * node[nd] + c for nd, c in measure], len(ev))
    peak = max(abs(r) for _, _, r in ref)
    assert 40 < len(ev) == len(ref) < 200 and abs(ref[-1][2]) < 0.05 * peak < min(abs(r) for _, _, r in ref[:-1])
    assert [e["member"] for e in ev] == [c for c, _, _ in ref]
    assert len({c for c, _, _ in ref}) >= 5  # a crack of several members, some of them several teeth down
    np.testing.assert_allclose([e["factor"] for e in ev], [lam for _, lam, _ in ref], rtol=1e-8)
    np.testing.assert_allclose([e["reaction"] for e in ev], [r for _, _, r in ref], rtol=1e-8)


def test_adaptive_softening_damages_only_resolved_members_and_follows_the_fine_scale():
    """Sequentially linear analysis on the adaptive mesh (the plate with its hole, saw-tooth members): the mesh
    is refined to lattice triangles before any member is damaged, so every damaged member lies in a level-3
    element; against the analysis written out here on the whole lattice (:func:`_sla_reference`) the peak load is
    within 3 % above, the damage starts in the same member, the same number of members is damaged, and the mesh
    keeps well under half the lattice's DOFs."""
    from polydem_cli.coupling.adaptive import Model
    from polydem_cli.coupling.stepper import COL, EVENT, Stepper

    lat, node, dom, pres, measure = _plate()
    pattern = {key: (1.0 if v else 0.0) for key, v in pres.items()}
    tf, tk = saw_teeth(K, 1e-3 * K, 5e-3, 10)
    TF, TK = np.tile(tf, (lat.n_members, 1)), np.tile(tk, (lat.n_members, 1))
    steps = 60
    held = {2 * node[nd] + c: v for (nd, c), v in pattern.items()}
    ref = _sla_reference(lat.x, lat.members, K, TF, TK, held, [2 * node[nd] for nd, _ in measure], steps)
    st = Stepper(_problem(lat, K, pattern, measure, dom, K), (TF, TK), {"enabled": True}, max_events=steps, drop=None)
    events = []
    while not st.done:
        row = st.advance()
        if row[COL["kind"]] == EVENT:
            events.append((int(row[COL["member"]]), row[COL["reaction"]], int(row[COL["dofs"]])))
    assert len(events) == len(ref) == steps and st.refinements > 0
    assert events[0][0] == ref[0][0]
    assert 1.0 <= max(r for _, r, _ in events) / max(r for _, _, r in ref) < 1.03  # measured 1.011
    assert np.count_nonzero(st.tooth) == len({c for c, _, _ in ref})
    m = Model(lat, dom, st.elements, K, k_ref=K)
    for q in np.flatnonzero(st.tooth):
        assert all(m.els[k, 3] == 1 for k in m.elements_of_member(int(q)))
    assert max(d for _, _, d in events) < 0.5 * 2 * lat.n_nodes


def test_eigenmode_stiffness_of_a_uniformly_stiffer_element_is_the_scaled_continuum():
    """The level-2 construction for members off the reference stiffness (Sorg's eigenmodes of the level-1
    element imposed on the element's boundary, eigenvalues from the energy of the inner lattice): for an
    element whose members are all c times stiffer the inner solution is affine, and the result is exactly
    c × the level-1 matrix (the constant-strain triangle of the homogenised continuum, :func:`_cst`)."""
    from polydem_cli.coupling.adaptive import Model
    from polydem_cli.coupling.meshkern import initial_mesh_of

    lat, node, dom, _, _ = _plate(hole=False)
    els = initial_mesh_of(lat, 8)
    m0 = Model(lat, dom, els, K, k_ref=K)
    k_el = max((i for i, lv in enumerate(m0.levels) if lv == 1), key=lambda i: els[i][3])  # interior, coarsest
    assert els[k_el][3] >= 4
    kmem = np.full(lat.n_members, K)
    kmem[m0.members_of(k_el)[0]] = 2.5 * K
    m1 = Model(lat, dom, els, kmem, k_ref=K)
    assert m1.levels[k_el] == 2
    np.testing.assert_allclose(m1.Ke[k_el], 2.5 * m0.Ke[k_el], rtol=1e-9, atol=1e-9 * K)
    np.testing.assert_allclose(m0.Ke[k_el], _cst(m0.X[k_el], K), rtol=1e-9, atol=1e-9 * K)


@pytest.mark.parametrize(
    "name", ["homogeneous_elastic", "heterogeneous_elastic", "homogeneous_softening", "heterogeneous_softening"]
)
def test_sorg_examples_adaptive_against_fully_resolved_on_a_small_plate(name):
    """The four examples of the study (polydem study coupling) on a 40 × 24-row plate: the adaptive solution
    is within 2 % of the fully resolved one (reaction, or peak of the softening curve) with fewer DOFs."""
    from polydem_cli.coupling.examples import run

    ref = run(name, adaptive=False, width=40.0, rows=24)
    ad = run(name, adaptive=True, width=40.0, rows=24)
    key = "peak" if name.endswith("softening") else "reaction"
    assert ad[key] == pytest.approx(ref[key], rel=0.02)
    assert ad["dofs"] < ref["dofs"]


def test_a_buffer_ring_adds_the_marked_elements_neighbours_of_their_side_or_larger():
    """``mark(..., buffer=1)``: the elements the indicator marks, plus their neighbours (the reference's edge
    sharing, :func:`_neighbours`) whose side is at least theirs, never a lattice triangle; two rings reach the
    neighbours of those."""
    from polydem_cli.coupling.adaptive import Model, mark, refine, solve
    from polydem_cli.coupling.meshkern import initial_mesh_of

    lat, node, dom, pres, measure = _plate(W=64.0, rows=40)
    els = initial_mesh_of(lat, 8)
    for _ in range(2):  # a mesh of mixed sides
        st = solve(lat, dom, els, K, pres, measure)
        els = refine(els, mark(lat, els, st.u, 0.1))
    st = solve(lat, dom, els, K, pres, measure)
    model = Model(lat, dom, els, K, K)
    els = [tuple(map(int, e)) for e in els]
    nb, _ = _neighbours(els)
    core = mark(lat, els, st.u, 0.1, model)
    assert core

    def ring(ks):
        return {n for k in ks for n in nb[k] if els[n][3] >= els[k][3] and els[n][3] > 1}

    one = core | ring(core)
    assert one > core  # the buffer adds elements here
    assert mark(lat, els, st.u, 0.1, model, buffer=1) == one
    assert mark(lat, els, st.u, 0.1, model, buffer=2) == one | ring(one)


def test_the_buffer_stops_the_refined_region_creeping_one_element_per_stage():
    """The homogeneous elastic example at 120 × 72 (the scenarios' size): without a buffer the refined region's
    edge creeps along the loaded edge one element per stage (13 stages); with one ring the indicator holds in
    fewer stages, and the reaction is the same to 0.2 % and within 0.5 % of the fully resolved plate's."""
    from polydem_cli.coupling import examples
    from polydem_cli.coupling.stepper import Stepper

    def run(buffer):
        p = examples.problem("homogeneous_elastic", 120.0, 72)
        ad = {"coarse_side": 8, "tol": 0.1, "theta": 0.5, "max_stages": 50, "buffer": buffer}
        st = Stepper(p, None, ad, displacement=1.0)
        while not st.done:
            row = st.advance()
        return st.solves, row[examples.COL["reaction"]], st.end_reason

    n0, r0, why0 = run(0)
    n1, r1, why1 = run(1)
    ref = examples.run("homogeneous_elastic", adaptive=False, width=120.0, rows=72)["reaction"]
    assert why0 == why1 == "the refinement indicator holds"
    assert n1 < n0 - 3
    assert r1 == pytest.approx(r0, rel=2e-3)
    assert r1 == pytest.approx(ref, rel=5e-3)


def _partition(els, dom, largest):
    """The elements are super-triangles on the tilings of their sides (powers of two up to ``largest``) that
    cover every domain triangle exactly once; {lattice triangle: its element}."""
    where = {}
    for k, e in enumerate(els):
        i, j, o, s = e
        assert o in (0, 1) and 1 <= s <= largest and s & (s - 1) == 0 and i % s == 0 and j % s == 0, e
        for t in _triangles(e):
            assert t in dom and t not in where, (e, t)
            where[t] = k
    assert len(where) == len(dom)
    return where


def _check_refinement(old, marked, new, where):
    """``new`` = ``old`` with the ``marked`` elements split: every marked element is covered by smaller ones, no two
    neighbours differ by more than a factor of two in side (2:1 balance), and an element neither marked nor kept was
    split because the balance asked it: it has a neighbour outside it of less than half its side."""
    kept = set(new)
    for k in marked:
        assert all(new[where[t]][3] < old[k][3] for t in _triangles(old[k]))
    nb, owner = _neighbours(new)
    assert all(new[a][3] <= 2 * new[b][3] for a in range(len(new)) for b in nb[a])
    for k, E in enumerate(old):
        if k in marked or E in kept:
            continue
        assert any(
            new[f][3] < E[3] / 2 and not _covers(E, _triangles(new[f])[0])
            for sg in _segments(E)
            for f in owner.get(sg, ())
        ), f"element {E} split without a reason"


def _check_model(lat, dom, els, m, kmem, shares):
    """The model of mesh ``els`` against the mesh's geometry and the element matrices written out here."""
    nb, owner = _neighbours(els)
    assert [set(q) for q in m.neighbours] == nb
    boundary = {ks[0] for ks in owner.values() if len(ks) == 1}
    xs = _position(lat)
    corners = {c for e in els for c in _corners(e)}
    hang = {}  # a corner of an element strictly inside an edge of another: (the edge's ends, fraction)
    for e in els:
        for p, q in _edges(e) if e[3] > 1 else ():
            for nd, t in _along(p, q)[1:-1]:
                if nd in corners:
                    hang.setdefault(nd, set()).update({(p, q, t), (q, p, 1.0 - t)})
    assert hang and set(m.hang) == set(hang)
    assert all(pqt in hang[nd] for nd, pqt in m.hang.items())
    assert set(m.active) == corners and set(m.mi) == corners - set(hang)
    g = np.array([[1.3e-3, -4e-4], [7e-4, 2e-4]])  # T carries an affine field from the masters to every active node
    q = np.zeros(2 * len(m.mi))
    for nd, i in m.mi.items():
        q[2 * i : 2 * i + 2] = g @ xs[nd]
    np.testing.assert_allclose((m.T @ q).reshape(-1, 2), [g @ xs[nd] for nd in m.active], rtol=0, atol=1e-12)
    rigid = [np.tile([1.0, 0.0], 3), np.tile([0.0, 1.0], 3)]
    checked = dict.fromkeys(("level 1", "Cauchy-Born", "eigenmode"), 0)
    for k, e in enumerate(els):
        X = np.array([xs[c] for c in _corners(e)])
        sh = shares(e)
        off = any(kmem[mm] != K for mm in sh)
        coarser_nb = any(els[n][3] < e[3] for n in nb[k])
        assert m.levels[k] == (3 if e[3] == 1 else 2 if (k in boundary or off or coarser_nb) else 1), e
        if m.levels[k] == 1:
            np.testing.assert_allclose(m.Ke[k], _cst(X, K), rtol=1e-9, atol=1e-9 * K)
            checked["level 1"] += 1
        elif m.levels[k] == 3 or not off:
            np.testing.assert_allclose(m.Ke[k], _cauchy_born(lat, X, sh, kmem), rtol=1e-9, atol=1e-9 * K)
            checked["Cauchy-Born"] += e[3] > 1
        else:  # Sorg's eigenmodes: Ke = Σ 2 E(v_i) v_i v_iᵀ over the level-1 element's deformation modes v_i
            rot = np.column_stack([-X[:, 1], X[:, 0]]).ravel()
            for r in rigid + [rot]:
                assert np.linalg.norm(m.Ke[k] @ r) < 1e-9 * K * np.linalg.norm(r)
            lam, V = np.linalg.eigh(m.Ke[k])
            C = _cst(X, 1.0)
            for i in (3, 4, 5):
                if min(abs(lam[i] - lam[j]) for j in (3, 4, 5) if j != i) < 1e-6 * lam[5]:
                    continue  # a repeated eigenvalue: its eigenvectors are any basis of its plane
                v = V[:, i]
                assert np.linalg.norm(C @ v - (v @ C @ v) * v) < 1e-9 * np.linalg.norm(C @ v)  # a mode of C
                assert lam[i] == pytest.approx(_inner_energy(lat, X, sh, kmem, v), rel=1e-8)
                checked["eigenmode"] += 1
    return checked


@pytest.mark.parametrize("seed", [0, 1])
def test_the_mesh_its_hanging_nodes_levels_and_element_matrices_follow_from_its_geometry(seed):
    """Random refinement sequences on a plate with its hole and stiffer members (2.5×) in three random discs,
    against the mesh's geometry worked out here from lattice coordinates and the element matrices written out here:
    the initial meshes (sides 1–16) and every refinement partition the domain into super-triangles on their tilings,
    the initial mesh as coarse as the domain allows, a refinement splits the marked elements and keeps the 2:1
    balance and splits nothing else the balance did not ask; the model's neighbours, levels (3: lattice triangles;
    2: on the boundary, next to a finer element or holding a member off the reference stiffness; 1: the rest),
    hanging nodes (each on the edge it follows, at its fraction), its map T (an affine field at the masters gives it
    at every active node) and its element matrices (level 1: the constant-strain triangle of the homogenised
    continuum; level 2 and 3 with members at the reference stiffness: Cauchy–Born over the members at their shares;
    level 2 holding stiffer members: Sorg's eigenmode element — blind to rigid motion, each eigenvector a mode of the
    level-1 element, its eigenvalue twice the least energy of the members inside with that mode on the edges)."""
    from polydem_cli.coupling.adaptive import Model, refine
    from polydem_cli.coupling.meshkern import initial_mesh_of

    rng = np.random.default_rng(seed)
    lat, node, dom, _, _ = _plate(W=48.0, rows=28)
    kmem = np.full(lat.n_members, K)
    mid = 0.5 * (lat.x[lat.members[:, 0]] + lat.x[lat.members[:, 1]])
    for c in rng.uniform((0.0, 0.0), lat.x.max(axis=0), (3, 2)):
        kmem[np.hypot(*(mid - c).T) < 4.0 * A] = 2.5 * K
    shares, _, _ = _member_shares(lat, dom)
    for s0 in (1, 2, 4, 16):
        els = [tuple(map(int, e)) for e in initial_mesh_of(lat, s0)]
        _partition(els, dom, s0)
        for e in els:  # as coarse as the domain allows: the super-triangle one size up leaves the domain
            if e[3] < s0:
                assert not all(t in dom for t in _triangles(_super(_triangles(e)[0], 2 * e[3]))), e
    els = [tuple(map(int, e)) for e in initial_mesh_of(lat, 8)]
    where = _partition(els, dom, 8)
    checked = dict.fromkeys(("level 1", "Cauchy-Born", "eigenmode"), 0)
    for stage in range(4):
        if stage:
            coarse = [k for k, e in enumerate(els) if e[3] > 1]
            marked = set(rng.choice(coarse, size=max(1, len(coarse) // 6), replace=False).tolist())
            old, els = els, [tuple(map(int, e)) for e in refine(els, marked)]
            where = _partition(els, dom, 8)
            _check_refinement(old, marked, els, where)
        m = Model(lat, dom, els, kmem, k_ref=K)
        assert {1, 2, 3} <= set(m.levels.tolist()) or stage == 0
        for kind, n in _check_model(lat, dom, els, m, kmem, shares).items():
            checked[kind] += n
    assert min(checked.values()) >= 20, checked  # coarse elements of every kind were checked


def test_updated_factor_solves_with_the_changed_matrix():
    """The Woodbury update (coupling/factor.py) against a dense solve of the changed matrix: a lattice stiffness
    with members softened and removed (c < 0, down to 1e-9 of the stiffness) one at a time."""
    from polydem_cli.coupling.factor import HeldSolver, add_dense

    lat = triangular_lattice(A, 10.0, 6.0)
    rng = np.random.default_rng(3)
    k = np.full(lat.n_members, K)
    n2 = 2 * lat.n_nodes
    left = np.flatnonzero(lat.x[:, 0] < 1e-9)
    right = np.flatnonzero(lat.x[:, 0] > lat.x[:, 0].max() - 1e-9)
    fixed = np.concatenate([2 * left, 2 * right, [2 * left[0] + 1]])
    val = np.concatenate([np.zeros(len(left)), np.full(len(right), 0.1), [0.0]])
    hs = HeldSolver(fixed, val, n2)
    Kc = None
    for step in range(12):
        u, r, Kc = hs.solve(Kc, lambda: assemble(lat, k))
        Kd = assemble(lat, k).toarray()
        free = np.setdiff1d(np.arange(n2), fixed)
        ref = np.zeros(n2)
        ref[fixed] = val
        ref[free] = np.linalg.solve(Kd[np.ix_(free, free)], -Kd[np.ix_(free, fixed)] @ val)
        assert np.max(np.abs(u - ref)) < 1e-9 * np.max(np.abs(ref))
        assert np.allclose(r, Kd @ ref, atol=1e-8 * K)
        m = int(rng.integers(lat.n_members))
        new = k[m] * (1e-9 if step % 3 == 2 else 0.5)
        a, b = lat.members[m]
        g = np.array([lat.n[m, 0], lat.n[m, 1], -lat.n[m, 0], -lat.n[m, 1]])
        dofs = [2 * a, 2 * a + 1, 2 * b, 2 * b + 1]
        hs.add(dofs, g, new - k[m])
        assert add_dense(Kc, dofs, (new - k[m]) * np.outer(g, g))
        k[m] = new
    assert hs.factorisations == 1  # one factor served every change


def test_saw_tooth_analysis_with_an_updated_factor_takes_the_events_of_fresh_factors(monkeypatch):
    """The softening examples' event sequence (critical member and load factor of every saw-tooth event, fully
    resolved and adaptive) with the factor updated between events equals that with a new factor for every solve —
    with the renewal rule (factor.term_limit) and with a factor kept until its residual check fails (far more
    terms than the rule allows)."""
    from polydem_cli.coupling import examples as ex
    from polydem_cli.coupling import factor

    runs, limits, rule = {}, [], factor.term_limit

    def recorded(fac):
        limits.append(rule(fac))
        return limits[-1]

    for label, limit in (("updated", recorded), ("kept", lambda fac: 10**6), ("fresh", lambda fac: 0)):
        monkeypatch.setattr(factor, "term_limit", limit)
        runs[label] = [ex.run("heterogeneous_softening", adaptive, width=32.0, rows=20) for adaptive in (False, True)]
    assert max(limits) > factor.MIN_TERMS  # the fully resolved plate's fill (53 a row), not the floor, set one
    for label in ("updated", "kept"):
        for upd, fresh in zip(runs[label], runs["fresh"]):
            assert len(upd["factor"]) > 20
            assert upd["damaged"] == fresh["damaged"]
            np.testing.assert_allclose(upd["factor"], fresh["factor"], rtol=1e-9)
            np.testing.assert_allclose(upd["reaction_curve"], fresh["reaction_curve"], rtol=1e-9)


def test_resolving_the_softer_members_first_removes_the_stiffening_of_the_interfaces():
    """``[adaptive] resolve_softer``: the heterogeneous plate's interface members (softer than k) lie in lattice
    triangles from the first mesh on, and the adaptive reaction comes within 1 % of the fully resolved one, where
    Sorg's level-2 elements over those soft bands leave it stiffer (without the indicator's buffer ring, which
    itself refines much of those bands: this test is of ``resolve_softer`` alone)."""
    from polydem_cli.coupling import examples as ex
    from polydem_cli.coupling.adaptive import Model
    from polydem_cli.coupling.stepper import ELASTIC, Stepper

    p = ex.problem("heterogeneous_elastic", width=56.0, rows=32)
    ref = ex.run("heterogeneous_elastic", adaptive=False, width=56.0, rows=32)["reaction"]
    out = {}
    for resolve in (False, True):
        ad = {"coarse_side": 8, "tol": 0.1, "theta": 0.8, "max_stages": 20, "resolve_softer": resolve, "buffer": 0}
        st = Stepper(p, None, ad)
        if resolve:
            m = Model(p.lat, p.domain, st.elements, p.k, k_ref=p.k_ref)
            soft = np.flatnonzero(p.k < p.k_ref)
            assert len(soft) and np.all(m.els[m.elements_of_members(soft), 3] == 1)
        while not st.done:
            row = st.advance()
        assert row[1] == ELASTIC
        out[resolve] = row[3] / ref - 1.0
    assert 0.0 <= out[True] < 0.01 < out[False]


def test_dissipated_energy_and_path_distance_of_saw_tooth_paths():
    """The study's measures of a whole fracture (reproductions/coupling.py): the energy dissipated along a path
    of events is the area between it and the secant back to the origin (a linear-softening bar: ½ f_t δ_u); two
    equal paths are 0 apart, a path with every reaction 10 % higher about 0.1 × the reaction's share apart."""
    from polydem_cli.reproductions.coupling import _path_distance, dissipated

    assert dissipated({"factor": [1.0, 2.0], "reaction_curve": [1.0, 0.0]}) == pytest.approx(1.0)
    assert dissipated({"factor": [1.0, 1.5], "reaction_curve": [1.0, 0.5]}) == pytest.approx(0.5)
    u = np.linspace(1.0, 3.0, 41)
    F = softening_force(u, 1.0, 1.0, 3.0)
    a = {"factor": u.tolist(), "reaction_curve": F.tolist()}
    assert dissipated(a) == pytest.approx(fracture_energy(1.0, 3.0), rel=1e-12)
    assert _path_distance(a, a) == 0.0
    b = {"factor": u.tolist(), "reaction_curve": (1.1 * F).tolist()}
    assert 0.02 < _path_distance(a, b) < 0.1


@pytest.mark.parametrize("intact", [False, True])
@pytest.mark.parametrize("name", ["homogeneous_softening", "heterogeneous_softening"])
def test_the_adaptive_saw_tooth_step_reads_the_mesh_as_a_scan_of_every_member_would(name, intact):
    """Model.sla_ratios (a coarser element's members from its constant strain, the lattice triangles' members from
    their nodes) against the scan it replaced: every member's elongation from the interpolation to every lattice
    node.  Along 80 solves of the example on a 40 × 24 plate, the members' strengths 0.8, 1 and 1.25 times the
    example's by direction (so that a coarser element's three directions differ): the same smallest load factor (1e-9), and the coarser elements to
    refine under the theta rule are those of the scan (members within 1e-9 of the threshold aside)."""
    from polydem_cli.coupling import examples as ex
    from polydem_cli.coupling.lattice import member_elongation
    from polydem_cli.coupling.problem import member_teeth
    from polydem_cli.coupling.stepper import Stepper

    p = ex.problem(name, 40.0, 24)
    TF, TK = member_teeth(p, ex.DU * ex.K_MAT / ex.FT, ex.TEETH)
    from polydem_cli.coupling.lattice import DIRECTIONS

    direction = np.argmax(np.abs(p.lat.n @ DIRECTIONS.T), axis=1)  # 0°, 60°, 120°
    TF = TF * np.array([0.8, 1.0, 1.25])[direction][:, None]  # each direction of an element its own strength
    # with intact_scale false the indicator's scale is taken from every element (it falls silent once members
    # crack), so that the theta rule, not the indicator, decides refinements along the way
    st = Stepper(p, (TF, TK), ex.adaptive_table(name) | {"intact_scale": intact}, max_events=5000)
    theta, nt = ex.adaptive_table(name)["theta"], st.TF.shape[1]
    m = np.arange(p.lat.n_members)
    checked = 0
    for _ in range(80):
        if st.done:
            break
        kk = st.stiffness()
        st._ensure_model(kk)
        model = st.model
        u = model.solve(p.pattern, p.measure, full=True).u  # every lattice node, interpolated
        f = kk * member_elongation(p.lat, u)
        ok = (st.tooth < nt) & (f > 0)
        s = st.TF[m, np.minimum(st.tooth, nt - 1)]
        lam = np.min(np.where(ok, s / np.where(ok, f, 1.0), np.inf))
        ratio_e, _, res, ratio_r, _, _ = model.sla_ratios(u, kk, st.tooth, st.TF)
        assert min(ratio_e.min(initial=np.inf), ratio_r.min(initial=np.inf)) == pytest.approx(lam, rel=1e-9)
        coarse = model.els[:, 3] > 1

        def elements(near, model=model, coarse=coarse):
            ks = model.elements_of_members(np.flatnonzero(near))
            return set(ks[coarse[ks]].tolist())

        strict = elements(ok & (lam * f > theta * s * (1 + 1e-9)))
        loose = elements(ok & (lam * f > theta * s * (1 - 1e-9)))
        ks = model.elements_of_members(res[ratio_r * theta < lam])
        new = set(ks[coarse[ks]].tolist()) | set(np.flatnonzero(ratio_e * theta < lam).tolist())
        assert strict <= new <= loose
        checked += bool(new)
        st.advance()
    assert checked >= 2 or intact  # refinements were decided along the way (with intact_scale, by the indicator)


def test_sla_ratios_of_a_coarser_element_are_its_members_own_under_an_affine_field():
    """Under an affine displacement (a general strain, shear included) every member's elongation is L n·ε·n, so
    Model.sla_ratios must give, element by element, the smallest strength / force over the element's members
    outside the lattice triangles (strengths random per member and weaker in one direction), and for the lattice
    triangles' members their own ratios — computed here member by member from the nodes."""
    from polydem_cli.coupling.adaptive import Model, refine
    from polydem_cli.coupling.meshkern import initial_mesh_of

    lat, node, dom, pres, measure = _plate(W=48.0, rows=28)
    els = initial_mesh_of(lat, 8)
    for step in (3, 7):  # a mesh of sides 8, 4, 2 (and 1 where the hole needs it)
        els = refine(els, set(k for k in range(0, len(els), step) if els[k, 3] > 1))
    model = Model(lat, dom, els, K, K)
    from polydem_cli.coupling.lattice import DIRECTIONS

    eps = np.array([[2.0e-4, 6.0e-4], [6.0e-4, 1.0e-4]])  # stretched most at 60°, compressed at 120°
    u = lat.x @ eps.T  # u = ε x
    direction = np.argmax(np.abs(lat.n @ DIRECTIONS.T), axis=1)
    # strengths random per member, the 120° members three times weaker: a member counted in the wrong direction
    # of its element changes the element's ratio
    f0 = np.random.default_rng(11).uniform(0.8, 1.2, lat.n_members) * np.array([1.0, 1.0, 0.3])[direction]
    TF = f0[:, None] * np.array([[1.0, 0.6, 0.3]])
    tooth = np.zeros(lat.n_members, np.int64)
    kk = np.full(lat.n_members, K)
    ratio_e, dir_e, res, ratio_r, f_r, WM = model.sla_ratios(u, kk, tooth, TF)
    f = kk * np.einsum("mi,ij,mj->m", lat.n, eps, lat.n) * lat.L  # k L n·ε·n
    ratio = np.where(f > 0, TF[:, 0] / np.where(f > 0, f, 1.0), np.inf)
    resolved = np.zeros(lat.n_members, bool)
    resolved[res] = True
    coarse = np.flatnonzero(model.els[:, 3] > 1)
    assert len(coarse) > 20 and len(res) > 100
    for k in coarse:
        ms = model.members_of(k)[0]
        ms = ms[~resolved[ms]]
        want = ratio[ms].min() if len(ms) else np.inf
        assert ratio_e[k] == pytest.approx(want, rel=1e-9)
        if np.isfinite(want):
            assert ratio[WM[k, dir_e[k]]] == pytest.approx(want, rel=1e-9)  # the limiting member named
    np.testing.assert_allclose(ratio_r, ratio[res], rtol=1e-9)


def test_min_gain_ends_an_elastic_analysis_where_the_marks_add_few_nodes():
    """``[adaptive] min_gain``: an elastic analysis ends on the first stage whose marks would refine to a mesh of
    fewer than 1 + min_gain times its master nodes (counted here by the DOF map T of each stage's model) — so it is
    the run without the setting cut after that stage: the same meshes and reactions up to there, bit for bit."""
    from polydem_cli.coupling import examples as ex
    from polydem_cli.coupling.adaptive import Model
    from polydem_cli.coupling.stepper import COL, Stepper

    name = "homogeneous_elastic"
    p = ex.problem(name, 40.0, 24)

    def run(gain):
        st, meshes, reactions = Stepper(p, None, ex.adaptive_table(name) | {"min_gain": gain}), [], []
        while not st.done:
            meshes.append(st.elements.copy())
            reactions.append(st.advance()[COL["reaction"]])
        return meshes, reactions, st.end_reason

    meshes, reactions, reason = run(0.0)
    assert reason == "the refinement indicator holds"
    nodes = [Model(p.lat, p.domain, els, p.k, p.k_ref).T.shape[1] // 2 for els in meshes]
    gains = [b / a - 1.0 for a, b in zip(nodes, nodes[1:])]
    assert len(gains) >= 3 and min(gains) < 0.1 < max(gains)  # a tail of small stages (the hole's corners)
    for gain in (0.5 * min(gains), 1.01 * min(gains), 0.1, 0.5):
        stop = next((i for i, g in enumerate(gains) if g < gain), None)  # the stage it ends on
        m, r, why = run(gain)
        n = len(meshes) if stop is None else stop + 1
        assert len(m) == n and all(np.array_equal(a, b) for a, b in zip(m, meshes))
        assert r == reactions[:n]
        assert ("min_gain" in why) == (stop is not None)


def test_marks_below_min_gain_wait_in_a_softening_run_and_resume_exactly():
    """Softening with ``min_gain``: the indicator's marks that would add fewer than min_gain of the nodes are not
    refined when their ``defer`` events are up but wait another ``defer`` events (their count starts again without
    a refinement); a stepper restored from ``state()`` just after that gives the uninterrupted rows, bit for bit."""
    from polydem_cli.coupling import examples as ex
    from polydem_cli.coupling.problem import member_teeth
    from polydem_cli.coupling.stepper import COL, EVENT, Stepper

    p = ex.problem("homogeneous_softening", 40.0, 24)
    teeth = member_teeth(p, ex.DU * ex.K_MAT / ex.FT, ex.TEETH)
    keep = [i for i, c in enumerate(COL) if c not in ("wall", "peak_memory")]
    table = ex.adaptive_table("homogeneous_softening") | {"defer": 3, "min_gain": 0.05}

    def stepper():
        return Stepper(p, teeth, table, max_events=150)

    st, rows, saved, again_waiting = stepper(), [], None, 0
    while not st.done:
        before = st._waited
        rows.append(st.advance()[keep])
        assert st._waited <= 3  # judged (refined or found small) every `defer` events
        if before >= 3 and st._waited == 1 and rows[-1][COL["kind"]] == EVENT:  # judged small: waits again
            again_waiting += 1
            if saved is None:
                saved = (len(rows), {k: np.copy(v) for k, v in st.state().items()})
    assert again_waiting >= 1 and saved is not None
    again = stepper()
    again.restore(saved[1])
    rest = []
    while not again.done:
        rest.append(again.advance()[keep])
    assert np.array_equal(np.array(rows[saved[0] :]), np.array(rest))
