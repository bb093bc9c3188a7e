"""polydem: 2D discrete element method for rigid convex polygons (Schneider 2012)."""


# Threads and the OpenMP wait policy: numba's OpenMP layer spins for a while in its barriers before it sleeps
# (libgomp's default).  That is what makes 2 threads pay on a quiet machine (make bench, 2026-12-02, three
# interleaved rounds: 2 / 1 threads 1.42-1.58x on dense_N1e3 and 1.29-1.35x on concrete_40x40 spinning;
# 0.97-1.16x and 0.66-0.86x with OMP_WAIT_POLICY=PASSIVE, the sleeping barrier's wake-up costs more than a
# step's parallel work).  Beside a busy process the spinning barrier is 2-3.4x slower than 1 thread; that
# case is left to the thread governor (engine/threads.py), which runs 1 thread while another process keeps a
# core busy, for --threads auto and --threads N alike (only --pin-threads keeps 2).  A user's own
# OMP_WAIT_POLICY / GOMP_SPINCOUNT win.

__version__ = "0.1.0"

#: the Python API (polydem_cli/api.py; docs/api.md): imported on first use, so that ``import polydem_cli`` (and the
#: command line's start) stays light and changes nothing
__all__ = [
    "Scenario",
    "Result",
    "Every",
    "RunState",
    "lab",
    "validate",
    "sweep",
    "calibrate",
    "PolydemError",
    "ScenarioError",
    "OutputError",
    "ResultError",
    "EngineError",
    "CallbackError",
    "setup_jit_cache",
    "__version__",
]


def __getattr__(name):
    if name in __all__:
        from . import api

        return getattr(api, name)
    raise AttributeError(f"module 'polydem_cli' has no attribute {name!r}")


def setup_jit_cache() -> str | None:
    """Point Numba's on-disk cache at polydem's own folder, keyed by a hash of the compiled sources
    (``_jit_cache.py``: a change anywhere in compiled code starts a fresh cache, older ones are removed);
    returns the folder.  ``polydem`` calls it before any command; call it once, before importing anything
    that compiles, in a script that uses polydem as a library.  Importing polydem changes nothing: without
    this call Numba caches beside the sources (its own default), with the same results."""
    from ._jit_cache import configure

    return configure()
