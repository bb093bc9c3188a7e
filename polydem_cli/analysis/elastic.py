"""Linear static response of a bond network: E and ν of a specimen without time integration.

The beams of thesis §5.1.2 are linear elastic until damage starts (κ ≤ κ_0), so the initial
stiffness of a bonded specimen is that of a frame of bar–Timoshenko beam elements between the
centroids.  This module assembles it with scipy.sparse and solves K u = 0 for the prescribed
displacements of the scenario's boundary conditions (every prescribed DOF held at its position,
the loaded set moved by a small û2), then evaluates the macroscopic measures of thesis §7.5.1
as the dynamic run does (:mod:`polydem_cli.analysis.macro`).

It is written independently of the time-stepping kernel: the element matrix is the textbook
stiffness of a 2-node bar + Timoshenko beam (shear area α_Q A_h, η = 12 E_h I_h/(G_h A_h,Q L_h²)),
in local DOFs ``[u_I, v_I, θ_I, u_II, v_II, θ_II]``::

    k = E_h I_h / (L_h³ (1 + η)),  a = E_h A_h / L_h
    K = [[ a,     0,        0,   -a,     0,        0     ],
         [ 0,   12k,     6Lk,    0,  -12k,      6Lk     ],
         [ 0,   6Lk, (4+η)L²k,   0,  -6Lk, (2-η)L²k     ],
         [-a,     0,        0,    a,     0,        0     ],
         [ 0,  -12k,    -6Lk,    0,   12k,     -6Lk     ],
         [ 0,   6Lk, (2-η)L²k,   0,  -6Lk, (4+η)L²k     ]]

rotated into the global frame (DOFs x1, x2, φ per particle).  Contact does not contribute:
specimens start touching without overlap.
"""

from __future__ import annotations

import numpy as np

from ..interactions.bonds.family import BEAM_BONDS


def element_stiffness(L, H, T, E, nu, shear_factor=5.0 / 6.0, angle=0.0) -> np.ndarray:
    """Global 6×6 stiffness of one beam of axis angle ``angle`` (DOFs x1, x2, φ of I then II)."""
    A = H * T
    I = T * H**3 / 12.0
    G = E / (2.0 * (1.0 + nu))
    eta = 12.0 * E * I / (G * shear_factor * A * L * L)
    k = E * I / (L**3 * (1.0 + eta))
    a = E * A / L
    Kl = np.array(
        [
            [a, 0, 0, -a, 0, 0],
            [0, 12 * k, 6 * L * k, 0, -12 * k, 6 * L * k],
            [0, 6 * L * k, (4 + eta) * L * L * k, 0, -6 * L * k, (2 - eta) * L * L * k],
            [-a, 0, 0, a, 0, 0],
            [0, -12 * k, -6 * L * k, 0, 12 * k, -6 * L * k],
            [0, 6 * L * k, (2 - eta) * L * L * k, 0, -6 * L * k, (4 + eta) * L * L * k],
        ]
    )
    c, s = np.cos(angle), np.sin(angle)
    R = np.zeros((6, 6))
    R[:3, :3] = R[3:, 3:] = [[c, s, 0], [-s, c, 0], [0, 0, 1]]
    return R.T @ Kl @ R


def assemble(system):
    """Sparse global stiffness (3n × 3n, CSR) of the undamaged bond network of a built system."""
    from scipy.sparse import coo_matrix

    net = BEAM_BONDS.network(system)
    p = net.params
    n = system.n
    if BEAM_BONDS.interface(system):
        return _assemble_interfaces(net, n)
    shear = system.scenario["bonds"]["shear_factor"] if system.scenario.get("bonds") else 5.0 / 6.0
    d = system.x0[p.b, :2] - system.x0[p.a, :2]
    ang = np.arctan2(d[:, 1], d[:, 0])
    L = np.hypot(d[:, 0], d[:, 1])
    rows, cols, vals = [], [], []
    for k in range(net.n):
        Ke = element_stiffness(L[k], p.H[k], p.T[k], net.E[k], net.nu[k], shear, ang[k])
        dofs = np.r_[3 * p.a[k] + np.arange(3), 3 * p.b[k] + np.arange(3)]
        rows.append(np.repeat(dofs, 6))
        cols.append(np.tile(dofs, 6))
        vals.append(Ke.ravel())
    if not rows:
        raise ValueError("the scene has no bonds: no static network to solve")
    return coo_matrix(
        (np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))), shape=(3 * n, 3 * n)
    ).tocsr()


