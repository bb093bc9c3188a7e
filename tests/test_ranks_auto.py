"""``polydem run --ranks auto`` (the default): the free cores counted by the rule of ``--threads auto``, and the
ranks chosen from them, the scene and the installed MPI (cli/run.py :func:`auto_ranks`)."""

import os
import subprocess
import sys

import pytest

from polydem_cli.cli import run as runmod
from polydem_cli.engine import threads

from conftest import SCEN

CONCRETE = str(SCEN / "concrete_tension.toml")


def _reader(busy_per_s, hz=100):
    """/proc/stat stand-in: ``busy_per_s`` cores busy, read at the wall times of the fake clock."""
    clock = {"t": 0.0}
    return (
        (lambda: (round(busy_per_s * clock["t"] * hz), hz)),
        (lambda: clock["t"]),
        (lambda dt: clock.__setitem__("t", clock["t"] + dt)),
    )


@pytest.mark.parametrize(("busy", "free"), [(0.0, 2), (0.4, 2), (1.0, 1), (1.6, 0), (2.0, 0), (3.0, 0)])
def test_free_cores_are_the_cores_less_the_others_busy_time(monkeypatch, busy, free):
    """2 cores: free = round(2 - busy CPU time of the others / wall), never below 0 (this idle process's own CPU
    time, microseconds, is subtracted from the busy time)."""
    monkeypatch.setattr(threads, "available_cores", lambda: 2)
    read, clock, sleep = _reader(busy)
    assert threads.free_cores(0.5, reader=read, clock=clock, sleep=sleep) == free


def test_free_cores_without_proc_stat_are_the_available_ones(monkeypatch):
    monkeypatch.setattr(threads, "available_cores", lambda: 3)
    assert threads.free_cores(0.1, reader=lambda: None, sleep=lambda dt: None) == 3


@pytest.fixture
def two_free(monkeypatch):
    monkeypatch.setattr(threads, "free_cores", lambda window=0.3: 2)
    monkeypatch.setattr(threads, "available_cores", lambda: 2)


def test_auto_starts_a_rank_per_free_core_on_a_scene_that_gains(two_free, monkeypatch, capsys):
    """The main job's panel (1,600 particles) on 2 free cores with MPI: 2 ranks, and a line saying so."""
    monkeypatch.setattr(runmod, "_mpiexec", lambda: "/usr/bin/mpiexec")
    monkeypatch.setattr(runmod, "_has_mpi4py", lambda: True)
    assert runmod.auto_ranks(CONCRETE, (), None, "auto", False) == 2
    assert "ranks auto: 2 ranks (2 free cores, 1,600 particles" in capsys.readouterr().err


def test_auto_stays_on_one_process(two_free, monkeypatch, capsys):
    """One process for: an asked thread count, a scene of fewer than 2 x AUTO_PARTICLES_PER_RANK particles, a
    quasi-static solver, no free second core, and (with a line saying so) no MPI."""
    monkeypatch.setattr(runmod, "_mpiexec", lambda: "/usr/bin/mpiexec")
    monkeypatch.setattr(runmod, "_has_mpi4py", lambda: True)
    assert runmod.auto_ranks(CONCRETE, (), None, 2, False) == 1
    assert runmod.auto_ranks(CONCRETE, (), None, 1, True) == 1
    assert capsys.readouterr().err == ""  # a thread count asked for: nothing to say

    def reason(*args):
        assert runmod.auto_ranks(*args) == 1
        return capsys.readouterr().err

    small = ["particles.0.nx=14", "particles.0.ny=14"]  # 196 particles: fewer than 2 x 200
    assert "one process: 196 particles, fewer than 2 x 200" in reason(CONCRETE, small, None, "auto", False)
    quasi = str(SCEN / "coupling" / "homogeneous_elastic.toml")
    assert "one process: [solver] kind = 'quasistatic'" in reason(quasi, (), None, "auto", False)
    monkeypatch.setattr(threads, "free_cores", lambda window=0.3: 1)
    assert "one process: 1 core free of 2" in reason(CONCRETE, (), None, "auto", False)
    monkeypatch.setattr(threads, "free_cores", lambda window=0.3: 2)
    monkeypatch.setattr(runmod, "_mpiexec", lambda: None)
    assert "one process: MPI is not installed here" in reason(CONCRETE, (), None, "auto", False)


