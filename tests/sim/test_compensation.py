"""The controller's compensation on the virtual machine (sim.compensation).

Known answers from LinuxCNC's code (compute_screw_comp: linear between
entries, end trims held, forward/reverse by direction; TYPE 0 loader:
trim = nominal - forward), and closed loops through the exact chain: a
table written from the truth removes it on a table-side and on a tool-side
axis alike (the issue's bug was a doubled tool-side error).
"""

import numpy as np
import pytest

from core import iso
from core.exceptions import ConfigError
from sim.compensation import AxisCompensation, ErrorModel, JointTable, VolumetricCompensation
from sim.errorfuncs import Constant, Polynomial, SplineTable
from sim.machine import Machine
from sim.machines import MACHINES, realistic_errors


def test_joint_table_known_answer():
    # TYPE 0: nominal, forward, reverse (where the joint really is when
    # commanded there, moving + / -): at 100 mm it is 10 um long moving +, 4 um
    # short moving -
    t = JointTable.from_type0([[0.0, 0.0, 0.0], [0.100, 0.100010, 0.099996]])
    assert t.fwd_trim_m == (0.0, pytest.approx(-10e-6)) and t.rev_trim_m == (0.0, pytest.approx(4e-6))
    p = np.array([-0.05, 0.0, 0.05, 0.100, 0.2])
    np.testing.assert_allclose(t.trim(p, +1), [0, 0, -5e-6, -10e-6, -10e-6], rtol=0, atol=1e-15)
    np.testing.assert_allclose(t.trim(p, -1), [0, 0, 2e-6, 4e-6, 4e-6], rtol=0, atol=1e-15)


@pytest.mark.parametrize("rows, match", [
    ([[0.0, 0.0, 0.0], [0.0, 0.0, 0.0]], "must increase"),
    ([[0.0, 0.0]], r"\(k, 3\)"),
    ([[0.0, np.nan, 0.0]], "finite"),
    ([[i * 1e-3, 0, 0] for i in range(257)], "at most 256"),
])
def test_joint_table_bad_input(rows, match):
    with pytest.raises(ConfigError, match=match):
        JointTable.from_type0(rows)


def test_axis_compensation_bad_input():
    m = Machine(MACHINES["vmc-3axis"]())
    t = JointTable.from_type0([[0, 0, 0]])
    with pytest.raises(ConfigError, match="linear axes"):
        AxisCompensation(m, {"C": t})
    with pytest.raises(ConfigError, match="idle_direction"):
        AxisCompensation(m, {"X": t}, idle_direction=0)
    with pytest.raises(ConfigError, match="joint_offset_m"):
        AxisCompensation(m, {"X": t}, joint_offset_m=(0, 0))


@pytest.mark.parametrize("name", ["vmc-3axis", "mikron-ucp710"])
def test_positioning_table_from_the_truth_removes_it_table_or_tool_side(name):
    """EXX (ISO, 38 um over the stroke) on a table-side X (vmc-3axis) and on a
    tool-side X (Mikron): a TYPE 0 table with forward = nominal + EXX(nominal)
    every 5 mm brings the tool to the commanded X to the table's linear
    interpolation of a quadratic (h^2 max|EXX''| / 8 = 2.5e-5 m^2 x 1e-4 /m / 8
    ~ 3e-10 m) plus EXX' x EXX (the table is read at the command, the error
    acts at the actual position: 6e-5 x 38e-6 ~ 2.3e-9 m): < 5 nm."""
    f = Polynomial((0.0, 6e-5, 1e-4))  # EXX(x) = 60 um/m x + 100 um/m^2 x^2
    cfg = MACHINES[name](errors={"EXX": f})
    m = Machine(cfg)
    x = np.arange(-0.355, 0.3551, 0.005)
    t = JointTable.from_type0(np.column_stack([x, x + f(x), x + f(x)]))
    comp = AxisCompensation(m, {"X": t})
    lin = np.column_stack([np.linspace(-0.29, 0.29, 59), np.full(59, 0.05), np.full(59, 0.1)])
    rot = None if not m.rotary_axes else np.zeros((59, len(m.rotary_axes)))
    before = m.tip_W(lin, rot) - lin
    after = comp.tip_W(lin, rot) - lin
    assert np.abs(before[:, 0]).max() > 20e-6
    assert np.abs(after).max() < 5e-9, np.abs(after).max()
    # the same table with the opposite column meaning (corrected command in
    # the forward column) doubles the error instead: the file's meaning matters
    wrong = AxisCompensation(m, {"X": JointTable.from_type0(np.column_stack([x, x - f(x), x - f(x)]))})
    assert np.allclose(wrong.tip_W(lin, rot) - lin, 2 * before, rtol=0, atol=5e-9)


def test_direction_picks_the_column_and_idle_is_stated():
    m = Machine(MACHINES["vmc-3axis"]())
    t = JointTable.from_type0([[-1.0, -1.0 + 2e-6, -1.0 - 2e-6], [1.0, 1.0 + 2e-6, 1.0 - 2e-6]])
    lin = np.zeros((3, 3))
    d = np.array([[1, 0, 0], [-1, 0, 0], [0, 0, 0]])
    tip = AxisCompensation(m, {"X": t}, idle_direction=-1).tip_W(lin, None, None, d)
    np.testing.assert_allclose(tip[:, 0], [-2e-6, 2e-6, 2e-6], rtol=0, atol=1e-15)


