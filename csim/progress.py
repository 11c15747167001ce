"""What csim shows on stderr while it works: a run's progress bar and the status of slow steps.

Both draw with rich, and only inside :func:`reporting` (the command line turns it on unless
``--quiet``), so that library calls, tests and the worker processes of ``csim compare``
print nothing:

- :class:`RunProgress`, the ``progress`` callback of :func:`csim.pipeline.run_case`: a bar
  against simulation time with the elapsed time and an ETA, on a terminal, once a run has
  taken ``delay`` (2 s);
- :func:`status`, a context manager around a slow step ("deriving the model", "compiling
  kernels (first run of this mechanism, ~30 s)"): a spinner on a terminal, one plain line
  on any other stderr (a log file, CI) once the step has taken ``delay`` (2 s).

A spinner and a bar shown at the same time are drawn together, one above the other.
"""
from __future__ import annotations

import sys
import threading
import time
from collections.abc import Iterator
from contextlib import contextmanager
from typing import TYPE_CHECKING

if TYPE_CHECKING:  # rich is imported where something is drawn: a warm run with --quiet pays nothing for it
    from rich.console import Console
    from rich.live import Live
    from rich.progress import Progress

__all__ = ["CountProgress", "RunProgress", "reporting", "status"]


class _Display:
    """Whether to draw (inside :func:`reporting`), and the console given for it (None: stderr)."""

    enabled: bool = False
    console: Console | None = None

    def is_terminal(self) -> bool:
        return self.console.is_terminal if self.console is not None else sys.stderr.isatty()

    def stream(self):
        return self.console.file if self.console is not None else sys.stderr

    def terminal(self) -> Console:
        """The console to draw on: the one given, else a rich console on stderr."""
        if self.console is None:
            from rich.console import Console

            self.console = Console(stderr=True)
        return self.console


_DISPLAY = _Display()


@contextmanager
def reporting(enabled: bool = True, console: Console | None = None) -> Iterator[None]:
    """Turn the progress bar and :func:`status` on (or off) for the block.

    Parameters
    ----------
    enabled : bool
        Draw at all; the command line passes ``not quiet``.
    console : rich.console.Console, optional
        Where to draw; default a console on the current ``sys.stderr``. Tests pass one that
        writes to a string and claims to be a terminal.

    Examples
    --------
    >>> with reporting(enabled=True):              # doctest: +SKIP
    ...     with status("deriving the model"):
    ...         build_model()
    """
    old = (_DISPLAY.enabled, _DISPLAY.console)
    _DISPLAY.enabled, _DISPLAY.console = enabled, console
    try:
        yield
    finally:
        _DISPLAY.enabled, _DISPLAY.console = old


def _start(live: Live) -> bool:
    """Start ``live``; False where rich cannot (a rich older than 14 with another display active)."""
    from rich.errors import LiveError

    try:
        live.start(refresh=True)
    except LiveError:
        return False
    return True


@contextmanager
def status(text: str, delay: float = 2.0) -> Iterator[None]:
    """Show that a slow step is under way, for as long as the block runs.

    On a terminal a spinner with ``text`` turns until the block ends, then disappears. On a
    stderr that is not a terminal, one plain line ``csim: TEXT ...`` is written once the block
    has run for ``delay`` seconds, so that a fast step leaves no trace in a log. Outside
    :func:`reporting` (library use, tests, worker processes) it shows nothing.

    Parameters
    ----------
    text : str
        What is being done, and how long it may take, e.g. ``"compiling kernels (first run
        of this mechanism, ~30 s)"``.
    delay : float
        Seconds after which the plain line appears on a stderr that is not a terminal [s];
        0 writes it at once.

    Examples
    --------
    >>> from csim.progress import status
    >>> with status("deriving the model"):        # doctest: +SKIP
    ...     model = build_numeric_model(definition)
    """
    if not _DISPLAY.enabled:
        yield
        return
    if _DISPLAY.is_terminal():
        from rich.live import Live
        from rich.spinner import Spinner

        live = Live(Spinner("dots", text=text), console=_DISPLAY.terminal(), transient=True, refresh_per_second=12.5,
                    redirect_stdout=False, redirect_stderr=False)
        started = _start(live)
        try:
            yield
        finally:
            if started:
                live.stop()
        return
    stream = _DISPLAY.stream()

    def line() -> None:
        stream.write(f"csim: {text} ...\n")
        stream.flush()

    if delay <= 0:
        line()
        yield
        return
    timer = threading.Timer(delay, line)
    timer.daemon = True
    timer.start()
    try:
        yield
    finally:
        timer.cancel()


