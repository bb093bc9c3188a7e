"""The pressure that follows another face's stress ([[proportional_pressure]], interactions/controllers/proportional.py):
on the 8 x 8 cm biaxial panel in its elastic range, the followed stress is the driven face's (up to the filter's
lag), the lateral stress (the pressure) and its ratio to the axial one as asked, the pressure's resultant on a side is p T L2 (the side's height, from the specimen), its work closes
the energy balance; bad entries are refused with their key."""

import numpy as np
import pytest

from polydem_cli.scenario.build import build_system
from polydem_cli.scenario.load import load_scenario
from polydem_cli.scenario.spec import ScenarioError

from conftest import SCEN
from helpers import run

PANEL = SCEN / "lab" / "smoke_biaxial.toml"


@pytest.mark.parametrize("alpha", [0.5, -0.1])
def test_the_lateral_stress_follows_the_axial_one(alpha):
    sets = [f"proportional_pressure.{k}.ratio={alpha}" for k in (0, 1)] + ["time.end_time=1.2e-2"]
    sc, _ = load_scenario(PANEL, sets)
    s = build_system(sc, str(PANEL))
    sim, h = run(s, every=200)
    g = sc["particles"][0]
    L1, L2, T = g["nx"] * g["h_pg"], g["ny"] * g["h_pg"], g["thickness"]
    tau = sc["proportional_pressure"][0]["filter_time"]
    late = h["time"] > 20 * tau  # past the filter's start-up
    s1, p = h["sigma22"], h["pp0_p:specimen.left"]
    assert np.abs(s1[late]).max() > 5e7  # 5 MPa: loaded, still elastic
    assert np.all(h["bonds_failed"] == 0)
    # the followed stress is the top row's reaction over its area, the [macro] axial stress (the same face), through
    # the filter: it lags a stress rising at ds/dt by tau ds/dt
    rate = np.gradient(s1, h["time"])
    sig = h["pp0_sigma_ref:specimen.left"]
    assert np.allclose(sig[late], s1[late] - tau * rate[late], rtol=0.01, atol=0.002 * abs(s1).max())
    # the lateral stress: -alpha times the axial one, lagging as the followed stress does
    assert np.allclose(p[late], -alpha * (s1[late] - tau * rate[late]), rtol=0.01, atol=0.002 * abs(s1).max())
    # its resultant on each side: p T L2 inwards (the sides' exposed edges span the specimen's height)
    assert np.allclose(h["pp0_f1:specimen.left"][late], p[late] * T * L2, rtol=1e-9)
    assert np.allclose(h["pp1_f1:specimen.right"][late], -p[late] * T * L2, rtol=1e-9)
    assert abs(L1 - L2) < 1e-12
    # its work is external work: the energy balance holds to the integrator's error
    scale = np.abs(h["external_work"]).max()
    assert abs(h["pp0_work:specimen.left"][-1]) > 0.01 * scale
    assert np.abs(h["energy_total"] - h["energy_total"][0]).max() < 0.02 * scale


@pytest.mark.parametrize(
    "sets, key, reason",
    [
        (["proportional_pressure.0.ratio=1.5"], "proportional_pressure[0].ratio", "<= 1"),
        (["proportional_pressure.0.ratio=-1.01"], "proportional_pressure[0].ratio", ">= -1"),
        (['proportional_pressure.0.reference="specimen"'], "proportional_pressure[0].reference_normal", "normal"),
        (["proportional_pressure.0.normal=[1.0, 0.0]"], "proportional_pressure[0].set", "no exposed edge"),
        (["proportional_pressure.0.filter_time=-1e-4"], "proportional_pressure[0].filter_time", ">= 0"),
    ],
)
def test_bad_entries_are_refused_with_their_key(sets, key, reason):
    with pytest.raises(ScenarioError) as e:
        sc, _ = load_scenario(PANEL, sets)
        build_system(sc, str(PANEL))
    assert key in str(e.value) and reason in str(e.value), str(e.value)
