"""The extended workpiece where its U95 left out an assumption (session 22, issue 13 item 7).

Two assumptions of the extended model move its workpiece without the data deciding them:

- the outliers' removal (session 21's ``OUTLIER_SHIFT_CARRIED``): its shift is now the form's outliers' alone
  (``core.discover.OUTLIER_REFIT_FORM_ONLY``), a chip on another feature no longer counted in it. gen_a
  reseat_hysteresis 1060 (a tuning seed): seven outliers, four of them on bore3's form; the shift they make is
  a downdate by the rows put back, of rank at most four (seven before);
- the name of a cause that is one explanation with another catalogue cause under two names
  (``NAMED_ALTERNATIVE_SHIFT_CARRIED``): gen_a feed_latency 1009 (a tuning seed), read part_change and
  periodic_axis_error, each ambiguous with nonrigid; with nonrigid in their place the workpiece moves by 21 and
  46 um RMS. Before, the extended workpiece was 13.61 um from the truth against the baseline's 4.96 and a U95
  of 7.28 um, the name taken as true.
"""

import pytest

import core.discover as D
from scenarios import hidden
from scenarios.blind import gen_a


def _fl1009():
    return hidden.blind_outcome(gen_a, "feed_latency", 1009, generator="gen_a")


@pytest.mark.slow
def test_gen_a_feed_latency_1009_workpiece_within_its_check():
    o = _fl1009()
    assert o.cause == "part_change" and not o.confident  # the decision this rule does not touch
    assert o.wp_ext_um <= o.wp_base_um + o.wp_u95_um, o


@pytest.mark.slow
def test_gen_a_feed_latency_1009_fails_with_the_name_taken_as_true(monkeypatch):
    monkeypatch.setattr(D, "NAMED_ALTERNATIVE_SHIFT_CARRIED", False)
    o = _fl1009()
    assert o.cause == "part_change" and not o.confident
    assert o.wp_ext_um > o.wp_base_um + o.wp_u95_um, o  # session 21's engine: 13.61 > 4.96 + 7.28


@pytest.mark.slow
def test_gen_a_feed_latency_1009_report_names_the_alternative_shift():
    from core.baseline import extra_columns
    from core.touches import from_log

    log, _ = gen_a.generate("feed_latency", 1009)
    t = from_log(log)
    rep = D.discover(t, chain=log.meta.get("kinematic_chain"), extra=extra_columns(log, t.row)).to_report()
    f = rep["findings"][0]
    sh = f["evidence"]["workpiece_shift_alternative"]
    assert f["cause"] == "part_change" and sh["alternative"] == "nonrigid" and sh["carried_in_u95"]
    assert "_alt_columns" not in f["evidence"]  # the columns never reach the report
    assert all("_columns" not in a for a in f["evidence"]["cause_alternatives"])


def _rh1060_shift(monkeypatch, form_only):
    from core.baseline import extra_columns
    from core.touches import from_log

    monkeypatch.setattr(D, "OUTLIER_REFIT_FORM_ONLY", form_only)
    log, _ = gen_a.generate("reseat_hysteresis", 1060)
    t = from_log(log)
    d = D.discover(t, chain=log.meta.get("kinematic_chain"), extra=extra_columns(log, t.row))
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
