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


class ReplayLink:
    """A link that is the firmware of a transcript: answers what it answered, checks what is sent."""

    def __init__(self, lines):
        self.lines = deque(lines)
        self.pending = deque()
        self.sent = 0

    def send(self, data):
        text = data.decode("latin-1").strip() or repr(data.decode("latin-1"))
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
    from core.probelog import read_probe_log

    log = read_probe_log(tmp_path / "log.csv")
    assert list(log.col("status")) == ["ok", "ok", "no_trigger"]
    assert np.isnan(log.columns["X_mm"][2])
    # the stale report is named and not taken: it repeats touch 2
    assert any("repeats the last successful probe" in e for e in events)
    assert "90.0, 10.0, 0.0" in " ".join(events)


# ---- the emulator answers as the firmware did ------------------------------------------------

_NUM = re.compile(r"-?\d+\.\d+")


def _shape(line):
    """A line with the positions replaced: what must agree exactly."""
    if line.startswith("<"):
        return re.sub(r"(MPos|WPos|WCO):[-\d.,]+", r"\1:#", line)
    if line.startswith("[PRB:"):
        return _NUM.sub("#", line)
    return line


def replay_on_emulator(lines, emu, max_wait_s=120.0):
    """Send what was sent; collect as many lines as the firmware gave before the next send."""
    i, compared = 0, 0
    while i < len(lines):
        d, text = lines[i]
        assert d == ">"
        i += 1
        want = []
        while i < len(lines) and lines[i][0] == "<":
            want.append(lines[i][1])
            i += 1
        emu.receive(b"?" if text == "?" else (text + "\n").encode())
        got = emu.take_output()
        end = emu.now + max_wait_s
        while len(got) < len(want):
            te = emu.next_event()
            if te is None or te > end:
                break
            emu.advance_to(te)
            got += emu.take_output()
        assert [_shape(x) for x in got] == [_shape(x) for x in want], f"after {text!r}"
        for g, w in zip(got, want):
            if w.startswith("[PRB:"):
                assert np.allclose(parse_prb(g)[0], parse_prb(w)[0], rtol=0, atol=2e-3), (g, w)
        compared += len(want)
    assert emu.internal_errors == []
    return compared


def _first_mpos(lines):
    st = next(t for d, t in lines if t.startswith("<"))
    return tuple(float(v) for v in st.split("MPos:")[1].split("|")[0].split(","))


def test_emulator_answers_the_campaign_as_the_firmware_did():
    lines = transcript(CAMPAIGN)
    emu = GrblEmulator(SimpleScene(), ControllerConfig(home=_first_mpos(lines)))
    # the session before left GRBL's refresh counters here: its first WCO comes on report 4
    emu.set_report_counters(wco=3, ovr=3)
    n = replay_on_emulator(lines, emu)
    assert n == sum(d == "<" for d, _ in lines) == 78
    assert emu.probes == 12 and all(t for t, _ in emu.touches)


def test_emulator_answers_the_miss_as_the_firmware_did():
    lines = transcript(MISS)
    emu = GrblEmulator(SimpleScene(), ControllerConfig(home=_first_mpos(lines)))
    emu.set_report_counters(wco=9, ovr=9)
    n = replay_on_emulator(lines, emu)
    assert n == sum(d == "<" for d, _ in lines) == 23
    assert emu.state == "Alarm" and emu.alarm == 5
