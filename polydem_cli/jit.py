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
