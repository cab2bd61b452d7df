"""core.lsq.normal_inverse: (X^T X)^-1 with its conditioning checked (review31d F6).

Used for discover's named-magnitude covariance with nonlinear parameters (core/discover.py, _magnitudes) and the
blind-lobe reporting (core/selfcal.py, blind_lobes), which inverted the normal matrix with no check: only an
exactly singular one raised (and fell back to pinv, a zero variance along the unseen direction).
"""

import numpy as np
import pytest

from core.exceptions import ConfigError
from core.lsq import RANK_TOL, normal_inverse


def test_well_conditioned_is_the_plain_inverse_bit_for_bit():
    rng = np.random.default_rng(31)
    for k in (1, 2, 5):
        X = rng.normal(size=(40, k)) * np.logspace(-6, 3, k)  # badly scaled but well conditioned once equilibrated
        assert np.array_equal(normal_inverse(X), np.linalg.inv(X.T @ X))


def test_nearly_collinear_columns_keep_the_floor_variance_by_hand():
    # x1 = e1, x2 = e1 + eps e2, eps = 1e-9: in doubles X^T X = [[1, 1], [1, 1]] exactly (1 + 1e-18 rounds to 1),
    # so the old inv raised and pinv gave variance 0.25 on each (the seen direction's alone). By hand: singular
    # values sqrt(2) and eps / sqrt(2) along v1 = (1, 1)/sqrt(2), v2 = (1, -1)/sqrt(2); the second is below
    # sqrt(RANK_TOL) sqrt(2) (the floor, 1.414e-6) and counts at it: cov = v1 v1^T / 2 + v2 v2^T / floor^2,
    # diagonal 0.25 + 0.5 / (2e-12) = 2.5e11 + 0.25, off-diagonal 0.25 - 2.5e11.
    eps = 1e-9
    X = np.array([[1.0, 1.0], [0.0, eps], [0.0, 0.0]])
    floor2 = RANK_TOL * 2.0
    want = np.array([[0.25 + 0.5 / floor2, 0.25 - 0.5 / floor2], [0.25 - 0.5 / floor2, 0.25 + 0.5 / floor2]])
    assert normal_inverse(X) == pytest.approx(want, rel=1e-6)  # rel: the column norms differ from 1 by 5e-19
    # the plain inverse here: singular (what the old code caught), pinv's 0.25 understated by 1e12
    with pytest.raises(np.linalg.LinAlgError):
        np.linalg.inv(X.T @ X)


def test_near_singular_where_inv_returns_rounding():
    # eps = 3e-8: eps^2 = 9e-16 is 4 ulps of 1, the normal matrix is not singular in doubles and inv returns
    # ~1e15 built on those 4 ulps (tens of % off the exact 1 / eps^2 = 1.1e15). Above the tolerance the answer
    # comes from X's SVD at the floor: finite, symmetric, positive semi-definite, the seen direction exact.
    X = np.array([[1.0, 1.0], [0.0, 3e-8], [0.0, 0.0]])
    C = normal_inverse(X)
    assert np.allclose(C, C.T, rtol=0, atol=1e-3)
    w = np.linalg.eigvalsh(C)
    # the seen direction: 1 / s1^2 = 0.5 (s1 = sqrt(2)), to the rounding the floor's variance leaks into it
    # (2.5e11 x 2.2e-16 = 6e-5 absolute; 1e-3 allowed)
    assert w.min() == pytest.approx(0.5, abs=1e-3)
    assert w.max() == pytest.approx(1.0 / (RANK_TOL * 2.0), rel=1e-6)  # the floor's variance
    # a zero column (a nonlinear parameter that moves nothing) is unseen: the floor's variance, not pinv's 0. The
    # other column equilibrated has singular value 1, so the floor is sqrt(RANK_TOL) = 1e-6 (the zero column in its
    # own units): variance 1e12; the seen one's 1 / |x1|^2 = 0.2
    Z = np.array([[1.0, 0.0], [2.0, 0.0]])
    assert np.diag(normal_inverse(Z)) == pytest.approx([0.2, 1.0 / RANK_TOL], rel=1e-12, abs=0)


def test_bad_input():
    with pytest.raises(ConfigError, match="finite"):
        normal_inverse(np.array([[1.0, np.nan]]))
    with pytest.raises(ConfigError, match="finite"):
        normal_inverse(np.ones(3))
