"""HDF5 result files: layout, writer process, reader.

Layout (``format = "polydem-result"``, ``format_version = 1``; units cm, g, s)::

    /                         attrs: format, format_version, code_version, created, scenario_file,
                                     scenario_text, resolved (JSON of the validated scenario with
                                     defaults), overrides (JSON list), seed, units, status
                                     ("running" | "finished" | "failed"), summary (JSON, at the end),
                                     segments (JSON: the provenance of each session — ranks, cores,
                                     threads, the steps it began and ended at, how it ended;
                                     io/provenance.py ``session``, solvers/driver.py),
                                     snapshot_of (only in a snapshot of a running result: its path)
    /particles/group          (n,)   int   group index (attr names: JSON list of group names)
    /particles/vertex_start   (n+1,) int   CSR offsets into body_vertices
    /particles/body_vertices  (nv,2) float vertices relative to the centroid (φ = 0), counter-clockwise
    /particles/{mass, inertia, area, radius, thickness}  (n,)
    /particles/x0             (n,3)  float initial (x1, x2, φ)
    /sets/<name>              int    particle indices of each named set
    /frames/step, /frames/time          (F,)
    /frames/x, /frames/v                (F, n, 3)  generalised positions (x1, x2, φ) and velocities
    /bonds/{pairs (nb,2), L, H, T, E, nu, kappa_0, kappa_m, eps0_dot, alpha, edges (nb,2,2)}  (with bonds)
    /frames/bond_d, bond_kappa (F, nb); bond_strain (F, nb, 4): ε_ax,M, |ϰ_M| H_h/2, |γ_M|, ε_v
    /bonds/fail_step (nb,) int  step at which each bond failed (-1: not failed; -2: unknown, old run)
    /bonds/fail_strain (nb, 3)  ε_ax,M, |ϰ_M| H_h/2, |γ_M| at failure (written with every checkpoint); with
        edge interfaces: the elements' mean opening / L_h, 0, their mean |slip| / L_h
    /bonds/{interface (1,) int: elements per edge, k_n, k_s, f_t, cohesion, friction, residual_friction, G_I, G_II,
        compressive_cap} (nb,) each, cgs: only with [bonds] model = "interface" (interactions/bonds/interface.py);
        bond_d is then the mean damage of a bond's elements, bond_kappa their largest strength ratio r (or σ_I/f_p);
        /bonds/crack_strength (nb,) f_p only with crack_criterion = "principal"
    /frames/bond_element_d (F, nb, n_e)  the damage of each interface element (model = "interface")
    /history/table            (R, C) float; attrs columns, units, descriptions (JSON lists)
    /checkpoint/slot0, slot1  complete engine state (Nordsieck arrays, contact history, energy
                              accumulators) plus frames_count, history_count, wall_elapsed
    /checkpoint/current       (1,) int  slot holding the latest complete checkpoint (-1: none)

Integrity.  Every non-empty dataset is chunked with HDF5's Fletcher-32 checksum (root attr
``checksums = "fletcher32"``): a damaged block fails its checksum when read and is reported as
corruption (``check_intact``; ``polydem report`` and ``--resume`` refuse with the damaged datasets
named), a truncated file as truncation.  A checkpoint slot that fails its checksums is skipped for the
older slot; a run is never resumed from a corrupt checkpoint.

Crash safety.  The simulation process never touches the file while running: it
streams length-prefixed messages to a separate writer process (its own
session, so a kill of the simulation — SIGKILL included — or Ctrl-C does not
reach it).  The writer applies every complete message and flushes; at end of
input it closes the file cleanly.  Checkpoints alternate between two slots and
``/checkpoint/current`` is switched only after a slot is complete.  A resumed
run truncates frames and history to the counts stored with the checkpoint and
recomputes them bit for bit.

One writer per result.  A run holds an exclusive lock (``flock``) on ``<result>.lock`` from before it
touches the result until its writer process has closed the file; the writer inherits the lock, so
it stays held while a killed run's writer finishes its last message.  A second run, ``--overwrite``
or ``--resume`` on a locked result is refused (exit 2) naming the holding process, and readers are
refused while it is held.  A reader of a running result asks its writer for a snapshot instead
(:func:`request_snapshot`: a copy without the checkpoints, root attribute ``snapshot_of``, taken between
two messages so frames, history and bonds agree); ``polydem report`` does so.  The kernel releases the lock when the holders die, so a killed run leaves
no stale lock (the empty ``.lock`` file may stay; it means nothing without a holder).
"""

