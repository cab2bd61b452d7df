"""Read, validate and write ``probe-log/1`` files (shared/spec/probe-log.md).

A probe log is the one data contract between every source of touches (the
simulator, the hardware adapter, anybody's shop-floor macros) and the core.
This module keeps the file's own units (mm, degrees, seconds, Celsius) and
column names; :func:`core.touches.from_log` turns a log into SI arrays.

Reading validates everything the spec promises and raises
:class:`~core.exceptions.ProbeLogError` with a one-line message naming the
file, the data row (0-based, as ``outlier_rows`` counts) and the file line.
Writing is lossless (floats as their shortest round-trip repr; a column read or
recorded at a printing step, a controller's 3-decimal readings, to that step's
decimals, declared column by column: :data:`NUMBER_FORMAT_DECIMALS`) and atomic
(a temporary file renamed into place).
"""

from __future__ import annotations

import codecs
import csv
import io
import math
import os
import re
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Iterable, Iterator, Mapping

import numpy as np

from .atomic import input_problem, write_text_atomic
from .exceptions import ConfigError, ProbeLogError, counted

FORMAT = "probe-log/1"
#: Format of :func:`summary` (what ``vmt check --json`` prints).
SUMMARY_FORMAT = "vmt-check/1"

#: Required columns, in the spec's order.
REQUIRED = ("setup", "target", "t_s", "X_mm", "Y_mm", "Z_mm",
            "Xn_mm", "Yn_mm", "Zn_mm", "nx", "ny", "nz")
#: Measured columns: empty in a plan, and in a touch whose status is not ok.
MEASURED = ("X_mm", "Y_mm", "Z_mm", "t_s")
#: Optional columns defined by the spec, in the order vmt writes them.
OPTIONAL = ("feature", "A_deg", "B_deg", "C_deg", "dx", "dy", "dz",
            "wx_mm", "wy_mm", "wz_mm", "wnx", "wny", "wnz", "stylus_r_mm", "status")
#: Columns holding text; every other column is numeric.
TEXT_COLUMNS = ("setup", "target", "feature", "status")
#: Tolerance on the length of unit vectors (normals, approach directions).
UNIT_TOL = 1e-6
#: The coarsest step a unit vector's components may be printed to and still be read (session 30, rank30b): a
#: vector whose components are printed to ``q`` (every component of the column's vectors written with the same
#: decimals, :func:`decimal_quantum`) misses length 1 by up to ``sqrt(3) q / 2`` (8.7e-5 at 4 decimals:
#: ``0.7071``); such a log is read with that tolerance (plus :data:`UNIT_TOL`) and its vectors normalised, the step
#: kept (:attr:`ProbeLog.unit_steps`: the planar baseline's rank tolerance takes the normals' step,
#: ``core.baseline.precision_rank_tol``). Coarser (3 decimals: 0.5 mrad of direction) is refused as before.
#: None: every vector within :data:`UNIT_TOL` (the behaviour before).
UNIT_STEP_MAX: float | None = 1e-4
#: Tolerance (mm) on a target's artefact-frame nominal across set-ups.
TARGET_TOL_MM = 1e-6
#: Largest length (mm) a position may have: 100 m, beyond any machine tool's
#: stroke. It keeps absurd values (1e200) from overflowing the analysis.
LENGTH_MAX_MM = 1e5
#: How far a touch may lie from its nominal, mm (review32d F3; the GRBL and LinuxCNC imports' bounds, kept here
#: in one place, hardware.transcript re-exports them): along its approach line within ALIGN_ALONG_MM (room for a
#: probing stroke, clearance + overtravel, of up to 10 mm; vmt's programs use 2 + 2 mm: a stylus moved along its
#: line triggers between the stroke's ends), and off that line by at most ALIGN_LATERAL_MM (the axes move along
#: the line, so a reading is on it to the controller's rounding, microns; a neighbouring row's line is
#: millimetres away). The probe-log reader warns of a valid touch beyond either, naming its row (a typed reading,
#: a row of another target); the imports refuse a report beyond them (it is not that row's touch).
ALIGN_ALONG_MM = 10.0
ALIGN_LATERAL_MM = 0.5
#: Largest stylus tip radius (mm): discs and balls on long styli stay under 50 mm.
STYLUS_R_MAX_MM = 100.0
#: Largest time since the campaign started (s): 1e10 s is 317 years, so a Unix
#: timestamp written by mistake still reads; 1e200 does not.
T_MAX_S = 1e10
#: Largest rotary axis position (deg): 1e6 deg is 2778 turns of a multi-turn table.
ANGLE_MAX_DEG = 1e6
#: Temperatures (Celsius) from absolute zero to 1000 C (no machine tool runs hotter).
TEMP_RANGE_C = (-273.15, 1000.0)

#: A number in a file: ``[+-]digits[.digits][e[+-]digits]`` (also ``.5`` and ``5.``, as C's strtod
#: reads them), ASCII digits only. Python's float() reads more: ``1_0`` as 10, Arabic-Indic or
#: full-width digits as digits; no CSV reader outside Python does, so vmt refuses them
#: (:func:`is_number`). ``nan`` and ``inf`` are not numbers here either (refused as not finite).
NUMBER = re.compile(r"[+-]?(?:[0-9]+(?:\.[0-9]*)?|\.[0-9]+)(?:[eE][+-]?[0-9]+)?\Z")

#: The columns whose printed step the reader records (:attr:`ProbeLog.text_steps`; session 31, rank31): the nominal
#: tip centres and normals, the numbers the planar design is built from (``core.baseline.precision_rank_tol``), and
#: (session 32, fitq32) the measured tip centres, whose rounding ``vmt fit`` floors each U95 on
#: (``core.features.printing_steps_mm``). A value round by design (``10.0000000``: 7 decimals written) is exact, not
#: rounded: only the text says how many digits were printed (``48.000`` is printed to 1 um, where its value alone
#: reads as whole mm). Counting costs up to 25 ns a cell (:func:`most_decimals`: one scan of each block's text for
#: a longer run of decimals): on a 1e6-row log 0.16 s for the six nominal columns printed to 7 decimals (2.3 % of its
#: read), 0.11 s written by vmt (1.2 %); every numeric column would cost some 6 %.
#: None: no column's step recorded (every decision from the values, as before).
TEXT_STEP_COLUMNS: tuple | None = ("Xn_mm", "Yn_mm", "Zn_mm", "nx", "ny", "nz", "X_mm", "Y_mm", "Z_mm")

#: :func:`most_decimals` counts up to this many decimals (a step of 1e-12 mm: 1e-14 of a 100 mm design, far below
#: any rank tolerance); a column holding more (a shortest round-trip repr, ``71.70328770000001``) reads as printed
#: to 1e-12, and its scan stops at the first such cell instead of growing with every longer run it meets.
TEXT_DECIMALS_MAX = 12

#: The metadata line vmt's writer declares its numbers with (session 31, the lead): every number is the shortest text
#: that reads back as the same double (``repr``), so the digits it shows are not the precision it was written to:
#: ``160.0`` is exactly 160, not 160 to a tenth of a mm. On reading, the columns of :data:`TEXT_STEP_COLUMNS` of a
#: log that declares it take the step 0 (exact): before, a log vmt wrote (``vmt import`` of a plan on whole mm, say)
#: read ``160.0`` as printed to 0.1 mm and its rank tolerance as ``10 x 0.1 mm / L`` (0.01 at L = 100 mm).
#: A file edited by hand keeps the line only if its numbers still are what it says.
NUMBER_FORMAT_KEY, NUMBER_FORMAT_EXACT = "number_format", "shortest round-trip"
#: Session 33 (step33): the same line names the columns printed to fixed decimals, the rest exact as above:
#: ``# number_format: shortest round-trip; decimals X_mm=3, Y_mm=3, Z_mm=3`` is a log whose measured tip centres
#: are a GRBL controller's ``[PRB:...]`` numbers (printed to 1 um) and every other number exact. The reader takes
#: each named column's step as ``10^-K`` (:attr:`ProbeLog.text_steps`, whatever its digits: ``10.0`` in a column
#: declared to 3 decimals is 10 printed to 1 um), refuses a cell with more decimals than its column declares, a
#: column the header lacks, a text column and a K that is not a whole number from 0 to :data:`TEXT_DECIMALS_MAX`;
#: the writer writes those columns to K decimals and declares them so. Before, the line had one word for the whole
#: file: ``vmt import`` and ``vmt probe`` logs declared a controller's 3-decimal readings exact (``vmt fit`` then
#: floored no U95 on their rounding), and a log written with fixed decimals in some columns dropped the line, so
#: its other columns' shortest round-trip digits read as a step (``160.0`` as 0.1 mm). A reader of an earlier
#: session reads such a line as other words (not its own: every column from its digits, as it read the files its
#: own writer wrote with fixed decimals).
NUMBER_FORMAT_DECIMALS = "decimals"


def number_format_value(fixed: Mapping[str, int] | None = None) -> str:
    """The ``number_format`` line's value for a log whose columns ``fixed`` (name -> decimals) are printed to
    fixed decimals and every other number exact (:data:`NUMBER_FORMAT_DECIMALS`)."""
    if not fixed:
        return NUMBER_FORMAT_EXACT
    for k, d in fixed.items():
        if not k or any(ch in k for ch in ",=;") or k != k.strip() or not (0 <= int(d) <= TEXT_DECIMALS_MAX):
            raise ValueError(f"cannot declare column {k!r} printed to {d!r} decimals")
    return (f"{NUMBER_FORMAT_EXACT}; {NUMBER_FORMAT_DECIMALS} "
            + ", ".join(f"{k}={int(d)}" for k, d in fixed.items()))


