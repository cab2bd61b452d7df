"""A named cause's magnitudes beside the unnamed smooth of the model reported (session 20, issue 13 item 3(d)).

Before, a cause kept beside an unnamed smooth reported magnitudes fitted beside the other named causes alone:
their U95 did not count the smooth (gen_a reversal 1054, a tuning seed: ``x_lost_motion`` -14.63 +- 0.64 um
against a true 13.87, which the report's sign convention reads -13.87). Now they are fitted beside the smooth's
columns too, with its penalty (the model reported), and the shift the smooth makes is tested and carried
(:func:`core.discover._beside_smooth`); the value reported stays the one beside the named causes alone (session 20's
review: more accurate on the tuning campaigns, the same U95).
"""

import types

import numpy as np
import pytest

import core.discover as D
from core.discover import _beside_smooth
from tests.discover_helpers import discovered


def _linear_case(lam):
    """A small linear design: a cause with one column (x) beside a constant, an unnamed smooth of three columns
    correlated with it (x^3, sin 2.5x, x cos x) with the ridge ``lam``; the cause's one magnitude its coefficient."""
    rng = np.random.default_rng(0)
    x = np.sort(rng.uniform(-1, 1, 60))
    cause = types.SimpleNamespace(magnitudes=lambda info, coef, bl: {"a_um": float(coef[0])}, bounds={},
                                  nonlinear=(), rebuild=None)
    tm = D.Term("c", x[:, None], ("a",), {}, "x", origin=cause, labels_all=("a",), map=np.eye(1))
    S = np.column_stack([x ** 3, np.sin(2.5 * x), x * np.cos(x)])
    sm = D.Term("unexplained", S, ("s0", "s1", "s2"), {}, "x", penalty=lam * np.eye(3), unnamed=True)
    return x, S, cause, tm, sm, np.ones((60, 1)) / np.sqrt(60)


def _shift_draws(lam, n_draws, smooth_coef=(0.0, 0.0, 0.0), seed=1):
    x, S, cause, tm, sm, Qo = _linear_case(lam)
    rows = np.arange(len(x))
    rng = np.random.default_rng(seed)
    out = []
    for _ in range(n_draws):
        y = 0.5 + 2.0 * x + S @ np.asarray(smooth_coef) + rng.standard_normal(len(x))
        bl = types.SimpleNamespace(y=y)
        l0, ls = {}, {}
        v0, u0 = D._magnitudes(cause, bl, tm, Qo, rows, boot=(None, []), lin=l0)
        vs, us = D._magnitudes(cause, bl, tm, Qo, rows, boot=(None, [sm]), lin=ls)
        v, u, fig = _beside_smooth(v0, u0, vs, us, 0.05, D._shift_variance(l0, ls))
        out.append((vs["a_um"] - v0["a_um"], D._shift_variance(l0, ls)["a_um"], fig["p_value"]["a_um"],
                    u["a_um"], us["a_um"], "a_um" in fig["carried_in_u95"]))
    return out


@pytest.mark.parametrize("lam", [0.3, 3.0, 30.0])
def test_beside_smooth_shift_test_under_no_shift(lam):
    """Under H0 (the smooth holds nothing, white noise): the shift's empirical variance over 2,000 noise draws matches
    the variance the test uses (within 10 %), and the test rejects at its level (0.05: 0.03..0.07). Measured: empirical
    var D 0.204, 0.0555, 0.00391 against the formula's mean 0.205, 0.0562, 0.00397; rejection 0.051, 0.049, 0.046.
    The approximation of before, (U95_s^2 - U95^2) / 4, was 25, 11 and 19 times the true variance here (rejecting
    none of the 2,000)."""
    a = _shift_draws(lam, 2000)
    d = np.array([r[0] for r in a])
    vd = np.array([r[1] for r in a])
    p = np.array([r[2] for r in a])
    assert d.var() == pytest.approx(vd.mean(), rel=0.10)
    assert 0.03 <= np.mean(p < 0.05) <= 0.07


def test_beside_smooth_carries_a_real_shift():
    """A smooth that holds part of the effect (its columns' true coefficients 5 each): the shift is real (p below
    alpha), carried: the U95 reported is hypot(U95 beside the smooth, D)."""
    for d, vd, p, u, us, carried in _shift_draws(3.0, 20, smooth_coef=(5.0, 5.0, 5.0)):
        assert p < 0.05 and carried
        assert u == pytest.approx(np.hypot(us, d))


def _run(effect, seed, beside):
    from core.touches import from_log
    from scenarios.blind import gen_a

    log, tr = gen_a.generate(effect, seed)
    t = from_log(log)
    old = D.MAGNITUDES_BESIDE_SMOOTH
    try:
        D.MAGNITUDES_BESIDE_SMOOTH = beside
        rep = discovered(log, t).to_report()
    finally:
        D.MAGNITUDES_BESIDE_SMOOTH = old
    return tr, rep


