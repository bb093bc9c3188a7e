"""The progress line of a run that ends at its load drop: the ETA counts towards the end that will fire,
not towards the safety limit (the demo stopped at "[65.4 %] … ETA 0:00:52" when its load had dropped)."""

import io
import re

from polydem_cli.solvers.progress import Progress

from conftest import SCEN
from helpers import run_scenario


def _line(pr, step, wall, end):
    pr.last = 0.0  # report now
    pr.update(step, step, wall, end=end)
    return pr.stream.getvalue().strip().splitlines()[-1]


def test_eta_bounded_by_the_safety_limit_before_the_peak_and_from_the_fall_after_it():
    """1,000 steps of safety limit at 100 steps/s; the load peaks at step 300 and falls linearly to 10 % at
    step 500 (10 % of the peak lost per 22.2 steps)."""
    pr = Progress(1000, 1e-3, 10, stream=io.StringIO())

    def load(step):
        return min(1.0, step / 300) if step <= 300 else 1.0 - 0.9 * (step - 300) / 200

    for s in range(0, 301, 50):
        pr.update(s, s, s / 100, end=(load(s), 0.1, "load / its peak"))
    line = _line(pr, 300, 3.0, (load(300), 0.1, "load / its peak"))
    assert "ETA ≤ 0:00:07" in line and "load 100 % of its peak, ends below 10 %" in line
    assert "the safety limit" in line
    for s in range(310, 401, 10):
        pr.update(s, s, s / 100, end=(load(s), 0.1, "load / its peak"))
    line = _line(pr, 400, 4.0, (load(400), 0.1, "load / its peak"))
    # 55 % now, 45 % of the peak still to lose at 0.45 % per step: 100 steps, 1 s; 400 of 500 steps done
    assert "load 55 % of its peak" in line and "from the fall so far" in line
    assert "ETA 0:00:01" in line and "[~80.0%]" in line
    assert re.search(r"of at most 1 s", line)


def test_no_end_criterion_keeps_the_plain_line():
    pr = Progress(1000, 1e-3, 10, stream=io.StringIO())
    pr.update(0, 0, 0.0)
    line = _line(pr, 500, 5.0, None)
    assert "[ 50.0%]" in line and "ETA 0:00:05" in line and "peak" not in line and "≤" not in line


def test_a_run_ended_by_its_load_drop_says_so_in_its_last_progress_line(tmp_path):
    err = io.StringIO()
    summary = run_scenario(  # a safety limit past the load drop
        SCEN / "ch7" / "smoke_concrete_tension.toml", tmp_path / "s.h5", ["time.end_displacement=0.01"], stream=err,
        quiet=False,
    )  # fmt: skip
    assert summary["end_reason"].startswith("the load fell below 0.1 of its peak")
    assert summary["steps"] < summary["end_step"]
    last = [ln for ln in err.getvalue().splitlines() if ln.startswith("[")][-1]
    m = re.search(r"load (\d+(?:\.\d+)?) % of its peak: ended below 10 %", last)
    assert m and float(m.group(1)) < 10, last
    assert last.startswith("[100.0%]") and "safety limit" not in last and "ETA 0:00:00 " in last
