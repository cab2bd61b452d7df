"""The emulator's GRBL 1.1h behaviour that the recorded transcripts pin down only in order,
not in time, and what they cannot show (homing, rotary axes, real contact geometry).

The firmware facts are cited from its sources (gnea/grbl 1.1h) or from the
recorded sessions in data/grbl-1.1h/.
"""

import math
import time

import numpy as np
import pytest

from core.exceptions import ConfigError
from hardware.emulator import (BANNER, MSG_UNLOCK, ControllerConfig, EmulatorRunner, GrblEmulator,
                               controller_for_machine)
from hardware.scene import SimpleScene


def say(emu, text):
    return [x for x in emu.feed_bytes(text.encode("latin-1") if isinstance(text, str) else text)[0] if x]


def step(emu, dt):
    """Advance emulated time by ``dt`` seconds; the lines printed meanwhile."""
    emu.advance_to(emu.now + dt)
    return [x for x in emu.take_output() if x]


def test_ok_means_queued_and_motion_takes_the_planned_time():
    """G1 X10 F600 at 100 mm/s^2: 0.1 s to 10 mm/s, cruise, 0.1 s to rest: 1.1 s in all."""
    emu = GrblEmulator(SimpleScene(), ControllerConfig(home=(0, 0, 50)))
    emu.receive(b"G1 X10 F600\n")
    assert emu.take_output() == ["ok"] and np.allclose(emu.pos_mm, [0, 0, 50])   # queued, not moved
    assert step(emu, 0.6) == [] and emu.state == "Run"
    assert emu.pos_mm[0] == pytest.approx(0.5 * 100 * 0.1 ** 2 + 10 * 0.5, abs=1e-9)     # 5.5 mm
    emu.receive(b"?")
    st = emu.take_output()[0]
    assert st.startswith("<Run|MPos:5.500,0.000,50.000|FS:600,0")    # the real feed, mm/min
    assert step(emu, 0.499) == [] and emu.state == "Run"
    step(emu, 0.002)
    assert emu.state == "Idle" and np.allclose(emu.pos_mm, [10, 0, 50])


def test_planner_holds_15_blocks_the_executing_one_included():
    """recorded-motion: 18 short moves, the 16th ok waited 9 s for the first block to finish."""
    emu = GrblEmulator(SimpleScene(), ControllerConfig(home=(0, 0, 50)))
    oks = []
    for k in range(16):
        emu.receive(f"G1 X{k + 1} F600\n".encode())
        oks.append(emu.take_output())
    assert oks[:15] == [["ok"]] * 15 and oks[15] == []          # the 16th waits
    t_first = 0.1 + 0.1                                           # 1 mm at 600 mm/min, 100 mm/s^2
    assert step(emu, t_first - 1e-6) == []
    assert step(emu, 2e-6) == ["ok"]                              # room after block 1


def test_hold_decelerates_then_resumes_and_the_rest_of_the_move_is_kept():
    emu = GrblEmulator(SimpleScene(), ControllerConfig(home=(0, 0, 50)))
    emu.receive(b"G1 X20 F600\n")
    step(emu, 0.5)
    emu.receive(b"!?")
    assert emu.take_output()[-1].startswith("<Hold:1|")
    emu.receive(b"~")                                  # ignored while decelerating (recorded-motion)
    step(emu, 0.1 + 1e-9)
    emu.receive(b"?")
    assert emu.take_output()[-1].startswith("<Hold:0|") and emu.pos_mm[0] == pytest.approx(4.5 + 0.5)
    emu.receive(b"~")
    assert emu.state_name() == "Run"
    step(emu, 10)
    assert emu.state == "Idle" and emu.pos_mm[0] == pytest.approx(20)


