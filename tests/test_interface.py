"""Edge-interface bonds (interactions/bonds/interface.py) against closed forms: one interface between two unit
squares sharing the edge x = 1/2 (I centred at the origin, II at (1, 0)), driven by prescribed positions.

The references are written out here from the law's definition (Potyondy 2012's elements, Alfano & Sacco 2006's
damage with friction, the Mohr-Coulomb surface with a tension cut-off): linear softening from f_t to zero at
u_f = 2 G_I / f_t in mode I, from c to zero at 2 G_II / c in mode II, the peak c + mu p and the residual mu_r p
under a normal compression p, the onset on the parabola sigma/f_t + (tau/c)^2 = 1, the moment k_n sum A_e s_e^2
theta of a rotation about the edge's middle, half of it with an open broken element, and no force under rigid
motion."""

import math

import numpy as np
import pytest

from polydem_cli.interactions.bonds.beam import (
    BS_DISS,
    BS_FRIC,
    N_BSTATS,
    BondParams,
    accept_history,
    beam_constants,
    new_history,
    new_history_new,
    new_work,
)
from polydem_cli.interactions.bonds.interface import (
    MODEL_INTERFACE,
    IfaceParams,
    accept_iface,
    body_frame,
    element_points,
    element_stiffness,
    iface_pass,
    stiffness_ratio,
)

E, NU = 1.0e4, 0.2
FT, COH, MU, MUR = 2.0, 3.0, 0.7, 0.5
GI, GII = 0.01, 0.04
H = T = L = 1.0
KN = E / L
KS = KN * (1 - 3 * NU) / (1 + NU)


def one_interface(ne=3, ft=FT, coh=COH, mu=MU, mur=MUR, gi=GI, gii=GII, phi0=(0.0, 0.0), cap=np.inf, principal=0):
    edges = np.array([[[0.5, -0.5], [0.5, 0.5]]])
    xa, xb = np.array([[0.0, 0.0]]), np.array([[1.0, 0.0]])
    ph = np.array([phi0], float)
    rI, rII, n0 = body_frame(*element_points(edges, xa, xb, ne), ph)
    EA, kb, eta, gfac = beam_constants([L], [H], [T], [E], [NU])
    one = lambda v: np.array([float(v)])  # noqa: E731
    ip = IfaceParams(
        MODEL_INTERFACE,
        rI,
        rII,
        n0,
        ph,
        one(H * T / ne),
        one(KN),
        one(stiffness_ratio(NU) * KN),
        one(ft),
        one(coh),
        one(mu),
        one(mur),
        one(gi),
        one(gii),
        one(0.25 * H),
        one(cap),
        principal,
        one(ft),
    )
    bp = BondParams(
        np.array([0]),
        np.array([1]),
        one(L),
        one(H),
        one(T),
        EA,
        kb,
        eta,
        gfac,
        one(1),
        one(1),
        one(1),
        one(0),
        one(1),
        one(0),
        0,
        np.ones(1),
        ip,
    )
    return bp, new_history(1, ne)


def step(bp, bh, x, final=True):
    """One evaluation at positions x (2, 3); accepted when final. (F, stats)."""
    F = np.zeros((2, 3))
    st = np.zeros(N_BSTATS)
    bn = new_history_new(1, bp.iface.rI.shape[1])
    iface_pass(final, np.asarray(x, float), bp, bh, bn, new_work(1, None, 2), F, st)
    if final:
        accept_history(bn, bh)
        accept_iface(bn, bh)
    return F, st


def pos(un=0.0, us=0.0, th=0.0):
    """II displaced by (un, us) from its place and turned by th about the middle of the edge."""
    c = np.array([0.5, 0.0]) + np.array([[math.cos(th), -math.sin(th)], [math.sin(th), math.cos(th)]]) @ [0.5, 0.0]
    return np.array([[0.0, 0.0, 0.0], [c[0] + un, c[1] + us, th]])