from __future__ import annotations

import json
import os
import pickle
import re
import struct
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

from ..errors import PolydemError

FORMAT = "polydem-result"
FORMAT_VERSION = 1
_HDR = struct.Struct("<Q")


class ResultError(PolydemError, RuntimeError):
    """A result file that cannot be used as asked: not a polydem result, damaged, held by another run, or one a run
    will not touch (:class:`..solvers.driver.Refused`)."""


# ====================================================================== one writer per result
_HELD: dict = {}  # absolute result path -> [lock fd, depth] held by this process


def lock_path(path) -> Path:
    """The lock file beside a result (``<result>.lock``)."""
    return Path(str(path) + ".lock")


def held_lock_fd(path):
    """The fd of this process's lock on ``path`` (None if not held here)."""
    h = _HELD.get(str(Path(path).absolute()))
    return h[0] if h else None


def _holder_text(fd: int) -> str:
    """The holder's description written into an open lock file."""
    try:
        os.lseek(fd, 0, os.SEEK_SET)
        return os.read(fd, 400).decode(errors="replace").strip() or "unknown process"
    except OSError:
        return "unknown process"


def _acquire(path) -> int:
    import fcntl
    import socket

    lp = lock_path(path)
    made = []  # folders made for the lock: removed again if the run writes nothing (result_lock.__exit__)
    d = lp.parent.absolute()
    while not d.exists() and d != d.parent:
        made.append(d)
        d = d.parent
    lp.parent.mkdir(parents=True, exist_ok=True)
    for _ in range(10):
        fd = os.open(lp, os.O_RDWR | os.O_CREAT, 0o644)
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError:
            who = _holder_text(fd)
            os.close(fd)
            raise ResultError(
                f"{path}: another polydem run is writing this result ({who}); wait for it to end "
                f"or choose another output path"
            ) from None
        try:  # a releasing holder may have removed the file between our open and our lock
            same = os.stat(lp).st_ino == os.fstat(fd).st_ino
        except FileNotFoundError:
            same = False
        if same:
            os.ftruncate(fd, 0)
            os.write(
                fd,
                f"process {os.getpid()} on {socket.gethostname()}, since {time.strftime('%Y-%m-%d %H:%M:%S')}".encode(),
            )
            return fd, made
        os.close(fd)
    raise ResultError(f"{path}: could not take the lock {lp} (it keeps being replaced)")


class result_lock:
    """Context manager: the exclusive right to write ``path`` (re-entrant within a process)."""

    def __init__(self, path):
        self.path = Path(path)
        self.key = str(self.path.absolute())

    def __enter__(self):
        if self.key in _HELD:
            _HELD[self.key][1] += 1
        else:
            fd, self.made = _acquire(self.path)
            _HELD[self.key] = [fd, 1]
        return self

    def __exit__(self, *exc):
        h = _HELD[self.key]
        h[1] -= 1
        if h[1] == 0:
            del _HELD[self.key]
            try:
                os.unlink(lock_path(self.path))
            except OSError:
                pass
            os.close(h[0])
            for d in getattr(self, "made", []):  # innermost first; only if still empty (nothing written)
                try:
                    d.rmdir()
                except OSError:
                    break
        return False


