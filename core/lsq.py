"""Constrained sparse linear least squares, conditioned and rank-checked.

The one solver of core: the 2D self-calibration (:mod:`core.selfcal`), the
volumetric identification (:mod:`core.volumetric`) and model discovery
(:mod:`core.discover`) all solve ``min |A theta - b|`` subject to
``C theta = d`` with :func:`solve`, in these steps (a function each):

1. :func:`_check_problem`: shapes, finite observations, enough observations
   for the free parameters;
2. :func:`_column_scale`: columns scaled to unit norm (style.md: condition
   before solving); a parameter no observation and no constraint touches is
   named;
3. :func:`_eliminate`: the constraints eliminated (pivoted QR picks the
   eliminated parameters), ``theta = D (Z psi + phi_0)``;
4. :func:`_factor_normal`: the reduced normal matrix factored, densely with
   an eigen rank check up to :data:`DENSE_MAX` free parameters; above, when
   the caller names a *diagonal block* (parameters each observation touches
   at most one of, as the workpiece of a self-calibration: one parameter per
   target), by block elimination (:func:`_factor_schur`: that block is
   diagonal, its Schur complement small and dense), else by sparse LU;
   unidentifiable combinations are named (:func:`describe_direction`);
5. :func:`_sigma` and :func:`_covariance`: the observation standard
   deviation (given or from the residuals) and the parameters' uncertainty
   (:class:`Covariance` mode).

:class:`LinearEstimator` keeps the factorisation so many right-hand sides
(Monte Carlo runs, JCGM 101) cost one back-substitution each.

:func:`remove_span` is the one gauge removal of core: what a set of
directions (a shift, a rotation, a scale...) can explain is taken out of a
vector by least squares; self-calibration uses it for the workpiece form
and for comparing an error map with the truth.

:class:`BlockDesign` and :class:`Basis` are a long log's design and its
orthonormal basis for model discovery (:mod:`core.discover`): a block of
indicator columns (a workpiece's targets, one per touch) kept as each
row's id and eliminated by means per id, the other columns dense; they
act as the matrices where discovery uses one and refuse any other numpy
use (``np.asarray`` raises).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from enum import StrEnum

import numpy as np
import scipy.linalg as sla
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from .exceptions import ConfigError, IdentifiabilityError


#: Rows a block of :func:`row_blocks` starts at a multiple of (the row unrolls of the BLAS kernels' micro-tiles:
#: 4 on Haswell and Zen, 16 on SkylakeX).
ROW_ALIGN = 64


def row_blocks(n: int, rows: int) -> list:
    """Slices of about ``rows`` rows covering ``range(n)`` whose products are the whole product's rows bit for bit.

    A matrix product taken a block of rows at a time gives the whole product's numbers only where each block's
    rows fall in the kernel's micro-tiles as they do in the whole: each block starts at a multiple of
    :data:`ROW_ALIGN` (``rows`` rounded up to one), and a tail shorter than that joins the block before it (a
    one-row block is a matrix-vector product, summed in another order). Measured on an AMD EPYC (OpenBLAS 0.3.31,
    Haswell kernels; session 25): blocks of any row count differed from the whole in 586 of 3,000 random products,
    blocks so laid out in none of 6,000.
    """
    step = -(-max(int(rows), 1) // ROW_ALIGN) * ROW_ALIGN
    out, a = [], 0
    while a < n:
        b = a + step if n - (a + step) >= ROW_ALIGN else n
        out.append(slice(a, b))
        a = b
    return out

#: Largest number of free parameters solved densely (with an eigen rank check).
DENSE_MAX = 500
#: Largest reduced (Schur complement) block factored densely by :func:`_factor_schur`;
#: above it the sparse LU of the whole normal matrix is used.
SCHUR_MAX = 4000
#: Targets per chunk when the Schur complement and the diagonal block's
#: variances are formed (bounds the dense work arrays to about
#: ``SCHUR_CHUNK * n_reduced * 8`` bytes).
SCHUR_CHUNK = 2048
#: Relative eigenvalue of the column-scaled normal matrix below which a
#: direction counts as unidentifiable (singular-value ratio 1e-6).
RANK_TOL = 1e-12


class Covariance(StrEnum):
    """What :func:`solve` computes of the parameters' uncertainty (:data:`COVARIANCE_MESSAGES`)."""

    AUTO = "auto"
    FULL = "full"
    STD = "std"
    NONE = "none"


#: What each :class:`Covariance` mode gives.
COVARIANCE_MESSAGES = {
    Covariance.AUTO: f"full covariance up to {DENSE_MAX} free parameters, standard uncertainties above",
    Covariance.FULL: "the full (n, n) covariance and the standard uncertainties",
    Covariance.STD: "the standard uncertainties only (no dense n x n matrix)",
    Covariance.NONE: "no uncertainty (the estimate and its factorisation only)",
}


def covariance_mode(value) -> Covariance:
    """``value`` as a :class:`Covariance`; ConfigError naming the modes otherwise."""
    try:
        return Covariance(value)
    except ValueError:
        raise ConfigError(f"covariance must be auto, full, std or none, got {value!r}") from None


@dataclass(frozen=True)
class Solution:
    """Outcome of :func:`solve`.

    Attributes
    ----------
    theta : (n,) float
        Estimate (units of the columns of A).
    residuals : (m,) float
        ``b - A theta``.
    rms : float
        Residual RMS.
    sigma : float
        Standard deviation of one observation (given or from residuals).
    sigma_source : str
        ``"given"`` or ``"residuals"``.
    dof : int
        ``m - (n - n_constraints)``.
    std : (n,) float or None
        Standard uncertainty of each parameter (None when not computed).
    cov : (n, n) float or None
        Covariance ``sigma^2 (A^T A)^-1`` on the constrained problem.
    estimator : LinearEstimator
        The factorisation, reusable for many right-hand sides.
    """

    theta: np.ndarray
    residuals: np.ndarray
    rms: float
    sigma: float
    sigma_source: str
    dof: int
    std: np.ndarray | None
    cov: np.ndarray | None
    estimator: "LinearEstimator" = field(repr=False, compare=False)


class LinearEstimator:
    """The constrained least-squares estimator, factored once.

    ``theta(b) = theta_0 + D Z M^-1 (A D Z)^T (b - A D phi_0)`` with column
    scaling ``D``, constraint null-space basis ``Z`` and ``M = (A D Z)^T (A D
    Z)``. :meth:`estimate` applies it to a batch of right-hand sides (the Monte
    Carlo runs) without refactoring.
    """

    def __init__(self, A, DZ, B, phi0_theta, r0_shift, solve_M, n_free, quad=None):
        self.A = A
        self.DZ = DZ  # (n, n_free) sparse: theta = DZ psi + theta0
        self._B = B  # (m, n_free) sparse, or None: A DZ applied as two products (block elimination)
        self.theta0 = phi0_theta
        self.b_shift = r0_shift  # A theta0
        self._solve_M = solve_M
        self.n_free = n_free
        self._quad = quad  # V -> diag(V M^-1 V^T) for sparse V (k, n_free), when the factor has a fast one

    @property
    def B(self):
        """(m, n_free) sparse ``A D Z`` (formed on first use when the factor did without it)."""
        if self._B is None:
            self._B = (self.A @ self.DZ).tocsr()
        return self._B

    def _Bt(self, e):
        """``(A D Z)^T e`` for (m,) or (m, r) ``e``."""
        if self._B is not None:
            return self._B.T @ e
        return self.DZ.T @ (self.A.T @ e)

    def psi(self, b: np.ndarray) -> np.ndarray:
        return self._solve_M(self._Bt(b - (self.b_shift if b.ndim == 1 else self.b_shift[:, None])))

    def estimate(self, b: np.ndarray) -> np.ndarray:
        """(n,) or (n, r) estimates for ``b`` of shape (m,) or (m, r)."""
        b = np.asarray(b, float)
        t = self.DZ @ self.psi(b)
        return t + (self.theta0 if b.ndim == 1 else self.theta0[:, None])

    def noise_gain(self, e: np.ndarray) -> np.ndarray:
        """(n, r) change of the estimate caused by observation noise ``e`` (m, r)."""
        return self.DZ @ self._solve_M(self._Bt(e))

    def covariance(self, sigma: float) -> np.ndarray:
        """(n, n) dense covariance ``sigma^2 DZ M^-1 DZ^T``."""
        MinvZt = self._solve_M(self.DZ.T.toarray())
        return sigma ** 2 * (self.DZ @ MinvZt)

    def covariance_of(self, index, sigma: float = 1.0) -> np.ndarray:
        """(k, k) dense covariance of ``theta[index]`` only, ``sigma^2 DZ_k M^-1 DZ_k^T``."""
        DZk = self.DZ[index]
        return sigma ** 2 * (DZk @ self._solve_M(DZk.T.toarray()))

    def std(self, sigma: float, index=None, block: int = 256) -> np.ndarray:
        """Standard uncertainties of ``theta[index]`` (default all), in blocks (no dense n x n)."""
        DZ = self.DZ if index is None else self.DZ[index]
        if self._quad is not None:
            return sigma * np.sqrt(np.maximum(self._quad(DZ), 0))
        DZt = DZ.T.tocsc()
        n = DZt.shape[1]
        out = np.empty(n)
        for a in range(0, n, block):
            cols = DZt[:, a:a + block].toarray()
            X = self._solve_M(cols)
            out[a:a + block] = np.einsum("ij,ij->j", cols, X)
        return sigma * np.sqrt(np.maximum(out, 0))