def drive(path, **kw):
    """Drive along path [(un, us)], recording (un, us, sigma, tau, dissipated so far, friction so far, active)."""
    bp, bh = one_interface(**kw)
    out, diss, fric = [], 0.0, 0.0
    for un, us in path:
        F, st = step(bp, bh, pos(un, us))
        diss += st[BS_DISS] - st[BS_FRIC]
        fric += st[BS_FRIC]
        out.append((un, us, F[0, 0] / (H * T), F[0, 1] / (H * T), diss, fric, bool(bh.active[0])))
    return np.array(out)


def test_stiffness_ratio_gives_the_lattice_poisson_ratio():
    # a regular triangular lattice of normal and shear springs: nu = (1 - alpha)/(3 + alpha) (plane stress)
    for nu in (-0.5, 0.0, 0.2, 0.3):
        a = stiffness_ratio(nu)
        assert (1 - a) / (3 + a) == pytest.approx(nu, abs=1e-12)


def test_mode_one_linear_softening_and_its_energy():
    u0, uf = FT / KN, 2 * GI / FT
    us = np.linspace(0, 1.2 * uf, 4001)
    r = drive([(u, 0.0) for u in us])
    sig = r[:, 2]
    ref = np.where(us <= u0, KN * us, np.clip(FT * (uf - us) / (uf - u0), 0, None))
    assert np.allclose(sig, ref, atol=1e-9 * FT + 1e-12)
    assert abs(r[:, 3]).max() < 1e-9 * FT  # no shear
    assert r[-1, 4] == pytest.approx(GI * H * T, rel=2e-3)  # G_I times the area, the trapezoidal rule's error
    assert not r[-1, 6]  # broken everywhere and open: handed over to contact


def test_mode_two_linear_softening_and_its_energy():
    s0, sf = COH / KS, 2 * GII / COH
    ss = np.linspace(0, 1.1 * sf, 4001)
    ss = ss[ss < 0.25 * H]
    r = drive([(0.0, s) for s in ss])
    ref = np.where(ss <= s0, KS * ss, np.clip(COH * (sf - ss) / (sf - s0), 0, None))
    assert np.allclose(r[:, 3], ref, atol=1e-9 * COH)
    assert r[-1, 4] == pytest.approx(GII * H * T, rel=2e-3)
    assert r[-1, 5] == pytest.approx(0.0, abs=1e-15)  # no compression: no friction


def test_shear_under_compression_peak_and_residual():
    p = 5.0
    un = -p / KN
    ss = np.linspace(0, 0.2, 20001)
    r = drive([(un, 0.0)] + [(un, s) for s in ss])
    assert np.allclose(r[:, 2], -p, rtol=1e-12)  # compression is carried at any damage
    tau = r[:, 3]
    assert tau.max() == pytest.approx(COH + MU * p, rel=1e-3)  # Mohr-Coulomb onset
    assert tau[-1] == pytest.approx(MUR * p, rel=1e-9)  # the broken faces' Coulomb friction
    assert r[-1, 5] > 0  # friction worked
    assert r[-1, 6]  # broken but closed: still the bond's (a frictional flat joint)


@pytest.mark.parametrize("omega", [0.3, 0.8, 1.2])
def test_mixed_mode_onset_on_the_tension_shear_parabola(omega):
    # along the ray sigma_bar = s cos(omega) ft, tau_bar = s sin(omega) c: the peak lies on sigma/f_t + (tau/c)^2 = 1
    ls = np.linspace(0, 3.0, 30001)
    path = [(s * math.cos(omega) * FT / KN, s * math.sin(omega) * COH / KS) for s in ls]
    r = drive(path, gi=1.0, gii=1.0)  # a long softening: the peak is the onset
    k = int(np.argmax(np.hypot(r[:, 2], r[:, 3])))
    sig, tau = r[k, 2], r[k, 3]
    assert sig / FT + (tau / COH) ** 2 == pytest.approx(1.0, abs=2e-3)
    a, b = math.cos(omega), math.sin(omega)
    s_on = 2.0 / (a + math.sqrt(a * a + 4 * b * b))  # the ray's r = 1
    assert sig == pytest.approx(s_on * a * FT, rel=2e-3)