def lock_holder(path) -> str | None:
    """Who holds the write lock of ``path`` if another process does (None: nobody, or this process)."""
    import fcntl

    if held_lock_fd(path) is not None:
        return None
    try:
        fd = os.open(lock_path(path), os.O_RDONLY)
    except OSError:
        return None
    try:
        fcntl.flock(fd, fcntl.LOCK_SH | fcntl.LOCK_NB)
        fcntl.flock(fd, fcntl.LOCK_UN)
        return None
    except OSError:
        return _holder_text(fd)
    finally:
        os.close(fd)


# ====================================================================== writer (child side)
def _ds(group, name, **kw):
    """create_dataset with HDF5's Fletcher-32 checksum on every chunk (chunked storage; empty arrays
    cannot be chunked and are stored plain), so that a damaged block is detected when read."""
    data = kw.get("data")
    shape = kw.get("shape", None if data is None else np.shape(data))
    if data is not None and np.size(data) == 0 and kw.get("maxshape") is None:
        return group.create_dataset(name, **kw)
    if kw.get("chunks") is None:
        kw["chunks"] = True
    if shape is not None and len(shape) == 0:
        return group.create_dataset(name, **{k: v for k, v in kw.items() if k != "chunks"})
    return group.create_dataset(name, fletcher32=True, **kw)