def parse_number_format(value: str, header, src: str, ln: int | None = None,
                        text_columns=()) -> tuple[bool, dict]:
    """``(exact, fixed)`` of a ``number_format`` value: ``exact`` True for vmt's own words
    (:data:`NUMBER_FORMAT_EXACT`, any case), ``fixed`` the columns it names printed to fixed decimals
    (:data:`NUMBER_FORMAT_DECIMALS`; name -> decimals). Other words: ``(False, {})``, not taken (the digits say
    the precision, as before), unless they hold vmt's list, ``decimals NAME=K`` (without vmt's words before it:
    refused, session 37; words without such a list, ``six decimals``, are still not taken). Raises
    :class:`~core.exceptions.ProbeLogError` (one line naming the file and the metadata line ``ln``) for that and
    for vmt's words followed by a list that does not hold: not ``decimals NAME=K, ...``, a
    column ``header`` lacks or one of ``text_columns``, a column named twice, a K that is not a whole number from
    0 to :data:`TEXT_DECIMALS_MAX`."""
    head, sep, tail = value.strip().partition(";")
    at = f"{src}: " + (f"line {ln}: " if ln is not None else "") + f"metadata {NUMBER_FORMAT_KEY}"
    if head.strip().lower() != NUMBER_FORMAT_EXACT:
        if re.search(rf"\b{NUMBER_FORMAT_DECIMALS}\s+[^\s=,;]+\s*=", value, re.IGNORECASE):
            # session 37 (audit37): vmt's list without vmt's words before it (``decimals X_mm=3``) was other
            # words, ignored without a word: every column then read from its digits, so a cell with more decimals
            # than the line says passed and the columns the line leaves exact read as printed to a step. Refused,
            # as a malformed kinematic_chain, tool_offset_mm or stylus_r_mm is: the line names vmt's list, so it
            # is meant as vmt's, and its one written form is the one taken.
            raise ProbeLogError(f"{at} {_shown(value, 60)}: a '{NUMBER_FORMAT_DECIMALS}' list goes after vmt's "
                                f"words: '{NUMBER_FORMAT_EXACT}; {NUMBER_FORMAT_DECIMALS} COLUMN=K, ...' (the "
                                "columns printed to K decimals, every other number exact)")
        return False, {}
    if not sep:
        return True, {}
    word, _, items = tail.strip().partition(" ")
    if word.lower() != NUMBER_FORMAT_DECIMALS or not items.strip():
        raise ProbeLogError(f"{at} {_shown(value, 60)}: after '{NUMBER_FORMAT_EXACT};' expected "
                            f"'{NUMBER_FORMAT_DECIMALS} COLUMN=K, ...' (the columns printed to K decimals)")
    fixed: dict = {}
    cols = set(header)
    for item in items.split(","):
        name, eq, k = (x.strip() for x in item.partition("="))
        if not name or not eq:
            raise ProbeLogError(f"{at}: {_shown(item.strip())} is not COLUMN=K (a column printed to K decimals)")
        if name not in cols:
            raise ProbeLogError(f"{at}: {NUMBER_FORMAT_DECIMALS} names column {name!r}, which the header does not "
                                "have")
        if name in text_columns:
            raise ProbeLogError(f"{at}: {NUMBER_FORMAT_DECIMALS} names column {name!r}, which holds text, not "
                                "numbers")
        if name in fixed:
            raise ProbeLogError(f"{at}: {NUMBER_FORMAT_DECIMALS} names column {name!r} twice")
        if not re.fullmatch(r"[0-9]{1,3}", k) or int(k) > TEXT_DECIMALS_MAX:
            raise ProbeLogError(f"{at}: {name}={_shown(k)}: the decimals must be a whole number from 0 to "
                                f"{TEXT_DECIMALS_MAX} (more are full precision: leave the column out, it is "
                                "then exact)")
        fixed[name] = int(k)
    return True, fixed

_MORE_DECIMALS: dict = {}
#: a number's exponent, read after its letter (the letter found by str.find: on the 1e6-row bench log, whose repr
#: columns hold a few hundred exponents, counting took 0.22 s with a regular expression's scan for it, 0.11 s so);
#: the mantissa read back from the letter to the cell's start
_EXPONENT = re.compile(r"[+-]?[0-9]+")


def most_decimals(cells) -> int | None:
    """The most decimals written in the cells (text of numbers): ``10.0000000`` has 7, ``10`` and ``10.`` 0;
    ``1.5e-3`` 4 (the mantissa's decimals less the exponent: the step 1e-4 it was written to, at least 0).
    None when no cell holds a number (every one empty); at most :data:`TEXT_DECIMALS_MAX`. Cells are taken as
    :data:`NUMBER` reads them (blanks around a cell ignored); one scan of the block's text, C-speed
    (:data:`TEXT_STEP_COLUMNS`)."""
    s = ",".join(cells)
    if not s.strip(", \t"):
        return None
    d = 0
    up = False
    for letter in "eE":  # numbers with an exponent (rare) counted apart
        e = s.find(letter)
        while e >= 0:
            m = _EXPONENT.match(s, e + 1)
            x = int(m.group()) if m else 0
            dot = s.find(".", s.rfind(",", 0, e) + 1, e)
            d, up = max(d, (e - dot - 1 if dot >= 0 else 0) - x), up or x > 0
            e = s.find(letter, e + 1)
    if up:  # (a positive exponent's mantissa has more decimals than its number: left out of the scan below;
        s = ",".join(c for c in cells if "e" not in c and "E" not in c)  # a negative one's, fewer)
    at = 0
    while True:  # a run of digits after a point longer than d: d grows to it (the text before it holds none)
        if d >= TEXT_DECIMALS_MAX:
            return TEXT_DECIMALS_MAX
        rx = _MORE_DECIMALS.get(d + 1)
        if rx is None:
            rx = _MORE_DECIMALS[d + 1] = re.compile(r"\.[0-9]{%d}[0-9]*" % (d + 1))
        m = rx.search(s, at)
        if m is None:
            return d
        d, at = m.end() - m.start() - 1, m.end()


#: Where a line of a CSV log ends: ``\r\n``, ``\r`` or ``\n``, as CSV (RFC 4180) and Python's csv
#: reader end a record. ``str.splitlines`` also breaks at form feed, vertical tab, ``\x1c``-``\x1e``,
#: U+0085, U+2028 and U+2029, which in a CSV file are characters of a cell (:func:`csv_lines`).
_EOL = re.compile(r"\r\n|\r|\n")


def first_finer(cells, decimals: int) -> int | None:
    """The index of the first cell written with more than ``decimals`` decimals (:func:`most_decimals`), or None:
    the cell a ``number_format`` line's refusal names (the probe log's reader and ``core.positioning``'s)."""
    k = most_decimals(cells) if len(cells) else None
    if k is None or k <= decimals:
        return None
    return next(i for i, c in enumerate(cells) if (most_decimals([c]) or 0) > decimals)


def csv_lines(text: str) -> list[str]:
    """The lines of ``text``, ended by ``\r\n``, ``\r`` or ``\n`` only (:data:`_EOL`), without their ends.

    As ``text.splitlines()`` but for the other characters Unicode counts as line breaks,
    which stay in their line (a form feed or U+2028 in a ``feature`` cell is part of the cell).
    """
    lines = _EOL.split(text) if "\r" in text else text.split("\n")
    if lines[-1] == "":  # the text ends with an end of line (or is empty)
        lines.pop()
    return lines


def is_number(cell: str) -> bool:
    """True when ``cell`` (surrounding blanks ignored) has the form of :data:`NUMBER`."""
    return NUMBER.match(cell.strip()) is not None


_LENGTHS = ("X_mm", "Y_mm", "Z_mm", "Xn_mm", "Yn_mm", "Zn_mm", "wx_mm", "wy_mm", "wz_mm")
#: The statuses the spec names (``ok``, and why a touch is not valid: ``no_trigger``,
#: ``early_trigger``, ``alarm``, the controller stopped the touch with an alarm) and the one
#: vmt adds, ``aborted`` (the rows of a stopped run that ``vmt import`` keeps). Every status
#: but ``ok`` (or an empty cell, the spec's default) marks a touch that is not valid: it is
#: kept in the log and left out of every fit (:attr:`ProbeLog.ok`); the spec's list is open,
#: so any other word reads the same way. A last row without an end of line must end in one
#: of these when ``status`` is its last column; any other word there (``abor``, ``ala``)
#: may be cut short.
KNOWN_STATUSES = ("ok", "no_trigger", "early_trigger", "alarm", "aborted")

_VECTORS = (("nx", "ny", "nz"), ("dx", "dy", "dz"), ("wnx", "wny", "wnz"))

#: The rotary-axis columns: an empty cell is the spec's default, 0 (as the column absent).
ROTARY_COLUMNS = ("A_deg", "B_deg", "C_deg")

#: The units the spec's column names carry (the name's last part), for the message naming a column in another unit.
_UNIT_WORDS = {"mm": "millimetres", "deg": "degrees", "s": "seconds", "C": "degrees Celsius"}


def _spec_meant(name: str, seen) -> str | None:
    """The spec column (:data:`REQUIRED`, :data:`OPTIONAL`) that ``name`` likely means, when ``name`` is not one
    and that column is not in ``seen``: the same stem in another unit or case (``C_rad``, ``c_deg``, ``X_in``,
    ``C``). None otherwise (review34: ``C_rad`` was kept as an unknown column and C read as 0 without a word;
    the spec allows other columns, so the reader warns, it does not refuse)."""
    if name in REQUIRED or name in OPTIONAL:
        return None
    stem = name.rsplit("_", 1)[0].lower() if "_" in name else name.lower()
    for c in REQUIRED + OPTIONAL:
        if "_" not in c or c in seen or c == "stylus_r_mm":
            continue
        if c.rsplit("_", 1)[0].lower() == stem:
            return c
    return None
#: Least cosine between a touch's approach direction (``dx,dy,dz``) and the reversed normal ``-(nx,ny,nz)``
#: (session 31, input31, review31 F5): the spec's normal points "out of the material (towards the stylus)" and
#: ``dx,dy,dz`` is "the approach direction of the stylus at the trigger", so a stylus that triggers on the surface
#: moves into it, ``-(d . n) > 0``. A direction along the normal's side (``d . n >= 0``: away from the surface, or
#: tangential to it) cannot trigger at the target and is refused, naming the row; on a row whose status is not ``ok``
#: (no_trigger, alarm: no trigger happened) it is a warning and the file is read (session 32: one retracting
#: no_trigger row refused the whole campaign's file, review31e). 0.0 refuses only what is
#: physically impossible (no approach angle, however oblique, is judged here); None: no check (before session 31).
APPROACH_INTO_MIN: float | None = 0.0


#: The ``status`` cells that mean a valid touch: empty (the spec's default) and ``ok`` in any case (``OK``, ``Ok``:
#: review31 F6, read as ``ok`` since session 31; before, such rows were left out of every fit without a word).
OK_CELLS = frozenset({"", "ok", "OK", "Ok", "oK"})


