"""No input kills the emulator; an idle client times out; a second client is refused, not hung.

Before (issue 15): ``G0 X1`` followed by 400 nines, then ``G38.2 Z-10 F100``,
killed the serving thread with an uncaught error while the port kept
listening; one idle connection blocked every other client for ever.
"""

import re
import socket
import time

import numpy as np
import pytest

from hardware.emulator import BANNER, ControllerConfig, GrblEmulator, PtyServer, TcpServer
from hardware.grbl import connect
from hardware.scene import SimpleScene

#: Every line GRBL 1.1h (and the emulator) may print.
_GRBL_LINE = re.compile(
    r"^(ok|error:\d+|ALARM:\d+|<[A-Za-z]+(:\d)?(\|[A-Za-z]+:[^|<>]*)*>|\[(MSG|GC|HLP|VER|OPT|AXS|PRB|"
    r"G5[4-9]|G28|G30|G92|TLO):[^\]]*\]|\$\d+=[-\d.]+|\$N\d=.*|>.*:(ok|error:\d+)|"
    + re.escape(BANNER) + r")$")


def _lines(sock, timeout_s=2.0, until=None):
    """Lines read from ``sock`` until ``until`` matches one, the peer closes, or the timeout."""
    sock.settimeout(0.05)
    buf, out, end = b"", [], time.monotonic() + timeout_s
    while time.monotonic() < end:
        try:
            data = sock.recv(4096)
        except socket.timeout:
            continue
        if not data:
            out.append(None)               # closed by the emulator
            break
        buf += data
        while b"\n" in buf:
            ln, buf = buf.split(b"\n", 1)
            ln = ln.decode("latin-1").strip()
            if ln:
                out.append(ln)
                if until and re.search(until, ln):
                    return out
    return out


def _fuzz_chunks(rng, n):
    """Binary garbage, half lines, long numbers, plausible and implausible G-code, real-time bytes."""
    words = ["G0", "G1", "G2", "G3", "G4", "G10", "G17", "G20", "G21", "G28", "G38.2", "G38.3", "G38.4",
             "G38.5", "G53", "G54", "G80", "G90", "G91", "G92", "G93", "G94", "M0", "M2", "M3", "M8",
             "$J=", "$H", "$X", "$$", "$#", "$C", "$RST=#", "$10=0", "$10=1", "$13=1", "$13=0",
             "$20=1", "$22=1", "$110=", "$N0=", "$SLP", "$I="]
    letters = "XYZFIJKLNPRSTABCQE"
    alone = [b"$X\n", b"$X\n", b"$H\n", b"~", b"!", b"$C\n", b"$J=G91 X5 F500\n", b"$SLP\n", b"\x18",
             b"G4 P0.5\n", b"M0\n", b"G10 L20 P1 X0\n", b"G92 Z3\n", b"G43.1 Z1\n"]
    for _ in range(n):
        kind = rng.integers(8)
        if kind == 7 or rng.random() < 0.2:
            yield alone[rng.integers(len(alone))]
            continue
        if kind == 0:
            yield bytes(rng.integers(0, 256, rng.integers(1, 300), dtype=np.uint8))
        elif kind == 1:
            yield b"G0 X1" + b"9" * int(rng.integers(10, 500)) + (b"\n" if rng.random() < 0.7 else b"")
        elif kind == 2:
            parts = [str(rng.choice(words))] + [
                f"{rng.choice(list(letters))}{rng.normal(0, 10 ** rng.integers(0, 12)):.{rng.integers(0, 9)}f}"
                for _ in range(rng.integers(0, 6))]
            yield (" ".join(parts) + ("\n" if rng.random() < 0.9 else "")).encode()
        elif kind == 3:
            yield bytes(rng.choice([0x3F, 0x21, 0x7E, 0x85, 0x90, 0x91, 0x95, 0x99, 0x9E, 0xA0],
                                   rng.integers(1, 5)))
        elif kind == 4:
            yield b"\x18" if rng.random() < 0.3 else b"\r\n"
        elif kind == 5:
            yield (f"G1 X{rng.uniform(-50, 50):.3f} Y{rng.uniform(-50, 50):.3f} "
                   f"Z{rng.uniform(-5, 50):.3f} F{rng.uniform(1, 3000):.1f}\n").encode()
        else:
            yield (f"G91 G38.{rng.integers(2, 6)} Z{rng.uniform(-60, 60):.4f} "
                   f"F{rng.uniform(0, 500):.1f}\n").encode()


