"""Live GRBL / grblHAL / FluidNC client over a TCP socket or a serial port.

The protocol, as this client uses it (GRBL 1.1 "simple send-response"):

- one G-code line at a time, answered by ``ok`` or ``error:N``;
- ``?`` (real-time, no newline) answered by ``<State|MPos:x,y,z|...>``
  (or ``WPos`` plus ``WCO``, then ``MPos = WPos + WCO``);
- a probing move ``G38.2`` (``G38.3`` where a miss is allowed) reports
  ``[PRB:x,y,z(,a,...):s]`` in machine coordinates, mm, any number of axes,
  ``s`` = 1 on contact;
- ``ALARM:N`` at any time (table and advice in :mod:`hardware.backend`).
  After a ``G38.2`` miss the firmware prints ``ALARM:5``, then, after its
  0.5 s alarm delay, ``[PRB:...:0]`` with the *previous* successful probe
  position (it does not update it on a failed ``G38.2``), then ``ok``: the
  alarm wins, the report is stale and never taken for a position. Every
  G-code line then gets ``error:9`` (alarm lock) until ``$X`` or ``$H``,
  which this client sends only on the user's word (``--unlock``,
  ``--home-cycle``). After ``ALARM:1`` (hard limit) or ``ALARM:2`` (soft limit)
  the firmware answers nothing, not even ``?``, until a reset (Ctrl-X,
  ``--reset``), and only then ``$X`` or ``$H``;
- a line holds at most 79 characters once spaces are removed (GRBL's
  80-byte line buffer; ``error:11`` beyond): numbers are written with
  fewer decimals when a line would not fit, and a line that cannot fit is
  refused by name before it is sent;
- the controller's axes: ``X, Y, Z`` when its status report has three
  values; otherwise named by the user (``--axes``) or read from ``$I``
  (grblHAL's ``[AXS:n:XYZAC]``). Positioning lines carry a word for every
  rotary axis the controller has, and no other (``--rotary``).

Positions always come from the controller's own ``PRB`` or status report,
never from the command that was sent. Lines that are neither an expected
answer nor a known informational message are reported through
``on_event`` (and kept in :attr:`GrblClient.unexpected`) and never taken for
a position. GRBL speaks millimetres: :class:`GrblBackend` converts to and
from metres at its boundary. Unless ``$13=1`` (report inches): then every
report is in inches, so the start reads ``$$`` (after a running move has
ended: ``$$`` needs the controller idle or in alarm) and refuses a
controller with ``$13=1``, naming the setting, before anything moves. It
converts nothing: a controller's units are its own setting, and a
conversion would hide which one a log was made with.

Motion: positioning is ``G53 G90 G1`` (machine coordinates, a feed move so
the maximum feed holds); probing is ``G91 G38.2`` by an increment from where
the machine stands, so work offsets never enter, nor GRBL's tool length
offset (``G43.1`` shifts the work coordinates only). The probe's length is
vmt's own: :class:`hardware.campaign.ProbeSettings` ``tool_offset_mm`` J
shifts every target this backend is given by + J and every report it
returns is logged - J (``vmt probe --tool-offset-mm``, session 36); the
backend itself speaks the controller's machine coordinates only.
"""

from __future__ import annotations

import errno
import os
import re
import select
import socket
import time
from dataclasses import dataclass, field
from typing import Callable
from urllib.parse import parse_qs, urlsplit

import numpy as np

from core.exceptions import HardwareError

from .backend import ALARMS, CRITICAL_ALARMS, ProbeResult, describe_alarm, describe_error

#: Characters a line may have once spaces are removed (GRBL's 80-byte line buffer).
LINE_MAX_CHARS = 79
#: After an alarm, how long to wait for the rest of the answer (GRBL waits 0.5 s after it), s.
ALARM_GRACE_S = 3.0

_NUM = r"[-+]?(?:\d+\.?\d*|\.\d+)"
_PRB = re.compile(rf"^\[PRB:({_NUM}(?:,{_NUM}){{2,8}}):([01])\]$")
_STATUS = re.compile(r"^<([A-Za-z]+)(?::\d+)?((?:\|[^|<>]*)*)>$")

#: Lines that inform and are harmless (not garbage, never a position).
_INFO = re.compile(r"^(\[(MSG|GC|HLP|VER|OPT|G54|G55|G56|G57|G58|G59|G28|G30|G92|TLO|echo|"
                   r"JSON|CTRL|AXS|NEWOPT|FIRMWARE|SIGNALS|NVS|BOARD|PLUGIN|AUX|SETTING|"
                   r"SD|DRIVER|COMPILE|IP|AP|STA|MAC|MODE|MSG)[^\]]*\]|\$\d+=.*|>.*:ok)$")
_BANNER = re.compile(r"^(Grbl|GrblHAL|grbl)\s*\S*\s*\[.*\]\s*$", re.I)


