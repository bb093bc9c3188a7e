"""Adaptive discrete–continuum coupling (Sorg 2014; issue 14): a quasi-static solver family.

So far the fine scale and the element levels: :mod:`.lattice` (the triangular lattice of bars, its sparse
stiffness and displacement-controlled solves), :mod:`.elements` (level 1: the homogenised continuum, λ = μ =
√3k/4; level 2: Cauchy–Born stiffness from the covered members), :mod:`.members` (linear softening and its
saw-tooth form), :mod:`.sla` (sequentially linear analysis through softening), :mod:`.mesh` (super-triangles
along lattice directions, split into four, hanging nodes) and :mod:`.adaptive` (levels 1–3 assembled through
the hanging-node constraints, the strain-jump indicator, refinement with 2:1 balance; linear elastic members).
Still to come: softening members in the adaptive loop, the eigenmode construction for heterogeneous level-2
elements, level-2 sub-problems in parallel, the four examples, and the solver's place in the run driver
(``[solver] kind``).
"""
