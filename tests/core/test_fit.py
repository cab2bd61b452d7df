"""core.fit and core.refdata: known answers, reference sets, round trips, bad input.

Tolerances
----------
Reference sets (1 nm, 1 nrad): the sets' least-squares answer is exact by
construction; the only errors left are rounding of the points (coordinates
up to ~1.7 m carry 2.2e-16 m per ulp), amplified by the conditioning of the
fit (condition numbers of the scaled Jacobians here are < 1e3) and the
Gauss-Newton stopping rule (full step < 1e-12 of the feature size, or at
the rounding floor). Over 6 x 2000 sets the worst seen was 7e-14 m and
1e-12 rad, so 1 nm / 1 nrad leave three orders of magnitude for other
platforms' BLAS while still catching any real algorithmic fault (a Kasa
circle on a 90 degree arc is off by ~0.1 µm; skspatial's cylinder by mm on
some sets; an iteration stopped early by ~1e-10).
"""

from __future__ import annotations

from functools import partial

import numpy as np
import pytest
from scipy.optimize import least_squares

from core import fit, refdata
from core.exceptions import FitError

FIT = {"plane": fit.fit_plane, "line": fit.fit_line, "circle2d": fit.fit_circle_2d,
       "circle3d": fit.fit_circle_3d, "sphere": fit.fit_sphere, "cylinder": fit.fit_cylinder}

N_SETS = 200  # per kind: hundreds of sets, ~3 s in total


def _position(f):
    return f.centre if hasattr(f, "centre") else f.point


def _direction(f):
    for name in ("normal", "direction", "axis"):
        if hasattr(f, name):
            return getattr(f, name)
    return None


# --------------------------------------------------------------------------- reference sets


@pytest.mark.parametrize("kind", refdata.KINDS)
def test_reference_sets_reproduce_known_answer(kind):
    rng = np.random.default_rng(100 + refdata.KINDS.index(kind))
    sets = refdata.make_refsets(kind, N_SETS, rng)
    dp = dd = dr = dres = 0.0
    for s in sets:
        f = FIT[kind](s.points)
        dp = max(dp, float(np.linalg.norm(_position(f) - s.position)))
        d = _direction(f)
        if d is not None:
            # |d - d_true| is the angle for small angles (and 2 for a sign flip)
            dd = max(dd, float(np.linalg.norm(d - s.direction)))
        if hasattr(f, "radius"):
            dr = max(dr, abs(f.radius - s.radius))
        dres = max(dres, float(np.max(np.abs(f.residuals - s.residuals))))
    assert dp < 1e-9, f"position off by {dp:.3g} m"
    assert dd < 1e-9, f"direction off by {dd:.3g} rad"
    assert dr < 1e-9, f"radius off by {dr:.3g} m"
    assert dres < 1e-9, f"residuals off by {dres:.3g} m"


@pytest.mark.parametrize("kind", refdata.KINDS)
def test_reference_sets_are_stationary_and_awkward(kind):
    """The sets really are what they claim: offsets to ~1 m, µm residuals, partial arcs."""
    rng = np.random.default_rng(7)
    sets = refdata.make_refsets(kind, 60, rng)
    offs = [np.max(np.abs(s.position)) for s in sets]
    assert max(offs) > 0.8  # positions far from the origin
    rms = [np.sqrt(np.mean(s.residuals**2)) for s in sets]
    assert 0.9e-6 < min(rms) and max(rms) < 5.1e-6
    if kind in ("circle2d", "circle3d", "cylinder"):
        arcs = np.degrees([s.arc_rad for s in sets])
        part = arcs[arcs < 360]
        assert len(part) > 10 and part.min() >= 90 and part.max() <= 120


def test_null_space_residuals_are_orthogonal(rng):
    J = rng.normal(size=(30, 5))
    e = refdata.null_space_residuals(J, rng.normal(size=30))
    assert np.max(np.abs(J.T @ e)) < 1e-13 * np.linalg.norm(J) * np.linalg.norm(e)