def printed_decimals(numbers: str) -> int | None:
    """The most decimals written in a controller's comma-separated numbers (``10.000,-0.066,5.283``: 3), the
    step it printed them to (``core.probelog.most_decimals``); None for no number. GRBL prints every position
    it reports, ``[PRB:...]`` and a status report's ``MPos``/``WPos`` alike, with one function
    (``printFloat_CoordValue``, report.c: ``N_DECIMAL_COORDVALUE_MM``, 3 decimals in mm, 4 in inches)."""
    from core.probelog import most_decimals

    return most_decimals(numbers.split(",")[:3])


def prb_decimals(line: str) -> int | None:
    """:func:`printed_decimals` of the X, Y, Z of a ``[PRB:x,y,z(,...):s]`` report; None when the line is no
    well-formed report."""
    m = _PRB.match(line.strip())
    return None if not m else printed_decimals(m.group(1))


def parse_prb(line: str):
    """Parse a ``[PRB:x,y,z(,...):s]`` report.

    Returns
    -------
    (axes_mm, ok) : ((k,) float, bool), k >= 3
        Machine coordinates of every reported axis, and whether it touched.
        ``None`` when the line is not a well-formed probe report.
    """
    m = _PRB.match(line.strip())
    if not m:
        return None
    return np.array([float(v) for v in m.group(1).split(",")]), m.group(2) == "1"


@dataclass(frozen=True)
class Status:
    """A parsed ``<State|...>`` report: state name and machine position, mm."""

    state: str
    mpos_mm: np.ndarray | None
    wco_mm: np.ndarray | None = None
    #: the most decimals the report printed its position with (``MPos``, else ``WPos``:
    #: :func:`printed_decimals`), the step the controller prints every position to, its probe reports' too
    decimals: int | None = None


def parse_status(line: str, wco_mm=None) -> Status | None:
    """Parse a GRBL 1.1 status report; ``None`` when the line is not one.

    ``MPos`` is used as is; ``WPos`` needs the work offset ``WCO`` (from this
    report or ``wco_mm`` remembered from an earlier one).
    """
    m = _STATUS.match(line.strip())
    if not m:
        return None
    fields = {}
    for part in m.group(2).split("|")[1:]:
        if ":" in part:
            k, v = part.split(":", 1)
            fields[k] = v

    def vec(v):
        try:
            a = np.array([float(x) for x in v.split(",")])
        except ValueError:
            return None
        return a if a.size >= 3 and np.all(np.isfinite(a)) else None

    wco = vec(fields["WCO"]) if "WCO" in fields else (None if wco_mm is None else np.asarray(wco_mm))
    if "MPos" in fields:
        mpos = vec(fields["MPos"])
        if mpos is None:
            return None
        printed = fields["MPos"]
    elif "WPos" in fields:
        w = vec(fields["WPos"])
        if w is None:
            return None
        mpos = None if wco is None or wco.size != w.size else w + wco
        printed = fields["WPos"]
    else:
        return None
    return Status(m.group(1), mpos, wco, printed_decimals(printed))


# ---------------------------------------------------------------------------
# links: a byte stream read line by line


class _LineBuffer:
    def __init__(self):
        self.buf = b""

    def pop(self) -> str | None:
        for sep in (b"\n", b"\r"):
            i = self.buf.find(sep)
            if i >= 0:
                line, self.buf = self.buf[:i], self.buf[i + 1:]
                return line.decode("ascii", errors="replace").strip()
        return None


class _Link:
    """A byte stream read line by line; subclasses implement ``_receive``."""

    where: str
    _lb: _LineBuffer

    def _receive(self, left_s: float) -> bytes | None:  # pragma: no cover - abstract
        """Bytes that arrived within ``left_s`` (None: none yet); raise HardwareError on loss."""
        raise NotImplementedError

    def readline(self, timeout_s: float) -> str | None:
        """Next non-empty line, or ``None`` after ``timeout_s``; a lost link raises."""
        end = time.monotonic() + timeout_s
        while True:
            line = self._lb.pop()
            while line is not None and line == "":
                line = self._lb.pop()
            if line is not None:
                return line
            left = end - time.monotonic()
            if left <= 0:
                return None
            data = self._receive(left)
            if data:
                self._lb.buf += data