def _eliminate(C: np.ndarray, d: np.ndarray, n: int):
    """(Z (n, n-k) sparse, theta0, F) with C (Z psi + theta0) = d for all psi.

    ``F`` (n-k,) are the parameters left free, in order: ``psi[i]`` is
    parameter ``F[i]`` (plus, for the eliminated ones, their combination).
    """
    k = C.shape[0]
    if k == 0:
        return sp.identity(n, format="csr"), np.zeros(n), np.arange(n)
    _q, r, piv = sla.qr(C, mode="economic", pivoting=True)
    if abs(r[k - 1, k - 1]) <= 1e-12 * abs(r[0, 0]):
        raise ConfigError("constraints are linearly dependent")
    P = np.sort(piv[:k])
    F = np.setdiff1d(np.arange(n), P)
    CP = C[:, P]
    T = np.linalg.solve(CP, C[:, F])  # theta_P = CP^-1 d - T theta_F
    T[np.abs(T) < 1e-14 * max(1.0, np.abs(T).max())] = 0.0
    Ts = sp.coo_matrix(T)
    rows = np.concatenate([F, P[Ts.row]])
    cols = np.concatenate([np.arange(len(F)), Ts.col])
    vals = np.concatenate([np.ones(len(F)), -Ts.data])
    Z = sp.csr_matrix((vals, (rows, cols)), shape=(n, len(F)))
    theta0 = np.zeros(n)
    theta0[P] = np.linalg.solve(CP, d)
    return Z, theta0, F


def describe_direction(v: np.ndarray, names, top: int = 4) -> str:
    """A direction ``v`` in words: its largest components, ``0.71*EXX@x=0mm -0.71*EXC,total[C=0deg]``."""
    idx = np.argsort(-np.abs(v))[:top]
    idx = [i for i in idx if abs(v[i]) > 0.05 * abs(v[idx[0]])]
    return " ".join(f"{'+' if v[i] >= 0 else '-'}{abs(v[i]):.2f}*{names[i]}" for i in idx).lstrip("+")


def _check_problem(A, b, C, d, names):
    """Step 1: (A csr, b, C, d, names) checked; enough observations for the free parameters."""
    A = sp.csr_matrix(A)
    b = np.asarray(b, float).ravel()
    m, n = A.shape
    names = list(names) if names is not None else [f"theta[{i}]" for i in range(n)]
    if b.shape != (m,):
        raise ConfigError(f"b: expected shape ({m},), got {b.shape}")
    if not np.all(np.isfinite(b)):
        raise ConfigError(f"b: {np.count_nonzero(~np.isfinite(b))} non-finite observations")
    C = np.zeros((0, n)) if C is None else np.atleast_2d(np.asarray(C, float))
    d = np.zeros(C.shape[0]) if d is None else np.asarray(d, float).ravel()
    k = C.shape[0]
    if m < n - k:
        raise IdentifiabilityError(f"{m} observations for {n - k} free parameters ({n} - {k} constraints)")
    return A, b, C, d, names


def column_norms(A: sp.csr_matrix) -> np.ndarray:
    """(n,) Euclidean norm of each column of a CSR matrix (no copy of ``A``)."""
    return np.sqrt(np.bincount(A.indices, weights=A.data * A.data, minlength=A.shape[1]))


def _column_scale(A: sp.csr_matrix, C: np.ndarray, names) -> np.ndarray:
    """Step 2: (n,) scale D making every observed column of ``A D`` unit-norm (1 for unobserved ones).

    Raises IdentifiabilityError naming the parameters neither an observation
    nor a constraint touches.
    """
    colnorm = column_norms(A)
    # rounding dust (cos 90 deg = 6e-17) is no observation
    colnorm[colnorm <= 1e-12 * max(colnorm.max(initial=0.0), 1e-300)] = 0.0
    in_c = np.any(C != 0, axis=0)
    zero = np.flatnonzero((colnorm == 0) & ~in_c)
    if zero.size:
        shown = ", ".join(names[i] for i in zero[:8]) + (f" and {zero.size - 8} more" if zero.size > 8 else "")
        raise IdentifiabilityError(f"no observation constrains {shown}")
    return np.where(colnorm > 0, 1.0 / np.where(colnorm > 0, colnorm, 1.0), 1.0)


def _factor_normal(B: sp.csr_matrix, DZ: sp.csr_matrix, names, rank_tol: float):
    """Step 4: ``(solve_M, None)``: ``solve_M(r) = M^-1 r`` for ``M = B^T B``, after the rank check.

    Dense (eigen-decomposition, then Cholesky) up to :data:`DENSE_MAX` free
    parameters, sparse LU above (:func:`_factor_schur` when there is a
    diagonal block). A rank deficiency raises IdentifiabilityError naming the
    parameter combinations (dense) or the near-null pivots (sparse LU).
    """
    if B.shape[1] <= DENSE_MAX:
        m, n = B.shape
        if B.nnz > 0.25 * m * n:
            # a nearly dense design (the MFB's: every row touches an axis's nodes and its set-up's
            # pose): one BLAS product (syrk, exactly symmetric) instead of a sparse one 10x slower;
            # the dense copy is at most 3x the sparse storage at this density
            Bd = B.toarray()
            Md = Bd.T @ Bd
        else:
            Md = (B.T @ B).toarray()
        w, V = np.linalg.eigh(Md)
        bad = w <= rank_tol * max(w[-1], 1e-300)
        if bad.any():
            dirs = [describe_direction(DZ @ V[:, i], names) for i in np.flatnonzero(bad)[:5]]
            raise IdentifiabilityError(
                f"rank deficient by {int(bad.sum())} beyond the constraints; unidentifiable: " + "; ".join(dirs))
        cf = sla.cho_factor(Md)
        return (lambda r: sla.cho_solve(cf, r)), None
    M = (B.T @ B).tocsc()
    try:
        lu = spla.splu(M, permc_spec="MMD_AT_PLUS_A", options={"SymmetricMode": True})
    except RuntimeError as e:
        raise IdentifiabilityError(f"normal matrix singular ({e}); the design is rank deficient") from None
    u = np.abs(lu.U.diagonal())
    badp = np.flatnonzero(u <= rank_tol * u.max())
    if badp.size:
        fcols = np.argsort(lu.perm_c)[badp]  # Pr M Pc = LU: column j of M Pc is M[:, argsort(perm_c)[j]]
        Zc = DZ.tocsc()
        shown = []
        for f in fcols[:5]:
            col = Zc[:, f]
            shown.append(names[col.indices[np.argmax(np.abs(col.data))]])
        raise IdentifiabilityError(
            f"rank deficient by about {badp.size} beyond the constraints; near-null pivots at: " + ", ".join(shown))
    return (lambda r: lu.solve(np.asarray(r, float))), None


def _split_rows(B: sp.csr_matrix, g: np.ndarray):
    """The diagonal block's entry of each row and the other entries as slots.

    Returns ``(tg, bg, I, V)``: ``tg`` (m,) the diagonal parameter (index
    into ``g``) of each row, -1 for none; ``bg`` (m,) its value; ``I``, ``V``
    (m, k) the column (index into the other parameters ``r``) and value of
    the row's other entries, padded with (0, 0.0). Slot ``s`` (a column of
    ``I``, ``V``) holds one entry per row, so a product of two slots is one
    pass over the rows (:func:`_gram`). ConfigError when a row has two
    diagonal entries.
    """
    m, nf = B.shape
    isg = np.zeros(nf, bool)
    isg[g] = True
    col = np.empty(nf, np.int64)
    col[g] = np.arange(len(g))
    col[~isg] = np.arange(nf - len(g))
    cnt = np.diff(B.indptr)
    eg = isg[B.indices]
    if m and cnt[0] > 0 and np.all(cnt == cnt[0]):  # a fixed count per row (a design built row-wise)
        ng_row = eg.reshape(m, cnt[0]).sum(axis=1)
    else:
        ng_row = np.bincount(np.repeat(np.arange(m), cnt)[eg], minlength=m)
    if ng_row.max(initial=0) > 1:
        raise ConfigError(f"diagonal block: observation {int(np.argmax(ng_row > 1))} touches "
                          f"{int(ng_row.max())} of its parameters (at most one allowed)")
    rows_g = np.repeat(np.arange(m), cnt)[eg] if not np.all(ng_row == 1) else np.arange(m)
    tg = np.full(m, -1, np.int64)
    bg = np.zeros(m)
    tg[rows_g] = col[B.indices[eg]]
    bg[rows_g] = B.data[eg]
    cnt_r = cnt - ng_row
    k = max(int(cnt_r.max(initial=0)), 1)
    ci, cv = col[B.indices[~eg]], B.data[~eg]
    if np.all(cnt_r == k):  # every row has k other entries: a reshape
        return tg, bg, ci.reshape(m, k).astype(np.int32 if nf < 2 ** 31 else np.int64), cv.reshape(m, k)
    start = np.concatenate([[0], np.cumsum(cnt_r)[:-1]])
    flat = np.arange(ci.size) + np.repeat(np.arange(m) * k - start, cnt_r)  # row * k + position in row
    I = np.zeros(m * k, np.int32 if nf < 2 ** 31 else np.int64)
    V = np.zeros(m * k)
    I[flat] = ci
    V[flat] = cv
    return tg, bg, I.reshape(m, k), V.reshape(m, k)


def _gram(I: np.ndarray, V: np.ndarray, r: int) -> np.ndarray:
    """Dense ``sum_rows v v^T`` (r, r) from the slots (m, k) of :func:`_split_rows`.

    Slot pair by slot pair with ``np.bincount``: ``k (k + 1) / 2`` passes
    over the rows with contiguous arrays (scipy's sparse product costs about
    ten times more for this tall, narrow shape).
    """
    k = I.shape[1]
    It, Vt = np.ascontiguousarray(I.T), np.ascontiguousarray(V.T)
    G = np.zeros(r * r)
    for a in range(k):
        ia = It[a].astype(np.int64) * r
        for b in range(a, k):
            w = Vt[a] * Vt[b]
            G += np.bincount(ia + It[b], weights=w if b == a else 2.0 * w, minlength=r * r)
    G = G.reshape(r, r)
    return 0.5 * (G + G.T)


