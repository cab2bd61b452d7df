"""The CLI's one way to read a log: the reader's warnings reach the user of every command.

The probe-log and positioning-log readers warn without refusing (an empty
angle column read as 0 beside written ones, a file that ends without an end
of line); until session 31 only ``vmt check`` printed those, and every other
command read the same file silently (input31, warn31). Every command that
reads a log reads it here: each warning is printed once, to stderr, as
``vmt COMMAND: warning: ...``, and a command that writes JSON carries the
same lines in it as ``input_warnings`` (:func:`input_warnings`).
``vmt check`` reads the log itself: the warnings are its summary's own lines.
"""

from __future__ import annotations

import sys


def say_warnings(command: str, warnings, bar=None) -> None:
    """Print each of ``warnings`` on stderr, one line each, named by ``command``
    (a progress line ``bar``, if one is drawn, is cleared first so the warning has a line of its own)."""
    if not warnings:
        return
    clear = getattr(bar, "clear", None)
    if callable(clear):
        clear()
    for w in warnings:
        print(f"vmt {command}: warning: {w}", file=sys.stderr, flush=True)


def read_probe(path, command: str, *, progress=None, bar=None):
    """:func:`core.probelog.read_probe_log` of ``path``, its warnings said (:func:`say_warnings`)."""
    from core.probelog import read_probe_log

    log = read_probe_log(path, progress=progress)
    say_warnings(command, log.warnings, bar if bar is not None else progress)
    return log


def read_positioning(path, command: str, *, kind: str = "log", bar=None):
    """A positioning test (:func:`core.positioning.load_positioning`, ``kind`` as there), its reader's
    warnings said (:func:`say_warnings`)."""
    from core.positioning import load_positioning

    log = load_positioning(path, kind=kind)
    say_warnings(command, log.warnings, bar)
    return log


def input_warnings(*logs) -> list[str]:
    """The readers' warnings of ``logs`` (None skipped), for a command's JSON: ``input_warnings``."""
    return [w for log in logs if log is not None for w in log.warnings]
