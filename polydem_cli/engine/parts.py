"""A rank's part of a decomposed scene (engine/distributed.py, engine/migrate.py): the scene cut to the particles a
rank holds (:func:`localize`), the particles every rank holds (:func:`large_particles`), the part itself
(:class:`Part`: its particles, scene, exchange lists, set members, geometry) and the families' declared layouts
(:func:`data_layout`, :func:`layout`) — what the first cut on rank 0 and a re-cut between neighbours share."""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from .. import mpicall
from ..boundary.prescribed import FIXED
from ..errors import DecompositionError
from ..interactions import ranks
from .families import used_families
from .halo import Halo

#: per-particle fields of System cut to a rank's part
_PER_PARTICLE = (
    "group",
    "radius",
    "area",
    "mass",
    "inertia",
    "thickness",
    "x0",
    "v0",
    "bc_kind",
    "bc_vel",
    "bc_acc",
    "ext",
)


def runs(first, counts) -> tuple:
    """Runs of rows taken one after another (a particle's vertices, CSR): the run k starts at row ``first[k]`` and
    has ``counts[k]`` rows.  (start, rows): the offsets of the runs in the result, and the rows in order — one index
    array, no loop over the runs."""
    counts = np.asarray(counts)
    start = np.concatenate([[0], np.cumsum(counts)]).astype(counts.dtype)
    return start, np.repeat(np.asarray(first) - start[:-1], counts) + np.arange(start[-1])


def localize(system, keep: np.ndarray, own: np.ndarray):
    """The part of ``system`` on one rank: the particles ``keep`` (sorted global indices) renumbered 0…, of which
    ``own`` (bool per kept particle) are the rank's; ghosts fixed and unloaded; sets cut to the owned members (their
    sizes over all ranks kept for the set means); each family's data cut as its ``data_layout`` declares
    (interactions/ranks.py ``localize``)."""
    keep = np.asarray(keep, np.int64)
    own = np.asarray(own, bool)
    fields = {k: np.array(getattr(system, k))[keep].copy() for k in _PER_PARTICLE}
    ghost = ~own
    if system.ext_ramp is not None:
        fields["ext_ramp"] = np.array(system.ext_ramp)[keep].copy()
        fields["ext_ramp"][ghost] = 0.0
    fields["bc_kind"][ghost] = FIXED
    fields["bc_vel"][ghost] = 0.0
    fields["bc_acc"][ghost] = 0.0
    fields["ext"][ghost] = 0.0
    vs = system.vert_start
    # the kept particles' vertices, in order: each one's run of body_v
    vert_start, rows = runs(vs[keep], np.diff(vs)[keep])  # offsets in vert_start's dtype
    body_v = system.body_v[rows]
    loc = np.full(system.n, -1, np.int64)
    loc[keep] = np.arange(len(keep))
    owned_global = np.zeros(system.n, bool)
    owned_global[keep[own]] = True
    sets = {name: loc[idx[owned_global[idx]]] for name, idx in system.sets.items()}
    # each set's size over all ranks (a scene joined from pieces at a re-cut, engine/migrate.py, carries them)
    set_counts = {name: len(idx) for name, idx in system.sets.items()} if system.gid is None else system.set_counts
    data = dict(system.family_data)
    for f in used_families(system):  # an unused family's data only says it is unused
        d = data.get(f.name)
        data[f.name] = None if d is None else ranks.localize(data_layout(f, d), d, keep, own)
    return replace(
        system,
        n=len(keep),
        vert_start=vert_start,
        body_v=body_v,
        sets=sets,
        set_counts=set_counts,
        family_data=data,
        own=own.astype(float),
        gid=keep.copy() if system.gid is None else system.gid[keep],
        specimens={},  # the whole scene's specimens (their shared edges) and macroscopic measures: rank 0's business
        macro=None,
        **fields,
    )


