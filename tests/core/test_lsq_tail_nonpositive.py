"""core.lsq.quadratic_form_sf at x <= 0 (session 37, tail37): the saddlepoint contour (QF_CONTOUR_NONPOSITIVE_X)
against answers from outside the code: scipy's beta and chi-square functions, the exponentials' closed form, a one-
dimensional integral over one term's density written here with scipy's quadrature (positive terms, relatively
accurate at any depth), and a sampled mixed case. x = 0 is core.uncertainty's ratio test (weights of both signs);
x < 0 a lower tail of the negated form. Imhof's quadrature, kept there before, is absolutely accurate only: at
1e-12 it was 50 % off, at 5e-47 it returned 0."""

import numpy as np
import pytest
from scipy import integrate, special, stats

import core.lsq as lsq
from core.lsq import quadratic_form_sf


def _two_opposite(a, k, b, m, x):
    """P(a chi2_k - b chi2_m > x) for x <= 0, a, b > 0: chi2_m's cdf at y0 = -x / b (there a chi2_k > x + b y
    always) plus the integral beyond of chi2_m's density times chi2_k's tail at (x + b y) / a, in y = y0 + z^2
    (chi2_1's density at 0 and chi2_1's tail at 0 are square-root singular: smooth in z), by scipy's quadrature in
    pieces around the integrand's largest value (found on a grid); the density from its formula (scipy's gammaln),
    the tail scipy's regularised incomplete gamma."""
    y0 = -x / b
    head = special.gammainc(m / 2, y0 / 2) if y0 > 0 else 0.0

    def f(z):
        y = y0 + z * z
        if z <= 0:
            return 0.0
        logpdf = (m / 2 - 1) * np.log(y) - y / 2 - (m / 2) * np.log(2.0) - special.gammaln(m / 2)
        return 2.0 * z * np.exp(logpdf) * special.gammaincc(k / 2, (x + b * y) / (2 * a))

    zs = np.geomspace(1e-8, 1e3, 2000) * np.sqrt(max(1.0, m))
    zm = zs[int(np.argmax([f(z) for z in zs]))]
    cuts = [0.0] + [zm * r for r in (0.5, 1.0, 2, 4, 8)] + [np.inf]
    return head + sum(integrate.quad(f, u, v, epsabs=0.0, epsrel=2e-14, limit=500)[0]
                      for u, v in zip(cuts[:-1], cuts[1:]))


def test_the_ratio_test_at_zero_is_a_beta_tail_to_rounding():
    """x = 0, a chi2_k - b chi2_m > 0 iff chi2_k / (chi2_k + chi2_m) > b / (a + b): scipy's beta(k/2, m/2) tail,
    the ratio test's own form (core.uncertainty._null_tail: weights lambda - c and -c on the rest of the residual
    space, lambda equal here). Tails 0.98 to 5e-150, relative 1e-12 (measured below 2e-14; Imhof's quadrature
    returned 0 below about 1e-16, and 3e135 x the tail at 5e-152)."""
    for k, m in ((1, 1), (1, 2), (2, 5), (1, 300), (3, 1000), (10, 40)):
        for c in (1e-3, 0.01, 0.1, 0.5, 0.9):
            ref = stats.beta(k / 2, m / 2).sf(c)
            if ref > 1e-300:
                assert quadratic_form_sf([1.0 - c, -c], 0.0, [k, m]) == pytest.approx(ref, rel=1e-12, abs=0), (k, m, c)
    lam, c, rest = 2.0, 0.05, 40   # three equal lambdas of one degree each beside the rest: beta(3/2, 40/2)
    assert quadratic_form_sf([lam - c] * 3 + [-c], 0.0, [1, 1, 1, rest]) == pytest.approx(
        stats.beta(1.5, rest / 2).sf(c / lam), rel=1e-12, abs=0)


def test_exponential_differences_below_zero_against_their_closed_form():
    """w1 chi2_2 - w2 chi2_2 at x <= 0: 1 - w2 / (w1 + w2) exp(x / (2 w2)) (w1 / (w1 + w2) at 0), also where one
    weight is 1e-3 of the other. Relative 1e-12 (measured 3e-14; Imhof's quadrature 1.7e-5 off at x = -60)."""
    for w1, w2 in ((1.0, 0.4), (0.3, 1.0), (1.0, 1e-3), (1e-3, 1.0)):
        for x in (0.0, -0.01, -0.5, -3.0, -20.0, -60.0):
            ref = w1 / (w1 + w2) if x == 0 else 1.0 - w2 / (w1 + w2) * np.exp(x / (2 * w2))
            assert quadratic_form_sf([w1, -w2], x, [2, 2]) == pytest.approx(ref, rel=1e-12, abs=0), (w1, w2, x)


