"""Bond network: a beam between every initially touching particle pair (thesis §5.1.2).

``L_h`` = centroid distance at t0, ``H_h`` = length of the shared edge, ``T_h`` =
particle thickness.  ``κ_m`` is given, or computed per beam from the energy
``G_h,ax`` by (5.12): ``κ_m = 2 G_h,ax / (E_h κ_0 L_h)``.  A beam with
``κ_m < κ_0`` would snap back; it is an input error naming the beams, or is
clamped to ``κ_m = κ_0`` with a warning if the scenario asks.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ...errors import NOVALUE, ScenarioError
from .beam import BondParams, beam_constants, empty_params
from .interface import MODEL_INTERFACE, IfaceParams, body_frame, element_points, empty_iface, stiffness_ratio


@dataclass
class BondNetwork:
    params: BondParams
    E: np.ndarray
    nu: np.ndarray
    edges: np.ndarray  # (nb, 2, 2) shared edge end points at t0
    clamped: list = field(default_factory=list)  # bond indices whose kappa_m was clamped
    perturbed: list = field(default_factory=list)  # (bond index, factor)
    #: one rank's part of a decomposed scene (``BeamBondFamily.data_layout``): the global index of each bond, and whether this
    #: rank counts it in the statistics (the rank owning its particle I); None in a whole scene
    gid: np.ndarray | None = None
    counted: np.ndarray | None = None

    @property
    def n(self) -> int:
        return int(self.params.a.shape[0])


def empty_network() -> BondNetwork:
    """A network of no bond."""
    return BondNetwork(empty_params(), np.zeros(0), np.zeros(0), np.zeros((0, 2, 2)))


def build_network(
    sc: dict, file: str, specimens: dict, group_ranges: dict, x0: np.ndarray, thickness: np.ndarray, dt: float
) -> BondNetwork:
    """The beam network of ``[bonds]``: one beam per initially touching pair of the bonded groups (the shared edge
    gives H_h, the centroid distance L_h, the thinner particle T), with ``[bonds]``'s E_h, ν_h, κ_0 and κ_m (κ_m
    from G_ax by (5.12) unless given), the ``bonds.perturb`` factors on E_h and the rate law's constants; an empty
    network without ``[bonds]``.  ScenarioError with the key path for an unknown group, no touching pair or
    κ_m < κ_0 (unless clamped)."""
    b = sc["bonds"]
    if b is None:
        return empty_network()
    if b["model"] == "interface" and b["crack_criterion"] == "principal" and sc["time"]["integrator"] == "verlet1":
        raise ScenarioError(
            file,
            "bonds.crack_criterion",
            "principal",
            "needs each step's provisional evaluation, where the particles' stresses are summed (time.integrator "
            "verlet or gear5, not verlet1)",
        )
    groups = b["groups"]
    if groups is None:
        groups = [g for g, sp in specimens.items() if len(sp.shared_pairs)]
    pairs, H, edges, phases = [], [], [], []
    for gi, g in enumerate(groups):
        if g not in specimens:
            raise ScenarioError(file, f"bonds.groups[{gi}]", g, f"unknown particle group ({', '.join(specimens)})")
        sp = specimens[g]
        lo = group_ranges[g][0]
        pairs.append(sp.shared_pairs + lo)
        H.append(sp.shared_lengths)
        edges.append(sp.shared_edges)
        phases.append(bond_phases(sp.phase, sp.shared_pairs))
    if not pairs or sum(len(p) for p in pairs) == 0:
        raise ScenarioError(
            file,
            "bonds.groups",
            groups,
            "no initially touching particle pairs to bond (generators voronoi or hexagon_packing "
            "with touching neighbours)",
        )
    P = np.vstack(pairs).astype(np.int64)
    H = np.concatenate(H)
    edges = np.vstack(edges)
    phase = np.concatenate(phases)
    order = np.lexsort((P[:, 1], P[:, 0]))
    P, H, edges, phase = P[order], H[order], edges[order], phase[order]
    a, bb = P[:, 0], P[:, 1]
    d = x0[bb, :2] - x0[a, :2]
    L = np.hypot(d[:, 0], d[:, 1])
    T = np.minimum(thickness[a], thickness[bb])
    nb = len(a)
    E, nu, kappa0, G_ax = _phase_values(b, phase, file)
    if b["model"] == "interface":
        kappa0 = np.ones(nb)  # the interface's onset is its strength ratio r = 1 (interface.py)
        G_ax = np.full(nb, np.nan)
    E_unperturbed = E.copy()
    perturbed = []
    for pi, p in enumerate(b["perturb"]):
        if p["pair"] is not None:
            i, j = sorted(p["pair"][0])
            hit = np.flatnonzero((a == i) & (bb == j))
            if len(hit) == 0:
                raise ScenarioError(file, f"bonds.perturb[{pi}].pair", p["pair"], "no bond joins these particles")
            k = int(hit[0])
        else:
            mid = 0.5 * (x0[a, :2] + x0[bb, :2])
            k = int(np.argmin(np.hypot(*(mid - np.asarray(p["at"])).T)))
        E[k] *= p["E_factor"]
        perturbed.append((k, p["E_factor"]))
    if b["model"] == "interface":
        kappam = np.ones(nb)
    elif b["kappa_m"] is not None:
        kappam = np.full(nb, b["kappa_m"])
    else:
        k0G = b["G_ax_kappa_0"] if b["G_ax_kappa_0"] is not None else kappa0
        # (5.12) with the unperturbed E_h: the perturbation scales the stiffness only
        kappam = 2.0 * G_ax / (E_unperturbed * k0G * L)
    bad = np.flatnonzero(kappam < kappa0)
    clamped = []
    if len(bad):
        if b["kappa_m_below_kappa_0"] == "error":
            show = ", ".join(
                f"{k} (particles {a[k]}-{bb[k]}, L_h = {L[k]:.4g}, kappa_m = {kappam[k]:.4g})" for k in bad[:5]
            )
            more = f" and {len(bad) - 5} more" if len(bad) > 5 else ""
            raise ScenarioError(
                file,
                "bonds",
                NOVALUE,
                f"{len(bad)} beam(s) have kappa_m < kappa_0 (kappa_0 = {kappa0[bad[0]]:g} at the first; the law would "
                "snap back): "
                f"{show}{more}; lower kappa_0, raise G_ax, or set kappa_m_below_kappa_0 = \"clamp\"",
            )
        kappam[bad] = kappa0[bad]
        clamped = [int(k) for k in bad]
    EA, kb, eta, gfac = beam_constants(L, H, T, E, nu, b["shear_factor"])
    rate = 1 if b["rate_dependent"] else 0
    eps0 = np.full(nb, b["eps0_dot"] if rate else 1.0)
    alpha = np.full(nb, b["alpha"] if rate else 0.0)
    tau = b["rate_filter"] if rate else 0.0
    rate_c = np.full(nb, 1.0 if tau == 0.0 else -np.expm1(-dt / tau))
    params = BondParams(
        a.copy(),
        bb.copy(),
        L,
        H,
        T,
        EA,
        kb,
        eta,
        gfac,
        kappa0,
        kappam,
        eps0,
        alpha,
        d[:, 0] / L,
        d[:, 1] / L,
        rate,
        rate_c,
        _interface(b, file, edges, x0, a, bb, L, H, T, E, nu) if b["model"] == "interface" else empty_iface(),
    )
    return BondNetwork(params, E, nu, edges, clamped, perturbed)


def _interface(b, file, edges, x0, a, bb, L, H, T, E, nu) -> IfaceParams:
    """The edge-interface model's data (interface.py): elements, stiffnesses per area k_n = E/L_h and
    k_s = alpha k_n, strengths and fracture energies; a pure mode whose fracture energy is below the energy density
    at its onset (the softening would snap back) is refused with the least energy that works."""
    ne = b["elements"] or 3
    over = np.flatnonzero(np.asarray(nu) > 1.0 / 3.0)
    if len(over):  # a phase's nu ([bonds.aggregate], [bonds.interface]) above 1/3: a negative shear stiffness
        raise ScenarioError(
            file,
            "bonds",
            NOVALUE,
            f"{len(over)} interface(s) have nu = {np.asarray(nu)[over[0]]:g} > 1/3 (bond {over[0]}, a phase's nu): "
            "k_s/k_n = (1 - 3 nu)/(1 + nu) would be negative",
        )
    rI, rII, n0 = element_points(edges, x0[a, :2], x0[bb, :2], ne)
    phi0 = np.column_stack([x0[a, 2], x0[bb, 2]]) if x0.shape[1] > 2 else np.zeros((len(a), 2))
    rI, rII, n0 = body_frame(rI, rII, n0, phi0)
    kn = E / L
    ks = stiffness_ratio(nu) * kn
    nb = len(a)
    ft = np.full(nb, b["f_t"])
    coh = np.full(nb, b["cohesion"])
    GI = np.full(nb, b["G_I"])
    GII = np.full(nb, b["G_II"])
    for key, G, s, k in (("G_I", GI, ft, kn), ("G_II", GII, coh, ks)):
        need = 0.5 * s * s / k  # the elastic energy density at the onset of the pure mode
        bad = np.flatnonzero(G < need)
        if len(bad):
            raise ScenarioError(
                file,
                f"bonds.{key}",
                b[key],
                f"below the energy density at its onset, {need.max():.4g} g/s^2 at the stiffest interface (bond "
                f"{bad[0]}, particles {a[bad[0]]}-{bb[bad[0]]}): the softening would snap back; raise {key} or lower "
                "the strength",
            )
    return IfaceParams(
        MODEL_INTERFACE,
        rI,
        rII,
        n0,
        phi0,
        H * T / ne,
        kn,
        ks,
        ft,
        coh,
        np.full(nb, b["friction"]),
        np.full(nb, b["residual_friction"]),
        GI,
        GII,
        0.25 * H,
        np.full(nb, np.inf if b["compressive_cap"] is None else b["compressive_cap"]),
        int(b["crack_criterion"] == "principal"),
        np.full(nb, b["f_t"] if b["crack_strength"] is None else b["crack_strength"]),
    )


#: the phase of a beam of a mesoscale specimen (``bond_phases``)
MATRIX, AGGREGATE, INTERFACE = 0, 1, 2


def bond_phases(cell_phase, pairs) -> np.ndarray:
    """Per bonded pair its phase: AGGREGATE (both cells in one aggregate), INTERFACE (one cell in an aggregate and
    the other in the matrix or in another aggregate), MATRIX otherwise or without phases (``cell_phase`` None)."""
    out = np.zeros(len(pairs), np.int64)
    if cell_phase is None or not len(pairs):
        return out
    pa, pb = cell_phase[pairs[:, 0]], cell_phase[pairs[:, 1]]
    out[(pa >= 0) & (pa == pb)] = AGGREGATE
    out[((pa >= 0) | (pb >= 0)) & (pa != pb)] = INTERFACE
    return out


def _phase_values(b: dict, phase: np.ndarray, file: str):
    """Per beam E_h, ν_h, κ_0 and G_h,ax: ``[bonds]``'s, replaced by ``[bonds.aggregate]``'s / ``[bonds.interface]``'s
    values for the beams of those phases."""
    nb = len(phase)
    vals = [np.full(nb, float(b[k]) if b[k] is not None else np.nan) for k in ("E", "nu", "kappa_0", "G_ax")]
    for name, ph in (("aggregate", AGGREGATE), ("interface", INTERFACE)):
        t = b.get(name)
        if t is None:
            continue
        if not np.any(phase == ph):
            raise ScenarioError(
                file,
                f"bonds.{name}",
                NOVALUE,
                f"no {name} beams: the bonded groups have no aggregates (a voronoi group's aggregate_fraction)",
            )
        if t["G_ax"] is not None and b["G_ax"] is None:
            raise ScenarioError(file, f"bonds.{name}.G_ax", t["G_ax"], "the beams use kappa_m, not G_ax ([bonds])")
        for v, k in zip(vals, ("E", "nu", "kappa_0", "G_ax")):
            if t[k] is not None:
                v[phase == ph] = t[k]
    return vals


def bond_links(params: BondParams, n: int):
    """CSR of bonded partners keyed by the smaller particle index (bonds are sorted by (a, b))."""
    start = np.zeros(n + 1, np.int64)
    if params.a.shape[0]:
        np.add.at(start, params.a + 1, 1)
        start = np.cumsum(start)
    return start