def _factor_schur(A: sp.csr_matrix, DZ: sp.csr_matrix, names, rank_tol: float, gth: np.ndarray, g: np.ndarray):
    """Step 4 by block elimination: ``M = [[D, W^T], [W, M_rr]]`` with ``D`` diagonal.

    ``g`` are the free parameters of the diagonal block (``gth`` the same
    parameters' columns of ``A``; each observation touches at most one of
    them: the workpiece of a self-calibration, one parameter per target),
    ``r`` the others. Then ``D`` is diagonal, and ``M`` is factored through
    the Schur complement ``S = M_rr - W D^-1 W^T`` (dense, ``len(r)`` square,
    Cholesky):

        x_r = S^-1 (b_r - W D^-1 b_g),   x_g = D^-1 (b_g - W^T x_r).

    Everything is summed on ``A``'s own rows (a fixed pattern, no ``A D Z``
    product is formed) and carried to the free parameters by ``D Z``, which
    keeps the two blocks apart (no constraint touches the diagonal block):
    ``S = Z_r^T S_A Z_r``, ``W = Z_r^T W_A D_g``. ``A^T A`` of the other
    columns is summed slot by slot (:func:`_gram`), ``W_A D_A^-1 W_A^T`` by
    dense products over chunks of :data:`SCHUR_CHUNK` diagonal parameters:
    work and memory grow linearly with the observations, not with the
    fill-in of a sparse LU. The rank check: ``M`` is singular exactly when
    ``S`` is (``D > 0``); a small Cholesky pivot of ``S`` sends it to an
    eigen-decomposition, whose null directions are named like the dense
    path's.

    Returns ``(solve_M, quad)`` with ``quad(V) = diag(V M^-1 V^T)`` computed
    as ``v_g D^-1 v_g + |L^-1 (v_r - W D^-1 v_g)|^2`` (no dense ``M^-1``).
    """
    m, n = A.shape
    nf = DZ.shape[1]
    keep = np.ones(nf, bool)
    keep[g] = False
    r = np.flatnonzero(keep)
    keep = np.ones(n, bool)
    keep[gth] = False
    rth = np.flatnonzero(keep)
    ng = len(g)
    DZc = DZ.tocsc()
    Zr = DZc[:, r][rth].tocsc()  # (n - ng, nr): the other parameters from the free ones
    Dg = np.asarray(DZ[gth, g]).ravel()  # the diagonal block's column scales
    if DZc[:, g][rth].nnz or DZ[gth][:, r].nnz:  # cannot happen when no constraint touches the block; a guard
        raise ConfigError("diagonal: the constraints couple the diagonal block with the other parameters")
    if not A.has_canonical_format:  # _gram needs one entry per column in a row
        A = A.copy()
        A.sum_duplicates()
    tg, bg, I, V = _split_rows(A, gth)
    has = tg >= 0
    dA = np.bincount(tg[has], weights=bg[has] ** 2, minlength=ng)
    SA = _gram(I, V, len(rth))
    # W_A (rth, g) in CSC: rows sorted by their diagonal parameter, each row's slots one after the
    # other (repeated indices within a column are summed by every product and by toarray)
    rows = np.flatnonzero(has)
    rows = rows[np.argsort(tg[rows], kind="stable")]
    k = I.shape[1]
    WA = sp.csc_matrix((np.ravel(V[rows] * bg[rows, None]), np.ravel(I[rows]),
                        np.concatenate([[0], np.cumsum(np.bincount(tg[rows], minlength=ng) * k)])),
                       shape=(len(rth), ng))
    del I, V, rows
    isd = 1.0 / np.sqrt(dA)
    syrk = sla.get_blas_funcs("syrk", (SA,))
    acc = np.zeros(SA.shape, order="F")
    for a in range(0, ng, SCHUR_CHUNK):
        Wc = WA[:, a:a + SCHUR_CHUNK].toarray() * isd[a:a + SCHUR_CHUNK]  # (rth, chunk), C order
        acc = syrk(1.0, Wc.T, trans=1, beta=1.0, c=acc, lower=1, overwrite_c=1)  # += Wc Wc^T, lower half
    acc = np.tril(acc)
    SA -= acc + np.tril(acc, -1).T
    S = Zr.T @ (Zr.T @ SA).T  # Z_r^T S_A Z_r (S_A symmetric)
    S = 0.5 * (S + S.T)
    W = (Zr.T @ WA @ sp.diags(Dg)).tocsc()  # (nr, ng)
    dg = Dg ** 2 * dA
    del WA, SA

    def full_psi(v_r):
        out = np.zeros(nf)
        out[r] = v_r
        out[g] = -(W.T @ v_r) / dg
        return out

    scale = max(float(np.max(np.diag(S), initial=0.0)), float(dg.max(initial=0.0)), 1e-300)
    try:
        L = sla.cholesky(S, lower=True)
        ok = np.min(np.diag(L), initial=np.inf) ** 2 > rank_tol * scale
    except np.linalg.LinAlgError:
        ok = False
    if not ok:
        w, Vs = np.linalg.eigh(S)
        bad = w <= rank_tol * scale
        if bad.any():
            dirs = [describe_direction(DZ @ full_psi(Vs[:, i]), names) for i in np.flatnonzero(bad)[:5]]
            raise IdentifiabilityError(
                f"rank deficient by {int(bad.sum())} beyond the constraints; unidentifiable: " + "; ".join(dirs))
        L = sla.cholesky(S, lower=True)

    def solve_M(rhs):
        R = np.asarray(rhs, float)
        one = R.ndim == 1
        R = R[:, None] if one else R
        y = R[g] / dg[:, None]
        xr = sla.cho_solve((L, True), R[r] - W @ y)
        out = np.empty_like(R)
        out[r] = xr
        out[g] = y - (W.T @ xr) / dg[:, None]
        return out[:, 0] if one else out

    def quad(Vq):
        Vq = sp.csc_matrix(Vq)
        Vg, Vr = Vq[:, g].tocsr(), Vq[:, r].tocsr()
        U = (Vr - Vg @ sp.diags(1.0 / dg) @ W.T).tocsr()
        out = np.asarray(Vg.multiply(Vg) @ (1.0 / dg)).ravel()
        for a in range(0, Vq.shape[0], SCHUR_CHUNK):
            Y = sla.solve_triangular(L, U[a:a + SCHUR_CHUNK].toarray().T, lower=True, check_finite=False)
            out[a:a + SCHUR_CHUNK] += np.einsum("ij,ij->j", Y, Y)
        return out

    return solve_M, quad


def _sigma(res: np.ndarray, dof: int, n_free: int, sigma) -> tuple[float, str]:
    """Step 5a: (sigma, source): the given one, or ``sqrt(r.r / dof)`` from the residuals."""
    if sigma is None:
        if dof <= 0:
            raise IdentifiabilityError(
                f"{len(res)} observations for {n_free} free parameters leave no residual to estimate sigma")
        return float(np.sqrt(res @ res / dof)), "residuals"
    if not (np.isfinite(sigma) and sigma > 0):
        raise ConfigError(f"sigma must be > 0, got {sigma}")
    return float(sigma), "given"


def _covariance(est: LinearEstimator, sigma: float, mode: Covariance):
    """Step 5b: (std, cov) of the parameters for ``mode`` (None where not computed)."""
    if mode == Covariance.AUTO:
        mode = Covariance.FULL if est.n_free <= DENSE_MAX else Covariance.STD
    if mode == Covariance.FULL:
        cov = est.covariance(sigma)
        return np.sqrt(np.maximum(np.diag(cov), 0)), cov
    if mode == Covariance.STD:
        return est.std(sigma), None
    return None, None


def _diagonal_free(diagonal, C: np.ndarray, F: np.ndarray, n: int):
    """(parameter indices, free-parameter indices) of the caller's ``diagonal`` block ((None, None) when not given)."""
    if diagonal is None:
        return None, None
    j = np.arange(n)[diagonal] if isinstance(diagonal, slice) else np.asarray(diagonal, int).ravel()
    if j.size and (j.min() < 0 or j.max() >= n):
        raise ConfigError(f"diagonal: indices must lie in 0..{n - 1}")
    if np.any(C[:, j] != 0):
        raise ConfigError("diagonal: a constraint touches a parameter of the diagonal block")
    pos = np.minimum(np.searchsorted(F, j), len(F) - 1)
    if np.any(F[pos] != j):  # cannot happen when no constraint touches them; a guard all the same
        raise ConfigError("diagonal: a parameter of the diagonal block was eliminated by the constraints")
    return j, pos


def solve(A, b, C=None, d=None, *, names=None, sigma=None, covariance: str = "auto",
          rank_tol: float = RANK_TOL, diagonal=None) -> Solution:
    """Least squares ``min |A theta - b|`` subject to ``C theta = d``.

    Conditioned before solving: columns scaled to unit norm, constraints
    eliminated (QR with pivoting picks the eliminated parameters), then the
    rank of the reduced normal matrix is checked and unidentifiable
    combinations are reported by name (the steps of the module docstring).

    Parameters
    ----------
    A : (m, n) sparse or dense
    b : (m,) float
    C : (k, n) float or None
        Equality constraints (the gauge, plus any extension's own).
    d : (k,) float or None
    names : sequence of str, optional
        Parameter names for messages (default ``theta[i]``).
    sigma : float or None
        Observation standard deviation; None = from the residuals.
    covariance : {"auto", "full", "std", "none"}
        A :class:`Covariance` mode (:data:`COVARIANCE_MESSAGES`): ``auto``
        gives the full covariance up to :data:`DENSE_MAX` free parameters,
        standard uncertainties only above.
    rank_tol : float
        Relative eigenvalue (or LU pivot) below which a direction counts as
        unidentifiable.
    diagonal : slice or (q,) int, optional
        Parameters each observation touches at most one of, and no
        constraint touches (the workpiece of a self-calibration: one
        parameter per target). Above :data:`DENSE_MAX` free parameters they
        are eliminated first (:func:`_factor_schur`), which keeps time and
        memory linear in the observations; the result is the same to
        rounding.

    Raises
    ------
    IdentifiabilityError
        Fewer observations than free parameters, a parameter no observation
        touches, or rank-deficient combinations (named).
    ConfigError
        Malformed ``b``, dependent constraints, a bad ``sigma`` or mode.
    """
    mode = covariance_mode(covariance)
    A, b, C, d, names = _check_problem(A, b, C, d, names)
    m, n = A.shape
    D = _column_scale(A, C, names)
    Z, phi0, F = _eliminate(C * D[None, :], d, n)
    DZ = (sp.diags(D) @ Z).tocsr()
    theta0 = D * phi0
    nf = DZ.shape[1]
    gth, gfree = _diagonal_free(diagonal, C, F, n)
    if nf > DENSE_MAX and gfree is not None and gfree.size and nf - gfree.size <= SCHUR_MAX:
        B = None
        solve_M, quad = _factor_schur(A, DZ, names, rank_tol, gth, gfree)
    else:
        B = (A @ DZ).tocsr()
        solve_M, quad = _factor_normal(B, DZ, names, rank_tol)
    est = LinearEstimator(A, DZ, B, theta0, A @ theta0, solve_M, nf, quad=quad)
    theta = est.estimate(b)
    res = b - A @ theta
    dof = m - nf
    rms = float(np.sqrt(np.mean(res ** 2))) if m else 0.0
    sig, src = _sigma(res, dof, nf, sigma)
    std, cov = _covariance(est, sig, mode)
    return Solution(theta=theta, residuals=res, rms=rms, sigma=sig, sigma_source=src, dof=int(dof),
                    std=std, cov=cov, estimator=est)


