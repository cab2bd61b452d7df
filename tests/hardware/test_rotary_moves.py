"""Rotary axes turn only at the safe Z, alone (review fault F3).

The rule, for every motion sequence vmt writes or sends: a line that changes
A, B or C starts at the safe Z and leaves X, Y, Z where they are; a set-up
change is retract along the approach, Z alone up to the safe Z, the turn
alone, X, Y across at the safe Z, then down; a program's first motion is Z
alone. Checked by reading back what is written (the LinuxCNC part program,
the GRBL dry run) and what is sent (a live campaign on an in-process virtual
machine, and on the GRBL emulator of a 5-axis controller, line by line).
Before the fix the first motion was one combined ``X Y Z A B C`` move and
every set-up change turned the table during the rise, 2 mm from the part.
"""

import re

import numpy as np
import pytest

from conftest import LIMITS, LIMITS_MM, plan_log, scene
from core.exceptions import PlanError
from core.probelog import make_log, read_probe_log, write_probe_log
from hardware.backend import VirtualBackend
from hardware.campaign import ProbeSettings, plan_steps, program_lines, run_campaign
from hardware.emulator import ControllerConfig, GrblEmulator, TcpServer
from hardware.grbl import connect
from hardware.linuxcnc import part_program
from scenarios.cli import main

SAFE_Z = 30.0
#: (A, C) of each row: 4 table rows at (0, 0), 4 sphere rows at C 90, 4 at A 10, C 180: the table
#: turns before the first touch (its angles unknown) and at two set-up changes
ROT = [(0.0, 0.0)] * 4 + [(0.0, 90.0)] * 4 + [(10.0, 180.0)] * 4
#: a word's value equal to a known coordinate: both come from the same double, printed with at
#: least 4 decimals (0.05 um, 0.00005 deg); 1e-3 is far above that and far below any real move
SAME = 1e-3
WORD = re.compile(r"([A-Z])(-?\d+(?:\.\d*)?)")


def rotary_plan():
    plan = plan_log()
    cols = dict(plan.columns)
    cols["A_deg"] = np.array([a for a, _ in ROT])
    cols["C_deg"] = np.array([c for _, c in ROT])
    cols["setup"] = np.array([f"A{a:g}C{c:g}" for a, c in ROT], dtype=object)
    return make_log(cols, plan.meta)


class Motion:
    """Follows absolute feed moves and probes line by line; asserts the turn rule at each line.

    ``state``: X, Y, Z (NaN: not known), A, B, C (NaN: not known). A probing line ends
    at the touch, not at its end point: X, Y, Z are unknown after it until the next move.
    """

    def __init__(self, safe_z):
        self.safe_z = safe_z
        self.xyz = np.full(3, np.nan)
        self.rot = np.full(3, np.nan)
        self.turns = []          # (line, X, Y, Z, A, B, C) of every line that turns
        self.first_motion = None

    def feed(self, line):
        """An absolute move (``G1 ...``, ``G53 G90 G1 ...``) or a probing line (``G38.x``)."""
        words = dict((a, float(v)) for a, v in WORD.findall(line) if a in "XYZABC")
        probing = "G38." in line
        if self.first_motion is None and words:
            self.first_motion = line
        if probing:
            assert not set(words) & set("ABC"), f"a probing move turns: {line}"
            self.xyz[:] = np.nan
            return
        new_rot = self.rot.copy()
        for i, a in enumerate("ABC"):
            if a in words:
                new_rot[i] = words[a]
        turn = bool(np.any(np.isnan(self.rot) != np.isnan(new_rot))
                    or np.any(np.abs(np.nan_to_num(new_rot) - np.nan_to_num(self.rot)) > 1e-9))
        before = self.xyz.copy()
        for i, a in enumerate("XYZ"):
            if a in words:
                self.xyz[i] = words[a]
        if turn:
            assert abs(before[2] - self.safe_z) < SAME, f"turns below the safe Z (Z {before[2]}): {line}"
            for i, a in enumerate("XYZ"):     # nothing else moves: a word repeats a known coordinate
                if a in words:
                    assert not np.isnan(before[i]) and abs(words[a] - before[i]) < SAME, \
                        f"{a} moves during a turn (from {before[i]}): {line}"
            self.turns.append((line, *self.xyz, *new_rot))
        self.rot = new_rot


