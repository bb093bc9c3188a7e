"""``time.end_load_drop`` and its hold (interactions/controllers/load_drop.py): the halt hook fed a load history
by hand, against the rule written out: the run ends at the first step of a stretch below ``fraction`` × the
running peak that has lasted ``hold`` steps; a stretch that ends above the fraction starts the count again."""

from __future__ import annotations

import numpy as np
import pytest


def _first_end(loads, fraction, hold):
    """The rule written out in Python: the step the run ends at, or None."""
    peak, since = 0.0, None
    for step, f in enumerate(loads):
        peak = max(peak, f)
        if peak > 0 and f < fraction * peak:
            since = step if since is None else since
            if step - since >= hold:
                return step
        else:
            since = None
    return None


def _hook_end(loads, fraction, hold):
    from polydem_cli.interactions.controllers.load_drop import ACC_STEP, HALT_END, LoadDrop, _fresh_acc, _halt

    z1, zi = np.zeros(1), np.zeros(0, np.int64)
    tot = np.zeros(1)
    fam = LoadDrop(zi, fraction, 0, z1, tot, z1, zi, _fresh_acc(), np.int64(hold))
    for step, f in enumerate(loads):
        fam.acc[ACC_STEP] = step
        tot[0] = -f  # the reaction convention: |f2| = |−Σ F_2|
        if _halt(fam) == HALT_END:
            return step
    return None


@pytest.mark.parametrize("hold", [0, 1, 3, 6])
def test_the_stop_ends_where_the_written_out_rule_does(hold):
    """A peak of 10, a one-step spike down to 4 (below half the peak) at step 5, then a fall below from step 12 on:
    without a hold the spike ends the run; a hold of 1 or more lets the spike pass and ends it hold steps into the
    fall."""
    loads = [0, 5, 10, 9, 8, 4, 8, 7, 7, 6, 6, 5.5, 4.5, 4, 3, 2, 1, 0.5, 0.2, 0.1]
    want = _first_end(loads, 0.5, hold)
    assert _hook_end(loads, 0.5, hold) == want
    assert want == (5 if hold == 0 else 12 + hold)


def test_an_old_checkpoint_restores_with_the_load_above_the_fraction():
    """A checkpoint of the stop written before the hold existed (4 accumulators) restores, the stretch below the
    fraction not begun."""
    from polydem_cli.interactions.controllers.load_drop import ACC_BELOW, LOAD_DROP, LoadDrop, _fresh_acc

    z1, zi = np.zeros(1), np.zeros(0, np.int64)
    b = LoadDrop(zi, 0.5, 0, z1, z1, z1, zi, _fresh_acc(), np.int64(4))
    LOAD_DROP.restore(b, {"drop_acc": np.array([10.0, 3.0, 40.0, 0.0])})
    assert list(b.acc[:4]) == [10.0, 3.0, 40.0, 0.0] and b.acc[ACC_BELOW] == -1.0
