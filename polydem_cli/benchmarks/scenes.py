"""The benchmark scenes of ``make bench`` by name (benchmarks/bench.py times them with threads, benchmarks/ranks.py on
MPI ranks): scenario file, overrides, steps timed."""

from __future__ import annotations

HEX = "scenarios/bench_dense_hexagons.toml"
#: base friction of the thesis's nuts (ch. 6) switched on for the hexagon scene
BASE = ["base.gravity=981.0", "materials.steel.k_u=8.35e5", "materials.steel.mu_u=0.258"]
#: the edge-interface material of scenarios/lab/smoke_interface_tension.toml on a beam scene
INTERFACE = [
    'bonds.model="interface"',
    "bonds.E=4.0e11",
    "bonds.nu=0.2",
    "bonds.f_t=3.0e7",
    "bonds.cohesion=6.0e7",
    "bonds.G_I=1.0e5",
    "bonds.G_II=4.0e5",
]
SCENES = {
    "bonded_30x30": ("scenarios/ch5/tension.toml", [], 3000),
    "bonded_300x300": ("scenarios/ch5/tension.toml", ["particles.0.nx=300", "particles.0.ny=300"], 100),
    "hex_base_friction": (HEX, BASE + ["base.gauss_points=7"], 500),
    "hex_base_friction_3gp": (HEX, BASE + ["base.gauss_points=3"], 500),
    "concrete_40x40": ("scenarios/bench_concrete_40.toml", [], 1000),
    # the same panel with edge-interface bonds (3 elements per edge) instead of beams: the interface law's cost
    "concrete_40x40_interface": ("scenarios/bench_concrete_40.toml", INTERFACE, 1000),
    # and with its principal-stress crack criterion (the particles' stresses summed every step; a crack strength
    # below f_t, so that the criterion's branch runs, not just its sum)
    "concrete_40x40_principal": (
        "scenarios/bench_concrete_40.toml",
        INTERFACE + ['bonds.crack_criterion="principal"', "bonds.crack_strength=2.5e7"],
        1000,
    ),
    "dense_N1e3": (HEX, ["particles.0.rows=32", "particles.0.row_counts=[32, 32]"], 1000),
    "dense_N1e4": (HEX, ["particles.0.rows=100", "particles.0.row_counts=[100, 100]"], 200),
    "dense_N1e5": (HEX, ["particles.0.rows=316", "particles.0.row_counts=[316, 316]"], 20),
    "lh_biaxial_1950": ("scenarios/lh/prepare_p100.toml", [], 2000),
    "lh_loading_1950": ("scenarios/lh/load_p100_kc1.toml", [], 4000),
}
#: scenes that start from the result of another run: skipped (with the command that makes it) when it is absent
NEEDS = {"lh_loading_1950": "outputs/lh/prepare_p100.h5"}
