"""vmt's GRBL client: parsing, line length, axes, alarms, links (TCP and pty) to the emulator."""

import numpy as np
import pytest

from core.exceptions import HardwareError
from hardware.backend import ALARM_RECOVERY, ALARMS, CRITICAL_ALARMS, ERRORS, VirtualBackend
from hardware.emulator import BANNER, ControllerConfig, Faults, GrblEmulator, PtyServer, TcpServer
from hardware.grbl import (LINE_MAX_CHARS, GrblBackend, GrblClient, connect, move_line, open_link,
                           parse_prb, parse_status, probe_line)
from hardware.scene import SimpleScene

FAST = 200.0     # emulated seconds per wall-clock second


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


def test_tables_are_grbl_1_1s():
    """Every code of GRBL 1.1h's report.h: errors 1-17 and 20-38, alarms 1-10."""
    assert sorted(ERRORS) == list(range(1, 18)) + list(range(20, 39))
    assert sorted(ALARMS) == sorted(ALARM_RECOVERY) == list(range(1, 11))
    assert CRITICAL_ALARMS == {1, 2}
    # a hard or soft limit needs a reset before $X / $H: --unlock alone is not the advice
    for a in (1, 2):
        assert "--reset" in ALARM_RECOVERY[a]
    assert "--home-cycle" in ALARM_RECOVERY[1] and "--unlock" in ALARM_RECOVERY[2]
    assert "--reset" not in ALARM_RECOVERY[5] and "--unlock" in ALARM_RECOVERY[5]


# ---- the lines vmt writes ------------------------------------------------------------------

def _chars(line):
    return len("".join(line.split()))


def test_lines_fit_grbl_s_79_characters_or_are_refused_by_name():
    assert move_line([10, 10, 2], 2000) == "G53 G90 G1 X10.0000 Y10.0000 Z2.0000 F2000.0"   # transcript
    assert probe_line([10, 10, 2], [10, 10, -2], 200) == "G91 G38.2 X0.0000 Y0.0000 Z-4.0000 F200.0"
    # six axes of three-digit numbers: decimals trimmed until it fits
    line = move_line([-123.4567, 234.5678, -345.6789], 1000, [-123.45678, 90.0, 359.99999])
    assert _chars(line) <= LINE_MAX_CHARS and "B90" in line and "X-123.4567" in line
    line = move_line([-12345.67891, -12345.67891, -1234.5678], 1000, [-1234.5678] * 3)
    assert _chars(line) <= LINE_MAX_CHARS and "X-12345.679" in line     # 3 decimals: 1 µm
    with pytest.raises(HardwareError, match="cannot be written within GRBL's 79 characters"):
        move_line([-123456.789, 234567.891, -345678.912], 1000, [-123456.789, 234567.891, 345678.912])
    # only the controller's rotary axes get words
    assert move_line([1, 2, 3], 100, [10, 20, 30], rotary="C") == \
        "G53 G90 G1 X1.0000 Y2.0000 Z3.0000 C30.0000 F100.0"
    # the client refuses a line GRBL would refuse, before sending it
    link = _ScriptLink([])
    with pytest.raises(HardwareError, match="at most 79"):
        GrblClient(link).command("G1 X" + "1" * 80)
    assert link.sent == []


# ---- the client against scripted answers ------------------------------------------------------

class _ScriptLink:
    """A link that answers from a script: the client must not take garbage for a position."""

    def __init__(self, answers):
        self.answers = list(answers)
        self.sent = []

    def send(self, data):
        self.sent.append(data.decode("latin-1"))

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


def test_alarm_5_wins_over_a_report_that_claims_contact():
    """Even a [PRB:...:1] after ALARM:5 is stale: the alarm decides (a miss), the report is named."""
    events = []
    link = _ScriptLink(["ALARM:5", "[PRB:0.000,0.000,1.000:1]", "ok", "error:9"])
    be = GrblBackend(GrblClient(link, timeout_s=0.2, on_event=events.append))
    be._pos_mm = np.array([0.0, 0.0, 5.0])
    r = be.probe([0, 0, 0.0], 100)
    assert r.status == "no_trigger" and r.alarm == 5 and np.allclose(r.pos_m, [0, 0, 0])
    assert link.sent == ["G91 G38.2 X0.0000 Y0.0000 Z-5.0000 F100.0\n", "G90\n"]
    assert any("not taken as a position" in e for e in events)


def test_critical_alarm_sends_nothing_more_and_says_reset():
    link = _ScriptLink(["ALARM:2", "[MSG:Reset to continue]"])
    be = GrblBackend(GrblClient(link, timeout_s=5))
    be._pos_mm = np.array([0.0, 0.0, 5.0])
    with pytest.raises(HardwareError, match=r"ALARM:2 \(soft limit.*--resume --reset --unlock"):
        be.probe([0, 0, 0.0], 100)
    assert len(link.sent) == 1            # no G90: the firmware would not answer it



