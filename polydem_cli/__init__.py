"""polydem: 2D discrete element method for rigid convex polygons (Schneider 2012)."""
__version__ = "0.1.0"