@pytest.mark.parametrize("ne", [2, 3, 5])
def test_rotation_moment_and_a_partly_broken_interface(ne):
    th = 1e-6
    bp, bh = one_interface(ne=ne)
    F, _ = step(bp, bh, pos(th=th), final=False)
    s = (np.arange(ne) + 0.5) / ne * H - H / 2
    M = KN * (H * T / ne) * np.sum(s * s) * th
    assert F[1, 2] == pytest.approx(-M, rel=1e-5)  # the moment resisting the turn
    assert abs(F[1, 0]) + abs(F[1, 1]) < 1e-4 * M  # no net force to first order
    # break the element at the top (s > 0, the last): turning II by +th about the edge's middle moves its top point
    # towards I (closing it), by -th away from I (opening it)
    bh.iface.D[0, -1] = 1.0
    Fc, _ = step(bp, bh, pos(th=th), final=False)
    Fo, _ = step(bp, bh, pos(th=-th), final=False)
    top = KN * (H * T / ne) * s[-1] ** 2 * th
    # the broken element carries its compression (the full moment), not its tension (the others' moment only)
    assert Fc[1, 2] == pytest.approx(-M, rel=1e-4)
    assert Fo[1, 2] == pytest.approx(M - top, rel=1e-4)


def test_rigid_motion_gives_no_force():
    bp, bh = one_interface()
    drive_to = [(2e-4, 1e-4 * k) for k in range(40)]  # damage it first
    for un, us in drive_to:
        step(bp, bh, pos(un, us))
    x = pos(2e-4, 39e-4)
    F0, _ = step(bp, bh, x, final=False)
    for phi in (0.3, 2.0, -2.9):
        R = np.array([[math.cos(phi), -math.sin(phi)], [math.sin(phi), math.cos(phi)]])
        y = x.copy()
        y[:, :2] = x[:, :2] @ R.T + [3.0, -7.0]
        y[:, 2] += phi
        F, _ = step(bp, bh, y, final=False)
        Fr = F.copy()
        Fr[:, :2] = F[:, :2] @ R  # back into the unrotated frame
        assert np.allclose(Fr, F0, atol=1e-9 * np.abs(F0).max())


def test_element_stiffness_matches_the_kernel():
    # the time step's stiffness against finite differences of the kernel's forces at t0
    bp, bh = one_interface(ne=3)
    K = element_stiffness(bp.iface)[0]
    h = 1e-9
    x0 = pos()
    for j in range(6):
        x = x0.copy()
        x.reshape(-1)[j] += h
        F, _ = step(bp, bh, x, final=False)
        col = -F.reshape(-1) / h
        assert np.allclose(col, K[:, j], rtol=1e-4, atol=1e-6 * np.abs(K).max())


# ---------------------------------------------------------------- in a scene: the whole program with interfaces

ROOT = __import__("pathlib").Path(__file__).resolve().parents[1]
SMOKE = str(ROOT / "scenarios/lab/smoke_interface_tension.toml")