def test_power_on_alarm_with_homing_and_home_cycle():
    """$22=1: power-on in alarm (HOMING_INIT_LOCK); $H moves Z first, then the rest, at $25."""
    emu = GrblEmulator(SimpleScene(), ControllerConfig(home=(10, 20, 80), homing=True))
    assert emu.state == "Alarm" and emu.greeting() == ["", BANNER, MSG_UNLOCK]
    assert say(emu, "G1 X1 F100\n") == ["error:9"]
    assert say(emu, "$X\nG90 G1 X0 Y0 Z0 F1000\n") == ["[MSG:Caution: Unlocked]", "ok", "ok"]
    t0 = emu.now
    emu.receive(b"$H\n")
    step(emu, 1.0)
    assert emu.state_name() == "Home" and emu.pos_mm[2] > 0 and emu.pos_mm[0] == 0   # Z first
    emu.receive(b"\x18")                                   # reset while homing: ALARM:6
    assert emu.take_output()[0] == "ALARM:6"
    assert say(emu, "") [-2:] == [BANNER, MSG_UNLOCK]
    assert say(emu, "$H\n") == ["ok"] and emu.state == "Idle" and np.allclose(emu.pos_mm, [10, 20, 80])
    # seek 500 mm/min: Z 0 -> 80 and XY took at least (80 + 22.4) / (500/60) s of emulated time
    assert emu.now - t0 > (80 + math.hypot(10, 20)) / (500 / 60)
    off = GrblEmulator(SimpleScene())
    assert off.state == "Idle" and say(off, "$H\n") == ["error:5"]


def test_status_refresh_counters_after_a_reset():
    """report.c: WCO on the first report after a reset, Ov on the next, then every 10 idle."""
    emu = GrblEmulator(SimpleScene())
    fields = []
    for _ in range(22):
        s = say(emu, "?")[0]
        fields.append(("W" if "|WCO:" in s else "") + ("O" if "|Ov:" in s else ""))
    assert fields[0] == "W" and fields[1] == "O"
    assert [i for i, f in enumerate(fields) if "W" in f] == [0, 10, 20]
    assert [i for i, f in enumerate(fields) if "O" in f] == [1, 11, 21]


def test_rotary_axes_of_the_machine():
    """A 5-axis controller (grblHAL-like): its axes everywhere, $1x3/$1x4 settings, [AXS]."""
    emu = GrblEmulator(SimpleScene(), ControllerConfig(axes="XYZAC", home=(0, 0, 30, 0, 90)))
    assert say(emu, "?")[0].startswith("<Idle|MPos:0.000,0.000,30.000,0.000,90.000|")
    settings = say(emu, "$$\n")[:-1]
    assert len(settings) == 22 + 4 * 5 and "$104=1000.000" in settings and "$134=200.000" in settings
    assert say(emu, "$I\n")[2] == "[AXS:5:XYZAC]"
    assert say(emu, "G1 B1 F100\n") == ["error:20"]                 # no B axis
    assert say(emu, "G1 A15 C45 F1000\n") == ["ok"]
    assert say(emu, "G38.2 Z-10 F100\n")[0] == "[PRB:0.000,0.000,0.000,15.000,45.000:1]"
    assert say(emu, "$#\n")[0] == "[G54:0.000,0.000,0.000,0.000,0.000]"
    three = GrblEmulator(SimpleScene())
    assert len(say(three, "$$\n")) == 34 + 1 and len(say(three, "$I\n")) == 3      # GRBL 1.1: no AXS


def test_probing_away_from_real_geometry():
    """G38.4/G38.5 report where contact is lost; G38.2 where it is made (table at z = 0)."""
    emu = GrblEmulator(SimpleScene(spheres=()), ControllerConfig(home=(10, 10, -0.5)))
    assert say(emu, "?")[0].endswith("|Pn:P|WCO:0.000,0.000,0.000>")     # inside the table
    assert say(emu, "G38.4 Z1 F100\n") == ["[PRB:10.000,10.000,0.000:1]", "ok"]
    assert emu.pos_mm[2] > 0 and "Pn:P" not in say(emu, "?")[0]
    assert say(emu, "G38.5 Z2\n") == ["ALARM:4", "ok"]                      # not touching at start
    say(emu, "$X\n")
    assert say(emu, "G38.2 Z-1\n") == ["[PRB:10.000,10.000,0.000:1]", "ok"]
    # never leaves the table: ALARM:5, and the report repeats the last probe with :0 (the
    # firmware clears probe_succeeded at the start of every cycle, motion_control.c)
    assert say(emu, "G38.4 Z-0.5\n") == ["ALARM:5", "[PRB:10.000,10.000,0.000:0]", "ok"]


