"""MPI calls from compiled code that Numba can cache: the halo exchange runs inside the time loop.

numba-mpi (the registry's binding of MPI for Numba) bakes the MPI library's function addresses and handles into the
compiled code as constants, so Numba refuses to cache a function that uses it ("uses dynamic globals"), and the
time loop would be compiled afresh by every rank of every run.  Here the addresses and handles are *data*: an
:class:`MpiApi` record of integers made by :func:`api` in each process (after ``mpi4py`` initialised MPI) and
passed into the loop like any array; the intrinsic :func:`ccall` calls a C function through an address held in
such an array.  The loop is then cached once, whatever process runs it.

Handles (communicator, datatype, operation, request) have the width the MPI library gives them: ``int`` in MPICH
and its derivatives (the ``mpich`` wheel, Intel MPI, Cray MPICH), a pointer in Open MPI.  :func:`api` stores them
as 64-bit integers whatever the library, with their width beside them (``rank[2]``), and requests as raw bytes
(``rank[3]`` per request); the compiled calls pass a handle as a C ``int`` or as 64 bits as that width says.  So
the record has the same types under every MPI and in a serial run: one loop type, one cached specialisation
(two specialisations of the loop in Numba's cache made a later process crash, engine/halo.py).
"""

from __future__ import annotations

import ctypes
from collections import namedtuple

import numpy as np
from llvmlite import ir
from numba import njit, types
from numba.extending import intrinsic

#: fn: C function addresses (ISEND, IRECV, WAITALL, ALLREDUCE); h: handles (COMM, DOUBLE, INT64, SUM, MAX, MIN) as
#: int64; req: room for the requests of one exchange (bytes); status: room for their statuses (bytes);
#: rank: [this rank, number of ranks, handle width in bytes (4 or 8), request size in bytes]
MpiApi = namedtuple("MpiApi", ["fn", "h", "req", "status", "rank"])
ISEND, IRECV, WAITALL, ALLREDUCE = range(4)
COMM, DOUBLE, INT64, SUM, MAX, MIN = range(6)


@intrinsic
def ccall(typingctx, fn, args):
    """``ccall(address, (a0, a1, ...)) -> int32``: call the C function at ``address`` (an integer) with the
    arguments of the tuple, each passed with the C type of its Numba type (int32 as ``int``, int64/intp as a
    64-bit integer or pointer, float64 as ``double``)."""
    if not isinstance(fn, types.Integer) or not isinstance(args, types.BaseTuple):
        return None
    sig = types.int32(fn, args)

    def codegen(context, builder, signature, llargs):
        addr, tup = llargs
        argtys = [context.get_value_type(t) for t in args.types]
        fnty = ir.FunctionType(ir.IntType(32), argtys)
        fptr = builder.inttoptr(addr, fnty.as_pointer())
        vals = [builder.extract_value(tup, i) for i in range(len(args.types))]
        return builder.call(fptr, vals)

    return sig, codegen


def _library():
    """The MPI library that mpi4py loaded into this process.

    mpi4py opens it privately (its symbols are not global), so it is found among the files mapped into the
    process (Linux ``/proc/self/maps``: the first ``libmpi*``/``libmpich*`` exporting ``MPI_Isend``), else by the
    system's library search; opening an already loaded library again gives the same code, so the addresses are
    those mpi4py calls."""
    from ctypes.util import find_library

    from mpi4py import MPI  # noqa: F401 - loads and initialises the library

    paths = []
    try:
        with open("/proc/self/maps") as maps:
            for line in maps:
                fields = line.split(maxsplit=5)
                path = fields[5].strip() if len(fields) == 6 else ""
                name = path.rsplit("/", 1)[-1]
                if name.startswith(("libmpi.", "libmpi_", "libmpich.", "libmpich_")) and path not in paths:
                    paths.append(path)
    except OSError:
        pass
    paths += [p for p in (find_library(n) for n in ("mpi", "mpich")) if p]
    for path in paths:
        try:
            lib = ctypes.CDLL(path)
            lib.MPI_Isend  # noqa: B018 - the probe
            return lib
        except (OSError, AttributeError):
            continue
    raise RuntimeError(f"no MPI library exporting MPI_Isend among those loaded by mpi4py (tried: {paths or 'none'})")


