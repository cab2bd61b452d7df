"""spline_weights at 2 and 3 nodes: sim's SplineTable's curve (natural cubic) and its end tangents (review31d F11).

The docstring, sim's SplineTable and every vmt-comp/1 JSON (scenarios.mfb.COMP_EXTRAPOLATION) say the tables
continue along the end tangent; before, 2-3 nodes were interpolated linearly and held beyond the ends.
Tolerances: 1e-12 on values of order 1-10, 1e-17 m on 5 um values (a few ulps of the splines' arithmetic; the sides are
different code paths, not the same doubles).
"""

import numpy as np
import pytest

from core.volumetric import spline_weights
from sim.compensation import ErrorModel
from sim.errorfuncs import SplineTable


def test_two_nodes_are_the_line_through_them_continued():
    x, v = np.array([0.0, 0.2]), np.array([1.0, 3.0])  # slope 10 per m
    u = np.array([-0.03, 0.0, 0.05, 0.2, 0.24])
    # by hand: 1 + 10 u everywhere, beyond the ends too (held ends gave 1 and 3 there)
    assert spline_weights(x, u) @ v == pytest.approx(1.0 + 10.0 * u, abs=1e-12)


def test_three_nodes_natural_cubic_by_hand():
    # nodes 0, 1, 2 (values 0, 1, 0): the natural spline's middle second derivative M1 solves
    # (h0 + h1)/3 M1 = (y2 - y1)/h1 - (y1 - y0)/h0 -> 2/3 M1 = -2, M1 = -3 (M0 = M2 = 0). On [0, 1]:
    # s(t) = t + M1/6 (t^3 - t) = 1.5 t - 0.5 t^3; s'(0) = 1.5, s'(2) = -1.5 (symmetric); s(0.5) = 0.6875
    x, v = np.array([0.0, 1.0, 2.0]), np.array([0.0, 1.0, 0.0])
    u = np.array([-0.1, 0.5, 1.0, 1.5, 2.2])
    want = np.array([-0.15, 0.6875, 1.0, 0.6875, -0.3])  # beyond: 0 + 1.5 (-0.1), 0 - 1.5 (0.2)
    assert spline_weights(x, u) @ v == pytest.approx(want, abs=1e-12)


@pytest.mark.parametrize("k", [2, 3, 4, 6])
def test_matches_sim_spline_table_and_the_compensating_controller(k):
    rng = np.random.default_rng(31 + k)
    x = np.sort(rng.uniform(-0.3, 0.4, k))
    v = rng.normal(0.0, 5e-6, k)
    u = np.linspace(x[0] - 0.04, x[-1] + 0.04, 57)  # NODE_MARGIN_M beyond each end
    want = SplineTable(tuple(x), tuple(v))(u)
    got = spline_weights(x, u) @ v
    assert np.max(np.abs(got - want)) < 1e-17  # m: 2e-12 of the 5 um values (ulps of two code paths)
    # the simulated controller applies the JSON's tables by the same rule
    em = ErrorModel("XFYZ", {"EXX": (x, v)}, {}, {})
    assert np.max(np.abs(em.values(np.column_stack([u, 0 * u, 0 * u]))["EXX"] - want)) < 1e-17
