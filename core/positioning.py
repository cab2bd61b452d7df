"""Positioning tests of one axis (ISO 230-2:2014): logs, importers, the figures.

A positioning test moves one axis to ``m`` target positions ``P_i``, ``n``
times approaching each from below (direction ``+``, the standard's ``↑``)
and from above (``-``, ``↓``), and an instrument (laser interferometer,
reference scale) measures where the axis went, ``P_ij``. This module

- reads, validates and writes ``positioning-log/1`` files (CSV with
  ``# key: value`` metadata; the format is described in README.md and in
  :func:`read_positioning_log`), with the same one-line typed errors as
  :mod:`core.probelog`;
- imports the ``.dat`` files of the EPICS motion package ecmc
  (:func:`parse_ecmc_dat`) and a generic whitespace/CSV table of target,
  cycle, direction and measured value (:func:`parse_table`);
- arranges a log into per-target, per-direction arrays
  (:func:`arrange`) and evaluates every figure of ISO 230-2
  (:func:`iso230_2`, :func:`figures`), returning a frozen
  :class:`Iso2302Result`;
- gives the standard's own model of the data as a baseline a model-
  discovery engine can test against (:func:`baseline`);
- estimates the uncertainty of each figure from the measuring conditions
  (:func:`figure_uncertainty`, ISO/TR 230-9 style).

The definitions (ISO 230-2, "Terms and definitions"; numbered 2.x in the
2006 edition, the numbers cited below, and carried unchanged into clause 3
of the 2014 edition; checked against two public reproductions, see
``tests/core/test_positioning.py``), for target ``i`` and cycle ``j``:

==========  =============================================================
2.5         positional deviation ``x_ij = P_ij - P_i``
2.10        mean unidirectional positional deviation ``x̄_i↑ = (1/n) Σ_j x_ij↑``
            (likewise ``↓``)
2.11        mean bidirectional positional deviation ``x̄_i = (x̄_i↑ + x̄_i↓) / 2``
2.12        reversal value ``B_i = x̄_i↑ - x̄_i↓``
2.13        reversal value of the axis ``B = max |B_i|``
2.14        mean reversal value ``B̄ = (1/m) Σ_i B_i``
2.15        estimator of the unidirectional standard uncertainty
            ``s_i↑ = sqrt(Σ_j (x_ij↑ - x̄_i↑)² / (n - 1))``
2.16        unidirectional repeatability ``R_i↑ = 4 s_i↑``
2.17        bidirectional repeatability
            ``R_i = max(2 s_i↑ + 2 s_i↓ + |B_i|, R_i↑, R_i↓)``
2.18        ``R↑ = max R_i↑``, ``R↓ = max R_i↓``
2.19        ``R = max R_i``
2.20        unidirectional systematic positioning error of an axis
            ``E↑ = max x̄_i↑ - min x̄_i↑``
2.21        bidirectional systematic positioning error of an axis
            ``E = max(x̄_i↑, x̄_i↓) - min(x̄_i↑, x̄_i↓)`` (over all i, both
            directions together)
2.22        range of the mean bidirectional positional deviation
            ``M = max x̄_i - min x̄_i``
2.23        unidirectional accuracy
            ``A↑ = max(x̄_i↑ + 2 s_i↑) - min(x̄_i↑ - 2 s_i↑)``
2.24        bidirectional accuracy ``A = max(x̄_i↑ + 2 s_i↑, x̄_i↓ + 2 s_i↓)
            - min(x̄_i↑ - 2 s_i↑, x̄_i↓ - 2 s_i↓)``
==========  =============================================================

Units: arrays keep the file's unit (mm for a linear axis, degrees for a
rotary one); :meth:`Iso2302Result.to_report` gives µm (arc seconds for a
rotary axis), the unit in every key.
"""

from __future__ import annotations

import csv
import io
import math
import os
import re
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Iterable, Mapping

import numpy as np

from .atomic import write_text_atomic
from .exceptions import VmtError, counted
from .probelog import (COMMENT_AFTER_HEADER, OK_CELLS, T_MAX_S, TEMP_RANGE_C, _comment_row, _num, add_meta,
                       csv_lines, is_number, last_row_check, ok_statuses, step_back, value_range)
from .probelog import (NUMBER_FORMAT_KEY, WRITE_ON_STEP_RTOL_POSITIONING, first_finer, most_decimals,
                       number_format_value, on_step, parse_number_format, step_decimals)

FORMAT = "positioning-log/1"
#: Format of :meth:`Iso2302Result.to_report` (what ``vmt iso230-2 --json`` writes).
REPORT_FORMAT = "vmt-iso230-2/1"
#: ISO 230-2 asks five approaches in each direction at every target for the
#: full test (and at least five targets); fewer are evaluated with a warning.
N_STANDARD = 5
#: Target positions ISO 230-2 asks of a linear axis: at least this many per metre of travel, and at least
#: :data:`TARGETS_MIN` in all, for axes up to :data:`TARGETS_RULE_MM` of travel (review30 F4: the warning
#: quoted the rule but checked 5 only; 6 targets over 2000 mm passed). The travel is the targets' span, a lower
#: bound of the measurement travel: the count asked is never more than the standard's.
TARGETS_PER_M = 5
TARGETS_MIN = 5
#: Travel up to which the per-metre rule is the standard's (2 m). ISO 230-2's target-count rules for a
#: longer linear axis and for a rotary axis are not known to vmt (neither the positioning-log spec nor the
#: docs state them): no count is asked there and the report says the rule is not checked (session 31; until
#: then a rotary axis was asked "at least 5", a clause vmt had not read, and a longer one the 2 m count, both
#: silent once met).
TARGETS_RULE_MM = 2000.0
#: The repeatability estimator s (2.15) needs n - 1 >= 1.
N_MIN = 2
#: Targets closer than this (file unit) are the same target P_i.
TARGET_TOL = 1e-6
#: Largest positional deviation x_ij = P_ij - P_i said without a warning, per file unit: 1 mm, 0.0573 deg (the
#: machine file's bounds on a translation / rotation error, core.iso.MAX_LINEAR_UM / MAX_ANGULAR_URAD: tens of
#: times a real machine's uncompensated positioning error, tens of um per metre or tens of arc seconds). A
#: larger deviation is warned of, naming the row and value (review32d F2: a reading typed 100 m off its target,
#: or deviations in um written in measured_mm, were evaluated to R 1.8e8 um without a word); it is refused when
#: it also reaches half the spacing of the targets (:func:`arrange`): the reading then lies nearer another
#: target than its own, which no positioning error does, a unit or typing slip. The reader's own bound (100 m,
#: core.probelog.value_range) is on the positions themselves, a physical size, and says nothing of this.
DEVIATION_WARN = {"mm": 1e-3 * 1000.0, "deg": 1000.0e-6 * 180.0 / math.pi}
#: Report scale per file unit: mm -> µm, deg -> arc seconds.
REPORT_UNIT = {"mm": ("um", 1e3), "deg": ("arcsec", 3600.0)}
CYCLE_KINDS = ("linear", "pilgrim")
#: Metadata key of the tool (probe) offsets J in effect during the test, ``X,Y,Z`` in mm: the
#: targets are the commanded positions (the readings the controller reports, tool offset applied),
#: and the axis (joint) position of a target is ``target + J`` along the axis tested
#: (:attr:`PositioningLog.joint_offset`), where vmt's error tables and LinuxCNC's compensation
#: tables are indexed. Absent: J = 0, the targets are the axis positions (a laser test run in
#: machine coordinates, no tool offset). ``vmt simulate positioning`` writes it when J is not 0.
TOOL_OFFSET_KEY = "tool_offset_mm"

_NUMERIC_REQUIRED = {"mm": ("target_mm", "measured_mm"), "deg": ("target_deg", "measured_deg")}


class PositioningLogError(VmtError, ValueError):
    """A positioning log (or an imported table) cannot be read or evaluated."""


# ---------------------------------------------------------------------------
# the log in memory


@dataclass(frozen=True)
class PositioningLog:
    """One positioning test in memory, in the file's unit.

    Attributes
    ----------
    meta : dict[str, str]
        ``# key: value`` metadata in file order (unknown keys kept).
    target : (N,) float
        Commanded target position P_i of each reading, mm (deg if
        ``unit == "deg"``).
    cycle : (N,) int
        Run number j >= 1.
    direction : (N,) int
        +1: the target was approached moving in the positive direction
        (ISO 230-2 ``↑``), -1: in the negative direction (``↓``).
    measured : (N,) float
        Position measured by the instrument, P_ij (same unit); NaN only in
        rows whose status is not ``ok``.
    t_s : (N,) float or None
        Seconds since the test started (NaN where a row has none).
    status : (N,) object
        ``"ok"`` (or ``""``) or why the reading is not valid.
    extra : dict[str, numpy.ndarray]
        Other columns: ``temp_<name>_C`` as float, anything else as text.
    source : str
        Where the log came from, for error messages.
    warnings : tuple of str
        What reading found doubtful but not wrong (one line each): a last
        row without an end of line that may be cut short
        (:func:`core.probelog.last_row_check`). :func:`arrange` passes them on.
    lines : (N,) int or None
        The file line of each row (for messages naming it, as the reader's own do); None when the log was not
        read from a file with lines (built in memory, an ecmc ``.dat``).
    text_steps : dict[str, float]
        The step the target and measured columns were printed to, file unit (session 34, review34: a log printed
        to 0.01 mm gave R 17.9 um for 5.4 at full precision without a word): ``10^-k`` for the most decimals
        ``k`` written in the column (``405.77``: 0.01), 0 where the metadata ``number_format`` declares the
        numbers exact (vmt's words, :data:`core.probelog.NUMBER_FORMAT_EXACT`) and ``10^-K`` for a column it
        declares printed to ``K`` decimals. Keyed ``target`` and ``measured``; empty when unknown (built in
        memory, an ecmc ``.dat``). :func:`printed_step` turns it into the rounding's uncertainty.
    """

    meta: dict[str, str]
    target: np.ndarray
    cycle: np.ndarray
    direction: np.ndarray
    measured: np.ndarray
    t_s: np.ndarray | None = None
    status: np.ndarray | None = None
    extra: dict[str, np.ndarray] = field(default_factory=dict)
    source: str = "<memory>"
    warnings: tuple = ()
    lines: np.ndarray | None = None
    text_steps: dict = field(default_factory=dict)

    @property
    def n(self) -> int:
        """Number of readings (rows)."""
        return int(self.target.shape[0])

    def __len__(self) -> int:
        return self.n

    @property
    def unit(self) -> str:
        """``mm`` (linear axis, default) or ``deg`` (rotary axis)."""
        return self.meta.get("unit", "mm") or "mm"

    @property
    def axis(self) -> str:
        return self.meta.get("axis", "")

    @property
    def ok(self) -> np.ndarray:
        """(N,) bool: the readings the evaluation uses."""
        if self.status is None:
            return np.ones(self.n, bool)
        return np.array([s in OK_CELLS for s in self.status], dtype=bool)

    @property
    def deviation(self) -> np.ndarray:
        """(N,) positional deviation ``x_ij = P_ij - P_i`` (ISO 230-2 2.5), file unit."""
        return self.measured - self.target

    @property
    def tool_offset_mm(self) -> tuple[float, float, float] | None:
        """The tool (probe) offsets J X, Y, Z of the test, mm (:data:`TOOL_OFFSET_KEY`), or None."""
        return _tool_offset(self.meta, self.source)

    @property
    def joint_offset(self) -> float:
        """Axis (joint) position minus target along the axis tested, file unit: J of that axis
        (:data:`TOOL_OFFSET_KEY`), 0.0 without the key."""
        J = self.tool_offset_mm
        return 0.0 if J is None else J[_LINEAR.index(self.axis)]


_LINEAR = ("X", "Y", "Z")