def test_a_panel_of_interfaces_in_tension_keeps_its_energy_and_breaks(tmp_path):
    """The smoke panel through its softening: the energy balance closes (the friction of broken elements is in
    'dissipated' and in its own column), E and nu are those of a lattice of k_n = E/L, k_s = k_n/3 (nu near the
    regular lattice's 0.2), the peak near the interfaces' f_t, and a crack of failed interfaces hands its pairs to
    contact."""
    import json

    import h5py

    from polydem_cli.scenario.load import load_scenario
    from polydem_cli.solvers import driver
    from polydem_cli.solvers.protocol import RunOptions, Source

    sc, text = load_scenario(SMOKE, [])
    out = tmp_path / "t.h5"
    driver.obtain(sc, out, source=Source(SMOKE, text, ()), opts=RunOptions(quiet=True))
    summ = json.loads((tmp_path / "t.summary.json").read_text())
    with h5py.File(out, "r") as f:
        cols = json.loads(f["history/table"].attrs["columns"])
        h = f["history/table"][...]
        b = f["bonds"]
        assert int(b["interface"][0]) == 3
        assert np.allclose(b["k_s"][...] / b["k_n"][...], 1.0 / 3.0)
        fr = f["frames"]
        ed = fr["bond_element_d"][-1]
    c = {n: i for i, n in enumerate(cols)}
    E = h[:, c["elastic"]] + h[:, c["kinetic"]] + h[:, c["dissipated"]] - h[:, c["external_work"]]
    assert np.abs(E - E[0]).max() < 1e-6 * h[:, c["external_work"]].max()
    assert h[-1, c["bonds_failed"]] >= 4
    assert h[-1, c["dissipated_interface_plastic"]] >= 0.0
    assert ed.shape[1] == 3 and ed.max() == 1.0
    m = summ["macro"]
    assert 2.5 < m["strength_MPa"] < 3.3  # the interfaces' f_t = 3 MPa
    assert 0.15 < m["nu"] < 0.25 and 30 < m["E_GPa"] < 42
    # the static solve of the assembled interface stiffnesses (analysis/elastic.py, what calibrate fits E and nu
    # with) gives the dynamic run's fitted E and nu
    from polydem_cli.analysis.elastic import static_response
    from polydem_cli.scenario.build import build_system

    st = static_response(build_system(sc, SMOKE))
    assert st["E"] / 1e10 == pytest.approx(m["E_GPa"], rel=5e-3)
    assert st["nu"] == pytest.approx(m["nu"], abs=5e-3)


def test_interfaces_resume_bit_for_bit(tmp_path):
    """Stopped mid-softening and resumed: the per-element damage, history and slip are checkpoint state."""
    import json

    import h5py

    from polydem_cli.scenario.load import load_scenario
    from polydem_cli.solvers import driver
    from polydem_cli.solvers.protocol import RunOptions, Source

    over = ["time.end_load_drop=0.6"]
    sc, text = load_scenario(SMOKE, over)
    src = Source(SMOKE, text, tuple(over))
    whole, part = tmp_path / "whole.h5", tmp_path / "part.h5"
    driver.obtain(sc, whole, source=src, opts=RunOptions(quiet=True))
    with h5py.File(whole, "r") as f:
        n = int(f["history/table"].shape[0])
    driver.obtain(sc, part, source=src, opts=RunOptions(quiet=True, stop_after=20000))
    with h5py.File(part, "r") as f:  # stopped after its peak, with interfaces softening, before the end
        t = f["history/table"]
        c = json.loads(t.attrs["columns"])
        assert t.shape[0] < n and t[-1, c.index("bonds_damaged")] > 0
        load = np.abs(t[:, c.index("f2:specimen.bottom")])
        assert load[-1] < load.max()
    driver.run(out=part, resume=True, opts=RunOptions(quiet=True))
    with h5py.File(whole, "r") as a, h5py.File(part, "r") as b:
        np.testing.assert_array_equal(a["history/table"][...], b["history/table"][...])
        np.testing.assert_array_equal(a["frames/bond_element_d"][-1], b["frames/bond_element_d"][-1])
    assert n > 10


MPIEXEC = __import__("pathlib").Path(__import__("sys").executable).with_name("mpiexec")