def is_ok_status(s: str) -> bool:
    """True for a ``status`` cell that means a valid touch (:data:`OK_CELLS`)."""
    return s in OK_CELLS


def ok_statuses(status: np.ndarray) -> np.ndarray:
    """``status`` with every spelling of ``ok`` (:func:`is_ok_status`, not empty) written ``ok``: the same
    array when there is none to change (distinct values looked at once, so 1e6 rows cost one ``set``)."""
    odd = [v for v in set(status.tolist()) if v != "ok" and v != "" and is_ok_status(v)]
    if not odd:
        return status
    out = status.copy()
    for v in odd:
        out[status == v] = "ok"
    return out


def _is_text(name: str) -> bool:
    return name in TEXT_COLUMNS


def _spec_numeric(name: str) -> bool:
    """True for a column the spec defines as numeric (every other unknown column may hold text)."""
    return (name in REQUIRED or name in OPTIONAL or _is_temp(name)) and not _is_text(name)


def _is_temp(name: str) -> bool:
    return name.startswith("temp_") and name.endswith("_C") and len(name) > 7


def value_range(name: str) -> tuple[float, float, str, str] | None:
    """``(lowest, highest, unit, why)`` a numeric column may hold, or None (any finite value).

    Lengths within +-:data:`LENGTH_MAX_MM`; the stylus radius in [0,
    :data:`STYLUS_R_MAX_MM`] (0: a pin or a tool used as the probe); ``t_s`` in [0, :data:`T_MAX_S`]; rotary
    positions within +-:data:`ANGLE_MAX_DEG`; temperatures in
    :data:`TEMP_RANGE_C`; components of unit vectors within +-(1 +
    :data:`UNIT_TOL`) (their length is checked after).
    """
    if name in _LENGTHS:
        return (-LENGTH_MAX_MM, LENGTH_MAX_MM, "mm", "no machine tool's stroke reaches 100 m")
    if name == "stylus_r_mm":
        return (0.0, STYLUS_R_MAX_MM, "mm", "a tip radius is not negative; 0 for a pin or a tool as the probe")
    if name == "t_s":
        return (0.0, T_MAX_S, "s", "time since the campaign started")
    if name in ("A_deg", "B_deg", "C_deg"):
        return (-ANGLE_MAX_DEG, ANGLE_MAX_DEG, "deg", "")
    if _is_temp(name):
        return (*TEMP_RANGE_C, "C", "")
    if any(name in trio for trio in _VECTORS):
        return (-1 - UNIT_TOL, 1 + UNIT_TOL, "", "a component of a unit vector")
    return None


@dataclass(frozen=True)
class ProbeLog:
    """One probe log in memory, in the file's units.

    Attributes
    ----------
    meta : dict[str, str]
        Metadata ``# key: value`` lines, in file order (unknown keys kept).
    columns : dict[str, numpy.ndarray]
        One array per column, in file order. Text columns are ``object``
        arrays of ``str`` (``""`` when empty); numeric columns are float64,
        NaN where the cell is empty. A validated log holds the spec's default
        in place of an empty cell where the spec gives one (:func:`_validate`:
        rotary angles 0, ``dx,dy,dz`` the reversed normal, ``stylus_r_mm``
        the metadata's), and ``status`` ``ok`` for ``OK``.
    source : str
        Where the log came from (the path), used in error messages.
    warnings : tuple of str
        What reading found doubtful but not wrong (one line each, naming the
        file and row), e.g. a last row without an end of line that may be
        torn. The CLI prints them.
    unit_steps : dict[str, float]
        For each unit-vector column trio read at its printed step's
        tolerance (keyed by its first column, ``"nx"``): the step its
        components were printed to (:data:`UNIT_STEP_MAX`); its vectors
        are stored normalised. Empty when every vector had length 1 within
        :data:`UNIT_TOL` (stored as read).
    text_steps : dict[str, float]
        For each column of :data:`TEXT_STEP_COLUMNS` read from text: the step
        it was printed to, ``10^-k`` for the most decimals ``k`` written in
        the column (``10.0000000``: 1e-7, whatever its values; ``10``: 1):
        the precision the file declares by its digits; 0 (exact) where the file
        declares its numbers exact, and ``10^-K`` for each column the
        ``number_format`` line declares printed to ``K`` decimals
        (:data:`NUMBER_FORMAT_DECIMALS`, any numeric column). Empty for a log
        built in memory (:func:`make_log`): its values alone say their step;
        an import sets the controller's (``hardware.campaign.log_from_plan``).
        The writer prints each column of a step to its decimals and declares it
        (:func:`fixed_decimals`).

    Columns the spec defines are numeric (except ``setup``, ``target``,
    ``feature``, ``status``); a column the spec does not define is numeric
    when every cell is empty or a finite number, and kept as text otherwise.
    """

    meta: dict[str, str]
    columns: dict[str, np.ndarray]
    source: str = "<memory>"
    warnings: tuple = ()
    unit_steps: dict = field(default_factory=dict)
    text_steps: dict = field(default_factory=dict)

    # ---- shape ---------------------------------------------------------
    @property
    def n(self) -> int:
        """Number of touches (rows)."""
        return len(self.columns["setup"]) if "setup" in self.columns else 0

    def __len__(self) -> int:
        return self.n

    def has(self, name: str) -> bool:
        """True when the log has column ``name``."""
        return name in self.columns

    def col(self, name: str) -> np.ndarray:
        """Column ``name``, or its spec default when the log has none."""
        if name in self.columns:
            return self.columns[name]
        n = self.n
        if name == "status":
            return np.array(["ok"] * n, dtype=object)
        if name in ("feature",):
            return np.array([""] * n, dtype=object)
        if name in ("A_deg", "B_deg", "C_deg"):
            return np.zeros(n)
        if name in ("dx", "dy", "dz"):
            return -self.col("n" + name[1])
        if name == "stylus_r_mm":
            v = self.meta.get("stylus_r_mm")
            return np.full(n, float(v) if v not in (None, "") else np.nan)
        return np.full(n, np.nan)

    # ---- derived -------------------------------------------------------
    @property
    def ok(self) -> np.ndarray:
        """(n,) bool: rows whose status is ``ok`` or empty (the spec's default; the rows fits use)."""
        st = self.col("status")
        return np.array([s in OK_CELLS for s in st], dtype=bool)

    @property
    def is_plan(self) -> bool:
        """True when every measured cell is empty (a plan, not a campaign)."""
        return all(np.all(np.isnan(self.columns[c])) for c in MEASURED)

    def positions_mm(self) -> np.ndarray:
        """(n, 3) reported stylus-tip centre, machine frame, mm."""
        return np.column_stack([self.columns[c] for c in ("X_mm", "Y_mm", "Z_mm")])

    def nominals_mm(self) -> np.ndarray:
        """(n, 3) nominal stylus-tip centre at contact, machine frame, mm."""
        return np.column_stack([self.columns[c] for c in ("Xn_mm", "Yn_mm", "Zn_mm")])

    def normals(self) -> np.ndarray:
        """(n, 3) nominal outward surface normal, machine frame."""
        return np.column_stack([self.columns[c] for c in ("nx", "ny", "nz")])

    def dq_mm(self) -> np.ndarray:
        """(n,) measured normal deviation ``n . (X - Xn)`` of each touch, mm."""
        return np.einsum("ij,ij->i", self.normals(), self.positions_mm() - self.nominals_mm())

    def temperature_columns(self) -> list[str]:
        """Names of the ``temp_<name>_C`` columns."""
        return [c for c in self.columns if c.startswith("temp_") and c.endswith("_C")]

    def select(self, rows: np.ndarray) -> "ProbeLog":
        """A new log with only ``rows`` (bool mask or indices), order kept."""
        return replace(self, columns={k: v[rows] for k, v in self.columns.items()})


def make_log(columns: Mapping[str, Iterable], meta: Mapping[str, str] | None = None,
             source: str = "<memory>", *, validate: bool = True) -> ProbeLog:
    """Build a :class:`ProbeLog` from column sequences (file units).

    Required columns must be present; ``format`` metadata is set to
    ``probe-log/1``. With ``validate`` the same checks as reading apply.
    """
    m = {"format": FORMAT}
    m.update({str(k): str(v) for k, v in (meta or {}).items()})
    cols: dict[str, np.ndarray] = {}
    for name, values in columns.items():
        if isinstance(values, np.ndarray) and values.dtype != object:
            vals = values
        else:
            vals = list(values)
        if _is_text(name) or (not _spec_numeric(name) and _text_cells(vals)):
            cols[name] = np.array(["" if v is None else str(v) for v in vals], dtype=object)
        else:
            cols[name] = np.asarray(vals, dtype=float).copy()
    log = ProbeLog(meta=m, columns=_ordered(cols), source=source)
    if validate:
        log = replace(log, unit_steps=_validate(log, lines=None))
    return log


def _text_cells(values) -> bool:
    """True when some value is a string that is not empty and not a finite number."""
    for v in values:
        if isinstance(v, str) and v.strip():
            if not is_number(v):
                return True
            if not math.isfinite(float(v)):  # 1e999
                return True
    return False


def _is_text_column(name: str, v: np.ndarray) -> bool:
    return _is_text(name) or v.dtype == object