@pytest.mark.parametrize("kind, single, batch, dname", [
    ("plane", fit.fit_plane, fit.fit_planes, "normal"),
    ("line", fit.fit_line, fit.fit_lines, "direction"),
])
def test_batched_fits_equal_single_fits(kind, single, batch, dname):
    rng = np.random.default_rng(31)
    sets = refdata.make_refsets(kind, 50, rng, n=12)
    fb = batch(np.stack([s.points for s in sets]))
    for i, s in enumerate(sets):
        f = single(s.points)
        # 1e-12: same SVD method, batch vs single LAPACK calls differ only by rounding
        assert np.linalg.norm(getattr(fb, dname)[i] - getattr(f, dname)) < 1e-12
        assert np.linalg.norm(fb.point[i] - f.point) < 1e-12
        assert np.max(np.abs(fb.residuals[i] - f.residuals)) < 1e-12
        T = fb.basis[i][:2] @ f.basis[:2].T  # (u, v) bases may differ by a rotation
        M = np.eye(len(f.param_names))
        if kind == "plane":
            M[1:, 1:] = T
        else:
            M[:2, :2] = M[2:, 2:] = T
        np.testing.assert_allclose(M @ f.cov @ M.T, fb.cov[i], rtol=1e-6,
                                   atol=1e-9 * np.max(np.abs(f.cov)))
        assert np.linalg.norm(fb.point[i] - s.position) < 1e-9


@pytest.mark.parametrize("func, points, match", [
    (fit.fit_planes, np.zeros((4, 3)), r"points must be \(b, n, 3\), got \(4, 3\)"),
    (fit.fit_planes, np.stack([np.eye(3), np.linspace(0, 1, 3)[:, None] * [1, 1, 1]]),
     r"collinear \(set 1"),
    (fit.fit_lines, np.stack([np.eye(3), np.full((3, 3), np.nan)]), r"non-finite values \(set 1, row 0\)"),
    (fit.fit_lines, np.ones((2, 3, 3)), r"coincident \(set 0\)"),
])
def test_batched_bad_input(func, points, match):
    with pytest.raises(FitError, match=match):
        func(points)


# --------------------------------------------------------------------------- known answers


def test_plane_known_answer():
    P = np.array([[0, 0, 1], [1, 0, 1], [0, 1, 1], [1, 1, 1.0]]) + [0.0, 0.0, 0.5]
    f = fit.fit_plane(P)
    np.testing.assert_allclose(f.normal, [0, 0, 1], atol=1e-15)
    np.testing.assert_allclose(f.point, [0.5, 0.5, 1.5], atol=1e-15)
    assert f.rms < 1e-15 and f.dof == 1


def test_line_known_answer():
    t = np.linspace(-1, 1, 5)[:, None]
    f = fit.fit_line([1.0, 2.0, 3.0] + t * [0.0, -1.0, 0.0])
    np.testing.assert_allclose(f.direction, [0, 1, 0], atol=1e-15)  # oriented +y
    np.testing.assert_allclose(f.point, [1, 2, 3], atol=1e-15)
    assert f.dof == 6


def test_circle_2d_known_answer():
    th = np.radians([10, 40, 95])
    f = fit.fit_circle_2d(np.column_stack([3 + 2 * np.cos(th), -1 + 2 * np.sin(th)]))
    np.testing.assert_allclose(f.centre, [3, -1], atol=1e-14)
    assert abs(f.radius - 2) < 1e-14
    assert f.dof == 0 and np.isnan(f.cov).all()  # exact fit: no scatter information


def test_sphere_known_answer():
    P = np.array([1.0, 2.0, 3.0]) + 0.5 * np.vstack([np.eye(3), -np.eye(3)])
    f = fit.fit_sphere(P)
    np.testing.assert_allclose(f.centre, [1, 2, 3], atol=1e-15)
    assert abs(f.radius - 0.5) < 1e-15


