"""The C axis's reported values against the exact simulator with single injected errors.

The self-calibration reports EXC, EYC,total and ECC as the tool relative to
the part (ISO 230-1). A table-side C line at c = (EX0C, EY0C) carries the
part, so the tool relative to the part moves by (R(-C) - I) c after the gauge
(0 at C = 0): a circle centred on -c. Worked by hand for EX0C = +12 um:
C = 75 deg gives 12 (cos 75 - 1, -sin 75) = (-8.894, -11.591) um, 130 deg
(-19.713, -9.193), 210 deg (-22.392, 6.000). The reported line (minus the
fitted centre) is then +c.

Tolerance 0.01 um: the identification is first order, the simulator exact;
the terms it leaves out are of order e^2 / L (12 um squared over the 0.1 m
lever of the pocket: 1.4 nm), five times below it; a wrong sign is off by
2|c| (> 10 um).
"""

from __future__ import annotations

import numpy as np
import pytest

from core.units import DEG, UM, URAD

TOL_UM = 0.01


def _identify(errors: dict, rotary_points=None, grid=(-0.110, 0.110, 0.022)):
    """A noise-free case-1 campaign (cross pocket at eq 19's angles, nmv3000) with ``errors`` only
    (``rotary_points``: the C axis's position in R, m; ``grid`` None: identify's own)."""
    t, res, machine, _ = _identify_log(errors, rotary_points, grid)
    return t, res, machine


def _identify_log(errors: dict, rotary_points=None, grid=(-0.110, 0.110, 0.022)):
    """:func:`_identify` and the probe log it identified."""
    from core.selfcal import Grid, self_calibrate
    from core.touches import from_log
    from scenarios.crosspocket import CROSS_ANGLES_DEG
    from sim import artefacts as A
    from sim.campaign import simulate_campaign
    from sim.catalog import make_plan
    from sim.machine import Machine
    from sim.machines import MACHINES
    from sim.probe import ProbeConfig

    kw = {} if rotary_points is None else {"rotary_points_R_m": {"C": rotary_points}}
    machine = Machine(MACHINES["nmv3000"](errors=errors, **kw))
    art = A.cross_pocket()
    log = simulate_campaign(art, machine, ProbeConfig(repeatability_k2_m=0.0), list(CROSS_ANGLES_DEG),
                            np.random.default_rng(0), plan=make_plan(art), check_collisions=False)
    t = from_log(log.select(np.abs(log.col("nz")) < 0.01))
    g = None if grid is None else Grid.regular(*grid)
    return t, self_calibrate(t, g, model_error=False), machine, log


def test_c_centre_of_a_c_carried_by_a_names_a():
    """review33b F1: C's location errors are relative to A, which carries it (nmv3000 V[w-C-A-b-...]):
    EY0A = +10 um alone, EX0C = EY0C = 0, moves C's line in R by +10 um in Y, so the circle's centre is
    (0, -10) um (review33b's end to end run with 0.02 um noise: (-0.02, -9.998)), and the note on the centre,
    as vmt identify writes it with the log's chain, names EY0A and where it puts the centre; main's note said
    the centre is minus (EX0C, EY0C), which is (0, 0) here. Tolerance TOL_UM (module docstring)."""
    from scenarios.identify_report import identify_record, identify_report
    from scenarios.reports import c_axis_centre_um
    from sim.errorfuncs import Constant

    t, res, machine, log = _identify_log({"EY0A": Constant(10 * UM)})
    np.testing.assert_allclose(c_axis_centre_um(res), [0.0, -10.0], atol=TOL_UM)
    rep = identify_report(res, None, identify_record(log))
    note = [n for n in rep["conventions"]["notes"] if n.startswith("EXC, EYC")]
    assert len(note) == 1 and "C rides on A" in note[0] and "EY0A alone puts the centre at (0, -EY0A)" in note[0]
    assert "d_A = (0, EY0A, EZ0A)" in note[0]
    # a log without a chain: the note says in words that the carrier adds to the line
    rep = identify_report(res, None, {**identify_record(log), "chain": None})
    note = [n for n in rep["conventions"]["notes"] if n.startswith("EXC, EYC")][0]
    assert "on a C carried by another axis" in note and "relative to the axis carrying it" in note
    # session 35: Fig. 13's label (report, recording) said "(EX0C, EY0C) = (0.0, 10.0) um" here, where both are
    # 0 and the 10 um is EY0A's: with the log's chain it names the carrier, without one it claims nothing
    from viz.figures import centre_label

    lab = centre_label(*c_axis_centre_um(res), chain=log.meta["kinematic_chain"])
    assert "C carried by A: its line (0.0, 10.0) µm" in lab and "EY0A" in lab and "(EX0C, EY0C) =" not in lab
    lab = centre_label(*c_axis_centre_um(res))
    assert "chain unknown" in lab and "(EX0C, EY0C) =" not in lab and "C line (0.0, 10.0) µm" in lab


