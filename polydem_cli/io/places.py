"""Where polydem writes: the checks every writer (the ``polydem`` commands, the Python API) makes before any work,
and the message an OSError while writing becomes.  Each raises :class:`~polydem_cli.errors.OutputError` with the
path and the reason; the command line prints it and exits 2 (cli/outputs.py).

* :func:`check_file` / :func:`check_dir`: a file (a result, a JSON, a VTKHDF file) or a folder of outputs cannot
  be written there — a directory in the way of a file, a file in the way of a folder, no permission, a read-only
  file system.  Nothing is left behind: a probe file is created in the nearest existing folder and removed;
  missing folders are made only when the work starts.
* :func:`write_error`: the OutputError of an OSError (h5py's too) raised while writing.
"""

from __future__ import annotations

import errno
import os
import re
import tempfile
from pathlib import Path

from ..errors import OutputError


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
        raise OutputError(f"{path}: cannot write {what} there ({why}{where})") from None


def check_file(out, what: str = "the output", example: str = "result.h5") -> None:
    """OutputError if the file ``out`` cannot be written (``what`` names it in the message, ``example`` is a file
    name to suggest when ``out`` is a folder)."""
    out = Path(out)
    if out.is_dir():
        raise OutputError(f"{out}: is a directory; give a file name (e.g. {out / example})")
    anc = _nearest_existing(out.parent)
    if not anc.is_dir():
        raise OutputError(f"{out}: cannot write {what} there ({anc} is a file, not a folder)")
    _probe(out, anc, what)


def check_dir(folder, what: str = "the outputs") -> None:
    """OutputError if files cannot be written into the folder ``folder`` (made later if missing)."""
    folder = Path(folder)
    anc = _nearest_existing(folder)
    if not anc.is_dir():
        where = "it is a file" if anc == folder.absolute() else f"{anc} is a file"
        raise OutputError(f"{folder}: cannot write {what} there ({where}, not a folder)")
    _probe(folder, anc, what)


#: errno values of a write that failed for want of room or permission
WRITE_ERRNOS = {errno.ENOSPC, errno.EDQUOT, errno.EROFS, errno.EACCES, errno.EPERM, errno.EFBIG}


def write_error(e: OSError, path) -> OutputError:
    """``cannot write <file>: <reason>`` for an OSError while writing ``path`` (the file the error names, else
    ``path``); an error that names no file and is not one of writing: ``<path>: <reason>``."""
    name = _filename(e)
    if name is None and e.errno not in WRITE_ERRNOS:
        return OutputError(f"{path}: {reason(e)}")
    return OutputError(f"cannot write {name or path}: {reason(e)}")
