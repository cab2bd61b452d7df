"""Real LinuxCNC closes the loop on rotary axes with vmt's rotary compensation files.

``make test-controllers`` (not ``make test``); never skipped: without LinuxCNC every test fails
(tests/controllers/conftest.py). The chain, end to end:

1. Truth: the nmv3000 (X Y Z A C) with one error, C's angular positioning error
   ``ECC(theta)`` (a first and a second harmonic and a constant, periodic in the turn).
2. An ISO 230-2 test of C at 0, 30, ..., 330 deg read through the exact chain
   (:class:`sim.machine.Machine`: the table's actual angle from ``T_R_W``), written
   as a positioning log, and ``vmt iso230-2 --comp-file C.comp`` (the project's
   path): 12 targets, less than a turn, so the file gets the two lines that close
   the turn (-30 deg with 330's deviations, 360 deg with 0's). A has a hand-made
   table with different forward and reverse columns (lost motion), so LinuxCNC's
   choice of column by direction is checked too.
3. LinuxCNC 2.9 (``hardware/linuxcnc_sim/vmt_rotary.ini``: trivkins X Y Z A C,
   C not wrapped) loads both files with its own mechanism (``[JOINT_n] COMP_FILE``,
   ``COMP_FILE_TYPE = 0``, ``usrmotLoadComp()``) and runs a program that turns C
   through the turn and beyond (-390 .. 790 deg, across 330 -> 360 and 0 -> -30 both
   ways) and A both ways, dwelling at each stop; ``vmt_joints.py`` reads back, at
   each stop, each joint's command (``pos-cmd``) and what LinuxCNC sends the motor
   (``motor-pos-cmd``).
4. Each read-back trim (motor command minus command) is compared with what the
   file says at that angle, as LinuxCNC documents and implements its tables
   (``compute_screw_comp()``, control.c: linear between lines, the forward column
   after a + move and the reverse after a -, the end lines held beyond the file):
   through :class:`sim.compensation.JointTable` (vmt's model of LinuxCNC) and by hand
   at the lines and midpoints.
5. The motor commands LinuxCNC produced are put through the exact chain again: the
   C error before (at the command) and after (at LinuxCNC's motor command).
6. A second run loads C's table written with ``--comp-range-deg=-400:800`` (the
   joint's limits in vmt_rotary.ini): the turn repeated every 360 deg, so the stops
   beyond the first file's lines (-390 .. 790 deg) are compensated too; the first run
   shows LinuxCNC holding the end lines there.
7. A third run makes C ``WRAPPED_ROTARY``: the program's C words are angles modulo
   360 and the interpreter counts turns (``unwrap_rotary()``, interp_find.cc: C10
   after C350 is joint position 370), so the joint leaves the first file's lines in
   ordinary use; the ranged file covers it.

Tolerances (each stated where asserted): the trims agree to the table's steepest slope
times one servo period's last step (``compute_screw_comp()`` takes the trim at the joint's
command while it moves and keeps it when ``vel_cmd`` is 0, so the trim held at a stop is
the one at the last servo period in motion, at most ``a T^2 = 1440 deg/s^2 * (1 ms)^2 =
1.44e-3 deg`` short of the stop: 4e-8 deg on A's steepest segment; measured up to 2e-9 deg;
doubles otherwise, the file's values parsed alike by LinuxCNC's sscanf and numpy); after compensation
the C error at the tested angles is at most the file's rounding (6 decimals:
0.5e-6 deg = 8.7 nrad) plus ECC's change over the trim (< 1 nrad), between them at
most the linear interpolation's bound ``h^2 / 8 * max|ECC''|`` (h = 30 deg).
"""

import json

import numpy as np
import pytest

from core.positioning import make_positioning_log, write_positioning_log
from hardware.linuxcnc import read_comp_file
from scenarios.cli import main
from sim.compensation import JointTable
from sim.errorfuncs import Constant, Periodic
from sim.machine import Machine
from sim.machines import MACHINES

