"""Offline LinuxCNC: the plan as a part program, and the controller's probe file back.

:func:`part_program` writes a plan as G-code for LinuxCNC: every touch is a
feed move to the approach start, a ``G38.2`` towards the probing end, a
``(LOG,N<row> G1 X#5061 Y#5062 Z#5063)`` line and a retract, between
``(LOGOPEN,file)`` and ``(LOGCLOSE)``, so the controller writes each
successful probe as one line of its log file, numbered by its plan row.
Not ``PROBEOPEN`` (vmt's programs before session 28): LinuxCNC writes a
``PROBEOPEN`` line only when the probed position differs from the last one
written (``GET_EXTERNAL_PROBE_POSITION``, src/emc/task/emccanon.cc: a
static position, all zeros at start, compared exactly), so two probes
tripping at the same position leave one line, and every later line would
fall one plan row early; a ``LOG`` line is written for every probe (the
interpreter expands it after the probe, src/emc/rs274ngc/interp_convert.cc).
The moves are the live campaign's (:func:`hardware.campaign.approach`): the
first is Z alone to the safe Z, and A, B, C (plans with rotary columns)
turn only there, in a line of their own, X, Y, Z unchanged. Only the
controller's axes get words (:func:`program_axes`: ``axes``, else the
plan's chain): LinuxCNC refuses a letter its machine lacks.

LinuxCNC writes the probed point in the coordinate system in effect
(offsets and XY rotation removed). The program therefore saves the modal
state (``M70``) and the user's ``G59.3`` (by default; ``wcs``), sets it to
zero with no rotation (``G10 L2 P9 X0 Y0 Z0 R0``), selects it and suspends
the ``G92`` / ``G52`` offsets (``G92.2``): the file then holds machine
coordinates, with the probe's tool length offset applied (load the probe
and ``G43`` before running, as for any probing job). At the end it puts
the user's ``G59.3`` back, re-applies their ``G92`` offsets if they were on
(``G92.3``) and restores the modal state (``M72``). A run that stops early
(a miss, an abort) leaves the frame zeroed: the program prints its earlier
values first (``DEBUG``), and its header says so.

:func:`read_probe_file` reads that file: one line per probe of 3 numbers
(X Y Z, older LinuxCNC) or 9 (X Y Z A B C U V W), as LinuxCNC writes it
(``%f``: 6 decimals). It also reads ``LOGOPEN`` files whose lines are
G-code words, as LinuxCNC's ``smartprobe.ngc`` writes them with
``(LOG,G1 X#5061 Y#5062 Z#5063)``: every line must carry X, Y and Z words,
and may carry the plan row (``N``). :func:`import_probe_file` merges it
with the plan into a full ``probe-log/1`` (its X, Y, Z declared printed to the
decimals the file wrote them with, session 33; a file in inches: exact, as
before): numbered lines go to their rows
(which must be 0, 1, 2, ...), others in plan order, and every line must lie
on its row's approach line, else the file is refused naming the line. A
file shorter than the plan is the record of a run that
stopped (a ``G38.2`` miss or an abort: LinuxCNC logs successful probes only
and stops at a miss): its lines are the first plan rows, the rows after them
are kept with status ``aborted`` and empty measured cells. Without a plan,
the file is taken for a surface (Z) probing job and the plan is built from
it (:func:`hardware.surface.plan_from_z_touches`).

:func:`comp_file` writes an identified positioning error as a LinuxCNC
per-joint compensation file (``COMP_FILE_TYPE = 0``),
:func:`positioning_comp_file` one from an ISO 230-2 positioning test,
:func:`read_comp_file`
reads one back (``sim.compensation`` applies it to the virtual machine as
LinuxCNC's motion controller does). Its nominal column is the joint
position, vmt's axis position ``reading + J``; LinuxCNC adds the tool
offset to the programmed position to make the joint command
(``emccanon.cc``) and looks the table up there, so the file (and the
strokes, docs/formats.md) assume the probe's LinuxCNC tool offset (its
tool table entry, with ``G43``) equals vmt's J; another offset shifts the
table by the difference.
"""

from __future__ import annotations

import math
import re
from pathlib import Path

import numpy as np

from core.exceptions import PlanError, ProbeLogError, counted
from core.keyreader import read_text_file
from core.probelog import ProbeLog, csv_lines

from .campaign import ProbeSettings, check_program, log_from_plan, motion, plan_steps
from .transcript import ALIGN_LATERAL_MM, Stroke, _on_row, _row_offset, along_bound, off_row_words, row_lines

_WCS_P = {"G54": 1, "G55": 2, "G56": 3, "G57": 4, "G58": 5, "G59": 6,
          "G59.1": 7, "G59.2": 8, "G59.3": 9}


def _words(p_mm, rot_deg=None, axes: str = "XYZ", rotary: str = "ABC") -> str:
    # 6 decimals (1 nm), as LinuxCNC writes its probe file: 4 would bend each probing line by up
    # to 0.05 um per axis, a lateral error of the touch on any surface not square to an axis
    w = " ".join(f"{a}{v:.6f}" for a, v in zip("XYZ", p_mm) if a in axes)
    if rot_deg is not None:     # only the controller's rotary axes: LinuxCNC refuses a letter it lacks
        w += "".join(f" {a}{v:.4f}" for a, v in zip("ABC", rot_deg) if a in rotary)
    return w


def check_axes(axes: str) -> str:
    """``axes`` as LinuxCNC's ``[TRAJ] COORDINATES`` names them for vmt: X, Y, Z then rotary axes among A, B, C
    (``"XYZAC"``), upper case; the same rule and message as ``vmt probe --axes`` (:func:`hardware.grbl.check_axes`).

    Raises
    ------
    PlanError
        Anything else.
    """
    a = str(axes).upper()
    if a[:3] != "XYZ" or len(set(a)) != len(a) or any(x not in "ABC" for x in a[3:]):
        raise PlanError(f"--axes {axes!r}: expected X, Y, Z then rotary axes A, B, C (e.g. XYZAC)")
    return a


