"""The ``auto`` thread count (engine/threads.py): it measures what other processes use and leaves them
their cores; a fixed count is kept."""

import subprocess
import sys
import time

import numba
import pytest

from polydem_cli.engine import threads as T


class FakeMachine:
    """A clock and /proc/stat counters driven by the test: ``others`` cores busy besides this process.

    The process's own CPU time comes from time.process_time(), which is small while the test sleeps,
    so the machine's busy ticks are the others' plus the little this process really used."""

    HZ = 100

    def __init__(self):
        self.t = 0.0
        self.ticks = 0.0
        self.others = 0.0

    def clock(self):
        return self.t

    def reader(self):
        return int(self.ticks), self.HZ

    def advance(self, seconds):
        self.t += seconds
        self.ticks += self.others * seconds * self.HZ


def _governor(machine, mode="auto", pin=False):
    return T.ThreadGovernor(mode, pin=pin, cores=2, max_threads=2, clock=machine.clock, reader=machine.reader)


def test_auto_leaves_a_busy_core_to_its_process_and_takes_it_back():
    m = FakeMachine()
    g = _governor(m)
    assert g.threads == 2
    m.others = 1.0  # one busy process appears
    m.advance(0.3)
    assert g.update() == 1  # first choice after FIRST_WINDOW_S, without confirmation
    m.others = 0.0
    m.advance(1.1)
    assert g.update() == 1  # one quiet window is not enough
    m.advance(1.1)
    assert g.update() == 2  # two in a row
    m.others = 1.0
    m.advance(1.1)
    g.update()
    m.others = 0.0  # a burst of one window does not make it flip
    m.advance(1.1)
    assert g.update() == 2
    assert [n for _, n in g.history] == [2, 1, 2]
    assert numba.get_num_threads() == 2


def test_busy_ticks_leave_out_niced_processes_unless_asked():
    line = "cpu  100 5000 200 9000 40 3 7 11 0 0"
    assert T.parse_stat(line, count_nice=False) == 100 + 200 + 3 + 7 + 11  # idle and iowait are not busy
    assert T.parse_stat(line, count_nice=True) == 100 + 5000 + 200 + 3 + 7 + 11
    assert T.parse_stat("cpu0 1 2 3 4", False) is None  # a per-core line is not the total


def test_a_count_is_a_ceiling_governed_like_auto():
    """--threads 2 beside a busy process drops to 1 (2 threads sharing a core run no faster than 1) and comes
    back; --threads 1 stays 1 when the machine is idle."""
    m = FakeMachine()
    g = _governor(m, 2)
    assert (g.mode, g.threads) == ("at most 2", 2)
    m.others = 1.0
    m.advance(0.3)
    assert g.update() == 1
    m.others = 0.0
    for _ in range(2):
        m.advance(1.1)
        g.update()
    assert g.threads == 2
    m1 = FakeMachine()  # idle
    g1 = _governor(m1, 1)
    m1.advance(2.0)
    assert g1.update() == 1 and numba.get_num_threads() == 1
    _governor(FakeMachine(), 2)  # leave the default for the other tests


def test_pinned_count_is_kept_whatever_the_load():
    m = FakeMachine()
    g = _governor(m, 2, pin=True)
    assert g.mode == "pinned 2"
    m.others = 1.0
    for _ in range(3):
        m.advance(2.0)
        assert g.update() == 2
    assert numba.get_num_threads() == 2
    assert [n for _, n in g.history] == [2]


def test_cli_pin_threads_needs_a_count(tmp_path):
    from conftest import SCEN, polydem_cmd

    r = subprocess.run(
        [*polydem_cmd(), "run", str(SCEN / "demo_hex_pile.toml"), "-o", str(tmp_path / "r.h5"), "--pin-threads"],
        capture_output=True,
        text=True,
    )
    assert r.returncode == 2 and "--pin-threads needs a count" in r.stderr
    assert not (tmp_path / "r.h5").exists()


def test_a_real_busy_process_is_measured_as_about_one_core():
    if T._cpu_ticks(False) is None:
        pytest.skip("no /proc/stat")
    g = T.ThreadGovernor("auto", cores=2, max_threads=2)
    busy = subprocess.Popen([sys.executable, "-c", "while True: pass"])
    try:
        time.sleep(0.3)  # let it start
        before = g._sample()
        time.sleep(1.0)
        now = g._sample()
    finally:
        busy.kill()
        busy.wait()
    assert g.others(now, before) > 0.7  # one spinning process (plus whatever else runs): at least most of a core


def test_auto_keeps_one_thread_for_a_scene_without_threaded_kernels(tmp_path):
    """polydem run with the default --threads auto: the disk box (no polygon contact, beams or base friction)
    runs on one thread whatever the free cores; the demo pile (polygon contact) may use more."""
    import json

    from polydem_cli.engine.runner import _threaded
    from polydem_cli.scenario.build import build_system
    from polydem_cli.scenario.load import load_scenario

    from conftest import SCEN, polydem_cmd

    def system(path):
        sc, _ = load_scenario(path, [])
        return build_system(sc, str(path))

    assert not _threaded(system(SCEN / "lh" / "smoke_disk_compression.toml"))
    assert _threaded(system(SCEN / "demo_hex_pile.toml"))
    out = tmp_path / "disks.h5"
    r = subprocess.run(
        polydem_cmd() + ["run", str(SCEN / "lh" / "smoke_disk_compression.toml"), "-o", str(out), "-q"],
        capture_output=True,
        text=True,
        env={**__import__("os").environ, "NUMBA_NUM_THREADS": "2"},
    )
    assert r.returncode == 0, r.stderr
    summary = json.loads(out.with_suffix(".summary.json").read_text())
    assert summary["threads"]["used"] == [1]
