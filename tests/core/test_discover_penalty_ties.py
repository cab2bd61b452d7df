"""The ridge penalty chosen from a held-out curve that cannot tell penalties apart (session 32, review32c F8).

Every ridge penalty of discover is chosen over :data:`core.discover.PENALTY_GRID` by the held-out mean square. Where
the curve is flat (the unnamed smooth in ``feature``: every column the held-out set-up's own, refitted unpenalised,
so the penalty never enters the held-out residuals), the first least value was decided by the last bits of the
figures, and a translation of the log chose another penalty and another extended workpiece (167.6 um apart on
review32c's both_outlier_clamp_relax_20002). :func:`core.discover._penalty_pick` takes the largest penalty within
:data:`core.discover.PENALTY_TIE_RTOL` (relative) of the least held-out mean square.
"""

import numpy as np
import pytest

import core.discover as D
from core.discover import _penalty_flatness, _penalty_pick


def test_a_flat_curve_takes_the_largest_penalty():
    # seven values equal to rounding (3e-15 relative: the reviewer's curve), the least one first: the largest penalty
    base = 0.2457
    cvs = base * (1 + np.array([-3e-15, 1e-15, 0.0, 2e-15, -1e-15, 1e-15, 0.0]))
    assert _penalty_pick(cvs) == len(cvs) - 1
    # the same curve with its rounding reversed: the same choice (the rule before took the first least value: the
    # smallest penalty here, the largest below; rounding decided it)
    assert _penalty_pick(cvs[::-1]) == len(cvs) - 1
    assert _penalty_flatness(cvs) < 1e-14


def test_a_curve_that_discriminates_takes_its_minimum():
    # the least relative spread of a discriminating curve review32c measured is 0.0076: its minimum is kept
    cvs = np.array([1.0, 0.99, 0.98, 0.9924, 1.01, 1.2, 1.5])
    assert _penalty_pick(cvs) == 2
    # a tie within 1e-9 relative between two penalties, a larger penalty beyond it: the larger of the tie only
    cvs = np.array([1.0, 0.98, 0.98 * (1 + 5e-10), 0.98 * (1 + 2e-9), 1.2, 1.3, 1.4])
    assert _penalty_pick(cvs) == 2
    assert _penalty_flatness(cvs) == pytest.approx(1.4 / 0.98 - 1)


def test_the_rule_before_is_the_first_least_value(monkeypatch):
    monkeypatch.setattr(D, "PENALTY_TIE_RTOL", None)
    cvs = np.array([1.0, 0.5, 0.5, 0.5, 0.7])
    assert _penalty_pick(cvs) == 1
    monkeypatch.setattr(D, "PENALTY_TIE_RTOL", 1e-9)
    assert _penalty_pick(cvs) == 3


def test_per_column_choice_and_a_failed_fit():
    # (n_grid, B): one choice per bootstrap refit, by the same rule; a NaN (a failed fit) is never chosen
    cvs = np.array([[1.0, 2.0, np.nan],
                    [1.0, 1.0, 3.0],
                    [1.0 + 1e-12, 1.5, 2.0],
                    [1.5, 1.0 + 1e-6, np.nan]])
    assert list(_penalty_pick(cvs)) == [2, 1, 2]
    assert _penalty_pick(np.array([np.nan, 2.0, 1.0])) == 2