def program_axes(plan: ProbeLog, axes: str | None = None) -> tuple[str, str]:
    """(the controller's axes, where they came from) for :func:`part_program` of ``plan``.

    LinuxCNC's interpreter refuses an axis letter its machine lacks ("Bad character 'b' used",
    rs274ngc_pre.cc: the word readers of axes outside the axis mask are dropped), so the program
    writes a word for every rotary axis the controller has and no other. Its axes are, first
    found: ``axes`` (``--axes``, or the CLI's ``--machine``, or the built-in machine a plan
    without a chain names: ``vmt machine program``); the plan's ``kinematic_chain`` (every
    simulated plan has it: the nmv3000's gives ``XYZAC``); ``XYZ`` for a plan without A, B, C
    columns.

    Raises
    ------
    PlanError
        Bad ``axes``; a plan with rotary columns whose machine is not known (name it: ``--axes``).
    """
    if axes is not None:
        return check_axes(axes), "--axes"
    chain = plan.meta.get("kinematic_chain")
    if chain:
        from core.chain import parse_chain
        from core.exceptions import ConfigError

        try:
            return "XYZ" + "".join(parse_chain(chain).rotary_axes), "the plan's kinematic_chain"
        except ConfigError:     # a chain vmt cannot parse names no axes: the machine's name, else --axes
            pass
    if any(plan.has(c) for c in ("A_deg", "B_deg", "C_deg")):
        raise PlanError("the plan has rotary columns (A_deg, B_deg, C_deg) but names no machine: name the "
                        "controller's axes with --axes (e.g. XYZAC) or give --machine (LinuxCNC refuses a word "
                        "for an axis it lacks)")
    return "XYZ", "the plan has no rotary columns"


def _rotary_sense_lines(axes: str) -> list:
    """The program header's lines on which way a positive rotary angle turns (review33b F3), for the rotary
    axes among ``axes``; none without one. vmt's chain turns the part by minus the angle about the axis line
    (``core.kinematics``: ``Rot(e, -theta)`` on the workpiece branch; the self-calibration paper's eq 1):
    +A, +B, +C are right-handed turns of the tool relative to the part (ISO 841), a table turning clockwise
    seen from the + end of X, Y, Z. A controller turning the other way puts each target at the mirrored angle,
    and the unguarded G1 to its approach start can drive the probe into the part: hence the dry check."""
    rot = [a for a in axes if a in "ABC"]
    if not rot:
        return []
    a = "C" if "C" in rot else rot[0]
    end = {"A": "+X", "B": "+Y", "C": "+Z, from above"}[a]
    return [f"(rotary axes {' '.join(rot)}: a positive angle is a right-handed turn of the tool relative to the "
            "part [ISO 841]:)",
            "(a table turns the part by minus the angle, clockwise seen from the + end of X, Y, Z, a head "
            "counter-clockwise;)",
            f"(dry check before the first run: at safe Z, with no part near the probe, turn {a} by +90 and look: "
            f"the table)",
            f"(must turn clockwise seen from {end}; if it turns the other way every target lies at the mirrored "
            "angle)",
            "(and the G1 moves to the approach starts drive the probe into the part: do not run this program)"]


def part_program(plan: ProbeLog, settings: ProbeSettings, *, probe_file: str = "vmt-probe.txt",
                 wcs: str = "G59.3", require_limits: bool = True, axes: str | None = None,
                 from_row: int = 0) -> str:
    """The LinuxCNC part program probing ``plan`` (safety-checked like a live campaign).

    Parameters
    ----------
    plan : ProbeLog
        The plan, rows in probing order.
    settings : ProbeSettings
        Feeds, clearance, overtravel, safe Z, soft limits (``allow_miss`` is
        ignored: LinuxCNC logs successful probes only, so every probe is G38.2
        and a miss stops the program).
    probe_file : str
        File named in ``(LOGOPEN,...)``, as LinuxCNC will resolve it.
    wcs : str
        Work coordinate system zeroed and used (``G54`` ... ``G59.3``).
    axes : str, optional
        The controller's axes (``[TRAJ] COORDINATES``: ``"XYZAC"``); default
        from the plan (:func:`program_axes`). The program writes a word for
        every rotary axis among them (from the plan's A, B, C; 0 for a
        column it lacks) and no other: LinuxCNC stops at a letter its
        machine lacks.
    from_row : int
        First plan row to probe. 0: the whole plan, the probe file opened
        with ``LOGOPEN``, which truncates it (src/emc/task/emccanon.cc:
        ``fopen(name, "wt")``): the program's header says to copy or import
        it before a re-run. ``K > 0``: the run that stopped at row ``K``
        continued, rows ``K`` on, the file opened with ``LOGAPPEND``
        (``fopen(name, "at")``): its lines ``N0..N<K-1>`` stay and the new
        ones follow, one file that :func:`import_probe_file` reads as one
        run (rows 0, 1, 2, ... checked; a wrong ``K`` leaves a gap or a
        repeat, refused naming the line).

    Raises
    ------
    PlanError
        Limits or feeds violated, unknown ``wcs``, a file name LinuxCNC cannot take;
        bad or unknown ``axes`` (:func:`program_axes`); a row that turns an axis
        the controller lacks (named with its angle).
    """
    if wcs not in _WCS_P:
        raise PlanError(f"--wcs {wcs!r}: expected one of {', '.join(_WCS_P)}")
    if any(c in probe_file for c in "()\n"):
        raise PlanError(f"probe file {probe_file!r}: parentheses and newlines are not allowed")
    if isinstance(from_row, bool) or not isinstance(from_row, (int, np.integer)) or not 0 <= from_row < plan.n:
        raise PlanError(f"--from-row {from_row!r}: expected a plan row, 0..{plan.n - 1} (the plan has "
                        f"{counted(plan.n, 'row')})")
    ctrl, _ = program_axes(plan, axes)
    steps = plan_steps(plan, settings)
    have = ctrl[3:]
    for st in steps:        # a turn of an axis the controller lacks cannot be written: refused by row
        for a, v in zip("ABC", st.rot_deg):
            if a not in have and abs(v) > 1e-9:
                raise PlanError(f"row {st.row} (target {st.target!r}) turns {a} to {v:g} deg but the controller's "
                                f"axes are {ctrl}: no {a} axis to turn (--axes names them)")
    rotary = bool(have) and any(plan.has(c) for c in ("A_deg", "B_deg", "C_deg"))
    steps = steps[from_row:]                  # plan_steps: one step per plan row, in plan order
    check_program(steps, settings, require_limits=require_limits, rotary=rotary)
    fm, fp = settings.move_feed_mm_min, settings.probe_feed_mm_min
    axes = ctrl if rotary else "XYZ"
    wcs_p = _WCS_P[wcs]
    base = 5201 + 20 * wcs_p                  # parameters of the frame: X Y Z A B C U V W R
    saved = {a: f"#<_vmt_wcs_{a.lower()}>" for a in axes + "R"}
    zero = " ".join(f"{a}0" for a in axes) + " R0"
    back = " ".join(f"{a}{saved[a]}" for a in axes + "R")
    if from_row:
        title = (f"(vmt probing program: rows {from_row}..{plan.n - 1}, {len(steps)} of {plan.n} touches from "
                 f"{Path(plan.source).name}, continuing a run that stopped at row {from_row})")
        logging = [f"(LOGAPPEND: {probe_file} must hold that run's lines N0..N{from_row - 1}; these rows follow them)",
                   f"(a run that stopped left {wcs} zeroed: set it back from the first run's DEBUG line after "
                   "this one)"]
        opener = f"(LOGAPPEND,{probe_file})"
    else:
        title = f"(vmt probing program: {plan.n} touches from {Path(plan.source).name})"
        logging = [f"(LOGOPEN truncates {probe_file}: after a stop, copy or import it before running this program "
                   "again;)",
                   "(continue instead: vmt machine program --from-row K, K = its line count, appends to it)"]
        opener = f"(LOGOPEN,{probe_file})"
    out = ["%",
           title,
           f"(coordinates: {wcs} set to zero with no rotation [R0] and selected, G92/G52 offsets)",
           "(suspended [G92.2]: the probe file holds machine coordinates)",
           f"(at the end your {wcs}, your G92 offsets and the modal state [M70/M72] are restored;)",
           f"(a run that stops early leaves {wcs} zeroed: its earlier values are the DEBUG line below)",
           "(load the probe tool with its length offset, G43, before running)",
           *_rotary_sense_lines(axes if rotary else ""),
           f"(probing stroke: clearance {settings.clearance_mm:g} + overtravel {settings.overtravel_mm:g} mm; "
           "each LOG line carries its G38.2 move as G91 G38.2 words, start to end:)",
           "(vmt import linuxcnc reads the stroke from them and checks each touch within it)",
           *logging,
           "M70"]
    out += [f"{saved[a]} = #{base + (9 if a == 'R' else 'XYZABC'.index(a))}" for a in axes + "R"]
    out += ["#<_vmt_g92_on> = #5210",
            f"(DEBUG, vmt: {wcs} was " + " ".join(f"{a}{saved[a]}" for a in axes + "R") + ")",
            "G21 G90 G94 G17 G40",
            f"G10 L2 P{wcs_p} {zero}",
            wcs,
            "G92.2",
            opener]
    prev = None
    for st, moves in motion(steps, settings, rotary=rotary):     # the rotary axes turn alone, at safe Z
        label = f"row {st.row} setup {st.setup} target {st.target}"
        out.append("(" + label.replace("(", "[").replace(")", "]") + ")")
        for m in moves:
            out.append(f"G1 {_words(m.xyz_mm, m.rot_deg, m.axes, have)} F{fm:.1f}")
        out.append(f"G38.2 {_words(st.end_mm)} F{fp:.1f}")
        # the touch, numbered by its plan row, and the probing move it ended (start to end, as GRBL's G91 G38.2
        # carries it): the import's along-the-line bound is that stroke
        move = " ".join(f"{a}{e - b:.4f}" for a, b, e in zip("XYZ", st.start_mm, st.end_mm))
        out.append(f"(LOG,N{st.row} G1 X#5061 Y#5062 Z#5063 G91 G38.2 {move})")
        out.append(f"G1 {_words(st.start_mm)} F{fm:.1f}")
        prev = st.start_mm
    if settings.safe_z_mm is not None and prev is not None:
        out.append(f"G1 {_words([prev[0], prev[1], settings.safe_z_mm])} F{fm:.1f}")
    out += ["(LOGCLOSE)",
            f"G10 L2 P{wcs_p} {back}",
            "o9001 if [#<_vmt_g92_on> EQ 1]",
            "G92.3",
            "o9001 endif",
            "M72",
            "M2", "%"]
    return "\n".join(out) + "\n"


