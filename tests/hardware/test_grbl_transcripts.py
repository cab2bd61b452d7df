"""The real GRBL 1.1h firmware's transcripts, replayed line by line.

1. To vmt's client: a fake link answers exactly as the firmware did and
   checks that every line vmt sends is the line the transcript shows, in
   order; every line of both transcripts is used.
2. To vmt's emulator: it receives what the client sent and must answer
   what the firmware answered, line by line. Positions aside: the
   firmware's stops after a contact depend on its host simulator's
   latency; the contact points themselves ([PRB]) must agree to 2 µm (two
   steps at 1000 steps/mm), since the emulator probes the same geometry.
"""

import re
from collections import deque
from pathlib import Path

import numpy as np
import pytest

from conftest import plan_log
from core.exceptions import HardwareError
from hardware.campaign import ProbeSettings, run_campaign
from hardware.emulator import ControllerConfig, GrblEmulator
from hardware.grbl import GrblBackend, GrblClient, parse_prb
from hardware.scene import SimpleScene

DATA = Path(__file__).parent / "data" / "grbl-1.1h"
CAMPAIGN = DATA / "grbl-1.1h-sim-vmt-campaign-transcript.txt"
MISS = DATA / "grbl-1.1h-sim-g38.2-miss-transcript.txt"
LIMITS_MM = ((-20, 200), (-20, 200), (-50, 100))


def transcript(path):
    """[(direction, text)] of a ``vmt probe --transcript`` file."""
    out = []
    for line in path.read_text().splitlines():
        t, d, text = line.split(" ", 2)
        float(t)
        assert d in "<>"
        out.append((d, text))
    return out


def firmware_settings():
    """The same firmware's answer to ``$$`` (recorded-protocol.txt: 1.1h, DEFAULTS_GENERIC, ``$13=0``)."""
    lines = transcript(DATA / "recorded-protocol.txt")
    k = lines.index((">", "$$"))
    out = []
    for d, t in lines[k + 1:]:
        assert d == "<"
        out.append(t)
        if t == "ok":
            return out


class ReplayLink:
    """A link that is the firmware of a transcript: answers what it answered, checks what is sent.

    The two campaign transcripts were recorded before vmt read the controller's
    settings (``$$``, for ``$13``: are reports in mm?) at the start: that one
    line, where the transcript has none, is answered with the same firmware's
    recorded ``$$`` listing (:func:`firmware_settings`) and counted in ``spliced``.
    """

    def __init__(self, lines):
        self.lines = deque(lines)
        self.pending = deque()
        self.sent = 0
        self.spliced = 0

    def send(self, data):
        text = data.decode("latin-1").strip() or repr(data.decode("latin-1"))
        if text == "$$" and not (self.lines and self.lines[0] == (">", "$$")):
            self.spliced += 1
            self.pending.extend(firmware_settings())
            return
        assert self.lines, f"vmt sent {text!r} after the transcript's end"
        d, want = self.lines.popleft()
        assert d == ">" and text == want, f"line {self.sent + 1} sent: vmt {text!r}, transcript {want!r}"
        self.sent += 1
        while self.lines and self.lines[0][0] == "<":
            self.pending.append(self.lines.popleft()[1])

    def readline(self, timeout_s):
        return self.pending.popleft() if self.pending else None

    def close(self):
        pass


def settings(feed):
    return ProbeSettings(probe_feed_mm_min=feed, move_feed_mm_min=2000.0, max_feed_mm_min=2000.0,
                         limits_mm=LIMITS_MM)


def test_client_replays_the_campaign_transcript(tmp_path):
    lines = transcript(CAMPAIGN)
    link = ReplayLink(lines)
    events = []
    be = GrblBackend(GrblClient(link, timeout_s=0.5, on_event=events.append))
    res = run_campaign(be, plan_log(), tmp_path / "log.csv", settings(200.0))
    assert not link.lines and not link.pending          # every line of the transcript used
    assert link.sent == sum(d == ">" for d, _ in lines) == 66
    assert link.spliced == 1                             # '$$', once, before anything moves
    assert res.rows_done == 12 and res.statuses == {"ok": 12}
    from core.probelog import read_probe_log

    log = read_probe_log(tmp_path / "log.csv")
    prb = [parse_prb(t)[0] for d, t in lines if t.startswith("[PRB")]
    assert np.array_equal(log.positions_mm(), np.array(prb))   # the controller's own numbers
    assert events == [] and be.client.unexpected == []


def test_client_replays_the_miss_transcript_alarm_5_wins(tmp_path):
    lines = transcript(MISS)
    link = ReplayLink(lines)
    events = []
    be = GrblBackend(GrblClient(link, timeout_s=0.5, on_event=events.append))
    with pytest.raises(HardwareError, match=r"ALARM:5 .*row 2 .*logged as no_trigger.*--resume --unlock"):
        run_campaign(be, plan_log(miss_rows=(2,)), tmp_path / "log.csv", settings(300.0))
    assert not link.lines and not link.pending          # down to the G90 refused with error:9
    assert lines[-2:] == [(">", "G90"), ("<", "error:9")]
    assert link.spliced == 1
    from core.probelog import read_probe_log

    log = read_probe_log(tmp_path / "log.csv")
    assert list(log.col("status")) == ["ok", "ok", "no_trigger"]
    assert np.isnan(log.columns["X_mm"][2])
    # the stale report is named and not taken: it repeats touch 2
    assert any("repeats the last successful probe" in e for e in events)
    assert "90.0, 10.0, 0.0" in " ".join(events)


