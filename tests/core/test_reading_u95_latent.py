"""Three latent faults of the reading-choice U95 (:func:`core.discover._reading_u95`, session 22's second review;
session 23, issue 13).

probe_lobing reads its lobes in one of two readings of the pre-travel and its magnitudes' U95 carries the choice: the
other reading is fitted in the chosen reading's label combinations and weighed by Akaike's weight. The review named
three faults the seeds run so far had not hit: (a) a magnitude the other reading does not report (the plausible
range's gate, a norm whose pair has a coefficient held at 0) dropped out of the carry, and the carried U95 was never
judged against the plausible range; (b) a coefficient the other reading holds at 0 by construction read as a measured
zero; (c) the two readings' parameter counts were made by two different cuts. Each test below fails on the code before
the mend. The cases are the real fits of two tuning seeds (gen_a probe_lobing 1023, gen_b probe_lobing 1002), taken
at the call that makes the report, with one input changed where the seeds do not reach the fault. docs/discovery.md,
"Session 23: three latent faults of the reading-choice U95".
"""
from __future__ import annotations

import dataclasses

import numpy as np
import pytest

import core.discover as D
from core.touches import from_log
from scenarios.blind import gen_a, gen_b
from tests.discover_helpers import discovered


def _call(mod, seed):
    """The arguments and result of the report's `_reading_u95` call on a probe_lobing campaign."""
    got = []
    orig = D._reading_u95

    def hook(*a):
        r = orig(*a)
        got.append((a, r))
        return r

    log, _ = mod.generate("probe_lobing", seed)
    t = from_log(log)
    D._reading_u95 = hook
    try:
        rep = discovered(log, t).to_report()
    finally:
        D._reading_u95 = orig
    got = [g for g in got if g[1] is not None]
    assert got
    return got[-1][0], got[-1][1], rep


@pytest.fixture(scope="module")
def a1023():
    return _call(gen_a, 1023)


def _again(args, **kw):
    """`_reading_u95` on the captured arguments, some replaced (no folds: the plain fit)."""
    cause, bl, tm, so, rows, vals, u95, sig, settings, folds, others = args
    kw = {"cause": cause, "tm": tm, "vals": vals, "u95": u95, **kw}
    return D._reading_u95(kw["cause"], bl, kw["tm"], so, rows, kw["vals"], kw["u95"], sig, settings, None, others)


def test_a_the_plausible_range_judges_the_carried_u95_and_keeps_the_other_readings_estimate(a1023):
    """(a) gen_a 1023's pre-travel variation: 5.299 +- 0.261 um in the chosen (normal) reading, 5.521 +- 0.272 in
    the other, whose weight is 0.41. Its plausible range narrowed to 5.1..5.365 um (0.265 wide, between the two
    U95s): the range's gate refused the other reading's value and the carry skipped it, so the chosen U95 stood as
    if the other reading agreed (0.261 um). Its value and U95 now enter the mixture (0.388 um), which is wider than
    the range: the magnitude is refused (`wider_than_range`), as the carry beside an unnamed smooth is judged."""
    args, r0, _ = a1023
    key = "pretravel_variation_pv_um"
    cause = dataclasses.replace(args[0], bounds={key: (5.1, 5.365)})
    uc = args[6][key]
    assert uc < 0.265 < r0["other_u95"][key]  # (the case: the chosen U95 inside the range, the other's beyond it)
    r = _again(args, cause=cause)
    w, v, vo, uo = r["weight_other"], args[5][key], r["other_values"][key], r["other_u95"][key]
    assert vo == pytest.approx(r0["other_values"][key], rel=1e-12) and uo == pytest.approx(r0["other_u95"][key])
    assert r["u95"][key] == pytest.approx(2 * np.sqrt((1 - w) * (uc / 2) ** 2 + w * ((uo / 2) ** 2 + (vo - v) ** 2)))
    assert r["u95"][key] > 0.265 and r.get("wider_than_range") == [key]


def test_b_a_coefficient_held_at_0_is_no_measured_zero():
    """(b) gen_b probe_lobing 1002 (read along the normal, whose first harmonic lies in the baseline): the other
    reading is fitted in the chosen reading's combinations, which hold the approach reading's first harmonic at 0.
    Its evidence showed `k1_amplitude_um` 9e-17 +- 7e-17 um, a measured zero; it is not that reading's estimate."""
    _, r, rep = _call(gen_b, 1002)
    f = [f for f in rep["findings"] if f["cause"] == "probe_lobing"][0]
    assert f["params"]["pretravel_along"] == "normal" and f["params"]["k1_amplitude_um"] is None
    ev = f["evidence"]["pretravel_reading"]
    assert ev["other_values"]["k1_amplitude_um"] is None and ev["other_u95"]["k1_amplitude_um"] is None
    assert ev["other_values"]["k3_amplitude_um"] is not None  # (the lobes the reading holds are still its estimates)