# What GRBL 1.1h answers to a G38.2 that ends in each alarm its probe cycle can raise (gnea/grbl 1.1h:
# system.h EXEC_ALARM_*, mc_probe_cycle in motion_control.c, limits_soft_check in limits.c, protocol.c),
# answer streams as recorded from that firmware (tests/hardware/data/grbl-1.1h/recorded-*.txt):
# 1 hard limit during the move and 2 soft limit (a probe target beyond the travel, checked by mc_line before
# the move) are critical: "[MSG:Reset to continue]", then nothing until a reset; 3 a reset during the move
# (ok for the line, the banner); 4 the probe already triggered at the start (mc_probe_cycle, before motion);
# 5 no contact within the travel (G38.2 only; then the stale [PRB:...:0] and ok).
PROBE_CYCLE_ALARMS = {
    1: (["ALARM:1", "[MSG:Reset to continue]"], None,
        r"^ALARM:1 \(hard limit: .*position is likely lost\): .*--resume --reset --home-cycle"),
    2: (["ALARM:2", "[MSG:Reset to continue]"], None,
        r"^ALARM:2 \(soft limit: the target lies outside the machine travel.*position kept\): "
        r".*--resume --reset --unlock"),
    3: (["ALARM:3", "ok", BANNER, "[MSG:'$H'|'$X' to unlock]", "error:9"], None,
        r"^ALARM:3 \(reset while in motion: .*position is likely lost\): re-run with --resume --home-cycle"),
    "3 before ok": (["ALARM:3", BANNER, "ok", "[MSG:'$H'|'$X' to unlock]", "error:9"], None,
                    r"^ALARM:3 \(reset while in motion: .*--resume --home-cycle.* \[during 'G91 G38\.2 .*"
                    r"the controller reset: \"Grbl 1\.1h \['\$' for help\]\"\]$"),
    4: (["ALARM:4", "ok", "error:9"], "early_trigger", None),
    5: (["ALARM:5", "[PRB:0.000,0.000,9.000:0]", "ok", "error:9"], "no_trigger", None),
}


@pytest.mark.parametrize("code", PROBE_CYCLE_ALARMS)
def test_each_alarm_a_probe_cycle_can_raise_gets_its_own_line(code):
    """GRBL's alarm codes are 1 hard limit, 2 soft limit, 3 reset in motion, 4 probe not in its initial
    state, 5 probe without contact (report.h / system.h of 1.1h): a G38.2 miss is ALARM:5, never ALARM:2.
    Each code a probing move can end in: 4 and 5 are touches (logged early_trigger / no_trigger with the
    alarm, the position the start / the commanded end), the others stop with one line naming the alarm,
    what it means and the options to resume, and send nothing more (after 1 and 2 GRBL would not answer;
    session 31: after ALARM:3 the G90 met the reset's banner and the line said only "controller reset while
    executing 'G90'", the alarm and its advice lost; the banner can also come before the line's ok)."""
    answers, status, said = PROBE_CYCLE_ALARMS[code]
    link = _ScriptLink(answers)
    be = GrblBackend(GrblClient(link, timeout_s=0.2))
    be._pos_mm = np.array([0.0, 0.0, 5.0])
    if status is None:
        with pytest.raises(HardwareError, match=said) as e:
            be.probe([0, 0, 0.0], 100)
        msg = str(e.value)
        assert "\n" not in msg and "[during 'G91 G38.2 X0.0000 Y0.0000 Z-5.0000 F100.0'" in msg
        assert len(link.sent) == 1
    else:
        r = be.probe([0, 0, 0.0], 100)
        assert (r.status, r.alarm) == (status, code)
        assert np.allclose(r.pos_m, [0, 0, 5e-3] if code == 4 else [0, 0, 0])
        assert link.sent == ["G91 G38.2 X0.0000 Y0.0000 Z-5.0000 F100.0\n", "G90\n"]


# ---- the client against the emulator -------------------------------------

def test_client_status_wpos_and_banner_over_tcp():
    emu = GrblEmulator(SimpleScene(), ControllerConfig(home=(1, 2, 3), report_wpos=True))
    with TcpServer(emu, time_scale=FAST) as srv:
        be = connect(srv.url, timeout_s=5)
        try:
            be.start()
            assert np.allclose(be.position_m(), [1e-3, 2e-3, 3e-3])
        finally:
            be.close()


def test_client_lost_connection_and_bad_urls():
    emu = GrblEmulator(SimpleScene(), faults=Faults(drop_before_probe=(1,)))
    with TcpServer(emu, time_scale=FAST) as srv:
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
        open_link(f"grbl://127.0.0.1:{srv.port}")     # closed now