def test_two_weights_of_opposite_sign_against_a_one_dimensional_integral():
    """a chi2_k - b chi2_m > x at x = 0, -0.1, -5: odd and even degrees, a weight 1e-3 of the other, 300 degrees
    beside one, tails 1 to 1.6e-21: the integral over chi2_m's density (_two_opposite; it agrees with the same
    integral from scipy.stats' logpdf and logsf within 3e-15). Relative 1e-12 (measured 3.5e-14; Imhof's quadrature
    1.7e-3 off at a = 1, b = 1e-3, x = -5)."""
    for a, k, b, m in ((1.0, 1, 0.3, 1), (1.0, 1, 1e-3, 1), (1.0, 1, 0.01, 300), (0.2, 3, 1.0, 2),
                       (1.0, 2, 0.05, 40), (0.05, 1, 1.0, 1), (0.01, 1, 1.0, 20)):
        for x in (0.0, -0.1, -5.0):
            ref = _two_opposite(a, k, b, m, x)
            assert quadratic_form_sf([a, -b], x, [k, m]) == pytest.approx(ref, rel=1e-12, abs=0), (a, k, b, m, x)


def test_negative_weights_only_below_zero_are_chi_square_lower_tails():
    """-w chi2_k > x (x < 0) is chi2_k's cdf at -x / w: scipy's, relatively, down to 1e-12 (Imhof's quadrature:
    50 % off at 2 degrees, 3e-5 at 100). Relative 1e-12 (measured 2.6e-14)."""
    for k in (2, 3, 10, 100):
        for q in (1e-12, 1e-6, 1e-2, 0.5, 0.99):
            x = float(stats.chi2.ppf(q, k))
            assert quadratic_form_sf([-2.0], -2.0 * x, [k]) == pytest.approx(q, rel=1e-12, abs=0), (k, q)
            assert quadratic_form_sf(np.full(k, -2.0), -2.0 * x) == pytest.approx(q, rel=1e-12, abs=0), (k, q)


def test_certain_events_and_the_mixed_case_against_sampling():
    """Q > x certain (all weights > 0, x < 0) is 1 and impossible (all < 0, x = 0) is 0, exactly. Four weights of
    both signs against 400,000 draws (seed 37): within 5 binomial standard errors (about 4e-3 relative; the study
    in the report drew 1e7)."""
    assert quadratic_form_sf([1.0, 0.5], -1e-9) == 1.0 and quadratic_form_sf([-1.0, -0.5], 0.0) == 0.0
    w = np.array([1.0, 0.5, -0.3, -0.7])
    z = np.random.default_rng(37).standard_normal((400_000, 4))
    q = (z * z) @ w
    for x in (0.0, -0.5, -2.0):
        est = float(np.mean(q > x))
        se = np.sqrt(est * (1 - est) / q.size)
        assert abs(quadratic_form_sf(w, x) - est) < 5 * se, x


def test_the_constant_off_is_imhof_and_x_above_zero_is_unchanged(monkeypatch):
    """QF_CONTOUR_NONPOSITIVE_X off: x <= 0 is Imhof's quadrature, the same doubles as core.lsq._qf_sf_imhof (the
    code before session 37); on or off, x > 0 takes the contour as before, the same doubles."""
    w, h = np.array([1.0, 0.5, -0.3, -0.7]), np.array([1.0, 2.0, 1.0, 3.0])
    up = [quadratic_form_sf(w, x, h) for x in (0.5, 3.0, 30.0)]
    on = [quadratic_form_sf(w, x, h) for x in (0.0, -0.5)]
    monkeypatch.setattr(lsq, "QF_CONTOUR_NONPOSITIVE_X", False)
    assert [quadratic_form_sf(w, x, h) for x in (0.5, 3.0, 30.0)] == up
    off = [quadratic_form_sf(w, x, h) for x in (0.0, -0.5)]
    assert off == [lsq._qf_sf_imhof(w, h, x) for x in (0.0, -0.5)]
    assert on == pytest.approx(off, abs=1e-9) and on != off
