"""The edge-interface model's data layout (interface.py has the law): its static data and per-element history, in
a module of their own so that beam.py (whose BondParams and BondHist carry them, empty for beams) and interface.py
(which imports the beams' statistics and damage form) do not import each other."""

from __future__ import annotations

from collections import namedtuple

import numpy as np

MODEL_BEAM, MODEL_INTERFACE = 0, 1

#: the interface's static data (the beams' BondParams.iface): ``model`` (scene-wide: 0 beams, 1 interfaces),
#: per bond ``rI``/``rII`` (nb, n_e, 2): the element points relative to the centroids of I and II in each particle's
#: body frame (turned back by its angle at t0: the point now is R(φ) r with the particle's angle φ), ``n0``
#: (nb, 2, 2) the edge normal from I to II in I's and in II's body frame, ``phi0`` (nb, 2) the two particles'
#: angles at t0, ``Ae`` element
#: area, ``kn``, ``ks``, ``ft``, ``coh``, ``mu`` (μ of the Mohr-Coulomb branch), ``mur`` (friction of broken
#: faces), ``GI``, ``GII``, ``slip_max`` (a quarter of the edge), ``cap`` the compressive cap of the normal stress (inf:
#: none); ``principal`` (scene-wide: 1 when an element also breaks where the largest principal stress of its two
#: particles' mean stress exceeds ``fp``, ``[bonds] crack_criterion = "principal"``; 0 its own traction alone),
#: ``fp`` (nb,) that crack strength (``[bonds] crack_strength``, default f_t)
IfaceParams = namedtuple(
    "IfaceParams",
    [
        "model",
        "rI",
        "rII",
        "n0",
        "phi0",
        "Ae",
        "kn",
        "ks",
        "ft",
        "coh",
        "mu",
        "mur",
        "GI",
        "GII",
        "slip_max",
        "cap",
        "principal",
        "fp",
    ],
)
#: per element (nb, n_e): damage D, history κ = max r, frictional slip s_p of the broken part, released energy
#: density Y at the last step (for the trapezoidal dissipation), permanent normal compaction cp (≤ 0) of the cap;
#: the committed ones and a final pass's new ones
IfaceHist = namedtuple("IfaceHist", ["D", "kap", "sp", "Y", "cp"])


def empty_iface(nb: int = 0, ne: int = 0, model: int = MODEL_BEAM) -> IfaceParams:
    """Interface data of ``nb`` bonds of ``ne`` elements, all zero (``nb = ne = 0``: the beams' empty one)."""
    z1 = np.zeros(nb)
    return IfaceParams(
        model,
        np.zeros((nb, ne, 2)),
        np.zeros((nb, ne, 2)),
        np.zeros((nb, 2, 2)),
        np.zeros((nb, 2)),
        z1,
        z1.copy(),
        z1.copy(),
        z1.copy(),
        z1.copy(),
        z1.copy(),
        z1.copy(),
        z1.copy(),
        z1.copy(),
        z1.copy(),
        z1.copy(),
        0,
        z1.copy(),
    )


def new_iface_hist(nb: int, ne: int) -> IfaceHist:
    """The elements' history of ``nb`` intact interfaces of ``ne`` elements ((0, 0) arrays for beams)."""
    return IfaceHist(*(np.zeros((nb, ne)) for _ in IfaceHist._fields))