#: C's angular positioning error (rad) as a function of the angle (rad): periodic in the turn
ECC = Periodic(12e-6, 2 * np.pi, 0.3) + Periodic(4e-6, np.pi, 1.0) + Constant(2e-6)
#: ECC'' bound (rad/rad^2): 12e-6 * 1^2 + 4e-6 * 2^2
ECC_D2_MAX = 12e-6 + 4 * 4e-6
C_TARGETS = np.arange(0.0, 360.0, 30.0)          # deg: 12 targets, less than a turn
C_STEP = 30.0
#: A's hand-made test: mean deviations (deg) approaching in + and in - (up minus down 0.0008 .. 0.0016 deg)
A_TARGETS = np.array([-90.0, -45.0, 0.0, 45.0, 90.0])
A_UP = np.array([0.0012, 0.0004, -0.0003, 0.0009, 0.0015])
A_DOWN = np.array([-0.0004, -0.0006, -0.0011, 0.0001, 0.0007])
#: The program's stops: (axis, angle deg). C through the turn and beyond, both ways; then A both ways.
C_STOPS = [-60, -30, -15, 0, 15, 45, 100, 123.456, 180, 250, 315, 330, 345, 359, 360, 375, 420, 530, 790,
           700, 350, 340, 300, 200, 95, 5, 0, -10, -29, -45, -60, -200, -390, -375, 10]
#: C's joint limits in vmt_rotary.ini, deg: the range the second file covers
C_RANGE = (-400.0, 800.0)
#: WRAPPED_ROTARY C: (the program's C word, the joint position rs274ngc's unwrap_rotary() makes of it). A word
#: is an angle modulo 360 (|word| < 360); positive: the nearest such position at or above the joint's, in the
#: joint's turn or the next; negative: at or below it.
W_STOPS = [(350, 350), (10, 370), (100, 460), (270, 630), (-200, 560), (-10, 370), (-300, 300)]
A_STOPS = [-90, -60, -20, 0, 45, 70, 90, 100, 60, 22.5, 0, -45, -80, -90, -100, -30]
#: s at each stop: vmtjoints writes a stop once its pins held still SETTLE_S = 0.1 s; the rest is margin for a
#: userspace poll loop starved on a loaded machine (a missed stop fails match_stops, naming it)
DWELL_S = 0.5
JOINT = {"X": 0, "Y": 1, "Z": 2, "A": 3, "C": 4}      # trivkins coordinates=XYZAC
#: The last step in motion before a stop, deg: the joints' MAX_ACCELERATION (vmt_rotary.ini) x the servo period^2
LAST_STEP_DEG = 1440.0 * 1e-3 ** 2
ROUND_RAD = np.radians(0.5e-6)                        # the file's 6 decimals, deg


def machine():
    return Machine(MACHINES["nmv3000"](errors={"ECC": ECC}))


def c_actual_deg(m, c_deg):
    """The table's actual C angle (deg) when C is at ``c_deg``, from the exact chain: W turns by -C about
    the C line (sim.machine), so the angle is minus the rotation about Z of ``T_R_W``; unwrapped to the
    commanded angle's turn."""
    c = np.radians(np.atleast_1d(np.asarray(c_deg, float)))
    m_rot = np.column_stack([np.zeros_like(c), c])
    R = m.T_R_W(np.zeros((len(c), 3)), m_rot)[:, :3, :3]
    act = -np.arctan2(R[:, 1, 0], R[:, 0, 0])
    return np.degrees(c + np.angle(np.exp(1j * (act - c))))


def trim_tol(rows):
    """deg: the steepest trim slope of a table's lines (either column) times :data:`LAST_STEP_DEG`, plus
    doubles' rounding (1e-12 deg)."""
    r = np.asarray(rows, float)
    slope = np.abs(np.diff(r[:, 0:1] - r[:, 1:], axis=0) / np.diff(r[:, 0])[:, None]).max()
    return float(slope * LAST_STEP_DEG + 1e-12)


def positioning_log(targets, up, down, axis):
    tg, cy, di, me = [], [], [], []
    for c in (1, 2, 3, 4, 5):
        for d, dev in (("+", up), ("-", down)):
            order = range(len(targets)) if d == "+" else reversed(range(len(targets)))
            for i in order:
                tg.append(targets[i]), cy.append(c), di.append(d), me.append(targets[i] + dev[i])
    return make_positioning_log(tg, cy, di, me, unit="deg", meta={"axis": axis})