def test_circle_3d_known_answer():
    th = np.radians([0, 30, 60, 90])
    P = np.column_stack([0.01 * np.cos(th), np.full(4, 0.2), 0.01 * np.sin(th)]) + [0.3, 0, 0]
    f = fit.fit_circle_3d(P)
    np.testing.assert_allclose(f.centre, [0.3, 0.2, 0], atol=1e-15)
    np.testing.assert_allclose(f.normal, [0, 1, 0], atol=1e-15)
    assert abs(f.radius - 0.01) < 1e-15


def test_cylinder_known_answer_mfb_hole_pattern():
    """The MFB hole (Viprey 2016 sec. 2.1): 8 points, 4 equispaced in each of 2 levels.

    With the same angles on both levels the points are the corners of a
    cuboid, which lie exactly on three cylinders (axes along the cuboid's
    edges): without a hint the fit must refuse; with the nominal axis it is exact.
    """
    th = np.radians([0, 90, 180, 270] * 2) + 0.3
    z = np.repeat([-0.004, 0.004], 4)
    P = np.column_stack([0.1 + 0.006 * np.cos(th), 0.05 + 0.006 * np.sin(th), 0.02 + z])
    with pytest.raises(FitError, match="different axes.*pass axis_hint"):
        fit.fit_cylinder(P)
    f = fit.fit_cylinder(P, axis_hint=[0, 0, 1])
    np.testing.assert_allclose(f.axis, [0, 0, 1], atol=1e-13)
    np.testing.assert_allclose(f.point, [0.1, 0.05, 0.02], atol=1e-15)
    assert abs(f.radius - 0.006) < 1e-15 and f.dof == 3


def test_cylinder_staggered_levels_need_no_hint():
    """Levels rotated by 45 degrees against each other single out the cylinder."""
    th = np.radians([0, 90, 180, 270, 45, 135, 225, 315]) + 0.3
    z = np.repeat([-0.004, 0.004], 4)
    P = np.column_stack([0.1 + 0.006 * np.cos(th), 0.05 + 0.006 * np.sin(th), 0.02 + z])
    f = fit.fit_cylinder(P)
    np.testing.assert_allclose(f.axis, [0, 0, 1], atol=1e-12)
    assert abs(f.radius - 0.006) < 1e-14


def test_axis_hint_orients_the_result():
    th = np.radians(np.arange(0, 360, 45))
    z = np.tile([0.0, 0.01], 4)
    P = np.column_stack([np.cos(th), np.sin(th), z]) * [0.01, 0.01, 1]
    assert fit.fit_cylinder(P).axis[2] > 0
    assert fit.fit_cylinder(P, axis_hint=[0, 0, -1]).axis[2] < 0


# --------------------------------------------------------------------------- paper and scipy checks


def _viprey_cubic_plane(P):
    """Viprey 2016 Appendix B (eqs. B.6-B.9), coefficients as printed."""
    X = P - P.mean(axis=0)
    x, y, z = X.T
    Sxx, Syy, Szz, Sxy, Sxz, Syz = x @ x, y @ y, z @ z, x @ y, x @ z, y @ z
    c3 = Sxy * (Syz**2 - Sxz**2) + Sxz * Syz * (Sxx - Syy)
    c2 = (Syz**3 + Syz * (Sxz**2 - 2 * Sxy**2 - Sxx**2) + Syz * (Sxx * Szz + Sxx * Syy - Syy * Szz)
          + Sxy * Sxz * (Sxx + Syy - 2 * Szz))
    c1 = (Sxy**3 + Sxy * (Sxz**2 - 2 * Syz**2 - Szz**2) + Sxy * (Sxx * Szz + Syy * Szz - Sxx * Syy)
          + Sxz * Syz * (Syy + Szz - 2 * Sxx))
    c0 = Syz * (Sxy**2 - Sxz**2) + Sxy * Sxz * (Szz - Syy)
    best = None
    for A in np.roots([c3, c2, c1, c0]):
        if abs(A.imag) > 1e-9 * max(1.0, abs(A)):
            continue
        A = A.real
        B = ((Sxy * Syz * A**2 + (Syz**2 - Sxy**2) * A - Sxy * Syz)
             / ((Syz * (Sxx - Syy) - Sxy * Sxz) * A + Sxy * (Syy - Szz) + Sxz * Syz))
        W = np.sum((A * x + B * y + z) ** 2) / (A * A + B * B + 1)  # eq. B.7 (with B y_i)
        if best is None or W < best[0]:
            best = (W, A, B)
    W, A, B = best
    return np.array([A, B, 1.0]) / np.sqrt(A * A + B * B + 1), W


