"""LinuxCNC per-joint compensation files: the columns LinuxCNC documents, and a closed loop.

LinuxCNC's docs (ini-config.adoc, COMP_FILE_TYPE = 0): "nominal (commanded)
position", then "the actual position as the joint is moving in the positive
direction", then in the negative direction. With an ISO 230-1 positioning
error E (actual minus commanded, tool relative to the part) the actual
position is nominal + E.
"""

from types import SimpleNamespace

import numpy as np
import pytest

from core.exceptions import ConfigError
from hardware.linuxcnc import COMP_SIZE, comp_file, read_comp_file
from sim.compensation import AxisCompensation, JointTable
from sim.errorfuncs import Polynomial
from sim.machine import Machine
from sim.machines import MACHINES


def _result(nodes_m, f):
    """A stand-in identification: tables on ``nodes_m`` per axis, E = f(x)."""
    return SimpleNamespace(design=SimpleNamespace(nodes={a: np.asarray(nodes_m, float) for a in "XYZ"}),
                           value=lambda s, x: f(np.asarray(x, float)))


def test_type0_columns_known_answer(tmp_path):
    # E(x) = 2 um + 10 um/m x: at 100 mm the joint really reaches 100.003 mm
    res = _result([0.0, 0.1], lambda x: 2e-6 + 1e-5 * x)
    assert comp_file(res, "X") == "0.000000 0.002000 0.002000\n100.000000 100.003000 100.003000\n"
    # Z indexed by the joint with a 150 mm probe: nominal = reading + 150 mm
    z = comp_file(res, "Z", joint_offset_m=0.150)
    assert z.splitlines()[1] == "250.000000 250.003000 250.003000"
    p = tmp_path / "Z.comp"
    p.write_text(z)
    np.testing.assert_allclose(read_comp_file(p), [[150, 150.002, 150.002], [250, 250.003, 250.003]])
    assert len(comp_file(res, "Y", step_m=0.005).splitlines()) == 21


def test_range_adds_the_stroke_ends_on_the_tables_continuation():
    # review29b F1: a line at each end of range_m beyond the nodes, valued by the table's own
    # continuation (res.value: the end tangent for an identified table; here E = 2 um + 10 um/m x
    # everywhere), so LinuxCNC's linear interpolation between lines gives that continuation exactly;
    # a range inside the nodes adds nothing (the file never shrinks)
    res = _result([0.0, 0.1], lambda x: 2e-6 + 1e-5 * x)
    assert comp_file(res, "X", range_m=(-0.05, 0.2)) == ("-50.000000 -49.998500 -49.998500\n"
                                                         "0.000000 0.002000 0.002000\n"
                                                         "100.000000 100.003000 100.003000\n"
                                                         "200.000000 200.004000 200.004000\n")
    assert comp_file(res, "X", range_m=(0.01, 0.09)) == comp_file(res, "X")
    t = comp_file(res, "X", step_m=0.005, range_m=(-0.05, 0.2)).splitlines()
    assert len(t) == 23 and t[0].startswith("-50.000000 ") and t[-1].startswith("200.000000 ")


@pytest.mark.parametrize("rng", [(0.2, -0.05), (float("nan"), 0.2), (0.0, float("inf"))])
def test_comp_file_bad_range(rng):
    with pytest.raises(ConfigError, match="range_m must be finite"):
        comp_file(_result([0.0, 0.1], lambda x: 0 * x), "X", range_m=rng)


@pytest.mark.parametrize("kw, match", [
    (dict(axis="Q"), "axis must be X, Y or Z"),
    (dict(axis="X", step_m=0.0), "step_m must be > 0"),
    (dict(axis="X", step_m=1e-4), f"at most {COMP_SIZE}"),
    (dict(axis="X", joint_offset_m=float("nan")), "joint_offset_m must be finite"),
])
def test_comp_file_bad_input(kw, match):
    with pytest.raises(ConfigError, match=match):
        comp_file(_result([0.0, 0.1], lambda x: 0 * x), **kw)


@pytest.mark.parametrize("text, match", [
    ("0 0 0\n1 1\n", "line 2: expected three finite numbers"),
    ("0 0 0\nx 1 1\n", "line 2: 'x' is not a number"),
    ("1 1 1\n0 0 0\n", "line 2: nominal 0 does not increase"),
    ("\n", "empty compensation file"),
    ("0 nan 0\n", "line 1: expected three finite"),
])
def test_read_comp_file_bad_lines(tmp_path, text, match):
    p = tmp_path / "bad.comp"
    p.write_text(text)
    with pytest.raises(ConfigError, match=match):
        read_comp_file(p)
    with pytest.raises(ConfigError, match="no such file"):
        read_comp_file(tmp_path / "none.comp")