def follow(lines, safe_z=SAFE_Z):
    m = Motion(safe_z)
    for ln in lines:
        if re.match(r"(G53 G90 )?G1 |G91 G38\.|G38\.", ln):
            m.feed(ln)
    return m


def expect_turns(m, from_xy=None):
    """One turn before the first touch, one at each of the two set-up changes, to the plan's angles;
    the first motion is Z alone to the safe Z (a live run knows X, Y: ``from_xy``, unchanged)."""
    assert [(t[4], t[6]) for t in m.turns] == [(0.0, 0.0), (0.0, 90.0), (10.0, 180.0)], m.turns
    assert all(abs(t[3] - SAFE_Z) < SAME for t in m.turns)
    words = dict((a, float(v)) for a, v in WORD.findall(m.first_motion) if a in "XYZABC")
    assert words.pop("Z") == SAFE_Z, m.first_motion
    assert words == ({} if from_xy is None else dict(zip("XY", from_xy))), m.first_motion


def settings(**kw):
    return ProbeSettings(limits_mm=LIMITS_MM, safe_z_mm=SAFE_Z, **kw)


def test_linuxcnc_program_turns_only_at_safe_z_alone():
    text = part_program(rotary_plan(), settings(), axes="XYZAC")
    m = follow(text.splitlines())
    expect_turns(m)
    lines = text.splitlines()
    # the set-up change, line by line: retract, Z up alone, turn alone, across, down, probe
    k = next(i for i, ln in enumerate(lines) if "C90.0000" in ln)
    retract, label, rise, turn, across, down, probe = lines[k - 3:k + 4]
    xy = lambda ln: re.findall(r"[XY]-?\d+\.\d+", ln)          # noqa: E731
    z = lambda ln: float(re.search(r"Z(-?\d+\.\d+)", ln).group(1))  # noqa: E731
    assert retract.startswith("G1 ") and "G38.2" in lines[k - 5] and label.startswith("(row 4 ")
    assert lines[k - 4].startswith("(LOG,N3 G1 X#5061 Y#5062 Z#5063 G91 G38.2 X")         # the touch before, logged with its row
    assert xy(rise) == xy(retract) and z(rise) == SAFE_Z and z(retract) < SAFE_Z
    assert turn == rise.replace(" F", " A0.0000 C90.0000 F")      # the controller's rotary axes only
    assert z(across) == SAFE_Z and xy(across) != xy(turn) and xy(down) == xy(across) and z(down) < SAFE_Z
    assert probe.startswith("G38.2 ")


def test_grbl_dry_run_turns_only_at_safe_z_alone(tmp_path, capsys):
    plan = write_probe_log(tmp_path / "plan.csv", rotary_plan())
    assert main(["probe", "--controller", "grbl://127.0.0.1:1", "--plan", str(plan), "--out",
                 str(tmp_path / "log.csv"), "--limits-mm", LIMITS, "--safe-z-mm", str(SAFE_Z),
                 "--rotary", "--axes", "XYZAC", "--dry-run"]) == 0
    lines = capsys.readouterr().out.splitlines()
    m = follow(lines)
    expect_turns(m)
    assert m.first_motion == f"G53 G90 G1 Z{SAFE_Z:.4f} F1000.0"
    assert not (tmp_path / "log.csv").exists()


class Recording(VirtualBackend):
    """The in-process virtual machine, writing each commanded move as the line GRBL would get."""

    def __init__(self, *a, **kw):
        super().__init__(*a, **kw)
        self.lines = []

    def move(self, target_m, feed_mm_min, rot_rad=None):
        from hardware.grbl import move_line

        rot = None if rot_rad is None else np.degrees(rot_rad)
        self.lines.append(move_line(np.asarray(target_m) * 1e3, feed_mm_min, rot, "ABC"))
        super().move(target_m, feed_mm_min, rot_rad)

    def probe(self, target_m, feed_mm_min, *, allow_miss=False):
        self.lines.append("G38.2 (to %s)" % np.round(np.asarray(target_m) * 1e3, 4).tolist())
        self.rots = getattr(self, "rots", []) + [np.degrees(self._rot).round(9).tolist()]
        return super().probe(target_m, feed_mm_min, allow_miss=allow_miss)


