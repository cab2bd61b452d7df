"""A harmonic's amplitude (the norm of a coefficient pair) with a real 95 % interval (session 21, issue 13 item 3(d)).

:func:`core.discover.norm_interval` inverts the equal-tailed test of ``|mu|`` by ``|m|`` for ``m ~ N(mu, S)`` in
two dimensions; the report's U95 of a norm magnitude is the symmetric cover ``max(hi - v, v - lo)`` and the
finding's ``evidence.magnitude_intervals`` gives ``[lo, hi]``. Checked here against the Rice distribution
(scipy's noncentral chi-square, not the code's integral), against draws of the 2-D normal, and by the
coverage of a toy whose truth is known (draws made here, apart from core).
"""
from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest
from scipy import stats

import core.discover as D
from core import causes
from core.units import UM
from tests.discover_helpers import discovered


@pytest.mark.parametrize("nu, r", [(0.0, 0.3), (0.0, 2.0), (0.7, 1.0), (2.0, 3.0), (5.0, 4.0), (20.0, 21.0)])
def test_norm_cdf_is_the_rice_cdf_when_isotropic(nu, r):
    s = 0.8
    exact = stats.ncx2.cdf((r / s) ** 2, 2, (nu / s) ** 2) if nu else stats.chi2.cdf((r / s) ** 2, 2)
    assert D.norm_cdf(r, np.array([0.6 * nu, 0.8 * nu]), s ** 2 * np.eye(2)) == pytest.approx(exact, abs=1e-9)


def test_norm_cdf_matches_draws_of_an_anisotropic_normal():
    rng = np.random.default_rng(3)
    S = np.array([[1.0, 0.6], [0.6, 0.5]])
    mu = np.array([0.7, -1.1])
    R = np.hypot(*rng.multivariate_normal(mu, S, 400_000).T)
    for r in (0.5, 1.3, 2.0, 3.5):
        p = np.mean(R <= r)
        assert abs(D.norm_cdf(r, mu, S) - p) < 4 * np.sqrt(p * (1 - p) / R.size) + 1e-6


def test_norm_interval_is_the_delta_methods_far_from_zero_and_reaches_zero_near_it():
    S = np.array([[0.04, 0.01], [0.01, 0.02]])
    m = np.array([3.0, 4.0])
    lo, hi = D.norm_interval(m, S)
    u = m / 5.0
    half = 2 * np.sqrt(u @ S @ u)  # k = 2: the level is 95.45 %
    # the delta method's interval, a little wider: k about 2.05 for the phase's share of the miss, and the phases
    # near the estimate's that the data allow (here 25 standard deviations from zero: a few degrees)
    assert 5.0 - 1.06 * half < lo < 5.0 - half and 5.0 + half < hi < 5.0 + 1.06 * half
    # each end is where some allowed phase's tail is the test's (NORM_LEVEL + the phase's share)
    a = D.NORM_LEVEL + D.NORM_PHASE_SHARE * (1 - D.NORM_LEVEL)
    ph = np.linspace(-0.2, 0.2, 4001) + np.arctan2(4.0, 3.0)
    U = np.column_stack([np.cos(ph), np.sin(ph)])
    ok = np.abs(U[:, 1] * 3.0 - U[:, 0] * 4.0) <= stats.norm.isf(D.NORM_PHASE_SHARE *
                                                                (1 - D.NORM_LEVEL) / 2) * np.sqrt(
        np.einsum("ij,jk,ik->i", np.column_stack([-U[:, 1], U[:, 0]]), S, np.column_stack([-U[:, 1], U[:, 0]])))
    F_lo = [D.norm_cdf(5.0, lo * w, S) for w in U[ok][::40]]
    F_hi = [D.norm_cdf(5.0, hi * w, S) for w in U[ok][::40]]
    # (within 1e-3: the code samples the allowed arc at NORM_PHASES + 1 phases, this check at a hundred; 1e-3 of
    # tail probability is 0.004 of the amplitude here, under 1 % of the U95)
    assert min(F_lo) == pytest.approx((1 + a) / 2, abs=1e-3) and max(F_hi) == pytest.approx((1 - a) / 2, abs=1e-3)
    # an amplitude within its noise: a zero is consistent, the upper end above the delta method's
    lo, hi = D.norm_interval(np.array([0.15, 0.05]), S)
    assert lo == 0.0 and hi > 0.158 + 2 * 0.14
    # below the zero's own lower quantile: only zero
    assert D.norm_interval(np.array([0.001, 0.0]), S) == (0.0, 0.0)