def api(comm=None, max_requests: int = 64) -> MpiApi:
    """The MPI entry points and handles of this process (``comm``: an mpi4py communicator, default the world)."""
    from mpi4py import MPI

    comm = comm or MPI.COMM_WORLD
    lib = _library()
    fn = np.array(
        [
            ctypes.cast(getattr(lib, name), ctypes.c_void_p).value
            for name in ("MPI_Isend", "MPI_Irecv", "MPI_Waitall", "MPI_Allreduce")
        ],
        np.int64,
    )
    width = MPI._sizeof(MPI.Comm)
    raw = np.array([MPI._handleof(h) for h in (comm, MPI.DOUBLE, MPI.INT64_T, MPI.SUM, MPI.MAX, MPI.MIN)], np.uint64)
    h = raw.astype(np.uint32).view(np.int32).astype(np.int64) if width == 4 else raw.view(np.int64)
    rsize = MPI._sizeof(MPI.Request)
    return MpiApi(
        fn,
        h,
        np.zeros(max_requests * rsize, np.uint8),
        np.zeros(max_requests * max(8, MPI._sizeof(MPI.Status)), np.uint8),
        np.array([comm.Get_rank(), comm.Get_size(), width, rsize], np.int64),
    )


def grow(mpi: MpiApi, requests: int) -> MpiApi:
    """``mpi`` with room for ``requests`` requests (and their statuses) if it has less."""
    rsize = int(mpi.rank[3])
    have = mpi.req.shape[0] // max(1, rsize)
    if requests <= have:
        return mpi
    per = mpi.status.shape[0] // max(1, have)
    return mpi._replace(req=np.zeros(requests * rsize, np.uint8), status=np.zeros(requests * per, np.uint8))


@njit(cache=True)
def _point(mpi, fn, buf, count, other, tag, k):
    """Isend or Irecv (``fn``) of ``count`` float64 at ``buf`` to/from rank ``other``; request slot ``k``."""
    req = mpi.req.ctypes.data + k * mpi.rank[3]
    if mpi.rank[2] == 4:
        return ccall(
            mpi.fn[fn],
            (
                buf.ctypes.data,
                np.int32(count),
                np.int32(mpi.h[DOUBLE]),
                np.int32(other),
                np.int32(tag),
                np.int32(mpi.h[COMM]),
                req,
            ),
        )
    return ccall(
        mpi.fn[fn],
        (buf.ctypes.data, np.int32(count), mpi.h[DOUBLE], np.int32(other), np.int32(tag), mpi.h[COMM], req),
    )


@njit(cache=True)
def isend(mpi, buf, count, dest, tag, k):
    """Start sending ``count`` float64 from the start of ``buf`` to rank ``dest``; request slot ``k``."""
    return _point(mpi, ISEND, buf, count, dest, tag, k)


@njit(cache=True)
def irecv(mpi, buf, count, source, tag, k):
    """Start receiving ``count`` float64 into the start of ``buf`` from rank ``source``; request slot ``k``."""
    return _point(mpi, IRECV, buf, count, source, tag, k)


@njit(cache=True)
def waitall(mpi, n):
    """Wait for the first ``n`` requests."""
    return ccall(mpi.fn[WAITALL], (np.int32(n), mpi.req.ctypes.data, mpi.status.ctypes.data))


@njit(cache=True)
def allreduce(mpi, send, recv, op):
    """``recv`` = the reduction over the ranks of ``send`` (float64 arrays of equal length); ``op``: SUM, MAX or MIN
    (the index of its handle in ``mpi.h``)."""
    n = np.int32(send.shape[0])
    if mpi.rank[2] == 4:
        return ccall(
            mpi.fn[ALLREDUCE],
            (
                send.ctypes.data,
                recv.ctypes.data,
                n,
                np.int32(mpi.h[DOUBLE]),
                np.int32(mpi.h[op]),
                np.int32(mpi.h[COMM]),
            ),
        )
    return ccall(
        mpi.fn[ALLREDUCE],
        (send.ctypes.data, recv.ctypes.data, n, mpi.h[DOUBLE], mpi.h[op], mpi.h[COMM]),
    )


def inert_api() -> MpiApi:
    """The MpiApi of a process that is not one of several ranks: no entry point, ``rank = [0, 1]``; the compiled
    code that holds one tests ``rank[1] > 1`` before any call."""
    return MpiApi(
        np.zeros(4, np.int64),
        np.zeros(6, np.int64),
        np.zeros(4, np.uint8),
        np.zeros(8, np.uint8),
        np.array([0, 1, 4, 4], np.int64),
    )
