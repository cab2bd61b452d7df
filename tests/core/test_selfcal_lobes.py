"""What the self-calibration's U95 does not cover: pre-travel lobes a design absorbs (core.selfcal.blind_lobes).

Review 27's case: a cross pocket (walls facing 0/90/180/270 deg in W) on a perfect machine with a 3-lobe
pre-travel read C-axis errors of up to 0.93 um at U95 0.22 um, residuals clean. The reason is the design:
an odd k acts with opposite signs on opposite walls, a translation per set-up. The statement is computed
from the design, so these tests build designs and check it names what a simulated lobe actually does.
"""

import numpy as np
import pytest

from core.design import example_cross_pocket
from core.exceptions import ConfigError
from core.selfcal import (Grid, LOBE_ALIAS_SIN, absorbed_lobes, blind_lobes, blind_lobes_line, estimator, nominal_touches,
                          not_covered, self_calibrate)
from core.units import UM
from tests.core.test_selfcal import freeform

GRID = Grid.regular(-0.110, 0.110, 0.022)
ANGLES = [0, 75, 130, 210]


def _wavy(n=60):
    """A free-form closed curve (tests/core/test_selfcal.py's): normals at many azimuths."""
    return freeform(n)


def _lobe_dq(t, k, a_um, b_um):
    """The normal deviations a pre-travel lobe makes (sim.probe: p along the approach, dq = -p on a normal
    approach), phi the approach azimuth in the machine frame."""
    phi = np.arctan2(t.d_R[:, 1], t.d_R[:, 0])
    return -(a_um * np.cos(k * phi) + b_um * np.sin(k * phi)) * UM


def _pocket():
    """The pocket's walls alone (normals 0/90/180/270 deg in W), as sim's cross-pocket probes them in the plane
    (its spheres' touches there are at two heights on the same four normals)."""
    w, wn, ids = example_cross_pocket(spheres=False)
    return nominal_touches(w, wn, ANGLES, stylus_r_m=0.003, target_ids=ids)


def _grid(t):
    return Grid.from_extent(t.pn_R, 0.022)


def test_cross_pocket_names_k3_into_the_c_axis_translations_and_a_simulated_lobe_goes_there():
    t = _pocket()
    des, est = estimator(t, _grid(t))
    blind = {b.k: b for b in blind_lobes(des, est, t)}
    assert 3 in blind and {"EXC", "EYC"} <= set(blind[3].blocks)
    assert blind[3].angle_deg < 1e-6      # exactly in the span (rounding only)
    # the round trip: a perfect machine, a 3-lobe pre-travel (review 27's 0.5 cos + 0.2 sin um), no noise
    dq = _lobe_dq(t, 3, 0.5, 0.2)
    from dataclasses import replace
    res = self_calibrate(replace(t, p_R=t.pn_R + dq[:, None] * t.n_R), _grid(t), sigma_m=0.1 * UM)
    assert res.rms_m < 1e-12               # no residual: nothing to see, no model error to budget
    s = des.slices
    exc, eyc = res.theta[s["EXC"]], res.theta[s["EYC"]]
    moved = np.hypot(exc, eyc).max()
    assert moved > 0.5 * UM                # the lobe reads as C-axis errors (0.54 um amplitude, up to 1.85x)
    # ... no larger than the statement's bound per um of lobe (amplitude 0.539 um); 1e-9 um: rounding
    amp = np.hypot(0.5, 0.2)
    assert np.abs(exc).max() <= blind[3].per_um["EXC"] * amp * UM + 1e-15
    assert np.abs(eyc).max() <= blind[3].per_um["EYC"] * amp * UM + 1e-15
    # and the report and the CLI's line say so
    rep = res.to_report()
    nc = rep["not_covered"]
    ks = [e["k"] for e in nc["pretravel_lobes"]]
    assert 3 in ks and "k = " in nc["what"] and "3" in nc["what"]
    e3 = nc["pretravel_lobes"][ks.index(3)]
    assert {"EXC", "EYC"} <= set(e3["into"])
    assert "k = 3" in blind_lobes_line(res.blind_lobes) and "EXC" in blind_lobes_line(res.blind_lobes)