@pytest.mark.parametrize("ex0c_um, ey0c_um", [(12.0, 0.0), (-5.0, 9.0)])
def test_reported_c_line_is_the_injected_one(ex0c_um, ey0c_um):
    from scenarios.reports import c_axis_centre_um, c_line_um, true_c_centre_um
    from sim.errorfuncs import Constant
    from viz.figures import centre_label

    t, res, machine = _identify({"EX0C": Constant(ex0c_um * UM), "EY0C": Constant(ey0c_um * UM)})
    c = np.asarray(res.design.c_rad)
    hand = np.array([[np.cos(a) - 1, -np.sin(a)] for a in c]) * ex0c_um \
        + np.array([[np.sin(a), np.cos(a) - 1] for a in c]) * ey0c_um          # (R(-C) - I) c
    np.testing.assert_allclose(res.EXC / UM, hand[:, 0], atol=TOL_UM)
    np.testing.assert_allclose(res.EYC / UM, hand[:, 1], atol=TOL_UM)
    np.testing.assert_allclose(c_line_um(res), [ex0c_um, ey0c_um], atol=TOL_UM)
    np.testing.assert_allclose(c_axis_centre_um(res), [-ex0c_um, -ey0c_um], atol=TOL_UM)
    # the truth in the gauge is the same point: the part rides on the line, nothing else is injected
    np.testing.assert_allclose(true_c_centre_um(machine, res, float(np.median(t.pn_R[:, 2]))),
                               [-ex0c_um, -ey0c_um], atol=1e-6)
    lab = centre_label(*c_axis_centre_um(res), chain=machine.chain)      # the nmv3000's C rides on A
    assert f"C carried by A: its line ({ex0c_um:.1f}, {ey0c_um:.1f}) µm\n= (EX0C, EY0C) + what A adds" in lab


def test_ecc_sign_and_the_linear_axes_in_the_centre():
    """ECC = +0.5 urad/deg: +37.5 urad at 75 deg, and the note says what that is; EXX = +4 um
    everywhere puts the tool 4 um further +X at the grid origin, so the C line (at 0) is seen at -4 um."""
    from scenarios.reports import c_line_um, true_c_centre_um
    from sim.errorfuncs import Constant, Polynomial

    t, res, machine = _identify({"ECC": Polynomial((0.0, 0.5 * URAD / DEG)), "EXX": Constant(4 * UM)})
    c_deg = np.asarray(res.design.c_rad) / DEG
    np.testing.assert_allclose(res.ECC / URAD, 0.5 * c_deg, atol=0.01)  # 0, 37.5, 65, 105 urad
    assert res.ECC[1] / URAD == pytest.approx(37.5, abs=0.01)
    np.testing.assert_allclose(c_line_um(res), [-4.0, 0.0], atol=TOL_UM)
    np.testing.assert_allclose(-true_c_centre_um(machine, res, float(np.median(t.pn_R[:, 2]))), [-4.0, 0.0],
                               atol=1e-6)
    note = [n for n in res.to_report()["conventions"]["notes"] if n.startswith("ECC")]
    assert note and "right-handed rotation of the tool relative to the part" in note[0]
    assert "rotation error of the table" not in note[0]  # main's note: the table's sign, the opposite one


def _radial(amp_um: float):
    """A once-per-revolution radial motion of C (the tool relative to the part)."""
    from sim.errorfuncs import Periodic

    return {"EXC": Periodic(amp_um * UM, 2 * np.pi, 0.3), "EYC": Periodic(amp_um * UM, 2 * np.pi, 0.3 + np.pi / 2)}