def _noisy_plane(rng, sigma=2e-6):
    n = rng.normal(size=3)
    n /= np.linalg.norm(n)
    B = fit._perp_basis(n)
    return (rng.uniform(-1, 1, 3) + rng.uniform(-0.05, 0.05, (25, 2)) @ B[:2]
            + rng.normal(0, sigma, (25, 3)))


def test_plane_svd_matches_viprey_cubic(rng):
    """The SVD plane and the paper's cubic agree (1e-12 rad: both exact up to rounding)."""
    for _ in range(20):
        P = _noisy_plane(rng)
        f = fit.fit_plane(P)
        n_c, W = _viprey_cubic_plane(P)
        assert np.linalg.norm(np.cross(n_c, f.normal)) < 1e-12
        assert abs(W - f.residuals @ f.residuals) < 1e-9 * W


def test_plane_matches_scipy_least_squares(rng):
    P = _noisy_plane(rng)
    f = fit.fit_plane(P)
    n0 = f.normal + [1e-3, -2e-3, 1e-3]

    def res(q):  # normal by two angles, offset d; full orthogonal distances
        n = np.array([np.cos(q[0]) * np.sin(q[1]), np.sin(q[0]) * np.sin(q[1]), np.cos(q[1])])
        return P @ n - q[2]

    n0 /= np.linalg.norm(n0)
    q0 = [np.arctan2(n0[1], n0[0]), np.arccos(n0[2]), float(P.mean(0) @ n0)]
    sol = least_squares(res, q0, xtol=1e-15, ftol=1e-15, gtol=1e-15)
    n = np.array([np.cos(sol.x[0]) * np.sin(sol.x[1]), np.sin(sol.x[0]) * np.sin(sol.x[1]),
                  np.cos(sol.x[1])])
    assert np.linalg.norm(np.cross(n, f.normal)) < 1e-9
    assert f.residuals @ f.residuals <= 2 * sol.cost * (1 + 1e-9)


def _cyl_scipy(P, a0, p0, R0):
    """Full nonlinear ODR cylinder with scipy: 5 parameters about a fixed frame."""
    B = fit._perp_basis(a0 / np.linalg.norm(a0))

    def unpack(q):
        a = B[2] + q[2] * B[0] + q[3] * B[1]
        a /= np.linalg.norm(a)
        return p0 + q[0] * B[0] + q[1] * B[1], a, q[4]

    def res(q):
        p, a, R = unpack(q)
        return np.linalg.norm(np.cross(P - p, a), axis=1) - R

    sol = least_squares(res, [0, 0, 0, 0, R0], x_scale="jac", xtol=1e-15, ftol=1e-15, gtol=1e-15)
    return (*unpack(sol.x), 2 * sol.cost)