def test_even_orders_are_seen_on_the_cross_pocket_and_leave_a_residual():
    """k = 2 is not named: its signal stays in the residuals (the budget's business), checked by simulation."""
    t = _pocket()
    des, est = estimator(t, _grid(t))
    named = {b.k for b in blind_lobes(des, est, t)}
    assert 2 not in named
    from dataclasses import replace
    dq = _lobe_dq(t, 2, 0.5, 0.0)
    res = self_calibrate(replace(t, p_R=t.pn_R + dq[:, None] * t.n_R), _grid(t), sigma_m=0.1 * UM,
                         model_error=False)
    # sine of the smallest principal angle >= LOBE_ALIAS_SIN: at least 1 % of the lobe's energy is residual
    frac = np.sum(res.residuals_m ** 2) / np.sum(dq ** 2)
    assert frac >= LOBE_ALIAS_SIN ** 2 * 0.99


@pytest.mark.parametrize("plan", ["pocket_and_spheres", "wavy"])
def test_a_design_with_normals_that_separate_k3_does_not_name_it(plan):
    """The paper's pocket with its two spheres' equators (normals every 45 deg: k = 3 aliases to 5, not to a
    translation) and a free-form curve: k = 3 leaves a residual, so it is not named; a simulated lobe shows."""
    if plan == "wavy":
        w, wn = _wavy(60)
        t = nominal_touches(w, wn, ANGLES)
    else:
        w, wn, ids = example_cross_pocket()
        t = nominal_touches(w, wn, ANGLES, stylus_r_m=0.003, target_ids=ids)
    des, est = estimator(t, GRID)
    blind = blind_lobes(des, est, t)
    assert 3 not in {b.k for b in blind}
    assert 3 not in [e["k"] for e in not_covered(blind)["pretravel_lobes"]]
    from dataclasses import replace
    dq = _lobe_dq(t, 3, 0.5, 0.2)
    res = self_calibrate(replace(t, p_R=t.pn_R + dq[:, None] * t.n_R), GRID, sigma_m=0.1 * UM, model_error=False)
    assert np.sum(res.residuals_m ** 2) >= LOBE_ALIAS_SIN ** 2 * np.sum(dq ** 2) * 0.99


def test_bad_input_touches_of_another_design():
    t = _pocket()
    des, est = estimator(t, _grid(t))
    w, wn = _wavy(40)
    with pytest.raises(ConfigError, match="touches for a design"):
        blind_lobes(des, est, nominal_touches(w, wn, ANGLES))


@pytest.mark.parametrize("plan", ["pocket", "wavy"])
def test_absorbed_lobes_from_a_basis_agrees_with_blind_lobes(plan):
    """discover's route (an orthonormal basis of the design) and identify's (the estimator) name the same
    orders at the same angles (to 1e-6 deg near 0; the rest are not named by either)."""
    from core.diagnosis import orth

    if plan == "wavy":
        w, wn = _wavy(60)
        t = nominal_touches(w, wn, ANGLES)
        g = GRID
    else:
        t = _pocket()
        g = _grid(t)
    des, est = estimator(t, g)
    Q = orth(des.A.toarray())
    phi = np.arctan2(t.d_R[:, 1], t.d_R[:, 0])
    got = absorbed_lobes(phi, lambda x: Q @ (Q.T @ x))
    want = blind_lobes(des, est, t)
    assert [k for k, _ in got] == [b.k for b in want]
    for (_, a), b in zip(got, want):
        assert abs(a - b.angle_deg) < 1e-6


def test_absorbed_lobes_bad_input():
    with pytest.raises(ConfigError, match="phi"):
        absorbed_lobes(np.array([0.0, np.nan]), lambda x: x)
    with pytest.raises(ConfigError, match="phi"):
        absorbed_lobes(np.zeros((3, 2)), lambda x: x)
