"""The U95 of the demo's error map (review30d F4): scenarios.reports.error_map_u95_um.

Known answers on a 3 x 2 grid (ECY yaw): a variance on one ECY node alone gives U95 = 2 |x| u on
that row and 0 elsewhere; variances on EXX[k] and EYX[k] give 2 sqrt(a^2 + b^2) down column k;
and on a random covariance the linear propagation agrees with core.uncertainty.error_map_u95
from Monte Carlo draws of the same covariance (40,000 draws: the standard error of a standard
deviation is 1/sqrt(2 n) = 0.35 %, the tolerance 2 % is about 6 of them).
"""
from types import SimpleNamespace

import numpy as np
import pytest

from core.selfcal import Yaw
from core.uncertainty import error_map_u95
from scenarios.reports import error_map_u95_um


def _des():
    nx, ny = 3, 2
    names = [("EXX", nx), ("EXY", ny), ("EYX", nx), ("EYY", ny), ("ECY", ny), ("EC0Y", 1)]
    slices, k = {}, 0
    for n, m in names:
        slices[n] = slice(k, k + m)
        k += m
    grid = SimpleNamespace(x_m=np.array([-0.1, 0.0, 0.1]), y_m=np.array([0.0, 0.11]))
    return SimpleNamespace(grid=grid, slices=slices, n_params=k, yaw=Yaw.ECY)


def test_one_yaw_node_alone():
    des = _des()
    cov = np.zeros((des.n_params, des.n_params))
    i = des.slices["ECY"].start + 1                   # y = 0.11 m
    cov[i, i] = (100e-6) ** 2                         # u 100 urad
    u = error_map_u95_um(SimpleNamespace(design=des, cov=cov))
    assert u.shape == (2, 3)                          # (ny, nx), as the map is drawn
    assert np.allclose(u[1], [20.0, 0.0, 20.0]) and np.allclose(u[0], 0.0)   # 2 x 0.1 m x 100 urad


def test_x_tables_down_one_column():
    des = _des()
    cov = np.zeros((des.n_params, des.n_params))
    a, b = des.slices["EXX"].start + 2, des.slices["EYX"].start + 2
    cov[a, a], cov[b, b] = (3e-6) ** 2, (4e-6) ** 2
    u = error_map_u95_um(SimpleNamespace(design=des, cov=cov))
    assert np.allclose(u[:, 2], 10.0) and np.allclose(u[:, :2], 0.0)       # 2 sqrt(9 + 16) um


def test_linear_agrees_with_monte_carlo(rng):
    des = _des()
    A = rng.normal(size=(des.n_params, des.n_params)) * 1e-6
    cov = A @ A.T
    err = rng.multivariate_normal(np.zeros(des.n_params), cov, size=40000)
    mc = error_map_u95(des, err).T / 1e-6
    lin = error_map_u95_um(SimpleNamespace(design=des, cov=cov))
    assert np.allclose(lin, mc, rtol=0.02)


def test_no_covariance_draws_none():
    assert error_map_u95_um(SimpleNamespace(design=_des(), cov=None)) is None


@pytest.fixture
def rng():
    return np.random.default_rng(30)