@pytest.mark.parametrize("arc_deg", [360, 120, 90])
def test_cylinder_sds_matches_scipy_least_squares(rng, arc_deg):
    """Iterated SDS (App. A) and a general nonlinear solver reach the same cylinder.

    Tolerance: both solve the same smooth problem to ~1e-12 relative; 1e-9
    rad / 1e-10 m leaves room for scipy's own stopping rule.
    """
    for _ in range(5):
        a = rng.normal(size=3)
        a /= np.linalg.norm(a)
        B = fit._perp_basis(a)
        th = rng.uniform(0, np.radians(arc_deg), 30)
        z = rng.uniform(-0.02, 0.02, 30)
        c = rng.uniform(-1, 1, 3)
        P = (c + 0.012 * (np.cos(th)[:, None] * B[0] + np.sin(th)[:, None] * B[1])
             + z[:, None] * a + rng.normal(0, 3e-6, (30, 3)))
        f = fit.fit_cylinder(P)
        # scipy starts from the truth disturbed by 1 mrad and 50 µm, not from our answer
        p, a_s, R, cost = _cyl_scipy(P, a + [1e-3, 0, -1e-3], c + 5e-5, 0.012)
        assert np.linalg.norm(np.cross(a_s, f.axis)) < 1e-9
        d = (f.point - p) - ((f.point - p) @ f.axis) * f.axis  # axis-to-axis offset at our point
        assert np.linalg.norm(d) < 1e-10
        assert abs(R - f.radius) < 1e-10
        assert f.residuals @ f.residuals <= cost * (1 + 1e-9)


def test_sds_step_equals_viprey_eq_a8(rng):
    """One SDS iteration equals the normal equations A.8 of Viprey 2016, with the
    screw mapped as (shift_u, shift_v, tilt_u, tilt_v, radius) = (u, v, beta, -alpha, r).

    A.8 as printed has +sum(z sin^2) in row 4, column 1, where symmetry (it is
    G^T G) needs -sum(z sin^2): the test uses the corrected entry.
    """
    a = np.array([0.3, -0.2, 0.93])
    a /= np.linalg.norm(a)
    B = fit._perp_basis(a)
    th = rng.uniform(0, 2.0, 20)
    z = rng.uniform(-0.02, 0.02, 20)
    P = 0.01 * (np.cos(th)[:, None] * B[0] + np.sin(th)[:, None] * B[1]) + z[:, None] * a
    P += rng.normal(0, 1e-5, P.shape)
    # current estimate: axis tilted by 2 mrad, shifted by 30 µm, radius 20 µm off
    a0 = a + 2e-3 * B[1]
    a0 /= np.linalg.norm(a0)
    B0 = fit._perp_basis(a0)
    p0, R0 = 3e-5 * B0[0], 0.01002
    r, J = fit._rj_cylinder(p0, B0, R0, P)
    ours = fit._solve_step(J, r)
    # the paper: points in the axis frame (eqs. A.1-A.3), xi_i = rho_i - R (A.2)
    L = (P - p0) @ B0.T
    x, y, zz = L.T
    rho = np.hypot(x, y)
    c, s, xi = x / rho, y / rho, rho - R0
    M = np.array([
        [np.sum(zz**2 * s**2), -np.sum(zz**2 * s * c), -np.sum(zz * s * c), -np.sum(zz * s**2), -np.sum(zz * s)],
        [-np.sum(zz**2 * s * c), np.sum(zz**2 * c**2), np.sum(zz * c**2), np.sum(zz * s * c), np.sum(zz * c)],
        [-np.sum(zz * s * c), np.sum(zz * c**2), np.sum(c**2), np.sum(s * c), np.sum(c)],
        [-np.sum(zz * s**2), np.sum(zz * s * c), np.sum(s * c), np.sum(s**2), np.sum(s)],  # corrected sign
        [-np.sum(zz * s), np.sum(zz * c), np.sum(c), np.sum(s), len(P)],
    ])
    assert np.allclose(M, M.T)
    rhs = np.array([-np.sum(xi * zz * s), np.sum(xi * zz * c), np.sum(xi * c), np.sum(xi * s), np.sum(xi)])
    alpha, beta, u, v, rr = np.linalg.solve(M, rhs)
    # 1e-7 relative: the normal equations square the condition number of the design
    # matrix (here ~3e2 in metres, so ~1e5), our SVD solve does not
    np.testing.assert_allclose(ours, [u, v, beta, -alpha, rr], rtol=1e-7, atol=1e-9 * np.abs(ours).max())