@pytest.mark.parametrize("name, side", [("vmc-3axis", "workpiece"), ("mikron-ucp710", "tool")])
def test_written_file_applied_as_linuxcnc_removes_the_error(tmp_path, name, side):
    """Writer -> file -> reader -> LinuxCNC's arithmetic on the exact machine: a
    60 um/m + 100 um/m^2 EXX is removed on a table-side and on a tool-side X to
    the controller's linear interpolation over 5 mm plus EXX' x EXX (< 5 nm,
    tests/sim/test_compensation.py); the joint indexed with a 150 mm offset."""
    f = Polynomial((0.0, 6e-5, 1e-4))
    m = Machine(MACHINES[name](errors={"EXX": f}))
    assert m.chain.side("X") == side
    p = tmp_path / "X.comp"
    p.write_text(comp_file(_result([-0.355, 0.355], f), "X", step_m=0.005, joint_offset_m=0.150))
    comp = AxisCompensation(m, {"X": JointTable.from_type0(read_comp_file(p) * 1e-3)},
                            joint_offset_m=(0.150, 0.0, 0.0))
    lin = np.column_stack([np.linspace(-0.3, 0.3, 61), np.full(61, 0.02), np.full(61, 0.1)])
    rot = None if not m.rotary_axes else np.zeros((61, 2))
    assert np.abs(m.tip_W(lin, rot) - lin).max() > 20e-6
    # the file rounds to 1 nm (6 decimals in mm)
    assert np.abs(comp.tip_W(lin, rot) - lin).max() < 6e-9


@pytest.mark.parametrize("name", ["vmc-3axis", "mikron-ucp710"])
def test_positioning_test_comp_table_closed_loop_with_a_probe_offset(tmp_path, name):
    """ISO 230-2 test of Z (probe J_Z 150 mm) -> positioning-log/1 file -> TYPE 0 table -> applied as
    LinuxCNC applies it (at the joint, reading + J) -> the test again. EZZ (the truth, at the axis
    position q = reading + 150 mm) = 20 um/m q + 300 um/m^2 q^2 + a 3 um lead (Reversal): ISO 230-2's
    E 98 um (vmc-3axis) and 101 um (Mikron) before. The table must sit at the axis positions
    target + J (the log's tool_offset_mm): read at the targets as they are (the readings), every lookup
    lands 150 mm off and leaves f(q) - f(q - 150 mm), 12-52 um (E 42 um measured). With the table in
    the right place the retest reads the targets themselves (no interpolation error there), and what
    is left is EZZ' x EZZ (the table is read at the command, the error acts at the actual position:
    3.5e-4 x 110e-6 = 0.04 um) plus the file's 1 nm rounding: 0.036 um measured on both machines;
    bound 0.1 um (2.5 x the predicted term), E likewise."""
    from dataclasses import replace

    from core.positioning import iso230_2, read_positioning_log, write_positioning_log
    from hardware.linuxcnc import positioning_comp_file
    from sim.errorfuncs import Reversal
    from sim.positioning import positioning_plan, simulate_positioning

    f = Polynomial((0.0, 2e-5, 3e-4)) + Reversal(3e-6)
    cfg = MACHINES[name](errors={"EZZ": f})
    cfg = replace(cfg, J_m=(0.0, 0.0, 0.150))
    m = Machine(cfg)
    rng = np.random.default_rng(1)
    plan = positioning_plan(m, "Z", rng=rng)
    p = tmp_path / "Z.csv"
    write_positioning_log(p, simulate_positioning(m, plan, rng))
    log = read_positioning_log(p)
    before = iso230_2(log)
    assert before.E > 0.080  # mm
    c = tmp_path / "Z.comp"
    c.write_text(positioning_comp_file(log))
    table = read_comp_file(c)
    comp = AxisCompensation(m, {"Z": JointTable.from_type0(table * 1e-3)})  # looked up at reading + J_m
    after = iso230_2(simulate_positioning(comp, plan, rng))
    assert np.abs(after.mean_up).max() < 1e-4 and np.abs(after.mean_down).max() < 1e-4, after.to_report()
    assert after.E < 1e-4, after.E
    assert log.meta["tool_offset_mm"] == "0.0,0.0,150.0" and log.joint_offset == 150.0
    np.testing.assert_allclose(table[:, 0], np.unique(log.target) + 150.0, rtol=0, atol=1e-9)
    # the same table at the targets as written (the readings): 150 mm off
    wrong = np.column_stack([table[:, 0] - 150.0, table[:, 1:] - 150.0])
    off = iso230_2(simulate_positioning(AxisCompensation(m, {"Z": JointTable.from_type0(wrong * 1e-3)}), plan, rng))
    assert off.E > 0.010


def test_positioning_comp_file_known_answer_and_no_offset():
    """Two targets, two cycles: forward / reverse = nominal + the mean deviation per direction; the
    nominal column is target + J of the axis (Y here), target as it is without the key."""
    from core.positioning import make_positioning_log
    from hardware.linuxcnc import positioning_comp_file

    rows = dict(target=[0, 100, 100, 0, 0, 100, 100, 0], cycle=[1, 1, 1, 1, 2, 2, 2, 2],
                direction=["+", "+", "-", "-", "+", "+", "-", "-"])
    dev = np.array([0.001, 0.003, 0.002, 0.000, 0.003, 0.005, 0.002, 0.002])
    meas = np.array(rows["target"], float) + dev
    log = make_positioning_log(rows["target"], rows["cycle"], rows["direction"], meas,
                               meta={"axis": "Y", "tool_offset_mm": "1,-20.5,150"})
    assert positioning_comp_file(log) == ("-20.500000 -20.498000 -20.499000\n"
                                          "79.500000 79.504000 79.502000\n")
    plain = make_positioning_log(rows["target"], rows["cycle"], rows["direction"], meas, meta={"axis": "Y"})
    assert positioning_comp_file(plain).splitlines()[1] == "100.000000 100.004000 100.002000"
