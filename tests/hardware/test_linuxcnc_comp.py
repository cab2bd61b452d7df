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
