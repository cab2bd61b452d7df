"""Session 33 (out33): a confident ``outlier`` needs dust to explain its rows better than one column of structure.

:func:`core.discover.outliers_structure` compares, by BIC, the screen's own reading (the baseline fitted on the
rows kept, one free value per set-aside row) with the baseline plus one structural column, every row kept
(:data:`core.discover.OUTLIERS_STRUCTURE_HEDGED`). Known answers on a made-up campaign of per-target offsets (a
target whose value drifts with time across its visits against isolated chips, and a step after reversed
approaches), the BIC checked against a direct least-squares fit of both models, bad input, and the two blind
misses it was built for (docs/discovery-studies.md, "Session 33: outliers that one column of structure explains").
"""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

import core.discover as D
from core.exceptions import ConfigError

N_TARGETS, VISITS, SIGMA = 20, 4, 0.3  # um: a probe's noise of gen_a's order


def _campaign(seed=0):
    """Per-target offsets: target ``T``'s ``VISITS`` touches at times 0, 1000, 2000, 3000 s (+ jitter), noise
    ``SIGMA``. Returns (orthonormal basis Q of the target indicators, target (n,), time (n,), noise (n,))."""
    rng = np.random.default_rng(seed)
    target = np.repeat(np.arange(N_TARGETS), VISITS)
    t = np.tile(np.arange(VISITS) * 1000.0, N_TARGETS) + rng.uniform(0, 50, N_TARGETS * VISITS)
    A = (target[:, None] == np.arange(N_TARGETS)[None, :]).astype(float)
    Q, _ = np.linalg.qr(A)
    return Q, target, t, rng.normal(0, SIGMA, len(target))


def _resid(Q, y):
    return y - Q @ (Q.T @ y)


def _time_column(target, t, T):
    x = np.zeros(len(target))
    m = target == T
    x[m] = t[m] - t[m].mean()
    return x


def _bic(y, X, n_free):
    """Direct BIC of the least-squares fit of ``y`` on ``X`` with ``n_free`` parameters."""
    c, *_ = np.linalg.lstsq(X, y, rcond=None)
    e = y - X @ c
    return len(y) * np.log(e @ e / len(y)) + n_free * np.log(len(y))


@pytest.mark.parametrize("seed", range(5))
def test_a_target_drifting_with_time_is_structure(seed):
    """Target 3 drifts 0 -> 6 um over its visits (20 sigma); its target mean leaves -3, -1, +1, +3 um, and the
    screen would set aside its two ends. Its time column explains them, the reversal column (random here) does not:
    structure, by more than the 2 log 2 the best of two columns pays."""
    Q, target, t, e = _campaign(seed)
    y = e.copy()
    m = np.where(target == 3)[0]
    y[m] += np.linspace(0, 6, VISITS)
    rng = np.random.default_rng(100 + seed)
    cols = {"time 3": _time_column(target, t, 3), "reversed approach": (rng.random(len(y)) < 0.2).astype(float)}
    got = D.outliers_structure(Q, _resid(Q, y), [m[0], m[-1]], cols)
    assert got["explains"] and got["column"] == "time 3"
    assert got["delta_bic"] < -10  # measured -38 to -14 over the five seeds: far from the decision's 0
    assert got["tried"] == ["reversed approach", "time 3"]


@pytest.mark.parametrize("seed", range(5))
def test_isolated_chips_are_dust(seed):
    """Two chips (+5 um, 17 sigma) on two targets' single visits: no column explains them."""
    Q, target, t, e = _campaign(seed)
    y = e.copy()
    rows = [3 * VISITS + 0, 11 * VISITS + 2]
    y[rows] += 5.0
    rng = np.random.default_rng(100 + seed)
    got = D.outliers_structure(Q, _resid(Q, y), rows, {"reversed approach": (rng.random(len(y)) < 0.2).astype(float)})
    assert not got["explains"] and got["delta_bic"] > 100  # measured 154-175


@pytest.mark.parametrize("seed", range(5))
def test_two_chips_on_one_target_not_in_time_order_are_dust(seed):
    """Chips at the first and third visits of one target (+5 um each): the target's time column is tried (two of
    its touches set aside, two kept) and does not explain them: a trend through +5, 0, +5, 0 leaves more than two
    free values do."""
    Q, target, t, e = _campaign(seed)
    y = e.copy()
    rows = [7 * VISITS + 0, 7 * VISITS + 2]
    y[rows] += 5.0
    got = D.outliers_structure(Q, _resid(Q, y), rows, {"time 7": _time_column(target, t, 7)})
    assert got["column"] == "time 7" and not got["explains"] and got["delta_bic"] > 50  # measured 110-125


@pytest.mark.parametrize("seed", range(5))
def test_a_step_after_reversed_approaches_is_structure(seed):
    """A seat that reads -6 um after a reversed approach, on 20 % of the touches: most of the flagged targets'
    step is taken by their offsets; a target flagged at some visits only shows it as an outlier. The screen's rows
    are those odd touches; the reversal column explains them."""
    Q, target, t, e = _campaign(seed)
    rng = np.random.default_rng(200 + seed)
    rev = (rng.random(len(target)) < 0.2).astype(float)
    y = e - 6.0 * rev
    r = _resid(Q, y)
    # the screen's reading: the touches standing out beyond 4 sigma of the target-mean fit
    rows = np.where(np.abs(r) > 4 * SIGMA * np.sqrt(1 - 1 / VISITS))[0]
    assert len(rows) >= 2
    got = D.outliers_structure(Q, r, rows, {"reversed approach": rev})
    assert got["explains"] and got["delta_bic"] < -10  # measured -88 to -60


