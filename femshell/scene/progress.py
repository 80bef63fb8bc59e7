"""Progress lines of a run: elapsed and remaining wall time, at most one line per ``interval`` seconds."""

from __future__ import annotations

import math
import sys
import time



def hms(sec):
    if not math.isfinite(sec):
        return "?"
    sec = int(round(sec))
    h, r = divmod(sec, 3600)
    m, s = divmod(r, 60)
    return f"{h}:{m:02d}:{s:02d}" if h else f"{m}:{s:02d}"


# ----------------------------------------------------------------------------- progress

class Progress:
    """Progress lines with elapsed time and an estimate of what remains."""

    def __init__(self, out, interval=0.0, quiet=False, wall_before=0.0):
        self.out = out
        self.interval = interval
        self.quiet = quiet
        self.t0 = time.perf_counter()
        self.wall_before = wall_before
        self.history = []     # (wall, fraction)
        self.last_print = -math.inf

    @property
    def elapsed(self):
        return time.perf_counter() - self.t0

    def say(self, text):
        if not self.quiet:
            print(text, file=self.out, flush=True)

    def failure(self, text):
        """A failed run is said even when quiet (then on stderr): its exit code alone does not say why."""
        print(text, file=sys.stderr if self.quiet else self.out, flush=True)

    def step(self, text, fraction=None, force=False):
        now = self.elapsed
        if fraction is not None and math.isfinite(fraction):
            self.history.append((now, float(fraction)))
            self.history = self.history[-12:]
        if not force and now - self.last_print < self.interval:
            return
        self.last_print = now
        eta = self.remaining()
        tail = f"{hms(self.wall_before + now)} elapsed" + (f", ~{hms(eta)} left" if eta is not None else "")
        self.say(f"{text}  [{tail}]")

    def remaining(self):
        """Wall seconds left, extrapolated from the last steps; None where that means nothing: the steps
        seen moved the run by less than MIN_FRACTION of its length (tiny steps, a huge t_final: their rate
        says little about the steps to come), or the figure exceeds MAX_ESTIMATE_S."""
        if len(self.history) < 2:
            return None
        (w0, f0), (w1, f1) = self.history[0], self.history[-1]
        if f1 >= 1.0:
            return 0.0
        if not f1 - f0 >= self.MIN_FRACTION or w1 <= w0:
            return None
        left = (1.0 - f1) * (w1 - w0) / (f1 - f0)
        return left if left <= self.MAX_ESTIMATE_S else None

    MIN_FRACTION = 1e-3
    MAX_ESTIMATE_S = 10 * 86400.0