def _on_node_errors(cfg, nodes):
    """21 errors the tables represent exactly: C2 splines through the realistic
    profiles at the nodes (not-a-knot, end tangents), and the squarenesses."""
    errs = realistic_errors(("X", "Y", "Z"), strokes=cfg.strokes, J_m=cfg.J_m, ripple=False)
    out = {}
    for s, f in errs.items():
        sy = iso.symbol(s)
        if sy.location:
            out[s] = f
        else:
            x = nodes[sy.axis]
            out[s] = SplineTable(tuple(x), tuple(np.asarray(f(x), float)))
    return out


@pytest.mark.parametrize("name", ["vmc-3axis", "mikron-ucp710"])
def test_volumetric_model_equal_to_the_truth_compensates_exactly(name, rng):
    """The 21 errors as tables that represent the truth exactly: the corrected
    command puts the tip where a perfect machine would, to the fixed point's
    convergence (three steps, < 1e-12 m), at any rotary position."""
    cfg0 = MACHINES[name]()
    nodes = {a: np.linspace(*cfg0.strokes[a], 9) for a in "XYZ"}
    errs = _on_node_errors(cfg0, nodes)
    m = Machine(MACHINES[name](errors=errs))
    tables = {s: (nodes[iso.symbol(s).axis], np.asarray(f(nodes[iso.symbol(s).axis]), float))
              for s, f in errs.items() if not iso.symbol(s).location}
    const = {s: f.value for s, f in errs.items() if iso.symbol(s).location}
    comp = VolumetricCompensation(m, ErrorModel(cfg0.chain, tables, const, dict(cfg0.rotary_points_R_m)))
    lin = np.column_stack([rng.uniform(*cfg0.strokes[a], 50) * 0.9 for a in "XYZ"])
    rot = None if not m.rotary_axes else np.column_stack(
        [rng.uniform(-0.5, 0.5, 50) for _ in m.rotary_axes])
    nominal = m.tip_W_nominal(lin, rot)
    assert np.abs(m.tip_W(lin, rot) - nominal).max() > 20e-6
    assert np.abs(comp.tip_W(lin, rot) - nominal).max() < 1e-12


def test_volumetric_bad_input():
    with pytest.raises(ConfigError, match="ErrorModel"):
        VolumetricCompensation(Machine(MACHINES["vmc-3axis"]()), {"EXX": Constant(0.0)})


@pytest.mark.parametrize("name", ["vmc-3axis", "mikron-ucp710"])
def test_tables_indexed_by_joint_position_compensate_any_stylus(name, rng):
    """The truth's motion errors are functions of the axis (joint) position reading + J
    (sim.machine), so a table written from them against joint positions compensates every
    stylus: LinuxCNC's per-joint table (EXX, EZZ: looked up at reading + the mounted stylus's J)
    to its linear interpolation (< 5 nm, as above), the volumetric model exactly (< 1e-12 m).
    Looked up at the reading instead (joint_offset_m = 0) the Z table misses by EZZ's slope x
    J_Z: 150-250 mm x ~1e-4 > 1 um."""
    fx, fz = Polynomial((0.0, 6e-5, 1e-4)), Polynomial((0.0, -8e-5, 2e-4))
    x = np.arange(-0.5, 0.7001, 0.005)
    tables = {"X": JointTable.from_type0(np.column_stack([x, x + fx(x), x + fx(x)])),
              "Z": JointTable.from_type0(np.column_stack([x, x + fz(x), x + fz(x)]))}
    cfg0 = MACHINES[name]()
    nodes = {a: np.linspace(cfg0.strokes[a][0] - 0.2, cfg0.strokes[a][1] + 0.3, 9) for a in "XYZ"}
    errs = _on_node_errors(cfg0, nodes)
    vtab = {s: (nodes[iso.symbol(s).axis], np.asarray(f(nodes[iso.symbol(s).axis]), float))
            for s, f in errs.items() if not iso.symbol(s).location}
    const = {s: f.value for s, f in errs.items() if iso.symbol(s).location}
    model = ErrorModel(cfg0.chain, vtab, const, dict(cfg0.rotary_points_R_m))
    lin = np.column_stack([rng.uniform(-0.2, 0.2, 40), rng.uniform(-0.1, 0.1, 40), rng.uniform(0.0, 0.2, 40)])
    for J in ((-0.100, 0.0, 0.150), (0.0, -0.100, 0.250)):
        m = Machine(MACHINES[name](errors={"EXX": fx, "EZZ": fz}, J_m=J))
        rot = None if not m.rotary_axes else np.zeros((40, len(m.rotary_axes)))
        nominal = m.tip_W_nominal(lin, rot)
        assert np.abs(m.tip_W(lin, rot) - nominal).max() > 5e-6  # ~9 um uncompensated
        assert np.abs(AxisCompensation(m, tables).tip_W(lin, rot) - nominal).max() < 5e-9
        at_reading = AxisCompensation(m, tables, joint_offset_m=(0.0, 0.0, 0.0)).tip_W(lin, rot) - nominal
        assert np.abs(at_reading[:, 2]).max() > 1e-6
        mv = Machine(MACHINES[name](errors=errs, J_m=J))
        assert np.abs(mv.tip_W(lin, rot) - nominal).max() > 20e-6
        assert np.abs(VolumetricCompensation(mv, model).tip_W(lin, rot) - nominal).max() < 1e-12