def test_live_campaign_turns_only_at_safe_z_alone(tmp_path):
    be = Recording(scene(), home_m=(0.05, 0.05, 0.01))
    run_campaign(be, rotary_plan(), tmp_path / "log.csv", settings())
    m = follow(be.lines)
    expect_turns(m, from_xy=(50.0, 50.0))
    # and every touch was made at its row's angles
    assert be.rots == [[a, 0.0, c] for a, c in ROT]


def test_resumed_campaign_turns_again_at_safe_z(tmp_path):
    """A resume does not know where the table stands: it rises, turns at the safe Z, then goes on."""
    out = tmp_path / "log.csv"
    plan = rotary_plan()
    first = Recording(scene(), home_m=(0.05, 0.05, 0.01))
    run_campaign(first, plan.select(np.arange(6)), out, settings())
    text = out.read_text().splitlines()
    be = Recording(scene(), home_m=(0.06, 0.04, 0.0))
    run_campaign(be, plan, out, settings(), resume=True)
    m = follow(be.lines)
    assert [(t[4], t[6]) for t in m.turns] == [(0.0, 90.0), (10.0, 180.0)]
    assert be.rots == [[a, 0.0, c] for a, c in ROT[6:]]
    assert read_probe_log(out).n == 12 and out.read_text().splitlines()[:len(text)] == text


def test_emulated_5_axis_grbl_gets_turns_only_at_safe_z_alone(tmp_path):
    """The lines a 5-axis GRBL (XYZAC) receives in a live campaign, as sent on the wire."""
    emu = GrblEmulator(scene(), ControllerConfig(axes="XYZAC", home=(0, 0, 30)))
    sent = []
    with TcpServer(emu, time_scale=1000) as srv:
        be = connect(srv.url, timeout_s=5, rotary=True)
        inner = be.client.link.send
        be.client.link.send = lambda data: (sent.append(data.decode().strip()), inner(data))[1]
        try:
            res = run_campaign(be, rotary_plan(), tmp_path / "log.csv", settings())
        finally:
            be.close()
    assert res.rows_done == 12 and res.statuses == {"ok": 12}
    moves = [ln for ln in sent if ln.startswith(("G53 G90 G1", "G91 G38."))]
    expect_turns(follow(moves), from_xy=(0.0, 0.0))      # the emulator's home: X0 Y0 Z30
    assert all(" B" not in ln for ln in moves)          # a controller without B never gets one
    log = read_probe_log(tmp_path / "log.csv")
    assert log.ok.all()


