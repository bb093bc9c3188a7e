"""Adaptive discrete–continuum coupling (Sorg 2014; issue 14): a quasi-static solver family.

So far the fine scale and the element levels: :mod:`.lattice` (the triangular lattice of bars, its sparse
stiffness and displacement-controlled solves), :mod:`.elements` (level 1: the homogenised continuum, λ = μ =
√3k/4; level 2: Cauchy–Born stiffness from the covered members), :mod:`.members` (linear softening and its
saw-tooth form) and :mod:`.sla` (sequentially linear analysis through softening).  Adaptive refinement, the
eigenmode construction for heterogeneous level-2 elements and the solver's place in the run driver follow.
"""
