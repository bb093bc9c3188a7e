"""Adaptive discrete–continuum coupling (Sorg 2014): the lattice, the adaptive mesh and the quasi-static
analyses that the quasi-static solver family (polydem_cli/solvers/quasistatic.py) runs.

Modules, lowest first (each imports only those before it):

* :mod:`.elements`, :mod:`.lattice`, :mod:`.members` — the element levels (level 1: the homogenised continuum,
  λ = μ = √3k/4; level 2: Cauchy–Born stiffness from the covered members), the triangular lattice of bars
  (sparse stiffness, displacement-controlled solves), linear softening and its saw-tooth form;
* :mod:`.mesh` — super-triangles along lattice directions, split into four, hanging nodes;
* :mod:`.meshkern` — the same as compiled array code: the lattice's bookkeeping built once, per mesh the
  neighbours, levels, hanging nodes, refinement with 2:1 balance and the element matrices (Numba);
* :mod:`.problem` — the plate problem (lattice, members, aggregates, supports, displacement pattern);
* :mod:`.adaptive` — levels 1–3 assembled through the hanging-node constraints (a heterogeneous level-2
  element by the eigenmodes of its level-1 counterpart), the strain-jump indicator, refinement with 2:1
  balance;
* :mod:`.stepper` — one solve at a time of the four analyses (elastic / softening, fully resolved / adaptive);
* :mod:`.scenario`, :mod:`.examples` — the quasi-static scenario tables, the four examples of the source.
"""