def read_probe_file(path) -> np.ndarray:
    """Read a LinuxCNC ``PROBEOPEN`` file, or a ``LOGOPEN`` file of ``G1 X.. Y.. Z..`` lines.

    Returns
    -------
    (n, k) float, k = 3 or 9
        One row per successful probe: X Y Z [A B C U V W] in the file's units
        (``LOGOPEN`` files: X Y Z, k = 3).

    Raises
    ------
    ProbeLogError
        Missing or empty file; a line (named by number) that is not 3 or 9
        numbers, not finite, or of another width than the first line; a
        ``LOGOPEN`` line without X, Y and Z words, or lines of both kinds;
        an ``N`` word (the plan row) that is not a whole number >= 0, or on
        some lines and not others.
    """
    return _read_lines(path)[0]


def _read_lines(path, inch: bool = False, printed: dict | None = None):
    """(the numbers of :func:`read_probe_file`, the plan row of each line (its ``N`` word, as
    :func:`part_program`'s ``LOG`` lines carry it) or ``None`` for a file without them, the
    file's line number of each row, ``"probe"`` for a PROBEOPEN file or ``"log"``, each line's
    probing stroke in mm (its ``G91 G38.2`` move; ``inch``: the file's units) or ``None`` for a file
    without them). ``printed``, a dict, gets the most decimals the file wrote X, Y, Z with (``{"X_mm": 6,
    ...}``: LinuxCNC's ``%f``), read from its text (:func:`core.probelog.most_decimals`)."""
    from core.probelog import most_decimals

    texts = []
    p = Path(path)
    text = read_text_file(p, ProbeLogError, "file")
    rows, width, kind = [], None, None
    tags, line_no, strokes = [], [], []
    for ln, line in enumerate(csv_lines(text), start=1):
        if not line.strip():
            continue
        if not rows:
            _first_line(p, ln, line, text)
        words = line.lstrip()[0].isalpha()
        if kind is not None and words != (kind == "log"):
            raise ProbeLogError(f"{p}: line {ln}: G-code words and bare numbers mixed in one file")
        kind = "log" if words else "probe"
        if words:
            vals, tag, stroke = _log_line(p, ln, line, inch, texts)
            if strokes and (stroke is None) != (strokes[-1] is None):
                raise ProbeLogError(f"{p}: line {ln}: a G91 G38.2 move (the probing stroke) on some lines and not "
                                    "on others")
            strokes.append(stroke)
            if tags and (tag is None) != (tags[-1] is None):
                raise ProbeLogError(f"{p}: line {ln}: an N word (the plan row) on some lines and not on others")
            tags.append(tag)
        else:
            parts = line.split()
            try:
                vals = [float(v) for v in parts]
            except ValueError:
                bad = next(v for v in parts if not _isnum(v))
                raise ProbeLogError(f"{p}: line {ln}: {bad!r} is not a number") from None
            if len(vals) not in (3, 9):
                raise ProbeLogError(f"{p}: line {ln}: {counted(len(vals), 'number')}, expected 3 (X Y Z) "
                                    "or 9 (X Y Z A B C U V W)")
            if width is not None and len(vals) != width:
                raise ProbeLogError(f"{p}: line {ln}: {counted(len(vals), 'number')} but earlier lines have {width}")
            texts.append(parts[:3])
        if not all(math.isfinite(v) for v in vals):
            raise ProbeLogError(f"{p}: line {ln}: not finite")
        width = len(vals)
        rows.append(vals)
        line_no.append(ln)
    if not rows:
        raise ProbeLogError(f"{p}: empty probe file")
    if printed is not None:
        for j, c in enumerate(("X_mm", "Y_mm", "Z_mm")):
            d = most_decimals([t[j] for t in texts])
            if d is not None:
                printed[c] = d
    return (np.array(rows), (tags if tags and tags[0] is not None else None), line_no, kind,
            (strokes if strokes and strokes[0] is not None else None))