class TcpLink(_Link):
    """GRBL over a TCP socket (grblHAL / FluidNC telnet, ``vmt machine serve``)."""

    #: A banner on a new connection says nothing of a reset: a network controller may greet every
    #: client with it (Grbl_Esp32's config.h defines ENABLE_TELNET_WELCOME_MSG: report_init_message
    #: to each new telnet client), and ``vmt machine serve`` does by default.
    resets_on_open = False

    def __init__(self, host: str, port: int, connect_timeout_s: float = 5.0):
        self.where = f"grbl://{host}:{port}"
        try:
            self.sock = socket.create_connection((host, port), timeout=connect_timeout_s)
        except OSError as e:
            raise HardwareError(f"{self.where}: cannot connect ({e.strerror or e})") from None
        self.sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        self._lb = _LineBuffer()

    def send(self, data: bytes) -> None:
        try:
            self.sock.sendall(data)
        except OSError as e:
            raise HardwareError(f"{self.where}: connection lost while sending ({e.strerror or e})") from None

    def _receive(self, left_s: float) -> bytes | None:
        self.sock.settimeout(left_s)
        try:
            data = self.sock.recv(4096)
        except socket.timeout:
            return None
        except OSError as e:
            raise HardwareError(f"{self.where}: connection lost ({e.strerror or e})") from None
        if not data:
            raise HardwareError(f"{self.where}: connection lost (closed by the controller)")
        return data

    def close(self) -> None:
        try:
            self.sock.close()
        except OSError:  # pragma: no cover
            pass


class SerialLink(_Link):
    """GRBL over a serial port or pty, standard library only (termios, raw 8N1)."""

    #: Opening an Arduino's serial port pulls DTR, which resets the board; GRBL prints its banner only
    #: from main()'s start-up loop (power-up, a reset), so a banner read at connect, before vmt sent a
    #: reset, means the board was reset, and GRBL's power-up cleared its machine position (main.c:
    #: memset(sys_position, 0)).
    resets_on_open = True

    def __init__(self, path: str, baud: int = 115200):
        import termios
        import tty

        self.where = f"serial://{path}"
        try:
            self.fd = os.open(path, os.O_RDWR | os.O_NOCTTY | os.O_NONBLOCK)
        except OSError as e:
            raise HardwareError(f"{self.where}: cannot open ({e.strerror})") from None
        try:
            tty.setraw(self.fd)
            attr = termios.tcgetattr(self.fd)
            speed = getattr(termios, f"B{baud}", None)
            if speed is None:
                raise HardwareError(f"{self.where}: baud rate {baud} not supported")
            attr[4] = attr[5] = speed
            attr[2] |= termios.CLOCAL | termios.CREAD
            termios.tcsetattr(self.fd, termios.TCSANOW, attr)
        except termios.error as e:
            os.close(self.fd)
            raise HardwareError(f"{self.where}: not a serial port ({e})") from None
        self._lb = _LineBuffer()

    def send(self, data: bytes) -> None:
        view = memoryview(data)
        end = time.monotonic() + 5.0
        while view:
            try:
                n = os.write(self.fd, view)
                view = view[n:]
            except BlockingIOError:
                if time.monotonic() > end:
                    raise HardwareError(f"{self.where}: write timed out") from None
                select.select([], [self.fd], [], 0.1)
            except OSError as e:
                raise HardwareError(f"{self.where}: connection lost ({e.strerror})") from None

    def _receive(self, left_s: float) -> bytes | None:
        r, _, _ = select.select([self.fd], [], [], left_s)
        if not r:
            return None
        try:
            data = os.read(self.fd, 4096)
        except BlockingIOError:
            return None
        except OSError as e:
            if e.errno == errno.EIO:
                raise HardwareError(f"{self.where}: connection lost (device closed)") from None
            raise HardwareError(f"{self.where}: connection lost ({e.strerror})") from None
        if not data:
            raise HardwareError(f"{self.where}: connection lost (end of file)")
        return data

    def close(self) -> None:
        try:
            os.close(self.fd)
        except OSError:  # pragma: no cover
            pass


def open_link(url: str):
    """A link from ``grbl://HOST:PORT`` or ``serial:///dev/ttyX[?baud=N]``."""
    try:
        u = urlsplit(url)
        port = u.port if u.scheme in ("grbl", "tcp") else None
    except ValueError:      # urllib's words for a port out of 0-65535, not a number, a torn [IPv6] (audit37: a traceback)
        raise HardwareError(f"machine {url!r}: not grbl://HOST:PORT (PORT a whole number 1-65535) or "
                            f"serial:///dev/ttyX") from None
    if u.scheme in ("grbl", "tcp"):
        if not u.hostname or port is None:
            raise HardwareError(f"machine {url!r}: expected grbl://HOST:PORT")
        return TcpLink(u.hostname, port)
    if u.scheme == "serial":
        if not u.path:
            raise HardwareError(f"machine {url!r}: expected serial:///dev/ttyX")
        q = parse_qs(u.query)
        try:
            baud = int(q.get("baud", ["115200"])[0])
        except ValueError:
            raise HardwareError(f"machine {url!r}: baud is not an integer") from None
        return SerialLink(u.path, baud)
    raise HardwareError(f"machine {url!r}: unknown scheme (use grbl://HOST:PORT or serial:///dev/ttyX)")


# ---------------------------------------------------------------------------
# the client


@dataclass
class Reply:
    """Everything the controller said in answer to one line."""

    command: str
    ok: bool = False
    error: int | None = None
    alarms: list = field(default_factory=list)
    prb: list = field(default_factory=list)   # [(axes_mm (k,), touched)]
    prb_decimals: list = field(default_factory=list)   # the decimals each report printed X, Y, Z with
    lines: list = field(default_factory=list)


