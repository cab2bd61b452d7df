"""core.diagnosis's nested F test against a design worked by hand (review31d F9: the residual dof of
:func:`core.diagnosis._nested_f_ss` and ``explained_rms_m`` had no test of their own; only the identity snapshot
of 16 campaigns changed when they were shifted)."""

import numpy as np
import pytest
from scipy import stats

from core import diagnosis as Dg


def test_nested_f_known_answer_by_hand():
    """Four observations y = 1, 2, 2, 4 at x = 0..3, the model a constant (dof 3): residuals y - 2.25 =
    (-1.25, -0.25, -0.25, 1.75), RSS 4.75. The added direction: the line's slope orthonormalised,
    u = (-3, -1, 1, 3) / sqrt(20); u.r = 9 / sqrt(20), SS = 81/20 = 4.05 (the line's fit: slope 0.9 over
    sum (x - 1.5)^2 = 5, 0.81 x 5 = 4.05; RSS of the line 0.7). F = (SS / k) / ((RSS - SS) / (dof - k))
    = 4.05 / (0.7 / 2) = 11.5714; p = F(1, 2) tail at 11.5714 = 0.076619 (scipy.stats.f.sf); explained
    RMS sqrt((SS - k s^2) / n) = sqrt((4.05 - 0.35) / 4) = 0.96177. Tolerance 1e-12 (a 4-row problem).
    A residual dof shifted by one (in s^2) gives F 17.36, p 0.053; SS - k s^2 / 2 gives RMS 0.98425."""
    y = np.array([1.0, 2.0, 2.0, 4.0])
    r = y - y.mean()
    rss = float(r @ r)
    assert rss == pytest.approx(4.75, rel=1e-15, abs=0)
    U = (np.array([-3.0, -1.0, 1.0, 3.0]) / np.sqrt(20))[:, None]
    x = np.arange(4.0)
    rss_line = float(np.linalg.lstsq(np.column_stack([np.ones(4), x]), y, rcond=None)[1][0])
    assert rss_line == pytest.approx(0.7, rel=1e-12, abs=0)  # the hand figure, by another path
    t = Dg.nested_f(U, r, rss, 3)
    assert t.k == 1 and t.ss == pytest.approx(4.05, rel=1e-12)
    F = 4.05 / (0.7 / 2)
    assert t.F == pytest.approx(F, rel=1e-12) and F == pytest.approx(11.5714, abs=1e-4)
    assert t.p_value == pytest.approx(stats.f.sf(F, 1, 2), rel=1e-10)
    assert t.p_value == pytest.approx(0.076619, abs=1e-6)
    assert t.explained_rms_m == pytest.approx(np.sqrt((4.05 - 0.35) / 4), rel=1e-12, abs=0)
    assert t.explained_rms_m == pytest.approx(0.96177, abs=1e-5)
    # no residual dof left beyond the direction: no test (dof - k < 1)
    assert Dg.nested_f(U, r, rss, 1).p_value == 1.0


def test_nested_f_two_directions_known_answer():
    """k = 2 on six observations (model: a constant, dof 5): the directions (1, -1, 0, 0, 0, 0) / sqrt 2 and
    (0, 0, 1, -1, 0, 0) / sqrt 2, residuals r = (1, -1, 2, 0, -1, -1): SS = (2 / sqrt 2)^2 + (2 / sqrt 2)^2 = 4,
    RSS 8, s^2 = (8 - 4) / (5 - 2) = 4/3, F = (4 / 2) / (4/3) = 1.5, p = F(2, 3) tail at 1.5 (scipy), explained
    RMS sqrt((4 - 2 x 4/3) / 6) = sqrt(2/9)."""
    r = np.array([1.0, -1.0, 2.0, 0.0, -1.0, -1.0])
    U = np.zeros((6, 2))
    U[[0, 1], 0] = np.array([1.0, -1.0]) / np.sqrt(2)
    U[[2, 3], 1] = np.array([1.0, -1.0]) / np.sqrt(2)
    t = Dg.nested_f(U, r, float(r @ r), 5)
    assert (t.k, t.ss, float(r @ r)) == (2, pytest.approx(4.0, rel=1e-12), 8.0)
    assert t.F == pytest.approx(1.5, rel=1e-12)
    assert t.p_value == pytest.approx(stats.f.sf(1.5, 2, 3), rel=1e-10)
    assert t.explained_rms_m == pytest.approx(np.sqrt(2 / 9), rel=1e-12, abs=0)
