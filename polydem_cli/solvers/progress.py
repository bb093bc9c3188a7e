"""Progress lines of a run on stderr, shared by every solver family."""

from __future__ import annotations

import datetime as _dt
import math
import sys
import time


def write_progress(stream, tty, msg, force=False, width=110):
    """A progress line: rewritten in place on a terminal (a newline after the final one), else one per line."""
    if tty:
        stream.write("\r" + msg.ljust(width))
        if force:
            stream.write("\n")
    else:
        stream.write(msg + "\n")
    stream.flush()


class Ticker:
    """The cadence of a progress line: every 0.5 s on a terminal, every 10 s otherwise (a log), always when
    forced; never when quiet."""

    def __init__(self, quiet=False, stream=None):
        self.quiet = quiet
        self.stream = stream or sys.stderr
        self.tty = hasattr(self.stream, "isatty") and self.stream.isatty()
        self.every = 0.5 if self.tty else 10.0
        self.last = 0.0

    def due(self, force=False) -> bool:
        if self.quiet:
            return False
        now = time.time()
        if not force and now - self.last < self.every:
            return False
        self.last = now
        return True

    def emit(self, msg, force=False, width=110):
        write_progress(self.stream, self.tty, msg, force, width)


class Progress(Ticker):
    """Simulated time, steps/s and ETA on stderr (a line every ~10 s when not a terminal).

    The rate and the ETA are measured from the first report on (the first chunk carries one-time
    costs: cache loading, the first neighbour list), over a sliding window of the last ~60 s of wall
    time, so that a change of machine load shows within a minute; before two reports no ETA is printed.

    A run with an end criterion (a family's ``end_progress``: the load-drop stop) usually ends before its
    safety limit (``time.end_time`` / ``end_displacement``), so the limit only bounds the ETA: before the
    measure falls the line says "ETA ≤ …" and how far the measure is from its end; once it falls (the load
    after its peak) the end is estimated from the fall so far — the mean rate since the measure last stood
    at its top, extrapolated linearly to the end value — and the percentage counts towards that end.
    """

    WINDOW = 60.0  # s of wall time
    #: the measure counts as at its top (the load at its peak) above this
    TOP = 0.999

    def __init__(self, total_steps, dt, n, quiet=False, stream=None):
        super().__init__(quiet, stream)
        self.total, self.dt, self.n = total_steps, dt, n
        self.samples = []  # (wall, steps_done) at each report
        self.top_step = None  # last step at which the end measure stood at its top

    def rate_eta(self, step, steps_done, wall):
        """(steps/s, ETA in s or None) from the samples so far plus this one."""
        self.samples.append((wall, steps_done))
        while len(self.samples) > 2 and wall - self.samples[1][0] >= self.WINDOW:
            self.samples.pop(0)
        w0, s0 = self.samples[0]
        if len(self.samples) < 2 or wall <= w0 or steps_done <= s0:
            return (steps_done / wall if wall > 0 else 0.0), None
        rate = (steps_done - s0) / (wall - w0)
        return rate, (self.total - step) / rate

    def steps_to_end(self, step, end):
        """Steps until the end criterion ``end = (now, end value, what)`` fires, from its fall since it last
        stood at its top; None while it has not fallen."""
        now, stop, _ = end
        if now >= self.TOP or self.top_step is None or step <= self.top_step:
            return None
        fall = (1.0 - now) / (step - self.top_step)  # per step, mean since the top
        return max(0.0, (now - stop) / fall)

    def track(self, step, end):
        if end is not None and end[0] >= self.TOP:
            self.top_step = step

    def update(self, step, steps_done, wall, force=False, end=None):
        """Report at ``step`` (``steps_done`` in this session, ``wall`` s); ``end``: the end criterion's
        ``(now, end value, what)`` or None.  Call after every chunk: the end measure is tracked each time."""
        self.track(step, end)
        if not self.due(force):
            return
        rate, eta = self.rate_eta(step, steps_done, wall)
        head = f"{100.0 * step / self.total:5.1f}%"
        bound = ""
        tail = ""
        if end is not None:
            left = self.steps_to_end(step, end)
            what, _, of = end[2].partition(" / ")
            tail = f" | {what} {100 * end[0]:.0f} % of {of}, ends below {100 * end[1]:.0f} %"
            if end[0] < end[1]:  # the criterion has fired: this is the last line
                head, tail = "100.0%", f" | {what} {100 * end[0]:.4g} % of {of}: ended below {100 * end[1]:.0f} %"
                eta = 0.0
            elif left is not None and left < self.total - step:
                head = f"~{100.0 * step / (step + left):4.1f}%"
                eta = left / rate if eta is not None and rate > 0 else None
                tail += " (ETA from the fall so far)"
            elif eta is not None:
                bound = "≤ "
                tail += " (ETA: the safety limit)"
        eta_s = "--:--:--" if eta is None or not math.isfinite(eta) else bound + str(_dt.timedelta(seconds=int(eta)))
        msg = (
            f"[{head}] t = {step * self.dt:.6g} of {'at most ' if end is not None else ''}{self.total * self.dt:.6g} s"
            f" | step {step:,} | {rate:.3g} steps/s, {rate * self.n:.3g} particle-steps/s | ETA {eta_s}{tail}"
        )
        self.emit(msg, force)
