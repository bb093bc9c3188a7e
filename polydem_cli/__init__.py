"""polydem: 2D discrete element method for rigid convex polygons (Schneider 2012)."""

import os as _os

from ._jit_cache import configure as _configure_jit_cache

# Threads under load: numba's OpenMP layer spins in its barriers by default, so a 2-thread run beside one
# busy process lost 2-3.4x against 1 thread (a spinning thread holds the core its partner needs).  Passive
# waiting costs nothing measurable on a quiet machine and keeps 2 threads >= 1 thread under load
# (make bench, 2026-12-02: concrete 40x40, 1 / 2 threads under one busy process 1.51 / 0.44 M particle-steps/s
# spinning, 1.21 / 1.34 M passive; quiet 1.33 / 1.73 spinning, 1.30 / 1.66 passive).  Must be set before
# the OpenMP runtime starts; a user's own OMP_WAIT_POLICY wins.
_os.environ.setdefault("OMP_WAIT_POLICY", "PASSIVE")

__version__ = "0.1.0"

_configure_jit_cache()