def test_controller_of_a_machine_description():
    """The seam for machine files: a machine's axes and strokes become the controller's."""
    from sim.machines import MACHINES

    c = controller_for_machine(MACHINES["nmv3000"]())
    assert c.axes == "XYZAC"
    assert c.travel[0] == pytest.approx((-160, 160)) and c.travel[3] == pytest.approx((-120, 30))
    assert c.home == pytest.approx((0, 0, 325, 0, 0))
    emu = GrblEmulator(SimpleScene(), c)
    assert emu.state == "Alarm"                       # soft limits need homing: power-on alarm
    assert say(emu, "$X\n")[-1] == "ok" and say(emu, "G1 X200 F100\n")[0] == "ALARM:2"
    with pytest.raises(ConfigError, match="expected XYZ then A, B, C"):
        ControllerConfig(axes="XYZCA")
    with pytest.raises(ConfigError, match="travel of X"):
        ControllerConfig(travel=((1, 0),))


def test_runner_time_scale():
    """A 1.1 s move at time scale 20 takes 55 ms of wall clock (within the runner's 20 ms tick)."""
    emu = GrblEmulator(SimpleScene(), ControllerConfig(home=(0, 0, 50)))
    runner = EmulatorRunner(emu, time_scale=20.0).start()
    try:
        t0 = time.monotonic()
        runner.send(None, b"G1 X10 F600\n")
        while emu.state != "Idle" or np.allclose(emu.pos_mm, [0, 0, 50]):
            time.sleep(0.002)
            assert time.monotonic() - t0 < 5
        wall = time.monotonic() - t0
    finally:
        runner.stop()
    assert 1.1 / 20 - 0.005 < wall < 1.1 / 20 + 0.2
    with pytest.raises(ConfigError, match="already has a runner"):
        EmulatorRunner(emu)
    with pytest.raises(ConfigError, match="time scale"):
        EmulatorRunner(GrblEmulator(SimpleScene()), time_scale=0)


def test_serial_receive_buffer_drops_what_a_busy_firmware_cannot_take():
    """serial.c: a ring of RX_BUFFER_SIZE + 1 = 129 slots, full when the next head would meet the
    tail: 128 bytes fit while a line waits (here a G38.2 behind a move), as [OPT:V,15,128] and
    serial_get_rx_buffer_available (128 - used) count them."""
    emu = GrblEmulator(SimpleScene(), ControllerConfig(home=(0, 0, 50)))
    emu.receive(b"G1 X100 F100\nG38.2 Z-60 F100\n")
    emu.receive(b"G1 X1\n" * 40)                        # 240 bytes: 128 kept
    assert emu._rx_dropped == 240 - 128
    out = say(emu, "")
    assert out.count("ok") == 1 + 1 + 21                # the move, the probe, 128 // 6 lines
    assert math.isclose(emu.pos_mm[0], 1.0)


def test_a_character_counting_sender_may_have_128_bytes_in_flight():
    """The review's case: a dwell holds the main loop, then exactly 128 bytes of lines (a sender
    counting characters against [OPT:...,128] sends that much): GRBL keeps them all; an emulator
    holding 127 dropped the last newline and ran 11 of the 12 lines."""
    emu = GrblEmulator(SimpleScene(), ControllerConfig(home=(0, 0, 30)))
    assert say(emu, b"$I\n")[1].startswith("[OPT:V,15,128]")
    assert say(emu, b"$10=3\n") == ["ok"]                # status reports show Bf:
    emu.receive(b"G4P5\n")
    buf = b"".join(b"G1X%02dF1000\n" % (k + 10) for k in range(10)) + b"G1X1F10\n" + b"G1X2F1000\n"
    assert len(buf) == 128
    emu.receive(buf)
    assert emu._rx_dropped == 0
    emu.receive(b"?")
    assert emu.take_output()[-1].split("|Bf:")[1].split("|")[0].endswith(",0")   # no room left
    emu.receive(b"G1X3F1000\n")                        # one byte more is dropped (the 129th)
    assert emu._rx_dropped > 0
    out, _ = emu.feed_bytes(b"", max_s=1e5)
    assert out.count("ok") == 1 + 12