class GrblClient:
    """Send-response GRBL client over a link (:class:`TcpLink`, :class:`SerialLink`).

    Parameters
    ----------
    link : object
        ``send(bytes)``, ``readline(timeout_s) -> str | None``, ``close()``.
    timeout_s : float
        Longest wait for the answer to one line (a long move included).
    on_event : callable(str) or None
        Called with a one-line description of every unexpected line or alarm.
    transcript : file-like or None
        Text stream receiving ``"<t_s> > sent"`` / ``"<t_s> < received"`` lines
        (the format :func:`hardware.transcript.import_grbl_transcript` reads).
    """

    def __init__(self, link, timeout_s: float = 60.0, on_event: Callable[[str], None] | None = None,
                 transcript=None, clock=time.time):
        self.link = link
        self.timeout_s = float(timeout_s)
        self.on_event = on_event
        self.transcript = transcript
        self.clock = clock
        self.unexpected: list[str] = []
        self.banners: list[str] = []        # every start-up banner read (a reset: power-up, DTR, Ctrl-X)
        self.alarm: int | None = None       # the last alarm seen, until cleared by the backend
        self.last_msg: str | None = None    # the last [MSG:...] line
        self._wco = None

    # -- plumbing
    def _note(self, msg: str) -> None:
        if self.on_event is not None:
            self.on_event(msg)

    def _log(self, d: str, line: str) -> None:
        if self.transcript is not None:
            self.transcript.write(f"{self.clock():.3f} {d} {line}\n")
            self.transcript.flush()

    def _send(self, data: str) -> None:
        self._log(">", data.strip() or repr(data))
        try:
            self.link.send(data.encode("latin-1"))
        except HardwareError as e:
            raise self._lost(e) from None

    def _read(self, timeout_s: float) -> str | None:
        try:
            line = self.link.readline(timeout_s)
        except HardwareError as e:
            raise self._lost(e) from None
        if line is not None:
            self._log("<", line)
            if line.startswith("[MSG:"):
                self.last_msg = line
            elif _BANNER.match(line):
                self.banners.append(line)
        return line

    def _lost(self, e: HardwareError) -> HardwareError:
        said = f" (its last message: {self.last_msg})" if self.last_msg else ""
        return HardwareError(f"{e}{said}")

    def _unexpected(self, line: str, context: str) -> None:
        shown = line if len(line) <= 80 else line[:77] + "..."
        self.unexpected.append(line)
        self._note(f"unexpected line from controller ({context}): {shown!r}")

    def _alarm(self, line: str) -> int | None:
        m = re.fullmatch(r"ALARM:(\d+)", line)
        if not m:
            return None
        code = int(m.group(1))
        self.alarm = code
        self._note(f"controller alarm ALARM:{code} ({ALARMS.get(code, 'unknown alarm')})")
        return code

    # -- commands
    def command(self, line: str, timeout_s: float | None = None) -> Reply:
        """Send one G-code line and collect the answer up to ``ok`` / ``error:N``.

        After an alarm the answer may end without ``ok`` (``ALARM:1``/``2``:
        the firmware then answers nothing until a reset): the reply is
        returned :data:`ALARM_GRACE_S` after the last line.

        Raises
        ------
        HardwareError
            The line is longer than GRBL takes, no answer within the timeout,
            connection lost, the controller reset (its banner) in the middle.
        """
        line = line.strip()
        n = len("".join(line.split()))
        if n > LINE_MAX_CHARS:
            raise HardwareError(f"line {line!r} has {n} characters without spaces; "
                                f"GRBL takes at most {LINE_MAX_CHARS} (error:11)")
        rep = Reply(line)
        self._send(line + "\n")
        limit = self.timeout_s if timeout_s is None else timeout_s
        end = time.monotonic() + limit
        while True:
            left = end - time.monotonic()
            got = self._read(max(left, 0.0)) if left > 0 else None
            if got is None:
                if rep.alarms:   # an alarm may end a command without its ok
                    return rep
                raise HardwareError(f"controller did not answer {line!r} within {limit:g} s")
            rep.lines.append(got)
            if got == "ok":
                rep.ok = True
                return rep
            m = re.fullmatch(r"error:(\d+)", got)
            if m:
                rep.error = int(m.group(1))
                return rep
            code = self._alarm(got)
            if code is not None:
                rep.alarms.append(code)
                end = min(end, time.monotonic() + ALARM_GRACE_S)   # then PRB / ok, or nothing
                continue
            if rep.alarms:
                end = min(end, time.monotonic() + ALARM_GRACE_S)
                if got == "[MSG:Reset to continue]":      # nothing more comes until a reset
                    return rep
            if got.startswith("[PRB"):
                p = parse_prb(got)
                if p is None:
                    self._unexpected(got, f"malformed probe report after {line!r}")
                else:
                    rep.prb.append(p)
                    rep.prb_decimals.append(prb_decimals(got))
                continue
            if _BANNER.match(got):
                if rep.alarms:     # ALARM:3 (reset in motion) then the banner: the alarm says what to do
                    raise HardwareError(f"{describe_alarm(rep.alarms[0])} [during {line!r}; the controller "
                                        f"reset: {got!r}]")
                raise HardwareError(f"controller reset while executing {line!r} ({got!r})")
            if got.startswith("<"):
                st = parse_status(got, self._wco)
                if st is not None:
                    if st.wco_mm is not None:
                        self._wco = st.wco_mm
                    continue
            if _INFO.match(got):
                continue
            self._unexpected(got, f"answering {line!r}")

    def expect_ok(self, line: str, timeout_s: float | None = None) -> Reply:
        """:meth:`command`, raising on ``error:N`` or an alarm (with what to do)."""
        rep = self.command(line, timeout_s)
        if rep.alarms:
            raise HardwareError(f"{describe_alarm(rep.alarms[0])} [on {line!r}]")
        if rep.error is not None:
            e = rep.error
            hint = ""
            if e == 9:
                hint = ("; the controller is in alarm" + (f": {describe_alarm(self.alarm)}"
                                                         if self.alarm is not None else
                                                         ": clear the cause and re-run with --unlock"))
            raise HardwareError(f"controller rejected {line!r}: {describe_error(e)}{hint}")
        return rep

    def status(self, timeout_s: float = 5.0) -> Status:
        """Query ``?`` until a well-formed status report arrives (resent every 0.5 s).

        Raises
        ------
        HardwareError
            No status report within ``timeout_s``: GRBL answers none while a
            hard or soft limit alarm waits for a reset.
        """
        end = time.monotonic() + timeout_s
        while time.monotonic() < end:
            self._send("?")
            tick = min(end, time.monotonic() + 0.5)
            while True:
                left = tick - time.monotonic()
                if left <= 0:
                    break
                got = self._read(left)
                if got is None:
                    break
                if got.startswith("<"):
                    st = parse_status(got, self._wco)
                    if st is not None:
                        if st.wco_mm is not None:
                            self._wco = st.wco_mm
                        if st.mpos_mm is None:
                            # $10=0 (WPos reports): the firmware adds WCO to one report in 10 (idle)
                            # to 30 (busy); ask again at once, this is no unexpected line
                            time.sleep(0.02)
                            break
                        return st
                    self._unexpected(got, "malformed status report")
                    continue
                if self._alarm(got) is not None or got in ("ok", "") or _BANNER.match(got) \
                        or _INFO.match(got) or re.fullmatch(r"error:\d+", got):
                    continue
                self._unexpected(got, "waiting for status")
        after = f" after {describe_alarm(self.alarm)}" if self.alarm is not None else ""
        raise HardwareError(f"controller did not answer a status query within {timeout_s:g} s{after}; "
                            "GRBL answers nothing after a hard or soft limit alarm (ALARM:1/2) until "
                            "a reset: re-run with --reset (then --unlock or --home-cycle)")

    def reset(self, timeout_s: float = 5.0) -> list[str]:
        """Soft reset (Ctrl-X) and wait for the banner; returns the lines read."""
        self._send("\x18")
        got_lines = []
        end = time.monotonic() + timeout_s
        while time.monotonic() < end:
            got = self._read(end - time.monotonic())
            if got is None:
                break
            got_lines.append(got)
            self._alarm(got)
            if _BANNER.match(got):
                # the lock message, if any, follows the banner at once
                more = self._read(0.3)
                if more is not None:
                    got_lines.append(more)
                return got_lines
        raise HardwareError(f"controller did not answer a reset (Ctrl-X) within {timeout_s:g} s")

    def settings(self, timeout_s: float = 5.0) -> dict[int, str]:
        """The controller's settings from ``$$`` (``{13: "0", ...}``, the values as written).

        Raises
        ------
        HardwareError
            The controller refuses ``$$`` (``error:8``: not idle) or lists nothing.
        """
        rep = self.command("$$", timeout_s)
        if rep.error is not None:
            raise HardwareError(f"controller rejected '$$' (its settings, read before anything moves, "
                                f"for $13: are positions reported in mm?): {describe_error(rep.error)}")
        out = {}
        for ln in rep.lines:
            m = re.fullmatch(r"\$(\d+)=([^\s(]*).*", ln)
            if m:
                out[int(m.group(1))] = m.group(2)
        if not out:
            raise HardwareError("controller answered '$$' with no setting: not a GRBL-family controller?")
        return out

    def axes_from_info(self, timeout_s: float = 5.0) -> str | None:
        """Axis letters from ``$I`` (grblHAL's ``[AXS:n:letters]``); None when not given."""
        rep = self.command("$I", timeout_s)
        for ln in rep.lines:
            m = re.fullmatch(r"\[AXS:(\d+):([A-Z]+)\]", ln)
            if m and int(m.group(1)) == len(m.group(2)):
                return m.group(2)
        return None

    def close(self) -> None:
        self.link.close()


