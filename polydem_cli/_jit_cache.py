"""Where Numba caches compiled kernels.

Numba's on-disk cache is keyed by the source file of each function only; a
change in a *called* function in another file does not invalidate the caller's
cache, so a stale caller would keep running the old callee (numba issue #6845).
polydem therefore keys its cache directory by a hash of the package's whole
source (every module that uses Numba): any change to compiled code starts a fresh cache.  Override with
``POLYDEM_CACHE_DIR``; ``NUMBA_CACHE_DIR`` set by the user wins.
"""

from __future__ import annotations

import hashlib
import os
import shutil
from pathlib import Path

_PKG = Path(__file__).resolve().parent


def source_hash() -> str:
    """Hash of every package module with compiled code (editing a CLI or report module keeps the cache)."""
    h = hashlib.sha1()
    for p in sorted(_PKG.rglob("*.py")):
        data = p.read_bytes()
        if b"njit" in data or b"prange" in data:
            h.update(str(p.relative_to(_PKG)).encode())
            h.update(data)
    return h.hexdigest()[:12]


def _writable(d: Path) -> bool:
    try:
        d.mkdir(parents=True, exist_ok=True)
        probe = d / ".probe"
        probe.write_text("")
        probe.unlink()
        return True
    except OSError:
        return False


def configure() -> str | None:
    if os.environ.get("NUMBA_CACHE_DIR"):
        return os.environ["NUMBA_CACHE_DIR"]
    tag = f"numba-{source_hash()}"
    bases = []
    if os.environ.get("POLYDEM_CACHE_DIR"):
        bases.append(Path(os.environ["POLYDEM_CACHE_DIR"]))
    bases += [_PKG.parent / ".jit_cache", Path(os.environ.get("XDG_CACHE_HOME", Path.home() / ".cache")) / "polydem"]
    for base in bases:
        d = base / tag
        if _writable(d):
            for old in base.glob("numba-*"):
                if old.name != tag:
                    shutil.rmtree(old, ignore_errors=True)
            os.environ["NUMBA_CACHE_DIR"] = str(d)
            try:  # numba already imported by the caller: set its config too
                import sys

                if "numba" in sys.modules:
                    sys.modules["numba"].config.CACHE_DIR = str(d)
            except Exception:  # pragma: no cover
                pass
            return str(d)
    return None


def loop_cached() -> bool:
    """True if the compiled time loop (engine/kernels.py ``run_steps``) is in the cache directory.

    Numba names its index files ``<module>.<function>-<line>.py<ver>.nbi`` inside a folder per package
    directory; their presence says that a run will load the loop instead of compiling it (a few minutes
    on a cold cache), which the explicit solver family (solvers/explicit.py) tells the user before the silent wait."""
    d = os.environ.get("NUMBA_CACHE_DIR")
    if not d or not Path(d).is_dir():
        return False
    return any(Path(d).glob("engine*/kernels.run_steps-*.nbi"))