@pytest.mark.skipif(not MPIEXEC.exists(), reason="the mpich wheel (test extra) is not installed")
@pytest.mark.parametrize("criterion", ["facet", "principal"])
def test_interfaces_failing_across_the_boundary_on_two_ranks_as_on_one_process(tmp_path, criterion):
    """The serial run.  With the principal criterion an element across the cut reads both particles' stresses, and
    a rank holds only some interfaces of its ghost: the ghost's stress is its owner's, sent with the halo exchange
    (Family.ghost_field); a ghost's own partial sum would break other elements than the serial run.  Its interfaces
    broken across the cut hand their faces over to contact, which a rank sums in another order (as in
    test_ranks.py's contacts across the boundary): then equal to round-off, the same interfaces broken."""
    from test_ranks import CONCRETE, FAST_PANEL, on_ranks, same_rows, serial

    over = FAST_PANEL + [
        'bonds.model="interface"',
        "bonds.nu=0.2",
        "bonds.f_t=3e7",
        "bonds.cohesion=6e7",
        "bonds.G_I=1e5",
        "bonds.G_II=4e5",
    ]
    if criterion == "principal":  # below the edges' f_t: the particles' stress breaks the elements first
        over += [f'bonds.crack_criterion="{criterion}"', "bonds.crack_strength=1.5e7"]
    steps = 6000
    s, sim, rows = serial(CONCRETE, over, steps)
    got = on_ranks(tmp_path, CONCRETE, over, steps)
    d = sim.bundle("bonds").h.d
    p = sim.bundle("bonds").p
    across = got["owner"][p.a] != got["owner"][p.b]
    assert across.sum() >= 5
    assert (d[across] > 0.0).sum() >= 1, "no interface damaged across the boundary: pull longer"
    x = sim.nord[:, :, 0]
    if criterion == "principal":  # elements broken outright (D = 1, brittle) across the cut: the criterion acted
        assert (sim.bundle("bonds").h.iface.D[across] == 1.0).sum() >= 3
        np.testing.assert_allclose(got["x"], x, rtol=0, atol=1e-12 * np.abs(x).max())
        np.testing.assert_array_equal(got["d"] >= 1.0, d >= 1.0)  # the same interfaces broken
        np.testing.assert_allclose(got["d"], d, rtol=0, atol=1e-12)
    else:
        np.testing.assert_array_equal(got["x"], x)
        np.testing.assert_array_equal(got["d"], d)
    same_rows(got["rows"], rows, tol=1e-10 if criterion == "facet" else 1e-8)


def test_particles_turned_at_the_start_are_the_reference():
    """Particles whose angles at t0 are not zero (body frames turned back by them): at rest no force, and an opening
    gives the same tractions as with angles zero."""
    ph = (0.4, -1.1)
    bp, bh = one_interface(phi0=ph)
    x = pos()
    x[:, 2] += ph
    F, _ = step(bp, bh, x, final=False)
    assert np.abs(F).max() < 1e-9
    x2 = pos(un=1e-4)
    x2[:, 2] += ph
    bp0, bh0 = one_interface()
    F1, _ = step(bp, bh, x2, final=False)
    F0, _ = step(bp0, bh0, pos(un=1e-4), final=False)
    np.testing.assert_allclose(F1, F0, rtol=1e-12, atol=1e-12 * np.abs(F0).max())


def test_the_compressive_cap_crushes_and_keeps_the_compaction():
    """Pushed together beyond the cap: the normal stress stays at -cap, the compaction beyond -cap/k_n is permanent
    (unloaded, the element opens only after it), and its work cap x compaction x area is dissipated."""
    cap = 3.0
    u0 = cap / KN
    path = list(np.linspace(0, -3 * u0, 301)) + list(np.linspace(-3 * u0, -1.5 * u0, 301)[1:])
    bp, bh = one_interface(cap=cap)
    sig, plast = [], 0.0
    for u in path:
        F, st = step(bp, bh, pos(u, 0.0))
        sig.append(F[0, 0] / (H * T))
        plast += st[BS_FRIC]
    sig = np.array(sig)
    assert sig.min() == pytest.approx(-cap, rel=1e-12)
    assert np.all(sig >= -cap * (1 + 1e-12))
    assert sig[300] == pytest.approx(-cap, rel=1e-12)  # at the deepest point, on the cap
    # unloaded elastically: the compaction 2 u0 is permanent, so at u = -1.5 u0 the element is open by 0.5 u0
    assert sig[-1] == pytest.approx(KN * 0.5 * u0, rel=1e-9)
    assert KN * 0.5 * u0 < FT  # (still intact: below f_t)
    assert plast == pytest.approx(cap * 2 * u0 * H * T, rel=1e-9)


