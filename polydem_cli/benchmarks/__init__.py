"""Developer benchmarks, apart from the product: ``polydem bench`` (the issue scenes, particle-steps per
second per thread setting), the comparison with LAMMPS (:mod:`.peers`, ``make bench-peers``) and the
particle-ordering measurement (:mod:`.ordering`)."""