def test_alarm_state_needs_the_users_word():
    emu = GrblEmulator(SimpleScene(), ControllerConfig(home=(0, 0, 5), homing=True))
    assert emu.state == "Alarm"                           # $22=1: powers on in alarm
    with TcpServer(emu, time_scale=FAST) as srv:
        be = connect(srv.url, timeout_s=5)
        with pytest.raises(HardwareError, match="--unlock"):
            be.start()
        assert emu.state == "Alarm"                       # nothing sent to unlock it
        be.start(unlock=True)
        assert emu.state == "Idle"
        be.close()


def test_rotary_words_only_for_the_controllers_axes():
    """A 5-axis controller XYZAC (grblHAL names its axes in $I): C and A words, never B."""
    emu = GrblEmulator(SimpleScene(), ControllerConfig(axes="XYZAC", home=(0, 0, 30)))
    sent = []
    with TcpServer(emu, time_scale=FAST) as srv:
        be = connect(srv.url, timeout_s=5, rotary=True)
        inner = be.client.link.send
        be.client.link.send = lambda data: (sent.append(data.decode()), inner(data))[1]
        try:
            be.start()
            assert be.axes == "XYZAC" and "$I\n" in sent
            be.move(np.array([10, 10, 3]) * 1e-3, 1000, np.radians([15.0, 0.0, 30.0]))
            assert sent[-1] == "G53 G90 G1 X10.0000 Y10.0000 Z3.0000 A15.0000 C30.0000 F1000.0\n"
            r = be.probe(np.array([10, 10, -3]) * 1e-3, 100)
            assert r.triggered and np.allclose(r.extra_axes, [15.0, 30.0])
            with pytest.raises(HardwareError, match="needs B = 5 deg .* axes are XYZAC"):
                be.move(np.array([10, 10, 3]) * 1e-3, 1000, np.radians([0.0, 5.0, 0.0]))
        finally:
            be.close()


def test_unnamed_extra_axes_need_the_users_word():
    """A 4-axis controller that does not name its axes ($I without [AXS]): --axes, checked."""
    link = _ScriptLink(["<Idle|MPos:0.000,0.000,5.000,0.000|FS:0,0>", "[VER:1.1h.20190830:]",
                        "[OPT:V,15,128]", "ok"])
    with pytest.raises(HardwareError, match="reports 4 axes but does not name them.*--axes"):
        GrblBackend(GrblClient(link, timeout_s=0.2)).start()
    link = _ScriptLink(["<Idle|MPos:0.000,0.000,5.000,0.000|FS:0,0>"])
    with pytest.raises(HardwareError, match="--axes XYZAC: the controller reports 4 axes"):
        GrblBackend(GrblClient(link, timeout_s=0.2), axes="XYZAC").start()
    with pytest.raises(HardwareError, match="expected X, Y, Z then"):
        GrblBackend(GrblClient(link), axes="XYQ")


@pytest.mark.parametrize("transport", ["tcp", "pty"])
def test_probe_through_the_protocol_equals_the_backend(transport):
    """Same touches through GRBL as directly; tolerance 0.5 µm: GRBL reports 3 decimals in mm."""
    emu = GrblEmulator(SimpleScene(scale=(50e-6, 0, 0)), ControllerConfig(home=(0, 0, 30)))
    direct = VirtualBackend(SimpleScene(scale=(50e-6, 0, 0)), home_m=(0, 0, 0.03))
    server = TcpServer(emu, time_scale=FAST) if transport == "tcp" else PtyServer(emu, time_scale=FAST)
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


# ---- units: $13 (report inches) ------------------------------------------