@pytest.mark.skipif(not MPIEXEC.exists(), reason="the mpich wheel (test extra) is not installed")
def test_interfaces_re_cut_on_two_ranks_carry_their_element_history(tmp_path):
    """Drifting sideways across the cut with a ghost margin of 1 µm, a weak interface panel under biaxial load is
    re-cut while its elements are damaged and crushed: their history (D, kappa, slip, compaction) travels through
    globalize / merge / scatter, and the run stays the serial one to round-off (the proportional pressure's
    reaction is summed over the ranks in another order)."""
    from test_ranks import on_ranks, same_rows, serial

    path = str(ROOT / "scenarios/lab/smoke_biaxial.toml")
    over = ["output.history_every=50", "particles.0.velocity=[500.0, 0.0, 0.0]"]
    over += ['bonds.model="interface"', "bonds.nu=0.2", "bonds.f_t=2e5", "bonds.cohesion=4e5", "bonds.G_I=1e2"]
    over += ["bonds.G_II=4e2", "bonds.compressive_cap=2e6"]
    steps = 3000
    s, sim, rows = serial(path, over, steps)
    got = on_ranks(tmp_path, path, over + ["--skin=0.0001"], steps)
    assert got["redistributions"] >= 1
    h = sim.bundle("bonds").h
    assert (h.iface.D > 0).any() and (h.iface.cp < 0).any()  # damaged and crushed elements travelled
    np.testing.assert_allclose(got["d"], h.d, rtol=0, atol=1e-6)
    x = sim.nord[:, :, 0]
    np.testing.assert_allclose(got["x"], x, rtol=0, atol=1e-9 * np.abs(x).max())
    same_rows(got["rows"], rows, tol=1e-5)


def _chain(angle, principal=1):
    """Three unit squares in a row along the direction ``angle`` (centroids at 0, 1, 2 along it), bonded by two
    interfaces of three elements; returns (bp, bh, positions at rest (3, 3), the row's unit vector)."""
    u = np.array([math.cos(angle), math.sin(angle)])
    w = np.array([-u[1], u[0]])
    c = [k * u for k in range(3)]
    edges = np.array([[c[k] + 0.5 * u - 0.5 * w, c[k] + 0.5 * u + 0.5 * w] for k in range(2)])
    xa, xb = np.array(c[:2]), np.array(c[1:])
    ph = np.full((2, 2), angle)
    rI, rII, n0 = body_frame(*element_points(edges, xa, xb, 3), ph)
    EA, kb, eta, gfac = beam_constants([L] * 2, [H] * 2, [T] * 2, [E] * 2, [NU] * 2)
    two = lambda v: np.full(2, float(v))  # noqa: E731
    ip = IfaceParams(MODEL_INTERFACE, rI, rII, n0, ph, two(H * T / 3), two(KN), two(KS), two(FT), two(COH), two(MU),
                     two(MUR), two(GI), two(GII), two(0.25 * H), two(np.inf), principal, two(FT))  # fmt: skip
    bp = BondParams(np.array([0, 1]), np.array([1, 2]), two(L), two(H), two(T), EA, kb, eta, gfac, two(1), two(1),
                    two(1), two(0), two(1), two(0), 0, np.ones(2), ip)  # fmt: skip
    x = np.column_stack([np.array(c), np.full(3, angle)])
    return bp, new_history(2, 3), x, u


@pytest.mark.parametrize("angle", [0.0, math.radians(30.0)])
def test_the_middle_particle_of_a_pulled_chain_carries_the_interfaces_traction_as_its_stress(angle):
    """Love–Weber's stress of the middle square of a chain whose end squares are pulled apart by δ each: both its
    faces carry σ = k_n δ at the arm (L + δ)/2 from its centroid (the middle of the element's two material points),
    so its stress is σ (1 + δ/L) u ⊗ u (u along the chain) — σ_xx = σ cos², σ_yy = σ sin², σ_xy = σ sin cos — for a
    chain along e1 and one turned by 30° (the tensor's transformation)."""
    bp, bh, x, u = _chain(angle)
    d = 1e-5  # below the onset: σ = k_n δ = 0.1 < f_t
    x[0, :2] -= d * u
    x[2, :2] += d * u
    w = new_work(2, None, 3, np.ones(3))  # unit squares of unit thickness: 1/V = 1
    iface_pass(False, x, bp, bh, new_history_new(2, 3), w, np.zeros((3, 3)), np.zeros(N_BSTATS))
    sig = KN * d * (1.0 + d / L)
    np.testing.assert_allclose(w.sg[1], sig * np.array([u[0] ** 2, u[1] ** 2, u[0] * u[1]]), rtol=1e-9, atol=1e-12)
    # the end squares: one face loaded, σ/2 (their stress is the mean over the square, the far face free)
    np.testing.assert_allclose(w.sg[0], 0.5 * sig * np.array([u[0] ** 2, u[1] ** 2, u[0] * u[1]]), rtol=1e-9)


