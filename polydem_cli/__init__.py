"""polydem: 2D discrete element method for rigid convex polygons (Schneider 2012)."""

from ._jit_cache import configure as _configure_jit_cache

# Threads and the OpenMP wait policy: numba's OpenMP layer spins for a while in its barriers before it sleeps
# (libgomp's default).  That is what makes 2 threads pay on a quiet machine (make bench, 2026-12-02, three
# interleaved rounds: 2 / 1 threads 1.42-1.58x on dense_N1e3 and 1.29-1.35x on concrete_40x40 spinning;
# 0.97-1.16x and 0.66-0.86x with OMP_WAIT_POLICY=PASSIVE, the sleeping barrier's wake-up costs more than a
# step's parallel work).  Beside a busy process the spinning barrier is 2-3.4x slower than 1 thread; that
# case is left to the thread governor (engine/threads.py), which runs 1 thread while another process keeps a
# core busy, for --threads auto and --threads N alike (only --pin-threads keeps 2).  A user's own
# OMP_WAIT_POLICY / GOMP_SPINCOUNT win.

__version__ = "0.1.0"

_configure_jit_cache()
