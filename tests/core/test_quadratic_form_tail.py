"""core.lsq.quadratic_form_sf where one weight dominates (session 36, imhof36): the saddlepoint contour against
answers from outside the code: scipy's chi-square and normal functions, finite sums derived by hand, and one-
dimensional convolutions integrated here by scipy's quadrature (all of positive terms, so relatively accurate at
any depth of the tail). The tails run from 1e-2 to 1e-12; the weights are the MFB residual tests' kind (one large,
many small; the three real weight sets Imhof's quadrature failed on, mfb35)."""

import numpy as np
import pytest
from scipy import integrate, stats

import core.lsq as lsq
from core.lsq import quadratic_form_sf

TAILS = (1e-2, 1e-4, 1e-6, 1e-8, 1e-10, 1e-12)


def _dominant_one_dof(w1, a, m, x):
    """P(w1 chi2_1 + a chi2_m > x) by conditioning on the second term q = chi2_m: P(a q > x) + the integral over
    q < x / a of chi2_m's density times chi2_1.sf((x - a q) / w1), by scipy's quadrature (positive terms; q = z^2
    for m = 1, whose density is singular at 0); q beyond its mean + 60 sd adds nothing."""
    qmax = min(x / a, m + 60.0 * np.sqrt(2.0 * m))
    if m == 1:
        body = integrate.quad(lambda z: 2.0 * stats.norm.pdf(z) * stats.chi2.sf((x - a * z * z) / w1, 1),
                              0.0, np.sqrt(qmax), epsabs=0.0, epsrel=1e-12, limit=400)[0]
    else:
        body = integrate.quad(lambda q: stats.chi2.pdf(q, m) * stats.chi2.sf((x - a * q) / w1, 1), 0.0, qmax,
                              epsabs=0.0, epsrel=1e-12, limit=400, points=[m])[0]
    return body + stats.chi2.sf(x / a, m)


def test_equal_weights_are_chi_square_tails_to_rounding():
    """k equal weights (or one weight of multiplicity k) are a scaled chi-square: scipy's chi2 tail, relatively,
    from 0.5 to 1e-20 (measured below 2e-13, 400 degrees at 1e-20 the worst: the contour's integrand is of the
    tail's size, nothing cancels; tolerance 1e-12 leaves 5 x for other platforms' libm)."""
    for k in (2, 3, 5, 40, 400):
        for p in (0.9, 0.5, 1e-2, 1e-5, 1e-8, 1e-12, 1e-20):
            x = float(stats.chi2.isf(p, k))
            assert quadratic_form_sf(np.full(k, 3.0), 3.0 * x) == pytest.approx(p, rel=1e-12, abs=0), (k, p)
            assert quadratic_form_sf([0.7], 0.7 * x, [k]) == pytest.approx(p, rel=1e-12, abs=0), (k, p)


def test_two_weights_of_even_multiplicity_against_their_finite_sums():
    """Exponential and gamma terms (by hand, partial fractions of the moment generating function): with rates
    a = 1 / (2 w1), b = 1 / (2 w2), P(w1 chi2_2 + w2 chi2_2 > x) = (w1 e^(-a x) - w2 e^(-b x)) / (w1 - w2), and
    P(w1 chi2_2 + w2 chi2_4 > x) = A e^(-a x) / a + e^(-b x) (-A / b + G (x / b + 1 / b^2)), A = a b^2 / (b - a)^2,
    G = a b^2 / (a - b). The second weight near the first (0.3) and far below it (1e-3: one dominates). Relative
    1e-11 (the finite sums lose about 1e-14 to cancellation when w2 is near w1)."""
    for w1, w2 in ((1.0, 0.3), (1.0, 1e-3), (2.5, 2.4)):
        a, b = 0.5 / w1, 0.5 / w2
        A, G = a * b * b / (b - a) ** 2, a * b * b / (a - b)

        def sf22(x):
            return (w1 * np.exp(-a * x) - w2 * np.exp(-b * x)) / (w1 - w2)

        def sf24(x):
            return A * np.exp(-a * x) / a + np.exp(-b * x) * (-A / b + G * (x / b + 1.0 / b ** 2))

        assert sf22(0.0) == pytest.approx(1.0) and sf24(0.0) == pytest.approx(1.0)   # the sums themselves
        for p in TAILS:
            x = -2.0 * w1 * np.log(p)   # about the tail p
            assert quadratic_form_sf([w1, w2], x, [2, 2]) == pytest.approx(sf22(x), rel=1e-11, abs=0), (w1, w2, p)
            assert quadratic_form_sf([w1, w2], x, [2, 4]) == pytest.approx(sf24(x), rel=1e-11, abs=0), (w1, w2, p)


