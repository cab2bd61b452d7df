"""Least-squares (Gaussian, orthogonal-distance) fitting of geometric features.

Features: plane, line (3D), circle in a plane (2D), circle in space (3D),
sphere, cylinder. Every fit minimises the sum of squared *orthogonal*
distances of the points to the feature (ISO 10360-6 Gaussian criterion)
and returns a frozen result with

- the feature parameters: a position on the feature nearest the centroid
  of the points (plane: centroid projected onto it; line / cylinder: the
  axis point nearest the centroid; circle / sphere: the centre), a unit
  direction (plane normal, line direction, circle normal, cylinder axis)
  with a fixed sign convention (see :func:`orient`), the radius;
- the orthogonal residuals ``(n,)`` and their RMS;
- the covariance of a *minimal local* parametrisation at the solution
  (``param_names`` and ``basis`` say what each parameter moves),
  ``cov = s**2 (J^T J)^-1`` with ``s**2 = sum(r**2) / dof`` and
  ``dof = m - k`` (m scalar residuals, k parameters). With ``dof == 0``
  the covariance is NaN (an exact fit says nothing about the scatter).

Method (scikit-image ``measure/fit.py`` style): the points are centred on
their centroid and scaled by their RMS distance to it, the problem is
solved in those coordinates, and the Jacobian at the solution in those
coordinates (the "scaled Jacobian") is checked: if its condition number exceeds
:attr:`FitTolerances.cond_max` the fit raises :class:`FitError` saying
"not enough significant data points" and naming the parameter combination
the data cannot determine.

- Plane and line: exact, non-iterative, by SVD of the centred points (the
  smallest / largest right singular vector); :func:`fit_planes` and
  :func:`fit_lines` do the same for a batch ``(b, n, 3)`` in one call. This is the same minimiser as
  the cubic of Viprey et al. 2016, Appendix B (eqs. B.4-B.9), without its
  special cases (``c = 0``, plane through the origin); the tests check the
  two against each other.
- Circle (2D, 3D), sphere, cylinder: Gauss-Newton on the orthogonal
  residuals. For the cylinder each iteration is the small-displacement-screw
  (SDS) linearisation of Viprey et al. 2016, Appendix A: the points are
  expressed in the frame of the current axis estimate (axis = z), the
  linear model ``xi_i = -z_i sin(th_i) alpha + z_i cos(th_i) beta +
  cos(th_i) u + sin(th_i) v + r`` (eq. A.5) is solved for the screw
  ``(alpha, beta, u, v, r)`` and the axis is moved by it; repeated until
  the screw is below :attr:`FitTolerances.step_tol`. The linear system is
  solved by SVD of the design matrix rather than the normal equations A.8
  (same solution, half the digits lost otherwise; note that row 4 of the
  printed A.8 has a sign typo: its first entry must be ``-sum z sin^2``
  for the matrix to be symmetric). Other nonlinear kinds use the same
  local-parametrisation Gauss-Newton iteration with step halving.

Initial guesses: circle / sphere from the algebraic (Kasa) fit; circle in
space from the SVD plane then Kasa in that plane; cylinder from a user
``axis_hint`` if given; else candidate axes (the principal directions of
the points, the axis of an algebraic quadric fit, a 600-direction grid on
the hemisphere) are scored by the algebraic circle fitted to the points
projected along them, SDS iterations run from the four best, and the
converged candidate with the smallest residual sum of squares is kept.

Units: the functions are unit-agnostic; vmt passes metres, so positions,
radii and residuals are in m, directions unit vectors, tilts in rad.
Frames: whatever frame the points are in (``_R`` or ``_W`` in callers).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from .exceptions import FitError

__all__ = [
    "FitTolerances",
    "TOL",
    "PlaneFit",
    "LineFit",
    "Circle2Fit",
    "Circle3Fit",
    "SphereFit",
    "CylinderFit",
    "fit_plane",
    "plane_point_normal",
    "cylinder_point_axis",
    "planes_point_normal",
    "cylinders_point_axis",
    "fit_line",
    "fit_planes",
    "fit_lines",
    "fit_circle_2d",
    "fit_circle_3d",
    "fit_sphere",
    "fit_cylinder",
    "orient",
    "REFERENCE_DIRECTION",
    "rounding_u95",
    "ROUNDING_K",
]


@dataclass(frozen=True)
class FitTolerances:
    """Numerical tolerances of the fits (all dimensionless).

    Attributes
    ----------
    cond_max : float
        Largest condition number accepted for the Jacobian at the solution
        in centred coordinates scaled to unit RMS distance. Above it a
        parameter combination is not determined by the data: with
        ``cond = 1e8`` an SVD solve still keeps ~8 significant digits,
        i.e. ~1e-8 of the feature size, which is the limit vmt accepts.
    step_tol : float
        Gauss-Newton / SDS iterations stop when the full step (scaled units
        and rad) is below this, or below its square root and no longer
        shrinking (the rounding floor). 1e-12 of the feature size is far below the 1 nm
        the reference tests ask for, yet well above rounding (~1e-15).
    max_iter : int
        Iteration cap; reaching it raises :class:`FitError`.
    rival_rms_ratio : float
        Cylinder without ``axis_hint``: if another candidate converges to an
        axis more than ``rival_angle`` away with an RMS residual within this
        factor of the best one (or both are at rounding level, 1e-9 of the
        feature size), the points do not single out one cylinder and the fit
        raises instead of picking one. 2: a rival fitting within twice the
        RMS cannot be rejected on the 8-12 points of an MFB feature.
    rival_angle : float
        rad; see ``rival_rms_ratio``.
    """

    cond_max: float = 1e8
    step_tol: float = 1e-12
    max_iter: int = 100
    rival_rms_ratio: float = 2.0
    rival_angle: float = 1e-3


TOL = FitTolerances()

#: Sign convention for unoriented directions: ``d . REFERENCE_DIRECTION > 0``.
#: Proportional to (1, sqrt 2, pi): positive on every coordinate axis, and
#: no direction with small integer ratios is perpendicular to it, so noise
#: cannot flip the sign of a "nice" axis.
REFERENCE_DIRECTION = np.array([1.0, np.sqrt(2.0), np.pi]) / np.sqrt(3.0 + np.pi**2)


def orient(d, hint=None):
    """Return the unit vector ``d`` with the vmt sign convention.

    Parameters
    ----------
    d : (3,) float
        Direction (any sign, unit).
    hint : (3,) float, optional
        If given, the result satisfies ``result . hint >= 0``; otherwise
        ``result . REFERENCE_DIRECTION > 0``.

    Returns
    -------
    (3,) float
    """
    d = np.asarray(d, dtype=float)
    ref = REFERENCE_DIRECTION if hint is None else np.asarray(hint, dtype=float)
    return -d if float(d @ ref) < 0.0 else d


# --------------------------------------------------------------------------- results


@dataclass(frozen=True)
class PlaneFit:
    """Least-squares plane.

    Attributes
    ----------
    point : (3,) float
        Centroid of the points projected onto the plane, m.
    normal : (3,) float
        Unit normal (sign: :func:`orient`).
    residuals : (n,) float
        Signed orthogonal distances ``(p_i - point) . normal``, m.
    rms : float
        RMS of ``residuals``, m.
    cov : (3, 3) float
        Covariance of (``offset_n`` m, ``tilt_u`` rad, ``tilt_v`` rad): the
        plane moves to ``point + offset_n normal`` and its normal tilts to
        ``normal + tilt_u u + tilt_v v``, ``(u, v) = basis[:2]``.
    dof : int
        ``n - 3``.
    basis : (3, 3) float
        Rows ``u, v, normal``: right-handed orthonormal frame.
    """

    point: np.ndarray
    normal: np.ndarray
    residuals: np.ndarray
    rms: float
    cov: np.ndarray
    dof: int
    basis: np.ndarray
    param_names: ClassVar[tuple[str, ...]] = ("offset_n", "tilt_u", "tilt_v")


@dataclass(frozen=True)
class LineFit:
    """Least-squares line in space.

    Attributes
    ----------
    point : (3,) float
        Point of the line nearest the centroid (= the centroid), m.
    direction : (3,) float
        Unit direction (sign: :func:`orient`).
    residuals : (n,) float
        Orthogonal distances to the line (>= 0), m.
    residual_uv : (n, 2) float
        Components of the offsets along ``basis[0]``, ``basis[1]``, m.
    rms : float
        RMS of ``residuals``, m.
    cov : (4, 4) float
        Covariance of (``shift_u``, ``shift_v`` m, ``tilt_u``, ``tilt_v``
        rad): ``point + shift_u u + shift_v v``, ``direction + tilt_u u +
        tilt_v v``.
    dof : int
        ``2 n - 4``.
    basis : (3, 3) float
        Rows ``u, v, direction``.
    """

    point: np.ndarray
    direction: np.ndarray
    residuals: np.ndarray
    residual_uv: np.ndarray
    rms: float
    cov: np.ndarray
    dof: int
    basis: np.ndarray
    param_names: ClassVar[tuple[str, ...]] = ("shift_u", "shift_v", "tilt_u", "tilt_v")


@dataclass(frozen=True)
class Circle2Fit:
    """Least-squares circle in the plane.

    Attributes
    ----------
    centre : (2,) float
        m.
    radius : float
        m.
    residuals : (n,) float
        ``|p_i - centre| - radius``, m.
    rms : float
        m.
    cov : (3, 3) float
        Covariance of (``centre_x``, ``centre_y``, ``radius``), m^2.
    dof : int
        ``n - 3``.
    iterations : int
        Gauss-Newton iterations used.
    """

    centre: np.ndarray
    radius: float
    residuals: np.ndarray
    rms: float
    cov: np.ndarray
    dof: int
    iterations: int
    param_names: ClassVar[tuple[str, ...]] = ("centre_x", "centre_y", "radius")


@dataclass(frozen=True)
class Circle3Fit:
    """Least-squares circle in space (orthogonal distance to the circle curve).

    Attributes
    ----------
    centre : (3,) float
        m.
    normal : (3,) float
        Unit normal of the circle's plane (sign: :func:`orient`).
    radius : float
        m.
    residuals : (n,) float
        Orthogonal distances to the circle (>= 0), m.
    residual_hr : (n, 2) float
        Components: height above the plane ``h`` and radial ``rho - radius``, m.
    rms : float
        m.
    cov : (6, 6) float
        Covariance of (``shift_u``, ``shift_v``, ``shift_n`` m, ``tilt_u``,
        ``tilt_v`` rad, ``radius`` m) in ``basis`` (rows ``u, v, normal``).
    dof : int
        ``2 n - 6``.
    basis : (3, 3) float
    iterations : int
    """

    centre: np.ndarray
    normal: np.ndarray
    radius: float
    residuals: np.ndarray
    residual_hr: np.ndarray
    rms: float
    cov: np.ndarray
    dof: int
    basis: np.ndarray
    iterations: int
    param_names: ClassVar[tuple[str, ...]] = (
        "shift_u", "shift_v", "shift_n", "tilt_u", "tilt_v", "radius")


@dataclass(frozen=True)
class SphereFit:
    """Least-squares sphere.

    Attributes
    ----------
    centre : (3,) float
        m.
    radius : float
        m.
    residuals : (n,) float
        ``|p_i - centre| - radius``, m.
    rms : float
        m.
    cov : (4, 4) float
        Covariance of (``centre_x``, ``centre_y``, ``centre_z``, ``radius``), m^2.
    dof : int
        ``n - 4``.
    iterations : int
    """

    centre: np.ndarray
    radius: float
    residuals: np.ndarray
    rms: float
    cov: np.ndarray
    dof: int
    iterations: int
    param_names: ClassVar[tuple[str, ...]] = ("centre_x", "centre_y", "centre_z", "radius")


@dataclass(frozen=True)
class CylinderFit:
    """Least-squares cylinder (Viprey et al. 2016, Appendix A, iterated).

    Attributes
    ----------
    point : (3,) float
        Point of the axis nearest the centroid of the points, m.
    axis : (3,) float
        Unit axis direction (sign: :func:`orient`, or along ``axis_hint``).
    radius : float
        m.
    residuals : (n,) float
        ``distance(p_i, axis) - radius``, m.
    rms : float
        m.
    cov : (5, 5) float
        Covariance of the SDS at the solution (``shift_u``, ``shift_v`` m,
        ``tilt_u``, ``tilt_v`` rad, ``radius`` m): ``point + shift_u u +
        shift_v v``, ``axis + tilt_u u + tilt_v v`` (pivot at ``point``).
        In the axis frame x = u, y = v, z = axis these are the screw of
        eqs. A.4-A.5 as ``(u, v, beta, -alpha, r)``.
    dof : int
        ``n - 5``.
    basis : (3, 3) float
        Rows ``u, v, axis``.
    iterations : int
        SDS iterations of the retained candidate.
    """

    point: np.ndarray
    axis: np.ndarray
    radius: float
    residuals: np.ndarray
    rms: float
    cov: np.ndarray
    dof: int
    basis: np.ndarray
    iterations: int
    param_names: ClassVar[tuple[str, ...]] = ("shift_u", "shift_v", "tilt_u", "tilt_v", "radius")


# --------------------------------------------------------------------------- helpers


def _centred(P):
    """Centroid, RMS distance to it and the centred points scaled by it: (c0, s, X)."""
    c0 = P.mean(axis=0)
    D = P - c0
    s = float(np.sqrt(np.mean(np.einsum("ij,ij->i", D, D))))
    return c0, s, D / s if s > 0.0 else D


def _prepared(points, n_min: int, kind: str, validate: bool):
    """(P, c0, s, X) of (n, 3) ``points``: checked by :func:`_check_points`, or only centred
    and scaled when the caller vouches for them (the light paths' ``validate=False``)."""
    if validate:
        return _check_points(points, 3, n_min, kind)
    c0, s, X = _centred(points)
    return points, c0, s, X


def _n_distinct(P) -> int:
    """Number of distinct rows of ``P`` (n, d) (same count as ``np.unique(P, axis=0)``)."""
    Q = P[np.lexsort(P.T[::-1])]
    return 1 + int(np.count_nonzero(np.any(Q[1:] != Q[:-1], axis=1))) if len(Q) else 0


def _check_points(points, dim: int, n_min: int, kind: str):
    """Validate and centre/scale ``points``; return (P, c0, s, X)."""
    try:
        P = np.asarray(points, dtype=float)
    except (TypeError, ValueError) as e:
        raise FitError(f"{kind} fit: points must be a numeric (n, {dim}) array ({e})") from None
    if P.ndim != 2 or P.shape[1] != dim:
        raise FitError(f"{kind} fit: points must be (n, {dim}), got {P.shape}")
    n = P.shape[0]
    if n < n_min:
        raise FitError(f"{kind} fit: not enough data points: needs at least {n_min}, got {n}")
    bad = ~np.isfinite(P).all(axis=1)
    if bad.any():
        raise FitError(f"{kind} fit: points contain non-finite values (row {int(np.argmax(bad))})")
    c0, s, X = _centred(P)
    if s == 0.0:
        raise FitError(f"{kind} fit: not enough significant data points: all points are coincident")
    n_distinct = _n_distinct(P)
    if n_distinct < n_min:
        raise FitError(f"{kind} fit: not enough significant data points: only {n_distinct} "
                       f"distinct points (coincident points), needs {n_min}")
    return P, c0, s, X


def _cross3(a, b):
    """``np.cross`` of two (3,) vectors without its generic-axis overhead (same operations, same bits)."""
    a0, a1, a2 = a.tolist()
    b0, b1, b2 = b.tolist()
    return np.array([a1 * b2 - a2 * b1, a2 * b0 - a0 * b2, a0 * b1 - a1 * b0])


def _perp_basis(d, u_prev=None):
    """Right-handed rows (u, v, d) with u close to ``u_prev`` when given."""
    if u_prev is None:
        a = np.eye(3)[int(np.argmin(np.abs(d)))]
    else:
        a = u_prev
    u = a - (a @ d) * d
    nu = np.linalg.norm(u)
    if nu < 1e-6:  # u_prev nearly along d: start afresh
        a = np.eye(3)[int(np.argmin(np.abs(d)))]
        u = a - (a @ d) * d
        nu = np.linalg.norm(u)
    u = u / nu
    v = _cross3(d, u)
    return np.stack([u, v, d])


def _conditioning(J, names):
    """Condition number of J (centred, scaled coordinates) and its weakest combination.

    J is evaluated on the centred points scaled to unit RMS distance, so its
    columns are O(sqrt(m)) for a well-spread data set and a column that is
    small only through rounding stays small (equilibrating the columns
    would hide exactly that degeneracy).
    """
    if not np.all(np.isfinite(J)):
        return np.inf, "non-finite Jacobian"
    _, sv, Vt = np.linalg.svd(J, full_matrices=False)
    cond = sv[0] / sv[-1] if sv[-1] > 0 else np.inf
    w = Vt[-1]
    idx = np.argsort(-np.abs(w))
    terms = [f"{w[i]:+.2f}*{names[i]}" for i in idx if abs(w[i]) >= 0.1]
    return cond, " ".join(terms)


def _check_rank(J, names, kind: str, what: str, tol: FitTolerances):
    cond, combo = _conditioning(J, names)
    if not cond <= tol.cond_max:
        raise FitError(f"{kind} fit: not enough significant data points: {what} "
                       f"(condition number {cond:.3g} of the scaled Jacobian > {tol.cond_max:.3g}; "
                       f"undetermined combination: {combo})")


def _covariance(J, r, k):
    """``s^2 (J^T J)^-1`` with ``s^2 = r.r / (m - k)``; NaN when ``m == k``."""
    m = r.size
    dof = m - k
    if dof <= 0:
        return np.full((k, k), np.nan), dof
    cn = np.linalg.norm(J, axis=0)
    _, sv, Vt = np.linalg.svd(J / cn, full_matrices=False)
    inv = (Vt.T / sv**2) @ Vt
    cov = inv / np.outer(cn, cn) * float(r @ r) / dof
    return 0.5 * (cov + cov.T), dof


def _solve_step(J, r):
    """Least-squares step ``J delta = -r`` via SVD of the column-equilibrated J."""
    cn = np.linalg.norm(J, axis=0)
    cn = np.where(cn > 0, cn, 1.0)
    delta, *_ = np.linalg.lstsq(J / cn, -r, rcond=None)
    return delta / cn


def _gauss_newton(state, resjac, update, X, tol: FitTolerances, kind: str):
    """Minimise ``|r|^2`` from ``state``; ``update(state, delta)`` applies a step."""
    r, J = resjac(state, X)
    cost = float(r @ r)
    if not np.isfinite(cost):
        raise FitError(f"{kind} fit: not enough significant data points: initial guess failed")
    prev = np.inf
    for it in range(tol.max_iter + 1):
        delta = _solve_step(J, r)
        if not np.all(np.isfinite(delta)):
            raise FitError(f"{kind} fit: not enough significant data points: singular step")
        size = float(np.linalg.norm(delta))
        # converged: the full Gauss-Newton step is negligible, or it is small and has
        # stopped shrinking (rounding floor: steps shrink by >= 2 each iteration until
        # then, the rate being ~ residual / radius for metrology data)
        if size < tol.step_tol or (size < np.sqrt(tol.step_tol) and size > 0.5 * prev):
            return state, r, J, it
        prev = size
        lam = 1.0
        # step halving (accept the first step that does not increase the cost), but only
        # for large steps: below sqrt(step_tol) the cost change is second order and
        # drowned by the rounding of the cost itself, so the full step is taken
        for _ in range(30 if size >= np.sqrt(tol.step_tol) else 0):
            new = update(state, lam * delta)
            r_new, J_new = resjac(new, X)
            c_new = float(r_new @ r_new)
            if np.isfinite(c_new) and c_new <= cost * (1 + 1e-12) + 1e-300:
                break
            lam *= 0.5
        else:
            if size >= np.sqrt(tol.step_tol):
                return state, r, J, it  # no descent possible: at the minimum to rounding
            new = update(state, delta)
            r_new, J_new = resjac(new, X)
            c_new = float(r_new @ r_new)
        state, r, J, cost = new, r_new, J_new, c_new
    raise FitError(f"{kind} fit: not enough significant data points: no convergence in "
                   f"{tol.max_iter} iterations")


def _kasa(X):
    """Algebraic circle / sphere ``|x|^2 = 2 c.x + k``: (centre, radius)."""
    A = np.hstack([2.0 * X, np.ones((X.shape[0], 1))])
    b = np.einsum("ij,ij->i", X, X)
    sol, *_ = np.linalg.lstsq(A, b, rcond=None)
    c = sol[:-1]
    R2 = sol[-1] + c @ c
    return c, float(np.sqrt(R2)) if R2 > 0 else 1.0


def _svd_frame(X):
    """Right singular vectors (rows, decreasing variance) and singular values."""
    _, S, Vt = np.linalg.svd(X, full_matrices=False)
    if Vt.shape[0] < X.shape[1]:  # fewer points than dims
        Vt = np.linalg.svd(np.vstack([X, np.zeros((X.shape[1], X.shape[1]))]))[2]
        S = np.concatenate([S, np.zeros(X.shape[1] - S.size)])
    return S, Vt


# --------------------------------------------------------------------------- residual models
# Each ``_rj_*`` returns the stacked orthogonal residual components r (m,)
# and their Jacobian J (m, k) with respect to the minimal local parameters
# named in the result's ``param_names``, for points X in any consistent units.


def _rj_plane(p, B, X):
    w = X - p
    r = w @ B[2]
    J = np.column_stack([-np.ones(len(X)), w @ B[0], w @ B[1]])
    return r, J


def _rj_line(p, B, X):
    w = X - p
    t = w @ B[2]
    ru, rv = w @ B[0], w @ B[1]
    n = len(X)
    z, o = np.zeros(n), np.ones(n)
    J = np.vstack([np.column_stack([-o, z, -t, z]), np.column_stack([z, -o, z, -t])])
    return np.concatenate([ru, rv]), J


def _rj_ball(c, R, X):
    """Circle in the plane (dim 2) or sphere (dim 3)."""
    w = X - c
    rho = np.linalg.norm(w, axis=1)
    e = w / rho[:, None]
    return rho - R, np.column_stack([-e, -np.ones(len(X))])


def _rj_circle3(c, B, R, X):
    w = X - c
    h = w @ B[2]
    wp = w - h[:, None] * B[2]
    rho = np.linalg.norm(wp, axis=1)
    e = wp / rho[:, None]
    eu, ev = e @ B[0], e @ B[1]
    n = len(X)
    z, o = np.zeros(n), np.ones(n)
    Jh = np.column_stack([z, z, -o, w @ B[0], w @ B[1], z])
    Jr = np.column_stack([-eu, -ev, z, -h * eu, -h * ev, -o])
    return np.concatenate([h, rho - R]), np.vstack([Jh, Jr])


def _rj_cylinder(p, B, R, X):
    """SDS model of Viprey et al. 2016 eq. A.5 in the current axis frame."""
    w = X - p
    t = w @ B[2]  # z_i of the paper
    wp = w - t[:, None] * B[2]
    rho = np.linalg.norm(wp, axis=1)  # sqrt(x_i^2 + y_i^2), eq. A.2
    e = wp / rho[:, None]  # n_i = (cos th_i, sin th_i, 0), eq. A.1
    eu, ev = e @ B[0], e @ B[1]
    J = np.column_stack([-eu, -ev, -t * eu, -t * ev, -np.ones(len(X))])
    return rho - R, J


# --------------------------------------------------------------------------- fits


def fit_plane(points, *, normal_hint=None, tol: FitTolerances = TOL) -> PlaneFit:
    """Least-squares plane through ``points`` (exact SVD solution).

    Same minimiser as Viprey et al. 2016, Appendix B (eq. B.4), without the
    cubic's special cases; the normal is the right singular vector of the
    centred points with the smallest singular value.

    Parameters
    ----------
    points : (n, 3) float
        Points, m, n >= 3.
    normal_hint : (3,) float, optional
        Orient the normal so that ``normal . normal_hint >= 0``.
    tol : FitTolerances

    Returns
    -------
    PlaneFit

    Raises
    ------
    FitError
        Wrong shape, non-finite values, fewer than 3 distinct points, or
        collinear points (the normal is not determined).
    """
    P, c0, s, X = _check_points(points, 3, 3, "plane")
    point, n, B = _plane_solve(P, c0, X, normal_hint, tol)
    _, J = _rj_plane(np.zeros(3), B, P - c0)
    r = (P - point) @ n
    cov, dof = _covariance(J, r, 3)
    return PlaneFit(point=point, normal=n, residuals=r, rms=float(np.sqrt(np.mean(r**2))),
                    cov=cov, dof=dof, basis=B)


def _plane_solve(P, c0, X, normal_hint, tol, basis: bool = True):
    """(point, normal, basis) of the plane through ``P`` (centroid ``c0``, scaled ``X``);
    the rank check when ``tol`` is given (None: the caller has checked these points);
    basis None when neither asked for nor needed by the check."""
    _, Vt = _svd_frame(X)
    n = orient(Vt[2], normal_hint)
    B = _perp_basis(n, Vt[0]) if basis or tol is not None else None
    if tol is not None:
        _, J = _rj_plane(np.zeros(3), B, X)
        _check_rank(J, PlaneFit.param_names, "plane", "points are collinear", tol)
    point = c0 + (np.mean(P - c0, axis=0) @ n) * n  # (mean is 0 up to rounding)
    return point, n, B


def plane_point_normal(points, *, normal_hint=None, tol: FitTolerances = TOL,
                       validate: bool = True) -> tuple[np.ndarray, np.ndarray]:
    """``(point, normal)`` of :func:`fit_plane`, bit for bit, without residuals or covariance.

    The light path for callers that refit the same feature many times (the
    finite-difference gain of :func:`core.mfb.poi_noise_gain`).

    Parameters
    ----------
    points : (n, 3) float
        Points, m, n >= 3.
    normal_hint : (3,) float, optional
        As :func:`fit_plane`.
    tol : FitTolerances
    validate : bool
        True: the checks of :func:`fit_plane` (shape, finite, distinct points,
        rank). False: none; only for points known good, e.g. a feature that
        passed :func:`fit_plane` moved by far less than its spread.

    Returns
    -------
    point : (3,) float
        m, as ``fit_plane(...).point``.
    normal : (3,) float
        As ``fit_plane(...).normal``.
    """
    P, c0, _, X = _prepared(points, 3, "plane", validate)
    point, n, _ = _plane_solve(P, c0, X, normal_hint, tol if validate else None, basis=False)
    return point, n


def fit_line(points, *, direction_hint=None, tol: FitTolerances = TOL) -> LineFit:
    """Least-squares line in space (exact SVD solution).

    Parameters
    ----------
    points : (n, 3) float
        Points, m, n >= 2.
    direction_hint : (3,) float, optional
        Orient the direction so that ``direction . direction_hint >= 0``.
    tol : FitTolerances

    Returns
    -------
    LineFit

    Raises
    ------
    FitError
        Wrong shape, non-finite values, coincident points.
    """
    P, c0, s, X = _check_points(points, 3, 2, "line")
    _, Vt = _svd_frame(X)
    d = orient(Vt[0], direction_hint)
    B = _perp_basis(d, Vt[1])
    _, J = _rj_line(np.zeros(3), B, X)
    _check_rank(J, LineFit.param_names, "line", "points are coincident", tol)
    r, J = _rj_line(np.zeros(3), B, P - c0)
    n = len(P)
    uv = np.column_stack([r[:n], r[n:]])
    cov, dof = _covariance(J, r, 4)
    dist = np.hypot(uv[:, 0], uv[:, 1])
    return LineFit(point=c0, direction=d, residuals=dist, residual_uv=uv,
                   rms=float(np.sqrt(np.mean(dist**2))), cov=cov, dof=dof, basis=B)


def _fit_ball(points, dim, kind, tol):
    n_min = dim + 1
    P, c0, s, X = _check_points(points, dim, n_min, kind)
    S, _ = _svd_frame(X)
    if S[dim - 1] <= S[0] / tol.cond_max:
        what = "points are collinear" if dim == 2 else "points are coplanar"
        raise FitError(f"{kind} fit: not enough significant data points: {what}, "
                       f"the radius is not determined")
    c, R = _kasa(X)
    names = Circle2Fit.param_names if dim == 2 else SphereFit.param_names

    def rj(st, Y):
        return _rj_ball(st[:dim], st[dim], Y)

    st, r, J, it = _gauss_newton(np.append(c, R), rj, lambda st, d: st + d, X, tol, kind)
    what = ("the points cover too short an arc (or one side only): the radius is not "
            "determined" if dim == 2 else "the points cover too small a cap: the radius is "
            "not determined")
    _check_rank(J, names, kind, what, tol)
    centre = c0 + s * st[:dim]
    R = s * st[dim]
    r, J = _rj_ball(centre - c0, R, P - c0)
    cov, dof = _covariance(J, r, dim + 1)
    return centre, float(R), r, cov, dof, it


def fit_circle_2d(points, *, tol: FitTolerances = TOL) -> Circle2Fit:
    """Least-squares (geometric) circle in the plane.

    Parameters
    ----------
    points : (n, 2) float
        Points, m, n >= 3.
    tol : FitTolerances

    Returns
    -------
    Circle2Fit

    Raises
    ------
    FitError
        Wrong shape, non-finite values, coincident or collinear points, or an
        arc too short for the radius to be determined.
    """
    centre, R, r, cov, dof, it = _fit_ball(points, 2, "circle", tol)
    return Circle2Fit(centre=centre, radius=R, residuals=r, rms=float(np.sqrt(np.mean(r**2))),
                      cov=cov, dof=dof, iterations=it)


def fit_sphere(points, *, tol: FitTolerances = TOL) -> SphereFit:
    """Least-squares (geometric) sphere.

    Parameters
    ----------
    points : (n, 3) float
        Points, m, n >= 4.
    tol : FitTolerances

    Returns
    -------
    SphereFit

    Raises
    ------
    FitError
        Wrong shape, non-finite values, coincident or coplanar points, or a
        cap too small for the radius to be determined.
    """
    centre, R, r, cov, dof, it = _fit_ball(points, 3, "sphere", tol)
    return SphereFit(centre=centre, radius=R, residuals=r, rms=float(np.sqrt(np.mean(r**2))),
                     cov=cov, dof=dof, iterations=it)


def fit_circle_3d(points, *, normal_hint=None, tol: FitTolerances = TOL) -> Circle3Fit:
    """Least-squares circle in space: minimises ``sum h_i^2 + (rho_i - R)^2``.

    ``h_i`` is the height of point i above the circle's plane and ``rho_i``
    its distance from the centre within the plane, so ``sqrt(h^2 +
    (rho - R)^2)`` is the orthogonal distance to the circle curve.

    Parameters
    ----------
    points : (n, 3) float
        Points, m, n >= 3.
    normal_hint : (3,) float, optional
        Orient the normal so that ``normal . normal_hint >= 0``.
    tol : FitTolerances

    Returns
    -------
    Circle3Fit

    Raises
    ------
    FitError
        Wrong shape, non-finite values, coincident or collinear points, or an
        arc too short for the radius to be determined.
    """
    kind = "circle3d"
    P, c0, s, X = _check_points(points, 3, 3, kind)
    S, Vt = _svd_frame(X)
    if S[1] <= S[0] / tol.cond_max:
        raise FitError(f"{kind} fit: not enough significant data points: points are collinear, "
                       f"the radius is not determined")
    B0 = np.stack([Vt[0], Vt[1], orient(Vt[2], normal_hint)])
    B0[1] = np.cross(B0[2], B0[0])
    c2, R = _kasa(np.column_stack([X @ B0[0], X @ B0[1]]))
    state0 = (c2[0] * B0[0] + c2[1] * B0[1], B0, R)

    def rj(st, Y):
        return _rj_circle3(st[0], st[1], st[2], Y)

    def upd(st, d):
        c, B, R = st
        n = B[2] + d[3] * B[0] + d[4] * B[1]
        n = n / np.linalg.norm(n)
        return (c + d[0] * B[0] + d[1] * B[1] + d[2] * B[2], _perp_basis(n, B[0]), R + d[5])

    (c, B, R), r, J, it = _gauss_newton(state0, rj, upd, X, tol, kind)
    _check_rank(J, Circle3Fit.param_names, kind,
                "the points cover too short an arc: the radius is not determined", tol)
    n = orient(B[2], normal_hint)
    B = _perp_basis(n, B[0])
    centre = c0 + s * c
    R = s * R
    r, J = _rj_circle3(centre - c0, B, R, P - c0)
    m = len(P)
    hr = np.column_stack([r[:m], r[m:]])
    cov, dof = _covariance(J, r, 6)
    dist = np.hypot(hr[:, 0], hr[:, 1])
    return Circle3Fit(centre=centre, normal=n, radius=float(R), residuals=dist, residual_hr=hr,
                      rms=float(np.sqrt(np.mean(dist**2))), cov=cov, dof=dof, basis=B,
                      iterations=it)


def _cylinder_axis_candidates(X, Vt, n_keep: int = 4, n_grid: int = 600):
    """Initial axis directions for a cylinder through centred, scaled ``X``.

    Candidates: the three principal directions of the points, the axis of an
    algebraic quadric fit (the eigenvector of its quadratic form nearest
    zero; needs n >= 9), and an ``n_grid``-direction Fibonacci grid on the
    hemisphere (spacing ~ 4 degrees for 600). Each is scored, all at once,
    by the RSS of the algebraic circle fitted to the points projected along
    it; the ``n_keep`` best directions at least ~11 degrees apart are
    returned, best first.
    """
    cands = [Vt[0], Vt[1], Vt[2]]
    if len(X) >= 9:
        x, y, z = X.T
        D = np.column_stack([x * x, y * y, z * z, x * y, x * z, y * z, x, y, z, np.ones(len(X))])
        q = np.linalg.svd(D)[2][-1]
        A = np.array([[q[0], q[3] / 2, q[4] / 2], [q[3] / 2, q[1], q[5] / 2], [q[4] / 2, q[5] / 2, q[2]]])
        w, V = np.linalg.eigh(A)
        cands.append(V[:, int(np.argmin(np.abs(w)))])
    k = np.arange(n_grid) + 0.5
    zc = 1.0 - k / n_grid  # hemisphere z in (0, 1)
    phi = k * np.pi * (3.0 - np.sqrt(5.0))
    rc = np.sqrt(1.0 - zc**2)
    C = np.vstack([np.array(cands), np.column_stack([rc * np.cos(phi), rc * np.sin(phi), zc])])
    # perpendicular bases for all candidates at once
    ref = np.where((np.abs(C[:, 0]) < 0.9)[:, None], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0])
    U = ref - np.einsum("ij,ij->i", ref, C)[:, None] * C
    U /= np.linalg.norm(U, axis=1)[:, None]
    V2 = np.cross(C, U)
    Y = np.stack([X @ U.T, X @ V2.T], axis=2).transpose(1, 0, 2)  # (m, n, 2)
    A = np.concatenate([2.0 * Y, np.ones(Y.shape[:2] + (1,))], axis=2)
    bq = np.einsum("mij,mij->mi", Y, Y)
    sol = np.einsum("mij,mj->mi", np.linalg.pinv(A), bq)
    res = np.einsum("mij,mj->mi", A, sol) - bq
    scores = np.einsum("mi,mi->m", res, res)
    keep = []
    for i in np.argsort(scores, kind="stable"):
        if all(abs(C[i] @ C[j]) < 0.98 for j in keep):
            keep.append(i)
        if len(keep) == n_keep:
            break
    return [C[i] for i in keep]