class _FileWriter:
    def __init__(self, path):
        self.path = path
        self.f = None

    def handle(self, op, arg):
        getattr(self, "op_" + op)(**arg)
        if self.f is not None:
            self.f.flush()

    def op_new(self, attrs):
        """A new result file of any solver family: its root attributes, status "running", checksums on every
        dataset written through :func:`_ds`, and an empty checkpoint store."""
        import h5py

        self.f = h5py.File(self.path, "w")
        f = self.f
        for k, v in attrs.items():
            f.attrs[k] = v
        f.attrs["status"] = "running"
        f.attrs["checksums"] = "fletcher32"  # on every dataset (except empty ones)
        ck = f.create_group("checkpoint")
        _ds(ck, "current", data=np.array([-1], np.int64))

    def op_group(self, path, data, attrs=None):
        """A group of static arrays (``data``: name -> array), created if missing, with ``attrs``."""
        g = self.f.require_group(path)
        for k, v in data.items():
            _ds(g, k, data=v)
        for k, v in (attrs or {}).items():
            g.attrs[k] = v

    def op_table(self, ncols, attrs, chunk_rows=None):
        """An empty /history/table of ``ncols`` columns that ``history`` messages extend."""
        C = int(ncols)
        rows = chunk_rows or max(1, min(4096, 65536 // max(C, 1)))
        t = _ds(
            self.f.require_group("history"), "table", shape=(0, C), maxshape=(None, C), dtype="f8", chunks=(rows, C)
        )
        for k, v in attrs.items():
            t.attrs[k] = v

    def op_put(self, path, data):
        """Replace one dataset (e.g. /damage/tooth with every checkpoint)."""
        grp, _, name = path.rpartition("/")
        g = self.f.require_group(grp) if grp else self.f
        if name in g:
            del g[name]
        _ds(g, name, data=data)

    def op_create(self, attrs, particles, sets, columns, n, velocities=True, statics=None, frame_fields=None):
        """The layout of an explicit (time-integration) result: particles, sets, frames, history, and what the
        interaction families add (``Family.static``, ``Family.frame_layout``): ``statics`` {group: {dataset:
        array}} (e.g. /bonds), ``frame_fields`` {name: (shape of one frame, column names or None)}."""
        self.op_new(attrs)
        f = self.f
        g = f.create_group("particles")
        for k, v in particles.items():
            if k != "group_names":
                _ds(g, k, data=v)
        g["group"].attrs["names"] = json.dumps(particles["group_names"])
        s = f.create_group("sets")
        for k, v in sets.items():
            _ds(s, k.replace("/", "|"), data=np.asarray(v, np.int64))
        fr = f.create_group("frames")
        _ds(fr, "step", shape=(0,), maxshape=(None,), dtype="i8", chunks=(1024,))
        _ds(fr, "time", shape=(0,), maxshape=(None,), dtype="f8", chunks=(1024,))
        ch = (1, max(n, 1), 3)
        _ds(fr, "x", shape=(0, n, 3), maxshape=(None, n, 3), dtype="f8", chunks=ch)
        if velocities:
            _ds(fr, "v", shape=(0, n, 3), maxshape=(None, n, 3), dtype="f8", chunks=ch)
        for name, records in (statics or {}).items():
            g = f.create_group(name)
            for k, v in records.items():
                _ds(g, k, data=v)
        for name, (shape, cols) in (frame_fields or {}).items():
            shape = tuple(shape)
            chunks = (1, max(shape[0], 1)) + shape[1:] if shape else (1024,)
            _ds(fr, name, shape=(0,) + shape, maxshape=(None,) + shape, dtype="f8", chunks=chunks)
            if cols is not None:
                fr[name].attrs["columns"] = json.dumps(cols)
        h = f.create_group("history")
        C = len(columns)
        t = _ds(
            h, "table", shape=(0, C), maxshape=(None, C), dtype="f8", chunks=(max(1, min(4096, 65536 // max(C, 1))), C)
        )
        t.attrs["columns"] = json.dumps([c[0] for c in columns])
        t.attrs["units"] = json.dumps([c[1] for c in columns])
        t.attrs["descriptions"] = json.dumps([c[2] for c in columns])

    def op_open(self, history_keep, frames_keep=None, trim=None):
        """Reopen a result to resume it: frames (if the result has them) and history cut to the counts of the
        checkpoint; ``trim``: {group: count} deletes the children named by a number >= count (quasi-static
        /stages/NNNN)."""
        import h5py

        self.f = h5py.File(self.path, "r+")
        f = self.f
        if frames_keep is not None:
            for d in f["frames"].values():
                d.resize(frames_keep, axis=0)
        f["history/table"].resize(history_keep, axis=0)
        for grp, keep in (trim or {}).items():
            for name in list(f.get(grp, {})):
                if int(name) >= keep:
                    del f[grp][name]
        f.attrs["status"] = "running"

    def op_frame(self, step, time, x, v, **extra):
        fr = self.f["frames"]
        k = fr["step"].shape[0]
        for name, val in [("step", step), ("time", time), ("x", x), ("v", v)] + list(extra.items()):
            if name not in fr:
                continue
            d = fr[name]
            d.resize(k + 1, axis=0)
            d[k] = val

    def op_history(self, rows):
        d = self.f["history/table"]
        k = d.shape[0]
        d.resize(k + len(rows), axis=0)
        d[k:] = rows

    def op_checkpoint(self, state, wall_elapsed, **counts):
        """The run's state into the slot that is not current, then the pointer switched to it; ``counts``
        (frames_count, history_count, stage_count, …): the rows of each table the state belongs to."""
        ck = self.f["checkpoint"]
        cur = int(ck["current"][0])
        slot = "slot1" if cur == 0 else "slot0"
        g = ck.require_group(slot)
        data = dict(state)
        for k, v in counts.items():
            data[k] = np.array([v], np.int64)
        data["wall_elapsed"] = np.array([wall_elapsed])
        for k in list(g):  # a field this state lacks (an optional one, e.g. a factor's) must not outlive its slot
            if k not in data:
                del g[k]
        for k, v in data.items():
            v = np.asarray(v)
            if k in g and g[k].shape[1:] == v.shape[1:] and g[k].dtype == v.dtype:
                g[k].resize(v.shape[0], axis=0)
                g[k][...] = v
            else:
                if k in g:
                    del g[k]
                _ds(g, k, data=v, maxshape=(None,) + v.shape[1:])
        self.f.flush()
        ck["current"][0] = 0 if slot == "slot0" else 1

    def op_bond_failure(self, step, strain):
        """Per bond: step of failure (-1 not failed) and the parts of (5.8) at failure."""
        g = self.f["bonds"]
        for name, v in (("fail_step", step), ("fail_strain", strain)):
            if name in g:
                g[name][...] = v
            else:
                _ds(g, name, data=v)
        g["fail_strain"].attrs["columns"] = json.dumps(["eps_ax_M", "abs_kappa_M_H_half", "abs_gamma_M"])

    def op_attrs(self, attrs):
        for k, v in attrs.items():
            self.f.attrs[k] = v

    def snapshot(self, dest):
        """Copy the result as it stands (between two messages, so frames, history and bonds agree) to
        ``dest`` for a reader of the running simulation (:func:`request_snapshot`): every group but the
        checkpoints, root attributes plus ``snapshot_of``; written to a temporary name and renamed, so a
        reader never sees a half-written snapshot."""
        import h5py

        dest = Path(dest)
        tmp = dest.with_name(dest.name + f".tmp{os.getpid()}")
        try:
            with h5py.File(tmp, "w") as g:
                for k, v in self.f.attrs.items():
                    g.attrs[k] = v
                g.attrs["snapshot_of"] = str(Path(self.path).resolve())
                for name in self.f:
                    if name != "checkpoint":
                        self.f.copy(self.f[name], g, name=name)
            os.replace(tmp, dest)
        finally:
            if tmp.exists():
                tmp.unlink()

    def close(self):
        if self.f is not None:
            self.f.close()
            self.f = None


def _read_exact(stream, n):
    """``n`` bytes from ``stream`` into a new bytearray, or None at the end of input before them."""
    buf = bytearray(n)
    view, got = memoryview(buf), 0
    while got < n:
        k = stream.readinto(view[got:])
        if not k:
            return None
        got += k
    return buf


def _read_message(stream):
    """One message of :meth:`ResultWriter.send` — ``(op, arg)`` — or None at the end of input (also mid-message: the
    sender died)."""
    hdr = _read_exact(stream, 2 * _HDR.size)
    if hdr is None:
        return None
    size, nbuf = struct.unpack("<QQ", hdr)
    sizes = _read_exact(stream, nbuf * _HDR.size) if nbuf else b""
    body = _read_exact(stream, size)
    if sizes is None or body is None:
        return None
    bufs = []
    for (n,) in struct.iter_unpack("<Q", sizes):
        b = _read_exact(stream, n)
        if b is None:
            return None
        bufs.append(b)
    return pickle.loads(body, buffers=bufs)


def writer_main(path):
    """Entry point of the writer process: apply messages from stdin until end of input."""
    w = _FileWriter(path)
    request = _request_path(path)
    inp = sys.stdin.buffer
    code = 0
    try:
        while True:
            msg = _read_message(inp)
            if msg is None:  # the end of input (or the sender died mid-message: that one is dropped)
                break
            op, arg = msg
            if op == "close":
                break
            w.handle(op, arg)
            if w.f is not None and os.path.exists(request):  # a reader asked for the state so far
                try:
                    w.snapshot(Path(request).read_text().strip())
                except Exception as e:  # a failed snapshot must not stop the run's output
                    print(f"polydem writer: snapshot for a reader failed: {type(e).__name__}: {e}", file=sys.stderr)
                finally:
                    try:
                        os.unlink(request)
                    except OSError:
                        pass
    except Exception as e:  # report and keep what is written
        print(f"polydem writer: {type(e).__name__}: {e}", file=sys.stderr)
        code = 1
    finally:
        w.close()
        try:
            os.unlink(str(path) + ".writer")
        except OSError:
            pass
    sys.exit(code)


# ====================================================================== writer (parent side)
class ResultWriter:
    """Sends output to the writer process.  ``mode``: 'create' or 'resume'."""

    def __init__(self, path):
        self.path = Path(path)
        self.path.parent.mkdir(parents=True, exist_ok=True)
        marker = Path(str(self.path) + ".writer")
        lock = held_lock_fd(self.path)  # the writer keeps the result's lock until it has closed the file
        self.proc = subprocess.Popen(
            [sys.executable, "-m", "polydem_cli.io.writer_proc", str(self.path)],
            stdin=subprocess.PIPE,
            start_new_session=True,
            pass_fds=(lock,) if lock is not None else (),
        )
        marker.write_text(f"{self.proc.pid} {os.getpid()}")  # writer, simulation

    def send(self, op, **arg):
        """One message to the writer process: its length and the lengths of its array buffers, the pickled
        ``(op, arg)`` without the arrays' data (pickle protocol 5, out of band), then each array's bytes written from
        the array itself — a frame or a checkpoint is not copied on this side (a copy of the whole state on rank 0 of a
        decomposed run, or of a serial run, while it was sent)."""
        bufs = []
        body = pickle.dumps((op, arg), protocol=5, buffer_callback=bufs.append)
        raws = [b.raw() for b in bufs]
        head = struct.pack(f"<QQ{len(raws)}Q", len(body), len(raws), *(r.nbytes for r in raws))
        try:
            out = self.proc.stdin
            out.write(head)
            out.write(body)
            for r in raws:
                out.write(r)
            out.flush()
        except BrokenPipeError:
            raise ResultError(f"{self.path}: the result writer stopped (see its message above)") from None

    def close(self, timeout=600.0):
        try:
            self.send("close")
        except ResultError:
            pass
        try:
            self.proc.stdin.close()
        except BrokenPipeError:
            pass
        code = self.proc.wait(timeout)
        if code != 0:
            raise ResultError(f"{self.path}: the result writer failed (exit code {code})")


def writer_pid(path) -> int | None:
    """PID of the simulation writing ``path`` if that run is still in progress, else None."""
    marker = Path(str(path) + ".writer")
    try:
        pids = [int(x) for x in marker.read_text().split()]
        for pid in pids:
            os.kill(pid, 0)
    except (OSError, ValueError):
        return None
    return pids[-1] if pids else None


def wait_for_writer(path, timeout=60.0):
    """Wait until no writer process holds ``path`` (after a killed run it finishes its last message)."""
    marker = Path(str(path) + ".writer")
    t0 = time.time()
    while marker.exists() and time.time() - t0 < timeout:
        try:
            pid = int((marker.read_text() or "0").split()[0])
            os.kill(pid, 0)
        except (ValueError, IndexError, ProcessLookupError, PermissionError):
            try:
                marker.unlink()
            except OSError:
                pass
            break
        time.sleep(0.05)


# ====================================================================== a running result
def _request_path(path) -> Path:
    return Path(str(path) + ".snapshot-request")


def request_snapshot(path, dest, timeout=120.0) -> bool:
    """Have the writer of a running simulation copy the result as it stands to ``dest``, for reading while
    the run goes on (the result itself is refused to readers until the run has ended).

    Leaves a request (``<result>.snapshot-request``, holding ``dest``) beside the result; the run's writer
    process answers it after its next message (a run sends history rows about every 0.5 s of wall time)
    with :meth:`_FileWriter.snapshot`.  Returns True when ``dest`` holds the copy, False when the run ended
    meanwhile (then read the result itself).  ResultError when the writer does not answer within
    ``timeout`` seconds (a run started by an older polydem, or one still compiling its kernels)."""
    p = Path(path)
    dest = Path(dest).resolve()
    req = _request_path(p)
    tmp = req.with_name(req.name + f".{os.getpid()}")
    tmp.write_text(str(dest))
    os.replace(tmp, req)  # the writer never reads a half-written request
    t0 = time.time()
    try:
        while time.time() - t0 < timeout:
            if not req.exists():  # answered (or withdrawn by the writer after a failed snapshot)
                return dest.exists()
            if writer_pid(p) is None:
                return False
            time.sleep(0.05)
    finally:
        try:
            req.unlink()
        except OSError:
            pass
    raise ResultError(
        f"{p}: still being written by a running simulation (process {writer_pid(p)}), which did not answer a "
        f"request for a snapshot within {timeout:.0f} s (a run started by an older polydem, or one still "
        "compiling); read it when the run has ended"
    )


def readable(path, tmpdir) -> Path:
    """The file a reader should open for the result ``path``: the result itself, or — while a simulation
    still writes it — a snapshot of its state so far, ``tmpdir/<stem>.running.h5`` (:func:`request_snapshot`),
    so that what is derived from it (figures, exports) is named ``<stem>.running*`` and never replaces the
    finished run's."""
    p = Path(path)
    if not p.exists() or writer_pid(p) is None:
        return p
    snap = Path(tmpdir) / f"{p.stem}.running.h5"
    return snap if request_snapshot(p, snap) else p


# ====================================================================== reader
def open_result(path, mode="r", fmt=FORMAT, what="a polydem result file"):
    """Open a result for reading (``fmt``: the ``format`` attribute expected, ``what`` names it in the error):
    refused while another process writes it, with a clear error for a missing, truncated or foreign file."""
    import h5py

    p = Path(path)
    if not p.exists():
        raise ResultError(f"{p}: no such result file")
    if pid := writer_pid(p):
        raise ResultError(
            f"{p}: still being written by a running simulation (process {pid}); read it when the run has ended"
        )
    if who := lock_holder(p):
        raise ResultError(f"{p}: still being written by a running simulation ({who}); read it when the run has ended")
    wait_for_writer(p)
    last = None
    for _ in range(200):
        try:
            f = h5py.File(p, mode)
            break
        except BlockingIOError as e:  # still locked by a finishing writer
            last = e
            time.sleep(0.05)
        except OSError as e:
            msg = str(e)
            if "truncated file" in msg:
                m = re.search(r"eof = (\d+).*stored_eof = (\d+)", msg)
                have = f" ({int(m.group(1)):,} of {int(m.group(2)):,} bytes)" if m else ""
                raise ResultError(
                    f"{p}: the file is truncated{have}: it was cut off (an interrupted copy or "
                    f"a full disk); it cannot be read or resumed"
                ) from None
            if "unable to lock file" in msg.lower() or getattr(e, "errno", None) in (11, 35):
                last = e
                time.sleep(0.05)
                continue
            raise ResultError(_not_hdf5(p) or f"{p}: not a readable HDF5 file ({e})") from None
    else:
        raise ResultError(f"{p}: file is locked by another process ({last})")
    if f.attrs.get("format") != fmt:
        f.close()
        raise ResultError(f"{p}: not {what}")
    return f


def _not_hdf5(p: Path) -> str | None:
    """What a file that HDF5 cannot open is, when it can be told: empty, a scenario (TOML), other text."""
    try:
        with open(p, "rb") as fh:
            head = fh.read(1 << 20)
    except OSError:
        return None
    if not head.strip():
        return f"{p}: file is empty (not a result)"
    if head[:8] == b"\x89HDF\r\n\x1a\n":
        return None  # an HDF5 file after all (damaged): h5py's own message
    try:
        text = head.decode("utf-8")
    except UnicodeDecodeError:
        return None
    import tomllib

    try:
        toml = bool(tomllib.loads(text))
    except tomllib.TOMLDecodeError:
        toml = False
    if toml or p.suffix.lower() == ".toml":
        return f"{p}: a scenario file, not a result: run it with polydem run {p} (it writes the result to report)"
    return f"{p}: not a readable HDF5 file (a text file; results are HDF5 files written by polydem run)"


def _is_corruption(e: Exception) -> bool:
    m = str(e).lower()
    return "fletcher32" in m or "checksum" in m or "data error" in m or "filter returned failure" in m


def read_checkpoint(f, notes=None) -> dict | None:
    """The latest intact checkpoint (None: none written).  A slot whose data fail their checksums is
    skipped for the other, older slot (said in ``notes``, a list, when given); if neither is intact,
    ResultError: a run is never resumed from a corrupt checkpoint."""
    ck = f.get("checkpoint")
    if ck is None:
        return None
    pointer_damaged = False
    try:
        cur = int(ck["current"][0])
    except OSError as e:
        if not _is_corruption(e):
            raise
        cur, pointer_damaged = 0, True  # the pointer itself is damaged: try both slots
    if cur < 0:
        return None
    found, bad = [], []
    for slot in (cur, 1 - cur):
        g = ck.get(f"slot{slot}")
        if g is None:
            continue
        try:
            found.append({k: g[k][...] for k in g} | {"_slot": slot})
        except OSError as e:
            if not _is_corruption(e):
                raise
            bad.append(f"/checkpoint/slot{slot}")
    if not found:
        if bad:
            raise ResultError(
                f"{f.filename}: corrupted checkpoint (checksum mismatch in {' and '.join(bad)}): "
                f"the run cannot be resumed"
            )
        return None
    if len(found) > 1 and pointer_damaged:  # both intact, no pointer: the later state (every family stores "step")
        found.sort(key=lambda c: int(c["step"][0]) if "step" in c else -1, reverse=True)
    best = found[0]
    if best.pop("_slot") != cur and notes is not None:
        notes.append(
            f"{f.filename}: /checkpoint/slot{cur} failed its checksums; using the older checkpoint at "
            f"step {int(best['step'][0]):,}"
        )
    return best


def verify_result(path, skip=(), fmt=FORMAT) -> list:
    """Read every dataset of a result once so that HDF5 checks its Fletcher-32 checksums; returns the
    names of the datasets that fail (empty: intact), leaving out those under the ``skip`` prefixes.
    Truncation is reported by ``open_result``."""
    import h5py

    bad = []
    with open_result(path, fmt=fmt) as f:

        def visit(name, obj):
            if isinstance(obj, h5py.Dataset) and not ("/" + name).startswith(tuple(skip)):
                try:
                    if obj.size:
                        obj[...]
                except OSError as e:
                    if not _is_corruption(e):
                        raise
                    bad.append("/" + name)

        f.visititems(visit)
    return bad


def check_intact(path, skip=(), fmt=FORMAT) -> None:
    """ResultError naming the damaged datasets if any fail their checksums."""
    bad = verify_result(path, skip, fmt)
    if bad:
        raise ResultError(
            f"{path}: corrupted data (checksum mismatch) in {', '.join(bad)}; the file was damaged "
            f"after it was written (disk, copy); its results cannot be trusted"
        )


def read_history(path) -> tuple[list, np.ndarray]:
    """(column names, the history table (rows, columns)) of a result."""
    with open_result(path) as f:
        t = f["history/table"]
        return json.loads(t.attrs["columns"]), t[...]


def read_frames(path):
    """(steps, times, positions (frames, n, 3), velocities or None) of a result's frames."""
    with open_result(path) as f:
        fr = f["frames"]
        return fr["step"][...], fr["time"][...], fr["x"][...], (fr["v"][...] if "v" in fr else None)


def result_groups(path) -> set:
    """The names of a result's top-level groups (particles, frames, history, bonds, …)."""
    with open_result(path) as f:
        return set(f.keys())


def read_bonds(path):
    """Static bond table and per-frame bond fields (None if the result has no bonds)."""
    with open_result(path) as f:
        if "bonds" not in f:
            return None
        d = {k: f["bonds"][k][...] for k in f["bonds"]}
        fr = f["frames"]
        d["frame_d"] = fr["bond_d"][...]
        d["frame_kappa"] = fr["bond_kappa"][...]
        d["frame_strain"] = fr["bond_strain"][...]
        return d


def read_static(path) -> dict:
    """The static particle data of a result (groups, outlines, masses, radii, x0, …) with the group names, the
    named sets and the resolved scenario."""
    with open_result(path) as f:
        g = f["particles"]
        d = {k: g[k][...] for k in g}
        d["group_names"] = json.loads(g["group"].attrs["names"])
        d["sets"] = {k.replace("|", "/"): f["sets"][k][...] for k in f["sets"]}
        d["attrs"] = {k: f.attrs[k] for k in f.attrs}
        return d
