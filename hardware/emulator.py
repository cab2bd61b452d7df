"""The virtual machine behind the GRBL protocol, on a TCP port or a pty.

``vmt machine serve`` runs :class:`GrblEmulator` over :class:`TcpServer`
(127.0.0.1 unless told otherwise) and optionally :class:`PtyServer`, so the
adapter, and anybody's sender software, can be tested against a machine
whose errors are known.

The emulator speaks enough GRBL 1.1: ``G90``/``G91``, ``G20``/``G21``,
``G53``, ``G0``/``G1`` (feed required for G1), ``G38.2``/``G38.3`` with
``F`` (``[PRB:...:s]`` in machine coordinates), real-time ``?`` (status),
``!``/``~`` (ignored), Ctrl-X (reset, banner), ``$X`` unlock, ``$H`` home,
``$$``/``$I``/``$G``, alarms (2 soft limit, 4 probe already triggered,
5 no contact) and ``ok``/``error:N``. Moves take no time and pass through
material (a real controller does not know about the part either); only
probing moves ask the machine, through the one method it must have
(duck typing, ``sim.probe.VirtualMachine`` or :class:`hardware.scene.SimpleScene`)::

    probe_move(start_m (3,), target_m (3,), rot_rad (3,)) -> (triggered, pos_m (3,))

:class:`Faults` injects the failures a campaign must survive: dropped
connections, alarms and garbage lines.
"""

from __future__ import annotations

import os
import re
import select
import socket
import threading
from dataclasses import dataclass, field

import numpy as np

