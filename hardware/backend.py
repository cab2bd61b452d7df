"""The probing backend: what a campaign needs from a machine, real or virtual.

A campaign (:mod:`hardware.campaign`) talks only to this interface, so the
same code drives a live GRBL controller (:class:`hardware.grbl.GrblBackend`)
and the virtual machine in-process (:class:`VirtualBackend`).

All positions at this interface are SI: metres, machine frame R (MCS), the
stylus-tip centre as the machine believes it. Feeds keep the shop unit of
every controller (mm/min) and say so in their names.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Protocol, runtime_checkable

import numpy as np

from core.exceptions import HardwareError
from core.touches import ProbeStatus

#: GRBL 1.1 alarm codes (grblHAL and FluidNC use the same numbers), in our words. The
#: firmware's alarm_codes_en_US.csv and report.h are the source; what to do is in
#: :data:`ALARM_RECOVERY`.
ALARMS = {
    1: "hard limit: a limit switch tripped, the machine stopped at once, its position is likely lost",
    2: "soft limit: the target lies outside the machine travel; stopped before it, position kept",
    3: "reset while in motion: the machine stopped at once, its position is likely lost",
    4: "probe not in the expected state at the start of a probing move "
       "(G38.2/G38.3: already triggered; G38.4/G38.5: not triggered)",
    5: "probe did not contact within the programmed travel (G38.2/G38.4); position kept",
    6: "homing failed: reset during the homing cycle",
    7: "homing failed: safety door opened during the homing cycle",
    8: "homing failed: the pull-off did not clear the limit switch",
    9: "homing failed: limit switch not found within the search distance",
    10: "homing failed: the second switch of a dual axis not found",
}

#: Alarms after which GRBL answers nothing, not even a status report, until a reset
#: (Ctrl-X): it prints ``[MSG:Reset to continue]`` and waits (protocol.c).
CRITICAL_ALARMS = frozenset({1, 2})

#: What each alarm needs before motion, in vmt's options. GRBL keeps its alarm lock
#: (``error:9`` for every G-code line) until ``$X`` (``--unlock``) or ``$H`` (``--home-cycle``);
#: after a critical alarm it first needs a reset (``--reset`` sends Ctrl-X).
ALARM_RECOVERY = {
    1: "clear the limit switch, then re-run with --resume --reset --home-cycle "
       "(GRBL needs a reset first; re-home: the position is likely lost)",
    2: "re-run with --resume --reset --unlock (GRBL needs a reset first, then $X; the position "
       "was kept) after fixing the plan or the limits",
    3: "re-run with --resume --home-cycle (the position is likely lost), or --unlock if it is known",
    4: "move the probe clear of the part, then re-run with --resume --unlock",
    5: "the miss is logged; re-run with --resume --unlock (or probe with --allow-miss)",
    6: "re-run with --resume --home-cycle",
    7: "close the door, then re-run with --resume --home-cycle",
    8: "check the homing switches and pull-off ($27), then re-run with --resume --home-cycle",
    9: "check the homing switches and travel ($130..), then re-run with --resume --home-cycle",
    10: "check the dual-axis homing switches, then re-run with --resume --home-cycle",
}

#: GRBL 1.1 error codes (``error:N``), in our words. The firmware's error_codes_en_US.csv,
#: report.h, gcode.c and system.c are the source; 18 and 19 are unused.
ERRORS = {
    1: "expected command letter: a G-code word has no letter before its value",
    2: "bad number format: a value is missing or not a number",
    3: "invalid statement: '$' command not recognised or not supported",
    4: "negative value where a positive one is expected",
    5: "setting disabled: homing ($H) is not enabled ($22=0)",
    6: "step pulse shorter than 3 microseconds ($0)",
    7: "EEPROM read failed: settings restored to defaults",
    8: "not idle: this '$' command needs the controller idle",
    9: "G-code locked out during alarm or jog",
    10: "soft limits need homing enabled ($20=1 needs $22=1)",
    11: "line overflow: more than 79 characters (spaces removed); the line was not executed",
    12: "a setting makes the step rate exceed the maximum (30 kHz)",
    13: "safety door open",
    14: "build info or startup line too long for the EEPROM; not stored",
    15: "jog target beyond the machine travel; jog ignored",
    16: "invalid jog command: no '=' or a G-code a jog does not allow",
    17: "laser mode needs PWM output",
    20: "unsupported or invalid G-code command in the block",
    21: "two commands of the same modal group in one block",
    22: "feed rate not set",
    23: "the command needs an integer value",
    24: "two commands that both use axis words in one block",
    25: "a word repeated in the block",
    26: "no axis words for a command (or motion mode) that needs them",
    27: "line number out of range",
    28: "a required value word (P, L) is missing",
    29: "G59.x work coordinate systems are not supported",
    30: "G53 is allowed only with G0 and G1",
    31: "axis words in a block where no command uses them",
    32: "G2/G3 arc without an axis word in the selected plane",
    33: "invalid motion target (a probing move of zero length, an arc end off the circle)",
    34: "arc radius error: R too small for the distance to the end point",
    35: "G2/G3 arc without an offset (I, J, K) in the selected plane",
    36: "unused value words in the block",
    37: "G43.1 dynamic tool length offset not on the tool length axis (Z)",
    38: "tool number above the supported maximum (255)",
}


def describe_alarm(code: int) -> str:
    """``ALARM:n (meaning): what to do`` for a message to the user."""
    what = ALARMS.get(code, "unknown alarm (see the controller's manual)")
    todo = ALARM_RECOVERY.get(code, "clear the cause, then re-run with --resume --unlock")
    return f"ALARM:{code} ({what}): {todo}"


def describe_error(code: int) -> str:
    """``error:n (meaning)``."""
    return f"error:{code} ({ERRORS.get(code, 'unknown error: see the controller manual')})"


@dataclass(frozen=True)
class ProbeResult:
    """Outcome of one probing move.

    Attributes
    ----------
    status : core.touches.ProbeStatus or str
        ``ok`` (triggered), ``no_trigger`` (the move ended without contact) or
        ``early_trigger`` (the probe was triggered before the move: GRBL's ALARM:4).
    pos_m : (3,) float
        Machine-reported stylus-tip centre at the trigger, machine frame R, m;
        where the move ended when nothing triggered.
    alarm : int or None
        Controller alarm raised by this move (5 for a G38.2 miss, 4 for a probe
        triggered before it), ``None`` if none.
        The touch is still a valid record; the campaign stops after logging it.
    extra_axes : tuple of float
        Further axes of the controller's probe report (A, B, C, ... in the
        controller's units), empty when it reports only X, Y, Z.
    reported_mm : (3,) float or None
        X, Y, Z as the controller reported them, mm (GRBL's ``[PRB:...]``
        numbers), ``None`` for a backend that measures in metres: the log
        writes these, so a report's ``-3.937`` is not logged
        ``-3.9369999999999994`` after the trip through metres.
    reported_decimals : int or None
        The most decimals the controller printed ``reported_mm`` with (GRBL: 3), the step its log
        declares for X_mm, Y_mm, Z_mm (session 33); None with ``reported_mm`` None.
    """

    status: str
    pos_m: np.ndarray
    alarm: int | None = None
    extra_axes: tuple = field(default=())
    reported_mm: np.ndarray | None = None
    reported_decimals: int | None = None

    @property
    def triggered(self) -> bool:
        return self.status == ProbeStatus.OK


@runtime_checkable
class ProbingBackend(Protocol):
    """A machine that can move, probe and report where it is.

    Every method may raise :class:`core.exceptions.HardwareError` (lost
    connection, controller alarm, garbage in place of an answer).
    """

    #: Free text naming the machine (written to the log's ``machine`` key).
    name: str

    def start(self, *, unlock: bool = False, home: bool = False) -> None:
        """Make the machine ready; ``unlock`` / ``home`` only on the user's word."""

    def position_m(self) -> np.ndarray:
        """(3,) current stylus-tip centre, machine frame R, m (the machine's own report)."""

    def move(self, target_m, feed_mm_min: float, rot_rad=None) -> None:
        """Move linearly (feed move, never rapid) to ``target_m`` (3,), machine frame, m.

        ``rot_rad`` (3,) A, B, C in rad, or ``None`` to leave rotary axes alone.
        """

    def probe(self, target_m, feed_mm_min: float, *, allow_miss: bool = False) -> ProbeResult:
        """Probe linearly from the current position towards ``target_m`` (3,), m.

        ``allow_miss``: a miss is a plain ``no_trigger`` (GRBL G38.3); without
        it a miss is a ``no_trigger`` with ``alarm=5`` (G38.2). A probe found
        triggered before the move (GRBL's ``ALARM:4``) is an ``early_trigger``
        with ``alarm=4``.
        """

    def temperatures_C(self) -> dict[str, float]:
        """Temperature sensors ``{name: degC}``; empty when the machine has none."""

    def close(self) -> None:
        """Release the connection."""


class VirtualBackend:
    """A virtual machine in-process, behind :class:`ProbingBackend`.

    Parameters
    ----------
    machine : object
        Anything with ``probe_move(start_m, target_m, rot_rad) -> (triggered, pos_m)``
        (``sim.probe.VirtualMachine``, :class:`hardware.scene.SimpleScene`).
        If it also has ``temperatures_C()``, its sensors are read at each touch.
    home_m : (3,) float
        Where the machine starts, machine frame, m.
    name : str
        Free text for the log.
    """

    def __init__(self, machine, home_m=(0.0, 0.0, 0.0), name: str = "virtual"):
        if not callable(getattr(machine, "probe_move", None)):
            raise HardwareError(f"virtual backend: {type(machine).__name__} has no probe_move method")
        self.machine = machine
        self.name = name
        self._pos = np.asarray(home_m, dtype=float).copy()
        self._rot = np.zeros(3)

    def start(self, *, unlock: bool = False, home: bool = False) -> None:
        return None

    def position_m(self) -> np.ndarray:
        return self._pos.copy()

    def move(self, target_m, feed_mm_min: float, rot_rad=None) -> None:
        self._pos = np.asarray(target_m, dtype=float).copy()
        if rot_rad is not None:
            self._rot = np.asarray(rot_rad, dtype=float).copy()

    def probe(self, target_m, feed_mm_min: float, *, allow_miss: bool = False) -> ProbeResult:
        start = self._pos.copy()
        target = np.asarray(target_m, dtype=float)
        if np.allclose(start, target, rtol=0, atol=1e-12):
            raise HardwareError("probing move of zero length")
        triggered, pos = self.machine.probe_move(start, target, self._rot.copy())
        pos = np.asarray(pos, dtype=float).reshape(3)
        if triggered and np.allclose(pos, start, rtol=0, atol=1e-12):
            raise HardwareError(describe_alarm(4))
        self._pos = pos.copy()
        if triggered:
            return ProbeResult(ProbeStatus.OK, pos)
        return ProbeResult(ProbeStatus.NO_TRIGGER, pos, alarm=None if allow_miss else 5)

    def temperatures_C(self) -> dict[str, float]:
        f = getattr(self.machine, "temperatures_C", None)
        return {str(k): float(v) for k, v in f().items()} if callable(f) else {}

    def close(self) -> None:
        return None