def _coverage(A, S, n, rng):
    L = np.linalg.cholesky(S)
    new = delta = 0
    for _ in range(n):
        th = rng.uniform(0, 2 * np.pi)
        m = A * np.array([np.cos(th), np.sin(th)]) + L @ rng.standard_normal(2)
        v = np.hypot(*m)
        lo, hi = D.norm_interval(m, S)
        new += abs(v - A) <= max(hi - v, v - lo)
        u = m / v
        delta += abs(v - A) <= 2 * np.sqrt(u @ S @ u)
    return new / n, delta / n


def test_toy_coverage_of_a_zero_and_of_an_amplitude_near_the_noise():
    """A toy with a known truth: a harmonic of amplitude A in noise S (draws made here). The delta method covers
    a zero amplitude ``1 - exp(-2)`` = 86.5 % of the time with isotropic noise (``|m|`` is Rayleigh there, its
    U95 twice the noise); the interval of the norm at least 95 % (97.5 % expected: the lower tail is empty)."""
    rng = np.random.default_rng(21)
    new, delta = _coverage(0.0, np.eye(2), 600, rng)
    assert new >= 0.95 and delta < 0.92
    for A, S in ((1.0, np.eye(2)), (2.0, np.array([[1.0, 0.6], [0.6, 0.5]]))):
        new, _ = _coverage(A, S, 600, rng)
        assert new > 0.95 - 3 * np.sqrt(0.95 * 0.05 / 600)


@pytest.mark.parametrize("A, S", [(0.5, np.diag([1.0, 0.01])), (1.0, np.diag([1.0, 0.01])),
                                  (1.0, np.diag([1.0, 0.1]))])


def test_interval_covers_along_the_noisy_axis_of_an_anisotropic_pair(A, S):
    """The session 21 review: with the estimate's phase held, the interval of ``|mu|`` covered 0.87-0.88 where
    the truth lies along the noisier axis and the amplitude is within a few noise widths (the law of ``|m|``
    depends on the unknown phase). The phases the data allow (NORM_PHASE_SHARE) cover it: at least 95.45 %
    less three binomial standard errors over 800 draws made here, the truth on the noisy axis."""
    rng = np.random.default_rng(7)
    L = np.linalg.cholesky(S)
    n, hit = 800, 0
    for _ in range(n):
        m = np.array([A, 0.0]) + L @ rng.standard_normal(2)
        lo, hi = D.norm_interval(m, S)
        hit += lo <= A <= hi
    assert hit / n >= D.NORM_LEVEL - 3 * np.sqrt(D.NORM_LEVEL * (1 - D.NORM_LEVEL) / n), hit / n


@pytest.mark.parametrize("name, info", [("probe_lobing", {}), ("periodic_axis_error", {"axis": "Y", "period_m": 0.025}),
                                        ("part_change", {"ring": True, "feature": "bore"})])


def test_declared_norms_are_the_magnitudes(name, info):
    """Every norm a cause declares (Cause.norms) is its magnitude's value: the interval is made for it."""
    cause = causes.lookup(name)
    rng = np.random.default_rng(5)
    coef = rng.normal(0, 2e-6, 8)
    vals = cause.magnitudes(info, coef, None)
    pairs = cause.norms(info)
    assert pairs
    for key, (i, j) in pairs.items():
        assert vals[key] == pytest.approx(np.hypot(coef[i], coef[j]) / UM, rel=1e-12, abs=0)
        out = D._norm_u95(cause, info, key, vals[key], coef, np.eye(8) * 1e-14)
        assert out is not None and out[1][0] <= vals[key] <= out[1][1]
    # a value that is not the declared norm gets no norm interval (the delta method's U95 stays)
    key = next(iter(pairs))
    assert D._norm_u95(cause, info, key, vals[key] * 1.01 + 1.0, coef, np.eye(8) * 1e-14) is None


def _bump_campaign(rng, c, w, amp, sigma, n=240):
    """A toy local scale defect along x: touches at random positions (mm -> m), normals along x, the bump
    ``amp hann((x - c) / w)`` read as ``-n_x`` times it (core.causes._defect_cols' sign) plus white noise."""
    x = rng.uniform(-0.04, 0.04, n)
    data = SimpleNamespace(x=x, y=np.zeros(n), nx=np.ones(n), ny=np.zeros(n))
    u = (x - c) / w
    y = -amp * np.where(np.abs(u) < 1, 0.5 * (1 + np.cos(np.pi * u)), 0.0) + rng.normal(0, sigma, n)
    return SimpleNamespace(data=data, y=y)


