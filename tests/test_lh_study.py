"""The Luding & Herrmann analysis (polydem_cli/reproductions/lh.py) against the paper's own numbers and curves
of known slopes (independent of any run)."""

import math

import numpy as np
import pytest

from polydem_cli.reproductions.lh import PAPER, analyse, mohr_coulomb


def test_common_tangent_of_the_papers_peaks_gives_its_cohesion():
    """Table 1.1's corrected peaks (p = 100 and 500) through the common-tangent construction: the cohesion
    c = 11.8, 31.9, 39.7, 60.6, 70.2 N/m^2 and sin(phi) between 0.21 and 0.24 (Table 1.1 and Fig. 1.8, checked by hand;
    the paper prints 11, 32, 40, 60, 71)."""
    expect = [11.8, 31.9, 39.7, 60.6, 70.2]
    for s1, s2, c_ref in zip(PAPER["peak_100"], PAPER["peak_500"], expect, strict=True):
        phi, c = mohr_coulomb(100.0, s1, 500.0, s2)
        assert c == pytest.approx(c_ref, abs=0.1)
        assert 0.21 <= math.sin(math.radians(phi)) <= 0.24


def test_analysis_recovers_slopes_peak_and_dilatancy_of_a_known_curve():
    """A synthetic run: eps_V = -0.3 eps_zz up to 1 %, then +0.19 per unit strain; sigma_xx = p; a
    corrected stress with its maximum 900 at eps_zz = 0.02.  nu = 1 - 0.3, late slope 0.19, and
    psi from d' = 2 sin(psi)/(1 - sin(psi))."""
    ezz = np.linspace(0.0, 0.035, 701)
    ev = np.where(ezz <= 0.01, -0.3 * ezz, -0.003 + 0.19 * (ezz - 0.01))
    p = 500.0
    szz = 900.0 - 1e6 * (ezz - 0.02) ** 2
    m = {"ezz": ezz, "ev": ev, "sxx": np.full_like(ezz, p), "szz": szz, "z0": 12.0, "x0": 6.5}
    a = analyse(m, p)
    assert a["nu"] == pytest.approx(0.7, abs=1e-9)
    assert a["late_slope"] == pytest.approx(0.19, abs=1e-9)
    sin_psi = 0.19 / (2.0 + 0.19)
    assert a["psi_deg"] == pytest.approx(math.degrees(math.asin(sin_psi)), abs=1e-6)
    assert a["peak_corrected"] == pytest.approx(900.0, abs=1e-6)
    assert a["eps_at_peak"] == pytest.approx(0.02, abs=1e-4)


def test_relaxation_time_of_an_exponential_approach():
    """p(t) = 400 - 300 exp(-t/tau) with tau = 2.3 ms (the paper's Fig. 1.4b): the fit gives tau back."""
    from polydem_cli.reproductions.lh import _tau

    t = np.linspace(0.0, 0.04, 2001)
    assert _tau(t, 400.0 - 300.0 * np.exp(-t / 0.0023)) == pytest.approx(0.0023, rel=1e-6)


def test_a_peak_on_the_last_loading_point_is_flagged_as_a_lower_bound():
    ezz = np.linspace(0.0, 0.035, 701)
    m = {"ezz": ezz, "ev": -0.3 * ezz, "sxx": np.full_like(ezz, 100.0), "z0": 12.0, "x0": 6.5}
    rising = analyse(m | {"szz": 100.0 + 5e3 * ezz}, 100.0)  # still rising where the loading stops
    assert rising["peak_is_lower_bound"] and rising["eps_at_peak"] == ezz[-1]
    turned = analyse(m | {"szz": 900.0 - 1e6 * (ezz - 0.02) ** 2}, 100.0)
    assert not turned["peak_is_lower_bound"]
