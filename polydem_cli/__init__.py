"""polydem: 2D discrete element method for rigid convex polygons (Schneider 2012)."""

from ._jit_cache import configure as _configure_jit_cache

__version__ = "0.1.0"

_configure_jit_cache()