def test_profile_interval_of_a_bumps_centre_and_half_width_covers_the_truth():
    """A toy bump with a known centre and half-width, fitted here by a grid search of its own (not the code's):
    the profile's interval holds the truth in about 95 % of the draws (k = 2 on one parameter)."""
    cause = causes.lookup("local_scale_defect")
    rng = np.random.default_rng(13)
    c, w, amp, sigma = 0.0031, 0.0042, 6e-6, 1e-6
    n_draw, inside = 60, {"centre_mm": 0, "half_width_mm": 0}
    cs, ws = c + np.linspace(-0.004, 0.004, 81), np.linspace(0.002, 0.008, 61)
    for _ in range(n_draw):
        bl = _bump_campaign(rng, c, w, amp, sigma)
        rows = np.arange(bl.y.size)
        Qo = np.ones((rows.size, 1)) / np.sqrt(rows.size)
        ro = bl.y - bl.y.mean()
        best = (np.inf, None)
        for cc in cs:  # the fit: least squares of one amplitude beside a constant, the best (centre, width)
            u = (bl.data.x[:, None] - cc) / ws[None, :]
            E = -np.where(np.abs(u) < 1, 0.5 * (1 + np.cos(np.pi * u)), 0.0)
            E = E - E.mean(axis=0)
            den = np.maximum((E * E).sum(axis=0), 1e-300)
            rss = ro @ ro - (E.T @ ro) ** 2 / den
            j = int(np.argmin(rss))
            if rss[j] < best[0]:
                best = (rss[j], (cc, ws[j]))
        tm = SimpleNamespace(info={"axis": "X", "centre_m": best[1][0], "half_width_m": best[1][1]}, penalty=None)
        out = D._profile_u95(cause, bl, tm, Qo, rows)
        for key, truth in (("centre_mm", c * 1e3), ("half_width_mm", w * 1e3)):
            _, lo, hi, _ = out[key]
            inside[key] += lo <= truth <= hi
    for key, k in inside.items():
        assert k / n_draw >= 0.85, (key, k)


def test_profile_interval_on_a_fine_grid_covers_at_its_stated_level_not_at_one_sigma():
    """The profile's threshold and dof, apart from its grid: the centre alone profiled (the half-width known) on a
    grid 1/50 of the interval's width, so the hull's widening to the next grid point adds about 2 %. Over 300
    draws the truth is inside 0.92-0.99 of the time (4 s^2: 95.45 % for one parameter; the binomial's sd 1.2 %).
    The test above cannot tell 84 % from 95 % (its coarse grid widens every interval); this one can: the same
    draws with the threshold at 2 s^2 (84.3 %) cover 0.857, with 7 as the seed 0.88 (measured, session 22)."""
    cause = causes.lookup("local_scale_defect")
    rng = np.random.default_rng(13)
    c, w, amp, sigma = 0.0031, 0.0042, 6e-6, 1e-6
    cs = c + np.linspace(-0.004, 0.004, 801)
    one = SimpleNamespace(profile=lambda info: {"centre_m": (cs, "centre_mm", 1e3)}, rebuild=cause.rebuild)
    n_draw, inside, widths = 300, 0, []
    for _ in range(n_draw):
        bl = _bump_campaign(rng, c, w, amp, sigma)
        rows = np.arange(bl.y.size)
        Qo = np.ones((rows.size, 1)) / np.sqrt(rows.size)
        ro = bl.y - bl.y.mean()
        u = (bl.data.x[:, None] - cs[None, :]) / w  # the fit, written here: the best centre on the grid
        E = -np.where(np.abs(u) < 1, 0.5 * (1 + np.cos(np.pi * u)), 0.0)
        E = E - E.mean(axis=0)
        rss = ro @ ro - (E.T @ ro) ** 2 / np.maximum((E * E).sum(axis=0), 1e-300)
        tm = SimpleNamespace(info={"axis": "X", "centre_m": cs[int(np.argmin(rss))], "half_width_m": w},
                             penalty=None)
        _, lo, hi, edge = D._profile_u95(one, bl, tm, Qo, rows)["centre_mm"]
        assert not edge
        inside += lo <= c * 1e3 <= hi
        widths.append(hi - lo)
    assert 0.92 <= inside / n_draw <= 0.99, inside
    assert np.median(widths) > 40 * (cs[1] - cs[0]) * 1e3  # the grid is fine against the interval