@pytest.mark.parametrize("kind", ["circle2d", "sphere", "circle3d"])
def test_other_nonlinear_fits_match_scipy(rng, kind):
    s = refdata.make_refset(kind, rng, residual_rms=(20e-6, 20e-6))
    f = FIT[kind](s.points)
    P = s.points
    if kind == "circle3d":
        B = fit._perp_basis(s.direction)

        def res(q):
            n = B[2] + q[3] * B[0] + q[4] * B[1]
            n /= np.linalg.norm(n)
            w = P - (s.position + 1e-4 + q[:3])
            h = w @ n
            rho = np.linalg.norm(w - h[:, None] * n, axis=1)
            return np.concatenate([h, rho - q[5]])

        sol = least_squares(res, [0, 0, 0, 0, 0, s.radius * 1.01], x_scale="jac",
                            xtol=1e-15, ftol=1e-15, gtol=1e-15)
        centre = s.position + 1e-4 + sol.x[:3]
        R = sol.x[5]
    else:
        def res(q):
            return np.linalg.norm(P - q[:-1], axis=1) - q[-1]

        sol = least_squares(res, np.append(s.position + 1e-4, s.radius * 1.01), x_scale="jac",
                            xtol=1e-15, ftol=1e-15, gtol=1e-15)
        centre, R = sol.x[:-1], sol.x[-1]
    assert np.linalg.norm(centre - f.centre) < 1e-10
    assert abs(R - f.radius) < 1e-10


# --------------------------------------------------------------------------- round trips


def _truth_and_sampler(kind, rng):
    """A fixed nominal set (on the feature) and its truth, for repeated noisy fits."""
    s = refdata.make_refset(kind, rng, n=30, offset_max=0.5, residual_rms=(1e-12, 1e-12),
                            p_partial=1.0)
    return s


def _local_params(kind, f, s, B0):
    """Estimate minus truth in the local parameters of ``param_names``, truth frame ``B0``."""
    if kind in ("circle2d", "sphere"):
        return np.append(f.centre - s.position, f.radius - s.radius)
    d = _direction(f)
    dp = _position(f) - s.position
    tilt = [d @ B0[0], d @ B0[1]]
    if kind == "plane":
        return np.array([dp @ B0[2], *tilt])
    if kind == "line":
        return np.array([dp @ B0[0], dp @ B0[1], *tilt])
    if kind == "circle3d":
        return np.array([dp @ B0[0], dp @ B0[1], dp @ B0[2], *tilt, f.radius - s.radius])
    return np.array([dp @ B0[0], dp @ B0[1], *tilt, f.radius - s.radius])  # cylinder


def _cov_in_frame(kind, f, B0):
    """Rotate a result's covariance from its (u, v) basis into the truth frame ``B0``."""
    if kind in ("circle2d", "sphere"):
        return f.cov
    T = B0[:2] @ f.basis[:2].T  # 2x2: (u, v) components -> (u0, v0) components
    blocks = {"plane": [np.eye(1), T], "line": [T, T], "circle3d": [T, np.eye(1), T, np.eye(1)],
              "cylinder": [T, T, np.eye(1)]}[kind]
    k = sum(b.shape[0] for b in blocks)
    M = np.zeros((k, k))
    i = 0
    for b in blocks:
        M[i:i + b.shape[0], i:i + b.shape[0]] = b
        i += b.shape[0]
    return M @ f.cov @ M.T


@pytest.mark.parametrize("kind", refdata.KINDS)
def test_round_trip_covariance_predicts_scatter(kind):
    """Truth -> seeded isotropic noise -> fit, 200 times: the spread of every parameter
    matches sqrt(diag(cov)) within 20 % (the sample std of 200 draws is itself
    uncertain by ~5 %, so 20 % is a 4-sigma bound)."""
    rng = np.random.default_rng(4242 + refdata.KINDS.index(kind))
    s = _truth_and_sampler(kind, rng)
    B0 = fit._perp_basis(s.direction) if s.direction is not None else None
    sigma = 2e-6
    est, covs = [], []
    for _ in range(200):
        P = s.points + rng.normal(0, sigma, s.points.shape)
        f = FIT[kind](P)
        est.append(_local_params(kind, f, s, B0))
        covs.append(_cov_in_frame(kind, f, B0))
    est = np.array(est)
    pred = np.sqrt(np.diag(np.mean(covs, axis=0)))
    emp = est.std(axis=0, ddof=1)
    ratio = emp / pred
    assert np.all(np.abs(ratio - 1) < 0.2), dict(zip(type(f).param_names, np.round(ratio, 3)))
    # and the estimate is unbiased within 4 standard errors of the mean
    assert np.all(np.abs(est.mean(axis=0)) < 4 * pred / np.sqrt(200) + 1e-12)