def program(stops, words=None):
    """G0 to each stop (``words``: the words to write instead of the stops' angles), dwelling there."""
    lines = ["%", "(vmt rotary compensation loop: each stop held for the joints' read-back)",
             "G21 G90 G94 G17", "G0 X0 Y0 Z0 A0 C0"]
    for k, (axis, ang) in enumerate(stops):
        lines += [f"G0 {axis}{ang if words is None else words[k]:.6f}", f"G4 P{DWELL_S}"]
    return "\n".join(lines + ["M2", "%"]) + "\n"


def match_stops(joint_log, stops):
    """The record of each stop, in order: the first record after the previous stop's whose pos_cmd is the
    stop's (every other joint where the program left it). Start-up and homing records come first."""
    want = np.zeros(5)
    out, k = [], 0
    for axis, ang in stops:
        want[JOINT[axis]] = ang
        while k < len(joint_log) and not np.allclose(joint_log[k]["pos_cmd"], want, rtol=0, atol=1e-9):
            k += 1
        assert k < len(joint_log), f"no record of the stop {axis}{ang} (records: {len(joint_log)})"
        out.append(joint_log[k])
        k += 1
    return out


@pytest.fixture(scope="module")
def runs(tmp_path_factory):
    """Two LinuxCNC runs: ``default`` (C's file with the two closing lines, A's file; C then A moved),
    ``ranged`` (C's file over C_RANGE; C moved)."""
    from hardware.linuxcnc_sim.loop import run_program

    tmp = tmp_path_factory.mktemp("rotary")
    m = machine()
    actual = c_actual_deg(m, C_TARGETS)
    dev = actual - C_TARGETS
    clog = write_positioning_log(tmp / "c.csv", positioning_log(C_TARGETS, dev, dev, "C"))
    alog = write_positioning_log(tmp / "a.csv", positioning_log(A_TARGETS, A_UP, A_DOWN, "A"))
    for log, comp, extra in ((clog, "C.comp", []), (alog, "A.comp", []),
                             (clog, "C-ranged.comp", [f"--comp-range-deg={C_RANGE[0]:g}:{C_RANGE[1]:g}"])):
        assert main(["iso230-2", str(log), "--json", str(tmp / (comp + ".json")), "--comp-file",
                     str(tmp / comp), *extra]) == 0
    out = {}
    for name, stops, files, words, wrapped in (
            ("default", [("C", float(a)) for a in C_STOPS] + [("A", float(a)) for a in A_STOPS],
             {"C": tmp / "C.comp", "A": tmp / "A.comp"}, None, ()),
            ("ranged", [("C", float(a)) for a in C_STOPS], {"C": tmp / "C-ranged.comp"}, None, ()),
            ("wrapped", [("C", float(j)) for _, j in W_STOPS], {"C": tmp / "C-ranged.comp"},
             [float(w) for w, _ in W_STOPS], ("C",))):
        prog = tmp / f"{name}.ngc"
        prog.write_text(program(stops, words))
        res = run_program(prog, None, out_dir=tmp / name, config="vmt_rotary.ini", comp_files=files,
                          wrapped_rotary=wrapped, timeout_s=240)
        assert res.ok, f"LinuxCNC ({name}): {res.errors}\n{res.output[-3000:]}"
        out[name] = (stops, {a: read_comp_file(f) for a, f in files.items()}, res)
    return tmp, m, dev, out