def test_a_covariance_that_is_not_finite_keeps_the_delta_methods_u95():
    cause = causes.lookup("probe_lobing")
    coef = np.array([1e-6, 0.0, 2e-6, 1e-6, 0.0, 0.0, 0.0, 0.0])
    cov = np.eye(8) * 1e-14
    cov[2, 3] = np.nan
    vals = cause.magnitudes({}, coef, None)
    assert D._norm_u95(cause, {}, "k2_amplitude_um", vals["k2_amplitude_um"], coef, cov) is None
    assert D._norm_u95(cause, {}, "k1_amplitude_um", vals["k1_amplitude_um"], coef, cov) is not None


def test_profile_in_small_chunks_is_the_profile_in_one(monkeypatch):
    """A long log fits the profile's trials a few at a time (PROFILE_CHUNK_BYTES): the intervals are the same as
    from one chunk of every trial (each trial's sum of squares is its own row of the batch)."""
    cause = causes.lookup("local_scale_defect")
    bl = _bump_campaign(np.random.default_rng(5), 0.0031, 0.0042, 6e-6, 1e-6)
    rows = np.arange(bl.y.size)
    Qo = np.ones((rows.size, 1)) / np.sqrt(rows.size)
    tm = SimpleNamespace(info={"axis": "X", "centre_m": 0.0031, "half_width_m": 0.0042}, penalty=None)
    one = D._profile_u95(cause, bl, tm, Qo, rows)
    monkeypatch.setattr(D, "PROFILE_CHUNK_BYTES", 3 * 8 * rows.size * 7)  # seven trials a chunk
    few = D._profile_u95(cause, bl, tm, Qo, rows)
    assert set(one) == {"centre_mm", "half_width_mm"} and set(few) == set(one)
    for key in one:
        np.testing.assert_allclose(few[key][:3], one[key][:3], rtol=0, atol=1e-12)
        assert few[key][3] == one[key][3]


def test_a_pair_with_no_spread_across_its_estimate_gets_an_interval():
    """A pair whose covariance is nil across the estimate (one coefficient nearly fixed): the estimate's own
    phase stays allowed. Before session 22 rounding (m . v about 1e-16 |m| at that phase) emptied the allowed
    set and discover stopped with an IndexError on gen_a periodic_axis_error (the pair below, from that
    campaign; 60 of these 300 rank-one draws)."""
    m = np.array([3.11359653e-21, 4.89096463e-06])
    S = np.array([[5.64258470e-45, 9.23343687e-30], [9.23343687e-30, 2.25838764e-14]])
    lo, hi = D.norm_interval(m, S)
    s = np.sqrt(S[1, 1])  # all the spread is along the estimate: the delta method's interval, k about 2.05
    assert 1.9 * s < m[1] - lo < 2.2 * s and 1.9 * s < hi - m[1] < 2.2 * s
    rng = np.random.default_rng(1)
    for i in range(300):
        a, r = rng.uniform(0, 2 * np.pi), rng.uniform(1, 10)
        b = a + rng.choice([0.0, np.pi / 2, rng.uniform(0, np.pi)])
        v = np.array([np.cos(b), np.sin(b)])
        S = np.outer(v, v) + (0.0 if i % 2 else 1e-40) * np.eye(2)
        lo, hi = D.norm_interval(r * np.array([np.cos(a), np.sin(a)]), S)
        assert 0 <= lo <= r <= hi


def test_a_pair_with_one_coefficient_undetermined_keeps_the_estimates_phase():
    """The gen_a probe_lobing 1025 campaign (a tuning seed): a candidate periodic_axis_error's pair in the search
    had one coefficient a rounding (variance 1.5e-45 m^2 against 3.6e-14), and ``m . v`` at the estimate's own
    phase, a rounding too, exceeded the allowed width across it: no phase was allowed and discover raised an
    IndexError (session 22). Given this S the interval is the other coefficient's, ``|m| +- ~2 sd``; whether such a
    norm is reported at all is _magnitudes' question (the next test)."""
    m = np.array([4.28679047e-22, -2.92711414e-06])
    S = np.array([[3.13983550e-45, -7.59952944e-30], [-7.59952944e-30, 3.59632123e-14]])
    lo, hi = D.norm_interval(m, S)
    sd = np.sqrt(S[1, 1])
    assert lo < 2.92711414e-06 < hi
    assert 1.9 * sd < 2.92711414e-06 - lo < 2.2 * sd and 1.9 * sd < hi - 2.92711414e-06 < 2.2 * sd