def fit_cylinder(points, *, axis_hint=None, tol: FitTolerances = TOL) -> CylinderFit:
    """Least-squares cylinder by iterated SDS linearisation (Viprey 2016, App. A).

    Each iteration expresses the points in the frame of the current axis
    (eqs. A.1-A.3), solves the linear least-squares problem of eq. A.5 for
    the screw ``(alpha, beta, u, v, r)`` (eqs. A.6-A.8, by SVD of the design
    matrix) and displaces the axis by it, until the screw is below
    ``tol.step_tol`` (feature-scaled units, rad).

    Parameters
    ----------
    points : (n, 3) float
        Points, m, n >= 5.
    axis_hint : (3,) float, optional
        Approximate axis direction. Used as the only initial axis (instead of
        the scored candidates) and to orient
        the result: ``axis . axis_hint >= 0``.
    tol : FitTolerances

    Returns
    -------
    CylinderFit

    Raises
    ------
    FitError
        Wrong shape, non-finite values, coincident or collinear points, all
        points in one section (axis tilt not determined), an arc too short
        for the radius to be determined, rival cylinders with different axes
        fitting about equally well (e.g. the MFB hole pattern of Viprey 2016
        sec. 2.1 with the same four angles on both levels: the 8 points are
        the corners of a cuboid, which lie exactly on three cylinders) when
        no ``axis_hint`` is given, or no convergence.
    """
    P, c0, s, X = _check_points(points, 3, 5, "cylinder")
    point, a, B, R, it = _cylinder_solve(P, c0, s, X, axis_hint, tol, validate=True)
    r, J = _rj_cylinder(point - c0, B, R, P - c0)
    cov, dof = _covariance(J, r, 5)
    return CylinderFit(point=point, axis=a, radius=float(R), residuals=r,
                       rms=float(np.sqrt(np.mean(r**2))), cov=cov, dof=dof, basis=B,
                       iterations=it)


def _cylinder_solve(P, c0, s, X, axis_hint, tol: FitTolerances, validate: bool):
    """(point, axis, basis, radius, iterations) of the cylinder through ``P`` (centroid
    ``c0``, scale ``s``, scaled ``X``). ``validate`` False (only with ``axis_hint``):
    no collinearity, hint or rank check; the caller has checked these points."""
    kind = "cylinder"
    if validate or axis_hint is None:
        S, Vt = _svd_frame(X)
        if S[1] <= S[0] / tol.cond_max:
            raise FitError(f"{kind} fit: not enough significant data points: points are collinear, "
                           f"the radius is not determined")
    if axis_hint is not None:
        h = np.asarray(axis_hint, dtype=float)
        if validate and (h.shape != (3,) or not np.all(np.isfinite(h)) or not np.linalg.norm(h) > 0):
            raise FitError(f"cylinder fit: axis_hint must be a finite non-zero (3,) vector, got {h!r}")
        candidates = [h / np.linalg.norm(h)]
    else:
        candidates = _cylinder_axis_candidates(X, Vt)

    def rj(st, Y):
        return _rj_cylinder(st[0], st[1], st[2], Y)

    def upd(st, d):
        p, B, R = st
        a = B[2] + d[2] * B[0] + d[3] * B[1]
        a = a / np.linalg.norm(a)
        p = p + d[0] * B[0] + d[1] * B[1]
        p = p - (p @ a) * a  # axis point nearest the centroid (origin)
        return (p, _perp_basis(a, B[0]), R + d[4])

    best, errors, rivals = None, [], []
    for a0 in candidates:
        B0 = _perp_basis(a0)
        c2, R0 = _kasa(np.column_stack([X @ B0[0], X @ B0[1]]))
        st0 = (c2[0] * B0[0] + c2[1] * B0[1], B0, R0)
        try:
            st, r, J, it = _gauss_newton(st0, rj, upd, X, tol, kind)
        except FitError as e:
            errors.append(str(e))
            continue
        cost = float(r @ r)
        rivals.append((cost, st, J, it))
        if best is None or cost < best[0]:
            best = (cost, st, J, it)
    if best is None:
        raise FitError(errors[0])
    _, (p, B, R), J, it = best
    floor = len(X) * 1e-18  # RSS of 1e-9 RMS in scaled units: rounding level
    for cost, (_, B2, _), _, _ in rivals if len(rivals) > 1 else ():
        if (np.linalg.norm(np.cross(B2[2], B[2])) > tol.rival_angle
                and cost <= tol.rival_rms_ratio**2 * best[0] + floor):
            raise FitError(
                f"cylinder fit: not enough significant data points: the points lie about equally "
                f"well on cylinders with different axes (rms {np.sqrt(best[0] / len(X)) * s:.3g} m "
                f"about {np.round(orient(B[2]), 4).tolist()}, {np.sqrt(cost / len(X)) * s:.3g} m "
                f"about {np.round(orient(B2[2]), 4).tolist()}); pass axis_hint")
    if validate:
        _check_rank(J, CylinderFit.param_names, kind,
                    "the points do not determine the axis and radius (one section, or one side "
                    "of the cylinder only)", tol)
    a = orient(B[2], axis_hint)
    B = _perp_basis(a, B[0])
    return c0 + s * p, a, B, s * R, it


def cylinder_point_axis(points, *, axis_hint, tol: FitTolerances = TOL,
                        validate: bool = True) -> tuple[np.ndarray, np.ndarray]:
    """``(point, axis)`` of :func:`fit_cylinder` with ``axis_hint``, bit for bit, without
    residuals or covariance.

    The light path for callers that refit the same feature many times (the
    finite-difference gain of :func:`core.mfb.poi_noise_gain`).

    Parameters
    ----------
    points : (n, 3) float
        Points, m, n >= 5.
    axis_hint : (3,) float
        Approximate axis (the only initial axis, and the sign of the result).
    tol : FitTolerances
    validate : bool
        True: the checks of :func:`fit_cylinder`. False: none (shape, finite
        values, distinct points, collinearity, rank); only for points known
        good, e.g. a feature that passed :func:`fit_cylinder` moved by far less
        than its spread. Non-convergence still raises :class:`FitError`.

    Returns
    -------
    point : (3,) float
        m, as ``fit_cylinder(...).point``.
    axis : (3,) float
        As ``fit_cylinder(...).axis``.
    """
    P, c0, s, X = _prepared(points, 5, "cylinder", validate)
    point, a, _, _, _ = _cylinder_solve(P, c0, s, X, axis_hint, tol, validate)
    return point, a


# --------------------------------------------------------------------------- batches


def _check_batch(points, kind: str, n_min: int):
    """Validate (b, n, 3) points; return (P, c0 (b, 1, 3), s (b,), D, X)."""
    try:
        P = np.asarray(points, dtype=float)
    except (TypeError, ValueError) as e:
        raise FitError(f"{kind} fit: points must be a numeric (b, n, 3) array ({e})") from None
    if P.ndim != 3 or P.shape[2] != 3:
        raise FitError(f"{kind} fit: points must be (b, n, 3), got {P.shape}")
    if P.shape[1] < n_min:
        raise FitError(f"{kind} fit: not enough data points: needs at least {n_min}, got {P.shape[1]}")
    bad = ~np.isfinite(P).all(axis=2)
    if bad.any():
        i, j = np.argwhere(bad)[0]
        raise FitError(f"{kind} fit: points contain non-finite values (set {i}, row {j})")
    c0 = P.mean(axis=1, keepdims=True)
    D = P - c0
    s = np.sqrt(np.mean(np.einsum("bij,bij->bi", D, D), axis=1))
    if np.any(s == 0.0):
        raise FitError(f"{kind} fit: not enough significant data points: all points are "
                       f"coincident (set {int(np.argmin(s))})")
    return P, c0, s, D, D / s[:, None, None]


def _batch_rank_and_cov(Js, Jm, r, k, kind, what, tol):
    """Rank check on the scaled Jacobians Js (b, m, k); covariances from Jm (metres)."""
    sv = np.linalg.svd(Js, compute_uv=False)
    with np.errstate(divide="ignore"):
        cond = np.where(sv[:, -1] > 0, sv[:, 0] / sv[:, -1], np.inf)
    if not np.all(cond <= tol.cond_max):
        i = int(np.argmax(~(cond <= tol.cond_max)))
        raise FitError(f"{kind} fit: not enough significant data points: {what} (set {i}, "
                       f"condition number {cond[i]:.3g} of the scaled Jacobian > {tol.cond_max:.3g})")
    dof = r.shape[1] - k
    if dof <= 0:
        return np.full((len(r), k, k), np.nan), dof
    _, svm, Vt = np.linalg.svd(Jm, full_matrices=False)
    inv = np.einsum("bji,bj,bjl->bil", Vt, 1.0 / svm**2, Vt)
    s2 = np.einsum("bi,bi->b", r, r) / dof
    return inv * s2[:, None, None], dof


def _orient_batch(d, hint):
    ref = REFERENCE_DIRECTION if hint is None else np.asarray(hint, dtype=float)
    return np.where((d @ ref < 0)[:, None], -d, d)


def fit_planes(points, *, normal_hint=None, tol: FitTolerances = TOL) -> PlaneFit:
    """Least-squares planes for a batch of point sets (same method as :func:`fit_plane`).

    Parameters
    ----------
    points : (b, n, 3) float
        b sets of n points each, m, n >= 3.
    normal_hint : (3,) float, optional
        Orient every normal so that ``normal . normal_hint >= 0``.
    tol : FitTolerances

    Returns
    -------
    PlaneFit
        Every array field gets a leading axis b: ``point (b, 3)``, ``normal
        (b, 3)``, ``residuals (b, n)``, ``rms (b,)``, ``cov (b, 3, 3)``,
        ``basis (b, 3, 3)``; ``dof`` is the common ``n - 3``.

    Raises
    ------
    FitError
        As :func:`fit_plane`, naming the first offending set.
    """
    P, c0, s, D, X = _check_batch(points, "plane", 3)
    _, _, Vt = np.linalg.svd(X, full_matrices=False)
    nrm = _orient_batch(Vt[:, 2], normal_hint)
    u = Vt[:, 0]
    B = np.stack([u, np.cross(nrm, u), nrm], axis=1)
    b, n, _ = P.shape

    def jac(Y):
        return np.concatenate([-np.ones((b, n, 1)), np.einsum("bij,bkj->bik", Y, B[:, :2])], axis=2)

    r = np.einsum("bij,bj->bi", D, nrm)
    cov, dof = _batch_rank_and_cov(jac(X), jac(D), r, 3, "plane", "points are collinear", tol)
    point = c0[:, 0] + np.mean(r, axis=1)[:, None] * nrm
    r = np.einsum("bij,bj->bi", P - point[:, None], nrm)
    return PlaneFit(point=point, normal=nrm, residuals=r, rms=np.sqrt(np.mean(r**2, axis=1)),
                    cov=cov, dof=dof, basis=B)


