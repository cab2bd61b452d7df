"""Run a probing plan on a machine: safety checks, append-only log, resume.

A plan (``probe-log/1`` with empty measured columns, rows in probing order)
becomes one probing step per row: approach to ``start = Xn - clearance * d``
(``d`` the unit approach direction, default ``-n``), probe towards
``end = Xn + overtravel * d``, log the touch, retract to ``start``.

Safety before any motion (:func:`check_program`): every point of the
program inside the soft limits, every feed at most the maximum feed.
Motion is feed moves only (never rapids), so the maximum feed holds.
The rotary axes turn only at the safe Z, in a move of their own (X, Y, Z
unchanged): between touches the probe retracts along its approach, rises
Z alone to the safe Z, the table turns if the next touch needs it, then X,
Y go across at the safe Z and Z comes down (:func:`approach`; the first
move of a campaign or program is Z alone). A program that commands its
rotary axes without a safe Z is refused: there is no height known to be
clear of the part.

The log (:class:`AppendLog`) is append-only: the header is created
atomically, then each touch is one ``write`` of one complete line followed
by ``fsync``. While a client writes it, the log is locked (an advisory
``flock``, taken before the log appears and before a resume reads it): a
second writer is refused with a message naming the log, so two
``vmt probe --resume`` never make every touch twice. Log row ``i`` is plan row ``i``, so the resume point is the
number of complete rows on disk (:func:`recover_log`; a torn last line is
cut off). A touch made but not yet on disk when the process died is made
again on resume: the log never holds a touch twice and never misses one.
Its ``number_format`` line (session 33; before, none) declares X_mm, Y_mm,
Z_mm printed to the decimals the controller prints (a GRBL's status report,
read at the start: 3), the plan's columns at the plan's steps, every other
number exact (:func:`log_decimals`); rows are written so, a resumed log's
by its own line.

The probe's tool offset J (spindle gauge point minus stylus-tip centre, mm: a machine file's
``[tool] offset_mm``, ``vmt identify --tool-offset-mm``; :attr:`ProbeSettings.tool_offset_mm`, session 36)
is for a controller whose machine coordinates are its spindle's (a real GRBL: it moves with ``G53`` and
reports ``[PRB:...]`` in machine coordinates, where no tool length offset enters). The plan's tip centres
go out as ``tip + J`` (every approach start and probing end: the soft limits and the safe Z are the
controller's machine coordinates), each report is logged as ``report - J`` (the tip centre the format
means), and the log says so in its ``tool_offset_mm`` line (``X,Y,Z``, mm; absent: none applied, J = 0).
A resume with another J is refused, nothing moved; a J off the controller's printing step (GRBL: 0.001
mm) is refused before the first touch, since ``report - J`` would need digits the controller never
printed.

A resume also needs the machine frame the log was made in: a controller
reset between the sessions (opening an Arduino GRBL's serial port resets it)
sets its machine position to 0 where the machine stands. Before any motion
:func:`resume_frame_problem` refuses one that says it was reset at connect
or stands farther than :data:`RESUME_POSITION_TOL_MM` from where the log's
last row left it, unless the run homes (``--home-cycle``).
"""

from __future__ import annotations

import csv
import fcntl
import io
import math
import os
import time
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Callable

import numpy as np

from core.exceptions import ConfigError, HardwareError, PlanError, ProbeLogError, counted
from core.probelog import (FORMAT, MEASURED, NUMBER_FORMAT_KEY, TEXT_COLUMNS, TOOL_OFFSET_KEY, ProbeLog,
                           number_format_value, parse_number_format, parse_probe_log, step_decimals)
from core.units import MM

from .backend import ALARMS, ProbeResult


@dataclass(frozen=True)
class ProbeSettings:
    """How a plan is probed (shop units, named).

    Attributes
    ----------
    probe_feed_mm_min, move_feed_mm_min : float
        Feed of probing moves and of positioning moves, mm/min.
    max_feed_mm_min : float
        No motion may be commanded faster.
    clearance_mm, overtravel_mm : float
        Approach start before, and probing end beyond, the nominal contact, mm.
    safe_z_mm : float or None
        If set, travel between touches goes up to this machine Z, across, and down.
    allow_miss : bool
        Probe with G38.3: a miss is logged ``no_trigger`` and the campaign goes on
        (G38.2: the miss is logged, then the controller alarm stops the campaign).
    limits_mm : (3, 2) tuple or None
        Soft limits ``((xmin, xmax), (ymin, ymax), (zmin, zmax))``, machine frame, mm.
    tool_offset_mm : (3,) tuple or None
        The probe's offsets J, mm (spindle gauge point minus stylus-tip centre): the controller's machine
        coordinates are the spindle's, so every point of the program is the plan's tip centre + J and every
        report is logged less J (module docstring). None: none applied (the controller's machine
        coordinates are the tip centre's, as the emulator's are by default).
    """

    probe_feed_mm_min: float = 100.0
    move_feed_mm_min: float = 1000.0
    max_feed_mm_min: float = 2000.0
    clearance_mm: float = 2.0
    overtravel_mm: float = 2.0
    safe_z_mm: float | None = None
    allow_miss: bool = False
    limits_mm: tuple | None = None
    tool_offset_mm: tuple | None = None

    def __post_init__(self):
        for k in ("probe_feed_mm_min", "move_feed_mm_min", "max_feed_mm_min",
                  "clearance_mm", "overtravel_mm"):
            v = getattr(self, k)
            if not (isinstance(v, (int, float)) and math.isfinite(v) and v > 0):
                raise ConfigError(f"{k} {v!r} must be a positive number")
        z = self.safe_z_mm
        if z is not None and not (isinstance(z, (int, float)) and math.isfinite(z)):
            # a NaN height passed every soft-limit comparison and went out as 'Znan'
            raise ConfigError(f"safe_z_mm {z!r} must be a finite number")
        if self.limits_mm is not None:
            lim = np.asarray(self.limits_mm, dtype=float)
            if lim.shape != (3, 2) or not np.all(np.isfinite(lim)) or np.any(lim[:, 0] >= lim[:, 1]):
                raise ConfigError(f"limits_mm {self.limits_mm!r}: expected ((xmin, xmax), "
                                  "(ymin, ymax), (zmin, zmax)) with min < max")
        if self.tool_offset_mm is not None:
            try:
                J = tuple(float(v) for v in self.tool_offset_mm)
            except (TypeError, ValueError):
                J = ()
            if len(J) != 3 or not all(math.isfinite(v) for v in J):
                raise ConfigError(f"tool_offset_mm {self.tool_offset_mm!r}: expected three finite numbers, mm")
            object.__setattr__(self, "tool_offset_mm", J)


def parse_limits(text: str) -> tuple:
    """``"X-10:300,Y0:200,Z-100:0"`` -> ``((-10, 300), (0, 200), (-100, 0))`` mm."""
    out = {}
    for part in text.split(","):
        part = part.strip()
        try:
            ax, rng = part[0].upper(), part[1:]
            lo, hi = (float(v) for v in rng.split(":"))
        except (ValueError, IndexError):
            raise ConfigError(f"--limits-mm {text!r}: {part!r} is not AXISmin:max (e.g. X-10:300)") from None
        if ax not in "XYZ" or ax in out:
            raise ConfigError(f"--limits-mm {text!r}: axis {ax!r} unknown or repeated")
        if not (math.isfinite(lo) and math.isfinite(hi) and lo < hi):   # (said as 'limits_mm ((nan, ...' before)
            raise ConfigError(f"--limits-mm {text!r}: {part!r}: expected finite min < max, mm")
        out[ax] = (lo, hi)
    if set(out) != set("XYZ"):
        raise ConfigError(f"--limits-mm {text!r}: give X, Y and Z")
    lim = tuple(out[a] for a in "XYZ")
    ProbeSettings(limits_mm=lim)
    return lim


# TOOL_OFFSET_KEY (core.probelog's, imported above): the metadata key of the tool offset J a campaign applied
# (``# tool_offset_mm: X,Y,Z``, mm; the positioning log's key of the same J, docs/formats.md). probe-log/1 lets
# a writer add metadata keys, and a reader that does not know one keeps it and ignores it: the readings stay the
# tip centres the format defines. vmt's reader refuses a value that is not three lengths (audit37).


def parse_tool_offset(text: str, name: str = "--tool-offset-mm") -> tuple[float, float, float]:
    """``"0,0,150"`` -> ``(0.0, 0.0, 150.0)``: the probe's offsets J, mm, three finite numbers each within
    :data:`core.probelog.LENGTH_MAX_MM`; else a ConfigError naming the option ``name`` and the value
    (:func:`core.probelog.parse_tool_offset_mm`, which the log reader applies to the line too)."""
    from core.probelog import parse_tool_offset_mm

    return parse_tool_offset_mm(text, name)


def tool_offset_text(J) -> str:
    """J as the log's ``tool_offset_mm`` value: ``X,Y,Z``, each the shortest text of its double."""
    return ",".join(repr(float(v) + 0.0) for v in J)


def log_tool_offset(meta: dict, src) -> tuple[float, float, float]:
    """The J a log says it was made with (its ``tool_offset_mm`` line); ``(0, 0, 0)`` without one (a log made
    with none applied). ProbeLogError naming the file for a value that is not three finite numbers."""
    v = meta.get(TOOL_OFFSET_KEY)
    if v is None:
        return (0.0, 0.0, 0.0)
    try:
        return parse_tool_offset(v, TOOL_OFFSET_KEY)
    except ConfigError as e:
        raise ProbeLogError(f"{src}: metadata {e}") from None


def tool_offset_step_problem(J, decimals) -> str | None:
    """Why ``report - J`` cannot be written to the controller's ``decimals`` (a component of J that is no
    multiple of its step ``10^-decimals``), or None. A report is printed to that step; a J off it would put
    digits in the reading the controller never printed (written to the step they would be cut).
    ``decimals``: one count for X, Y, Z, or ``{"X_mm": 3, ...}`` per column (a column not named: exact)."""
    if decimals is None or J is None:
        return None
    per = decimals if isinstance(decimals, dict) else {c: decimals for c in MEASURED_XYZ}
    for a, v in zip("XYZ", J):
        d = per.get(f"{a}_mm")
        if d is None:
            continue
        q = 10.0 ** -int(d)
        if abs(v / q - round(v / q)) > 1e-6:
            return (f"its {a} {float(v) + 0.0!r} mm is not a multiple of the controller's printing step {q:g} mm "
                    f"({int(d)} decimals): the readings (report - J) would carry digits the controller never "
                    f"printed; give J to {int(d)} decimals")
    return None


@dataclass(frozen=True)
class Step:
    """One touch of the program: plan row, approach start and probing end (machine frame, mm)."""

    row: int
    setup: str
    target: str
    start_mm: np.ndarray
    end_mm: np.ndarray
    rot_deg: np.ndarray


def check_plan(plan: ProbeLog) -> None:
    """A plan must have rows and empty measured columns."""
    if plan.n == 0:
        raise PlanError(f"{plan.source}: the plan has no rows")
    for c in MEASURED:
        filled = ~np.isnan(plan.columns[c])
        if filled.any():
            r = int(np.argmax(filled))
            raise PlanError(f"{plan.source}: row {r}: column {c!r} is filled: a plan's measured "
                            "columns must be empty (is this a campaign log?)")


def plan_steps(plan: ProbeLog, settings: ProbeSettings) -> list[Step]:
    """One :class:`Step` per plan row, in plan order, in the controller's machine coordinates: the plan's tip
    centres + the settings' ``tool_offset_mm`` J when given."""
    check_plan(plan)
    pn = plan.nominals_mm()
    if settings.tool_offset_mm is not None:
        pn = pn + np.asarray(settings.tool_offset_mm, dtype=float)
    d = np.column_stack([plan.col(c) for c in ("dx", "dy", "dz")])
    rot = np.column_stack([plan.col(c) for c in ("A_deg", "B_deg", "C_deg")])
    rot = np.where(np.isnan(rot), 0.0, rot)
    out = []
    for i in range(plan.n):
        out.append(Step(i, str(plan.columns["setup"][i]), str(plan.columns["target"][i]),
                        pn[i] - settings.clearance_mm * d[i], pn[i] + settings.overtravel_mm * d[i],
                        rot[i]))
    return out


#: Two rotary positions closer than this (deg) are the same: no turn between them. Plan angles are
#: written as text; 1e-9 deg is far below any controller's resolution (GRBL 3 decimals, LinuxCNC 4 here).
ROT_SAME_DEG = 1e-9


@dataclass(frozen=True)
class Move:
    """One positioning move (machine frame): a feed move, never a rapid.

    Attributes
    ----------
    xyz_mm : (3,) float
        Target X, Y, Z, mm (only the axes in ``axes`` are commanded).
    rot_deg : (3,) float or None
        A, B, C of a turn, deg; ``None``: the rotary axes are not commanded (they stay).
    axes : str
        The linear axes commanded: ``"XYZ"``, or ``"Z"`` for the first rise of a program,
        which does not know where X and Y stand.
    """

    xyz_mm: np.ndarray
    rot_deg: np.ndarray | None = None
    axes: str = "XYZ"

    @property
    def turns(self) -> bool:
        return self.rot_deg is not None


def approach(from_mm, step: Step, settings: ProbeSettings, *, from_rot=None,
             rotary: bool = False) -> list[Move]:
    """The moves from ``from_mm`` (``None``: unknown) to ``step``'s approach start.

    With a safe Z: rise Z alone to it at the current X, Y (a program's first
    move: Z alone, X and Y unknown), then, if the rotary axes must turn, turn
    them alone there (X, Y, Z unchanged), then X, Y across at the safe Z,
    then down to the approach start. The rotary axes never turn anywhere
    else: not on the rise, not near the part. Without a safe Z: straight to
    the approach start, and a turn is refused (there is no height known to be
    clear of the part).

    Parameters
    ----------
    from_rot : (3,) float or None
        Where the rotary axes stand, A, B, C deg; ``None``: unknown (they are
        turned to the step's angles before its first move).
    rotary : bool
        The rotary axes are commanded (``False``: they are left where they are).

    Raises
    ------
    PlanError
        A turn is needed and no safe Z is given.
    """
    s = step.start_mm
    rot = np.asarray(step.rot_deg, dtype=float)
    turn = rotary and (from_rot is None
                       or bool(np.any(np.abs(rot - np.asarray(from_rot, dtype=float)) > ROT_SAME_DEG)))
    z = settings.safe_z_mm
    if z is None:
        if turn:
            raise PlanError(f"row {step.row} (target {step.target!r}): the rotary axes are commanded "
                            f"(A, B, C = {np.round(rot, 4).tolist()} deg) but no safe Z is given: they "
                            "would turn on the way to the part; give --safe-z-mm, a machine Z clear of "
                            "the part, where they turn alone")
        return [Move(np.array(s, dtype=float))]
    if from_mm is None:
        here = Move(np.array([np.nan, np.nan, z]), None, "Z")
    else:
        here = Move(np.array([from_mm[0], from_mm[1], z], dtype=float))
    out = [here]
    if turn:
        out.append(Move(here.xyz_mm.copy(), rot.copy(), here.axes))
    out += [Move(np.array([s[0], s[1], z], dtype=float)), Move(np.array(s, dtype=float))]
    return out


def motion(steps: list[Step], settings: ProbeSettings, *, rotary: bool = False, from_mm=None,
           from_rot=None):
    """Every step's moves in order: ``(step, [Move, ...])`` (see :func:`approach`).

    After a step the machine stands at its approach start (the retract after
    the touch), with the rotary axes at the step's angles if they are commanded.
    """
    prev, rot = from_mm, from_rot
    for st in steps:
        yield st, approach(prev, st, settings, from_rot=rot, rotary=rotary)
        prev = st.start_mm
        if rotary:
            rot = st.rot_deg


def plan_turns(steps: list[Step]) -> bool:
    """Whether any step's rotary angles are not zero (a machine that commands its rotary axes wherever the plan
    asks to, the in-process virtual one, then turns them)."""
    return any(bool(np.any(st.rot_deg != 0)) for st in steps)


def check_program(steps: list[Step], settings: ProbeSettings, *, require_limits: bool = True,
                  rotary: bool = False, from_rot=None) -> None:
    """Refuse a program that would leave the soft limits, exceed the maximum feed or turn unsafely.

    ``rotary``, ``from_rot``: as :func:`approach` (a program that commands
    its rotary axes needs a safe Z to turn them at).

    Raises
    ------
    PlanError
        Naming the plan row and the point (mm) or the feed at fault, the
        turn that has no safe Z, or an approach start above the safe Z.
    """
    mx = settings.max_feed_mm_min
    for k in ("probe_feed_mm_min", "move_feed_mm_min"):
        if getattr(settings, k) > mx:
            raise PlanError(f"{k} {getattr(settings, k):g} exceeds the maximum feed {mx:g} mm/min")
    program = list(motion(steps, settings, rotary=rotary, from_rot=from_rot))   # refuses a turn without safe Z
    if settings.safe_z_mm is not None:
        # the safe Z is a rise from every approach start: one below a start would move the stylus down, toward
        # the part, before a move across (and a turn there is not safe)
        for st in steps:
            if not st.start_mm[2] <= settings.safe_z_mm + 1e-9:
                raise PlanError(f"row {st.row} (target {st.target!r}): approach start Z {st.start_mm[2]:.4f} mm is "
                                f"above the safe Z {settings.safe_z_mm:g} mm (--safe-z-mm): the rise to the safe Z "
                                f"would move the stylus down toward the part")
    if settings.limits_mm is None:
        if require_limits:
            raise PlanError("no soft limits given (--limits-mm X..:..,Y..:..,Z..:..): "
                            "refusing to move a machine without them")
        return
    lim = np.asarray(settings.limits_mm, dtype=float)
    for st, moves in program:
        for what, p, axes in [("approach", m.xyz_mm, m.axes) for m in moves] + [
                ("probing end", st.end_mm, "XYZ")]:
            on = np.array([a in axes for a in "XYZ"])     # an axis not commanded is not checked
            bad = on & ~((p >= lim[:, 0] - 1e-9) & (p <= lim[:, 1] + 1e-9))   # NaN is outside too
            if bad.any():
                ax = "XYZ"[int(np.argmax(bad))]
                raise PlanError(f"row {st.row} (target {st.target!r}): {what} "
                                f"{np.round(p, 4).tolist()} mm is outside the soft limits "
                                f"of {ax} {lim['XYZ'.index(ax)].tolist()} mm")


def program_lines(steps: list[Step], settings: ProbeSettings, rotary: bool = False,
                  rotary_axes: str = "ABC") -> list[str]:
    """The GRBL lines a campaign sends (for ``--dry-run``), assuming every probe triggers.

    ``rotary_axes`` names the controller's rotary axes (``"AC"`` for XYZAC):
    only those get a word, as in a live run. The first line raises Z alone
    (a live run sends the X and Y the controller reports; a dry run does not
    know them).
    """
    from .grbl import move_line, probe_line

    out = ["G21", "G90", "G94"]
    prev = None
    for st, moves in motion(steps, settings, rotary=rotary):
        out.append(f"(row {st.row} setup {st.setup} target {st.target})")
        for m in moves:
            out.append(move_line(m.xyz_mm, settings.move_feed_mm_min, m.rot_deg, rotary_axes, axes=m.axes))
        out.append(probe_line(st.start_mm, st.end_mm, settings.probe_feed_mm_min, settings.allow_miss))
        out.append("G90")
        out.append(move_line(st.start_mm, settings.move_feed_mm_min))    # the retract: the rotary axes stay
        prev = st.start_mm
    if settings.safe_z_mm is not None and prev is not None:
        out.append(move_line([prev[0], prev[1], settings.safe_z_mm], settings.move_feed_mm_min))
    return out


# ---------------------------------------------------------------------------
# the append-only log


#: Plan metadata a measured log keeps under its own name: what the part, the probe and the machine's
#: structure are (the analysis reads them: ``stylus_r_mm``, ``kinematic_chain``, and ``machine``, the
#: machine the plan was made for, whose kinematic model a state identified from the log holds: ``vmt vcmm
#: --machine-state`` compares it). Every other key of the plan is about how the plan was made (a
#: simulator's ``generator``, ``probe_repeatability_k2_um``, ``feed_mm_per_min``, ``seed``) and is kept as
#: ``plan_<key>``: a measured log never claims the simulator's provenance or settings as its own. What
#: moved the machine and reported the touches is the log's own ``controller`` line (:data:`CONTROLLER_KEY`;
#: before session 37 a measured log wrote it as ``machine`` and the plan's machine as ``plan_machine``,
#: which :func:`core.state.log_machine` still reads).
PLAN_META_KEPT = ("artefact", "stylus_r_mm", "kinematic_chain", "machine")
#: The metadata key naming the controller a measured log was made through (``grbl://HOST:PORT``,
#: ``virtual:SCENE``; ``linuxcnc``, ``grbl`` for ``vmt import``).
CONTROLLER_KEY = "controller"


def plan_meta(meta: dict) -> dict:
    """The plan's metadata as a measured log carries it (:data:`PLAN_META_KEPT`; ``format`` dropped)."""
    out = {}
    for k, v in meta.items():
        if k == "format":
            continue
        out[k if (k in PLAN_META_KEPT or k.startswith("plan_")) else f"plan_{k}"] = v  # (a plan's own plan_*)
    return out


def log_columns(plan: ProbeLog, temps: list[str]) -> list[str]:
    """Columns of the campaign log: the plan's, then ``status``, then ``temp_<name>_C``."""
    cols = list(plan.columns)
    if "status" not in cols:
        cols.append("status")
    cols += [f"temp_{t}_C" for t in temps if f"temp_{t}_C" not in cols]
    return cols


def _cell(v, decimals: int | None = None) -> str:
    """A cell of a campaign log: text as is, a number as its shortest round-trip repr, or to ``decimals`` fixed
    decimals in a column the log declares so (``number_format``), NaN empty."""
    if isinstance(v, str):
        return v
    v = float(v)
    return "" if math.isnan(v) else repr(v) if decimals is None else f"{v:.{int(decimals)}f}"


#: The measured tip centres: the columns a controller's reports fill (:func:`log_decimals`).
MEASURED_XYZ = ("X_mm", "Y_mm", "Z_mm")


def log_decimals(plan: ProbeLog, columns, measured: int | None) -> dict[str, int]:
    """The columns a campaign log of ``plan`` prints to fixed decimals (``number_format``, session 33), in the
    order of ``columns``: the plan's columns printed to a step (a plan read from a file printed so: its
    :attr:`~core.probelog.ProbeLog.text_steps`; vmt's own plans are exact), and X_mm, Y_mm, Z_mm to the
    ``measured`` decimals the controller printed its reports with (None: exact, a backend measuring in
    metres). Every other column (``t_s``, temperatures) is exact."""
    out = {}
    for c in columns:
        d = (measured if c in MEASURED_XYZ else None if c in MEASURED
             else step_decimals(plan.text_steps.get(c)))
        if d is not None:
            out[c] = int(d)
    return out


def _csv_line(cells: list[str]) -> str:
    buf = io.StringIO()
    csv.writer(buf, lineterminator="\n").writerow(cells)
    return buf.getvalue()


def lock_log(fd: int, path) -> None:
    """Take the writer's lock on the open log ``fd`` (advisory ``flock``, released on close or death).

    Raises
    ------
    PlanError
        Another process holds it (naming the log), or the file system cannot lock.
    """
    try:
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except BlockingIOError:
        raise PlanError(f"{path}: another process is writing this log right now (a second vmt probe?); "
                        "two writers would make touches twice: wait for it to end, or choose another --out") from None
    except OSError as e:
        raise PlanError(f"{path}: cannot lock the log ({e.strerror}): a second writer could not be kept "
                        "out; write the log on a local disk") from None


def open_locked(path) -> int:
    """Open an existing log for appending and lock it (see :func:`lock_log`); return the descriptor."""
    fd = os.open(path, os.O_WRONLY | os.O_APPEND)
    try:
        lock_log(fd, path)
    except BaseException:
        os.close(fd)
        raise
    return fd


class AppendLog:
    """A probe log written one fsync'ed line per touch, locked against a second writer.

    Use :meth:`create` for a new log (atomic: metadata and header appear
    complete or not at all, and locked from the moment they appear) or the
    constructor on an existing log after :func:`recover_log` (``fd`` from
    :func:`open_locked` when the lock was taken before recovering).
    """

    def __init__(self, path: Path, columns: list[str], fd: int | None = None, decimals: dict | None = None):
        self.path = Path(path)
        self.columns = list(columns)
        #: the columns written to fixed decimals, as the log's ``number_format`` line declares them
        self.decimals = dict(decimals or {})
        self.fd = open_locked(self.path) if fd is None else fd

    @classmethod
    def create(cls, path, columns: list[str], meta: dict, decimals: dict | None = None) -> "AppendLog":
        p = Path(path)
        p.parent.mkdir(parents=True, exist_ok=True)
        text = "".join(f"# {k}: {' '.join(str(v).split())}\n" for k, v in meta.items())
        text += _csv_line(columns)
        tmp = p.with_name(f".{p.name}.{os.getpid()}.tmp")
        fd = os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_TRUNC | os.O_APPEND, 0o644)
        try:
            lock_log(fd, tmp)        # the lock goes with the file: locked before it is the log
            os.write(fd, text.encode("utf-8"))
            os.fsync(fd)
            try:
                os.link(tmp, p)          # fails if the log appeared meanwhile: never overwrite
            except FileExistsError:
                raise PlanError(f"{p}: exists; use --resume to continue it, or choose another --out") from None
        except BaseException:
            os.close(fd)
            raise
        finally:
            os.unlink(tmp)
        _fsync_dir(p.parent)
        return cls(p, columns, fd=fd, decimals=decimals)

    def append(self, row: dict) -> None:
        """Write one touch (``{column: value}``; missing columns empty; the columns of :attr:`decimals` to their
        fixed decimals) and fsync."""
        data = _csv_line([_cell(row.get(c, ""), self.decimals.get(c)) for c in self.columns]).encode("utf-8")
        n = os.write(self.fd, data)
        if n != len(data):  # pragma: no cover - a full disk
            raise HardwareError(f"{self.path}: short write ({n} of {len(data)} bytes)")
        os.fsync(self.fd)

    def close(self) -> None:
        """Close the log (and release the lock)."""
        if self.fd is not None:
            os.close(self.fd)
            self.fd = None


def _whole_rows(path) -> int | None:
    """Rows of an :class:`AppendLog` on disk (whole lines after the header; a torn last line is none), or None
    when it cannot be read. Read only: ``--resume`` (:func:`recover_log`) cuts a torn line."""
    try:
        data = Path(path).read_bytes()
    except OSError:
        return None
    body = [ln for ln in data.split(b"\n")[:-1] if not ln.startswith(b"#")]
    return max(len(body) - 1, 0)


def _fsync_dir(d: Path) -> None:
    try:
        fd = os.open(d, os.O_RDONLY)
    except OSError:  # pragma: no cover
        return
    try:
        os.fsync(fd)
    except OSError:  # pragma: no cover
        pass
    finally:
        os.close(fd)


@dataclass(frozen=True)
class Recovered:
    """What :func:`recover_log` found on disk."""

    rows_done: int
    columns: list
    meta: dict
    last_t_s: float
    torn_bytes: int
    #: the columns the log declares printed to fixed decimals (its ``number_format`` line; session 33), appended
    #: so; empty for a log ``vmt probe`` began before session 33 (no such line: its rows appended as they were,
    #: shortest round-trip)
    decimals: dict = field(default_factory=dict)


def recover_log(path, plan: ProbeLog, *, locked: bool = False) -> Recovered:
    """Find where a campaign stopped: complete rows on disk, checked against the plan.

    A last line without its newline (the process died while writing it) is
    cut off the file, once the rest is found a log of this plan (a file that
    is not, e.g. a compressed log, is refused and left as it was). Every
    complete row must be the plan row of the same index (same ``setup``,
    ``target`` and nominal point). Unless the caller
    holds the writer's lock (``locked``), it is taken for the recovery, so
    a line another client is writing is never cut.

    Raises
    ------
    PlanError
        The log does not belong to this plan, or has more rows than it, or
        another process is writing it.
    ProbeLogError
        The file is not a readable probe log.
    """
    p = Path(path)
    if not locked:
        fd = open_locked(p)
        try:
            return recover_log(p, plan, locked=True)
        finally:
            os.close(fd)
    data = p.read_bytes()
    keep = data.rfind(b"\n") + 1
    torn = len(data) - keep
    try:
        text = data.decode("utf-8")
    except UnicodeDecodeError as e:
        if e.start < keep or e.reason != "unexpected end of data":  # more than a character cut by the tear
            from core.atomic import not_text_problem

            raise ProbeLogError(f"{p}: {not_text_problem(p, data[:8], e)}") from None
    if torn:
        text = data[:keep].decode("utf-8")
    log = parse_probe_log(text, source=str(p))
    header = next(line for line in text.splitlines() if line and not line.startswith("#"))
    columns = next(csv.reader([header]))
    plan_cols = [c for c in plan.columns]
    missing = [c for c in plan_cols if c not in columns]
    if missing:
        raise PlanError(f"{p}: log has no column {missing[0]!r} of the plan: not a log of this plan")
    if log.n > plan.n:
        raise PlanError(f"{p}: {counted(log.n, 'row')} but the plan has {plan.n}: not a log of this plan")
    pn, ln = plan.nominals_mm(), log.nominals_mm()
    for i in range(log.n):
        same = (log.columns["setup"][i] == plan.columns["setup"][i]
                and log.columns["target"][i] == plan.columns["target"][i]
                and np.allclose(ln[i], pn[i], rtol=0, atol=1e-9))
        if not same:
            raise PlanError(f"{p}: row {i} (setup {log.columns['setup'][i]!r}, target "
                            f"{log.columns['target'][i]!r}) is not plan row {i}: not a log of this plan")
    if torn:  # cut only now, the rows before it found a log of this plan: another file is left whole
        with open(p, "r+b") as f:
            f.truncate(keep)
            f.flush()
            os.fsync(f.fileno())
    t = log.columns["t_s"]
    t = t[~np.isnan(t)]
    return Recovered(log.n, columns, dict(log.meta), float(t.max()) if t.size else 0.0, torn,
                     _declared(text, columns, p))


def _declared(text: str, columns: list, src) -> dict:
    """The columns the log's ``number_format`` line declares printed to fixed decimals (none without it)."""
    for line in text.splitlines():
        if not line.strip():
            continue
        if not line.startswith("#"):
            break
        k, colon, v = line[1:].partition(":")
        if colon and k.strip() == NUMBER_FORMAT_KEY:
            return parse_number_format(v, columns, str(src), None, TEXT_COLUMNS)[1]
    return {}


# ---------------------------------------------------------------------------
# the campaign


#: How far (mm) the machine may stand, on a resume, from the path its log left it on (the last logged
#: row's probing segment and retract, the moves to the next row and its probing segment: a lost link,
#: an alarm or a killed process stops it somewhere on that path) before vmt takes its machine position
#: for lost (:func:`resume_frame_problem`). Above the 2 mm a user jogs to clear a probe found in
#: contact (ALARM:4, the default clearance) and a controlled stop, which stays on the path; a
#: controller reset moves the reading by the machine's whole former position (GRBL's power-up sets the
#: machine position to 0 where the machine stands), which a machine homed to a travel end keeps far
#: from any probing point. A reset with the machine within this distance of machine zero along that
#: path passes unseen: over a serial link its banner at connect still tells (``reset_at_connect``).
RESUME_POSITION_TOL_MM = 5.0


def _resume_path(steps: list[Step], done: int, settings: ProbeSettings) -> list[np.ndarray]:
    """The points (mm) of the path the machine may stand on after ``done`` logged rows: the last
    logged row's probing segment (end, start: the retract), the moves to row ``done`` and its probing
    segment (a touch made but not yet on disk is made again)."""
    last = steps[done - 1]
    pts = [np.asarray(last.end_mm, float), np.asarray(last.start_mm, float)]
    if done < len(steps):
        nxt = steps[done]
        pts += [np.asarray(m.xyz_mm, float) for m in approach(last.start_mm, nxt, settings)]
        pts += [np.asarray(nxt.start_mm, float), np.asarray(nxt.end_mm, float)]
    return pts


def _distance_to_path(p, pts) -> float:
    best = float(np.linalg.norm(p - pts[0]))
    for a, b in zip(pts[:-1], pts[1:]):
        d = b - a
        L2 = float(d @ d)
        t = 0.0 if L2 == 0.0 else min(1.0, max(0.0, float((p - a) @ d) / L2))
        best = min(best, float(np.linalg.norm(p - a - t * d)))
    return best


def resume_frame_problem(backend, steps: list[Step], done: int, settings: ProbeSettings) -> str | None:
    """Why the machine frame of a resumed run may not be its log's, or None.

    ``backend.reset_at_connect()`` (when it has one) names a reset seen at connect (a serial GRBL's
    banner: opening the port resets an Arduino). A backend whose machine position outlives a
    connection (``keeps_position``) must stand within :data:`RESUME_POSITION_TOL_MM` of the path
    the log's last row left it on (:func:`_resume_path`); the in-process virtual machine starts at its
    home, as a homed machine does, and is not checked.
    """
    said = getattr(backend, "reset_at_connect", None)
    why = said() if callable(said) else None
    if why:
        return why
    if not getattr(backend, "keeps_position", False) or done <= 0:
        return None
    here = np.asarray(backend.position_m(), float) / MM
    pts = _resume_path(steps, done, settings)
    d = _distance_to_path(here, pts)
    if d <= RESUME_POSITION_TOL_MM:
        return None
    r = pts[1]
    return (f"the machine reads X{here[0]:.3f} Y{here[1]:.3f} Z{here[2]:.3f} mm, {d:.1f} mm from the path "
            f"the log's last row (row {done - 1}) left it on (its retract point X{r[0]:.3f} Y{r[1]:.3f} "
            f"Z{r[2]:.3f} mm, the moves to row {done}; more than {RESUME_POSITION_TOL_MM:g} mm): the "
            "controller was reset (its machine position set to 0 where the machine stood) or the machine "
            "was moved (then moving it back to that path resumes too)")


@dataclass(frozen=True)
class CampaignResult:
    """Outcome of :func:`run_campaign`."""

    out: Path
    rows_total: int
    rows_before: int          # complete rows found on disk at the start (resume)
    rows_done: int            # complete rows on disk at the end
    torn_bytes: int = 0
    statuses: dict = field(default_factory=dict)


def run_campaign(backend, plan: ProbeLog, out, settings: ProbeSettings, *, resume: bool = False,
                 unlock: bool = False, home: bool = False, plan_path: str | None = None,
                 clock: Callable[[], float] = time.time,
                 on_touch: Callable[[int, ProbeResult], None] | None = None,
                 require_limits: bool = True,
                 on_start: Callable[[int, int], None] | None = None) -> CampaignResult:
    """Probe ``plan`` on ``backend`` and append every touch to the log ``out``.

    Parameters
    ----------
    backend : hardware.backend.ProbingBackend
    plan : ProbeLog
        The plan (measured columns empty), rows in probing order.
    out : path-like
        The campaign log. A new log must not exist; with ``resume`` an
        existing log is continued after its last complete row.
    settings : ProbeSettings
    resume, unlock, home : bool
        ``unlock`` (``$X``) and ``home`` (``$H``) only on the user's word.
    clock : callable
        Wall-clock seconds (``t_s`` is ``clock() - started_unix``, never going backwards).
    on_touch : callable(row, ProbeResult) or None
        Called after each touch is on disk.
    on_start : callable(rows_on_disk, rows_of_plan) or None
        Called once, when the log is recovered (or found absent), before any motion: a resumed
        run's progress starts at the rows already done, not at zero.

    Raises
    ------
    PlanError
        Before any motion: limits, feeds, a log that exists or belongs to another plan.
    HardwareError
        The machine failed; every touch made before is on disk, ``resume`` continues.
    """
    steps = plan_steps(plan, settings)
    rotary = getattr(backend, "rotary", None)       # does the backend command the rotary axes?
    if rotary is None:          # one that does not say (in-process virtual) turns when the plan asks to
        rotary = plan_turns(steps)
    rotary = bool(rotary)
    check_program(steps, settings, require_limits=require_limits, rotary=rotary)
    p = Path(out)
    torn = 0
    fd = None
    if p.exists():
        if not resume:
            raise PlanError(f"{p}: exists; use --resume to continue it, or choose another --out")
        fd = open_locked(p)             # before reading: a second writer stops here
        try:
            rec = recover_log(p, plan, locked=True)
            done, columns, torn = rec.rows_done, rec.columns, rec.torn_bytes
            try:
                started = float(rec.meta.get("started_unix", ""))
            except ValueError:
                raise PlanError(f"{p}: metadata started_unix missing or not a number") from None
        except BaseException:
            os.close(fd)
            raise
        last_t = rec.last_t_s
        temps = [c[5:-2] for c in columns if c.startswith("temp_") and c.endswith("_C")]
        decimals = rec.decimals
        try:    # one log, one J: its readings are the reports less the J it was begun with
            problem = resume_offset_problem(p, rec.meta, settings.tool_offset_mm)
        except BaseException:
            os.close(fd)
            raise
        if problem:
            os.close(fd)
            raise PlanError(problem)
    else:
        done, last_t, started = 0, 0.0, None
    statuses: dict[str, int] = {}
    before = done
    if on_start is not None:  # (rows already on disk, rows of the plan): a resumed run's progress starts there
        on_start(before, plan.n)
    if done >= plan.n:
        if fd is not None:
            os.close(fd)
        return CampaignResult(p, plan.n, done, done, torn, statuses)
    resumed = fd is not None and before > 0 and not home   # $H re-establishes the machine position

    def frame_lost(why: str) -> HardwareError:
        return HardwareError(
            f"{p}: not resumed, nothing moved, the log kept ({before} of {plan.n} rows): {why}; its "
            "positions would not be the log's: re-run with --resume --home-cycle ($H sets the machine "
            "position again; a machine without homing cannot be tied to the log: start a new log)")

    try:
        try:
            backend.start(unlock=unlock, home=home)
        except HardwareError as e:   # in alarm after a reset (homing enabled): say why, not only $X
            if not resumed:
                raise
            try:
                why = resume_frame_problem(backend, steps, before, settings)
            except HardwareError:
                why = None
            if why:
                raise frame_lost(why) from None
            raise e from None
        if resumed:
            why = resume_frame_problem(backend, steps, before, settings)
            if why:
                raise frame_lost(why)
    except BaseException:
        if fd is not None:
            os.close(fd)
        raise
    if started is None:
        temps = sorted(backend.temperatures_C())
        columns = log_columns(plan, temps)
        started = float(clock())
        meta = {"format": FORMAT, **plan_meta(plan.meta)}
        meta.update({CONTROLLER_KEY: backend.name, "source": "vmt probe",
                     "plan": plan_path or plan.source, "started_unix": repr(started),
                     "probe_feed_mm_min": settings.probe_feed_mm_min,
                     "clearance_mm": settings.clearance_mm, "overtravel_mm": settings.overtravel_mm})
        if settings.tool_offset_mm is not None:   # the J applied: the readings are the reports less it
            meta[TOOL_OFFSET_KEY] = tool_offset_text(settings.tool_offset_mm)
        # the controller's printing step on X, Y, Z (GRBL: its status report's decimals, as its [PRB:...] prints
        # them), the plan's on its columns, every other number exact: said in the log (session 33)
        decimals = log_decimals(plan, columns, getattr(backend, "report_decimals", None))
        off_step = tool_offset_step_problem(settings.tool_offset_mm, decimals.get("X_mm"))
        if off_step:     # before the log exists and before the first move (a $H the user asked for aside)
            raise ConfigError(f"--tool-offset-mm {tool_offset_text(settings.tool_offset_mm)}: {off_step}; "
                              "nothing probed, no log written")
        meta[NUMBER_FORMAT_KEY] = number_format_value(decimals)
        log = AppendLog.create(p, columns, meta, decimals)
    else:
        log = AppendLog(p, columns, fd=fd, decimals=decimals)
    try:
        cur = backend.position_m() / MM
        # the one planner of every writer (motion: the program, the dry run); where the rotary axes stand is not
        # known at the start, so they turn at the first safe Z
        for st, moves in motion(steps[done:], settings, rotary=rotary, from_mm=cur):
            for m in moves:
                backend.move(m.xyz_mm * MM, settings.move_feed_mm_min,
                             None if m.rot_deg is None else np.radians(m.rot_deg))
            res = backend.probe(st.end_mm * MM, settings.probe_feed_mm_min,
                                allow_miss=settings.allow_miss)
            t = max(float(clock()) - started, last_t)
            row = {c: plan.columns[c][st.row] for c in plan.columns}
            row["status"] = res.status
            if res.triggered:
                # the controller's own digits when it reported mm (a trip through metres moves the last one)
                x = (np.asarray(res.reported_mm, dtype=float) if res.reported_mm is not None
                     else np.asarray(res.pos_m, dtype=float) / MM)
                # a report printed to more decimals than the log declares would be cut to them: refused, nothing
                # written (a log the first run declared exact, begun on a backend measuring in metres, takes
                # the report's repr, every digit: its declaration then understates the step, as before session 33)
                printed = getattr(res, "reported_decimals", None) if res.reported_mm is not None else None
                want = decimals.get("X_mm")
                if printed is not None and want is not None and printed > want:
                    raise HardwareError(
                        f"the controller printed the probe report of row {st.row} (target {st.target!r}) to "
                        f"{printed} decimals, but the log declares X_mm, Y_mm, Z_mm printed to {want} "
                        f"({NUMBER_FORMAT_KEY}, from the controller's status report when the log began): not "
                        "logged, the log kept; a controller that prints another step needs a new log")
                if settings.tool_offset_mm is not None:   # the spindle's position -> the tip centre's
                    x = x - np.asarray(settings.tool_offset_mm, dtype=float)
                    if want is not None:   # J on the step (checked at the start): the float subtraction's last bit
                        x = np.round(x, int(want))
                row.update({"X_mm": x[0], "Y_mm": x[1], "Z_mm": x[2], "t_s": t})
                last_t = t
            else:          # probe-log/1: the measured cells of an invalid touch stay empty
                row.update({c: float("nan") for c in MEASURED})
            if temps:
                tc = backend.temperatures_C()
                row.update({f"temp_{k}_C": tc.get(k, float("nan")) for k in temps})
            log.append(row)
            statuses[res.status] = statuses.get(res.status, 0) + 1
            done = st.row + 1
            if on_touch is not None:
                on_touch(st.row, res)
            if res.alarm is not None:
                raise HardwareError(
                    f"ALARM:{res.alarm} ({ALARMS.get(res.alarm, 'alarm')}) at row {st.row} "
                    f"(target {st.target!r}, logged as {res.status}); {done} of {plan.n} rows on disk: "
                    "clear the cause and continue with --resume --unlock")
            backend.move(st.start_mm * MM, settings.move_feed_mm_min)    # retract along the approach
            cur = st.start_mm
        if settings.safe_z_mm is not None:
            backend.move(np.array([cur[0], cur[1], settings.safe_z_mm]) * MM, settings.move_feed_mm_min)
    except HardwareError as e:
        raise HardwareError(f"{e} [{done} of {plan.n} rows in {p}; continue with --resume]"
                            if "--resume" not in str(e) else str(e)) from None
    except KeyboardInterrupt as e:   # Ctrl-C (or SIGTERM, which vmt probe turns into one): the same note
        # as a lost connection; counted on disk: the signal lands anywhere, e.g. in the fsync of a row written
        on_disk = _whole_rows(p)
        e.args = (f"[{done if on_disk is None else on_disk} of {plan.n} rows in {p}; continue with --resume]",)
        raise
    finally:
        log.close()
    return CampaignResult(p, plan.n, before, done, torn, statuses)


def head_meta(path) -> dict:
    """The metadata lines (``# key: value``, first value of a key) at the head of a log, read without
    parsing its rows: what a resume is checked against before the program is (:func:`resume_offset_problem`)."""
    meta = {}
    with open(path, "rb") as f:
        for raw in f:
            line = raw.decode("utf-8", errors="replace").lstrip("\ufeff").rstrip("\r\n")
            if not line.strip():
                continue
            if not line.startswith("#"):
                break
            k, colon, v = line[1:].partition(":")
            if colon:
                meta.setdefault(k.strip(), v.strip())
    return meta


def resume_offset_problem(path, meta: dict, J) -> str | None:
    """Why a log begun with one tool offset J (its ``tool_offset_mm`` line; none: 0) cannot be resumed with
    ``J`` (None: none applied), or None when they are the same J."""
    was = log_tool_offset(meta, path)
    now = (0.0, 0.0, 0.0) if J is None else tuple(float(v) for v in J)
    if all(a == b for a, b in zip(was, now)):
        return None
    said = (f"--tool-offset-mm {tool_offset_text(now)}" if J is not None else "no --tool-offset-mm (J = 0)")
    began = (f"its {TOOL_OFFSET_KEY} line says J = {tool_offset_text(was)} mm" if TOOL_OFFSET_KEY in meta
             else "it has no tool_offset_mm line: begun with none applied (J = 0)")
    return (f"{path}: not resumed, nothing moved, the log kept: {began}, the resume gives {said}: one log holds "
            "one J (its readings are the reports less J); resume with the log's J, or start a new log")


def log_from_plan(plan: ProbeLog, pos_mm, status, t_s, meta: dict | None = None,
                  source: str = "<memory>", printed: dict | None = None) -> ProbeLog:
    """A full ``probe-log/1`` from a plan and what the machine measured.

    Parameters
    ----------
    plan : ProbeLog
        The plan, one row per touch in probing order.
    pos_mm : (n, 3) float
        Reported X, Y, Z of each touch, machine frame, mm (ignored where not ok).
    status : (n,) str
        ``ok`` or why the touch is invalid (``no_trigger``, ...).
    t_s : (n,) float
        Time of each touch, s since the start; must not go backwards.
    meta : dict
        Metadata added to (and overriding) the plan's.
    printed : dict, optional
        The decimals the source printed each measured column with (``{"X_mm": 3, ...}``: a GRBL report's,
        read from its text), the log's :attr:`~core.probelog.ProbeLog.text_steps` for them (the writer
        prints them so and declares it, ``number_format``); a measured column not named is exact. The plan's
        other columns keep the plan's steps (session 33; before, every column of an import was declared exact).

    Raises
    ------
    ProbeLogError
        The result breaks ``probe-log/1`` (e.g. time going backwards).
    """
    from core.probelog import make_log

    n = plan.n
    pos = np.asarray(pos_mm, dtype=float).reshape(n, 3)
    st = np.array([str(s) for s in status], dtype=object)
    t = np.asarray(t_s, dtype=float).reshape(n)
    ok = st == "ok"
    cols = {c: v.copy() for c, v in plan.columns.items()}
    for j, c in enumerate(("X_mm", "Y_mm", "Z_mm")):
        cols[c] = np.where(ok, pos[:, j], np.nan)
    cols["t_s"] = np.where(ok, t, np.nan)
    cols["status"] = st
    m = plan_meta(plan.meta)
    m.update(meta or {})
    log = make_log(cols, m, source=source)
    steps = {k: q for k, q in plan.text_steps.items() if k in log.columns and k not in MEASURED}
    steps.update({k: 10.0 ** -int(d) for k, d in (printed or {}).items() if d is not None})
    return replace(log, text_steps=steps)
