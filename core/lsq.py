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
   an eigen rank check up to :data:`DENSE_MAX` free parameters, by sparse LU
   above; unidentifiable combinations are named (:func:`describe_direction`);
5. :func:`_sigma` and :func:`_covariance`: the observation standard
   deviation (given or from the residuals) and the parameters' uncertainty
   (:class:`Covariance` mode).

:class:`LinearEstimator` keeps the factorisation so many right-hand sides
(Monte Carlo runs, JCGM 101) cost one back-substitution each.

:func:`remove_span` is the one gauge removal of core: what a set of
directions (a shift, a rotation, a scale...) can explain is taken out of a
vector by least squares; self-calibration uses it for the workpiece form
and for comparing an error map with the truth.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from enum import StrEnum

import numpy as np
import scipy.linalg as sla
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from .exceptions import ConfigError, IdentifiabilityError

#: Largest number of free parameters solved densely (with an eigen rank check).
DENSE_MAX = 500
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

    def __init__(self, A, DZ, B, phi0_theta, r0_shift, solve_M, n_free):
        self.A = A
        self.DZ = DZ  # (n, n_free) sparse: theta = DZ psi + theta0
        self.B = B  # (m, n_free) sparse
        self.theta0 = phi0_theta
        self.b_shift = r0_shift  # A theta0
        self._solve_M = solve_M
        self.n_free = n_free

    def psi(self, b: np.ndarray) -> np.ndarray:
        rhs = self.B.T @ (b - (self.b_shift if b.ndim == 1 else self.b_shift[:, None]))
        return self._solve_M(rhs)

    def estimate(self, b: np.ndarray) -> np.ndarray:
        """(n,) or (n, r) estimates for ``b`` of shape (m,) or (m, r)."""
        b = np.asarray(b, float)
        t = self.DZ @ self.psi(b)
        return t + (self.theta0 if b.ndim == 1 else self.theta0[:, None])

    def noise_gain(self, e: np.ndarray) -> np.ndarray:
        """(n, r) change of the estimate caused by observation noise ``e`` (m, r)."""
        return self.DZ @ self._solve_M(self.B.T @ e)

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
        DZt = DZ.T.tocsc()
        n = DZt.shape[1]
        out = np.empty(n)
        for a in range(0, n, block):
            cols = DZt[:, a:a + block].toarray()
            X = self._solve_M(cols)
            out[a:a + block] = np.einsum("ij,ij->j", cols, X)
        return sigma * np.sqrt(np.maximum(out, 0))


def _eliminate(C: np.ndarray, d: np.ndarray, n: int):
    """Z (n, n-k) sparse and theta0 with C (Z psi + theta0) = d for all psi."""
    k = C.shape[0]
    if k == 0:
        return sp.identity(n, format="csr"), np.zeros(n)
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
    return Z, theta0


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


def _column_scale(A: sp.csr_matrix, C: np.ndarray, names) -> np.ndarray:
    """Step 2: (n,) scale D making every observed column of ``A D`` unit-norm (1 for unobserved ones).

    Raises IdentifiabilityError naming the parameters neither an observation
    nor a constraint touches.
    """
    colnorm = np.sqrt(np.asarray(A.multiply(A).sum(axis=0)).ravel())
    # rounding dust (cos 90 deg = 6e-17) is no observation
    colnorm[colnorm <= 1e-12 * max(colnorm.max(initial=0.0), 1e-300)] = 0.0
    in_c = np.any(C != 0, axis=0)
    zero = np.flatnonzero((colnorm == 0) & ~in_c)
    if zero.size:
        shown = ", ".join(names[i] for i in zero[:8]) + (f" and {zero.size - 8} more" if zero.size > 8 else "")
        raise IdentifiabilityError(f"no observation constrains {shown}")
    return np.where(colnorm > 0, 1.0 / np.where(colnorm > 0, colnorm, 1.0), 1.0)


def _factor_normal(B: sp.csc_matrix, DZ: sp.csr_matrix, names, rank_tol: float):
    """Step 4: ``solve_M(r) = M^-1 r`` for ``M = B^T B``, after the rank check.

    Dense (eigen-decomposition, then Cholesky) up to :data:`DENSE_MAX` free
    parameters, sparse LU above; a rank deficiency raises
    IdentifiabilityError naming the parameter combinations (dense) or the
    near-null pivots (sparse).
    """
    M = (B.T @ B).tocsc()
    if B.shape[1] <= DENSE_MAX:
        Md = M.toarray()
        w, V = np.linalg.eigh(Md)
        bad = w <= rank_tol * max(w[-1], 1e-300)
        if bad.any():
            dirs = [describe_direction(DZ @ V[:, i], names) for i in np.flatnonzero(bad)[:5]]
            raise IdentifiabilityError(
                f"rank deficient by {int(bad.sum())} beyond the constraints; unidentifiable: " + "; ".join(dirs))
        cf = sla.cho_factor(Md)
        return lambda r: sla.cho_solve(cf, r)
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
    return lambda r: lu.solve(np.asarray(r, float))


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


def solve(A, b, C=None, d=None, *, names=None, sigma=None, covariance: str = "auto",
          rank_tol: float = RANK_TOL) -> Solution:
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
    Z, phi0 = _eliminate(C * D[None, :], d, n)
    DZ = (sp.diags(D) @ Z).tocsr()
    theta0 = D * phi0
    B = (A @ DZ).tocsc()
    nf = B.shape[1]
    est = LinearEstimator(A, DZ, B, theta0, A @ theta0, _factor_normal(B, DZ, names, rank_tol), nf)
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
