"""matplotlib for polydem's figures: pyplot on the Agg backend (files, no screen), except inside a Jupyter kernel,
where the notebook's own inline backend stays (the Python API returns figures a notebook shows: switching the
kernel to Agg would hide every later figure of the user's)."""

from __future__ import annotations

import sys


def pyplot():
    """matplotlib.pyplot, on Agg unless this process is a Jupyter kernel."""
    import matplotlib

    if "ipykernel" not in sys.modules:
        matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt
