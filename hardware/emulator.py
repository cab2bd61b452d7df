"""GRBL 1.1h, emulated: the virtual machine behind the GRBL protocol, on a TCP port or a pty.

``vmt machine serve`` runs a :class:`GrblEmulator` through an
:class:`EmulatorRunner` (the firmware's clock) on a :class:`TcpServer`
(127.0.0.1 unless told otherwise) and optionally a :class:`PtyServer`, so
the adapter, and anybody's sender software, can be tested against a machine
whose errors are known.

What it does as GRBL 1.1h does (read from the firmware's ``protocol.c``,
``gcode.c``, ``system.c``, ``settings.c``, ``report.c``, ``motion_control.c``
and checked against the firmware itself, built for a PC with grbl-sim):

- lines: spaces, control characters and comments are dropped and letters
  upper-cased before anything else; a line keeps at most 79 characters
  (80-byte buffer with its terminator): more is ``error:11`` and the line
  is not executed; the serial receive buffer holds 128 bytes and drops
  what does not fit while the firmware is busy;
- ``ok`` means the block is in the planner (15 blocks), not that it is
  done; motion takes time (trapezoidal speed per block, the axes' maximum
  rates ``$110..`` and accelerations ``$120..``); a line waits for room in
  the planner; ``G38.x``, ``G4``, ``M0/M2/M30`` and ``$H`` wait for the
  planner to empty;
- real-time characters act at once: ``?`` status, ``!`` feed hold
  (``Hold:1`` while decelerating, then ``Hold:0``), ``~`` resume (only
  from ``Hold:0``), Ctrl-X (0x18) soft reset, 0x85 jog cancel; override
  characters (0x90-0xA1) change the reported ``Ov:`` values only (the
  speed is not changed: a documented simplification);
- status ``<Idle|Run|Hold:0|Hold:1|Jog|Home|Alarm|Check|Sleep|MPos or
  WPos|Bf (if $10 bit 1)|FS:feed,spindle|Pn:P|WCO|Ov>``, ``WCO`` and
  ``Ov`` on GRBL's own refresh counters (every 10 reports idle, 30/20
  busy, ``Ov`` on the report after a ``WCO``);
- G-code: G0 G1 G2 G3 G4 G10 L2/L20 G17-G19 G20 G21 G28 G28.1 G30 G30.1
  G38.2-G38.5 G40 G43.1 G49 G53 G54-G59 G61 G80 G90 G91 G91.1 G92 G92.1
  G93 G94 M0 M1 M2 M30 M3 M4 M5 M8 M9 F S T N, with GRBL's error checks
  and codes (``G53 G38.2`` is ``error:30``, a zero-length probe
  ``error:33``, a word twice ``error:25`` ...);
- probing: ``ALARM:4`` when the probe is not in the expected state at
  the start; a contact stops the move (deceleration past the trigger);
  a ``G38.2``/``G38.4`` miss raises ``ALARM:5`` and then, 0.5 s later (the
  firmware's alarm delay), prints ``[PRB:...:0]`` with the *previous*
  probe position (the firmware does not update it), then ``ok``;
  ``G38.3``/``G38.5`` report the end of the move with ``:0``;
- ``$$`` (the 34 settings of a 3-axis GRBL, 4 more per extra axis),
  ``$n=v`` (with GRBL's checks: ``error:4`` negative, ``error:6`` step
  pulse under 3 us, ``error:10`` soft limits without homing), ``$#``,
  ``$G``, ``$I`` (``$I=`` stores the build info), ``$N``/``$Nn=``, ``$C``,
  ``$X``, ``$H`` (``error:5`` when ``$22=0``), ``$J=`` (``error:15`` beyond
  soft limits, ``error:16`` for other G-codes), ``$RST=$|#|*``, ``$SLP``;
- a hardware reset (:meth:`GrblEmulator.power_cycle`: power-up, DTR): the
  machine position 0 where the machine stands (the machine model keeps where
  it physically is, until ``$H`` finds the switches), the banner;
  :class:`TcpServer` ``on_connect`` greets, resets or says nothing;
- alarms: power-on in alarm when ``$22=1``; Ctrl-X during motion raises
  ``ALARM:3`` (``ALARM:6`` while homing), then ``ok`` for the line that was
  executing, then the banner and ``[MSG:'$H'|'$X' to unlock]``; a
  soft-limit target raises ``ALARM:2`` (after a controlled stop) and
  ``[MSG:Reset to continue]``, and then the firmware answers *nothing*, not
  even status reports, until a reset; only after the reset can ``$X``
  unlock (the position is kept). G-code in alarm gets ``error:9``.

Where it differs, by design: the soft-limit box is the machine's own
travel in its own frame (``ControllerConfig.travel``) instead of GRBL's
``[-$13x, 0]``; ``$H`` moves straight to ``ControllerConfig.home`` (Z
first, then the others) at the seek rate ``$25``; the probe pin is the
machine's contact (``in_contact`` when the machine has it, else the last
probing move's outcome); ``$6=1`` inverts it as on the real pin; planner
blocks start and stop at rest (no junction blending); arcs are cut into
chords of at most ``$12``; extra axes beyond X, Y, Z follow grblHAL: their
words are accepted, reported in ``MPos``/``[PRB]``/``$#``, numbered ``$103``,
``$113``... in ``$$``, and named in ``$I`` by ``[AXS:n:letters]``.

The probe's length (session 36): ``tool_offset_mm`` J (spindle gauge point minus stylus-tip centre, as
a machine file's ``[tool] offset_mm``) makes the machine position the spindle's, as on a real GRBL
machine: the stylus-tip centre the virtual machine reads stands at ``machine position - J`` (the
firmware knows nothing of it; ``G43.1`` still shifts only the work coordinates). J = 0 (the default):
the machine position is the tip centre's, as before. ``vmt probe --tool-offset-mm J`` against it logs
the tip centres the direct simulation logs.

The virtual machine is duck-typed, one method (``sim.probe.VirtualMachine``
through ``hardware.virtual`` or :class:`hardware.scene.SimpleScene`)::

    probe_move(start_m (3,), target_m (3,), rot_rad (3,) A, B, C) -> (triggered, pos_m (3,))

and optionally ``in_contact(pos_m (3,), rot_rad (3,)) -> bool``.

:class:`Faults` injects the failures a campaign must survive: dropped
connections, alarms and garbage lines.
"""

from __future__ import annotations

import math
import os
import select
import socket
import threading
import time
from collections import deque
from dataclasses import dataclass, field

import numpy as np

VERSION, BUILD_DATE = "1.1h", "20190830"
BANNER = f"Grbl {VERSION} ['$' for help]"
#: Characters a line may keep after spaces and comments are stripped (80-byte buffer).
LINE_MAX_CHARS = 79
#: Bytes the serial receive ring holds: serial.h's RX_BUFFER_SIZE, 128 (``[OPT:V,15,128]``, and
#: ``Bf:`` counts free bytes of it). serial.c's ring has RX_BUFFER_SIZE + 1 = 129 slots and is full
#: when the next head would meet the tail, so 128 bytes fit (the one slot kept free is the 129th).
RX_BUFFER_BYTES = 128
#: Planner blocks (``[OPT:V,15,128]``).
PLANNER_BLOCKS = 15
#: The firmware waits this long after printing an alarm (``report_alarm_message``), s.
ALARM_DELAY_S = 0.5
MM_PER_INCH = 25.4
N_STARTUP_LINES = 2
MAX_LINE_NUMBER = 10_000_000
MAX_TOOL_NUMBER = 255
WCO_REFRESH_BUSY, WCO_REFRESH_IDLE = 30, 10
OVR_REFRESH_BUSY, OVR_REFRESH_IDLE = 20, 10
MSG_UNLOCK = "[MSG:'$H'|'$X' to unlock]"
MSG_RESET = "[MSG:Reset to continue]"
#: A link marker in :meth:`GrblEmulator.take_output`: close the connection here.
DROP = "\x00drop"

_GARBAGE = ("[PRB:12.500,zz,3.000:1]", "ok?", "<Idle|MPos:1.0,abc,3>", "\x7f\x01noise\x02",
            "[PRB:1.000,2.000:1]", "ALARM", "error:", "[PRB:5.000,5.000,5.000:1")

#: GRBL 1.1h's settings besides the per-axis ones: number -> (meaning, power-on value, decimals
#: printed, None for an integer). The values are the firmware's DEFAULTS_GENERIC.
GLOBAL_SETTINGS = {
    0: ("step pulse, us", 10, None), 1: ("step idle delay, ms", 25, None),
    2: ("step port invert mask", 0, None), 3: ("direction port invert mask", 0, None),
    4: ("step enable invert", 0, None), 5: ("limit pins invert", 0, None),
    6: ("probe pin invert", 0, None), 10: ("status report mask", 1, None),
    11: ("junction deviation, mm", 0.010, 3), 12: ("arc tolerance, mm", 0.002, 3),
    13: ("report inches", 0, None), 20: ("soft limits", 0, None), 21: ("hard limits", 0, None),
    22: ("homing cycle", 0, None), 23: ("homing direction invert mask", 0, None),
    24: ("homing feed, mm/min", 25.0, 3), 25: ("homing seek, mm/min", 500.0, 3),
    26: ("homing debounce, ms", 250, None), 27: ("homing pull-off, mm", 1.0, 3),
    30: ("maximum spindle speed, rpm", 1000.0, 0), 31: ("minimum spindle speed, rpm", 0.0, 0),
    32: ("laser mode", 0, None)}
#: Per-axis settings: base number -> meaning (``$100`` X, ``$101`` Y, ... ``$103`` the 4th axis).
AXIS_SETTINGS = {100: "steps per unit", 110: "maximum rate, unit/min",
                 120: "acceleration, unit/s^2", 130: "maximum travel, unit"}


@dataclass(frozen=True)
class Faults:
    """Failures to inject, counted over the emulator's life (probing moves from 1).

    Attributes
    ----------
    drop_before_probe : tuple of int
        On receiving probing move k, close the connection without executing it.
    drop_after_probe : tuple of int
        Execute probing move k, then close the connection before answering.
    alarm_at_probe : dict[int, int]
        Raise ``ALARM:code`` instead of executing probing move k (1, a hard
        limit, then needs a reset as on the real firmware).
    garbage_every : int
        Put a garbage line before every n-th answer line (0: never).
    """

    drop_before_probe: tuple = ()
    drop_after_probe: tuple = ()
    alarm_at_probe: dict = field(default_factory=dict)
    garbage_every: int = 0


@dataclass(frozen=True)
class ControllerConfig:
    """What the GRBL controller of a machine knows: its axes and its settings.

    Attributes
    ----------
    axes : str
        Axis letters, ``"XYZ"`` then rotary axes in ``A``, ``B``, ``C`` order
        (e.g. ``"XYZAC"``); reported in this order.
    home : tuple of float
        Position at power-on and after ``$H``, one value per axis, mm (X, Y, Z)
        and deg (rotary). Shorter: the rest is 0.
    travel : tuple of (lo, hi) or None
        Soft-limit box per axis in machine coordinates (mm, deg; ``None`` for
        an axis without limits). Given: soft limits on, which GRBL allows only
        with homing (``$20=1`` and ``$22=1``): the controller powers on in alarm.
    homing : bool
        ``$22=1`` without soft limits: powers on in alarm, ``$H`` homes.
    steps_per_unit, max_rate_per_min, accel_per_s2 : float
        ``$10x``, ``$11x``, ``$12x`` of every axis (unit: mm or deg).
    report_wpos : bool
        ``$10=0``: status reports ``WPos`` instead of ``MPos``.
    probe_invert : bool
        ``$6=1``.
    """

    axes: str = "XYZ"
    home: tuple = (0.0, 0.0, 0.0)
    travel: tuple | None = None
    homing: bool = False
    steps_per_unit: float = 1000.0
    max_rate_per_min: float = 2000.0
    accel_per_s2: float = 100.0
    report_wpos: bool = False
    probe_invert: bool = False

    def __post_init__(self):
        from core.exceptions import ConfigError

        ax = self.axes.upper()
        if ax[:3] != "XYZ" or len(set(ax)) != len(ax) or any(a not in "ABC" for a in ax[3:]) \
                or list(ax[3:]) != sorted(ax[3:]):
            raise ConfigError(f"controller axes {self.axes!r}: expected XYZ then A, B, C in order (e.g. XYZAC)")
        object.__setattr__(self, "axes", ax)
        h = tuple(float(v) for v in self.home) + (0.0,) * max(0, len(ax) - len(self.home))
        if len(h) != len(ax) or not all(math.isfinite(v) for v in h):
            raise ConfigError(f"controller home {self.home!r}: at most {len(ax)} finite values")
        object.__setattr__(self, "home", h)
        if self.travel is not None:
            t = list(self.travel) + [None] * max(0, len(ax) - len(self.travel))
            if len(t) != len(ax):
                raise ConfigError(f"controller travel {self.travel!r}: at most {len(ax)} axes")
            out = []
            for a, r in zip(ax, t):
                if r is None:
                    out.append(None)
                    continue
                lo, hi = (float(v) for v in r)
                if not (math.isfinite(lo) and math.isfinite(hi) and lo < hi):
                    raise ConfigError(f"controller travel of {a} {r!r}: expected finite lo < hi")
                out.append((lo, hi))
            object.__setattr__(self, "travel", tuple(out))
        for k in ("steps_per_unit", "max_rate_per_min", "accel_per_s2"):
            v = getattr(self, k)
            if not (isinstance(v, (int, float)) and math.isfinite(v) and v > 0):
                raise ConfigError(f"controller {k} {v!r}: expected a positive number")


def controller_for_machine(config, home=None) -> ControllerConfig:
    """The controller of a machine description: its axes, and its strokes as soft limits.

    The seam for machine files: anything with ``strokes`` (axis -> (min, max)
    in m and rad, as ``sim.machine.MachineConfig``) gives a controller with
    those axes and that travel (mm, deg).

    Parameters
    ----------
    config : object with ``strokes`` mapping
    home : sequence of float or None
        Power-on / ``$H`` position (mm, deg); default the middle of X and Y
        and the top of Z.
    """
    from core.exceptions import ConfigError

    st = dict(config.strokes)
    missing = [a for a in "XYZ" if a not in st]
    if missing:
        raise ConfigError(f"machine {getattr(config, 'name', '?')!r}: no stroke for {missing[0]}")
    axes = "XYZ" + "".join(a for a in "ABC" if a in st)
    travel = tuple((math.degrees(lo), math.degrees(hi)) if a in "ABC" else (lo * 1e3, hi * 1e3)
                   for a in axes for lo, hi in [st[a]])
    if home is None:
        home = (0.5 * (travel[0][0] + travel[0][1]), 0.5 * (travel[1][0] + travel[1][1]), travel[2][1])
    return ControllerConfig(axes=axes, home=tuple(home), travel=travel)


# ---------------------------------------------------------------------------
# motion: blocks with trapezoidal speed, started and stopped at rest


@dataclass
class _Block:
    start: np.ndarray          # (n,) machine coordinates, mm / deg
    end: np.ndarray
    v_max: float               # units/s along the path
    accel: float               # units/s^2 along the path
    kind: str = "line"         # line | probe | jog | home
    probe: dict | None = None  # probing: s_trig, report, away, no_error; filled on trigger

    @property
    def length(self) -> float:
        return float(np.linalg.norm(self.end - self.start))


def _profile(t0, s0, s_end, v_max, a):
    """Phases ``(t, s, v, acc, dur)`` from rest at ``s0`` to rest at ``s_end``."""
    d = max(0.0, s_end - s0)
    if d <= 0.0:
        return [(t0, s0, 0.0, 0.0, 0.0)]
    vp = min(v_max, math.sqrt(a * d))
    da = vp * vp / (2 * a)
    dc = max(0.0, d - 2 * da)
    out = [(t0, s0, 0.0, a, vp / a)]
    t = t0 + vp / a
    if dc > 0:
        out.append((t, s0 + da, vp, 0.0, dc / vp))
        t += dc / vp
    out.append((t, s0 + da + dc, vp, -a, vp / a))
    return out


def _phase_at(phases, t):
    for ph in phases:
        if t <= ph[0] + ph[4]:
            return ph
    return phases[-1]


def _eval(phases, t):
    """(s, v) at time ``t`` (clamped to the phases)."""
    t0, s0, v0, acc, dur = _phase_at(phases, t)
    dt = min(max(t - t0, 0.0), dur)
    return s0 + v0 * dt + 0.5 * acc * dt * dt, max(0.0, v0 + acc * dt)


def _time_at_s(phases, s):
    """First time the path reaches ``s`` (None if it never does)."""
    for t0, s0, v0, acc, dur in phases:
        ds_phase = v0 * dur + 0.5 * acc * dur * dur
        if s <= s0 + ds_phase + 1e-12:
            ds = max(0.0, s - s0)
            root = math.sqrt(max(0.0, v0 * v0 + 2 * acc * ds))
            return t0 + (2 * ds / (v0 + root) if v0 + root > 0 else 0.0)
    return None


def _fmt(v: float, decimals: int) -> str:
    return f"{float(v) + 0.0:.{decimals}f}"


class GrblEmulator:
    """The GRBL 1.1h firmware: bytes in, lines out, on an emulated clock.

    Transport-agnostic and single-threaded: :meth:`receive` takes bytes
    (real-time characters act at once), :meth:`advance_to` moves the
    emulated clock (motion, probing, delays), :meth:`take_output` returns
    the lines printed since. :meth:`feed_bytes` does all three until nothing
    more can happen without input (for tests). :class:`EmulatorRunner`
    drives it in real time.

    Parameters
    ----------
    machine : object
        ``probe_move(start_m, target_m, rot_rad) -> (triggered, pos_m)``;
        optionally ``in_contact(pos_m, rot_rad) -> bool``.
    config : ControllerConfig
    faults : Faults
    start_in_alarm : bool or None
        Power on in alarm; default: when homing is enabled, as GRBL does.
    tool_offset_mm : (3,) float or None
        The probe's offsets J, mm: the tip centre the machine model reads is the machine position - J
        (module docstring). None: (0, 0, 0), the machine position is the tip centre's.
    """

    def __init__(self, machine, config: ControllerConfig | None = None, *, faults: Faults | None = None,
                 start_in_alarm: bool | None = None, tool_offset_mm=None):
        from core.exceptions import ConfigError

        J = np.zeros(3) if tool_offset_mm is None else np.asarray(tool_offset_mm, dtype=float).reshape(-1)
        if J.shape != (3,) or not np.all(np.isfinite(J)):
            raise ConfigError(f"tool offset {tool_offset_mm!r}: expected three finite numbers X,Y,Z, mm")
        self.machine = machine
        self.config = config or ControllerConfig()
        self.faults = faults or Faults()
        self.axes = self.config.axes
        self.n = len(self.axes)
        self._lin = np.array([a in "XYZ" for a in self.axes])
        self.settings = self._default_settings()
        self.coord_data = {k: np.zeros(self.n) for k in range(8)}   # G54..G59, G28, G30
        self.startup_lines = [""] * N_STARTUP_LINES
        self.build_info = ""
        self.now = 0.0
        self.pos = np.array(self.config.home, dtype=float)        # machine position, mm / deg
        #: Where the machine model's frame has the machine position's zero (mm / deg): the machine
        #: physically stands at ``pos + frame_mm``. 0 until a power-up reset (:meth:`power_cycle`) sets
        #: the position to 0 where the machine stands; ``$H`` finds the switches and sets it back to 0.
        self.frame_mm = np.zeros(self.n)
        #: The probe's offsets J (mm): the tip centre the machine model reads stands at machine position + the
        #: frame - J (:meth:`_model_xyz`); a reset or ``$H`` does not change it (the probe is what it is).
        self.tool_offset_mm = J
        self.probes = 0            # probing moves received
        self.touches: list = []    # (triggered, pos_mm (3,)) of every executed probing move
        self.alarm: int | None = None
        self.internal_errors: list[str] = []   # a bug would land here; the firmware survives
        self._out: list[str] = []
        self._answered = 0
        self._rx: deque = deque()
        self._rx_dropped = 0
        self._line = bytearray()
        self._line_flags = 0       # 1 overflow, 2 in (comment), 4 after ;
        self._queue: deque = deque()
        self._active: _Block | None = None
        self._phases: list = []
        self._holding = False      # a feed hold is decelerating or complete
        self._hold_done = False    # Hold:0, ready to resume
        self._cancel = False       # motion cancel (probe contact, jog cancel): block ends at rest
        self._rt_status = False
        self._rt_hold = False
        self._rt_start = False
        self._rt_jog_cancel = False
        self._reset_after_line = False
        self._critical = False     # ALARM:1/2: nothing but a reset
        self._sleep = False
        self._contact = False      # probe pin from the last probing move (machines without in_contact)
        self._ovr = [100, 100, 100]
        self._wco_counter = 0
        self._ovr_counter = 0
        homing = bool(self.settings[22])
        self.state = "Alarm" if (homing if start_in_alarm is None else start_in_alarm) else "Idle"
        self._gc_init()
        self._busy_line = False
        self._wait = None
        self._main = self._main_loop()
        self._step_main()

    # ---------------------------------------------------------------- settings
    def _default_settings(self) -> dict:
        cfg = self.config
        s = {k: float(v[1]) for k, v in GLOBAL_SETTINGS.items()}
        s[10] = 0.0 if cfg.report_wpos else 1.0
        s[6] = 1.0 if cfg.probe_invert else 0.0
        s[22] = 1.0 if (cfg.homing or cfg.travel is not None) else 0.0
        s[20] = 1.0 if cfg.travel is not None else 0.0
        for i in range(self.n):
            s[100 + i] = float(cfg.steps_per_unit)
            s[110 + i] = float(cfg.max_rate_per_min)
            s[120 + i] = float(cfg.accel_per_s2)
            tr = cfg.travel[i] if cfg.travel is not None else None
            s[130 + i] = float(tr[1] - tr[0]) if tr is not None else 200.0
        return s

    def settings_lines(self) -> list[str]:
        """The ``$$`` listing, in the firmware's order."""
        out = []
        for k, (_m, _d, dec) in GLOBAL_SETTINGS.items():
            v = self.settings[k]
            out.append(f"${k}={int(v)}" if dec is None else f"${k}={_fmt(v, dec)}")
        for base in AXIS_SETTINGS:
            for i in range(self.n):
                out.append(f"${base + i}={_fmt(self.settings[base + i], 3)}")
        return out

    def _store_setting(self, n: float, v: float) -> int:
        if v < 0:
            return 4
        if n >= 100:
            k = int(n) - 100
            if k % 10 >= self.n or k // 10 >= 4 or n != int(n):
                return 3
            self.settings[int(n)] = v
            return 0
        if n != int(n) or int(n) not in GLOBAL_SETTINGS:
            return 3
        n = int(n)
        iv = math.trunc(v) % 256
        if n == 0 and iv < 3:
            return 6
        if n == 20 and iv and not self.settings[22]:
            return 10
        if n == 22 and not iv:
            self.settings[20] = 0.0
        self.settings[n] = float(iv) if GLOBAL_SETTINGS[n][2] is None else v
        if n == 13:
            self._wco_counter = 0
        return 0

    def _restore(self, what: str) -> None:
        if what in "$*":
            self.settings = self._default_settings()
        if what in "#*":
            self.coord_data = {k: np.zeros(self.n) for k in range(8)}
        if what == "*":
            self.startup_lines = [""] * N_STARTUP_LINES
            self.build_info = ""

    # ---------------------------------------------------------------- parser state
    def _gc_init(self) -> None:
        self.gc = {"motion": 0.0, "coord": 0, "plane": 0, "inch": False, "incremental": False,
                   "inverse_time": False, "spindle": 5, "coolant": 9, "tool": 0, "feed": 0.0,
                   "speed": 0.0, "line": 0}
        self.coord_system = self.coord_data[0].copy()
        self.g92 = np.zeros(self.n)
        self.tlo = 0.0
        self.gc_pos = self.pos.copy()
        self.probe_pos = np.zeros(self.n)
        self.probe_ok = False

    def set_report_counters(self, wco: int, ovr: int) -> None:
        """GRBL's status refresh counters: ``WCO:`` after ``wco`` more reports, ``Ov:`` after ``ovr``
        (where a session left them; a reset zeroes both)."""
        self._wco_counter, self._ovr_counter = int(wco), int(ovr)

    def wco(self) -> np.ndarray:
        """Work coordinate offset (G5x + G92, tool length on Z), mm / deg."""
        w = self.coord_system + self.g92
        w[2] += self.tlo
        return w

    # ---------------------------------------------------------------- output
    def _print(self, line: str) -> None:
        g = self.faults.garbage_every
        if g and line != DROP and not line.startswith("<"):
            self._answered += 1
            if self._answered % g == 0:
                self._out.append(_GARBAGE[(self._answered // g) % len(_GARBAGE)])
        self._out.append(line)

    def take_output(self) -> list[str]:
        """Lines printed since the last call (``DROP`` where a link must close)."""
        out, self._out = self._out, []
        return out

    def greeting(self) -> list[str]:
        """What a new connection reads first: the banner, and the lock message in alarm."""
        return ["", BANNER] + ([MSG_UNLOCK] if self.state == "Alarm" and not self._critical else [])

    def _units(self, v_mm, decimals_mm=3, decimals_in=4) -> str:
        inch = bool(self.settings[13])
        vals = [v / MM_PER_INCH if (inch and lin) else v for v, lin in zip(v_mm, self._lin)]
        return ",".join(_fmt(v, decimals_in if inch else decimals_mm) for v in vals)

    # ---------------------------------------------------------------- motion
    def position(self) -> np.ndarray:
        """Machine position now (mm, deg)."""
        b = self._active
        if b is None or b.length == 0:
            return self.pos.copy()
        s, _v = _eval(self._phases, self.now)
        return b.start + (b.end - b.start) * (s / b.length)

    @property
    def pos_mm(self) -> np.ndarray:
        """X, Y, Z of the machine position now, mm."""
        return self.position()[:3]

    def speed_per_min(self) -> float:
        if self._active is None or self._active.length == 0:
            return 0.0
        return _eval(self._phases, self.now)[1] * 60.0

    def _limits(self, vec, rates) -> float:
        u = np.abs(vec)
        m = u > 0
        return float(np.min(np.asarray(rates)[m] / u[m])) if m.any() else math.inf

    def _make_block(self, start, end, feed_per_min, kind="line", rapid=False) -> _Block:
        d = end - start
        L = float(np.linalg.norm(d))
        u = d / L if L > 0 else d
        rates = [self.settings[110 + i] for i in range(self.n)]
        acc = [self.settings[120 + i] for i in range(self.n)]
        rapid_rate = self._limits(u, rates)
        v = max(rapid_rate if rapid else min(feed_per_min, rapid_rate), 1.0)   # MINIMUM_FEED_RATE
        return _Block(start.copy(), end.copy(), v / 60.0, max(self._limits(u, acc), 1e-9), kind)

    def _start_block(self, b: _Block, t: float) -> None:
        self._active = b
        self._cancel = False
        self._phases = _profile(t, 0.0, b.length, b.v_max, b.accel)
        if b.probe is not None and b.probe["s_trig"] is not None:
            b.probe["t_trig"] = _time_at_s(self._phases, b.probe["s_trig"])

    def _motion_end_time(self) -> float:
        t0, _s, _v, _a, dur = self._phases[-1]
        return t0 + dur

    def _decelerate(self) -> None:
        """Stop the active block from its present speed (hold or cancel)."""
        b = self._active
        s, v = _eval(self._phases, self.now)
        if v <= 0:
            self._phases = [(self.now, s, 0.0, 0.0, 0.0)]
            return
        stop = s + v * v / (2 * b.accel)
        if stop >= b.length:          # already decelerating to the block's end
            return
        self._phases = [(self.now, s, v, -b.accel, v / b.accel)]

    def _cycle_start(self) -> None:
        """Start the next queued block (auto-cycle start) when nothing moves and nothing holds."""
        if self._active is None and self._queue and not self._holding:
            b = self._queue.popleft()
            self._start_block(b, self.now)
            if self.state in ("Idle", "Run"):
                self.state = "Jog" if b.kind == "jog" else ("Home" if b.kind == "home" else "Run")
            self._contact = False

    def _next_motion_event(self) -> float | None:
        b = self._active
        if b is None or (self._holding and self._hold_done):
            return None                 # nothing moves, or Hold:0 until ~ or a reset
        pr = b.probe
        if pr is not None and pr.get("t_trig") is not None and not pr.get("hit"):
            return max(min(pr["t_trig"], self._motion_end_time()), self.now)
        return max(self._motion_end_time(), self.now)

    def _motion_event(self) -> bool:
        """Whatever the motion does at ``now``: a probe contact, a hold complete, a block done."""
        b = self._active
        if b is None:
            return False
        pr = b.probe
        if pr is not None and pr.get("t_trig") is not None and not pr.get("hit") \
                and self.now >= pr["t_trig"] - 1e-12:
            pr["hit"] = True            # the pin changed: cancel the motion, decelerating
            self._cancel = True
            self._decelerate()
            return True
        t_end = self._motion_end_time()
        if self.now < t_end - 1e-12:
            return False
        s, _v = _eval(self._phases, t_end)
        if self._holding and not self._cancel and s < b.length - 1e-9:
            if self._hold_done:
                return False
            self._hold_done = True      # Hold:0, the rest of the block waits for ~
            return True
        cancelled = self._cancel
        self.pos = b.start + (b.end - b.start) * (s / b.length) if (cancelled and b.length > 0) else b.end.copy()
        self._active = None
        self._phases = []
        self._cancel = False
        if b.kind == "jog" and cancelled:
            self._queue.clear()
            self.gc_pos = self.pos.copy()
        if self._holding:
            if b.kind == "jog":
                self._holding = self._hold_done = False
                self.state = "Idle"
            else:
                self._hold_done = True
            return True
        if self._queue:
            self._cycle_start()
        elif self.state in ("Run", "Jog"):
            self.state = "Idle"
        return True

    def _feed_hold(self) -> None:
        if self.state in ("Alarm", "Check", "Sleep") or self._critical:
            return
        if self.state == "Jog":
            self._jog_cancel()
            return
        if self.state in ("Run", "Home") and self._active is not None:
            if self.state == "Home":
                return
            self._holding = True
            self._hold_done = False
            self._decelerate()
            self.state = "Hold"
        elif self.state == "Idle":
            self._holding = True
            self._hold_done = True
            self.state = "Hold"

    def _resume(self) -> None:
        if self.state != "Hold" or not self._hold_done:
            return
        self._holding = False
        self._hold_done = False
        b = self._active
        if b is not None:
            s, _v = _eval(self._phases, self.now)
            self._phases = _profile(self.now, s, b.length, b.v_max, b.accel)
            if b.probe is not None and b.probe["s_trig"] is not None and not b.probe.get("hit"):
                b.probe["t_trig"] = _time_at_s(self._phases, b.probe["s_trig"])
            self.state = "Run"
        elif self._queue:
            self.state = "Run"
            self._cycle_start()
        else:
            self.state = "Idle"

    def _jog_cancel(self) -> None:
        if self.state != "Jog" or self._active is None:
            return
        self._cancel = True
        self._decelerate()

    # ---------------------------------------------------------------- input
    def receive(self, data: bytes) -> None:
        """Bytes from the serial line: real-time characters act now, the rest is buffered."""
        for b in bytes(data):
            if b in (0x18, 0x3F, 0x7E, 0x21) or b >= 0x80:
                self._run_main()          # the firmware keeps up with the line: what came first runs first
                if b == 0x18:
                    self._soft_reset()
                    continue
                if b == 0x3F:             # ?
                    self._rt_status = True
                elif b == 0x7E:           # ~
                    self._rt_start = True
                elif b == 0x21:           # !
                    self._rt_hold = True
                elif b == 0x85:
                    self._rt_jog_cancel = True
                elif 0x90 <= b <= 0xA1:
                    self._override(b)
                # other extended characters are thrown away, as the firmware does
                self._realtime()
                continue
            if len(self._rx) >= RX_BUFFER_BYTES:
                self._run_main()          # the firmware reads while bytes arrive
            if len(self._rx) >= RX_BUFFER_BYTES:
                self._rx_dropped += 1
                continue
            self._rx.append(b)
        self._realtime()
        self._run_main()

    def _override(self, b: int) -> None:
        f, r, s = self._ovr
        f = {0x90: 100, 0x91: f + 10, 0x92: f - 10, 0x93: f + 1, 0x94: f - 1}.get(b, f)
        r = {0x95: 100, 0x96: 50, 0x97: 25}.get(b, r)
        s = {0x99: 100, 0x9A: s + 10, 0x9B: s - 10, 0x9C: s + 1, 0x9D: s - 1}.get(b, s)
        new = [min(200, max(10, f)), r, min(200, max(10, s))]
        if new != self._ovr:
            self._ovr = new
            self._ovr_counter = 0

    def _realtime(self) -> None:
        """``protocol_execute_realtime``: status, hold, resume (not in a critical alarm)."""
        if self._critical or (self._wait is not None and self._wait.get("no_rt")):
            return
        if self._rt_jog_cancel:
            self._rt_jog_cancel = False
            self._jog_cancel()
        if self._rt_hold:
            self._rt_hold = False
            self._feed_hold()
        if self._rt_start:
            self._rt_start = False
            self._resume()
        if self._rt_status:
            self._rt_status = False
            self._print(self.status_line())

    # ---------------------------------------------------------------- clock
    def advance_to(self, t: float) -> None:
        """Run the firmware up to emulated time ``t`` (s)."""
        for _ in range(1_000_000):
            te = self.next_event()
            if te is None or te > t:
                break
            self.now = max(self.now, te)
            if not self._process():     # an event that changes nothing would loop for ever
                self.internal_errors.append(f"stuck event at t = {te!r}")
                break
        self.now = max(self.now, t)
        self._process()

    def next_event(self) -> float | None:
        """Emulated time of the next thing that happens without input (None: nothing)."""
        cand = [x for x in (self._next_motion_event(),
                            self._wait.get("until") if self._wait else None) if x is not None]
        return min(cand) if cand else None

    def _process(self) -> bool:
        """Motion events due now, real-time commands, the main loop; True if anything happened."""
        any_ = False
        for _ in range(10_000):
            did = False
            te = self._next_motion_event()
            if te is not None and te <= self.now:
                did |= self._motion_event()
            self._realtime()
            did |= self._run_main()
            any_ |= did
            if not did:
                break
        return any_

    def quiet(self) -> bool:
        """Nothing in progress: no motion, no line executing, nothing buffered."""
        return (self._active is None and not self._queue and not self._busy_line and not self._rx
                and not self._critical)

    def feed_bytes(self, data: bytes, max_s: float = 3600.0) -> tuple[list[str], bool]:
        """Receive ``data`` and run until nothing more happens without input.

        Returns (lines printed, whether the link was dropped). ``max_s``
        bounds the emulated time spent (a move of a kilometre at 1 mm/min).
        """
        self.receive(data)
        end = self.now + max_s
        for _ in range(100_000):
            te = self.next_event()
            if te is None or te > end:
                break
            self.advance_to(te)
        out = self.take_output()
        drop = DROP in out
        return [x for x in out if x != DROP], drop

    # ---------------------------------------------------------------- the main loop
    def _run_main(self) -> bool:
        """Resume the main loop while what it waits for is there; True if it ran."""
        ran = False
        for _ in range(10_000):
            w = self._wait
            if w is None:
                return ran
            ready = (w.get("until") is not None and self.now >= w["until"] - 1e-12) or \
                    (w.get("cond") is not None and w["cond"]())
            if not ready:
                return ran
            self._step_main()
            ran = True
        return ran

    def _step_main(self) -> None:
        gen = self._main
        try:
            w = gen.send(None)
        except StopIteration:            # pragma: no cover - the loop never ends
            w = None
        except Exception as e:           # a bug: keep serving, keep the evidence
            self.internal_errors.append(f"{type(e).__name__}: {e}")
            self._busy_line = False
            self._print("error:1")
            self._main = gen = self._main_loop()
            w = gen.send(None)
        if gen is self._main:
            self._wait = w
        if self._reset_after_line:       # $C off, $RST=: the firmware resets after the ok
            self._reset_after_line = False
            self._soft_reset()

    def _main_loop(self):
        while True:
            raw, overflow = yield from self._read_line()
            self._busy_line = True
            if overflow:
                status = 11
            elif not raw:
                status = 0
            elif raw[0] == "$":
                status = yield from self._system(raw)
            elif self.state in ("Alarm", "Jog"):
                status = 9
            else:
                status = yield from self._gcode(raw)
            self._busy_line = False
            self._print("ok" if status == 0 else f"error:{status}")
            if self._reset_after_line:
                yield {"no_rt": True}       # the driver resets now

    def _read_line(self):
        while True:
            while self._rx:
                c = self._rx.popleft()
                if c in (10, 13):
                    line = self._line.decode("latin-1")
                    overflow = bool(self._line_flags & 1)
                    self._line = bytearray()
                    self._line_flags = 0
                    while self._holding:     # a feed hold suspends the main loop until ~ or a reset
                        yield {"cond": lambda: not self._holding}
                    return line, overflow
                if self._line_flags:
                    if c == 0x29 and self._line_flags & 2:     # ) ends a (comment)
                        self._line_flags &= ~2
                    continue
                if c <= 0x20 or c == 0x2F:                     # spaces, controls, block delete
                    continue
                if c == 0x28:
                    self._line_flags |= 2
                elif c == 0x3B:
                    self._line_flags |= 4
                elif len(self._line) >= LINE_MAX_CHARS:
                    self._line_flags |= 1
                else:
                    self._line.append(c - 32 if 0x61 <= c <= 0x7A else c)
            yield {"cond": lambda: bool(self._rx)}

    def _delay(self, seconds: float, rt: bool = True):
        yield {"until": self.now + seconds, "no_rt": not rt}

    def _raise_alarm(self, code: int):
        """Alarm: ``ALARM:n``, the firmware's 0.5 s delay; 1 and 2 then wait for a reset."""
        self.state = "Alarm"
        self.alarm = code
        self._print(f"ALARM:{code}")
        yield from self._delay(ALARM_DELAY_S, rt=False)
        if code in (1, 2):
            self._print(MSG_RESET)
            self._critical = True
            self._rt_status = False
            while True:
                yield {"no_rt": True}

    def _sync(self):
        """``protocol_buffer_synchronize``: wait until every queued block is done."""
        self._cycle_start()
        while self._active is not None or self._queue:
            yield {"cond": lambda: self._active is None and not self._queue}

    # ---------------------------------------------------------------- reset
    def _soft_reset(self) -> None:
        moving = self._active is not None and (self.state in ("Run", "Jog", "Home")
                                               or (self._holding and not self._hold_done))
        alarm = None
        if not self._critical and moving:
            alarm = 6 if self.state == "Home" else 3
        executing = self._busy_line
        self._sleep = False
        self.pos = self.position()
        self._active = None
        self._phases = []
        self._queue.clear()
        self._holding = self._cancel = False
        self._hold_done = False
        self._rx.clear()
        self._line = bytearray()
        self._line_flags = 0
        self._critical = False
        self._busy_line = False
        self._reset_after_line = False
        if self.state in ("Home", "Sleep"):
            self.state = "Alarm"
        elif self.state not in ("Alarm",):
            self.state = "Idle"
        self._main = self._after_reset(alarm, executing)
        self._wait = None
        self._step_main()

    def power_cycle(self) -> None:
        """A hardware reset: power-up, the reset button, or DTR when a host opens an Arduino's
        serial port. GRBL's main() then sets the machine position to 0 where the machine stands
        (``memset(sys_position, 0)``), powers on in alarm when homing is enabled (HOMING_INIT_LOCK),
        clears the parser, the planner and the receive buffer, and prints its banner. Motion stops
        where it is (no ALARM:3: the firmware that would print it restarts); the settings and the
        G54..G59 offsets (EEPROM) stay."""
        here = self.position()
        self.frame_mm = self.frame_mm + here
        self.pos = np.zeros(self.n)
        self._active = None
        self._phases = []
        self._queue.clear()
        self._holding = self._cancel = self._hold_done = False
        self._rx.clear()
        self._line = bytearray()
        self._line_flags = 0
        self._critical = self._sleep = self._busy_line = self._reset_after_line = False
        self.alarm = None
        self.state = "Alarm" if self.settings[22] else "Idle"
        self._main = self._after_reset(None, False)
        self._wait = None
        self._step_main()

    def _after_reset(self, alarm, executing):
        if alarm is not None:
            self.state = "Alarm"
            self.alarm = alarm
            self._print(f"ALARM:{alarm}")
            yield from self._delay(ALARM_DELAY_S, rt=False)
        if executing:
            self._print("ok")
        self._rt_status = self._rt_hold = self._rt_start = self._rt_jog_cancel = False
        self._ovr = [100, 100, 100]
        self._wco_counter = self._ovr_counter = 0
        self._gc_init()
        self._print("")
        self._print(BANNER)
        if self.state == "Alarm":
            self._print(MSG_UNLOCK)
        else:
            self.state = "Idle"
            yield from self._startup_lines()
        yield from self._main_loop()

    def _startup_lines(self):
        for s in self.startup_lines:
            if s:
                st = yield from self._gcode(s)
                self._print(f">{s}:" + ("ok" if st == 0 else f"error:{st}"))

    # ---------------------------------------------------------------- status
    def state_name(self) -> str:
        """The state as a status report names it (``Idle``, ``Run``, ``Hold:0`` ...)."""
        if self._sleep:
            return "Sleep"
        if self.state == "Hold":
            return "Hold:0" if self._hold_done else "Hold:1"
        return self.state

    def status_line(self) -> str:
        """A ``<State|...>`` report now (advances GRBL's WCO / Ov refresh counters)."""
        st = self.state_name()
        p = self.position()
        wco = self.wco()
        mask = int(self.settings[10])
        parts = [st]
        if mask & 1:
            parts.append("MPos:" + self._units(p))
        else:
            parts.append("WPos:" + self._units(p - wco))
        if mask & 2:
            parts.append(f"Bf:{PLANNER_BLOCKS - self._planner_blocks()},{RX_BUFFER_BYTES - len(self._rx)}")
        inch = bool(self.settings[13])
        feed = self.speed_per_min() / (MM_PER_INCH if inch else 1.0)
        parts.append(f"FS:{_fmt(feed, 1 if inch else 0)},{_fmt(self.gc['speed'], 0)}")
        if self._probe_pin(p):
            parts.append("Pn:P")
        busy = self.state in ("Run", "Hold", "Jog", "Home")
        if self._wco_counter > 0:
            self._wco_counter -= 1
        else:
            self._wco_counter = (WCO_REFRESH_BUSY if busy else WCO_REFRESH_IDLE) - 1
            if self._ovr_counter == 0:
                self._ovr_counter = 1
            parts.append("WCO:" + self._units(wco))
        if self._ovr_counter > 0:
            self._ovr_counter -= 1
        else:
            self._ovr_counter = (OVR_REFRESH_BUSY if busy else OVR_REFRESH_IDLE) - 1
            ov = "Ov:" + ",".join(str(v) for v in self._ovr)
            spindle = {3: "S", 4: "C"}.get(self.gc["spindle"], "")
            flood = "F" if self.gc["coolant"] == 8 else ""
            parts.append(ov + (f"|A:{spindle}{flood}" if spindle or flood else ""))
        return "<" + "|".join(parts) + ">"

    # ---------------------------------------------------------------- probe pin
    def _abc_rad(self, p) -> np.ndarray:
        abc = np.zeros(3)
        for i, a in enumerate(self.axes):
            if a in "ABC":
                abc["ABC".index(a)] = math.radians(p[i])
        return abc

    def _model_xyz(self, p) -> np.ndarray:
        """The tip centre (mm, the machine model's frame) at machine position ``p``: ``p + frame - J``."""
        return np.asarray(p, float)[:3] + self.frame_mm[:3] - self.tool_offset_mm

    def _contact_now(self, p) -> bool:
        f = getattr(self.machine, "in_contact", None)
        if callable(f):
            q = np.asarray(p, float) + self.frame_mm
            return bool(f(self._model_xyz(p) * 1e-3, self._abc_rad(q)))
        return self._contact and self._active is None

    def _probe_pin(self, p=None) -> bool:
        p = self.position() if p is None else p
        return self._contact_now(p) != bool(self.settings[6])

    # ---------------------------------------------------------------- $ commands
    def _system(self, line: str):
        st = self.state
        c = line[1:2]
        if line == "$":
            self._print("[HLP:$$ $# $G $I $N $x=val $Nx=line $J=line $SLP $C $X $H ~ ! ? ctrl-x]")
            return 0
        if c == "J":
            if st not in ("Idle", "Jog"):
                return 8
            if line[2:3] != "=":
                return 3
            return (yield from self._gcode(line[3:], jog=True))
        if c in ("$", "G", "C", "X"):
            if len(line) != 2:
                return 3
            if c == "$":
                if st in ("Run", "Hold"):
                    return 8
                for x in self.settings_lines():
                    self._print(x)
            elif c == "G":
                self._print(self._gc_report())
            elif c == "C":
                if st == "Check":
                    self._print("[MSG:Disabled]")
                    self._reset_after_line = True
                else:
                    if st != "Idle":
                        return 8
                    self.state = "Check"
                    self._print("[MSG:Enabled]")
            elif c == "X" and st == "Alarm":
                self._print("[MSG:Caution: Unlocked]")
                self.state = "Idle"
                self.alarm = None
            return 0
        if st not in ("Idle", "Alarm"):
            return 8
        if c == "#":
            if len(line) != 2:
                return 3
            for k in range(8):
                name = {6: "G28", 7: "G30"}.get(k, f"G{54 + k}")
                self._print(f"[{name}:{self._units(self.coord_data[k])}]")
            self._print(f"[G92:{self._units(self.g92)}]")
            self._print(f"[TLO:{self._units([self.tlo])}]")
            self._print(self._prb_report())
            return 0
        if c == "H":
            if not self.settings[22]:
                return 5
            if len(line) != 2:
                return 3
            yield from self._home()
            return 0
        if c == "S":
            if line != "$SLP":
                return 3
            self._print("ok")
            self._print("[MSG:Sleeping]")
            self.state = "Sleep"
            self._sleep = True
            self._busy_line = False
            while True:                     # asleep until a reset; status reports still answered
                yield {"cond": lambda: False}
        if c == "I":
            if len(line) == 2:
                self._print(f"[VER:{VERSION}.{BUILD_DATE}:{self.build_info}]")
                self._print(f"[OPT:V,{PLANNER_BLOCKS},{RX_BUFFER_BYTES}]")
                if self.n > 3:          # grblHAL names its axes; GRBL 1.1 has X, Y, Z only
                    self._print(f"[AXS:{self.n}:{self.axes}]")
                return 0
            if line[2] != "=":
                return 3
            self.build_info = line[3:]
            return 0
        if c == "R":
            if not (line.startswith("$RST=") and len(line) == 6 and line[5] in "$#*"):
                return 3
            self._restore(line[5])
            self._print("[MSG:Restoring defaults]")
            self._reset_after_line = True
            return 0
        if c == "N":
            if len(line) == 2:
                for k, s in enumerate(self.startup_lines):
                    self._print(f"$N{k}={s}")
                return 0
            if st != "Idle":
                return 8
            err, n, i = _number_then_equals(line, 2)
            if err:
                return err
            block = line[i:]
            status = yield from self._gcode(block)
            if status:
                return status
            k = math.trunc(n)
            if 0 <= k < N_STARTUP_LINES:
                self.startup_lines[k] = block
            return 0
        err, n, i = _number_then_equals(line, 1)
        if err:
            return err
        v, j = _read_float(line, i)
        if v is None:
            return 2
        if j != len(line) or n > 255:
            return 3
        return self._store_setting(n, v)

    def _gc_report(self) -> str:
        g = self.gc
        m = g["motion"]
        motion = f"G{m:.1f}" if m != int(m) else f"G{int(m)}"
        words = [motion, f"G{54 + g['coord']}", f"G{17 + g['plane']}", "G20" if g["inch"] else "G21",
                 "G91" if g["incremental"] else "G90", "G93" if g["inverse_time"] else "G94",
                 f"M{g['spindle']}", f"M{g['coolant']}", f"T{g['tool']}"]
        inch = g["inch"]
        feed = g["feed"] / (MM_PER_INCH if inch else 1.0)
        return f"[GC:{' '.join(words)} F{_fmt(feed, 1 if inch else 0)} S{_fmt(g['speed'], 0)}]"

    def _prb_report(self) -> str:
        return f"[PRB:{self._units(self.probe_pos)}:{1 if self.probe_ok else 0}]"

    def _home(self):
        self.state = "Home"
        # the switches are where they always were: the homing moves run in the machine model's frame
        self.pos = self.position() + self.frame_mm
        self.frame_mm = np.zeros(self.n)
        target = np.array(self.config.home, dtype=float)
        seek = self.settings[25]
        z_first = self.pos.copy()
        z_first[2] = target[2]
        for goal in (z_first, target):
            b = self._make_block(self.position(), goal, seek, kind="home")
            if b.length > 0:
                self._queue.append(b)
                self._cycle_start()
                yield from self._sync()
        self.pos = target.copy()
        self.gc_pos = self.pos.copy()
        self.state = "Idle"
        self.alarm = None
        yield from self._startup_lines()

    # ---------------------------------------------------------------- G-code
    def _gcode(self, line: str, jog: bool = False):
        """``gc_execute_line``: parse, check as GRBL does, execute. Returns the status code."""
        n = self.n
        words = {}                 # value words
        axis = {}                  # axis words, mm / deg as written
        cmd_groups = set()
        gb = dict(self.gc)         # the block's modal state
        nonmodal = None
        nonmodal_mant = 0
        axis_command = None        # "motion", "nonmodal", "tlo"
        if jog:
            gb["motion"] = 1.0
            gb["inverse_time"] = False
        i = 0
        while i < len(line):
            letter = line[i]
            if not ("A" <= letter <= "Z"):
                return 1
            value, j = _read_float(line, i + 1)
            if value is None:
                return 2
            i = j
            iv = math.trunc(value) % 256
            mant = round(100 * (value - iv)) % 65536
            if letter == "G":
                if iv in (10, 28, 30, 92) or iv in (4, 53):
                    if iv in (10, 28, 30, 92) and mant == 0:
                        if axis_command:
                            return 24
                        axis_command = "nonmodal"
                    group = 0
                    nonmodal = iv
                    if iv in (28, 30, 92):
                        if mant not in (0, 10):
                            return 20
                        nonmodal_mant = mant
                        mant = 0
                elif iv in (0, 1, 2, 3, 38, 80):
                    if iv != 80:
                        if axis_command:
                            return 24
                        axis_command = "motion"
                    group = 1
                    if iv == 38:
                        if mant not in (20, 30, 40, 50):
                            return 20
                        gb["motion"] = 38 + mant / 100
                        mant = 0
                    else:
                        gb["motion"] = float(iv)
                elif iv in (17, 18, 19):
                    group = 2
                    gb["plane"] = iv - 17
                elif iv in (90, 91):
                    if mant == 0:
                        group = 3
                        gb["incremental"] = iv == 91
                    else:
                        group = 4
                        if mant != 10 or iv == 90:
                            return 20
                        mant = 0
                elif iv in (93, 94):
                    group = 5
                    gb["inverse_time"] = iv == 93
                elif iv in (20, 21):
                    group = 6
                    gb["inch"] = iv == 20
                elif iv == 40:
                    group = 7
                elif iv in (43, 49):
                    group = 8
                    if axis_command:
                        return 24
                    axis_command = "tlo"
                    if iv == 43 and mant != 10:
                        return 20
                    gb["tlo_mode"] = "cancel" if iv == 49 else "dynamic"
                    mant = 0
                elif 54 <= iv <= 59:
                    group = 12
                    gb["coord"] = iv - 54
                elif iv == 61:
                    group = 13
                    if mant != 0:
                        return 20
                else:
                    return 20
                if mant > 0:
                    return 23
                if ("G", group) in cmd_groups:
                    return 21
                cmd_groups.add(("G", group))
            elif letter == "M":
                if mant > 0:
                    return 23
                if iv in (0, 1, 2, 30):
                    group = 4
                    if iv != 1:
                        gb["flow"] = iv
                elif iv in (3, 4, 5):
                    group = 7
                    gb["spindle"] = iv
                elif iv in (8, 9):
                    group = 8
                    gb["coolant"] = iv
                else:
                    return 20
                if ("M", group) in cmd_groups:
                    return 21
                cmd_groups.add(("M", group))
            elif letter in self.axes:
                if letter in axis:
                    return 25
                axis[letter] = value
            elif letter in "FIJKLNPRST":
                if letter in words:
                    return 25
                if letter == "T" and value > MAX_TOOL_NUMBER:
                    return 38
                if letter in "FNPTS" and value < 0:
                    return 4
                words[letter] = value
            else:
                return 20
        # ---- step 3: checks
        if axis and not axis_command:
            axis_command = "motion"
        if "N" in words and words["N"] > MAX_LINE_NUMBER:
            return 27
        inch = gb["inch"]
        k_in = MM_PER_INCH if inch else 1.0
        if jog:
            if "F" not in words:
                return 22
            feed = words["F"] * k_in
        elif gb["inverse_time"]:
            if axis_command == "motion" and gb["motion"] not in (80.0, 0.0) and "F" not in words:
                return 22
            feed = words.get("F", 0.0)
        elif not self.gc["inverse_time"]:
            feed = words["F"] * k_in if "F" in words else self.gc["feed"]
        else:
            feed = words["F"] * k_in if "F" in words else 0.0
        speed = words.get("S", self.gc["speed"])
        used = set(words)
        if nonmodal == 4:
            if "P" not in words:
                return 28
            used.discard("P")
        plane = [(0, 1, 2), (2, 0, 1), (1, 2, 0)][gb["plane"]]
        vals = {a: v * (k_in if a in "XYZ" else 1.0) for a, v in axis.items()}
        has = np.array([a in vals for a in self.axes])
        xyz = np.array([vals.get(a, 0.0) for a in self.axes])
        if axis_command == "tlo" and gb.get("tlo_mode") == "dynamic" and set(vals) != {"Z"}:
            return 37
        block_coord = self.coord_system.copy()
        if ("G", 12) in cmd_groups and gb["coord"] != self.gc["coord"]:
            block_coord = self.coord_data[gb["coord"]].copy()
        target = self.gc_pos.copy()
        coord_select = None
        store = None
        if nonmodal == 10 and axis_command:
            if not has.any():
                return 26
            if "P" not in words and "L" not in words:
                return 28
            p = math.trunc(words.get("P", 0.0))
            if p > 6:
                return 29
            L = math.trunc(words.get("L", 0.0)) % 256
            if L not in (2, 20) or (L == 2 and "R" in words):
                return 20
            used -= {"L", "P"}
            coord_select = p - 1 if p > 0 else gb["coord"]
            store = self.coord_data[coord_select].copy()
            for i2 in range(n):
                if has[i2]:
                    if L == 20:
                        store[i2] = self.gc_pos[i2] - self.g92[i2] - xyz[i2] - (self.tlo if i2 == 2 else 0.0)
                    else:
                        store[i2] = xyz[i2]
        elif nonmodal == 92 and nonmodal_mant == 0:
            if not has.any():
                return 26
            store = np.where(has, self.gc_pos - block_coord - xyz - np.where(np.arange(n) == 2, self.tlo, 0.0),
                             self.g92)
        else:
            if axis_command != "tlo" and has.any():
                for i2 in range(n):
                    if not has[i2]:
                        continue
                    if nonmodal == 53:
                        target[i2] = xyz[i2]
                    elif gb["incremental"]:
                        target[i2] = self.gc_pos[i2] + xyz[i2]
                    else:
                        target[i2] = xyz[i2] + block_coord[i2] + self.g92[i2] + (self.tlo if i2 == 2 else 0.0)
            if nonmodal in (28, 30) and nonmodal_mant == 0:
                store = self.coord_data[6 if nonmodal == 28 else 7].copy()
                if has.any():
                    store = np.where(has, store, self.gc_pos)
                else:
                    axis_command = None
            if nonmodal == 53 and gb["motion"] not in (0.0, 1.0):
                return 30
        arc = None
        motion = gb["motion"]
        if motion == 80.0:
            if has.any():
                return 31
        elif axis_command == "motion":
            if motion == 0.0:
                if not has.any():
                    axis_command = None
            else:
                if feed == 0.0:
                    return 22
                if motion == 1.0:
                    if not has.any():
                        axis_command = None
                elif motion in (2.0, 3.0):
                    a0, a1, _al = plane
                    if not has.any():
                        return 26
                    if not (has[a0] or has[a1]):
                        return 32
                    x = target[a0] - self.gc_pos[a0]
                    y = target[a1] - self.gc_pos[a1]
                    if "R" in words:
                        used.discard("R")
                        if np.allclose(target, self.gc_pos, rtol=0, atol=0):
                            return 33
                        r = words["R"] * k_in
                        h2 = 4.0 * r * r - x * x - y * y
                        if h2 < 0:
                            return 34
                        h = -math.sqrt(h2) / math.hypot(x, y)
                        if motion == 3.0:
                            h = -h
                        if r < 0:
                            h, r = -h, -r
                        ij = (0.5 * (x - y * h), 0.5 * (y + x * h))
                    else:
                        ijk = [words.get(c, 0.0) * k_in for c in "IJK"]
                        have = ["IJK"[a0] in words, "IJK"[a1] in words]
                        if not any(have):
                            return 35
                        used -= {"I", "J", "K"}
                        ij = (ijk[a0], ijk[a1])
                        tr = math.hypot(x - ij[0], y - ij[1])
                        r = math.hypot(*ij)
                        dr = abs(tr - r)
                        if dr > 0.005 and (dr > 0.5 or dr > 0.001 * r):
                            return 33
                    arc = (ij, r, motion == 2.0)
                else:                              # probing
                    if not has.any():
                        return 26
                    if np.array_equal(target, self.gc_pos):
                        return 33
        used -= {"N", "F"} if jog else {"N", "F", "S", "T"}
        if used:
            return 36
        # ---- step 4: execute
        if jog:
            allowed = {("G", 3), ("G", 6), ("G", 0)}
            if cmd_groups - allowed or nonmodal not in (None, 53):
                return 16
            if self.settings[20] and self._outside(target):
                return 15
            if axis_command == "motion" and not np.array_equal(target, self.gc_pos):
                b = self._make_block(self.gc_pos, target, feed, kind="jog")
                yield from self._wait_planner()
                self._queue.append(b)
                if self.state == "Idle":
                    self._cycle_start()
            self.gc_pos = target
            return 0
        self.gc["line"] = words.get("N", 0)
        self.gc["inverse_time"] = gb["inverse_time"]
        self.gc["feed"] = feed
        self.gc["speed"] = speed
        self.gc["tool"] = math.trunc(words.get("T", self.gc["tool"]))
        self.gc["spindle"] = gb["spindle"]
        self.gc["coolant"] = gb["coolant"]
        if nonmodal == 4:
            yield from self._sync()
            if self.state != "Check":
                yield from self._delay(float(words["P"]))
        self.gc["plane"] = gb["plane"]
        self.gc["inch"] = gb["inch"]
        if axis_command == "tlo":
            self.tlo = 0.0 if gb.get("tlo_mode") == "cancel" else xyz[2]
            self._wco_counter = 0
        if gb["coord"] != self.gc["coord"]:
            self.gc["coord"] = gb["coord"]
            self.coord_system = block_coord
            self._wco_counter = 0
        self.gc["incremental"] = gb["incremental"]
        if nonmodal == 10 and store is not None:
            self.coord_data[coord_select] = store
            if coord_select == self.gc["coord"]:
                self.coord_system = store.copy()
                self._wco_counter = 0
        elif nonmodal in (28, 30) and nonmodal_mant == 0:
            if axis_command:
                yield from self._line_to(target, feed, rapid=True)
            yield from self._line_to(store, feed, rapid=True)
            self.gc_pos = store.copy()
        elif nonmodal in (28, 30) and nonmodal_mant == 10:
            self.coord_data[6 if nonmodal == 28 else 7] = self.gc_pos.copy()
        elif nonmodal == 92 and nonmodal_mant == 0:
            self.g92 = store
            self._wco_counter = 0
        elif nonmodal == 92 and nonmodal_mant == 10:
            self.g92 = np.zeros(n)
            self._wco_counter = 0
        self.gc["motion"] = motion
        if motion != 80.0 and axis_command == "motion":
            if motion in (0.0, 1.0):
                f = feed
                if gb["inverse_time"] and motion == 1.0:     # G93: F is 1/min for the whole block
                    f = feed * float(np.linalg.norm(target - self.gc_pos))
                yield from self._line_to(target, f, rapid=motion == 0.0)
                self.gc_pos = target
            elif motion in (2.0, 3.0):
                yield from self._arc_to(target, arc, plane, feed)
                self.gc_pos = target
            else:
                where = yield from self._probe_cycle(target, feed, motion)
                if where == "target":
                    self.gc_pos = target
                elif where == "system":
                    self.gc_pos = self.position()
        flow = gb.get("flow")
        if flow is not None:
            yield from self._sync()
            if flow == 0:
                if self.state != "Check":
                    self._feed_hold()
            else:
                self.gc.update(motion=1.0, plane=0, incremental=False, inverse_time=False, coord=0,
                               spindle=5, coolant=9)
                self.coord_system = self.coord_data[0].copy()
                self._wco_counter = 0
                self._print("[MSG:Pgm End]")
        return 0

    def _outside(self, target) -> bool:
        """Beyond the soft limits: the machine's travel box, or else GRBL's own ``[-$13x, 0]``."""
        tr = self.config.travel
        for i, v in enumerate(target):
            lo, hi = (-self.settings[130 + i], 0.0) if tr is None else (tr[i] or (-math.inf, math.inf))
            if not (lo - 1e-9 <= v <= hi + 1e-9):
                return True
        return False

    def _planner_blocks(self) -> int:
        """Blocks in the planner, the one executing included."""
        return len(self._queue) + (self._active is not None)

    def _wait_planner(self):
        while self._planner_blocks() >= PLANNER_BLOCKS:
            self._cycle_start()
            yield {"cond": lambda: self._planner_blocks() < PLANNER_BLOCKS}

    def _line_to(self, target, feed, rapid=False, kind="line"):
        """``mc_line``: soft limits, wait for planner room, queue."""
        target = np.asarray(target, dtype=float)
        if self.settings[20] and self._outside(target):
            if self.state == "Run":
                self._feed_hold()
                yield {"cond": lambda: self._active is None or self._hold_done}
            self.pos = self.position()
            self._active = None
            self._phases = []
            self._queue.clear()
            self._holding = False
            yield from self._raise_alarm(2)
        if self.state == "Check":
            return
        yield from self._wait_planner()
        start = self._queue[-1].end if self._queue else (
            self._active.end if self._active is not None else self.pos)
        b = self._make_block(start, target, feed, kind=kind, rapid=rapid)
        if b.length == 0:
            return
        self._queue.append(b)
        if self.state == "Idle":
            self._cycle_start()

    def _arc_to(self, target, arc, plane, feed):
        (ci, cj), r, clockwise = arc
        a0, a1, al = plane
        p0 = self.gc_pos.copy()
        c0, c1 = p0[a0] + ci, p0[a1] + cj
        ang0 = math.atan2(p0[a1] - c1, p0[a0] - c0)
        ang1 = math.atan2(target[a1] - c1, target[a0] - c0)
        sweep = ang1 - ang0
        if clockwise:
            if sweep >= -1e-12:
                sweep -= 2 * math.pi
        elif sweep <= 1e-12:
            sweep += 2 * math.pi
        tol = max(self.settings[12], 1e-6)
        step = 2 * math.acos(max(-1.0, min(1.0, 1 - tol / max(r, 1e-9)))) or abs(sweep)
        nseg = max(1, min(10_000, int(math.ceil(abs(sweep) * r / max(r * step, 1e-9)))))
        for k in range(1, nseg + 1):
            f = k / nseg
            q = p0 + (target - p0) * f
            q[a0] = c0 + r * math.cos(ang0 + sweep * f)
            q[a1] = c1 + r * math.sin(ang0 + sweep * f)
            if k == nseg:
                q = target.copy()
            yield from self._line_to(q, feed)

    def _probe_cycle(self, target, feed, motion):
        """``mc_probe_cycle``; returns where the parser position comes from."""
        if self.state == "Check":
            return "target"
        away = motion in (38.4, 38.5)
        no_error = motion in (38.3, 38.5)
        self.probes += 1
        k = self.probes
        f = self.faults
        if k in f.drop_before_probe:
            self._print(DROP)
            return "none"
        yield from self._sync()
        if k in f.alarm_at_probe:
            yield from self._raise_alarm(int(f.alarm_at_probe[k]))
            return "none"
        self.probe_ok = False
        start = self.position()
        s_trig, report = self._find_trigger(start, target, away)
        if s_trig == "initial":
            yield from self._raise_alarm(4)
            return "none"
        b = self._make_block(start, target, feed, kind="probe")
        b.probe = {"s_trig": s_trig, "report": report}
        self._queue.append(b)
        self._cycle_start()
        yield {"cond": lambda: self._active is None and not self._queue}
        if b.probe.get("hit"):
            self.probe_ok = True
            self.probe_pos = report
            self._contact = not away
            self.touches.append((True, report[:3].copy()))
        else:
            self._contact = away
            self.touches.append((False, self.position()[:3].copy()))
            if no_error:
                self.probe_pos = self.position()
            else:
                yield from self._raise_alarm(5)
        if k in f.drop_after_probe:
            self._print(DROP)
        self._print(self._prb_report())
        return "system" if self.probe_ok else "target"

    def _find_trigger(self, start, target, away):
        """Where along the move the pin changes: ``(s, report position)``, ``(None, None)``
        for a miss, ``("initial", None)`` when the pin is wrong at the start (ALARM:4)."""
        fr = self.frame_mm            # the machine model's frame: where the machine physically is
        # the tip centre, J from the machine position (the spindle's); a trigger found there goes back by + J
        s_m, t_m = self._model_xyz(start) * 1e-3, self._model_xyz(target) * 1e-3
        back = fr[:3] - self.tool_offset_mm          # machine position = tip centre - back
        rot = self._abc_rad(start + fr)
        d = target - start
        L = float(np.linalg.norm(d))
        if self.settings[6]:              # $6=1: the pin reads active out of contact
            away = not away
        has_contact = callable(getattr(self.machine, "in_contact", None))
        if not away:
            if has_contact and self._contact_now(start):
                return "initial", None
            trig, p_m = self.machine.probe_move(s_m, t_m, rot)
            p = np.asarray(p_m, dtype=float).reshape(3) * 1e3 - back
            if bool(trig) and np.allclose(p, start[:3], rtol=0, atol=1e-9):
                return "initial", None
            if not trig:
                return None, None
        else:
            u3 = (t_m - s_m) / np.linalg.norm(t_m - s_m)
            c0 = self._contact_now(start) if has_contact else \
                bool(self.machine.probe_move(s_m, s_m + u3 * 1e-9, rot)[0])
            if not c0:
                return "initial", None
            trig, p_m = self.machine.probe_move(t_m, s_m, rot)    # the exit, seen from the end
            p = np.asarray(p_m, dtype=float).reshape(3) * 1e3 - back
            if trig and np.allclose(p, target[:3], rtol=0, atol=1e-9):
                return None, None                                   # never leaves the material
            if not trig:
                p = start[:3].copy()
        u = d / L
        s = float(np.clip((p - start[:3]) @ u[:3], 0.0, L))
        rep = start + u * s
        rep[:3] = p
        return s, rep


def _number_then_equals(line: str, i: int):
    """``N=`` at ``line[i:]`` (``$N0=...``, ``$110=...``): (error status or 0, N, index after =)."""
    n, j = _read_float(line, i)
    if n is None:
        return 2, None, i
    if line[j:j + 1] != "=":
        return 3, None, j
    return 0, n, j + 1


def _read_float(s: str, i: int):
    """GRBL's ``read_float`` at ``s[i:]``: sign, digits, one point. Returns (value, next index)."""
    j = i
    if j < len(s) and s[j] in "+-":
        j += 1
    digits = point = 0
    k = j
    while k < len(s):
        ch = s[k]
        if "0" <= ch <= "9":
            digits += 1
        elif ch == "." and not point:
            point = 1
        else:
            break
        k += 1
    if not digits:
        return None, i
    return float(s[i:k]), k


# ---------------------------------------------------------------------------
# running it in real time, on ports


_POWER_CYCLE = object()   # an EmulatorRunner inbox item: a hardware reset, not bytes


class EmulatorRunner:
    """The firmware's clock: drives one :class:`GrblEmulator` on a thread.

    Emulated time runs ``time_scale`` times faster than the wall clock (1:
    a real machine's pace; tests use more so that motion stays short).
    Ports (:class:`TcpServer` connections, :class:`PtyServer`) hand it the
    bytes they receive; its output goes to the port that sent the latest
    byte, as a controller with several streams answers the active one.
    """

    def __init__(self, emulator: GrblEmulator, time_scale: float = 1.0, clock=time.monotonic):
        from core.exceptions import ConfigError

        if not (isinstance(time_scale, (int, float)) and math.isfinite(time_scale) and time_scale > 0):
            raise ConfigError(f"time scale {time_scale!r}: expected a positive number")
        if getattr(emulator, "_runner", None) is not None:
            raise ConfigError("this emulator already has a runner (one firmware, one clock)")
        emulator._runner = self
        self.emulator = emulator
        self.time_scale = float(time_scale)
        self.clock = clock
        self._t0 = clock()
        self._e0 = emulator.now
        self._lock = threading.Lock()
        self._wake = threading.Event()
        self._inbox: deque = deque()
        self._active_port = None
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self._users = 0
        self._quiet = emulator.quiet()
        self._greeting = emulator.greeting()

    @staticmethod
    def of(emulator_or_runner, time_scale: float = 1.0) -> "EmulatorRunner":
        if isinstance(emulator_or_runner, EmulatorRunner):
            return emulator_or_runner
        r = getattr(emulator_or_runner, "_runner", None)
        return r if r is not None else EmulatorRunner(emulator_or_runner, time_scale)

    def emulated_now(self) -> float:
        return self._e0 + (self.clock() - self._t0) * self.time_scale

    def send(self, port, data: bytes) -> None:
        """Bytes from a port (thread-safe, never waits for the firmware)."""
        with self._lock:
            self._inbox.append((port, bytes(data)))
        self._wake.set()

    def power_cycle(self, port) -> None:
        """A hardware reset (:meth:`GrblEmulator.power_cycle`) on the firmware's thread, in turn with
        the bytes received; its banner goes to ``port`` (thread-safe, never waits)."""
        with self._lock:
            self._inbox.append((port, _POWER_CYCLE))
        self._wake.set()

    def greeting(self) -> list[str]:
        """What a new connection reads first (as of the firmware's last step)."""
        return list(self._greeting)

    def quiet(self) -> bool:
        """Nothing in progress and nothing waiting (as of the firmware's last step)."""
        with self._lock:
            waiting = bool(self._inbox)
        return self._quiet and not waiting

    def forget(self, port) -> None:
        with self._lock:
            if self._active_port is port:
                self._active_port = None

    def start(self) -> "EmulatorRunner":
        with self._lock:
            self._users += 1
            if self._thread is None or not self._thread.is_alive():
                self._stop.clear()
                self._thread = threading.Thread(target=self._run, name="grbl-firmware", daemon=True)
                self._thread.start()
        return self

    def stop(self) -> None:
        with self._lock:
            self._users -= 1
            last = self._users <= 0
        if last:
            self._stop.set()
            self._wake.set()
            if self._thread is not None:
                self._thread.join(timeout=2.0)

    def _output(self, port, out) -> None:
        chunk = []
        for line in out:
            if line == DROP:
                if chunk and port is not None:
                    port.write(("".join(x + "\r\n" for x in chunk)).encode("latin-1"))
                chunk = []
                if port is not None:
                    port.drop()
                    self.forget(port)
                port = None
                continue
            chunk.append(line)
        if chunk and port is not None:
            port.write(("".join(x + "\r\n" for x in chunk)).encode("latin-1"))

    def _run(self) -> None:
        """The firmware thread: the only one that touches the emulator once started."""
        emu = self.emulator
        while not self._stop.is_set():
            self._wake.clear()                # a send() from now on wakes the wait below
            while True:                       # one received chunk at a time, outputs as they come
                with self._lock:
                    item = self._inbox.popleft() if self._inbox else None
                    if item is not None and item[0] is not None:
                        self._active_port = item[0]
                    port = self._active_port
                try:
                    emu.advance_to(self.emulated_now())
                    if item is not None:
                        if item[1] is _POWER_CYCLE:
                            emu.power_cycle()
                        else:
                            emu.receive(item[1])
                except Exception as e:          # never let the firmware thread die
                    emu.internal_errors.append(f"{type(e).__name__}: {e}")
                self._output(port, emu.take_output())
                if item is None:
                    break
            self._quiet = emu.quiet()
            self._greeting = emu.greeting()
            te = emu.next_event()
            wait = 0.02
            if te is not None:
                wait = min(wait, max(0.0, (te - self.emulated_now()) / self.time_scale))
            self._wake.wait(timeout=max(wait, 0.0005))


class _TcpPort:
    """One TCP connection: bytes in go to the runner, bytes out are buffered here."""

    MAX_OUT = 1 << 20

    def __init__(self, conn):
        self.conn = conn
        self.out = bytearray()
        self.lock = threading.Lock()
        self.dropped = False       # a fault: close after what was answered before it
        self.overflow = False      # the client does not read: close at once

    def write(self, data: bytes) -> None:
        with self.lock:
            if not self.out:               # send now what the socket takes; the session sends the rest
                try:
                    data = data[self.conn.send(data):]
                except (BlockingIOError, InterruptedError):
                    pass
                except OSError:
                    self.dropped = True
                    return
            if len(self.out) + len(data) > self.MAX_OUT:
                self.overflow = True       # a client that does not read is let go
                return
            self.out += data

    def drop(self) -> None:
        self.dropped = True


class TcpServer:
    """Serve a :class:`GrblEmulator` on a TCP port, one client at a time.

    Listens on ``host`` (127.0.0.1 by default); ``port=0`` picks a free port
    (see :attr:`port`). What a new client meets, ``on_connect``:

    - ``"greet"`` (default): the banner (and the lock message in alarm), the
      machine's state kept: a network controller's greeting to each new client
      (Grbl_Esp32's ENABLE_TELNET_WELCOME_MSG, on in its config.h), not a reset;
    - ``"reset"``: a hardware reset first (:meth:`GrblEmulator.power_cycle`:
      the machine position 0 where the machine stands, in alarm when homing is
      enabled, the banner): GRBL 1.1h on an Arduino, whose board resets when a
      host opens its serial port (DTR), behind a bridge that opens the port per
      client;
    - ``"silent"``: nothing printed, the state kept: GRBL behind a bridge that
      holds its port open (GRBL prints its banner only on a reset).

    Several clients: the first is served; another one connecting meanwhile
    reads ``[MSG:vmt emulator busy: one client at a time]`` and is closed
    (:attr:`refused` counts them). A client that sends nothing for
    ``idle_timeout_s`` while the machine has nothing in progress reads
    ``[MSG:vmt emulator: no input for N s, closing]`` and is closed, so an
    idle connection never blocks the next client.
    """

    ON_CONNECT = ("greet", "reset", "silent")

    def __init__(self, emulator, host: str = "127.0.0.1", port: int = 0, *,
                 time_scale: float = 1.0, idle_timeout_s: float = 300.0, on_connect: str = "greet"):
        if on_connect not in self.ON_CONNECT:
            from core.exceptions import ConfigError

            raise ConfigError(f"on_connect {on_connect!r}: expected one of {', '.join(self.ON_CONNECT)}")
        self.on_connect = on_connect
        self.runner = EmulatorRunner.of(emulator, time_scale)
        self.emulator = self.runner.emulator
        self.idle_timeout_s = float(idle_timeout_s)
        self.sock = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
        self.sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        self.sock.bind((host, port))
        self.sock.listen(8)
        self.sock.settimeout(0.05)
        self.host, self.port = self.sock.getsockname()[:2]
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self._busy = threading.Lock()
        self._sessions: list[threading.Thread] = []
        self.connections = 0      # clients served
        self.refused = 0          # clients turned away while another was served
        self.timeouts = 0         # clients closed for idling

    @property
    def url(self) -> str:
        return f"grbl://{self.host}:{self.port}"

    def start(self) -> "TcpServer":
        self.runner.start()
        self._thread = threading.Thread(target=self.serve, name="grbl-tcp", daemon=True)
        self._thread.start()
        return self

    def serve(self) -> None:
        """Accept clients until :meth:`stop`."""
        while not self._stop.is_set():
            try:
                conn, _ = self.sock.accept()
            except (socket.timeout, OSError):
                continue
            try:
                if not self._busy.acquire(timeout=0.5):    # the last client may be closing just now
                    self.refused += 1
                    self._refuse(conn)
                    continue
                self.connections += 1
                t = threading.Thread(target=self._session, args=(conn,), name="grbl-client", daemon=True)
                self._sessions.append(t)
                t.start()
            except Exception:        # pragma: no cover - keep accepting whatever happens
                try:
                    conn.close()
                except OSError:
                    pass
        try:
            self.sock.close()
        except OSError:  # pragma: no cover
            pass

    @staticmethod
    def _refuse(conn) -> None:
        try:
            conn.settimeout(1.0)
            conn.sendall(b"[MSG:vmt emulator busy: one client at a time]\r\n")
        except OSError:
            pass
        finally:
            try:
                conn.close()
            except OSError:  # pragma: no cover
                pass

    def _session(self, conn) -> None:
        port = _TcpPort(conn)
        try:
            conn.setblocking(False)
            if self.on_connect == "greet":
                port.write(("".join(x + "\r\n" for x in self.runner.greeting())).encode("latin-1"))
            elif self.on_connect == "reset":
                self.runner.power_cycle(port)
            last_in = time.monotonic()
            while not self._stop.is_set() and not port.dropped and not port.overflow:
                with port.lock:
                    pending = bool(port.out)
                r, w, _ = select.select([conn], [conn] if pending else [], [], 0.02)
                if w:
                    with port.lock:
                        try:
                            n = conn.send(port.out)
                            del port.out[:n]
                        except (BlockingIOError, InterruptedError):
                            pass
                if r:
                    try:
                        data = conn.recv(4096)
                    except (BlockingIOError, InterruptedError):
                        data = None
                    if data == b"":
                        return
                    if data:
                        last_in = time.monotonic()
                        self.runner.send(port, data)
                if time.monotonic() - last_in > self.idle_timeout_s and self.runner.quiet():
                    self.timeouts += 1
                    msg = f"[MSG:vmt emulator: no input for {self.idle_timeout_s:g} s, closing]\r\n"
                    try:
                        conn.setblocking(True)
                        conn.settimeout(1.0)
                        conn.sendall(bytes(port.out) + msg.encode())
                    except OSError:
                        pass
                    return
            if port.dropped and not port.overflow:   # a fault: send what was answered before it
                with port.lock:
                    try:
                        conn.setblocking(True)
                        conn.settimeout(0.2)
                        conn.sendall(bytes(port.out))
                    except OSError:
                        pass
        except OSError:
            return
        finally:
            self.runner.forget(port)
            try:
                conn.close()
            except OSError:  # pragma: no cover
                pass
            self._busy.release()

    def stop(self) -> None:
        self._stop.set()
        if self._thread is not None:
            self._thread.join(timeout=2.0)
        for t in self._sessions:
            t.join(timeout=2.0)
        self.runner.stop()

    def __enter__(self):
        return self.start()

    def __exit__(self, *exc):
        self.stop()


class _PtyPort:
    def __init__(self, fd):
        self.fd = fd

    def write(self, data: bytes) -> None:
        try:
            os.write(self.fd, data)
        except OSError:        # nobody reading and the line is full: the bytes are gone, as on a wire
            pass

    def drop(self) -> None:    # a serial line cannot be dropped
        pass


class PtyServer:
    """Serve a :class:`GrblEmulator` on a pseudo-terminal: :attr:`path` is the serial port."""

    def __init__(self, emulator, *, time_scale: float = 1.0):
        import pty
        import tty

        self.runner = EmulatorRunner.of(emulator, time_scale)
        self.emulator = self.runner.emulator
        self.master, self.slave = pty.openpty()
        tty.setraw(self.slave)      # no echo, no line editing: a plain 8-bit serial line
        os.set_blocking(self.master, False)
        self.path = os.ttyname(self.slave)
        self._port = _PtyPort(self.master)
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self._reset_on_open = False     # a power cycle armed for the host's next opening (power_cycle)

    @property
    def url(self) -> str:
        return f"serial://{self.path}"

    def power_cycle(self) -> None:
        """A hardware reset of the controller when the host next opens its port, as an Arduino's is
        (DTR): it happens at the host's first bytes, once the host has opened the line and set it up,
        and its banner comes before their answers. Made at once, the banner would sit in the line
        before the host opened it, and the host's set-up (``tcsetattr`` with TCSAFLUSH, as
        ``tty.setraw`` does) discards it as a real line's stale bytes: a test that read it or not
        by the threads' timing (session 31)."""
        self._reset_on_open = True

    def start(self) -> "PtyServer":
        self.runner.start()
        self._thread = threading.Thread(target=self.serve, name="grbl-pty", daemon=True)
        self._thread.start()
        return self

    def serve(self) -> None:
        while not self._stop.is_set():
            try:
                r, _, _ = select.select([self.master], [], [], 0.05)
                if not r:
                    continue
                data = os.read(self.master, 4096)
            except (OSError, ValueError):
                time.sleep(0.05)
                continue
            if data:
                if self._reset_on_open:   # the host opened the port: the board resets first (the inbox keeps
                    self._reset_on_open = False   # the order: banner, then the answers to these bytes)
                    self.runner.power_cycle(self._port)
                self.runner.send(self._port, data)

    def stop(self) -> None:
        self._stop.set()
        if self._thread is not None:
            self._thread.join(timeout=2.0)
        self.runner.stop()
        for fd in (self.master, self.slave):
            try:
                os.close(fd)
            except OSError:  # pragma: no cover
                pass

    def __enter__(self):
        return self.start()

    def __exit__(self, *exc):
        self.stop()
