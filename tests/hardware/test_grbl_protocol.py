"""GRBL parsing, the emulator's protocol, the client against it (TCP and pty)."""

import numpy as np
import pytest

from core.exceptions import HardwareError
from hardware.backend import VirtualBackend
from hardware.emulator import BANNER, Faults, GrblEmulator, PtyServer, TcpServer
from hardware.grbl import GrblBackend, GrblClient, connect, open_link, parse_prb, parse_status
from hardware.scene import SimpleScene


# ---- parsing -------------------------------------------------------------

def test_parse_prb_any_number_of_axes():
    p, ok = parse_prb("[PRB:1.000,-2.500,3.25:1]")
    assert ok and np.allclose(p, [1, -2.5, 3.25])
    p, ok = parse_prb("[PRB:1.0,2.0,3.0,45.000,0.000,-90.000:0]")
    assert not ok and p.size == 6 and p[3] == 45
    assert parse_prb("[PRB:1.0,2.0:1]") is None           # two axes: not a position
    assert parse_prb("[PRB:12.5,zz,3:1]") is None
    assert parse_prb("[PRB:1,2,3:2]") is None
    assert parse_prb("[PRB:1,2,3:1") is None
    assert parse_prb("ok") is None


def test_parse_status_mpos_wpos_and_garbage():
    s = parse_status("<Idle|MPos:1.000,2.000,-3.000|FS:0,0>")
    assert s.state == "Idle" and np.allclose(s.mpos_mm, [1, 2, -3])
    s = parse_status("<Hold:0|WPos:1.000,2.000,3.000|FS:0,0|WCO:10.000,0.000,-5.000>")
    assert s.state == "Hold" and np.allclose(s.mpos_mm, [11, 2, -2])
    assert parse_status("<Idle|WPos:1,2,3|FS:0,0>").mpos_mm is None   # WCO unknown
    assert np.allclose(parse_status("<Idle|WPos:1,2,3>", wco_mm=[1, 1, 1]).mpos_mm, [2, 3, 4])
    assert parse_status("<Idle|MPos:1.0,abc,3>") is None
    assert parse_status("Idle|MPos:1,2,3") is None


# ---- the emulator, bytes in and out ---------------------------------------

def say(emu, text):
    out, drop = emu.feed_bytes(text.encode())
    return out


def test_emulator_speaks_grbl():
    emu = GrblEmulator(SimpleScene(), home_mm=(10, 10, 5), limits_mm=((-1, 200), (-1, 200), (-50, 60)))
    assert say(emu, "?") == ["<Idle|MPos:10.000,10.000,5.000|FS:0,0>"]
    assert say(emu, "G1 X20\n") == ["error:22"]                    # no feed yet
    assert say(emu, "G21 G90 G1 X20 F500\n") == ["ok"]
    assert say(emu, "G91 G1 Y-5 F500\n") == ["ok"]
    assert np.allclose(emu.pos_mm, [20, 5, 5])
    assert say(emu, "G90\nG20 G1 X1\nG21\n") == ["ok", "ok", "ok"]   # inches
    assert np.isclose(emu.pos_mm[0], 25.4)
    assert say(emu, "G91 G38.2 Z0 F100\n") == ["error:33"]          # zero-length probe
    assert say(emu, "G38.2 Z-10 F100\n") == ["[PRB:25.400,5.000,0.000:1]", "ok"]
    assert say(emu, "G38.3 Z-1\n") == ["ALARM:4", "ok"]             # already in contact
    assert say(emu, "G1 Z5\n") == ["error:9"] and say(emu, "?")[0].startswith("<Alarm|")
    assert say(emu, "$X\n") == ["[MSG:Caution: Unlocked]", "ok"]
    assert say(emu, "G90 G1 Z5 F500\nG91 G38.3 Z1\n") == ["ok", "[PRB:25.400,5.000,6.000:0]", "ok"]
    assert say(emu, "G38.2 Z1\n") == ["ALARM:5", "[PRB:25.400,5.000,7.000:0]", "ok"]
    assert say(emu, "$H\n") == ["ok"] and np.allclose(emu.pos_mm, [10, 10, 5])
    assert say(emu, "G90 G1 Z100\n")[0] == "ALARM:2"                 # soft limit
    assert say(emu, "$X\nG4.5 X1\nQ1\n$Q\n") == ["[MSG:Caution: Unlocked]", "ok",
                                                 "error:20", "error:20", "error:3"]
    assert say(emu, "\x18")[-1] == BANNER


def test_emulator_reports_rotary_axes():
    emu = GrblEmulator(SimpleScene(), axes="XYZABC", home_mm=(10, 10, 5))
    assert say(emu, "G1 A30 F100\nG38.2 Z-10\n")[-2] == "[PRB:10.000,10.000,0.000,30.000,0.000,0.000:1]"
    assert say(GrblEmulator(SimpleScene()), "G1 A30 F100\n") == ["error:20"]