BANNER = "Grbl 1.1h ['$' for help]"
_WORD = re.compile(r"([A-Z])([-+]?(?:\d+\.?\d*|\.\d+))")
_GARBAGE = ("[PRB:12.500,zz,3.000:1]", "ok?", "<Idle|MPos:1.0,abc,3>", "\x7f\x01noise\x02",
            "[PRB:1.000,2.000:1]", "ALARM", "error:", "[PRB:5.000,5.000,5.000:1")


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
        Raise ``ALARM:code`` instead of executing probing move k (e.g. 1, hard limit).
    garbage_every : int
        Put a garbage line before every n-th answered line (0: never).
    """

    drop_before_probe: tuple = ()
    drop_after_probe: tuple = ()
    alarm_at_probe: dict = field(default_factory=dict)
    garbage_every: int = 0


class GrblEmulator:
    """The GRBL state machine: bytes in, bytes out, transport-agnostic.

    Parameters
    ----------
    machine : object
        Has ``probe_move(start_m, target_m, rot_rad) -> (triggered, pos_m)``.
    axes : str
        Axes reported in status and probe reports, ``"XYZ"`` or e.g. ``"XYZABC"``.
    home_mm : (3,) float
        Machine position at power-on and after ``$H``, mm.
    limits_mm : (3, 2) float or None
        Soft limits ``[[xmin, xmax], ...]`` in machine coordinates, mm.
    decimals : int
        Decimals of reported positions (GRBL: 3 in mm).
    overshoot_mm : float
        How far past the trigger the machine stops (deceleration), mm.
    report_wpos : bool
        Report ``WPos`` plus ``WCO`` instead of ``MPos`` (GRBL ``$10=0``).
    start_in_alarm : bool
        Power on in alarm, as a GRBL with homing enabled does.
    faults : Faults
    """

    def __init__(self, machine, *, axes: str = "XYZ", home_mm=(0.0, 0.0, 0.0), limits_mm=None,
                 decimals: int = 3, overshoot_mm: float = 0.05, report_wpos: bool = False,
                 start_in_alarm: bool = False, faults: Faults | None = None):
        self.machine = machine
        self.axes = axes
        self.home_mm = np.asarray(home_mm, dtype=float)
        self.limits_mm = None if limits_mm is None else np.asarray(limits_mm, dtype=float)
        self.decimals = int(decimals)
        self.overshoot_mm = float(overshoot_mm)
        self.report_wpos = report_wpos
        self.faults = faults or Faults()
        self.lock = threading.RLock()
        self.pos_mm = self.home_mm.copy()
        self.rot_deg = np.zeros(3)
        self.state = "Alarm" if start_in_alarm else "Idle"
        self.alarm: int | None = None
        self.incremental = False
        self.inch = False
        self.motion = 0.0
        self.feed = 0.0
        self.probes = 0          # probing moves received
        self.touches = []        # (triggered, pos_mm) of every executed probing move
        self._answered = 0
        self._buf = b""

    # -- formatting
    def _fmt(self, v) -> str:
        return ",".join(f"{x:.{self.decimals}f}" for x in v)

    def _axes_mm(self, p_mm) -> list:
        return list(p_mm) + list(self.rot_deg[: max(0, len(self.axes) - 3)])

    def status_line(self) -> str:
        p = self._axes_mm(self.pos_mm)
        if self.report_wpos:
            return f"<{self.state}|WPos:{self._fmt(p)}|FS:0,0|WCO:{self._fmt([0.0] * len(p))}>"
        return f"<{self.state}|MPos:{self._fmt(p)}|FS:0,0>"

    # -- input
    def feed_bytes(self, data: bytes) -> tuple[list[str], bool]:
        """Process received bytes; return (lines to send, close the connection)."""
        out: list[str] = []
        with self.lock:
            for b in data:
                c = bytes([b])
                if c == b"?":
                    out.append(self.status_line())
                elif c == b"\x18":
                    self._buf = b""
                    self.incremental = False
                    if self.state not in ("Alarm",):
                        self.state = "Idle"
                    out += ["", BANNER]
                elif c in (b"!", b"~") or b >= 0x80:
                    continue
                elif c in (b"\n", b"\r"):
                    line, self._buf = self._buf.decode("ascii", "replace"), b""
                    if not line.strip() and c == b"\r":
                        continue
                    ans, drop = self._line(line)
                    for a in ans:
                        self._answered += 1
                        g = self.faults.garbage_every
                        if g and self._answered % g == 0:
                            out.append(_GARBAGE[(self._answered // g) % len(_GARBAGE)])
                        out.append(a)
                    if drop:
                        return out, True
                else:
                    self._buf += c
        return out, False

    def _line(self, raw: str) -> tuple[list[str], bool]:
        s = re.sub(r"\([^)]*\)", "", raw).split(";")[0]
        s = "".join(s.split()).upper()
        if not s:
            return ["ok"], False
        if s.startswith("$"):
            return self._dollar(s), False
        if self.state == "Alarm":
            return ["error:9"], False
        words = _WORD.findall(s)
        if "".join(a + v for a, v in words) != s:
            return ["error:1" if not s[:1].isalpha() else "error:2"], False
        g: list[float] = []
        vals: dict[str, float] = {}
        for a, v in words:
            if a == "G":
                g.append(float(v))
            elif a in "XYZABCFPNSTM":
                if a in vals and a not in "M":
                    return ["error:25"], False
                vals[a] = float(v)
            else:
                return ["error:20"], False
        g53 = False
        motion = None
        for code in g:
            if code in (90.0, 91.0):
                self.incremental = code == 91.0
            elif code in (20.0, 21.0):
                self.inch = code == 20.0
            elif code == 53.0:
                g53 = True
            elif code in (0.0, 1.0, 38.2, 38.3):
                if motion is not None:
                    return ["error:21"], False
                motion = code
            elif code in (17.0, 40.0, 49.0, 80.0, 94.0, 54.0, 4.0):
                continue
            else:
                return ["error:20"], False
        if "F" in vals:
            self.feed = vals["F"] * (25.4 if self.inch else 1.0)
        for a in "ABC":
            if a in vals and a not in self.axes:
                return ["error:20"], False
        axis_words = [a for a in "XYZABC" if a in vals]
        if motion is None:
            if not axis_words:
                return ["ok"], False
            motion = self.motion
        if g53 and (motion not in (0.0, 1.0)):
            return ["error:20"], False
        if motion in (38.2, 38.3) or motion == 1.0:
            if self.feed <= 0:
                return ["error:22"], False
        if not axis_words:
            return (["error:26"] if motion in (38.2, 38.3) else ["ok"]), False
        self.motion = motion if motion in (0.0, 1.0) else self.motion
        k = 25.4 if self.inch else 1.0
        target = self.pos_mm.copy()
        rot = self.rot_deg.copy()
        for i, a in enumerate("XYZ"):
            if a in vals:
                target[i] = (target[i] if (self.incremental and not g53) else 0.0) + vals[a] * k
        for i, a in enumerate("ABC"):
            if a in vals:
                rot[i] = (rot[i] if (self.incremental and not g53) else 0.0) + vals[a]
        if self.limits_mm is not None and (np.any(target < self.limits_mm[:, 0] - 1e-9)
                                           or np.any(target > self.limits_mm[:, 1] + 1e-9)):
            self.state, self.alarm = "Alarm", 2
            return ["ALARM:2", "[MSG:Reset to continue]"], False
        if motion in (0.0, 1.0):
            self.pos_mm, self.rot_deg = target, rot
            return ["ok"], False
        return self._probe(target, rot, allow_miss=motion == 38.3)

    def _probe(self, target_mm, rot_deg, allow_miss: bool) -> tuple[list[str], bool]:
        self.probes += 1
        k = self.probes
        f = self.faults
        if k in f.drop_before_probe:
            return [], True
        if k in f.alarm_at_probe:
            code = int(f.alarm_at_probe[k])
            self.state, self.alarm = "Alarm", code
            return [f"ALARM:{code}"], False
        start = self.pos_mm.copy()
        if np.allclose(start, target_mm, atol=1e-9):
            return ["error:33"], False
        self.rot_deg = rot_deg
        trig, p_m = self.machine.probe_move(start * 1e-3, target_mm * 1e-3, np.radians(rot_deg))
        p = np.asarray(p_m, dtype=float).reshape(3) * 1e3
        if trig and np.allclose(p, start, atol=1e-9):
            self.state, self.alarm = "Alarm", 4
            return ["ALARM:4", "ok"], k in f.drop_after_probe
        self.touches.append((bool(trig), p.copy()))
        rep = f"[PRB:{self._fmt(self._axes_mm(p))}:{1 if trig else 0}]"
        if trig:
            u = target_mm - start
            u = u / np.linalg.norm(u)
            room = float((target_mm - p) @ u)
            self.pos_mm = p + u * max(0.0, min(self.overshoot_mm, room))
            out = [rep, "ok"]
        else:
            self.pos_mm = target_mm.copy()
            if allow_miss:
                out = [rep, "ok"]
            else:
                self.state, self.alarm = "Alarm", 5
                out = ["ALARM:5", rep, "ok"]
        return ([], True) if k in f.drop_after_probe else (out, False)

    def _dollar(self, s: str) -> list[str]:
        if s == "$X":
            if self.state == "Alarm":
                self.state, self.alarm = "Idle", None
                return ["[MSG:Caution: Unlocked]", "ok"]
            return ["ok"]
        if s == "$H":
            self.pos_mm = self.home_mm.copy()
            self.rot_deg = np.zeros(3)
            self.state, self.alarm = "Idle", None
            return ["ok"]
        if s == "$$":
            return ["$10=1", "$22=1", "ok"]
        if s == "$I":
            return ["[VER:1.1h.vmt-emulator:]", "[OPT:V,15,128]", "ok"]
        if s == "$G":
            return [f"[GC:G{int(self.motion)} G54 G17 {'G20' if self.inch else 'G21'} "
                    f"{'G91' if self.incremental else 'G90'} G94 M5 M9 T0 F{self.feed:g} S0]", "ok"]
        return ["error:3"]


class TcpServer:
    """Serve a :class:`GrblEmulator` on a TCP port, one client at a time.

    Listens on ``host`` (127.0.0.1 by default); ``port=0`` picks a free port
    (see :attr:`port`). Each new client gets the banner, as after a power-on.
    """

    def __init__(self, emulator: GrblEmulator, host: str = "127.0.0.1", port: int = 0):
        self.emulator = emulator
        self.sock = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
        self.sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        self.sock.bind((host, port))
        self.sock.listen(4)
        self.sock.settimeout(0.1)
        self.host, self.port = self.sock.getsockname()[:2]
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self.connections = 0

    @property
    def url(self) -> str:
        return f"grbl://{self.host}:{self.port}"

    def start(self) -> "TcpServer":
        self._thread = threading.Thread(target=self.serve, name="grbl-emulator", daemon=True)
        self._thread.start()
        return self

    def serve(self) -> None:
        """Accept and serve clients until :meth:`stop`."""
        while not self._stop.is_set():
            try:
                conn, _ = self.sock.accept()
            except (socket.timeout, OSError):
                continue
            self.connections += 1
            with conn:
                self._session(conn)
        self.sock.close()

    def _session(self, conn) -> None:
        conn.settimeout(0.1)
        try:
            conn.sendall(f"\r\n{BANNER}\r\n".encode())
            while not self._stop.is_set():
                try:
                    data = conn.recv(4096)
                except socket.timeout:
                    continue
                if not data:
                    return
                lines, drop = self.emulator.feed_bytes(data)
                if lines:
                    conn.sendall("".join(x + "\r\n" for x in lines).encode("latin-1"))
                if drop:
                    return
        except OSError:
            return

    def stop(self) -> None:
        self._stop.set()
        if self._thread is not None:
            self._thread.join(timeout=2.0)

    def __enter__(self):
        return self.start()

    def __exit__(self, *exc):
        self.stop()


class PtyServer:
    """Serve a :class:`GrblEmulator` on a pseudo-terminal: :attr:`path` is the serial port."""

    def __init__(self, emulator: GrblEmulator):
        import pty
        import tty

        self.emulator = emulator
        self.master, self.slave = pty.openpty()
        tty.setraw(self.slave)      # no echo, no line editing: a plain 8-bit serial line
        self.path = os.ttyname(self.slave)
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None

    @property
    def url(self) -> str:
        return f"serial://{self.path}"

    def start(self) -> "PtyServer":
        self._thread = threading.Thread(target=self.serve, name="grbl-emulator-pty", daemon=True)
        self._thread.start()
        return self

    def serve(self) -> None:
        while not self._stop.is_set():
            r, _, _ = select.select([self.master], [], [], 0.1)
            if not r:
                continue
            try:
                data = os.read(self.master, 4096)
            except OSError:
                continue
            lines, _drop = self.emulator.feed_bytes(data)   # a serial line cannot be dropped
            if lines:
                os.write(self.master, "".join(x + "\r\n" for x in lines).encode("latin-1"))

    def stop(self) -> None:
        self._stop.set()
        if self._thread is not None:
            self._thread.join(timeout=2.0)
        for fd in (self.master, self.slave):
            try:
                os.close(fd)
            except OSError:  # pragma: no cover
                pass

    def __enter__(self):
        return self.start()

    def __exit__(self, *exc):
        self.stop()
