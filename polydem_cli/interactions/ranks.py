"""What an interaction family needs to run on several MPI ranks (engine/distributed.py): its data renumbered to
a rank's part (``Family.localize``, ``scatter``) and its accumulators joined over the ranks (``merge``) or shared
out again (``scatter``: sums on rank 0 only, so that the ranks' sums stay the scene's)."""

from __future__ import annotations

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


def merge_acc(accs, sums=(), maxima=()) -> np.ndarray:
    """The scene's accumulators from every rank's (rank 0 first): ``sums`` summed, ``maxima`` the largest, the
    others rank 0's."""
    accs = np.asarray(accs, float)
    acc = accs[0].copy()
    for k in sums:
        acc[k] = accs[:, k].sum()
    for k in maxima:
        acc[k] = accs[:, k].max()
    return acc


def rank_acc(acc, rank: int, sums=()) -> np.ndarray:
    """A rank's share of the scene's accumulators: the ``sums`` on rank 0 only."""
    acc = np.array(acc, float)
    if rank != 0:
        acc[list(sums)] = 0.0
    return acc