def test_auto_never_starts_ranks_under_a_launcher_or_batch_system(monkeypatch):
    """A single-rank mpiexec, srun or a job script's plain command (one rank as far as the launcher's size says), and
    the ranks polydem itself started: auto runs the one process it is, without asking auto_ranks."""

    def never(*a, **k):
        raise AssertionError("auto_ranks asked under a launcher")

    monkeypatch.setattr(runmod, "auto_ranks", never)
    for var in runmod.LAUNCHER_VARS:
        for k in runmod.LAUNCHER_VARS:
            monkeypatch.delenv(k, raising=False)
        monkeypatch.setenv(var, "1")
        assert runmod._ranks(CONCRETE, (), None, "auto") == 1


def test_a_finished_result_is_not_started_on_ranks(two_free, monkeypatch, tmp_path):
    """--continue on a result that holds the same finished run (overrides included): one process, nothing built."""
    monkeypatch.setattr(runmod, "_mpiexec", lambda: "/usr/bin/mpiexec")
    monkeypatch.setattr(runmod, "_has_mpi4py", lambda: True)
    seen = []
    monkeypatch.setattr(runmod, "_finished", lambda sc, res: seen.append((sc["time"]["end_time"], str(res))) or True)
    over = ["time.end_time=1e-5"]
    assert runmod.auto_ranks(CONCRETE, over, None, "auto", False, out=tmp_path / "r.h5", cont=True) == 1
    assert seen == [(1e-5, str(tmp_path / "r.h5"))]


def test_auto_on_a_bad_scenario_leaves_the_refusal_to_the_run(two_free, tmp_path):
    """auto never refuses: an unreadable scenario gives 1, and the run then says what is wrong, once."""
    bad = tmp_path / "bad.toml"
    bad.write_text("[time\n")
    assert runmod.auto_ranks(str(bad), (), None, "auto", False) == 1
    env = dict(os.environ, POLYDEM_RANKS="auto")
    r = subprocess.run(
        [sys.executable, "-m", "polydem_cli", "run", str(bad), "-o", str(tmp_path / "r.h5")],
        capture_output=True,
        text=True,
        env=env,
    )
    assert r.returncode == 2 and r.stderr.count("error:") == 1, r.stderr


def test_ranks_must_be_auto_or_a_count(tmp_path):
    r = subprocess.run(
        [sys.executable, "-m", "polydem_cli", "run", CONCRETE, "-o", str(tmp_path / "r.h5"), "--ranks", "two"],
        capture_output=True,
        text=True,
    )
    assert r.returncode == 2 and "--ranks two: at least 1, or auto" in r.stderr


@pytest.mark.parametrize(
    ("particles", "free", "ranks"), [(1600, 2, 2), (1600, 1, 1), (399, 2, 1), (400, 2, 2), (1000, 8, 5), (10**6, 0, 1)]
)
def test_auto_rank_count(particles, free, ranks):
    """A rank per free core, at most one per 200 particles, one process below two."""
    assert threads.auto_rank_count(particles, free) == ranks


def test_bench_reports_the_default_setting(monkeypatch):
    """make bench's default column: 2 ranks (the ranks column's interleaved ratio) where --ranks auto starts them
    (idle, 2 cores, 1,600 particles), one process with --threads auto against 1 thread beside a busy process, and
    one process in both where the scene does not decompose."""
    from polydem_cli.benchmarks import bench

    monkeypatch.setattr(threads, "available_cores", lambda: 2)

    def runs(one, auto):
        r = [{"particles": 1600, "particle_steps_per_s": one, "threads_used": 1} for _ in bench.SETTINGS]
        r[bench.SETTINGS.index("auto")] = {"particles": 1600, "particle_steps_per_s": auto, "threads_used": 2}
        return r

    d = {"ranks": {"speedup_median": 1.7}}
    got = bench._default(d, runs(2.0, 3.0), runs(2.0, 1.9))
    assert got["idle_setting"] == "2 ranks x 1 thread" and got["idle_over_1_thread"] == 1.7
    assert got["busy_setting"].startswith("1 process") and got["busy_over_1_thread"] == pytest.approx(0.95)
    got = bench._default({"ranks": {"unsupported": "plates"}}, runs(2.0, 3.0), runs(2.0, 1.9))
    assert got["idle_over_1_thread"] == pytest.approx(1.5) and got["idle_setting"].startswith("1 process")