def _assemble_interfaces(net, n):
    """The undamaged edge interfaces' stiffness (interactions/bonds/interface.py: Σ_e A_e Bᵀ diag(k_n, k_s) B per
    bond, global DOFs) with k_n = E/L_h and k_s = (1 − 3ν)/(1 + ν) k_n from the network's present E and ν."""
    from scipy.sparse import coo_matrix

    from ..interactions.bonds.interface import element_stiffness as iface_stiffness
    from ..interactions.bonds.interface import stiffness_ratio

    p = net.params
    if not net.n:
        raise ValueError("the scene has no bonds: no static network to solve")
    kn = net.E / p.L
    Ke = iface_stiffness(p.iface, kn, stiffness_ratio(net.nu) * kn)
    dofs = np.column_stack([3 * p.a, 3 * p.a + 1, 3 * p.a + 2, 3 * p.b, 3 * p.b + 1, 3 * p.b + 2])
    rows = np.repeat(dofs, 6, axis=1).ravel()
    cols = np.tile(dofs, (1, 6)).ravel()
    return coo_matrix((Ke.reshape(-1), (rows, cols)), shape=(3 * n, 3 * n)).tocsr()


def static_response(system, u2=None) -> dict:
    """Solve the network with every prescribed DOF of the scenario held, the macro load set moved
    by ``u2`` in e2 (default 1e-6 L2, well inside the elastic range), and return the macroscopic
    E, ν (and the reaction, strains) as the dynamic run's measures define them."""
    from scipy.sparse.linalg import spsolve

    m = system.macro
    if m is None:
        raise ValueError("the scenario has no [macro] table (specimen, sets, L1, L2)")
    n = system.n
    K = assemble(system)
    u2 = 1e-6 * m.L2 if u2 is None else float(u2)
    presc = (system.bc_kind != 0).ravel()  # every prescribed DOF
    load = system.sets[m.load_set]
    ub = np.zeros(3 * n)
    ub[3 * load + 1] = u2
    if not np.any(system.bc_kind[load, 1] != 0):
        raise ValueError(f"{m.load_set}: x2 is not prescribed, no displacement to apply")
    # rigid modes not held by the supports: translation in e1 (the dynamic run leaves it free, and
    # eps11 is a difference) and particles without bonds
    bonded = np.zeros(n, bool)
    bonded[BEAM_BONDS.network(system).params.a] = True
    bonded[BEAM_BONDS.network(system).params.b] = True
    fix = presc.copy()
    fix[np.repeat(~bonded, 3)] = True
    if not np.any(presc.reshape(n, 3)[:, 0]):
        fix[3 * int(np.flatnonzero(bonded)[0])] = True
    free = np.flatnonzero(~fix)
    u = ub.copy()
    rhs = -(K[free][:, np.flatnonzero(fix)] @ ub[fix])
    u[free] = spsolve(K[free][:, free].tocsc(), rhs)
    f = K @ u  # force the supports apply = -(interaction forces)
    f2 = float(np.sum(f[3 * load + 1]))
    U = u.reshape(n, 3)
    left, right = system.sets[m.left], system.sets[m.right]
    sigma = f2 / (m.L1 * m.T)
    eps22 = u2 / m.L2
    eps11 = (U[right, 0].mean() - U[left, 0].mean()) / m.L1
    return {
        "E": sigma / eps22,
        "nu": -eps11 / eps22,
        "sigma22": sigma,
        "eps22": eps22,
        "eps11": eps11,
        "f2": f2,
        "u2": u2,
        "dofs": int(len(free)),
    }