def test_the_files_close_the_turn(runs):
    """C's file: the 12 targets and the two closing lines; its deviations the chain's ECC (known answer:
    actual - target = +ECC(target) on this machine's C, to the file's 6 decimals). The ranged file: every
    30 deg from -420 to 810 (the lines at or beyond C_RANGE's ends), each line the deviation of its angle
    modulo 360."""
    tmp, m, dev, out = runs
    rows = read_comp_file(tmp / "C.comp")
    assert list(rows[:, 0]) == [-30.0, *C_TARGETS, 360.0]
    assert np.allclose(dev, np.degrees(ECC(np.radians(C_TARGETS))), rtol=0, atol=1e-12)
    assert np.allclose(rows[1:-1, 1] - rows[1:-1, 0], dev, rtol=0, atol=0.5e-6 + 1e-12)
    # -30 carries 330's deviations, 360 carries 0's (each line rounded to 6 decimals on its own: 1e-9)
    assert np.allclose(rows[0, 1:] - rows[0, 0], rows[-2, 1:] - rows[-2, 0], rtol=0, atol=1e-9)
    assert np.allclose(rows[-1, 1:] - rows[-1, 0], rows[1, 1:] - rows[1, 0], rtol=0, atol=1e-9)
    arows = read_comp_file(tmp / "A.comp")
    assert list(arows[:, 0]) == [-270.0, *A_TARGETS, 270.0]
    ranged = read_comp_file(tmp / "C-ranged.comp")
    assert list(ranged[:, 0]) == list(np.arange(-420.0, 811.0, 30.0))
    ecc_deg = np.degrees(ECC(np.radians(ranged[:, 0])))
    assert np.allclose(ranged[:, 1] - ranged[:, 0], ecc_deg, rtol=0, atol=0.5e-6 + 1e-9)


@pytest.mark.parametrize("name", ["default", "ranged", "wrapped"])
def test_linuxcnc_commands_what_the_file_says_at_every_angle(runs, name):
    """At every stop, motor-pos-cmd - pos-cmd of A and C equals the file's trim at the joint's command, in
    the column of the joint's last move (forward after +, reverse after -; a joint not moved since start-up:
    none, LinuxCNC keeps its initial 0), linear between lines, the end lines' trims held beyond them
    (compute_screw_comp, control.c). Both through JointTable and by hand at chosen angles."""
    tmp, m, dev, out = runs
    stops, files, res = out[name]
    recs = match_stops(res.joint_log, stops)
    tabs = {a: JointTable.from_type0(r) for a, r in files.items()}
    tol = {a: trim_tol(r) for a, r in files.items()}
    pos = {"A": 0.0, "C": 0.0}
    last_dir = {"A": 0, "C": 0}
    got, want, rows = {"A": [], "C": []}, {"A": [], "C": []}, []
    for (axis, ang), r in zip(stops, recs):
        if ang != pos[axis]:
            last_dir[axis] = 1 if ang > pos[axis] else -1
        pos[axis] = ang
        assert r["motor_offset"] == [0.0] * 5, r             # immediate homing at HOME 0: no motor offset
        for a in ("A", "C"):
            j = JOINT[a]
            trim = r["motor_pos_cmd"][j] - r["pos_cmd"][j]
            exp = 0.0 if last_dir[a] == 0 or a not in tabs else float(tabs[a].trim(np.array([pos[a]]),
                                                                                   last_dir[a])[0])
            got[a].append(trim), want[a].append(exp)
        rows.append(f"{axis}{ang:+9.3f}  A trim {got['A'][-1]:+.9f} (file {want['A'][-1]:+.9f})  "
                    f"C trim {got['C'][-1]:+.9f} (file {want['C'][-1]:+.9f}) deg")
    for a in ("A", "C"):
        assert np.allclose(got[a], want[a], rtol=0, atol=tol.get(a, 0.0)), "\n".join(rows)
    if name == "wrapped":
        return
    if name == "ranged":
        # by hand: beyond the first file's lines, the repeated turn (trim of the angle modulo 360)
        c0 = {r[0]: r for r in read_comp_file(tmp / "C.comp")}
        c_trim = {ang: g for (axis, ang), g in zip(stops, got["C"]) if axis == "C"}
        f60, f90 = c0[60.0][0] - c0[60.0][1], c0[90.0][0] - c0[90.0][1]
        assert c_trim[790.0] == pytest.approx(f60 + (f90 - f60) / 3, abs=tol["C"])     # 70 deg's place, moving +
        assert c_trim[-390.0] == pytest.approx(c0[330.0][0] - c0[330.0][2], abs=tol["C"])   # 330's, moving -
        return
    # by hand, from the file's lines (trim = nominal - forward, resp. reverse)
    crow = {r[0]: r for r in read_comp_file(tmp / "C.comp")}
    fwd = {k: v[0] - v[1] for k, v in crow.items()}
    rev = {k: v[0] - v[2] for k, v in crow.items()}
    c_trim = {ang: g for (axis, ang), g in zip(stops, got["C"]) if axis == "C"}
    assert c_trim[345.0] == pytest.approx((fwd[330.0] + fwd[0.0]) / 2, abs=tol["C"])   # the closing segment
    assert c_trim[360.0] == pytest.approx(fwd[0.0], abs=tol["C"])                     # back at 0's place
    assert c_trim[375.0] == pytest.approx(fwd[0.0], abs=tol["C"])                     # beyond: held
    assert c_trim[420.0] == pytest.approx(fwd[0.0], abs=tol["C"])
    assert c_trim[-15.0] == pytest.approx((fwd[330.0] + fwd[0.0]) / 2, abs=tol["C"])  # below 0, moving +
    assert c_trim[-45.0] == pytest.approx(rev[330.0], abs=tol["C"])                   # below -30: held
    assert c_trim[340.0] == pytest.approx(rev[330.0] + (rev[0.0] - rev[330.0]) / 3, abs=tol["C"])
    arow = {r[0]: r for r in read_comp_file(tmp / "A.comp")}
    a_trim = {}
    for (axis, ang), g in zip(stops, got["A"]):
        if axis == "A":
            a_trim.setdefault(ang, []).append(g)
    assert a_trim[45.0][0] == pytest.approx(45.0 - arow[45.0][1], abs=tol["A"])       # reached moving +
    assert a_trim[-45.0][0] == pytest.approx(-45.0 - arow[-45.0][2], abs=tol["A"])    # reached moving -
    assert a_trim[0.0][0] == pytest.approx(-arow[0.0][1], abs=tol["A"])
    assert a_trim[0.0][1] == pytest.approx(-arow[0.0][2], abs=tol["A"])
    assert got["A"][:len(C_STOPS)] == [0.0] * len(C_STOPS)                                 # A not moved yet


