"""The re-cut of a decomposed run by neighbour exchange (issue 54 item 2): when a particle has moved half the ghost
margin since its part was cut (engine/halo.py), every rank cuts the scene again where the particles are now, and
the particles move to the ranks that hold them after the cut — each sent by the rank that owned it, with its whole
state, to those ranks only.  Nothing of the whole scene is gathered anywhere; rank 0 is a rank like the others.

1. **The new boxes** by recursive coordinate bisection of the ordinary particles' present centroids, computed where
   they are (engine/decompose.py ``bisect_ranks``: the medians found by counting, reductions of a few numbers per
   box) — the same owners and boxes the serial bisection of the whole scene gives.  A large particle (a wall, on
   every rank) goes to the rank whose box holds its centroid, as at the first cut.
2. **Who holds what**: the owner of each particle works out the ranks that will hold it — its new owner, the ranks
   whose box lies within its bounding radius plus the halo width (engine/decompose.py ``ghosts``), every rank for a
   large particle, and the new owner of each of its bond partners (whose new owners come from their owners over
   the present halo, one neighbour exchange).
3. **The pieces**: each rank sends each of those ranks one message — the particles it owned that the rank will
   hold (their static data, vertices, set memberships, integrator history, the ranks that will hold them), each
   family's data of them (interactions/ranks.py ``pack``, from ``Family.data_layout``: the bonds it counts with
   their histories, the contacts it counts, the groups and load entries of the particles) and the family states
   (``Family.state_layout``).  How many messages a rank receives comes from one reduction over the ranks
   (``Reduce_scatter_block``); then the messages go point to point, each piece dropped once sent.
4. **The new part**: each rank joins its pieces into the scene of the particles it holds (interactions/ranks.py
   ``join``), cuts it as the first cut cuts the whole scene (engine/parts.py ``localize``), makes its halo's
   exchange lists from the holders the pieces carry, and its share of the family states — the accumulators (a few
   numbers per family) allgathered and combined as a checkpoint combines them.  An error on any rank after the
   pieces are sent stops every rank alike.

The part and its state equal what rank 0's cut of the gathered whole scene gives (tests/test_ranks_many.py compares
them array by array, through tests/ranks_run.py ``--compare-recut``), so a run re-cut this way stays bit-identical
to a serial one.
"""

from __future__ import annotations

import functools
from dataclasses import replace

import numpy as np

from ..errors import DecompositionError
from ..interactions import ranks
from ..interactions.ranks import Entries, Pairs, Rebuilt, Rows, Same, Summed
from .decompose import _thickness, bisect_ranks, box_distance, box_gap
from .families import used_families
from .simulation import EngineError

_OWNER_TAG = 41
_PIECE_TAG = 43


def reducer(comm):
    """``reduce(array, op)``: the array's elementwise sum, minimum or maximum over the ranks (an allreduce)."""
    from mpi4py import MPI

    ops = {"sum": MPI.SUM, "min": MPI.MIN, "max": MPI.MAX}

    def reduce(a, op):
        a = np.ascontiguousarray(a)
        out = np.empty_like(a)
        comm.Allreduce(a, out, op=ops[op])
        return out

    return reduce


def new_boxes(part, x, reduce, nranks: int):
    """(owner of each held particle — −1 for the ghosts that are not large —, boxes (P, 4)): the bisection of the
    ordinary particles at their present positions ``x`` (held, (n, ≥2)), and a large particle's owner the rank whose
    box holds its centroid (decided by its present owner, told to every rank).  DecompositionError, on every rank,
    where :func:`~.decompose.decompose` refuses: fewer ordinary particles than ranks, or a box narrower than the
    interaction range."""
    keep, own, large = part.keep, part.own, part.large
    g = part.geom
    x = np.asarray(x, float)[:, :2]
    small = own & ~large
    n_small = int(reduce(np.array([small.sum()], np.int64), "sum")[0])
    if n_small < nranks:
        raise DecompositionError(
            f"{nranks} ranks for {n_small} particles (plates and walls aside): each rank must own at least one"
        )
    o_small, boxes = bisect_ranks(x[small], keep[small], nranks, reduce, g["method"])
    owner = np.full(len(keep), -1, np.int64)
    owner[small] = o_small
    big = np.flatnonzero(large)  # held by every rank, in the same (global) order
    got = np.full(len(big), -1, np.int64)
    for k, i in enumerate(big):
        if own[i]:
            got[k] = int(np.argmin([box_distance(x[i : i + 1], b)[0] for b in boxes]))
    owner[big] = reduce(got, "max")
    if nranks > 1:
        lo = reduce(x[small].min(axis=0) if small.any() else np.full(2, np.inf), "min")
        hi = reduce(x[small].max(axis=0) if small.any() else np.full(2, -np.inf), "max")
        w = _thickness(boxes, np.vstack([lo, hi]))
        r = int(np.argmin(w))
        halo = g["rmax"] + (g["reach"] + g["skin"])  # as decompose() sums it
        span = halo + g["rmax"]
        if w[r] < span:
            raise DecompositionError(
                f"{nranks} ranks ({g['method']}): the box of rank {r} is {w[r]:.4g} cm across, narrower than the "
                f"interaction range {span:.4g} cm (two bounding radii and the reach {g['reach'] + g['skin']:.4g} cm), "
                "so its ghosts would come from beyond its neighbours: use fewer ranks"
            )
    return owner, boxes


