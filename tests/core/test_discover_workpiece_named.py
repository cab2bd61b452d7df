"""The extended workpiece where its U95 left out an assumption (session 22, issue 13 item 7).

Two assumptions of the extended model move its workpiece without the data deciding them:

- the outliers' removal (session 21's ``OUTLIER_SHIFT_CARRIED``): its shift is now the form's outliers' alone
  (``core.discover.OUTLIER_REFIT_FORM_ONLY``), a chip on another feature no longer counted in it. gen_a
  reseat_hysteresis 1060 (a tuning seed): seven outliers, four of them on bore3's form; the shift they make is
  a downdate by the rows put back, of rank at most four (seven before; ``OUTLIER_BELOW_KEPT`` off, which
  adds a fifth: an outlier reading less material than the touches kept at its target);
- the name of a cause that is one explanation with another catalogue cause under two names
  (``NAMED_ALTERNATIVE_SHIFT_CARRIED``, measured and left off: it inflates covering U95s where the name is right): gen_a feed_latency 1009 (a tuning seed), read part_change and
  periodic_axis_error, each ambiguous with nonrigid; with nonrigid in their place the workpiece moves by 21 and
  46 um RMS. Before, the extended workpiece was 13.61 um from the truth against the baseline's 4.96 and a U95
  of 7.28 um, the name taken as true.
"""

import pytest

import core.discover as D
from scenarios import hidden
from scenarios.blind import gen_a
from tests.discover_helpers import discovered


def _fl1009():
    return hidden.blind_outcome(gen_a, "feed_latency", 1009, generator="gen_a")


@pytest.mark.slow
def test_gen_a_feed_latency_1009_workpiece_within_its_check_with_the_alternative_carried(monkeypatch):
    # measured and left off (it inflates covering U95s where the name is right: docs/discovery.md, session 22)
    monkeypatch.setattr(D, "NAMED_ALTERNATIVE_SHIFT_CARRIED", True)
    monkeypatch.setattr(D, "WORKPIECE_U95_GROWTH_WITHHELD", False)  # (the extended estimate offered: session 35)
    o = _fl1009()
    assert o.cause == "part_change" and not o.confident  # the decision this rule does not touch
    assert o.wp_ext_um <= o.wp_base_um + o.wp_u95_um, o


@pytest.mark.slow
def test_gen_a_feed_latency_1009_fails_with_the_name_taken_as_true_the_default(monkeypatch):
    monkeypatch.setattr(D, "NAMED_ALTERNATIVE_SHIFT_CARRIED", False)
    monkeypatch.setattr(D, "WORKPIECE_U95_GROWTH_WITHHELD", False)  # (the extended estimate offered: session 35)
    o = _fl1009()
    assert o.cause == "part_change" and not o.confident
    # session 32: the hedged part_change's own shift (HEDGED_SHIFT_CARRIED, on) covers it: 13.61 <= 4.96 + 14.30
    assert o.wp_ext_um <= o.wp_base_um + o.wp_u95_um, o
    monkeypatch.setattr(D, "HEDGED_SHIFT_CARRIED", None)
    monkeypatch.setattr(D, "FINE_SHIFT_CARRIED", False)  # (its hedged 6.78 mm periodic term's shift, session 34)
    o = _fl1009()
    assert o.wp_ext_um > o.wp_base_um + o.wp_u95_um, o  # session 21's engine: 13.61 > 4.96 + 7.28


@pytest.mark.slow
def test_gen_a_feed_latency_1009_extended_workpiece_not_offered_beyond_its_u95_growth(monkeypatch):
    """Session 35 (earn35): the one tuning campaign of 256 whose extended U95 (RMS outside the part's gauge) exceeds
    three times the baseline's: 15.33 um against 3.23 (x4.75), the estimate 13.61 um from the truth against the
    baseline's 4.96, within its check by that U95 alone. With WORKPIECE_U95_GROWTH_WITHHELD (off) it is not
    offered; the finding is unchanged."""
    monkeypatch.setattr(D, "WORKPIECE_U95_GROWTH_WITHHELD", True)
    o = _fl1009()
    assert o.cause == "part_change" and not o.confident
    assert o.wp_ext_um != o.wp_ext_um and abs(o.wp_base_um - 4.96) < 0.01, o  # (NaN: withheld; the baseline's stays)


@pytest.mark.slow
def test_gen_a_feed_latency_1009_report_names_the_alternative_shift(monkeypatch):
    monkeypatch.setattr(D, "NAMED_ALTERNATIVE_SHIFT_CARRIED", True)

    log, _ = gen_a.generate("feed_latency", 1009)
    rep = discovered(log).to_report()
    f = rep["findings"][0]
    sh = f["evidence"]["workpiece_shift_alternative"]
    assert f["cause"] == "part_change" and sh["alternative"] == "nonrigid" and sh["carried_in_u95"]
    assert "_alt_columns" not in f["evidence"]  # the columns never reach the report
    assert all("_columns" not in a for a in f["evidence"]["cause_alternatives"])