#: What a LinuxCNC probe file is, for a file that is none.
PROBE_FILE_KINDS = ("a PROBEOPEN file (3 or 9 numbers a line: X Y Z [A B C U V W]) or a LOGOPEN file "
                    "(lines like 'G1 X1.0 Y2.0 Z-0.5')")


def _first_line(p: Path, ln: int, line: str, text: str) -> None:
    """ProbeLogError unless the file's first line (``line``, number ``ln``, of ``text``) could open a
    probe file: a file of another kind (a probe-log/1 CSV, a part program, a table) is named as not
    a LinuxCNC probe file, with what was expected, rather than by the first word its first line
    fails on ('a,b,c' is not a G-code word)."""
    shown = line.strip()[:40]
    if line.lstrip().startswith("#") and "probe-log/1" in line:
        raise ProbeLogError(f"{p}: a probe-log/1 file (vmt's own log), not a LinuxCNC probe file: "
                            f"it needs no import (vmt check {p.name})")
    code = "\n".join(ln_ for ln_ in re.sub(r"\([^)]*\)", "", text).splitlines()   # a LOG line's own move is no program
                     if not (_LOG_START.match(ln_) and _LOG_MOVE.search(ln_)))
    probing = re.search(r"(?<![A-Za-z])G\s*38\.[2-5]", code, re.IGNORECASE)
    if probing:
        raise ProbeLogError(f"{p}: a part program (it probes: {probing[0]}), not the probe file it writes; "
                            "expected " + PROBE_FILE_KINDS)
    if line.lstrip()[0].isalpha():
        code = re.sub(r"\([^)]*\)|;.*$", "", line).strip()
        if code and not re.fullmatch(r"(?:" + _WORD.pattern + r"\s*)+", code):
            raise ProbeLogError(f"{p}: not a LinuxCNC probe file: line {ln} is {shown!r}; expected "
                                + PROBE_FILE_KINDS)
        return
    parts = line.split()
    if not all(_isnum(v) for v in parts) or len(parts) not in (3, 9):
        raise ProbeLogError(f"{p}: not a LinuxCNC probe file: line {ln} is {shown!r}; expected " + PROBE_FILE_KINDS)


_WORD = re.compile(r"([A-Za-z])\s*([-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?)")


#: A LOG line's probing move (:func:`part_program` since session 30): ``G91 G38.2`` and its axis words, the
#: move from its start to its end (clearance + overtravel long).
_LOG_MOVE = re.compile(r"G0*91\s*G0*38\.2(?![\d])", re.I)
#: How a LOG line of a touch begins (``N<row> G1 X``): its G38.2 is the logged move, not a program's.
_LOG_START = re.compile(r"\s*(?:N\s*\d+\s*)?G\s*0*1\s*X", re.I)


def _log_line(p: Path, ln: int, line: str, inch: bool = False, texts: list | None = None) -> tuple:
    """(X, Y, Z, the plan row or None, the probing move's length mm or None) of a ``LOGOPEN`` line such as
    ``G1 X1.000000 Y2.000000 Z-0.500000`` (``N<row>`` and a ``G91 G38.2 X.. Y.. Z..`` tail: its probing
    move, :func:`part_program`'s); ``texts`` gets the X, Y, Z words' numbers as written."""
    from .transcript import _stroke_mm

    code = re.sub(r"\([^)]*\)|;.*$", "", line)
    stroke = None
    if (m := _LOG_MOVE.search(code)) is not None:
        tail = code[m.end():]
        stroke = _stroke_mm("G91 " + tail, inch)
        if stroke is None or not re.fullmatch(r"(?:\s*[XYZ]\s*[-+]?(?:\d+\.?\d*|\.\d+))+\s*", tail, re.I):
            raise ProbeLogError(f"{p}: line {ln}: its G91 G38.2 move {tail.strip()[:40]!r} is not X, Y, Z "
                                "words of a move of non-zero length")
        code = code[:m.start()]
    words, pos = [], 0
    while pos < len(code):
        if code[pos].isspace():
            pos += 1
            continue
        m = _WORD.match(code, pos)
        if m is None:
            bad = code[pos:].split()[0]
            raise ProbeLogError(f"{p}: line {ln}: {bad[:30]!r} is not a G-code word "
                                "(expected lines like 'G1 X1.0 Y2.0 Z-0.5')")
        words.append(m.groups())
        pos = m.end()
    got = {}
    for letter, v in words:
        letter = letter.upper()
        if letter in "XYZN":
            if letter in got:
                raise ProbeLogError(f"{p}: line {ln}: two {letter} words")
            got[letter] = v
    missing = [a for a in "XYZ" if a not in got]
    if missing:
        raise ProbeLogError(f"{p}: line {ln}: no {', '.join(missing)} word (a probe log line "
                            "needs X, Y and Z, e.g. (LOG,G1 X#5061 Y#5062 Z#5063))")
    tag = None
    if "N" in got:
        if not re.fullmatch(r"\+?\d+", got["N"]):
            raise ProbeLogError(f"{p}: line {ln}: N{got['N']}: the plan row must be a whole number >= 0")
        tag = int(got["N"])
    if texts is not None:
        texts.append([got["X"], got["Y"], got["Z"]])
    return [float(got["X"]), float(got["Y"]), float(got["Z"])], tag, stroke


def _number_lines(p: Path, error):
    """(line number, numbers) of every non-blank line of text file ``p``;
    ``error`` (a VmtError class) names the file and line of what is wrong."""
    for ln, line in enumerate(csv_lines(read_text_file(p, error, "file")), start=1):
        parts = line.split()
        if not parts:
            continue
        try:
            yield ln, [float(v) for v in parts]
        except ValueError:
            bad = next(v for v in parts if not _isnum(v))
            raise error(f"{p}: line {ln}: {bad!r} is not a number") from None


def _isnum(v: str) -> bool:
    try:
        float(v)
        return True
    except ValueError:
        return False