def ghost_owners(comm, part, owner):
    """The new owners of this rank's ghosts, from their owners over the present halo (one exchange with each
    neighbour, in the halo's order); ``owner``: the new owners of the owned (and large) particles."""
    L = part.lists
    owner = owner.copy()
    reqs, bufs = [], []
    for k, q in enumerate(L["nbr"]):
        snd = np.ascontiguousarray(owner[L["send_idx"][L["send_start"][k] : L["send_start"][k + 1]]])
        rcv = np.empty(L["recv_start"][k + 1] - L["recv_start"][k], np.int64)
        reqs.append(comm.Isend(snd, dest=int(q), tag=_OWNER_TAG))
        reqs.append(comm.Irecv(rcv, source=int(q), tag=_OWNER_TAG))
        bufs.append((k, rcv, snd))
    from mpi4py import MPI

    MPI.Request.Waitall(reqs)
    for k, rcv, _ in bufs:
        idx = L["recv_idx"][L["recv_start"][k] : L["recv_start"][k + 1]]
        owner[idx] = np.where(part.large[idx], owner[idx], rcv)
    return owner


def holders(part, x, owner, boxes, nranks: int):
    """(particle, rank) pairs, ascending: the ranks that will hold each owned particle after the cut — its owner,
    the ranks whose box lies within its bounding radius plus the halo width, every rank for a large particle, the
    owner of each bond partner (engine/decompose.py ``ghosts``, from the owner's side)."""
    from .parts import _bond_pairs

    own, large = part.own, part.large
    g = part.geom
    halo = g["rmax"] + (g["reach"] + g["skin"])  # as decompose() sums it
    x = np.asarray(x, float)[:, :2]
    mine = np.flatnonzero(own)
    rad = np.asarray(part.system.radius, float)
    pairs = [np.column_stack([mine, owner[mine]])]
    small = mine[~large[mine]]
    if len(small):
        lo, hi = x[small].min(axis=0), x[small].max(axis=0)
        reach = rad[small].max() + halo
        region = np.array([lo[0], hi[0], lo[1], hi[1]])
        for q in np.flatnonzero(box_gap(region, boxes) <= reach):
            near = small[box_distance(x[small], boxes[q]) <= rad[small] + halo]
            pairs.append(np.column_stack([near, np.full(len(near), q)]))
    big = mine[large[mine]]
    if len(big):
        pairs.append(np.column_stack([np.repeat(big, nranks), np.tile(np.arange(nranks), len(big))]))
    bonds = _bond_pairs(part.system)
    if bonds is not None:
        for s, t in ((0, 1), (1, 0)):
            sel = own[bonds[:, s]]
            pairs.append(np.column_stack([bonds[sel, s], owner[bonds[sel, t]]]))
    both = np.concatenate(pairs).astype(np.int64)
    key = np.unique(both[:, 0] * nranks + both[:, 1])  # one number per pair: a sort of integers, not of rows
    return np.column_stack([key // nranks, key % nranks])


def _exchange(comm, dests, make):
    """Send each rank of ``dests`` its piece ``make(rank)`` (made, sent and dropped one after the other) and receive
    the pieces sent here, in the order of the ranks that sent them (this rank's own among them, made last).  The count
    of messages each rank receives comes from one reduction over the ranks; the pieces go point to point."""
    from mpi4py import MPI

    rank, size = comm.Get_rank(), comm.Get_size()
    mark = np.zeros(size, np.int64)
    others = [d for d in dests if d != rank]
    mark[others] = 1
    count = np.zeros(1, np.int64)
    comm.Reduce_scatter_block(mark, count, op=MPI.SUM)
    reqs = [comm.isend(make(d), dest=d, tag=_PIECE_TAG) for d in others]  # (isend pickles at once)
    got = {}
    st = MPI.Status()
    for _ in range(int(count[0])):
        pc = comm.recv(source=MPI.ANY_SOURCE, tag=_PIECE_TAG, status=st)
        got[st.Get_source()] = pc
    MPI.Request.waitall(reqs)
    if rank in dests:
        got[rank] = make(rank)
    return [got[r] for r in sorted(got)]


def _per_particle_fields():
    from .parts import _PER_PARTICLE

    return _PER_PARTICLE


def _pack(part, nord, owner, hold, dest, fstate):
    """The piece of this rank's part that rank ``dest`` gets (module doc, 3.); ``hold``: (particle, rank) pairs,
    those of ``dest`` with their particles ascending."""
    from .parts import data_layout, layout

    s = part.system
    sent = hold[hold[:, 1] == dest, 0]
    # what ``dest`` will hold as far as this rank knows: what it sends there, what ``dest`` will own, the walls (a pair
    # of two held particles of which this rank sends neither is sent by their owner)
    held = (owner == dest) | part.large
    held[sent] = True
    vs = s.vert_start
    nv = np.diff(vs)[sent]
    rows = np.repeat(vs[sent], nv) + (np.arange(nv.sum()) - np.repeat(np.cumsum(nv) - nv, nv))
    newly = sent[owner[sent] == dest]  # the particles it will own: the ranks that will hold each
    h = hold[np.isin(hold[:, 0], newly)]
    names = sorted(part.held_sets)
    pc = {
        "gid": part.keep[sent],
        "owner": owner[sent],
        "large": part.large[sent],
        "nord": nord[sent],
        "fields": {k: np.asarray(getattr(s, k))[sent] for k in _per_particle_fields()},
        "ext_ramp": None if s.ext_ramp is None else np.asarray(s.ext_ramp)[sent],
        "nv": nv,
        "body_v": s.body_v[rows],
        "sets": {n: np.isin(part.keep[sent], part.held_sets[n]) for n in names},
        "holders": (part.keep[h[:, 0]], h[:, 1]),
        "data": {},
        "state": {},
    }
    for f in used_families(s):
        d = s.family_data.get(f.name)
        if d is None:
            continue
        pd = ranks.pack(data_layout(f, d), d, part.keep, part.own, owner, dest, sent, held)
        pc["data"][f.name] = pd
        sent_ids = np.concatenate([v for k, v in pd.items() if k.endswith(":ids")] + [np.zeros(0, np.int64)])
        st = {}
        g = fstate[f.name]
        for names_, kind in layout(f, s):
            if isinstance(kind, Rows):
                ids = g[("rows",) + tuple(names_)]
                sel = np.isin(ids, sent_ids)
                st[("rows",) + tuple(names_)] = ids[sel]
                st.update({k: g[k][sel] for k in names_})
            elif isinstance(kind, Pairs):
                a, b = g[names_[0]], g[names_[1]]
                la, lb = np.searchsorted(part.keep, a), np.searchsorted(part.keep, b)
                sel = (owner[la] == dest) | (owner[lb] == dest) if len(a) else np.zeros(0, bool)
                st.update({k: g[k][sel] for k in names_})
        pc["state"][f.name] = st
    return pc


def _small_kinds(lay):
    return tuple((n, k) for n, k in lay if isinstance(k, (Same, Summed, Entries, Rebuilt)))


def recut(rs):
    """Every rank: the scene cut again at the present positions by neighbour exchange (module doc); the rank's new
    part installed in ``rs`` (engine/distributed.py RankSimulation) with a fresh engine, and its share of the
    checkpoint fields returned (for ``_settle``).  A refused cut (DecompositionError on every rank) changes
    nothing."""
    from .parts import layout

    comm, part, sim = rs.comm, rs.part, rs.sim
    rank, size = comm.Get_rank(), comm.Get_size()
    reduce = reducer(comm)
    x = sim.nord[:, :, 0]
    owner, boxes = new_boxes(part, x, reduce, size)
    owner = ghost_owners(comm, part, owner)
    hold = holders(part, x, owner, boxes, size)
    # the family states in the whole scene's numbering, only what this rank counts; the small ones over the ranks
    st = sim.state()
    fams = used_families(part.system)
    fstate = {f.name: ranks.globalize(layout(f, part.system), st, part.keep, part.own, part.system) for f in fams}
    small = comm.allgather(
        {
            f.name: {
                k: fstate[f.name][k]
                for n, kd in _small_kinds(layout(f, part.system))
                if not isinstance(kd, Rebuilt)
                for k in n
            }
            for f in fams
        }
    )
    acc = comm.allgather(st["acc"])
    head = {k: st[k] for k in ("step", "ended", "acc")}
    nord = st["nord"]
    # the old engine (its bundles' work arrays) freed before the new part comes: what the pieces need is in the state
    del st, x, sim
    rs.sim = rs.halo = None
    make = functools.partial(_pack, part, nord, owner, hold, fstate=fstate)
    del fstate, nord
    got = _exchange(comm, [int(d) for d in np.unique(hold[:, 1])], make)
    del make
    err = new = local = None
    try:
        new, local = _new_part(part, got, rank, size, boxes, fams, small, acc, head)
    except BaseException as e:  # noqa: BLE001 - told to every rank (the others would wait in the halo forever)
        err = e
    del got
    said = comm.allgather(None if err is None else f"{type(err).__name__}: {err}")
    failed = [(r, m) for r, m in enumerate(said) if m]
    if failed:
        if err is not None:
            raise err
        raise EngineError(f"the re-cut failed on rank {failed[0][0]}: {failed[0][1]}")
    rs.part, rs.cut = new, None
    rs._engine()
    return local


def _new_part(part, got, rank, size, boxes, fams, small, acc, head):
    """(the new part, its share of the checkpoint fields) from the pieces ``got`` (module doc, 4.)."""
    from .parts import Part, data_layout, layout, localize, runs

    # the scene of the particles this rank now holds, in the order of their global numbers
    gids = np.concatenate([pc["gid"] for pc in got])
    order = np.argsort(gids, kind="stable")
    G = gids[order]
    if len(G) and np.any(G[1:] == G[:-1]):  # pragma: no cover - a particle sent twice
        raise RuntimeError("a particle reached a rank twice at a re-cut")
    own = np.concatenate([pc["owner"] for pc in got])[order] == rank
    large = np.concatenate([pc["large"] for pc in got])[order]
    old = part.system
    fields = {k: np.concatenate([pc["fields"][k] for pc in got])[order] for k in _per_particle_fields()}
    nv = np.concatenate([pc["nv"] for pc in got]).astype(old.vert_start.dtype)
    first = np.concatenate([[0], np.cumsum(nv)[:-1]])
    bv = np.concatenate([pc["body_v"] for pc in got])
    vert_start, rows = runs(first[order], nv[order])
    body_v = bv[rows]
    sets = {n: np.flatnonzero(np.concatenate([pc["sets"][n] for pc in got])[order]) for n in sorted(part.held_sets)}
    data = dict(old.family_data)
    for f in fams:
        d = old.family_data.get(f.name)
        if d is not None:
            data[f.name] = ranks.join(data_layout(f, d), d, [pc["data"][f.name] for pc in got], G, order, part.keep)
    joined = replace(
        old,
        n=len(G),
        vert_start=vert_start,
        body_v=body_v,
        sets=sets,
        family_data=data,
        own=None,
        gid=G,
        ext_ramp=None if old.ext_ramp is None else np.concatenate([pc["ext_ramp"] for pc in got])[order],
        **fields,
    )
    system = localize(joined, np.arange(len(G)), own)
    held_sets = {n: G[m] for n, m in sets.items()}
    hg = np.concatenate([pc["holders"][0] for pc in got])
    hr = np.concatenate([pc["holders"][1] for pc in got])
    owners = np.concatenate([pc["owner"] for pc in got])[order]
    xcut = np.concatenate([pc["nord"] for pc in got])[order][:, :2, 0]
    lists = _lists(part, rank, G, own, large, owners, hg, hr, xcut, np.asarray(system.radius, float), boxes)
    new = Part(rank, size, G, own, system, lists, held_sets, part.n_whole, part.geom, large)
    # this rank's share of the checkpoint fields
    local = {
        "step": head["step"],
        "ended": head["ended"],
        "nord": np.concatenate([pc["nord"] for pc in got])[order],
        "acc": np.sum(acc, axis=0) if rank == 0 else np.zeros_like(head["acc"]),
    }
    for f in fams:
        lay = layout(f, system)
        sm = _small_kinds(lay)
        merged = ranks.merge(sm, [s_[f.name] for s_ in small], system)
        local.update(ranks.scatter(sm, merged, G, own, system, rank))
        for names_, kind in lay:
            if isinstance(kind, Rows):
                key = ("rows",) + tuple(names_)
                ids = np.concatenate([pc["state"][f.name][key] for pc in got])
                srt = np.argsort(ids)
                want = np.asarray(kind.ids(system)[0], np.int64)
                at = srt[np.searchsorted(ids[srt], want)] if len(ids) else np.zeros(0, np.int64)
                if len(want) and not np.array_equal(ids[at], want):  # pragma: no cover - a row not sent
                    raise RuntimeError(f"interaction family '{f.name}': a row's history did not reach its rank")
                for k in names_:
                    local[k] = np.concatenate([pc["state"][f.name][k] for pc in got])[at]
            elif isinstance(kind, Pairs):
                st_p = {k: np.concatenate([pc["state"][f.name][k] for pc in got]) for k in names_}
                local.update(ranks.scatter(((names_, kind),), st_p, G, own, system, rank))
    return new, local


def _lists(part, rank, G, own, large, owners, hg, hr, xcut, radius, boxes) -> dict:
    """The halo's exchange lists of the new part (as engine/distributed.py ``Cut._halo_lists`` makes them from the
    whole scene): to each neighbour the owned particles it will hold, from each the ghosts it owns, in the order of
    their global numbers; the owned particles it watches and the near ranks that do not hold them."""
    i64 = np.int64
    lo = np.searchsorted(G, hg)  # (owned particle, holder) pairs in local numbers
    other = hr != rank
    p_of, q_of = lo[other], hr[other]
    nbr, s_idx, s_start, r_idx, r_start = [], [], [0], [], [0]
    for q in np.union1d(q_of, owners[~own]):
        send = np.sort(p_of[q_of == q])
        recv = np.flatnonzero(owners == q)
        nbr.append(int(q))
        s_idx.extend(send)
        s_start.append(len(s_idx))
        r_idx.extend(recv)
        r_start.append(len(r_idx))
    L = part.lists
    e = 0.5 * part.geom["skin"]
    near = part.geom["rmax"] + part.geom["reach"] + e
    mine = np.flatnonzero(own & ~large)
    rad = radius[mine]
    gap = box_gap(boxes[rank], boxes)
    cand = [q for q in range(len(boxes)) if q != rank and gap[q] <= rad.max(initial=0.0) + near + e]
    col = np.full(len(boxes), -1)
    col[cand] = np.arange(len(cand))
    holds = np.zeros((len(mine), len(cand)), bool)
    row = np.searchsorted(mine, p_of)
    hit = (
        (row < len(mine)) & (mine[np.minimum(row, len(mine) - 1)] == p_of) & (col[q_of] >= 0) if len(mine) else row < 0
    )
    holds[row[hit], col[q_of[hit]]] = True
    watch = (gap[cand][None, :] <= (rad + near + e)[:, None]) & ~holds
    return {
        "nbr": np.array(nbr, i64),
        "send_start": np.array(s_start, i64),
        "send_idx": np.array(s_idx, i64),
        "recv_start": np.array(r_start, i64),
        "recv_idx": np.array(r_idx, i64),
        "mine": mine.astype(i64),
        "xref": xcut[mine].copy(),
        "rad": rad,
        "lim": L["lim"].copy(),
        "boxes": np.ascontiguousarray(boxes, float),
        "wstart": np.concatenate([[0], np.cumsum(watch.sum(axis=1))]).astype(i64),
        "wrank": np.array(cand, i64)[np.nonzero(watch)[1]],
    }