def test_a_norm_with_a_coefficient_the_data_cannot_see_is_not_reported():
    """gen_a periodic_axis_error 1025 (a tuning seed): its EXX pair's cos coefficient lies along a weak direction
    (held at 0, not known to be 0). The amplitude's gradient is 0 there, so the weak-direction check let it through
    and the report gave 3.970 +- 0.273 um, a lower bound read as an estimate (the session 22 review). A norm whose
    pair has a coefficient along a weak direction is not reported."""
    import scenarios.blind.gen_a as gen_a
    log, _ = gen_a.generate("periodic_axis_error", 1025)
    rep = discovered(log).to_report()
    f = next(f for f in rep["findings"] if f["cause"] == "periodic_axis_error")
    assert f["evidence"]["not_identifiable_directions"] >= 1
    assert f["params"]["EXX_amplitude_um"] is None and f["params_u95"]["EXX_amplitude_um"] is None


def _first_finding(monkeypatch, gen, effect, seed, **flags):

    for k, v in flags.items():
        monkeypatch.setattr(D, k, v)
    log, tr = gen.generate(effect, seed)
    return discovered(log).to_report()[
        "findings"][0], tr


def test_norm_intervals_rule_in_the_report(monkeypatch):
    """:data:`core.discover.NORM_INTERVALS` in a report of its own (review31d F9: only the identity snapshot failed
    without it). gen_a periodic_axis_error 1000 (a tuning seed, the truth a Y-axis periodic error): the finding's
    cross amplitude EXY (0.038 um, of the order of its noise) gets the norm's interval, which stops at 0 (a norm
    is >= 0), and its U95 is the interval's symmetric cover max(hi - v, v - lo); without the rule the delta
    method's 0.068 um (v - U95 < 0), no interval. (1 s a run.)"""
    from scenarios.blind import gen_a

    f, tr = _first_finding(monkeypatch, gen_a, "periodic_axis_error", 1000)
    assert f["cause"] == "periodic_axis_error" and f["params"]["axis"] == tr.params["axis"] == "Y", f
    iv = f["evidence"]["magnitude_intervals"]
    assert set(iv) == {"EXY_amplitude_um", "EYY_amplitude_um"}
    for key, (lo, hi) in iv.items():
        v = f["params"][key]
        assert lo <= v <= hi and f["params_u95"][key] == pytest.approx(max(hi - v, v - lo), rel=1e-12, abs=0), key
    assert iv["EXY_amplitude_um"][0] == 0.0 and iv["EYY_amplitude_um"][0] > 2.0
    g, _ = _first_finding(monkeypatch, gen_a, "periodic_axis_error", 1000, NORM_INTERVALS=False)
    assert g["params"]["EXY_amplitude_um"] == f["params"]["EXY_amplitude_um"]
    assert "magnitude_intervals" not in g["evidence"]
    assert g["params"]["EXY_amplitude_um"] - g["params_u95"]["EXY_amplitude_um"] < 0.0  # the delta method's


def test_profile_nonlinear_rule_covers_a_centre_the_delta_method_misses(monkeypatch):
    """:data:`core.discover.PROFILE_NONLINEAR` in a report of its own (review31d F9). gen_b local_scale_defect 1000
    (a tuning seed, the truth's centre -154.85 mm on Y): the finding's centre -153.91 mm, 0.94 mm off. Its U95 from
    the profile likelihood, 1.16 mm (the interval [-154.49, -152.75] booked in magnitude_intervals), covers the
    truth; the delta method's, 0.56 mm, does not (without the rule). (1-2 s a run.)"""
    from scenarios.blind import gen_b

    f, tr = _first_finding(monkeypatch, gen_b, "local_scale_defect", 1000)
    assert f["cause"] == "local_scale_defect" and f["params"]["axis"] == "Y", f
    err = abs(f["params"]["centre_mm"] - tr.params["centre_mm"])
    assert 0.9 < err <= f["params_u95"]["centre_mm"], (err, f["params_u95"])
    assert "centre_mm" in f["evidence"]["magnitude_intervals"]
    g, _ = _first_finding(monkeypatch, gen_b, "local_scale_defect", 1000, PROFILE_NONLINEAR=False)
    assert g["params"]["centre_mm"] == f["params"]["centre_mm"]
    assert g["params_u95"]["centre_mm"] < err  # the delta method's 0.56 mm misses the truth
    assert "magnitude_intervals" not in g["evidence"]
