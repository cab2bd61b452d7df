"""Outliers that follow the turn of the approach hand the lead to ``unexplained`` (issue 13, session 24).

:data:`core.discover.OUTLIERS_TURNED_UNEXPLAINED`, :func:`core.discover._turned_outliers_unexplained`: where
the outlier finding would lead the report (no named cause beside it) and its own centred-turn test fired
(:func:`core.discover.centred_turn_p` below ``alpha_family``), the outliers are the minority readings of a
mechanism of the move out of the catalogue, not dust: the report reads ``unexplained``.
"""

from __future__ import annotations

import numpy as np
import pytest

import core.discover as D
from core.discover import Finding, Settings, _turned_outliers_unexplained


def _f(cause, **ev):
    return Finding(cause, dict(ev), {}, {}, 0.3, "unknown" if cause == "unexplained" else "data")


def test_turned_outliers_unexplained_unit():
    """Made-up findings: outliers alone whose centred turn is below alpha_family (0.0025) get an
    ``unexplained`` finding ahead of them, its text naming the turn and its sum of squares the outliers';
    beside an ``unexplained`` finding that one leads, the outliers lose ``leads`` and its text gains the turn;
    a centred turn at alpha_family or above, none at all, or a named cause first change nothing."""
    st = Settings()
    fo = _f("outlier", confidence="ambiguous", centred_turn_p=1e-4, explained_ss_um2=50.0)
    out = _turned_outliers_unexplained([fo], st, 0.3)
    assert [f.cause for f in out] == ["unexplained", "outlier"]
    assert out[0].evidence["explained_ss_um2"] == 50.0 and out[0].evidence["of"] == "outliers"
    assert "turn of the approach" in out[0].evidence["text"] and out[1] is fo and "turned_lead" in fo.evidence
    assert fo.evidence["confidence"] == "ambiguous"

    fo = _f("outlier", confidence="ambiguous", centred_turn_p=1e-4, explained_ss_um2=50.0, leads="x")
    un = _f("unexplained", text="residuals follow x", explained_ss_um2=10.0)
    out = _turned_outliers_unexplained([fo, un], st, 0.3)
    assert out == [un, fo] and "leads" not in fo.evidence
    assert un.evidence["text"].startswith("residuals follow x; ") and "centred turn" in un.evidence["text"]

    for p in (st.alpha_family, 0.5, None):
        fo = _f("outlier", confidence="ambiguous", explained_ss_um2=50.0,
                **({} if p is None else {"centred_turn_p": p}))
        assert [f.cause for f in _turned_outliers_unexplained([fo], st, 0.3)] == ["outlier"]
        assert "turned_lead" not in fo.evidence
    named = _f("c_drift", confidence="ambiguous", explained_ss_um2=5.0)
    fo = _f("outlier", confidence="ambiguous", centred_turn_p=1e-4, explained_ss_um2=50.0)
    assert _turned_outliers_unexplained([named, fo], st, 0.3) == [named, fo]
    assert _turned_outliers_unexplained([], st, 0.3) == []


@pytest.mark.parametrize("seed, beside", [(1012, False), (1088, False), (1262, True)])
def test_gen_a_reseat_hysteresis_turned_outliers_read_unexplained(seed, beside, monkeypatch):
    """gen_a reseat_hysteresis (out of catalogue: ``unexplained`` is right) 1012 and 1088, outliers alone
    (centred turn p 1.2e-4, 1.0e-5), and 1262, outliers leading beside an ``unexplained`` finding (3.8e-4):
    `outlier?` before (the flag off, as on 586aff4: the test fails there), ``unexplained`` with the flag, the
    outlier finding second and unchanged (its rows and confidence)."""
    from scenarios.blind import gen_a
    from scenarios.hidden import blind_outcome

    monkeypatch.setattr(D, "OUTLIERS_TURNED_UNEXPLAINED", False)
    off = blind_outcome(gen_a, "reseat_hysteresis", seed, generator="gen_a")
    assert off.cause == "outlier" and not off.confident, off
    monkeypatch.setattr(D, "OUTLIERS_TURNED_UNEXPLAINED", True)
    on = blind_outcome(gen_a, "reseat_hysteresis", seed, generator="gen_a")
    assert on.cause == "unexplained" and on.cause in on.acceptable, on
    assert on.findings == ("unexplained", "outlier"), on.findings
    # only the order moves: the fits, and so the workpiece and its U95, are the same
    assert np.array_equal([on.wp_ext_um, on.wp_u95_um], [off.wp_ext_um, off.wp_u95_um], equal_nan=True)


def test_gen_a_outlier_1070_closest_true_chips_keep_the_lead():
    """gen_a outlier 1000-1299's true chips: no outlier finding has a centred turn below alpha_family (216 tested;
    the smallest, 1070's two chips of one set-up, p = 0.00298): 1070 still reads ``outlier``."""
    from scenarios.blind import gen_a
    from scenarios.hidden import blind_outcome

    o = blind_outcome(gen_a, "outlier", 1070, generator="gen_a")
    assert o.cause == "outlier", o