# ---- the emulator answers as the firmware did ------------------------------------------------

_NUM = re.compile(r"-?\d+\.\d+")
_RT = {"?": b"?", "!": b"!", "~": b"~", "^X": b"\x18", "0x85": b"\x85"}


def _shape(line):
    """A line with the positions replaced: what must agree exactly.

    Status reports: positions (MPos, WPos, WCO) and the realtime feed aside; of the
    input pins only the probe (``P``): grbl-sim reads its limit and control pins
    as active (``Pn:XYZRHS``), and the emulator has no limit switches.
    """
    if line.startswith("<"):
        line = re.sub(r"(MPos|WPos|WCO):[-\d.,:]+", r"\1:#", line)
        line = re.sub(r"\|FS:[\d.]+,", "|FS:#,", line)
        line = re.sub(r"\|Pn:([A-Z]+)", lambda m: "|Pn:P" if "P" in m.group(1) else "", line)
        return line
    if line.startswith("[PRB:"):
        return _NUM.sub("#", line)
    return line


def replay_on_emulator(lines, emu, budget_s=600.0):
    """The emulator receives what was sent and must say what the firmware said, in order.

    Time aside: emulated time only runs while the firmware's next answer is
    awaited, and before a ``?`` until the emulator is in the state the
    firmware reported (never backwards). The whole answer stream is compared
    (after each send, never more lines than the firmware had given).
    """
    want = [t for d, t in lines if d == "<"]
    got = []

    def collect():
        got.extend(x for x in emu.take_output() if x != "")

    def run_until(pred):
        end = emu.now + budget_s
        while not pred():
            te = emu.next_event()
            if te is None or te > end:
                return
            emu.advance_to(te)
            collect()

    n_before = 0
    for i, (d, text) in enumerate(lines):
        if d == "<":
            n_before += 1
            continue
        n_after = n_before + next((k for k, (d2, _) in enumerate(lines[i + 1:]) if d2 == ">"),
                                  len(lines) - i - 1)
        if text == "?" and n_after > n_before and want[n_before].startswith("<"):
            state = want[n_before][1:].split("|")[0]
            run_until(lambda: emu.state_name() == state)
        emu.receive(_RT.get(text, (text + "\n").encode("latin-1")))
        collect()
        run_until(lambda: len(got) >= n_after)
        assert len(got) <= n_after, f"after {text!r}: extra {got[n_after:]}"
    assert [_shape(x) for x in got] == [_shape(x) for x in want]
    for g, w in zip(got, want):
        if w.startswith("[PRB:") and "PRB:0.000,0.000,0.000:0" not in w:
            assert np.allclose(parse_prb(g)[0], parse_prb(w)[0], rtol=0, atol=2e-3), (g, w)
    assert emu.internal_errors == []
    return len(want)


def _first_mpos(lines):
    st = next(t for d, t in lines if t.startswith("<"))
    return tuple(float(v) for v in st.split("MPos:")[1].split("|")[0].split(","))


def test_emulator_answers_the_campaign_as_the_firmware_did():
    lines = transcript(CAMPAIGN)
    emu = GrblEmulator(SimpleScene(), ControllerConfig(home=_first_mpos(lines)))
    # the session before left GRBL's refresh counters here: its first WCO comes on report 4
    emu.set_report_counters(wco=3, ovr=3)
    assert replay_on_emulator(lines, emu) == 78
    assert emu.probes == 12 and all(t for t, _ in emu.touches)


def test_emulator_answers_the_miss_as_the_firmware_did():
    lines = transcript(MISS)
    emu = GrblEmulator(SimpleScene(), ControllerConfig(home=_first_mpos(lines)))
    emu.set_report_counters(wco=9, ovr=9)
    assert replay_on_emulator(lines, emu) == 23
    assert emu.state == "Alarm" and emu.alarm == 5


# ---- sessions recorded from the firmware (grbl-sim, no contact model) -----------------------

class AlwaysTouching:
    """grbl-sim's probe pin: it always reads contact (``$6=1`` inverts it to never)."""

    def in_contact(self, pos_m, rot_rad=None):
        return True

    def probe_move(self, start_m, target_m, rot_rad=None):
        return True, np.asarray(start_m, dtype=float).copy()


#: GRBL 1.1h's DEFAULTS_GENERIC, as the recorded firmware had them.
GENERIC = dict(steps_per_unit=250.0, max_rate_per_min=500.0, accel_per_s2=10.0)
RECORDED = {
    # name: (controller, firmware lines answered)
    "protocol": (ControllerConfig(probe_invert=True, **GENERIC), 198),
    "probe_open": (ControllerConfig(probe_invert=True, **GENERIC), 58),
    "probe_closed": (ControllerConfig(**GENERIC), 31),
    "limits": (ControllerConfig(probe_invert=True, travel=((-50, 0),) * 3, **GENERIC), 26),
    "motion": (ControllerConfig(probe_invert=True, **GENERIC), 146),
}


@pytest.mark.parametrize("name", sorted(RECORDED))
def test_emulator_answers_recorded_sessions_as_the_firmware_did(name):
    lines = transcript(DATA / f"recorded-{name}.txt")
    config, n = RECORDED[name]
    # the sessions start after a reset (settings written, then Ctrl-X): no power-on alarm
    emu = GrblEmulator(AlwaysTouching(), config, start_in_alarm=False)
    assert replay_on_emulator(lines, emu) == n == sum(d == "<" for d, _ in lines)
