"""Honest uncertainty beside the penalised ``nonrigid`` cause (session 16, issue 13 item 3(d)).

The field's RMS and peak take their U95 from a parametric bootstrap (``core.discover._penalised_bootstrap``:
truths drawn from the ridge's posterior, data simulated from each, the ridge chosen again, the basic
bias-corrected interval; a one-sided bound for an RMS that reaches zero), and a cause fitted beside an adopted
``nonrigid`` has its coefficients, covariance and determined directions with nonrigid's columns penalised in the
nuisance (before: projected on the baseline's columns alone, as if the field were not in the model).
"""

import dataclasses

import numpy as np
import pytest

import discover_synth as S
from core import causes
from core.discover import _gram_beside, _penalised_bootstrap, discover

SEEDS = range(100, 140)


@pytest.fixture(scope="module")
def field_runs():
    """The synthetic non-rigid field (P2(xs) P2(ys) in E_X, 6 um, 0.3 um noise) on 40 seeds: the reports' nonrigid
    findings with the true magnitudes (those of the true coefficients on the same probed extent)."""
    out = []
    for seed in SEEDS:
        t, _ = S.campaign("nonrigid_field", seed, 6e-6)
        d = discover(t)
        f = next((f for f in d.to_report()["findings"] if f["cause"] == "nonrigid"), None)
        if f is None:
            continue
        axes = f["params"]["axes"]
        coef = np.zeros(6 * len(axes))
        coef[6 * axes.index("X") + 4] = 6e-6
        out.append((f, causes.nonrigid_magnitudes({"axes": axes}, coef, d.baseline)))
    return out


@pytest.mark.slow
def test_nonrigid_u95_covers_the_truth(field_runs):
    """Coverage of the field's U95 over 40 seeds of a known field. Expected rate 0.95 per interval; 80 intervals
    of the RMS (both axes) and 80 of the peak: at most 8 misses each (P(9 or more | 0.95 coverage) = 0.02).
    Measured: the RMS 2 misses (EX 105, 135), the peak 1 (EX 119; 2 with EX 113 before session 17's principal root
    of the posterior and the search's own penalty grid). The ridge's Bayesian U95 by the delta
    method (session 15) missed the RMS 10 times in 76 (EX 105, 114, 130, 135, 136; the zero field of Y 102, 118,
    123, 132, 135) and named nonrigid on 38 seeds: this test fails on it."""
    assert len(field_runs) >= 38
    miss = {"rms": [], "peak": []}
    for f, truth in field_runs:
        for k, v in truth.items():
            u, p = f["params_u95"][k], f["params"][k]
            if u is None or p is None or abs(p - v) > u:
                miss["rms" if "rms" in k else "peak"].append(k)
    assert len(miss["rms"]) <= 8, miss
    assert len(miss["peak"]) <= 8, miss


def test_nonrigid_u95_intervals_reported(field_runs):
    """Each finding says how its U95 was made; an RMS of a zero field is a one-sided bound (upper, >= the value)."""
    f, truth = field_runs[0]
    iv = f["evidence"]["magnitude_interval95"]
    assert iv["method"].startswith("parametric bootstrap, 200 refits")
    for k in truth:
        assert k in iv
    one = [f for f, _ in field_runs if "upper_one_sided" in f["evidence"]["magnitude_interval95"]["EY_field_rms_um"]]
    assert one  # the zero field of Y is bounded from above on some seeds
    for f in one:
        up = f["evidence"]["magnitude_interval95"]["EY_field_rms_um"]["upper_one_sided"]
        v, u = f["params"]["EY_field_rms_um"], f["params_u95"]["EY_field_rms_um"]
        assert v - u <= 0 <= v + u and v + u >= up - 1e-12


def test_penalised_bootstrap_bad_input():
    """Inconsistent shapes and a non-finite or negative noise variance are refused."""
    rng = np.random.default_rng(0)
    n, k = 30, 3
    Ep, ro, yr, Qo = rng.normal(size=(n, k)), rng.normal(size=n), rng.normal(size=n), np.zeros((n, 0))
    tm = dataclasses.make_dataclass("T", ["columns", "penalty", "info", "evidence"])(Ep, np.eye(k), {}, {})
    args = dict(cause=None, bl=None, tm=tm, Ep=Ep, ro=ro, yr=yr, Qo=Qo, rows=np.arange(n), folds=None, others=[],
                c_hat=np.zeros(k), s2=1.0, vals={}, num=[])
    for bad in (dict(s2=np.nan), dict(s2=-1.0), dict(ro=ro[:-1]), dict(c_hat=np.zeros(k + 1)),
                dict(rows=np.arange(n - 1))):
        with pytest.raises(ValueError):
            _penalised_bootstrap(**{**args, **bad})


def test_gram_beside_known_answer():
    """Beside penalised columns S with penalty P the Gram matrix of a column e is what their ridge fit leaves:
    with P = 0 the projection out of S (e = S: nothing left), with P large e's own Gram."""
    rng = np.random.default_rng(1)
    S_ = rng.normal(size=(40, 2))
    e = S_[:, :1].copy()
    Q = np.zeros((40, 0))
    assert abs(_gram_beside(e, Q, (S_, np.zeros((2, 2))))[0, 0]) < 1e-9
    assert np.isclose(_gram_beside(e, Q, (S_, 1e12 * np.eye(2)))[0, 0], float(e[:, 0] @ e[:, 0]), rtol=1e-6)
    assert np.isclose(_gram_beside(e, Q, None)[0, 0], float(e[:, 0] @ e[:, 0]))


def _with_reversal(seed: int, field_um: float):
    """The synthetic field (P2 P2 in E_X, ``field_um``) and a reversal of 1.5 um lost motion in X: the reversal's
    finding (its params and U95)."""
    t, _ = S.campaign("nonrigid_field", seed, field_um * 1e-6)
    e2, kw = S.effect("reversal", t, np.random.default_rng(seed + 5000), 1.5e-6)
    t = dataclasses.replace(t, p_R=t.p_R + e2[:, None] * t.n_R, **kw)
    rep = discover(t).to_report()
    return rep, next((f for f in rep["findings"] if f["cause"] == "reversal"), None)


@pytest.mark.parametrize("seed", [100, 102])
def test_cause_beside_nonrigid_fitted_with_it(seed):
    """A reversal (1.5 um lost motion in X, 0 in Y) adopted beside a 20 um non-rigid field: its lost motions cover
    the truth and their U95 is at most 1.5 times that of the same campaign without the field (the same noise), the
    field's columns penalised in the nuisance. Measured: x 1.40 +- 0.53 and 1.37 +- 0.52 um at seeds 100 and 102
    against 0.42 and 0.41 field-free (1.24-1.27 times: the joint fit's Bayesian block carries the field's prior
    spread along the reversal's columns). Before (the reversal's magnitudes projected on the baseline's columns
    alone, the field left in its residuals): 1.44 +- 1.21 and 1.35 +- 1.20 um, 2.8-2.9 times the field-free U95
    for both lost motions: this test fails there."""
    rep, f = _with_reversal(seed, 20.0)
    assert rep["findings"][0]["cause"] == "nonrigid" and f is not None, [g["cause"] for g in rep["findings"]]
    _, f0 = _with_reversal(seed, 0.0)
    assert f0 is not None
    for k, truth in (("x_lost_motion_um", 1.5), ("y_lost_motion_um", 0.0)):
        v, u, u0 = f["params"][k], f["params_u95"][k], f0["params_u95"][k]
        assert abs(v - truth) <= u, (k, v, u)
        assert u <= 1.5 * u0, (k, u, u0)