def remove_span(v, B, rcond: float = 1e-12) -> np.ndarray:
    """``v`` less its least-squares fit by the columns of ``B``: ``(I - B B^+) v``.

    The one gauge removal of core: ``B``'s columns are the directions the data
    cannot see (a workpiece shift, rotation, scale, a common offset...), and
    what remains is the part of ``v`` they cannot explain.

    Parameters
    ----------
    v : (n,) or (n, r) float
        One vector or ``r`` columns (a matrix: ``remove_span(np.eye(n), B)``
        is the projector).
    B : (n, q) float
        Directions; dependent columns are allowed (their span is used).
    rcond : float
        Singular values below ``rcond`` times the largest count as zero.

    Returns
    -------
    (n,) or (n, r) float
    """
    B = np.asarray(B, float)
    v = np.asarray(v, float)
    if B.ndim != 2 or B.shape[0] != v.shape[0]:
        raise ConfigError(f"remove_span: B must be (n, q) with n = {v.shape[0]}, got {B.shape}")
    U, s, _ = np.linalg.svd(B, full_matrices=False)
    Q = U[:, s > rcond * max(s.max(initial=0.0), 1e-300)]
    return v - Q @ (Q.T @ v)


def normal_inverse(X, rank_tol: float = RANK_TOL) -> np.ndarray:
    """``(X^T X)^-1`` for a covariance ``s^2 (X^T X)^-1``, its conditioning checked (review31d F6).

    Where the column-equilibrated normal matrix's condition number is at most
    ``1 / rank_tol`` (:data:`RANK_TOL`: an eigenvalue ratio of 1e-12, 1e-6 in
    singular values): ``np.linalg.inv(X^T X)``, the very doubles of the plain
    inverse. Above it (nearly collinear columns, where inverting the normal
    matrix squares X's conditioning, and ``inv`` raises only on an exactly
    singular one): from X's own SVD, columns equilibrated, each singular
    value below ``sqrt(rank_tol)`` of the largest counted at that floor. A
    direction the data barely see keeps the widest variance the tolerance
    allows, never the zero a truncated ``pinv`` gives it (a combination
    nobody measured reported with a small U95); a zero column is such a
    direction.

    Parameters
    ----------
    X : (n, k) float
        The design (columns the parameters').
    rank_tol : float
        Eigenvalue ratio of the equilibrated normal matrix.

    Returns
    -------
    (k, k) float
    """
    X = np.asarray(X, float)
    if X.ndim != 2 or not np.all(np.isfinite(X)):
        raise ConfigError(f"normal_inverse: X must be a finite (n, k) array, got shape {X.shape}")
    G = X.T @ X
    d = np.sqrt(np.diag(G))
    if d.size and np.all(d > 0) and np.linalg.cond(G / np.outer(d, d)) * rank_tol <= 1.0:
        return np.linalg.inv(G)
    dd = np.where(d > 0, d, 1.0)
    _, s, Vt = np.linalg.svd(X / dd, full_matrices=False)
    if s.size < X.shape[1]:  # fewer rows than columns: the missing directions are unseen
        s = np.concatenate([s, np.zeros(X.shape[1] - s.size)])
        Vt = np.linalg.svd(X / dd, full_matrices=True)[2]
    floor = np.sqrt(rank_tol) * max(float(s.max(initial=0.0)), 1.0)
    W = Vt.T / np.maximum(s, floor)
    return (W @ W.T) / np.outer(dd, dd)


# ---------------------------------------------------------------------------
# block designs: one indicator column per row, eliminated (long logs)
# ---------------------------------------------------------------------------
#: :func:`group_sums` of a dense block of more cells than this takes the indicator block's CSR product (the same
#: sums bit for bit), not one bincount over the cells: their (id, column) index is an int64 per cell (61 MiB for a
#: long log's eight columns at 1e6 rows, beside the block, at every product of a block basis with them).
GROUP_CELLS_MAX = 1 << 21


def group_sums(ids: np.ndarray, g: int, X: np.ndarray) -> np.ndarray:
    """(g,) or (g, k): the rows of ``X`` summed per id (``G^T X`` for the indicator block ``G``)."""
    if X.ndim == 1:
        return np.bincount(ids, weights=X, minlength=g)
    if isinstance(X, np.ndarray) and X.ndim == 2 and X.size <= GROUP_CELLS_MAX:
        # every (id, column) cell summed in row order from 0, as the indicator block's CSR product sums them: the
        # same sums bit for bit (3,000 random layouts, magnitudes 1e-8-1e8), 58 -> 14 us at 432 x 12
        k = X.shape[1]
        cells = (np.asarray(ids)[:, None] * k + np.arange(k)).ravel()
        return np.bincount(cells, weights=X.ravel(), minlength=g * k).reshape(g, k)
    G = sp.csr_matrix((np.ones(len(ids)), (ids, np.arange(len(ids)))), shape=(g, len(ids)))
    return _dense(G @ X)


def _dense(X) -> np.ndarray:
    """``X`` as a dense array (a sparse matrix formed: a block of rows, a product's small result)."""
    return X.toarray() if sp.issparse(X) else np.asarray(X)


@dataclass(frozen=True, eq=False)
class DiagLowRank:
    """A symmetric matrix ``scale * (diag(d) + L K L^T)`` kept as its factors (``L`` thin: (p, k), ``K`` (k, k)).

    The covariance of a long log's workpiece fit (:func:`core.discover._constrained_blocks`):
    with every target's column an indicator, eliminating the targets
    leaves the inverse of the normal matrix (in the gauge) as the targets'
    ``1 / count`` on the diagonal plus a rank-``k`` term through the
    machine's columns and the gauge rows (``k = m + r``). Formed, it is
    ``p^2`` numbers (858 MB at 10,356 parameters); kept, ``p k + k^2``.

    ``M[i, j]`` for two integers is a number, ``M[np.ix_(a, b)]`` a dense
    (len(a), len(b)) block, :meth:`diagonal` the (p,) diagonal,
    :meth:`take` the same kind of matrix on a subset of its rows and
    columns, :meth:`toarray` the whole matrix (for checks).
    """

    d: np.ndarray
    L: np.ndarray
    K: np.ndarray
    scale: float = 1.0

    @property
    def shape(self) -> tuple:
        return (len(self.d), len(self.d))

    @property
    def ndim(self) -> int:
        return 2

    def diagonal(self) -> np.ndarray:
        # one (p, k) product and a row-wise sum (einsum's three-operand loop took 3.19 s at p 10,356, k 366; 0.21 s)
        return self.scale * (self.d + np.sum((self.L @ self.K) * self.L, axis=1))

    def take(self, idx) -> "DiagLowRank":
        """The matrix on rows and columns ``idx`` (distinct integers: a repeated index would need the diagonal
        term off the diagonal too, which this form cannot hold; ConfigError)."""
        idx = np.asarray(idx)
        if idx.ndim != 1 or (idx.size and idx.dtype.kind not in "iu"):
            raise ConfigError("DiagLowRank.take: a 1-d array of integer indices")
        if np.unique(idx % len(self.d) if idx.size else idx).size != idx.size:
            raise ConfigError("DiagLowRank.take: the indices must be distinct")
        return DiagLowRank(self.d[idx], self.L[idx], self.K, self.scale)

    def __getitem__(self, key):
        if not (isinstance(key, tuple) and len(key) == 2):
            raise ConfigError("DiagLowRank: index with two integers or np.ix_(rows, cols)")
        a, b = (np.asarray(k) for k in key)
        if a.ndim == 0 and b.ndim == 0:
            return float(self.scale * ((self.d[a] if a == b else 0.0) + self.L[a] @ self.K @ self.L[b]))
        a, b = a.ravel(), b.ravel()
        out = (self.L[a] @ self.K) @ self.L[b].T
        out += (a[:, None] == b[None, :]) * self.d[a][:, None]
        return self.scale * out

    def toarray(self) -> np.ndarray:
        i = np.arange(len(self.d))
        return self[np.ix_(i, i)]