def test_bic_against_a_direct_fit():
    """The two BICs against explicit least squares: dust = target indicators + one dummy per outlier row; structure
    = target indicators + the column, plus the 2 log m of the m = 2 columns tried."""
    Q, target, t, e = _campaign(1)
    A = (target[:, None] == np.arange(N_TARGETS)[None, :]).astype(float)
    y = e.copy()
    m = np.where(target == 5)[0]
    y[m] += np.linspace(0, 4, VISITS)
    rows = [m[0], m[-1]]
    x = _time_column(target, t, 5)
    cols = {"time 5": x, "other": np.sin(np.arange(len(y)))}
    got = D.outliers_structure(Q, _resid(Q, y), rows, cols)
    dummies = np.zeros((len(y), 2))
    dummies[rows, [0, 1]] = 1.0
    bic_dust = _bic(y, np.hstack([A, dummies]), N_TARGETS + 2)
    bic_struct = min(_bic(y, np.hstack([A, c[:, None]]), N_TARGETS + 1) for c in cols.values()) + 2 * np.log(2)
    # the basis's residuals and projections against a fresh lstsq: agreement to rounding (values ~ -400)
    assert got["bic_dust"] == pytest.approx(bic_dust, abs=1e-6)
    assert got["bic_structure"] == pytest.approx(bic_struct, abs=1e-6)
    assert got["delta_bic"] == pytest.approx(bic_struct - bic_dust, abs=1e-6)


def test_a_column_inside_the_baseline_is_not_tried():
    """A column the baseline spans (a target's indicator) explains nothing new: skipped; none left -> None."""
    Q, target, t, e = _campaign(2)
    y = e.copy()
    y[[0, 5]] += 5.0
    inside = (target == 4).astype(float)
    assert D.outliers_structure(Q, _resid(Q, y), [0, 5], {"inside": inside}) is None
    got = D.outliers_structure(Q, _resid(Q, y), [0, 5], {"inside": inside, "time 0": _time_column(target, t, 0)})
    assert got["tried"] == ["time 0"]


def test_bad_input():
    Q, target, t, e = _campaign(3)
    r = _resid(Q, e)
    with pytest.raises(ConfigError, match="outliers within"):
        D.outliers_structure(Q, r, [len(r)], {})
    with pytest.raises(ConfigError, match="outliers within"):
        D.outliers_structure(Q[:-1], r, [0], {})
    with pytest.raises(ConfigError, match="column x has shape"):
        D.outliers_structure(Q, r, [0, 1], {"x": np.zeros(3)})


def test_columns_of_a_planar_campaign(monkeypatch):
    """:func:`core.discover.outlier_structure_columns`: a target's time only where it holds two outliers and a
    kept touch; the reversal where the approach's cosine with the move before is negative (0 without one). With
    :data:`core.discover.OUTLIER_STRUCTURE_REVERSAL_TRAVEL` (on since session 36) the reversal also as a travel along
    the approach, read on the normal: the flag times the approach's cosine with the normal."""
    monkeypatch.setattr(D, "OUTLIER_STRUCTURE_REVERSAL_TRAVEL", False)
    target = np.array([0, 0, 0, 1, 1, 2, 2, 2])
    t_s = np.arange(8) * 10.0
    d = np.tile([1.0, 0, 0], (8, 1))
    d_prev = d.copy()
    d_prev[[2, 6]] = [-1.0, 0, 0]
    d_prev[[4]] = [0.0, 1, 0]  # a right angle: not reversed
    d_prev[0] = np.nan
    touches = SimpleNamespace(t_s=t_s, target=target, target_ids=("a", "b", "c"), d_R=d, d_prev_R=d_prev)
    bl = SimpleNamespace(kind="planar", y=np.zeros(8), whiten=None, data=SimpleNamespace(touches=touches))
    cols = D.outlier_structure_columns(bl, [0, 1, 3, 4])
    # target a: two outliers and a kept touch -> its time; target b: both touches set aside -> none
    assert sorted(cols) == ["reversed approach", "time a"]
    assert cols["time a"] == pytest.approx([-10, 0, 10, 0, 0, 0, 0, 0])
    assert cols["reversed approach"].tolist() == [0, 0, 1, 0, 0, 0, 1, 0]
    # the travel: normals at 0 and 60 degrees to the approach (cosines 1 and 0.5) on the two reversed touches
    n = np.tile([1.0, 0, 0], (8, 1))
    n[6] = [0.5, np.sqrt(0.75), 0]
    touches.n_R = n
    monkeypatch.setattr(D, "OUTLIER_STRUCTURE_REVERSAL_TRAVEL", True)
    cols = D.outlier_structure_columns(bl, [0, 1, 3, 4])
    assert sorted(cols) == ["reversed approach", "reversed approach travel", "time a"]
    assert cols["reversed approach travel"] == pytest.approx([0, 0, 1, 0, 0, 0, 0.5, 0], abs=1e-15)
    assert D.outlier_structure_columns(SimpleNamespace(kind="volumetric"), [0, 1]) == {}