class RunProgress:
    """Progress bar of one run against simulation time; call it with the current time.

    Drawn with rich on stderr, with the percentage, ``t = T/T_END s``, the elapsed time and
    an ETA, once ``delay`` seconds of wall time have passed, and only inside
    :func:`reporting` on a terminal. The bar disappears when closed. Use it as a context
    manager, or call :meth:`close`.

    Parameters
    ----------
    t_end : float
        End time of the run [s].
    delay : float
        Seconds of wall time before the bar first appears [s].
    label : str
        Text before the bar.
    enabled : bool, optional
        Draw at all; default: inside :func:`reporting`, on a terminal.
    """

    def __init__(self, t_end: float, delay: float = 2.0, label: str = "simulating", enabled: bool | None = None):
        if enabled is None:
            enabled = _DISPLAY.enabled
        self.enabled = bool(enabled) and _DISPLAY.is_terminal()
        self.t_end = float(t_end)
        self.delay = delay
        self.start = time.monotonic()
        self.drawn = False
        self._progress: Progress | None = None
        if self.enabled:  # the task starts now, so that elapsed time and ETA count from the run's start
            from rich.progress import (
                BarColumn,
                Progress,
                TaskProgressColumn,
                TextColumn,
                TimeElapsedColumn,
                TimeRemainingColumn,
            )

            self._progress = Progress(
                TextColumn("{task.description}"), BarColumn(), TaskProgressColumn(),
                TextColumn("t = {task.completed:.4g}/{task.total:g} s"), TimeElapsedColumn(),
                TextColumn("ETA"), TimeRemainingColumn(),
                console=_DISPLAY.terminal(), transient=True, redirect_stdout=False, redirect_stderr=False,
            )
            self._task = self._progress.add_task(label, total=self.t_end)

    def __call__(self, t: float) -> None:
        if self._progress is None:
            return
        self._progress.update(self._task, completed=min(max(float(t), 0.0), self.t_end))
        if not self.drawn and time.monotonic() - self.start >= self.delay:
            self.drawn = _start(self._progress.live)
            if self.drawn:
                self._progress.refresh()  # drawn at once, also beneath a status spinner

    def close(self) -> None:
        """Remove the bar (if it was drawn)."""
        if self._progress is not None and self.drawn:
            self._progress.stop()
            self.drawn = False

    def __enter__(self) -> RunProgress:
        return self

    def __exit__(self, *exc) -> None:
        self.close()


class CountProgress:
    """Progress bar of a study against the number of runs; call it as ``bar(done, total)``.

    Drawn with rich on stderr (runs done / total, elapsed time, ETA), only inside
    :func:`reporting` on a terminal; on any other stderr one plain line every ``every``
    seconds of wall time (a log of a long sweep in CI shows it moving). Use it as a context
    manager.

    Parameters
    ----------
    total : int
        Runs to make.
    label : str
        Text before the bar.
    every : float
        Seconds between the plain lines [s].
    """

    def __init__(self, total: int, label: str = "runs", every: float = 30.0):
        self.total, self.label, self.every = int(total), label, every
        self.enabled = _DISPLAY.enabled
        self._last = time.monotonic()
        self._progress: Progress | None = None
        if self.enabled and _DISPLAY.is_terminal():
            from rich.progress import (
                BarColumn,
                MofNCompleteColumn,
                Progress,
                TextColumn,
                TimeElapsedColumn,
                TimeRemainingColumn,
            )

            self._progress = Progress(
                TextColumn("{task.description}"), BarColumn(), MofNCompleteColumn(), TimeElapsedColumn(),
                TimeRemainingColumn(), console=_DISPLAY.terminal(), transient=True,
                redirect_stdout=False, redirect_stderr=False)
            self._task = self._progress.add_task(label, total=self.total)
            _start(self._progress.live)

    def __call__(self, done: int, total: int) -> None:
        if self._progress is not None:
            self._progress.update(self._task, completed=done, total=total)
        elif self.enabled and time.monotonic() - self._last >= self.every:
            self._last = time.monotonic()
            stream = _DISPLAY.stream()
            stream.write(f"csim: {self.label}: {done}/{total} done\n")
            stream.flush()

    def __enter__(self) -> CountProgress:
        return self

    def __exit__(self, *exc) -> None:
        if self._progress is not None:
            self._progress.stop()