def large_particles(system) -> np.ndarray:
    """(n,) bool: the particles on every rank — large ones (plates, walls: bounding radius above four times the
    median, interactions/search.py) and those a family needs everywhere (``Family.replicated``)."""
    from ..interactions.search import large_particle_mask

    large = large_particle_mask(np.asarray(system.radius, float)).copy()
    for f in used_families(system):
        large[np.asarray(f.replicated(system), np.int64)] = True
    return large


def _bond_pairs(system):
    from ..interactions.bonds.family import BEAM_BONDS

    net = BEAM_BONDS.data(system)
    if net is None or net.n == 0:
        return None
    return np.column_stack([net.params.a, net.params.b])


class Part:
    """One rank's part of a decomposed scene — all a rank holds of it, no array of the whole scene: the global
    numbers of the particles it holds (``keep``, sorted) and which of them it owns (``own``), its scene
    (:func:`localize`), its halo's exchange lists, the set members it holds (``held_sets``, global numbers), the
    whole scene's particle count, which held particles are on every rank (``large``) and the decomposition's
    geometry (``geom``: the reach, the largest ordinary bounding radius, the ghost margin, the method) — what a re-cut
    by neighbour exchange needs (engine/migrate.py).  ``cut``: the :class:`Cut` it came from, on the rank that cut
    it (None once sent or re-cut)."""

    def __init__(self, rank, nranks, keep, own, system, lists, held_sets, n_whole, geom, large=None):
        self.rank, self.nranks = rank, nranks
        self.keep, self.own, self.system = keep, own, system
        self.lists, self.held_sets = lists, held_sets
        self.n_whole = n_whole  # the whole scene's particle count (rank 0 gathers into arrays of it)
        self.geom = geom
        self.large = np.zeros(len(keep), bool) if large is None else large
        self.cut = None

    def __getstate__(self):  # sent to its rank without the whole scene's decomposition
        return dict(self.__dict__, cut=None)

    def halo(self, mpi, fwd=None) -> Halo:
        """This rank's halo exchange (engine/halo.py) on its exchange lists; ``fwd``: a family's per-particle
        field (n, k) sent to the ghosts with the positions (Family.ghost_field), or None."""
        L = self.lists
        mpi = mpicall.grow(mpi, 2 * len(L["nbr"]))  # a request per neighbour and direction (walls: every rank)
        fwd = np.zeros((self.system.n, 0)) if fwd is None else fwd
        if fwd.ndim != 2 or fwd.shape[0] != self.system.n or fwd.dtype != np.float64 or not fwd.flags.c_contiguous:
            raise ValueError(
                f"a ghost field must be a C-contiguous float64 array (n = {self.system.n}, k), not "
                f"{fwd.dtype} {fwd.shape}"
            )  # (the compiled exchange indexes it unchecked)
        w = 6 + fwd.shape[1]
        return Halo(
            mpi,
            L["nbr"],
            L["send_start"],
            L["send_idx"],
            L["recv_start"],
            L["recv_idx"],
            np.zeros(w * max(1, len(L["send_idx"]))),
            np.zeros(w * max(1, len(L["recv_idx"]))),
            np.zeros(1),
            L["mine"],
            L["xref"].copy(),
            L["rad"],
            L["lim"],
            L["boxes"],
            L["wstart"],
            L["wrank"],
            np.zeros(1),
            np.zeros(1),
            np.zeros(0, np.int64),
            np.zeros(0, np.int64),
            np.zeros(1),
            fwd,
        )


def data_layout(family, data):
    """The family's declared cut of its scene data ``data`` to a rank's part (Family.data_layout); a family without
    one refuses, and so does one whose data it cannot cut (the layout raises)."""
    lay = family.data_layout(data)
    if lay is None:
        raise DecompositionError(
            f"interaction family '{family.name}' does not run on several ranks yet (use --ranks 1)"
        )
    return lay


def layout(family, system):
    """The family's declared checkpoint layout over the ranks (Family.state_layout); a family without one refuses."""
    lay = family.state_layout(system)
    if lay is None:
        raise DecompositionError(
            f"interaction family '{family.name}' does not run on several ranks yet (use --ranks 1)"
        )
    return lay