# A probe-file line is its plan row's touch only on that row's approach line. The program moves the
# probe from ``Xn - clearance d`` to ``Xn + overtravel d`` in the frame it zeroes (the file's frame:
# machine coordinates less the tool offset), and LinuxCNC records the feedback position where the probe
# tripped (``probedPos = carte_pos_fb``, src/emc/motion/control.c), so a touch lies on the line through the
# row's nominal ``Xn`` along ``d``. The machine's geometric errors do not move it off that line (the
# controller reports its axes' own readings, which those errors do not bend); what does is the following error
# across the line (microns on a straight feed move) and the file's 6 decimals (0.5 nm). The bounds are
# GRBL's (:data:`hardware.transcript.ALIGN_LATERAL_MM`, 0.5 mm off the line: a hundred times those,
# while a neighbouring row's line is millimetres away; along it, the program's stroke, clearance +
# overtravel, when the import is given it (``vmt import --clearance-mm/--overtravel-mm``, as the program
# was written: :func:`hardware.transcript.program_stroke`; the probe file does not say it), else
# :data:`hardware.transcript.ALIGN_ALONG_MM`, 10 mm, room for the 2 + 2 mm default). A line beyond them
# is refused naming its row (session 28: lines were booked to rows by order alone, and LinuxCNC writes
# no PROBEOPEN line for a probe at exactly the previous probe's position, so a repeated touch shifted
# every later line one row early, without a word).

#: Why a PROBEOPEN file can be a line short with nothing wrong (src/emc/task/emccanon.cc,
#: GET_EXTERNAL_PROBE_POSITION: ``if (last_probed_position != position)`` before each ``fprintf``, the last
#: position written kept in a function ``static``: all zeros when LinuxCNC starts, and kept from one program
#: run to the next while it runs). A LOGOPEN file's ``(LOG,...)`` line is written every time it is executed.
PROBEOPEN_SKIPS = ("LinuxCNC writes no PROBEOPEN line for a probe at exactly the position of the last line it "
                   "wrote: the previous probe's (before the first, all zeros, or the last probe of an earlier "
                   "program in the same LinuxCNC session)")


def _check_rows(path, pos, rows, line_no, plan: ProbeLog, kind: str, stroke: Stroke | None = None,
                line_strokes=None) -> None:
    """ProbeLogError naming the first line of ``pos`` (mm) that is not a touch of its plan row ``rows[i]``
    (along the line within the line's own stroke, ``line_strokes[i]``, else ``stroke``,
    :func:`hardware.transcript.along_bound`)."""
    pn, d = row_lines(plan)
    for i, (p, r) in enumerate(zip(pos, rows)):
        if line_strokes is not None:
            stroke = Stroke(float(line_strokes[i]), f"the program's stroke, its G91 G38.2 move on this LOG line "
                                                    f"({line_strokes[i]:g} mm)")
        if _on_row(p, pn[r], d[r], along_bound(stroke)):
            continue
        why = ": not this plan's probe file"
        if kind != "tagged":
            nxt = r + 1 < plan.n and _row_offset(p, pn[r + 1], d[r + 1])[0] <= ALIGN_LATERAL_MM
            why = (f"; it lies on row {r + 1}'s line: the lines are one row early" if nxt
                   else why + ", or lines are missing")
            if nxt and kind == "probe":
                why += f" ({PROBEOPEN_SKIPS}; vmt machine program's programs log every probe with its row)"
        raise ProbeLogError(f"{path}: line {line_no[i]}: {off_row_words(p, plan, r, pn, d, stroke)}{why}")


#: How far a 9-number PROBEOPEN line's A, B or C may lie from its plan row's, deg (modulo 360: a continuous
#: axis may report 435 for 75). The file holds the position where the probe tripped, the rotary axes standing
#: at their commanded angle (an axis at rest holds it within its in-position band, thousandths of a degree;
#: LinuxCNC writes 6 decimals); plans index in whole degrees. 0.01 deg is 10x that band, far below any index.
ROTARY_TOL_DEG = 0.01


def _check_rotary(path, data, line_no, plan: ProbeLog) -> None:
    """ProbeLogError naming the first line of a 9-number file whose A, B or C is not its plan row's (review30
    F8: a file with C = 0 on every line was booked at a cross-pocket plan's C = 75/130/210, 276 rows)."""
    if data.shape[1] < 6:
        return
    for j, ax in enumerate("ABC"):
        want = np.asarray(plan.col(f"{ax}_deg"), float)[: data.shape[0]]
        got = data[:, 3 + j]
        off = np.abs((got - want + 180.0) % 360.0 - 180.0)
        bad = np.flatnonzero(~(off <= ROTARY_TOL_DEG))
        if bad.size:
            i = int(bad[0])
            raise ProbeLogError(
                f"{path}: line {line_no[i]}: {ax} {got[i]:g} deg, but plan row {i} "
                f"(target {plan.col('target')[i]}) has {ax} {want[i]:g} deg (within {ROTARY_TOL_DEG:g} deg, "
                "modulo 360): not this plan's set-up")


def _short_file_note(k: int, n: int, kind: str, numbered: bool) -> str:
    """What a probe file of ``k`` lines for a plan of ``n > k`` rows says (metadata ``probe_file_rows``).

    A LOGOPEN file has a line for every probe its program logged (LinuxCNC writes a ``(LOG,...)`` line each
    time it runs; a numbered one, ``N<row>``, :func:`part_program`'s, was checked row by row): the program
    stopped at plan row ``k``. A PROBEOPEN file is short either so or because LinuxCNC skipped touches at
    exactly the last position it wrote (:data:`PROBEOPEN_SKIPS`), and it does not say which: both are said.
    """
    rest = f"row {k}" if n - k == 1 else f"rows {k}..{n - 1}"
    if kind == "probe":
        return (f"lines for {k} of {n} plan rows: the program stopped at plan row {k} (a G38.2 miss or an abort), "
                f"or touches at a repeated position left no line ({PROBEOPEN_SKIPS}); a PROBEOPEN file does not "
                f"tell which (a LOGOPEN file of vmt machine program's, a line per probe numbered by its row, does). "
                f"Its lines fill rows 0..{k - 1} in order (each checked on its row's approach line), {rest} marked "
                "aborted")
    logged = ("its LOG lines numbered 0..{}, one per probe".format(k - 1) if numbered
              else "a LOGOPEN file has a line for every probe its program logged")
    more = (f"; to continue: vmt machine program --from-row {k} (appends to this file: keep it)" if numbered
            else "")
    return (f"lines for {k} of {n} plan rows: the program stopped at plan row {k} (a G38.2 miss or an abort; "
            f"{logged}); {rest} marked aborted{more}")