def test_a_dominant_weight_of_two_degrees_beside_many_small_equal_ones():
    """w1 chi2_2 + a chi2_m (m small weights a): conditioning on the rest R = a chi2_m, P = P(R > x) +
    E[exp(-(x - R) / (2 w1)); R < x], and E[exp(t chi2_m); chi2_m < c] = (1 - 2t)^(-m/2) chi2_m.cdf(c (1 - 2t)):
    closed in scipy's chi-square. The MFB's kind: one weight 1, 300-500 weights 1e-3 to 1e-2. Relative 1e-11."""
    def sf(a, m, x):
        return (np.exp(-x / 2.0) * (1.0 - a) ** (-m / 2.0) * stats.chi2.cdf(x / a * (1.0 - a), m)
                + stats.chi2.sf(x / a, m))

    for a, m in ((1e-3, 300), (5e-3, 300), (1e-2, 500)):
        for p in TAILS:
            x = a * m - 2.0 * np.log(p)
            assert quadratic_form_sf([1.0, a], x, [2, m]) == pytest.approx(sf(a, m, x), rel=1e-11, abs=0), (a, m, p)


def test_a_dominant_weight_of_one_degree_against_a_convolution_where_imhof_failed():
    """The MFB's case: the dominant weight of one degree (Imhof's integrand then decays as u^-1.5 and oscillates).
    References: the convolution over the dominant term (_dominant_one_dof, scipy's quadrature on positive terms,
    relative error about 1e-13) with the rest a chi-square of m small equal weights, or the second weight of
    mfb-3axis seed 12's between-node interval (2.2e-7 of the first: the set Imhof returned 0 on, where the tail is
    the level 7.9e-6). Relative 1e-9 (the reference's quadrature; measured below 1e-14). Imhof's quadrature on
    the real set (core.lsq._qf_sf_imhof) returns 0: the failure mended."""
    for a, m in ((1e-3, 300), (1e-2, 200), (2.2e-7, 1)):
        for p in TAILS:
            x = float(stats.chi2.isf(p, 1)) + a * m
            ref = _dominant_one_dof(1.0, a, m, x)
            assert quadratic_form_sf([1.0, a], x, [1, m]) == pytest.approx(ref, rel=1e-9, abs=0), (a, m, p)
    w = np.array([1.5489779657860352e-15, 3.356912282963863e-22])   # mfb-3axis seed 12 (mfb35), real scale
    x = 3.090691179289217e-14   # Satterthwaite's p there is the per-interval level 7.94e-6
    ref = _dominant_one_dof(w[0], w[1], 1, x)
    assert 7e-6 < ref < 9e-6 and quadratic_form_sf(w, x) == pytest.approx(ref, rel=1e-9, abs=0)
    old = lsq._qf_sf_imhof(w / w[0], np.ones(2), x / w[0])
    assert abs(old - ref) > 0.1 * ref   # Imhof's quadrature: 0 here


def test_the_real_weight_sets_imhof_failed_on_lie_between_their_bounds():
    """The other two of mfb35's three failing sets (7 weights, the first dominant) at their level point: the tail
    lies between P(w1 chi2_1 + w2 chi2_1 > x) (the five smallest terms dropped: they only add) and
    P(w1 chi2_1 + w2 chi2_6 > x) (each of them raised to w2), both convolutions of scipy's functions; Imhof's
    quadrature fell below the lower one (0, and 8.1e-6 against 9.6e-6)."""
    sets = (([9.69925113017865e-16, 2.0321285083381135e-18, 5.2128850195084666e-20, 4.6582365589589416e-21,
              1.1633372061170254e-22, 1.4588943162240955e-25, 2.6995011450190183e-27], 1.932883574730517e-14),
            ([1.320245684823552e-16, 2.3022395068156222e-18, 8.538684046861145e-19, 1.005983752159247e-19,
              4.9343873107287406e-20, 3.5594103448101704e-20, 8.009887394203841e-21], 2.5849863261908416e-15))
    for w, x in sets:
        w = np.array(w)
        low = _dominant_one_dof(w[0], w[1], 1, x)
        high = _dominant_one_dof(w[0], w[1], 6, x)
        p = quadratic_form_sf(w, x)
        assert low * (1 - 1e-12) <= p <= high * (1 + 1e-12) and high < 1.1 * low, (low, p, high)
        assert lsq._qf_sf_imhof(w / w[0], np.ones(w.size), x / w[0]) < low