def _rh1060_shift(monkeypatch, form_only):

    monkeypatch.setattr(D, "OUTLIER_REFIT_FORM_ONLY", form_only)
    monkeypatch.setattr(D, "OUTLIER_BELOW_KEPT", False)  # (a fifth outlier, below the touches kept at its target)
    log, _ = gen_a.generate("reseat_hysteresis", 1060)
    d = discovered(log)
    fo = next(f for f in d.findings if f.cause == "outlier")
    return len(d.outlier_rows), fo.evidence["workpiece_shift"]


@pytest.mark.slow
def test_gen_a_reseat_1060_removal_shift_is_the_forms_outliers_alone(monkeypatch):
    n_out, sh = _rh1060_shift(monkeypatch, True)
    assert n_out == 7 and sh["carried_in_u95"]
    assert sh["dof"] <= 4, sh  # four outliers on bore3's form put back: a downdate of rank four at most


@pytest.mark.slow
def test_gen_a_reseat_1060_every_outlier_put_back_before(monkeypatch):
    n_out, sh = _rh1060_shift(monkeypatch, False)
    assert sh["dof"] > 4, sh  # session 21: the seven put back (dof 7)


def _ol1505(monkeypatch, on):  # OUTLIER_BELOW_KEPT: measured and left off (gen_b outlier's covering U95s)
    monkeypatch.setattr(D, "OUTLIER_BELOW_KEPT", on)
    # the screen's choice before OUTLIER_CHIPS_READ_MORE (which sets the three chips aside instead:
    # tests/core/test_discover_chips_read_more.py): what this flag was measured on
    monkeypatch.setattr(D, "OUTLIER_CHIPS_READ_MORE", False)
    return hidden.blind_outcome(gen_a, "outlier", 1505, generator="gen_a")


@pytest.mark.slow
def test_gen_a_outlier_1505_removal_of_a_clean_touch_carried(monkeypatch):
    # three chips on one target's four touches (9.1, 8.4, 4.4 um): the screen removed the clean touch and the
    # smallest chip, both reading less material than the two large chips it kept; no particle reads less
    o = _ol1505(monkeypatch, True)
    assert o.cause == "outlier" and o.confident  # the decision is not touched
    assert o.shift_carried and o.wp_u95_um > 0.5, o  # 0.39 -> 0.54 um
    assert o.wp_ext_um <= o.wp_base_um + o.wp_u95_um, o


@pytest.mark.slow
def test_gen_a_outlier_1505_not_carried_before(monkeypatch):
    o = _ol1505(monkeypatch, False)
    assert not o.shift_carried and o.wp_u95_um < 0.4, o  # the U95 of the touches kept alone


def _td6105():
    return hidden.blind_outcome(gen_a, "thermal_drift", 6105, generator="gen_a")


@pytest.mark.slow
def test_gen_a_thermal_drift_6105_extended_workpiece_within_its_check():
    # session 24's blind check (spent seed), pinned then as a strict xfail: c_drift's per-set-up rates (k = 3,
    # held-out gain 2.31 um^2) won round one against thermal_drift's quadratic (k = 8, p 8.5e-55, gain 1.28), the
    # cause's form by the smallest p over its warm-up of 430 s (gain 3.37), and moved the workpiece by 3.18 um RMS
    # (4.32 um from the truth > 1.76 + 1.26). With ENTRANT_FORM_HELD_OUT (session 25) the warm-up takes the round
    # (held-out mean square 0.49 against c_drift's 1.56 um^2, margin 0.20): 0.36 um from the truth, U95 0.44.
    o = _td6105()
    assert o.cause == "thermal_drift" and o.confident, o
    assert o.wp_ext_um <= o.wp_base_um + o.wp_u95_um, o


@pytest.mark.slow
def test_gen_a_thermal_drift_6105_beyond_its_check_without_the_held_out_entrant(monkeypatch):
    # with the round c_drift won reopened once the rival check drops it (DROPPED_ROUND_REOPENED, on since session 36)
    # the campaign reads thermal_drift without the entrant rule too: session 24's failure is shown with that one off
    monkeypatch.setattr(D, "DROPPED_ROUND_REOPENED", False)
    monkeypatch.setattr(D, "ENTRANT_FORM_HELD_OUT", False)
    o = _td6105()
    assert o.cause == "c_drift" and not o.confident, o
    assert o.wp_ext_um > o.wp_base_um + o.wp_u95_um, o  # session 24's engine: 4.32 > 1.76 + 1.26
    monkeypatch.setattr(D, "DROPPED_ROUND_REOPENED", True)
    o = _td6105()
    assert o.cause == "thermal_drift" and o.wp_ext_um <= o.wp_base_um + o.wp_u95_um, o  # 0.41 against 1.76 + 0.57