def fit_lines(points, *, direction_hint=None, tol: FitTolerances = TOL) -> LineFit:
    """Least-squares lines for a batch of point sets (same method as :func:`fit_line`).

    Parameters
    ----------
    points : (b, n, 3) float
        b sets of n points each, m, n >= 2.
    direction_hint : (3,) float, optional
    tol : FitTolerances

    Returns
    -------
    LineFit
        Array fields with a leading axis b: ``point (b, 3)``, ``direction
        (b, 3)``, ``residuals (b, n)``, ``residual_uv (b, n, 2)``, ``rms
        (b,)``, ``cov (b, 4, 4)``, ``basis (b, 3, 3)``; ``dof = 2 n - 4``.

    Raises
    ------
    FitError
        As :func:`fit_line`, naming the first offending set.
    """
    P, c0, s, D, X = _check_batch(points, "line", 2)
    b, n, _ = P.shape
    if n < 3:  # pad so that the SVD returns a full 3x3 frame
        _, _, Vt = np.linalg.svd(np.concatenate([X, np.zeros((b, 3 - n, 3))], axis=1))
    else:
        _, _, Vt = np.linalg.svd(X, full_matrices=False)
    d = _orient_batch(Vt[:, 0], direction_hint)
    u = Vt[:, 1]
    B = np.stack([u, np.cross(d, u), d], axis=1)

    def jac(Y):
        t = np.einsum("bij,bj->bi", Y, d)
        z, o = np.zeros((b, n)), np.ones((b, n))
        Ju = np.stack([-o, z, -t, z], axis=2)
        Jv = np.stack([z, -o, z, -t], axis=2)
        return np.concatenate([Ju, Jv], axis=1)

    uv = np.einsum("bij,bkj->bik", D, B[:, :2])
    r = np.concatenate([uv[:, :, 0], uv[:, :, 1]], axis=1)
    cov, dof = _batch_rank_and_cov(jac(X), jac(D), r, 4, "line", "points are coincident", tol)
    dist = np.hypot(uv[:, :, 0], uv[:, :, 1])
    return LineFit(point=c0[:, 0], direction=d, residuals=dist, residual_uv=uv,
                   rms=np.sqrt(np.mean(dist**2, axis=1)), cov=cov, dof=dof, basis=B)


# --------------------------------------------------------------------------- U95 and form


def planes_point_normal(points, *, normal_hint=None) -> tuple[np.ndarray, np.ndarray]:
    """:func:`plane_point_normal` (``validate=False``) of each set of a batch, in one call.

    Parameters
    ----------
    points : (b, n, 3) float
        b sets of n >= 3 points, m, each known good (no checks: see
        :func:`plane_point_normal`).
    normal_hint : (3,) float, optional

    Returns
    -------
    point : (b, 3) float
        m.
    normal : (b, 3) float
        Unit normals, oriented by ``normal_hint`` (or :func:`orient`).
    """
    P = points
    c0 = P.mean(axis=1)
    D = P - c0[:, None]
    s = np.sqrt(np.mean(np.einsum("bij,bij->bi", D, D), axis=1))
    _, _, Vt = np.linalg.svd(D / s[:, None, None], full_matrices=False)
    n = _orient_batch(Vt[:, 2], normal_hint)
    point = c0 + np.einsum("bj,bj->b", D.mean(axis=1), n)[:, None] * n
    return point, n


def _perp_basis_batch(d, u_prev):
    """Rows (u, v, d) per item, u the part of ``u_prev`` (b, 3) normal to ``d`` (b, 3);
    None when some ``u_prev`` is nearly along its ``d`` (the caller falls back)."""
    u = u_prev - np.einsum("bj,bj->b", u_prev, d)[:, None] * d
    nu = np.linalg.norm(u, axis=1)
    if np.any(nu < 1e-6):
        return None
    u = u / nu[:, None]
    return np.stack([u, np.cross(d, u), d], axis=1)


def cylinders_point_axis(points, *, axis_hint, tol: FitTolerances = TOL) -> tuple[np.ndarray, np.ndarray]:
    """:func:`cylinder_point_axis` (``validate=False``) of each set of a batch, in one call.

    The same iteration as :func:`fit_cylinder` from ``axis_hint`` (iterated
    SDS, Viprey 2016 App. A; the same start, steps and stopping rule per set),
    run on the whole batch at once; a set whose step must be halved, or that
    has not converged in ``tol.max_iter`` iterations, is refitted alone by
    :func:`cylinder_point_axis`. Agrees with the one-set path to rounding
    (batched rather than single linear algebra), not bit for bit.

    Parameters
    ----------
    points : (b, n, 3) float
        b sets of n >= 5 points, m, each known good (no checks).
    axis_hint : (3,) float
        The initial axis of every set, and the sign of the results.
    tol : FitTolerances

    Returns
    -------
    point : (b, 3) float
        Axis point nearest each set's centroid, m.
    axis : (b, 3) float
        Unit axes.
    """
    Q = points
    b, m, _ = Q.shape
    c0 = Q.mean(axis=1)
    D = Q - c0[:, None]
    s = np.sqrt(np.mean(np.einsum("bij,bij->bi", D, D), axis=1))
    X = D / s[:, None, None]
    h = np.asarray(axis_hint, dtype=float)
    B0 = _perp_basis(h / np.linalg.norm(h))
    # start: the algebraic circle of the points projected along the hint (_kasa)
    Y = np.stack([X @ B0[0], X @ B0[1]], axis=2)
    A = np.concatenate([2.0 * Y, np.ones((b, m, 1))], axis=2)
    sol = np.einsum("bij,bj->bi", np.linalg.pinv(A), np.einsum("bij,bij->bi", Y, Y))
    R2 = sol[:, 2] + np.einsum("bi,bi->b", sol[:, :2], sol[:, :2])
    R = np.where(R2 > 0, np.sqrt(np.abs(R2)), 1.0)
    p = sol[:, :1] * B0[0] + sol[:, 1:2] * B0[1]
    B = np.broadcast_to(B0, (b, 3, 3)).copy()

    def resjac(p, B, R):
        w = X - p[:, None]
        t = np.einsum("bij,bj->bi", w, B[:, 2])
        wp = w - t[:, :, None] * B[:, None, 2]
        rho = np.linalg.norm(wp, axis=2)
        e = wp / rho[:, :, None]
        eu, ev = np.einsum("bij,bj->bi", e, B[:, 0]), np.einsum("bij,bj->bi", e, B[:, 1])
        J = np.stack([-eu, -ev, -t * eu, -t * ev, -np.ones_like(t)], axis=2)
        return rho - R[:, None], J

    r, J = resjac(p, B, R)
    cost = np.einsum("bi,bi->b", r, r)
    prev = np.full(b, np.inf)
    active = np.ones(b, bool)
    alone = ~np.isfinite(cost)  # refitted one by one (cylinder_point_axis)
    active &= ~alone
    sq = np.sqrt(tol.step_tol)
    for _ in range(tol.max_iter + 1):
        if not active.any():
            break
        cn = np.linalg.norm(J, axis=1)
        cn = np.where(cn > 0, cn, 1.0)
        U, S, Vt = np.linalg.svd(J / cn[:, None], full_matrices=False)
        delta = -np.einsum("bji,bj->bi", Vt, np.einsum("bij,bi->bj", U, r) / S) / cn
        size = np.linalg.norm(delta, axis=1)
        bad = active & ~np.all(np.isfinite(delta), axis=1)
        alone |= bad
        active &= ~bad
        done = active & ((size < tol.step_tol) | ((size < sq) & (size > 0.5 * prev)))
        active &= ~done
        prev = size
        a = B[:, 2] + delta[:, 2:3] * B[:, 0] + delta[:, 3:4] * B[:, 1]
        a = a / np.linalg.norm(a, axis=1)[:, None]
        p_new = p + delta[:, :1] * B[:, 0] + delta[:, 1:2] * B[:, 1]
        p_new = p_new - np.einsum("bj,bj->b", p_new, a)[:, None] * a
        B_new = _perp_basis_batch(a, B[:, 0])
        if B_new is None:
            B_new = B
            alone |= active
            active[:] = False
        R_new = R + delta[:, 4]
        r_new, J_new = resjac(p_new, B_new, R_new)
        c_new = np.einsum("bi,bi->b", r_new, r_new)
        # a large step that does not descend would be halved: that set goes alone
        halve = active & (size >= sq) & ~(np.isfinite(c_new) & (c_new <= cost * (1 + 1e-12) + 1e-300))
        alone |= halve
        active &= ~halve
        k = active
        p[k], B[k], R[k], r[k], J[k], cost[k] = p_new[k], B_new[k], R_new[k], r_new[k], J_new[k], c_new[k]
    alone |= active  # no convergence: the one-set path says so
    axis = _orient_batch(B[:, 2], h)
    point = c0 + s[:, None] * p
    for i in np.flatnonzero(alone):
        point[i], axis[i] = cylinder_point_axis(Q[i], axis_hint=h, tol=tol, validate=False)
    return point, axis