def import_probe_file(path, plan: ProbeLog | None = None, *, dt_s: float = 1.0,
                      units: str = "mm", stroke: Stroke | None = None) -> ProbeLog:
    """Merge a LinuxCNC probe file with its plan into a full ``probe-log/1``.

    The file holds no clock: ``t_s`` is the touch index (plan order) times
    ``dt_s``, and metadata ``t_s_source`` says so.

    A ``LOGOPEN`` file whose lines carry the plan row (``N`` word, as
    :func:`part_program` writes them) books each line to that row: the rows
    must be 0, 1, 2, ... (one line per probe, none skipped). Any other file
    (a ``PROBEOPEN`` file, a ``LOGOPEN`` file without ``N``) is read in plan
    order. Either way every line must lie on its row's approach line
    (:data:`ALIGN_LATERAL_MM`; along it within ``stroke``, else
    :data:`hardware.transcript.ALIGN_ALONG_MM`), else the file is refused
    naming the line, the row and the bound.

    Parameters
    ----------
    path : path-like
        ``PROBEOPEN`` or ``LOGOPEN`` file (:func:`read_probe_file`).
    plan : ProbeLog or None
        The plan that was run. A file with fewer lines than the plan (the
        program stopped; or, a PROBEOPEN file, touches at a repeated position
        skipped) fills the first rows; the others get status ``aborted`` and
        metadata ``probe_file_rows`` says how many were in the file and what
        that can mean (:func:`_short_file_note`). ``None``: the file is a surface (Z) probing job and the plan is
        built from it (:func:`hardware.surface.plan_from_z_touches`).
    dt_s : float
        Seconds between touches (``t_s``).
    units : {"mm", "inch"}
        Units of the file (a ``G20`` program writes inches).
    stroke : hardware.transcript.Stroke, optional
        The program's probing stroke (clearance + overtravel, mm:
        :func:`hardware.transcript.program_stroke`); default not known. A
        file whose lines carry their probing move (``G91 G38.2 X.. Y.. Z..``,
        :func:`part_program`'s since session 30) is checked against each
        line's own stroke instead.

    Raises
    ------
    PlanError
        The file has more lines than the plan has rows; bad ``units``.
    ProbeLogError
        A bad line of the file (see :func:`read_probe_file`); a line not on
        its row's approach line; row numbers that are not 0, 1, 2, ...
    """
    if units not in ("mm", "inch"):
        raise PlanError(f"units {units!r}: expected mm or inch")
    printed: dict = {}
    data, tags, line_no, kind, strokes = _read_lines(path, units == "inch", printed)
    pos = data[:, :3] * (25.4 if units == "inch" else 1.0)
    if units == "inch":     # a step of 25.4 x 10^-K mm is no decimal step: the converted values written exact
        printed = {}
    meta = {"controller": "linuxcnc", "source": f"vmt import linuxcnc {Path(path).name}",
            "t_s_source": f"plan order x {dt_s:g} s (the probe file has no clock)"}
    built = plan is None
    if built:
        from .surface import plan_from_z_touches

        plan = plan_from_z_touches(pos, source=str(path))
        meta["plan_source"] = "built from the probe file: a surface (Z) probing job (vmt plan grid)"
    k, n = data.shape[0], plan.n
    if k > n:
        raise PlanError(f"{path}: {k} probe lines but the plan {plan.source} has "
                        f"{counted(n, 'row')}: not the file of this plan")
    if tags is not None:
        for i, r in enumerate(tags):
            if r != i:
                raise ProbeLogError(
                    f"{path}: line {line_no[i]}: N{r}, but it is probe line {i + 1}, plan row {i}'s: "
                    + (f"row {r} is beyond the plan's {n} rows" if r >= n else
                       "a line is missing or repeated (the program writes one line per probe, in plan order)"))
    if not built:
        _check_rotary(path, data, line_no, plan)
        _check_rows(path, pos, range(k), line_no, plan, "tagged" if tags is not None else kind, stroke, strokes)
    status = ["ok"] * k + ["aborted"] * (n - k)
    if k < n:
        pos = np.vstack([pos, np.full((n - k, 3), np.nan)])
        meta["probe_file_rows"] = _short_file_note(k, n, kind, tags is not None)
    t = np.arange(n) * float(dt_s)
    return log_from_plan(plan, pos, status, t, meta, source=str(path), printed=printed)


# --------------------------------------------------------------------------- compensation files
#: LinuxCNC's largest compensation table (``EMCMOT_COMP_SIZE``, src/emc/motion/motion.h).
COMP_SIZE = 256


def comp_file(res, axis: str, step_m: float | None = None, joint_offset_m: float = 0.0,
              range_m: tuple | None = None, error=None) -> str:
    """LinuxCNC per-joint compensation file (``COMP_FILE_TYPE = 0``) for the positioning error of ``axis``.

    LinuxCNC documents TYPE 0 lines as ``nominal forward reverse`` in machine
    units (docs/src/config/ini-config.adoc, ``[JOINT_n] COMP_FILE``): the
    commanded position, and the *actual* position the joint reaches there
    moving in + and in -. Its loader (``usrmotLoadComp()``,
    src/emc/motion/usrmotintf.cc) stores ``trim = nominal - forward``
    (``- reverse``), and ``compute_screw_comp()`` (src/emc/motion/control.c)
    adds the trim, interpolated linearly between lines and held beyond the
    ends, to the command (``motor_pos_cmd``) while reporting the position
    without it (``pos_fb``). The positioning error ``E`` of ``core.volumetric``
    is ISO 230-1's (the tool relative to the part, actual minus commanded,
    whichever side of the bed the axis is on), so the actual position is
    ``nominal + E`` and the joint is sent to ``nominal - E``: the same
    column for a table-moving and a tool-moving axis. Forward and reverse
    are equal (the MFB sees no reversal).

    Parameters
    ----------
    res : core.volumetric.VolumetricResult
        Identified tables (``res.value("EXX", x)`` at axis positions x, m).
    axis : {"X", "Y", "Z"}
    step_m : float, optional
        Spacing of the lines along the table (by its C2 spline), m; default
        the table's nodes. At most :data:`COMP_SIZE` lines.
    joint_offset_m : float
        Shift of the nominal column from the tables' positions, m: vmt's
        tables are functions of the joint (axis) positions, reading + J,
        which LinuxCNC indexes too, so the default 0 writes them as they
        are. Nominal = table position + ``joint_offset_m``.
    range_m : (float, float), optional
        The axis positions (as the tables', m) the file must cover, e.g. the
        machine's stroke: a line is added at each end beyond the table's end
        nodes, its value the table's continuation there (:func:`core.volumetric.
        spline_weights`: along the end tangent, as the ``vmt-comp/1`` JSON
        says, for any number of nodes). LinuxCNC interpolates
        linearly between lines, so the file then gives the JSON's
        extrapolation exactly; without the lines it holds the end trims
        beyond the file (motion.c's sentinels, ``compute_screw_comp()``), and
        the first node is the gauge zero (trim 0): below it the joint would
        be left uncompensated while the JSON extrapolates (review29b F1).
        Default: the table's nodes only.
    error : callable, optional
        ``error(x) -> (k,)``: the error the file carries at the axis positions
        ``x`` (k,) m, instead of the identified ``E<axis><axis>`` (its value on
        the line through readings 0 of the other axes): the axis's error along
        another line of the work volume (:func:`core.comprule.line_table`;
        ``vmt scenario --comp-line-mm``). The same lines and format.

    Returns
    -------
    str
        Lines ``nominal forward reverse``, mm, 6 decimals, ascending, no
        header (LinuxCNC stops reading at the first line that is not three
        numbers).
    """
    from core import iso
    from core.exceptions import ConfigError
    from core.units import MM

    a = axis.upper() if isinstance(axis, str) else axis
    if a not in iso.LINEAR_AXES:
        raise ConfigError(f"comp_file: axis must be X, Y or Z, got {axis!r}")
    if not math.isfinite(joint_offset_m):
        raise ConfigError(f"comp_file: joint_offset_m must be finite, got {joint_offset_m!r}")
    x = res.design.nodes[a]
    if step_m is not None:
        if not (step_m > 0):
            raise ConfigError(f"comp_file: step_m must be > 0, got {step_m!r}")
        x = np.arange(x[0], x[-1] + 0.5 * step_m, step_m)
    if range_m is not None:
        lo, hi = (float(v) for v in range_m)
        if not (math.isfinite(lo) and math.isfinite(hi) and lo < hi):
            raise ConfigError(f"comp_file: range_m must be finite (min, max), min < max, got {range_m!r}")
        x = np.r_[[lo] if lo < x[0] - 1e-6 else [], x, [hi] if hi > x[-1] + 1e-6 else []]
    if len(x) > COMP_SIZE:
        raise ConfigError(f"comp_file: {len(x)} lines, LinuxCNC takes at most {COMP_SIZE} per joint")
    e = res.value(f"E{a}{a}", x) if error is None else np.asarray(error(x), float)
    if e.shape != x.shape or not np.all(np.isfinite(e)):
        raise ConfigError(f"comp_file: the error of {a} must be {len(x)} finite values, got shape {e.shape}")
    nom = (x + joint_offset_m) / MM
    act = nom + e / MM
    return comp_text(np.column_stack([nom, act, act]))


