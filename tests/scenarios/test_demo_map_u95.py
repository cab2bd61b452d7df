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

from core.selfcal import Yaw, map_gauge_basis, map_in_gauge
from core.uncertainty import error_map_u95
from scenarios.reports import error_map_u95_um, map_u95_coverage


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


def _gauge_fixed_cov(des):
    """The gauge of eqs 16-17 on the 3 x 2 grid: nodes (0, 0) and (0.1, 0) m without variance (EXX/EYX at
    x = 0, 0.1, EXY/EYY/ECY at y = 0, EC0Y none); 1 um on EXX/EYX at x = -0.1, EXY/EYY at y = 0.11, 1 urad
    on ECY there. U95 = 2 sqrt(var E_X + var E_Y): 2 sqrt 2 um at (-0.1, 0) and (0, 0.11), 2 sqrt 4.01 at
    (-0.1, 0.11), 2 sqrt 2.01 at (0.1, 0.11) m."""
    cov = np.zeros((des.n_params, des.n_params))
    for name, k in (("EXX", 0), ("EYX", 0), ("EXY", 1), ("EYY", 1), ("ECY", 1)):
        i = des.slices[name].start + k
        cov[i, i] = 1e-12
    return cov


def _maps(des, rng):
    """An identified map (um, (ny, nx)) and a truth equal to it but for a shift, rotation and scale."""
    x_mm, y_mm = des.grid.x_m * 1e3, des.grid.y_m * 1e3
    ex, ey = rng.normal(size=(2, 2, 3)) * 3.0
    X, Y = np.meshgrid(des.grid.x_m, des.grid.y_m)
    g = map_gauge_basis(X, Y) @ np.array([2e-6, -3e-6, 40e-6, 25e-6]) * 1e6
    return x_mm, y_mm, ex, ey, ex + g[:6].reshape(2, 3), ey + g[6:].reshape(2, 3)


def _drawn(des, ex, ey, tex, tey):
    """The truth as the demo draws it: fitted to the identified map by the gauge (map_in_gauge), um."""
    X, Y = np.meshgrid(des.grid.x_m, des.grid.y_m)
    a, b = map_in_gauge(X, Y, tex * 1e-6, tey * 1e-6, ex * 1e-6, ey * 1e-6)
    return a * 1e6, b * 1e6


def test_coverage_of_a_truth_that_differs_by_the_gauge_alone(rng):
    """Identified = truth but for a shift, a rotation and a scale (what self-calibration cannot see): within
    the U95 at every node, in the U95's gauge and as drawn; the gauge's two nodes (U95 0) counted apart."""
    des = _des()
    res = SimpleNamespace(design=des, cov=_gauge_fixed_cov(des))
    x_mm, y_mm, ex, ey, tex, tey = _maps(des, rng)
    for truth in ((tex, tey), _drawn(des, ex, ey, tex, tey)):
        c = map_u95_coverage(res, x_mm, y_mm, ex, ey, *truth)
        assert (c["outside"], c["nodes"], c["gauge_nodes"]) == (0, 4, 2) and c["max_ratio"] < 1e-9
    assert c["outside_as_drawn"] == 0


