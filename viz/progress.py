"""Terminal progress with an estimate of the time left, for long runs.

Library code never prints: a long loop (campaign, Monte Carlo, hardware run)
takes an optional ``progress`` callback and calls ``progress(done, total)``.
The CLI passes a :class:`TerminalProgress`, which draws one self-rewriting
line on stderr only when stderr is a terminal and is silent otherwise (logs,
pipes, CI, tests).

Examples
--------
>>> def monte_carlo(n, rng, progress=None):               # library side
...     for i in range(n):
...         ...
...         if progress is not None:
...             progress(i + 1, n)
>>> with TerminalProgress("Monte Carlo") as bar:          # doctest: +SKIP
...     monte_carlo(1000, rng, progress=bar)
"""

from __future__ import annotations

import sys
import time
from collections.abc import Callable
from typing import TextIO

#: What library code accepts: ``progress(done, total)``.
ProgressCallback = Callable[[int, int], None]


def no_progress(done: int, total: int) -> None:
    """A callback that does nothing (the default of library functions)."""


def format_duration(seconds: float) -> str:
    """``"42 s"``, ``"3 min 05 s"``, ``"2 h 07 min"``."""
    s = max(0, int(round(seconds)))
    if s < 60:
        return f"{s} s"
    if s < 3600:
        return f"{s // 60} min {s % 60:02d} s"
    return f"{s // 3600} h {(s % 3600) // 60:02d} min"


class TerminalProgress:
    """A progress line with the time left, drawn only on a terminal.

    Parameters
    ----------
    label : str
        What is running (``"campaign"``, ``"Monte Carlo"``).
    stream : text stream, optional
        Where to draw; default ``sys.stderr`` (looked up at construction).
    min_interval_s : float
        Minimum time between redraws (the last call always draws).
    clock : callable, optional
        Monotonic clock in s (tests pass a fake one).
    counts_seconds : bool
        ``done`` and ``total`` count the seconds an earlier run took (``vmt bench``'s benchmarks, weighted by
        their last wall times): before the first item is done, the time left is that run's, less the time
        spent since (said "as the last run"); without it there is no estimate until an item is done, and a
        single long item (``vmt bench --only X``) showed none at all.

    Notes
    -----
    The estimate is the mean rate so far: ``left = elapsed / (done -
    done_before) * (total - done)``; no estimate before the first item is
    done. ``done_before`` (a count of items) is 0 unless :meth:`begin` says
    how many were done before this run (a resumed campaign: their time is
    not in ``elapsed``).
    """

    def __init__(self, label: str, *, stream: TextIO | None = None,
                 min_interval_s: float = 0.2, clock: Callable[[], float] = time.monotonic,
                 counts_seconds: bool = False):
        self.label = label
        self.counts_seconds = bool(counts_seconds)
        self.stream = sys.stderr if stream is None else stream
        isatty = getattr(self.stream, "isatty", None)
        self.enabled = bool(isatty()) if callable(isatty) else False
        self.min_interval_s = float(min_interval_s)
        self._clock = clock
        self._t0 = clock()
        self._last_draw = -float("inf")
        self._width = 0
        self._drawn = False
        self.done_before = 0

    def begin(self, done: int, total: int) -> None:
        """This run starts with ``done`` of ``total`` already done (a resumed campaign): the time
        left counts from now, at the rate of the items this run does; the line is drawn."""
        self.done_before = int(done)
        self._t0 = self._clock()
        self(done, total)

    def line(self, done: int, total: int) -> str:
        """The text of the progress line for ``done`` of ``total``."""
        elapsed = self._clock() - self._t0
        if total > 0:
            frac = min(max(done / total, 0.0), 1.0)
            bar = "#" * int(round(20 * frac))
            head = f"{self.label}: [{bar:<20}] {done}/{total} ({100 * frac:3.0f} %)"
        else:
            head = f"{self.label}: {done}"
        if done >= total > 0:
            return f"{head}  done in {format_duration(elapsed)}"
        if done > self.done_before and total > 0:
            left = elapsed / (done - self.done_before) * (total - done)
            return f"{head}  ~{format_duration(left)} left"
        if self.counts_seconds and total > done:
            return f"{head}  ~{format_duration(max(total - done - elapsed, 0.0))} left as the last run"
        return head

    def __call__(self, done: int, total: int) -> None:
        if not self.enabled:
            return
        now = self._clock()
        final = total > 0 and done >= total
        if not final and now - self._last_draw < self.min_interval_s:
            return
        self._last_draw = now
        text = self.line(done, total)
        pad = " " * max(0, self._width - len(text))
        self._width = len(text)
        self.stream.write("\r" + text + pad)
        self.stream.flush()
        self._drawn = True

    def clear(self) -> None:
        """Erase the line before the caller prints one of its own (it is drawn again at the next call)."""
        if self.enabled:
            self.stream.write("\r\033[K")
            self.stream.flush()
            self._last_draw = -float("inf")

    def close(self) -> None:
        """End the line (if anything was drawn)."""
        if self.enabled and self._drawn:
            self.stream.write("\n")
            self.stream.flush()
            self._drawn = False

    def __enter__(self) -> TerminalProgress:
        return self

    def __exit__(self, *exc) -> None:
        self.close()