def test_a_moment_alone_enters_the_particles_stress_by_its_first_moment():
    """II turned by θ about the middle of the edge: the elements carry σ_e = −k_n s_e θ at s_e = −1/3, 0, 1/3 (no
    net force), and I's Love–Weber stress is their first moment, σ_xy = ½ Σ s_e A_e σ_e = −k_n θ/27 (A_e = 1/3,
    V = 1), σ_xx = σ_yy = 0 to first order in θ."""
    bp, bh = one_interface(principal=1)
    th = 1e-6
    w = new_work(1, None, 2, np.ones(2))
    iface_pass(False, pos(th=th), bp, bh, new_history_new(1, 3), w, np.zeros((2, 3)), np.zeros(N_BSTATS))
    np.testing.assert_allclose(w.sg[0], [0.0, 0.0, -KN * th / 27.0], atol=1e-6 * KN * th)


@pytest.mark.parametrize("s1, broken", [(2.0, True), (0.9, False)])
def test_the_principal_criterion_breaks_an_element_its_own_traction_leaves_intact(s1, broken):
    """An interface pressed (σ̄ < 0, inside the Mohr–Coulomb branch: no damage by its own traction) between two
    particles whose mean stress has the principal tension s1 f_t (as the provisional pass would leave it; σ_yy a
    compression of 5 f_t): with crack_criterion 'principal' its elements break (D = 1, κ = s1) once s1 > 1, and
    keep the normal compression (σ = k_n u_n: a crack across them does not soften compression); below 1, or with
    'facet', they stay intact."""
    for principal in (0, 1):
        bp, bh = one_interface(principal=principal)
        x = pos(un=-1e-5)
        w = new_work(1, None, 2, np.ones(2))
        w.sg[:] = [s1 * FT, -5.0 * FT, 0.0]
        bn = new_history_new(1, 3)
        F = np.zeros((2, 3))
        iface_pass(True, x, bp, bh, bn, w, F, np.zeros(N_BSTATS))
        hit = principal and broken
        np.testing.assert_array_equal(bn.iface.D[0], 1.0 if hit else 0.0)
        np.testing.assert_allclose(bn.iface.kap[0], s1 if hit else 0.0)
        np.testing.assert_allclose(F[0, 0], -KN * 1e-5 * H * T, rtol=1e-9)  # the compression, on I towards -x


def test_the_principal_criterion_with_one_evaluation_per_step_is_refused_naming_the_key():
    """verlet1 has no provisional evaluation, where the particles' stresses are summed: refused, file and key named."""
    from click.testing import CliRunner

    from polydem_cli.cli import main

    lab = str(ROOT / "scenarios/lab/smoke_interface_c30_37.toml")
    sets = ["--set", 'bonds.crack_criterion="principal"']
    r = CliRunner().invoke(main, ["check", lab, *sets, "--set", 'time.integrator="verlet1"'])
    assert r.exit_code == 2 and f"{lab}: bonds.crack_criterion = 'principal'" in r.output and "verlet1" in r.output
    assert CliRunner().invoke(main, ["check", lab, *sets]).exit_code == 0
    r = CliRunner().invoke(main, ["check", lab, "--set", "bonds.crack_strength=3e7"])  # without the criterion
    assert r.exit_code == 0 and 'bonds.crack_strength (bonds.crack_criterion is not "principal")' in r.output