def _ordered(cols: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
    """Columns in the canonical order: required, optional, then the rest."""
    out = {k: cols[k] for k in REQUIRED if k in cols}
    out.update({k: cols[k] for k in OPTIONAL if k in cols})
    out.update({k: v for k, v in cols.items() if k not in out})
    return out


# ---------------------------------------------------------------------------
# reading


def read_probe_log(path: str | os.PathLike, *, progress=None) -> ProbeLog:
    """Read and validate a ``probe-log/1`` file.

    The file is read line by line and its columns are built in blocks of
    :data:`CHUNK_ROWS` rows, so memory grows with the columns, never with
    the text (a million rows of 20 columns: 0.55 GB peak for ``vmt check``,
    3.75 GB when the text, its lines and every cell were held at once): a
    regular file is read twice (a first pass checks the encoding, NUL bytes
    and counts the lines), a pipe is read into memory once.

    Parameters
    ----------
    path : path-like
        The CSV file (a regular file, or a pipe).
    progress : callable, optional
        ``progress(lines_done, lines)`` after each block of rows parsed and once
        when the log is validated (``lines_done == lines``): a 1e6-row file
        takes some 20 s.

    Returns
    -------
    ProbeLog

    Raises
    ------
    ProbeLogError
        One line naming the file, row and what is wrong: missing, unreadable
        or empty file, a folder or device, no header, missing required
        column, a non-numeric or non-finite value, a value outside its
        physical range (:func:`value_range`), a normal or approach vector
        not of unit length (tolerance 1e-6), a ``target`` whose
        artefact-frame nominal differs between set-ups, time going
        backwards, a row of the wrong width, a torn last row, an approach
        direction not into the material (:data:`APPROACH_INTO_MIN`), a
        metadata key given twice with two values, a ``#`` line after the
        header. Empty cells of optional columns take the spec's defaults
        (:func:`_validate`).
    """
    p = Path(path)
    src = str(p)
    problem = input_problem(p, "probe log file")
    if problem:
        raise ProbeLogError(f"{src}: {problem}")
    try:
        with p.open("rb") as f:
            if not f.seekable():  # a pipe: read once, then twice from memory
                f = io.BytesIO(f.read())
            n_lines, unterminated = _scan(f, src)
            f.seek(0)
            return _parse(_file_lines(f), n_lines, unterminated, src, progress)
    except OSError as e:
        raise ProbeLogError(f"{src}: cannot read: {e.strerror or e}") from None
    except UnicodeDecodeError:  # the first pass found it UTF-8: another program wrote to it since
        raise ProbeLogError(f"{src}: changed while being read (not UTF-8 text any more): read it again") from None


def _file_lines(f) -> Iterator[str]:
    """The lines of a binary file as :func:`csv_lines` of its UTF-8 text gives them."""
    for i, raw in enumerate(f):  # split at b"\n", which no UTF-8 sequence holds
        yield from csv_lines(raw.decode("utf-8-sig" if i == 0 else "utf-8"))


def _scan(f, src: str) -> tuple[int, bool]:
    """First pass over a binary file: (number of lines, True when the last ends without an end of line).

    Raises, in this order, on text that is not UTF-8 (naming the byte
    offset in the file), on NUL bytes and on a file with nothing but white space.
    """
    off, n, nul, blank, last = 0, 0, False, True, ""
    for i, raw in enumerate(f):
        bom = 3 if i == 0 and raw.startswith(codecs.BOM_UTF8) else 0
        try:
            s = raw[bom:].decode("utf-8")
        except UnicodeDecodeError as e:
            from core.atomic import not_text_problem

            raise ProbeLogError(f"{src}: {not_text_problem(src, raw if off == 0 else b'', e, off + bom)}") from None
        off += len(raw)
        nul = nul or "\x00" in s
        blank = blank and not s.strip()
        n += len(csv_lines(s))
        last = s
    if nul:
        raise ProbeLogError(f"{src}: holds NUL bytes: not a text file")
    if blank:
        raise ProbeLogError(f"{src}: empty file")
    return n, not last.endswith(("\n", "\r"))


#: What a user does about a torn last row of a probe log.
PROBE_LOG_REMEDY = "`vmt probe --resume` cuts it off, or delete the line"


def _torn(src: str, r: int, ln: int, what: str, error: type = ProbeLogError,
          remedy: str = PROBE_LOG_REMEDY) -> Exception:
    return error(
        f"{src}: row {r} (line {ln}): torn last row ({what}, and no end of line): its writer was "
        f"interrupted; {remedy} (if the row is whole, written by hand or another tool, correct it and end "
        "the file with a newline)")


def last_row_check(src: str, header: list, row: list, r: int, ln: int, *, numeric, width: int | None = None,
                   statuses: tuple = KNOWN_STATUSES, error: type = ProbeLogError,
                   remedy: str = PROBE_LOG_REMEDY) -> str | None:
    """The torn-row rule for the last row of a CSV log that ends without an end of line.

    Where a writer that died would have stopped. ``row`` (its cells) is
    refused as torn (``error``, one line naming ``src``, data row ``r`` and
    file line ``ln``) when a cut would change its meaning: fewer fields than
    ``width`` (default the header's), a last field in a column that
    ``numeric(name)`` says holds numbers cut to no number, or a last
    ``status`` field that is not one of ``statuses`` (empty, or any other
    word: ``abor`` may be ``aborted`` cut short). A row that still reads
    whole gives a warning (returned; a file written by hand may lack its
    last end of line), a whole status word none (it reads as written). The
    probe-log and positioning-log readers share it.
    """
    width = len(header) if width is None else width
    if len(row) < width:
        raise _torn(src, r, ln, f"{len(row)} of {width} fields", error, remedy)
    cell, name = row[-1].strip(), header[len(row) - 1] if len(row) <= len(header) else ""
    if name == "status":
        if cell not in statuses and cell.lower() not in statuses:  # OK is ok, whole (OK_CELLS)
            raise _torn(src, r, ln, f"last field status {_shown(cell)} is not a whole status word "
                        f"({', '.join(statuses)})", error, remedy)
        return None
    if numeric(name) and cell:
        try:
            float(cell)
        except ValueError:
            raise _torn(src, r, ln, f"last field {name} {cell!r} is no number", error, remedy) from None
    return (f"{src}: row {r} (line {ln}): the file ends without an end of line: if its writer was "
            f"interrupted, the last field ({name} {_shown(cell)}) may be cut short")


def parse_probe_log(text: str, source: str = "<memory>") -> ProbeLog:
    """Parse probe-log text (see :func:`read_probe_log`).

    A last row without an end of line is where a writer that died would
    have stopped. It is refused as torn when it may be cut short and the
    cut would change its meaning: too few fields, a number cut to no number,
    or a ``status`` last field that is not one of :data:`KNOWN_STATUSES`
    (empty, or any other word: ``abor`` may be ``aborted`` cut short). A
    last row that still reads whole (a number, a text column) is kept with a
    warning (:attr:`ProbeLog.warnings`): a file written by hand may lack its
    last end of line.
    """
    if "\x00" in text:
        raise ProbeLogError(f"{source}: holds NUL bytes: not a text file")
    if not text.strip():
        raise ProbeLogError(f"{source}: empty file")
    lines = csv_lines(text)
    return _parse(iter(lines), len(lines), not text.endswith(("\n", "\r")), source)


#: Rows parsed into column arrays at a time (bounds the memory of raw text cells).
CHUNK_ROWS = 32768
#: Distinct values of a text column shared as one string object each (setup and
#: target names, statuses repeat): past this many, new values are kept as read.
_POOL_MAX = 65536


def _with_ends(first: str, rest: Iterator[str]) -> Iterator[str]:
    """``first`` then ``rest``, each line but the last with its end of line (as the csv reader wants)."""
    prev = first
    for s in rest:
        yield prev + "\n"
        prev = s
    yield prev


class _Columns:
    """Column arrays built block by block from rows of text cells.

    Numbers are parsed by ``float`` (a block at once when every cell is a
    finite number, cell by cell otherwise); the first bad cell of each
    column is kept as its error and raised only after every row was read,
    so a file with several faults names the same one as reading everything
    first would (rows' widths, then columns in header order).
    """

    def __init__(self, header: list[str], src: str, declared: Mapping[str, int] | None = None):
        self.header, self.src = header, src
        self.kind = ["text" if _is_text(h) else "num" if _spec_numeric(h) else "unknown" for h in header]
        self.parts: list[list] = [[] for _ in header]
        self.error: list[str | None] = [None] * len(header)
        self.pools: list[dict] = [{} for _ in header]
        self.lines: list[np.ndarray] = []
        self.n = 0
        want = TEXT_STEP_COLUMNS or ()
        declared = dict(declared or {})
        #: the most decimals written so far in each column whose step is recorded or declared (None: no number yet)
        self.decimals: dict[int, int | None] = {j: None for j, h in enumerate(header) if h in want or h in declared}
        #: the decimals the metadata declares, by column index (``number_format``'s ``decimals``), and the first cell
        #: found with more (its message; raised after the rows' and the numbers' own errors)
        self.declared: dict[int, int] = {j: declared[h] for j, h in enumerate(header) if h in declared}
        self.declared_error: str | None = None

    def _text(self, j: int, cells) -> list:
        pool = self.pools[j]
        out = []
        for c in cells:
            c = c.strip()
            v = pool.get(c)
            if v is None:
                v = c
                if len(pool) < _POOL_MAX:
                    pool[c] = c
            out.append(v)
        return out

    def _numbers(self, j: int, cells, row0: int, lines: np.ndarray) -> np.ndarray | None:
        try:
            v = np.fromiter(map(float, cells), float, count=len(cells))
            # what float() reads beyond NUMBER: '_' between digits, non-ASCII digits and blanks
            # (nan, inf fail isfinite); one pass over the joined block keeps 1e6 rows fast
            if np.isfinite(v).all() and "_" not in (block := "".join(cells)) and block.isascii():
                return v
        except ValueError:
            pass
        v = np.empty(len(cells))
        name = self.header[j]
        for r, c in enumerate(cells):
            c = c.strip()
            if c == "":
                v[r] = np.nan
                continue
            try:
                x = float(c)
            except ValueError:
                x = None
            if x is None or (math.isfinite(x) and not is_number(c)):
                self.error[j] = (f"{self.src}: row {row0 + r} (line {lines[r]}): column {name!r}: "
                                 f"{_shown(c)} is not a number")
                return None
            if not math.isfinite(x):
                self.error[j] = (f"{self.src}: row {row0 + r} (line {lines[r]}): column {name!r}: "
                                 f"{_shown(c)} is not finite")
                return None
            v[r] = x
        return v

    def add(self, rows: list[list[str]], lines: list[int]) -> None:
        """Parse a block of rows (each as wide as the header) read from file ``lines``."""
        if not rows:
            return
        ln = np.asarray(lines, dtype=np.int64)
        for j, cells in enumerate(zip(*rows)):
            if self.kind[j] == "text":
                self.parts[j].append(np.array(self._text(j, cells), dtype=object))
            elif self.kind[j] == "unknown":
                self.parts[j].extend(c.strip() for c in cells)
            elif self.error[j] is None:
                v = self._numbers(j, cells, self.n, ln)
                if v is not None:
                    self.parts[j].append(v)
                    if j in self.decimals:
                        self._count(j, cells, self.n, ln)
        self.lines.append(ln)
        self.n += len(rows)

    def _count(self, j: int, cells, row0: int, lines: np.ndarray) -> None:
        """Count the decimals of a block of column ``j``'s cells (rows from ``row0``, file ``lines``); a cell
        with more than the column declares is kept as :attr:`declared_error` (the first one met)."""
        d, k = self.decimals[j], most_decimals(cells)
        self.decimals[j] = k if d is None else d if k is None else max(d, k)
        want = self.declared.get(j)
        r = (first_finer(cells, want) if want is not None and k is not None and k > want and self.declared_error is None
             else None)   # (the block's count k above: the search only where a cell is finer, once per log)
        if r is not None:
            self.declared_error = (
                f"{self.src}: row {row0 + r} (line {lines[r]}): column {self.header[j]!r}: {_shown(cells[r].strip())} "
                f"has more decimals than the {want} the metadata {NUMBER_FORMAT_KEY} declares for the column: "
                "correct the line (or the number)")

    def columns(self) -> dict[str, np.ndarray]:
        """The columns, or the first column's first error (``ProbeLogError``)."""
        cols: dict[str, np.ndarray] = {}
        lines = self.line_of_row()
        for j, name in enumerate(self.header):
            if self.error[j] is not None:
                raise ProbeLogError(self.error[j])
            part = self.parts[j]
            if self.kind[j] == "unknown":
                if _text_cells(part):
                    if j in self.declared:
                        raise ProbeLogError(f"{self.src}: metadata {NUMBER_FORMAT_KEY}: {NUMBER_FORMAT_DECIMALS} "
                                            f"names column {name!r}, which holds text, not numbers")
                    cols[name] = np.array(self._text(j, part), dtype=object)
                else:
                    v = self._numbers(j, part, 0, lines)
                    if v is None:  # pragma: no cover - _text_cells let no bad cell through
                        raise ProbeLogError(self.error[j])
                    cols[name] = v
                    if j in self.decimals:
                        self._count(j, part, 0, lines)
            elif self.kind[j] == "text":
                cols[name] = np.concatenate(part) if part else np.array([], dtype=object)
            else:
                cols[name] = np.concatenate(part) if part else np.empty(0)
            self.parts[j] = []
        return cols

    def line_of_row(self) -> np.ndarray:
        return np.concatenate(self.lines) if self.lines else np.empty(0, dtype=np.int64)

    def steps(self, exact: bool = False) -> dict[str, float]:
        """The step each recorded column was printed to (:attr:`ProbeLog.text_steps`): a declared column's
        declared step (``10^-K``), every other column of :data:`TEXT_STEP_COLUMNS` that holds a number the step
        of its most decimals, or 0 where the file declares its numbers ``exact`` (:data:`NUMBER_FORMAT_KEY`)."""
        want = TEXT_STEP_COLUMNS or ()
        out = {self.header[j]: 0.0 if exact else 10.0 ** -d for j, d in self.decimals.items()
               if d is not None and self.header[j] in want and j not in self.declared}
        out.update({self.header[j]: 10.0 ** -k for j, k in self.declared.items()})
        return out


#: The metadata keys whose value changes how vmt reads a log (probe log and positioning log): a key given twice with
#: two values is refused (review31 F13). Any other key (``machine``, ``Note``, an operator's ``TODO:``) is kept and
#: ignored as the specs say of unknown keys ("Unknown keys are kept and ignored"): given again with another value,
#: the first is kept and a warning names both lines (review31e F1: refusing them stopped every command on a shop
#: macro's repeated ``# Note:`` comment).
READ_META_KEYS = frozenset({"format", "stylus_r_mm", "kinematic_chain", "unit", "axis", "cycle_kind",
                            "number_format"})


def add_meta(meta: dict, meta_line: dict, s: str, ln: int, src: str, error: type = ProbeLogError,
             warnings: list | None = None) -> None:
    """Add the metadata line ``s`` (file line ``ln``, starting with ``#``) to ``meta``: ``# key: value``; a line
    without ``:`` is a comment. A key of :data:`READ_META_KEYS` given again with another value is refused
    (``error``, naming the key and both lines: review31 F13; before session 31 the last line won without a word);
    any other key keeps its first value, and ``warnings`` gets a line naming both. The same value again is the
    same statement, kept once. The probe-log and positioning-log readers share it."""
    body = s[1:].strip()
    if ":" not in body:
        return
    k, v = body.split(":", 1)
    k, v = k.strip(), v.strip()
    if k in meta and meta[k] != v:
        both = f"{_shown(meta[k])} on line {meta_line[k]}, {_shown(v)} on line {ln}"
        if k in READ_META_KEYS:
            raise error(f"{src}: line {ln}: metadata key {k!r} given twice: {both}: keep the one that holds")
        if warnings is not None:
            warnings.append(f"line {ln}: metadata key {k!r} given twice ({both}): the first kept (vmt does not "
                            "read it)")
    meta.setdefault(k, v)
    meta_line.setdefault(k, ln)


#: What a ``#`` line after the header is (review31 F14): the spec has metadata lines before the header only.
COMMENT_AFTER_HEADER = ("a '#' line after the header: metadata and comment lines are allowed only before the "
                        "header (line {header}); move it up or delete it")


#: First characters of a cell that may start a ``#`` line (``#`` itself, or blanks before it): the cheap test every
#: row meets before :func:`_comment_row`.
_COMMENT_STARTS = ("#", " ", "\t")


def _comment_row(row: list[str]) -> bool:
    """True for a CSV record that is a ``#`` line (its first cell starts with ``#``)."""
    return bool(row) and row[0].lstrip().startswith("#")


def _parse(lines: Iterator[str], n_lines: int, unterminated: bool, src: str, progress=None) -> ProbeLog:
    """Parse the lines of a probe log (``n_lines`` in all; the last without an end of line when ``unterminated``);
    ``progress(lines_done, n_lines)`` after each block and when validated (:func:`read_probe_log`)."""
    meta: dict[str, str] = {}
    meta_line: dict[str, int] = {}
    meta_warnings: list[str] = []
    i, first = 0, None
    for s in lines:
        i += 1
        if s.startswith("#"):
            add_meta(meta, meta_line, s, i, src, warnings=meta_warnings)
        elif s.strip():
            first = s
            break
    if first is None:
        raise ProbeLogError(f"{src}: no header row (only metadata lines)")
    fmt = meta.get("format")
    if fmt is not None and fmt != FORMAT:
        raise ProbeLogError(f"{src}: format {fmt!r} is not {FORMAT!r}")
    header_line = i  # 1-based file line of the header
    reader = csv.reader(_with_ends(first, lines))
    try:
        header = [h.strip() for h in next(reader)]
    except (StopIteration, csv.Error) as e:  # pragma: no cover - csv edge
        raise ProbeLogError(f"{src}: line {header_line}: unreadable header ({e})") from None
    if not any(h in REQUIRED for h in header):
        raise ProbeLogError(
            f"{src}: line {header_line}: no header row (expected columns such as "
            f"'setup,target,t_s,...', got {','.join(header[:4])!r})")
    seen = set()
    for h in header:
        if h in seen:
            raise ProbeLogError(f"{src}: line {header_line}: duplicate column {h!r}")
        if not h:
            raise ProbeLogError(f"{src}: line {header_line}: empty column name")
        seen.add(h)
    missing = [c for c in REQUIRED if c not in seen]
    if missing:
        near = [h for h in header if _spec_meant(h, ()) == missing[0]]
        raise ProbeLogError(f"{src}: missing required column {missing[0]!r}"
                            + (f" (and {len(missing) - 1} more)" if len(missing) > 1 else "")
                            + (f"; column {near[0]!r} is there: the spec's name carries its unit "
                               f"({missing[0]!r}: {_UNIT_WORDS.get(missing[0].rsplit('_', 1)[-1], '')})"
                               if near else ""))
    misnamed = [(h, m) for h in header if (m := _spec_meant(h, seen)) is not None]
    width = len(header)
    declared = meta.pop(NUMBER_FORMAT_KEY, None)  # (the file's text, not the log's content: a round trip equal)
    exact, fixed = (False, {}) if declared is None else parse_number_format(
        declared, header, src, meta_line.get(NUMBER_FORMAT_KEY), TEXT_COLUMNS)
    cols = _Columns(header, src, fixed)
    block: list[list[str]] = []
    block_lines: list[int] = []
    last_row, last_ln, last_end = None, 0, 0
    hashed: list[tuple[int, str]] = []  # whole rows whose set-up starts with '#' (file line, set-up)
    # the file line where each record starts: a quoted cell may hold ends of line, so a record
    # may span lines (reader.line_num counts the lines read, the header's first)
    ln, end = header_line + 1, header_line
    try:
        for row in reader:
            ln, end = end + 1, header_line - 1 + reader.line_num
            if not row or not "".join(row).strip():  # a blank row (every cell white space)
                continue
            if row[0][:1] in _COMMENT_STARTS and _comment_row(row):
                if len(row) != width:
                    raise ProbeLogError(f"{src}: line {ln}: " + COMMENT_AFTER_HEADER.format(header=header_line))
                hashed.append((ln, row[0].strip()))  # a whole row: a set-up named '#..', or a row commented out
            if len(row) != width:
                if unterminated and end == n_lines and len(row) < width:
                    last_row_check(src, header, row, cols.n + len(block), ln, numeric=_spec_numeric)
                raise ProbeLogError(
                    f"{src}: row {cols.n + len(block)} (line {ln}): {counted(len(row), 'field')}, header has {width}")
            block.append(row)
            block_lines.append(ln)
            last_row, last_ln, last_end = row, ln, end
            if len(block) == CHUNK_ROWS:
                cols.add(block, block_lines)
                block, block_lines = [], []
                if progress is not None:
                    progress(end, n_lines)
    except csv.Error as e:  # in the record that starts at line end + 1
        raise ProbeLogError(f"{src}: line {end + 1}: {e}") from None
    cols.add(block, block_lines)
    del block, block_lines
    # the last row ends the file without an end of line: torn, or written by hand?
    warnings = list(meta_warnings)
    for h, m in misnamed:   # (review34: a 'C_rad' column was carried along and C read as 0 without a word)
        warnings.append(f"column {h!r} is not a probe-log column and is not read (carried along): the spec's is "
                        f"{m!r} ({_UNIT_WORDS.get(m.rsplit('_', 1)[-1], 'no unit')}); without it "
                        + (f"{m.split('_')[0]} is read as 0" if m in ROTARY_COLUMNS else f"{m!r} takes its default")
                        + f": rename the column {m!r} (and convert its values) if it means that")
    if hashed:  # (review31e F2: a data row commented out with '#' became a one-touch set-up without a word)
        warnings.append(f"line {hashed[0][0]}: a whole row after the header starts with '#' (set-up {hashed[0][1]!r}"
                        + (f"; {len(hashed) - 1} more such rows" if len(hashed) > 1 else "")
                        + "): read as a touch, not a comment ('#' lines are comments only before the header); "
                          "delete a commented-out row, or name the set-up without '#'")
    if unterminated and last_row is not None and last_end == n_lines:
        w = last_row_check(src, header, last_row, cols.n - 1, last_ln, numeric=_spec_numeric)
        if w is not None:
            warnings.append(w)
    line_of_row = cols.line_of_row()
    columns = cols.columns()
    if cols.declared_error is not None:
        raise ProbeLogError(cols.declared_error)
    steps = cols.steps(exact)  # every number exact as written but the columns declared to fixed decimals
    log = ProbeLog(meta=meta, columns=columns, source=src, warnings=tuple(warnings), text_steps=steps)
    log = replace(log, unit_steps=_validate(log, lines=line_of_row, warnings=warnings))
    if len(warnings) > len(log.warnings):
        log = replace(log, warnings=tuple(warnings))
    if progress is not None:
        progress(n_lines, n_lines)
    return log


def _shown(cell: str, n: int = 40) -> str:
    """``repr`` of a cell, cut to ``n`` characters (a message stays one short line)."""
    return repr(cell if len(cell) <= n else cell[:n] + "...")


def _num(x) -> str:
    """A value for a message: 6 significant digits when they are the value, else every digit it has
    (``100000.001`` next to a bound of ``100000`` must not print as ``100000``)."""
    x = float(x)
    g = f"{x:.6g}"
    return g if float(g) == x else repr(x)


def _xyz(v) -> str:
    """``(1, 2, 3.01)``: a point for a message (plain numbers, never ``np.float64(...)``)."""
    return "(" + ", ".join(f"{float(x):.9g}" for x in v) + ")"


def step_back(t: np.ndarray) -> tuple[int, int] | None:
    """The first place a clock goes backwards: ``(row before, row)`` of the first decrease
    between successive known times (NaN rows skipped), or None."""
    idx = np.flatnonzero(~np.isnan(t))
    back = np.flatnonzero(np.diff(t[idx]) < 0)
    return (int(idx[back[0]]), int(idx[back[0] + 1])) if back.size else None


def _where(src: str, r: int, lines: np.ndarray | None) -> str:
    return f"{src}: row {r}" + (f" (line {lines[r]})" if lines is not None else "")


def decimal_quantum(v: np.ndarray, max_decimals: int = 9) -> float:
    """The step the values ``v`` are printed to: ``10^-k`` for the fewest decimals ``k`` (0 .. ``max_decimals``)
    that write every one of them (to 1e-3 of that step: a value read from text and scaled back carries a few ulp);
    0.0 when none does (full precision, or values computed, not read)."""
    v = np.asarray(v, float).ravel()
    v = v[np.isfinite(v)]
    if not v.size:
        return 0.0
    for k in range(max_decimals + 1):
        s = v * 10.0 ** k
        if np.max(np.abs(s - np.round(s))) <= 1e-3:
            return 10.0 ** -k
    return 0.0


def rounding_sd(q):
    """The standard uncertainty of a value printed (or read) to the step ``q``: ``q / sqrt(12)``, the rounding
    error's rectangular distribution of half-width ``q / 2`` (JCGM 100:2008, F.2.2.1, the resolution of an
    indication). The one rule of every estimator that floors a scatter or an uncertainty on a printing step
    (``core.causes.clock_sensors``: a temperature's scatter; ``core.features``: ``vmt fit``'s U95). Works on
    floats and arrays alike."""
    return q / np.sqrt(12.0)


def far_from_nominal(log: ProbeLog, ok: np.ndarray, lines: np.ndarray | None, warnings: list) -> None:
    """Warn of valid touches farther from their nominal than a probe triggers (:data:`ALIGN_ALONG_MM` along the
    approach line, :data:`ALIGN_LATERAL_MM` off it), naming the first row of each kind and counting the rest
    (review32d F3: a reading typed 10 mm off along its normal gave identify a residual of 364 um blamed on the
    error tables, and one 99.9 m off sideways passed unseen). Warned, not refused: the log's own format bounds
    only the values, a program with a longer stroke may write a far touch, and identify names the rows that
    dominate its residual (:func:`core.selfcal.dominant_rows`)."""
    c = log.columns
    v = np.column_stack([c[k] - c[kn] for k, kn in (("X_mm", "Xn_mm"), ("Y_mm", "Yn_mm"), ("Z_mm", "Zn_mm"))])
    d = (np.column_stack([c["dx"], c["dy"], c["dz"]]) if "dx" in c
         else -np.column_stack([c["nx"], c["ny"], c["nz"]]))
    with np.errstate(invalid="ignore"):
        along = np.einsum("ij,ij->i", v, d)
        lat = np.linalg.norm(v - along[:, None] * d, axis=1)
        far = (ok & (np.abs(along) > ALIGN_ALONG_MM), ok & (lat > ALIGN_LATERAL_MM))
    for bad, what, bound, why in (
            (far[0], "along its approach line (dx,dy,dz)", ALIGN_ALONG_MM, "a probing stroke's ends may be from it"),
            (far[1], "off its approach line", ALIGN_LATERAL_MM, "a reading may lie off the line the axes moved on")):
        if bad.any():
            r = int(np.argmax(bad))
            how = (f"{along[r]:+.6g} mm from its nominal {what}" if bound == ALIGN_ALONG_MM else
                   f"{lat[r]:.6g} mm {what} through its nominal")
            more = f" ({counted(int(bad.sum()) - 1, 'more such touch', 'more such touches')})" if bad.sum() > 1 else ""
            warnings.append(
                f"{_where(log.source, r, lines)}: set-up {c['setup'][r]!r}, target {c['target'][r]!r}: reading "
                f"{_xyz((c['X_mm'][r], c['Y_mm'][r], c['Z_mm'][r]))} mm lies {how}, beyond the {bound:g} mm {why}"
                f"{more}: a typed or misplaced reading? Every fit takes it as a touch")


#: The metadata key of the probe's offsets J a log's readings were logged with (``X,Y,Z`` mm; docs/formats.md,
#: "Metadata vmt writes and reads"; written by :mod:`hardware.campaign`).
TOOL_OFFSET_KEY = "tool_offset_mm"


def parse_tool_offset_mm(text: str, name: str = "--tool-offset-mm") -> tuple[float, float, float]:
    """``"0,0,150"`` -> ``(0.0, 0.0, 150.0)``: the probe's offsets J, mm, three finite numbers each within
    :data:`LENGTH_MAX_MM`; else a ConfigError naming ``name`` (the option, or the metadata key) and the value.
    The one parser of ``--tool-offset-mm`` and of a log's ``tool_offset_mm`` line
    (:func:`hardware.campaign.parse_tool_offset`)."""
    try:
        v = tuple(float(x) for x in str(text).split(","))
    except ValueError:
        v = ()
    if len(v) != 3 or not all(math.isfinite(x) for x in v):
        raise ConfigError(f"{name} {text!r}: expected X,Y,Z, three finite numbers, mm (the probe's offsets J: "
                          "spindle gauge point minus stylus-tip centre)")
    if max(abs(x) for x in v) > LENGTH_MAX_MM:
        raise ConfigError(f"{name} {text!r}: beyond {LENGTH_MAX_MM:g} mm, no probe's offset")
    return v


def _check_meta_values(meta: Mapping, src) -> None:
    """Refuse a ``kinematic_chain`` that is no chain and a ``tool_offset_mm`` that is not three finite lengths,
    naming the file (audit37: ``vmt check`` passed both, which ``identify``, ``discover`` and ``vcmm`` then
    refused: a file ``check`` accepts is a file they accept, docs/formats.md). An empty value is no statement."""
    from .chain import parse_chain

    chain = meta.get("kinematic_chain")
    if chain not in (None, ""):
        try:
            parse_chain(chain)
        except ConfigError as e:
            raise ProbeLogError(f"{src}: metadata kinematic_chain: {e}") from None
    J = meta.get(TOOL_OFFSET_KEY)
    if J is not None:
        try:
            parse_tool_offset_mm(J, TOOL_OFFSET_KEY)
        except ConfigError as e:
            raise ProbeLogError(f"{src}: metadata {e}") from None


def _validate(log: ProbeLog, lines: np.ndarray | None, warnings: list | None = None) -> dict:
    """Check ``log`` (raise :class:`ProbeLogError` naming the first problem); normalise in place the unit vectors
    printed to a step up to :data:`UNIT_STEP_MAX` and return those steps (:attr:`ProbeLog.unit_steps`).

    Empty cells of the optional columns the spec gives a default take it, in place (session 31, review31 F3, F9:
    before, they were NaN, which ``vmt check`` passed and ``discover`` and ``identify`` then broke on or
    misread): ``A_deg``, ``B_deg``, ``C_deg`` 0; ``dx,dy,dz`` (all three empty: one given in part is refused)
    the reversed normal; ``stylus_r_mm`` the metadata ``stylus_r_mm`` (left empty without it: the row has no
    radius, which only ``vmt fit`` needs and refuses naming the row); ``status`` ``ok``, any case
    (:data:`OK_CELLS`; written ``ok``). The columns whose default is "empty" or "none" (``feature``,
    ``wx_mm``.., ``wnx``.., ``temp_<name>_C``) keep their empty cells. A rotary column with some cells empty
    and others not adds a line to ``warnings`` (an empty angle beside written ones is more often an omission
    than a 0)."""
    steps: dict = {}
    src = log.source
    c = log.columns
    n = log.n
    for name in REQUIRED:
        if name not in c:
            raise ProbeLogError(f"{src}: missing required column {name!r}")
    for name, v in c.items():
        if len(v) != n:
            raise ProbeLogError(f"{src}: column {name!r} has {len(v)} rows, expected {n}")
        if _is_text_column(name, v):
            if _spec_numeric(name):
                raise ProbeLogError(f"{src}: column {name!r} holds text, not numbers")
            continue
        bad = ~np.isfinite(v) & ~np.isnan(v)
        if bad.any():
            r = int(np.argmax(bad))
            raise ProbeLogError(f"{_where(src, r, lines)}: column {name!r} is not finite")
        rng = value_range(name)
        if rng is not None:
            lo, hi, unit, why = rng
            with np.errstate(invalid="ignore"):
                out = (v < lo) | (v > hi)
            if out.any():
                r = int(np.argmax(out))
                raise ProbeLogError(f"{_where(src, r, lines)}: column {name!r}: {_num(v[r])} is out of "
                                    f"range (must be >= {lo:g} and <= {hi:g}{' ' + unit if unit else ''}"
                                    f"{': ' + why if why else ''})")
    if "status" in c:
        c["status"] = ok_statuses(c["status"])
    for name in ROTARY_COLUMNS:  # the spec's default, 0, for an empty cell as for the column absent
        if name in c and (empty := np.isnan(c[name])).any():
            if warnings is not None and not empty.all():
                r = int(np.argmax(empty))
                warnings.append(f"{_where(src, r, lines)}: column {name!r} is empty: read as 0, the format's "
                                f"default ({counted(int(empty.sum()), 'empty cell')} of {n})")
            c[name] = np.where(empty, 0.0, c[name])
    ok = log.ok
    plan = n > 0 and log.is_plan
    # required cells: ids always; measured ones only for ok rows of a campaign
    for name in ("setup", "target"):
        empty = np.array([s == "" for s in c[name]], dtype=bool)
        if empty.any():
            r = int(np.argmax(empty))
            raise ProbeLogError(f"{_where(src, r, lines)}: column {name!r} is empty")
    for name in REQUIRED:
        if _is_text(name):
            continue
        need = ok if (name in MEASURED and not plan) else (
            np.zeros(n, bool) if name in MEASURED else np.ones(n, bool))
        empty = np.isnan(c[name]) & need
        if empty.any():
            r = int(np.argmax(empty))
            raise ProbeLogError(f"{_where(src, r, lines)}: column {name!r} is empty")
    # unit vectors
    for trio in _VECTORS:
        present = [t for t in trio if t in c]
        if not present:
            continue
        if len(present) != 3:
            miss = [t for t in trio if t not in c][0]
            raise ProbeLogError(f"{src}: column {miss!r} missing beside {present[0]!r}")
        v = np.column_stack([c[t] for t in trio])
        filled = ~np.isnan(v).any(axis=1)
        partial = np.isnan(v).any(axis=1) & ~np.isnan(v).all(axis=1)
        if partial.any():
            r = int(np.argmax(partial))
            raise ProbeLogError(f"{_where(src, r, lines)}: vector {','.join(trio)} is partly empty")
        norm = np.linalg.norm(np.where(filled[:, None], v, 1.0), axis=1)
        bad = filled & (np.abs(norm - 1.0) > UNIT_TOL)
        if bad.any():
            # printed to q: each component within q / 2 of the unit vector's, its length within sqrt(3) q / 2
            q = decimal_quantum(v[filled]) if UNIT_STEP_MAX is not None else 0.0
            tol = UNIT_TOL + np.sqrt(3.0) * q / 2 if 0 < q <= UNIT_STEP_MAX * (1 + 1e-9) else UNIT_TOL
            far = filled & (np.abs(norm - 1.0) > tol)
            if far.any():
                r = int(np.argmax(far))
                at = (f"; {tol:.2g} for components printed to {q:g}" if tol > UNIT_TOL else
                      f"; components printed to {q:g}, coarser than {UNIT_STEP_MAX:g}" if q > 0 and UNIT_STEP_MAX
                      else "")
                raise ProbeLogError(
                    f"{_where(src, r, lines)}: vector ({','.join(trio)}) has length "
                    f"{norm[r]:.9g}, not 1 (tolerance {UNIT_TOL:g}{at})")
            for t, col in zip(trio, (v / norm[:, None]).T):
                c[t] = np.where(filled, col, c[t])
            steps[trio[0]] = q
    if "dx" in c:  # an approach direction left empty is the spec's default, the reversed normal
        d = np.column_stack([c["dx"], c["dy"], c["dz"]])
        empty = np.isnan(d).all(axis=1)
        if empty.any():
            for t, nt in zip(("dx", "dy", "dz"), ("nx", "ny", "nz")):
                c[t] = np.where(empty, -c[nt], c[t])
        if APPROACH_INTO_MIN is not None:
            d = np.column_stack([c["dx"], c["dy"], c["dz"]])
            into = -np.einsum("ij,ij->i", d, np.column_stack([c["nx"], c["ny"], c["nz"]]))
            bad = into <= APPROACH_INTO_MIN
            if bad.any():
                # a row not valid as a touch (no_trigger, alarm, ...) triggered nowhere: its direction is what the
                # machine was doing when it stopped (a retract), used by no analysis: warned of, the file kept
                rows = np.flatnonzero(bad)
                valid = (np.fromiter((is_ok_status(s) for s in c["status"][rows]), bool, rows.size)
                         if "status" in c else np.ones(rows.size, bool))
                r = int(rows[valid][0]) if valid.any() else int(rows[0])
                way = "tangential to" if abs(into[r]) <= UNIT_TOL else "out of"
                what = (f"approach direction (dx,dy,dz) {_xyz(d[r])} points {way} the surface: its angle to the "
                        f"normal (nx,ny,nz) pointing out of the material is "
                        f"{np.degrees(np.arccos(np.clip(-into[r], -1, 1))):.4g} deg")
                if valid.any():
                    raise ProbeLogError(
                        f"{_where(src, r, lines)}: {what}; a stylus triggers moving into the material, against the "
                        "normal (under 90 deg to -(nx,ny,nz))")
                if warnings is not None:
                    more = f" (and {rows.size - 1} more such invalid rows)" if rows.size > 1 else ""
                    warnings.append(f"{_where(src, r, lines)}: status {c['status'][r]!r}: {what}{more}; kept (the "
                                    "row is not a touch, no analysis reads its direction)")
    if warnings is not None and not plan and n:
        far_from_nominal(log, ok, lines, warnings)
    # time never goes backwards (rows are in the order touches happened)
    t = c["t_s"]
    back = step_back(t)
    if back is not None:
        before, r = back
        raise ProbeLogError(f"{_where(src, r, lines)}: time goes backwards (t_s {t[r]:g} after {t[before]:g})")
    # a target is one physical point: same artefact-frame nominal in every set-up
    if all(k in c for k in ("wx_mm", "wy_mm", "wz_mm")):
        w = np.column_stack([c["wx_mm"], c["wy_mm"], c["wz_mm"]])
        # a point is given whole or not at all (as a vector is): an empty coordinate is no coordinate
        partial = np.isnan(w).any(axis=1) & ~np.isnan(w).all(axis=1)
        if partial.any():
            r = int(np.argmax(partial))
            raise ProbeLogError(f"{_where(src, r, lines)}: artefact-frame point wx_mm,wy_mm,wz_mm is partly empty")
        rows = np.flatnonzero(~np.isnan(w).all(axis=1))
        if rows.size:
            index: dict[str, int] = {}
            code = np.fromiter((index.setdefault(t, len(index)) for t in c["target"][rows]), np.int64, rows.size)
            _, first = np.unique(code, return_index=True)  # codes are 0..k-1: first[code] is its first row
            r0 = rows[first[code]]
            # a NaN coordinate compares as no difference (as a row-by-row check would)
            bad = np.max(np.abs(w[rows] - w[r0]), axis=1) > TARGET_TOL_MM
            if bad.any():
                k = int(np.argmax(bad))
                r, r0, tgt = int(rows[k]), int(r0[k]), c["target"][rows[k]]
                raise ProbeLogError(
                    f"{_where(src, r, lines)}: target {tgt!r} has artefact-frame nominal "
                    f"{_xyz(w[r])} mm in set-up {c['setup'][r]!r} but "
                    f"{_xyz(w[r0])} mm in set-up {c['setup'][r0]!r}")
    _check_meta_values(log.meta, src)
    sr = log.meta.get("stylus_r_mm")
    if sr not in (None, ""):
        if not is_number(sr):
            raise ProbeLogError(f"{src}: metadata stylus_r_mm {_shown(sr)} is not a length")
        v = float(sr)
        if not (math.isfinite(v) and 0 <= v <= STYLUS_R_MAX_MM):
            raise ProbeLogError(f"{src}: metadata stylus_r_mm {_shown(sr)} is out of range (must be >= 0 "
                                f"and <= {STYLUS_R_MAX_MM:g} mm: a tip radius is not negative)")
        if "stylus_r_mm" in c:  # an empty cell is the metadata's radius (the spec's default)
            c["stylus_r_mm"] = np.where(np.isnan(c["stylus_r_mm"]), v, c["stylus_r_mm"])
    return steps


# ---------------------------------------------------------------------------
# writing


def _fmt(v: float) -> str:
    return "" if math.isnan(v) else repr(float(v))


#: rows formatted at a time by :func:`iter_probe_log_text` (a block: ~1 MB of text, ~7 MB of cells)
WRITE_BLOCK_ROWS = 5_000


def _csv_cell(c) -> str:
    """One text cell as ``csv.writer`` (excel dialect) writes it: quoted only when it must be."""
    c = "" if c is None else str(c)
    if not any(ch in c for ch in ',"\r\n'):
        return c
    buf = io.StringIO()
    csv.writer(buf, lineterminator="\n").writerow([c])
    return buf.getvalue()[:-1]


def _column_cells(name: str, v: np.ndarray, decimals: int | None = None) -> list:
    """The cells of one column block: text as csv writes it; numbers as ``repr(float)`` (to ``decimals`` fixed
    decimals where given: a column read from a file printed to that step), NaN empty."""
    if _is_text_column(name, v):
        cells = ["" if c is None else str(c) for c in v.tolist()]
        if any(ch in "".join(cells) for ch in ',"\r\n'):  # rare: quote the cells that need it
            cells = [_csv_cell(c) for c in cells]
        return cells
    fmt = repr if decimals is None else f"{{:.{decimals}f}}".format
    cells = list(map(fmt, v.astype(float).tolist()))
    for i in np.flatnonzero(np.isnan(v)).tolist():
        cells[i] = ""
    return cells


def fixed_decimals(log: ProbeLog) -> dict[str, int]:
    """The columns the writer prints to fixed decimals, name -> decimals: each numeric column of ``log`` whose
    :attr:`ProbeLog.text_steps` is a step ``10^-K`` (K from 0 to :data:`TEXT_DECIMALS_MAX` - 1), in the log's
    column order. A step of 0 (exact) or of :data:`TEXT_DECIMALS_MAX` decimals (the most the reader counts: a
    shortest round-trip repr read without the declaration) is written as its shortest round-trip repr, every digit
    of the double, and declared exact (before session 33 such a column was cut to 12 decimals).

    A column whose values no longer sit on their step (code changed them after they were read: a correction,
    a shift) is written exact too, never rounded back to the step it was read with: ``round(v, K) == v`` holds
    exactly for a value read from ``K`` decimals (the nearest double to a ``K``-decimal number), and only then
    do ``K`` decimals give the value back."""
    out = {}
    for k in _ordered(dict(log.columns)):
        d = step_decimals(log.text_steps.get(k))
        if d is not None and not _is_text_column(k, log.columns[k]) and not any(ch in k for ch in ",=;"):
            if on_step(log.columns[k], d, WRITE_ON_STEP_RTOL_PROBE):
                out[k] = d  # (a name the line cannot hold, ``a;b``, is written whole: exact)
    return out


#: :func:`on_step`'s tolerance for the probe log's writer (:func:`fixed_decimals`), in steps: none. Its columns
#: of a step hold the numbers as read (a controller's print, a file's digits), each the nearest double to a
#: ``K``-decimal number, on which ``round(v, K) == v`` holds exactly; a value code changed after reading (a
#: correction of any size) must be written whole, so no tolerance may round a change back onto the step.
WRITE_ON_STEP_RTOL_PROBE = 0.0
#: :func:`on_step`'s tolerance for the positioning log's writer (``core.positioning._written_decimals``), in
#: steps: 1e-6. A table's measured column is computed, target + deviation (``405.771`` + ``2.5 um`` x 1e-3), and
#: carries the sum's rounding, off the nearest double of its K-decimal value by up to 1.1e-13 mm (20,000 sums of
#: a 3-decimal target within +-1000 mm and a 0.1 um deviation: a quarter off, the worst 1.14e-13 mm): exactness
#: would drop the line and write 17 digits. 1e-6 of the step holds that noise for every step of 1e-6 mm and
#: coarser (1e-12 mm) and rounds off no change a reading could carry (1 pm at a 1 um step).
WRITE_ON_STEP_RTOL_POSITIONING = 1e-6


def on_step(values, decimals: int, rtol: float = 0.0) -> bool:
    """Whether every finite value lies on the step ``10^-decimals``: ``|round(v, decimals) - v|`` at most
    ``rtol`` steps (``rtol`` 0: exactly, ``round(v, K) == v``, which holds for the nearest double to any
    ``K``-decimal number up to 2^53 x 10^-K). NaN and infinities are left out (an empty cell, a value the text
    writes whole); no finite value: True. The writers' question (:func:`fixed_decimals`,
    ``core.positioning._written_decimals``): may this column be written to ``decimals`` decimals and declared
    so without moving a value? Each caller states its ``rtol`` (:data:`WRITE_ON_STEP_RTOL_PROBE`,
    :data:`WRITE_ON_STEP_RTOL_POSITIONING`)."""
    x = np.asarray(values, dtype=float)
    x = x[np.isfinite(x)]
    if not x.size:
        return True
    dev = np.abs(np.round(x, decimals) - x)
    return bool(np.all(dev == 0.0)) if rtol == 0.0 else bool(np.max(dev) <= rtol * 10.0 ** -decimals)


def step_decimals(q: float | None) -> int | None:
    """The decimals a column printed to the step ``q`` is written with (:func:`fixed_decimals`): ``K`` for
    ``q = 10^-K`` up to :data:`TEXT_DECIMALS_MAX` - 1 decimals; None (written exact) for no step, 0 or finer."""
    if q is None or not q > 0:
        return None
    d = max(0, int(round(-math.log10(q))))
    return d if d < TEXT_DECIMALS_MAX else None


def iter_probe_log_text(log: ProbeLog, rows_per_block: int = WRITE_BLOCK_ROWS) -> Iterator[str]:
    """The file text of ``log`` in pieces: metadata and header, then blocks of rows.

    ``"".join`` of the pieces is :func:`format_probe_log`; a writer that takes
    the pieces one by one never holds more than one block of text (1e6 rows:
    a 200 MB file written one block of rows at a time, a few MB).
    """
    buf = io.StringIO()
    meta = dict(log.meta)
    meta.setdefault("format", FORMAT)
    # the columns of a step (a log read from a file printed to one, a controller's readings) written to its
    # decimals and declared so; every other number repr, the digits shown not a precision: declared exact
    fixed = fixed_decimals(log)
    meta[NUMBER_FORMAT_KEY] = number_format_value(fixed)
    meta = {"format": meta.pop("format"), **meta}
    for k, v in meta.items():
        buf.write(f"# {k}: {' '.join(str(v).split())}\n")
    cols = _ordered(dict(log.columns))
    csv.writer(buf, lineterminator="\n").writerow(list(cols))
    yield buf.getvalue()
    for r0 in range(0, log.n, int(rows_per_block)):
        cells = [_column_cells(k, v[r0:r0 + int(rows_per_block)], fixed.get(k)) for k, v in cols.items()]
        yield "\n".join(map(",".join, zip(*cells))) + "\n"


def format_probe_log(log: ProbeLog) -> str:
    """The file text of ``log`` (metadata, header, one row per touch)."""
    return "".join(iter_probe_log_text(log))


def write_probe_log(path: str | os.PathLike, log: ProbeLog, *, special: bool = False) -> Path:
    """Write ``log`` to ``path`` atomically; reading it back gives ``log``.

    The text is written block by block (:func:`iter_probe_log_text`), never
    whole in memory. Only a regular file is replaced; ``special`` writes
    through a device or FIFO the user named (:func:`core.atomic.write_text_atomic`).
    """
    return write_text_atomic(path, iter_probe_log_text(log), special=special)


def summary(log: ProbeLog) -> dict:
    """Short numeric summary of a log (for ``vmt check``)."""
    ok = log.ok
    out = {
        "format": SUMMARY_FORMAT,
        "touches": log.n,
        "ok": int(ok.sum()),
        "setups": len(dict.fromkeys(log.col("setup"))),
        "targets": len(dict.fromkeys(log.col("target"))),
        "plan": bool(log.n and log.is_plan),
    }
    t = log.columns["t_s"][ok]
    t = t[~np.isnan(t)]
    out["time_span_s"] = float(t.max() - t.min()) if t.size else 0.0
    for ax in ("X", "Y", "Z"):
        v = log.columns[f"{ax}_mm"][ok]
        if log.is_plan:
            v = log.columns[f"{ax}n_mm"]
        v = v[~np.isnan(v)]
        out[f"{ax}_range_mm"] = [float(v.min()), float(v.max())] if v.size else None
    for ax in ("A", "B", "C"):
        if log.has(f"{ax}_deg"):
            v = log.columns[f"{ax}_deg"]
            out[f"{ax}_values_deg"] = sorted({float(x) for x in v if not math.isnan(x)})
    statuses: dict[str, int] = {}
    for s in log.col("status"):
        statuses[s or "ok"] = statuses.get(s or "ok", 0) + 1
    out["status"] = statuses
    out["repeated"] = repeated_touches(log)
    out["turned_within_setup"] = turned_within_setup(log)
    out["warnings"] = list(log.warnings)
    return out


def turned_within_setup(log: ProbeLog) -> list[dict]:
    """Set-ups whose rotary position changes between their rows, one record per (set-up, axis): ``setup``,
    ``axis``, ``min_deg``, ``max_deg``, the set-up's first row and position (``first_row``, ``first_deg``) and the
    first row off it (``row``, ``row_deg``); rows are 0-based, as identify names them. An empty cell is skipped.

    The planar self-calibration (``vmt identify``, ``vmt discover``) takes one indexing per set-up and refuses
    such a log; a 5-axis campaign may turn within a placement on purpose. ``vmt check`` says which, so the file
    is not called valid and then refused by the next command without a word (an empty ``C_deg`` cell read as 0
    in a set-up at C 75 is the usual cause). The rows of every status count: a set-up is one indexing.
    O(n log n) over the rows (a 1e6-row log).
    """
    out: list[dict] = []
    setups = np.asarray(log.col("setup"), dtype=object)
    for ax in ("A", "B", "C"):
        if not log.has(f"{ax}_deg"):
            continue
        v = np.asarray(log.columns[f"{ax}_deg"], dtype=float)
        rows = np.flatnonzero(~np.isnan(v))
        if rows.size == 0:
            continue
        names, first, code = np.unique(setups[rows], return_index=True, return_inverse=True)
        x0 = v[rows[first]][code]                        # each row's set-up's first position (file order)
        off = np.abs(v[rows] - x0) > 1e-9
        for g in np.argsort(first):                      # the set-ups in the order the file has them
            k = np.flatnonzero(off & (code == g))
            if k.size:
                vals = v[rows[code == g]]
                out.append({"setup": names[g], "axis": ax, "min_deg": float(vals.min()), "max_deg": float(vals.max()),
                            "first_row": int(rows[first[g]]), "first_deg": float(v[rows[first[g]]]),
                            "row": int(rows[k[0]]), "row_deg": float(v[rows[k[0]]])})
    return out


def repeated_touches(log: ProbeLog, examples: int = 3) -> dict:
    """Touches of a (setup, target) pair made more than once.

    Two writers appending to one log, or a campaign resumed by hand, make
    every touch twice; a plan may also repeat targets on purpose (a drift
    check). Either way ``vmt check`` says so.

    Returns
    -------
    dict
        ``touches``: rows beyond the first of each pair; ``pairs``: pairs
        made more than once; ``examples``: up to ``examples`` of them as
        ``{"setup", "target", "times"}``, first repeated first.
    """
    count: dict[tuple, int] = {}
    for key in zip(log.col("setup"), log.col("target")):
        count[key] = count.get(key, 0) + 1
    rep = [(k, v) for k, v in count.items() if v > 1]
    return {"touches": int(sum(v - 1 for _k, v in rep)), "pairs": len(rep),
            "examples": [{"setup": str(k[0]), "target": str(k[1]), "times": v} for k, v in rep[:examples]]}