def c_errors(m, stops, res):
    """(commands, motor commands, error before, error after): C's stops, deg, and errors, rad."""
    recs = match_stops(res.joint_log, stops)
    j = JOINT["C"]
    cmd = np.array([r["pos_cmd"][j] for (axis, _), r in zip(stops, recs) if axis == "C"])
    motor = np.array([r["motor_pos_cmd"][j] for (axis, _), r in zip(stops, recs) if axis == "C"])
    before = np.radians(c_actual_deg(m, cmd) - cmd)               # rad: the machine without compensation
    after = np.radians(c_actual_deg(m, motor) - cmd)              # rad: at LinuxCNC's motor command
    return cmd, motor, before, after


def test_the_c_error_through_the_exact_chain_before_and_after(runs):
    """LinuxCNC's motor commands through the exact chain: at the tested angles the C error falls from ECC to
    the file's rounding; between them, inside the file's lines (-30 .. 360 deg, across 330 -> 360 and
    0 -> -30), to the interpolation bound; beyond the lines LinuxCNC holds the end trims, so there the
    error is ECC(angle) - ECC(end line's angle): stated, not compensated. With the ranged file every stop
    (-390 .. 790 deg) is within the interpolation bound."""
    tmp, m, dev, out = runs
    stops, files, res = out["default"]
    cmd, motor, before, after = c_errors(m, stops, res)
    assert np.allclose(before, ECC(np.radians(cmd)), rtol=0, atol=1e-12)   # the chain reads ECC back
    tested = np.isclose(np.mod(cmd, C_STEP), 0) & (cmd >= -30) & (cmd <= 360)
    inside = (cmd >= -30) & (cmd <= 360)
    bound = (np.radians(C_STEP) ** 2 / 8) * ECC_D2_MAX           # 0.96 urad
    # the file's rounding, the trim held from the last step in motion (trim_tol), and ECC's change over the
    # trim (max|ECC'| 20e-6 x 0.001 deg: 3.5e-10 rad) within the last 1e-9 rad
    slack = ROUND_RAD + np.radians(trim_tol(read_comp_file(tmp / "C.comp"))) + 1e-9
    assert np.all(np.abs(after[tested]) <= slack), after[tested]
    assert np.all(np.abs(after[inside]) <= bound + slack), after[inside]
    beyond = ~inside
    end = np.where(cmd[beyond] > 360, 0.0, 330.0)                 # the line LinuxCNC holds there
    held = ECC(np.radians(cmd[beyond])) - ECC(np.radians(end))
    assert np.allclose(after[beyond], held, rtol=0, atol=slack), (cmd[beyond], after[beyond], held)
    stops2, files2, res2 = out["ranged"]
    cmd2, motor2, before2, after2 = c_errors(m, stops2, res2)
    assert np.array_equal(cmd2, cmd) and np.array_equal(before2, before)
    slack2 = ROUND_RAD + np.radians(trim_tol(files2["C"])) + 1e-9
    on_line = np.isclose(np.mod(cmd2, C_STEP), 0) | np.isclose(np.mod(cmd2, C_STEP), C_STEP)
    assert np.all(np.abs(after2[on_line]) <= slack2), after2[on_line]
    assert np.all(np.abs(after2) <= bound + slack2), (cmd2, after2)
    figures = {"c_stops": int(len(cmd)), "inside_lines": int(inside.sum()),
               "before_max_urad": round(float(np.abs(before).max() * 1e6), 3),
               "after_tested_max_urad": round(float(np.abs(after[tested]).max() * 1e6), 4),
               "after_inside_max_urad": round(float(np.abs(after[inside]).max() * 1e6), 3),
               "interpolation_bound_urad": round(bound * 1e6, 3),
               "beyond_lines": {f"{c:g}": round(float(a * 1e6), 3) for c, a in zip(cmd[beyond], after[beyond])},
               "before_beyond_urad": {f"{c:g}": round(float(b * 1e6), 3) for c, b in zip(cmd[beyond], before[beyond])},
               "ranged_after_max_urad": round(float(np.abs(after2).max() * 1e6), 3),
               "ranged_after_beyond_first_lines_urad": {f"{c:g}": round(float(a * 1e6), 3)
                                                        for c, a in zip(cmd2[beyond], after2[beyond])},
               "run_s": [round(res.run_s, 1), round(res2.run_s, 1)], "wall_s": [round(res.wall_s, 1),
                                                                                 round(res2.wall_s, 1)]}
    (tmp / "rotary_figures.json").write_text(json.dumps(figures))
    print(f"\nLinuxCNC rotary compensation loop: {json.dumps(figures)}")


