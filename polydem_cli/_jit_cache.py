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
import threading
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


_LOCAL = threading.local()


def lock_path(cache_dir: str, py_func) -> str:
    """The lock file of one compiled function in ``cache_dir`` (:func:`lock_compiles`)."""
    key = hashlib.sha1(f"{py_func.__module__}.{py_func.__qualname__}".encode()).hexdigest()[:16]
    return os.path.join(cache_dir, ".locks", key + ".lock")


def lock_compiles(cache_dir: str):
    """Let one process at a time load or compile a function into ``cache_dir``.

    Numba's disk cache is not safe for processes that compile the same function at once: each writes the index
    and the numbered data files of its own overloads, so an index can end up naming another process's machine
    code, and loading it crashes (numba issues #4807, #10128).  It happened here: two test workers and three runs
    compiling on a cold cache left a loop whose next load segfaulted.  ``polydem batch -j 2``, ``make test``'s two
    workers and several runs started together all compile at once on a fresh checkout.  So each compilation of a
    function (the cache's load, the compile, its save) holds an exclusive ``flock`` on that function's lock file
    (:func:`lock_path`); a process that wants the same function waits, then loads what the first saved (no more
    than compiling it again would cost), one that wants another function does not wait.  A callee compiled inside
    takes its own lock (the call graph has no cycles: no deadlock); a lock already held by this thread is not taken
    again.  Where no lock file can be made (the cache folder removed under a running process) the compile goes on
    unlocked, as Numba's own.  Calls of already compiled code never reach this.  Installed once per process, by
    :func:`configure`."""
    import fcntl

    from numba.core import dispatcher

    D = dispatcher.Dispatcher
    if getattr(D.compile, "polydem_lock", None) is not None:
        D.compile.polydem_lock[0] = cache_dir
        return
    plain = D.compile
    where = [cache_dir]

    def compile(self, sig):
        if type(self._cache).__name__ == "NullCache":  # not cached: nothing shared to protect
            return plain(self, sig)
        held = _LOCAL.__dict__.setdefault("held", set())
        path = lock_path(where[0], self.py_func)
        if path in held:  # this thread holds it (a recursive compile of the same function)
            return plain(self, sig)
        try:
            os.makedirs(os.path.dirname(path), exist_ok=True)
            fd = os.open(path, os.O_RDWR | os.O_CREAT, 0o644)
        except OSError:
            return plain(self, sig)
        try:
            fcntl.flock(fd, fcntl.LOCK_EX)
            held.add(path)
            try:
                return plain(self, sig)
            finally:
                held.discard(path)
        finally:
            os.close(fd)  # releases the lock

    compile.polydem_lock = where
    compile.__doc__ = plain.__doc__
    D.compile = compile


def configure() -> str | None:
    """Point Numba's cache at polydem's folder (the module's docstring) and lock it against concurrent compiles
    (:func:`lock_compiles`); returns the folder."""
    if os.environ.get("NUMBA_CACHE_DIR"):
        if _writable(Path(os.environ["NUMBA_CACHE_DIR"])):
            lock_compiles(os.environ["NUMBA_CACHE_DIR"])
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
            lock_compiles(str(d))
            return str(d)
    return None


def loop_cached() -> bool:
    """True if the compiled time loop (engine/kernels.py ``run_steps``) is in the cache directory.

    Numba names its index files ``<module>.<function>-<line>.py<ver>.nbi`` inside a folder per package
    directory; their presence says that a run will load the loop instead of compiling it (a few minutes
    on a cold cache), which the explicit solver family (solvers/explicit.py) tells the user before the silent wait."""
    return cached("engine*/kernels.run_steps-*.nbi")


def cached(pattern: str) -> bool:
    """True if Numba's cache directory holds an index file matching ``pattern`` (``<package folder>*/<module>.
    <function>-*.nbi``): the function will be loaded, not compiled."""
    d = os.environ.get("NUMBA_CACHE_DIR")
    if not d or not Path(d).is_dir():
        return False
    return any(Path(d).glob(pattern))
