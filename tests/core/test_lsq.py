"""The shared solver's helpers (core.lsq): gauge removal and covariance modes.

The solver itself is exercised by every identification (tests/core/test_selfcal.py,
test_volumetric.py, test_discover_*.py): round trips, rank messages, sparse path.
"""

import numpy as np
import scipy.sparse as sp
import pytest

from core.exceptions import ConfigError, IdentifiabilityError
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


# ---------------------------------------------------------------------------
# block elimination of a diagonal block (the workpiece of a self-calibration)
# ---------------------------------------------------------------------------
def one_per_row_problem(rng, m=400, q=40, p=12):
    """Rows touch one of q 'target' parameters (diagonal block) and p shared ones; two constraints."""
    tgt = rng.integers(0, q, m)
    tgt[:q] = np.arange(q)  # every target observed
    A = np.zeros((m, q + p))
    A[np.arange(m), tgt] = rng.uniform(0.5, 2.0, m)
    A[:, q:] = rng.standard_normal((m, p)) * (rng.random((m, p)) < 0.5)
    C = np.zeros((2, q + p))
    C[0, q] = 1.0
    C[1, q + 1:q + 3] = (1.0, -1.0)
    return A, C, np.array([0.3, -0.1])


@pytest.mark.parametrize("dense_max", [0, 10])
def test_block_elimination_equals_the_dense_solve(monkeypatch, rng, dense_max):
    """Known answer: the Schur path gives the dense path's estimate, residuals and
    standard uncertainties to rounding (same problem, DENSE_MAX lowered to force it)."""
    from core import lsq

    A, C, d = one_per_row_problem(rng)
    b = A @ rng.standard_normal(A.shape[1]) + 0.01 * rng.standard_normal(A.shape[0])
    ref = solve(A, b, C, d, covariance="full")
    monkeypatch.setattr(lsq, "DENSE_MAX", dense_max)
    sch = solve(A, b, C, d, covariance="std", diagonal=slice(0, 40))
    lu = solve(A, b, C, d, covariance="std")  # the sparse LU of the whole normal matrix
    for s in (sch, lu):
        np.testing.assert_allclose(s.theta, ref.theta, rtol=1e-10, atol=1e-12)
        np.testing.assert_allclose(s.std, ref.std, rtol=1e-9, atol=1e-15)
        assert s.sigma == pytest.approx(ref.sigma, rel=1e-10)
    # many right-hand sides through the same factor (Monte Carlo)
    E = rng.standard_normal((A.shape[0], 5))
    np.testing.assert_allclose(sch.estimator.noise_gain(E), ref.estimator.noise_gain(E), rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(sch.estimator.covariance_of([0, 45]), ref.estimator.covariance_of([0, 45]),
                               rtol=1e-9, atol=1e-15)


def test_block_elimination_names_the_unidentifiable(monkeypatch, rng):
    """Two shared parameters with equal columns: the Schur complement is singular and the
    message names the pair, as the dense path does."""
    from core import lsq

    A, C, d = one_per_row_problem(rng)
    A[:, -1] = A[:, -2]
    monkeypatch.setattr(lsq, "DENSE_MAX", 0)
    names = [f"t{i}" for i in range(40)] + [f"s{i}" for i in range(12)]
    with pytest.raises(IdentifiabilityError, match=r"rank deficient by 1 beyond the constraints; "
                                                    r"unidentifiable: .*s1[01].*s1[01]"):
        solve(A, np.zeros(A.shape[0]), C, d, names=names, diagonal=slice(0, 40))


def test_block_elimination_bad_diagonal(monkeypatch, rng):
    from core import lsq

    A, C, d = one_per_row_problem(rng)
    monkeypatch.setattr(lsq, "DENSE_MAX", 0)
    A2 = A.copy()
    A2[5, 7] = A2[5, 8] = 1.0  # row 5 already touches target 5
    with pytest.raises(ConfigError, match=r"diagonal block: observation 5 touches 3 of its parameters"):
        solve(A2, np.zeros(A.shape[0]), C, d, diagonal=slice(0, 40))
    with pytest.raises(ConfigError, match="a constraint touches a parameter of the diagonal block"):
        solve(A, np.zeros(A.shape[0]), C, d, diagonal=slice(0, 41))
    with pytest.raises(ConfigError, match=r"diagonal: indices must lie in 0..51"):
        solve(A, np.zeros(A.shape[0]), C, d, diagonal=[3, 99])


# --- block designs (a long self-calibration log's design, the targets' block eliminated) ---
def _blocks(seed=3, n=240, g=12, m=5):
    from core.lsq import BlockDesign

    r = np.random.default_rng(seed)
    ids = np.r_[np.arange(g), r.integers(0, g - 2, n - g)]  # every target present, two of them once only
    D = r.normal(size=(n, m))
    D[:, 2] = D[:, 0] - 2 * D[:, 1]  # a dependent column
    D[:, 3] = np.eye(g)[ids] @ r.normal(size=g)  # a column inside the targets' block
    return BlockDesign(ids, D, np.arange(2, 2 + g), np.r_[0:2, 2 + g:2 + g + m - 2]), r


def test_block_design_round_trip_and_products():
    """toarray / from_sparse round trip; A @ theta, A.T @ X, A[rows], hstack and gram equal the dense matrix's."""
    import scipy.sparse as sp

    from core.lsq import BlockDesign

    A, r = _blocks()
    Ad = A.toarray()
    assert A.shape == Ad.shape and np.all(Ad[:, A.g_cols].sum(axis=1) == 1)
    B = BlockDesign.from_sparse(sp.csr_matrix(Ad), A.g_cols)
    assert np.array_equal(B.toarray(), Ad)
    assert sp.issparse(B.D) and not sp.issparse(A.D)  # from_sparse keeps the machine block sparse
    th, X, E = r.normal(size=A.shape[1]), r.normal(size=(A.shape[0], 3)), r.normal(size=(A.shape[0], 2))
    rows = np.arange(0, A.shape[0], 3)
    for M in (A, B):  # D dense and D sparse: the same matrix
        np.testing.assert_allclose(M @ th, Ad @ th, atol=1e-13)
        np.testing.assert_allclose(M.T @ X, Ad.T @ X, atol=1e-12)
        np.testing.assert_allclose(M.T @ X[:, 0], Ad.T @ X[:, 0], atol=1e-12)
        np.testing.assert_allclose(M.gram(), Ad.T @ Ad, atol=1e-12)
        assert np.array_equal(M[rows].toarray(), Ad[rows])
        ME = np.hstack([M, E])
        assert np.array_equal(ME.toarray(), np.hstack([Ad, E])) and sp.issparse(ME.D) == sp.issparse(M.D)
        Q, QA = M.basis(1e-9), A.basis(1e-9)  # the basis of either: the same span, rank and leverage
        assert Q.shape == QA.shape
        np.testing.assert_allclose(Q @ (Q.T @ X), QA @ (QA.T @ X), atol=1e-12)
        np.testing.assert_allclose(Q.leverage(), QA.leverage(), atol=1e-12)


def test_block_basis_is_the_dense_orth_span():
    """The basis of a block design spans what diagnosis.orth spans (same rank at two cuts, same projector and
    leverage), and behaves as a matrix where discovery uses one (hstack with new directions, Q[:, k:])."""
    from core.diagnosis import new_basis, orth
    from core.lsq import Basis, leverage

    A, r = _blocks()
    Ad = A.toarray()
    for tol in (1e-9, 1e-7):
        Q, Qd = A.basis(tol), orth(Ad, tol=tol)
        assert Q.shape == Qd.shape == (A.shape[0], A.shape[1] - 2)  # the dependent and the in-block column
        np.testing.assert_allclose(Q.toarray().T @ Q.toarray(), np.eye(Q.shape[1]), atol=1e-12)
        X = r.normal(size=(A.shape[0], 4))
        np.testing.assert_allclose(Q @ (Q.T @ X), Qd @ (Qd.T @ X), atol=1e-12)
        np.testing.assert_allclose(leverage(Q), leverage(Qd), atol=1e-12)
    rows = np.arange(1, A.shape[0], 4)  # a subset of rows: Q[rows].T @ X, dense and sparse X
    np.testing.assert_allclose(Q.rows_rmatmul(rows, X[rows]), Q.toarray()[rows].T @ X[rows], atol=1e-12)
    np.testing.assert_allclose(Q.rows_rmatmul(rows, sp.csr_matrix(X[rows])), Q.toarray()[rows].T @ X[rows],
                               atol=1e-12)
    U = new_basis(Q, X)
    Q2 = np.hstack([Q, U])
    assert isinstance(Q2, Basis) and Q2.shape[1] == Q.shape[1] + 4 and np.array_equal(Q2[:, Q.shape[1]:], U)
    # a basis widened with new directions, as discovery extends it
    np.testing.assert_allclose(Q2.rows_rmatmul(rows, X[rows]), Q2.toarray()[rows].T @ X[rows], atol=1e-12)
    assert np.array_equal(Q2, Q2) and not np.array_equal(Q2, Q)
    # (Q @ c)[rows] without the product over every row (its span, dense columns and indicators), c 2-D and 1-D
    for B in (Q, Q2):
        c = r.normal(size=(B.shape[1], 3))
        np.testing.assert_allclose(B.rows_matmul(rows, c), B.toarray()[rows] @ c, atol=1e-12)
        np.testing.assert_allclose(B.rows_matmul(rows, c[:, 0]), (B @ c[:, 0])[rows], atol=1e-12)


def test_basis_rows_rmatmul_into_a_sum_is_the_sum_bit_for_bit():
    """``rows_rmatmul(pos, X, out=S)`` (a block of rows' share added in place, only the indicators the rows touch
    formed) holds what ``S + rows_rmatmul(pos, X)`` does, bit for bit, for dense and sparse ``X`` (sparse with
    some columns empty on the block), over blocks whose rows repeat targets (ten targets on 240 rows), and a sum
    over blocks started from zeros is the sum started from the first block's share."""
    import scipy.sparse as sp

    A, r = _blocks()
    Q = A.basis(1e-9)
    X = r.normal(size=(A.shape[0], 6))
    Xs = X * (r.random(X.shape) < 0.3)
    Xs[:, 4] = 0.0
    for Y in (X, sp.csr_matrix(Xs)):
        ref, got = None, np.zeros((Q.shape[1], 6))
        for a in range(0, A.shape[0], 50):
            pos = np.arange(a, min(a + 50, A.shape[0]))
            assert len(np.unique(A.ids[pos])) < len(pos)  # repeated targets within the block
            share = Q.rows_rmatmul(pos, Y[pos])
            ref = share if ref is None else ref + share
            before = got.copy()
            assert Q.rows_rmatmul(pos, Y[pos], out=got) is got
            assert np.array_equal(got, before + share)
        assert np.array_equal(got, ref)
        np.testing.assert_allclose(got, Q.toarray().T @ (Y.toarray() if sp.issparse(Y) else Y), atol=1e-12)
    # counts that leave a row's id without a column: refused on both paths (into a sum, out[-1] took it silently)
    from core.lsq import Basis
    bad = Basis(Q.ids, np.where(np.arange(len(Q.counts)) == Q.ids[0], 0, Q.counts), Q.U, Q.span)
    for out in (None, np.zeros((bad.shape[1], 6))):
        with pytest.raises(ValueError, match="no indicator column"):
            bad.rows_rmatmul(np.arange(5), X[:5], out=out)


def test_block_design_bad_input():
    """Ids outside the block, a D of the wrong shape, columns numbered twice, an indicator column that is not one
    1 per row, and densifying an operator: one-line ConfigErrors."""
    import scipy.sparse as sp

    from core.lsq import BlockDesign

    A, _ = _blocks()
    with pytest.raises(ConfigError, match="ids must lie"):
        BlockDesign(A.ids + A.g, A.D, A.g_cols, A.d_cols)
    with pytest.raises(ConfigError, match="D \\(n"):
        BlockDesign(A.ids, A.D[:-1], A.g_cols, A.d_cols)
    with pytest.raises(ConfigError, match="once each"):
        BlockDesign(A.ids, A.D, A.g_cols, np.r_[A.d_cols[:-1], 0])
    Ad = A.toarray()
    Ad[0, A.g_cols[1]] = 1.0  # row 0 in two targets
    with pytest.raises(ConfigError, match="one 1 per row"):
        BlockDesign.from_sparse(sp.csr_matrix(Ad), A.g_cols)
    with pytest.raises(ConfigError, match="not an array"):
        np.asarray(A.basis())
    with pytest.raises(ConfigError, match="not defined"):
        np.vstack([A, A])


def test_block_basis_from_blocks_of_rows_is_one_factorisation(monkeypatch):
    """The block basis's R stacked from blocks of a few rows (TSQR) gives the span, rank and leverage of one block
    and of the dense orth (1e-12), its kept map is orthonormal, and its rows, products and toarray agree."""
    from core import lsq
    from core.diagnosis import orth

    A, r = _blocks(n=300)
    one = A.basis(1e-9)
    monkeypatch.setattr(lsq, "CHUNK_BYTES", 8 * 5 * 7)  # 7 rows a block
    B = lsq.BlockDesign(A.ids, A.D, A.g_cols, A.d_cols)
    Q, Qd = B.basis(1e-9), orth(A.toarray(), tol=1e-9)
    assert Q.span is not None and Q.shape == one.shape == Qd.shape
    X = r.normal(size=(A.shape[0], 3))
    for P in (one, Qd):
        np.testing.assert_allclose(Q @ (Q.T @ X), P @ (P.T @ X), atol=1e-12)
    Qa = Q.toarray()
    np.testing.assert_allclose(Qa.T @ Qa, np.eye(Q.shape[1]), atol=1e-13)
    np.testing.assert_allclose(lsq.leverage(Q), np.sum(Qa ** 2, axis=1), atol=1e-13)
    c = r.normal(size=Q.shape[1])
    np.testing.assert_allclose(Q @ c, Qa @ c, atol=1e-13)
    np.testing.assert_allclose(Q.dense_rows(np.arange(5, 40)), Qa[5:40, Q.k:], atol=1e-14)
    # each row's one nonzero indicator entry sits in its id's column
    jc = Q.indicator_columns(Q.ids)
    assert np.all(jc >= 0) and np.array_equal(np.argmax(np.abs(Qa[:, :Q.k]), axis=1), jc)
    np.testing.assert_allclose(lsq.row_column_norms(A.D, np.arange(0, 300, 2)), np.linalg.norm(A.D[::2], axis=0),
                               rtol=1e-14)


def test_block_basis_span_columns_cannot_be_taken():
    """Q[:, j] inside the basis's own (mapped) directions is refused with a one-line ConfigError naming the first
    column that can be taken; an empty hstack leaves the design itself."""
    A, _ = _blocks()
    Q = A.basis()
    with pytest.raises(ConfigError, match=f"k >= {Q.shape[1]}"):
        Q[:, Q.k:]
    assert np.hstack([A, np.zeros((A.shape[0], 0))]) is A


def test_group_sums_of_a_dense_block_are_the_indicator_products_bit_for_bit():
    """core.lsq.group_sums sums a dense (n, k) block per id by one bincount over (id, column) cells (session 23):
    the sums must be the indicator block's CSR product's bit for bit (each cell summed from 0 in row order), over
    ids that skip groups, magnitudes 1e-8-1e8 (where the order of the additions shows), C and Fortran layouts."""
    from core.lsq import group_sums

    rng = np.random.default_rng(23)
    for trial in range(300):
        n, g, k = int(rng.integers(1, 400)), int(rng.integers(1, 60)), int(rng.integers(0, 13))
        ids = rng.integers(0, g, n)
        X = rng.normal(size=(n, k)) * 10.0 ** rng.integers(-8, 9, size=(n, 1))
        if trial % 2:
            X = np.asfortranarray(X)
        G = sp.csr_matrix((np.ones(n), (ids, np.arange(n))), shape=(g, n))
        got = group_sums(ids, g, X)
        assert got.shape == (g, k) and np.array_equal(got, np.asarray(G @ X)), trial
    # a sum whose order matters: 1e16 + 1 - 1e16 is 0 in row order, 1 in another
    X = np.array([[1e16], [1.0], [-1e16]])
    assert group_sums(np.zeros(3, int), 1, X)[0, 0] == 0.0


def test_quadratic_form_sf_known_answers():
    """The exact tail against closed forms (session 30, small30): equal weights are a scaled
    chi-square (chi2_k tails at 1e-2, 1e-3, 1e-5 for k = 2, 3, 4, 6: error below 3e-6, 2e-7, 2e-9, Imhof's
    quadrature's accuracy (measured 1.9e-6, 8.5e-8, 8.9e-10); since session 36 x > 0 takes the saddlepoint
    contour, measured below 1e-15 here: tests/core/test_quadratic_form_tail.py), and 2 chi2_40 at 30); weights
    (1 - c) on 4 degrees and -c on 20 at x = 0 (Imhof's) are the beta tail of a ratio
    of chi-squares, P(chi2_4 / (chi2_4 + chi2_20) > c) = beta(2, 10).sf(c) (error below 1e-9, measured
    1e-16); all-zero weights are a point mass at 0."""
    from scipy import stats

    from core.lsq import quadratic_form_sf

    for k, tol in ((2, 3e-6), (3, 2e-7), (4, 2e-9), (6, 2e-9)):
        for p in (1e-2, 1e-3, 1e-5):
            x = float(stats.chi2.isf(p, k))
            assert quadratic_form_sf(np.ones(k), x) == pytest.approx(p, abs=tol)
            assert quadratic_form_sf([2.5], 2.5 * x, [k]) == pytest.approx(p, abs=tol)
    assert quadratic_form_sf([2.0], 30.0, [40]) == pytest.approx(stats.chi2.sf(15.0, 40), abs=1e-9)
    for c in (0.05, 0.3, 0.6):
        assert quadratic_form_sf([1 - c, -c], 0.0, [4, 20]) == pytest.approx(stats.beta(2, 10).sf(c), abs=1e-9)
    assert quadratic_form_sf([0.0, 0.0], -1.0) == 1.0 and quadratic_form_sf([0.0], 1.0) == 0.0


def test_quadratic_form_sf_unequal_weights_against_sampling():
    """200 unequal weights (u^4, u uniform: a few dominate, as a fine table's eigenvalues do), tail
    at the mean + 3 sd (a 'z' of 3): the inversion against 400,000 draws of the form, within 4
    binomial standard errors (sd 1e-4 here); both are about 0.0043, three times a normal's 0.00135:
    why a z > 3 gate on such a statistic does not give the normal's rate."""
    from core.lsq import quadratic_form_sf

    rng = np.random.default_rng(0)
    w = rng.uniform(0, 1, 200) ** 4
    x = w.sum() + 3 * np.sqrt(2 * (w ** 2).sum())
    p = quadratic_form_sf(w, x)
    draws = np.concatenate([(rng.standard_normal((100_000, 200)) ** 2) @ w for _ in range(4)])
    mc = float(np.mean(draws > x))
    assert abs(p - mc) < 4 * np.sqrt(mc * (1 - mc) / draws.size)
    assert 2.5e-3 < p < 6e-3


def test_quadratic_form_sf_bad_input():
    from core.lsq import quadratic_form_sf

    for args, match in ((([1.0, np.nan],), "weights"), (([1.0, 1.0], 1.0, [1.0]), "mult"),
                        (([1.0, 1.0], 1.0, [1.0, 0.0]), "mult"), (([1.0, 1.0], np.inf), "x"),
                        (([1.0],), "degrees of freedom")):
        with pytest.raises(ConfigError, match=match):
            quadratic_form_sf(*args)


# ---------------------------------------------------------------------------
# known answers of solve's own (review31d F3: sigma, dof, rank threshold)
# ---------------------------------------------------------------------------
def test_constrained_line_known_answer_by_hand():
    """A line y = a + b x through the point (1, 1) (the constraint a + b = 1), four observations x = 0..3,
    y = 1, 2, 2, 4. By hand: a = 1 - b, so y - 1 = b (x - 1): b = sum (x-1)(y-1) / sum (x-1)^2
    = (0 + 0 + 1 + 6) / (1 + 0 + 1 + 4) = 7/6, a = -1/6; residuals 7/6, 1, -1/6, 2/3, RSS = (49 + 36 + 1 + 16)/36
    = 17/6; dof = m - n + c = 4 - 2 + 1 = 3; sigma^2 = RSS / dof = 17/18; var b = sigma^2 / sum (x-1)^2 = 17/108,
    a = 1 - b: var a = var b, cov(a, b) = -var b; rms = sqrt(RSS / m) = sqrt(17/24). Tolerance 1e-14 (rounding of
    a 2 x 2 problem); a sigma over dof + 1 moves sigma by 13 %, a dof of m - n + c + 1 to 4."""
    x = np.arange(4.0)
    A = np.column_stack([np.ones(4), x])
    y = np.array([1.0, 2.0, 2.0, 4.0])
    for cov in ("full", "std"):
        sol = solve(A, y, C=np.array([[1.0, 1.0]]), d=np.array([1.0]), covariance=cov)
        np.testing.assert_allclose(sol.theta, [-1 / 6, 7 / 6], rtol=0, atol=1e-14)
        np.testing.assert_allclose(sol.residuals, [7 / 6, 1.0, -1 / 6, 2 / 3], rtol=0, atol=1e-14)
        assert sol.dof == 3 and sol.sigma_source == "residuals"
        assert sol.sigma == pytest.approx(np.sqrt(17 / 18), rel=1e-14, abs=0)
        assert sol.rms == pytest.approx(np.sqrt(17 / 24), rel=1e-14, abs=0)
        np.testing.assert_allclose(sol.std, np.sqrt(17 / 108) * np.ones(2), rtol=1e-13)
    np.testing.assert_allclose(sol_full_cov := solve(A, y, C=np.array([[1.0, 1.0]]), d=np.array([1.0]),
                                                     covariance="full").cov,
                               17 / 108 * np.array([[1.0, -1.0], [-1.0, 1.0]]), rtol=1e-13)
    assert sol_full_cov.shape == (2, 2)
    # unconstrained, the same data: the ordinary line, dof m - n = 2, sigma^2 = RSS / 2 (numpy's lstsq for RSS)
    free = solve(A, y)
    rss = float(np.linalg.lstsq(A, y, rcond=None)[1][0])
    assert free.dof == 2 and free.sigma == pytest.approx(np.sqrt(rss / 2), rel=1e-13, abs=0)


def _near_collinear(eps):
    """Two columns u and u + eps v (u, v orthonormal), four rows. Scaled to unit norm, their normal matrix is
    [[1, c], [c, 1]] with c = 1 / sqrt(1 + eps^2): relative eigenvalue (1 - c) / (1 + c) ~ eps^2 / 4."""
    u = np.array([1.0, 1.0, 1.0, 1.0]) / 2
    v = np.array([1.0, -1.0, 1.0, -1.0]) / 2
    c = 1 / np.sqrt(1 + eps ** 2)
    return np.column_stack([u, u + eps * v]), (1 - c) / (1 + c)


def test_rank_threshold_either_side_of_rank_tol():
    """RANK_TOL (1e-12: a relative eigenvalue of the column-scaled normal matrix, singular-value ratio 1e-6):
    two nearly collinear columns whose relative eigenvalue is 1e-11 (10 x above) are solved, and at 1e-13
    (10 x below) refused as one unidentifiable combination, named. A threshold 1e4 x smaller accepts the second;
    1e2 x larger refuses the first. (The eigenvalue ~1e-13 is computed to 1.1e-16 absolute at most: 0.11 %.)"""
    from core.lsq import RANK_TOL

    assert RANK_TOL == 1e-12
    A_ok, r_ok = _near_collinear(2 * np.sqrt(1e-11))
    A_bad, r_bad = _near_collinear(2 * np.sqrt(1e-13))
    assert r_ok == pytest.approx(1e-11, rel=1e-4, abs=0)
    # r_bad is the closed form of the test's own matrix (not core's figure): (1 - c) / (1 + c) ~ (1 - c) / 2 with
    # 1 - c = 2e-13, where c = 1 / sqrt(1 + eps^2) is three roundings of numbers near 1 (1 + eps^2: half an ulp of
    # 2.2e-16, halved by the sqrt; the sqrt: 1.1e-16; the division: 0.55e-16), 2.2e-16 at most in c, so at most
    # 1.1e-16 in r_bad: 1.1e-3 of 1e-13. rel=1.1e-3, abs=0 is that bound (the docstring's 0.1 %). The double is
    # the same on every IEEE platform (+, sqrt and / correctly rounded): 9.992e-14, 8.0e-4 off. (Session 37 left
    # abs=1e-12 written out here, pytest's hidden default: it was the whole tolerance, accepting 0 to 1.1e-12,
    # past RANK_TOL, so the check could not see a matrix on the wrong side of the threshold.)
    assert r_bad == pytest.approx(1e-13, rel=1.1e-3, abs=0)
    b = np.array([1.0, 2.0, 0.5, 1.5])
    sol = solve(A_ok, b, names=["p", "q"])
    # the fit is b's projection on span(u, v) = (b.u) u + (b.v) v = 2.5 u - v, by hand; through the normal matrix
    # to about its condition (1e11) x 1.1e-16 = 1.1e-5 (measured 1.35e-6)
    np.testing.assert_allclose(A_ok @ sol.theta, [0.75, 1.75, 0.75, 1.75], rtol=0, atol=1.1e-5)
    with pytest.raises(IdentifiabilityError, match=r"\bp\b.*\bq\b|\bq\b.*\bp\b"):
        solve(A_bad, b, names=["p", "q"])
