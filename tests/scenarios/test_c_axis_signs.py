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


def _identify(errors: dict):
    """A noise-free case-1 campaign (cross pocket at eq 19's angles, nmv3000) with ``errors`` only."""
    from core.selfcal import Grid, self_calibrate
    from core.touches import from_log
    from scenarios.crosspocket import CROSS_ANGLES_DEG
    from sim import artefacts as A
    from sim.campaign import simulate_campaign
    from sim.catalog import make_plan
    from sim.machine import Machine
    from sim.machines import MACHINES
    from sim.probe import ProbeConfig

    machine = Machine(MACHINES["nmv3000"](errors=errors))
    art = A.cross_pocket()
    log = simulate_campaign(art, machine, ProbeConfig(repeatability_k2_m=0.0), list(CROSS_ANGLES_DEG),
                            np.random.default_rng(0), plan=make_plan(art), check_collisions=False)
    t = from_log(log.select(np.abs(log.col("nz")) < 0.01))
    return t, self_calibrate(t, Grid.regular(-0.110, 0.110, 0.022), model_error=False), machine


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
    assert f"(EX0C, EY0C) = ({ex0c_um:.1f}, {ey0c_um:.1f}) µm" in centre_label(*c_axis_centre_um(res))


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