@pytest.mark.parametrize("seed", range(4))
def test_fuzzed_input_never_kills_it_and_every_answer_is_grbl(seed):
    rng = np.random.default_rng(seed)
    emu = GrblEmulator(SimpleScene(), ControllerConfig(axes="XYZAC", home=(10, 10, 20),
                                                        travel=((-100, 100),) * 3))
    for chunk in _fuzz_chunks(rng, 400):
        out, _ = emu.feed_bytes(chunk, max_s=30.0)
        for ln in out:
            assert ln == "" or _GRBL_LINE.match(ln), (chunk[:60], ln)
    assert emu.internal_errors == []
    # still a controller: reset, unlock, move, probe the table, report
    out, _ = emu.feed_bytes(b"\x18")
    assert BANNER in out
    # (G54 may hold an offset the fuzz stored, as EEPROM would: move in machine coordinates)
    out, _ = emu.feed_bytes(b"$X\n$10=1\n$13=0\nG21 G90 G94 G53 G1 X10 Y10 Z5 F1000\nG91 G38.2 Z-10 F100\n")
    assert out[-2].startswith("[PRB:10.000,10.000,0.000,") and out[-2].endswith(":1]") and out[-1] == "ok"
    assert emu.feed_bytes(b"?")[0][0].startswith("<Idle|MPos:")


def test_the_line_that_killed_it_over_tcp_then_other_clients():
    emu = GrblEmulator(SimpleScene(), ControllerConfig(home=(10, 10, 5)))
    with TcpServer(emu, time_scale=100.0) as srv:
        with socket.create_connection((srv.host, srv.port)) as s:
            assert _lines(s, until="Grbl")[-1] == BANNER
            s.sendall(b"G0 X1" + b"9" * 400 + b"\nG38.2 Z-10 F100\n")
            assert _lines(s, until="ok$") == ["error:11", "[PRB:10.000,10.000,0.000:1]", "ok"]
            s.sendall(b"G0 X1" + b"9" * 60 + b"\n")     # fits in 79: a move of 2e60 mm, accepted
            assert _lines(s, until="ok") == ["ok"]
            s.sendall(b"?")
            assert _lines(s, until="^<")[0].startswith("<Run|")
            s.sendall(b"\x18")
            assert _lines(s, until="unlock") == ["ALARM:3", BANNER, "[MSG:'$H'|'$X' to unlock]"]
            s.sendall(bytes(range(256)) * 4 + b"\n$X\n")
            assert _lines(s, until=r"Unlocked")[-1] == "[MSG:Caution: Unlocked]"
        # the next client is served
        be = connect(srv.url, timeout_s=5)
        try:
            be.start()
            assert be.position_m()[2] < 0.001
        finally:
            be.close()
    assert emu.internal_errors == [] and srv.connections == 2


def test_a_second_client_is_refused_while_one_is_served():
    emu = GrblEmulator(SimpleScene(), ControllerConfig(home=(0, 0, 5)))
    with TcpServer(emu, time_scale=100.0) as srv:
        first = socket.create_connection((srv.host, srv.port))
        assert _lines(first, until="Grbl")[-1] == BANNER
        with socket.create_connection((srv.host, srv.port)) as second:
            assert _lines(second) == ["[MSG:vmt emulator busy: one client at a time]", None]
        first.sendall(b"G1 X1 F100\n?")               # the first is still served
        assert _lines(first, until="^<")[0] == "ok"
        first.close()
        time.sleep(0.1)
        with socket.create_connection((srv.host, srv.port)) as third:
            assert _lines(third, until="Grbl")[-1] == BANNER
            third.sendall(b"$X\n")
            assert _lines(third, until="ok") == ["ok"]
    assert (srv.connections, srv.refused) == (2, 1)


