"""Checked reading of parsed TOML documents: one line naming the file, the key and what is wrong.

The machine file (:mod:`sim.machinefile`), the virtual-CMM task file
(:mod:`core.vcmm`) and the regression study file (:mod:`scenarios.regress`)
read their documents through a :class:`KeyReader`; each sets its own error
class (a :class:`core.exceptions.ConfigError`) so the CLI reports every one
the same way (exit 2).
"""

from __future__ import annotations

import math

from .exceptions import ConfigError, VmtError


class KeyReader:
    """Typed getters over a parsed document; every failure raises ``self.error_class`` as
    ``"<source>: <key>: <what is wrong>"``."""

    error_class: type[ConfigError] = ConfigError

    def __init__(self, source: str):
        self.source = source

    def fail(self, key, what):
        raise self.error_class(f"{self.source}: {key}: {what}")

    def table(self, key, v) -> dict:
        if not isinstance(v, dict):
            self.fail(key, f"expected a table, got {v!r}")
        return v

    def string(self, key, v, *, nonempty: bool = False) -> str:
        if not isinstance(v, str) or (nonempty and not v):
            self.fail(key, f"expected a {'non-empty ' if nonempty else ''}string, got {v!r}")
        return v

    def number(self, key, v, *, positive: bool = False, nonneg: bool = False) -> float:
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(float(v)):
            self.fail(key, f"expected a finite number, got {v!r}")
        if positive and v <= 0:
            self.fail(key, f"must be > 0, got {v!r}")
        if nonneg and v < 0:
            self.fail(key, f"must be >= 0, got {v!r}")
        return float(v)

    def integer(self, key, v, lo: int | None = None) -> int:
        if isinstance(v, bool) or not isinstance(v, int) or (lo is not None and v < lo):
            self.fail(key, "expected an integer" + (f" >= {lo}" if lo is not None else "") + f", got {v!r}")
        return int(v)

    def keys(self, key, t, allowed):
        """Refuse a key of table ``t`` (at ``key``) that is not in ``allowed``."""
        for k in t:
            if k not in allowed:
                self.fail(f"{key}.{k}" if key else k, f"unknown key (expected one of {', '.join(allowed)})")


def read_text_file(path, error_class: type[VmtError], what: str) -> str:
    """The UTF-8 text of a file (TOML documents, LinuxCNC's probe and compensation files), or
    ``error_class`` naming the path: ``no such <what>``, ``is a directory, not a <what>``, cannot
    read it, or not UTF-8 (with the byte)."""
    from pathlib import Path

    from core.atomic import input_problem

    p = Path(path)
    problem = input_problem(p, what)
    if problem == "no such file":
        raise error_class(f"{p}: no such {what}")
    if problem:
        raise error_class(f"{p}: {problem}")
    try:
        return p.read_text(encoding="utf-8")
    except UnicodeDecodeError as e:
        from core.atomic import not_text_problem

        raise error_class(f"{p}: {not_text_problem(p, e.object[:8], e)}") from None