# --------------------------------------------------------------------------- bad input


def _arc(n, deg, R=0.01, dim=2, z=None):
    th = np.radians(np.linspace(0, deg, n))
    xy = np.column_stack([R * np.cos(th), R * np.sin(th)])
    if dim == 2:
        return xy
    z = np.zeros(n) if z is None else z
    return np.column_stack([xy, z])


_line = np.linspace(0, 1, 6)[:, None] * [1.0, 2.0, 3.0]
_one_side = np.vstack([_arc(6, 0.01, dim=3), _arc(6, 0.01, dim=3, z=np.full(6, 0.01))])


@pytest.mark.parametrize("func, points, match", [
    (fit.fit_plane, np.zeros((5, 2)), r"points must be \(n, 3\), got \(5, 2\)"),
    (fit.fit_plane, np.zeros(3), r"points must be \(n, 3\), got \(3,\)"),
    (fit.fit_circle_2d, np.zeros((5, 3)), r"points must be \(n, 2\), got \(5, 3\)"),
    (fit.fit_plane, [[0, 0, 0], [1, 0, 0]], "needs at least 3, got 2"),
    (fit.fit_cylinder, np.eye(3), "needs at least 5, got 3"),
    (fit.fit_sphere, [[0, 0, 0], [1, 0, 0], [0, 1, np.nan], [0, 0, 1]], r"non-finite values \(row 2\)"),
    (fit.fit_line, [[0, 0, np.inf], [1, 0, 0]], "non-finite"),
    (fit.fit_plane, [["a", 0, 0]] * 3, "numeric"),
    (fit.fit_plane, np.ones((5, 3)), "coincident"),
    (fit.fit_line, np.ones((4, 3)), "coincident"),
    (fit.fit_sphere, np.repeat(np.eye(3), 2, axis=0), "coincident"),
    (fit.fit_plane, _line, "not enough significant data points: points are collinear"),
    (fit.fit_circle_2d, _line[:, :2], "collinear"),
    (fit.fit_circle_3d, _line, "collinear"),
    (fit.fit_cylinder, _line, "collinear"),
    (fit.fit_sphere, _arc(8, 300, dim=3), "coplanar"),
    # one side only: a 0.01 degree arc does not determine the radius
    (fit.fit_circle_2d, _arc(10, 0.01), "not enough significant data points.*radius is not determined"),
    (fit.fit_circle_3d, _arc(10, 0.01, dim=3), "radius is not determined"),
    (partial(fit.fit_cylinder, axis_hint=[0, 0, 1]), _one_side, "not enough significant data points.*one side"),
    (fit.fit_cylinder, _one_side, "not enough significant data points"),
    # all points in one section: the axis tilt is not determined
    (fit.fit_cylinder, _arc(12, 300, dim=3), "not enough significant data points.*tilt"),
])
def test_degenerate_input_raises(func, points, match):
    with pytest.raises(FitError, match=match):
        func(points)


def test_bad_axis_hint():
    P = np.vstack([_arc(6, 300, dim=3), _arc(6, 300, dim=3, z=np.full(6, 0.01))])
    with pytest.raises(FitError, match="axis_hint"):
        fit.fit_cylinder(P, axis_hint=[0, 0, 0])


def test_refdata_bad_kind():
    from core.exceptions import ConfigError
    with pytest.raises(ConfigError, match="kind must be one of"):
        refdata.make_refset("cone", np.random.default_rng(0))


