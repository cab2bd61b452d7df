"""rank30's leftovers (session 30, rank30b): the outlier screen's refitted bases and the long log's elimination at
the baseline's rank tolerance (the log's printed precision, ``core.baseline.precision_rank_tol``).

review30c's plate logs (tests/core/data/rank30, test_discover_rank30.py) printed to fewer decimals: their two
rounding directions sit at QR pivots ~1-2 ``q / L`` of the largest; the baseline's ``rank_tol`` (10 ``q / L``) drops
them. Every fit of the same rows must drop them too.
"""
import numpy as np
import pytest

from core import baseline as B
from core import discover as D
from core.lsq import BlockDesign, DiagLowRank

from test_discover_rank30 import _planar, _rounded, _text


@pytest.fixture(scope="module")
def plate4():
    """plate_none_300 with Xn, Yn, Zn printed to 4 decimals of a mm: its planar baseline (rank 113 at its
    rank_tol 1.2e-5; 115 at 1e-9: the two rounding directions) and the baseline's basis Qall."""
    _, bl = _planar(_rounded(_text("plate_none_300"), 4))
    A = np.asarray(bl.A)
    Qall = D.orth_of(A, tol=bl.rank_tol, qr=bl.qr)
    assert Qall.shape[1] == 113 and D.orth_of(A).shape[1] == 115
    return bl, A, Qall


@pytest.mark.parametrize("row, m, flagged", [(100, 7.335, True), (10, 8.275, False)])
def test_outlier_screen_factors_the_rows_at_the_baselines_rank_tol(plate4, row, m, flagged):
    """The screen's verdict on a row does not depend on whether the caller hands it the baseline's basis (the
    engine's first screen: Qall, cut at rank_tol) or lets it factor the design itself (the extended designs'
    screens, a long log's rows after a removal, the slip test's fits). Known answers: one row of the 4-decimal
    log moved by ``m`` residual sigmas, halfway between the two thresholds the bisection measured with Qall
    (row 100: 7.279 sigma, row 10: 8.299) and with the screen's old 1e-9 cut (7.391 and 8.250: two more
    parameters made of the file's rounding move the deleted t and the Bonferroni bound's dof), 0.05 sigma from
    each. Fails with OUTLIER_RANK_TOL off (row 100 not flagged, row 10 flagged)."""
    bl, A, Qall = plate4
    y = bl.y.copy()
    y[row] += m * np.std(bl.y - Qall @ (Qall.T @ bl.y))
    given = D.find_outliers(A, y, Q=Qall, rank_tol=bl.rank_tol)
    assert (row in given) is flagged
    assert D.find_outliers(A, y, Q=None, rank_tol=bl.rank_tol) == given
    # no rank_tol (a design without one): orth_of's 1e-9, as before
    assert (row in D.find_outliers(A, y, Q=None)) is not flagged


def _dense_and_block(text, monkeypatch):
    t, dense = _planar(text)
    with monkeypatch.context() as mp:
        mp.setattr(B, "DENSE_DESIGN_BYTES", 0)
        block = B.planar(t)
    assert isinstance(block.A, BlockDesign) and not isinstance(dense.A, BlockDesign)
    assert block.rank_tol == dense.rank_tol and block.info["grid_step_mm"] == dense.info["grid_step_mm"]
    return dense, block


def _same_fit(a, b, tol):
    for u, v in zip(a[:2], b[:2]):
        u, v = (w.toarray() if isinstance(w, DiagLowRank) else w for w in (u, v))
        np.testing.assert_allclose(v, u, rtol=0, atol=tol * np.abs(u).max())
    assert np.array_equal(a[2], b[2])


@pytest.mark.parametrize("k", [None, 4, 3])
def test_long_log_elimination_agrees_with_the_dense_fit_on_a_rounded_log(monkeypatch, k):
    """The long log's fit eliminates the targets (_constrained_schur) on the rounded plate logs (their gauge's
    smallest direction 0.036 of the largest, condition 2.2e3: far from any cut) and equals the dense SVD's at the
    baseline's rank_tol: estimate and covariance to 1e-12 of their largest (measured at most 5e-14 on both
    logs, full precision and 5, 4, 3 decimals, every grid), the same parameters estimable."""
    text = _text("plate_none_300") if k is None else _rounded(_text("plate_none_300"), k)
    dense, block = _dense_and_block(text, monkeypatch)
    for rows in (np.arange(dense.n), np.arange(3, dense.n)):
        a = D._constrained(dense.A, dense.y, dense.C, dense.d, rows, None, 0, tol=dense.rank_tol)
        b = D._constrained(block.A, block.y, block.C, block.d, rows, None, 0, tol=block.rank_tol)
        assert isinstance(b[1], DiagLowRank) and b[2].all()
        _same_fit(a, b, 1e-12)


@pytest.mark.parametrize("eps", [3e-3, 1e-3])
def test_long_log_elimination_leaves_a_direction_near_the_cut_to_the_whole_matrix(monkeypatch, eps):
    """A log printed to 2 decimals of a mm (rank_tol 1.2e-3) with a near-collinear extension (its second column
    the first plus ``eps`` of another): the gauge's direction along their difference is at 9.2e-4 (eps 3e-3) or
    3.1e-4 (1e-3) of the largest, below the cut, so the dense fit leaves 9 parameters estimable; the equilibrated
    Schur complement's condition number is 1.3e6 or 1.2e7, below SCHUR_COND_MAX (1e8). Without
    SCHUR_TOL_MARGIN the elimination kept that direction (all 128 estimable, the estimate 17% and 53% of its
    largest from the dense one's); with it (the condition above 1 / (10 x 1.2e-3)^2 = 6.9e3) the whole normal
    matrix decides, as the dense fit."""
    dense, block = _dense_and_block(_rounded(_text("plate_none_300"), 2), monkeypatch)
    n = dense.n
    assert dense.rank_tol == pytest.approx(1.2e-3, rel=0.01)
    e = np.random.default_rng(3).normal(size=n)
    E = np.column_stack([e, e + eps * np.random.default_rng(4).normal(size=n)])
    C1 = np.hstack([dense.C, np.zeros((dense.C.shape[0], 2))])
    a = D._constrained(np.hstack([dense.A, E]), dense.y, C1, dense.d, np.arange(n), None, 0, tol=dense.rank_tol)
    b = D._constrained(np.hstack([block.A, E]), block.y, C1, block.d, np.arange(n), None, 0, tol=block.rank_tol)
    assert not a[2].all() and not isinstance(b[1], DiagLowRank)
    _same_fit(a, b, 1e-9)
