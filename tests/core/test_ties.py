"""Ties broken by a fixed order, not by the floating-point kernels' rounding (issue 19 item 6).

Two terms that span the same space outside the model (the set-up's and the
C angle's when each set-up has its own C; a campaign-long C drift and one
within each set-up beside the set-ups' own angles) explain the same sum of
squares in exact arithmetic; which one a sort put first was the rounding of
the machine's BLAS and SIMD loops (gen_a thermal_bending 604, gen_a nonrigid
2, gen_b stylus_pickup 501 differed between Haswell and SkylakeX kernels).
"""

from __future__ import annotations

import numpy as np
import pytest

from core.diagnosis import TIE_RTOL, Covariate, diagnose, nested_f_batch, orth, rank_with_ties, tied
from core.discover import _better_trial, _Trial


def test_tied_known_answers():
    assert tied(1.0, 3, 1.0 + 0.5 * TIE_RTOL * 10.0, 3, 10.0)  # within TIE_RTOL of rss
    assert not tied(1.0, 3, 1.0 + 2 * TIE_RTOL * 10.0, 3, 10.0)  # beyond it
    assert not tied(1.0, 3, 1.0, 4, 10.0)  # another dimension is another test, whatever its ss
    assert not tied(float("nan"), 3, 1.0, 3, 10.0)  # bad input: never a tie (the key decides)


def test_rank_with_ties_known_answer():
    items = ["a", "b", "c", "d"]
    key = {"a": 3.0, "b": 1.0 + 1e-15, "c": 2.0, "d": 1.0}.__getitem__
    ssk = {"a": (5.0, 1), "b": (9.0, 2), "c": (7.0, 2), "d": (9.0 + 1e-9, 2)}.__getitem__
    # b and d tie (same k, ss 1e-9 apart, rss 1): input order b, d although d sorts first
    assert rank_with_ties(items, key, ssk, 1.0) == ["b", "d", "c", "a"]
    assert rank_with_ties(items[::-1], key, ssk, 1.0) == ["d", "b", "c", "a"]
    # no tie at a scale where 1e-9 is beyond TIE_RTOL: the key's order
    assert rank_with_ties(items, key, ssk, 1e-3) == ["d", "b", "c", "a"]
    assert rank_with_ties([], key, ssk, 1.0) == []


