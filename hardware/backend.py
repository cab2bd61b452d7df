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

#: GRBL alarm codes the adapter names (GRBL 1.1 / grblHAL / FluidNC agree).
ALARMS = {
    1: "hard limit triggered",
    2: "soft limit: target outside machine travel",
    3: "reset while in motion",
    4: "probe already triggered before the probing move",
    5: "probe did not contact within the programmed travel",
    6: "homing failed: reset during cycle",
    7: "homing failed: door opened",
    8: "homing failed: pull-off did not clear the switch",
    9: "homing failed: switch not found",
    10: "homing failed: second switch",
}


@dataclass(frozen=True)
class ProbeResult:
    """Outcome of one probing move.

    Attributes
    ----------
    status : core.touches.ProbeStatus or str
        ``ok`` (triggered) or ``no_trigger`` (the move ended without contact).
    pos_m : (3,) float
        Machine-reported stylus-tip centre at the trigger, machine frame R, m;
        where the move ended when nothing triggered.
    alarm : int or None
        Controller alarm raised by this move (5 for a G38.2 miss), ``None`` if none.
        The touch is still a valid record; the campaign stops after logging it.
    extra_axes : tuple of float
        Further axes of the controller's probe report (A, B, C, ... in the
        controller's units), empty when it reports only X, Y, Z.
    """

    status: str
    pos_m: np.ndarray
    alarm: int | None = None
    extra_axes: tuple = field(default=())

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
        it a miss is a ``no_trigger`` with ``alarm=5`` (G38.2).
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
            raise HardwareError(f"ALARM:4 ({ALARMS[4]})")
        self._pos = pos.copy()
        if triggered:
            return ProbeResult(ProbeStatus.OK, pos)
        return ProbeResult(ProbeStatus.NO_TRIGGER, pos, alarm=None if allow_miss else 5)

    def temperatures_C(self) -> dict[str, float]:
        f = getattr(self.machine, "temperatures_C", None)
        return {str(k): float(v) for k, v in f().items()} if callable(f) else {}

    def close(self) -> None:
        return None