# ---- the client against the emulator -------------------------------------

def test_client_status_wpos_and_banner_over_tcp():
    emu = GrblEmulator(SimpleScene(), home_mm=(1, 2, 3), report_wpos=True)
    with TcpServer(emu) as srv:
        be = connect(srv.url, timeout_s=5)
        try:
            be.start()
            assert np.allclose(be.position_m(), [1e-3, 2e-3, 3e-3])
        finally:
            be.close()


def test_client_lost_connection_and_bad_urls():
    emu = GrblEmulator(SimpleScene(), faults=Faults(drop_before_probe=(1,)))
    with TcpServer(emu) as srv:
        be = connect(srv.url, timeout_s=5)
        be.start()
        with pytest.raises(HardwareError, match="connection lost"):
            be.probe([0, 0, -0.001], 100)
        be.close()
    for url, msg in [("grbl://127.0.0.1", "HOST:PORT"), ("ftp://x", "unknown scheme"),
                     ("serial://", "serial:///dev/ttyX"), ("serial:///nonexistent/tty", "cannot open")]:
        with pytest.raises(HardwareError, match=msg):
            open_link(url)
    with pytest.raises(HardwareError, match="cannot connect"):
        srv_port = srv.port   # closed now
        open_link(f"grbl://127.0.0.1:{srv_port}")


class _ScriptLink:
    """A link that answers from a script: the client must not take garbage for a position."""

    def __init__(self, answers):
        self.answers = list(answers)
        self.sent = []

    def send(self, data):
        self.sent.append(data.decode())

    def readline(self, timeout_s):
        return self.answers.pop(0) if self.answers else None

    def close(self):
        pass


def test_garbage_is_reported_never_taken_for_a_position():
    events = []
    link = _ScriptLink(["<Idle|MPos:0.000,0.000,5.000|FS:0,0>",
                        "[PRB:1.0,zz,3:1]", "ok", "ok"])
    be = GrblBackend(GrblClient(link, timeout_s=0.2, on_event=events.append))
    be._pos_mm = np.array([0.0, 0.0, 5.0])
    with pytest.raises(HardwareError, match="0 probe reports"):
        be.probe([0, 0, 0.0], 100)
    assert any("malformed probe report" in e for e in events)
    # a well-formed report far off the commanded path is refused too
    link = _ScriptLink(["[PRB:40.000,0.000,3.000:1]", "ok", "ok"])
    be = GrblBackend(GrblClient(link, timeout_s=0.2))
    be._pos_mm = np.array([0.0, 0.0, 5.0])
    with pytest.raises(HardwareError, match="off the commanded path"):
        be.probe([0, 0, 0.0], 100)
    # a reset in the middle of a command
    link = _ScriptLink(["", BANNER])
    with pytest.raises(HardwareError, match="reset"):
        GrblClient(link, timeout_s=0.2).command("G1 X1 F100")
    # silence
    with pytest.raises(HardwareError, match="did not answer"):
        GrblClient(_ScriptLink([]), timeout_s=0.05).command("G1 X1 F100")


def test_alarm_state_needs_the_users_word():
    emu = GrblEmulator(SimpleScene(), start_in_alarm=True, home_mm=(0, 0, 5))
    with TcpServer(emu) as srv:
        be = connect(srv.url, timeout_s=5)
        with pytest.raises(HardwareError, match="--unlock"):
            be.start()
        assert emu.state == "Alarm"                       # nothing sent to unlock it
        be.start(unlock=True)
        assert emu.state == "Idle"
        be.close()


@pytest.mark.parametrize("transport", ["tcp", "pty"])
def test_probe_through_the_protocol_equals_the_backend(transport):
    """Same touches through GRBL as directly; tolerance 0.5 µm: GRBL reports 3 decimals in mm."""
    emu = GrblEmulator(SimpleScene(scale=(50e-6, 0, 0)), home_mm=(0, 0, 30))
    direct = VirtualBackend(SimpleScene(scale=(50e-6, 0, 0)), home_m=(0, 0, 0.03))
    server = TcpServer(emu) if transport == "tcp" else PtyServer(emu)
    with server:
        be = connect(server.url, timeout_s=5)
        try:
            be.start()
            for start, end in [((10, 10, 3), (10, 10, -3)), ((50, 70, 3), (50, 60, -3)),
                               ((75, 50, 5), (55, 50, 5))]:
                got = []
                for b in (be, direct):
                    b.move(np.array(start) * 1e-3, 1000)
                    got.append(b.probe(np.array(end) * 1e-3, 100))
                assert got[0].triggered and got[1].triggered
                assert np.allclose(got[0].pos_m, got[1].pos_m, atol=0.5e-6 + 1e-9)
        finally:
            be.close()