@dataclass(frozen=True, eq=False)
class BlockDesign:
    """A design ``[G | D]`` whose block ``G`` has one unit entry per row (a workpiece's target per touch).

    The design of a long self-calibration log: ``n`` touches by ``p``
    parameters, of which ``g`` are the targets' own columns (``G``, one 1
    per row) and ``m`` the machine's (``D``). Stored as the rows' ids
    and ``D`` only: ``n * m`` numbers instead of ``n * p`` (``D`` dense, or
    sparse CSR as :meth:`from_sparse` keeps it: a log's machine columns are
    grid functions of local support and per-set-up columns, 14 of 326
    non-zero per row on the benchmark's logs), and the
    projections discovery needs are formed by eliminating ``G`` (means per
    id, Frisch-Waugh-Lovell) so that only ``D``'s part outside it is
    factored densely (:meth:`basis`).

    Attributes
    ----------
    ids : (n,) int
        The ``G`` column (0..g-1) of each row.
    D : (n, m) float array, or scipy.sparse CSR matrix
        Every pass over its rows forms a block of them at a time
        (:data:`CHUNK_BYTES`), products with it are dense.
    g_cols, d_cols : (g,), (m,) int
        Where ``G``'s and ``D``'s columns sit among the design's ``p = g + m``.

    Supports what :mod:`core.discover` does with a design: ``A[rows]``,
    ``A @ theta``, ``A.T @ X``, ``np.hstack([A, E])`` (``E`` joins ``D``),
    ``A.shape``, :meth:`gram` and :meth:`basis`; :meth:`toarray` for checks.
    """

    ids: np.ndarray
    D: np.ndarray | sp.csr_matrix
    g_cols: np.ndarray
    d_cols: np.ndarray
    _bases: dict = field(default_factory=dict, repr=False, compare=False)

    def __post_init__(self):
        ids = np.asarray(self.ids)
        g, m = len(self.g_cols), len(self.d_cols)
        if ids.ndim != 1 or self.D.ndim != 2 or self.D.shape != (len(ids), m):
            raise ConfigError(f"BlockDesign: ids (n,) and D (n, {m}) needed, got {ids.shape} and {self.D.shape}")
        if ids.size and (ids.min() < 0 or ids.max() >= g):
            raise ConfigError(f"BlockDesign: ids must lie in 0..{g - 1}, got {ids.min()}..{ids.max()}")
        cols = np.concatenate([self.g_cols, self.d_cols]).astype(int)
        if not np.array_equal(np.sort(cols), np.arange(g + m)):
            raise ConfigError("BlockDesign: g_cols and d_cols must number the columns 0..p-1 once each")

    @classmethod
    def from_sparse(cls, A, g_cols) -> "BlockDesign":
        """Split a sparse (or dense) design whose columns ``g_cols`` hold one 1 per row and nothing else."""
        # the columns taken from the rows (CSR) as they are: through a CSC copy (session 22 and before) the same
        # arrays bit for bit, with the copy and the CSC block beside them (traced peak 51 -> 19 MB at 1e5 rows)
        A = sp.csr_matrix(A)
        g_cols = np.asarray(g_cols, int)
        G = A[:, g_cols]
        if np.any(np.diff(G.indptr) != 1) or np.any(G.data != 1.0):
            raise ConfigError("BlockDesign: the indicator columns must hold exactly one 1 per row")
        d_cols = np.setdiff1d(np.arange(A.shape[1]), g_cols)
        # D kept sparse, in row order (CSR: a block of rows is a slice of its arrays); dense it was n x m numbers
        # (2.8 GB at 1e6 rows and 356 machine columns, where its 14 non-zeros a row take 170 MB)
        D = A[:, d_cols]
        D.sort_indices()
        return cls(G.indices.astype(np.int64), D, g_cols, d_cols)

    @property
    def shape(self) -> tuple:
        return (len(self.ids), len(self.g_cols) + len(self.d_cols))

    @property
    def ndim(self) -> int:
        return 2

    @property
    def g(self) -> int:
        return len(self.g_cols)

    @property
    def T(self) -> "_Transposed":
        return _Transposed(self)

    def __len__(self) -> int:
        return len(self.ids)

    def __getitem__(self, rows) -> "BlockDesign":
        if isinstance(rows, tuple):
            raise ConfigError("BlockDesign: only rows can be selected (A[rows])")
        return BlockDesign(self.ids[rows], self.D[rows], self.g_cols, self.d_cols)

    def __matmul__(self, theta):
        theta = np.asarray(theta, float)
        return theta[self.g_cols][self.ids] + self.D @ theta[self.d_cols]

    def rmatmul(self, X: np.ndarray) -> np.ndarray:
        """``A^T X``: (p,) or (p, k)."""
        out = np.zeros((self.shape[1],) + X.shape[1:])
        out[self.g_cols] = group_sums(self.ids, self.g, X)
        out[self.d_cols] = self.D.T @ X
        return out

    def hstack(self, E: np.ndarray) -> "BlockDesign":
        """``[A | E]``: the new columns join the dense block."""
        E = np.asarray(E, float).reshape(len(self.ids), -1)
        if not E.shape[1]:  # nothing joins: the same design (not a copy of D)
            return self
        p = self.shape[1]
        D = sp.hstack([self.D, sp.csr_matrix(E)], format="csr") if sp.issparse(self.D) else np.hstack([self.D, E])
        return BlockDesign(self.ids, D, self.g_cols,
                           np.concatenate([self.d_cols, np.arange(p, p + E.shape[1])]))

    def gram(self) -> np.ndarray:
        """(p, p) ``A^T A`` (dense: the parameters, not the rows)."""
        p = self.shape[1]
        N = np.zeros((p, p))
        gd = group_sums(self.ids, self.g, self.D)
        N[self.g_cols, self.g_cols] = np.bincount(self.ids, minlength=self.g)
        N[np.ix_(self.g_cols, self.d_cols)] = gd
        N[np.ix_(self.d_cols, self.g_cols)] = gd.T
        N[np.ix_(self.d_cols, self.d_cols)] = _dense(self.D.T @ self.D)
        return N

    def toarray(self) -> np.ndarray:
        A = np.zeros(self.shape)
        A[np.arange(len(self.ids)), self.g_cols[self.ids]] = 1.0
        A[:, self.d_cols] = _dense(self.D)
        return A

    def basis(self, tol: float = 1e-9) -> "Basis":
        """Orthonormal basis of the column space, rank cut at ``tol`` as :func:`core.diagnosis.orth` cuts it.

        The indicator columns of the ids present, normalised (``1 / sqrt(count)``),
        then ``D``'s columns scaled to unit norm, their means per id removed
        (``Ds``), and a pivoted QR of what is left: its directions with
        ``|R_ii| > tol`` (a unit column's share outside the indicators) are
        kept. ``Ds`` is never formed: its ``R`` is stacked from the QR of a
        block of rows at a time (TSQR), the pivoted QR is of that ``R``
        (the same ``|R_ii|`` as ``Ds``'s own, to rounding), and the basis is
        ``Ds P R^-1`` kept as a map of ``D``'s columns (:class:`CentredSpan`,
        re-orthonormalised once, CholeskyQR2), so that it costs ``m x r``
        numbers beside ``D`` instead of ``n x r``. One factorisation serves
        every ``tol``.

        Because the basis is recomputed as ``D T - mean T`` on every use, with
        ``|T|`` about ``1 / |R_rr|``, it is orthonormal only to about
        ``eps cond(R)``, not to rounding as a formed ``Q`` is: ``U^T U - I``
        measured 2e-10 (nearly collinear columns, tol 1e-7), 5e-7 (least
        singular value 1e-10, tol 1e-12), 1.9e-5 (2e-12, tol 1e-12) on 3,000 x 12
        test matrices, where a formed ``Q`` keeps 7e-16. On the benchmark's
        1e4-row log (a well-conditioned design) the reports of this path and
        the dense one differ by at most 9e-12 relative, with the same findings.
        """
        if "qr" not in self._bases:
            ids, D = self.ids, self.D
            cnt = np.bincount(ids, minlength=self.g).astype(float)
            nrm = np.sqrt(_col_sumsq(D))
            keep = np.flatnonzero(nrm > 0)
            mean = group_sums(ids, self.g, D) / np.maximum(cnt, 1.0)[:, None]  # (g, m): D's means per id
            R = np.zeros((0, keep.size))
            mk, sk = mean[:, keep], 1.0 / nrm[keep]
            for c in _chunks(len(ids), 4 * D.shape[1]):  # (a block, its means, the stack and its R: 4 blocks held)
                W = np.empty((R.shape[0] + c.stop - c.start, keep.size))
                W[:R.shape[0]] = R
                Ds = W[R.shape[0]:]
                np.take(_dense(D[c]), keep, axis=1, out=Ds)
                Ds -= mk[ids[c]]
                Ds *= sk
                R = sla.qr(W, mode="r", overwrite_a=True)[0][:keep.size]
            if keep.size:
                _, R2, piv = sla.qr(R, pivoting=True)
                d = np.abs(np.diag(R2))
            else:
                R2, piv, d = np.zeros((0, 0)), np.zeros(0, int), np.zeros(0)
            self._bases["qr"] = (cnt, mean, nrm, keep, R2, piv, d, {})
        cnt, mean, nrm, keep, R2, piv, d, made = self._bases["qr"]
        r = int(np.sum(d > tol))
        if r not in made:
            T = np.zeros((self.D.shape[1], r))
            T[keep[piv[:r]]] = sla.solve_triangular(R2[:r, :r], np.eye(r)) / nrm[keep[piv[:r]]][:, None]
            made[r] = CentredSpan(self.ids, self.D, mean, T).orthonormalised()
        return Basis(self.ids, cnt, np.zeros((len(self.ids), 0)), made[r])


#: Bytes of a block of rows formed at once by the block design's and its basis's row-wise passes.
CHUNK_BYTES = 32 << 20


