"""The scene ``polydem run --ranks N`` built before it started the ranks, handed to rank 0 instead of built again.

The launcher (cli/run.py) builds the whole scene to check that it can be cut for N ranks (``--ranks auto``: to choose
N). Building it again on rank 0 took as long again (39 s of rank 0's 44 s start-up for 10⁵ bonded cells on this
machine, about 6 min at 10⁶) and peaked at the build's transient memory (about 9 kB per particle, several times the
built scene). So the launcher writes the built scene to a temporary file — a header line, the key line, then the
pickled scene, about 1.1 kB per particle — and names it in ``$POLYDEM_SCENE``; rank 0 of the ranks it started reads it
back when it is the scene of the same scenario (its canonical digest and file name) and deletes it. Anything else —
no file, another scenario, a file that is not one, a run not started by ``polydem run --ranks`` — and rank 0 builds
the scene itself, as a run under a cluster's launcher always does. The scene is the same either way: the build is
deterministic, and a pickle keeps every array bit for bit (tests/test_handover.py).

Nothing is unpickled before the file has shown itself to be a hand-over of this scene: a regular file of this user,
readable by no one else, whose first line is :data:`MAGIC` and whose second is the key.
"""

from __future__ import annotations

import json
import os
import pickle
import stat
import tempfile

#: the environment variable naming the file the launcher wrote
ENV = "POLYDEM_SCENE"
#: the variable polydem's launcher sets for the ranks it starts (cli/run.py ``_launch``): only they take a scene
LAUNCHED = "POLYDEM_RANK_PIDS"
MAGIC = b"polydem scene hand-over 1\n"


def _key(resolved: dict, file) -> bytes:
    from ..io.provenance import scenario_digest

    return json.dumps({"scenario_digest": scenario_digest(resolved), "file": str(file)}).encode() + b"\n"


def hand_over(system, resolved: dict, file) -> str:
    """Write ``system`` (built from ``resolved``, read from ``file``) to a new temporary file (mode 0600); its path."""
    fd, path = tempfile.mkstemp(prefix="polydem-scene-", suffix=".pickle")
    try:
        with os.fdopen(fd, "wb") as f:
            f.write(MAGIC)
            f.write(_key(resolved, file))
            pickle.dump(system, f, protocol=pickle.HIGHEST_PROTOCOL)
    except BaseException:
        discard(path)
        raise
    return path


def take(resolved: dict, file):
    """The scene handed over in ``$POLYDEM_SCENE`` if this process is a rank polydem's launcher started and the scene
    was built from ``resolved`` and ``file``, else None.  The variable is cleared, and a hand-over file deleted once
    its header is read, taken or not: a scene is taken once.  Any other file is left alone and nothing of it
    unpickled."""
    path = os.environ.pop(ENV, None)
    if not path or not os.environ.get(LAUNCHED):
        return None
    try:
        st = os.stat(path)  # before opening: a FIFO would block the open
        if not stat.S_ISREG(st.st_mode) or st.st_uid != os.getuid() or st.st_mode & 0o077:
            return None
        with open(path, "rb") as f:
            if f.read(len(MAGIC)) != MAGIC:
                return None
            try:
                if f.readline(4096) != _key(resolved, file):
                    return None
                return pickle.load(f)
            finally:
                discard(path)
    except Exception:  # noqa: BLE001 - an unreadable or truncated hand-over: the scene is built instead
        return None


def discard(path) -> None:
    """Delete a hand-over (or the launcher's other temporary) file if it is still there."""
    try:
        os.unlink(path)
    except OSError:
        pass