def test_a_wrapped_c_counts_turns_and_the_ranged_file_follows(runs):
    """WRAPPED_ROTARY C: LinuxCNC took each C word to the joint position unwrap_rotary() gives (C10 after C350
    is 370: match_stops finds every stop at W_STOPS' joint positions, in order), looked the ranged file up there
    (the trims: test_linuxcnc_commands_what_the_file_says_at_every_angle[wrapped]), and the C error through the
    exact chain is within the interpolation bound at every stop. The first file would have held its 360 line
    (0's trim) at 370 .. 630 deg: its trims there, from JointTable (checked against LinuxCNC beyond the lines in
    the default run), give the errors printed beside."""
    tmp, m, dev, out = runs
    stops, files, res = out["wrapped"]
    cmd, motor, before, after = c_errors(m, stops, res)
    assert list(cmd) == [float(j) for _, j in W_STOPS]
    slack = ROUND_RAD + np.radians(trim_tol(files["C"])) + 1e-9
    bound = (np.radians(C_STEP) ** 2 / 8) * ECC_D2_MAX
    assert np.all(np.abs(after) <= bound + slack), (cmd, after)
    first = JointTable.from_type0(read_comp_file(tmp / "C.comp"))
    dirs = np.sign(np.diff(np.r_[0.0, cmd]))
    held = np.radians(c_actual_deg(m, cmd + first.trim(cmd, dirs)) - cmd)
    figures = {"joint_deg": [float(c) for c in cmd], "words": [w for w, _ in W_STOPS],
               "before_urad": [round(float(b * 1e6), 3) for b in before],
               "after_ranged_urad": [round(float(a * 1e6), 3) for a in after],
               "first_file_would_leave_urad": [round(float(h * 1e6), 3) for h in held],
               "run_s": round(res.run_s, 1)}
    print(f"\nLinuxCNC wrapped C: {json.dumps(figures)}")