def test_an_idle_client_times_out_a_busy_one_does_not():
    emu = GrblEmulator(SimpleScene(), ControllerConfig(home=(0, 0, 50)))
    with TcpServer(emu, time_scale=1.0, idle_timeout_s=0.3) as srv:
        with socket.create_connection((srv.host, srv.port)) as s:
            s.sendall(b"G1 X10 F600\n")               # 1.1 s of motion at time scale 1
            got = _lines(s, timeout_s=0.9)
            assert got[-1] == "ok" and None not in got   # moving: not idle
            got = _lines(s, timeout_s=3.0)
            assert got[-2:] == ["[MSG:vmt emulator: no input for 0.3 s, closing]", None]
        be = connect(srv.url, timeout_s=5)             # the slot is free again
        be.start()
        be.close()
    assert srv.timeouts == 1 and np.allclose(emu.pos_mm, [10, 0, 50])


def test_a_client_that_never_reads_is_let_go_and_the_firmware_runs_on(monkeypatch):
    from hardware import emulator as E

    monkeypatch.setattr(E._TcpPort, "MAX_OUT", 4096)
    emu = GrblEmulator(SimpleScene())
    with TcpServer(emu, time_scale=100.0) as srv:
        with socket.create_connection((srv.host, srv.port)) as s:
            s.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 4096)
            for _ in range(200):
                try:
                    s.sendall(b"$$\n" + b"?" * 50)
                except OSError:
                    break
                time.sleep(0.001)
            time.sleep(0.3)
        be = connect(srv.url, timeout_s=5)
        be.start()
        be.close()
    assert emu.internal_errors == []


def test_garbage_on_the_serial_port_too():
    emu = GrblEmulator(SimpleScene(), ControllerConfig(home=(0, 0, 5)))
    with PtyServer(emu, time_scale=100.0) as srv:
        import os

        fd = os.open(srv.path, os.O_RDWR | os.O_NOCTTY)
        try:
            os.write(fd, bytes(range(256)) + b"\n" + b"G0 X1" + b"9" * 400 + b"\n")
            time.sleep(0.2)
        finally:
            os.close(fd)
        be = connect(srv.url, timeout_s=5)
        be.start()
        be.close()
    assert emu.internal_errors == []


@pytest.mark.parametrize("mode", ["greet", "reset", "silent"])
def test_tcp_server_on_connect(mode):
    """What a new TCP client meets: the banner and the state kept (greet: a network controller's welcome),
    a hardware reset (reset: DTR when a bridge opens an Arduino's port), or nothing (silent)."""
    emu = GrblEmulator(SimpleScene(), ControllerConfig(home=(0, 0, 30)))
    with TcpServer(emu, time_scale=200.0, on_connect=mode) as srv:
        for k in range(2):
            with socket.create_connection((srv.host, srv.port)) as s:
                got = _lines(s, timeout_s=0.3)
                assert got == ([] if mode == "silent" else [BANNER])
                s.sendall(b"?")
                st = _lines(s, until="^<")[-1]
                # reset: 0 where it stands (each time); otherwise the position kept: 30, then the 20 moved to
                want = "0.000,0.000,0.000" if mode == "reset" else ("0.000,0.000,30.000", "0.000,0.000,20.000")[k]
                assert st.startswith(f"<Idle|MPos:{want}|"), st
                s.sendall(b"G53 G90 G1 Z20 F6000\nG4P0.01\n")
                assert _lines(s, until="ok.*", timeout_s=2.0)[-1] == "ok"
                time.sleep(0.05)
    from core.exceptions import ConfigError

    with pytest.raises(ConfigError, match="on_connect 'dtr'"):
        TcpServer(GrblEmulator(SimpleScene()), on_connect="dtr")
