"""The pair parameters of polygon contact, mixed once per pair of parameter classes (thesis (4.4), (4.8), (4.15),
(4.17)), against the rules written out by hand."""

import numpy as np

from polydem_cli.interactions.contact.family import mixed_table


def test_each_pair_of_classes_gets_the_thesis_mixing_rules():
    # two materials (particles 0, 1 and 3 of A; 2 of B) and particle 4 of A with a perturbed k_n
    kn = np.array([1e6, 1e6, 3e6, 1e6, 0.5e6])
    gn = np.array([10.0, 10.0, 30.0, 10.0, 10.0])
    kt = np.array([2e5, 2e5, 6e5, 2e5, 2e5])
    mu = np.array([0.2, 0.2, 0.6, 0.2, 0.2])
    cls, mix = mixed_table(kn, gn, kt, mu)
    assert mix.shape == (3, 3, 4)
    assert cls[0] == cls[1] == cls[3] and len({cls[0], cls[2], cls[4]}) == 3
    AB = mix[cls[0], cls[2]]
    assert AB[0] == 2 * 1e6 * 3e6 / 4e6  # (4.4): 1.5e6
    assert AB[1] == 20.0  # (4.8): arithmetic mean
    assert AB[2] == 2 * 2e5 * 6e5 / 8e5  # (4.15): 3e5
    assert np.isclose(AB[3], 0.3)  # (4.17): 2 0.2 0.6 / 0.8
    assert np.array_equal(mix[cls[2], cls[0]], AB)  # symmetric
    AA = mix[cls[0], cls[0]]
    assert np.allclose(AA, (1e6, 10.0, 2e5, 0.2), rtol=1e-15, atol=0)  # a material with itself keeps its values
    assert mix[cls[0], cls[4], 0] == 2 * 1e6 * 0.5e6 / 1.5e6  # the perturbed particle mixes as its own class


def test_no_tangential_stiffness_mixes_to_zero_not_nan():
    cls, mix = mixed_table(np.ones(2), np.zeros(2), np.zeros(2), np.zeros(2))
    assert np.all(np.isfinite(mix)) and mix[0, 0, 2] == 0.0 and mix[0, 0, 3] == 0.0


def test_a_perturb_entry_is_checked_and_reported_unused_in_a_scene_without_contact():
    import pytest

    from polydem_cli.errors import ScenarioError
    from polydem_cli.scenario.build import build_system
    from polydem_cli.scenario.load import load_scenario

    from conftest import SCEN

    sc, _ = load_scenario(SCEN / "ch5" / "tension.toml", ["particles.0.nx=4", "particles.0.ny=4"])
    assert sc["contact"] is None
    bad = dict(sc, perturb=[{"set": "no_such_set", "at": None, "k_n_factor": 0.5}])
    with pytest.raises(ScenarioError, match="no_such_set"):
        build_system(bad, "x")
    good = dict(sc, perturb=[{"set": "specimen", "at": None, "k_n_factor": 0.5}])
    assert "perturb[0] (no [contact])" in build_system(good, "x").unused
