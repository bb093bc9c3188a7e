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

import sys
from contextlib import contextmanager
from pathlib import Path

import click

from ..errors import OutputError
from ..io.places import check_dir, check_file, reason, write_error

EXIT_INPUT = 2


def fail(msg: str, code: int = EXIT_INPUT):
    """``error: <msg>`` on stderr, exit ``code`` (2: bad input or an output place that cannot be written)."""
    click.echo(f"error: {msg}", err=True)
    sys.exit(code)


def writable_file(out: Path, what: str = "the output", example: str = "result.h5") -> None:
    """Exit 2 at once if the file ``out`` cannot be written (io/places.py :func:`check_file`)."""
    try:
        check_file(out, what, example)
    except OutputError as e:
        fail(str(e))


def writable_dir(folder: Path, what: str = "the outputs") -> None:
    """Exit 2 at once if files cannot be written into the folder ``folder`` (io/places.py :func:`check_dir`)."""
    try:
        check_dir(folder, what)
    except OutputError as e:
        fail(str(e))


@contextmanager
def writing(path):
    """Turn an OSError raised inside into ``error: cannot write <file>: <reason>`` (the file the error names, else
    ``path``) and exit 2."""
    try:
        yield
    except OSError as e:
        cannot_write(e, path)


def cannot_write(e: OSError, path) -> None:
    """``error: cannot write <file>: <reason>`` for an OSError while writing ``path`` (io/places.py
    :func:`write_error`); exit 2."""
    fail(str(write_error(e, path)))


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