# --------------------------------------------------------------------------- light paths (issue 19 item 3)


@pytest.mark.parametrize("validate", [True, False])
def test_light_fits_equal_full_fits_bit_for_bit(validate):
    # plane_point_normal / cylinder_point_axis run the very operations of
    # fit_plane / fit_cylinder minus residuals and covariance: equal, not close
    rng = np.random.default_rng(41)
    for s in refdata.make_refsets("plane", 30, rng, n=12):
        f = fit.fit_plane(s.points, normal_hint=s.direction)
        q, n = fit.plane_point_normal(s.points, normal_hint=s.direction, validate=validate)
        np.testing.assert_array_equal(q, f.point)
        np.testing.assert_array_equal(n, f.normal)
    for s in refdata.make_refsets("cylinder", 30, rng, n=12):
        hint = s.direction + rng.normal(0, 0.02, 3)
        f = fit.fit_cylinder(s.points, axis_hint=hint)
        q, a = fit.cylinder_point_axis(s.points, axis_hint=hint, validate=validate)
        np.testing.assert_array_equal(q, f.point)
        np.testing.assert_array_equal(a, f.axis)


def test_batched_light_fits_equal_single_light_fits():
    rng = np.random.default_rng(43)
    sets = refdata.make_refsets("plane", 40, rng, n=8)
    P = np.stack([s.points for s in sets])
    q, n = fit.planes_point_normal(P, normal_hint=[0.0, 0.0, 1.0])
    for i in range(len(P)):
        qi, ni = fit.plane_point_normal(P[i], normal_hint=[0.0, 0.0, 1.0], validate=False)
        # measured equal (the batched SVD is LAPACK's per set); 1e-15 relative allows a reordered sum
        assert np.abs(q[i] - qi).max() <= 1e-15 * np.abs(qi).max() and np.abs(n[i] - ni).max() <= 1e-15
    # cylinders: the perturbed copies of one set around one hint, as the MFB gain fits them
    s = refdata.make_refset("cylinder", rng, n=12)
    Q = np.broadcast_to(s.points, (24, 12, 3)).copy()
    Q[np.arange(24), np.arange(24) % 12] += rng.normal(0, 1e-6, (24, 3))
    hint = s.direction + 0.01
    q, a = fit.cylinders_point_axis(Q, axis_hint=hint)
    for i in range(len(Q)):
        qi, ai = fit.cylinder_point_axis(Q[i], axis_hint=hint, validate=False)
        # measured 3.3e-16 relative (batched vs single SVD steps); 1e-14: rounding, far
        # below the iteration's own stopping step (1e-12 of the feature size)
        assert np.abs(q[i] - qi).max() <= 1e-14 * np.abs(qi).max()
        assert np.abs(a[i] - ai).max() <= 1e-14
        assert (a[i] @ hint) > 0


@pytest.mark.parametrize("func, points, match", [
    (fit.plane_point_normal, np.zeros((5, 2)), r"points must be \(n, 3\), got \(5, 2\)"),
    (fit.plane_point_normal, np.ones((5, 3)), "coincident"),
    (fit.plane_point_normal, _line, "not enough significant data points: points are collinear"),
    (partial(fit.cylinder_point_axis, axis_hint=[0, 0, 1]), _line, "collinear"),
    (partial(fit.cylinder_point_axis, axis_hint=[0, 0, 1]), _one_side, "not enough significant data points.*one side"),
    (partial(fit.cylinder_point_axis, axis_hint=[0, 0, 0]), _arc(12, 300, dim=3) + [0, 0, 1e-3], "axis_hint"),
])
def test_light_fits_check_like_the_full_fits(func, points, match):
    with pytest.raises(FitError, match=match):
        func(points)


def test_distinct_count_matches_numpy_unique():
    rng = np.random.default_rng(47)
    P = rng.integers(0, 3, (40, 3)).astype(float)
    assert fit._n_distinct(P) == np.unique(P, axis=0).shape[0]
    assert fit._n_distinct(np.ones((4, 3))) == 1