def test_many_unequal_small_weights_against_the_rest_sampled():
    """One weight 1 of one degree and 300 unequal small ones (1e-3 to 1e-2, geometric), the MFB's shape, at tails
    1e-3 and 1e-8: P = E_R[chi2_1.sf(x - R)], R the small terms' sum; 20,000 draws of R (the dominant term
    integrated exactly, so the estimate's relative standard error is that of chi2_1.sf(x - R): about 3e-4 here).
    Within 5 standard errors: a loose check, independent of any inversion integral (Imhof's quadrature is 5e-6 off
    relatively at 1e-8 here: 300 small terms damp its integrand; its failures need fewer)."""
    rng = np.random.default_rng(36)
    small = np.geomspace(1e-3, 1e-2, 300)
    R = np.concatenate([(rng.standard_normal((5000, 300)) ** 2) @ small for _ in range(4)])
    for p in (1e-3, 1e-8):
        x = float(stats.chi2.isf(p, 1)) + small.sum()
        g = stats.chi2.sf(x - R, 1)
        est, se = g.mean(), g.std() / np.sqrt(g.size)
        got = quadratic_form_sf(np.concatenate([[1.0], small]), x)
        assert abs(got - est) < 5 * se and se < 1e-3 * est, (p, got, est, se)


def test_mixed_signs_and_negative_x_against_exponentials():
    """w1 chi2_2 - w2 chi2_2 is the difference of exponentials of means 2 w1, 2 w2: for x >= 0,
    P(> x) = w1 / (w1 + w2) exp(-x / (2 w1)) (the contour: a negative weight's branch point is on the other side;
    also where the negative weight is the larger); for x < 0, 1 - w2 / (w1 + w2) exp(x / (2 w2)) (Imhof's form,
    absolute 1e-9 at 4 degrees). Z1^2 - Z2^2 = 2 U V (U, V independent standard normals), whose density is
    K0(|z| / 2) / (2 pi): P(> x) = int_{x/2}^inf K0(z) dz / pi (scipy's k0; Imhof's quadrature is 6.6e-5 off at
    x = 5). Relative 1e-12 (measured 1e-15)."""
    from scipy import special

    for w1, w2 in ((1.0, 0.4), (0.3, 1.0)):
        for x in (0.5, 5.0, 20.0, 40.0):
            assert quadratic_form_sf([w1, -w2], x, [2, 2]) == pytest.approx(w1 / (w1 + w2) * np.exp(-x / (2 * w1)),
                                                                             rel=1e-12, abs=0)
    for x in (0.1, 5.0):
        ref = integrate.quad(lambda z: special.k0(z) / np.pi, x / 2, np.inf, epsabs=0.0, epsrel=1e-13, limit=200)[0]
        assert quadratic_form_sf([1.0, -1.0], x) == pytest.approx(ref, rel=1e-12, abs=0)
    w1, w2 = 1.0, 0.4
    for x in (-3.0,):
        assert quadratic_form_sf([w1, -w2], x, [2, 2]) == pytest.approx(
            1.0 - w2 / (w1 + w2) * np.exp(x / (2 * w2)), abs=1e-9)


def test_the_contour_off_is_imhof_as_before(monkeypatch):
    """QF_SADDLE_CONTOUR off: every tail is Imhof's quadrature, the same doubles as core.lsq._qf_sf_imhof (the
    code before session 36); on, x > 0 with a positive weight takes the contour (here within Imhof's stated 1e-9
    at 12 degrees of it), x <= 0 Imhof's only with QF_CONTOUR_NONPOSITIVE_X off (session 37; on, the contour:
    w1 / (w1 + w2) = 2/3 exactly at x = 0, where Imhof's is 1.4e-13 off; tests/core/test_lsq_tail_nonpositive.py)."""
    w, h, x = np.array([1.0, 0.5, 0.25]), np.full(3, 4.0), 24.0
    on = quadratic_form_sf(w, x, h)
    monkeypatch.setattr(lsq, "QF_SADDLE_CONTOUR", False)
    off = quadratic_form_sf(w, x, h)
    assert off == lsq._qf_sf_imhof(w, h, x) and on == pytest.approx(off, abs=1e-9) and on != off
    monkeypatch.setattr(lsq, "QF_SADDLE_CONTOUR", True)
    assert quadratic_form_sf([1.0, -0.5], 0.0, [2, 2]) == pytest.approx(2.0 / 3.0, rel=1e-14, abs=0)
    monkeypatch.setattr(lsq, "QF_CONTOUR_NONPOSITIVE_X", False)
    assert quadratic_form_sf([1.0, -0.5], 0.0, [2, 2]) == lsq._qf_sf_imhof(np.array([1.0, -0.5]), np.full(2, 2.0), 0.0)
