import os
import sys
from pathlib import Path

import pytest

import polydem_cli

polydem_cli.setup_jit_cache()  # the tests compile in-process: the same cache as the polydem command's
# every polydem run of the suite (in-process and the commands it starts) on one process unless a test asks for
# ranks: `--ranks auto` would start ranks beside the other test worker (tests/test_ranks_auto.py tests auto itself)
os.environ.setdefault("POLYDEM_RANKS", "1")

ROOT = Path(__file__).resolve().parents[1]
SCEN = ROOT / "scenarios"


@pytest.fixture
def root():
    return ROOT


def polydem_cmd():
    """The polydem CLI of this checkout (the console script of the venv, or python -m)."""
    exe = Path(sys.executable).with_name("polydem")
    if exe.exists():
        return [str(exe)]
    return [sys.executable, "-m", "polydem_cli"]


#: dyn per force unit of the plots (1 N = 1e5 dyn): the tests' own table, not the report's
DYN_PER_UNIT = {"kN": 1e8, "N": 1e5, "mN": 1e2, "µN": 1e-1, "nN": 1e-4}
