"""Where the commands write: every command that writes files checks its output place before any work and turns
an OSError while writing into one line naming the path and the reason (exit code 2), never a traceback.

* :func:`writable_file` / :func:`writable_dir`: exit 2 at once when a file (a result, a JSON, a VTKHDF file) or
  a folder of outputs (figures, a study) cannot be written there — a directory in the way of a file, a file in
  the way of a folder, no permission, a read-only file system.  Nothing is left behind: a probe file is
  created in the nearest existing folder and removed; missing folders are made only when the work starts.
* :func:`writing`: a context manager around the writing that turns an OSError (h5py's too) into the same line.
* :func:`remove_existing`: ``--overwrite`` of a file that cannot be removed.
"""

from __future__ import annotations

import errno
import os
import re
import sys
import tempfile
from contextlib import contextmanager
from pathlib import Path

import click

EXIT_INPUT = 2


def fail(msg: str, code: int = EXIT_INPUT):
    """``error: <msg>`` on stderr, exit ``code`` (2: bad input or an output place that cannot be written)."""
    click.echo(f"error: {msg}", err=True)
    sys.exit(code)


def reason(e: OSError) -> str:
    """'Permission denied', 'Read-only file system', ... of an OSError; h5py puts the C library's text inside
    its own message (``error message = '...'``)."""
    m = re.search(r"error message = '([^']*)'", str(e))
    if m:
        return m.group(1)
    return e.strerror or str(e)


def _filename(e: OSError) -> str | None:
    if e.filename:
        return str(e.filename)
    m = re.search(r"name = '([^']*)'", str(e))  # h5py: "unable to open file: name = '<path>', errno = 13, ..."
    return m.group(1) if m else None


def _nearest_existing(p: Path) -> Path:
    anc = p.absolute()
    while not anc.exists() and anc != anc.parent:
        anc = anc.parent
    return anc


def _probe(path: Path, folder: Path, what: str) -> None:
    try:
        fd, probe = tempfile.mkstemp(prefix=".polydem-probe-", dir=folder)
        os.close(fd)
        os.unlink(probe)
    except OSError as e:
        where = "" if folder == path.absolute() else f" in {folder}"
        why = "files cannot be created" if e.errno == errno.ENOENT else reason(e)  # /proc, /sys
        fail(f"{path}: cannot write {what} there ({why}{where})")


def writable_file(out: Path, what: str = "the output", example: str = "result.h5") -> None:
    """Exit 2 at once if the file ``out`` cannot be written (``what`` names it in the message, ``example`` is a
    file name to suggest when ``out`` is a folder)."""
    out = Path(out)
    if out.is_dir():
        fail(f"{out}: is a directory; give a file name (e.g. {out / example})")
    anc = _nearest_existing(out.parent)
    if not anc.is_dir():
        fail(f"{out}: cannot write {what} there ({anc} is a file, not a folder)")
    _probe(out, anc, what)


def writable_dir(folder: Path, what: str = "the outputs") -> None:
    """Exit 2 at once if files cannot be written into the folder ``folder`` (made later if missing)."""
    folder = Path(folder)
    anc = _nearest_existing(folder)
    if not anc.is_dir():
        where = "it is a file" if anc == folder.absolute() else f"{anc} is a file"
        fail(f"{folder}: cannot write {what} there ({where}, not a folder)")
    _probe(folder, anc, what)


@contextmanager
def writing(path):
    """Turn an OSError raised inside into ``error: cannot write <file>: <reason>`` (the file the error names, else
    ``path``) and exit 2."""
    try:
        yield
    except OSError as e:
        cannot_write(e, path)


def cannot_write(e: OSError, path) -> None:
    """``error: cannot write <file>: <reason>`` for an OSError while writing ``path`` (the file the error names,
    else ``path``); an error that names no file and is not one of writing: ``error: <path>: <reason>``; exit 2."""
    name = _filename(e)
    if name is None and e.errno not in _WRITE_ERRNOS:
        fail(f"{path}: {reason(e)}")
    fail(f"cannot write {name or path}: {reason(e)}")


_WRITE_ERRNOS = {errno.ENOSPC, errno.EDQUOT, errno.EROFS, errno.EACCES, errno.EPERM, errno.EFBIG}


def remove_existing(out: Path, what: str = "the existing result") -> None:
    """``--overwrite``: remove ``out`` (exit 2 with the reason if it cannot be removed)."""
    try:
        Path(out).unlink()
    except FileNotFoundError:
        pass
    except OSError as e:
        fail(f"{out}: cannot remove {what} ({reason(e)}); nothing was run")


class Stopped(Exception):
    """SIGINT (Ctrl-C) or SIGTERM inside :func:`stop_on_signals`; ``signum`` is the signal number."""

    def __init__(self, signum: int):
        super().__init__(signum)
        self.signum = int(signum)


@contextmanager
def stop_on_signals():
    """SIGINT and SIGTERM raise :class:`Stopped` inside (KeyboardInterrupt for SIGINT outside the main thread),
    so that a command can say what it wrote before it stopped; exit code 128 + signum (as ``polydem run``)."""
    import signal
    import threading

    if threading.current_thread() is not threading.main_thread():
        yield
        return

    def stop(signum, frame):
        raise Stopped(signum)

    old = {s: signal.signal(s, stop) for s in (signal.SIGINT, signal.SIGTERM)}
    try:
        yield
    finally:
        for s, h in old.items():
            signal.signal(s, h)


def listing(folders) -> dict:
    """{file: (inode, size, mtime)} of the files directly in ``folders`` (missing folders: none): compared
    before and after a command to tell which files it wrote."""
    out = {}
    for d in folders:
        try:
            for p in Path(d).iterdir():
                if p.is_file() and not p.name.startswith("."):
                    st = p.stat()
                    out[p] = (st.st_ino, st.st_size, st.st_mtime_ns)
        except OSError:
            pass
    return out