def test_rotary_program_without_safe_z_is_refused(tmp_path, capsys):
    """No safe Z: no height is known to be clear of the part, so nothing that turns is written or sent."""
    plan = rotary_plan()
    no_z = ProbeSettings(limits_mm=LIMITS_MM)
    with pytest.raises(PlanError, match=r"row 0 .*rotary axes are commanded.*--safe-z-mm"):
        part_program(plan, no_z, axes="XYZAC")
    with pytest.raises(PlanError, match=r"row 0 .*--safe-z-mm"):
        program_lines(plan_steps(plan, no_z), no_z, rotary=True)
    out = tmp_path / "log.csv"
    with pytest.raises(PlanError, match=r"row 0 .*--safe-z-mm"):   # the table's angles at the start: unknown
        run_campaign(VirtualBackend(scene()), plan, out, no_z)
    assert not out.exists()
    p = write_probe_log(tmp_path / "plan.csv", plan)
    capsys.readouterr()
    assert main(["machine", "program", "--plan", str(p), "--out", str(tmp_path / "p.ngc"),
                 "--limits-mm", LIMITS, "--axes", "XYZAC"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "--safe-z-mm" in err and "Traceback" not in err
    assert not (tmp_path / "p.ngc").exists()
    # a plan that turns nothing is written as before: no rotary words, straight to each approach start
    flat = part_program(plan_log(), no_z)
    assert not re.search(r" [ABC]-?\d", flat)


def test_program_reproduces_the_live_campaign_touch_for_touch(tmp_path):
    """The LinuxCNC program, read line by line on the same virtual machine (G1 moves, G38.2 probes
    from where the machine stands, A B C modal), touches where the live campaign touches, at the
    same angles: the same probing lines, start and end, to the program's 6 decimals."""
    plan = rotary_plan()
    live = Recording(scene(), home_m=(0.05, 0.05, 0.01))
    run_campaign(live, plan, tmp_path / "log.csv", settings())
    log = read_probe_log(tmp_path / "log.csv")
    machine = scene()
    pos, rot, touches, rots = np.full(3, np.nan), np.zeros(3), [], []
    for ln in part_program(plan, settings(), axes="XYZAC").splitlines():
        w = dict((a, float(v)) for a, v in WORD.findall(ln) if a in "XYZABC")
        if ln.startswith("G1 "):
            for i, a in enumerate("XYZ"):
                pos[i] = w.get(a, pos[i])
            for i, a in enumerate("ABC"):
                rot[i] = w.get(a, rot[i])
        elif ln.startswith("G38.2 "):
            end = np.array([w["X"], w["Y"], w["Z"]])
            hit, q = machine.probe_move(pos * 1e-3, end * 1e-3, np.radians(rot))
            assert hit
            touches.append(np.asarray(q) * 1e3)
            rots.append(rot.round(9).tolist())
            pos = np.asarray(q) * 1e3
    assert rots == live.rots
    # the program's points carry 6 decimals (0.5 nm per axis); a touch moves by at most about as much
    assert np.abs(np.array(touches) - log.positions_mm()).max() < 2e-6


def test_safe_z_below_an_approach_start_is_refused(tmp_path, capsys):
    """A safe Z below an approach start would make the rise a descent toward the part: refused, naming the row,
    before anything is written or sent (for plans that turn and plans that do not)."""
    for plan in (rotary_plan(), plan_log()):
        steps = plan_steps(plan, ProbeSettings(limits_mm=LIMITS_MM))
        top = max(range(len(steps)), key=lambda i: steps[i].start_mm[2])
        z = steps[top].start_mm[2]
        low = ProbeSettings(limits_mm=LIMITS_MM, safe_z_mm=z - 0.5)
        with pytest.raises(PlanError, match=rf"row {steps[top].row} .*above the safe Z {z - 0.5:g} mm"):
            part_program(plan, low, axes="XYZAC")
        with pytest.raises(PlanError, match=r"above the safe Z"):
            run_campaign(VirtualBackend(scene()), plan, tmp_path / "log.csv", low)
        assert not (tmp_path / "log.csv").exists()
        part_program(plan, ProbeSettings(limits_mm=LIMITS_MM, safe_z_mm=z), axes="XYZAC")   # at the start's height
    p = write_probe_log(tmp_path / "plan.csv", plan)
    capsys.readouterr()
    assert main(["machine", "program", "--plan", str(p), "--out", str(tmp_path / "p.ngc"), "--limits-mm", LIMITS,
                 "--safe-z-mm", f"{z - 0.5:g}"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "above the safe Z" in err and "Traceback" not in err
    assert not (tmp_path / "p.ngc").exists()


def test_rotary_probe_without_safe_z_is_refused_before_connecting(tmp_path, capsys):
    """`vmt probe --rotary` with no safe Z is refused before the controller is reached: port 9 on loopback
    (discard: nothing listens here) would fail to connect if the check came after."""
    p = write_probe_log(tmp_path / "plan.csv", rotary_plan())
    capsys.readouterr()
    assert main(["probe", "--controller", "grbl://127.0.0.1:9", "--plan", str(p), "--out", str(tmp_path / "l.csv"),
                 "--limits-mm", LIMITS, "--rotary"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "--safe-z-mm" in err and "connect" not in err.lower()
    assert not (tmp_path / "l.csv").exists()
