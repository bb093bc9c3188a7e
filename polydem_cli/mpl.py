"""matplotlib for polydem's figures: pyplot on the Agg backend (files, no screen), except inside a Jupyter kernel or
a session that has imported pyplot already, whose own backend stays (the Python API returns figures a notebook
shows: switching the kernel to Agg would hide every later figure of the user's)."""

from __future__ import annotations

import sys


def pyplot():
    """matplotlib.pyplot, on Agg unless this process is a Jupyter kernel or has chosen its backend already."""
    import matplotlib

    if "ipykernel" not in sys.modules and "matplotlib.pyplot" not in sys.modules:
        matplotlib.use("Agg")  # pyplot already imported: the user's (an interactive session's) backend stays
    import matplotlib.pyplot as plt

    return plt
