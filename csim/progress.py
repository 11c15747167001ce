"""A progress bar on stderr for runs that take more than a couple of seconds."""
from __future__ import annotations

import sys
import time


class ProgressBar:
    """Call with the current simulation time; draws once ``delay`` seconds have passed.

    Parameters
    ----------
    t_end : float
        End time of the run [s].
    enabled : bool
        Draw at all (off when stderr is not a terminal, or with ``--quiet``).
    delay : float
        Seconds of wall time before the bar first appears [s].
    stream : file
    """

    def __init__(self, t_end: float, enabled: bool = True, delay: float = 2.0, stream=None, label: str = ""):
        self.stream = stream or sys.stderr
        self.t_end = t_end
        self.enabled = enabled
        self.delay = delay
        self.label = label
        self.start = time.monotonic()
        self.last = 0.0
        self.drawn = False

    @classmethod
    def for_terminal(cls, t_end: float, quiet: bool, label: str = "") -> ProgressBar:
        return cls(t_end, enabled=not quiet and sys.stderr.isatty(), label=label)

    def __call__(self, t: float) -> None:
        if not self.enabled:
            return
        now = time.monotonic()
        if now - self.start < self.delay or now - self.last < 0.1:
            return
        self.last = now
        frac = min(max(t / self.t_end, 0.0), 1.0)
        width = 30
        bar = "#" * int(frac * width) + "." * (width - int(frac * width))
        self.stream.write(f"\r{self.label}[{bar}] {100 * frac:5.1f}%  t = {t:.4g}/{self.t_end:g} s  "
                          f"{now - self.start:.1f} s elapsed")
        self.stream.flush()
        self.drawn = True

    def close(self) -> None:
        if self.drawn:
            self.stream.write("\r" + " " * 79 + "\r")
            self.stream.flush()
