"""The compile locks of polydem_cli/_jit_cache.py: a process compiles a function into the shared Numba cache only while it
holds that function's lock, so that two processes never write the same function's index and data files at once (numba issues
#4807, #10128: a run then loads another process's machine code and crashes)."""

import fcntl
import os
import subprocess
import sys
import textwrap
import time
from pathlib import Path
from types import SimpleNamespace

from polydem_cli._jit_cache import lock_path

COMPILER = textwrap.dedent(
    """
    import os, sys
    sys.path.insert(0, sys.argv[1])
    from polydem_cli._jit_cache import configure
    configure()  # NUMBA_CACHE_DIR is set by the test: the lock goes on it
    import kern
    assert kern.twice(2.0) == 4.0
    open(sys.argv[2], "w").write("done")
    """
)


def test_a_compile_waits_for_the_lock_and_then_runs(tmp_path):
    """While another process holds the function's lock, a compiling process does not get past its compile; once
    the lock is released it finishes (mutation: lock_compiles returning at once -> the compile finishes in 2-3 s and
    the test fails)."""
    cache = tmp_path / "cache"
    cache.mkdir()
    (tmp_path / "kern.py").write_text(
        "from numba import njit\n\n@njit(cache=True)\ndef twice(x):\n    return 2.0 * x\n"
    )
    script = tmp_path / "compile.py"
    script.write_text(COMPILER)
    done = tmp_path / "done"
    env = dict(os.environ, NUMBA_CACHE_DIR=str(cache))
    # the lock of kern.twice (the module's name and the function's: what lock_path keys on)
    lock = Path(lock_path(str(cache), SimpleNamespace(__module__="kern", __qualname__="twice")))
    lock.parent.mkdir(parents=True)
    fd = os.open(lock, os.O_RDWR | os.O_CREAT, 0o644)
    fcntl.flock(fd, fcntl.LOCK_EX)
    try:
        p = subprocess.Popen([sys.executable, str(script), str(tmp_path), str(done)], env=env)
        waited = 0.0
        while waited < 10.0 and p.poll() is None:  # a process that ignores the lock compiles this in 2-3 s
            time.sleep(0.5)
            waited += 0.5
        assert p.poll() is None and not done.exists(), "the compile went ahead while another process held the lock"
    finally:
        os.close(fd)  # releases the lock
    assert p.wait(timeout=300) == 0 and done.read_text() == "done"
    # the second process loads from the cache the first one saved (index and data written once)
    assert list(cache.rglob("*.nbi")) and list(cache.rglob("*.nbc"))
