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
    assert (
        T.busy_elsewhere(now, before) > 0.7
    )  # one spinning process (plus whatever else runs): at least most of a core


def test_auto_keeps_one_thread_for_a_scene_without_threaded_kernels(tmp_path):
    """polydem run with the default --threads auto: the disk box (no polygon contact, beams or base friction)
    runs on one thread whatever the free cores; the demo pile (polygon contact) may use more."""
    import json

    from polydem_cli.engine.threads import threaded as _threaded
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


class Scene:
    """Chunks of compiled steps whose speed depends on the thread count, on the fake machine's clock."""

    def __init__(self, machine, rates):
        self.m, self.rates = machine, rates  # steps per second by thread count

    def chunks(self, g, n, wall=0.1):
        for _ in range(n):
            steps = int(self.rates[g.threads] * wall)
            self.m.advance(wall)
            g.update(steps, wall)
        return g.threads


@pytest.mark.parametrize(
    "rates, chosen",
    [
        ({1: 19.0e3, 2: 9.5e3}, 1),  # the disk box: two threads half as fast
        ({1: 1.89e3, 2: 1.77e3}, 1),  # the concrete panel: 0.94x
        ({1: 1.00e3, 2: 1.02e3}, 1),  # a gain inside the margin is not worth a second core
        ({1: 2.63e3, 2: 3.86e3}, 2),  # bonded 300 x 300: 1.47x
    ],
)
def test_auto_runs_one_thread_where_one_is_measured_faster(rates, chosen):
    m = FakeMachine()
    g = _governor(m)
    s = Scene(m, rates)
    # one slot of PROBE_SLOT_S a chunk: the free cores first, then one thread, interleaved
    settings = [s.chunks(g, 1, wall=T.PROBE_SLOT_S) for _ in range(2 * T.PROBE_SLOTS)]
    assert settings[:-1] == [1, 2] * (T.PROBE_SLOTS - 1) + [1]  # the count after each chunk
    assert not g.probing and g.threads == chosen
    assert s.chunks(g, 50) == chosen  # and kept
    ((_, measured, c),) = g.probes
    assert c == chosen and measured[1] == pytest.approx(rates[1], rel=0.02)
    assert measured[2] == pytest.approx(rates[2], rel=0.02)


def test_auto_probes_again_as_the_step_cost_changes():
    """A bonded specimen on one thread cracks into a contact-heavy one on which two threads pay."""
    m = FakeMachine()
    g = _governor(m)
    s = Scene(m, {1: 2.0e3, 2: 1.5e3})
    s.chunks(g, 40)
    assert g.threads == 1
    s.rates = {1: 2.0e3, 2: 3.5e3}
    s.chunks(g, int(T.REPROBE_S / 0.1) - 60)
    assert g.threads == 1  # no new probe before REPROBE_S
    s.chunks(g, 100)
    assert g.threads == 2 and [c for _, _, c in g.probes] == [1, 2]


def test_auto_probe_waits_while_other_processes_hold_the_cores_and_a_count_is_not_probed():
    m = FakeMachine()
    g = _governor(m)
    m.others = 1.0
    s = Scene(m, {1: 2.0e3, 2: 1.0e3})
    s.chunks(g, 30)
    assert g.threads == 1 and g.probing is False and g.probes == []
    m.others = 0.0  # the other process ends: the free core is probed, and it does not pay here
    s.chunks(g, 60)
    assert g.threads == 1 and [c for _, _, c in g.probes] == [1]
    assert 2 in [n for _, n in g.history]
    g2 = _governor(FakeMachine(), 2)  # --threads 2: the user's ceiling, governed by load only
    Scene(g2.clock.__self__, {1: 2.0e3, 2: 1.0e3}).chunks(g2, 60)
    assert g2.threads == 2 and g2.probes == []


def test_run_feeds_the_governor_each_chunk_and_records_the_probe(tmp_path, monkeypatch):
    """The wiring: polydem run passes every chunk's steps and wall time to the governor, and the summary
    records what the probe measured."""
    import json

    from polydem_cli.scenario.build import build_system
    from polydem_cli.scenario.load import load_scenario
    from polydem_cli.solvers import explicit as runner

    from conftest import SCEN

    seen = []
    update = T.ThreadGovernor.update

    def spy(self, steps=0, wall=0.0):
        seen.append((steps, wall))
        return update(self, steps, wall)

    monkeypatch.setattr(T.ThreadGovernor, "update", spy)
    monkeypatch.setattr(T, "PROBE_SLOT_S", 0.0)  # every chunk a slot: the probe ends within this short run
    monkeypatch.setattr(runner, "CHECK_STEPS", 100)  # chunks of at most 100 steps: 20 of them
    monkeypatch.setattr(T.ThreadGovernor, "_update_cap", lambda self: None)  # as if both cores were free
    out = tmp_path / "pile.h5"
    sc, text = load_scenario(SCEN / "demo_hex_pile.toml", ["time.end_displacement=0.02"])
    system = build_system(sc, str(SCEN / "demo_hex_pile.toml"))
    runner.run(system, out=out, scenario_file=str(SCEN / "demo_hex_pile.toml"), scenario_text=text, quiet=True)
    summary = json.loads(out.with_suffix(".summary.json").read_text())
    assert seen and all(st > 0 and w > 0 for st, w in seen)
    assert sum(st for st, _ in seen) == summary["steps"]
    if numba.config.NUMBA_NUM_THREADS > 1:
        (probe,) = summary["threads"]["probes"]
        rates = {int(k): v for k, v in probe["particle_steps_per_s"].items()}
        assert set(rates) == {1, 2} and probe["chosen"] in (1, 2)


def test_ranks_on_one_machine_share_its_cores(monkeypatch):
    """A decomposed run's governor: at most an equal share of the cores per rank, or the cores a launcher bound the
    rank to; one thread when the ranks fill the machine."""
    monkeypatch.setattr(T.os, "cpu_count", lambda: 64)
    monkeypatch.setattr(T, "available_cores", lambda: 64)
    monkeypatch.setattr(numba.config, "NUMBA_NUM_THREADS", 64)
    assert T.per_rank(16) == 4 and T.per_rank(64) == 1 and T.per_rank(128) == 1 and T.per_rank(1) == 64
    monkeypatch.setattr(T, "available_cores", lambda: 2)  # srun --cpus-per-task=2
    assert T.per_rank(32) == 2


def test_a_bound_rank_counts_the_load_of_its_own_cores_only(tmp_path):
    """A rank bound to 2 of 4 cores (a batch job's --cpus-per-task) measures the busy ticks of those 2: the other
    ranks' cores are not its competition."""
    stat = tmp_path / "stat"
    stat.write_text(
        "cpu  400 0 40 1000 0 0 0 0 0 0\n"
        "cpu0 100 0 10 250 0 0 0 0 0 0\n"
        "cpu1 100 0 10 250 0 0 0 0 0 0\n"
        "cpu2 190 0 10 250 0 0 0 0 0 0\n"
        "cpu3 10 0 10 250 0 0 0 0 0 0\n"
    )
    assert T._cpu_ticks(False, str(stat), cpus={0, 1, 2, 3})[0] == 440  # every core: the total line
    assert T._cpu_ticks(False, str(stat), cpus={2, 3})[0] == 220
    assert T._cpu_ticks(False, str(stat), cpus={0})[0] == 110