def _setup_and_c(seed: int, order, eps: float = 1e-15, angles=(2.0, 0.0, 1.0)):
    """Diagnoses of a set-up effect with one C angle per set-up (the same span, columns reordered)."""
    rng = np.random.default_rng(7)
    n = 90
    setup = np.repeat(np.arange(3), n // 3)
    C = np.array(angles)[setup] * 0.7
    covs = {"setup": Covariate("setup", setup, "categorical", 0, (0,), "the set-up", "time"),
            "C": Covariate("C", C, "categorical", 0, (0,), "the C angle", "direction"),
            "x": Covariate("x", rng.uniform(-1, 1, n), "smooth", 5, (0,), "x", "position")}
    modes = np.ones((n, 1))
    Q = orth(np.column_stack([np.ones(n), rng.normal(size=n)]))
    y = np.array([0.0, 2.0, -1.0])[setup] * 1e-6 + rng.normal(0, 3e-7, n)
    y = y * (1 + eps * np.random.default_rng(seed).standard_normal(n))  # a rounding-level perturbation
    r = y - Q @ (Q.T @ y)
    return diagnose(Q, r, n - 2, [covs[k] for k in order], modes, sigma_m=3e-7, material_sigma=0.3)


def test_diagnose_breaks_a_tie_in_the_covariates_order():
    """Fails on main: the order of set-up and C followed the rounding (4 and 3 of these 12 perturbations flipped it)."""
    for order in (("setup", "C", "x"), ("C", "setup", "x")):
        for seed in range(12):
            d = _setup_and_c(seed, order)
            assert [x.covariate for x in d[:2]] == list(order[:2]), (order, seed)
            assert d[0].significant(0.05) and d[0].k == d[1].k == 2  # a real finding, the tie exact
            assert abs(d[0].explained_rms_um - d[1].explained_rms_um) < 1e-9 * d[0].explained_rms_um
    # not a tie: a set-up effect C cannot follow (two set-ups at one angle) is ranked by its evidence
    d = _setup_and_c(0, ("C", "setup", "x"), angles=(0.0, 0.0, 1.0))
    assert d[0].covariate == "setup" and d[0].explained_rms_um > 1.1 * next(
        x.explained_rms_um for x in d if x.covariate == "C")


def test_better_trial_takes_the_catalogue_first_of_tied_trials():
    """Two trials spanning the same space outside the model: the first scan's wins, whatever the rounding.

    Fails on main (no rule: the smaller p, then the larger F, picked b over a in 4 of these 12
    perturbations, this machine).
    """
    rng = np.random.default_rng(11)
    n = 60
    Q = orth(np.column_stack([np.ones(n), np.linspace(-1, 1, n)]))
    a = rng.normal(size=n)
    b = 3.0 * a + Q @ np.array([0.4, -2.0])  # the same direction once the model is projected out
    c = rng.normal(size=n)
    y = 0.5 * a + rng.normal(0, 0.1, n)
    for seed in range(12):
        yy = y * (1 + 1e-15 * np.random.default_rng(seed).standard_normal(n))
        r = yy - Q @ (Q.T @ yy)
        rss = float(r @ r)
        ss, k, F, p = nested_f_batch(np.stack([a, b, c])[:, :, None], Q, r, rss, n - 2)
        cands = [_Trial(float(p[j]), float(F[j]), int(k[j]), None, j, None, float(ss[j]), (j, 0)) for j in range(3)]
        assert tied(ss[0], k[0], ss[1], k[1], rss) and not tied(ss[0], k[0], ss[2], k[2], rss)
        for seq in ([0, 1, 2], [1, 0, 2], [2, 1, 0], [2, 0, 1]):
            best = None
            for j in seq:
                if best is None or _better_trial(cands[j], best, rss):
                    best = cands[j]
            assert best.order == (0, 0), (seed, seq)  # a and b tie; a is first in the catalogue; c explains less


def test_family_ss_keeps_the_first_of_tied_terms():
    """Fails on main: of two tied terms of one family the one rounding made larger named the family.

    (gen_a nonrigid 2 under OPENBLAS_CORETYPE=Sandybridge: 'the structure follows y' against 'xy'.)
    """
    from core.diagnosis import Diagnosis, NestedTest
    from core.discover import _family_ss

    class Bl:
        covs = {"y": Covariate("y", np.zeros(3), "smooth", 5, (0,), "y", "position"),
                "xy": Covariate("xy", np.zeros(3), "smooth", 5, (0,), "xy", "position"),
                "time": Covariate("time", np.zeros(3), "smooth", 5, (0,), "time", "time")}

        def covariate(self, name):
            return self.covs.get(name)

    def diag(name, rms_um, ss, k=5):
        return Diagnosis(name, rms_um, 1e-9, 1e-9, k, name, True, test=NestedTest(k, ss, 10.0, 1e-9, rms_um * 1e-6))

    rss, n = 1e-8, 100
    tie = [diag("y", 0.7086747750483215, 4.0e-9), diag("xy", 0.7086747750483222, 4.0e-9 * (1 + 1e-14)),
           diag("time", 0.3, 1e-9)]
    assert _family_ss(Bl(), tie, n, rss)["position"][1] == "y"  # the first in diagnose's order, not the larger
    assert _family_ss(Bl(), tie, n, rss)["time"][1] == "time"
    apart = [diag("y", 0.70, 4.0e-9), diag("xy", 0.71, 4.1e-9)]  # 1e-11 apart: 1e-3 of rss, no tie
    assert _family_ss(Bl(), apart, n, rss)["position"] == (pytest.approx((0.71e-6) ** 2 * n, abs=0), "xy")
    assert _family_ss(Bl(), tie, n)["position"][1] == "xy"  # without rss (no model to judge a tie): the larger


def test_smallest_angle_known_answers():
    """Fails on main (no helper; its arccos gave 8.5e-7 deg for a span inside the model under Sandybridge kernels)."""
    from core.discover import _smallest_angle_deg

    n = 50
    Q = np.eye(n)[:, :3]
    for deg in (0.0, 1e-9, 1e-3, 4.6, 45.0, 89.0):
        t = np.radians(deg)
        e = np.zeros((n, 1))
        e[0, 0], e[5, 0] = np.cos(t), np.sin(t)
        assert _smallest_angle_deg(Q, e) == pytest.approx(deg, rel=1e-12, abs=1e-13), deg
    rng = np.random.default_rng(2)
    inside = orth(Q @ rng.normal(size=(3, 2)))  # a span inside the model: exactly zero, to rounding
    assert _smallest_angle_deg(Q, inside) < 1e-12
    assert _smallest_angle_deg(Q, np.zeros((n, 0))) == 90.0  # no span: nothing is aligned (as before)


def test_spline_knots_do_not_count_a_rounding_split_repeat_as_a_value():
    """Known answers: repeats of one value parted by rounding (6e-17 m, as the BLAS kernels part repeat touches'
    positions: gen_a nonrigid 1039's x, 78 distinct values on SkylakeX kernels and 79 on Haswell's) are one value,
    so the spline's quantile knots and its basis are those of the exact repeats; values 1e-6 of the span apart
    stay two."""
    from core.diagnosis import DISTINCT_RTOL, distinct_values, spline_basis

    rng = np.random.default_rng(2)
    base = np.round(rng.uniform(-0.4, 0.1, 30), 4)
    exact = np.repeat(base, 3)
    split = exact + np.tile([0.0, 5.551115123125783e-17, -5.551115123125783e-17], 30)
    assert np.unique(split).size > np.unique(exact).size  # np.unique parts them
    u = distinct_values(split)
    assert u.size == np.unique(exact).size and np.max(np.abs(u - np.unique(exact))) <= 6e-17
    np.testing.assert_allclose(spline_basis(split, 12), spline_basis(exact, 12), rtol=0, atol=1e-12)
    close = np.array([0.0, 1e-6, 1.0])  # 1e-6 of the span apart: two values (1e-6 > DISTINCT_RTOL)
    assert distinct_values(close).tolist() == [0.0, 1e-6, 1.0] and 1e-6 > DISTINCT_RTOL
    assert distinct_values(np.array([2.0])).tolist() == [2.0] and distinct_values(np.zeros(0)).size == 0
    one = np.array([0.3, 0.3 + 5.551115123125783e-17, 0.3])  # a constant parted by rounding: one value, no spline
    assert np.unique(one).size == 2 and distinct_values(one).tolist() == [0.3]
    assert spline_basis(one, 5).shape == (3, 1)
