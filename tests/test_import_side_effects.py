"""Importing polydem changes nothing (issue 35: no side effects on import): no environment variable, no file;
the cache set-up is an explicit call that the ``polydem`` command makes before any command."""

import json
import os
import subprocess
import sys

from conftest import polydem_cmd

PROBE = r"""
import json, os, sys
before = dict(os.environ)
import polydem_cli, polydem_cli.cli, polydem_cli.solvers.driver, polydem_cli.report.make
after = dict(os.environ)
changed = sorted(k for k in set(before) | set(after) if before.get(k) != after.get(k))
d = polydem_cli.setup_jit_cache()
print(json.dumps({"changed": changed, "dir": d, "env": os.environ.get("NUMBA_CACHE_DIR")}))
"""


def test_import_changes_no_environment_and_no_file(tmp_path):
    env = {k: v for k, v in os.environ.items() if k not in ("NUMBA_CACHE_DIR",)}
    env["POLYDEM_CACHE_DIR"] = str(tmp_path / "cache")
    stale = tmp_path / "cache" / "numba-000000000000"  # a cache of other sources: set-up removes it, import not
    stale.mkdir(parents=True)
    r = subprocess.run(
        [
            sys.executable,
            "-c",
            PROBE.replace(
                "d = polydem_cli",
                "assert (__import__('pathlib').Path(os.environ['POLYDEM_CACHE_DIR']) / 'numba-000000000000').is_dir()\nd = polydem_cli",
            ),
        ],
        capture_output=True,
        text=True,
        env=env,
    )
    assert r.returncode == 0, r.stderr
    got = json.loads(r.stdout.strip().splitlines()[-1])
    assert got["changed"] == []  # import: nothing
    assert got["dir"] == got["env"] and got["dir"].startswith(str(tmp_path / "cache" / "numba-"))  # the call: set
    assert not stale.exists()


def test_the_command_sets_the_cache_up_before_its_work(tmp_path):
    """``polydem schema`` compiles nothing but goes through the set-up: the folder of this source is created.
    (``polydem check`` would compile the stability estimate into the empty cache: over a minute.)"""
    env = {k: v for k, v in os.environ.items() if k not in ("NUMBA_CACHE_DIR",)}
    env["POLYDEM_CACHE_DIR"] = str(tmp_path / "cache")
    r = subprocess.run(polydem_cmd() + ["schema"], capture_output=True, text=True, env=env)
    assert r.returncode == 0, r.stderr
    assert r.stdout.startswith("# Scenario file reference")
    assert len(list((tmp_path / "cache").glob("numba-*"))) == 1
