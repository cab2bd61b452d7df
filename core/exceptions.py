"""One error hierarchy for every bad input vmt can meet.

Every error carries a one-line message that names the file, row or
parameter and what is wrong. The CLI prints ``str(err)`` and exits 2.
"""

from __future__ import annotations


class VmtError(Exception):
    """Root of vmt's own errors: bad input, never a bug."""

    def __init__(self, message: str):
        # one line, always: a multi-line message would read like a traceback
        super().__init__(" ".join(str(message).split()))


class ConfigError(VmtError, ValueError):
    """A parameter or configuration value is out of its domain."""


class ProbeLogError(VmtError, ValueError):
    """A probe-log file does not follow ``probe-log/1``."""


class FitError(VmtError, ValueError):
    """Too few or degenerate points for a feature fit."""


class IdentifiabilityError(VmtError, ValueError):
    """A measurement design cannot identify the requested parameters."""


class PlanError(VmtError, ValueError):
    """A probing plan cannot be executed (collision, missed surface, limits)."""


class HardwareError(VmtError):
    """A machine or controller failed: lost connection, alarm, garbage."""


class OutputError(VmtError):
    """An output cannot be written as asked: not a regular file, not writable, not a valid result."""


def counted(n, singular: str, plural: str | None = None) -> str:
    """``n`` and its noun in the right number, for messages: ``counted(1, "entry")`` is ``1 entry``,
    ``counted(3, "entry")`` ``3 entries`` ("holds 1 entries" was said of a folder of one file).

    The plural is ``plural`` when given (``"axes"``), else the singular with ``es`` after s, x, ch
    or sh (``touch``: ``touches``), ``ies`` for a consonant and y (``entry``), ``s`` otherwise.
    """
    if n == 1:
        return f"{n} {singular}"
    if plural is None:
        if singular.endswith(("s", "x", "ch", "sh")):
            plural = singular + "es"
        elif singular.endswith("y") and singular[-2:-1] not in tuple("aeiou"):
            plural = singular[:-1] + "ies"
        else:
            plural = singular + "s"
    return f"{n} {plural}"