def test_coverage_counts_a_bias_beyond_the_u95_in_the_u95_s_own_gauge(rng):
    """A 5 um bias in E_X at (-0.1, 0) m, U95 2 sqrt 2 um there: outside, 1.77 x. A 2 um bias in E_Y at the
    gauge node (0.1, 0) m: in the U95's gauge (the truth made equal to the map where the gauge fixes it) a
    rotation of 20 urad, hypot(x, y) x 20 urad at the other nodes: 2.97 um at (0.1, 0.11) m, U95 2 sqrt 2.01 =
    2.84 um: outside, 1.05 x (2.0, 2.2, 2.97 um elsewhere, within 2.83, 2.83, 4.0); fitted to the map as
    drawn, the bias is spread over every node and none is outside: the drawn comparison is not the U95's."""
    des = _des()
    res = SimpleNamespace(design=des, cov=_gauge_fixed_cov(des))
    x_mm, y_mm, ex, ey, tex, tey = _maps(des, rng)
    c = map_u95_coverage(res, x_mm, y_mm, ex, ey, tex - 5.0 * (np.arange(6).reshape(2, 3) == 0), tey)
    assert (c["outside"], c["nodes"]) == (1, 4) and c["worst_mm"] == [-100.0, 0.0]
    assert c["max_ratio"] == pytest.approx(5.0 / (2 * np.sqrt(2)), rel=1e-9)
    assert c["worst_gap_um"] == pytest.approx(5.0, rel=1e-9)
    tey = tey - 2.0 * (np.arange(6).reshape(2, 3) == 2)
    c = map_u95_coverage(res, x_mm, y_mm, ex, ey, *_drawn(des, ex, ey, tex, tey))
    assert (c["outside"], c["worst_mm"]) == (1, [100.0, 110.0])
    assert c["worst_gap_um"] == pytest.approx(20 * np.hypot(0.1, 0.11), rel=1e-9)
    assert c["max_ratio"] == pytest.approx(20 * np.hypot(0.1, 0.11) / (2 * np.sqrt(2.01)), rel=1e-9)
    assert c["outside_as_drawn"] == 0


def test_no_truth_or_no_covariance_gives_none(rng):
    des = _des()
    x_mm, y_mm, ex, ey, tex, tey = _maps(des, rng)
    assert map_u95_coverage(SimpleNamespace(design=des, cov=None), x_mm, y_mm, ex, ey, tex, tey) is None
    assert map_u95_coverage(SimpleNamespace(design=des, cov=_gauge_fixed_cov(des)), x_mm, y_mm, ex, ey,
                            None, None) is None


@pytest.fixture
def rng():
    return np.random.default_rng(30)


@pytest.mark.parametrize("lobing, outside", [("demo", (36, 119)), ("none", (0, 12))])
def test_the_demo_maps_truth_outside_its_u95_is_the_lobing_probes(tmp_path, monkeypatch, lobing, outside):
    """Session 30 drew the demo's error map with its U95 and found the truth outside it at 32 of 121 nodes
    (the truth fitted to the map, as drawn; 30 of the 119 the gauge leaves free). In the U95's own gauge:
    70 of 119 (up to 2.9 x at (110, 22) mm). The same campaign (seed 2026) without the lobing probe: 1 of 119
    (seed 2027: 4; a U95 that holds leaves about 5 %, 6 of 119, correlated nodes more: at most 12 asked);
    with it, at least 36 (30 %) asked of what measures 70. Without the worn screw too, 0 of 119; with the
    lobing alone 111 of 119: the screw's ripple, which the residuals show, widens the U95."""
    import scenarios.demo as D
    from core.selfcal import Grid, self_calibrate
    from scenarios.reports import error_map_um, true_error_map

    if lobing == "none":
        monkeypatch.setattr(D, "LOBING_M", ())
    machine, probe, _ = D._machine(2026, lambda *a, **k: None)
    _, _, _, t, _ = D._campaign(machine, probe, 2026, tmp_path, lambda *a, **k: None)
    res = self_calibrate(t, Grid.regular(-0.110, 0.110, 0.022))
    x, y, ex, ey = error_map_um(res)
    tex, tey = true_error_map(machine, x, y, float(np.median(t.pn_R[:, 2])), ex, ey)
    c = map_u95_coverage(res, x, y, ex, ey, tex, tey)
    assert (c["nodes"], c["gauge_nodes"]) == (119, 2)
    assert outside[0] <= c["outside"] <= outside[1], c
    if lobing == "demo":      # as drawn, the fit to the map takes up part of the bias (30 of 119 measured)
        assert c["outside_as_drawn"] < c["outside"]