def _tool_offset(meta: Mapping[str, str], src: str) -> tuple[float, float, float] | None:
    """The :data:`TOOL_OFFSET_KEY` of ``meta`` as 3 floats (mm), None without it; one-line errors:
    not 3 numbers, beyond the probe log's length bound, a log in degrees or of no linear axis."""
    text = meta.get(TOOL_OFFSET_KEY)
    if text is None:
        return None
    where = f"{src}: metadata {TOOL_OFFSET_KEY}"
    parts = [p.strip() for p in str(text).split(",")]
    if len(parts) != 3:
        raise PositioningLogError(f"{where} {text!r}: expected 3 numbers X,Y,Z in mm")
    J = tuple(_finite_number(p, where, "value") for p in parts)
    _, big, _, why = value_range("X_mm")
    if any(abs(v) > big for v in J):
        raise PositioningLogError(f"{where} {text!r}: beyond +-{big:g} mm ({why})")
    if (meta.get("unit", "mm") or "mm") != "mm":
        raise PositioningLogError(f"{where}: a tool offset applies to a linear axis, the log is in "
                                  f"{meta.get('unit')!r}")
    if meta.get("axis", "") not in _LINEAR:
        raise PositioningLogError(f"{where}: needs the axis tested (metadata axis X, Y or Z), got "
                                  f"{meta.get('axis', '')!r}")
    return J


def _direction_array(values, src: str) -> np.ndarray:
    out = np.empty(len(values), dtype=np.int64)
    for r, v in enumerate(values):
        if isinstance(v, str):
            s = v.strip()
            if s not in ("+", "-"):
                raise PositioningLogError(f"{src}: row {r}: direction {v!r} is not '+' or '-'")
            out[r] = 1 if s == "+" else -1
        else:
            try:
                f = float(v)
            except (TypeError, ValueError):
                raise PositioningLogError(f"{src}: row {r}: direction {v!r} is not '+' or '-'") from None
            if f not in (1.0, -1.0):
                raise PositioningLogError(f"{src}: row {r}: direction {v!r} is not +1 or -1")
            out[r] = int(f)
    return out


def make_positioning_log(target, cycle, direction, measured, *, t_s=None, status=None,
                         extra: Mapping[str, Iterable] | None = None,
                         meta: Mapping[str, str] | None = None, unit: str = "mm",
                         source: str = "<memory>", lines: list[int] | None = None) -> PositioningLog:
    """Build and validate a :class:`PositioningLog` from sequences (file unit).

    ``direction`` holds ``"+"``/``"-"`` or +1/-1; ``unit`` is ``mm`` or
    ``deg``; ``format`` and ``unit`` are written into the metadata. ``lines``:
    the file line of each reading, for error messages (an importer's).
    """
    m = {"format": FORMAT}
    m.update({str(k): str(v) for k, v in (meta or {}).items()})
    m["unit"] = unit
    tgt = np.asarray(target, dtype=float).reshape(-1).copy()
    n = tgt.shape[0]
    try:
        cyc_f = np.asarray(cycle, dtype=float).reshape(-1)
    except (TypeError, ValueError):
        raise PositioningLogError(f"{source}: cycle numbers must be integers") from None
    if cyc_f.shape[0] == n and np.any(cyc_f != np.round(cyc_f)):
        r = int(np.argmax(cyc_f != np.round(cyc_f)))
        raise PositioningLogError(f"{source}: row {r}: cycle {cyc_f[r]!r} is not a whole number")
    ts = None if t_s is None else np.asarray(t_s, dtype=float).reshape(-1).copy()
    st = None if status is None else np.array(["" if s is None else str(s) for s in status], dtype=object)
    ex = {}
    for k, v in (extra or {}).items():
        ex[k] = (np.asarray(v, dtype=float).copy() if _is_temp(k)
                 else np.array(["" if s is None else str(s) for s in v], dtype=object))
    log = PositioningLog(meta=m, target=tgt, cycle=cyc_f.astype(np.int64),
                         direction=_direction_array(list(direction), source),
                         measured=np.asarray(measured, dtype=float).reshape(-1).copy(),
                         t_s=ts, status=st, extra=ex, source=source,
                         lines=None if lines is None or len(lines) != n else np.asarray(lines, dtype=np.int64))
    _validate(log, None if log.lines is None else list(log.lines))
    return log


def _is_temp(name: str) -> bool:
    return name.startswith("temp_") and name.endswith("_C") and len(name) > 7


def _finite_number(text: str, where: str, what: str) -> float:
    """``float(text)``, or a one-line error ``"<where>: <what> '<text>' is not a number"``.

    A number has the form :data:`core.probelog.NUMBER` (``[+-]digits[.digits][e[+-]digits]``, ASCII
    digits): ``1_0`` and non-ASCII digits, which Python's float() alone reads, are not numbers.
    """
    try:
        v = float(text)
    except ValueError:
        v = None
    if v is not None and not math.isfinite(v):
        raise PositioningLogError(f"{where}: {what} {text!r} is not finite")
    if v is None or not is_number(text):
        raise PositioningLogError(f"{where}: {what} {text!r} is not a number")
    return v