def _fit(words, feed_word: str, lead: str) -> str:
    """``lead`` + words + ``feed_word``, with the fewest decimals dropped to fit GRBL's line.

    ``words``: [(letter, value)]. Decimals go 4, then trailing zeros cut, then 3
    (1 µm, GRBL's display resolution). Raises when even that does not fit.
    """
    def build(dec, strip):
        parts = []
        for a, v in words:
            t = f"{v:.{dec}f}"
            if strip and "." in t:
                t = t.rstrip("0").rstrip(".")
                t = "0" if t in ("-0", "") else t
            parts.append(f"{a}{t}")
        return " ".join([lead] + parts + ([feed_word] if feed_word else []))

    for dec, strip in ((4, False), (4, True), (3, True)):
        line = build(dec, strip)
        if len("".join(line.split())) <= LINE_MAX_CHARS:
            return line
    raise HardwareError(f"line {build(3, True)!r} cannot be written within GRBL's "
                        f"{LINE_MAX_CHARS} characters (error:11): too many axes or too large values")


def move_line(target_mm, feed_mm_min: float, rot_deg=None, rotary: str = "ABC", axes: str = "XYZ") -> str:
    """The positioning line: a feed move in machine coordinates (``G53 G90 G1``).

    ``rot_deg`` (3,) A, B, C in degrees, or None; only the axes in ``rotary``
    (the controller's rotary axes) get a word. Only the linear ``axes`` get a
    word (``"Z"``: a rise whose X and Y are where the machine stands).
    """
    words = [(a, float(v)) for a, v in zip("XYZ", target_mm) if a in axes]
    if rot_deg is not None:
        words += [(a, float(v)) for a, v in zip("ABC", rot_deg) if a in rotary]
    return _fit(words, f"F{feed_mm_min:.1f}", "G53 G90 G1")