def positioning_comp_file(test, range_deg=None) -> str:
    """LinuxCNC TYPE 0 compensation file from an ISO 230-2 positioning test of one axis.

    One line per target ``P_i``: ``nominal forward reverse`` with nominal the
    axis (joint) position of the target, ``P_i + J`` (the log's
    ``tool_offset_mm``, :attr:`core.positioning.PositioningLog.joint_offset`;
    LinuxCNC looks its table up at the joint command, the programmed position
    plus the tool offset), and forward / reverse where the axis really went,
    nominal plus the mean deviation approached in + / in - (ISO 230-2's
    ``x̄_i↑``, ``x̄_i↓``: the standard's deviation, measured minus target, is
    the tool relative to the part, as :func:`comp_file`'s E). A log without
    the key has J = 0: its targets are taken as the axis positions. A
    rotary test (degrees) over less than a turn gets the two lines that
    close it (:func:`rotary_wrap_rows`).

    Parameters
    ----------
    test : core.positioning.PositioningLog or PositioningTest
        In the log's unit (mm; degrees for a rotary joint).
    range_deg : (lo, hi) or None
        A rotary test only: the joint positions the table must cover, deg (the
        joint's ``MIN_LIMIT``, ``MAX_LIMIT``): the test's turn repeated every
        360 deg out to them (:func:`rotary_wrap_rows`). Default: the two
        closing lines.

    Returns
    -------
    str
        Lines in the log's unit, 6 decimals, ascending, no header.

    Raises
    ------
    ConfigError
        More than :data:`COMP_SIZE` lines; ``range_deg`` on a linear test or
        not two finite numbers lo < hi. (A log that cannot be arranged
        raises :class:`core.positioning.PositioningLogError`.)
    """
    from core.exceptions import ConfigError
    from core.positioning import PositioningLog, arrange

    t = arrange(test) if isinstance(test, PositioningLog) else test
    if range_deg is not None and t.unit != "deg":
        raise ConfigError(f"positioning_comp_file: a range in degrees is for a rotary test, this one is in {t.unit}")
    if t.m > COMP_SIZE:
        raise ConfigError(f"positioning_comp_file: {t.m} targets, LinuxCNC takes at most {COMP_SIZE} per joint")
    nom = np.asarray(t.targets, float) + float(t.joint_offset)
    fwd = nom + np.nanmean(t.dev_up, axis=1)
    rev = nom + np.nanmean(t.dev_down, axis=1)
    rows = np.column_stack([nom, fwd, rev])
    if t.unit == "deg":
        rows = rotary_wrap_rows(rows, range_deg)
        if len(rows) > COMP_SIZE:
            what = "the lines closing the turn" if range_deg is None else \
                f"the turn repeated over {range_deg[0]:g}..{range_deg[1]:g} deg"
            raise ConfigError(f"positioning_comp_file: {t.m} targets and {what} (rotary_wrap_rows) make "
                              f"{len(rows)} lines, LinuxCNC takes at most {COMP_SIZE} per joint")
    return comp_text(rows)


#: The turn of a rotary joint, degrees: a table at C and at C + 360 is at the same place
TURN_DEG = 360.0