def test_jog_cancel_and_overrides_act_at_once():
    """0x85 stops a jog with a controlled deceleration and flushes it; 0x91 (+10 % feed) shows in Ov."""
    emu = GrblEmulator(SimpleScene(), ControllerConfig(home=(0, 0, 50)))
    emu.receive(b"$J=G91 X-5 F300\n$J=G91 X-5 F300\n")
    assert emu.take_output() == ["ok", "ok"] and emu.state == "Jog"
    step(emu, 0.2)                                 # 5 mm/s reached after 0.05 s
    x0 = emu.pos_mm[0]
    emu.receive(b"\x85")
    step(emu, 0.05 + 1e-9)                         # 5 mm/s to rest at 100 mm/s^2: 0.05 s, 0.125 mm
    assert emu.state == "Idle" and emu.pos_mm[0] == pytest.approx(x0 - 0.125)
    assert step(emu, 5) == [] and emu.pos_mm[0] == pytest.approx(x0 - 0.125)   # both jogs flushed
    assert say(emu, b"G1 X0 F100\n") == ["ok"]     # the parser position followed the cancelled jog
    step(emu, 10)
    assert "|WCO:" in say(emu, "?")[0]             # the first report after power-on: WCO (Ov waits)
    emu.receive(b"\x91?")                          # an override change: Ov on the very next report
    assert emu.take_output()[-1].split("|Ov:")[1].startswith("110,100,100")


def test_without_a_travel_box_the_soft_limits_are_grbls_own():
    """limits.c: with $20=1 a target must lie in [-$13x, 0] (machine zero at the home switches)."""
    emu = GrblEmulator(SimpleScene(), ControllerConfig(home=(0, 0, 0), homing=True), start_in_alarm=False)
    assert say(emu, "$130=50\n$20=1\nG1 X-49 F1000\n") == ["ok", "ok", "ok"]
    assert say(emu, "G1 X-51\n") == ["ALARM:2", "[MSG:Reset to continue]"]
    assert say(emu, "?") == [] and say(emu, "$X\n") == []         # nothing until a reset
    assert say(emu, "\x18") == ["ok", BANNER, MSG_UNLOCK] and emu.pos_mm[0] == pytest.approx(-49)
    assert say(emu, "$X\n$J=G91 X50 F100\n") == ["[MSG:Caution: Unlocked]", "ok", "error:15"]


def test_power_cycle_sets_the_position_to_zero_where_the_machine_stands_and_home_restores_it():
    """GRBL's main(): a hardware reset (power-up, DTR) sets the machine position to 0 where the machine
    stands (memset(sys_position, 0)), powers on in alarm when homing is enabled, prints the banner; the
    machine itself has not moved, so the table (z = 0 in the old frame) is touched 40 mm lower in the
    new one. $H finds the switches where they were: the old frame again."""
    emu = GrblEmulator(SimpleScene(), ControllerConfig(home=(10, 20, 50), homing=True))
    assert say(emu, "$H\nG53 G90 G1 X30 Y30 Z40 F1000\n") == ["ok", "ok"]
    settings = dict(emu.settings)
    emu.power_cycle()
    assert emu.take_output() == ["", BANNER, MSG_UNLOCK] and emu.state == "Alarm"
    assert np.allclose(emu.pos_mm, 0) and np.allclose(emu.frame_mm, [30, 30, 40]) and emu.settings == settings
    assert say(emu, "$X\nG91 G38.2 Z-60 F300\n")[-2] == "[PRB:0.000,0.000,-40.000:1]"
    assert say(emu, "$H\n") == ["ok"] and np.allclose(emu.pos_mm, [10, 20, 50]) and np.allclose(emu.frame_mm, 0)
    assert say(emu, "G53 G90 G1 X30 Y30 Z10 F1000\nG91 G38.2 Z-20 F300\n")[-2] == "[PRB:30.000,30.000,0.000:1]"
    off = GrblEmulator(SimpleScene(), ControllerConfig(home=(0, 0, 5)))   # homing off: Idle after it
    off.power_cycle()
    assert off.take_output() == ["", BANNER] and off.state == "Idle" and np.allclose(off.frame_mm, [0, 0, 5])

