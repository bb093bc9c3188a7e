"""Product workflows over many runs, each through the one run driver (solvers/driver.py) and so for every
solver family: ``polydem calibrate`` (beam parameters from macroscopic targets), ``polydem sweep`` (variants on
Dask), the time-step study (speed against error per integrator) and the dynamic increase factor over strain
rates."""