def test_inch_reports_are_refused_before_anything_moves(tmp_path, capsys):
    """``$13=1`` (review fault F4): the emulator then reports MPos and [PRB] in inches, which vmt
    read as mm; the first touch failed with a message not naming the cause, or near the origin
    passed silently. Now the start refuses, naming $13, before any line that moves; $13=0 runs."""
    from conftest import LIMITS, plan_log
    from core.probelog import read_probe_log, write_probe_log
    from scenarios.cli import main

    plan = write_probe_log(tmp_path / "plan.csv", plan_log())
    emu = GrblEmulator(SimpleScene(), ControllerConfig(home=(0, 0, 50)))
    args = lambda out: ["probe", "--controller", srv.url, "--plan", str(plan), "--out", str(out),  # noqa: E731
                        "--limits-mm", LIMITS, "--safe-z-mm", "30", "--timeout-s", "5"]
    with TcpServer(emu, time_scale=FAST) as srv:
        c = connect(srv.url, timeout_s=5).client
        c.status()                                    # past the banner
        c.expect_ok("$13=1")                          # as a user sets it
        st = c.status()
        assert np.allclose(st.mpos_mm, [0, 0, 50 / 25.4], atol=1e-4)   # what the client reads: inches
        c.close()
        capsys.readouterr()
        assert main(args(tmp_path / "inch.csv")) == 2
        err = capsys.readouterr().err
        assert err.count("\n") == 1 and "Traceback" not in err
        assert "reports positions in inches ($13=1)" in err and "set $13=0" in err
        assert not (tmp_path / "inch.csv").exists()
        assert emu.probes == 0 and np.allclose(emu.position()[:3], [0, 0, 50])   # nothing moved
        c = connect(srv.url, timeout_s=5).client
        c.status()
        c.expect_ok("$13=0")
        c.close()
        assert main(args(tmp_path / "mm.csv")) == 0
    log = read_probe_log(tmp_path / "mm.csv")
    assert log.ok.all() and np.allclose(log.positions_mm()[0], [10, 10, 0], atol=1e-3)


def test_settings_that_do_not_say_the_units_are_refused():
    """No $13 in the listing, a $13 that is no number, or '$$' refused: nothing moves."""
    status = "<Idle|MPos:0.000,0.000,5.000|FS:0,0>"
    for answers, msg in [([status, "$0=10", "$10=1", "ok"], r"no \$13"),
                         ([status, "$13=x", "ok"], r"\$13 .* is 'x'"),
                         ([status, "error:8"], r"rejected '\$\$'.*\$13.*not idle"),
                         ([status, "ok"], "no setting")]:
        link = _ScriptLink(answers)
        with pytest.raises(HardwareError, match=msg):
            GrblBackend(GrblClient(link, timeout_s=0.2)).start()
        assert link.sent == ["?", "$$\n"]


def test_wpos_reports_wait_for_wco_without_warnings(tmp_path, capsys):
    """``$10=0`` (WPos reports, G54 offset set): the firmware adds WCO to one report in 10 when
    idle, so the first status queries cannot give MPos; that is the protocol, not an unexpected
    line (review F7: nine 'unexpected line' warnings, 0.5 s each). The touches equal $10=1's."""
    from conftest import LIMITS, plan_log
    from core.probelog import read_probe_log, write_probe_log
    from scenarios.cli import main

    plan = write_probe_log(tmp_path / "plan.csv", plan_log())
    logs = []
    for wpos in (False, True):
        emu = GrblEmulator(SimpleScene(), ControllerConfig(home=(0, 0, 50)))
        with TcpServer(emu, time_scale=FAST) as srv:
            c = connect(srv.url, timeout_s=5).client
            c.status()
            c.expect_ok("G10 L2 P1 X5 Y-3 Z2")          # a work offset: WPos != MPos
            if wpos:
                c.expect_ok("$10=0")
            c.status()              # a sender polled it since (as a GUI does): the forced WCO report is gone
            c.close()
            capsys.readouterr()
            out = tmp_path / f"log{int(wpos)}.csv"
            assert main(["probe", "--controller", srv.url, "--plan", str(plan), "--out", str(out),
                         "--limits-mm", LIMITS, "--safe-z-mm", "30", "--timeout-s", "5"]) == 0
            err = capsys.readouterr().err
            assert "unexpected" not in err and "warning" not in err, err
        logs.append(read_probe_log(out))
    assert np.array_equal(logs[0].positions_mm(), logs[1].positions_mm())


@pytest.mark.parametrize("serial, reset, said", [(True, False, True), (False, False, False), (True, True, False)])
def test_a_banner_at_connect_is_a_reset_on_a_serial_link_only(serial, reset, said):
    """GrblBackend.reset_at_connect: a banner read before the first status report means the board was
    reset when a serial port opened (DTR); over TCP it may be a network controller's greeting (Grbl_Esp32's
    telnet welcome), and after --reset it answers vmt's own Ctrl-X: then the position decides."""
    st = "<Idle|MPos:1.000,2.000,3.000|FS:0,0>"
    script = (["", BANNER] if reset else []) + ["", BANNER, st, "$13=0", "ok", "ok", "ok", "ok", st]
    link = _ScriptLink(script)
    link.resets_on_open, link.where = serial, "serial:///dev/ttyACM0" if serial else "grbl://h:1"
    be = GrblBackend(GrblClient(link, timeout_s=0.5), reset=reset)   # --reset: a banner answers its Ctrl-X
    be.start()
    why = be.reset_at_connect()
    assert (why is not None) == said
    if said:
        assert why.startswith(f"the controller printed its start-up banner ({BANNER!r}) when "
                              "serial:///dev/ttyACM0 was opened")
