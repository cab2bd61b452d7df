"""A named cause smaller than turned outliers beside it hands the lead to ``unexplained`` (session 25, miss6).

:data:`core.discover.NAMED_BESIDE_TURNED_OUTLIERS_UNEXPLAINED`,
:func:`core.discover._named_beside_turned_outliers_unexplained`: where a named cause leads beside an outlier
finding whose own centred-turn test fired (:func:`core.discover.centred_turn_p` below ``alpha_family``) and the
named causes together explain less than those outliers carry, the outliers are the minority readings of a
mechanism of the move out of the catalogue (a re-seat) and the report reads ``unexplained``.
"""

from __future__ import annotations

import numpy as np
import pytest

import core.discover as D
from core.discover import Finding, Settings, _named_beside_turned_outliers_unexplained as rule


def _f(cause, **ev):
    return Finding(cause, dict(ev), {}, {}, 0.3, "unknown" if cause == "unexplained" else "probe")


def test_named_beside_turned_outliers_unit():
    """Made-up findings. A named cause (1.7 um^2) beside outliers whose centred turn is 1e-5 and who carry
    154 um^2: an ``unexplained`` finding is made ahead of both (its sum of squares the outliers', ``of``
    ``outliers``, its text naming the turn and both sums), the named cause and the outliers follow unchanged in
    order. An ``unexplained`` finding already in the list moves first instead (its text gains the turn).
    Nothing changes where: the named causes together explain as much as the outliers carry (equal counts as
    enough), the centred turn is at alpha_family (0.0025) or above or absent, the outliers or an ``unexplained``
    finding already lead, or there are no findings."""
    st = Settings()
    named = _f("stylus_bending", confidence="ambiguous", explained_ss_um2=1.7)
    fo = _f("outlier", confidence="ambiguous", centred_turn_p=1e-5, explained_ss_um2=154.0)
    out = rule([named, fo], st, 0.26)
    assert [f.cause for f in out] == ["unexplained", "stylus_bending", "outlier"]
    assert out[1] is named and out[2] is fo and named.evidence["confidence"] == "ambiguous"
    ev = out[0].evidence
    assert ev["explained_ss_um2"] == 154.0 and ev["of"] == "outliers" and ev["centred_turn_p"] == 1e-5
    assert "turn of the approach" in ev["text"] and "154 um^2" in ev["text"] and "1.7 um^2" in ev["text"]
    assert out[0].rms_um == 0.26 and "turned_lead" in fo.evidence

    # two named causes: their sum is what the outliers are compared with
    a, b = _f("c_drift", explained_ss_um2=60.0), _f("stylus_bending", explained_ss_um2=50.0)
    fo = _f("outlier", centred_turn_p=1e-4, explained_ss_um2=100.0)
    assert rule([a, b, fo], st, 0.3) == [a, b, fo] and "turned_lead" not in fo.evidence
    fo = _f("outlier", centred_turn_p=1e-4, explained_ss_um2=111.0)
    assert [f.cause for f in rule([a, b, fo], st, 0.3)] == ["unexplained", "c_drift", "stylus_bending", "outlier"]

    # an unexplained finding already present leads
    named = _f("c_drift", explained_ss_um2=5.0)
    un = _f("unexplained", text="residuals follow time", explained_ss_um2=3.0)
    fo = _f("outlier", centred_turn_p=1e-4, explained_ss_um2=50.0)
    out = rule([named, un, fo], st, 0.3)
    assert out == [un, named, fo]
    assert un.evidence["text"].startswith("residuals follow time; ") and "centred turn" in un.evidence["text"]

    # unchanged
    for ss_named, p in ((50.0, 1e-4), (60.0, 1e-4), (5.0, st.alpha_family), (5.0, 0.3), (5.0, None)):
        named = _f("c_drift", explained_ss_um2=ss_named)
        fo = _f("outlier", explained_ss_um2=50.0, **({} if p is None else {"centred_turn_p": p}))
        assert rule([named, fo], st, 0.3) == [named, fo], (ss_named, p)
    fo = _f("outlier", centred_turn_p=1e-4, explained_ss_um2=50.0)
    named = _f("c_drift", explained_ss_um2=5.0)
    assert rule([fo, named], st, 0.3) == [fo, named]
    un = _f("unexplained", explained_ss_um2=1.0)
    assert rule([un, named, fo], st, 0.3) == [un, named, fo]
    assert rule([], st, 0.3) == []


# 1279's named cause was local_scale_defect on the 80 mm grid BIC chose with the outliers in; since session 27 a
# bump beside touches set aside has the grid chosen again on the kept touches (core.discover.GRID_AFTER_OUTLIERS),
# 55 mm, where stylus_bending is named beside the outliers instead (`unexplained` first either way; extended
# workpiece 2.855 -> 2.881 um, the baseline's 2.819, U95 0.409)
@pytest.mark.parametrize("seed, named", [(1146, "stylus_bending"), (1279, "stylus_bending"),
                                         (6300, "stylus_bending")])
def test_gen_a_reseat_hysteresis_named_beside_turned_outliers_reads_unexplained(seed, named, monkeypatch):
    """gen_a reseat_hysteresis (out of catalogue: ``unexplained`` is right) 1146 and 1279 (tuning seeds, visible
    6.9 and 3.1 sigma) and 6300 (session 24's blind check, spent: `stylus_bending?`, 1.73 um^2 beside 13 outliers
    carrying 154 um^2 whose centred turn is p = 1e-5): a named cause, ambiguous, first beside turned outliers that
    carry more than it explains. Flag off: the named cause leads, hedged; on: ``unexplained`` first, then the
    named cause and the outliers as before, the workpiece figures unchanged (only the order of the findings
    moves)."""
    from scenarios.blind import gen_a
    from scenarios.hidden import blind_outcome

    # since session 36 INSIDE_SMOOTH_REFUSED refuses 1279's bump (nothing beyond the smooth map), and the campaign reads
    # `unexplained` without this rule: the rule's own mechanism is tested with that one off, the two together after
    monkeypatch.setattr(D, "INSIDE_SMOOTH_REFUSED", False)
    monkeypatch.setattr(D, "NAMED_BESIDE_TURNED_OUTLIERS_UNEXPLAINED", False)
    off = blind_outcome(gen_a, "reseat_hysteresis", seed, generator="gen_a")
    assert off.cause == named and not off.confident and off.findings == (named, "outlier"), off
    monkeypatch.setattr(D, "NAMED_BESIDE_TURNED_OUTLIERS_UNEXPLAINED", True)
    on = blind_outcome(gen_a, "reseat_hysteresis", seed, generator="gen_a")
    assert on.cause == "unexplained" and on.cause in on.acceptable, on
    assert on.findings == ("unexplained",) + off.findings, on.findings
    assert np.array_equal([on.wp_ext_um, on.wp_u95_um], [off.wp_ext_um, off.wp_u95_um], equal_nan=True)
    if seed == 1279:
        monkeypatch.setattr(D, "INSIDE_SMOOTH_REFUSED", True)
        monkeypatch.setattr(D, "NAMED_BESIDE_TURNED_OUTLIERS_UNEXPLAINED", False)
        assert blind_outcome(gen_a, "reseat_hysteresis", seed, generator="gen_a").findings == ("unexplained", "outlier")
