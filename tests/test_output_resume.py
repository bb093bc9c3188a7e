"""HDF5 result layout, summary, checkpoints, kill and resume (issue 2 items 6-8)."""

import json
import signal
import subprocess
import time

import h5py
import numpy as np
import pytest

from polydem_cli.io.hdf5 import open_result, read_checkpoint, read_frames, read_history, read_static
from polydem_cli.scenario.build import build_system
from polydem_cli.scenario.load import load_scenario
from polydem_cli.solvers.explicit import run

from conftest import SCEN, polydem_cmd

DEMO = SCEN / "demo_hex_pile.toml"


def _system(overrides=()):
    sc, text = load_scenario(DEMO, overrides)
    return build_system(sc, str(DEMO)), text


def test_result_layout_and_summary(tmp_path):
    system, text = _system(["time.end_displacement=0.05"])
    out = tmp_path / "r.h5"
    summary = run(system, out=out, scenario_file=str(DEMO), scenario_text=text, quiet=True)
    with h5py.File(out, "r") as f:
        assert f.attrs["format"] == "polydem-result" and f.attrs["format_version"] == 1
        assert f.attrs["status"] == "finished"
        assert "[[particles]]" in f.attrs["scenario_text"]
        resolved = json.loads(f.attrs["resolved"])
        assert resolved["time"]["end_displacement"] == 0.05  # override recorded in the resolved scenario
        assert resolved["output"]["history_every"] == 20  # defaults filled in
        assert f["frames/x"].shape[1:] == (system.n, 3)
        assert f["frames/x"].shape[0] == len(system.frame_steps) == f["frames/time"].shape[0]
        cols = json.loads(f["history/table"].attrs["columns"])
        assert cols[:3] == ["time", "step", "kinetic"] and "f2:top_plate" in cols and "u2:top_plate" in cols
        assert f["history/table"].shape == (system.end_step // 20 + 1, len(cols))
        assert read_checkpoint(f)["step"][0] == system.end_step
        assert f["particles/vertex_start"][-1] == f["particles/body_vertices"].shape[0]
        assert set(f["sets"]) >= {"nuts", "nuts.top", "top_plate", "all"}
    # the prescribed displacement column is exact
    cols, tab = read_history(out)
    u2 = tab[:, cols.index("u2:top_plate")]
    assert np.allclose(u2, -1.0 * tab[:, cols.index("time")], atol=1e-15)
    # frames reproduce particle outlines
    st = read_static(out)
    assert st["group_names"] == ["nuts", "bottom_plate", "top_plate"]
    s = json.loads((tmp_path / "r.summary.json").read_text())
    for k in ("wall_time_s", "steps", "particles", "particle_steps_per_s", "observables"):
        assert k in s
    assert s == summary and s["status"] == "finished" and s["steps"] == system.end_step
    assert s["particles"] == 40 and s["particle_steps_per_s"] > 0
    assert s["observables"]["max_overlap_ratio"] > 0


def test_resume_in_process_is_bit_identical(tmp_path):
    system, text = _system(["time.end_displacement=0.06", "output.frame_interval=0.01"])
    a, b = tmp_path / "a.h5", tmp_path / "b.h5"
    run(system, out=a, scenario_file=str(DEMO), scenario_text=text, quiet=True)
    run(system, out=b, scenario_file=str(DEMO), scenario_text=text, quiet=True, stop_after_steps=2345)
    with open_result(b) as f:
        assert f.attrs["status"] == "running"
        assert read_checkpoint(f)["step"][0] == 2345
    run(out=b, resume=True, quiet=True)
    _assert_same_result(a, b)


def test_resume_of_a_result_with_another_column_layout(tmp_path):
    """A result written by another polydem version whose history table has its columns in another order and
    one this version does not compute (the contact columns moved when contact became a family): the resumed
    rows go into the file's order by name, the unknown column is NaN, and the run ends as the uninterrupted one."""
    system, text = _system(["time.end_displacement=0.06", "output.frame_interval=0.01"])
    a, b = tmp_path / "a.h5", tmp_path / "b.h5"
    run(system, out=a, scenario_file=str(DEMO), scenario_text=text, quiet=True)
    run(system, out=b, scenario_file=str(DEMO), scenario_text=text, quiet=True, stop_after_steps=2345)
    with h5py.File(b, "r+") as f:  # rewrite the table as an "older version" would have laid it out
        t = f["history/table"]
        cols, units, desc = (json.loads(t.attrs[k]) for k in ("columns", "units", "descriptions"))
        data = t[...]
        perm = list(reversed(range(len(cols))))
        old = np.column_stack([data[:, perm], np.full(len(data), 7.0)])
        del f["history/table"]
        c = old.shape[1]
        t = f["history"].create_dataset(
            "table", data=old, maxshape=(None, c), chunks=(64, c), fletcher32=True, dtype="f8"
        )
        t.attrs["columns"] = json.dumps([cols[k] for k in perm] + ["retired_column"])
        t.attrs["units"] = json.dumps([units[k] for k in perm] + ["-"])
        t.attrs["descriptions"] = json.dumps([desc[k] for k in perm] + ["a column of an older version"])
    run(out=b, resume=True, quiet=True)
    ca, ha = read_history(a)
    cb, hb = read_history(b)
    assert cb == [ca[k] for k in perm] + ["retired_column"]
    assert np.array_equal(hb[:, : len(ca)], ha[:, perm])
    kept = len(data)
    assert np.all(hb[:kept, -1] == 7.0) and np.all(np.isnan(hb[kept:, -1]))
    with open_result(a) as fa, open_result(b) as fb:
        assert np.array_equal(read_checkpoint(fa)["nord"], read_checkpoint(fb)["nord"])


def _assert_same_result(a, b):
    sa, ta, xa, va = read_frames(a)
    sb, tb, xb, vb = read_frames(b)
    assert np.array_equal(sa, sb) and np.array_equal(xa, xb) and np.array_equal(va, vb)
    ca, ha = read_history(a)
    cb, hb = read_history(b)
    assert ca == cb
    assert np.array_equal(ha, hb)
    with open_result(a) as fa, open_result(b) as fb:
        assert fb.attrs["status"] == "finished"
        ka, kb = read_checkpoint(fa), read_checkpoint(fb)
        assert np.array_equal(ka["nord"], kb["nord"])
        for k in ("contact_a", "contact_b", "contact_ut", "contact_upl", "contact_vt"):
            assert np.array_equal(ka[k], kb[k])


def _wait_marker(marker, p):
    """Wait until the run of ``p`` has started writing (its writer marker exists); the time then."""
    t0 = time.time()
    while not marker.exists() and time.time() - t0 < 120:
        assert p.poll() is None, p.communicate()
        time.sleep(0.02)
    assert marker.exists(), p.communicate()
    return time.time()


def _start(args, tmp_path, name):
    return subprocess.Popen(
        polydem_cmd() + args, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, cwd=tmp_path
    )


@pytest.mark.slow
@pytest.mark.parametrize("sig", [signal.SIGKILL, signal.SIGTERM])
def test_killed_run_resumes_to_the_same_final_state(tmp_path, sig):
    """A run killed mid-way (subprocess) keeps its frames and, resumed, equals the uninterrupted run."""
    sets = [
        "--set",
        "output.checkpoint_interval=0.2",
        "--set",
        "time.end_displacement=0.6",
        "--set",
        "output.frame_interval=0.01",
        "-q",
    ]
    ref, cut = tmp_path / "ref.h5", tmp_path / "cut.h5"
    # a short run fills the compilation cache; the uninterrupted run then measures how long the time
    # loop takes on this machine (from the writer's marker to the end), so that the kill lands in the
    # middle however fast the machine is
    r = subprocess.run(
        polydem_cmd()
        + ["run", str(DEMO), "-o", str(tmp_path / "warm.h5"), "-q", "--set", "time.end_displacement=0.001"],
        capture_output=True,
        text=True,
    )
    assert r.returncode == 0, r.stderr
    p = _start(["run", str(DEMO), "-o", str(ref)] + sets, tmp_path, "ref")
    t_loop = _wait_marker(tmp_path / "ref.h5.writer", p)
    out, err = p.communicate(timeout=300)
    assert p.returncode == 0, err
    t_loop = time.time() - t_loop
    # the machine's speed can change between the two runs (another job starts): if the run has already
    # ended when the signal is due, try again with an earlier kill
    for frac in (0.5, 0.3, 0.15, 0.05):
        cut.unlink(missing_ok=True)
        p = _start(["run", str(DEMO), "-o", str(cut), "--overwrite"] + sets, tmp_path, "cut")
        _wait_marker(tmp_path / "cut.h5.writer", p)
        time.sleep(frac * t_loop)
        if p.poll() is None:
            break
        p.communicate()
    else:
        pytest.fail("every run ended before the signal was due")
    p.send_signal(sig)
    out, err = p.communicate(timeout=60)
    if sig == signal.SIGTERM:
        assert p.returncode == 143 and "polydem run --resume" in err  # 128 + SIGTERM
    else:
        assert p.returncode == -signal.SIGKILL
    # the file is intact and readable, frames written before the kill are there
    with open_result(cut) as f:
        assert f.attrs["status"] == "running"
        ck = read_checkpoint(f)
        assert 0 < ck["step"][0] < 60000
        nframes = f["frames/x"].shape[0]
        assert nframes >= ck["frames_count"][0] >= 1
        kept = f["frames/x"][:nframes]
    r = subprocess.run(
        polydem_cmd() + ["run", "--resume", str(cut), "-q"], capture_output=True, text=True, cwd=tmp_path
    )
    assert r.returncode == 0, r.stderr
    _assert_same_result(ref, cut)
    assert np.array_equal(read_frames(ref)[2][:nframes], kept)  # frames from before the kill were right
    assert json.loads((tmp_path / "cut.summary.json").read_text())["resumed"] is True


def test_resume_without_checkpoint_or_file_is_an_input_error(tmp_path):
    r = subprocess.run(polydem_cmd() + ["run", "--resume", str(tmp_path / "nope.h5")], capture_output=True, text=True)
    assert r.returncode == 2 and "no such result file" in r.stderr
    junk = tmp_path / "junk.h5"
    junk.write_text("not hdf5")
    r = subprocess.run(polydem_cmd() + ["run", "--resume", str(junk)], capture_output=True, text=True)
    assert r.returncode == 2 and "not a readable HDF5 file" in r.stderr


def test_result_of_a_running_simulation_is_refused_at_once(tmp_path):
    """A reader (report, collation, a second `run --continue`) meets a file whose simulation
    and writer are alive: a clear error without waiting, not a lock timeout."""
    import os

    from polydem_cli.io.hdf5 import ResultError, writer_pid

    out = tmp_path / "r.h5"
    out.write_bytes(b"")
    marker = tmp_path / "r.h5.writer"
    marker.write_text(f"{os.getpid()} {os.getpid()}")
    assert writer_pid(out) == os.getpid()
    with pytest.raises(ResultError, match="still being written by a running simulation"):
        open_result(out)
    marker.write_text("999999999 999999999")  # a dead run: not in progress
    assert writer_pid(out) is None


def test_resume_says_where_it_continues_and_leaves_a_finished_run_alone(tmp_path):
    """--resume names the step and time it continues from; on a finished run it does nothing (the
    summary is not rewritten with this session's 0 particle-steps/s)."""
    from polydem_cli.solvers.driver import AlreadyFinished

    system, text = _system(["time.end_displacement=0.04", "output.frame_interval=0.01"])
    out = tmp_path / "r.h5"
    run(system, out=out, scenario_file=str(DEMO), scenario_text=text, quiet=True, stop_after_steps=100)
    r = subprocess.run(polydem_cmd() + ["run", "--resume", str(out)], capture_output=True, text=True, cwd=tmp_path)
    assert r.returncode == 0, r.stderr
    assert f"resuming {out} from step 100 (t = " in r.stderr
    s_before = (tmp_path / "r.summary.json").read_text()
    assert json.loads(s_before)["particle_steps_per_s"] > 0
    with open_result(out) as f:
        attrs_before = f.attrs["summary"]
    r = subprocess.run(polydem_cmd() + ["run", "--resume", str(out)], capture_output=True, text=True, cwd=tmp_path)
    assert r.returncode == 0 and "already finished" in r.stdout and "nothing to do" in r.stdout, r.stderr
    assert (tmp_path / "r.summary.json").read_text() == s_before
    with open_result(out) as f:
        assert f.attrs["summary"] == attrs_before
    with pytest.raises(AlreadyFinished):
        run(out=out, resume=True, quiet=True)


def test_run_ends_with_a_summary_on_stdout(tmp_path):
    r = subprocess.run(
        polydem_cmd() + ["run", str(DEMO), "-o", str(tmp_path / "p.h5"), "--set", "time.end_displacement=0.02"],
        capture_output=True,
        text=True,
    )
    assert r.returncode == 0, r.stderr
    for part in (
        f"wrote {tmp_path / 'p.h5'}",
        "steps",
        "s wall",
        "particle-steps/s",
        "end: end time",
        "peak load |f2:top_plate| = ",
        "energy-balance error",
    ):
        assert part in r.stdout, (part, r.stdout)
    # the end line's rate divides the steps by the stepping's wall time, and says so beside the whole wall time
    sm = json.loads((tmp_path / "p.summary.json").read_text())
    assert sm["startup_wall_time_s"] > 0 and sm["stepping_wall_time_s"] > 0
    assert sm["startup_wall_time_s"] + sm["stepping_wall_time_s"] <= sm["wall_time_s"] * (1 + 1e-9)
    rate = sm["steps_this_session"] * sm["particles"] / sm["stepping_wall_time_s"]
    assert np.isclose(sm["particle_steps_per_s"], rate, rtol=1e-9)
    head = r.stdout.splitlines()[0]
    assert f"{sm['wall_time_s']:.1f} s wall: {sm['startup_wall_time_s']:.1f} s before the first step" in head, head
    assert f"{sm['stepping_wall_time_s']:.1f} s stepping at {sm['particle_steps_per_s']:.3g} particle-steps/s" in head


def test_progress_eta_ignores_the_first_chunk():
    """The first report carries one-time costs (here: 10 steps in 5 s, then 1000 steps/s): it prints no
    ETA, and the next ETA comes from the rate after it, not from the average."""
    import io

    from polydem_cli.solvers.progress import Progress

    pr = Progress(100_000, 1e-3, 10, stream=io.StringIO())
    rate, eta = pr.rate_eta(10, 10, 5.0)
    assert eta is None
    rate, eta = pr.rate_eta(10_010, 10_010, 15.0)
    assert rate == pytest.approx(1000.0) and eta == pytest.approx((100_000 - 10_010) / 1000.0)
    # the window follows a change of speed (the machine got busy: 100 steps/s)
    for k in range(1, 20):
        rate, eta = pr.rate_eta(10_010 + 1000 * k, 10_010 + 1000 * k, 15.0 + 10.0 * k)
    assert rate == pytest.approx(100.0)


def test_one_writer_per_result(tmp_path):
    """A second run on a result being written — new path, --overwrite, --resume, --continue — is refused
    (exit 2, the path and the running process named) before it writes anything; the first run's file
    stays intact.  A lock file left without a living holder (a killed run) does not block."""
    sets = ["--set", "time.end_displacement=1.5", "--set", "output.checkpoint_interval=0.5", "-q"]
    out = tmp_path / "r.h5"
    a = _start(["run", str(DEMO), "-o", str(out)] + sets, tmp_path, "a")
    _wait_marker(tmp_path / "r.h5.writer", a)
    for extra in ([], ["--overwrite"], ["--continue"]):
        r = subprocess.run(
            polydem_cmd() + ["run", str(DEMO), "-o", str(out)] + sets + extra,
            capture_output=True,
            text=True,
            cwd=tmp_path,
        )
        assert r.returncode == 2, (extra, r.stderr)
        assert f"{out}: another polydem run is writing this result (process {a.pid} " in r.stderr, r.stderr
    r = subprocess.run(polydem_cmd() + ["run", "--resume", str(out)], capture_output=True, text=True, cwd=tmp_path)
    assert r.returncode == 2 and "another polydem run is writing this result" in r.stderr, r.stderr
    assert a.poll() is None, "the first run ended before the checks; lengthen it"
    out_a, err_a = a.communicate(timeout=600)
    assert a.returncode == 0, err_a
    with open_result(out) as f:
        assert f.attrs["status"] == "finished"
        s = json.loads(f.attrs["summary"])
        cols = json.loads(f["history/table"].attrs["columns"])
        tab = f["history/table"][:]
    assert s["steps"] == s["end_step"] and tab[-1, cols.index("step")] == s["steps"]
    assert np.all(np.diff(tab[:, cols.index("step")]) > 0)  # one writer: rows in order, none twice
    assert json.loads((tmp_path / "r.summary.json").read_text()) == s
    assert not (tmp_path / "r.h5.lock").exists()  # released at the end


def test_two_runs_started_together_on_a_new_path(tmp_path):
    sets = ["--set", "time.end_displacement=0.2", "-q"]
    out = tmp_path / "new" / "r.h5"
    ps = [_start(["run", str(DEMO), "-o", str(out)] + sets, tmp_path, n) for n in ("a", "b")]
    res = [p.communicate(timeout=600) for p in ps]
    codes = sorted(p.returncode for p in ps)
    assert codes == [0, 2], (codes, res)
    err = res[[p.returncode for p in ps].index(2)][1]
    assert "another polydem run is writing this result" in err or "result file exists" in err, err
    with open_result(out) as f:
        assert f.attrs["status"] == "finished"


def test_stale_lock_file_does_not_block(tmp_path):
    out = tmp_path / "r.h5"
    (tmp_path / "r.h5.lock").write_text("process 999999999 on elsewhere, since 2020-01-01 00:00:00")
    r = subprocess.run(
        polydem_cmd() + ["run", str(DEMO), "-o", str(out), "-q", "--set", "time.end_displacement=0.01"],
        capture_output=True,
        text=True,
    )
    assert r.returncode == 0, r.stderr
    with open_result(out) as f:
        assert f.attrs["status"] == "finished"


def _damage(path, ds, chunk=0):
    """Overwrite 64 bytes inside the written part of one chunk of dataset ``ds`` with zeros (as a bad
    disk block would), bypassing HDF5."""
    with h5py.File(path, "r") as f:
        d = f[ds]
        info = d.id.get_chunk_info(chunk)
        frac = min(1.0, d.shape[0] / d.chunks[0])
    with open(path, "r+b") as fh:
        fh.seek(info.byte_offset + int(info.size * frac * 0.5))
        fh.write(b"\0" * 64)


@pytest.fixture(scope="module")
def interrupted(tmp_path_factory):
    """An interrupted demo run with two complete checkpoints (steps 3,000 and 4,000 of 6,000)."""
    tmp = tmp_path_factory.mktemp("damaged")
    system, text = _system(["time.end_displacement=0.06", "output.frame_interval=0.01"])
    out = tmp / "c.h5"
    run(system, out=out, scenario_file=str(DEMO), scenario_text=text, quiet=True, stop_after_steps=3000)
    run(out=out, resume=True, quiet=True, stop_after_steps=4000)
    ref = tmp / "ref.h5"
    run(
        _system(["time.end_displacement=0.06", "output.frame_interval=0.01"])[0],
        out=ref,
        scenario_file=str(DEMO),
        scenario_text=text,
        quiet=True,
    )
    return out, ref


@pytest.mark.parametrize("ds", ["history/table", "frames/x"])
def test_damaged_block_is_reported_by_report_and_resume(tmp_path, interrupted, ds):
    import shutil

    p = tmp_path / "c.h5"
    shutil.copy(interrupted[0], p)
    _damage(p, ds, chunk=0 if ds.startswith("history") else 1)
    for cmd in (["report", str(p), "--out", str(tmp_path / "rep")], ["run", "--resume", str(p)]):
        r = subprocess.run(polydem_cmd() + cmd, capture_output=True, text=True)
        assert r.returncode == 2, (cmd, r.stderr)
        assert f"{p}: corrupted data (checksum mismatch) in /{ds}" in r.stderr
    assert not (tmp_path / "rep").exists() or not list((tmp_path / "rep").glob("*.png"))


def test_damaged_checkpoint_falls_back_to_the_other_slot(tmp_path, interrupted):
    import shutil

    p = tmp_path / "c.h5"
    shutil.copy(interrupted[0], p)
    with h5py.File(p, "r") as f:
        cur = int(f["checkpoint/current"][0])
        big = max(f[f"checkpoint/slot{cur}"], key=lambda n: f[f"checkpoint/slot{cur}/{n}"].size)
    _damage(p, f"checkpoint/slot{cur}/{big}")
    r = subprocess.run(polydem_cmd() + ["run", "--resume", str(p)], capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    assert f"/checkpoint/slot{cur} failed its checksums; using the older checkpoint at step 3,000" in r.stderr
    assert "resuming" in r.stderr and "from step 3,000" in r.stderr
    _assert_same_result(interrupted[1], p)  # recomputed from the older checkpoint: the same run


def test_both_checkpoints_damaged_refuses_to_resume(tmp_path, interrupted):
    import shutil

    p = tmp_path / "c.h5"
    shutil.copy(interrupted[0], p)
    with h5py.File(p, "r") as f:
        names = [
            (s, n) for s in ("slot0", "slot1") for n in f[f"checkpoint/{s}"] if f[f"checkpoint/{s}/{n}"].size > 100
        ]
    for s, n in names:
        _damage(p, f"checkpoint/{s}/{n}")
    r = subprocess.run(polydem_cmd() + ["run", "--resume", str(p)], capture_output=True, text=True)
    assert r.returncode == 2 and "corrupted checkpoint (checksum mismatch in /checkpoint/slot" in r.stderr, r.stderr
    assert "cannot be resumed" in r.stderr


def test_truncated_file_is_reported_as_truncated(tmp_path, interrupted):
    import os
    import shutil

    p = tmp_path / "c.h5"
    shutil.copy(interrupted[1], p)
    os.truncate(p, os.path.getsize(p) // 2)
    for cmd in (["report", str(p)], ["run", "--resume", str(p)]):
        r = subprocess.run(polydem_cmd() + cmd, capture_output=True, text=True)
        assert r.returncode == 2 and f"{p}: the file is truncated (" in r.stderr, (cmd, r.stderr)
        assert "locked" not in r.stderr


def test_cold_cache_announced(tmp_path, monkeypatch):
    """A run that has to compile the loop says so before the silent minutes of a cold cache (and how long it
    took); a warm one stays quiet about it.  loop_cached must recognise the cache this test session filled."""
    import io

    import polydem_cli.solvers.explicit as R
    from polydem_cli._jit_cache import loop_cached

    for name in ("a.h5", "w.h5"):  # the first run may compile (a cold cache), the second finds the loop
        system, text = _system(["time.end_displacement=0.002"])
        warm = io.StringIO()
        run(system, out=tmp_path / name, scenario_file=str(DEMO), scenario_text=text, stream=warm)
    assert loop_cached()
    assert "compiling the time loop" not in warm.getvalue()
    monkeypatch.setattr(R, "loop_cached", lambda: False)
    cold = io.StringIO()
    system, text = _system(["time.end_displacement=0.002"])
    run(system, out=tmp_path / "b.h5", scenario_file=str(DEMO), scenario_text=text, stream=cold)
    lines = cold.getvalue().splitlines()
    first = next(i for i, ln in enumerate(lines) if ln.startswith("compiling the time loop"))
    done = next(i for i, ln in enumerate(lines) if ln.startswith("compiled in "))
    prog = next(i for i, ln in enumerate(lines) if ln.startswith("["))
    assert first < done < prog  # announced before the work, timed before the first progress line


def test_report_of_a_running_result_reads_a_snapshot(tmp_path):
    """`polydem report` (and `export`) on a result still being written gets a snapshot of its state so far from the
    run's writer (figures named <stem>.running_*, the run goes on); the snapshot is what the file held
    at that moment: its history and frames are the first rows of the result as the run leaves it."""
    from polydem_cli.io.hdf5 import ResultError, request_snapshot

    sets = ["--set", "time.end_displacement=1.5", "--set", "time.dt=1e-6", "--set", "output.frame_interval=0.002"]
    out = tmp_path / "r.h5"
    a = _start(["run", str(DEMO), "-o", str(out), "-q"] + sets, tmp_path, "a")
    try:
        _wait_marker(tmp_path / "r.h5.writer", a)
        time.sleep(1.0)  # some frames and history rows
        r = subprocess.run(
            polydem_cmd() + ["report", str(out), "--out", str(tmp_path / "figs")],
            capture_output=True,
            text=True,
            cwd=tmp_path,
        )
        assert r.returncode == 0, r.stderr
        assert f"{out}: still running" in r.stderr, r.stderr
        assert (tmp_path / "figs" / "r.running_history.png").exists(), r.stdout
        assert not (tmp_path / "figs" / "r_history.png").exists()
        r = subprocess.run(polydem_cmd() + ["export", str(out)], capture_output=True, text=True, cwd=tmp_path)
        assert r.returncode == 0 and "still running" in r.stderr, r.stderr
        assert (tmp_path / "r.running.vtkhdf").exists() and not (tmp_path / "r.vtkhdf").exists()
        snap = tmp_path / "snap.h5"
        assert request_snapshot(out, snap, timeout=60)
        assert a.poll() is None, "the run ended before the checks; lengthen it"
        with pytest.raises(ResultError, match="still being written"):
            open_result(out)  # the result itself stays closed to readers
        assert not (tmp_path / "r.h5.snapshot-request").exists()
        time.sleep(1.0)  # the run goes on past the snapshot before it is stopped (on a loaded machine, too)
    finally:
        a.send_signal(signal.SIGTERM)
        a.communicate(timeout=60)
    with open_result(snap) as s, open_result(out) as f:
        assert s.attrs["snapshot_of"] == str(out.resolve()) and "checkpoint" not in s
        hs, hf = s["history/table"][:], f["history/table"][:]
        xs, xf = s["frames/x"][:], f["frames/x"][:]
    assert 2 <= len(hs) < len(hf) and np.array_equal(hs, hf[: len(hs)])
    assert 1 <= len(xs) <= len(xf) and np.array_equal(xs, xf[: len(xs)])


def test_a_checkpoint_without_an_optional_field_does_not_keep_an_older_ones(tmp_path):
    """The two checkpoint slots are written in turn: a field that one state has and a later one lacks (the
    quasi-static stepper's factor, absent right after a mesh refinement) must not survive in the slot, or a resume
    reads the older state's field with the newer state.  Found as a quasi-static run resumed after a refinement that
    differed from the uninterrupted one in the last bits (its factor replayed from a stale stiffness)."""
    from polydem_cli.io.hdf5 import ResultWriter

    path = tmp_path / "r.h5"
    w = ResultWriter(path)
    w.send("new", attrs={"format": "polydem-test"})
    w.send("checkpoint", state={"step": np.array([1]), "factor": np.arange(4.0)}, wall_elapsed=0.1)
    w.send("checkpoint", state={"step": np.array([2]), "factor": np.arange(3.0)}, wall_elapsed=0.2)
    w.send("checkpoint", state={"step": np.array([3])}, wall_elapsed=0.3)  # into the slot of step 1
    w.close()
    with h5py.File(path, "r") as f:
        ck = read_checkpoint(f)
        assert int(ck["step"][0]) == 3 and "factor" not in ck
        assert sorted(f["checkpoint/slot0"]) == ["step", "wall_elapsed"]
        assert np.array_equal(f["checkpoint/slot1/factor"][...], np.arange(3.0))  # the older slot keeps its own
