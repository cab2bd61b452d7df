"""The discovery engine on synthetic first-order data (eq 14 plus one effect).

These check the statistics and the candidate library in isolation; the
hidden-effect tests in tests/scenarios/test_discover_hidden.py hide the
effects in the simulated machine or probe instead.
"""

import dataclasses

import numpy as np
import pytest

from core import selfcal
from core.design import example_cross_pocket
from core.discover import discover, find_outliers
from core.exceptions import ConfigError, IdentifiabilityError

SIG = 0.3e-6


@pytest.fixture(scope="module")
def plan():
    w, wn, _ = example_cross_pocket()
    return selfcal.nominal_touches(w, wn, [0, 75, 130, 210], stylus_r_m=0.003)


def _with(t, dq):
    ts = np.arange(t.n) * 10.0
    return dataclasses.replace(t, p_R=t.pn_R + dq[:, None] * t.n_R, t_s=ts)


def _effect(t, name, mag):
    x, y = t.pn_R[:, 0], t.pn_R[:, 1]
    nx = t.n_R[:, 0]
    phi = np.arctan2(t.d_R[:, 1], t.d_R[:, 0])
    tt = np.arange(t.n) / t.n
    return {
        "none": 0 * x,
        "thermal_drift": -nx * mag * tt - nx * (x / 0.1) * mag * tt,
        "probe_lobing": mag * np.cos(3 * phi + 0.4),
        "reversal": nx * np.sign(-nx) * mag / 2,
        "nonrigid": -nx * (x / 0.1) * (y / 0.1) * mag,
        "periodic_axis_error": -nx * mag * np.sin(2 * np.pi * x / 0.0125),
    }[name]


@pytest.mark.parametrize("cause", ["none", "thermal_drift", "probe_lobing", "reversal", "nonrigid",
                                   "periodic_axis_error"])
def test_engine_names_the_effect(plan, cause):
    rng = np.random.default_rng(7)
    dq = _effect(plan, cause, 3e-6) + rng.normal(0, SIG, plan.n)
    rep = discover(_with(plan, dq)).to_report()
    assert rep["cause"] == cause
    if cause != "none":
        assert rep["gain"]["rms_ratio"] < 0.8 and rep["gain"]["cv_rms_ratio"] < 0.9
    assert set(rep) >= {"baseline", "findings", "cause", "extended", "baseline_cv_rms_um", "gain",
                        "workpiece", "outlier_rows"}


def test_outliers_found_by_row(plan):
    rng = np.random.default_rng(3)
    dq = rng.normal(0, SIG, plan.n)
    dq[[7, 150, 300]] += [6e-6, -5e-6, 8e-6]
    t = _with(plan, dq)
    d = discover(t)
    assert d.cause == "outlier" and d.outlier_rows == (7, 150, 300)
    assert find_outliers(np.ones((plan.n, 1)), rng.normal(0, 1, plan.n)) == []


def test_bad_input(plan):
    with pytest.raises(ConfigError, match="at least 10 valid touches"):
        discover(plan.subset(np.arange(5)))
    one = plan.subset(plan.setup == 0)
    with pytest.raises(IdentifiabilityError, match="no baseline"):
        discover(one)


def test_symmetric_design_still_discovers_but_says_workpiece_not_identifiable():
    """A symmetric part at C 90 deg apart: the self-calibration is rank deficient
    beyond the gauge; residuals need no gauge, so discovery runs and says so."""
    w, wn, _ = example_cross_pocket(spheres=False)
    t = selfcal.nominal_touches(w, wn, [0, 90, 180, 270], stylus_r_m=0.003)
    rng = np.random.default_rng(11)
    d = discover(_with(t, rng.normal(0, SIG, t.n)))
    rep = d.to_report()
    assert rep["cause"] == "none" and rep["workpiece_identifiable"] is False
    assert "NOT identifiable" in " ".join(rep["conventions"])


def test_out_of_plane_touches_are_left_out_and_said(plan):
    rng = np.random.default_rng(5)
    t = _with(plan, rng.normal(0, SIG, plan.n))
    n = t.n_R.copy()
    n[:6] = [0.6, 0.0, 0.8]  # six touches on a raised face: not for the planar model
    t = dataclasses.replace(t, n_R=n)
    rep = discover(t).to_report()
    assert rep["baseline"]["n"] == plan.n - 6
    assert any("6 touches with normals out of the XY plane" in c for c in rep["conventions"])


def test_drift_follows_a_logged_temperature(plan):
    """With temp_*_C columns, drift may follow the temperature rather than time:
    a scale error growing with a temperature that rises and falls is found."""
    rng = np.random.default_rng(21)
    n = plan.n
    temp = 20 + 1.5 * np.sin(np.linspace(0, 3 * np.pi, n))  # rises and falls: not linear in time
    x = plan.pn_R[:, 0]
    dq = -plan.n_R[:, 0] * x * 11.5e-6 * (temp - temp.mean()) + rng.normal(0, SIG, n)
    t = dataclasses.replace(_with(plan, dq), temps_C={"temp_spindle_C": temp})
    rep = discover(t).to_report()
    assert rep["cause"] == "thermal_drift"
    p = rep["findings"][0]["params"]
    assert "x_scale_ppm_per_K" in p and abs(p["x_scale_ppm_per_K"] - 11.5) < 1.5