def test_gen_a_reversal_1054_lost_motion_within_its_u95_beside_the_feature_smooth():
    """gen_a reversal 1054 (tuning seed): the reversal is kept beside an unnamed smooth in `feature` that nests it
    (a bore's lost motion is its size per set-up). Beside the named causes alone the true lost motion lay outside
    the U95 (0.76 um off, U95 0.64); beside the smooth's columns the variance inflation is 65 and the shift the
    smooth makes real (p 5e-5 against its exact variance), carried: the truth lies inside. Reported: the value beside
    the named causes alone with the U95 reaching the fit beside the smooth (-14.63 +- 10.66; session 20's review: the
    fit beside the smooth, -5.33, lies farther from the truth). The decisions do not move."""
    tr, before = _run("reversal", 1054, False)
    _, after = _run("reversal", 1054, True)
    axis = tr.params["axis"].lower()
    key = f"{axis}_lost_motion_um"
    truth = -tr.physical["lost_motion_um"]  # the report's sign: a lag against the motion reads negative
    fb = next(f for f in before["findings"] if f["cause"] == "reversal")
    fa = next(f for f in after["findings"] if f["cause"] == "reversal")
    assert abs(fb["params"][key] - truth) > fb["params_u95"][key]
    assert abs(fa["params"][key] - truth) <= fa["params_u95"][key]
    ev0 = fa["evidence"]["magnitudes_beside_smooth"]
    assert fa["params"][key] == pytest.approx(fb["params"][key])  # the value beside the named causes alone
    assert fa["params_u95"][key] > abs(ev0["shift"][key])  # reaching the fit beside the smooth
    ev = fa["evidence"]["magnitudes_beside_smooth"]
    assert ev["smooth"] == "feature" and key in ev["carried_in_u95"] and ev["variance_inflation"][key] > 10
    assert "magnitudes_beside_smooth" not in fb["evidence"]
    assert [(f["cause"], f["evidence"].get("confidence")) for f in before["findings"]] == \
        [(f["cause"], f["evidence"].get("confidence")) for f in after["findings"]]
    assert before["workpiece"] == after["workpiece"]


def _ranged(lam, bounds, smooth_coef):
    x, S, cause, tm, sm, Qo = _linear_case(lam)
    cause.bounds = bounds
    rows = np.arange(len(x))
    y = 0.5 + 2.0 * x + S @ np.asarray(smooth_coef) + np.random.default_rng(3).standard_normal(len(x))
    bl = types.SimpleNamespace(y=y)
    v0, u0 = D._magnitudes(cause, bl, tm, Qo, rows, boot=(None, []))
    return D._magnitudes_beside_smooth(cause, bl, tm, Qo, rows, None, [], [sm], v0, u0, 0.05)


def test_beside_smooth_range_judged_after_the_carry():
    """The plausible range is judged on the U95 reported beside the smooth, the shift carried: a magnitude whose
    U95 there exceeds its range is no value, said undetermined in size (``wider_than_range`` and the note that makes
    the finding ambiguous), not ``not_determined`` (a direction the ridge leaves open). Before, the U95 beside the
    smooth was judged before the carry and labelled ``not_determined`` without the flag; the carried one not at all.
    """
    # no shift to carry: the U95 beside the smooth (about 1.5 at lam 3) against a range of 1
    v, u, fig, note = _ranged(3.0, {"a_um": (1.5, 2.5)}, (0.0, 0.0, 0.0))
    assert v["a_um"] is None and u["a_um"] is None
    assert fig["wider_than_range"] == ["a_um"] and fig["not_determined"] == [] and "a_um" in note
    # U95 1.81 beside the smooth, within a range of 2.1; the carried shift (-1.67) takes it to 2.46, beyond
    v0, u0, fig0, _ = _ranged(3.0, {}, (5.0, 5.0, 5.0))
    assert fig0["carried_in_u95"] == ["a_um"] and np.sqrt(u0["a_um"] ** 2 - fig0["shift"]["a_um"] ** 2) < 2.1 < u0["a_um"]
    v, u, fig, note = _ranged(3.0, {"a_um": (11.0, 13.1)}, (5.0, 5.0, 5.0))
    assert v["a_um"] is None and fig["wider_than_range"] == ["a_um"] and note
    # a wide range: reported, no note
    v, u, fig, note = _ranged(3.0, {"a_um": (-100.0, 100.0)}, (5.0, 5.0, 5.0))
    assert v["a_um"] is not None and fig["wider_than_range"] == [] and note is None
