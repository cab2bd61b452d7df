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