def rotary_wrap_rows(rows, range_deg=None) -> np.ndarray:
    """A rotary joint's TYPE 0 rows (degrees) closed around the turn (review33b F6).

    LinuxCNC looks the table up at the joint command as it is (``compute_screw_comp`` in
    src/emc/motion/control.c: linear between the lines, the end lines' values held beyond them; no
    modulo), so a test at 0, 90, 180, 270 deg leaves 270-360 deg at 270's trim where the table, back
    at 0 deg's place, needs 0's. When the targets span less than a turn, this adds a line at the first
    target + 360 deg with the first target's deviations and one at the last target - 360 deg with the
    last's (a command below the first target, on an axis not wrapped to 0-360); the error is taken as
    periodic in the turn, as a table's positioning error is. A test over a whole turn or more is
    returned as it is. ``rows``: (k, 3) nominal, forward, reverse, ascending nominals.

    Those two lines cover the joint positions ``last - 360 .. first + 360``; beyond them LinuxCNC
    holds the end lines (checked on LinuxCNC 2.9: tests/controllers/test_linuxcnc_rotary.py). A joint
    that goes further (limits beyond one turn; a ``WRAPPED_ROTARY`` axis, whose joint position counts
    turns: rs274ngc's ``unwrap_rotary()`` takes C350 then C10 to joint position 370) needs
    ``range_deg = (lo, hi)``, its ``MIN_LIMIT`` and ``MAX_LIMIT``: the rows of the test's first turn
    (nominals below first + 360) are repeated every 360 deg, below the first target and above the
    last, out to the first line at or beyond each end; the measured rows are kept as they are (a test
    over more than a turn keeps all its own). Without ``range_deg``: the range ``(last - 360,
    first + 360)`` below a whole turn, none from a whole turn on (the rows as they are)."""
    rows = np.asarray(rows, float)
    first, last = rows[0], rows[-1]
    if range_deg is None:
        if last[0] - first[0] >= TURN_DEG - 1e-9:
            return rows
        return np.vstack([last - TURN_DEG, rows, first + TURN_DEG])
    from core.exceptions import ConfigError

    try:
        lo, hi = (float(v) for v in range_deg)
    except (TypeError, ValueError):
        raise ConfigError(f"rotary_wrap_rows: range_deg must be two numbers (lo, hi), got {range_deg!r}") from None
    if not (math.isfinite(lo) and math.isfinite(hi) and lo < hi):
        raise ConfigError(f"rotary_wrap_rows: range_deg must be finite, lo < hi, got {range_deg!r}")
    turn = rows[rows[:, 0] < first[0] + TURN_DEG - 1e-9]
    copies = math.ceil(max(first[0] - lo, 0.0) / TURN_DEG) + math.ceil(max(hi - last[0], 0.0) / TURN_DEG)
    if copies * len(turn) > 4 * COMP_SIZE:           # far beyond LinuxCNC's table: said before building it
        raise ConfigError(f"rotary_wrap_rows: the turn ({len(turn)} lines) repeated over {lo:g}..{hi:g} deg makes "
                          f"about {copies * len(turn)} lines, LinuxCNC takes at most {COMP_SIZE} per joint")
    shift = np.array([TURN_DEG, TURN_DEG, TURN_DEG])
    below, above = [], []
    k = 1
    while lo < first[0] - 1e-9:                      # copies below the first target, down past lo
        c = turn - k * shift
        below.insert(0, c[c[:, 0] < first[0] - 1e-9])
        if c[0, 0] <= lo + 1e-9:
            break
        k += 1
    k = 1
    while hi > last[0] + 1e-9:                       # copies above the last target, up past hi
        c = turn + k * shift
        above.append(c[c[:, 0] > last[0] + 1e-9])
        if c[-1, 0] >= hi - 1e-9:
            break
        k += 1
    low = np.vstack(below) if below else np.empty((0, 3))
    high = np.vstack(above) if above else np.empty((0, 3))
    if len(low):                                     # from the last line at or below lo ...
        low = low[low[:, 0] >= low[low[:, 0] <= lo + 1e-9, 0].max()]
    if len(high):                                    # ... to the first at or above hi
        high = high[high[:, 0] <= high[high[:, 0] >= hi - 1e-9, 0].min()]
    return np.vstack([low, rows, high])


def add_comp(old_rows, residual_rows) -> np.ndarray:
    """The TYPE 0 table a joint needs when ``residual_rows`` was measured with ``old_rows`` loaded.

    LinuxCNC keeps one table per joint (``usrmotLoadComp()`` builds it from
    the file; src/emc/motion/usrmotintf.cc): a new ``COMP_FILE`` replaces the
    old one, it does not add to it. A positioning test (or an identification)
    made while the old table was active measures the residual ``r(x)``: with
    the old table the joint goes to ``x + trim_old(x)``, ``trim_old = -d_old``
    (``d = actual - nominal``, the file's forward or reverse less its
    nominal), and reaches ``x - d_old(x) + E(x)``, so ``r = E - d_old`` and the
    table to load is ``d = E = d_old + r``, to first order (``E`` taken at
    ``x`` rather than ``x + trim``: the trims are tens of um, ``E``'s slope
    about 1e-4, a few nm). Loading the residual's table alone gives the
    machine ``E - r = d_old`` back: as uncorrected as before the first file
    (review32a: the Mikron's X 24 um -> 0.66 um -> about 24 um).

    Both tables are added as LinuxCNC applies each (linear between lines,
    the end values held beyond them), on the union of their nominals, so
    the sum is exact between and beyond the lines of either.

    Parameters
    ----------
    old_rows, residual_rows : (k, 3) float
        ``nominal forward reverse`` (:func:`read_comp_file`), the same unit
        and the same joint positions (the same tool offset).

    Returns
    -------
    (m, 3) float
        The summed table, nominals the union of both (at 6 decimals, as written).

    Raises
    ------
    ConfigError
        Not (k, 3) finite rows with increasing nominals; more than :data:`COMP_SIZE` lines.
    """
    from core.exceptions import ConfigError

    tabs = []
    for name, r in (("old", old_rows), ("residual", residual_rows)):
        a = np.asarray(r, float)
        if a.ndim != 2 or a.shape[1] != 3 or a.shape[0] < 1 or not np.all(np.isfinite(a)) \
                or np.any(np.diff(a[:, 0]) <= 0):
            raise ConfigError(f"add_comp: the {name} table must be (k, 3) finite rows, nominals increasing")
        tabs.append(a)
    u = np.unique(np.round(np.concatenate([t[:, 0] for t in tabs]), 6))
    if len(u) > COMP_SIZE:
        raise ConfigError(f"add_comp: {len(u)} lines in the union of both tables' nominals, LinuxCNC takes at most "
                          f"{COMP_SIZE} per joint")
    fwd, rev = u.copy(), u.copy()
    for t in tabs:
        fwd += np.interp(u, t[:, 0], t[:, 1] - t[:, 0])
        rev += np.interp(u, t[:, 0], t[:, 2] - t[:, 0])
    return np.column_stack([u, fwd, rev])


def comp_text(rows) -> str:
    """``nominal forward reverse`` lines of a TYPE 0 table (6 decimals, no header: LinuxCNC stops at the first
    line that is not three numbers)."""
    return "".join(f"{u:.6f} {v:.6f} {w:.6f}\n" for u, v, w in np.asarray(rows, float))


def read_comp_file(path) -> np.ndarray:
    """Read a LinuxCNC compensation file: (k, 3) ``nominal forward reverse`` as written (machine units).

    Stricter than LinuxCNC, which stops at the first line that is not three
    numbers and keeps what it read: here such a line (named by number) is an
    error, so no table is silently cut short.

    Raises
    ------
    ConfigError
        No such file; a line that is not three finite numbers; nominal
        values not strictly increasing (LinuxCNC: "compensation values must
        increase"); more than :data:`COMP_SIZE` lines.
    """
    from core.exceptions import ConfigError

    p = Path(path)
    rows = []
    for ln, vals in _number_lines(p, ConfigError):
        if len(vals) != 3 or not all(math.isfinite(v) for v in vals):
            raise ConfigError(f"{p}: line {ln}: expected three finite numbers (nominal forward reverse), "
                              f"got {len(vals)} numbers")
        if rows and vals[0] <= rows[-1][0]:
            raise ConfigError(f"{p}: line {ln}: nominal {vals[0]:g} does not increase "
                              "(LinuxCNC: compensation values must increase)")
        rows.append(vals)
    if not rows:
        raise ConfigError(f"{p}: empty compensation file")
    if len(rows) > COMP_SIZE:
        raise ConfigError(f"{p}: {len(rows)} lines, LinuxCNC takes at most {COMP_SIZE} per joint")
    return np.array(rows)