def probe_line(start_mm, end_mm, feed_mm_min: float, allow_miss: bool = False) -> str:
    """The probing line: ``G91 G38.2`` (``G38.3`` with ``allow_miss``) by ``end - start``."""
    d = np.asarray(end_mm, dtype=float) - np.asarray(start_mm, dtype=float)
    g = "G38.3" if allow_miss else "G38.2"
    return _fit(list(zip("XYZ", (float(v) for v in d))), f"F{feed_mm_min:.1f}", f"G91 {g}")


class GrblBackend:
    """A GRBL-family controller behind :class:`hardware.backend.ProbingBackend`.

    Parameters
    ----------
    client : GrblClient
    name : str
        Free text for the log (the machine URL).
    rotary : bool
        Send the controller's rotary axes (A, B, C: those it has) in positioning moves.
    path_tol_mm : float
        Largest distance of a probe report from the commanded probing segment
        (and beyond its ends): a report farther away is not taken.
    axes : str or None
        The controller's axes as the user names them (``"XYZAC"``); None: read
        them (three values in the status report: X, Y, Z; more: ``$I``).
    reset : bool
        Soft-reset the controller (Ctrl-X) before anything else (after a hard
        or soft limit alarm GRBL needs it).
    """

    def __init__(self, client: GrblClient, name: str = "grbl", rotary: bool = False,
                 path_tol_mm: float = 1.0, axes: str | None = None, reset: bool = False):
        self.client = client
        self.name = name
        self.rotary = rotary
        self.path_tol_mm = float(path_tol_mm)
        self.user_axes = None if axes is None else check_axes(axes)
        self.axes: str | None = None
        self.reset = reset
        self._pos_mm: np.ndarray | None = None
        self._connect_banner: str | None = None
        #: the decimals the controller prints positions with, read from its status report's text at
        #: :meth:`start` (:attr:`Status.decimals`; GRBL prints ``[PRB:...]`` with the same function): the
        #: campaign log declares its X_mm, Y_mm, Z_mm printed to them (``number_format``). None before start.
        self.report_decimals: int | None = None

    #: A controller's machine position outlives a connection (unless the controller was reset):
    #: a resumed campaign checks it against where its log left the machine
    #: (:func:`hardware.campaign.resume_frame_problem`).
    keeps_position = True

    def reset_at_connect(self) -> str | None:
        """Why the controller was reset when vmt connected (its machine position lost), or None.

        A banner read before any reset vmt sent, on a link whose opening resets the board
        (:attr:`SerialLink.resets_on_open`: DTR on an Arduino). Over TCP a banner may be a network
        controller's greeting (:attr:`TcpLink.resets_on_open`), and after ``--reset`` vmt's own
        Ctrl-X is answered by one: the machine position then decides (:mod:`hardware.campaign`).
        """
        if self._connect_banner is None or not getattr(self.client.link, "resets_on_open", False):
            return None
        return (f"the controller printed its start-up banner ({self._connect_banner!r}) when "
                f"{self.client.link.where} was opened: opening the port resets an Arduino GRBL (DTR), "
                "and GRBL's start-up sets its machine position to 0 where the machine stands")

    def start(self, *, unlock: bool = False, home: bool = False) -> None:
        c = self.client
        if self.reset:
            c.reset()
        seen = len(c.banners)
        try:
            st = c.status(timeout_s=min(5.0, c.timeout_s))
        finally:          # a banner before the first status report: the controller greeted or was reset
            if not self.reset and len(c.banners) > seen:
                self._connect_banner = c.banners[seen]
        self.axes = self._axes(st)
        end = time.monotonic() + c.timeout_s
        while st.state.split(":")[0].lower() in ("run", "jog", "home") and time.monotonic() < end:
            time.sleep(0.05)      # a move still running (a resume after a lost link): '$$' needs it done
            st = c.status(timeout_s=min(5.0, c.timeout_s))
        self._check_units(c.settings(timeout_s=min(5.0, c.timeout_s)))
        if st.state.lower() == "alarm":
            if not unlock and not home:
                why = describe_alarm(c.alarm) if c.alarm is not None else (
                    "the controller is in alarm: clear the cause and re-run with --unlock "
                    "(sends $X) or --home-cycle (sends $H)")
                raise HardwareError(f"controller in alarm, nothing sent: {why}")
        if home:
            c.expect_ok("$H", timeout_s=max(c.timeout_s, 120.0))
        elif st.state.lower() == "alarm" and unlock:
            c.expect_ok("$X")
        c.alarm = None
        for line in ("G21", "G90", "G94"):
            c.expect_ok(line)
        st = c.status()
        self._pos_mm = st.mpos_mm[:3].copy()
        self.report_decimals = st.decimals

    @staticmethod
    def _check_units(settings: dict[int, str]) -> None:
        """Refuse a controller that reports inches (``$13=1``), before anything moves.

        vmt reads every position the controller reports (status, ``[PRB]``)
        as millimetres and converts nothing: a controller's units are its
        own setting, and a silent conversion would hide which one a log was
        made with. So the setting is named and left to the user.
        """
        v = settings.get(13)
        if v is None:
            raise HardwareError("the controller's settings ($$) have no $13 (report inches): vmt cannot "
                                "tell whether it reports millimetres; nothing moved")
        try:
            inch = float(v) != 0
        except ValueError:
            raise HardwareError(f"the controller's $13 (report inches) is {v!r}, not a number; "
                                "nothing moved") from None
        if inch:
            raise HardwareError(f"the controller reports positions in inches ($13={v}); vmt reads them "
                                "as millimetres and converts no controller's units: set $13=0 (send "
                                "'$13=0') and run again; nothing moved")

    def _axes(self, st: Status) -> str:
        k = st.mpos_mm.size
        if self.user_axes is not None:
            if len(self.user_axes) != k:
                raise HardwareError(f"--axes {self.user_axes}: the controller reports {k} axes "
                                    f"({','.join(f'{v:g}' for v in st.mpos_mm)})")
            return self.user_axes
        if k == 3:
            return "XYZ"
        got = self.client.axes_from_info()
        if got is not None and len(got) == k:
            return check_axes(got)
        raise HardwareError(f"the controller reports {k} axes but does not name them ($I has no "
                            "[AXS:n:letters]): name them with --axes, e.g. --axes XYZA")

    @property
    def rotary_axes(self) -> str:
        """The controller's rotary axes, ``""`` before :meth:`start`."""
        return "".join(a for a in (self.axes or "") if a in "ABC")

    def position_m(self) -> np.ndarray:
        st = self.client.status()
        self._pos_mm = st.mpos_mm[:3].copy()
        return self._pos_mm * 1e-3

    def move(self, target_m, feed_mm_min: float, rot_rad=None) -> None:
        t = np.asarray(target_m, dtype=float) * 1e3
        rot = None
        if self.rotary and rot_rad is not None:
            rot = np.degrees(np.asarray(rot_rad, dtype=float).reshape(3))
            have = self.rotary_axes
            for a, v in zip("ABC", rot):
                if a not in have and abs(v) > 1e-9:
                    raise HardwareError(f"the plan needs {a} = {v:g} deg but the controller's axes are "
                                        f"{self.axes}: no {a} axis to turn")
        self.client.expect_ok(move_line(t, feed_mm_min, rot, self.rotary_axes))
        self._pos_mm = t

    def probe(self, target_m, feed_mm_min: float, *, allow_miss: bool = False) -> ProbeResult:
        """One probing move (``G91 G38.2``, or ``G38.3`` with ``allow_miss``).

        GRBL answers a contact with ``[PRB:x,y,z:1]`` and ``ok``. A ``G38.2``
        miss raises ``ALARM:5``: the alarm decides, the ``[PRB:...:0]`` that
        follows repeats the previous probe and is never a position, the touch
        is a ``no_trigger`` with ``alarm=5``. The ``G90`` that restores
        absolute mode is then refused with ``error:9`` (alarm lock), as the
        firmware does; the controller stays locked until ``$X`` (``--unlock``)
        when the campaign is resumed. ``ALARM:4`` (the probe already triggered
        before the move, nothing moved) is an ``early_trigger`` with
        ``alarm=4``, the word ``vmt import grbl`` gives it. Any other alarm
        (1 hard limit, 2 soft limit, 3 a reset during the move) raises with what
        to do, and nothing more is sent.
        """
        if self._pos_mm is None:
            self.position_m()
        start = self._pos_mm.copy()
        end = np.asarray(target_m, dtype=float) * 1e3
        d = end - start
        if np.linalg.norm(d) < 1e-4:
            raise HardwareError("probing move of zero length")
        line = probe_line(start, end, feed_mm_min, allow_miss)
        rep = self.client.command(line)
        crit = [a for a in rep.alarms if a in CRITICAL_ALARMS]
        if crit:       # the firmware now answers nothing until a reset: send nothing more
            raise HardwareError(f"{describe_alarm(crit[0])} [during {line!r}]")
        other = [a for a in rep.alarms if a not in (4, 5)]
        if other:      # e.g. ALARM:3, a reset during the move: its banner would fail the G90 (session 31)
            raise HardwareError(f"{describe_alarm(other[0])} [during {line!r}]")
        back = self.client.command("G90")
        if back.error is not None and not (back.error == 9 and rep.alarms):
            raise HardwareError(f"controller rejected 'G90': {describe_error(back.error)}")
        if rep.error is not None:
            raise HardwareError(f"controller rejected {line!r}: {describe_error(rep.error)}")
        if 4 in rep.alarms:
            # the probe was already in contact (or its pin in the wrong state) before the move: nothing moved, no
            # position; the touch is logged early_trigger, as vmt import grbl reads the same alarm (review 27)
            self._pos_mm = None
            return ProbeResult("early_trigger", start * 1e-3, alarm=4)
        if 5 in rep.alarms:
            for axes_mm, touched in rep.prb:
                self.client._note(f"ALARM:5 (no contact): the probe report that follows it "
                                  f"({np.round(axes_mm, 3).tolist()}:{int(touched)}) repeats the last "
                                  "successful probe; not taken as a position")
            self._pos_mm = None           # the machine stands at the end of the move; re-read it
            return ProbeResult("no_trigger", end * 1e-3, alarm=5)
        if len(rep.prb) != 1:
            raise HardwareError(f"{len(rep.prb)} probe reports after {line!r} (expected exactly 1)")
        axes, touched = rep.prb[0]
        printed = rep.prb_decimals[0] if rep.prb_decimals else None
        p = axes[:3]
        # the report must lie on the commanded segment: never take a stray line for a touch
        u = d / np.linalg.norm(d)
        s = float((p - start) @ u)
        off = float(np.linalg.norm(p - start - s * u))
        if off > self.path_tol_mm or s < -self.path_tol_mm or s > np.linalg.norm(d) + self.path_tol_mm:
            raise HardwareError(f"probe report {np.round(p, 4).tolist()} mm is off the commanded "
                                f"path {np.round(start, 4).tolist()} -> {np.round(end, 4).tolist()} mm")
        # where the machine stopped (deceleration past the trigger), from its own report
        self._pos_mm = self.client.status().mpos_mm[:3].copy()
        if touched:
            return ProbeResult("ok", p * 1e-3, extra_axes=tuple(axes[3:]), reported_mm=p.copy(),
                               reported_decimals=printed)
        if not allow_miss:
            raise HardwareError(f"G38.2 ended without contact and without ALARM:5 ({line!r})")
        return ProbeResult("no_trigger", p * 1e-3, extra_axes=tuple(axes[3:]))

    def temperatures_C(self) -> dict[str, float]:
        return {}

    def close(self) -> None:
        self.client.close()


def check_axes(axes: str) -> str:
    a = str(axes).upper()
    if a[:3] != "XYZ" or len(set(a)) != len(a) or any(x not in "ABC" for x in a[3:]):
        raise HardwareError(f"axes {axes!r}: expected X, Y, Z then rotary axes A, B, C (e.g. XYZAC)")
    return a


def connect(url: str, *, timeout_s: float = 60.0, on_event=None, transcript=None,
            rotary: bool = False, axes: str | None = None, reset: bool = False) -> GrblBackend:
    """Open ``grbl://HOST:PORT`` or ``serial:///dev/ttyX`` as a :class:`GrblBackend`."""
    link = open_link(url)
    client = GrblClient(link, timeout_s=timeout_s, on_event=on_event, transcript=transcript)
    return GrblBackend(client, name=url, rotary=rotary, axes=axes, reset=reset)