def _target_groups(values: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The targets P_i among ``values``: ``(group of each value, first value of each group)``.

    Sorted, a value more than :data:`TARGET_TOL` above the one before starts a new target; closer
    values are the same target (a chain). The one grouping both the duplicate check
    (:func:`_validate`) and :func:`arrange` use, so what the check lets through never lands on
    another reading's place in the arrays.
    """
    order = np.argsort(values, kind="stable")
    groups = np.zeros(values.size, dtype=np.int64)
    if values.size == 0:
        return groups, np.empty(0)
    new = np.diff(values[order]) > TARGET_TOL
    groups[order] = np.concatenate([[0], np.cumsum(new)])
    starts = np.concatenate([[0], np.flatnonzero(new) + 1])
    return groups, values[order][starts]


# ---------------------------------------------------------------------------
# reading positioning-log/1


def _read_text(path, what: str) -> tuple[str, str]:
    p = Path(path)
    src = str(p)
    if not p.exists():
        raise PositioningLogError(f"{src}: no such file")
    if p.is_dir():
        raise PositioningLogError(f"{src}: is a directory, not {what}")
    try:
        return p.read_text(encoding="utf-8-sig"), src
    except UnicodeDecodeError as e:
        from core.atomic import not_text_problem

        with open(p, "rb") as f:  # the decoded bytes e.object start after a byte-order mark
            head = f.read(8)
        bom = 3 if head.startswith(b"\xef\xbb\xbf") else 0
        raise PositioningLogError(f"{src}: {not_text_problem(src, head, e, bom)}") from None


def read_positioning_log(path: str | os.PathLike) -> PositioningLog:
    """Read and validate a ``positioning-log/1`` file.

    The file: UTF-8 CSV, one header row, one row per reading in the order
    measured; ``# key: value`` lines before the header are metadata, of
    which ``format: positioning-log/1`` is required (``axis``, ``unit`` =
    ``mm`` or ``deg``, ``machine``, ``instrument``, ``cycle_kind`` =
    ``linear`` or ``pilgrim`` are known; others are kept). Required
    columns ``target_mm, cycle, direction, measured_mm`` (``target_deg``,
    ``measured_deg`` for a rotary axis); optional ``t_s``,
    ``temp_<name>_C``, ``status``.

    Raises
    ------
    PositioningLogError
        One line naming the file, the data row (0-based) and file line:
        missing/empty file, no or wrong ``format``, missing column, a
        value that is not a number (the form :data:`core.probelog.NUMBER`),
        a cycle that is not a whole number >= 1, a direction that is not
        ``+`` or ``-``, a value beyond the probe log's bounds (positions
        beyond 100 m or 1e6 deg, ``t_s`` below 0 or beyond 1e10 s, a
        temperature outside -273.15..1000 C), time going backwards, the
        same (target, cycle, direction) twice among valid readings (targets
        grouped as :func:`arrange` groups them), a torn last row (the probe log's rule,
        :func:`core.probelog.last_row_check`: a last row without an end of
        line with too few fields, a number cut to no number, or a status
        other than ``ok``; one that still reads whole is kept with a warning),
        a ``number_format`` line that does not hold (naming its file line,
        the probe log's words) or a cell with more decimals than it declares.
    """
    text, src = _read_text(path, "a positioning log")
    return parse_positioning_log(text, source=src)


def _split_meta(text: str, src: str, warnings: list | None = None
                ) -> tuple[dict[str, str], dict[str, int], list[str], int]:
    """``(meta, meta_line, lines, i)``: the ``# key: value`` lines before the header, each key's file line
    (``meta_line``, 1-based, for errors that name the line), the file's lines and the header's index."""
    if not text.strip():
        raise PositioningLogError(f"{src}: empty file")
    lines = csv_lines(text)
    meta: dict[str, str] = {}
    meta_line: dict[str, int] = {}
    i = 0
    while i < len(lines) and (lines[i].startswith("#") or not lines[i].strip()):
        if lines[i].startswith("#"):  # a key vmt reads given twice with two values is refused (the probe log's rule)
            add_meta(meta, meta_line, lines[i], i + 1, src, error=PositioningLogError, warnings=warnings)
        i += 1
    if i >= len(lines):
        raise PositioningLogError(f"{src}: no header row (only metadata lines)")
    return meta, meta_line, lines, i


def parse_positioning_log(text: str, source: str = "<memory>") -> PositioningLog:
    """Parse ``positioning-log/1`` text (see :func:`read_positioning_log`)."""
    src = source
    meta_warnings: list[str] = []
    meta, meta_line, lines, i = _split_meta(text, src, meta_warnings)
    fmt = meta.get("format")
    if fmt is None:
        raise PositioningLogError(f"{src}: no '# format: {FORMAT}' metadata line")
    if fmt != FORMAT:
        raise PositioningLogError(f"{src}: format {fmt!r} is not {FORMAT!r}")
    header_line = i + 1
    reader = csv.reader(io.StringIO("\n".join(lines[i:])))
    header = [h.strip() for h in next(reader)]
    seen: set[str] = set()
    for h in header:
        if not h:
            raise PositioningLogError(f"{src}: line {header_line}: empty column name")
        if h in seen:
            raise PositioningLogError(f"{src}: line {header_line}: duplicate column {h!r}")
        seen.add(h)
    unit = meta.get("unit", "")
    if unit and unit not in _NUMERIC_REQUIRED:
        raise PositioningLogError(f"{src}: metadata unit {unit!r} is not 'mm' or 'deg'")
    if not unit:
        unit = "deg" if "target_deg" in seen else "mm"
        meta["unit"] = unit
    tname, mname = _NUMERIC_REQUIRED[unit]
    other = "deg" if unit == "mm" else "mm"
    for c in (tname, "cycle", "direction", mname):
        if c not in seen:
            hint = (f" (the columns are in {other}: set '# unit: {other}')"
                    if c in (tname, mname) and c.replace(unit, other) in seen else "")
            raise PositioningLogError(f"{src}: missing required column {c!r}{hint}")
    raw: list[list[str]] = []
    line_of_row: list[int] = []
    last_end = 0
    unterminated, n_lines = not text.endswith(("\n", "\r")), len(lines)

    def last_row(row, r, ln):  # where a writer that died would have stopped: the probe log's rule
        return last_row_check(src, header, row, r, ln, error=PositioningLogError, statuses=("ok",),
                              remedy="delete the line",
                              numeric=lambda h: h in (tname, mname, "cycle", "t_s") or _is_temp(h))

    # the file line where each record starts (a quoted cell may hold ends of line; reader.line_num
    # counts the lines read, the header's first) and where the last one read ends
    ln, end = header_line + 1, header_line
    try:
        for row in reader:
            ln, end = end + 1, header_line - 1 + reader.line_num
            if not row or all(not c.strip() for c in row):
                continue
            if len(row) != len(header):
                if _comment_row(row):  # the probe log's rule: '#' lines only before the header (review31 F14)
                    raise PositioningLogError(f"{src}: line {ln}: " + COMMENT_AFTER_HEADER.format(header=header_line))
                if unterminated and end == n_lines and len(row) < len(header):
                    last_row(row, len(raw), ln)
                raise PositioningLogError(
                    f"{src}: row {len(raw)} (line {ln}): {counted(len(row), 'field')}, header has {len(header)}")
            raw.append([c.strip() for c in row])
            line_of_row.append(ln)
            last_end = end
    except csv.Error as e:  # in the record that starts at line end + 1
        raise PositioningLogError(f"{src}: line {end + 1}: {e}") from None
    warnings = tuple(meta_warnings)
    if unterminated and raw and last_end == n_lines:
        w = last_row(raw[-1], len(raw) - 1, line_of_row[-1])
        warnings += () if w is None else (w,)
    col = {h: [r[j] for r in raw] for j, h in enumerate(header)}

    def where(r: int) -> str:
        return f"{src}: row {r} (line {line_of_row[r]})"

    def numbers(name: str, allow_empty: bool) -> np.ndarray:
        out = np.empty(len(raw))
        for r, c in enumerate(col[name]):
            if c == "" and allow_empty:
                out[r] = np.nan
                continue
            if c == "":
                raise PositioningLogError(f"{where(r)}: column {name!r}: is empty")
            out[r] = _finite_number(c, where(r), f"column {name!r}:")
        return out

    status = ok_statuses(np.array(col["status"], dtype=object)) if "status" in col else None  # OK is ok
    ok = np.array([s in OK_CELLS for s in status], bool) if status is not None else np.ones(len(raw), bool)
    target = numbers(tname, allow_empty=False)
    measured = numbers(mname, allow_empty=True)
    miss = np.isnan(measured) & ok
    if miss.any():
        r = int(np.argmax(miss))
        raise PositioningLogError(f"{where(r)}: column {mname!r} is empty in a valid reading")
    cyc = numbers("cycle", allow_empty=False)
    direction = np.empty(len(raw), dtype=np.int64)
    for r, c in enumerate(col["direction"]):
        if c not in ("+", "-"):
            raise PositioningLogError(f"{where(r)}: direction {c!r} is not '+' or '-'")
        direction[r] = 1 if c == "+" else -1
    bad = (cyc != np.round(cyc)) | (cyc < 1)
    if bad.any():
        r = int(np.argmax(bad))
        raise PositioningLogError(f"{where(r)}: cycle {col['cycle'][r]!r} is not a whole number >= 1")
    t_s = numbers("t_s", allow_empty=True) if "t_s" in col else None
    extra = {}
    for h in header:
        if h in (tname, mname, "cycle", "direction", "status", "t_s"):
            continue
        extra[h] = numbers(h, allow_empty=True) if _is_temp(h) else np.array(col[h], dtype=object)
    steps = _column_steps(meta, header, {"target": (tname, col[tname]),
                                         "measured": (mname, [c for c, o in zip(col[mname], ok) if o])}, src,
                          whole={tname: col[tname], mname: col[mname]}, where=where,
                          meta_line=meta_line.get(NUMBER_FORMAT_KEY))
    log = PositioningLog(meta=meta, target=target, cycle=cyc.astype(np.int64), direction=direction,
                         measured=measured, t_s=t_s, status=status, extra=extra, source=src, warnings=warnings,
                         lines=np.asarray(line_of_row, dtype=np.int64), text_steps=steps)
    _validate(log, line_of_row)
    return log


def _column_steps(meta: Mapping[str, str], header, cells: Mapping[str, tuple[str, list]], src: str,
                  scale: Mapping[str, float] | None = None, whole: Mapping[str, list] | None = None,
                  where=None, meta_line: int | None = None) -> dict:
    """:attr:`PositioningLog.text_steps` of the columns ``cells`` (key -> (column name, its cells' text)): the
    step of each column's most decimals, or what the metadata ``number_format`` declares (the probe log's line,
    :func:`core.probelog.parse_number_format`: vmt's words say the numbers are exact, ``decimals NAME=K`` a
    column printed to K decimals). ``scale``: key -> factor from the column's unit to the file unit (a table's
    ``deviation_um``: 1e-3).

    A column declared to K decimals is held to it as the probe log's reader holds its columns (session 35,
    iso34's leftover): a cell of ``whole`` (column name -> every row's text, status aside) written with more
    decimals than K is refused, one line naming the row (``where(r)``), since the line would claim a step the
    number does not have (before, the step was taken from the line and such a cell read silently).
    ``meta_line``: the ``number_format`` line's place in the file, named by its errors as the probe log's reader
    names it (``FILE: line N: metadata number_format ...``; session 38: before, the positioning log's errors
    named the file alone)."""
    declared = meta.get(NUMBER_FORMAT_KEY)
    exact, fixed = False, {}
    if declared is not None:
        from .exceptions import ProbeLogError

        try:
            exact, fixed = parse_number_format(declared, header, src, meta_line)
        except ProbeLogError as e:
            raise PositioningLogError(str(e)) from None
    out = {}
    for key, (name, text) in cells.items():
        k = (scale or {}).get(key, 1.0)
        if name in fixed:
            out[key] = k * 10.0 ** -fixed[name]
            _held_to_declared(name, (whole or {}).get(name, ()), fixed[name], where)
        elif exact:
            out[key] = 0.0
        else:
            d = most_decimals(text)
            if d is not None:
                out[key] = k * 10.0 ** -d
    return out


def _held_to_declared(name: str, text, decimals: int, where) -> None:
    """Refuse the first cell of ``text`` (a column's cells, row by row) written with more decimals than the
    ``decimals`` the ``number_format`` line declares for column ``name`` (the probe log reader's rule and
    words); ``where(r)`` names row ``r``."""
    r = first_finer(text, decimals)
    if r is None:
        return
    at = where(r) if where is not None else f"row {r}"
    raise PositioningLogError(
        f"{at}: column {name!r}: {text[r].strip()[:40]!r} has more decimals than the {decimals} the metadata "
        f"{NUMBER_FORMAT_KEY} declares for the column: correct the line (or the number)")


#: Axis letters of ISO 841: the linear axes (a positioning log of one in mm) and the rotary axes (in deg).
LINEAR_LETTERS, ROTARY_LETTERS = ("X", "Y", "Z", "U", "V", "W"), ("A", "B", "C")


def _axis_fits_unit(axis: str, unit: str, src: str) -> None:
    """Refuse an axis letter that contradicts the unit (review30 F6: '# axis: X' with '# unit: deg' gave figures
    in arcsec under a plot labelled 'X / mm'). The format says lengths in mm and deg for a rotary axis: one of
    the two lines is wrong, and which one decides whether the figures are um or arcsec, so neither is guessed.
    Other axis names (none, 'X1', a joint's name) say nothing of the unit and pass."""
    a = axis.strip().upper()
    if unit == "deg" and a in LINEAR_LETTERS:
        raise PositioningLogError(f"{src}: metadata axis {axis!r} is a linear axis but unit is 'deg' (a rotary "
                                  "axis's, A B C): correct '# axis:' or '# unit: mm' and the column names")
    if unit == "mm" and a in ROTARY_LETTERS:
        raise PositioningLogError(f"{src}: metadata axis {axis!r} is a rotary axis but unit is 'mm' (a linear "
                                  "axis's, X Y Z U V W): correct '# axis:' or '# unit: deg' and the column names")


def _validate(log: PositioningLog, lines: list[int] | None) -> None:
    src = log.source
    n = log.n

    def where(r: int) -> str:
        return f"{src}: row {r}" + (f" (line {lines[r]})" if lines is not None else "")

    unit = log.unit
    if unit not in _NUMERIC_REQUIRED:
        raise PositioningLogError(f"{src}: unit {unit!r} is not 'mm' or 'deg'")
    _tool_offset(log.meta, src)
    _axis_fits_unit(log.axis, unit, src)
    kind = log.meta.get("cycle_kind", "")
    if kind and kind not in CYCLE_KINDS:
        raise PositioningLogError(f"{src}: metadata cycle_kind {kind!r} is not 'linear' or 'pilgrim'")
    arrays = {"target": log.target, "cycle": log.cycle, "direction": log.direction,
              "measured": log.measured}
    if log.t_s is not None:
        arrays["t_s"] = log.t_s
    if log.status is not None:
        arrays["status"] = log.status
    arrays.update(log.extra)
    for name, v in arrays.items():
        if np.shape(v) != (n,):
            raise PositioningLogError(f"{src}: column {name!r} has shape {np.shape(v)}, expected ({n},)")
    ok = log.ok
    bad = ~np.isfinite(log.target)
    if bad.any():
        raise PositioningLogError(f"{where(int(np.argmax(bad)))}: target is not a finite number")
    bad = ~np.isfinite(log.measured) & ok
    if bad.any():
        raise PositioningLogError(f"{where(int(np.argmax(bad)))}: measured value is not a finite number")
    bad = log.cycle < 1
    if bad.any():
        r = int(np.argmax(bad))
        raise PositioningLogError(f"{where(r)}: cycle {int(log.cycle[r])} is not >= 1")
    bad = ~np.isin(log.direction, (1, -1))
    if bad.any():
        raise PositioningLogError(f"{where(int(np.argmax(bad)))}: direction is not +1 or -1")
    if log.t_s is not None:
        t = log.t_s
        bad = np.isinf(t)
        if bad.any():
            raise PositioningLogError(f"{where(int(np.argmax(bad)))}: t_s is not finite")
        back = step_back(t)
        if back is not None:
            before, r = back
            raise PositioningLogError(f"{where(r)}: time goes backwards (t_s {t[r]:g} after {t[before]:g}); "
                                      "rows must be in the order measured")
    # the probe log's physical bounds (core.probelog.value_range): keep absurd values out of the figures
    if unit == "mm":
        _, big, _, why = value_range("X_mm")
    else:
        big, why = value_range("C_deg")[1], "2778 turns of a multi-turn table"
    bounds = [(f"target_{unit}", log.target, -big, big, unit, why),
              (f"measured_{unit}", log.measured, -big, big, unit, why)]
    if log.t_s is not None:
        bounds.append(("t_s", log.t_s, 0.0, T_MAX_S, "s", "time since the test started"))
    bounds += [(k, v, *TEMP_RANGE_C, "C", "") for k, v in log.extra.items() if _is_temp(k)]
    for name, v, lo, hi, u, why in bounds:
        v = np.asarray(v, dtype=float)
        with np.errstate(invalid="ignore"):
            out = (v < lo) | (v > hi)
        if out.any():
            r = int(np.argmax(out))
            raise PositioningLogError(f"{where(r)}: column {name!r}: {_num(v[r])} is out of range (must be "
                                      f">= {lo:g} and <= {hi:g} {u}{': ' + why if why else ''})")
    # one valid reading per (target, cycle, direction), targets grouped as arrange() groups them
    first: dict[tuple, int] = {}
    rows = np.flatnonzero(ok)
    groups, _ = _target_groups(log.target[rows])
    table = log.meta.get("imported_from", "") == "table" and log.status is None  # no status to mark
    for r, g in zip(rows, groups):
        key = (int(g), int(log.cycle[r]), int(log.direction[r]))
        if key in first:
            d = "+" if log.direction[r] > 0 else "-"
            fix = ("delete the reading that is not valid" if table
                   else "mark one reading with a status other than ok")
            raise PositioningLogError(
                f"{where(int(r))}: target {_num(log.target[r])} {unit}, cycle {int(log.cycle[r])}, "
                f"direction '{d}' already measured in row {first[key]} ({fix})")
        first[key] = int(r)


# ---------------------------------------------------------------------------
# writing


def _fmt(v: float) -> str:
    return "" if math.isnan(v) else repr(float(v))


def format_positioning_log(log: PositioningLog) -> str:
    """The file text of ``log``: metadata, header, one row per reading."""
    buf = io.StringIO()
    meta = dict(log.meta)
    meta["format"] = FORMAT
    meta.setdefault("unit", log.unit)
    meta = {"format": meta.pop("format"), **meta}
    fixed = _written_decimals(log)
    if fixed is None:
        meta.pop(NUMBER_FORMAT_KEY, None)
    else:
        meta[NUMBER_FORMAT_KEY] = number_format_value(fixed)
    for k, v in meta.items():
        buf.write(f"# {k}: {' '.join(str(v).split())}\n")
    u = log.unit
    cols: dict[str, tuple[np.ndarray, bool]] = {
        f"target_{u}": (log.target, False), "cycle": (log.cycle, None),
        "direction": (log.direction, None), f"measured_{u}": (log.measured, False)}
    if log.t_s is not None:
        cols["t_s"] = (log.t_s, False)
    for k, v in log.extra.items():
        cols[k] = (v, not _is_temp(k))
    if log.status is not None:
        cols["status"] = (log.status, True)
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(list(cols))
    for r in range(log.n):
        row = []
        for name, (v, text) in cols.items():
            if name == "cycle":
                row.append(str(int(v[r])))
            elif name == "direction":
                row.append("+" if v[r] > 0 else "-")
            elif name in (fixed or {}) and not math.isnan(v[r]):
                row.append(f"{float(v[r]):.{fixed[name]}f}")
            else:
                row.append(v[r] if text else _fmt(v[r]))
        w.writerow(row)
    return buf.getvalue()


def _written_decimals(log: PositioningLog) -> dict | None:
    """The columns the writer prints to fixed decimals (name -> K), the others exact (shortest round-trip),
    as the probe log's writer declares them (``number_format``, :data:`core.probelog.NUMBER_FORMAT_KEY`): a
    target or measured column read with a step ``10^-K`` (:attr:`PositioningLog.text_steps`) is written to K
    decimals, so a read -> write -> read keeps its step (``405.770`` would otherwise come back as ``405.77``,
    a 0.01 mm step); a log built in memory declares its numbers exact. None (no line: the digits say the step,
    as before session 34) when a known step does not hold its column's values (a table's measured column is
    target + deviation: a target finer than the deviation's step)."""
    u = log.unit
    fixed = {}
    for key, name, v in (("target", f"target_{u}", log.target), ("measured", f"measured_{u}", log.measured)):
        d = step_decimals(log.text_steps.get(key))
        if d is None:
            continue
        if not on_step(v, d, WRITE_ON_STEP_RTOL_POSITIONING):   # (a computed column's float noise held: there)
            return None
        fixed[name] = d
    return fixed


def write_positioning_log(path: str | os.PathLike, log: PositioningLog, *, special: bool = False) -> Path:
    """Write ``log`` atomically; reading it back gives the same log. ``special``: the user named a
    device or pipe (``/dev/stdout``): written through (:func:`core.atomic.check_output`)."""
    return write_text_atomic(path, format_positioning_log(log), special=special)


# ---------------------------------------------------------------------------
# importers: ecmc .dat and a generic table

_ECMC_LINE = re.compile(r"^\s*([A-Za-z_][A-Za-z0-9_]*)\s*(?:\[\s*([^\]]*)\])?\s*=\s*(.*?)\s*$")
_ECMC_UNITS = {"mm": ("mm", 1.0), "um": ("mm", 1e-3), "µm": ("mm", 1e-3), "deg": ("deg", 1.0),
               "degree": ("deg", 1.0), "degrees": ("deg", 1.0)}


def read_ecmc_dat(path: str | os.PathLike) -> PositioningLog:
    """Read an ecmc ISO 230-2 ``.dat`` file (see :func:`parse_ecmc_dat`)."""
    text, src = _read_text(path, "an ecmc .dat file")
    return parse_ecmc_dat(text, source=src)


def parse_ecmc_dat(text: str, source: str = "<memory>") -> PositioningLog:
    """Parse the ISO 230-2 input file of ecmc (EPICS motion control, ESS/PSI).

    The format, as ecmc's own scripts write it (``ecmccfg`` examples
    ``fat_sat/report.md_ISO230.dat``): one ``KEY=VALUE`` a line, ``#``
    comments, blank lines ignored::

        UNIT=mm                   (optional, default mm)
        CYCLES=5                  (optional; n)
        POSITIONS=5               (optional; m)
        TGT_DATA[i]=P_i           target i = 1..m
        REF_DATA_FWD[i,j]=P_ij    reference reading, target i, cycle j, FWD
        REF_DATA_BWD[i,j]=P_ij    likewise BWD

    ``FWD`` is the positive direction: ecmc's test sequence starts below
    the first target ("approach first test position from below") and
    steps upwards; ``BWD`` comes back from above the last. (ecmc's own
    evaluation script stores ``REF_DATA_FWD`` as its backward data and
    vice versa, so its reported directions are swapped.) Other keys
    (``DEC``, ``REF_PV``, ``TEST_PV``, ``TGT_SET_PV``, ...) are kept in the
    metadata as ``ecmc_<key>``. The file has no clock: rows are written in
    the order of ecmc's linear cycle (cycle j: FWD ascending, then BWD
    descending) and ``cycle_kind`` is ``linear``.

    Raises
    ------
    PositioningLogError
        A line that is not ``KEY=VALUE``, a value that is not a number, an
        index out of the declared ``POSITIONS``/``CYCLES``, a value given
        twice, a reading without its target, a target or cycle missing in
        one direction, an unknown unit.
    """
    src = source
    if not text.strip():
        raise PositioningLogError(f"{src}: empty file")
    scalars: dict[str, tuple[str, int]] = {}
    tgt: dict[int, tuple[float, int]] = {}
    ref: dict[str, dict[tuple[int, int], tuple[float, int]]] = {"FWD": {}, "BWD": {}}
    texts: dict[str, list[str]] = {"target": [], "measured": []}   # the numbers as printed: their step
    extra_meta: dict[str, str] = {}

    def num(v: str, ln: int, what: str) -> float:
        return _finite_number(v, f"{src}: line {ln}", what)

    def index(s: str, count: int, ln: int, key: str) -> tuple[int, ...]:
        parts = [p.strip() for p in s.split(",")]
        if len(parts) != count or not all(p.isascii() and p.isdigit() and int(p) >= 1 for p in parts):
            want = "[i]" if count == 1 else "[i,j]"
            raise PositioningLogError(f"{src}: line {ln}: {key}[{s}]: index must be {want} with whole numbers >= 1")
        return tuple(int(p) for p in parts)

    for ln, line in enumerate(csv_lines(text), start=1):
        s = line.strip()
        if not s or s.startswith("#"):
            continue
        mt = _ECMC_LINE.match(s)
        if not mt:
            raise PositioningLogError(f"{src}: line {ln}: not KEY=VALUE or KEY[i,j]=VALUE: {s[:40]!r}")
        key, idx, val = mt.group(1).upper(), mt.group(2), mt.group(3)
        if key == "TGT_DATA":
            if idx is None:
                raise PositioningLogError(f"{src}: line {ln}: TGT_DATA needs an index [i]")
            (i,) = index(idx, 1, ln, key)
            if i in tgt:
                raise PositioningLogError(f"{src}: line {ln}: TGT_DATA[{i}] given twice (first on line {tgt[i][1]})")
            tgt[i] = (num(val, ln, f"TGT_DATA[{i}]"), ln)
            texts["target"].append(val)
        elif key in ("REF_DATA_FWD", "REF_DATA_BWD"):
            d = key[-3:]
            if idx is None:
                raise PositioningLogError(f"{src}: line {ln}: {key} needs an index [i,j]")
            ij = index(idx, 2, ln, key)
            if ij in ref[d]:
                raise PositioningLogError(
                    f"{src}: line {ln}: {key}[{ij[0]},{ij[1]}] given twice (first on line {ref[d][ij][1]})")
            ref[d][ij] = (num(val, ln, f"{key}[{ij[0]},{ij[1]}]"), ln)
            texts["measured"].append(val)
        elif idx is None and key in ("UNIT", "CYCLES", "POSITIONS"):
            if key in scalars:
                raise PositioningLogError(f"{src}: line {ln}: {key} given twice (first on line {scalars[key][1]})")
            scalars[key] = (val, ln)
        else:
            extra_meta[f"ecmc_{key}" + (f"[{idx}]" if idx is not None else "")] = val
    unit_txt, uln = scalars.get("UNIT", ("mm", 0))
    if unit_txt.strip().lower() not in _ECMC_UNITS:
        raise PositioningLogError(f"{src}: line {uln}: UNIT {unit_txt!r} is not mm, um or deg")
    unit, scale = _ECMC_UNITS[unit_txt.strip().lower()]
    declared = {}
    for key in ("POSITIONS", "CYCLES"):
        if key in scalars:
            v, ln = scalars[key]
            if not (v.strip().isascii() and v.strip().isdigit()) or int(v) < 1:
                raise PositioningLogError(f"{src}: line {ln}: {key} {v!r} is not a whole number >= 1")
            declared[key] = int(v)
    if not tgt:
        raise PositioningLogError(f"{src}: no TGT_DATA[i] lines (not an ecmc ISO 230-2 file?)")
    for d in ("FWD", "BWD"):
        if not ref[d]:
            raise PositioningLogError(f"{src}: no REF_DATA_{d}[i,j] lines: ISO 230-2 needs both directions")
    m = declared.get("POSITIONS", max(tgt))
    n = declared.get("CYCLES", max(j for d in ref for (_, j) in ref[d]))
    for i, (_, ln) in tgt.items():
        if i > m:
            raise PositioningLogError(f"{src}: line {ln}: TGT_DATA[{i}] beyond POSITIONS={m}")
    for d in ("FWD", "BWD"):
        for (i, j), (_, ln) in ref[d].items():
            if i > m or j > n:
                raise PositioningLogError(
                    f"{src}: line {ln}: REF_DATA_{d}[{i},{j}] beyond POSITIONS={m}, CYCLES={n}")
    for i in range(1, m + 1):
        if i not in tgt:
            raise PositioningLogError(f"{src}: TGT_DATA[{i}] missing (POSITIONS={m})")
        for d in ("FWD", "BWD"):
            for j in range(1, n + 1):
                if (i, j) not in ref[d]:
                    raise PositioningLogError(f"{src}: REF_DATA_{d}[{i},{j}] missing (POSITIONS={m}, CYCLES={n})")
    order = sorted(range(1, m + 1), key=lambda i: tgt[i][0])
    rows_t, rows_c, rows_d, rows_m, rows_ln = [], [], [], [], []
    for j in range(1, n + 1):
        for d, seq in (("FWD", order), ("BWD", order[::-1])):
            for i in seq:
                rows_t.append(tgt[i][0] * scale)
                rows_c.append(j)
                rows_d.append(1 if d == "FWD" else -1)
                rows_m.append(ref[d][(i, j)][0] * scale)
                rows_ln.append(ref[d][(i, j)][1])
    meta = {"axis": "", "instrument": "reference encoder (ecmc REF_PV)", "cycle_kind": "linear",
            "imported_from": "ecmc .dat", "row_order": "ecmc linear cycle (assumed; the file has no clock)"}
    meta.update(extra_meta)
    log = make_positioning_log(rows_t, rows_c, rows_d, rows_m, meta=meta, unit=unit, source=src, lines=rows_ln)
    steps = _column_steps({}, (), {k: (k, v) for k, v in texts.items()}, src,
                          scale={"target": scale, "measured": scale})
    return replace(log, text_steps=steps)


_TABLE_NAMES = {
    "target": ("target", "target_mm", "target_deg", "p", "p_i", "nominal", "position", "tgt"),
    "cycle": ("cycle", "run", "j", "repetition", "rep"),
    "direction": ("direction", "dir", "approach"),
    "measured": ("measured", "measured_mm", "measured_deg", "actual", "p_ij", "reading", "ref"),
    "deviation_um": ("deviation_um", "error_um", "x_um", "dev_um"),
}
_DIRECTION_WORDS = {"+": 1, "up": 1, "pos": 1, "positive": 1, "fwd": 1, "forward": 1, "↑": 1, "1": 1,
                    "+1": 1, "-": -1, "down": -1, "neg": -1, "negative": -1, "bwd": -1, "backward": -1,
                    "↓": -1, "-1": -1}


def read_table(path: str | os.PathLike, unit: str | None = None) -> PositioningLog:
    """Read a generic table of readings (see :func:`parse_table`)."""
    text, src = _read_text(path, "a table")
    return parse_table(text, source=src, unit=unit)


def parse_table(text: str, source: str = "<memory>", unit: str | None = None) -> PositioningLog:
    """A generic whitespace-, comma-, semicolon- or tab-separated table.

    One reading a line: target, cycle, direction, measured value, in that
    order, or in any order under a header row naming them (``target``,
    ``cycle``/``run``, ``direction``/``dir``, ``measured``/``actual``;
    ``deviation_um`` instead of ``measured`` gives ``measured = target +
    deviation``, on a linear axis only). A header column that names none of
    these is refused, not dropped (a ``status`` column dropped would let
    invalid readings into the figures: such a file is a positioning log and
    needs its ``# format:`` line). Directions: ``+ - up down fwd bwd forward
    backward pos neg +1 -1 1``. Lines starting with ``#`` are comments
    (``# key: value`` lines become metadata), anywhere in the file, unlike a
    positioning log's (before its header only); a key vmt reads given twice
    with two values is refused, as in a positioning log (a ``# unit: mm``
    below a ``# unit: deg`` read the table in mm before session 31), and any
    other key keeps its first value with a warning (:func:`core.probelog.add_meta`). The unit (``mm`` or ``deg``):
    the one in the target or measured column's name (``target_deg``), else
    ``unit``, else a ``# unit:`` comment line, else mm; a name in another
    unit than ``unit`` or the ``# unit:`` line, or two names in two units,
    are refused. Rows are taken to be in the order measured.
    """
    src = source
    if not text.strip():
        raise PositioningLogError(f"{src}: empty file")
    meta: dict[str, str] = {}
    meta_line: dict[str, int] = {}
    meta_warnings: list[str] = []
    rows: list[tuple[int, list[str]]] = []
    for ln, line in enumerate(csv_lines(text), start=1):
        s = line.strip()
        if not s:
            continue
        if s.startswith("#"):   # anywhere in a table (a comment between blocks); a key vmt reads twice with two
            add_meta(meta, meta_line, s, ln, src, error=PositioningLogError,   # values is refused (warn31: the last
                     warnings=meta_warnings)                                    # won), another keeps its first
            continue
        if "," in s or ";" in s:
            cells = [c.strip() for c in re.split(r"[,;]", s)]
        else:
            cells = s.split()
        rows.append((ln, cells))
    if not rows:
        raise PositioningLogError(f"{src}: no data rows")
    given, said = (unit, "asked for") if unit else (meta.get("unit"), "from the '# unit:' line")
    if given and given not in _NUMERIC_REQUIRED:
        raise PositioningLogError(f"{src}: unit {given!r} is not 'mm' or 'deg'")
    first = rows[0][1]

    def reads_as_float(c: str) -> bool:  # (Python's float: any text a data row's first cell could hold)
        try:
            float(c)
            return True
        except ValueError:
            return False

    cols: dict[str, int]
    if not reads_as_float(first[0]):     # a header names its first column; a data row starts with its target
        lookup = {}
        for j, name in enumerate(first):
            key = name.strip().lower()
            canon = next((c for c, names in _TABLE_NAMES.items() if key in names), None)
            if canon is None:   # refused, not dropped: a status column dropped let invalid readings in
                cased = next((k for k in meta if k.lower() == "format" and k != "format"), None)
                raise PositioningLogError(
                    f"{src}: line {rows[0][0]}: column {name!r} is not a table column (target, cycle, "
                    f"direction, measured or deviation_um): delete it, or, for a positioning log, "
                    + (f"write line {meta_line[cased]}'s key in lower case, '# format: {FORMAT}' (metadata keys "
                       f"are case-sensitive: '# {cased}:' is another key)" if cased is not None else
                       f"add the line '# format: {FORMAT}'"))
            if canon in lookup:
                raise PositioningLogError(f"{src}: line {rows[0][0]}: two columns mean {canon!r}")
            lookup[canon] = j
        for need in ("target", "cycle", "direction"):
            if need not in lookup:
                raise PositioningLogError(
                    f"{src}: line {rows[0][0]}: header has no {need!r} column (got {', '.join(first)})")
        if "measured" not in lookup and "deviation_um" not in lookup:
            raise PositioningLogError(
                f"{src}: line {rows[0][0]}: header has no 'measured' or 'deviation_um' column")
        cols = lookup
        # a unit in a column's name (target_deg, measured_mm) is the table's unit
        named = [(first[cols[c]], first[cols[c]].strip().lower().rsplit("_", 1)[-1])
                 for c in ("target", "measured") if c in cols]
        named = [(name, u) for name, u in named if u in _NUMERIC_REQUIRED]   # not p_i, p_ij
        for name, u in named[1:]:
            if u != named[0][1]:
                raise PositioningLogError(f"{src}: line {rows[0][0]}: column {name!r} is in {u} but column "
                                          f"{named[0][0]!r} is in {named[0][1]}")
        if named and given and named[0][1] != given:
            raise PositioningLogError(f"{src}: line {rows[0][0]}: column {named[0][0]!r} is in {named[0][1]} "
                                      f"but the unit is {given} ({said})")
        unit = named[0][1] if named else (given or "mm")
        if "deviation_um" in cols and unit != "mm":
            raise PositioningLogError(
                f"{src}: line {rows[0][0]}: column {first[cols['deviation_um']]!r} is a length (um) but the "
                f"table is in {unit}: give the measured angle instead (measured_deg)")
        rows = rows[1:]
        width = len(first)
        if not rows:
            raise PositioningLogError(f"{src}: no data rows after the header")
    else:
        cols = {"target": 0, "cycle": 1, "direction": 2, "measured": 3}
        width = 4
        unit = given or "mm"
    tg, cy, di, me, lns = [], [], [], [], []
    mkey = "measured" if "measured" in cols else "deviation_um"
    steps = _column_steps({}, (), {"target": ("target", [c[cols["target"]] for _, c in rows if len(c) == width]),
                                   "measured": (mkey, [c[cols[mkey]] for _, c in rows if len(c) == width])},
                          src, scale={"measured": 1e-3 if mkey == "deviation_um" else 1.0})
    for ln, cells in rows:
        if len(cells) != width:
            raise PositioningLogError(f"{src}: line {ln}: {counted(len(cells), 'field')}, expected {width}")

        def val(name: str) -> float:
            return _finite_number(cells[cols[name]], f"{src}: line {ln}", name)

        t = val("target")
        c = val("cycle")
        if c != round(c) or c < 1:
            raise PositioningLogError(f"{src}: line {ln}: cycle {cells[cols['cycle']]!r} is not a whole number >= 1")
        dtxt = cells[cols["direction"]].strip().lower()
        if dtxt not in _DIRECTION_WORDS:
            raise PositioningLogError(f"{src}: line {ln}: direction {cells[cols['direction']]!r} is not + or -")
        mv = val("measured") if "measured" in cols else t + val("deviation_um") * 1e-3
        lns.append(ln)
        tg.append(t)
        cy.append(int(c))
        di.append(_DIRECTION_WORDS[dtxt])
        me.append(mv)
    meta.setdefault("imported_from", "table")
    meta.pop("format", None)
    meta.pop("unit", None)
    log = make_positioning_log(tg, cy, di, me, meta=meta, unit=unit, source=src, lines=lns)
    return replace(log, warnings=log.warnings + tuple(meta_warnings), text_steps=steps)


def load_positioning(path: str | os.PathLike, kind: str = "auto", unit: str | None = None) -> PositioningLog:
    """Read a positioning test from ``positioning-log/1``, an ecmc ``.dat`` or a table.

    ``kind``: ``log``, ``ecmc``, ``table`` or ``auto`` (a ``# format:``
    line means a positioning log, ``TGT_DATA[`` an ecmc file, anything
    else a table). ``unit`` applies to tables only.
    """
    if kind not in ("auto", "log", "ecmc", "table"):
        raise PositioningLogError(f"input kind {kind!r} is not auto, log, ecmc or table")
    text, src = _read_text(path, "a positioning test")
    if kind == "auto":
        if re.search(r"^\s*#\s*format\s*:", text, re.M):
            kind = "log"
        elif re.search(r"^\s*TGT_DATA\s*\[", text, re.M | re.I):
            kind = "ecmc"
        else:
            kind = "table"
    if kind == "log":
        return parse_positioning_log(text, source=src)
    if kind == "ecmc":
        return parse_ecmc_dat(text, source=src)
    return parse_table(text, source=src, unit=unit)


# ---------------------------------------------------------------------------
# arranging a log for the evaluation


@dataclass(frozen=True)
class PositioningTest:
    """A log arranged per target and direction (valid readings only).

    Attributes
    ----------
    unit : str
        ``mm`` or ``deg``: the unit of every array here.
    targets : (m,) float
        Target positions P_i, ascending.
    cycles : (n,) int
        Cycle numbers j present (ascending); column k of the arrays is
        cycle ``cycles[k]``.
    dev_up, dev_down : (m, n) float
        Positional deviations ``x_ij`` approached in ``+`` / ``-``; NaN
        where a target has no valid reading of that cycle.
    t_up, t_down : (m, n) float
        Time of each reading, s (NaN when unknown).
    row_up, row_down : (m, n) int
        Row of each reading in the log (-1 where missing).
    warnings : tuple of str
        What makes this test less than ISO 230-2's full test.
    axis, cycle_kind : str
        From the log's metadata.
    joint_offset : float
        Axis (joint) position minus target along the axis
        (:attr:`PositioningLog.joint_offset`): target ``P_i`` is the axis at
        ``P_i + joint_offset``.
    """

    unit: str
    targets: np.ndarray
    cycles: np.ndarray
    dev_up: np.ndarray
    dev_down: np.ndarray
    t_up: np.ndarray
    t_down: np.ndarray
    row_up: np.ndarray
    row_down: np.ndarray
    warnings: tuple[str, ...] = ()
    axis: str = ""
    cycle_kind: str = ""
    joint_offset: float = 0.0

    @property
    def m(self) -> int:
        return int(self.targets.shape[0])

    @property
    def n_up(self) -> np.ndarray:
        """(m,) valid readings per target approached in +."""
        return np.sum(~np.isnan(self.dev_up), axis=1)

    @property
    def n_down(self) -> np.ndarray:
        return np.sum(~np.isnan(self.dev_down), axis=1)


def row_where(log: PositioningLog, r: int) -> str:
    """``FILE: row r (line l)``: where a reading is, as the reader's own refusals say it (docs/formats.md: each
    names the 0-based data row and the file line; review34: the evaluation's named the row only). The line is
    left out where the log has none (built in memory, an ecmc ``.dat``)."""
    ln = None if log.lines is None or r >= len(log.lines) else int(log.lines[r])
    return f"{log.source}: row {r}" + (f" (line {ln})" if ln is not None else "")


def skipped_readings(log: PositioningLog) -> dict:
    """How many readings the log holds and how many the evaluation leaves out for their ``status``
    (review34: the sample's ``beam interrupted`` row was skipped without a word): ``readings``, ``valid``,
    ``skipped`` and ``skipped_by_status`` (status -> count, in order of first appearance)."""
    ok = log.ok
    by: dict[str, int] = {}
    if log.status is not None:
        for st in log.status[~ok]:
            by[str(st)] = by.get(str(st), 0) + 1
    return {"readings": log.n, "valid": int(ok.sum()), "skipped": int(log.n - ok.sum()), "skipped_by_status": by}


def skipped_said(counts: Mapping) -> str:
    """``91 readings, 1 skipped for its status ('beam interrupted')``, or '' when none was skipped."""
    k = int(counts.get("skipped", 0))
    if not k:
        return ""
    by = counts.get("skipped_by_status") or {}
    shown = ", ".join(f"{st!r}" + (f" x{c}" if c > 1 else "") for st, c in list(by.items())[:4])
    more = f", {len(by) - 4} more statuses" if len(by) > 4 else ""
    return (f"{counted(int(counts['readings']), 'reading')}, {k} skipped for "
            f"{'its' if k == 1 else 'their'} status ({shown}{more})")


def _deviation_check(log: PositioningLog, rows: np.ndarray, groups: np.ndarray, targets: np.ndarray) -> list:
    """Refuse a valid reading whose deviation is beyond :data:`DEVIATION_WARN` and at least half the spacing
    of its target's neighbours (nearer another target than its own: a unit or typing slip, not an error of
    positioning); return the warnings for one beyond :data:`DEVIATION_WARN` only (row, value, count)."""
    u = log.unit
    dev = log.deviation[rows]
    warn = DEVIATION_WARN[u]
    gap = np.diff(targets)  # the targets sorted; each target's nearest neighbour's distance
    near = np.full(targets.size, np.inf)
    if gap.size:
        near[:-1] = gap
        near[1:] = np.minimum(near[1:], gap)
    half = 0.5 * near[groups]
    big = np.abs(dev) > warn
    if not big.any():
        return []
    said = f"{1e3 * warn:g} um" if u == "mm" else f"{warn:.4g} deg ({warn * 3600.0:.0f} arcsec)"
    refuse = big & (np.abs(dev) >= half)
    if refuse.any():
        k = int(np.argmax(refuse))
        r = int(rows[k])
        raise PositioningLogError(
            f"{row_where(log, r)}: measured {_num(log.measured[r])} {u} at target {_num(log.target[r])} {u} "
            f"is {dev[k]:.6g} {u} off it, nearer another target than its own (half the targets' spacing "
            f"there: {half[k]:.6g} {u}): no positioning error, a unit or typing slip (deviations in the "
            f"measured column? the wrong unit?)" + (f"; {int(refuse.sum())} such readings" if refuse.sum() > 1
                                                     else ""))
    k = int(np.argmax(big))
    r = int(rows[k])
    return [f"{row_where(log, r)}: measured {_num(log.measured[r])} {u} at target {_num(log.target[r])} {u} is "
            f"{dev[k]:.6g} {u} off it, beyond {said}, tens of times a machine's positioning error (a unit or "
            f"typing slip?); {counted(int(big.sum()), 'reading')} so far off, every figure includes them"]


def arrange(log: PositioningLog) -> PositioningTest:
    """Arrange the valid readings of ``log`` per target and direction.

    Raises
    ------
    PositioningLogError
        No valid reading in one direction, a target approached in one
        direction only, fewer than ``N_MIN`` = 2 readings of a target in a
        direction (the estimator s of 2.15 needs n - 1 >= 1), fewer than 2
        targets.
    """
    src = log.source
    u = log.unit
    ok = log.ok
    rows = np.flatnonzero(ok)
    if rows.size == 0:  # say which words left them out (review31 F6: a log all 'OK' got no hint before)
        words = list(dict.fromkeys(str(w) for w in log.status)) if log.status is not None else []
        shown = ", ".join(repr(w) for w in words[:5]) + (", ..." if len(words) > 5 else "")
        raise PositioningLogError(f"{src}: no valid readings" + (
            f": every reading's status is not 'ok' ({shown})" if log.n else ""))
    for d, name in ((1, "+"), (-1, "-")):
        if not np.any(log.direction[rows] == d):
            raise PositioningLogError(
                f"{src}: no valid readings approached in the '{name}' direction "
                "(ISO 230-2 needs both directions at every target)")
    # targets: sorted, values closer than TARGET_TOL are one target
    groups, targets_arr = _target_groups(log.target[rows])
    m = targets_arr.size
    if m < 2:
        raise PositioningLogError(f"{src}: one target only ({targets_arr[0]:g} {u}); ISO 230-2 needs several")
    far = _deviation_check(log, rows, groups, targets_arr)
    cycles = np.unique(log.cycle[rows])
    col_of = {int(c): k for k, c in enumerate(cycles)}
    n = cycles.size
    out = {d: (np.full((m, n), np.nan), np.full((m, n), np.nan), np.full((m, n), -1, np.int64))
           for d in (1, -1)}
    dev = log.deviation
    t = log.t_s if log.t_s is not None else np.full(log.n, np.nan)
    for k, r in enumerate(rows):
        D, T, R = out[int(log.direction[r])]
        i, c = groups[k], col_of[int(log.cycle[r])]
        D[i, c] = dev[r]
        T[i, c] = t[r]
        R[i, c] = r
    warnings = list(log.warnings) + far
    for d, name in ((1, "+"), (-1, "-")):
        cnt = np.sum(~np.isnan(out[d][0]), axis=1)
        other = np.sum(~np.isnan(out[-d][0]), axis=1)
        for i in range(m):
            if cnt[i] == 0 and other[i] > 0:
                raise PositioningLogError(
                    f"{src}: target {_num(targets_arr[i])} {u} has readings in "
                    f"'{'-' if d > 0 else '+'}' but none in '{name}': the targets do not "
                    "match between directions")
            if cnt[i] < N_MIN:
                raise PositioningLogError(
                    f"{src}: target {_num(targets_arr[i])} {u}, direction '{name}': {int(cnt[i])} "
                    f"valid reading; the repeatability estimator needs at least {N_MIN} "
                    f"(ISO 230-2 asks {N_STANDARD})")
    counts = np.concatenate([np.sum(~np.isnan(out[d][0]), axis=1) for d in (1, -1)])
    if counts.min() < N_STANDARD:
        warnings.append(
            f"{counted(int(counts.min()), 'valid approach')} at some target and direction: ISO 230-2 asks "
            f"{N_STANDARD} in each direction; s, R and A rest on fewer and are not the standard's figures")
    if counts.min() != counts.max():
        warnings.append(f"unequal numbers of valid readings per target and direction "
                        f"({int(counts.min())} to {int(counts.max())})")
    want, why = targets_asked(targets_arr, u)
    if want is None:
        warnings.append(f"{counted(m, 'target')}: {why}")
    elif m < want:
        warnings.append(f"{counted(m, 'target')}: ISO 230-2 asks at least {want} ({why})")
    return PositioningTest(unit=u, targets=targets_arr, cycles=cycles.astype(np.int64),
                           dev_up=out[1][0], dev_down=out[-1][0], t_up=out[1][1], t_down=out[-1][1],
                           row_up=out[1][2], row_down=out[-1][2], warnings=tuple(warnings),
                           axis=log.axis, cycle_kind=log.meta.get("cycle_kind", ""),
                           joint_offset=log.joint_offset)


def cycles_said(report: Mapping) -> str:
    """``5 cycles``, or ``5-6 cycles`` when the valid readings per target and direction differ (a reading
    retaken, one invalid), for the headers of a :meth:`Iso2302Result.to_report` dict (review30: '7 targets
    x 6 cycles' where one target had a 6th)."""
    n = [int(r[k]) for r in report.get("per_target", ()) for k in ("n_up", "n_down") if k in r]
    if not n:
        return f"{report.get('cycles', '?')} cycles"
    lo, hi = min(n), max(n)
    return f"{hi} cycles" if lo == hi else f"{lo}-{hi} cycles"


def targets_asked(targets, unit: str) -> tuple[int | None, str]:
    """How many target positions ISO 230-2 asks of this test, and the rule, for the warning and the report.

    A linear axis (``unit`` mm) whose travel (the targets' span) is at most :data:`TARGETS_RULE_MM`:
    ``max(TARGETS_MIN, ceil(TARGETS_PER_M x travel in m))``. A longer linear axis, or a rotary axis
    (deg): ``None``, the standard's rule for it not known to vmt, and the text says it is not checked.
    """
    t = np.asarray(targets, float)
    if unit != "mm":
        return None, ("ISO 230-2's target-count rule for a rotary axis is not checked (vmt holds only its "
                      f"rule for linear axes up to {TARGETS_RULE_MM / 1000:g} m)")
    span = float(np.ptp(t)) if t.size else 0.0
    if span > TARGETS_RULE_MM * (1 + 1e-12):
        return None, (f"ISO 230-2's target-count rule for a linear axis over {TARGETS_RULE_MM / 1000:g} m is "
                      f"not checked (these span {span:g} mm; vmt holds only its rule up to "
                      f"{TARGETS_RULE_MM / 1000:g} m: {TARGETS_PER_M} per metre, at least {TARGETS_MIN})")
    per_m = int(math.ceil(TARGETS_PER_M * span / 1000.0 - 1e-9))
    rule = (f"{TARGETS_PER_M} per metre of travel up to {TARGETS_RULE_MM / 1000:g} m, at least {TARGETS_MIN}; "
            f"these span {span:g} mm")
    return max(TARGETS_MIN, per_m), rule


# ---------------------------------------------------------------------------
# the figures


@dataclass(frozen=True)
class Iso2302Result:
    """Every figure of ISO 230-2 for one axis, in the file unit (mm or deg).

    Per target (``(m,)`` arrays): ``mean_up``/``mean_down`` (2.10),
    ``mean_bi`` (2.11), ``B_i`` (2.12), ``s_up``/``s_down`` (2.15),
    ``R_up_i``/``R_down_i`` (2.16), ``R_i`` (2.17), ``n_up``/``n_down``
    (readings used). Of the axis (floats): ``B`` (2.13), ``B_mean`` (2.14),
    ``R_up``/``R_down`` (2.18), ``R`` (2.19), ``E_up``/``E_down`` (2.20),
    ``E`` (2.21), ``M`` (2.22), ``A_up``/``A_down`` (2.23), ``A`` (2.24).
    """

    unit: str
    targets: np.ndarray
    n_up: np.ndarray
    n_down: np.ndarray
    mean_up: np.ndarray
    mean_down: np.ndarray
    mean_bi: np.ndarray
    B_i: np.ndarray
    s_up: np.ndarray
    s_down: np.ndarray
    R_up_i: np.ndarray
    R_down_i: np.ndarray
    R_i: np.ndarray
    B: float
    B_mean: float
    R_up: float
    R_down: float
    R: float
    E_up: float
    E_down: float
    E: float
    M: float
    A_up: float
    A_down: float
    A: float
    warnings: tuple[str, ...] = ()
    axis: str = ""
    cycle_kind: str = ""

    #: The axis figures, in the order the standard lists them.
    FIGURES = ("B", "B_mean", "R_up", "R_down", "R", "E_up", "E_down", "E", "M", "A_up", "A_down", "A")

    def to_report(self) -> dict:
        """Plain dict for JSON: µm (arc seconds for ``deg``), unit in every key.

        Top level: ``B_um, B_mean_um, R_up_um, R_down_um, R_um, E_up_um,
        E_down_um, E_um, M_um, A_up_um, A_down_um, A_um`` and ``per_target``
        (one dict per target with ``target_mm``, ``n_up``, ``n_down``,
        ``mean_up_um``, ``mean_down_um``, ``mean_um``, ``B_um``,
        ``s_up_um``, ``s_down_um``, ``R_up_um``, ``R_down_um``, ``R_um`` and
        the band edges ``x̄ ± 2s`` as ``lower_up_um`` ... ``upper_down_um``);
        ``cycles``: the largest number of valid readings at one target in one direction (the cycle count
        when every target has them all; ``readings_per_target_min``/``_max`` beside it: a retaken or
        invalid reading makes them differ, review32b F1.2);
        ``target_count_rule``: ``checked`` (false for a rotary axis and a linear
        one over 2 m, whose rule vmt does not hold), ``asked`` (the targets
        ISO 230-2 asks, None unchecked) and ``rule`` (:func:`targets_asked`).
        """
        ru, k = REPORT_UNIT[self.unit]
        out: dict = {"format": REPORT_FORMAT, "standard": "ISO 230-2:2014", "axis": self.axis, "unit": ru,
                     "cycle_kind": self.cycle_kind, "targets": int(self.targets.size),
                     "cycles": int(max(self.n_up.max(), self.n_down.max())),
                     "readings_per_target_min": int(min(self.n_up.min(), self.n_down.min())),
                     "readings_per_target_max": int(max(self.n_up.max(), self.n_down.max()))}
        for f in self.FIGURES:
            out[f"{f}_{ru}"] = float(getattr(self, f)) * k
        rows = []
        for i in range(self.targets.size):
            rows.append({
                f"target_{self.unit}": float(self.targets[i]),
                "n_up": int(self.n_up[i]), "n_down": int(self.n_down[i]),
                f"mean_up_{ru}": float(self.mean_up[i]) * k,
                f"mean_down_{ru}": float(self.mean_down[i]) * k,
                f"mean_{ru}": float(self.mean_bi[i]) * k,
                f"B_{ru}": float(self.B_i[i]) * k,
                f"s_up_{ru}": float(self.s_up[i]) * k,
                f"s_down_{ru}": float(self.s_down[i]) * k,
                f"R_up_{ru}": float(self.R_up_i[i]) * k,
                f"R_down_{ru}": float(self.R_down_i[i]) * k,
                f"R_{ru}": float(self.R_i[i]) * k,
                f"lower_up_{ru}": float(self.mean_up[i] - 2 * self.s_up[i]) * k,
                f"upper_up_{ru}": float(self.mean_up[i] + 2 * self.s_up[i]) * k,
                f"lower_down_{ru}": float(self.mean_down[i] - 2 * self.s_down[i]) * k,
                f"upper_down_{ru}": float(self.mean_down[i] + 2 * self.s_down[i]) * k,
            })
        out["per_target"] = rows
        want, why = targets_asked(self.targets, self.unit)
        out["target_count_rule"] = {"checked": want is not None, "asked": want, "rule": why}
        out["warnings"] = list(self.warnings)
        return out


def _check_vector(name: str, v, m: int | None) -> np.ndarray:
    a = np.asarray(v, dtype=float)
    if a.ndim != 1 or (m is not None and a.shape[0] != m):
        raise PositioningLogError(f"{name} must be a 1-D array of {m} values, got shape {a.shape}")
    if not np.all(np.isfinite(a)):
        raise PositioningLogError(f"{name} must be finite")
    return a


def figures(targets, mean_up, mean_down, s_up, s_down, *, n_up=None, n_down=None, unit: str = "mm",
            warnings: Iterable[str] = (), axis: str = "", cycle_kind: str = "") -> Iso2302Result:
    """ISO 230-2 figures from the per-target statistics.

    Parameters
    ----------
    targets : (m,) float
        Target positions P_i (file unit).
    mean_up, mean_down : (m,) float
        Mean unidirectional positional deviations x̄_i↑, x̄_i↓ (2.10).
    s_up, s_down : (m,) float
        Estimators s_i↑, s_i↓ (2.15), >= 0.
    n_up, n_down : (m,) int, optional
        Readings behind each mean (reported only).

    Returns
    -------
    Iso2302Result
        Every per-target and axis figure (definitions 2.11-2.24, module
        docstring), in the unit of the inputs.
    """
    P = _check_vector("targets", targets, None)
    m = P.shape[0]
    if m < 1:
        raise PositioningLogError("no targets")
    xu = _check_vector("mean_up", mean_up, m)
    xd = _check_vector("mean_down", mean_down, m)
    su = _check_vector("s_up", s_up, m)
    sd = _check_vector("s_down", s_down, m)
    if np.any(su < 0) or np.any(sd < 0):
        raise PositioningLogError("s_up and s_down must be >= 0")
    nu = np.zeros(m, np.int64) if n_up is None else np.asarray(n_up, np.int64)
    nd = np.zeros(m, np.int64) if n_down is None else np.asarray(n_down, np.int64)
    xm = 0.5 * (xu + xd)                                   # 2.11
    Bi = xu - xd                                           # 2.12
    Ru_i = 4.0 * su                                        # 2.16
    Rd_i = 4.0 * sd
    Ri = np.maximum(2.0 * su + 2.0 * sd + np.abs(Bi), np.maximum(Ru_i, Rd_i))  # 2.17
    both = np.concatenate([xu, xd])
    upper = np.concatenate([xu + 2.0 * su, xd + 2.0 * sd])
    lower = np.concatenate([xu - 2.0 * su, xd - 2.0 * sd])
    return Iso2302Result(
        unit=unit, targets=P, n_up=nu, n_down=nd, mean_up=xu, mean_down=xd, mean_bi=xm, B_i=Bi,
        s_up=su, s_down=sd, R_up_i=Ru_i, R_down_i=Rd_i, R_i=Ri,
        B=float(np.max(np.abs(Bi))),                       # 2.13
        B_mean=float(np.mean(Bi)),                         # 2.14
        R_up=float(np.max(Ru_i)), R_down=float(np.max(Rd_i)),  # 2.18
        R=float(np.max(Ri)),                               # 2.19
        E_up=float(np.max(xu) - np.min(xu)), E_down=float(np.max(xd) - np.min(xd)),  # 2.20
        E=float(np.max(both) - np.min(both)),              # 2.21
        M=float(np.max(xm) - np.min(xm)),                  # 2.22
        A_up=float(np.max(xu + 2 * su) - np.min(xu - 2 * su)),  # 2.23
        A_down=float(np.max(xd + 2 * sd) - np.min(xd - 2 * sd)),
        A=float(np.max(upper) - np.min(lower)),            # 2.24
        warnings=tuple(warnings), axis=axis, cycle_kind=cycle_kind)


def iso230_2(test: PositioningTest | PositioningLog) -> Iso2302Result:
    """Evaluate a positioning test by ISO 230-2 (every figure of the module docstring).

    ``x̄_i`` is the mean (2.10) and ``s_i`` the sample standard deviation
    with ``n - 1`` in the denominator (2.15) of the valid readings of each
    target and direction.
    """
    if isinstance(test, PositioningLog):
        test = arrange(test)
    n_up, n_down = test.n_up, test.n_down
    mean_up = np.nanmean(test.dev_up, axis=1)
    mean_down = np.nanmean(test.dev_down, axis=1)
    s_up = np.nanstd(test.dev_up, axis=1, ddof=1)
    s_down = np.nanstd(test.dev_down, axis=1, ddof=1)
    return figures(test.targets, mean_up, mean_down, s_up, s_down, n_up=n_up, n_down=n_down,
                   unit=test.unit, warnings=test.warnings, axis=test.axis, cycle_kind=test.cycle_kind)


# ---------------------------------------------------------------------------
# the standard's model as a baseline (for model discovery)


@dataclass(frozen=True)
class PositioningBaseline:
    """ISO 230-2's own model of a test: ``x_ij = x̄_i(direction) + e_ij``.

    The model has one systematic deviation per target and direction
    (``2 m`` parameters) and treats everything else as random with a
    standard deviation per target and direction. What it cannot express
    (drift across cycles, a first-cycle effect, outliers, reversal or
    pitch errors between targets) stays in the residuals; a discovery
    engine tests candidate models against these. All arrays ``(N,)`` over
    the valid readings, in measurement order (log row), file unit.

    Attributes
    ----------
    row, target_index, cycle, direction : (N,) int
    target, t_s : (N,) float (t_s NaN when the log has no clock)
    deviation : (N,) float      x_ij
    fitted : (N,) float         x̄_i↑ or x̄_i↓ of the reading's target and direction
    residual : (N,) float       deviation - fitted
    s_up_pooled, s_down_pooled : float
        Pooled within-target standard deviation per direction,
        ``sqrt(Σ_i (n_i - 1) s_i² / Σ_i (n_i - 1))``.
    n_params : int              2 m
    dof : int                   N - 2 m
    unit : str
    """

    row: np.ndarray
    target_index: np.ndarray
    cycle: np.ndarray
    direction: np.ndarray
    target: np.ndarray
    t_s: np.ndarray
    deviation: np.ndarray
    fitted: np.ndarray
    residual: np.ndarray
    s_up_pooled: float
    s_down_pooled: float
    n_params: int
    dof: int
    unit: str

    @property
    def rms(self) -> float:
        """RMS of the residuals (file unit)."""
        return float(np.sqrt(np.mean(self.residual ** 2)))


def baseline(test: PositioningTest) -> PositioningBaseline:
    """The standard's model fitted to ``test`` (see :class:`PositioningBaseline`)."""
    parts = []
    for d, D, T, R in ((1, test.dev_up, test.t_up, test.row_up), (-1, test.dev_down, test.t_down, test.row_down)):
        mean = np.nanmean(D, axis=1)
        ii, kk = np.nonzero(~np.isnan(D))
        parts.append((R[ii, kk], ii, test.cycles[kk], np.full(ii.size, d), test.targets[ii],
                      T[ii, kk], D[ii, kk], mean[ii]))
    cat = [np.concatenate(x) for x in zip(*parts)]
    order = np.argsort(cat[0], kind="stable")
    row, ti, cyc, dirn, tgt, t, dev, fit = (a[order] for a in cat)

    def pooled(D):
        k = np.sum(~np.isnan(D), axis=1) - 1
        ss = np.nansum((D - np.nanmean(D, axis=1)[:, None]) ** 2, axis=1)
        return float(np.sqrt(ss.sum() / k.sum())) if k.sum() > 0 else float("nan")

    N = row.size
    return PositioningBaseline(row=row, target_index=ti, cycle=cyc, direction=dirn, target=tgt, t_s=t,
                               deviation=dev, fitted=fit, residual=dev - fit,
                               s_up_pooled=pooled(test.dev_up), s_down_pooled=pooled(test.dev_down),
                               n_params=2 * test.m, dof=int(N - 2 * test.m), unit=test.unit)


# ---------------------------------------------------------------------------
# uncertainty of the test (ISO/TR 230-9 style budget)


@dataclass(frozen=True)
class UncertaintyInputs:
    """What the test-uncertainty budget needs; standard uncertainties (k = 1).

    Attributes
    ----------
    u_instrument_um : float
        Length-independent part of the instrument's uncertainty (resolution,
        noise floor, dead path), µm.
    u_instrument_um_per_m : float
        Length-proportional part (laser calibration, wavelength
        compensation for air; scale calibration), µm per m of travel.
    misalignment_urad : float
        Largest expected angle between the beam (scale) and the axis, µrad:
        the cosine error ``L (1 - cos φ) <= L φ² / 2``.
    temperature_C : float
        Mean temperature of the machine scale (or part) during the test,
        for the budget only: vmt does NOT correct the readings. ISO 230-2
        states its results at 20 °C; the readings must arrive corrected to
        20 °C (a laser's material-temperature compensation, the nominal
        differential expansion, applied at the instrument). What the
        correction itself is uncertain by is booked here (``u_temperature_K``
        through ``alpha_per_K``, ``|T - 20|`` through ``u_alpha_per_K``); the
        correction ``L alpha_per_K (T - 20)`` that uncorrected readings would
        still hold is said by :attr:`UncertaintyBudget.temperature` (session 31,
        review31 F10: this said "the readings are corrected to 20 °C" and
        nothing corrected them).
    u_temperature_K : float
        Standard uncertainty of that temperature, K.
    alpha_per_K : float
        Expansion coefficient of the correction that was applied (steel 11.5e-6).
    u_alpha_per_K : float
        Its standard uncertainty, 1/K.
    eve_um : float
        Environmental variation error E_VE: range of the reading in a
        stationary drift check over the duration of the test, µm.
    """

    u_instrument_um: float = 0.0
    u_instrument_um_per_m: float = 0.0
    misalignment_urad: float = 0.0
    temperature_C: float = 20.0
    u_temperature_K: float = 0.0
    alpha_per_K: float = 11.5e-6
    u_alpha_per_K: float = 0.0
    eve_um: float = 0.0

    def __post_init__(self):
        for k in ("u_instrument_um", "u_instrument_um_per_m", "misalignment_urad", "u_temperature_K",
                  "alpha_per_K", "u_alpha_per_K", "eve_um"):
            v = getattr(self, k)
            if not (isinstance(v, (int, float)) and math.isfinite(v) and v >= 0):
                raise PositioningLogError(f"uncertainty input {k} must be a finite number >= 0, got {v!r}")
        t = self.temperature_C
        if not (isinstance(t, (int, float)) and math.isfinite(t) and -50 < t < 100):
            raise PositioningLogError(f"uncertainty input temperature_C must be a workshop temperature, got {t!r}")


@dataclass(frozen=True)
class UncertaintyBudget:
    """Expanded uncertainty (k = 2) of each ISO 230-2 figure, µm.

    ``contributions``: source -> (u on the range figures, u on the
    difference figures), µm, k = 1. ``U``: figure name (``E``, ``R``, ...)
    -> expanded uncertainty, µm. ``temperature``: what was done about the
    temperature (:func:`temperature_statement`): nothing to the readings.
    """

    travel_mm: float
    contributions: dict[str, tuple[float, float]]
    U: dict[str, float]
    k: float = 2.0
    temperature: dict | None = None
    U_sampling: dict | None = None
    step_u: dict | None = None

    def to_report(self) -> dict:
        return {"k": self.k, "travel_mm": self.travel_mm,
                "U_what": ("U_<figure>_um: the measuring conditions' part only (instrument, alignment, temperature, "
                           "environment); U_sampling_<figure>_um: the test's own sampling scatter (the figure's "
                           "spread over repeats of the same test, :func:`sampling_uncertainty`), stated apart: "
                           "ISO 230-2's figures are statistics of the readings taken, and a repeat of the test "
                           "moves them by this much"),
                "contributions": [{"source": s, "u_range_um": a, "u_difference_um": b}
                                  for s, (a, b) in self.contributions.items()]
                + ([{"source": STEP_SOURCE, **{f"u_{f}_um": v for f, v in self.step_u.items()}}]
                   if self.step_u else []),
                **{f"U_{f}_um": v for f, v in self.U.items()},
                **({f"U_sampling_{f}_um": v for f, v in self.U_sampling.items()} if self.U_sampling else {}),
                **({"temperature": dict(self.temperature)} if self.temperature is not None else {})}


#: Repeats of the test :func:`sampling_uncertainty` draws (a 2 x std read to ~1.6 % at 4000: sd of a std
#: from N draws is ~1/sqrt(2N)); its generator's seed is fixed, so a report is reproducible.
SAMPLING_RUNS = 4000


def sampling_uncertainty(result: "Iso2302Result", runs: int = SAMPLING_RUNS, seed: int = 0) -> dict:
    """Per figure, 2 x the standard deviation of that figure over repeats of the same test, µm (arcsec for
    a rotary axis): the test's own sampling scatter, which the conditions' budget (:func:`figure_uncertainty`)
    leaves out (review32b F1.1: the sample log's R 5.402 um moves with 2 x std 1.00 um between repeats, its
    conditions' U 0.231).

    A Monte Carlo (JCGM 101) of the test with the log's per-target means and s as the truth and its own number
    of readings n per target and direction: each repeat draws the means from ``N(x̄, s / sqrt n)`` and the
    s from ``s sqrt(chi2_{n-1} / (n - 1))`` (independent, normal readings: their exact sampling laws) and
    evaluates every figure by :func:`figures`. Where n < 2 the s is kept. A plug-in estimate: the truth is the
    data's own, so it is itself uncertain (a 5-reading s by ~35 %). The conditions' budget holds the
    contributions ISO 230-2 names, combined as ISO/TR 230-9 does; the sampling scatter is not among them, so
    this is stated beside that U, not added to it.
    """
    if not (isinstance(runs, int) and runs >= 10):
        raise PositioningLogError(f"sampling_uncertainty: runs must be an integer >= 10, got {runs!r}")
    rng = np.random.default_rng(seed)
    ru, kf = REPORT_UNIT[result.unit]
    m = result.targets.size

    def draw(mean, s, n):
        n = np.asarray(n, float)
        ok = n >= 2
        nn = np.where(ok, n, 2.0)
        mu = mean + s / np.sqrt(np.maximum(n, 1.0)) * rng.standard_normal((runs, m))
        sd = np.where(ok, s * np.sqrt(rng.chisquare(nn - 1.0, (runs, m)) / (nn - 1.0)), s)
        return mu, sd

    xu, su = draw(result.mean_up, result.s_up, result.n_up)
    xd, sd = draw(result.mean_down, result.s_down, result.n_down)
    vals = {f: np.empty(runs) for f in Iso2302Result.FIGURES}
    for i in range(runs):
        r = figures(result.targets, xu[i], xd[i], su[i], sd[i], unit=result.unit)
        for f in Iso2302Result.FIGURES:
            vals[f][i] = getattr(r, f)
    return {f: 2.0 * float(np.std(v, ddof=1)) * kf for f, v in vals.items()}


#: How the rounding of readings printed to a step q enters each figure (session 34, review34: the sample printed to
#: 0.01 mm gave B 8.0, R 17.9, E 18.0, A 34.9 um against 3.3, 5.4, 16.7, 18.6 at full precision, without a word).
#: Each reading's rounding error is uniform of width q: u_q = q / sqrt 12 (GUM 4.3.7). A machine that repeats to
#: better than q prints its n readings of one target alike, so the errors do not average out over the cycles: a
#: mean carries u_q, whatever n, and a difference of two means sqrt 2 u_q (B_i, hence B and B̄; E and M, the
#: range of the means). An s carries about u_q (the rounding adds q²/12 to a spread reading's variance, Sheppard,
#: and a reading finer than q has an s of 0 to about q/2), so 2 s carries 2 u_q: R↑ = 4 s carries 4 u_q, and R
#: (at most 2 s↑ + 2 s↓ + |B_i| or a 4 s) 4 u_q; A↑ (two means and two 2 s) sqrt(1 + 1 + 4 + 4) u_q. The factors
#: multiply u_q; the figures themselves are the standard's, from the readings as printed.
STEP_SENSITIVITY = {"B": math.sqrt(2.0), "B_mean": math.sqrt(2.0), "R_up": 4.0, "R_down": 4.0, "R": 4.0,
                    "E_up": math.sqrt(2.0), "E_down": math.sqrt(2.0), "E": math.sqrt(2.0), "M": math.sqrt(2.0),
                    "A_up": math.sqrt(10.0), "A_down": math.sqrt(10.0), "A": math.sqrt(10.0)}

#: :func:`printed_step` warns when the measured column's step exceeds this many times the median s of the test
#: (over targets and directions). At q = s the rounding adds q²/12 to s² (s up by 4 %) and the rounded readings
#: still behave as continuous ones (Sheppard's correction holds up to q of about 2 s); beyond, five readings of a
#: target take one to three printed values, s is mostly the rounding's, and R and A describe the print, not the
#: machine (the sample at 0.01 mm: q 10 um against s 0.19-0.85 um, R 17.9 for 5.4).
STEP_COARSE_RATIO = 1.0


def printed_step(log: PositioningLog, result: "Iso2302Result") -> tuple[dict, str | None]:
    """What the printed step of ``log``'s readings does to ``result``'s figures: ``(report, warning)``.

    ``report`` (the JSON's ``printed_step``): ``column`` (the measured column), ``step_<unit>`` and
    ``target_step_<unit>`` (:attr:`PositioningLog.text_steps`, file unit; None when unknown, 0 when declared
    exact), ``u_reading_<ru>`` (q / sqrt 12, µm or arcsec) and ``u_<figure>_<ru>`` (:data:`STEP_SENSITIVITY`
    times it), ``s_median_<ru>``, ``coarse`` (q > :data:`STEP_COARSE_RATIO` x the median s) and ``how``.
    ``warning``: one line when coarse, else None. The figures are not changed: the rounding enters U cond
    (:func:`figure_uncertainty`'s ``step``) as a measuring-conditions contribution."""
    u = log.unit
    ru, k = REPORT_UNIT[u]
    mname = _NUMERIC_REQUIRED[u][1]
    q, qt = log.text_steps.get("measured"), log.text_steps.get("target")
    s_all = np.concatenate([np.asarray(result.s_up, float), np.asarray(result.s_down, float)])
    s_med = float(np.median(s_all)) if s_all.size else 0.0
    out: dict = {"column": mname, f"step_{u}": q, f"target_step_{u}": qt, f"s_median_{ru}": s_med * k}
    if q is None:
        out["how"] = "the step the readings were printed to is not known here (not read from text)"
        return out, None
    uq = q / math.sqrt(12.0)
    out[f"u_reading_{ru}"] = uq * k
    out.update({f"u_{f}_{ru}": c * uq * k for f, c in STEP_SENSITIVITY.items()})
    coarse = q > STEP_COARSE_RATIO * s_med
    out["coarse"] = bool(coarse)
    out["how"] = ("each reading's rounding is uniform of width one step (u = step / sqrt 12); a machine repeating "
                  "finer than the step prints its readings alike, so the rounding does not average over cycles: "
                  "sqrt 2 u on B, B_mean, E, M (differences of means), 4 u on R (2 s + 2 s), sqrt 10 u on A; "
                  "in U cond as a measuring-conditions contribution; the figures are the standard's, from the "
                  f"readings as printed; warned when the step exceeds {STEP_COARSE_RATIO:g} x the median s")
    if not coarse:
        return out, None
    qs = f"{q:g} {u}" + (f" ({q * k:g} {ru})" if u == "mm" else "")
    w = (f"{log.source}: {mname} is printed to {qs}, coarser than the readings' repeatability (median s "
         f"{s_med * k:.3g} {ru}{': most targets print their readings alike' if s_med == 0 else ''}): the rounding (u {uq * k:.3g} {ru} a reading) is in every figure, R and A "
         f"up to {STEP_SENSITIVITY['R'] * uq * k:.3g} / {STEP_SENSITIVITY['A'] * uq * k:.3g} {ru} (1 sigma), "
         "B and E by a step (JSON printed_step; in U cond when asked for): export the readings with more decimals")
    return out, w


def temperature_statement(travel_mm: float, inputs: UncertaintyInputs) -> dict:
    """What the budget did with the test's temperature: it corrects no reading (session 31, review31 F10).

    ``expansion_if_uncorrected_um`` is the nominal expansion over the travel, ``L alpha (T - 20 °C)``: the
    scale error E, M and A still hold if the readings did NOT arrive corrected to 20 °C (800 mm x 11.5e-6/K x
    0.5 K = 4.6 um, outside the README sample's U = 2.07 um). ``warning``: a sentence when ``T != 20 °C``.
    """
    dT = inputs.temperature_C - 20.0
    e = travel_mm * 1e3 * inputs.alpha_per_K * dT
    out = {"temperature_C": inputs.temperature_C, "readings_corrected_by_vmt": False,
           "expansion_if_uncorrected_um": e,
           "what": "the readings are taken as already corrected to 20 °C (e.g. by the laser's material-temperature "
                   "compensation); the temperature enters the uncertainty only"}
    if dT != 0:
        out["warning"] = (f"--temp-c {inputs.temperature_C:g}: vmt does not correct the readings to 20 °C; if they "
                          f"did not arrive corrected, E, M and A hold a scale error L alpha (T - 20) = "
                          f"{travel_mm:g} mm x {inputs.alpha_per_K:g}/K x {dT:+g} K = {e:+.3f} um that U "
                          "does not cover")
    return out


#: The budget's name for the readings' printed step (:data:`STEP_SENSITIVITY`).
STEP_SOURCE = "printed step (rounding)"


def figure_uncertainty(result: Iso2302Result, inputs: UncertaintyInputs,
                       step: float | None = None) -> UncertaintyBudget:
    """The uncertainty of the test's figures from the measuring conditions.

    In the manner of ISO/TR 230-9 (combined standard uncertainty as the
    root sum of squares of independent contributions, k = 2), with the
    contributions ISO 230-2 names for this test, each modelled here as:

    ========================  ==================================  ============
    source                    on the range figures (E, M, A)      on B, R
    ========================  ==================================  ============
    instrument                ``sqrt(u_c² + (u_ppm L)²)``          0
    misalignment (cosine)     ``L φ²/2 / (2 sqrt 3)``              0
    temperature measurement   ``L α u_T``                          0
    expansion coefficient     ``L |T - 20 °C| u_α``                0
    environmental variation   ``E_VE / (2 sqrt 3)``                same
    ========================  ==================================  ============

    ``L`` is the measurement travel (largest minus smallest target). The
    ``step``: the step the measured readings were printed to, mm (:attr:`PositioningLog.text_steps`): its
    rounding, u = step / sqrt 12 a reading, enters each figure with :data:`STEP_SENSITIVITY`'s factor
    (``step_u``, a contribution of its own: it neither cancels at one target nor grows with L). The
    instrument, alignment and temperature errors are scale-like (they grow
    with the distance from where the instrument was zeroed), so they enter
    a range over the targets with their value at ``L`` and cancel in a
    difference at one target (B_i, s_i, hence B, B̄, R); the drift of the
    environment during the test does not cancel. The cosine error lies
    between 0 and ``L φ²/2`` (one-sided, rectangular: u = width / sqrt 12);
    a range read as E_VE is rectangular of half-width E_VE / 2. Not
    in ``U``: the test's own sampling scatter (the means and s rest on n
    readings: R and A move most), stated beside it as ``U_sampling``
    (:func:`sampling_uncertainty`); set-up errors (Abbe offsets of the
    instrument to the tool), which belong to the machine's own budget.
    """
    if result.unit != "mm":
        raise PositioningLogError("the test-uncertainty budget is for linear axes (unit mm)")
    L_mm = float(np.max(result.targets) - np.min(result.targets))
    L_m = L_mm * 1e-3
    phi = inputs.misalignment_urad * 1e-6
    rows = {
        "instrument": (math.hypot(inputs.u_instrument_um, inputs.u_instrument_um_per_m * L_m), 0.0),
        "misalignment (cosine)": (L_m * 1e6 * phi * phi / 2 / math.sqrt(12.0), 0.0),
        "temperature measurement": (L_m * 1e6 * inputs.alpha_per_K * inputs.u_temperature_K, 0.0),
        "expansion coefficient": (L_m * 1e6 * abs(inputs.temperature_C - 20.0) * inputs.u_alpha_per_K, 0.0),
    }
    u_eve = inputs.eve_um / math.sqrt(12.0)
    rows["environmental variation"] = (u_eve, u_eve)
    u_range = math.sqrt(sum(a * a for a, _ in rows.values()))
    u_diff = math.sqrt(sum(b * b for _, b in rows.values()))
    k = 2.0
    U = {f: k * u_range for f in ("E_up", "E_down", "E", "M", "A_up", "A_down", "A")}
    U.update({f: k * u_diff for f in ("B", "B_mean", "R_up", "R_down", "R")})
    step_u = None
    if step:
        uq = step * 1e3 / math.sqrt(12.0)
        step_u = {f: c * uq for f, c in STEP_SENSITIVITY.items()}
        U = {f: math.hypot(v, k * step_u[f]) for f, v in U.items()}
    return UncertaintyBudget(travel_mm=L_mm, contributions=rows, U=U, k=k,
                             temperature=temperature_statement(L_mm, inputs),
                             U_sampling=sampling_uncertainty(result), step_u=step_u)

