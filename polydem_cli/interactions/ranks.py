"""What an interaction family needs to run on several MPI ranks (engine/distributed.py), from layouts the family
declares: its scene data cut to a rank's part (:func:`localize`, from ``Family.data_layout``; the renumbering
:func:`local_numbers`) and the communication layer of its checkpoint fields — joined over the ranks
(:func:`globalize`, :func:`merge`) and shared out again (:func:`scatter`: sums on rank 0 only, so that the ranks'
sums stay the scene's) from ``Family.state_layout``."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, fields, is_dataclass, replace

import numpy as np


def local_numbers(keep, own, *indices) -> tuple:
    """(loc, owned) of a rank's part: ``loc[g]`` the local number of global particle g (−1 where the rank does not
    hold it), ``owned[g]`` whether the rank owns it; ``keep``: the held particles (sorted global numbers), ``own``:
    which of them are owned; sized to cover ``keep`` and every array of global numbers in ``indices``."""
    keep = np.asarray(keep, np.int64)
    n = 1 + max([int(keep.max(initial=-1))] + [int(np.max(np.asarray(i), initial=-1)) for i in indices])
    loc = np.full(n, -1, np.int64)
    loc[keep] = np.arange(len(keep))
    owned = np.zeros(n, bool)
    owned[keep[np.asarray(own, bool)]] = True
    return loc, owned


# ---------------------------------------------------------------- a family's scene data cut to a rank's part
#
# A family declares how the data its ``build`` made for the whole scene are cut to one rank's part
# (``Family.data_layout``: a tuple of (field paths, kind)); :func:`localize` does the cutting.  A path names a field
# of the data: a dict key, a namedtuple's or dataclass's field, or a tuple's position, nested with dots
# ("0.wall": the field ``wall`` of the tuple's first item).


@dataclass(frozen=True)
class PerParticle:
    """Arrays along the particles (axis 0, the whole scene's numbering): a rank keeps its held particles' rows."""


@dataclass(frozen=True)
class Held:
    """Arrays of particle numbers that every rank holds (walls, which every rank keeps): mapped to local numbers."""


@dataclass(frozen=True)
class Owned:
    """Entries as lists of arrays, one array per entry: the first path holds particle numbers, the others arrays along
    them (a force per particle); a rank keeps the members it owns, renumbered, so that each member is loaded or
    measured on one rank."""


@dataclass(frozen=True)
class PairRows:
    """Interactions of a fixed numbering between two particles (beams, edge interfaces): a rank keeps the rows with
    an owned particle (both are held: the ghost margin covers a bond's reach), renumbered, each counted on the rank
    owning the first.  ``a``, ``b``: the paths of the rows' particle numbers; ``along``: paths of arrays along the
    rows, or of containers whose every array along the rows is cut (a path ending in ``.*``); ``ids``,
    ``counted``: where to write each kept row's number in the whole scene and whether this rank counts it (1/0);
    ``emptied``: paths of lists of the whole scene that a part does not carry (set to [])."""

    a: str
    b: str
    along: tuple = ()
    ids: str | None = None
    counted: str | None = None
    emptied: tuple = ()


@dataclass(frozen=True)
class Groups:
    """Members grouped by particle, in CSR (a particle's base Gauss points): ``particle`` the groups' particle numbers,
    ``start`` the offsets of their members; ``per_group``, ``per_member``: paths of arrays along the groups and along
    the members.  A rank keeps the groups of the particles it owns (the members act on their particle alone, so each
    is counted once, on its owner), renumbered; ``ids``: where to write the kept members' numbers in the whole
    scene."""

    particle: str
    start: str
    per_group: tuple = ()
    per_member: tuple = ()
    ids: str | None = None


@dataclass(frozen=True)
class HeldMembers:
    """Arrays of particle numbers of a kind (the disks among the particles): a rank keeps those it holds, renumbered;
    ``count``: the path where to write how many it keeps."""

    count: str | None = None


@dataclass(frozen=True)
class PairList:
    """A list of particle pairs with per-pair fields (an initial contact history): the first two paths are the pairs'
    particle numbers, the others arrays along them; a rank keeps the pairs it evaluates, renumbered —
    ``evaluated(a, b, loc, owned, data)`` → mask over the global pairs (default: both held, one owned).  A list the
    data lack is left out."""

    evaluated: Callable | None = None


def _get(obj, path: str):
    for key in path.split("."):
        if isinstance(obj, dict):
            obj = obj[key]
        elif key.isdigit() and isinstance(obj, (tuple, list)) and not hasattr(obj, "_fields"):
            obj = obj[int(key)]
        else:
            obj = getattr(obj, key)
    return obj


def _put(obj, path: str, value):
    """A copy of ``obj`` with the field at ``path`` replaced (the containers along the path copied, not changed)."""
    key, _, rest = path.partition(".")
    if rest:
        value = _put(_get(obj, key), rest, value)
    if isinstance(obj, dict):
        return {**obj, key: value}
    if hasattr(obj, "_replace"):
        return obj._replace(**{key: value})
    if is_dataclass(obj):
        return replace(obj, **{key: value})
    if isinstance(obj, (tuple, list)):
        items = list(obj)
        items[int(key)] = value
        return type(obj)(items)
    raise TypeError(f"cannot set {key!r} of a {type(obj).__name__}")


def localize(layout, data, keep: np.ndarray, own: np.ndarray):
    """The family's scene data ``data`` cut to a rank's part (``keep``: its held particles, sorted global numbers;
    ``own``: which of them it owns) as ``layout`` declares; fields the layout does not name stay as they are."""
    if data is None:
        return None
    keep = np.asarray(keep, np.int64)
    own = np.asarray(own, bool)
    out = data
    for paths, kind in layout:
        if isinstance(kind, PerParticle):
            for p in paths:
                out = _put(out, p, np.asarray(_get(data, p))[keep])
        elif isinstance(kind, Held):
            vals = [np.asarray(_get(data, p), np.int64) for p in paths]
            loc, _ = local_numbers(keep, own, *vals)
            for p, v in zip(paths, vals):
                out = _put(out, p, loc[v])
        elif isinstance(kind, Owned):
            lists = [list(_get(data, p)) for p in paths]
            members = [np.asarray(i, np.int64) for i in lists[0]]
            loc, owned = local_numbers(keep, own, *members)
            sel = [owned[i] for i in members]
            out = _put(out, paths[0], [loc[i[m]] for i, m in zip(members, sel)])
            for p, vals in zip(paths[1:], lists[1:]):
                out = _put(out, p, [np.asarray(v)[m] for v, m in zip(vals, sel)])
        elif isinstance(kind, PairRows):
            out = _pair_rows(kind, data, out, keep, own)
        elif isinstance(kind, Groups):
            out = _groups(kind, data, out, keep, own)
        elif isinstance(kind, HeldMembers):
            vals = [np.asarray(_get(data, p), np.int64) for p in paths]
            loc, _ = local_numbers(keep, own, *vals)
            for p, v in zip(paths, vals):
                m = loc[v]
                out = _put(out, p, m[m >= 0])
                if kind.count is not None:
                    out = _put(out, kind.count, int(np.count_nonzero(m >= 0)))
        elif isinstance(kind, PairList):
            out = _pair_list(kind, paths, data, out, keep, own)
        else:
            raise TypeError(f"unknown data kind {kind!r}")
    return out


def _arrays_of(cont) -> list:
    """The field names of a container (dict, namedtuple, dataclass; None: none)."""
    if cont is None:
        return []
    if isinstance(cont, dict):
        return list(cont)
    if hasattr(cont, "_fields"):
        return list(cont._fields)
    if is_dataclass(cont):
        return [f.name for f in fields(cont)]
    raise TypeError(f"cannot list the fields of a {type(cont).__name__}")


def _pair_rows(kind: PairRows, data, out, keep, own):
    a, b = np.asarray(_get(data, kind.a), np.int64), np.asarray(_get(data, kind.b), np.int64)
    loc, owned = local_numbers(keep, own, a, b)
    sel = np.flatnonzero(owned[a] | owned[b])
    if np.any(loc[a[sel]] < 0) or np.any(loc[b[sel]] < 0):
        raise ValueError("a partner of an owned particle is not among the kept particles")
    for p in _row_paths(kind, data):
        out = _put(out, p, np.asarray(_get(data, p))[sel])
    out = _put(out, kind.a, loc[a[sel]].astype(np.int64))
    out = _put(out, kind.b, loc[b[sel]].astype(np.int64))
    if kind.ids is not None:  # the rows' numbers in the whole scene (data joined from pieces carry them already)
        ids0 = _get(data, kind.ids)
        out = _put(out, kind.ids, (sel if ids0 is None else np.asarray(ids0, np.int64)[sel]).astype(np.int64))
    if kind.counted is not None:
        out = _put(out, kind.counted, owned[a[sel]].astype(np.int64))
    for p in kind.emptied:
        out = _put(out, p, [])
    return out


def _groups(kind: Groups, data, out, keep, own):
    idx = np.asarray(_get(data, kind.particle), np.int64)
    start = np.asarray(_get(data, kind.start), np.int64)
    q = np.flatnonzero(np.isin(idx, keep[own]))
    members = [np.arange(start[k], start[k + 1]) for k in q]
    m = np.concatenate(members).astype(np.int64) if members else np.zeros(0, np.int64)
    out = _put(out, kind.start, np.concatenate([[0], np.cumsum(np.diff(start)[q])]).astype(np.int64))
    out = _put(out, kind.particle, np.searchsorted(keep, idx[q]).astype(np.int64))
    for p in kind.per_group:
        out = _put(out, p, np.asarray(_get(data, p))[q])
    for p in kind.per_member:
        out = _put(out, p, np.asarray(_get(data, p))[m])
    if kind.ids is not None:
        ids0 = _get(data, kind.ids)
        out = _put(out, kind.ids, m if ids0 is None else np.asarray(ids0, np.int64)[m])
    return out


def _evaluated_here(a, b, loc, owned):
    """The default of where a pair (global numbers) is evaluated: on a rank holding both and owning one."""
    return (loc[a] >= 0) & (loc[b] >= 0) & (owned[a] | owned[b])


def _pair_list(kind: PairList, paths, data, out, keep, own):
    try:
        a, b = (np.asarray(_get(data, p), np.int64) for p in paths[:2])
    except (KeyError, AttributeError):
        return out  # the data hold no such list
    loc, owned = local_numbers(keep, own, a, b)
    if kind.evaluated is not None:
        sel = np.asarray(kind.evaluated(a, b, loc, owned, data), bool)
    else:
        sel = _evaluated_here(a, b, loc, owned)
    out = _put(out, paths[0], loc[a[sel]])
    out = _put(out, paths[1], loc[b[sel]])
    for p in paths[2:]:
        out = _put(out, p, np.asarray(_get(data, p))[sel])
    return out


# ---------------------------------------------------------------- a family's scene data moved between ranks
#
# A re-cut by neighbour exchange (engine/migrate.py) sends each rank, from each rank that owned them, the particles it
# will hold with their share of every family's data, packed from the same declaration (:func:`pack`); the receiver
# joins the pieces into a scene of the particles it holds, numbered in the order of their global numbers
# (:func:`join`), which :func:`localize` then cuts as it cuts the whole scene.  Numbers in a piece are global.


def _row_paths(kind: PairRows, data) -> list:
    """The paths of the arrays along a pair-row kind's rows (``.*`` expanded)."""
    a = np.asarray(_get(data, kind.a))
    paths = []
    for p in kind.along:
        if p.endswith(".*"):
            cont = p[:-2]
            c = _get(data, cont)
            for name in _arrays_of(c):
                v = _get(c, name)
                if isinstance(v, np.ndarray) and v.shape[:1] == a.shape:
                    paths.append(f"{cont}.{name}")
        else:
            paths.append(p)
    return paths


def _needs_ids(kind):
    if kind.ids is None:
        raise TypeError(f"{type(kind).__name__} without ids: its rows cannot move between ranks (declare ids)")


def pack(layout, data, gid, own, owner, dest: int, sent, held=None) -> dict:
    """What rank ``dest`` gets of this rank's part of a family's data ``data`` at a re-cut: the rows of the particles
    ``sent`` (local numbers, ascending) for the per-particle kinds; the interactions this rank counts whose particles
    ``dest`` will own (``owner``: each held particle's new owner) for the pair rows and lists; the groups and entries of
    the particles this rank owns that ``dest`` will own.  Particle and row numbers global (``gid``: each held
    particle's); ``own``: which this rank owns now; ``held``: whether ``dest`` will hold each held particle (default:
    the particles ``sent`` and those ``dest`` will own) — a pair of a list goes only where both are held."""
    out = {}
    gid = np.asarray(gid, np.int64)
    own = np.asarray(own, bool)
    owner = np.asarray(owner, np.int64)
    sent = np.asarray(sent, np.int64)
    if held is None:
        held = owner == dest
        held[sent] = True
    for i, (paths, kind) in enumerate(layout):
        key = f"{i}:"
        if isinstance(kind, PerParticle):
            for p in paths:
                out[key + p] = np.asarray(_get(data, p))[sent]
        elif isinstance(kind, Held):
            pass  # on every rank: the receiver maps its own
        elif isinstance(kind, Owned):
            members = [np.asarray(m, np.int64) for m in _get(data, paths[0])]
            sel = [own[m] & (owner[m] == dest) for m in members]
            out[key + paths[0]] = [gid[m[s]] for m, s in zip(members, sel)]
            for p in paths[1:]:
                out[key + p] = [np.asarray(v)[s] for v, s in zip(_get(data, p), sel)]
        elif isinstance(kind, PairRows):
            _needs_ids(kind)
            a, b = np.asarray(_get(data, kind.a), np.int64), np.asarray(_get(data, kind.b), np.int64)
            counted = np.asarray(_get(data, kind.counted), bool) if kind.counted else own[a]
            sel = counted & ((owner[a] == dest) | (owner[b] == dest))
            for p in _row_paths(kind, data):
                out[key + p] = np.asarray(_get(data, p))[sel]
            out[key + kind.a], out[key + kind.b] = gid[a[sel]], gid[b[sel]]
            out[key + "ids"] = np.asarray(_get(data, kind.ids), np.int64)[sel]
        elif isinstance(kind, Groups):
            _needs_ids(kind)
            idx = np.asarray(_get(data, kind.particle), np.int64)
            start = np.asarray(_get(data, kind.start), np.int64)
            q = np.flatnonzero(own[idx] & (owner[idx] == dest))
            m = np.concatenate([np.arange(start[k], start[k + 1]) for k in q] + [np.zeros(0, np.int64)])
            out[key + kind.particle] = gid[idx[q]]
            out[key + "sizes"] = np.diff(start)[q]
            for p in kind.per_group:
                out[key + p] = np.asarray(_get(data, p))[q]
            for p in kind.per_member:
                out[key + p] = np.asarray(_get(data, p))[m]
            out[key + "ids"] = np.asarray(_get(data, kind.ids), np.int64)[m]
        elif isinstance(kind, HeldMembers):
            for p in paths:
                member = np.zeros(len(gid), bool)
                member[np.asarray(_get(data, p), np.int64)] = True
                out[key + p] = member[sent]
        elif isinstance(kind, PairList):
            try:
                a, b = (np.asarray(_get(data, p), np.int64) for p in paths[:2])
            except (KeyError, AttributeError):
                continue
            sel = (own[a] | own[b]) & ((owner[a] == dest) | (owner[b] == dest)) & held[a] & held[b]
            out[key + paths[0]], out[key + paths[1]] = gid[a[sel]], gid[b[sel]]
            for p in paths[2:]:
                out[key + p] = np.asarray(_get(data, p))[sel]
        else:
            raise TypeError(f"unknown data kind {kind!r}")
    return out


def join(layout, template, pieces: list, gids: np.ndarray, order: np.ndarray, held_gid: np.ndarray):
    """A family's data of the scene of the particles ``gids`` (sorted global numbers; numbered 0… in that order) from
    the ``pieces`` (:func:`pack`, in the order of the ranks that sent them; their particles, concatenated, sorted by
    ``order``), shaped as ``template`` (this rank's data before the re-cut, whose held particles were ``held_gid``):
    the interactions with their global numbers (the ids), ready for :func:`localize` to cut.  Rows come out in the
    order of their numbers, load entries' members and groups in the order of their particles' numbers, list pairs by
    (a, b): the order the whole scene has them in (sets and Gauss points are built ascending), so that a re-cut's
    part equals the first cut's."""
    if template is None:
        return None
    gids = np.asarray(gids, np.int64)

    def sub(g, missing_ok=False):
        g = np.asarray(g, np.int64)
        i = np.minimum(np.searchsorted(gids, g), max(len(gids) - 1, 0))
        there = gids[i] == g if len(gids) else np.zeros(len(g), bool)
        if not missing_ok and not there.all():  # pragma: no cover - a piece refers to a particle not sent here
            raise RuntimeError("a re-cut's piece refers to a particle this rank does not hold")
        return np.where(there, i, -1)

    out = template
    for i, (paths, kind) in enumerate(layout):
        key = f"{i}:"
        if isinstance(kind, PerParticle):
            for p in paths:
                out = _put(out, p, np.concatenate([pc[key + p] for pc in pieces])[order])
        elif isinstance(kind, Held):
            for p in paths:
                out = _put(out, p, sub(np.asarray(held_gid)[np.asarray(_get(template, p), np.int64)]))
        elif isinstance(kind, Owned):
            n_e = len(_get(template, paths[0]))
            members = [np.concatenate([pc[key + paths[0]][e] for pc in pieces]) for e in range(n_e)]
            srt = [np.argsort(m, kind="stable") for m in members]
            out = _put(out, paths[0], [sub(m[s]) for m, s in zip(members, srt)])
            for p in paths[1:]:
                vals = [np.concatenate([np.asarray(pc[key + p][e]) for pc in pieces]) for e in range(n_e)]
                out = _put(out, p, [v[s] for v, s in zip(vals, srt)])
        elif isinstance(kind, PairRows):
            ids = np.concatenate([pc[key + "ids"] for pc in pieces])
            srt = np.argsort(ids, kind="stable")
            # the arrays along the rows that every piece carries (a rank without rows counts the fixed-size empty
            # arrays of another kind of bond among them: those stay the template's)
            for p in _row_paths(kind, template):
                if all(key + p in pc for pc in pieces):
                    out = _put(out, p, np.concatenate([pc[key + p] for pc in pieces])[srt])
            out = _put(out, kind.a, sub(np.concatenate([pc[key + kind.a] for pc in pieces])[srt]))
            out = _put(out, kind.b, sub(np.concatenate([pc[key + kind.b] for pc in pieces])[srt]))
            out = _put(out, kind.ids, ids[srt])
            if kind.counted is not None:
                out = _put(out, kind.counted, np.zeros(len(ids), np.int64))
        elif isinstance(kind, Groups):
            part = np.concatenate([pc[key + kind.particle] for pc in pieces])
            sizes = np.concatenate([pc[key + "sizes"] for pc in pieces]).astype(np.int64)
            srt = np.argsort(part, kind="stable")
            first = np.concatenate([[0], np.cumsum(sizes)[:-1]]).astype(np.int64)
            m = np.concatenate([np.arange(first[k], first[k] + sizes[k]) for k in srt] + [np.zeros(0, np.int64)])
            out = _put(out, kind.particle, sub(part[srt]))
            out = _put(out, kind.start, np.concatenate([[0], np.cumsum(sizes[srt])]).astype(np.int64))
            for p in kind.per_group:
                out = _put(out, p, np.concatenate([pc[key + p] for pc in pieces])[srt])
            for p in kind.per_member:
                out = _put(out, p, np.concatenate([pc[key + p] for pc in pieces])[m])
            out = _put(out, kind.ids, np.concatenate([pc[key + "ids"] for pc in pieces])[m])
        elif isinstance(kind, HeldMembers):
            for p in paths:
                member = np.concatenate([pc[key + p] for pc in pieces])[order]
                out = _put(out, p, np.flatnonzero(member).astype(np.int64))
                if kind.count is not None:
                    out = _put(out, kind.count, int(member.sum()))
        elif isinstance(kind, PairList):
            if not any(key + paths[0] in pc for pc in pieces):
                continue
            a = np.concatenate([pc[key + paths[0]] for pc in pieces])
            b = np.concatenate([pc[key + paths[1]] for pc in pieces])
            _, first = np.unique(np.column_stack([a, b]), axis=0, return_index=True)  # sorted by (a, b), once each
            first = first[(sub(a[first], True) >= 0) & (sub(b[first], True) >= 0)]
            out = _put(out, paths[0], sub(a[first]))
            out = _put(out, paths[1], sub(b[first]))
            for p in paths[2:]:
                out = _put(out, p, np.concatenate([pc[key + p] for pc in pieces])[first])
    return out


# ---------------------------------------------------------------- a family's checkpoint fields over the ranks
#
# A family declares how each of its checkpoint fields (``Family.state``) is held over the ranks of a decomposed run
# (``Family.state_layout``: a tuple of (field names, kind)); the three movements below serve every family from that
# declaration, as LAMMPS' AtomVec pack/unpack serves every atom style: ``globalize`` (a rank's fields in the whole
# scene's numbering, only what the rank counts), ``merge`` (the whole scene's fields from every rank's: the fields a
# serial run writes, so a checkpoint resumes on any number of ranks) and ``scatter`` (a rank's share of the whole
# scene's fields).  engine/distributed.py calls them for checkpoints and re-cuts; no family moves its own state.


@dataclass(frozen=True)
class Same:
    """Fields every rank holds alike (a controller's peak and load): rank 0's are the scene's."""


@dataclass(frozen=True)
class Summed:
    """Fields each rank holds its share of (sums over its own particles or interactions): summed over the ranks, and
    shared out on rank 0 only (zeros elsewhere), so that the ranks' sum stays the scene's."""


@dataclass(frozen=True)
class Entries:
    """Accumulator entries along the fields' last axis, each combined its way: ``sums`` as :class:`Summed`,
    ``maxima`` the largest (on every rank), ``particles`` entries holding a particle number (−1: none; global in
    the checkpoint, local on a rank, −1 where the rank does not hold it), ``fixed`` (entry, value) pairs set on every
    movement (a list's size to rebuild it); the others rank 0's.  ``argmax``: groups (key, entry, …): the rank with
    the largest key gives the group; ``first``: groups (step, entry, …): the rank with the smallest positive step
    gives it (the first contained pair)."""

    sums: tuple = ()
    maxima: tuple = ()
    particles: tuple = ()
    fixed: tuple = ()
    argmax: tuple = ()
    first: tuple = ()


@dataclass(frozen=True)
class Rows:
    """Per-interaction fields of a fixed numbering (a bond, a base Gauss point): ``ids(part)`` gives each local row's
    number in the whole scene and whether this rank counts it (each row is counted on one rank), ``n(system)`` the
    whole scene's row count."""

    ids: Callable
    n: Callable


@dataclass(frozen=True)
class Pairs:
    """A list of particle pairs that grows and shrinks (contacts with history): the first two names are its particle
    numbers (a, b), the others its per-pair fields.  Each pair comes from the rank counting it
    (``counted(a, b, own, part)`` → mask; default the owner of the smaller number, as the kernels count) and goes to
    every rank that evaluates it (``evaluated(a, b, loc, owned, part)`` → mask over global (a, b); default both held
    and one of them owned)."""

    counted: Callable | None = None
    evaluated: Callable | None = None


@dataclass(frozen=True)
class Rebuilt:
    """Fields not carried over the ranks but made afresh for the scene or the part they go to (a pair list's
    buffers, rebuilt at the first pass): ``make(name, system)``."""

    make: Callable


def _entries_merge(kind: Entries, vals):
    out = np.array(vals[0], copy=True)
    st = np.stack([np.asarray(v) for v in vals])
    for k in kind.sums:
        out[..., k] = st[..., k].sum(axis=0)
    for k in kind.maxima:
        out[..., k] = st[..., k].max(axis=0)
    for key, *rest in kind.argmax:
        r = _giver(st, kind, st[..., key] == st[..., key].max(), rest)
        out[..., [key, *rest]] = st[r][..., [key, *rest]]
    for step, *rest in kind.first:
        s = np.where(st[..., step] > 0, st[..., step], np.inf)
        if np.isfinite(s.min()):
            r = _giver(st, kind, s == s.min(), rest)
            out[..., [step, *rest]] = st[r][..., [step, *rest]]
    for k, v in kind.fixed:
        out[..., k] = v
    return out


def _giver(st, kind: Entries, tied, rest) -> int:
    """The rank that gives an arg-max (or first-step) group: the first of the ``tied`` ranks that holds the group's
    particles (after a share-out every rank has the key, only the ranks holding its particles their numbers)."""
    ranks_ = np.flatnonzero(tied)
    refs = [e for e in rest if e in kind.particles]
    for r in ranks_:
        if all(st[r][..., e] >= 0 for e in refs):
            return int(r)
    return int(ranks_[0])


def _renumber(v, entries, table):
    """Entries holding particle numbers mapped through ``table`` (−1 stays −1, numbers beyond it become −1)."""
    v = np.array(v, copy=True)
    for k in entries:
        p = int(v[..., k])
        v[..., k] = table[p] if 0 <= p < len(table) else -1
    return v


def globalize(layout, state: dict, keep: np.ndarray, own: np.ndarray, part) -> dict:
    """One rank's checkpoint fields ``state`` (its part ``part``, a System) in the whole scene's numbering, only what
    it counts (its owned particles, the interactions it counts), as ``layout`` declares them."""
    keep = np.asarray(keep, np.int64)
    own = np.asarray(own, bool)
    out = {}
    for names, kind in layout:
        if isinstance(kind, (Same, Summed)):
            out.update({k: np.array(state[k], copy=True) for k in names})
        elif isinstance(kind, Entries):
            out.update({k: _renumber(state[k], kind.particles, keep) for k in names})
        elif isinstance(kind, Rows):
            gid, counted = kind.ids(part)
            out.update({k: state[k][counted] for k in names})
            out[("rows",) + tuple(names)] = np.asarray(gid)[counted]
        elif isinstance(kind, Pairs):
            a, b = np.asarray(state[names[0]], np.int64), np.asarray(state[names[1]], np.int64)
            if kind.counted is not None:
                sel = kind.counted(a, b, own, part)
            else:
                sel = own[np.minimum(a, b)] if len(a) else np.zeros(0, bool)
            out.update({k: state[k][sel] for k in names[2:]})
            out[names[0]], out[names[1]] = keep[a[sel]], keep[b[sel]]
        elif not isinstance(kind, Rebuilt):
            raise TypeError(f"unknown state kind {kind!r}")
    return out


def merge(layout, partials: list, system, consume: bool = False) -> dict:
    """The whole scene's checkpoint fields from every rank's :func:`globalize` (rank 0's first).  ``consume``: each
    rank's rows and pairs are taken out of its partial as they are copied, so that fewer copies of them are held at
    once (the partials are left without them)."""
    out = {}
    for names, kind in layout:
        if isinstance(kind, Same):
            out.update({k: partials[0][k] for k in names})
        elif isinstance(kind, Summed):
            out.update({k: np.sum([p[k] for p in partials], axis=0) for k in names})
        elif isinstance(kind, Entries):
            out.update({k: _entries_merge(kind, [p[k] for p in partials]) for k in names})
        elif isinstance(kind, Rows):
            n, key = int(kind.n(system)), ("rows",) + tuple(names)
            for k in names:
                v = partials[0][k]
                out[k] = np.zeros((n,) + v.shape[1:], v.dtype)
                for p in partials:
                    out[k][p[key]] = p.pop(k) if consume else p[k]
        elif isinstance(kind, Pairs):
            for k in names:
                out[k] = np.concatenate([p[k] for p in partials])
                if consume:
                    for p in partials:
                        del p[k]
        elif isinstance(kind, Rebuilt):
            out.update({k: kind.make(k, system) for k in names})
    return out


def scatter(layout, state: dict, keep: np.ndarray, own: np.ndarray, part, rank: int) -> dict:
    """A rank's share of the whole scene's checkpoint fields ``state``: its part's rows, the pairs it evaluates,
    renumbered; sums on rank 0 only."""
    out = {}
    for names, kind in layout:
        if isinstance(kind, Same):
            out.update({k: np.array(state[k], copy=True) for k in names})
        elif isinstance(kind, Summed):
            out.update({k: np.array(state[k], copy=True) if rank == 0 else np.zeros_like(state[k]) for k in names})
        elif isinstance(kind, Entries):
            loc, _ = local_numbers(keep, own)
            for k in names:
                v = _renumber(state[k], kind.particles, loc)
                if rank != 0:
                    v[..., list(kind.sums)] = 0
                for e, val in kind.fixed:
                    v[..., e] = val
                out[k] = v
        elif isinstance(kind, Rows):  # (a field an older checkpoint lacks is left to the family's restore)
            gid, _ = kind.ids(part)
            out.update({k: state[k][gid] for k in names if k in state})
        elif isinstance(kind, Pairs):
            a, b = np.asarray(state[names[0]], np.int64), np.asarray(state[names[1]], np.int64)
            loc, owned = local_numbers(keep, own, a, b)
            if kind.evaluated is not None:
                sel = kind.evaluated(a, b, loc, owned, part)
            else:
                sel = _evaluated_here(a, b, loc, owned)
            out.update({k: state[k][sel] for k in names[2:]})
            out[names[0]], out[names[1]] = loc[a[sel]], loc[b[sel]]
        elif isinstance(kind, Rebuilt):
            out.update({k: kind.make(k, part) for k in names})
    return out