@pytest.mark.parametrize("case", ["radial", "linear_slope"])
def test_true_centre_holds_radial_motion_and_non_constant_linear_errors(case):
    """The truth's centre in the gauge against the identified one where main's star (the tip deviation at the
    grid origin at C = 0) is wrong: a 3 um once-per-revolution radial motion with the C line (main's star:
    -(12, 0) + the radial motion at C = 0 = (-11.1, 2.9) um, 3 um off the fitted (-12, 0): the radial motion's
    circle through the four angles has no offset), and EXX = 3 um + 50 um/m x with the C axis at (22, 0) mm
    (the gauge's scale, fixed at the last node, folds the slope into the centre: 4.1 um, main's star 3.0)."""
    from scenarios.reports import c_axis_centre_um, true_c_centre_um
    from sim.errorfuncs import Constant, Polynomial

    if case == "radial":
        t, res, machine = _identify({"EX0C": Constant(12 * UM), **_radial(3.0)})
    else:
        t, res, machine = _identify({"EXX": Polynomial((3 * UM, 50e-6))}, (0.022, 0.0, 0.0), None)
    z = float(np.median(t.pn_R[:, 2]))
    truth = true_c_centre_um(machine, res, z)
    np.testing.assert_allclose(c_axis_centre_um(res), truth, atol=TOL_UM)
    xo, yo = res.design.grid.origin_m
    lin, rot = np.array([[xo, yo, z]]), np.zeros((1, len(machine.rotary_axes)))
    star = (machine.tip_W(lin, rot) - machine.tip_W_nominal(lin, rot))[0, :2] / UM   # main's star
    assert np.hypot(*(star - truth)) > 1.0   # 3.0 / 1.1 um: main's star fails here


def test_c_line_label_names_the_gauge():
    from viz.figures import centre_label, line_from_centre

    np.testing.assert_array_equal(line_from_centre([0.0, -2.5]), [0.0, 2.5])
    assert str(line_from_centre([0.0, 1.0])[0]) == "0.0"   # no -0.0 in labels and JSON
    lab = centre_label(4.1, -0.04, chain="V[w-C-b-Y-X-Z-(C)-t]")           # C on the bed
    assert "(EX0C, EY0C) = (-4.1, 0.0) µm" in lab and "gauge of eqs 16-17" in lab and "x = y = 0" not in lab


@pytest.mark.parametrize("chain, said", [
    ("V[w-C-b-Y-X-Z-(C)-t]", "(EX0C, EY0C) = (-4.1, 0.0) µm"),
    ("V[w-C-A-b-Y-X-Z-(C)-t]", "C carried by A: its line (-4.1, 0.0) µm\n= (EX0C, EY0C) + what A adds\n(EY0A, EB0A"),
    ("[w C' A' b X Y Z (C1) t]", "C carried by A: its line (-4.1, 0.0) µm"),
    ("V[w-C-B-b-Y-X-Z-(C)-t]", "C carried by B: its line (-4.1, 0.0) µm\n= (EX0C, EY0C) + what B adds\n(EX0B, EA0B"),
    ("V[w-C-X-b-Y-Z-(C)-t]", "C line (-4.1, 0.0) µm: (EX0C, EY0C)\nif C sits on the bed (C carried by X;"),
    ("V[w-X-Y-b-Z-(C)-t]", "C line (-4.1, 0.0) µm: (EX0C, EY0C)\nif C sits on the bed (chain unknown;"),
    (None, "C line (-4.1, 0.0) µm: (EX0C, EY0C)\nif C sits on the bed (chain unknown;"),
])
def test_c_line_label_says_what_carries_c(chain, said):
    """The label claims (EX0C, EY0C) = the line only for a C on the bed; carried by A or B it names the carrier
    and its terms (core.selfcal.c_centre_note's), carried by another axis or with no chain (or none with C) it
    says the line is (EX0C, EY0C) only on the bed. The figure's legend and the recording's label carry it."""
    from viz.figures import centre_label, rotary_centre_figure

    lab = centre_label(4.1, -0.04, chain=chain)
    assert lab.startswith("centre (4.1, -0.0) µm:\n") and said in lab and "gauge of eqs 16-17" in lab
    assert ("(EX0C, EY0C) =" in lab) == (chain == "V[w-C-b-Y-X-Z-(C)-t]")
    fig = rotary_centre_figure([0, 75, 130, 210], [0.0, -8.9, -19.7, -22.4], [0.0, -11.6, -9.2, 6.0],
                               centre_um=(4.1, -0.04), chain=chain)
    assert lab in [t.get_text() for t in fig.axes[0].get_legend().get_texts()]
