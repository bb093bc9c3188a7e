"""The scene ``polydem run --ranks N`` builds for its check, handed to rank 0 (scenario/handover.py): taken only for
the scenario it was built from, once, only by a rank polydem's launcher started, nothing unpickled from a file that
is not a hand-over, and the same scene as a build — the same compiled types of every array, and a run from it equal
to a run from a fresh build bit for bit.  Through the CLI on two ranks: tests/test_ranks.py
``test_polydem_run_on_two_ranks_writes_the_serial_result`` and ``test_interrupted_on_two_ranks_resumes_on_one_and_back``."""

import os
import pickle
from pathlib import Path

import numba
import numpy as np
import pytest

from polydem_cli.scenario import handover
from polydem_cli.scenario.build import build_system
from polydem_cli.scenario.load import load_scenario

from helpers import run

ROOT = Path(__file__).resolve().parents[1]
#: a bonded panel with contact and a load-drop stop: beams, contact histories and a controller in one scene
PANEL = ROOT / "scenarios/ch7/smoke_concrete_tension.toml"


def _scene(*overrides):
    sc, _ = load_scenario(PANEL, list(overrides))
    return sc, str(PANEL)


@pytest.fixture
def launched(tmp_path, monkeypatch):
    """A rank of polydem's launcher, its temporary files in ``tmp_path``."""
    monkeypatch.setenv("TMPDIR", str(tmp_path))
    monkeypatch.setattr("tempfile.tempdir", None)  # tempfile caches its folder: look again
    monkeypatch.delenv(handover.ENV, raising=False)
    monkeypatch.setenv(handover.LAUNCHED, str(tmp_path / "pids.txt"))
    return tmp_path


def _arrays(obj, path="", seen=None, depth=0):
    """(path, array) of every numpy array reachable through attributes, dict values and sequence items."""
    seen = set() if seen is None else seen
    if id(obj) in seen or depth > 6:
        return
    seen.add(id(obj))
    if isinstance(obj, np.ndarray):
        yield path, obj
    elif isinstance(obj, dict):
        for k, v in obj.items():
            yield from _arrays(v, f"{path}[{k!r}]", seen, depth + 1)
    elif isinstance(obj, list | tuple):
        for i, v in enumerate(obj):
            yield from _arrays(v, f"{path}[{i}]", seen, depth + 1)
    elif hasattr(obj, "__dict__") or hasattr(obj, "__slots__"):
        names = list(getattr(obj, "__dict__", {})) + list(getattr(obj, "__slots__", ()))
        for k in names:
            if hasattr(obj, k):
                yield from _arrays(getattr(obj, k), f"{path}.{k}", seen, depth + 1)


def test_the_handed_scene_runs_as_a_built_one(launched, monkeypatch):
    sc, file = _scene()
    path = handover.hand_over(build_system(sc, file), sc, file)
    assert Path(path).parent == launched and os.stat(path).st_mode & 0o777 == 0o600
    monkeypatch.setenv(handover.ENV, path)
    handed = handover.take(sc, file)
    assert handed is not None
    assert not Path(path).exists() and handover.ENV not in os.environ  # taken once
    assert handover.take(sc, file) is None
    built = build_system(sc, file)
    # every array of the scene with its values, dtype and the type the compiled code sees (layout, read-only)
    a, b = dict(_arrays(handed)), dict(_arrays(built))
    assert a.keys() == b.keys() and len(a) > 20
    for k in b:
        assert numba.typeof(a[k]) == numba.typeof(b[k]), k
        np.testing.assert_array_equal(a[k], b[k], err_msg=k)
    steps = 200
    sim_h, hist_h = run(handed, steps)
    sim_b, hist_b = run(built, steps)
    np.testing.assert_array_equal(sim_h.x, sim_b.x)
    np.testing.assert_array_equal(sim_h.v, sim_b.v)
    for k in hist_b:
        np.testing.assert_array_equal(hist_h[k], hist_b[k], err_msg=k)
    assert sim_b.step == steps and np.ptp(sim_b.x[:, 0]) > 0


def test_a_scene_of_another_scenario_is_not_taken(launched, monkeypatch):
    sc, file = _scene()
    system = build_system(sc, file)
    path = handover.hand_over(system, sc, file)
    monkeypatch.setenv(handover.ENV, path)
    other, _ = _scene("particles.0.nx=11")
    assert handover.take(other, file) is None
    assert not Path(path).exists()  # a hand-over file is read once, taken or not
    path = handover.hand_over(system, sc, file)
    monkeypatch.setenv(handover.ENV, path)
    assert handover.take(sc, "another/file.toml") is None  # the same scenario read from another file
    # a process that polydem's launcher did not start (a serial run, a cluster's mpiexec) builds its own
    path = handover.hand_over(system, sc, file)
    monkeypatch.setenv(handover.ENV, path)
    monkeypatch.delenv(handover.LAUNCHED)
    assert handover.take(sc, file) is None


def test_a_file_that_is_not_a_hand_over_is_left_alone_and_not_unpickled(launched, monkeypatch):
    sc, file = _scene()
    hit = launched / "unpickled"

    class Trap:
        def __reduce__(self):
            return (Path.touch, (hit,))

    trap = pickle.dumps(Trap())
    contents = (b"", b"not a pickle", trap, handover.MAGIC + trap, handover.MAGIC + b"{}\n" + trap)
    for content in contents:
        foreign = launched / "mine.dat"
        foreign.write_bytes(content)
        foreign.chmod(0o600)
        monkeypatch.setenv(handover.ENV, str(foreign))
        assert handover.take(sc, file) is None
        assert not hit.exists()
        if not content.startswith(handover.MAGIC):
            assert foreign.read_bytes() == content
    # a hand-over of this very scene that others could have written to is not read
    path = handover.hand_over(build_system(sc, file), sc, file)
    os.chmod(path, 0o644)
    monkeypatch.setenv(handover.ENV, path)
    assert handover.take(sc, file) is None and Path(path).exists()
    monkeypatch.setenv(handover.ENV, str(launched / "missing"))
    assert handover.take(sc, file) is None
    fifo = launched / "fifo"
    os.mkfifo(fifo)
    monkeypatch.setenv(handover.ENV, str(fifo))
    assert handover.take(sc, file) is None  # not opened: it would wait for a writer
