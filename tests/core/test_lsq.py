"""The shared solver's helpers (core.lsq): gauge removal and covariance modes.

The solver itself is exercised by every identification (tests/core/test_selfcal.py,
test_volumetric.py, test_discover_*.py): round trips, rank messages, sparse path.
"""

import numpy as np
import pytest

from core.exceptions import ConfigError
from core.lsq import COVARIANCE_MESSAGES, Covariance, covariance_mode, remove_span, solve


def test_remove_span_known_answer_line():
    """Removing offset and slope from samples of a line plus a parabola leaves the parabola's
    part orthogonal to the line: worked by hand for x = -1, 0, 1 (x^2 -> (1, -2, 1) / 3)."""
    x = np.array([-1.0, 0.0, 1.0])
    B = np.column_stack([np.ones(3), x])
    np.testing.assert_allclose(remove_span(3.0 + 2.0 * x, B), 0.0, atol=1e-15)
    np.testing.assert_allclose(remove_span(x ** 2, B), np.array([1.0, -2.0, 1.0]) / 3, atol=1e-15)


def test_remove_span_dependent_columns_and_projector():
    """A repeated column changes nothing (the span is used); eye gives the idempotent projector."""
    rng = np.random.default_rng(3)
    B = rng.standard_normal((8, 2))
    v = rng.standard_normal(8)
    np.testing.assert_allclose(remove_span(v, np.column_stack([B, B[:, :1]])), remove_span(v, B), atol=1e-14)
    P = remove_span(np.eye(8), B)
    np.testing.assert_allclose(P @ P, P, atol=1e-14)
    np.testing.assert_allclose(P @ B, 0.0, atol=1e-14)


def test_remove_span_bad_shape():
    with pytest.raises(ConfigError, match=r"B must be \(n, q\) with n = 3"):
        remove_span(np.zeros(3), np.zeros((4, 1)))


def test_covariance_modes():
    assert set(COVARIANCE_MESSAGES) == set(Covariance)
    assert covariance_mode("std") is Covariance.STD and Covariance.NONE == "none"
    with pytest.raises(ConfigError, match="covariance must be auto, full, std or none, got 'diag'"):
        covariance_mode("diag")
    # known answer: b = theta (identity), sigma 2 -> std 2 everywhere
    sol = solve(np.eye(3), np.array([1.0, 2.0, 3.0]), sigma=2.0, covariance=Covariance.STD)
    np.testing.assert_allclose(sol.theta, [1, 2, 3], atol=1e-15)
    np.testing.assert_allclose(sol.std, 2.0, atol=1e-15)
    assert sol.cov is None
    with pytest.raises(ConfigError, match="covariance must be"):
        solve(np.eye(3), np.zeros(3), sigma=1.0, covariance="diag")
