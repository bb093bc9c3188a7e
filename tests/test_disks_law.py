"""The Luding-Herrmann contact law (LH 1.6)-(1.8) on prescribed overlap paths and in a binary collision."""

import numpy as np
import pytest

from polydem_cli.interactions.disks.law import contact_duration, lh_energy, lh_hysteretic

K2 = 1.0e5
K1 = K2 / 2
KC = 2 * K2  # strong cohesion: the attraction branch is reached well before delta = 0


def _follow(path, k1=K1, k2=K2, kc=KC):
    """Forces along a path of overlaps, the history carried from state to state."""
    dmax = 0.0
    f = np.zeros(len(path))
    hist = np.zeros(len(path))
    for i, d in enumerate(path):
        f[i], dmax = lh_hysteretic(d, dmax, k1, k2, kc)
        hist[i] = dmax
    return f, hist


def _slope(path, f, lo, hi):
    sel = (path >= lo) & (path <= hi)
    return np.polyfit(path[sel], f[sel], 1)[0]


def test_loading_unloading_reloading_and_attraction_follow_the_three_lines():
    dmax = 1.0e-5
    n = 2001
    load = np.linspace(1e-9, dmax, n)
    unload = np.linspace(dmax, 1e-9, n)
    f_l, _ = _follow(load)
    f_u, h_u = _follow(np.concatenate([load, unload]))
    f_u = f_u[n:]
    assert np.all(h_u[n:] == pytest.approx(dmax))  # the history is the largest overlap
    # loading: slope k1 through the origin
    assert np.allclose(f_l, K1 * load, rtol=1e-12)
    # unloading: slope k2, zero force at delta_0 = (1 - k1/k2) delta_max
    d0 = (1 - K1 / K2) * dmax
    dmin = (K2 - K1) / (K2 + KC) * dmax
    assert _slope(unload, f_u, dmin * 1.05, dmax) == pytest.approx(K2, rel=1e-9)
    k0 = np.argmin(np.abs(f_u[: np.argmin(f_u)]))
    assert unload[k0] == pytest.approx(d0, abs=2 * dmax / n)
    # attraction: the largest at delta_min, force -k_c delta_min, then along -k_c delta to zero at contact loss
    k = int(np.argmin(f_u))
    assert unload[k] == pytest.approx(dmin, abs=2 * dmax / n)
    assert f_u[k] == pytest.approx(-KC * dmin, rel=2e-3)
    assert _slope(unload, f_u, 0.0, dmin * 0.95) == pytest.approx(-KC, rel=1e-9)
    assert abs(f_u[-1]) < 1e-3 * abs(f_u[k])
    # reloading from the attraction branch: back along -k_c, then the k2 line, then k1 beyond delta_max
    re = np.linspace(1e-9, 2 * dmax, 2 * n)
    f_all, h_all = _follow(np.concatenate([load, unload, re]))
    f_r, h_r = f_all[2 * n :], h_all[2 * n :]
    assert _slope(re, f_r, 0.0, dmin * 0.95) == pytest.approx(-KC, rel=1e-9)
    assert _slope(re, f_r, dmin * 1.05, dmax * 0.99) == pytest.approx(K2, rel=1e-9)
    assert _slope(re, f_r, dmax * 1.01, 2 * dmax) == pytest.approx(K1, rel=1e-9)
    assert h_r[-1] == pytest.approx(2 * dmax)


def _loop_work(path, **kw):
    f, _ = _follow(path, **kw)
    return np.sum(0.5 * (f[1:] + f[:-1]) * np.diff(path))  # work done on the contact around the path


def test_a_closed_cycle_dissipates_the_enclosed_area_and_small_cycles_nothing():
    dmax = 1.0e-5
    n = 20001
    path = np.concatenate([np.linspace(0, dmax, n), np.linspace(dmax, 0, n)])
    w = _loop_work(path)
    dmin = (K2 - K1) / (K2 + KC) * dmax
    # the loop is the triangle (0, 0), (delta_max, k1 delta_max), (delta_min, -kc delta_min): shoelace area
    xs = np.array([0.0, dmax, dmin])
    ys = np.array([0.0, K1 * dmax, -KC * dmin])
    area = 0.5 * abs(np.dot(xs, np.roll(ys, -1)) - np.dot(ys, np.roll(xs, -1)))
    assert w == pytest.approx(area, rel=1e-6)
    # the same from the stored energy: work in along k1 minus what the contact returns
    assert w == pytest.approx(0.5 * K1 * dmax**2 - lh_energy(dmax, dmax, K1, K2, KC), rel=1e-6)
    # an un/reloading cycle between the limit lines is reversible (after a first loading to delta_max)
    inner = np.concatenate(
        [np.linspace(0, dmax, n), np.linspace(dmax, 0.4 * dmax, n), np.linspace(0.4 * dmax, dmax, n)]
    )
    w_inner = _loop_work(inner) - _loop_work(np.linspace(0, dmax, n))
    assert abs(w_inner) < 1e-6 * area


@pytest.mark.parametrize("kc", [0.0, 0.5 * K2, 4 * K2])
def test_stored_energy_is_the_potential_of_the_reversible_branches(kc):
    dmax = 1.0e-5
    h = 1e-10
    dmin = (K2 - K1) / (K2 + kc) * dmax
    for d in np.linspace(0.02, 0.98, 25) * dmax:
        if abs(d - dmin) < 10 * h:
            continue  # the kink between the -k_c and k_2 lines
        f, _ = lh_hysteretic(d, dmax, K1, K2, kc)
        dE = (lh_energy(d + h, dmax, K1, K2, kc) - lh_energy(d - h, dmax, K1, K2, kc)) / (2 * h)
        assert dE == pytest.approx(f, rel=1e-5, abs=1e-9 * K2 * dmax)
    assert lh_energy(0.0, dmax, K1, K2, kc) == 0.0


@pytest.mark.parametrize("gamma0,paper", [(0.0, 2.03e-5), (0.1, 2.04e-5), (0.5, 2.21e-5)])
def test_binary_collision_lasts_the_half_period_of_lh_1_8(gamma0, paper):
    """k1 = k2, kc = 0: two disks of reduced mass m12 = 0.42e-5 kg meet at 0.1 m/s; the overlap obeys
    m12 d''  = -(f_hys + gamma0 d'), integrated here with a small step (velocity Verlet on the relative
    coordinate); the contact lasts from delta = 0 to delta = 0 again."""
    m12 = 0.42e-5
    tc = contact_duration(K2, m12, gamma0)
    assert tc == pytest.approx(paper, rel=0.01)  # the paper's figures (its m12 is rounded, LH §1.4)
    dt = tc / 20000
    d, v, t, dmax = 0.0, 0.1, 0.0, 0.0
    f, dmax = lh_hysteretic(1e-30, dmax, K2, K2, 0.0)
    a = -(f + gamma0 * v) / m12
    while True:
        v_half = v + 0.5 * dt * a
        d_new = d + dt * v_half
        if d_new <= 0.0 and t > 0:
            t += dt * d / (d - d_new)  # the crossing inside the step
            break
        d = d_new
        t += dt
        f, dmax = lh_hysteretic(d, dmax, K2, K2, 0.0)
        a = -(f + gamma0 * v_half) / m12
        v = v_half + 0.5 * dt * a
    assert t == pytest.approx(tc, rel=1e-3)
