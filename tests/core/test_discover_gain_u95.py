"""The U95 of discovery's cross-validated gain, judged against the repeated experiment.

The measurand is the cross-validated RMS ratio (extended / baseline) that
campaigns of one machine give: the same machine, workpiece, effect and
plan, new probing noise each time. Its spread over repeated campaigns is
measured here directly (not from the jackknife the engine uses), so a
U95 that is too narrow or far too wide fails.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from core.discover import _ratio_u95, cv_ratio_text, discover

import discover_synth as ds


def repeated_campaign(name: str, truth_seed: int, noise_seed: int, mag_m: float):
    """discover_synth's campaign with the truth drawn from ``truth_seed`` and the noise from ``noise_seed``."""
    rng = np.random.default_rng(truth_seed)
    t = ds.plan()
    e, kw = ds.effect(name, t, rng, mag_m)
    mf, _ = ds.machine_and_form(t, rng)
    dq = mf + e + np.random.default_rng(10_000 + noise_seed).normal(0, ds.SIG, t.n)
    return dataclasses.replace(t, p_R=t.pn_R + dq[:, None] * t.n_R, **kw)


def test_u95_covers_the_ratio_of_repeated_campaigns():
    # a 1 um, 9.3 mm periodic Y error at 0.3 um noise: named every time, the ratio near 0.5, and the
    # case where the jackknife's standard deviation came out lowest against the repeated campaigns'
    # (0.016 against 0.021 over 30 repeats; probe lobing 0.009 against 0.008, a thermal drift 0.040-0.044
    # against 0.045-0.048): the t factor of 4 set-ups (3.18) is what keeps the coverage
    R, U = [], []
    for noise_seed in range(20):
        rep = discover(repeated_campaign("periodic_axis_error", 0, noise_seed, 1e-6)).to_report()
        assert rep["cause"] == "periodic_axis_error"
        R.append(rep["gain"]["cv_rms_ratio"])
        U.append(rep["gain"]["cv_rms_ratio_u95"])
    R, U = np.array(R), np.array(U, float)
    truth = R.mean()  # the ratio's expectation over campaigns (its own error sd / sqrt(20), ~0.005)
    covered = np.abs(R - truth) <= U
    # at a true 95 %, 4 or more misses of 20 has probability 0.016
    assert covered.sum() >= 17, (covered.sum(), R.std(ddof=1), np.median(U))
    # and not covering by being vast: the U95 against the repeated campaigns' own 95 % half-width
    half = 1.96 * R.std(ddof=1)
    assert 0.7 * half <= np.median(U) <= 3.0 * half, (np.median(U), half)


def test_jackknife_by_hand():
    # three set-ups: baseline sums of squares 4, 4, 8 over 4 rows each; extended 1, 1, 1.
    # Left out in turn: sqrt((2/8) / (12/8)) = sqrt(1/6) twice, sqrt((2/8) / (8/8)) = 0.5 once;
    # their mean 0.438832, deviations -0.030584, -0.030584, 0.061168: jackknife variance
    # 2/3 * 0.0056123 = 0.0037415, sd 0.061168; t(0.975, 2) = 4.302653 -> 0.263184
    held_b = {0: (4.0, 4.0), 1: (4.0, 4.0), 2: (8.0, 4.0)}
    held_e = {0: (1.0, 4.0), 1: (1.0, 4.0), 2: (1.0, 4.0)}
    assert _ratio_u95(held_b, held_e) == pytest.approx(0.263184, abs=2e-6)


def test_no_u95_where_there_is_nothing_to_resample():
    two = {0: (1.0, 3.0), 1: (2.0, 3.0)}
    assert _ratio_u95(two, {0: (0.5, 3.0), 1: (0.5, 3.0)}) is None  # two set-ups: no spread
    assert _ratio_u95(None, two) is None  # no cross-validation (Mallows' Cp)
    assert _ratio_u95(two, two) is None  # no extension: the same held-out residuals
    t, _ = ds.campaign("none", 3)
    rep = discover(t).to_report()
    assert rep["cause"] == "none" and rep["gain"]["cv_rms_ratio_u95"] is None
    assert cv_ratio_text(rep["gain"]) == "x1.00"
    assert cv_ratio_text({"cv_rms_ratio": 0.274, "cv_rms_ratio_u95": 0.031}) == "x0.27 +- 0.03 (U95)"