def test_b_a_held_coefficient_does_not_widen_the_u95_as_a_measurement(a1023, monkeypatch):
    """(b) gen_a 1023 with the chosen reading's combinations holding sin3 at 0 (`tm.map` without it): the other
    reading's third-harmonic amplitude was |cos3| = 2.522 um read as a measurement (U95 0.090 -> 0.221 um at weight
    0.93; with cos3 held, 1.052 um and U95 1.923 at 0.38). It is now not reported there. At those weights (above
    READING_FREE_WEIGHT) the magnitude is free in a reading that may well be the true one: no U95 (the session 23
    review). The held norm is the lower bound it is (`other_lower_bounds`) where the other reading weighs little
    (the level raised to 1 here to reach it): below the chosen value it widens nothing."""
    args, _, _ = a1023
    tm, vals, u95 = args[2], args[5], args[6]
    key = "k3_amplitude_um"
    for lab in ("cos3", "sin3"):
        keep = [i for i, x in enumerate(tm.labels_all) if x != lab]
        r = _again(args, tm=dataclasses.replace(tm, map=np.eye(len(tm.labels_all))[:, keep]))
        assert r["other_values"][key] is None and r["other_u95"][key] is None, lab
        assert r["weight_other"] > 0.3 and r["u95"][key] is None and key in r["free_in_other"]
    monkeypatch.setattr(D, "READING_FREE_WEIGHT", 1.0)
    for lab in ("cos3", "sin3"):
        keep = [i for i, x in enumerate(tm.labels_all) if x != lab]
        r = _again(args, tm=dataclasses.replace(tm, map=np.eye(len(tm.labels_all))[:, keep]))
        lo = r["other_lower_bounds"][key]
        assert 1.0 < lo < vals[key]
        assert r["u95"][key] == pytest.approx(u95[key], rel=1e-12, abs=0)


def test_a_a_norms_lower_bound_above_the_value_is_carried(a1023, monkeypatch):
    """(a) The held norm's lower bound where it lies above the value reported (the chosen value put at 2.0 um, the
    other reading's |cos3| 2.522 um with sin3 held): the other reading's amplitude is at least that, so the mixture's
    second moment about the value is at least ``w_o (lower - v)^2`` (Jensen): the U95 carries it. (Where the other
    reading's weight is at most READING_FREE_WEIGHT; here 0.93, the level raised to 1 to reach the carry: at the
    default the U95 is None, test_b_a_held_coefficient_does_not_widen_the_u95_as_a_measurement.)"""
    monkeypatch.setattr(D, "READING_FREE_WEIGHT", 1.0)
    args, _, _ = a1023
    tm, vals, u95 = args[2], dict(args[5]), args[6]
    key = "k3_amplitude_um"
    vals[key] = 2.0
    keep = [i for i, x in enumerate(tm.labels_all) if x != "sin3"]
    r = _again(args, tm=dataclasses.replace(tm, map=np.eye(len(tm.labels_all))[:, keep]), vals=vals)
    lo, w = r["other_lower_bounds"][key], r["weight_other"]
    assert lo > 2.0 and w > 0.1
    assert key in r["carried_in_u95"]
    assert r["u95"][key] == pytest.approx(2 * np.sqrt((1 - w) * (u95[key] / 2) ** 2 + w * (lo - 2.0) ** 2))


def test_c_both_readings_counted_by_one_cut(a1023):
    """(c) The same lobes' combinations with two of them nearly parallel (cos3 and cos3 + 1e-3 sin3, what a cause
    adopted after the lobes can leave of them beside the model): the chosen reading's count was new_basis's (a
    singular value above 1e-5 kept), the other's _determined's (below WEAK_SV, 1e-2, cut): 8 against 7, and what the
    eighth direction caught (297 um^2) counted for the chosen reading alone, weight 0.0. Both now by _determined's
    cut: 7 and 7."""
    args, _, _ = a1023
    tm = args[2]
    M = tm.map.copy()
    M[:, 5] = M[:, 4] + 1e-3 * M[:, 5]
    r = _again(args, tm=dataclasses.replace(tm, map=M))
    k_c, k_o = r["columns"]
    assert k_c == k_o == 7
    assert abs(r["explained_gap_um2"]) < 5.0 and r["weight_other"] > 0.01


def test_a_the_report_refuses_a_carried_u95_beyond_the_plausible_range(monkeypatch):
    """(a) The same through discover: probe_lobing's pre-travel variation given a plausible range of 5.1..5.365 um
    (0.265 wide) on gen_a 1023. Its U95 in the chosen reading (0.261 um) is inside it, the carried one is not: the
    report gives it no value, says why in `magnitude_undetermined` and names the finding at most ambiguous. Before,
    5.299 +- 0.261 um was reported (the other reading refused by the range and skipped, the carry never judged)."""
    from core import causes

    key = "pretravel_variation_pv_um"
    cause = [c for c in causes.REGISTRY if c.name == "probe_lobing"][0]
    monkeypatch.setitem(cause.bounds, key, (5.1, 5.365))
    _, r, rep = _call(gen_a, 1023)
    f = [f for f in rep["findings"] if f["cause"] == "probe_lobing"][0]
    assert f["params"][key] is None and f["params_u95"][key] is None
    ev = f["evidence"]
    assert ev["pretravel_reading"]["wider_than_range"] == [key]
    assert "across the two pre-travel readings" in ev["magnitude_undetermined"]
    assert ev["confidence"] == "ambiguous"  # (it was already: ambiguous with lobing_per_setup)
    assert f["params"]["k3_amplitude_um"] is not None  # (the other magnitudes are reported as before)