def test_outliers_beside_a_turn_structure_unit(monkeypatch):
    """OUTLIERS_BESIDE_TURN_UNEXPLAINED on made-up findings: outliers without a centred turn below alpha_family
    leading beside an ``unexplained`` finding whose strongest covariate is the turn from the previous touch hand
    it the lead (its text unchanged, the outliers' ``leads`` dropped); beside one whose strongest covariate is
    another, or with the flag off, nothing changes."""
    st = Settings()

    def case(cov):
        fo = _f("outlier", confidence="ambiguous", centred_turn_p=0.5, explained_ss_um2=70.0, leads="x")
        un = _f("unexplained", text="t", explained_ss_um2=60.0, diagnosis=[{"covariate": cov}])
        return fo, un

    fo, un = case("turn_from_previous")
    assert _turned_outliers_unexplained([fo, un], st, 0.3) == [un, fo]
    assert "leads" not in fo.evidence and "turned_lead" in fo.evidence and un.evidence["text"] == "t"
    fo, un = case("y")
    assert _turned_outliers_unexplained([fo, un], st, 0.3) == [fo, un] and "leads" in fo.evidence
    monkeypatch.setattr(D, "OUTLIERS_BESIDE_TURN_UNEXPLAINED", False)
    fo, un = case("turn_from_previous")
    assert _turned_outliers_unexplained([fo, un], st, 0.3) == [fo, un] and "leads" in fo.evidence


@pytest.mark.parametrize("seed", [1036, 1154])
def test_gen_a_reseat_hysteresis_outliers_beside_a_turn_structure_read_unexplained(seed, monkeypatch):
    """gen_a reseat_hysteresis 1036 (centred turn p 0.51) and 1154 (0.022): outliers leading beside an
    ``unexplained`` finding whose diagnosis follows the turn of the approach first: `outlier?` with
    OUTLIERS_BESIDE_TURN_UNEXPLAINED off (and on 586aff4), ``unexplained`` with it."""
    from scenarios.blind import gen_a
    from scenarios.hidden import blind_outcome

    monkeypatch.setattr(D, "OUTLIERS_BESIDE_TURN_UNEXPLAINED", False)
    off = blind_outcome(gen_a, "reseat_hysteresis", seed, generator="gen_a")
    assert off.cause == "outlier" and not off.confident, off
    monkeypatch.setattr(D, "OUTLIERS_BESIDE_TURN_UNEXPLAINED", True)
    on = blind_outcome(gen_a, "reseat_hysteresis", seed, generator="gen_a")
    assert on.cause == "unexplained" and on.findings[:2] == ("unexplained", "outlier"), on



def test_centred_turn_through_unit():
    """The turn from the move before each touch (a no-trigger row's included): rounded degrees less the target's
    mean; a touch with no move before it turns 0."""
    from core.discover import centred_turn_through

    d = np.array([[1.0, 0, 0], [0, 1.0, 0], [-1.0, 0, 0]])
    prev = np.array([[np.nan] * 3, [1.0, 0, 0], [0, -1.0, 0]])
    assert np.allclose(centred_turn_through(d, prev, [0, 0, 1]), [-45, 45, 0])
    assert centred_turn_through(np.zeros((0, 3)), np.zeros((0, 3)), []).shape == (0,)
    with pytest.raises(Exception):
        centred_turn_through(d, prev[:2], [0, 0, 1])


def test_gen_a_reseat_6306_retry_after_no_trigger_is_no_dust(monkeypatch):
    """gen_a reseat_hysteresis 6306 (session 24's blind check, spent; out of catalogue, 5.1 sigma visible): its
    four outliers are the re-seat's minority readings; log row 165 retries the no-trigger row 164 (same target),
    whose approach turned 119.5 deg and re-seated the probe: the retry turned 10 deg from it, 129 deg from the
    touch before. Counted from the touches alone (the flag off, as on 9a06759) the centred turn reads 0.0056 and
    the report `outlier`, confident (a confident misnaming: the test fails there); counted through the no-trigger
    approach (:data:`core.discover.TURN_THROUGH_NO_TRIGGER`) 6e-5, the report ``unexplained``."""
    from core.touches import from_log
    from scenarios.blind import gen_a
    from scenarios.hidden import blind_outcome

    log, _ = gen_a.generate("reseat_hysteresis", 6306)
    t = from_log(log)
    k = int(np.flatnonzero(t.row == 165)[0])
    assert log.col("status")[164] == "no_trigger"
    d164 = np.array([float(log.col(c)[164]) for c in ("dx", "dy", "dz")])
    assert np.array_equal(t.d_prev_R[k], d164) and np.all(np.isnan(t.d_prev_R[0]))
    assert np.array_equal(t.d_prev_R[1], t.d_R[0])

    # since session 36 the reversal as a travel (OUTLIER_STRUCTURE_REVERSAL_TRAVEL) hedges the `outlier` reading on its
    # own; this test's subject, the turn counted through the no-trigger row, is held with it off
    monkeypatch.setattr(D, "OUTLIER_STRUCTURE_REVERSAL_TRAVEL", False)
    monkeypatch.setattr(D, "TURN_THROUGH_NO_TRIGGER", False)
    off = blind_outcome(gen_a, "reseat_hysteresis", 6306, generator="gen_a")
    assert off.cause == "outlier" and off.confident, off
    monkeypatch.setattr(D, "TURN_THROUGH_NO_TRIGGER", True)
    on = blind_outcome(gen_a, "reseat_hysteresis", 6306, generator="gen_a")
    assert on.cause == "unexplained" and on.cause in on.acceptable, on
    assert on.findings == ("unexplained", "outlier"), on.findings
