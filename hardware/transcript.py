"""Import a GRBL session transcript (a sender's console log) with its plan.

Every well-formed ``[PRB:x,y,z(,...):s]`` report in the transcript is one
touch, in order: ``s = 1`` is ``ok`` with the reported X, Y, Z (machine
coordinates, mm), ``s = 0`` is ``no_trigger``. A report answering a ``$#``
query (it follows the ``[G92:...]`` / ``[TLO:...]`` lines of that answer)
repeats the last probe and is skipped. A line that starts like a probe
report but is not one is an error naming the line: garbage is never taken
for a position.

The decimals the reports print X, Y, Z with (GRBL 1.1h in mm: 3) are read
from the text (:func:`report_decimals`) and declared as the log's step for
those columns (``number_format``'s ``decimals``, session 33): ``vmt fit``
floors its U95 on them.

Reports are read as millimetres. GRBL reports inches, ``[PRB:...]`` too,
when its setting ``$13`` (report inches) is 1: a transcript that shows
``$13=1`` (its ``$$`` dump, or the setting sent) before a probe report is
refused naming both lines, as ``vmt probe`` refuses such a controller; a
later ``$13=0`` ends it. Most senders' logs hold no settings dump: then the
report's own print says the units. GRBL prints every position with a fixed
number of decimals, 3 in mm and 4 in inches (``printFloat_CoordValue``,
report.c; ``N_DECIMAL_COORDVALUE_MM`` / ``_INCH``, config.h; grblHAL the
same), so a report whose X, Y and Z all print 4 decimals, with no ``$13``
before it, is refused as inches, naming its line; a ``$13=0`` before it
(the ``$$`` answer kept in the transcript) says mm, for a firmware built
to print mm to 4 decimals. Any other print is read as mm, as before.

Timestamps, when lines carry them, give ``t_s`` (seconds since the first
timestamp): a leading number of seconds (``12.345 < [PRB:...]``, what
``vmt probe --transcript`` writes), a clock time ``HH:MM:SS(.fff)`` or an
ISO date-time, optionally in brackets. Without timestamps ``t_s`` is the
touch index. ``t_s`` must not go backwards (a clock time passing midnight
is unwrapped).

A run that stopped (an alarm, a lost connection, the user's stop) leaves
fewer reports than the plan has rows. :func:`import_transcript` then does
what the LinuxCNC import does with a short probe file: the reports fill the
first plan rows, every row after them is kept with status ``aborted`` and
empty measured cells (probe-log/1: a touch not taken), and the stop's
reason goes into the metadata (``stop_reason``, with ``transcript_reports``
saying how many of the plan's rows the transcript holds). The touch that was
under way when the controller stopped is marked by the alarm that stopped it
(GRBL 1.1h, as recorded in ``tests/hardware/data/grbl-1.1h``): ``ALARM:4``
(the probe already in contact at the start of a ``G38.2``; no report
follows) is ``early_trigger``; ``ALARM:5`` whose ``[PRB:...:0]`` never came
(the transcript ends in the firmware's 0.5 s alarm delay) is
``no_trigger``; any other alarm after a probing command was sent (a reset,
``ALARM:3``, or a limit) is ``alarm``. Without an alarm (the transcript just
ends: the connection lost, the sender killed) the row is ``aborted``: what
happened to it is not known.
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field
from datetime import datetime
from pathlib import Path

import numpy as np

from core.atomic import head_problem, input_problem
from core.exceptions import PlanError, ProbeLogError, counted
from core.probelog import ALIGN_ALONG_MM as _ALIGN_ALONG_MM, ALIGN_LATERAL_MM as _ALIGN_LATERAL_MM
from core.probelog import ProbeLog, csv_lines, most_decimals

from .campaign import log_from_plan
from .grbl import parse_prb

_TS = re.compile(
    r"^\s*\[?\s*(?:(?P<iso>\d{4}-\d\d-\d\d[T ]\d\d:\d\d:\d\d(?:[.,]\d+)?)"
    r"|(?P<hms>\d\d?:\d\d:\d\d(?:[.,]\d+)?)"
    r"|(?P<sec>\d+(?:\.\d+)?)(?=\s))\s*\]?")
_PRB_TOKEN = re.compile(r"\[PRB[^\]]*\]?")
_ALARM = re.compile(r"\bALARM:(\d+)")
_PROBING = re.compile(r"(?<![A-Z])G0*38\.[2-5](?!\d)", re.I)  # spaces optional: G91G38.2Z-4 (GRBL strips them)
_RESET_SENT = re.compile(r"^(\^X|\x18|0x18|ctrl-x)$", re.I)
_BANNER = re.compile(r"^(Grbl|GrblHAL)\s*\S*\s*\[.*\]\s*$", re.I)
# a sent line's words, spaces optional (GRBL strips them): G91 (relative), G20/G21 (inch/mm), X/Y/Z values
_G91 = re.compile(r"G0*91(?![.\d])", re.I)
_UNITS = re.compile(r"G0*(2[01])(?![.\d])", re.I)
_AXIS_WORDS = re.compile(r"([XYZ])\s*([-+]?(?:\d+\.?\d*|\.\d+))", re.I)
#: ``$13=v`` in a settings dump (``$$``, received) or a setting sent: GRBL's "report inches". With
#: ``$13=1`` every report, ``[PRB:...]`` too (report_probe_parameters prints with
#: printFloat_CoordValue), is in inches.
_REPORT_INCHES = re.compile(r"^\$13\s*=\s*([^\s(]*)")
#: The decimals GRBL prints a position with in inches (``N_DECIMAL_COORDVALUE_INCH``, config.h; in mm
#: ``N_DECIMAL_COORDVALUE_MM`` = 3): ``printFloat`` writes exactly that many, trailing zeros kept.
GRBL_INCH_DECIMALS = 4


def _stamp_decimals(line: str) -> int:
    """The decimals of a line's timestamp (its seconds' fraction), 0 without one."""
    m = _TS.match(line)
    if not m:
        return 0
    text = m.group("iso") or m.group("hms") or m.group("sec")
    _, dot, frac = text.replace(",", ".").rpartition(":")[2].partition(".")
    return len(frac) if dot else 0


def _stamp(line: str) -> float | None:
    m = _TS.match(line)
    if not m:
        return None
    if m.group("iso"):
        return datetime.fromisoformat(m.group("iso").replace(",", ".").replace(" ", "T")).timestamp()
    if m.group("hms"):
        h, mi, s = m.group("hms").replace(",", ".").split(":")
        return int(h) * 3600 + int(mi) * 60 + float(s)
    return float(m.group("sec"))


@dataclass
class Session:
    """What a transcript holds: its probe reports and what stopped it.

    ``pos_mm``, ``touched``, ``t_s``, ``lines`` are :func:`read_transcript`'s.
    ``alarms``: ``(line, code)`` of every ``ALARM:n`` received; ``probing``:
    the lines where a probing command (``G38.2`` .. ``G38.5``) was sent;
    ``errors``: ``(line, code)`` of every ``error:n``; ``resets``: lines where
    the controller was reset (Ctrl-X sent, or its banner received);
    ``n_lines``: the transcript's last line; ``strokes``: per probing command, the length of its move, mm,
    when the line says it (``G91`` on it, in mm: ``vmt probe`` sends ``G91 G38.2 X.. Y.. Z..`` from the
    approach start, a move of clearance + overtravel), else None.
    """

    pos_mm: np.ndarray
    touched: np.ndarray
    t_s: np.ndarray | None
    lines: list
    alarms: list = field(default_factory=list)
    probing: list = field(default_factory=list)
    errors: list = field(default_factory=list)
    resets: list = field(default_factory=list)
    n_lines: int = 0
    strokes: list = field(default_factory=list)
    #: per report, the text of its X, Y, Z numbers as the controller printed them (their decimals: the step
    #: :func:`report_decimals` reads)
    printed: list = field(default_factory=list)


def read_transcript(path):
    """The probe reports of a transcript.

    Returns
    -------
    pos_mm : (n, 3) float
        Reported X, Y, Z of each probe, machine coordinates, mm.
    touched : (n,) bool
    t_s : (n,) float or None
        Seconds since the transcript's first timestamp, ``None`` without timestamps.
    lines : list of int
        1-based transcript line of each report.

    Raises
    ------
    ProbeLogError
        Missing file, a malformed probe report, timestamps on some probe
        lines only, time going backwards.
    """
    s = read_session(path)
    return s.pos_mm, s.touched, s.t_s, s.lines


def read_session(path, *, stopped_at_first: bool = False) -> Session:
    """:func:`read_transcript`'s reports, with the alarms, errors, resets and probing commands around them.

    A line's direction is its ``>`` (sent) or ``<`` (received) after the
    timestamp, when it has one; a line without either is read both ways
    (another sender's console log). ``stopped_at_first``: a session whose
    first probing move was stopped by an alarm (no report at all) is read,
    not refused (:func:`import_transcript` names that alarm in its refusal).

    Raises
    ------
    ProbeLogError
        See :func:`read_transcript`.
    """
    p = Path(path)
    problem = input_problem(p, "transcript")  # (a pipe is read too: vmt import grbl /dev/stdin)
    if problem:
        raise ProbeLogError(f"{p}: {problem}")
    data = p.read_bytes()
    problem = head_problem(p, data[:8])
    if problem:
        raise ProbeLogError(f"{p}: {problem}")
    # a stray byte of serial noise in a line that is not a probe report is harmless: decoded with
    # replacement (a probe report it garbles is refused as malformed, below)
    text = data.decode("utf-8", errors="replace")
    pos, touched, stamps, where, printed = [], [], [], [], []
    alarms, probing, errors, resets, strokes = [], [], [], [], []
    inch = False      # G20 sent: a probing move's words in inches (the reports stay mm, $13=0)
    t0 = None
    stamp_decimals = 0    # the most decimals a timestamp prints: t_s is exact to them (review34)
    prev_info = False
    inch_reports = None     # (line, value, numeric) of a $13 that makes the reports after it inches
    mm_stated = None        # line of a $13=0 (the reports after it are mm whatever they print)
    ln = 0
    for ln, line in enumerate(csv_lines(text), start=1):
        ts = _stamp(line)
        if ts is not None and t0 is None:
            t0 = ts
        if ts is not None:
            stamp_decimals = max(stamp_decimals, _stamp_decimals(line))
        m = _TS.match(line)
        body = (line[m.end():] if m else line).strip()
        way = body[:1] if body[:1] in "<>" else ""
        if way:
            body = body[1:].strip()
        if way != ">":
            a = _ALARM.search(body)
            if a:
                alarms.append((ln, int(a.group(1))))
            e = re.fullmatch(r"error:(\d+)", body)
            if e:
                errors.append((ln, int(e.group(1))))
            if _BANNER.match(body):
                resets.append(ln)
        m13 = _REPORT_INCHES.match(body)     # received in a $$ dump, or sent to change it
        if m13:
            try:
                inch_reports = (ln, m13.group(1), True) if float(m13.group(1)) != 0 else None
                mm_stated = ln if inch_reports is None else None
            except ValueError:
                inch_reports = (ln, m13.group(1), False)   # not a number: the units unknown (the live client's word)
                mm_stated = None
        if way != "<" and not body.startswith("["):
            u = _UNITS.findall(body)
            if u:
                inch = u[-1] == "20"
            if _PROBING.search(body):
                probing.append(ln)
                strokes.append(_stroke_mm(body, inch))
            elif _RESET_SENT.match(body):
                resets.append(ln)
        tok = _PRB_TOKEN.search(line)
        if not tok:
            prev_info = bool(re.search(r"\[(G5[4-9]|G28|G30|G92|TLO):", line)) or (
                prev_info and not line.strip())
            continue
        if prev_info:               # the PRB line of a `$#` answer repeats the last probe
            prev_info = False
            continue
        if inch_reports is not None:  # the live client refuses such a controller (GrblBackend._check_units)
            if not inch_reports[2]:
                raise ProbeLogError(
                    f"{p}: line {ln}: the controller's $13 (report inches, line {inch_reports[0]}) is {inch_reports[1]!r}, "
                    "not a number: vmt cannot tell whether the probe reports are millimetres")
            raise ProbeLogError(
                f"{p}: line {ln}: the probe report is in inches (the controller's $13={inch_reports[1]}, report "
                f"inches, line {inch_reports[0]}); vmt reads reports as millimetres and converts no controller's "
                "units, as vmt probe refuses $13=1: set $13=0 (send '$13=0') and probe again")
        r = parse_prb(tok.group(0))
        if r is None:
            raise ProbeLogError(f"{p}: line {ln}: malformed probe report {tok.group(0)[:60]!r}")
        xyz_text = tok.group(0)[5:].split(":")[0].split(",")[:3]
        if mm_stated is None and all(most_decimals([v]) == GRBL_INCH_DECIMALS for v in xyz_text):
            raise ProbeLogError(
                f"{p}: line {ln}: the probe report prints {GRBL_INCH_DECIMALS} decimals, as GRBL prints inches "
                f"($13=1, report inches; mm it prints to 3) and the transcript shows no $13 before it: vmt reads "
                "reports as millimetres and converts no controller's units: set $13=0 (send '$13=0') and probe "
                "again; a controller that reports mm to 4 decimals: keep its '$$' answer ($13=0) in the "
                "transcript before the reports")
        pos.append(r[0][:3])
        printed.append(xyz_text)
        touched.append(r[1])
        stamps.append(ts)
        where.append(ln)
    first_stopped = stopped_at_first and bool(probing) and any(a > probing[0] for a, _ in alarms)
    if not pos and not first_stopped:
        raise ProbeLogError(f"{p}: no probe reports ([PRB:...]) in it: not a GRBL session transcript "
                            "(vmt probe --transcript writes one), or of a session that probed nothing")
    have = [s is not None for s in stamps]
    if any(have) and not all(have):
        ln_ = where[have.index(False)]
        raise ProbeLogError(f"{p}: line {ln_}: probe report without a timestamp (others have one)")
    t = None
    if have and all(have):
        t = np.array(stamps, dtype=float) - t0
        off = 0.0
        for i in range(1, len(t)):
            t[i] += off
            if t[i] < t[i - 1]:
                if t[i - 1] - t[i] > 43200 and _TS.match(csv_lines(text)[where[i] - 1]).group("hms"):
                    off += 86400.0
                    t[i] += 86400.0
                else:
                    raise ProbeLogError(f"{p}: line {where[i]}: time goes backwards")
        # the differences of stamps printed to d decimals are exact to d decimals; the float subtraction of two
        # 1.8e9 s epoch stamps leaves noise near 1e-7 s (review34: 4.365999937057495 for 4.366), rounded off
        t = np.round(t, stamp_decimals)
    return Session(np.array(pos, dtype=float).reshape(-1, 3), np.array(touched, dtype=bool), t, where, alarms,
                   probing, errors, resets, ln, strokes, printed)


def report_decimals(s: Session) -> dict[str, int]:
    """The decimals the transcript's reports printed X, Y, Z with, per column (``{"X_mm": 3, ...}``): the most
    written in each over every report (GRBL 1.1h in mm: 3, a step of 1 um; ``core.probelog.most_decimals``),
    read from the text, not assumed. The imported log declares its X_mm, Y_mm, Z_mm so (``number_format``,
    session 33: before, an import declared them exact and ``vmt fit`` floored no U95 on their rounding)."""
    from core.probelog import most_decimals

    out = {}
    for j, c in enumerate(("X_mm", "Y_mm", "Z_mm")):
        d = most_decimals([p[j] for p in s.printed if len(p) > j])
        if d is not None:
            out[c] = d
    return out


def _stroke_mm(body: str, inch: bool) -> float | None:
    """The length of a probing command's move, mm, when it is relative (``G91`` on its line) with axis words;
    else None (an absolute target: where the move started is not on the line)."""
    if not _G91.search(body):
        return None
    w = _AXIS_WORDS.findall(body)
    if not w:
        return None
    v = np.array([float(x) for _, x in w]) * (25.4 if inch else 1.0)
    n = float(np.sqrt(v @ v))
    return n if np.isfinite(n) and n > 0 else None


def _stop(s: Session, plan: ProbeLog) -> tuple[str, str, str]:
    """Why a session with fewer reports than plan rows stopped.

    Returns ``(status of the first row without a report, the reason, where the run stopped)``.
    """
    from .backend import ALARMS, describe_error

    k = len(s.lines)
    last = s.lines[-1] if k else 0
    after = [ln for ln in s.probing if ln > last]
    # the alarm that ended the session: no report after it, but the stale [PRB:...:0] an ALARM:5 is followed by
    for ln, code in reversed(s.alarms):
        later = [i for i in range(k) if s.lines[i] > ln]
        if later and not (code == 5 and len(later) == 1 and not s.touched[later[0]]):
            break
        what = f"ALARM:{code} ({ALARMS.get(code, 'unknown alarm')}) at line {ln}"
        if later:                     # a G38.2 miss: its row is the report's, no_trigger
            r = later[0]
            return "aborted", what, f"at plan row {r} (target {plan.col('target')[r]!r}, no_trigger)"
        under_way = any(last < p_ln < ln for p_ln in s.probing)
        st = {4: "early_trigger", 5: "no_trigger"}.get(code, "alarm" if under_way else "aborted")
        if st == "aborted":
            return st, what, f"after plan row {k - 1}" if k else "before the first plan row"
        return st, what, f"at plan row {k} (target {plan.col('target')[k]!r}, {st})"
    where = f"after plan row {k - 1}"
    errs = [(ln, c) for ln, c in s.errors if ln > last]
    if errs:
        ln, c = errs[0]
        return "aborted", f"{describe_error(c)} at line {ln}", where
    resets = [ln for ln in s.resets if ln > last]
    if resets:
        return "aborted", f"the controller was reset at line {resets[0]}", where
    if after:
        return "aborted", (f"the transcript ends at line {s.n_lines} without an alarm, during the probing "
                           f"move sent at line {after[-1]} (a lost connection, or the sender stopped)"), where
    return "aborted", (f"the transcript ends at line {s.n_lines} without an alarm "
                       "(a lost connection, or the sender stopped)"), where


#: A report is its plan row's touch only on that row's approach line: ``vmt probe`` moves from
#: ``Xn - clearance d`` to ``Xn + overtravel d`` in machine coordinates (G53) and GRBL reports the machine
#: position where the probe stopped, so a report lies on the line through the row's nominal ``Xn`` along ``d``
#: (off it by the firmware's step resolution, microns) within clearance/overtravel of ``Xn`` (2 mm each by
#: default). The bounds, mm: off the line by at most :data:`ALIGN_LATERAL_MM` (a hundred times the 0.005 mm a
#: report is rounded to; a neighbouring row's line is millimetres away), along it within the program's stroke
#: (clearance + overtravel, :func:`along_bound`) of ``Xn`` where the import knows it (the transcript's own
#: ``G91 G38.2`` move; ``vmt import``'s ``--clearance-mm``/``--overtravel-mm``), else :data:`ALIGN_ALONG_MM`.
#: Beyond them the report is not that row's: refused (a transcript of another plan, or one report off), or, when
#: it lies on the previous row's line, taken as that touch repeated (session 26: ``vmt probe`` killed after a
#: report reached the transcript but before its log line was synced repeats the touch on ``--resume``) and the
#: first dropped. A miss's report (``[PRB:...:0]``) is not checked: after ALARM:5 GRBL repeats the last
#: successful probe's position in it.
#: The along-the-line bound when the program's stroke is not known, mm (:data:`ALIGN_ALONG_MM`): room for a stroke
#: (clearance + overtravel) of up to 10 mm; 2 + 2 mm by default. A longer stroke's far touches are refused by it,
#: and a short one's neighbouring row along the same line may pass it: give the import the stroke (session 29).
#: Both bounds live in core.probelog (one place: the probe-log reader warns of a touch beyond them, review32d F3).
ALIGN_LATERAL_MM = _ALIGN_LATERAL_MM
ALIGN_ALONG_MM = _ALIGN_ALONG_MM
#: Added to a known stroke, mm: a touch lies between the stroke's ends (``-clearance`` .. ``+overtravel`` along
#: the line, so within clearance + overtravel of the nominal); this much more for the reports' rounding (GRBL
#: 0.001 mm) and the servo's following error along the line (microns).
ALIGN_ALONG_SLACK_MM = 0.01


@dataclass(frozen=True)
class Stroke:
    """A probing stroke the import knows: ``mm`` its length (clearance + overtravel), ``said`` where it is
    from (a refusal's words)."""

    mm: float
    said: str


def along_bound(stroke: "Stroke | None") -> float:
    """How far along its approach line a touch may lie from its nominal, mm: the stroke's length
    (+ :data:`ALIGN_ALONG_SLACK_MM`), or :data:`ALIGN_ALONG_MM` when the stroke is not known."""
    return ALIGN_ALONG_MM if stroke is None else stroke.mm + ALIGN_ALONG_SLACK_MM


def program_stroke(clearance_mm: float | None, overtravel_mm: float | None) -> "Stroke | None":
    """The stroke of a program written with ``--clearance-mm``/``--overtravel-mm`` (the one not given: its
    default, 2 mm), or None when neither is given. :class:`core.exceptions.ConfigError` for a value that is
    not a finite number >= 0, or both 0."""
    from core.exceptions import ConfigError

    if clearance_mm is None and overtravel_mm is None:
        return None
    c = 2.0 if clearance_mm is None else clearance_mm
    o = 2.0 if overtravel_mm is None else overtravel_mm
    for name, v in (("--clearance-mm", c), ("--overtravel-mm", o)):
        if not (np.isfinite(v) and v >= 0):
            raise ConfigError(f"{name} must be a finite number >= 0 (the program's, mm), got {v!r}")
    if c + o <= 0:
        raise ConfigError("--clearance-mm and --overtravel-mm are both 0: no probing stroke")
    return Stroke(float(c + o), f"the program's stroke, clearance {c:g} + overtravel {o:g} mm")


def _row_offset(p, pn, d) -> tuple[float, float]:
    """(distance off the approach line, distance along it) of report ``p`` from nominal ``pn`` along ``d``."""
    v = np.asarray(p, float) - pn
    n = float(np.linalg.norm(d)) if np.all(np.isfinite(d)) else 0.0
    if n == 0.0:            # no approach direction in the plan: the distance from the nominal, all along
        return 0.0, float(np.linalg.norm(v))
    u = d / n
    along = float(v @ u)
    return float(np.linalg.norm(v - along * u)), along


def _on_row(p, pn, d, along_mm: float = ALIGN_ALONG_MM) -> bool:
    lat, along = _row_offset(p, pn, d)
    return lat <= ALIGN_LATERAL_MM and abs(along) <= along_mm


def row_lines(plan: ProbeLog) -> tuple[np.ndarray, np.ndarray]:
    """Each plan row's approach line: its nominal (n, 3) mm and its approach direction (n, 3)."""
    return plan.nominals_mm(), np.column_stack([plan.col(c) for c in ("dx", "dy", "dz")])


def off_row_words(p, plan: ProbeLog, r: int, pn, d, stroke: "Stroke | None" = None,
                  unknown: str = "give vmt import the program's --clearance-mm and --overtravel-mm") -> str:
    """Where report ``p`` (mm) lies against plan row ``r``'s approach line (``pn``, ``d``: :func:`row_lines`),
    in a refusal's words: the GRBL and LinuxCNC imports' one account of a touch booked to the wrong row, with the
    along-the-line bound and where it is from (``stroke``, :func:`along_bound`; ``unknown``: what to do when the
    stroke is not known)."""
    lat, along = _row_offset(p, pn[r], d[r])
    bound = (f"{stroke.mm:g} mm of the nominal: {stroke.said}" if stroke is not None else
             f"{ALIGN_ALONG_MM:g} mm of the nominal: the program's stroke not known, {unknown}")
    return (f"[{p[0]:g}, {p[1]:g}, {p[2]:g}] mm is not a touch of plan row {r} (target {plan.col('target')[r]!r}, "
            f"nominal [{pn[r][0]:g}, {pn[r][1]:g}, {pn[r][2]:g}] mm): {lat:.3f} mm off its approach line, "
            f"{along:+.3f} mm along it (a touch lies within {ALIGN_LATERAL_MM:g} mm of the line and {bound})")


def _report_stroke(s: "Session", j: int, default: "Stroke | None") -> "Stroke | None":
    """The stroke of report ``j``'s probing command (the last one sent before it) when its line says it
    (:attr:`Session.strokes`), else ``default``."""
    import bisect

    k = bisect.bisect_left(s.probing, s.lines[j]) - 1
    if 0 <= k < len(s.strokes) and s.strokes[k] is not None:
        return Stroke(s.strokes[k], f"the stroke of the G38 move sent at line {s.probing[k]}")
    return default


#: What to do when a transcript's probing moves do not say their stroke (the refusal's words).
_UNKNOWN_GRBL = ("its G38 move is not relative (G91) in the transcript: give vmt import the program's "
                 "--clearance-mm and --overtravel-mm")


def _align(path, s: "Session", plan: ProbeLog, stroke: "Stroke | None" = None, offset_given: bool = False):
    """The session with each report on its plan row's approach line (:data:`ALIGN_LATERAL_MM`, along it
    within its probing move's stroke, else ``stroke``'s, else :data:`ALIGN_ALONG_MM`), a repeated touch's
    first report dropped; and the notes of what was dropped. Raises ProbeLogError naming the first report
    that is not its row's touch (``None`` instead, when ``s`` has more reports than the plan rows and the
    count is the better refusal). ``offset_given``: the reports were taken less a tool offset (the refusal then
    does not suggest one)."""
    from dataclasses import replace

    pn, d = row_lines(plan)
    n = plan.n
    keep, notes = [], []
    for j, p in enumerate(s.pos_mm):
        r = len(keep)
        st = _report_stroke(s, j, stroke)
        along = along_bound(st)
        # a miss's [PRB:...:0] after ALARM:5 repeats the last successful probe's position (GRBL 1.1h): it
        # takes its row by order, its position says nothing
        if r < n and (not s.touched[j] or _on_row(p, pn[r], d[r], along)):
            keep.append(j)
            continue
        if keep and s.touched[keep[-1]] and _on_row(p, pn[r - 1], d[r - 1], along):
            notes.append(f"lines {s.lines[keep[-1]]} and {s.lines[j]} both report plan row {r - 1} (target "
                         f"{plan.col('target')[r - 1]!r}): the touch repeated on a resume, the first dropped")
            keep[-1] = j
            continue
        if r >= n:
            return None, notes
        # an error:N between the last report kept and this one (review34): a sender that went on after the
        # controller refused a probing command leaves its row without a report, and every later report one off
        since = s.lines[keep[-1]] if keep else 0
        err = next(((ln, code) for ln, code in s.errors if since < ln < s.lines[j]), None)
        if err is not None:
            sent = [ln for ln in s.probing if since < ln < err[0]]
            raise ProbeLogError(
                f"{path}: line {err[0]}: error:{err[1]} answered "
                + (f"the probing command of line {sent[-1]} " if sent else "a command ")
                + f"(plan row {r}, target {plan.col('target')[r]!r}) and the sender went on: row {r} has no "
                f"report and the reports after it would be one row off: cut the transcript after line {err[0]} "
                "to import the rows before it (the run stopped there)")
        raise ProbeLogError(f"{path}: line {s.lines[j]}: report {j + 1} "
                            f"{off_row_words(p, plan, r, pn, d, st, _UNKNOWN_GRBL)}: "
                            "not this plan's transcript, or its reports are one off"
                            + ("" if offset_given else ", or its controller's machine coordinates are the spindle's "
                               "(give the probe's --tool-offset-mm)"))
    k = np.array(keep, dtype=int)
    return replace(s, pos_mm=s.pos_mm[k].reshape(-1, 3), touched=s.touched[k],
                   t_s=None if s.t_s is None else s.t_s[k], lines=[s.lines[i] for i in keep]), notes


def import_transcript(path, plan: ProbeLog, *, dt_s: float = 1.0, stroke: Stroke | None = None,
                      tool_offset_mm=None) -> ProbeLog:
    """Merge a GRBL transcript with its plan into a full ``probe-log/1``.

    One report per plan row, in order. A transcript with fewer reports is
    the record of a run that stopped: the reports fill the first rows, the
    row under way is marked by the alarm that stopped it, the rows after it
    ``aborted`` (see the module docstring); metadata ``transcript_reports``
    and ``stop_reason`` say how many rows the transcript holds and why it
    stopped.

    Each report must lie on its row's approach line (:data:`ALIGN_LATERAL_MM`; along it within the stroke of
    its probing move, the transcript's ``G91 G38.2`` line, else ``stroke`` (:func:`program_stroke`: the
    program's clearance + overtravel), else :data:`ALIGN_ALONG_MM`): one that does not is refused, naming its
    line and the bound, unless it lies on the previous row's line (a touch repeated on a resume: the first
    report dropped, said in ``transcript_repeats``).

    ``tool_offset_mm`` J (mm, session 36): the controller's machine coordinates were the spindle's (a real
    GRBL's), the probe's tip centre J from them: every report is taken less J (the tip centre the plan and
    the format mean) before it is matched to its row, and the log records J (``tool_offset_mm``). A J off
    the reports' printing step is refused (:func:`hardware.campaign.tool_offset_step_problem`).

    Raises
    ------
    PlanError
        More probe reports than plan rows.
    ProbeLogError
        See :func:`read_transcript`; a report that is not its row's touch.
    ConfigError
        ``tool_offset_mm`` off the reports' printing step.
    """
    from core.exceptions import ConfigError

    from .campaign import TOOL_OFFSET_KEY, tool_offset_step_problem, tool_offset_text

    s = read_session(path, stopped_at_first=True)
    printed = report_decimals(s)
    k, n = len(s.pos_mm), plan.n
    if k == 0:      # nothing measured: a log of it would read as a plan (as LinuxCNC's empty probe file, refused)
        _, why, _ = _stop(s, plan)
        raise ProbeLogError(f"{path}: no probe reports ([PRB:...]): the run stopped at its first touch, {why}; "
                            "nothing measured to import")
    if tool_offset_mm is not None:
        J = np.asarray(tool_offset_mm, dtype=float).reshape(3)
        off_step = tool_offset_step_problem(J, printed)
        if off_step:
            raise ConfigError(f"--tool-offset-mm {tool_offset_text(J)}: {off_step} ({path}'s reports); nothing "
                              "written")
        # the spindle's machine position -> the tip centre's, rounded back to the step the reports were printed
        # to (J is on it: the float subtraction's last bit only)
        tip = s.pos_mm - J
        for j, c in enumerate(("X_mm", "Y_mm", "Z_mm")):
            if printed.get(c) is not None:
                tip[:, j] = np.round(tip[:, j], printed[c])
        from dataclasses import replace

        s = replace(s, pos_mm=tip)
    try:
        aligned, repeats = _align(path, s, plan, stroke, offset_given=tool_offset_mm is not None)
    except ProbeLogError:
        if k > n:       # more reports than rows and not this plan's touches: the count says it best
            aligned = None
        else:
            raise
    if aligned is None:
        raise PlanError(f"{path}: {k} probe reports but the plan {plan.source} has {counted(n, 'row')}: "
                        "not the transcript of this plan")
    s = aligned
    pos, touched, t = s.pos_mm, s.touched, s.t_s
    k = len(pos)
    src = "transcript timestamps" if t is not None else f"plan order x {dt_s:g} s (no timestamps)"
    if t is None:
        t = np.arange(k) * float(dt_s)
    status = ["ok" if x else "no_trigger" for x in touched]
    meta = {"controller": "grbl", "source": f"vmt import grbl {Path(path).name}", "t_s_source": src}
    if tool_offset_mm is not None:   # the J taken off the reports: the readings are the tip centres
        meta[TOOL_OFFSET_KEY] = tool_offset_text(tool_offset_mm)
    if repeats:
        meta["transcript_repeats"] = "; ".join(repeats)
    if k < n:
        first, why, at = _stop(s, plan)
        status += [first] + ["aborted"] * (n - k - 1)
        pos = np.vstack([pos.reshape(-1, 3), np.full((n - k, 3), np.nan)])
        t = np.concatenate([t, np.full(n - k, np.nan)])
        rest = f"rows {k}..{n - 1}" if n - k > 1 else f"row {k}"
        marked = "aborted" if first == "aborted" else f"{first}, then aborted"
        meta["transcript_reports"] = (f"{k} of {n}: the run stopped {at}; {rest} not measured "
                                      f"({marked})")
        meta["stop_reason"] = why
    return log_from_plan(plan, pos, status, t, meta, source=str(path), printed=printed)