def _chunks(n: int, width: int):
    """Slices of ``n`` rows, each about :data:`CHUNK_BYTES` at ``width`` doubles a row."""
    step = max(CHUNK_BYTES // (8 * max(width, 1)), 1)
    return [slice(a, min(a + step, n)) for a in range(0, n, step)]


def _col_sumsq(D: np.ndarray | sp.spmatrix, rows=None) -> np.ndarray:
    """(m,) each column's sum of squares over ``rows`` (all), a block of rows at a time (no n x m temporary)."""
    out = np.zeros(D.shape[1])
    rows = np.arange(D.shape[0]) if rows is None else np.asarray(rows)
    for c in _chunks(len(rows), D.shape[1]):
        Dc = _dense(D[rows[c]])
        out += np.einsum("ij,ij->j", Dc, Dc)
    return out


def row_column_norms(D: np.ndarray, rows=None) -> np.ndarray:
    """(m,) the columns' norms over ``rows`` (all rows when None) of a tall ``D``, without copying those rows whole."""
    return np.sqrt(_col_sumsq(D, rows))


class CentredSpan:
    """The (n, r) matrix ``(D - mean[ids]) T`` as an operator: a block design's basis outside its indicators.

    ``D`` (n, m) the design's machine block (dense or sparse CSR), ``mean`` (g, m) its columns' means
    per id, ``T`` (m, r). Products ``U @ c``, ``U.T @ X``, its rows
    (:meth:`rows`) and their squares' sums, without forming ``U``.
    """

    def __init__(self, ids: np.ndarray, D: np.ndarray | sp.spmatrix, mean: np.ndarray, T: np.ndarray):
        self.ids, self.D, self.mean, self.T = ids, D, mean, T
        self.MT = mean @ T  # (g, r)

    @property
    def r(self) -> int:
        return self.T.shape[1]

    def rows(self, pos) -> np.ndarray:
        return self.D[pos] @ self.T - self.MT[self.ids[pos]]

    def matmul(self, c: np.ndarray, out: np.ndarray | None = None) -> np.ndarray:
        """``U @ c``, added to ``out`` when given (a block of rows at a time: no rows x k temporaries)."""
        Tc, Mc = self.T @ c, self.MT @ c
        if out is None:
            out = np.zeros((len(self.ids),) + np.shape(c)[1:])
        for ch in _chunks(len(self.ids), self.D.shape[1] + (Tc.shape[1] if Tc.ndim == 2 else 1)):
            out[ch] += self.D[ch] @ Tc - Mc[self.ids[ch]]
        return out

    def rmatmul(self, X: np.ndarray) -> np.ndarray:
        return self.T.T @ (self.D.T @ X) - self.MT.T @ group_sums(self.ids, len(self.MT), X)

    def sq_rows(self) -> np.ndarray:
        out = np.empty(len(self.ids))
        for c in _chunks(len(self.ids), self.r):
            out[c] = np.sum(self.rows(c) ** 2, axis=1)
        return out

    def gram(self) -> np.ndarray:
        G = np.zeros((self.r, self.r))
        for c in _chunks(len(self.ids), max(self.r, self.D.shape[1])):
            U = self.rows(c)
            G += U.T @ U
        return G

    def orthonormalised(self) -> "CentredSpan":
        """The same span with ``T`` corrected by the Cholesky factor of ``U^T U`` (orthonormal to about eps cond(R): see :meth:`BlockDesign.basis`)."""
        if not self.r:
            return self
        L = np.linalg.cholesky(self.gram())
        return CentredSpan(self.ids, self.D, self.mean, sla.solve_triangular(L, self.T.T, lower=True).T)


class _Transposed:
    """``A.T`` of a :class:`BlockDesign` or :class:`Basis`: only ``A.T @ X``."""

    def __init__(self, of):
        self.of = of

    def __matmul__(self, X):
        return self.of.rmatmul(np.asarray(X, float))


def _hstack_blocks(arrays):
    head, rest = arrays[0], [np.asarray(a, float) for a in arrays[1:]]
    if any(isinstance(a, (BlockDesign, Basis)) for a in arrays[1:]):
        raise ConfigError("hstack: a block design or basis can only come first")
    if not rest:
        return head
    return head.hstack(np.hstack([r.reshape(head.shape[0], -1) for r in rest]))


@dataclass(frozen=True, eq=False)
class Basis:
    """An orthonormal basis ``[G diag(count)^-1/2 | U]`` of a :class:`BlockDesign`'s column space.

    The indicator columns of the ids present (those with ``count > 0``),
    normalised, then ``U`` (n, r) dense, orthonormal and orthogonal to them
    (zero mean per id). Acts like the (n, g' + r) matrix where
    :mod:`core.discover` and :mod:`core.diagnosis` use one: ``Q @ c``,
    ``Q.T @ X``, ``Q.shape``, ``np.hstack([Q, V])`` (``V`` orthonormal and
    outside ``Q``, as :func:`core.diagnosis.new_basis` gives), ``Q[:, k:]``
    for ``k`` at or beyond the indicators, ``np.array_equal``; the rows'
    leverage by :func:`leverage`.
    """

    ids: np.ndarray
    counts: np.ndarray
    U: np.ndarray
    span: CentredSpan | None = None  # the design's own directions, kept as a map (before U's columns)

    def __post_init__(self):
        object.__setattr__(self, "_r", self.span.r if self.span is not None else 0)
        object.__setattr__(self, "_present", np.flatnonzero(self.counts > 0))
        object.__setattr__(self, "_scale", 1.0 / np.sqrt(self.counts[self._present]))
        pos = np.full(len(self.counts), -1)
        pos[self._present] = np.arange(len(self._present))
        object.__setattr__(self, "_pos", pos)

    @property
    def k(self) -> int:
        """Indicator columns (ids present)."""
        return len(self._present)

    @property
    def shape(self) -> tuple:
        return (len(self.ids), self.k + self._r + self.U.shape[1])

    @property
    def ndim(self) -> int:
        return 2

    @property
    def T(self) -> _Transposed:
        return _Transposed(self)

    def rmatmul(self, X: np.ndarray) -> np.ndarray:
        gs = group_sums(self.ids, len(self.counts), X)[self._present]
        gs = gs * (self._scale if X.ndim == 1 else self._scale[:, None])
        parts = [gs] + ([self.span.rmatmul(X)] if self._r else []) + [self.U.T @ X]
        return np.concatenate(parts, axis=0)

    def __matmul__(self, c):
        c = np.asarray(c, float)
        k, r = self.k, self._r
        cg = c[:k] * (self._scale if c.ndim == 1 else self._scale[:, None])
        out = cg[self._pos[self.ids]]
        if self.U.shape[1]:
            out += self.U @ c[k + r:]
        return self.span.matmul(c[k:k + r], out) if r else out

    def subtract_matmul(self, c: np.ndarray, B: np.ndarray, rows: int = 8192) -> np.ndarray:
        """``B - self @ c`` written over ``B`` (n, m), ``self @ c`` made ``rows`` rows at a time: each block's
        products are :meth:`__matmul__`'s on those rows in the same order (the indicators' scaled entries, plus
        the dense columns' product, plus the span's rows), so ``B`` holds ``B - self @ c`` bit for bit without the
        (n, m) product and its (n, m) temporaries beside it (two arrays of 61 MiB for 8 columns at 1e6 rows)."""
        c = np.asarray(c, float)
        k, r = self.k, self._r
        cg = c[:k] * (self._scale if c.ndim == 1 else self._scale[:, None])
        cu = c[k + r:]
        if r:
            Tc, Mc = self.span.T @ c[k:k + r], self.span.MT @ c[k:k + r]
        for ch in row_blocks(len(self.ids), rows):
            out = cg[self._pos[self.ids[ch]]]
            if self.U.shape[1]:
                out += self.U[ch] @ cu
            if r:
                out += self.span.D[ch] @ Tc - Mc[self.span.ids[ch]]
            np.subtract(B[ch], out, out=B[ch])
        return B

    def hstack(self, V: np.ndarray) -> "Basis":
        return Basis(self.ids, self.counts, np.hstack([self.U, V]), self.span)

    def __getitem__(self, key):
        k = self.k + self._r
        if (isinstance(key, tuple) and len(key) == 2 and key[0] == slice(None) and isinstance(key[1], slice)
                and key[1].step is None and (key[1].start or 0) >= k):
            s = key[1]
            return self.U[:, (s.start or 0) - k:None if s.stop is None else s.stop - k]
        raise ConfigError(f"Basis: only its dense columns can be taken (Q[:, k:] with k >= {k}), not {key!r}")

    def indicator_columns(self, ids) -> np.ndarray:
        """The columns of ``ids``' indicators among the basis's (-1 for an id with no rows)."""
        return self._pos[ids]

    def rows_rmatmul(self, pos: np.ndarray, X, out: np.ndarray | None = None) -> np.ndarray:
        """``Q[pos].T @ X`` for rows ``pos`` of the basis and ``X`` (len(pos), m) dense or sparse, without
        forming ``Q[pos]``: the indicator part as a sparse (k, len(pos)) matrix, then the dense part.

        ``out`` (q, m): the product added to it in place (and returned), a block of rows' share of a sum: only
        the indicators of the ids the rows touch are formed (a (k, m) table beside ``out`` was 55 MiB at the
        bench's 1e6 rows for the 700 per-set-up columns), each as the whole product has it, so ``out`` holds
        what ``out + rows_rmatmul(pos, X)`` would, bit for bit (the other rows of the product are zeros)."""
        col = self._pos[self.ids[pos]]
        if col.size and col.min() < 0:  # out[-1] would take it silently
            raise ValueError("rows_rmatmul: a row's id has no indicator column (its count is 0)")
        Up = self.dense_rows(pos)
        bot = (X.T @ Up).T if sp.issparse(X) else Up.T @ X
        if out is None:
            top = sp.csr_matrix((self._scale[col], (col, np.arange(len(pos)))), shape=(self.k, len(pos))) @ X
            return np.vstack([_dense(top), np.asarray(bot)])
        J, jinv = np.unique(col, return_inverse=True)
        top = sp.csr_matrix((self._scale[col], (jinv, np.arange(len(pos)))), shape=(len(J), len(pos))) @ X
        if sp.issparse(top):
            top = top.tocoo()
            top.sum_duplicates()
            out[J[top.row], top.col] += top.data
        else:
            out[J] += top
        out[self.k:] += np.asarray(bot)
        return out

    def rows_matmul(self, pos, c: np.ndarray) -> np.ndarray:
        """``(Q @ c)[pos]`` for rows ``pos`` (``c`` (q,) or (q, m)), without the product over every row."""
        c = np.asarray(c, float)
        k = self.k
        cg = c[:k] * (self._scale if c.ndim == 1 else self._scale[:, None])
        return cg[self._pos[self.ids[pos]]] + self.dense_rows(pos) @ c[k:]

    def dense_rows(self, pos) -> np.ndarray:
        """(len(pos), r + dense columns): the rows ``pos`` of the basis outside its indicator columns."""
        return np.hstack([self.span.rows(pos), self.U[pos]]) if self._r else self.U[pos]

    def dense_rmatmul(self, X: np.ndarray) -> np.ndarray:
        """``X``'s products with the basis's columns outside the indicators: ``dense_rows(all).T @ X``."""
        return np.concatenate([self.span.rmatmul(X), self.U.T @ X], axis=0) if self._r else self.U.T @ X

    def leverage(self) -> np.ndarray:
        h = self._scale[self._pos[self.ids]] ** 2 + np.sum(self.U ** 2, axis=1)
        return h + self.span.sq_rows() if self._r else h

    def toarray(self) -> np.ndarray:
        Q = np.zeros(self.shape)
        Q[np.arange(len(self.ids)), self._pos[self.ids]] = self._scale[self._pos[self.ids]]
        Q[:, self.k:] = self.dense_rows(slice(None))
        return Q

    def equals(self, other) -> bool:
        return self is other or (isinstance(other, Basis) and self.span is other.span
                                 and np.array_equal(self.ids, other.ids)
                                 and np.array_equal(self.counts, other.counts) and np.array_equal(self.U, other.U))


def _array_function(self, func, types, args, kwargs):
    """numpy's hstack and array_equal on a block design or basis (NEP 18); any other function refused."""
    if func is np.hstack:
        return _hstack_blocks(list(args[0]))
    if func is np.array_equal and isinstance(self, Basis):
        a, b = args[0], args[1]
        return isinstance(a, Basis) and a.equals(b)
    raise ConfigError(f"{type(self).__name__} is an operator, not an array: numpy.{func.__name__} is not defined "
                      "on it")


def _no_array(self, *a, **k):
    raise ConfigError(f"{type(self).__name__} is an operator, not an array: use its toarray() where a dense "
                      "matrix is meant")


for _cls in (BlockDesign, Basis):
    _cls.__array_function__ = _array_function
    _cls.__array__ = _no_array
DiagLowRank.__array__ = _no_array


def leverage(Q) -> np.ndarray:
    """(n,) the rows' leverage ``sum(Q ** 2, axis=1)`` of an orthonormal basis (an array or a :class:`Basis`)."""
    return Q.leverage() if isinstance(Q, Basis) else np.sum(Q ** 2, axis=1)


def orth_of(A, tol: float = 1e-9, qr=None):
    """Orthonormal basis of ``A``'s columns: :func:`core.diagnosis.orth` of an array, :meth:`BlockDesign.basis` of a block
    design."""
    if isinstance(A, BlockDesign):
        return A.basis(tol)
    from .diagnosis import orth

    return orth(A, tol=tol, qr=qr)


#: Compute :func:`quadratic_form_sf`'s upper tail (``x > 0``, some weight > 0) as the inversion integral on a contour
#: through its saddlepoint (:func:`_qf_sf_contour`) instead of Imhof's integral on the real line
#: (:func:`_qf_sf_imhof`, kept for ``x <= 0`` and as the fallback). Session 36 (imhof36): on the MFB's 969 recorded
#: weight sets two contours agree to 5e-15 relative, on closed forms the contour is within 2e-13 relative at tails 0.5
#: to 1e-20, and a tail costs a median 0.15 x Imhof's; Imhof's quadrature returned 0 or up to 1e-4 too much when one
#: weight dominates (docs/papers-mfb.md, "Imhof's quadrature where one weight dominates").
QF_SADDLE_CONTOUR = True
#: With :data:`QF_SADDLE_CONTOUR`, also ``x <= 0`` on a contour through the saddlepoint (:func:`_qf_sf_contour`;
#: session 37, tail37), where Imhof's quadrature was kept: ``x = 0`` is the ratio test of
#: :func:`core.uncertainty.model_error_budget` (weights of both signs), ``x < 0`` a lower tail. Against beta tails
#: (``x = 0``, 0.98 to 5e-150), the exponentials' closed form, chi-square lower tails (to 1e-12) and a 1-D integral
#: over one term's density: within 3.5e-14 relative (Imhof's quadrature: 50 % off at 1e-12, 0 below about 1e-16).
#: On 350 recorded ratio-test weight sets (the paper's pocket, 80 campaigns) Imhof's was within 1.5e-14 absolute
#: (the 8 tails below 1e-15 moved relatively: it returned 0 or 2e-15), no gate decision moved; a tail costs a median
#: 1.6 x Imhof's there (6.6 ms against 4.2: many degrees of freedom, where Imhof's integrand falls fast).
QF_CONTOUR_NONPOSITIVE_X = True
#: ``x < 0``: the parabola bends left, ``b = -QF_LEFT_BEND / (4 c)`` (it crosses ``Re s = 0`` at ``t = 2 c /
#: sqrt(QF_LEFT_BEND)``).
QF_LEFT_BEND = 1.0


def quadratic_form_sf(weights, x: float = 0.0, mult=None) -> float:
    """``P(sum_j w_j chi2_{h_j} > x)``: the exact tail of a quadratic form in independent standard normals.

    ``weights`` ``w_j`` (any sign; a Gaussian vector's quadratic form ``e^T B e``, ``e ~ N(0, S)``, has the
    eigenvalues of ``S^1/2 B S^1/2`` as weights, each of multiplicity 1), ``mult`` ``h_j`` their
    multiplicities (degrees of freedom; 1 each by default; at least 2 in all, as Imhof's integral needs; one weight
    of one degree is ``scipy.stats.chi2``). The tail is the inversion integral of the form's moment generating
    function ``M(s) = prod_j (1 - 2 w_j s)^(-h_j / 2)``:

        P(Q > x) = 1/(2 pi i) int_{c - i inf}^{c + i inf} M(s) exp(-s x) ds / s,   0 < c < 1 / (2 max w_j)

    (``c > 0`` when no weight is positive). Where ``x > 0`` and a weight is positive (:data:`QF_SADDLE_CONTOUR`) it
    is taken on a parabola through the saddlepoint of ``M(s) exp(-s x) / s`` that bends towards ``Re s -> +inf``
    (:func:`_qf_sf_contour`): the integrand is of the tail's own size and decays as a Gaussian, so a far tail is
    accurate relatively (within 2e-13 against chi-square tails from 0.5 to 1e-20, 1e-14 against a dominant weight
    with a chi-square or a convolution beside it, tests/core/test_quadratic_form_tail.py), also where one weight
    dominates the others. Where ``x <= 0`` (:data:`QF_CONTOUR_NONPOSITIVE_X`; the ratio of two quadratic forms
    below) on the same saddle's parabola bent towards ``Re s -> -inf`` (``x < 0``) or followed further (``x = 0``:
    no ``exp(-s x)``, the integrand falls as a power of ``|s|``): within 3.5e-14 relative of beta tails, chi-square
    lower tails and a 1-D integral (tests/core/test_lsq_tail_nonpositive.py); ``Q > x`` certain (all weights > 0,
    ``x < 0``) is 1, impossible (all < 0, ``x = 0``) 0. Elsewhere (the constants off, or the contour's check
    fails) Imhof's form of the same integral on the real line (Biometrika 48, 1961, eq 3.2; :func:`_qf_sf_imhof`),
    accurate absolutely (below 3e-6 at 2 degrees of freedom, 1e-7 at 3, 1e-9 from 4 on; not where one weight
    dominates: there its integrand decays as for one degree and its error reached 1e-4). The result clipped to
    [0, 1]. A ratio of two
    quadratic forms of one vector, ``e^T B e / e^T D e > c``, is ``e^T (B - c D) e > 0``: weights of ``B - c D``,
    ``x`` 0 (what :func:`core.uncertainty.model_error_budget` tests when the noise's variance is the residuals'
    own). ``weights`` all 0: 1 if ``x < 0`` else 0.

    Raises
    ------
    ConfigError
        ``weights`` or ``mult`` not finite, ``mult`` not > 0 or not of ``weights``' length, ``x`` not finite,
        fewer than 2 degrees of freedom with non-zero weights.
    """
    w = np.atleast_1d(np.asarray(weights, float)).ravel()
    h = np.ones_like(w) if mult is None else np.atleast_1d(np.asarray(mult, float)).ravel()
    if not np.all(np.isfinite(w)):
        raise ConfigError("quadratic_form_sf: weights must be finite")
    if h.shape != w.shape or not np.all(np.isfinite(h)) or np.any(h <= 0):
        raise ConfigError(f"quadratic_form_sf: mult must be {w.size} finite values > 0, got {mult!r}")
    if not np.isfinite(x):
        raise ConfigError(f"quadratic_form_sf: x must be finite, got {x!r}")
    keep = w != 0
    w, h = w[keep], h[keep]
    if not w.size:
        return 1.0 if x < 0 else 0.0
    if float(h.sum()) < 2.0:
        raise ConfigError(f"quadratic_form_sf: {float(h.sum()):g} degrees of freedom with non-zero weights: at least 2 "
                          "(one weight of one degree: scipy.stats.chi2)")
    s = float(np.max(np.abs(w)))   # scaled to the largest weight: u of order 1 where the integrand lives
    w, xs = w / s, float(x) / s
    if QF_SADDLE_CONTOUR and xs > 0 and w.max() > 0:
        p = _qf_sf_contour(w, h, xs)
        if p is not None:
            return float(min(max(p, 0.0), 1.0))
    elif QF_SADDLE_CONTOUR and QF_CONTOUR_NONPOSITIVE_X and xs <= 0:
        if w.min() > 0 or (xs == 0 and w.max() < 0):   # Q > 0 >= x, or Q < 0 = x: certain either way
            return 1.0 if w.min() > 0 else 0.0
        p = _qf_sf_contour(w, h, xs)
        if p is not None:
            return float(min(max(p, 0.0), 1.0))
    return _qf_sf_imhof(w, h, xs)


def _qf_sf_imhof(w: np.ndarray, h: np.ndarray, xs: float) -> float:
    """:func:`quadratic_form_sf` by Imhof's inversion (Biometrika 48, 1961, eq 3.2), weights ``w`` scaled to a largest
    ``|w_j|`` of 1, multiplicities ``h``, ``xs`` scaled alike:

        P(Q > x) = 1/2 + (1/pi) int_0^inf sin(theta(u)) / (u rho(u)) du,
        theta(u) = 1/2 sum_j h_j atan(w_j u) - x u / 2,   rho(u) = prod_j (1 + w_j^2 u^2)^(h_j / 4),

    by adaptive quadrature in pieces; the integrand decays as ``u^-(1 + sum h / 2)`` once ``u`` passes the inverse of
    every weight, as ``u^-(1 + h_1 / 2)`` before the small ones act (a dominant weight ``w_1`` of one degree: slowly,
    and oscillating, the error reaching 1e-4 absolute)."""
    from scipy import integrate

    def f(u):
        if u == 0.0:
            return 0.5 * float(h @ w) - 0.5 * xs
        th = 0.5 * float(h @ np.arctan(w * u)) - 0.5 * xs * u
        return np.sin(th) * np.exp(-0.25 * float(h @ np.log1p((w * u) ** 2))) / u

    import warnings

    with warnings.catch_warnings():  # the far tail's slow oscillation: its part is below 1e-6 (the tests' known answers)
        warnings.simplefilter("ignore", integrate.IntegrationWarning)
        val = sum(integrate.quad(f, a, b, limit=1000, epsabs=1e-11, epsrel=1e-9)[0]
                  for a, b in zip((0.0, 1.0, 10.0, 100.0, 1e3, 1e4), (1.0, 10.0, 100.0, 1e3, 1e4, np.inf)))
    return float(min(max(0.5 + val / np.pi, 0.0), 1.0))


def _qf_sf_contour(w: np.ndarray, h: np.ndarray, xs: float, bend: float = 1.0):
    """:func:`quadratic_form_sf`'s ``P(Q > x)`` on a contour through the saddlepoint (``x > 0`` and some ``w_j > 0``,
    or ``x = 0`` and weights of both signs, or ``x < 0`` and some ``w_j < 0``; weights scaled to a largest ``|w_j|``
    of 1, ``xs`` alike), or None where the contour fails its check.

    The integrand ``g(s) = M(s) exp(-s x) / s`` is analytic but for the pole at 0 and the branch cuts
    ``[1 / (2 w_j), inf)`` of the positive weights (``(-inf, 1 / (2 w_j)]`` of the negative), and ``exp(-s x)``
    vanishes as ``Re s -> +inf``; so the line ``Re s = c`` may bend to the right, onto the parabola
    ``s(t) = c + b t^2 + i t`` (Cauchy: the region between holds no singularity). ``c`` is the saddlepoint of
    ``log g`` on ``(0, 1 / (2 max w))`` (``g`` there is of the tail's own size, so no 1/2 cancels it, as it does in
    Imhof's form), ``b = bend / (4 (p - c))`` (a far tail), ``p = 1 / (2 max w)``: the parabola crosses ``Re s = p`` at
    ``t = 2 (p - c)``, the width over which the dominant weight's factor falls (a tail far out, ``c`` near ``p``:
    then ``|g|`` falls as ``exp(-x b t^2)``, in a few of the oscillations that make Imhof's integral slow). By
    symmetry (``g`` real on the real axis) ``P = (1/pi) int_0^inf Im(g(s(t)) s'(t)) dt``, by adaptive quadrature in
    pieces of 1, 3, 10... saddle widths ``sigma``. ``bend`` scales ``b`` (tests: another contour, the same integral).

    The parabola is followed up to ``t_top``, the first ``t`` of a geometric grid where ``|g|`` is ``exp(-45)`` of
    its value at ``c`` or starts to rise again; the contour goes on up the vertical ray ``Re s = Re s(t_top)``, on
    which ``|g|`` only falls (each ``|1 - 2 w_j s|`` and ``|s|`` grow with ``Im s``; no singularity lies between the
    ray and the rest of the parabola, all being on the real axis), as ``Im s^(-1 - sum h / 2)`` far up. The ray is
    left out where its part is provably small: the sum of ``|g|`` at the start of each step of a geometric grid up the
    ray (an upper bound, ``|g|`` falling) and the power tail beyond at most ``1e-14`` of ``|g(c)|`` times the saddle's
    width (the result is about 0.4 of that). Else, and where ``|g|`` rises above ``exp(3)`` of its value at ``c``
    below ``t_top`` (a large factor of small weights, ``x`` near or below the mean: far out it outgrows
    ``exp(-s x)``), ``b`` is quartered, up to 8 times. None if that fails, or where the quadrature's error estimate
    exceeds 1e-10 of the result. In the bulk (``c`` below 0.8 ``p``: ``x`` near or below the mean, where
    ``exp(-x b t^2)`` falls slowly and the integrand oscillates on the way) ``b`` starts at a quarter (``c`` from
    0.7 ``p``) or a sixteenth: on the MFB's weight sets there half the integrand's evaluations, the tails' alike.

    ``x < 0`` (session 37): ``exp(-s x)`` vanishes as ``Re s -> -inf`` instead, so the parabola bends left,
    ``b = -bend QF_LEFT_BEND / (4 c)`` (it crosses ``Re s = 0``, the pole's abscissa, at ``t = 2 c``, away from the
    real axis: the region between it and ``Re s = c`` holds no singularity either); the saddle is on ``(0, p)``, or
    on ``(0, inf)`` with no positive weight. ``x = 0`` (the ratio test): no ``exp(-s x)``, ``|g|`` falls only as
    ``|s|^(-1 - sum h / 2)`` (as ``t^(-2 - sum h)`` on the parabola), so the parabola (bent right) is followed down
    to ``exp(-80)`` on a grid out to ``2^50`` saddle widths, in pieces up to ``1e15`` widths: with 2 degrees of
    freedom in all the ray's part is then below ``1e-14`` as for the others (at ``exp(-45)`` it was about 1e-12)."""
    import warnings

    from scipy import integrate, optimize

    p = 0.5 / float(w.max()) if w.max() > 0 else np.inf
    hw = h * w

    def dlog(s):   # d/ds log g on the real axis, increasing from -inf at 0 to +inf at p (to -x where p is inf)
        return float(np.sum(hw / (1.0 - 2.0 * w * s))) - xs - 1.0 / s

    if np.isfinite(p):
        lo, hi = p * 1e-15, p * (1.0 - 1e-15)
    else:   # no positive weight (then x < 0): dlog tends to -x > 0 and is positive from (sum h + 2) / |x| on
        lo, hi = 1e-15 / (abs(xs) + float(h.sum())), (float(h.sum()) + 2.0) / abs(xs) if xs < 0 else np.inf
    if not (np.isfinite(hi) and dlog(lo) < 0.0 < dlog(hi)):
        return None
    c = optimize.brentq(dlog, lo, hi, xtol=1e-300, rtol=1e-15, maxiter=300)
    oc = 1.0 - 2.0 * w * c
    sig = 1.0 / np.sqrt(float(np.sum(2.0 * hw * w / oc ** 2)) + 1.0 / c ** 2)   # the saddle's width in t
    log0 = -0.5 * float(h @ np.log(oc)) - c * xs - np.log(c)
    # x = 0: no exp(-s x), |g| falls only as a power of |s| (as t^-(2 + sum h) on the parabola): followed further
    # down and out, so that the ray's part is bounded below 1e-14 also where 2 degrees of freedom fall slowly
    floor = -45.0 if xs != 0.0 else -80.0
    grid = sig * (np.geomspace(0.125, 2.0 ** 30, 94) if xs != 0.0 else np.geomspace(0.125, 2.0 ** 50, 150))
    up = np.geomspace(1.0, 2.0 ** 40, 81)   # the vertical ray's heights, in t_top

    def logabs(a, tt):   # log |g(a + i t) / g(c)|
        return (-0.25 * (h @ np.log(((1.0 - 2.0 * np.outer(w, a)) ** 2 + np.outer(4.0 * w * w, tt ** 2))
                                    / (oc * oc)[:, None]))
                - xs * (a - c) - 0.5 * np.log((a * a + tt * tt) / (c * c)))

    def turn(b):   # t_top on the parabola of b, or None where it fails the check
        rel = logabs(c + b * grid ** 2, grid)
        rising = np.nonzero((rel[1:] > rel[:-1] + 0.5) | (rel[1:] > 3.0))[0]
        stop = np.nonzero(rel < floor)[0]
        k = min(stop[0] if stop.size else grid.size, rising[0] if rising.size else grid.size)
        if k == grid.size or rel[:k + 1].max() > 3.0:
            return None
        top = float(grid[k])
        ys = top * up   # |g| falls up the ray: a step's first value bounds it; beyond, |g| ~ y^-(1 + sum h / 2)
        mag = np.exp(logabs(np.full(ys.size, c + b * top * top), ys))
        ray = float(np.sum(np.diff(ys) * mag[:-1]) + mag[-1] * ys[-1] / (0.5 * float(h.sum())))
        return top if ray <= 1e-14 * sig else None

    # flatter in the bulk (c below 0.8 p: x near or below the mean, exp(-x b t^2) slow): half the evaluations there
    if xs >= 0.0:
        b = bend * (1.0 if c >= 0.8 * p else 0.25 if c >= 0.7 * p else 0.0625) * 0.25 / (p - c)
    else:   # x < 0: exp(-s x) vanishes as Re s -> -inf: the parabola bends left, towards the pole at 0
        b = -bend * QF_LEFT_BEND * 0.25 / c
    for _ in range(9):
        top = turn(b)
        if top is not None:
            break
        b *= 0.25
    else:
        return None

    def f(t):
        z = complex(c + b * t * t, t)
        return (np.exp(-0.5 * np.sum(h * np.log(1.0 - 2.0 * w * z)) - z * xs - np.log(z) - log0)
                * complex(2.0 * b * t, 1.0)).imag

    steps = (1, 3, 10, 30, 100, 300, 1e3, 3e3, 1e4) + (tuple(k * 10.0 ** e for e in range(4, 15) for k in (3, 10))
                                                       if xs == 0.0 else ())
    cuts = [0.0] + [sig * k for k in steps if sig * k < top] + [top]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", integrate.IntegrationWarning)
        parts = [integrate.quad(f, t0, t1, epsabs=1e-14 * sig, epsrel=1e-12, limit=200)
                 for t0, t1 in zip(cuts[:-1], cuts[1:])]
    val, err = sum(v for v, _ in parts), sum(e for _, e in parts)
    if not err <= 1e-10 * abs(val):
        return None
    return float(np.exp(log0) * val / np.pi)