def coverage_factor(dof: int, p: float = 0.95) -> float:
    """Two-sided coverage factor for ``dof`` degrees of freedom (JCGM 100 G.3: Student's t).

    The covariance of a fit scales with ``s**2 = sum(r**2) / dof`` estimated
    from the same residuals, so its expanded uncertainty takes Student's
    ``t_{(1+p)/2, dof}`` (2.57 at 5 dof, 2.04 at 30, 1.96 at infinity), not 2.
    NaN when ``dof < 1``.
    """
    # scipy.special's inverse of Student's t CDF: scipy.stats.t.ppf's value (it calls the same function; equal in
    # every double for dof 1..2000, 1e4, 1e6, 1e9 at p 0.5, 0.6827, 0.95, 0.99), without importing scipy.stats
    # (0.5 s of `vmt fit`'s 0.7 s of CPU on a 5,000-row log)
    from scipy.special import stdtrit

    return float(stdtrit(dof, 0.5 + p / 2.0)) if dof >= 1 else float("nan")


def u95(fit) -> dict:
    """Expanded uncertainty (95 %) of each parameter of a fit, ``{param_name: U95}``.

    ``U95 = t_{0.975, dof} * sqrt(diag(cov))`` in the parameter's unit (m or
    rad). It covers the scatter of the points about the feature (probing
    noise and form alike, treated as random): a systematic machine error
    common to every point is not in it.
    """
    k = coverage_factor(fit.dof)
    sd = np.sqrt(np.clip(np.diag(fit.cov), 0.0, None))
    return {name: float(k * s) for name, s in zip(fit.param_names, sd)}


#: Coverage factor of :func:`rounding_u95`: the normal distribution's 95 % factor. The rounding bound is Type B
#: (known, not estimated from the residuals: no Student t); the parameter's rounding error is a sum of rectangular
#: terms, whose 95 % point lies at or below 1.96 standard deviations (1.645 for one term, 1.90 for two equal ones,
#: 1.96 in the limit), so 1.96 covers it (one term: 0.566 q against its largest error 0.5 q).
ROUNDING_K = 1.959963984540054


def _rounding_gain(fit, P):
    """The gain ``(k, n, d)`` of each fitted parameter to each coordinate of each point (``d(param) / d(p_ic)``
    to first order), from the fit's own Jacobian at its solution: ``-(J^T J)^-1 J^T D``, ``D`` the gradient of
    each residual row with respect to its point (the feature's unit normal there)."""
    n = len(P)
    if isinstance(fit, PlaneFit):
        c0 = P.mean(axis=0)
        _, J = _rj_plane(np.zeros(3), fit.basis, P - c0)
        D, who = np.broadcast_to(fit.normal, (n, 3)), np.arange(n)
    elif isinstance(fit, LineFit):
        _, J = _rj_line(np.zeros(3), fit.basis, P - fit.point)
        D = np.vstack([np.broadcast_to(fit.basis[0], (n, 3)), np.broadcast_to(fit.basis[1], (n, 3))])
        who = np.concatenate([np.arange(n), np.arange(n)])
    elif isinstance(fit, (Circle2Fit, SphereFit)):
        _, J = _rj_ball(fit.centre, fit.radius, P)
        D, who = -J[:, :-1], np.arange(n)
    elif isinstance(fit, Circle3Fit):
        _, J = _rj_circle3(fit.centre, fit.basis, fit.radius, P)
        w = P - fit.centre
        wp = w - np.outer(w @ fit.basis[2], fit.basis[2])
        D = np.vstack([np.broadcast_to(fit.basis[2], (n, 3)), wp / np.linalg.norm(wp, axis=1)[:, None]])
        who = np.concatenate([np.arange(n), np.arange(n)])
    elif isinstance(fit, CylinderFit):
        _, J = _rj_cylinder(fit.point, fit.basis, fit.radius, P)
        w = P - fit.point
        wp = w - np.outer(w @ fit.axis, fit.axis)
        D, who = wp / np.linalg.norm(wp, axis=1)[:, None], np.arange(n)
    else:
        raise FitError(f"{type(fit).__name__}: no rounding bound for this kind of fit")
    G = -np.linalg.pinv(J)                                   # (k, m): d(param) / d(residual row)
    gain = np.zeros((J.shape[1], n, P.shape[1]))
    np.add.at(gain, (slice(None), who), G[:, :, None] * D[None])   # rows of one point summed
    return gain


def rounding_u95(fit, points, step) -> dict:
    """U95 of each parameter of a fit from its points' printing step, ``{param_name: U95}`` (m or rad).

    Each coordinate ``c`` of each point carries its rounding, rectangular of half-width ``step_c / 2``
    (:func:`core.probelog.rounding_sd`: ``step_c / sqrt(12)``). The rounding errors of different points are not
    independent: a wall whose touches share one printed X shares its rounding (every touch 0.4 um off when the
    wall lies at 48.0004 mm and the log prints 48.000), and no number of touches averages it out; nor is that
    seen in the residuals (they are zero). The bound holds whatever their correlation: the standard deviation of
    a sum is at most the sum of the terms' standard deviations, so a parameter with gain ``g_ic`` to coordinate
    ``c`` of point ``i`` (:func:`_rounding_gain`, first order) has ``u <= sqrt(sum_c (sum_i |g_ic| u_c)^2)``,
    the coordinates' steps independent of each other. It is reached where each coordinate's errors move
    together (an axis-aligned wall's offset: ``u = step / sqrt(12)``); it is pessimistic by up to ``sqrt(n)``
    where they are independent (a plane at a general tilt, noise of a step or more dithering the rounding), where
    the residual scatter's Student-t U95 (:func:`u95`) already holds them and is the larger anyway when the
    noise is a step or more. ``U95 = ROUNDING_K u``.

    Parameters
    ----------
    fit : PlaneFit, LineFit, Circle2Fit, Circle3Fit, SphereFit or CylinderFit
        A fit of ``points``.
    points : (n, d) float
        The points fitted, m.
    step : float or (d,) float
        The step each coordinate was printed to, m (0: exact).

    Returns
    -------
    dict
        ``{param_name: U95}`` in the parameter's unit; 0 for every parameter at step 0.
    """
    from .probelog import rounding_sd

    P = np.asarray(points, dtype=float)
    u_c = rounding_sd(np.broadcast_to(np.asarray(step, dtype=float), (P.shape[1],)))
    if not np.all(np.isfinite(u_c) & (u_c >= 0)):
        raise FitError(f"rounding bound: the printing step must be finite and >= 0, got {step!r}")
    if not np.any(u_c > 0):
        return {name: 0.0 for name in fit.param_names}
    a = np.sum(np.abs(_rounding_gain(fit, P)), axis=1) * u_c      # (k, d): each coordinate's worst sum
    u = np.sqrt(np.sum(a**2, axis=1))
    return {name: float(ROUNDING_K * v) for name, v in zip(fit.param_names, u)}


def form_deviation(fit) -> float:
    """Form deviation of the points about the least-squares feature, m.

    Peak-to-valley of the signed orthogonal residuals, ``max(r) - min(r)``:
    flatness for a plane, sphericity, roundness (circle), cylindricity,
    each referred to the least-squares feature (ISO 12781 / 12181 / 12180
    "LS" reference; the minimum-zone value is never larger). It includes the
    probing noise: with noise ``sigma`` and ``n`` points it is about
    ``d2(n) * sigma`` (3.1 sigma at 12 points) even on a perfect part.

    Raises
    ------
    FitError
        A fit whose residuals are unsigned distances (line, circle in space).
    """
    if isinstance(fit, (LineFit, Circle3Fit)):
        raise FitError(f"{type(fit).__name__}: residuals are distances, not signed: no form deviation")
    r = np.asarray(fit.residuals, dtype=float)
    return float(r.max() - r.min())
