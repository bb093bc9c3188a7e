"""Compilation helpers shared by the kernels."""

from __future__ import annotations

import types

from numba import njit


def named_copy(f, name):
    """A copy of ``f`` under another name.

    Numba's disk cache is keyed by the function's qualified name and source
    line; two compilations of one Python function (serial and parallel) would
    overwrite each other's cache entry and the serial caller would silently
    run the parallel code or vice versa.
    """
    g = types.FunctionType(f.__code__, f.__globals__, name, f.__defaults__, f.__closure__)
    g.__qualname__ = name
    g.__doc__ = f.__doc__
    return g


def serial_and_parallel(f):
    """(serial, parallel) cached compilations of a kernel written with ``prange``."""
    base = f.__name__.lstrip("_")
    return (
        njit(cache=True)(named_copy(f, f"_{base}_serial")),
        njit(cache=True, parallel=True)(named_copy(f, f"_{base}_parallel")),
    )


def loop_njit(f):
    """Compile a function of the time loop or an interaction family's hook: cached, and without Numba's
    reference counting (NRT).

    The loop hands the bundles of every interaction family (interactions/protocol.py) — some 170 arrays in
    nested namedtuples — through several call levels each step; with reference counting every level
    increments and decrements the count of every array it touches, which cost about 15 µs per step
    (34 against 17 µs per step of the 36-particle bonded specimen, one thread, 2026-12-03).  These functions
    only read and write arrays they are handed; a function compiled this way cannot allocate one (Numba
    refuses to compile it)."""
    return njit(cache=True, _nrt=False)(f)
