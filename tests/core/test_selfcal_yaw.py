"""Self-calibration for machines whose Y rides on X (yaw ECX instead of ECY)."""

import numpy as np
import pytest

from core import selfcal
from core.design import example_cross_pocket
from core.exceptions import ConfigError


@pytest.mark.parametrize("chain, yaw", [
    ("V[w-C-A-b-Y-X-Z-(C)-t]", "ECY"),   # the paper's NMV3000: X on Y
    ("[w C' A' b X Y Z (C1) t]", "ECX"),  # the MFB paper's Mikron: Y on X
    ("V[w-X-Y-b-Z-(C)-t]", "ECY"),        # table X on saddle Y
    ("V[w-Y-X-b-Z-(C)-t]", "ECX"),        # table Y on saddle X
    ("V[w-X-b-Y-Z-(C)-t]", "ECY"),        # X and Y on different branches: no coupling yaw
    (None, "ECY"),
])
def test_yaw_for_chain(chain, yaw):
    assert selfcal.yaw_for_chain(chain) == yaw


@pytest.fixture(scope="module")
def design():
    w, wn, _ = example_cross_pocket()
    t = selfcal.nominal_touches(w, wn, [0, 75, 130, 210], stylus_r_m=0.003)
    grid = selfcal.Grid.regular(-0.110, 0.110, 0.022)
    return t, grid, selfcal.build_design(t, grid, yaw="ECX")


def test_null_space_is_the_eleven_gauge_directions(design):
    _, _, des = design
    A = des.A.toarray()
    assert np.abs(A @ des.N).max() < 1e-12 * np.abs(A).max()
    s = np.linalg.svd(A / np.linalg.norm(A, axis=0), compute_uv=False)
    assert int(np.sum(s > 1e-9 * s[0])) == des.n_params - 11
    assert np.linalg.matrix_rank(des.C @ des.N) == 11
    assert "ECX" in des.slices and "ECY" not in des.slices


def test_known_answer_in_the_model_space(design):
    """A truth drawn in the ECX model space is recovered to rounding, in the gauge."""
    t, grid, des = design
    rng = np.random.default_rng(8)
    theta = rng.normal(0, 2e-6, des.n_params)
    theta[des.slices["ECX"]] = rng.normal(0, 20e-6, len(grid.x_m))
    dq = des.A @ theta
    tt = selfcal.nominal_touches(*example_cross_pocket()[:2], [0, 75, 130, 210], stylus_r_m=0.003, dq_m=dq)
    res = selfcal.self_calibrate(tt, grid, yaw="ECX")
    truth = des.to_gauge(theta)
    np.testing.assert_allclose(res.theta, truth, atol=1e-12)
    assert res.rms_m < 1e-13 and len(res.ECX) == len(grid.x_m)


def test_bad_yaw(design):
    t, grid, _ = design
    with pytest.raises(ConfigError, match="yaw must be 'ECY' or 'ECX'"):
        selfcal.build_design(t, grid, yaw="EBX")
